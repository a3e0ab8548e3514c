"""Running the pipeline over a source into sinks: the replay command and the pieces the live loop,
the evaluation and the web server share.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import stopping
from .config import PipelineConfig
from .errors import ConfigError, SourceError
from .outputs.base import EventSink
from .pipeline import Pipeline
from .sources import DepthSource, open_source
from .surface.model import load_surface
from .types import Frame, TouchEvent


@dataclass
class RunSummary:
    """What a run did: counts, touches, and the per-frame time of the touch path."""

    source: str
    frames: int = 0
    learning_frames: int = 0
    skipped_frames: int = 0
    events: int = 0
    touches: int = 0
    ms_per_frame: list[float] = field(default_factory=list)
    outputs: list[str] = field(default_factory=list)

    @property
    def median_ms(self) -> float:
        return float(np.median(self.ms_per_frame)) if self.ms_per_frame else float("nan")

    @property
    def p95_ms(self) -> float:
        return float(np.percentile(self.ms_per_frame, 95)) if self.ms_per_frame else float("nan")

    def describe(self) -> str:
        lines = [
            f"{self.source}: {self.frames} frames ({self.learning_frames} learning the surface, "
            f"{self.skipped_frames} skipped), {self.touches} touches, {self.events} events",
        ]
        if self.ms_per_frame:
            lines.append(
                f"touch path: median {self.median_ms:.3f} ms, p95 {self.p95_ms:.3f} ms per frame"
            )
        lines += [f"wrote {o}" for o in self.outputs]
        return "\n".join(lines)


def process_stream(
    source: DepthSource, pipeline: Pipeline, sinks: list[EventSink] | None = None
) -> Iterator[tuple[Frame, list[TouchEvent]]]:
    """Run ``pipeline`` over every frame of ``source``, sending each frame to ``sinks``.

    Yields (frame, events). At the end of the stream, or at a stop request (SIGTERM, Ctrl-C), the
    touches still active are ended with ``up`` on the last frame (yielded with that frame again).
    """
    sinks = sinks or []
    last: Frame | None = None
    with stopping.listen():  # SIGTERM / Ctrl-C: stop here, between frames (see stopping.py)
        for frame in source.frames():
            if stopping.requested():
                break
            last = frame
            events = pipeline.process(frame)
            for s in sinks:
                s.send(frame, events)
            yield frame, events
    if last is not None:
        tail = pipeline.finish()
        if tail:
            for s in sinks:
                s.send(last, tail)
            yield last, tail


def build_sinks(
    events_path: str | Path | None = None,
    tuio: str | None = None,
    calibration: object | None = None,
) -> list[EventSink]:
    """The sinks a command asked for (JSON Lines file, TUIO UDP)."""
    from .outputs.jsonl import JsonlSink

    sinks: list[EventSink] = []
    try:
        if events_path:
            sinks.append(JsonlSink(events_path))
        if tuio:
            from .outputs.tuio import TuioSink, parse_hostport

            host, port = parse_hostport(tuio)
            sinks.append(TuioSink(host, port, calibration=calibration))  # type: ignore[arg-type]
    except BaseException:
        # a later sink failed: the ones already open keep nothing (no temporary events file)
        for s in sinks:
            if isinstance(s, JsonlSink):
                s.close(commit=False)
            else:
                s.close()
        raise
    return sinks


def load_calibration_file(path: str | Path | None) -> object | None:
    if not path:
        return None
    from .calibration import load_calibration

    return load_calibration(path)


def replay(
    recording: str | Path,
    *,
    config: PipelineConfig | None = None,
    events_path: str | Path | None = None,
    surface_path: str | Path | None = None,
    save_surface_path: str | Path | None = None,
    surface_frames: int | None = None,
    filter_name: str | None = None,
    tuio: str | None = None,
    calibration_path: str | Path | None = None,
    progress: bool = False,
) -> RunSummary:
    """Run the sensor over a recording as fast as possible; write the outputs asked for.

    Errors a user can fix (bad file, too short, unwritable output) raise DepthTouchError before
    anything is written; the events file appears only when the run completes.
    """
    cfg = config or PipelineConfig()
    if filter_name:
        cfg = cfg.replace(filter={"name": filter_name})
    surface = load_surface(surface_path) if surface_path else None
    calibration = load_calibration_file(calibration_path)
    if surface_frames is not None and surface_frames < 2:
        raise ConfigError(f"--surface-frames {surface_frames} is too small; give at least 2")
    rec_path = Path(str(recording))
    for out in (events_path, save_surface_path):
        if out and rec_path.exists() and Path(out).resolve() == rec_path.resolve():
            raise SourceError(f"{out}: is the recording itself; give another output file name")
    if save_surface_path:
        parent = Path(save_surface_path).parent
        if Path(save_surface_path).is_dir():
            raise SourceError(
                f"{save_surface_path}: is a folder; give a file name for the surface"
            )
        if not (parent if str(parent) else Path(".")).is_dir():
            raise SourceError(
                f"{save_surface_path}: folder {parent} does not exist; create it first"
            )
    pipeline = Pipeline(cfg, surface=surface, calibration=calibration,  # type: ignore[arg-type]
                        surface_frames=surface_frames, strict=True)
    with contextlib.ExitStack() as stack:
        source = stack.enter_context(open_source(recording))
        _check_surface_fits(source, surface, surface_frames, cfg)
        sinks = build_sinks(events_path, tuio, calibration)
        for s in sinks:
            stack.enter_context(s)  # type: ignore[arg-type]
        summary = RunSummary(source=str(recording))
        n_total = len(source) if hasattr(source, "__len__") else None  # type: ignore[arg-type]
        bar = _progress(progress, n_total)
        touched: set[int] = set()
        for _frame, events in process_stream(source, pipeline, sinks):
            if "total" in pipeline.last_timing_ms and not pipeline.learning:
                summary.ms_per_frame.append(pipeline.last_timing_ms["total"])
                pipeline.last_timing_ms = {}
            touched.update(e.id for e in events)
            if bar is not None:
                bar.advance()
        if bar is not None:
            bar.close()
        if pipeline.surface is None and not stopping.requested():  # a stop is no short file
            raise SourceError(
                f"{recording}: only {pipeline.stats.frames} frames, fewer than the surface "
                "learning needs; record a longer empty start or give --surface-frames / --surface"
            )
        summary.frames = pipeline.stats.frames
        summary.learning_frames = pipeline.stats.learning_frames
        summary.skipped_frames = pipeline.stats.skipped_frames
        summary.events = pipeline.stats.events
        summary.touches = len(touched)
        if events_path:
            summary.outputs.append(str(events_path))
    if save_surface_path and pipeline.surface is not None:
        pipeline.surface.save(save_surface_path)
        summary.outputs.append(str(save_surface_path))
    return summary


def _check_surface_fits(
    source: DepthSource, surface: object | None, surface_frames: int | None, cfg: PipelineConfig
) -> None:
    if surface is not None:
        w, h = source.resolution_wh
        sw, sh = surface.resolution_wh  # type: ignore[attr-defined]
        if (w, h) != (sw, sh):
            raise SourceError(
                f"the surface file is {sw}x{sh} but the recording is {w}x{h}; learn the surface "
                "from this camera (omit --surface)"
            )
        return
    n = len(source) if hasattr(source, "__len__") else None  # type: ignore[arg-type]
    if n is None:
        return
    need_frames = surface_frames or cfg.surface.learn_frames
    if need_frames is not None:
        if n < need_frames:
            raise SourceError(
                f"{source.name}: {n} frames, fewer than the {need_frames} the surface needs; "
                "give a longer recording or a smaller --surface-frames"
            )
        return
    ts = getattr(source, "timestamps", None)
    if ts is not None and len(ts) and ts[-1] - ts[0] < cfg.surface.learn_s - 1e-9:
        raise SourceError(
            f"{source.name}: {ts[-1] - ts[0]:.2f} s long, shorter than the {cfg.surface.learn_s} s "
            "of empty surface to learn; give a longer recording, --surface-frames N or --surface"
        )


class _Bar:
    def __init__(self, total: int | None) -> None:
        from rich.progress import Progress

        self._p = Progress(transient=True)
        self._p.start()
        self._task = self._p.add_task("replaying", total=total)
        self._last = time.monotonic()

    def advance(self) -> None:
        self._p.advance(self._task)

    def close(self) -> None:
        self._p.stop()


def _progress(enabled: bool, total: int | None) -> _Bar | None:
    import sys

    if not enabled or not sys.stderr.isatty():
        return None
    return _Bar(total)
