"""The live loop (``depthtouch run``): a camera, the pipeline and the outputs, kept running.

- A reader thread pulls frames from the source into a one-slot mailbox that keeps only the
  newest frame: when processing falls behind, stale frames are dropped (and counted), never
  queued, so latency stays bounded by about one frame interval plus the processing time.
- Before the surface is learned, the scene must stay still for a countdown (the user is asked
  to clear the surface while it moves); motion during learning restarts it.
- A camera that stops delivering (unplugged, USB reset) is closed and reopened with
  exponential back-off while the outputs stay open; touches that were down get their ``up``.
- Frame timestamps drive the pipeline (re-based to start at 0 and kept increasing across
  reconnects); the loop's own clock only paces retries and the status line.

:class:`LiveLoop` is the testable core (no terminal); :func:`run_live` wires a source spec,
the pipeline, the outputs and a rich status line for the CLI.
"""

from __future__ import annotations

import collections
import contextlib
import dataclasses
import logging
import math
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import cv2
import numpy as np

from .errors import ConfigError, DepthTouchError, SourceError, SurfaceError
from .outputs.base import EventSink
from .sources.base import DepthSource, SourceBase
from .types import Frame, TouchEvent

log = logging.getLogger(__name__)

#: Source specs that are cameras (frames arrive at the device's pace); anything else is a
#: recording or the simulator, which ``run`` plays at its recorded pace, like a camera.
LIVE_PREFIXES = ("realsense", "openni")


class PipelineLike(Protocol):
    """What the loop needs of :class:`depthtouch.pipeline.Pipeline`."""

    @property
    def learning(self) -> bool: ...

    @property
    def learn_progress(self) -> float: ...

    def process(self, frame: Frame) -> list[TouchEvent]: ...

    def reset(self) -> None: ...


