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
import signal
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

_requested = threading.Event()
_listeners: list[Callable[[], None]] = []


def request() -> bool:
    """Ask the running loop to stop; True when a loop listens (it stops at its next frame)."""
    _requested.set()
    for callback in list(_listeners):
        callback()
    return bool(_listeners)


def wait(event: threading.Event, seconds: float, slice_s: float = 0.01) -> bool:
    """``event.wait(seconds)`` for the main thread, when a stop signal's handler sets ``event``
    (a :func:`listen` callback): True once it is set. It polls ``is_set`` in ``slice_s`` sleeps
    and never takes the event's lock. ``Event.wait`` holds that lock for a moment on the way in
    and out; a signal landing then ran the handler in the same thread, whose ``set`` waited for
    the lock its own thread held: the command hung (a replay paced in real time, about 1 run in
    40 of the signal tests)."""
    end = time.monotonic() + seconds
    while not event.is_set():
        left = end - time.monotonic()
        if left <= 0.0:
            return False
        time.sleep(min(left, slice_s))
    return True


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


STOP_SIGNALS = ("SIGTERM", "SIGHUP", "SIGINT")


def stop_on_signals() -> dict[int, Any]:
    """SIGTERM, SIGHUP and Ctrl-C stop the command: a loop that listens ends at its next frame;
    otherwise, or at a second signal, KeyboardInterrupt is raised and the command's Ctrl-C
    cleanup runs. Returns the handlers replaced (for :func:`restore`); main thread only."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    nums = [getattr(signal, n) for n in STOP_SIGNALS if hasattr(signal, n)]

    def stop(signum: int, frame: object) -> None:
        again = requested()
        if request() and not again:
            return
        for n in nums:  # the cleanup that follows must not be cut short by a third signal
            signal.signal(n, signal.SIG_IGN)
        raise KeyboardInterrupt

    return {n: signal.signal(n, stop) for n in nums}


def restore(handlers: dict[int, Any]) -> None:
    """Put back the handlers :func:`stop_on_signals` replaced."""
    for signum, handler in handlers.items():
        signal.signal(signum, handler)


def interrupted(e: BaseException) -> bool:
    """A KeyboardInterrupt, or one that a compiled kernel's dispatch turned into a SystemError."""
    seen: BaseException | None = e
    while seen is not None:
        if isinstance(seen, KeyboardInterrupt):
            return True
        seen = seen.__cause__ or seen.__context__
    return False
