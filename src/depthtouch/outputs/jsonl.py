"""JSON Lines events file (docs/formats.md, section 2).

Written to a temporary file beside the target and renamed into place on close, so that a run that
fails never leaves a half-written events file; ``flush()`` makes the lines so far durable in the
temporary file for long live runs.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from ..errors import OutputError
from ..types import Frame, TouchEvent
from .base import SinkBase


class JsonlSink(SinkBase):
    """Writes one line per event; ``close(commit=True)`` moves the file into place."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        parent = self.path.parent if str(self.path.parent) else Path(".")
        if self.path.is_dir():
            raise OutputError(f"{self.path}: is a folder; give a file name for the events")
        if not parent.is_dir():
            raise OutputError(f"{self.path}: folder {parent} does not exist; create it first")
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".part", dir=parent)
        except OSError as e:
            raise OutputError(f"{self.path}: cannot write here ({e.strerror}); choose another path") from e
        self._tmp = Path(tmp)
        self._fh: IO[str] | None = os.fdopen(fd, "w", encoding="utf-8")
        self.count = 0

    def send(self, frame: Frame, events: list[TouchEvent]) -> None:
        fh = self._fh
        if fh is None:
            raise OutputError(f"{self.path}: events file already closed")
        for ev in events:
            fh.write(json.dumps(ev.to_dict(), separators=(", ", ": ")) + "\n")
        self.count += len(events)

    def flush(self) -> None:
        if self._fh is not None:
            self._fh.flush()

    def close(self, commit: bool = True) -> None:
        fh, self._fh = self._fh, None
        if fh is None:
            return
        fh.close()
        if commit:
            os.replace(self._tmp, self.path)
        else:
            self._tmp.unlink(missing_ok=True)

    def __exit__(self, exc_type, exc, tb) -> None:  # type: ignore[no-untyped-def]
        # A run that ends with an error other than Ctrl-C keeps no partial file.
        self.close(commit=exc_type is None or exc_type is KeyboardInterrupt)


def read_events(path: str | Path) -> Iterator[TouchEvent]:
    """Read an events file back; a malformed line raises OutputError with its line number."""
    p = Path(path)
    try:
        fh = p.open(encoding="utf-8")
    except OSError as e:
        raise OutputError(f"{p}: cannot read events ({e.strerror}); check the path") from e
    with fh:
        for n, line in enumerate(fh, 1):
            if not line.strip():
                continue
            try:
                yield TouchEvent.from_dict(json.loads(line))
            except (ValueError, KeyError, TypeError) as e:
                raise OutputError(f"{p}:{n}: not a touch event ({e}); see docs/formats.md") from e
