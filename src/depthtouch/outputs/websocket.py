"""WebSocket stream of the touch events, for browser applications.

Three layers, each testable alone:

- :func:`frame_message` / :func:`gesture_message` / :func:`encode_message`: pure encoding of one
  processed frame into ``{"type": "frame", "frame", "t", "touches": [...], "status": {...}}``
  and of a recognised gesture into ``{"type": "gesture", "kind", ...}`` (docs/websocket.md; the
  JSON schemas are in ``depthtouch/web/protocol.schema.json``).
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

from ..gestures import GestureEvent, GestureRecognizer
from ..types import FrameResult, TouchEvent
from .base import SinkBase

log = logging.getLogger(__name__)

#: Item kinds carried by a client queue.
TEXT = "text"
BINARY = "binary"


#: The protocol version in ``hello``; bumped when a message changes incompatibly.
PROTOCOL_VERSION = 1
_DRAG_PHASES = {"drag_start": "start", "drag": "move", "drag_end": "end"}


def _touch_dict(ev: TouchEvent, unit_wh: tuple[float, float] | None = None) -> dict[str, Any]:
    d = ev.to_dict()
    del d["frame"], d["t"]
    if unit_wh is not None:  # normalised [0, 1] of the screen (calibrated) or the depth image
        x, y = (ev.extra["sx"], ev.extra["sy"]) if "sx" in ev.extra else (ev.x, ev.y)
        d["nx"] = round(min(max(float(x) / unit_wh[0], 0.0), 1.0), 6)
        d["ny"] = round(min(max(float(y) / unit_wh[1], 0.0), 1.0), 6)
    return d


def gesture_message(g: GestureEvent) -> dict[str, Any]:
    """The JSON object sent for a recognised gesture: :meth:`GestureEvent.to_dict`, with the
    three drag kinds as one ``drag`` kind and a ``phase`` (start, move, end)."""
    d = g.to_dict()
    if g.kind in _DRAG_PHASES:
        d["kind"], d["phase"] = "drag", _DRAG_PHASES[g.kind]
    return d


def frame_message(
    frame_index: int,
    t_s: float,
    events: Sequence[TouchEvent],
    status: Mapping[str, Any],
    unit_wh: tuple[float, float] | None = None,
) -> dict[str, Any]:
    """The JSON object sent for one processed frame.

    touches: one entry per event of the frame (``id``, ``state``, ``x``, ``y`` in depth-image
    pixels, then the optional fields such as ``sx``, ``sy`` in screen pixels), in event order;
    with ``unit_wh`` (the screen size when events carry ``sx``, else the depth image's) also
    ``nx``, ``ny`` normalised to [0, 1]. A frame with no touches still produces a message (it
    carries the status line).
    """
    return {
        "type": "frame",
        "frame": int(frame_index),
        "t": round(float(t_s), 6),
        "touches": [_touch_dict(ev, unit_wh) for ev in events],
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
    height: bool = False  # asked for height-map images


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
        self._lock = threading.Lock()  # guards the counts for readers in other threads
        self._n_clients = 0
        self._n_height = 0

    @property
    def n_clients(self) -> int:
        with self._lock:
            return self._n_clients

    @property
    def n_height_clients(self) -> int:
        """Clients that asked for height-map images (binary messages go only to them)."""
        with self._lock:
            return self._n_height

    def _count(self) -> None:
        with self._lock:
            self._n_clients = len(self._clients)
            self._n_height = sum(c.height for c in self._clients.values())

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
    def add(self, ws: WebSocketLike, abort: Callable[[], None] | None = None,
            height: bool = False) -> _Client:
        """Register a connected client and start its writer task.

        abort: closes the connection at once (the transport's ``abort``); used for clients that
        stopped reading, which could not complete a close handshake.
        height: the client wants the binary height-map images (default False).
        """
        client = _Client(ws, ClientQueue(self.queue_size), abort, height=height)
        self._clients[id(ws)] = client
        self._count()
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
        self._count()

    def subscribe(self, ws: WebSocketLike, height: bool) -> None:
        """Start or stop sending height-map images to one client."""
        client = self._clients.get(id(ws))
        if client is not None:
            client.height = bool(height)
            self._count()

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
            if kind == BINARY and not client.height:
                continue
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

    screen_wh: the calibrated screen's size (px), to normalise ``sx``, ``sy``; None: positions
    are normalised to the depth image.

    Each frame's events also feed a :class:`~depthtouch.gestures.GestureRecognizer` (depth
    pixels; its slop in mm once the result's surface knows its scale), whose gestures follow
    the frame message as ``gesture`` messages. :meth:`send` never blocks and never raises on a
    client problem.
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
        self._gestures: GestureRecognizer | None = None
        self._mm_per_px: float | None = None
        self.screen_wh: tuple[int, int] | None = None
        self.gestures_sent = 0

    def reset(self) -> None:
        """Forget the fps history, the active touches and the gestures (a new stream starts)."""
        self._times.clear()
        self._active.clear()
        self._gestures = None

    def _recognizer(self) -> GestureRecognizer:
        if self._gestures is None:
            self._gestures = GestureRecognizer(mm_per_px=self._mm_per_px)
        return self._gestures

    def send(self, result: FrameResult) -> None:
        t0 = time.perf_counter()
        frame, events = result.frame, result.events
        total = result.timing_ms.get("total")
        if total is not None:
            self._ms = round(float(total), 3)
        elif result.learning:
            self._ms = None  # no touch path yet (a frame ending touches keeps the last figure)
        self._learning = result.learning
        if self._mm_per_px is None and result.surface is not None:
            self._mm_per_px = getattr(result.surface, "mm_per_px", None)
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
        found = self._recognizer().update(frame_index, t_s, events) if (
            events or self._active) else []
        text = encode_message(frame_message(frame_index, t_s, events, self.status(),
                                            self._unit_wh(events)))
        self.frames += 1
        self.broadcaster.post(TEXT, text, t0)
        for g in found:
            self.broadcaster.post(TEXT, encode_message(gesture_message(g)), t0)
            self.gestures_sent += 1
        return text

    def _unit_wh(self, events: Sequence[TouchEvent]) -> tuple[float, float] | None:
        if any("sx" in ev.extra for ev in events):
            sw = self.screen_wh
            return (float(sw[0]), float(sw[1])) if sw is not None else None
        wh = self._resolution_wh
        return (float(wh[0]), float(wh[1])) if wh is not None else None

    def status(self) -> dict[str, Any]:
        """fps (from frame timestamps), ms_per_frame, touches (active ids), learning."""
        fps = None
        if len(self._times) >= 2 and self._times[-1] > self._times[0]:
            fps = round((len(self._times) - 1) / (self._times[-1] - self._times[0]), 2)
        return {"fps": fps, "ms_per_frame": self._ms, "touches": len(self._active),
                "learning": self._learning}

    def close(self) -> None:
        """Nothing to release: the server owns the connections."""