@dataclass(frozen=True)
class LiveConfig:
    """Settings of the live loop.

    countdown_s: seconds the scene must stay still before the surface is learned (default 3.0,
        range [0, 60]; frame time).
    motion_threshold_mm: a pixel moved when its depth changed by more than this against the
        reference frame (default 15 mm, range (0, 500]; D435 noise is ~4 mm RMS at 1 m).
    motion_fraction: the scene moves when more than this share of valid pixels moved
        (default 0.01, range (0, 1]).
    backoff_initial_s: first wait before reopening a lost camera (default 0.5 s, (0, 60]).
    backoff_max_s: longest wait between attempts; the wait doubles up to it (default 8 s).
    status_hz: status-line updates per second (default 4, range (0, 60]).
    flush_interval_s: sinks with ``flush()`` (the events file) are flushed this often
        (default 1.0 s, range (0, 3600]).
    learn_max_hz: the surface is learned from at most this many frames per second (default 30,
        range (0, 1000]); a 90 Hz camera would otherwise triple the frames kept and the time
        the final surface computation blocks the loop, for no better surface.
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
        checks = (
            ("countdown_s", self.countdown_s, 0.0, 60.0, False),
            ("motion_threshold_mm", self.motion_threshold_mm, 0.0, 500.0, True),
            ("motion_fraction", self.motion_fraction, 0.0, 1.0, True),
            ("backoff_initial_s", self.backoff_initial_s, 0.0, 60.0, True),
            ("backoff_max_s", self.backoff_max_s, self.backoff_initial_s, 600.0, False),
            ("status_hz", self.status_hz, 0.0, 60.0, True),
            ("flush_interval_s", self.flush_interval_s, 0.0, 3600.0, True),
            ("learn_max_hz", self.learn_max_hz, 0.0, 1000.0, True),
        )
        for name, v, lo, hi, lo_open in checks:
            if not (v > lo if lo_open else v >= lo) or not v <= hi:
                lb = "(" if lo_open else "["
                raise ConfigError(f"live.{name} = {v!r} is out of range; allowed {lb}{lo}, {hi}]")


# --- pure per-frame maths ---------------------------------------------------------------------
def motion_fraction(
    reference: np.ndarray, depth: np.ndarray, depth_scale_m: float, threshold_mm: float,
    step_px: int = 2,
) -> float:
    """Share of pixels (valid in both frames) whose depth changed by more than ``threshold_mm``.

    reference, depth: uint16 (H, W) in units of ``depth_scale_m`` metres; 0 = no data.
    step_px: sample every step-th row and column (default 2; motion is never one pixel wide).
    Returns a value in [0, 1]; 0 when no pixel is valid in both.
    """
    if reference.shape != depth.shape:
        return 1.0  # another resolution: certainly not the same scene
    a = reference[::step_px, ::step_px]
    b = depth[::step_px, ::step_px]
    valid = (a > 0) & (b > 0)
    n = int(np.count_nonzero(valid))
    if n == 0:
        return 0.0
    diff = cv2.absdiff(a, b)
    units = threshold_mm / (depth_scale_m * 1000.0)
    moved = np.count_nonzero((diff > units) & valid)
    return float(moved) / n


class StillnessGate:
    """Tells how long (frame time) the scene has been still against a reference frame.

    A frame that differs from the reference by more than the thresholds (see
    :func:`motion_fraction`) becomes the new reference and restarts the still time.
    """

    def __init__(self, threshold_mm: float = 15.0, max_fraction: float = 0.01) -> None:
        self.threshold_mm = threshold_mm
        self.max_fraction = max_fraction
        self.reset()

    def reset(self) -> None:
        self._ref: np.ndarray | None = None
        self._since_s = 0.0
        self.last_motion_s: float | None = None
        self.last_fraction = 0.0
        self.moved = False

    def update(self, frame: Frame) -> float:
        """Seconds the scene has been still up to this frame (0 on the first or a moving one);
        ``moved`` tells whether this frame moved against the reference."""
        self.moved = False
        if self._ref is None:
            self._ref, self._since_s = frame.depth, frame.timestamp_s
            return 0.0
        f = motion_fraction(self._ref, frame.depth, frame.depth_scale_m, self.threshold_mm)
        self.last_fraction = f
        self.moved = f > self.max_fraction
        if self.moved:
            self._ref, self._since_s = frame.depth, frame.timestamp_s
            self.last_motion_s = frame.timestamp_s
            return 0.0
        return frame.timestamp_s - self._since_s


# --- the mailbox and the reader ----------------------------------------------------------------
@dataclass(frozen=True)
class Delivery:
    """A frame as taken from the mailbox: ``seq`` counts every frame the reader got (0-based),
    ``arrival_s`` is the loop clock when it arrived."""

    frame: Frame
    seq: int
    arrival_s: float


@dataclass(frozen=True)
class Ended:
    """The reader stopped: ``error`` is None when the source simply ended."""

    error: BaseException | None


class LatestFrameMailbox:
    """A one-slot, thread-safe mailbox: :meth:`put` replaces an unread frame (counted in
    ``dropped``), :meth:`get` takes the newest. After :meth:`finish`, :meth:`get` returns the
    unread frame (if any) and then :class:`Ended`."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._item: Delivery | None = None
        self._ended: Ended | None = None
        self.put_count = 0
        self.dropped = 0

    def put(self, item: Delivery) -> None:
        with self._cond:
            if self._item is not None:
                self.dropped += 1
            self._item = item
            self.put_count += 1
            self._cond.notify()

    def finish(self, error: BaseException | None) -> None:
        with self._cond:
            self._ended = Ended(error)
            self._cond.notify()

    def get(self, timeout_s: float) -> Delivery | Ended | None:
        """The newest frame, the end marker, or None after ``timeout_s`` without either."""
        with self._cond:
            if self._item is None and self._ended is None:
                self._cond.wait(timeout_s)
            item, self._item = self._item, None
            if item is not None:
                return item
            return self._ended


class _Reader(threading.Thread):
    def __init__(self, source: DepthSource, mailbox: LatestFrameMailbox,
                 clock: Callable[[], float]) -> None:
        super().__init__(name="depthtouch-reader", daemon=True)
        self.source, self.mailbox, self.clock = source, mailbox, clock
        self.stopping = threading.Event()

    def run(self) -> None:
        error: BaseException | None = None
        gen = self.source.frames()
        try:
            for seq, frame in enumerate(gen):
                if self.stopping.is_set():
                    break
                self.mailbox.put(Delivery(frame, seq, self.clock()))
        except BaseException as e:  # handed to the loop: SourceError = disconnect, else raised
            error = e
        finally:
            close = getattr(gen, "close", None)
            if close is not None:
                with contextlib.suppress(Exception):
                    close()
            self.mailbox.finish(error)


