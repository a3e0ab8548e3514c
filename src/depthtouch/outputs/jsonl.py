"""JSON Lines events file (docs/formats.md, section 2).

Written to a temporary file beside the target and renamed into place on close, so that a run that
fails never leaves a half-written events file; ``flush()`` makes the lines so far durable in the
temporary file for long live runs.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path
from types import TracebackType

from ..errors import OutputError
from ..files import AtomicTextFile
from ..types import FrameResult, TouchEvent
from .base import SinkBase


class JsonlSink(SinkBase):
    """Writes one line per event; ``close(commit=True)`` moves the file into place."""

    def __init__(self, path: str | Path) -> None:
        self._file = AtomicTextFile(path, what="the events")
        self.path = self._file.path
        self.count = 0

    def send(self, result: FrameResult) -> None:
        fh = self._file.fh
        if fh is None:
            raise OutputError(f"{self.path}: events file already closed")
        for ev in result.events:
            fh.write(json.dumps(ev.to_dict(), separators=(", ", ": ")) + "\n")
        self.count += len(result.events)

    def flush(self) -> None:
        if self._file.fh is not None:
            self._file.fh.flush()

    def close(self, commit: bool = True) -> None:
        self._file.close(commit)

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        # A run that ends with an error other than Ctrl-C keeps no partial file.
        self.close(commit=exc_type is None or exc_type is KeyboardInterrupt)


_STATES = ("down", "move", "up")


def parse_event(obj: object) -> TouchEvent:
    """A decoded JSON line -> TouchEvent; ValueError naming the first bad field.

    ``frame`` and ``id`` are whole numbers >= 0, ``t``, ``x``, ``y`` finite numbers, ``state`` one
    of down, move, up; unknown fields are kept in ``extra``.
    """
    if not isinstance(obj, dict):
        raise ValueError(f"expected a JSON object, got {type(obj).__name__}")
    for key in ("frame", "t", "id", "state", "x", "y"):
        if key not in obj:
            raise ValueError(f"no {key!r} field")
    for key in ("frame", "id"):
        v = obj[key]
        if not isinstance(v, int) or isinstance(v, bool) or v < 0:
            raise ValueError(f"{key} = {_short(v)} must be a whole number >= 0")
    for key in ("t", "x", "y"):
        v = obj[key]
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
            raise ValueError(f"{key} = {_short(v)} must be a finite number")
    if obj["state"] not in _STATES:
        raise ValueError(f"state = {_short(obj['state'])} must be down, move or up")
    return TouchEvent.from_dict(obj)


def _short(value: object, limit: int = 30) -> str:
    r = " ".join(repr(value).split())
    return r if len(r) <= limit else r[: limit - 3] + "..."


def read_events(path: str | Path) -> Iterator[TouchEvent]:
    """Read an events file back; a malformed line raises OutputError with its line number."""
    p = Path(path)
    try:
        fh = p.open(encoding="utf-8")
    except OSError as e:
        raise OutputError(f"{p}: cannot read events ({e.strerror}); check the path") from e
    with fh:
        n = 0
        while True:
            try:
                line = fh.readline()
            except UnicodeDecodeError:
                raise OutputError(
                    f"{p}:{n + 1}: not UTF-8 text; give a JSON Lines events file"
                ) from None
            if not line:
                return
            n += 1
            if not line.strip():
                continue
            try:
                obj = json.loads(line)
            except (ValueError, RecursionError) as e:
                # JSONDecodeError is a ValueError; deep nesting exhausts the recursion limit
                raise OutputError(
                    f"{p}:{n}: not JSON ({type(e).__name__}); see docs/formats.md"
                ) from None
            try:
                event = parse_event(obj)
            except ValueError as e:
                raise OutputError(
                    f"{p}:{n}: not a touch event ({e}); see docs/formats.md"
                ) from None
            yield event
