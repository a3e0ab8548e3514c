"""The output-sink protocol: every sink gets every processed frame with its touch events.

Sinks are called once per frame even when there are no events (TUIO resends ``alive`` while
idle). A sink must never block or crash the pipeline: network errors are counted and logged
once, not raised from :meth:`send`.
"""

from __future__ import annotations

from types import TracebackType
from typing import Protocol, runtime_checkable

from ..types import Frame, TouchEvent


@runtime_checkable
class EventSink(Protocol):
    def send(self, frame: Frame, events: list[TouchEvent]) -> None: ...

    def close(self) -> None: ...


class SinkBase:
    """Context-manager plumbing for sinks."""

    def send(self, frame: Frame, events: list[TouchEvent]) -> None:  # pragma: no cover
        raise NotImplementedError

    def close(self) -> None:
        """Flush and release; safe to call twice."""

    def __enter__(self) -> SinkBase:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