# --- status ------------------------------------------------------------------------------------
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


# --- the loop ----------------------------------------------------------------------------------
class LiveLoop:
    """Source -> pipeline -> sinks, live, with surface countdown, frame dropping and reconnects.

    source_factory: opens the source; called again after a disconnect. A SourceError on the
        first call ends :meth:`run` (no camera at start); later ones are retried with back-off.
    pipeline: a :class:`~depthtouch.pipeline.Pipeline` (or anything :class:`PipelineLike`);
        ``reset()`` is used to restart learning when the scene moved.
    sinks: outputs, called once per processed frame (also while waiting/learning, with no
        events); the loop never closes them.
    clock: seconds, monotonic (default ``time.monotonic``); for latency, fps and status only.
    status: called with a :class:`LiveStatus` a few times a second and on phase changes.
    """

    def __init__(
        self,
        source_factory: Callable[[], DepthSource],
        pipeline: PipelineLike,
        sinks: Sequence[EventSink] = (),
        *,
        config: LiveConfig | None = None,
        clock: Callable[[], float] = time.monotonic,
        status: Callable[[LiveStatus], None] | None = None,
    ) -> None:
        self.source_factory = source_factory
        self.pipeline = pipeline
        self.sinks = list(sinks)
        self.config = config or LiveConfig()
        self.clock = clock
        self.status = status
        self.result = LiveResult()
        self.gate = StillnessGate(self.config.motion_threshold_mm, self.config.motion_fraction)
        self.phase = "learning" if pipeline.learning else "running"
        self.message = ""
        self._active: set[int] = set()
        self._warned: set[str] = set()
        self._last_frame: Frame | None = None
        self._last_arrival = 0.0
        self._offset_s: float | None = None
        self._seq_base = 0
        self._dropped_before = 0
        self._mailbox: LatestFrameMailbox | None = None
        self._times: collections.deque[float] = collections.deque(maxlen=120)
        self._ms_ewma = 0.0
        self._latency_sum_ms = 0.0
        self._last_status_s: float | None = None
        self._last_status_key: tuple[str, str] | None = None
        self._last_flush_s: float | None = None
        self._countdown_left_s = self.config.countdown_s
        self._last_learn_t: float | None = None
        if self.phase == "learning":
            self.phase = "waiting" if self.config.countdown_s > 0 else "learning"

    # --- public -------------------------------------------------------------------------------
    def run(self, max_frames: int | None = None,
            stop_event: threading.Event | None = None) -> LiveResult:
        """Run until the source ends, ``max_frames`` frames were processed or ``stop_event`` is
        set; returns the counts. Touches still down get their ``up`` at the end."""
        stop = stop_event or threading.Event()
        source: DepthSource | None = self.source_factory()
        reader: _Reader | None = None
        try:
            while source is not None and not stop.is_set():
                mailbox = LatestFrameMailbox()
                self._mailbox = mailbox
                reader = _Reader(source, mailbox, self.clock)
                reader.start()
                ended = self._consume(mailbox, stop, max_frames)
                self._stop_reader(reader, source)
                reader = None
                self._close_session(mailbox)
                with contextlib.suppress(Exception):
                    source.close()
                source = None
                if ended is None or ended.error is None:
                    break
                if not isinstance(ended.error, SourceError):
                    raise ended.error
                self._end_touches()
                source = self._reopen(stop, ended.error)
        finally:
            if source is not None:
                if reader is not None:
                    self._stop_reader(reader, source)
                with contextlib.suppress(Exception):
                    source.close()
            if self._mailbox is not None:
                self._close_session(self._mailbox)
            self._end_touches()
            self._flush(force=True)
        return self.result

    # --- internals ----------------------------------------------------------------------------
    def _consume(self, mailbox: LatestFrameMailbox, stop: threading.Event,
                 max_frames: int | None) -> Ended | None:
        while not stop.is_set():
            if max_frames is not None and self.result.processed >= max_frames:
                return None
            item = mailbox.get(0.1)
            if item is None:
                self._emit(self.clock())
                continue
            if isinstance(item, Ended):
                return item
            self._handle(item)
        return None

    def _close_session(self, mailbox: LatestFrameMailbox) -> None:
        self._dropped_before += mailbox.dropped
        self._seq_base += mailbox.put_count
        self.result.received = self._seq_base
        self.result.dropped = self._dropped_before
        self._offset_s = None
        self._mailbox = None

    def _stop_reader(self, reader: _Reader, source: DepthSource) -> None:
        reader.stopping.set()
        reader.join(2.0)
        if reader.is_alive():  # stuck in a blocking read: closing the device releases it
            with contextlib.suppress(Exception):
                source.close()
            reader.join(2.0)

    def _reopen(self, stop: threading.Event, error: BaseException) -> DepthSource | None:
        delay = self.config.backoff_initial_s
        while not stop.is_set():
            self.phase = "reconnecting"
            self.message = f"camera lost ({error}); reopening in {delay:g} s"
            self._emit(self.clock(), force=True)
            if stop.wait(delay):
                return None
            try:
                source = self.source_factory()
            except SourceError as e:
                error = e
                delay = min(delay * 2.0, self.config.backoff_max_s)
                continue
            self.result.reconnects += 1
            if self.pipeline.learning:  # learning restarts on the new stream
                self.pipeline.reset()
                self._last_learn_t = None
                self.phase = "waiting" if self.config.countdown_s > 0 else "learning"
            else:
                self.phase = "running"
            self.message = "camera reopened"
            self.gate.reset()
            return source
        return None

    def _rebase(self, d: Delivery) -> Frame | None:
        f = d.frame
        last = self._last_frame
        if self._offset_s is None:
            base = 0.0 if last is None else (
                last.timestamp_s + max(d.arrival_s - self._last_arrival, 1e-3))
            self._offset_s = base - f.timestamp_s
        t = f.timestamp_s + self._offset_s
        if last is not None and t <= last.timestamp_s:
            return None
        return dataclasses.replace(f, timestamp_s=t, index=self._seq_base + d.seq)

    def _handle(self, d: Delivery) -> None:
        t0 = self.clock()
        frame = self._rebase(d)
        if frame is None:
            self._warn("time", "frames whose time does not increase are skipped")
            return
        latency_ms = max(0.0, (t0 - d.arrival_s) * 1000.0)
        events: list[TouchEvent] = []
        cfg = self.config
        if self.phase == "waiting":
            still_s = self.gate.update(frame)
            left = cfg.countdown_s - still_s
            self._countdown_left_s = max(left, 0.0)
            moving = (self.gate.last_motion_s is not None
                      and frame.timestamp_s - self.gate.last_motion_s < 0.5)
            secs = math.ceil(max(left, 0.0))
            self.message = ("the scene moves: clear the surface and keep still" if moving
                            else f"keep the surface clear: learning starts in {secs} s")
            if left <= 0:
                self.phase, self.message = "learning", "learning the surface: keep it clear"
        elif self.phase == "learning":
            self.gate.update(frame)
            if cfg.countdown_s > 0 and self.gate.moved:
                self.pipeline.reset()
                self._last_learn_t = None
                self.result.learn_restarts += 1
                self.phase = "waiting"
                self.message = "something moved while learning: clear the surface"
            elif self._learn_due(frame):
                events = self._process(frame)
                if not self.pipeline.learning:
                    self.phase, self.message = "running", "surface learned: touch away"
                else:
                    pct = 100.0 * float(self.pipeline.learn_progress)
                    self.message = f"learning the surface {pct:.0f}%: keep it clear"
        else:
            self.phase = "running"
            events = self._process(frame)
        self._send(frame, events)
        self._last_frame, self._last_arrival = frame, d.arrival_s
        t1 = self.clock()
        r = self.result
        r.processed += 1
        r.latency_ms_max = max(r.latency_ms_max, latency_ms)
        self._latency_sum_ms += latency_ms
        r.latency_ms_mean = self._latency_sum_ms / r.processed
        ms = (t1 - t0) * 1000.0
        self._ms_ewma = ms if r.processed == 1 else 0.9 * self._ms_ewma + 0.1 * ms
        self._times.append(t1)
        self._flush()
        self._emit(t1)

    def _learn_due(self, frame: Frame) -> bool:
        """Whether this frame goes to the surface learner (at most ``learn_max_hz``)."""
        last = self._last_learn_t
        # 5 % slack: a 30 Hz camera's intervals jitter around 1/30 s
        if last is not None and frame.timestamp_s - last < 0.95 / self.config.learn_max_hz:
            return False
        self._last_learn_t = frame.timestamp_s
        return True

    def _process(self, frame: Frame) -> list[TouchEvent]:
        try:
            return self.pipeline.process(frame)
        except (DepthTouchError, ValueError) as e:
            self._warn("pipeline", f"frame {frame.index} skipped: {e}")
            return []

    def _send(self, frame: Frame, events: list[TouchEvent]) -> None:
        for e in events:
            if e.state == "up":
                self._active.discard(e.id)
            else:
                self._active.add(e.id)
        self.result.events += len(events)
        for sink in self.sinks:
            try:
                sink.send(frame, events)
            except DepthTouchError as e:
                self.result.sink_errors += 1
                self._warn(f"sink{id(sink)}", f"{type(sink).__name__}: {e}")

    def _end_touches(self) -> None:
        finish = getattr(self.pipeline, "finish", None)
        if finish is None or self._last_frame is None or not self._active:
            return
        events = finish()
        if events:
            self._send(self._last_frame, events)

    def _flush(self, force: bool = False) -> None:
        now = self.clock()
        if not force and self._last_flush_s is not None and \
                now - self._last_flush_s < self.config.flush_interval_s:
            return
        self._last_flush_s = now
        for sink in self.sinks:
            flush = getattr(sink, "flush", None)
            if flush is not None:
                with contextlib.suppress(DepthTouchError, OSError):
                    flush()

    def _warn(self, key: str, message: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            log.warning("%s; further ones are counted, not shown", message)

    def snapshot(self) -> LiveStatus:
        times = self._times
        fps = 0.0
        if len(times) >= 2:
            recent = [t for t in times if t >= times[-1] - 2.0]
            if len(recent) >= 2 and recent[-1] > recent[0]:
                fps = (len(recent) - 1) / (recent[-1] - recent[0])
        dropped = self._dropped_before + (self._mailbox.dropped if self._mailbox else 0)
        countdown = self._countdown_left_s if self.phase == "waiting" else None
        return LiveStatus(
            phase=self.phase, message=self.message, fps=fps, ms_per_frame=self._ms_ewma,
            processed=self.result.processed, dropped=dropped, touches=len(self._active),
            reconnects=self.result.reconnects, countdown_s=countdown,
            learn_progress=float(self.pipeline.learn_progress),
        )

    def _emit(self, now: float, force: bool = False) -> None:
        if self.status is None:
            return
        key = (self.phase, self.message)
        due = (self._last_status_s is None
               or now - self._last_status_s >= 1.0 / self.config.status_hz)
        if force or due or key != self._last_status_key:
            self._last_status_s, self._last_status_key = now, key
            self.status(self.snapshot())


# --- sources for the live loop -----------------------------------------------------------------
class PacedSource(SourceBase):
    """Plays a recorded source at its own pace (frame timestamps), as a camera would deliver it.

    inner: any source. speed: playback speed factor (default 1.0, > 0).
    clock/sleep: injectable for tests (default ``time.monotonic`` / ``time.sleep``).
    """

    def __init__(self, inner: DepthSource, speed: float = 1.0, *,
                 clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        if not speed > 0:
            raise ConfigError(f"speed = {speed!r} is out of range; must be > 0")
        self.inner, self.speed, self._clock, self._sleep = inner, float(speed), clock, sleep
        self.name, self.depth_scale_m, self.K = inner.name, inner.depth_scale_m, inner.K
        self.fps, self.resolution_wh = inner.fps, inner.resolution_wh

    def frames(self) -> Iterator[Frame]:
        start: tuple[float, float] | None = None
        for f in self.inner.frames():
            if start is None:
                start = (self._clock(), f.timestamp_s)
            due = start[0] + (f.timestamp_s - start[1]) / self.speed
            wait = due - self._clock()
            if wait > 0:
                self._sleep(wait)
            yield f

    def close(self) -> None:
        self.inner.close()


def parse_web_address(text: str, default_port: int = 8765) -> tuple[str, int]:
    """``"HOST:PORT"``, ``"HOST"`` or ``":PORT"`` -> (host, port); ConfigError when malformed."""
    host, sep, port_text = str(text).strip().rpartition(":")
    if not sep:
        host, port_text = (("", port_text) if port_text.isdigit()
                           else (port_text, str(default_port)))
    host = host.strip("[]") or "127.0.0.1"
    if not port_text.isdigit() or not 0 <= int(port_text) <= 65535:
        raise ConfigError(f"web address {text!r} is not HOST:PORT; e.g. 127.0.0.1:8765")
    return host, int(port_text)


def is_live_spec(spec: str) -> bool:
    """True for camera specs (``realsense[:SERIAL]``, ``openni[:URI]``)."""
    text = str(spec)
    return any(text == p or text.startswith(p + ":") for p in LIVE_PREFIXES)


def source_factory_for(spec: str, **options: Any) -> Callable[[], DepthSource]:
    """A factory that opens ``spec``; recordings and the simulator are paced like a camera."""
    from .sources import open_source

    def factory() -> DepthSource:
        src = open_source(spec, **options)
        return src if is_live_spec(spec) else PacedSource(src)

    return factory


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


class _HeightPublisher:
    """Sends a few height maps per second to the web page (a sink)."""

    def __init__(self, server: Any, pipeline: Any) -> None:
        self.server, self.pipeline = server, pipeline

    def send(self, frame: Frame, events: list[TouchEvent]) -> None:
        if self.server.height_due(frame.timestamp_s):
            self.server.publish_height(frame, self.pipeline.height_map_mm(frame))

    def close(self) -> None:
        """Nothing to release (the server is stopped by its owner)."""


def run_live(
    source: str | Callable[[], DepthSource],
    *,
    config: Any = None,
    events_path: str | Path | None = None,
    tuio: str | None = None,
    serve: str | None = None,
    calibration_path: str | Path | None = None,
    surface_path: str | Path | None = None,
    save_surface_path: str | Path | None = None,
    source_options: dict[str, Any] | None = None,
    live_config: LiveConfig | None = None,
    max_seconds: float | None = None,
    show_status: bool = True,
) -> LiveResult:
    """``depthtouch run``: open the source, the outputs and the pipeline, run until Ctrl-C
    (or ``max_seconds`` of wall time, or the end of a recording), then close everything; the
    events file is committed on Ctrl-C too.

    source: a spec for :func:`~depthtouch.sources.open_source` (cameras stream live, recordings
    and ``sim:`` are paced at their own timestamps) or a factory returning a source.
    tuio: "HOST:PORT" for TUIO 1.1 over UDP. serve: "HOST:PORT" for the web page.
    """
    from .outputs.jsonl import JsonlSink
    from .pipeline import Pipeline
    from .runner import build_sinks, load_calibration_file

    calibration = load_calibration_file(calibration_path)
    surface = None
    if surface_path:
        from .surface.model import load_surface

        surface = load_surface(surface_path)
    pipeline = Pipeline(config, surface=surface, calibration=calibration)  # type: ignore[arg-type]
    if isinstance(source, str):
        name, opener = source, source_factory_for(source, **(source_options or {}))
    else:
        name, opener = "source", source

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
    stop = threading.Event()
    timer = threading.Timer(max_seconds, stop.set) if max_seconds else None
    sinks = build_sinks(events_path, tuio, calibration)
    completed = False
    try:
        with contextlib.ExitStack() as stack:
            if serve:
                from .web.server import WebServer

                host, port = parse_web_address(serve)
                server = WebServer(host, port, calibration=calibration, source_name=name)
                stack.enter_context(server)
                server.attach_pipeline(pipeline)
                sinks += [server.sink, _HeightPublisher(server, pipeline)]
                log.warning("web page: %s", server.url)
            status = stack.enter_context(RichStatusLine()) if show_status else None
            loop = LiveLoop(factory, pipeline, sinks, config=live_config, status=status)
            if timer is not None:
                timer.daemon = True
                timer.start()
            try:
                from . import stopping

                with stopping.listen(stop.set):  # SIGTERM / Ctrl-C end the loop between frames
                    loop.run(stop_event=stop)
            except KeyboardInterrupt:
                loop.result.interrupted = True
            completed = True
    finally:
        if timer is not None:
            timer.cancel()
        for sink in sinks:  # an events file is kept after a clean end or Ctrl-C, not on errors
            if isinstance(sink, JsonlSink):
                sink.close(commit=completed)
            else:
                sink.close()
    if save_surface_path and pipeline.surface is not None:
        pipeline.surface.save(save_surface_path)
    return loop.result
