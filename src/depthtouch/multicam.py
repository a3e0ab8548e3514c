"""Several cameras, one screen, in the one loop: merged frame streams and a fusing pipeline.

Each camera keeps its own :class:`~depthtouch.pipeline.Pipeline` (its own surface, tracker and
calibration to the shared screen). :func:`merge_by_time` merges the cameras' frame streams into
one, in timestamp order, each frame tagged with its camera (:class:`CameraFrame`);
:class:`MultiPipeline` looks like a Pipeline to :func:`~depthtouch.driver.drive`: it runs the
frame's camera pipeline, fuses the touches (:class:`~depthtouch.fusion.Fusion`) and returns a
:class:`~depthtouch.types.FrameResult` whose events are the fused ones, so that every sink
(events file, TUIO, WebSocket, gestures) takes the fused stream unchanged::

    sources = [open_source("a.npz"), open_source("b.npz")]
    pipes = [Pipeline(calibration=load_calibration(p)) for p in ("a.json", "b.json")]
    drive(merge_by_time(sources), MultiPipeline(pipes), [JsonlSink("fused.jsonl")])

A fused event's ``frame`` and ``t`` are those of the camera frame that produced it; ``cam`` is
the camera (0-based, in the order given) that saw the touch best, ``x``, ``y`` its pixels.
"""

from __future__ import annotations

import contextlib
import heapq
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path

from .calibration import Calibration
from .config import PipelineConfig
from .driver import DriveStats, drive
from .errors import ConfigError, SourceError
from .fusion import Fusion, FusionConfig, view_polygon
from .outputs.base import Sink
from .pipeline import Pipeline
from .types import Closing, Frame, FrameResult, StreamGap, TouchEvent, close_quietly


@dataclass(frozen=True)
class CameraFrame(Frame):
    """A frame tagged with the index of the camera it came from (0-based); ``last_of_instant``
    is False when another camera's frame of the same timestamp follows (cameras in step)."""

    cam: int = 0
    last_of_instant: bool = True

    @classmethod
    def of(cls, frame: Frame, cam: int, *, index: int | None = None,
           timestamp_s: float | None = None, last_of_instant: bool = True) -> CameraFrame:
        values = {f.name: getattr(frame, f.name) for f in fields(Frame)}
        if index is not None:
            values["index"] = index
        if timestamp_s is not None:
            values["timestamp_s"] = timestamp_s
        return cls(**values, cam=cam, last_of_instant=last_of_instant)


class MergedSource(Closing):
    """The frames of several sources in timestamp order (ties: camera order), tagged with
    their camera. For recordings that share a clock (recorded together, or cut from one).
    :meth:`close` closes every source (safe twice).

    A merged frame's ``index`` counts instants (distinct timestamps) from 0: cameras in step
    keep their own frame numbers; out of step, every frame is an instant of its own."""

    def __init__(self, sources: Sequence[object]) -> None:
        if not sources:
            raise ConfigError("no sources to merge; give at least one")
        self.sources = list(sources)
        self.name = " + ".join(str(getattr(s, "name", s)) for s in self.sources)

    def __len__(self) -> int:
        return sum(len(s) for s in self.sources)  # type: ignore[arg-type,misc]

    def close(self) -> None:
        for s in self.sources:
            close = getattr(s, "close", None)
            if close is not None:
                close()

    def frames(self) -> Iterator[Frame | StreamGap]:
        its = [iter(s.frames()) for s in self.sources]  # type: ignore[attr-defined]
        heap: list[tuple[float, int, Frame]] = []

        def push(cam: int) -> None:
            for item in its[cam]:
                if isinstance(item, Frame):  # a recording has no gaps; a gap ends nothing here
                    heapq.heappush(heap, (item.timestamp_s, cam, item))
                    return

        try:
            for cam in range(len(its)):
                push(cam)
            instant, last_t = -1, None
            while heap:
                t, cam, frame = heapq.heappop(heap)
                push(cam)
                if last_t is None or t != last_t:
                    instant, last_t = instant + 1, t
                last = not heap or heap[0][0] != t
                yield CameraFrame.of(frame, cam, index=instant, last_of_instant=last)
        finally:
            for it in its:
                close_quietly(it)


def merge_by_time(sources: Sequence[object]) -> MergedSource:
    """See :class:`MergedSource`."""
    return MergedSource(sources)


