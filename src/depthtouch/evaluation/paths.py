"""Touch paths for measuring filters: true and measured paths, and their metrics.

- :class:`TouchPath`: a true path, its measurement (NaN rows = frames where the touch was missed)
  and the timestamps;
- :func:`path_metrics` (the paper's angle error, lag, overshoot of one filtered path) and
  :func:`jitter_mm` (a still finger);
- :func:`simulate_paths`: straight lines, circles, sharp zig-zags, speed changes, a still finger,
  with depth-like noise.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

KINDS: tuple[str, ...] = ("straight", "circle", "zigzag", "speed_change", "still")

#: A sample counts as moving when the true speed exceeds this (mm/s).
MOVING_MM_S = 20.0
#: Direction change over two frames that counts as a sharp turn (degrees).
TURN_DEG = 45.0
#: Window after a sharp turn in which overshoot is measured (s).
TURN_WINDOW_S = 0.3
#: Time shifts searched for the lag (ms): a filter may lead (prediction) or lag.
LAG_SHIFTS_MS = np.arange(-150.0, 400.0 + 0.5, 1.0)


@dataclass(frozen=True)
class TouchPath:
    """One touch path: timestamps (T,) s, true and measured positions (T, 2) mm.

    ``measured_xy_mm`` rows that are NaN are frames where the touch was not measured (a filter
    is not updated then). ``kind`` names the shape (for per-kind tables).
    """

    kind: str
    t_s: np.ndarray
    true_xy_mm: np.ndarray
    measured_xy_mm: np.ndarray

    def __post_init__(self) -> None:
        n = self.t_s.shape[0]
        if self.t_s.ndim != 1 or n < 2:
            raise ValueError(
                f"TouchPath.t_s: expected shape (T,) with T >= 2, got {self.t_s.shape}"
            )
        for name in ("true_xy_mm", "measured_xy_mm"):
            a = getattr(self, name)
            if a.shape != (n, 2):
                raise ValueError(f"TouchPath.{name}: expected shape ({n}, 2), got {a.shape}")


# --- metrics -----------------------------------------------------------------------------------
def _wrap_deg(a: np.ndarray) -> np.ndarray:
    return np.abs((a + 180.0) % 360.0 - 180.0)


def angle_error_deg(true_xy: np.ndarray, filtered_xy: np.ndarray, moving: np.ndarray) -> float:
    """The paper's measure: mean angle between successive displacement vectors of the filtered
    and the true path, in degrees, over steps where the true path moves (``moving``, (T-1,)).
    NaN when no step qualifies."""
    d_true = np.diff(true_xy, axis=0)
    d_filt = np.diff(filtered_xy, axis=0)
    ok = moving & np.isfinite(d_filt).all(axis=1) & (np.abs(d_filt).sum(axis=1) > 0)
    if not ok.any():
        return math.nan
    a_true = np.degrees(np.arctan2(d_true[ok, 1], d_true[ok, 0]))
    a_filt = np.degrees(np.arctan2(d_filt[ok, 1], d_filt[ok, 0]))
    return float(_wrap_deg(a_filt - a_true).mean())


def lag_ms(
    true_xy: np.ndarray, t_s: np.ndarray, filtered_xy: np.ndarray, moving: np.ndarray
) -> float:
    """Mean delay of the filtered path behind the true one while moving, in ms.

    The time shift s (−150…400 ms, 1 ms steps) that minimises the mean squared distance between
    the filtered position at t and the true position at t − s, over moving samples. The true
    path is interpolated linearly and held at its ends (before the first sample the finger was
    where it went down). Negative means the filter runs ahead (prediction). NaN when not moving.
    """
    ok = moving & np.isfinite(filtered_xy).all(axis=1)
    if ok.sum() < 2:
        return math.nan
    tq = t_s[ok][None, :] - LAG_SHIFTS_MS[:, None] / 1000.0
    err = np.zeros(tq.shape)
    for axis in (0, 1):
        err += (np.interp(tq, t_s, true_xy[:, axis]) - filtered_xy[ok, axis][None, :]) ** 2
    return float(LAG_SHIFTS_MS[int(np.argmin(err.mean(axis=1)))])


def _dist_to_polyline(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance (mm) of each point (K, 2) to the polyline (M, 2), M >= 2."""
    a, b = poly[:-1], poly[1:]
    ab = b - a
    len2 = np.maximum((ab**2).sum(axis=1), 1e-12)
    ap = points[:, None, :] - a[None, :, :]
    u = np.clip((ap * ab[None]).sum(axis=2) / len2[None], 0.0, 1.0)
    closest = a[None] + u[..., None] * ab[None]
    return np.asarray(np.sqrt(((points[:, None, :] - closest) ** 2).sum(axis=2)).min(axis=1))


