"""``depthtouch run --source A --source B --calibration a.json --calibration b.json``: several
live cameras, one screen.

Each camera runs in its own :class:`~depthtouch.sources.camera.CameraStream` (reader thread,
newest frame first, reconnects); one feeder thread per camera hands its frames to a mailbox that
keeps each camera's newest frame, and the loop takes them oldest first. Device clocks of
different cameras are not comparable, so every frame is stamped with the loop's monotonic clock
when it arrives: that is the time the fusion compares. The loop is
:func:`~depthtouch.driver.drive` with a :class:`~depthtouch.multicam.MultiPipeline`.
A camera that is lost and reopened ends only the touches it alone was seeing; a touch another
camera sees keeps its id.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

from .driver import DriveStats, Pacer, drive
from .fusion import FusionConfig
from .live import LiveConfig, LiveResult, RichStatusLine, StatusBoard
from .multicam import CameraFrame, MultiPipeline, open_calibrations
from .outputs.base import Sink
from .sources.base import DepthSource
from .sources.camera import CameraStream, StreamCounts
from .types import Frame, StreamGap, close_quietly

_END = object()


class NewestPerCamera:
    """Thread-safe: each camera's newest unread item (a newer one replaces it: ``dropped``);
    :meth:`get` takes the one that arrived first. ``finish(cam)`` marks a camera ended."""

    def __init__(self, n: int) -> None:
        self._cond = threading.Condition()
        self._slots: dict[int, tuple[float, object]] = {}
        self._open = set(range(n))
        self.dropped = 0

    def put(self, cam: int, arrival_s: float, item: object) -> None:
        with self._cond:
            if cam in self._slots:
                self.dropped += 1
                if isinstance(self._slots[cam][1], StreamGap):
                    return  # the gap goes first (it ends the touches); this frame is dropped
            self._slots[cam] = (arrival_s, item)
            self._cond.notify()

    def finish(self, cam: int) -> None:
        with self._cond:
            self._open.discard(cam)
            self._cond.notify()

    def get(self, timeout_s: float) -> tuple[int, object] | None:
        """(cam, item) of the earliest arrival; (-1, _END) when every camera ended; None after
        ``timeout_s`` without either."""
        with self._cond:
            if not self._slots and self._open:
                self._cond.wait(timeout_s)
            if self._slots:
                cam = min(self._slots, key=lambda c: self._slots[c][0])
                return cam, self._slots.pop(cam)[1]
            return None if self._open else (-1, _END)


class LiveMerge:
    """Several camera streams as one source of :class:`CameraFrame` stamped by arrival.

    Looks like a CameraStream to the status board (phase, message, dropped, counts).
    """

    def __init__(self, streams: Sequence[CameraStream], stop: threading.Event,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.streams, self.stop, self.clock = list(streams), stop, clock
        self.mailbox = NewestPerCamera(len(self.streams))

    @property
    def phase(self) -> str:
        return next((s.phase for s in self.streams if s.phase != "running"), "running")

    @property
    def message(self) -> str:
        return next((f"camera {k}: {s.message}" for k, s in enumerate(self.streams)
                     if s.phase != "running"), "")

    @property
    def dropped(self) -> int:
        return self.mailbox.dropped + sum(s.dropped for s in self.streams)

    @property
    def counts(self) -> StreamCounts:
        c = StreamCounts()
        for s in self.streams:
            c.received += s.counts.received
            c.reconnects += s.counts.reconnects
            c.latency_ms_max = max(c.latency_ms_max, s.counts.latency_ms_max)
            c.latency_ms_mean = max(c.latency_ms_mean, s.counts.latency_ms_mean)
        c.dropped = self.dropped
        return c

    def _feed(self, cam: int, stream: CameraStream, errors: list[BaseException]) -> None:
        gen = stream.frames()
        try:
            for item in gen:
                self.mailbox.put(cam, self.clock(), item)
        except BaseException as e:  # raised in the loop's thread
            errors.append(e)
            self.stop.set()
        finally:
            close_quietly(gen)
            self.mailbox.finish(cam)

    def frames(self) -> Iterator[Frame | StreamGap]:
        errors: list[BaseException] = []
        threads = [threading.Thread(target=self._feed, args=(k, s, errors), daemon=True,
                                    name=f"depthtouch-camera-{k}")
                   for k, s in enumerate(self.streams)]
        for t in threads:
            t.start()
        t0 = self.clock()
        seq = 0
        try:
            while not self.stop.is_set():
                got = self.mailbox.get(0.1)
                if got is None:
                    continue
                cam, item = got
                if item is _END:
                    break
                if isinstance(item, StreamGap):
                    yield StreamGap(f"camera {cam}: {item.reason}", cam=cam)
                elif isinstance(item, Frame):
                    yield CameraFrame.of(item, cam, index=seq, timestamp_s=self.clock() - t0)
                    seq += 1
        finally:
            self.stop.set()
            for t in threads:
                t.join(5.0)
        if errors:
            raise errors[0]


def run_live_multi(
    sources: Sequence[str],
    calibration_paths: Sequence[str | Path],
    *,
    config: Any = None,
    fusion: FusionConfig | None = None,
    events_path: str | Path | None = None,
    tuio: str | None = None,
    uinput: bool = False,
    source_options: dict[str, Any] | None = None,
    live_config: LiveConfig | None = None,
    max_seconds: float | None = None,
    show_status: bool = True,
    serve: str | None = None,
    extra_sinks: Sequence[Sink] = (),
) -> LiveResult:
    """Run several cameras (or paced recordings) fused onto one screen until Ctrl-C,
    ``max_seconds`` or the end of every source; returns the counts (see ``run_live``).
    serve: "HOST:PORT" for the web page: the fused touches, each camera's part of the screen
    and the calibration flow per camera (docs/multicam.md)."""
    from .outputs import open_outputs
    from .pipeline import Pipeline
    from .sources import is_live_spec, open_source
    from .surface.gate import LearningGate

    live_config = live_config or LiveConfig()
    cals = open_calibrations(calibration_paths, len(sources))
    stop = threading.Event()
    clock = time.monotonic
    streams = []
    for spec in sources:
        opts = source_options or {}
        pacer = None if is_live_spec(spec) else Pacer(1.0, wait=stop.wait)

        def factory(spec: str = spec, opts: dict[str, Any] = opts) -> DepthSource:
            return open_source(spec, **opts)

        streams.append(CameraStream(
            factory, stop=stop, pace=pacer.until if pacer else None,
            backoff_initial_s=live_config.backoff_initial_s,
            backoff_max_s=live_config.backoff_max_s, clock=clock))
    merged = LiveMerge(streams, stop, clock)
    multi = MultiPipeline([Pipeline(config, calibration=c, gate=LearningGate(live_config.gate()))
                           for c in cals], fusion)
    result, stats = LiveResult(), DriveStats(keep=1000)
    timer: threading.Timer | None = None
    with open_outputs(events_path=events_path, tuio=tuio, calibration=cals[0],
                      uinput=uinput) as outputs, contextlib.ExitStack() as stack:
        sinks = [*outputs.sinks, *extra_sinks]
        if serve:
            from .web.serve import WebPage

            page = stack.enter_context(WebPage(serve, multi, source_name=" + ".join(sources),
                                               camera_names=sources))
            sinks += page.sinks
        status = stack.enter_context(RichStatusLine()) if show_status else None
        board = StatusBoard(merged, None, status, live_config.status_hz, clock)  # type: ignore[arg-type]
        if max_seconds:
            timer = threading.Timer(max_seconds, stop.set)
            timer.daemon = True
            timer.start()
        try:
            drive(merged, multi, sinks, stop=stop, on_result=board,
                  lenient=True, flush_interval_s=live_config.flush_interval_s, stats=stats)
        except KeyboardInterrupt:
            result.interrupted = True
        finally:
            stop.set()
            if timer is not None:
                timer.cancel()
        outputs.commit()
    c = merged.counts
    result.processed, result.events, result.sink_errors = stats.frames, stats.events, \
        stats.sink_errors
    result.received, result.dropped, result.reconnects = c.received, c.dropped, c.reconnects
    result.latency_ms_mean, result.latency_ms_max = c.latency_ms_mean, c.latency_ms_max
    return result