class MultiPipeline:
    """One pipeline per camera and the fusion of their touches; a Pipeline to ``drive``.

    pipelines: one per camera, in camera order; each needs a calibration to the one screen
        (the same screen size for all). fusion: the fusion rules (default :class:`FusionConfig`).
    Frames must be :class:`CameraFrame` (a plain Frame is camera 0).
    """

    def __init__(self, pipelines: Sequence[Pipeline],
                 fusion: FusionConfig | None = None) -> None:
        if not pipelines:
            raise ConfigError("no cameras; give at least one source")
        screens = set()
        for k, p in enumerate(pipelines):
            if p.calibration is None:
                raise ConfigError(
                    f"camera {k} has no calibration; give one --calibration per source "
                    "(several cameras meet on one screen)"
                )
            screens.add(tuple(getattr(p.calibration, "screen_wh", ())))
        if len(screens) > 1:
            raise ConfigError(
                f"the calibrations have different screen sizes {sorted(screens)}; calibrate "
                "every camera to the same screen"
            )
        self.pipelines = list(pipelines)
        self.fusion = Fusion(fusion)
        self._views: set[int] = set()
        self._last: FrameResult | None = None
        self._pending: dict[int, Calibration] = {}  # from the web page, applied by the loop
        #: each camera's depth image size, known from its first processed frame
        self.resolutions: list[tuple[int, int] | None] = [None] * len(self.pipelines)
        #: increases whenever a camera's image size or calibration changes (its screen part)
        self.views_version = 0

    @property
    def learning(self) -> bool:
        """True while any camera still learns its surface."""
        return any(p.learning for p in self.pipelines)

    @property
    def calibration(self) -> object:
        return self.pipelines[0].calibration

    @property
    def calibrations(self) -> list[Calibration]:
        """Each camera's calibration to the shared screen, in camera order."""
        return [p.calibration for p in self.pipelines]  # type: ignore[misc]

    def set_camera_calibration(self, cam: int, calibration: Calibration) -> None:
        """Map camera ``cam`` with this calibration from its next frame on (the web page's
        calibration flow; any thread). ConfigError for a camera out of range or another
        screen size than the others'."""
        if not 0 <= cam < len(self.pipelines):
            raise ConfigError(f"camera {cam} is out of range; give 0..{len(self.pipelines) - 1}")
        others = {tuple(c.screen_wh) for k, c in enumerate(self.calibrations) if k != cam}
        if others and others != {tuple(calibration.screen_wh)}:
            raise ConfigError(f"camera {cam}'s calibration is for a {calibration.screen_wh} "
                              f"screen, the others' for {sorted(others)}; use the same screen")
        self._pending[cam] = calibration

    def process(self, frame: Frame) -> FrameResult:
        cam = getattr(frame, "cam", 0)
        if not 0 <= cam < len(self.pipelines):
            raise SourceError(f"frame of camera {cam}, but there are {len(self.pipelines)}")
        pipe = self.pipelines[cam]
        cal = self._pending.pop(cam, None)
        if cal is not None:
            pipe.set_calibration(cal)
            self._views.discard(cam)
        r = pipe.process(frame)
        if cam not in self._views and r.status != "skipped":
            self.fusion.set_view(cam, view_polygon(pipe.calibration, r.frame.resolution_wh))
            self._views.add(cam)
            self.resolutions[cam] = r.frame.resolution_wh
            self.views_version += 1
        t0 = time.perf_counter()
        events = self.fusion.update(cam, r.frame.timestamp_s, r.frame.index, r.events,
                                    emit=getattr(frame, "last_of_instant", True))
        return self._result(r, events, (time.perf_counter() - t0) * 1e3)

    def _result(self, r: FrameResult, events: list[TouchEvent], fusion_ms: float) -> FrameResult:
        timing = dict(r.timing_ms)
        if "total" in timing:
            timing["fusion"] = fusion_ms
            timing["total"] += fusion_ms
        out = FrameResult(r.frame, events, r.points, r.status, timing, r.learn_progress, r.note,
                          r.surface)
        if r.status != "skipped":
            self._last = out
        return out

    def end_camera(self, cam: int) -> FrameResult | None:
        """Camera ``cam`` was lost (a gap in its stream): its pipeline ends its touches (and
        starts its surface learning over if unfinished); of the fused touches, only those this
        camera alone saw end (``up`` on the last frame); the others keep their ids."""
        if not 0 <= cam < len(self.pipelines):
            raise SourceError(f"gap of camera {cam}, but there are {len(self.pipelines)}")
        self.pipelines[cam].finish()  # its own ids end; the fusion forgets them below
        last = self._last
        if last is None:
            return None
        events = self.fusion.drop_camera(cam, last.frame.index)
        return FrameResult(last.frame, events, last.points, "ended", {}, last.learn_progress,
                           "", last.surface)

    def finish(self) -> FrameResult | None:
        """End every camera's touches and every fused touch (``up`` on the last frame)."""
        events: list[TouchEvent] = []
        for cam, p in enumerate(self.pipelines):
            tail = p.finish()
            if tail is not None and tail.events:
                events += self.fusion.update(cam, tail.frame.timestamp_s, tail.frame.index,
                                             tail.events)
        last = self._last
        if last is None:
            return None
        events = [e for e in events if e.state == "up"]
        events += self.fusion.finish(last.frame.index, last.frame.timestamp_s)
        return FrameResult(last.frame, events, last.points, "ended", {}, last.learn_progress,
                           "", last.surface)


