"""Accuracy tables (terminal, HTML, Markdown), figures, and the demo report.

``depthtouch demo --out demo-report`` (:func:`run_demo`) renders simulator scenes, runs the sensor
on them, evaluates against the ground truth and writes ``index.html`` with PNG frames (height
map above the surface with the touch points), the touch paths over the truth, and the accuracy
table. matplotlib is imported lazily with the Agg backend (no display needed).
"""

from __future__ import annotations

import html
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import OutputError
from ..types import FrameResult, TouchEvent
from .metrics import EvalResult, Truth, evaluate
from .summary import Metrics, summarize

if TYPE_CHECKING:
    from rich.table import Table

# (key, header, format) of the table columns; keys are Metrics fields or computed below
COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("recordings", "recs", "{:d}"),
    ("contacts", "contacts", "{:d}"),
    ("occluded_contacts", "hidden", "{:d}"),
    ("contact_recall", "recall", "{:.3f}"),
    ("frame_recall", "frame rec", "{:.3f}"),
    ("false_touches", "false", "{:d}"),
    ("false_per_min", "false/min", "{:.1f}"),
    ("hover_ge25", "hover>=25", "{:d}"),
    ("error_median_mm", "err med mm", "{:.2f}"),
    ("error_p95_mm", "err p95 mm", "{:.2f}"),
    ("id_switches", "id sw", "{:d}"),
    ("down_latency_median_frames", "down lat", "{:.1f}"),
    ("lift_latency_median_frames", "lift lat", "{:.1f}"),
    ("angle_error_deg", "angle deg", "{:.1f}"),
    ("jitter_rms_mm", "jitter mm", "{:.2f}"),
    ("ms_per_frame_median", "ms/frame", "{:.1f}"),
)


def _value(m: Metrics, key: str) -> Any:
    if key == "hover_ge25":
        return m.false_from_hover_at_least(25.0)
    return getattr(m, key)


def _fmt(v: Any, fmt: str) -> str:
    if isinstance(v, float) and not math.isfinite(v):
        return "-"
    return fmt.format(v)


def table_rows(metrics: Mapping[str, Metrics]) -> list[list[str]]:
    """One row of formatted cells per entry (name first), in COLUMNS order."""
    return [[name, *(_fmt(_value(m, k), f) for k, _, f in COLUMNS)] for name, m in metrics.items()]


def metrics_table(metrics: Mapping[str, Metrics], title: str = "accuracy") -> Table:
    """A rich table of metrics, one row per entry."""
    from rich.table import Table

    t = Table(title=title, header_style="bold")
    t.add_column("case")
    for _, head, _ in COLUMNS:
        t.add_column(head, justify="right")
    for row in table_rows(metrics):
        t.add_row(*row)
    return t


def metrics_markdown(metrics: Mapping[str, Metrics], first: str = "case") -> str:
    """A Markdown table of metrics."""
    heads = [first, *(h for _, h, _ in COLUMNS)]
    lines = ["| " + " | ".join(heads) + " |", "|" + "---|" * len(heads)]
    lines += ["| " + " | ".join(r) + " |" for r in table_rows(metrics)]
    return "\n".join(lines)


def metrics_html(metrics: Mapping[str, Metrics], first: str = "case") -> str:
    """An HTML table of metrics."""
    heads = "".join(f"<th>{html.escape(h)}</th>" for h in (first, *(h for _, h, _ in COLUMNS)))
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>"
        for r in table_rows(metrics)
    )
    return f"<table><thead><tr>{heads}</tr></thead><tbody>{body}</tbody></table>"


