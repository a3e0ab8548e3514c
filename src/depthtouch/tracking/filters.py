"""Touch path correction: per-touch filters that smooth the wobble depth noise puts on a path.

Five filters, selectable by name (:data:`FILTERS`) through :func:`make_filter`:

- ``none``: the measurement as it is.
- ``lowpass``: exponential smoothing with a fixed cutoff frequency.
- ``kalman``: Kalman filter with a constant-velocity model per axis.
- ``adaptive``: the paper's filter (Lee & Kwon 2019): Kalman-like prediction, and a correction
  weight that grows with the distance between the predicted and the measured position, so a
  sudden turn is followed at once while a still finger's noise is smoothed.
- ``one_euro``: the 1€ filter (Casiez, Roussel, Vogel, CHI 2012), ``fc = min_cutoff +
  beta·|dx/dt|``, numerically the same as the authors' reference implementation (PyPI
  ``OneEuroFilter``).
- ``adaptive_euro``: the adaptive filter followed by a 1€ stage whose cutoff follows the speed
  (the norm of the velocity, the same on both axes), and a lock of a finger proven at rest: a
  finger at rest is held still (a one-frame jump of its tip ignored), a drag passes with the
  adaptive filter's lag; and a landing: from touch-down, the mean of the measurements until
  they show that the finger moves.

Every filter keeps its state per touch id in arrays, so one frame's update runs over all active
touches at once. Positions are millimetres on the surface, so the parameters are physical.
Time comes only from the timestamps passed to :meth:`update`. A touch whose timestamp did not
advance since its last update (a repeated or backwards timestamp) is treated as "no time
elapsed": it returns its previous output and its state is left unchanged, so no ``dt`` is ever
divided by zero.

The default parameters were chosen by measurement (``depthtouch bench-filters``, see
docs/filters.md): each filter's free parameter tuned on one seed set of simulated paths at 30 fps
with 1–3 mm RMS noise, under the constraint of at most one frame (33 ms) of lag; the table in the
docs is measured on another seed set.
"""

from __future__ import annotations

import numpy as np

from ..config import FilterConfig
from ..errors import ConfigError
from .adaptive_euro import AdaptiveEuroFilter
from .filterbase import FilterBase, Param, TouchFilter, smoothing_factor  # noqa: F401

FILTERS: tuple[str, ...] = ("none", "lowpass", "kalman", "adaptive", "one_euro", "adaptive_euro")

#: The filter the pipeline uses by default, chosen by measurement on the hard suite's tune half
#: (docs/filters.md): the adaptive filter's turns and lag, with a finger at rest held still.
DEFAULT_FILTER = "adaptive_euro"


class NoFilter(FilterBase):
    """``none``: returns the measurements unchanged (the raw path)."""

    name = "none"

    def _step(self, s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray) -> np.ndarray:
        return xy.copy()


class LowPassFilter(FilterBase):
    """``lowpass``: exponential smoothing ``y += a·(x − y)``, a = dt/(dt + 1/(2π·cutoff_hz)).

    cutoff_hz: cutoff frequency in Hz, range (0, 1000], default 5.0. A finger drawing a stroke
    moves mostly below a few Hz while depth noise is white up to the Nyquist frequency (15 Hz
    at 30 fps); without a velocity the filter lags 1/(2π·fc) on a straight line (32 ms at
    5 Hz), so 5 Hz is the lowest cutoff within a one-frame lag budget at 30 fps (tuned).
    """

    name = "lowpass"
    PARAMS = {"cutoff_hz": Param(5.0, 0.0, 1000.0)}

    def _step(self, s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray) -> np.ndarray:
        a = smoothing_factor(dt_s, self.params["cutoff_hz"])[:, None]
        prev = s[:, 0:2]
        return prev + a * (xy - prev)