def open_calibrations(paths: Sequence[str | Path], n_sources: int) -> list[Calibration]:
    """One calibration per source, in the same order; ConfigError naming the counts else."""
    if len(paths) != n_sources:
        raise ConfigError(
            f"{n_sources} sources but {len(paths)} --calibration file(s); give one --calibration "
            "per source, in the same order"
        )
    from .calibration import load_calibration

    return [load_calibration(p) for p in paths]


@dataclass
class MultiSummary:
    """What a fused run did: the loop's counts, frames per camera, files written."""

    stats: DriveStats
    camera_frames: list[int] = field(default_factory=list)
    outputs: list[str] = field(default_factory=list)

    def describe(self) -> str:
        s = self.stats
        per_cam = ", ".join(f"camera {k}: {n} frames" for k, n in enumerate(self.camera_frames))
        lines = [f"{per_cam}; {s.touches} fused touches, {s.events} events"]
        if s.ms_per_frame:
            lines.append(f"touch path with fusion: median {s.median_ms:.3f} ms, "
                         f"p95 {s.p95_ms:.3f} ms per frame")
        if s.interrupted:
            lines.append("interrupted: the outputs hold the frames replayed so far")
        lines += [f"wrote {o}" for o in self.outputs]
        return "\n".join(lines)


def check_single_only(**options: object) -> None:
    """ConfigError for options that apply to one camera only (``--surface`` ...)."""
    given = [name for name, value in options.items() if value]
    if given:
        flag = "--" + given[0].replace("_", "-")
        raise ConfigError(f"{flag} applies to one camera; with several sources each learns its "
                          "own surface (omit it)")


def replay_multi(
    recordings: Sequence[str | Path],
    calibration_paths: Sequence[str | Path],
    *,
    config: PipelineConfig | None = None,
    fusion: FusionConfig | None = None,
    events_path: str | Path | None = None,
    tuio: str | None = None,
    uinput: bool = False,
    surface_frames: int | None = None,
    realtime: float | None = None,
    extra_sinks: Sequence[Sink] = (),
) -> MultiSummary:
    """``depthtouch replay A.npz B.npz --calibration a.json --calibration b.json``: every
    recording through its own pipeline, merged by time, fused, into the outputs asked for.
    The recordings must share a clock (their timestamps are compared as they are)."""
    from .outputs import open_outputs
    from .replay import check_surface_fits
    from .sources import open_source

    cals = open_calibrations(calibration_paths, len(recordings))
    cfg = config or PipelineConfig()
    if surface_frames is not None and surface_frames < 2:
        raise ConfigError(f"--surface-frames {surface_frames} is too small; give at least 2")
    summary = MultiSummary(DriveStats())
    with contextlib.ExitStack() as stack:
        sources = [stack.enter_context(open_source(r)) for r in recordings]
        for s in sources:
            check_surface_fits(s, None, surface_frames, cfg)
        outputs = stack.enter_context(open_outputs(events_path=events_path, tuio=tuio,
                                                   calibration=cals[0], uinput=uinput))
        multi = MultiPipeline([Pipeline(cfg, calibration=c, surface_frames=surface_frames,
                                        strict=True) for c in cals], fusion)
        try:
            drive(merge_by_time(sources), multi, [*outputs.sinks, *extra_sinks],
                  pace=realtime, stats=summary.stats)
        except KeyboardInterrupt:
            summary.stats.interrupted = True
        if multi.learning and not summary.stats.interrupted:
            raise SourceError(
                "a recording ended before its surface was learned; record a longer empty start "
                "or give --surface-frames"
            )
        outputs.commit()
        summary.camera_frames = [p.stats.frames for p in multi.pipelines]
    summary.outputs += outputs.written
    return summary
