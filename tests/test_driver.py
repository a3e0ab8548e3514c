"""The one loop: results to every sink, touches ended at the end, at a gap, on a stop and on
Ctrl-C; sink errors raised for recordings and counted for live streams."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from depthtouch.driver import drive
from depthtouch.errors import OutputError
from depthtouch.types import Frame, FrameResult, StreamGap, TouchEvent, TouchPoints


def frames(n: int) -> list[Frame]:
    return [Frame(np.zeros((4, 4), np.uint16), i / 30.0, i) for i in range(n)]


class OneTouch:
    """A touch down from the first frame on; ``finish`` lifts it."""

    def __init__(self) -> None:
        self.down = False
        self.last: Frame | None = None
        self.finishes = 0

    def process(self, frame: Frame) -> FrameResult:
        self.last = frame
        state = "move" if self.down else "down"
        self.down = True
        ev = TouchEvent(frame.index, frame.timestamp_s, 1, state, 1.0, 2.0)  # type: ignore[arg-type]
        return FrameResult(frame, [ev], TouchPoints.empty(), "ok", {"total": 0.1})

    def finish(self) -> FrameResult | None:
        self.finishes += 1
        if not self.down or self.last is None:
            return None
        self.down = False
        f = self.last
        up = TouchEvent(f.index, f.timestamp_s, 1, "up", 1.0, 2.0)
        return FrameResult(f, [up], TouchPoints.empty(), "ended")


class Collect:
    def __init__(self, fail_at: int | None = None) -> None:
        self.results: list[FrameResult] = []
        self.fail_at = fail_at

    def send(self, result: FrameResult) -> None:
        if self.fail_at is not None and result.frame.index == self.fail_at:
            raise OutputError("disk full; free space")
        self.results.append(result)

    def close(self) -> None:
        pass

    def states(self) -> list[str]:
        return [e.state for r in self.results for e in r.events]


class Listed:
    def __init__(self, items: list[Frame | StreamGap]) -> None:
        self.items = items

    def frames(self):  # type: ignore[no-untyped-def]
        yield from self.items


def test_every_result_reaches_every_sink_and_touches_end() -> None:
    a, b = Collect(), Collect()
    stats = drive(Listed(frames(5)), OneTouch(), [a, b])
    assert a.states() == b.states() == ["down", "move", "move", "move", "move", "up"]
    assert (stats.frames, stats.events, stats.touches) == (5, 6, 1)
    assert stats.ms_per_frame == [0.1] * 5 and a.results[-1].status == "ended"


def test_a_gap_ends_the_touches_down() -> None:
    f = frames(4)
    sink = Collect()
    stats = drive(Listed([f[0], f[1], StreamGap("camera lost"), f[2], f[3]]), OneTouch(), [sink])
    assert sink.states() == ["down", "move", "up", "down", "move", "up"] and stats.gaps == 1


def test_stop_and_max_frames() -> None:
    stop = threading.Event()
    sink = Collect()
    pipe = OneTouch()
    original = pipe.process

    def process(frame: Frame) -> FrameResult:
        if frame.index == 3:
            stop.set()
        return original(frame)

    pipe.process = process  # type: ignore[method-assign]
    assert drive(Listed(frames(10)), pipe, [sink], stop=stop).frames == 4
    assert sink.states()[-1] == "up"
    assert drive(Listed(frames(10)), OneTouch(), [Collect()], max_frames=2).frames == 2


def test_sink_errors_raise_for_recordings_and_are_counted_live() -> None:
    with pytest.raises(OutputError, match="disk full"):
        drive(Listed(frames(5)), OneTouch(), [Collect(fail_at=2)])
    stats = drive(Listed(frames(5)), OneTouch(), [Collect(fail_at=2)], lenient=True)
    assert stats.sink_errors == 1 and stats.frames == 5


def test_ctrl_c_ends_the_touches_then_is_raised() -> None:
    class Interrupted(Listed):
        def frames(self):  # type: ignore[no-untyped-def]
            yield from self.items[:3]
            raise KeyboardInterrupt

    sink = Collect()
    with pytest.raises(KeyboardInterrupt):
        drive(Interrupted(frames(5)), OneTouch(), [sink])
    assert sink.states() == ["down", "move", "move", "up"]


def test_stop_wait_takes_no_lock_and_a_signal_ends_it() -> None:
    """The paced loop's wait (stopping.wait) never takes the event's lock: Event.wait holds it
    for a moment, and a stop signal landing then blocked its own handler's set() for ever. It
    returns True as soon as a signal handler sets the event, False after its time otherwise."""
    import signal
    import time

    from depthtouch import stopping

    ev = threading.Event()
    with ev._cond:  # held by this thread, as inside Event.wait: a lock-taking wait would hang
        assert stopping.wait(ev, 0.03) is False
    old = signal.signal(signal.SIGALRM, lambda *_: ev.set())
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.05)
        t0 = time.monotonic()
        assert stopping.wait(ev, 5.0) is True
        assert time.monotonic() - t0 < 1.0
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
