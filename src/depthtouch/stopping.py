"""Stop requests (SIGTERM, SIGHUP, Ctrl-C) honoured by the processing loops between frames.

A Python signal handler that raises runs in the main thread at the next bytecode, which may be
inside a compiled kernel's dispatch: numba then reports a ``SystemError`` instead of the
``KeyboardInterrupt``, and the command's cleanup sees an error (the events file is dropped). So a
loop that runs the pipeline in the main thread *listens*: the handler only calls
:func:`request`, and the loop stops at its next frame, ends the touches still down and closes
its outputs as at the end of a recording. Without a listener the handler raises as before.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator

_requested = threading.Event()
_listeners: list[Callable[[], None]] = []


def request() -> bool:
    """Ask the running loop to stop; True when a loop listens (it stops at its next frame)."""
    _requested.set()
    for callback in list(_listeners):
        callback()
    return bool(_listeners)


def requested() -> bool:
    """True once a stop was requested (until :func:`reset`)."""
    return _requested.is_set()


def reset() -> None:
    """Forget an earlier request (a new command starts)."""
    _requested.clear()


@contextlib.contextmanager
def listen(callback: Callable[[], None] | None = None) -> Iterator[None]:
    """While inside, stop requests are left to the caller's loop (``callback`` is called on
    each, e.g. an Event's ``set``; else the loop polls :func:`requested`)."""
    cb = callback if callback is not None else (lambda: None)
    _listeners.append(cb)
    try:
        if _requested.is_set():
            cb()
        yield
    finally:
        _listeners.remove(cb)
