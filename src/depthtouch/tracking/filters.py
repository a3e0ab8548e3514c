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


class AdaptiveEuroFilter(FilterBase):
    """``adaptive_euro``: the adaptive filter, then a 1€ stage on its output.

    The adaptive stage (``min_cutoff_hz``, ``half_weight_mm``, as :class:`AdaptiveFilter`) follows
    turns and speed changes at once but leaves most of a still finger's noise. The 1€ stage
    smooths its output with the cutoff ``rest_cutoff_hz + beta_per_mm·max(0, s − rest_mm_s)``,
    s the speed of the adaptive stage's output (its step per dt, as a vector low-passed at
    ``speed_cutoff_hz``, then its norm: both axes get one cutoff, so a path keeps its
    direction). Below ``rest_mm_s`` (the speed noise of a finger at rest) the cutoff stays at
    ``rest_cutoff_hz``; a drag raises it so far that the stage adds almost no lag.

    rest_cutoff_hz: cutoff of a finger at rest, range (0, 1000], default 0.3.
    rest_mm_s: speed taken as rest, range [0, 1000], default 40 mm/s.
    beta_per_mm: rise of the cutoff with speed above rest, Hz per mm/s, range [0, 100],
        default 0.2 (at 100 mm/s above rest the cutoff is 20 Hz).
    speed_cutoff_hz: cutoff of the speed estimate, range (0, 1000], default 3.0.
    hold_mm: the stage's weight rises toward 1 with the gap g between its output and the
        adaptive stage's, ``a + (1 − a)·(1 − 2^(−(g/hold_mm)²))``: a gap the noise cannot
        explain (a tip that landed off its first measurement) is closed at once; range
        (0, 1000], default 3.0 mm.
    noise_mm, noise_s: the touch's measured noise σ (mm RMS per axis, from the second
        differences of its measurements: 3.07·σ is their mean norm for white noise; each
        clipped at 3σ + 1 mm so that a jump or a turn does not inflate it), averaged over
        ``noise_s`` (default 1 s) starting from ``noise_mm`` (default 1 mm); it sets the rest
        lock's radius. (Scaling ``hold_mm`` or ``half_weight_mm`` by it was measured and left
        out: docs/filters.md.)
    The rest lock (lock_frames > 0): a finger proven still is held at the running mean of its
    measurements, ignoring one-frame jumps of its tip estimate.

    - It locks when the weighted least-squares line through its measurements (weights decaying
      by 1 − 1/lock_frames per frame: about the last ``lock_frames``, default 32, after at
      least that many) moves slower than ``lock_mm_s`` (default 5 mm/s). Noise cannot fake
      this: the line's slope is known to about ±1-2 mm/s, so a slow drag (10 mm/s and more)
      never locks and passes exactly as with the lock off.
    - The lock starts at the output so far (the 1€ stage's, or the landing's: no jump), with
      a radius of max(``lock_mm``, ``lock_sigmas``·σ) (defaults 4 mm, 3). Its mean then runs
      over the last ``lock_mean_frames`` (default 30) measurements that lie within twice the
      radius: a far outlier moves neither the output nor the mean.
    - It ends when the median of the last three measurements leaves the radius: a one-frame
      jump never ends it, a real move ends it on its second frame (then the 1€ stage, which
      ran all along, is the output again; it closes the gap at once).
    - Ranges: lock_frames [0, 10000] (0 turns the lock off, values under 2 count as 2),
      lock_mm_s (0, 10000], lock_mm (0, 1000], lock_sigmas [0, 100], lock_mean_frames
      [1, 1e6], noise_mm (0, 100], noise_s (0, 1000].
    The landing (land_frames > 0): from touch-down, a finger is taken as still until its
    measurements show that it moves, and the output is their mean (the weighted mean of the
    lock's sums). A tap at range, too short for the lock, is held from its first frame.

    - Each frame, the weighted line through the measurements gives a speed and its standard
      error (from the touch's noise σ). Its ratio z is tested from the third measurement on.
    - The output is the mean plus a·(the 1€ stage's output − the mean), with a rising from 0
      at z = ``land_blend_sigmas`` (default 1.5) to 1 at z = ``land_sigmas`` (default 6). A
      drag from touch-down leaves the mean as soon as its line is steeper than the noise.
    - It ends for good at z > ``land_sigmas`` or after ``land_frames`` (default 32)
      measurements; then the 1€ stage, which ran all along, is the output (or the lock).
    - Cost on a drag from touch-down: at most half a frame's travel on the second frame (the
      mean of two), under 1 mm more lag than without it at 10-60 mm/s.
    - Ranges: land_frames [0, 10000] (0 turns it off), land_blend_sigmas [0, 100],
      land_sigmas (0, 100].
    Defaults chosen by measurement (docs/filters.md).
    """

    name = "adaptive_euro"
    PARAMS = {
        "min_cutoff_hz": Param(3.0, 0.0, 1000.0),
        "half_weight_mm": Param(6.0, 0.0, 1000.0),
        "rest_cutoff_hz": Param(0.3, 0.0, 1000.0),
        "rest_mm_s": Param(40.0, 0.0, 1000.0, lo_open=False),
        "beta_per_mm": Param(0.2, 0.0, 100.0, lo_open=False),
        "speed_cutoff_hz": Param(3.0, 0.0, 1000.0),
        "hold_mm": Param(3.0, 0.0, 1000.0),
        "lock_mm": Param(4.0, 0.0, 1000.0),
        "lock_frames": Param(32.0, 0.0, 10000.0, lo_open=False),
        "lock_mean_frames": Param(30.0, 1.0, 1e6, lo_open=False),
        "lock_mm_s": Param(5.0, 0.0, 10000.0),
        "lock_sigmas": Param(3.0, 0.0, 100.0, lo_open=False),
        "noise_mm": Param(1.0, 0.0, 100.0),
        "noise_s": Param(1.0, 0.0, 1000.0),
        "land_frames": Param(32.0, 0.0, 10000.0, lo_open=False),
        "land_blend_sigmas": Param(1.5, 0.0, 100.0, lo_open=False),
        "land_sigmas": Param(6.0, 0.0, 100.0),
    }
    # the adaptive stage's position (mm) and velocity (mm/s); the smoothed speed vector (mm/s);
    # the 1€ stage's output (mm); the noise: the last two measurements (mm), how many were seen,
    # the noise estimate (mm RMS per axis); the stillness test: exponentially weighted sums of
    # the measurements over time (weight, Σt, Σt², Σx, Σtx; t in s relative to the last update);
    # the lock: its mean (mm), its frame count (0 = not locked), its squared radius (mm²)
    _FIELDS = {"p": (2,), "v": (2,), "dx": (2,), "e": (2,), "z1": (2,), "z2": (2,), "nz": (1,),
               "sd": (1,), "q0": (1,), "qt": (1,), "qtt": (1,), "qx": (2,), "qtx": (2,),
               "m": (2,), "n": (1,), "r2": (1,), "land": (1,)}

    def _init(self, rows: np.ndarray, xy: np.ndarray) -> None:
        st = self._state
        for k in ("v", "dx", "qt", "qtt", "qtx", "m", "n", "r2"):
            st[k][rows] = 0.0
        for k in ("p", "e", "z1", "z2", "qx"):
            st[k][rows] = xy
        st["nz"][rows] = 1.0
        st["q0"][rows] = 1.0
        st["sd"][rows] = self.params["noise_mm"]
        st["land"][rows] = 1.0 if self.params["land_frames"] > 0 else 0.0

    def _step(self, s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray) -> np.ndarray:
        p_col, v_col, dx_col = self._COLS["p"], self._COLS["v"], self._COLS["dx"]
        prm = self.params
        v, p_old = s[:, v_col], s[:, p_col]
        pred = p_old + v * dt_s[:, None]
        innov = xy - pred
        d_mm = np.hypot(innov[:, 0], innov[:, 1])
        w0 = smoothing_factor(dt_s, prm["min_cutoff_hz"])
        w = w0 + (1.0 - w0) * (1.0 - np.exp2(-((d_mm / prm["half_weight_mm"]) ** 2)))
        beta = w * w / (2.0 - w)
        p = pred + w[:, None] * innov
        dt = dt_s[:, None]
        dx = s[:, dx_col]
        dx = dx + smoothing_factor(dt, prm["speed_cutoff_hz"]) * ((p - p_old) / dt - dx)
        s[:, v_col] = v + (beta / dt_s)[:, None] * innov
        s[:, p_col], s[:, dx_col] = p, dx
        speed = np.hypot(dx[:, 0], dx[:, 1])
        cutoff = prm["rest_cutoff_hz"] + prm["beta_per_mm"] * np.maximum(0.0, speed - prm["rest_mm_s"])
        e_col = self._COLS["e"]
        prev = s[:, e_col]
        gap = p - prev
        a = smoothing_factor(dt_s, cutoff)
        # a gap the noise cannot explain (a tip that landed off its first measurement, a start)
        # is closed at once, as the adaptive stage's weight does
        a = a + (1.0 - a) * (1.0 - np.exp2(-((np.hypot(gap[:, 0], gap[:, 1]) / prm["hold_mm"]) ** 2)))
        e = prev + a[:, None] * gap
        s[:, e_col] = e
        if prm["lock_frames"] <= 0 and prm["land_frames"] <= 0:
            return e
        sd, med = self._recent(s, xy, dt_s)
        return self._lock(s, xy, e, dt_s, sd, med)

    def _recent(self, s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """The touch's measurement noise (mm RMS per axis, from the second differences of its
        measurements) and the median of its last three measurements, with this one."""
        c = self._COLS
        prm = self.params
        z1, z2 = s[:, c["z1"]], s[:, c["z2"]]
        sd, nz = s[:, c["sd"]][:, 0], s[:, c["nz"]][:, 0]
        # white noise of sd per axis gives second differences of RMS sqrt(6)·sd per axis, a
        # mean norm of 3.07·sd; a jump or a turn is clipped so that one does not inflate it
        dd = xy - 2.0 * z1 + z2
        est = np.minimum(np.hypot(dd[:, 0], dd[:, 1]) / 3.07, 3.0 * sd + 1.0)
        rate = np.maximum(1.0 / np.maximum(nz - 1.0, 1.0),
                          smoothing_factor(dt_s, 1.0 / (2.0 * np.pi * prm["noise_s"])))
        sd = np.where(nz >= 2.0, sd + rate * (est - sd), sd)
        med = np.maximum(np.minimum(xy, z1), np.minimum(np.maximum(xy, z1), z2))
        med = np.where((nz >= 2.0)[:, None], med, xy)
        s[:, c["z2"]], s[:, c["z1"]] = z1, xy
        s[:, c["sd"]], s[:, c["nz"]] = sd[:, None], (nz + 1.0)[:, None]
        return sd, med

    def _landing(self, s: np.ndarray, e: np.ndarray, land: np.ndarray, seen: np.ndarray,
                 speed: np.ndarray, speed_sd: np.ndarray, mean: np.ndarray) -> np.ndarray:
        """The landing (see the class doc): updates its flag, returns the output. ``speed``:
        the weighted line's speed (mm/s) and ``speed_sd`` its standard error; ``mean``: the
        weighted mean of the measurements."""
        prm = self.params
        z = np.where(seen < 2.0, 0.0, speed / np.maximum(speed_sd, 1e-12))
        lo, hi = prm["land_blend_sigmas"], prm["land_sigmas"]
        a = np.clip((z - lo) / max(hi - lo, 1e-9), 0.0, 1.0)
        land = land & (seen <= prm["land_frames"]) & (z <= hi)
        s[:, self._COLS["land"]] = land[:, None]
        return np.where(land[:, None], mean + a[:, None] * (e - mean), e)

    def _lock(self, s: np.ndarray, xy: np.ndarray, e: np.ndarray, dt_s: np.ndarray,
              sd: np.ndarray, med: np.ndarray) -> np.ndarray:
        """The lock of a finger at rest (see the class doc): updates its fields, returns the
        output."""
        c = self._COLS
        prm = self.params
        lock_frames = max(prm["lock_frames"], 2.0)  # a line needs two points
        # the sums' horizon (the landing reads them too)
        frames = max(lock_frames, prm["land_frames"])
        # stillness: the weighted least-squares line through the measurements (weights
        # decaying by 1 - 1/frames per frame; sums kept about the current time, so old times
        # shift by -dt) is slower than lock_mm_s
        q0, qt, qtt = s[:, c["q0"]][:, 0], s[:, c["qt"]][:, 0], s[:, c["qtt"]][:, 0]
        qx, qtx = s[:, c["qx"]], s[:, c["qtx"]]
        keep = 1.0 - 1.0 / frames
        qtt = (qtt - 2.0 * dt_s * qt + dt_s * dt_s * q0) * keep
        qtx = (qtx - dt_s[:, None] * qx) * keep
        qt = (qt - dt_s * q0) * keep
        q0 = q0 * keep + 1.0
        qx = qx * keep + xy
        s[:, c["q0"]], s[:, c["qt"]], s[:, c["qtt"]] = q0[:, None], qt[:, None], qtt[:, None]
        s[:, c["qx"]], s[:, c["qtx"]] = qx, qtx
        den = np.maximum(q0 * qtt - qt * qt, 1e-12)
        slope = (q0[:, None] * qtx - qt[:, None] * qx) / den[:, None]
        seen = s[:, c["nz"]][:, 0] - 1.0  # measurements so far, this one included
        speed = np.hypot(slope[:, 0], slope[:, 1])
        still = (seen >= lock_frames) & (speed <= prm["lock_mm_s"]) & (prm["lock_frames"] > 0)
        land = s[:, c["land"]][:, 0] > 0
        if land.any():
            e = self._landing(s, e, land, seen, speed, sd * np.sqrt(q0 / den), qx / q0[:, None])
        # a lock holds while the median of the last three measurements (a one-frame jump does
        # not move it) stays within its radius
        m, n, r2 = s[:, c["m"]], s[:, c["n"]][:, 0], s[:, c["r2"]][:, 0]
        stay = (n > 0) & (np.sum((med - m) ** 2, axis=1) <= r2)
        # its mean runs over the rest (the last lock_mean_frames), fed only by measurements
        # within twice its radius: a far outlier changes neither output nor mean (a nearer one
        # moves the mean by 1/n of its distance; leaving those out too measured worse, as they
        # are much of a noisy camera's spread)
        near = stay & (np.sum((xy - m) ** 2, axis=1) <= 4.0 * r2)
        n = np.where(near, np.minimum(n + 1.0, prm["lock_mean_frames"]), n)
        m = np.where(near[:, None], m + (xy - m) / np.maximum(n, 1.0)[:, None], m)
        # a new lock starts from the output so far (the 1€ stage's, or the landing's mean: no
        # jump), counted as lock_frames frames of mean (at most lock_mean_frames); its radius
        # follows the touch's noise
        enter = (n <= 0) & still
        m = np.where(enter[:, None], e, m)
        r2 = np.where(enter, np.maximum(prm["lock_mm"], prm["lock_sigmas"] * sd) ** 2, r2)
        n = np.where(enter, min(lock_frames, prm["lock_mean_frames"]), np.where(stay, n, 0.0))
        s[:, c["m"]] = m
        s[:, c["n"]], s[:, c["r2"]] = n[:, None], r2[:, None]
        return np.where((n > 0)[:, None], m, e)


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
