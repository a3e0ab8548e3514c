"""``depthtouch run``: a camera, the pipeline and the outputs, kept running, with a status line.

The loop is :func:`depthtouch.driver.drive`; this module adds only what a live camera needs:
the camera thread that keeps the newest frame and reopens a lost camera
(:class:`~depthtouch.sources.camera.CameraStream`), the learning gate that waits for a clear,
still surface (:mod:`depthtouch.surface.gate`), and a status line (fps, ms per frame, dropped
frames, touches; the countdown while the surface is learned).
"""

from __future__ import annotations

import collections
import contextlib
import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .checks import check_range
from .driver import DriveStats, Pacer, Sink, drive
from .errors import SurfaceError
from .sources.base import DepthSource
from .sources.camera import CameraStream
from .surface.gate import GateConfig, LearningGate
from .types import FrameResult

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LiveConfig:
    """Settings of the live loop.

    countdown_s, motion_threshold_mm, motion_fraction, learn_max_hz: the learning gate (see
        :class:`~depthtouch.surface.gate.GateConfig`; countdown default 3.0 s, range [0, 60]).
    backoff_initial_s: first wait before reopening a lost camera (default 0.5 s, (0, 60]).
    backoff_max_s: longest wait between attempts; the wait doubles up to it (default 8 s).
    status_hz: status-line updates per second (default 4, range (0, 60]).
    flush_interval_s: sinks with ``flush()`` (the events file) are flushed this often
        (default 1.0 s, range (0, 3600]).
    """

    countdown_s: float = 3.0
    motion_threshold_mm: float = 15.0
    motion_fraction: float = 0.01
    backoff_initial_s: float = 0.5
    backoff_max_s: float = 8.0
    status_hz: float = 4.0
    flush_interval_s: float = 1.0
    learn_max_hz: float = 30.0

    def __post_init__(self) -> None:
        self.gate()  # checks its own ranges
        check_range("live.backoff_initial_s", self.backoff_initial_s, 0.0, 60.0, lo_open=True)
        check_range("live.backoff_max_s", self.backoff_max_s, self.backoff_initial_s, 600.0)
        check_range("live.status_hz", self.status_hz, 0.0, 60.0, lo_open=True)
        check_range("live.flush_interval_s", self.flush_interval_s, 0.0, 3600.0, lo_open=True)

    def gate(self) -> GateConfig:
        return GateConfig(self.countdown_s, self.motion_threshold_mm, self.motion_fraction,
                          self.learn_max_hz)


@dataclass(frozen=True)
class LiveStatus:
    """A snapshot for the status line. phase: waiting | learning | running | reconnecting."""

    phase: str
    message: str
    fps: float
    ms_per_frame: float
    processed: int
    dropped: int
    touches: int
    reconnects: int
    countdown_s: float | None = None
    learn_progress: float = 0.0


def format_status(s: LiveStatus) -> str:
    """The one-line text of a status snapshot."""
    head = (f"{s.fps:4.1f} fps {s.ms_per_frame:4.1f} ms/frame dropped {s.dropped} "
            f"touches {s.touches}")
    if s.reconnects:
        head += f" reconnects {s.reconnects}"
    return f"[{s.phase}] {head}" + (f"  | {s.message}" if s.message else "")


@dataclass
class LiveResult:
    """Counts of a run: frames received from the source(s), processed, dropped (stale),
    reconnects, learning restarts (motion), events sent, and the frame latency in the loop
    (arrival to processing start, ms)."""

    received: int = 0
    processed: int = 0
    dropped: int = 0
    reconnects: int = 0
    learn_restarts: int = 0
    events: int = 0
    sink_errors: int = 0
    latency_ms_mean: float = 0.0
    latency_ms_max: float = 0.0
    interrupted: bool = False

    def describe(self) -> str:
        return (
            f"{self.processed} frames processed, {self.dropped} dropped (stale), "
            f"{self.events} events, {self.reconnects} reconnects, latency "
            f"{self.latency_ms_mean:.1f} ms mean / {self.latency_ms_max:.1f} ms max"
        )


