"""The output-sink protocol: every sink gets every frame's result (its touch events on it).

Sinks are called once per frame even when there are no events (TUIO resends ``alive`` while
idle). A sink must never block or crash the pipeline: network errors are counted and logged
once, not raised from :meth:`send`. Sinks read the coordinates the pipeline put on the events
(``sx``, ``sy`` when calibrated; ``X``, ``Y``, ``Z``); they never compute them again.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from ..types import Closing, FrameResult


@runtime_checkable
class Sink(Protocol):
    def send(self, result: FrameResult) -> None: ...

    def close(self) -> None: ...


#: The former name of :class:`Sink`.
EventSink = Sink


class SinkBase(Closing):
    """Context-manager plumbing for sinks."""

    def send(self, result: FrameResult) -> None:  # pragma: no cover
        raise NotImplementedError

    def close(self) -> None:
        """Flush and release; safe to call twice."""