class KalmanFilter(FilterBase):
    """``kalman``: constant-velocity Kalman filter, x and y independent with the same model.

    measurement_noise_mm: RMS noise of a measured touch point, range (0, 100], default 2.0: the
        middle of the 1–3 mm a depth camera gives at 0.5–1.5 m.
    process_noise_mm_s2: RMS of the unmodelled acceleration (white, per frame), range
        (0, 1e6], default 500 (0.5 m/s²: along most of a stroke a finger moves at a steady
        speed; turns and stops are short bursts of 2–10 m/s² that a larger value would follow
        at the cost of letting noise through); tuned on simulated paths (one-frame lag budget).
    initial_speed_mm_s: RMS of the unknown speed when a touch goes down, range [0, 1e5],
        default 500 (touch strokes run at 0.05–1 m/s).
    """

    name = "kalman"
    PARAMS = {
        "measurement_noise_mm": Param(2.0, 0.0, 100.0),
        "process_noise_mm_s2": Param(500.0, 0.0, 1e6),
        "initial_speed_mm_s": Param(500.0, 0.0, 1e5, lo_open=False),
    }
    _FIELDS = {"v": (2,), "p": (3,)}  # velocity mm/s; covariance (pp, pv, vv) shared by x and y

    def _init(self, rows: np.ndarray, xy: np.ndarray) -> None:
        self._state["v"][rows] = 0.0
        self._state["p"][rows] = [
            self.params["measurement_noise_mm"] ** 2,
            0.0,
            self.params["initial_speed_mm_s"] ** 2,
        ]

    def _step(self, s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray) -> np.ndarray:
        q = self.params["process_noise_mm_s2"] ** 2
        r = self.params["measurement_noise_mm"] ** 2
        v_col, p_col = self._COLS["v"], self._COLS["p"]
        v = s[:, v_col]
        pp, pv, vv = s[:, p_col].T
        # predict: F = [[1, dt], [0, 1]], Q = q·[[dt⁴/4, dt³/2], [dt³/2, dt²]] (discrete white
        # acceleration)
        dt = dt_s
        pred = s[:, 0:2] + v * dt[:, None]
        pp = pp + 2.0 * dt * pv + dt * dt * vv + q * dt**4 / 4.0
        pv = pv + dt * vv + q * dt**3 / 2.0
        vv = vv + q * dt * dt
        # correct
        s_mm2 = pp + r  # innovation variance
        k_pos, k_vel = pp / s_mm2, pv / s_mm2
        innov = xy - pred
        out = pred + k_pos[:, None] * innov
        s[:, v_col] = v + k_vel[:, None] * innov
        s[:, p_col] = np.stack(
            [(1.0 - k_pos) * pp, (1.0 - k_pos) * pv, vv - k_vel * pv], axis=1
        )
        return out


class AdaptiveFilter(FilterBase):
    """``adaptive``: the paper's path correction filter (Lee & Kwon 2019).

    Prediction as in a constant-velocity Kalman filter (``p̂ = p + v·dt``); the correction
    ``p = p̂ + w·(z − p̂)`` uses a weight w that grows with the distance d = |z − p̂| between the
    measured and the predicted position: ``w = w0 + (1 − w0)·(1 − 2^(−(d/half_weight_mm)²))``.
    A still or steadily moving finger gives small innovations (noise only), so w ≈ w0 and the
    noise is smoothed; a sudden turn or speed change gives a large one, so w → 1 and the output
    follows the measurement at once. The velocity is corrected with the alpha-beta gain of a
    steady-state Kalman filter for that weight (Benedict–Bordner, ``β = w²/(2 − w)``).

    min_cutoff_hz: sets w0 from the frame interval, w0 = dt/(dt + 1/(2π·fc)), so the smoothing
        of a still finger is the same at 30, 60 or 90 fps; range (0, 1000], default 3.0.
    half_weight_mm: innovation at which w is halfway between w0 and 1, range (0, 1000],
        default 6.0: a few times the RMS innovation of the ~1 mm touch-point noise measured on
        full depth frames, so noise alone barely raises the weight while a turn or a speed
        change (a few mm off the prediction per 30 fps frame) is followed at once. Both defaults
        were chosen on full depth frames, where lag shows as position error (docs/filters.md);
        0.25 Hz and 12 mm smooth more and suit point paths with 1-3 mm noise.
    """

    name = "adaptive"
    PARAMS = {
        "min_cutoff_hz": Param(3.0, 0.0, 1000.0),
        "half_weight_mm": Param(6.0, 0.0, 1000.0),
    }
    _FIELDS = {"v": (2,)}

    def _step(self, s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray) -> np.ndarray:
        v_col = self._COLS["v"]
        v = s[:, v_col]
        pred = s[:, 0:2] + v * dt_s[:, None]
        innov = xy - pred
        d_mm = np.hypot(innov[:, 0], innov[:, 1])
        w0 = smoothing_factor(dt_s, self.params["min_cutoff_hz"])
        w = w0 + (1.0 - w0) * (1.0 - np.exp2(-((d_mm / self.params["half_weight_mm"]) ** 2)))
        beta = w * w / (2.0 - w)
        s[:, v_col] = v + (beta / dt_s)[:, None] * innov
        return pred + w[:, None] * innov


