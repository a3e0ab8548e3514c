"""A camera as the loop wants it: newest frame first, times that increase, reconnects.

:class:`CameraStream` wraps a source factory:

- A reader thread pulls frames from the source into a one-slot mailbox that keeps only the
  newest frame: when processing falls behind, stale frames are dropped (and counted), never
  queued, so latency stays bounded by about one frame interval plus the processing time.
- A camera that stops delivering (unplugged, USB reset: a SourceError) is closed and reopened
  with exponential back-off; between the two streams a :class:`~depthtouch.types.StreamGap` is
  yielded, so that the touches that were down get their ``up``.
- Frame timestamps are re-based to start at 0 and kept increasing across reconnects; the loop's
  own clock only paces retries and measures latency.
- A recording (or the simulator) can be played through it at its own pace, as a camera would
  deliver it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import threading
import time
from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass

from ..errors import SourceError
from ..types import Frame, StreamGap, close_quietly
from .base import DepthSource

log = logging.getLogger(__name__)


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
                 clock: Callable[[], float], pace: Callable[[float], bool] | None) -> None:
        super().__init__(name="depthtouch-reader", daemon=True)
        self.source, self.mailbox, self.clock, self.pace = source, mailbox, clock, pace
        self.stopping = threading.Event()

    def run(self) -> None:
        error: BaseException | None = None
        gen = self.source.frames()
        try:
            for seq, frame in enumerate(gen):
                if self.stopping.is_set() or (
                        self.pace is not None and self.pace(frame.timestamp_s)):
                    break
                self.mailbox.put(Delivery(frame, seq, self.clock()))
        except BaseException as e:  # handed to the loop: SourceError = disconnect, else raised
            error = e
        finally:
            close_quietly(gen)
            self.mailbox.finish(error)


@dataclass
class StreamCounts:
    """Frames received from the source(s), dropped (stale), reconnects, and the latency of the
    frames handed on (arrival to hand-over, ms)."""

    received: int = 0
    dropped: int = 0
    reconnects: int = 0
    latency_ms_mean: float = 0.0
    latency_ms_max: float = 0.0


class CameraStream:
    """A source that yields the newest frame of a camera, and reopens it when it is lost.

    factory: opens the source; called again after a disconnect. A SourceError on the first call
        is raised (no camera at start); later ones are retried with back-off.
    stop: ends the stream (also while waiting for frames or for a camera).
    pace: for recordings, ``pace(t_s)`` waits for frame time ``t_s`` in the reader thread and
        returns True to stop (see :class:`depthtouch.driver.Pacer`); None for cameras.
    backoff_initial_s, backoff_max_s: first and longest wait between reopening attempts.
    on_idle: called about ten times a second while no frame comes (a status line stays alive).
    clock: seconds, monotonic; for latency and status only.
    """

    def __init__(
        self,
        factory: Callable[[], DepthSource],
        *,
        stop: threading.Event | None = None,
        pace: Callable[[float], bool] | None = None,
        backoff_initial_s: float = 0.5,
        backoff_max_s: float = 8.0,
        on_idle: Callable[[], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.factory, self.pace = factory, pace
        self.stop = stop or threading.Event()
        self.backoff_initial_s, self.backoff_max_s = backoff_initial_s, backoff_max_s
        self.on_idle, self.clock = on_idle, clock
        self.counts = StreamCounts()
        self.phase = "running"  # "reconnecting" while a lost camera is reopened
        self.message = ""
        self._mailbox: LatestFrameMailbox | None = None
        self._seq_base = 0
        self._dropped_before = 0
        self._latency_sum_ms = 0.0
        self._handed = 0
        self._last: tuple[float, float] | None = None  # (timestamp_s, arrival_s) handed last
        self._offset_s: float | None = None

    @property
    def dropped(self) -> int:
        return self._dropped_before + (self._mailbox.dropped if self._mailbox else 0)

    def frames(self) -> Iterator[Frame | StreamGap]:
        source: DepthSource | None = self.factory()
        reader: _Reader | None = None
        try:
            while source is not None and not self.stop.is_set():
                mailbox = LatestFrameMailbox()
                self._mailbox = mailbox
                reader = _Reader(source, mailbox, self.clock, self.pace)
                reader.start()
                ended = yield from self._consume(mailbox)
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
                yield StreamGap(f"camera lost ({ended.error})")
                source = self._reopen(ended.error)
        finally:
            if source is not None:
                if reader is not None:
                    self._stop_reader(reader, source)
                with contextlib.suppress(Exception):
                    source.close()
            if self._mailbox is not None:
                self._close_session(self._mailbox)

    def _consume(self, mailbox: LatestFrameMailbox) -> Generator[Frame, None, Ended | None]:
        """Frames of one session; returns the end marker (None when stopped)."""
        while not self.stop.is_set():
            item = mailbox.get(0.1)
            if item is None:
                if self.on_idle is not None:
                    self.on_idle()
                continue
            if isinstance(item, Ended):
                return item
            frame = self._rebase(item)
            if frame is None:
                log.debug("frame %d: time does not increase; skipped", item.frame.index)
                continue
            latency_ms = max(0.0, (self.clock() - item.arrival_s) * 1000.0)
            self._handed += 1
            self._latency_sum_ms += latency_ms
            c = self.counts
            c.latency_ms_max = max(c.latency_ms_max, latency_ms)
            c.latency_ms_mean = self._latency_sum_ms / self._handed
            c.received = self._seq_base + mailbox.put_count
            c.dropped = self.dropped
            self._last = (frame.timestamp_s, item.arrival_s)
            yield frame
        return None

    def _close_session(self, mailbox: LatestFrameMailbox) -> None:
        self._dropped_before += mailbox.dropped
        self._seq_base += mailbox.put_count
        self.counts.received = self._seq_base
        self.counts.dropped = self._dropped_before
        self._offset_s = None
        self._mailbox = None

    def _stop_reader(self, reader: _Reader, source: DepthSource) -> None:
        reader.stopping.set()
        reader.join(2.0)
        if reader.is_alive():  # stuck in a blocking read: closing the device releases it
            with contextlib.suppress(Exception):
                source.close()
            reader.join(2.0)

    def _reopen(self, error: BaseException) -> DepthSource | None:
        delay = self.backoff_initial_s
        while not self.stop.is_set():
            self.phase = "reconnecting"
            self.message = f"camera lost ({error}); reopening in {delay:g} s"
            if self.on_idle is not None:
                self.on_idle()
            if self.stop.wait(delay):
                return None
            try:
                source = self.factory()
            except SourceError as e:
                error = e
                delay = min(delay * 2.0, self.backoff_max_s)
                continue
            self.counts.reconnects += 1
            self.phase, self.message = "running", "camera reopened"
            return source
        return None

    def _rebase(self, d: Delivery) -> Frame | None:
        f = d.frame
        last = self._last
        if self._offset_s is None:
            base = 0.0 if last is None else last[0] + max(d.arrival_s - last[1], 1e-3)
            self._offset_s = base - f.timestamp_s
        t = f.timestamp_s + self._offset_s
        if last is not None and t <= last[0]:
            return None
        return dataclasses.replace(f, timestamp_s=t, index=self._seq_base + d.seq)
