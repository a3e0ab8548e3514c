"""Running the sensor over a suite's cases and evaluating it: one recording, one case with
several configurations, a grid of cases in worker processes, and the ``depthtouch eval``
commands over recordings and suites.

The suite itself (its file, cases and cached recordings) is :mod:`depthtouch.evaluation.suite`.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from ..config import PipelineConfig
from ..errors import ConfigError
from ..sources.base import ArraySource, DepthSource
from ..types import FrameResult, TouchEvent
from .emptystart import shorten
from .metrics import GATE_MM, EvalResult, FrameNotes, Truth, evaluate, read_truth
from .notes import contact_pixels
from .suite import SuiteCase, ensure_recording, load_suite
from .summary import Metrics, summarize


# --- running -------------------------------------------------------------------------------------
class EventCollector:
    """A sink that keeps every event of a run (for the evaluation)."""

    def __init__(self) -> None:
        self.events: list[TouchEvent] = []

    def send(self, result: FrameResult) -> None:
        self.events.extend(result.events)

    def close(self) -> None:
        """Nothing to release."""


def run_source(source: DepthSource, config: PipelineConfig | None,
               notes: dict[int, FrameNotes] | None = None,
               probes: Mapping[int, np.ndarray] | None = None,
               ) -> tuple[list[TouchEvent], list[float]]:
    """Run the sensor over a source; returns (events, ms per frame of the touch path). With
    ``notes``, fills it with what each frame showed for naming missed contacts
    (:class:`~depthtouch.evaluation.notes.NotingCollector`; ``probes``: per frame, the pixels
    to note the band near, such as the truth's contacts: then only those frames are noted)."""
    from ..driver import drive
    from ..pipeline import Pipeline
    from .notes import NotingCollector

    pipeline = Pipeline(config)
    collect = (EventCollector() if notes is None
               else NotingCollector(pipeline, probes))
    stats = drive(source, pipeline, [collect])
    if notes is not None and isinstance(collect, NotingCollector):
        notes.update(collect.notes)
    return collect.events, stats.ms_per_frame


def run_pipeline(
    recording: str | Path, config: PipelineConfig | None = None,
    notes: dict[int, FrameNotes] | None = None,
    probes: Mapping[int, np.ndarray] | None = None,
) -> tuple[list[TouchEvent], list[float]]:
    """Run the sensor over a recording file; returns (events, ms per processed frame)
    (``notes``, ``probes``: as :func:`run_source`)."""
    from ..sources import open_source

    with open_source(recording) as src:
        return run_source(src, config, notes, probes)


def evaluate_recording(
    recording: str | Path,
    truth: str | Path | Truth,
    config: PipelineConfig | None = None,
    *,
    gate_mm: float = GATE_MM,
    label: str = "",
) -> EvalResult:
    """Run the pipeline on one recording file and evaluate it against its truth."""
    t = truth if isinstance(truth, Truth) else read_truth(truth)
    notes: dict[int, FrameNotes] = {}
    events, timing = run_pipeline(recording, config, notes, contact_pixels(t))
    settle = (config or PipelineConfig()).tracking.down_frames
    return evaluate(t, events, gate_mm=gate_mm, settle_frames=settle, timing_ms=timing,
                    label=label, point_notes=notes)


def evaluate_case(
    case: SuiteCase,
    configs: Sequence[PipelineConfig | None] = (None,),
    *,
    gate_mm: float = GATE_MM,
    cache: Path | None = None,
) -> list[EvalResult]:
    """Evaluate the pipeline with each of ``configs`` on one case (rendered once).

    Without ``cache`` the case is rendered in memory; with it, the recording is read from the
    cache, or rendered and written there first.
    """
    if cache is not None and case.empty_s == 0.0:
        rec_path, truth_path = ensure_recording(case, cache)
        return [evaluate_recording(rec_path, truth_path, cfg, gate_mm=gate_mm, label=case.label)
                for cfg in configs]
    from .metrics import truth_from_dict

    source, doc = _recording(case, cache)
    truth = truth_from_dict(doc, case.label)
    out = []
    for cfg in configs:
        notes: dict[int, FrameNotes] = {}
        events, timing = run_source(source, cfg, notes, contact_pixels(truth))
        settle = (cfg or PipelineConfig()).tracking.down_frames
        out.append(evaluate(truth, events, gate_mm=gate_mm, settle_frames=settle,
                            timing_ms=timing, label=case.label, point_notes=notes))
    return out


def _recording(case: SuiteCase, cache: Path | None) -> tuple[ArraySource, dict[str, Any]]:
    """A case's frames (a source that can be read again, for each config) and truth document:
    rendered in memory, or read from the cache (rendered there first), its empty start
    shortened (``empty_s``)."""
    if cache is not None:
        rec_path, truth_path = ensure_recording(case, cache)
        with np.load(rec_path) as z:
            depth, ts, scale = z["depth"], z["timestamps"], float(z["depth_scale"])
            K = z["K"] if "K" in z.files else None
        doc = json.loads(truth_path.read_text(encoding="utf-8"))
        fps = None
    else:
        from ..sim import render_scene

        rec = render_scene(case.scene, **case.render_kwargs())
        depth, ts, scale, K, doc, fps = (rec.depth, rec.timestamps_s, rec.depth_scale_m, rec.K,
                                         rec.truth, rec.fps)
    if case.empty_s > 0.0:
        depth, ts, doc = shorten(depth, ts, doc, case.empty_s)
    return ArraySource(depth, ts, scale, K, fps=fps, name=case.label), doc


_Job = tuple[SuiteCase, Sequence[PipelineConfig | None], float, Path | None]


def _worker(job: _Job) -> list[EvalResult]:
    case, configs, gate, cache = job
    return evaluate_case(case, configs, gate_mm=gate, cache=cache)


def run_grid(
    cases: Sequence[SuiteCase],
    configs: Sequence[PipelineConfig | None] = (None,),
    *,
    gate_mm: float = GATE_MM,
    workers: int = 1,
    cache: Path | None = None,
    progress: Callable[[SuiteCase, EvalResult], None] | None = None,
) -> list[list[EvalResult]]:
    """Evaluate every config on every case; ``result[k][i]`` is config k on case i.

    Cases run in ``workers`` processes when > 1; each case is rendered once for all configs.
    """
    if workers < 1:
        raise ConfigError(f"workers = {workers} must be at least 1")
    jobs: list[_Job] = [(c, list(configs), gate_mm, cache) for c in cases]
    per_case: list[list[EvalResult]] = []

    def done(c: SuiteCase, rs: list[EvalResult]) -> None:
        if progress:
            progress(c, rs[0])
        per_case.append(rs)

    if workers == 1 or len(cases) < 2:
        for c, job in zip(cases, jobs, strict=True):
            done(c, _worker(job))
    else:
        with ProcessPoolExecutor(max_workers=min(workers, len(cases))) as ex:
            for c, rs in zip(cases, ex.map(_worker, jobs), strict=True):
                done(c, rs)
    return [[rs[k] for rs in per_case] for k in range(len(configs))]


def run_cases(
    cases: Sequence[SuiteCase],
    config: PipelineConfig | None = None,
    *,
    gate_mm: float = GATE_MM,
    workers: int = 1,
    cache: Path | None = None,
    progress: Callable[[SuiteCase, EvalResult], None] | None = None,
) -> list[EvalResult]:
    """Evaluate one config on cases; results in the order of ``cases`` (see :func:`run_grid`)."""
    return run_grid(cases, [config], gate_mm=gate_mm, workers=workers, cache=cache,
                    progress=progress)[0]


#: the case attributes a suite's results can be pooled by (``--by``), besides ``all``
GROUP_KEYS = ("scene", "camera", "group", "label", "distance_m", "surface")


def check_group_key(by: str) -> None:
    """Refuse a ``--by`` that is neither one of :data:`GROUP_KEYS` nor ``all``."""
    if by != "all" and by not in GROUP_KEYS:
        raise ConfigError(f"cannot group by {by!r}; use {', '.join(GROUP_KEYS)} or all")


def group_metrics(
    cases: Sequence[SuiteCase], results: Sequence[EvalResult], by: str
) -> dict[str, Metrics]:
    """Pool results by a case attribute (one of :data:`GROUP_KEYS`) or ``all``."""
    check_group_key(by)
    if by == "all":
        return {"all": summarize(results)}
    groups: dict[str, list[EvalResult]] = {}
    for c, r in zip(cases, results, strict=True):
        groups.setdefault(str(getattr(c, by)), []).append(r)
    return {k: summarize(v) for k, v in groups.items()}


def default_workers() -> int:
    """Processes for a suite run: the usable cores, at most 4 (override with DEPTHTOUCH_WORKERS)."""
    env = os.environ.get("DEPTHTOUCH_WORKERS")
    if env:
        try:
            n = int(env)
        except ValueError:
            raise ConfigError(f"DEPTHTOUCH_WORKERS = {env!r} must be a whole number") from None
        return max(1, n)
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    return max(1, min(4, cores))



# --- commands ------------------------------------------------------------------------------------
def eval_recording_command(
    recording: str | Path | None,
    truth: str | Path | None,
    *,
    events_path: str | Path | None = None,
    config: PipelineConfig | None = None,
    gate_mm: float = GATE_MM,
    space: str = "depth",
) -> dict[str, Metrics]:
    """``depthtouch eval REC --truth T``, or ``--events E --truth T`` (no sensor run).

    space: "screen" scores an events file by its ``sx``, ``sy`` (fused cameras, whose screen is
    the truth's image: ``depthtouch sim --views``), "depth" by ``x``, ``y``."""
    if truth is None:
        raise ConfigError("eval needs --truth TRUTH.json for a recording (or use --suite NAME)")
    t = read_truth(truth)
    name = Path(str(events_path or recording)).name
    if events_path is not None:
        from ..outputs.jsonl import read_events

        settle = (config or PipelineConfig()).tracking.down_frames
        events = list(read_events(events_path))
        if space == "screen":
            from ..fusion import in_screen

            events = in_screen(events)
        res = evaluate(t, events, gate_mm=gate_mm, settle_frames=settle, label=name)
    elif recording is not None:
        res = evaluate_recording(recording, t, config, gate_mm=gate_mm, label=name)
    else:
        raise ConfigError("eval needs a RECORDING, --events FILE or --suite NAME")
    return {name: summarize([res])}


def eval_suite_command(
    suite: str | Path,
    *,
    subset: str | None = None,
    by: str = "scene",
    config: PipelineConfig | None = None,
    workers: int | None = None,
    cache: Path | None = None,
    progress: Callable[[SuiteCase, EvalResult], None] | None = None,
    fps: float | None = None,
    resolution_scale: float | None = None,
    noise_scale: float | None = None,
    body: bool = False,
    drop_rate: float | None = None,
    breathing_mm: float | None = None,
    empty_s: float | None = None,
    edge_mm: float | None = None,
) -> dict[str, Metrics]:
    """``depthtouch eval --suite NAME``: metrics pooled by ``by``, plus ``all`` at the end.

    cache: keep the rendered recordings in this folder (None: render in memory only).
    fps: render every case at this frame rate (None: the suite's own, 30 fps).
    resolution_scale: every camera at this many times its resolution (None: its own).
    noise_scale: every camera's axial noise times this (None: its own).
    body: every arm goes on into a body that leaves the view (``render_scene(body=True)``).
    drop_rate: frames the camera never delivers (``render_scene(drop_rate=)``; None: none).
    breathing_mm: frames that move as a whole (``render_scene(breathing_mm=)``; None: none).
    empty_s: every recording's empty start shortened to this (s; None: as rendered).
    edge_mm: the surface ends inside the view, this far above what lies beyond its edge
    (``render_scene(edge_mm=)``; None: the surface fills the view).
    """
    check_group_key(by)  # before any case is rendered
    s = (load_suite(suite).at_fps(fps).at_resolution(resolution_scale).at_noise(noise_scale)
         .with_body(body).with_drops(drop_rate).with_breathing(breathing_mm)
         .with_empty_start(empty_s).with_edge(edge_mm))
    cases = s.select(subset)
    results = run_cases(cases, config, gate_mm=s.gate_mm, workers=workers or default_workers(),
                        cache=cache, progress=progress)
    out = group_metrics(cases, results, by) if by != "all" else {}
    out["all"] = summarize(results)
    return out