class StatusBoard:
    """Turns the stream's results into :class:`LiveStatus` snapshots, a few a second.

    stream: the camera stream (dropped frames, reconnects); gate: the learning gate (countdown);
    emit: called with each snapshot (e.g. :class:`RichStatusLine`); clock: monotonic seconds.
    """

    def __init__(self, stream: CameraStream, gate: LearningGate | None,
                 emit: Callable[[LiveStatus], None] | None, status_hz: float = 4.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.stream, self.gate, self.emit, self.clock = stream, gate, emit, clock
        self.status_hz = status_hz
        self.processed = 0
        self.phase = "learning"
        self.message = ""
        self.learn_progress = 0.0
        self._active: set[int] = set()
        self._times: collections.deque[float] = collections.deque(maxlen=120)
        self._ms_ewma = 0.0
        self._last_s: float | None = None
        self._last_key: tuple[str, str] | None = None
        self._t_in: float | None = None

    def __call__(self, result: FrameResult) -> None:
        now = self.clock()
        self.processed += 1
        for e in result.events:
            (self._active.discard if e.state == "up" else self._active.add)(e.id)
        ms = result.timing_ms.get("total")
        if ms is not None:
            self._ms_ewma = ms if self._ms_ewma == 0 else 0.9 * self._ms_ewma + 0.1 * ms
        self._times.append(now)
        self.learn_progress = result.learn_progress
        if result.learning:
            gate = self.gate
            self.phase = gate.phase if gate is not None else "learning"
            self.message = result.note
        elif result.status == "ended":
            pass
        else:
            if self.phase in ("waiting", "learning"):
                self.message = "surface learned: touch away"
            self.phase = "running"
        self.update(now)

    def snapshot(self) -> LiveStatus:
        times = self._times
        fps = 0.0
        if len(times) >= 2:
            recent = [t for t in times if t >= times[-1] - 2.0]
            if len(recent) >= 2 and recent[-1] > recent[0]:
                fps = (len(recent) - 1) / (recent[-1] - recent[0])
        s = self.stream
        phase, message = ((s.phase, s.message) if s.phase == "reconnecting"
                          else (self.phase, self.message))
        countdown = (self.gate.countdown_left_s if self.gate is not None and phase == "waiting"
                     else None)
        return LiveStatus(phase=phase, message=message, fps=fps, ms_per_frame=self._ms_ewma,
                          processed=self.processed, dropped=s.dropped, touches=len(self._active),
                          reconnects=s.counts.reconnects, countdown_s=countdown,
                          learn_progress=self.learn_progress)

    def update(self, now: float | None = None, force: bool = False) -> None:
        """Emit a snapshot when one is due (or the phase or message changed)."""
        if self.emit is None:
            return
        now = self.clock() if now is None else now
        snap = self.snapshot()
        key = (snap.phase, snap.message)
        due = self._last_s is None or now - self._last_s >= 1.0 / self.status_hz
        if force or due or key != self._last_key:
            self._last_s, self._last_key = now, key
            self.emit(snap)


class LiveLoop:
    """A live run: camera stream -> pipeline -> sinks, with the status board.

    source_factory: opens the source; called again after a disconnect (see CameraStream).
    pipeline: a :class:`~depthtouch.pipeline.Pipeline`, made with ``gate=loop.gate`` so that
        it learns the surface only from a still scene (:meth:`make_gate`).
    sinks: outputs; the loop never closes them. status: called with :class:`LiveStatus`.
    pace: True for recordings (played at their own pace in the camera thread).
    """

    def __init__(
        self,
        source_factory: Callable[[], DepthSource],
        pipeline: Any,
        sinks: Sequence[Sink] = (),
        *,
        config: LiveConfig | None = None,
        gate: LearningGate | None = None,
        clock: Callable[[], float] = time.monotonic,
        status: Callable[[LiveStatus], None] | None = None,
        pace: bool = False,
    ) -> None:
        self.config = config or LiveConfig()
        self.pipeline, self.sinks, self.clock, self.gate = pipeline, list(sinks), clock, gate
        self.stop = threading.Event()
        pacer = Pacer(1.0, clock=clock, wait=lambda s: self.stop.wait(s)) if pace else None
        self.stream = CameraStream(
            source_factory, stop=self.stop, pace=pacer.until if pacer else None,
            backoff_initial_s=self.config.backoff_initial_s,
            backoff_max_s=self.config.backoff_max_s, clock=clock,
            on_idle=lambda: self.board.update(force=self.stream.phase == "reconnecting"),
        )
        self.board = StatusBoard(self.stream, gate, status, self.config.status_hz, clock)
        self.stats = DriveStats(keep=1000)
        self.result = LiveResult()

    def run(self, max_frames: int | None = None,
            stop_event: threading.Event | None = None) -> LiveResult:
        """Run until the source ends, ``max_frames`` frames were processed or ``stop_event`` is
        set; returns the counts. Touches still down get their ``up`` at the end. Ctrl-C ends it
        the same way (``interrupted``)."""
        if stop_event is not None:  # the caller's event ends the stream and the loop
            self.stop = self.stream.stop = stop_event
        try:
            drive(self.stream, self.pipeline, self.sinks, stop=self.stop, max_frames=max_frames,
                  on_result=self.board, lenient=True,
                  flush_interval_s=self.config.flush_interval_s, clock=self.clock,
                  stats=self.stats)
        except KeyboardInterrupt:
            self.result.interrupted = True
        finally:
            self.stop.set()
        s, c, r = self.stats, self.stream.counts, self.result
        r.processed, r.events, r.sink_errors = s.frames, s.events, s.sink_errors
        r.received, r.dropped, r.reconnects = c.received, self.stream.dropped, c.reconnects
        r.latency_ms_mean, r.latency_ms_max = c.latency_ms_mean, c.latency_ms_max
        r.learn_restarts = self.gate.restarts if self.gate is not None else 0
        return r


# --- terminal front end ------------------------------------------------------------------------
class RichStatusLine:
    """One rich status line on stderr, updated in place (plain lines when not a terminal)."""

    def __init__(self) -> None:
        from rich.console import Console
        from rich.live import Live
        from rich.text import Text

        self._text = Text
        self._console = Console(stderr=True)
        self._live = Live(Text(""), console=self._console, refresh_per_second=8,
                          transient=False, auto_refresh=self._console.is_terminal)
        self._last_plain = ""

    def __enter__(self) -> RichStatusLine:
        if self._console.is_terminal:
            self._live.start()
        return self

    def __call__(self, s: LiveStatus) -> None:
        line = format_status(s)
        if self._console.is_terminal:
            self._live.update(self._text(line, no_wrap=True, overflow="ellipsis"))
        elif s.phase != "running" and s.message != self._last_plain:
            self._last_plain = s.message  # logs: only the prompts, not the 4 Hz numbers
            self._console.print(line, highlight=False, markup=False, soft_wrap=True)

    def __exit__(self, *exc: object) -> None:
        if self._console.is_terminal:
            self._live.stop()


def run_live(
    source: str | Callable[[], DepthSource],
    *,
    config: Any = None,
    events_path: str | Path | None = None,
    tuio: str | None = None,
    uinput: bool = False,
    serve: str | None = None,
    calibration_path: str | Path | None = None,
    surface_path: str | Path | None = None,
    save_surface_path: str | Path | None = None,
    source_options: dict[str, Any] | None = None,
    live_config: LiveConfig | None = None,
    max_seconds: float | None = None,
    show_status: bool = True,
    extra_sinks: Sequence[Sink] = (),
) -> LiveResult:
    """``depthtouch run``: open the source, the outputs and the pipeline, run until Ctrl-C
    (or ``max_seconds`` of wall time, or the end of a recording), then close everything; the
    events file is committed on Ctrl-C too.

    source: a spec for :func:`~depthtouch.sources.open_source` (cameras stream live, recordings
    and ``sim:`` are paced at their own timestamps) or a factory returning a source.
    tuio: "HOST:PORT" for TUIO 1.1 over UDP. uinput: also a virtual touchscreen (Linux).
    serve: "HOST:PORT" for the web page.
    """
    from .outputs import open_outputs
    from .pipeline import Pipeline
    from .sources import is_live_spec, open_source
    from .surface.model import load_surface
    from .web.serve import WebPage

    live_config = live_config or LiveConfig()
    surface = load_surface(surface_path) if surface_path else None
    gate = LearningGate(live_config.gate())
    outputs = open_outputs(events_path=events_path, tuio=tuio, calibration_path=calibration_path,
                           uinput=uinput)
    pipeline = Pipeline(config, surface=surface, calibration=outputs.calibration, gate=gate)
    if isinstance(source, str):
        spec, options = source, source_options or {}
        name, opener, pace = spec, lambda: open_source(spec, **options), not is_live_spec(spec)
    else:
        name, opener, pace = "source", source, False

    def factory() -> DepthSource:
        src = opener()
        if surface is not None and surface.resolution_wh != src.resolution_wh:
            src.close()
            (sw, sh), (w, h) = surface.resolution_wh, src.resolution_wh
            raise SurfaceError(
                f"the surface file is {sw}x{sh} but {src.name} gives {w}x{h}; learn the surface "
                "again (omit --surface) or pick the same --resolution"
            )
        return src

    timer: threading.Timer | None = None
    with outputs, contextlib.ExitStack() as stack:
        sinks: list[Sink] = [*outputs.sinks, *extra_sinks]
        if serve:
            page = stack.enter_context(WebPage(serve, pipeline, source_name=name))
            sinks += page.sinks
        status = stack.enter_context(RichStatusLine()) if show_status else None
        loop = LiveLoop(factory, pipeline, sinks, config=live_config, gate=gate, status=status,
                        pace=pace)
        if max_seconds:
            timer = threading.Timer(max_seconds, loop.stop.set)
            timer.daemon = True
            timer.start()
        try:
            result = loop.run()
        finally:
            if timer is not None:
                timer.cancel()
        outputs.commit()  # after a clean end or Ctrl-C; on errors the events file is not kept
    if save_surface_path and not pipeline.learning:
        pipeline.surface.save(save_surface_path)
    return result