# --- figures -------------------------------------------------------------------------------------
def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_height_map(
    height_mm: np.ndarray,
    path: str | Path,
    *,
    touches_xy: np.ndarray | None = None,
    truth_xy: np.ndarray | None = None,
    title: str = "",
    max_mm: float = 60.0,
) -> Path:
    """Height above the surface (mm, NaN = unknown) as an image, with reported touches (x) and
    true contacts (o) on top; saved as PNG."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.8), dpi=100)
    im = ax.imshow(np.clip(height_mm, -5.0, max_mm), cmap="magma", vmin=-5.0, vmax=max_mm)
    fig.colorbar(im, ax=ax, label="height above surface (mm)", shrink=0.8)
    if truth_xy is not None and len(truth_xy):
        ax.scatter(truth_xy[:, 0], truth_xy[:, 1], s=80, facecolors="none", edgecolors="cyan",
                   linewidths=1.5, label="true contact")
    if touches_xy is not None and len(touches_xy):
        ax.scatter(touches_xy[:, 0], touches_xy[:, 1], s=40, marker="x", c="lime",
                   label="reported touch")
    if (truth_xy is not None and len(truth_xy)) or (touches_xy is not None and len(touches_xy)):
        ax.legend(loc="lower right", fontsize=8)
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px)")
    return _save(fig, plt, path)


def plot_depth(depth_mm: np.ndarray, path: str | Path, *, title: str = "") -> Path:
    """A raw depth frame (mm; 0 = missing, shown black) as a PNG."""
    plt = _plt()
    d = np.where(depth_mm > 0, depth_mm, np.nan).astype(np.float32)
    fig, ax = plt.subplots(figsize=(6.4, 4.8), dpi=100)
    finite = d[np.isfinite(d)]
    lo, hi = (np.percentile(finite, [1, 99]) if finite.size else (0.0, 1.0))
    cmap = plt.get_cmap("viridis").with_extremes(bad="black")
    im = ax.imshow(d, cmap=cmap, vmin=lo, vmax=hi)
    fig.colorbar(im, ax=ax, label="depth (mm)", shrink=0.8)
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px)")
    return _save(fig, plt, path)


def plot_paths(
    truth: Truth, events: Sequence[TouchEvent], path: str | Path, *, title: str = ""
) -> Path:
    """Reported touch paths (coloured per id) over the true contact paths (grey), image px."""
    plt = _plt()
    w, h = _resolution(truth)
    fig, ax = plt.subplots(figsize=(6.4, 4.8), dpi=100)
    for cid in np.unique(truth.contact_id):
        sel = truth.contact_id == cid
        xy = truth.contact_xy_px[sel]
        ax.plot(xy[:, 0], xy[:, 1], "-", color="0.6", lw=4, alpha=0.6, solid_capstyle="round")
    by_id: dict[int, list[tuple[float, float]]] = {}
    for e in events:
        if e.state != "up":
            by_id.setdefault(e.id, []).append((e.x, e.y))
    cmap = plt.get_cmap("tab10")
    for k, (_rid, pts) in enumerate(sorted(by_id.items())):
        a = np.asarray(pts)
        ax.plot(a[:, 0], a[:, 1], ".-", color=cmap(k % 10), lw=1, ms=2)
    ax.plot([], [], "-", color="0.6", lw=4, label="truth")
    ax.plot([], [], ".-", color=cmap(0), lw=1, label="reported (one colour per id)")
    # zoom on where the touches are (with a margin), inside the image
    arrays = [truth.contact_xy_px.reshape(-1, 2)]
    arrays += [np.asarray(v, dtype=np.float64).reshape(-1, 2) for v in by_id.values()]
    allp = np.concatenate(arrays)
    if allp.size:
        lo = np.maximum(allp.min(axis=0) - 40.0, 0.0)
        hi = np.minimum(allp.max(axis=0) + 40.0, [w, h])
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(hi[1], lo[1])
    else:
        ax.set_xlim(0, w)
        ax.set_ylim(h, 0)
    ax.set_aspect("equal")
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px)")
    return _save(fig, plt, path)


def plot_xy(
    series: Mapping[str, tuple[Sequence[float], Sequence[float]]],
    path: str | Path,
    *,
    xlabel: str,
    ylabel: str,
    title: str = "",
    hline: float | None = None,
) -> Path:
    """Line plot of named (x, y) series (used by the experiments)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.6, 3.6), dpi=100)
    for name, (x, y) in series.items():
        ax.plot(x, y, "o-", label=name, ms=4)
    if hline is not None:
        ax.axhline(hline, color="0.5", ls="--", lw=1)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, plt, path)


def _resolution(truth: Truth) -> tuple[int, int]:
    cam = truth.meta.get("camera", {})
    wh = cam.get("resolution_wh") if isinstance(cam, dict) else None
    if isinstance(wh, list) and len(wh) == 2:
        return int(wh[0]), int(wh[1])
    return int(round(2 * truth.K[0, 2])), int(round(2 * truth.K[1, 2]))


def _save(fig: Any, plt: Any, path: str | Path) -> Path:
    p = Path(path)
    fig.tight_layout()
    fig.savefig(p)
    plt.close(fig)
    return p


# --- demo ----------------------------------------------------------------------------------------
DEMO_SCENES = ("multitouch", "drags", "taps", "hover")


@dataclass(frozen=True)
class DemoResult:
    """What the demo wrote: the report page, the metrics per scene and overall."""

    index: Path
    metrics: dict[str, Metrics]
    seconds: float


