"""Path filters replayed on the tracks a suite gave: a filter compared on a suite in seconds.

Rendering a suite's recordings and finding their touches takes minutes; the path filter is the
last stage and changes nothing before it (the tracker never reads its output). So its inputs
can be recorded once and replayed through any filter:

- :func:`record_case` runs the pipeline with a :class:`FilterTap` as its path filter (it passes
  each measurement through unchanged and keeps every call it gets) and keeps the calls, the
  events, the px -> mm scale of each frame and the truth: a :class:`TrackRecord`.
- :func:`replay_events` feeds the calls to another filter and rebuilds the events as the
  pipeline does (a touch measured in a frame takes the filter's output; one that is not repeats
  the position it last reported); :func:`replay` evaluates them against the truth.

The events of a replay are those of a pipeline run with that filter, position for position
(``tests/evaluation/test_filterreplay.py``). Run it on a suite with
``benchmarks/filter_replay.py``.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..config import FilterConfig, PipelineConfig
from ..sources.base import ArraySource
from ..surface.surface import Surface
from ..tracking.filters import TouchFilter, make_filter
from ..types import FrameResult, TouchEvent
from .metrics import GATE_MM, EvalResult, Truth, evaluate, read_truth, truth_from_dict
from .suite import SuiteCase
from .suiterun import default_workers
from .summary import Metrics, summarize


@dataclass
class FilterTap:
    """A path filter that changes nothing and keeps every call: ``("update", t_s, ids,
    xy_mm)``, ``("drop", ids)`` and ``("reset",)`` in the order they came."""

    calls: list[tuple[Any, ...]] = field(default_factory=list)

    def update(self, ids: np.ndarray, xy_mm: np.ndarray, timestamp_s: float) -> np.ndarray:
        ids_c = np.array(ids, dtype=np.int64).reshape(-1)
        xy = np.array(xy_mm, dtype=np.float64).reshape(-1, 2)
        self.calls.append(("update", float(timestamp_s), ids_c, xy))
        return xy.copy()

    def drop(self, ids: np.ndarray) -> None:
        self.calls.append(("drop", np.array(ids, dtype=np.int64).reshape(-1)))

    def reset(self) -> None:
        self.calls.append(("reset",))


@dataclass(frozen=True)
class TrackRecord:
    """What one recording gave the path filter, and what is needed to score a replay.

    case: the suite case recorded; calls: the :class:`FilterTap`'s calls; events: the run's
    events (unfiltered positions); scale_mm_per_px: the pipeline's px -> mm scale at each
    frame's time (s -> mm per px).
    """

    case: SuiteCase
    calls: tuple[tuple[Any, ...], ...]
    events: tuple[TouchEvent, ...]
    scale_mm_per_px: dict[float, float]
    truth: Truth
    settle_frames: int


class _Scales:
    """A sink that keeps the events and the px -> mm scale of ``surface`` at each frame's time
    (the pipeline's scale for that frame's filter input)."""

    def __init__(self, surface: Surface) -> None:
        self.surface = surface
        self.events: list[TouchEvent] = []
        self.scale: dict[float, float] = {}

    def send(self, result: FrameResult) -> None:
        self.events.extend(result.events)
        self.scale[result.frame.timestamp_s] = self.surface.mm_per_px or 1.0

    def close(self) -> None:
        """Nothing to release."""


def record_case(case: SuiteCase, config: PipelineConfig | None = None,
                cache: Path | None = None) -> TrackRecord:
    """Run the pipeline on ``case`` with a :class:`FilterTap`, keep what it gave. Without
    ``cache`` the case is rendered in memory; with it, its recording is read from the cache
    (rendered and written there first if missing), as ``depthtouch eval --cache`` does."""
    from ..driver import drive
    from ..pipeline import Pipeline

    cfg = config or PipelineConfig()
    tap = FilterTap()
    pipeline = Pipeline(cfg, path_filter=tap)
    sink = _Scales(pipeline.surface)
    if cache is not None:
        from ..sources import open_source
        from .suite import ensure_recording

        rec_path, truth_path = ensure_recording(case, cache)
        truth = read_truth(truth_path)
        with open_source(rec_path) as src:
            drive(src, pipeline, [sink])
    else:
        from ..sim import render_scene

        rec = render_scene(case.scene, **case.render_kwargs())
        truth = truth_from_dict(rec.truth, case.label)
        drive(ArraySource.of_recording(rec, case.label), pipeline, [sink])
    return TrackRecord(case, tuple(tap.calls), tuple(sink.events), sink.scale, truth,
                       cfg.tracking.down_frames)


def record_cases(cases: Sequence[SuiteCase], config: PipelineConfig | None = None,
                 workers: int | None = None, cache: Path | None = None) -> list[TrackRecord]:
    """:func:`record_case` over ``cases``, in ``workers`` processes (default: cores, <= 4)."""
    n = workers or default_workers()
    if n <= 1 or len(cases) <= 1:
        return [record_case(c, config, cache) for c in cases]
    with ProcessPoolExecutor(n) as ex:
        return list(ex.map(record_case, cases, [config] * len(cases), [cache] * len(cases)))


_FROM_POSITION = ("X", "Y", "Z", "sx", "sy")  # event fields computed from the position


def replay_events(rec: TrackRecord, filt: TouchFilter) -> list[TouchEvent]:
    """The events ``rec``'s run would have given with ``filt`` as its path filter (their
    frame, time, id, state and position; of the other fields, those computed from the
    position, X/Y/Z and sx/sy, are left out: the recorded ones belong to another position)."""
    outputs: dict[tuple[float, int], tuple[float, float]] = {}
    for call in rec.calls:
        if call[0] == "update":
            _, t, ids, xy = call
            out = filt.update(ids, xy, t)
            for i, (x, y) in zip(ids.tolist(), out.tolist(), strict=True):
                outputs[(t, i)] = (x, y)
        elif call[0] == "drop":
            filt.drop(call[1])
        else:
            filt.reset()
    reported: dict[int, tuple[float, float]] = {}
    events = []
    for e in rec.events:
        got = outputs.get((e.t, e.id))
        if got is not None:  # measured this frame: the filter's output, back in px
            scale = rec.scale_mm_per_px.get(e.t, 1.0)
            xy = (got[0] / scale, got[1] / scale)
        else:  # a grace frame or an up repeats what was last reported
            xy = reported.get(e.id, (e.x, e.y))
        if e.state == "up":
            reported.pop(e.id, None)
        else:
            reported[e.id] = xy
        extra = {k: v for k, v in e.extra.items() if k not in _FROM_POSITION}
        events.append(TouchEvent(e.frame, e.t, e.id, e.state, float(xy[0]), float(xy[1]),
                                 extra))
    return events


def replay(records: Sequence[TrackRecord], filter_config: FilterConfig | str,
           gate_mm: float = GATE_MM) -> tuple[Metrics, list[EvalResult]]:
    """Every record replayed through a new filter of ``filter_config``, evaluated."""
    cfg = filter_config if isinstance(filter_config, FilterConfig) else FilterConfig(
        filter_config)
    results = [evaluate(r.truth, replay_events(r, make_filter(cfg)), gate_mm=gate_mm,
                        settle_frames=r.settle_frames, label=r.case.label) for r in records]
    return summarize(results), results
