"""Measuring touch path filters on the same paths: ``depthtouch bench-filters``.

The paths and their metrics are in :mod:`depthtouch.evaluation.paths`; here:
:func:`run_filter` and :func:`compare_filters` (one row of metrics per filter),
:func:`tune_filters`, :func:`bench_filters` (the command) and its report.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..errors import ConfigError, OutputError
from ..tracking.filters import DEFAULT_FILTER, FILTERS, FilterBase, default_params, make_filter
from .paths import (  # noqa: F401  (re-exported: the bench's vocabulary)
    KINDS,
    LAG_SHIFTS_MS,
    MOVING_MM_S,
    TURN_DEG,
    TURN_WINDOW_S,
    TouchPath,
    angle_error_deg,
    jitter_mm,
    lag_ms,
    moving_steps,
    overshoot_mm,
    path_metrics,
    simulate_paths,
    turn_indices,
)

#: Paper's average angle errors (Lee & Kwon 2019), for reference in tables.
PAPER_ANGLE_ERROR_DEG = {"none": 12.688, "lowpass": 10.792, "kalman": 6.937, "adaptive": 6.813}


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
