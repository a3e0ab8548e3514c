"""Outputs: where touch events go (JSON Lines file, TUIO over UDP, WebSocket for the web page).

:func:`open_outputs` opens the ones a command asked for, together, so that a failure to open a
later one leaves nothing behind of the earlier ones (no temporary events file)::

    with open_outputs(events_path="touches.jsonl", tuio="127.0.0.1:3333") as outputs:
        drive(source, Pipeline(calibration=outputs.calibration), outputs.sinks)
        outputs.commit()
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from types import TracebackType
from typing import Any

from .base import Sink, SinkBase

__all__ = ["Outputs", "Sink", "SinkBase", "open_outputs"]


class Outputs:
    """The sinks of one run and the screen calibration they share.

    :meth:`commit` marks the run as complete: on close the events file is then moved into place
    (after a clean end or Ctrl-C); closed without it (an error), no events file is kept.
    """

    def __init__(self, sinks: list[Sink], calibration: Any | None) -> None:
        self.sinks, self.calibration = sinks, calibration
        self.committed = False
        self.written: list[str] = []

    def commit(self) -> None:
        self.committed = True

    def close(self) -> None:
        from .jsonl import JsonlSink

        for s in self.sinks:
            with contextlib.suppress(Exception):
                if isinstance(s, JsonlSink):
                    s.close(commit=self.committed)
                    if self.committed:
                        self.written.append(str(s.path))
                else:
                    s.close()

    def __enter__(self) -> Outputs:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is KeyboardInterrupt:
            self.committed = True  # Ctrl-C is a way to end a run: keep what it made
        self.close()


def open_outputs(
    *,
    events_path: str | Path | None = None,
    tuio: str | None = None,
    calibration_path: str | Path | None = None,
    calibration: Any | None = None,
    uinput: bool = False,
) -> Outputs:
    """Open the outputs a command asked for: an events file, a TUIO sender ("HOST:PORT"), a
    virtual touchscreen (Linux uinput; without a calibration it takes the depth image's size at
    the first frame).

    calibration_path: a screen calibration to load (or ``calibration``, already loaded); the
    pipeline adds ``sx``, ``sy`` with it and TUIO normalises to its screen.
    """
    if calibration is None and calibration_path:
        from ..calibration import load_calibration

        calibration = load_calibration(calibration_path)
    sinks: list[Sink] = []
    try:
        if events_path:
            from .jsonl import JsonlSink

            sinks.append(JsonlSink(events_path))
        if tuio:
            from ..checks import parse_address
            from .tuio import DEFAULT_PORT, TuioSink

            host, port = parse_address(tuio, what="TUIO address", default_port=DEFAULT_PORT)
            screen_wh = calibration.screen_wh if calibration is not None else None
            sinks.append(TuioSink(host, port, screen_wh=screen_wh))
        if uinput:
            from .uinput import UinputSink

            sinks.append(UinputSink(calibration=calibration))
    except BaseException:
        Outputs(sinks, calibration).close()  # not committed: the ones already open keep nothing
        raise
    return Outputs(sinks, calibration)
