"""Measuring touch path filters: simulated paths, the paper's angle error, lag, jitter, overshoot.

Reusable pieces for any source of paths (simulated here, or the simulator's rendered drags
through ``depthtouch eval``):

- :class:`TouchPath`: a true path, its measurement (NaN rows = frames where the touch was missed)
  and the timestamps;
- :func:`path_metrics` (angle error, lag, overshoot of one filtered path) and :func:`jitter_mm`;
- :func:`run_filter` and :func:`compare_filters` (one row of metrics per filter);
- :func:`simulate_paths` (straight lines, circles, sharp zig-zags, speed changes, a still
  finger, with depth-like noise), :func:`tune_filters` and :func:`bench_filters` (the
  ``depthtouch bench-filters`` command).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError, OutputError
from ..tracking.filters import DEFAULT_FILTER, FILTERS, FilterBase, default_params, make_filter

#: Paper's average angle errors (Lee & Kwon 2019), for reference in tables.
PAPER_ANGLE_ERROR_DEG = {"none": 12.688, "lowpass": 10.792, "kalman": 6.937, "adaptive": 6.813}

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


# --- running filters ---------------------------------------------------------------------------
def run_filter(filt: FilterBase, paths: Sequence[TouchPath]) -> list[np.ndarray]:
    """Filter every path (each its own touch id); returns filtered (T, 2) arrays, NaN where the
    path was not measured. Paths with identical timestamps run together, one update per frame
    for all of them; the filter is reset before and after."""
    out: list[np.ndarray] = [np.full(p.measured_xy_mm.shape, np.nan) for p in paths]
    groups: dict[bytes, list[int]] = {}
    for i, p in enumerate(paths):
        groups.setdefault(np.ascontiguousarray(p.t_s, dtype=np.float64).tobytes(), []).append(i)
    for members in groups.values():
        filt.reset()
        t_s = paths[members[0]].t_s
        meas = np.stack([paths[i].measured_xy_mm for i in members])  # (P, T, 2)
        ids = np.arange(len(members), dtype=np.int64)
        res = np.full(meas.shape, np.nan)
        for k in range(t_s.shape[0]):
            seen = np.isfinite(meas[:, k]).all(axis=1)
            res[seen, k] = filt.update(ids[seen], meas[seen, k], float(t_s[k]))
        for j, i in enumerate(members):
            out[i] = res[j]
    filt.reset()
    return out


def _nanmean(values: list[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.mean(finite)) if finite else math.nan


def evaluate(filt: FilterBase, paths: Sequence[TouchPath]) -> dict[str, Any]:
    """Metrics of one filter over paths: means over the paths where each metric is defined
    (jitter over still paths, overshoot over paths with sharp turns), and per-kind angle error."""
    filtered = run_filter(filt, paths)
    per = [path_metrics(p.true_xy_mm, p.t_s, f) for p, f in zip(paths, filtered, strict=True)]
    still = [
        jitter_mm(f)
        for p, f in zip(paths, filtered, strict=True)
        if not moving_steps(p.true_xy_mm, p.t_s).any()
    ]
    kinds = sorted({p.kind for p in paths})
    return {
        "filter": filt.name,
        "params": dict(filt.params),
        "angle_error_deg": _nanmean([m["angle_error_deg"] for m in per]),
        "lag_ms": _nanmean([m["lag_ms"] for m in per]),
        "jitter_mm": _nanmean(still),
        "overshoot_mm": _nanmean([m["overshoot_mm"] for m in per]),
        "angle_error_by_kind": {
            k: _nanmean(
                [m["angle_error_deg"] for p, m in zip(paths, per, strict=True) if p.kind == k]
            )
            for k in kinds
        },
    }


def compare_filters(
    paths: Sequence[TouchPath],
    filters: Mapping[str, Mapping[str, float]] | Sequence[str] | None = None,
) -> list[dict[str, Any]]:
    """One row of metrics per filter on the same paths (see :func:`evaluate` for the fields).

    filters: names (default parameters), or name -> parameters; default: all of FILTERS.
    """
    if filters is None:
        filters = FILTERS
    spec = dict(filters) if isinstance(filters, Mapping) else {n: {} for n in filters}
    return [evaluate(make_filter(name, **params), paths) for name, params in spec.items()]


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


# --- tuning and the benchmark ------------------------------------------------------------------
#: Parameter grids searched by :func:`tune_filters` (the free parameters of each filter; the
#: camera-given ones, like the Kalman measurement noise, stay at their physical values).
TUNE_GRIDS: dict[str, dict[str, tuple[float, ...]]] = {
    "none": {},
    "lowpass": {"cutoff_hz": (1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 12.0)},
    "kalman": {"process_noise_mm_s2": (100.0, 200.0, 500.0, 1000.0, 2000.0, 5000.0, 10000.0)},
    "adaptive": {
        "min_cutoff_hz": (0.25, 0.5, 1.0, 2.0, 3.0),
        "half_weight_mm": (4.5, 6.0, 9.0, 12.0, 18.0, 24.0),
    },
    "one_euro": {
        "min_cutoff_hz": (0.25, 0.5, 1.0, 2.0, 3.0),
        "beta_per_mm": (0.003, 0.005, 0.01, 0.02, 0.04),
    },
}

#: Seeds of the tuning set; the benchmark's default measurement seed is different.
TUNE_SEED = 1000
BENCH_SEED = 1


def _grid(grid: Mapping[str, Sequence[float]]) -> list[dict[str, float]]:
    combos: list[dict[str, float]] = [{}]
    for name, values in grid.items():
        combos = [{**c, name: float(v)} for c in combos for v in values]
    return combos


def tune_filters(
    paths: Sequence[TouchPath],
    *,
    max_added_lag_ms: float,
    grids: Mapping[str, Mapping[str, Sequence[float]]] = TUNE_GRIDS,
) -> dict[str, dict[str, float]]:
    """Per filter, the grid point with the lowest angle error whose lag exceeds the raw path's
    by at most ``max_added_lag_ms`` (e.g. one frame). Returns name -> parameters (the
    defaults for a filter without a grid or without any point inside the lag budget)."""
    raw_lag = evaluate(make_filter("none"), paths)["lag_ms"]
    best: dict[str, dict[str, float]] = {}
    for name, grid in grids.items():
        chosen, score = default_params(name), math.inf
        for params in _grid(grid):
            row = evaluate(make_filter(name, **params), paths)
            if row["lag_ms"] - raw_lag <= max_added_lag_ms and row["angle_error_deg"] < score:
                chosen, score = {**default_params(name), **params}, row["angle_error_deg"]
        best[name] = chosen
    return best


def meets_default_bar(row: Mapping[str, Any], raw: Mapping[str, Any], fps_hz: float) -> bool:
    """The bar for the default filter: lower angle error and jitter than raw, and no more than
    one frame of added lag."""
    return bool(
        row["angle_error_deg"] < raw["angle_error_deg"]
        and row["jitter_mm"] < raw["jitter_mm"]
        and row["lag_ms"] - raw["lag_ms"] <= 1000.0 / fps_hz
    )


def choose_default(rows: Sequence[Mapping[str, Any]], fps_hz: float) -> str | None:
    """The filter with the lowest angle error among those meeting :func:`meets_default_bar`."""
    raw = next(r for r in rows if r["filter"] == "none")
    ok = [r for r in rows if r["filter"] != "none" and meets_default_bar(r, raw, fps_hz)]
    return min(ok, key=lambda r: r["angle_error_deg"])["filter"] if ok else None


def bench_filters(
    seed: int = BENCH_SEED,
    *,
    fps_list: Sequence[float] = (30.0, 60.0, 90.0),
    per_kind: int = 8,
    outlier_rate: float = 0.02,
    tune: bool = False,
) -> dict[str, Any]:
    """The ``bench-filters`` measurement: every filter on the same simulated paths.

    Rows at each frame rate for clean noise (1–3 mm RMS) and, at the first rate, with
    ``outlier_rate`` outliers. With ``tune``, the parameters are first re-tuned on the tuning
    seed set (a one-frame lag budget at the first rate) and the tuned values are measured;
    otherwise the shipped defaults are. ``default`` is the filter :func:`choose_default` picks
    at the first rate, ``shipped_default`` the one filters.py ships.
    """
    if not fps_list:
        raise ConfigError("bench_filters needs at least one frame rate")
    fps0 = float(fps_list[0])
    if tune:
        tune_paths = simulate_paths(TUNE_SEED, fps_hz=fps0, per_kind=per_kind)
        params = tune_filters(tune_paths, max_added_lag_ms=1000.0 / fps0)
    else:
        params = {name: default_params(name) for name in FILTERS}
    if seed == TUNE_SEED and tune:
        raise ConfigError(f"seed {seed} is the tuning seed; measure on another seed")
    by_fps = {}
    for fps in fps_list:
        paths = simulate_paths(seed, fps_hz=float(fps), per_kind=per_kind)
        by_fps[f"{float(fps):g}"] = compare_filters(paths, params)
    outlier_paths = simulate_paths(seed, fps_hz=fps0, per_kind=per_kind, outlier_rate=outlier_rate)
    rows0 = by_fps[f"{fps0:g}"]
    return {
        "seed": seed,
        "tuned": tune,
        "fps_hz": fps0,
        "paths_per_kind": per_kind,
        "noise_mm": [1.0, 3.0],
        "outlier_rate": outlier_rate,
        "params": params,
        "rows": rows0,
        "by_fps": by_fps,
        "with_outliers": compare_filters(outlier_paths, params),
        "paper_angle_error_deg": PAPER_ANGLE_ERROR_DEG,
        "default": choose_default(rows0, fps0),
        "shipped_default": DEFAULT_FILTER,
    }


# --- reporting ---------------------------------------------------------------------------------
def _fmt(v: float, digits: int) -> str:
    return "–" if not math.isfinite(v) else f"{v:.{digits}f}"


def format_table(result: Mapping[str, Any]) -> str:
    """A Markdown table of :func:`bench_filters` results (main rate, with the other rates' angle
    errors and the outlier run's angle error and jitter as extra columns)."""
    fps0 = result["fps_hz"]
    others = [k for k in result["by_fps"] if k != f"{fps0:g}"]
    head = ["filter", "angle error °", "paper °", "lag ms", "jitter mm", "overshoot mm"]
    head += [f"angle ° @{k} fps" for k in others] + ["angle ° / jitter mm, outliers"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for i, r in enumerate(result["rows"]):
        name = r["filter"]
        paper = result["paper_angle_error_deg"].get(name, math.nan)
        cells = [
            name + (" (default)" if name == result["shipped_default"] else ""),
            _fmt(r["angle_error_deg"], 2),
            _fmt(paper, 3),
            _fmt(r["lag_ms"], 1),
            _fmt(r["jitter_mm"], 2),
            _fmt(r["overshoot_mm"], 2),
        ]
        cells += [_fmt(result["by_fps"][k][i]["angle_error_deg"], 2) for k in others]
        o = result["with_outliers"][i]
        cells.append(f"{_fmt(o['angle_error_deg'], 2)} / {_fmt(o['jitter_mm'], 2)}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def describe(result: Mapping[str, Any]) -> str:
    """The text report of ``depthtouch bench-filters``."""
    fps0 = result["fps_hz"]
    params = "\n".join(
        f"  {n}: " + (", ".join(f"{k}={v:g}" for k, v in p.items()) or "-")
        for n, p in result["params"].items()
    )
    return (
        f"touch path filters on simulated paths (seed {result['seed']}, "
        f"{result['paths_per_kind']} paths per kind, {fps0:g} fps, noise 1-3 mm RMS; outlier "
        f"column: {result['outlier_rate']:.0%} outliers)\n\n{format_table(result)}\n\n"
        f"parameters ({'tuned now' if result['tuned'] else 'shipped defaults'}):\n{params}\n"
        f"best by measurement: {result['default']}; shipped default: {result['shipped_default']}"
    )


def write_figure(path: str, seed: int = BENCH_SEED, *, fps_hz: float = 30.0) -> None:
    """Plot a zig-zag and a circle: the true path, the raw measurement and each filter's output
    (defaults), one panel per filter, to a PNG file."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # the zig-zag with the most turns, and one loop of a circle, so each panel stays readable
    zigs = simulate_paths(seed, fps_hz=fps_hz, per_kind=8, kinds=("zigzag",), duration_s=1.5)
    zig = max(zigs, key=lambda p: len(turn_indices(p.true_xy_mm)))
    c = simulate_paths(seed, fps_hz=fps_hz, per_kind=1, kinds=("circle",), duration_s=3.0)[0]
    heading = np.unwrap(np.arctan2(*np.diff(c.true_xy_mm, axis=0).T[::-1]))
    n = max(3, int(np.searchsorted(np.abs(heading - heading[0]), 2 * math.pi)) + 2)
    circ = TouchPath("circle", c.t_s[:n], c.true_xy_mm[:n], c.measured_xy_mm[:n])
    names = [n for n in FILTERS if n != "none"]
    fig, axes = plt.subplots(2, len(names), figsize=(4.0 * len(names), 8.0))
    for row, p in enumerate((zig, circ)):
        for col, name in enumerate(names):
            ax = axes[row, col]
            out = run_filter(make_filter(name), [p])[0]
            m = path_metrics(p.true_xy_mm, p.t_s, out)
            ax.plot(*p.true_xy_mm.T, "k-", lw=2, label="true")
            ax.plot(*p.measured_xy_mm.T, ".", color="0.6", ms=4, label="raw")
            ax.plot(*out.T, "-o", color="C3", ms=2.5, lw=1.2, label=name)
            ax.set_title(f"{name}: {m['angle_error_deg']:.1f}°, lag {m['lag_ms']:.0f} ms")
            ax.set_aspect("equal")
            ax.tick_params(labelsize=7)
            if row == 0 and col == 0:
                ax.legend(fontsize=8)
    fig.suptitle(f"touch path filters at {fps_hz:g} fps (mm; angle error per path)")
    fig.tight_layout()
    try:
        fig.savefig(path, dpi=80)
    except OSError as e:
        raise OutputError(f"cannot write figure {path}: {e.strerror}; pick a writable path") from e
    finally:
        plt.close(fig)


def to_json(result: Mapping[str, Any]) -> str:
    """Results as strict JSON (undefined metrics, NaN, become null)."""

    def clean(v: Any) -> Any:
        if isinstance(v, float):
            return v if math.isfinite(v) else None
        if isinstance(v, Mapping):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        return v

    return json.dumps(clean(result), indent=1, allow_nan=False)