def turn_indices(true_xy: np.ndarray) -> np.ndarray:
    """Samples where the true path turns by more than TURN_DEG over two frames (one per turn)."""
    d = np.diff(true_xy, axis=0)
    if d.shape[0] < 3:
        return np.zeros(0, dtype=np.intp)
    ang = np.arctan2(d[:, 1], d[:, 0])
    step = np.hypot(d[:, 0], d[:, 1]) > 1e-9
    change = _wrap_deg(np.degrees(ang[2:] - ang[:-2]))
    sharp = (change > TURN_DEG) & step[2:] & step[:-2]
    idx = np.flatnonzero(sharp) + 1  # the middle sample of the two steps
    first = np.concatenate([[True], np.diff(idx) > 2]) if idx.size else idx.astype(bool)
    return idx[first]


def overshoot_mm(true_xy: np.ndarray, t_s: np.ndarray, filtered_xy: np.ndarray) -> float:
    """Mean over sharp turns of the largest distance (mm) of the filtered path from the true
    path within TURN_WINDOW_S after the turn. NaN when the path has no sharp turn.

    A filter that carries its velocity past a corner shows here; raw measurements show their
    noise (about 2.5 RMS) as the baseline."""
    peaks = []
    for k in turn_indices(true_xy).tolist():
        t0 = t_s[k]
        win = (t_s >= t0) & (t_s <= t0 + TURN_WINDOW_S) & np.isfinite(filtered_xy).all(axis=1)
        local = (t_s >= t0 - 2 * TURN_WINDOW_S) & (t_s <= t0 + 2 * TURN_WINDOW_S)
        if win.any() and local.sum() >= 2:
            peaks.append(_dist_to_polyline(filtered_xy[win], true_xy[local]).max())
    return float(np.mean(peaks)) if peaks else math.nan


def jitter_mm(xy: np.ndarray) -> float:
    """RMS distance (mm) of positions (T, 2) from their mean: the jitter of a still finger.
    NaN rows are ignored; NaN when fewer than 2 rows remain."""
    a = np.asarray(xy, dtype=np.float64)
    a = a[np.isfinite(a).all(axis=1)]
    if a.shape[0] < 2:
        return math.nan
    return float(np.sqrt(((a - a.mean(axis=0)) ** 2).sum(axis=1).mean()))


