"""``depthtouch play EVENTS.jsonl``: play a recorded touch-events file into outputs.

Drives an application with a recorded session (or an automated UI test) through the virtual
touchscreen (``--uinput``) and/or TUIO, paced by the events' timestamps (``fast=True`` skips the
waits). It reads only the events file: nothing here imports the pipeline or its compiled kernels,
so it starts quickly, also inside an emulated machine.

Positions: the events' ``sx``, ``sy`` when present (a calibrated replay), else ``x``, ``y``. Their
range is the calibration's screen (``calibration_path``) or ``screen_wh_px``.

Every contact is lifted when play ends, on an error, on Ctrl-C and on SIGTERM (which ends play
normally, ``terminated=True``).
"""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np

from ..calibration import apply_calibration
from ..errors import ConfigError
from ..types import Frame, FrameResult, TouchEvent, TouchPoints
from .base import EventSink
from .jsonl import read_events


@dataclass
class PlaySummary:
    """What a play did."""

    path: str
    frames: int = 0
    events: int = 0
    touches: int = 0
    seconds: float = 0.0
    terminated: bool = False
    outputs: tuple[str, ...] = ()

    def describe(self) -> str:
        end = " (stopped by SIGTERM)" if self.terminated else ""
        return (f"{self.path}: {self.events} events of {self.touches} touches in {self.frames} "
                f"frames played in {self.seconds:.2f} s to {', '.join(self.outputs)}{end}")


def group_frames(events: Iterable[TouchEvent]) -> Iterator[list[TouchEvent]]:
    """Consecutive events with the same frame number -> one list per frame, in file order."""
    batch: list[TouchEvent] = []
    for e in events:
        if batch and e.frame != batch[0].frame:
            yield batch
            batch = []
        batch.append(e)
    if batch:
        yield batch


class _Terminated(Exception):
    """SIGTERM arrived: stop playing, lift every contact, end normally."""


class _SigtermStops:
    """While installed, SIGTERM raises _Terminated in the main thread, but never inside
    :meth:`atomic` (a frame half written to a device): there it takes effect at the block's end."""

    def __init__(self) -> None:
        self._critical = False
        self._pending = False
        self._previous: Any = None

    def _handler(self, signum: int, frame: FrameType | None) -> None:
        if self._critical:
            self._pending = True
        else:
            raise _Terminated

    @contextlib.contextmanager
    def atomic(self) -> Iterator[None]:
        self._critical = True
        try:
            yield
        finally:
            self._critical = False
        if self._pending:
            raise _Terminated

    def __enter__(self) -> _SigtermStops:
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGTERM, self._handler)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGTERM, self._previous)


def _screen(calibration_path: str | Path | None, screen_wh_px: tuple[int, int] | None) -> Any:
    """The calibration to map with: the file's, or an identity over ``screen_wh_px``."""
    from ..calibration import Calibration, load_calibration

    if calibration_path is not None and screen_wh_px is not None:
        raise ConfigError("give --screen or --calibration, not both (the calibration has a size)")
    if calibration_path is not None:
        return load_calibration(calibration_path)
    if screen_wh_px is None:
        raise ConfigError(
            "play needs the positions' range: --calibration FILE (the replay's) or --screen WxH"
        )
    return Calibration(np.eye(3), screen_wh_px, 0.0)


def open_sinks(
    calibration: Any, *, uinput: bool, tuio: str | None, uinput_settle_s: float = 0.5,
) -> list[tuple[str, EventSink]]:
    """The outputs play writes to, as (description, sink); errors close what was opened."""
    sinks: list[tuple[str, EventSink]] = []
    try:
        if uinput:
            from .uinput import UinputSink

            w, h = calibration.screen_wh
            sinks.append((f"uinput {w}x{h}", UinputSink(
                calibration=calibration, settle_s=uinput_settle_s)))
        if tuio:
            from .tuio import TuioSink, parse_hostport

            host, port = parse_hostport(tuio)
            sinks.append((f"TUIO {host}:{port}",
                          TuioSink(host, port, screen_wh=calibration.screen_wh)))
    except BaseException:
        for _, s in sinks:
            s.close()
        raise
    return sinks


def play(
    events_path: str | Path,
    *,
    uinput: bool = False,
    tuio: str | None = None,
    calibration_path: str | Path | None = None,
    screen_wh_px: tuple[int, int] | None = None,
    fast: bool = False,
    uinput_settle_s: float = 0.5,
    sleep: Callable[[float], None] = time.sleep,
    clock: Callable[[], float] = time.monotonic,
) -> PlaySummary:
    """Play ``events_path`` into the outputs asked for (at least one of ``uinput``, ``tuio``).

    fast: send frame after frame without waiting; otherwise each frame is sent when the wall
    time since the first one equals its ``t`` minus the first ``t`` (a late frame is sent at once).
    uinput_settle_s: wait after creating the virtual touchscreen, seconds [0, 10] (default 0.5).
    Raises OutputError / ConfigError / CalibrationError (one line) before anything is sent.
    """
    if not uinput and not tuio:
        raise ConfigError("play has no output; give --uinput and/or --tuio HOST:PORT")
    path = Path(events_path)
    batches = group_frames(read_events(path))
    first = next(batches, None)  # reads (and checks) the start of the file before any output
    calibration = _screen(calibration_path, screen_wh_px)
    w, h = calibration.screen_wh
    # the sinks' protocol takes a frame; only its time and size are used here (no pixel memory)
    canvas = np.broadcast_to(np.zeros(1, np.uint16), (h, w))
    summary = PlaySummary(str(path))
    touched: set[int] = set()
    start = clock()
    try:
        with _SigtermStops() as sigterm, contextlib.ExitStack() as stack:
            opened = open_sinks(calibration, uinput=uinput, tuio=tuio,
                                uinput_settle_s=uinput_settle_s)
            for _, s in opened:
                stack.callback(s.close)
            summary.outputs = tuple(name for name, _ in opened)
            start = clock()
            t0 = first[0].t if first else 0.0
            for batch in _chain(first, batches):
                if not fast:
                    delay = (batch[0].t - t0) - (clock() - start)
                    if delay > 0:
                        sleep(delay)
                frame = Frame(canvas, batch[0].t, batch[0].frame)
                # events recorded without a calibration get their screen position here, once
                if any("sx" not in e.extra for e in batch):
                    batch = [e if "sx" in e.extra else apply_calibration([e], calibration)[0]
                             for e in batch]
                result = FrameResult(frame, batch, TouchPoints.empty(), "ok")
                with sigterm.atomic():
                    for _, s in opened:
                        s.send(result)
                summary.frames += 1
                summary.events += len(batch)
                touched.update(e.id for e in batch)
    except _Terminated:  # the sinks are closed (every contact lifted) on the way out
        summary.terminated = True
    summary.touches = len(touched)
    summary.seconds = clock() - start
    return summary


def _chain(first: list[TouchEvent] | None, rest: Iterator[list[TouchEvent]]
           ) -> Iterator[list[TouchEvent]]:
    if first is not None:
        yield first
        yield from rest
