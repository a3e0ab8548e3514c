"""``depthtouch replay``: the sensor over a recording, as fast as it goes or at its own pace.

The loop is :func:`depthtouch.driver.drive`; this adds the checks a recording allows before the
first frame (long enough to learn the surface, the right size for a saved one, outputs that are
not the recording itself) and a progress bar.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from . import stopping
from .config import PipelineConfig
from .driver import DriveStats, FrameTimes, drive
from .errors import ConfigError, SourceError
from .files import check_output_path
from .outputs import open_outputs
from .outputs.base import Sink
from .pipeline import Pipeline
from .sources import DepthSource, open_source
from .surface.model import load_surface
from .types import FrameResult


@dataclass
class RunSummary(FrameTimes):
    """What a run did: counts, touches, and the per-frame time of the touch path."""

    source: str
    frames: int = 0
    learning_frames: int = 0
    skipped_frames: int = 0
    events: int = 0
    touches: int = 0
    ms_per_frame: list[float] = field(default_factory=list)
    outputs: list[str] = field(default_factory=list)
    interrupted: bool = False

    def describe(self) -> str:
        lines = [
            f"{self.source}: {self.frames} frames ({self.learning_frames} learning the surface, "
            f"{self.skipped_frames} skipped), {self.touches} touches, {self.events} events",
        ]
        if self.ms_per_frame:
            lines.append(
                f"touch path: median {self.median_ms:.3f} ms, p95 {self.p95_ms:.3f} ms per frame"
            )
        if self.interrupted:
            lines.append("interrupted: the outputs hold the frames replayed so far")
        lines += [f"wrote {o}" for o in self.outputs]
        return "\n".join(lines)


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
    realtime: float | None = None,
    uinput: bool = False,
    extra_sinks: Sequence[Sink] = (),
) -> RunSummary:
    """Run the sensor over a recording; write the outputs asked for.

    realtime: None (as fast as possible) or a speed factor (1.0 = the recording's own pace).
    Errors a user can fix (bad file, too short, unwritable output) raise DepthTouchError before
    anything is written; the events file appears only when the run completes (or on Ctrl-C,
    with the events so far: the touches still down end with ``up``).
    """
    cfg = config or PipelineConfig()
    if filter_name:
        cfg = cfg.replace(filter={"name": filter_name})
    surface = load_surface(surface_path) if surface_path else None
    if surface_frames is not None and surface_frames < 2:
        raise ConfigError(f"--surface-frames {surface_frames} is too small; give at least 2")
    rec_path = Path(str(recording))
    for out in (events_path, save_surface_path):
        if out and rec_path.exists() and Path(out).resolve() == rec_path.resolve():
            raise SourceError(f"{out}: is the recording itself; give another output file name")
    if save_surface_path:
        check_output_path(save_surface_path, what="the surface", error=SourceError)
    summary = RunSummary(source=str(recording))
    with contextlib.ExitStack() as stack:
        source = stack.enter_context(open_source(recording))
        check_surface_fits(source, surface, surface_frames, cfg)
        outputs = stack.enter_context(open_outputs(events_path=events_path, tuio=tuio,
                                                   calibration_path=calibration_path,
                                                   uinput=uinput))
        pipeline = Pipeline(cfg, surface=surface, calibration=outputs.calibration,
                            surface_frames=surface_frames, strict=True)
        n_total = len(source) if hasattr(source, "__len__") else None  # type: ignore[arg-type]
        bar = stack.enter_context(_progress(progress, n_total))
        stats = DriveStats()
        try:
            drive(source, pipeline, [*outputs.sinks, *extra_sinks], pace=realtime,
                  on_result=bar, stats=stats)
        except KeyboardInterrupt:
            summary.interrupted = True
        summary.interrupted |= stopping.requested()  # SIGTERM, SIGHUP, Ctrl-C: a clean stop
        if pipeline.learning and not summary.interrupted:
            raise SourceError(
                f"{recording}: only {pipeline.stats.frames} frames, fewer than the surface "
                "learning needs; record a longer empty start or give --surface-frames / --surface"
            )
        outputs.commit()
        summary.frames = pipeline.stats.frames
        summary.learning_frames = pipeline.stats.learning_frames
        summary.skipped_frames = pipeline.stats.skipped_frames
        summary.events = stats.events
        summary.touches = stats.touches
        summary.ms_per_frame = stats.ms_per_frame
    summary.outputs += outputs.written
    if save_surface_path and not pipeline.learning:
        pipeline.surface.save(save_surface_path)
        summary.outputs.append(str(save_surface_path))
    return summary


def check_surface_fits(
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
    """A rich progress bar on stderr (a terminal only); called with each result."""

    def __init__(self, total: int | None) -> None:
        from rich.progress import Progress

        self._p = Progress(transient=True)
        self._task = self._p.add_task("replaying", total=total)

    def __call__(self, result: FrameResult) -> None:
        if result.status != "ended":
            self._p.advance(self._task)

    def __enter__(self) -> _Bar:
        self._p.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._p.stop()


@contextlib.contextmanager
def _progress(enabled: bool, total: int | None) -> Iterator[Callable[[FrameResult], None] | None]:
    import sys

    if not enabled or not sys.stderr.isatty():
        yield None
        return
    with _Bar(total) as bar:
        yield bar
