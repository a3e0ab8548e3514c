"""The one loop: source -> pipeline -> sinks, for every command.

``replay``, ``run``, ``serve``, the evaluation suite and the demo all call :func:`drive`; each
adds only what is its own (a camera thread, a status line, a web server, a progress bar)::

    stats = drive(open_source("rec.npz"), Pipeline(), [JsonlSink("touches.jsonl")])

Per frame the pipeline makes one :class:`~depthtouch.types.FrameResult` and every sink gets it.
At the end of the stream (or on ``stop``, or Ctrl-C) the touches still down are ended with
``up`` on the last frame, so that no application keeps a finger down. A source may yield a
:class:`~depthtouch.types.StreamGap` between frames (a camera was lost and reopened): the touches
are ended there too; with several cameras (a :class:`CameraProcessor`), a gap naming its camera
ends only the touches that camera alone was seeing.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from . import stopping
from .errors import ConfigError, DepthTouchError
from .outputs.base import Sink
from .types import Frame, FrameResult, StreamGap, close_quietly

log = logging.getLogger(__name__)


class Processor(Protocol):
    """What the loop needs of :class:`depthtouch.pipeline.Pipeline`."""

    def process(self, frame: Frame) -> FrameResult: ...

    def finish(self) -> FrameResult | None: ...


@runtime_checkable
class CameraProcessor(Processor, Protocol):
    """A processor of several cameras (:class:`depthtouch.multicam.MultiPipeline`): one camera
    lost ends only what that camera alone was seeing."""

    def end_camera(self, cam: int) -> FrameResult | None: ...


class FrameSource(Protocol):
    def frames(self) -> Iterable[Frame | StreamGap]: ...


class FrameTimes:
    """Median and p95 of a summary's ``ms_per_frame`` (NaN when there is none)."""

    ms_per_frame: list[float]

    @property
    def median_ms(self) -> float:
        return float(np.median(self.ms_per_frame)) if self.ms_per_frame else float("nan")

    @property
    def p95_ms(self) -> float:
        return float(np.percentile(self.ms_per_frame, 95)) if self.ms_per_frame else float("nan")


@dataclass
class DriveStats(FrameTimes):
    """What a drive did. ``ms_per_frame``: the touch path's time of each frame once the surface
    was learned (bounded to the last ``keep`` frames); ``interrupted``: ended by Ctrl-C."""

    frames: int = 0
    events: int = 0
    touches: int = 0
    sink_errors: int = 0
    gaps: int = 0
    interrupted: bool = False
    ms_per_frame: list[float] = field(default_factory=list)
    keep: int = 100_000


class Pacer:
    """Waits until each frame's time (relative to the first, divided by ``speed``) has come, so
    that a recording plays as a camera would deliver it. ``speed`` > 0 (1.0 = real time)."""

    def __init__(self, speed: float = 1.0, *, clock: Callable[[], float] = time.monotonic,
                 wait: Callable[[float], bool] | None = None) -> None:
        if not speed > 0:
            raise ConfigError(f"speed = {speed!r} is out of range; must be > 0")
        self.speed, self._clock = float(speed), clock
        self._wait = wait or _sleep
        self._start: tuple[float, float] | None = None

    def reset(self) -> None:
        """The next frame starts the clock again (a looped recording)."""
        self._start = None

    def until(self, t_s: float) -> bool:
        """Wait for frame time ``t_s``; True when the wait was cut short (stop)."""
        if self._start is None or t_s < self._start[1]:
            self._start = (self._clock(), t_s)
            return False
        delay = self._start[0] + (t_s - self._start[1]) / self.speed - self._clock()
        return delay > 0 and bool(self._wait(delay))


