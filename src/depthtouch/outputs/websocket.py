"""WebSocket stream of the touch events, for browser applications.

Three layers, each testable alone:

- :func:`frame_message` / :func:`encode_message`: pure encoding of one processed frame into the
  JSON text message ``{"type": "frame", "frame", "t", "touches": [...], "status": {...}}``.
- :class:`ClientQueue`: a per-client bounded queue that never blocks the producer; when full it
  drops the oldest item (the client skips frames) and counts what it dropped.
- :class:`Broadcaster`: the client registry living in the server's asyncio loop. The pipeline
  thread hands it a message with :meth:`Broadcaster.post` (never blocks: one
  ``call_soon_threadsafe``); one writer task per client drains that client's queue. A client
  whose queue stays full for ``drop_after_s`` or whose send takes longer than ``send_timeout_s``
  is closed, so a slow or vanished client never stalls the pipeline nor the other clients.

:class:`WebSocketSink` is the :class:`~depthtouch.outputs.base.EventSink` that the processing
loop calls per frame. The aiohttp server itself lives in :mod:`depthtouch.web.server`; nothing
here imports aiohttp (a client only needs ``send_str``, ``send_bytes`` and ``close`` coroutines).
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import json
import logging
import math
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from ..types import FrameResult, TouchEvent
from .base import SinkBase

log = logging.getLogger(__name__)

#: Item kinds carried by a client queue.
TEXT = "text"
BINARY = "binary"


def _touch_dict(ev: TouchEvent) -> dict[str, Any]:
    d = ev.to_dict()
    del d["frame"], d["t"]
    return d


def frame_message(
    frame_index: int,
    t_s: float,
    events: Sequence[TouchEvent],
    status: Mapping[str, Any],
) -> dict[str, Any]:
    """The JSON object sent for one processed frame.

    touches: one entry per event of the frame (``id``, ``state``, ``x``, ``y`` in depth-image
    pixels, then the optional fields such as ``sx``, ``sy``), in event order. A frame with no
    touches still produces a message (it carries the status line).
    """
    return {
        "type": "frame",
        "frame": int(frame_index),
        "t": round(float(t_s), 6),
        "touches": [_touch_dict(ev) for ev in events],
        "status": dict(status),
    }


def encode_message(message: Mapping[str, Any]) -> str:
    """Compact JSON text; NaN and infinities become null (browsers reject bare NaN)."""
    return json.dumps(_finite(message), separators=(",", ":"), allow_nan=False)


def _finite(obj: Any) -> Any:
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Mapping):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, np.generic):
        return _finite(obj.item())
    return obj


class ClientQueue:
    """Bounded FIFO of (kind, payload, t0) items that never blocks :meth:`put`.

    maxsize: items kept (default 8, >= 1); when full the oldest item is dropped and counted in
    ``skipped``. ``full_since_s`` is the loop time at which the queue last became full, None
    while it has room. Single-threaded: use it from the asyncio loop only.
    """

    def __init__(self, maxsize: int = 8) -> None:
        if maxsize < 1:
            raise ValueError(f"ClientQueue maxsize = {maxsize} must be at least 1")
        self.maxsize = maxsize
        self._items: collections.deque[tuple[str, str | bytes, float]] = collections.deque()
        self._ready = asyncio.Event()
        self.skipped = 0
        self.full_since_s: float | None = None

    def __len__(self) -> int:
        return len(self._items)

    def put(self, kind: str, payload: str | bytes, t0: float, now_s: float) -> int:
        """Add an item; returns how many old items were dropped to make room (0 or 1)."""
        dropped = 0
        if len(self._items) >= self.maxsize:
            self._items.popleft()
            self.skipped += 1
            dropped = 1
        self._items.append((kind, payload, t0))
        if len(self._items) >= self.maxsize:
            if self.full_since_s is None:
                self.full_since_s = now_s
        else:
            self.full_since_s = None
        self._ready.set()
        return dropped

    async def get(self) -> tuple[str, str | bytes, float]:
        """Wait for and remove the oldest item."""
        while not self._items:
            self._ready.clear()
            await self._ready.wait()
        item = self._items.popleft()
        self.full_since_s = None
        return item


class WebSocketLike(Protocol):
    async def send_str(self, data: str) -> None: ...

    async def send_bytes(self, data: bytes) -> None: ...

    async def close(self) -> Any: ...


@dataclass
class _Client:
    ws: WebSocketLike
    queue: ClientQueue
    abort: Callable[[], None] | None = None  # drops the connection without a close handshake
    task: asyncio.Task[None] | None = None
    sent: int = 0


class Broadcaster:
    """Fan-out of messages to WebSocket clients, bounded per client.

    queue_size: messages buffered per client before it skips frames (default 8).
    send_timeout_s: a single send slower than this closes the client (default 2.0).
    drop_after_s: a client whose queue stays full this long is closed (default 3.0).
    Latencies from :meth:`post` (``t0``) to the end of each text send are kept in
    ``latencies_ms`` (last 10 000) for benchmarks.
    """

    def __init__(
        self, queue_size: int = 8, send_timeout_s: float = 2.0, drop_after_s: float = 3.0
    ) -> None:
        if queue_size < 1:
            raise ValueError(f"queue_size = {queue_size} must be at least 1")
        self.queue_size = queue_size
        self.send_timeout_s = send_timeout_s
        self.drop_after_s = drop_after_s
        self.loop: asyncio.AbstractEventLoop | None = None
        self._clients: dict[int, _Client] = {}
        self.latencies_ms: collections.deque[float] = collections.deque(maxlen=10_000)
        self.skipped = 0
        self.dropped_clients = 0
        self._lock = threading.Lock()  # guards n_clients for readers in other threads
        self._n_clients = 0

    @property
    def n_clients(self) -> int:
        with self._lock:
            return self._n_clients

    def bind(self, loop: asyncio.AbstractEventLoop) -> None:
        """Attach to the loop that runs the server; posts before this are ignored."""
        self.loop = loop

    # --- called from any thread -----------------------------------------------------------------
    def post(self, kind: str, payload: str | bytes, t0: float | None = None) -> None:
        """Queue a message for every client without blocking; a no-op without a running loop."""
        loop = self.loop
        if loop is None or loop.is_closed() or self.n_clients == 0:
            return
        t = time.perf_counter() if t0 is None else t0
        with contextlib.suppress(RuntimeError):  # the loop closed between check and call
            loop.call_soon_threadsafe(self._fanout, kind, payload, t)

    # --- called in the loop ---------------------------------------------------------------------
    def add(self, ws: WebSocketLike, abort: Callable[[], None] | None = None) -> _Client:
        """Register a connected client and start its writer task.

        abort: closes the connection at once (the transport's ``abort``); used for clients that
        stopped reading, which could not complete a close handshake.
        """
        client = _Client(ws, ClientQueue(self.queue_size), abort)
        self._clients[id(ws)] = client
        with self._lock:
            self._n_clients = len(self._clients)
        client.task = asyncio.get_running_loop().create_task(self._writer(client))
        return client

    def remove(self, ws: WebSocketLike) -> None:
        """Forget a client and stop its writer (its handler ended, or it was dropped)."""
        client = self._clients.get(id(ws))
        if client is not None:
            self._forget(client)
            if client.task is not None:
                client.task.cancel()

    def _forget(self, client: _Client) -> None:
        self._clients.pop(id(client.ws), None)
        with self._lock:
            self._n_clients = len(self._clients)

    def send_to(self, ws: WebSocketLike, kind: str, payload: str | bytes) -> None:
        """Queue a message for one client (e.g. the greeting)."""
        client = self._clients.get(id(ws))
        if client is not None:
            client.queue.put(kind, payload, time.perf_counter(), self._now())

    def _now(self) -> float:
        return self.loop.time() if self.loop is not None else 0.0

    def _fanout(self, kind: str, payload: str | bytes, t0: float) -> None:
        now = self._now()
        for client in list(self._clients.values()):
            self.skipped += client.queue.put(kind, payload, t0, now)
            since = client.queue.full_since_s
            if since is not None and now - since > self.drop_after_s:
                log.warning("websocket client too slow for %.1f s; dropping it", now - since)
                self._drop(client)

    def _drop(self, client: _Client) -> None:
        self.dropped_clients += 1
        self.remove(client.ws)
        _abort(client)

    async def _writer(self, client: _Client) -> None:
        while True:
            kind, payload, t0 = await client.queue.get()
            try:
                if kind == TEXT:
                    text = payload if isinstance(payload, str) else payload.decode()
                    await asyncio.wait_for(client.ws.send_str(text), self.send_timeout_s)
                    self.latencies_ms.append((time.perf_counter() - t0) * 1000.0)
                else:
                    data = payload if isinstance(payload, bytes) else payload.encode()
                    await asyncio.wait_for(client.ws.send_bytes(data), self.send_timeout_s)
                client.sent += 1
            except asyncio.TimeoutError:
                log.warning("websocket send took over %.1f s; dropping the client",
                            self.send_timeout_s)
                self.dropped_clients += 1
                self._forget(client)
                _abort(client)
                return
            except Exception as e:  # gone (ConnectionError) or broken: forget this client
                if not isinstance(e, (ConnectionError, RuntimeError)):
                    log.warning("websocket send failed (%s); dropping the client", e)
                self._forget(client)
                return

    async def close_all(self) -> None:
        """Close every client (server shutdown): a close handshake, or abort when it stalls."""
        clients = list(self._clients.values())
        for client in clients:
            self.remove(client.ws)
        await asyncio.gather(*(_close_or_abort(c) for c in clients))


def _abort(client: _Client) -> None:
    if client.abort is not None:
        client.abort()
    else:
        asyncio.get_running_loop().create_task(_close_or_abort(client))


async def _close_or_abort(client: _Client) -> None:
    try:
        await asyncio.wait_for(client.ws.close(), 0.5)
    except (asyncio.TimeoutError, asyncio.CancelledError, ConnectionError, RuntimeError):
        # a client that stopped reading cannot take the close frame: cut the connection
        if client.abort is not None:
            client.abort()


class WebSocketSink(SinkBase):
    """Per-frame event sink that broadcasts each frame's events and a status line.

    broadcaster: where messages go (owned by :class:`depthtouch.web.server.WebServer`).
    Each frame's status line (ms per frame, learning) comes with its result; ``sx``, ``sy`` are
    the pipeline's, on the events.
    fps_window: frames over which fps is measured from the frame timestamps (default 30).

    :meth:`send` never blocks and never raises on a client problem.
    """

    def __init__(
        self,
        broadcaster: Broadcaster,
        fps_window: int = 30,
    ) -> None:
        self.broadcaster = broadcaster
        self._ms: float | None = None
        self._learning = False
        self._times: collections.deque[float] = collections.deque(maxlen=max(2, fps_window))
        self._active: set[int] = set()
        self.frames = 0
        self.on_resolution: Callable[[tuple[int, int]], None] | None = None
        self._resolution_wh: tuple[int, int] | None = None

    def reset(self) -> None:
        """Forget the fps history and the active touches (a new stream starts)."""
        self._times.clear()
        self._active.clear()

    def send(self, result: FrameResult) -> None:
        t0 = time.perf_counter()
        frame, events = result.frame, result.events
        total = result.timing_ms.get("total")
        if total is not None:
            self._ms = round(float(total), 3)
        elif result.learning:
            self._ms = None  # no touch path yet (a frame ending touches keeps the last figure)
        self._learning = result.learning
        wh = frame.resolution_wh
        if wh != self._resolution_wh:
            self._resolution_wh = wh
            if self.on_resolution is not None:
                self.on_resolution(wh)
        self.publish(frame.index, frame.timestamp_s, events, t0=t0)

    def publish(
        self,
        frame_index: int,
        t_s: float,
        events: Sequence[TouchEvent],
        t0: float | None = None,
    ) -> str:
        """Encode and broadcast one frame's events; returns the text sent (for tests)."""
        t0 = time.perf_counter() if t0 is None else t0
        if self._times and t_s <= self._times[-1]:
            self._times.clear()  # time went back: a looped recording restarted
        self._times.append(float(t_s))
        for ev in events:
            if ev.state == "up":
                self._active.discard(ev.id)
            else:
                self._active.add(ev.id)
        text = encode_message(frame_message(frame_index, t_s, events, self.status()))
        self.frames += 1
        self.broadcaster.post(TEXT, text, t0)
        return text

    def status(self) -> dict[str, Any]:
        """fps (from frame timestamps), ms_per_frame, touches (active ids), learning."""
        fps = None
        if len(self._times) >= 2 and self._times[-1] > self._times[0]:
            fps = round((len(self._times) - 1) / (self._times[-1] - self._times[0]), 2)
        return {"fps": fps, "ms_per_frame": self._ms, "touches": len(self._active),
                "learning": self._learning}

    def close(self) -> None:
        """Nothing to release: the server owns the connections."""