def _run_scene(
    scene: str, camera: str, distance_m: float, seed: int, out: Path, config: Any
) -> tuple[EvalResult, list[TouchEvent], Truth, str]:
    from ..driver import drive
    from ..outputs.jsonl import JsonlSink
    from ..pipeline import Pipeline
    from ..sim import render_scene
    from ..sources.base import ArraySource
    from .metrics import truth_from_dict
    from .suiterun import EventCollector

    rec = render_scene(scene, camera=camera, distance_m=distance_m, seed=seed)
    truth = truth_from_dict(rec.truth, f"{scene} truth")
    pipe = Pipeline(config)
    # the frame with the most true contacts (then the latest) is shown as the height map
    counts = np.bincount(truth.contact_frame, minlength=truth.n_frames)
    busiest = np.flatnonzero(counts == counts.max())
    show = int(busiest[len(busiest) // 2])
    seen: dict[str, Any] = {}

    def keep_shown(result: FrameResult) -> None:
        if result.frame.index == show and result.status != "ended":
            seen["height"] = result.height_map_mm()
            seen["touches"] = [e for e in result.events if e.state != "up"]

    collect = EventCollector()
    with JsonlSink(out / f"{scene}.events.jsonl") as sink:
        stats = drive(ArraySource.of_recording(rec, scene), pipe, [collect, sink],
                      on_result=keep_shown)
    events, timing = collect.events, stats.ms_per_frame
    height, shown = seen.get("height"), seen.get("touches", [])
    res = evaluate(truth, events, timing_ms=timing, label=scene,
                   settle_frames=pipe.config.tracking.down_frames)
    plot_depth(rec.depth[show].astype(np.float32) * (rec.depth_scale_m * 1000.0),
               out / f"{scene}-depth.png", title=f"{scene}: depth frame {show} (input)")
    if height is not None:
        sel = truth.contact_frame == show
        plot_height_map(
            height, out / f"{scene}-height.png",
            touches_xy=np.array([[e.x, e.y] for e in shown]).reshape(-1, 2),
            truth_xy=truth.contact_xy_px[sel],
            title=f"{scene}: height above the surface, frame {show}",
        )
    plot_paths(truth, events, out / f"{scene}-paths.png",
               title=f"{scene}: reported touch paths over the truth")
    return res, events, truth, f"{camera} at {distance_m:g} m, seed {seed}"


def run_demo(
    out: str | Path,
    *,
    scenes: Sequence[str] = DEMO_SCENES,
    camera: str = "kinect-v2",
    distance_m: float = 1.0,
    seed: int = 1,
    config: Any = None,
    progress: Callable[[str], None] | None = None,
) -> DemoResult:
    """Render ``scenes``, run the sensor, evaluate, and write ``out/index.html`` with figures."""
    t0 = time.perf_counter()
    root = Path(out)
    if root.exists() and not root.is_dir():
        raise OutputError(f"{root}: exists and is not a folder; choose another --out")
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputError(f"{root}: cannot create the report folder ({e.strerror})") from e
    metrics: dict[str, Metrics] = {}
    results: list[EvalResult] = []
    setup = ""
    for scene in scenes:
        if progress:
            progress(f"rendering and running {scene} ({camera}, {distance_m:g} m)")
        res, _events, _truth, setup = _run_scene(scene, camera, distance_m, seed, root, config)
        results.append(res)
        metrics[scene] = summarize([res])
    metrics["all"] = summarize(results)
    seconds = time.perf_counter() - t0
    index = root / "index.html"
    index.write_text(_demo_html(list(scenes), metrics, setup, seconds), encoding="utf-8")
    return DemoResult(index, metrics, seconds)


_CSS = """body{font-family:system-ui,sans-serif;margin:2em;max-width:1400px}
table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;padding:3px 6px;
text-align:right}td:first-child{text-align:left}img{max-width:640px;margin:4px}
.row{display:flex;flex-wrap:wrap}"""


def _demo_html(
    scenes: list[str], metrics: Mapping[str, Metrics], setup: str, seconds: float
) -> str:
    from .. import __version__

    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>depthtouch demo</title>",
        f"<style>{_CSS}</style></head><body>",
        "<h1>depthtouch demo</h1>",
        f"<p>Simulated depth camera ({html.escape(setup)}), depthtouch {__version__}; the sensor "
        "learned each empty surface, then found, tracked and reported the touches; they are "
        "matched to the simulator's ground truth (20 mm gate on the surface). "
        f"Total time {seconds:.1f} s.</p>",
        "<h2>Accuracy</h2>", metrics_html(metrics, "scene"),
        "<p>contacts: true contacts the camera can see (hidden: tip never visible, left out); "
        "recall: true contacts found; frame rec: contact frames matched (after the debounce); "
        "false: reported touches matching no contact; hover&gt;=25: of those, from fingers "
        "hovering 25 mm or higher; err: distance on the surface; lat: frames; angle: drag-path "
        "angle error; jitter: still finger, RMS.</p>",
    ]
    for s in scenes:
        parts.append(f"<h2>{html.escape(s)}</h2><div class='row'>")
        for kind in ("depth", "height", "paths"):
            name = f"{s}-{kind}.png"
            parts.append(f"<img src='{name}' alt='{html.escape(s)} {kind}'>")
        link = f"<a href='{html.escape(s)}.events.jsonl'>events (JSON Lines)</a>"
        parts.append(f"</div><p>{link}</p>")
    parts.append("</body></html>")
    return "\n".join(parts)