def drive(
    source: FrameSource,
    pipeline: Processor,
    sinks: Sequence[Sink] = (),
    *,
    pace: Pacer | float | None = None,
    stop: threading.Event | None = None,
    max_frames: int | None = None,
    on_result: Callable[[FrameResult], None] | None = None,
    lenient: bool = False,
    flush_interval_s: float | None = None,
    clock: Callable[[], float] = time.monotonic,
    stats: DriveStats | None = None,
) -> DriveStats:
    """Run ``pipeline`` over ``source`` into ``sinks`` until the source ends, ``max_frames``
    frames were processed or ``stop`` is set; returns the counts.

    pace: None (as fast as possible), a speed factor (1.0 = the recording's own pace) or a
        :class:`Pacer`. Cameras need none.
    on_result: called with each result after the sinks (a status line, a progress bar).
    lenient: a live stream: a frame the pipeline cannot process and a sink that fails are
        warned about once and counted, never raised (a recording: they are raised).
    flush_interval_s: call ``flush()`` of the sinks that have one this often (clock time).
    stats: counts into this object (the caller keeps them if Ctrl-C ends the drive).
    A stop request (SIGTERM, SIGHUP, Ctrl-C through :mod:`depthtouch.stopping`) ends the loop at
    the next frame like ``stop``; a KeyboardInterrupt raised inside it ends the touches still
    down, then is raised again.
    The sinks are not closed here: their owner closes them.
    """
    stats = stats if stats is not None else DriveStats()
    stop = stop or threading.Event()
    # (not stop.wait: the loop runs in the main thread, where a signal handler sets ``stop``)
    pacer = (Pacer(pace, wait=functools.partial(stopping.wait, stop))
             if isinstance(pace, (int, float)) else pace)
    warned: set[str] = set()
    touched: set[int] = set()
    last_flush = clock()

    def warn(key: str, message: str) -> None:
        if key not in warned:
            warned.add(key)
            log.warning("%s; further ones are counted, not shown", message)

    def deliver(result: FrameResult) -> None:
        stats.events += len(result.events)
        touched.update(e.id for e in result.events)
        for sink in sinks:
            try:
                sink.send(result)
            except DepthTouchError as e:
                if not lenient:
                    raise
                stats.sink_errors += 1
                warn(f"sink{id(sink)}", f"{type(sink).__name__}: {e}")
        if on_result is not None:
            on_result(result)

    def end_touches(gap: StreamGap | None = None) -> None:
        if gap is not None and gap.cam is not None and isinstance(pipeline, CameraProcessor):
            tail = pipeline.end_camera(gap.cam)
        else:
            tail = pipeline.finish()
        if tail is not None and tail.events:
            deliver(tail)

    frames = iter(source.frames())
    interrupted = False
    try:
        # SIGTERM, SIGHUP, Ctrl-C (depthtouch.stopping) set ``stop``: the loop ends between frames
        with stopping.listen(stop.set):
            for item in frames:
                if stop.is_set():
                    break
                if isinstance(item, StreamGap):
                    stats.gaps += 1
                    end_touches(item)
                    continue
                if pacer is not None and pacer.until(item.timestamp_s):
                    break
                try:
                    result = pipeline.process(item)
                except (DepthTouchError, ValueError) as e:
                    if not lenient:
                        raise
                    warn("pipeline", f"frame {item.index} skipped: {e}")
                    continue
                stats.frames += 1
                total = result.timing_ms.get("total")
                if total is not None:
                    if len(stats.ms_per_frame) >= stats.keep:
                        del stats.ms_per_frame[: stats.keep // 2]
                    stats.ms_per_frame.append(total)
                deliver(result)
                if flush_interval_s is not None and clock() - last_flush >= flush_interval_s:
                    last_flush = clock()
                    _flush(sinks)
                if max_frames is not None and stats.frames >= max_frames:
                    break
    except KeyboardInterrupt:
        interrupted = stats.interrupted = True
    finally:
        close_quietly(frames)
        stats.touches = len(touched)
    end_touches()
    stats.touches = len(touched)
    if flush_interval_s is not None:
        _flush(sinks)
    if interrupted:
        raise KeyboardInterrupt
    return stats


def _sleep(seconds: float) -> bool:
    time.sleep(seconds)
    return False


def _flush(sinks: Sequence[Sink]) -> None:
    for sink in sinks:
        flush = getattr(sink, "flush", None)
        if flush is not None:
            with contextlib.suppress(DepthTouchError, OSError):
                flush()
