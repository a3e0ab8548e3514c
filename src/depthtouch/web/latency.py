"""Event latency of the WebSocket output, for benchmarks.

:func:`measure_ws_latency` runs a :class:`~depthtouch.web.server.WebServer` on 127.0.0.1 with an
ephemeral port, connects aiohttp clients, publishes ``n_frames`` synthetic frames of touch
events through the server's sink (exactly as a processing loop does) and reports two delays:

- send: from the sink's ``send`` call (the frame has been processed) to the end of the server's
  ``send_str`` for that message (handed to the socket), per client;
- receive: from the same start to the message arriving in the client (includes the loopback
  hop and the client's own parsing loop; an upper bound of what a browser on this machine sees).

It also reports the time the processing thread spends in the sink's ``send`` (encoding and
handing over), which must stay small even when ``stalled_clients`` connected clients never read.
"""

from __future__ import annotations

import asyncio
import base64
import json
import os
import socket
import threading
import time
from typing import Any

import numpy as np
from aiohttp import ClientSession, WSMsgType

from ..types import TouchEvent
from .server import WebServer


def _percentiles(values_ms: list[float]) -> tuple[float, float]:
    if not values_ms:
        return float("nan"), float("nan")
    a = np.asarray(values_ms, dtype=np.float64)
    return float(np.median(a)), float(np.percentile(a, 95))


def _events(i: int, n_touches: int, fps: float) -> list[TouchEvent]:
    t = i / fps
    return [
        TouchEvent(i, t, k + 1, "down" if i == 0 else "move", 100.0 + 40 * k + i % 200,
                   120.0 + 0.5 * (i % 200), {"area": 60})
        for k in range(n_touches)
    ]


def stalled_client(port: int) -> socket.socket:
    """A WebSocket client that completes the handshake and never reads again."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # before connect: small window
    sock.settimeout(5.0)
    sock.connect(("127.0.0.1", port))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(
        (f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
         f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
         "Sec-WebSocket-Version: 13\r\n\r\n").encode()
    )
    return sock


def measure_ws_latency(
    n_frames: int = 300,
    *,
    n_touches: int = 2,
    clients: int = 1,
    stalled_clients: int = 0,
    interval_s: float = 1.0 / 60.0,
    timeout_s: float = 30.0,
) -> dict[str, Any]:
    """Median and 95th percentile, in ms, of the event latency (see the module doc).

    n_frames: frames published (default 300, >= 1). n_touches: events per frame (default 2).
    clients: connected WebSocket clients (default 1). stalled_clients: extra clients that never
    read (default 0; the server drops them after its ``drop_after_s``). interval_s: time between
    frames (default 1/60 s).
    Returns ``median_ms``, ``p95_ms`` (send), ``recv_median_ms``, ``recv_p95_ms``,
    ``publish_median_ms``, ``publish_max_ms`` (time in the sink's send), ``n_frames``,
    ``received`` (frame messages received by the reading clients), ``skipped`` (messages dropped
    from full client queues), ``dropped_clients`` and ``clients``.
    """
    if n_frames < 1 or clients < 1 or stalled_clients < 0:
        raise ValueError(
            f"n_frames = {n_frames} and clients = {clients} must be at least 1, "
            f"stalled_clients = {stalled_clients} at least 0"
        )
    server = WebServer("127.0.0.1", 0)  # default queue: 8 messages per client
    server.broadcaster.drop_after_s = 0.5
    server.broadcaster.send_timeout_s = 0.5
    server.start()
    stalled = [stalled_client(server.port) for _ in range(stalled_clients)]
    publish_ms: list[float] = []
    starts = np.full(n_frames, np.nan)
    recv_ms: list[float] = []
    received = [0]
    lock = threading.Lock()
    done = threading.Event()

    async def client() -> None:
        async with ClientSession() as session, session.ws_connect(f"{server.url}ws") as ws:
            async for msg in ws:
                if msg.type != WSMsgType.TEXT:
                    continue
                now = time.perf_counter()
                data = json.loads(msg.data)
                if data.get("type") != "frame":
                    continue
                i = int(data["frame"])
                with lock:
                    recv_ms.append((now - starts[i]) * 1000.0)
                    received[0] += 1
                if i == n_frames - 1:
                    break

    def run_clients() -> None:
        async def main() -> None:
            await asyncio.wait_for(
                asyncio.gather(*(client() for _ in range(clients))), timeout_s
            )

        try:
            asyncio.run(main())
        finally:
            done.set()

    thread = threading.Thread(target=run_clients, name="ws-latency-clients", daemon=True)
    try:
        thread.start()
        deadline = time.monotonic() + timeout_s
        want = clients + stalled_clients
        while server.broadcaster.n_clients < want and time.monotonic() < deadline:
            time.sleep(0.005)
        time.sleep(0.05)  # let the greeting go out before measuring
        server.broadcaster.latencies_ms.clear()
        skipped0 = server.broadcaster.skipped
        for i in range(n_frames):
            evs = _events(i, n_touches, 30.0)
            t0 = time.perf_counter()
            starts[i] = t0
            server.sink.publish(i, evs[0].t if evs else i / 30.0, evs, t0=t0)
            publish_ms.append((time.perf_counter() - t0) * 1000.0)
            time.sleep(interval_s)
        done.wait(timeout_s)
        send_ms = list(server.broadcaster.latencies_ms)
        skipped = server.broadcaster.skipped - skipped0
        dropped = server.broadcaster.dropped_clients
    finally:
        server.stop()
        thread.join(5.0)
        for sock in stalled:
            sock.close()
    send_med, send_p95 = _percentiles(send_ms)
    recv_med, recv_p95 = _percentiles(recv_ms)
    return {
        "median_ms": send_med,
        "p95_ms": send_p95,
        "recv_median_ms": recv_med,
        "recv_p95_ms": recv_p95,
        "publish_median_ms": float(np.median(publish_ms)) if publish_ms else float("nan"),
        "publish_max_ms": float(np.max(publish_ms)) if publish_ms else float("nan"),
        "n_frames": n_frames,
        "received": received[0],
        "skipped": skipped,
        "dropped_clients": dropped,
        "clients": clients,
    }