def moving_steps(true_xy: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """(T-1,) bool: steps where the true speed exceeds MOVING_MM_S."""
    d = np.diff(true_xy, axis=0)
    dt = np.maximum(np.diff(t_s), 1e-9)
    return np.asarray(np.hypot(d[:, 0], d[:, 1]) / dt > MOVING_MM_S)


def path_metrics(true_xy: np.ndarray, t: np.ndarray, filtered_xy: np.ndarray) -> dict[str, float]:
    """Angle error (deg), lag (ms) and overshoot at sharp turns (mm) of one filtered path.

    true_xy, filtered_xy: (T, 2) mm (filtered NaN rows = not measured); t: (T,) s. Values are
    NaN where undefined (a still path has no angle error or lag; a path without turns no
    overshoot).
    """
    true_xy = np.asarray(true_xy, dtype=np.float64)
    filtered_xy = np.asarray(filtered_xy, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    if true_xy.shape != filtered_xy.shape or true_xy.shape != (t.shape[0], 2):
        raise ValueError(
            f"path_metrics: expected true_xy and filtered_xy of shape ({t.shape[0]}, 2), "
            f"got {true_xy.shape} and {filtered_xy.shape}"
        )
    steps = moving_steps(true_xy, t)
    samples = np.concatenate([[False], steps])
    return {
        "angle_error_deg": angle_error_deg(true_xy, filtered_xy, steps),
        "lag_ms": lag_ms(true_xy, t, filtered_xy, samples),
        "overshoot_mm": overshoot_mm(true_xy, t, filtered_xy),
    }


# --- simulated paths ---------------------------------------------------------------------------
def _unit(angle: float) -> np.ndarray:
    return np.array([math.cos(angle), math.sin(angle)])


def _true_path(kind: str, rng: np.random.Generator, t: np.ndarray) -> np.ndarray:
    """True positions (T, 2) mm at times t for one path shape; parameters drawn from rng."""
    p0 = rng.uniform(100.0, 500.0, 2)
    speed = float(np.exp(rng.uniform(math.log(50.0), math.log(1000.0))))  # 0.05–1 m/s
    heading = rng.uniform(0, 2 * math.pi)
    if kind == "straight":
        return p0 + np.outer(speed * t, _unit(heading))
    if kind == "circle":
        # at most 0.3 rad of turn per 30 fps frame, so the circle is drawn, not sampled away
        radius = max(rng.uniform(20.0, 150.0), speed / (30.0 * 0.3))
        omega = speed / radius * rng.choice([-1.0, 1.0])
        ang = heading + omega * t
        return p0 + radius * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    if kind == "zigzag":
        n_seg = 40
        seg_mm = rng.uniform(30.0, 120.0, n_seg)
        turns = np.radians(rng.uniform(60.0, 150.0, n_seg)) * rng.choice([-1.0, 1.0], n_seg)
        headings = heading + np.concatenate([[0.0], np.cumsum(turns[:-1])])
        verts = p0 + np.concatenate(
            [
                [[0.0, 0.0]],
                np.cumsum(
                    seg_mm[:, None] * np.stack([np.cos(headings), np.sin(headings)], axis=1), axis=0
                ),
            ]
        )
        arc = np.concatenate([[0.0], np.cumsum(seg_mm)])
        s = speed * t
        return np.stack([np.interp(s, arc, verts[:, 0]), np.interp(s, arc, verts[:, 1])], axis=1)
    if kind == "speed_change":
        # piecewise constant speed (a new one every 0.3–0.8 s), gently curving direction
        knots = np.concatenate([[0.0], np.cumsum(rng.uniform(0.3, 0.8, 20))])
        speeds = np.exp(rng.uniform(math.log(50.0), math.log(1000.0), knots.size))
        s_knots = np.concatenate([[0.0], np.cumsum(speeds[:-1] * np.diff(knots))])
        s = np.interp(t, knots, s_knots)
        curvature = rng.uniform(-1.0, 1.0) / 300.0  # rad per mm: radius >= 300 mm
        ang = heading + curvature * s
        ds = np.diff(s, prepend=0.0)
        return p0 + np.cumsum(ds[:, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1), axis=0)
    if kind == "still":
        return np.tile(p0, (t.size, 1))
    raise ConfigError(f"unknown path kind {kind!r}; use one of {', '.join(KINDS)}")


def simulate_paths(
    seed: int,
    *,
    fps_hz: float = 30.0,
    per_kind: int = 8,
    duration_s: float = 3.0,
    noise_mm: tuple[float, float] = (1.0, 3.0),
    outlier_rate: float = 0.0,
    outlier_mm: float = 15.0,
    kinds: Sequence[str] = KINDS,
) -> list[TouchPath]:
    """Seeded touch paths with depth-like noise, all sampled at the same timestamps.

    Each path gets its own noise RMS per axis drawn from ``noise_mm`` (1–3 mm: the touch point
    error of a depth camera at 0.5–1.5 m); with ``outlier_rate`` > 0 that fraction of samples is
    displaced by ``outlier_mm`` in a random direction (a mis-detected fingertip). The true path
    depends only on the seed, not on fps, so rates can be compared.
    """
    if fps_hz <= 0 or duration_s <= 0 or per_kind < 1:
        raise ConfigError("simulate_paths needs fps_hz > 0, duration_s > 0 and per_kind >= 1")
    n = int(round(duration_s * fps_hz))
    t = np.arange(n) / fps_hz
    paths = []
    for ki, kind in enumerate(kinds):
        for j in range(per_kind):
            shape_rng = np.random.default_rng([seed, ki, j, 0])
            noise_rng = np.random.default_rng([seed, ki, j, int(fps_hz * 1000)])
            true_xy = _true_path(kind, shape_rng, t)
            sigma = noise_rng.uniform(*noise_mm)
            meas = true_xy + noise_rng.normal(0.0, sigma, true_xy.shape)
            if outlier_rate > 0:
                hit = noise_rng.random(n) < outlier_rate
                ang = noise_rng.uniform(0, 2 * math.pi, n)
                meas[hit] += outlier_mm * np.stack([np.cos(ang), np.sin(ang)], axis=1)[hit]
            paths.append(TouchPath(kind, t, true_xy, meas))
    return paths