class OneEuroFilter(FilterBase):
    """``one_euro``: the 1€ filter, per axis, as in the authors' reference implementation.

    The speed is the difference between the measurement and the previous output divided by dt,
    smoothed with cutoff d_cutoff_hz; the position is smoothed with cutoff
    ``min_cutoff_hz + beta_per_mm·|speed|`` (per axis, speed in mm/s).

    min_cutoff_hz: cutoff of a still finger in Hz, range (0, 1000], default 2.0 (tuned; lower
        removes more jitter of a still finger but delays the start of a slow stroke).
    beta_per_mm: rise of the cutoff with speed in Hz per mm/s (= 1/mm), range [0, 100],
        default 0.01: at 0.1 m/s the cutoff is 3 Hz, at 1 m/s 12 Hz, so a fast stroke is barely
        delayed; tuned on simulated paths under a one-frame lag budget.
    d_cutoff_hz: cutoff of the speed estimate in Hz, range (0, 1000], default 1.0 (the
        authors' value).
    """

    name = "one_euro"
    PARAMS = {
        "min_cutoff_hz": Param(2.0, 0.0, 1000.0),
        "beta_per_mm": Param(0.01, 0.0, 100.0, lo_open=False),
        "d_cutoff_hz": Param(1.0, 0.0, 1000.0),
    }
    _FIELDS = {"dx": (2,)}  # smoothed speed per axis, mm/s

    def _step(self, s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray) -> np.ndarray:
        dx_col = self._COLS["dx"]
        prev = s[:, 0:2]
        dt = dt_s[:, None]
        speed = (xy - prev) / dt
        edx = s[:, dx_col]
        edx = edx + smoothing_factor(dt, self.params["d_cutoff_hz"]) * (speed - edx)
        s[:, dx_col] = edx
        cutoff = self.params["min_cutoff_hz"] + self.params["beta_per_mm"] * np.abs(edx)
        return prev + smoothing_factor(dt, cutoff) * (xy - prev)


_CLASSES: dict[str, type[FilterBase]] = {
    c.name: c for c in (NoFilter, LowPassFilter, KalmanFilter, AdaptiveFilter, OneEuroFilter,
                        AdaptiveEuroFilter)
}
assert tuple(_CLASSES) == FILTERS


def filter_class(name: str) -> type[FilterBase]:
    """The class of a filter by name, or ConfigError listing the valid names."""
    try:
        return _CLASSES[name]
    except (KeyError, TypeError):
        raise ConfigError(f"unknown filter {name!r}; use one of {', '.join(FILTERS)}") from None


def default_params(name: str) -> dict[str, float]:
    """The default parameters of a filter (see each class's docstring for why)."""
    return {k: p.default for k, p in filter_class(name).PARAMS.items()}


def make_filter(cfg: FilterConfig | str, **params: float) -> FilterBase:
    """Build the filter a config names; parameters left out keep their defaults.

    ``make_filter(FilterConfig("one_euro", {"beta_per_mm": 0.01}))`` or
    ``make_filter("kalman", process_noise_mm_s2=2000)``. An unknown name, an unknown parameter or
    an out-of-range value raises ConfigError naming the valid choices or range.
    """
    if isinstance(cfg, FilterConfig):
        name, given = cfg.name, {**cfg.params, **params}
    else:
        name, given = cfg, dict(params)
    cls = filter_class(name)
    for k, v in given.items():
        if not isinstance(v, (int, float)) or isinstance(v, bool):
            raise ConfigError(f"filter.params.{k} = {v!r} must be a number")
    return cls(**given)
