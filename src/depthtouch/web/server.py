"""The local web server: static page, WebSocket event stream and the calibration endpoint.

:class:`WebServer` runs aiohttp in a background thread with its own asyncio loop, so any
processing loop can use it::

    server = WebServer("127.0.0.1", 8765)
    server.start()                      # binds; OutputError if the port is taken
    server.on_calibration = pipeline.set_calibration  # a fit on the page maps the events
    for frame in source.frames():
        result = pipeline.process(frame)
        server.sink.send(result)        # never blocks
        server.send_height(result)      # a few times per second, only to clients that asked
    server.stop()

(:class:`depthtouch.web.serve.WebPage` does this wiring for ``run --serve`` and ``serve``.)

Routes: ``GET /`` and ``GET /<name>`` serve only the files of ``web/static`` (read once at
construction; any other name is 404, so no path can leave the folder); ``GET /ws`` upgrades to a
WebSocket when the Origin header is the server's own, one of ``allowed_origins`` (``serve
--allow-origin``) or absent (non-browser clients); ``GET /ws?height=1`` also subscribes to the
height-map images; ``POST /api/calibration`` fits and saves a screen calibration from the page's
calibration flow.

WebSocket messages (docs/websocket.md; schemas in ``protocol.schema.json`` here), server to
client: text JSON ``hello`` (on connect, with the protocol ``version``), ``frame`` (every
processed frame, see :mod:`depthtouch.outputs.websocket`), ``gesture`` (tap, double tap, long
press, drag, pinch, rotate), ``meta`` (resolution changed), ``calibration`` (a calibration was
loaded or fitted), ``cameras`` (several cameras: each one's part of the screen, the overlaps and
its calibration targets; on connect and when one changes), ``reset`` (a looped recording
restarted), ``info`` (a line for the page);
binary: a JPEG of the colour height map, only to clients that asked for it. Client to server:
``{"type": "subscribe", "height": true | false}``; anything else is ignored.
"""

from __future__ import annotations

import asyncio
import ipaddress
import json
import logging
import threading
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import numpy as np
from aiohttp import WSMsgType, web

from ..errors import DepthTouchError, OutputError
from ..outputs.websocket import (
    BINARY,
    PROTOCOL_VERSION,
    TEXT,
    Broadcaster,
    WebSocketSink,
    encode_message,
)
from ..types import Frame, FrameResult, TouchEvent
from .calibrate import (
    camera_calibration_path,
    fit_and_save,
    parse_calibration_request,
    parse_camera,
)
from .cameras import CameraView, cameras_message
from .heightview import colorize_height, encode_jpeg

__all__ = ["WebServer", "colorize_height", "encode_jpeg", "fit_and_save",
           "parse_calibration_request"]

log = logging.getLogger(__name__)

STATIC_DIR = Path(__file__).parent / "static"
_CONTENT_TYPES = {
    ".html": "text/html",
    ".js": "text/javascript",
    ".css": "text/css",
    ".png": "image/png",
    ".svg": "image/svg+xml",
}


def _load_static(folder: Path) -> dict[str, tuple[bytes, str]]:
    files: dict[str, tuple[bytes, str]] = {}
    if not folder.is_dir():
        raise OutputError(f"{folder}: web files missing; reinstall depthtouch with its web files")
    for p in sorted(folder.iterdir()):
        ctype = _CONTENT_TYPES.get(p.suffix.lower())
        if p.is_file() and ctype is not None:
            files[p.name] = (p.read_bytes(), ctype)
    if "index.html" not in files:
        raise OutputError(f"{folder}: no index.html; reinstall depthtouch with its web files")
    return files


def _is_ip_literal(hostname: str) -> bool:
    try:
        ipaddress.ip_address(hostname.strip("[]"))
    except ValueError:
        return False
    return True


class WebServer:
    """Local web page + WebSocket stream, served from a background thread.

    host: interface to bind (default "127.0.0.1"; "0.0.0.0" exposes it to the network).
    port: TCP port (default 8765; 0 picks a free one, see :attr:`port` after :meth:`start`).
    calibration: a loaded Calibration (adds sx, sy to the events; the pad draws with them).
    calibration_out: where the page's calibration flow saves its fit (default calibration.json).
    pad_wh: drawing-pad size in screen pixels; calibration targets are placed in it
        (default (960, 540)).
    height_hz: most height-map images per second (default 5, range (0, 10]).
    height_range_mm: heights mapped to the colour scale (default (3, 80): surface noise below
        3 mm is flat, fingers in the touch band are blue to green, hands are red).
    queue_size: messages buffered per client before it skips frames (default 8).
    allowed_origins: extra browser origins allowed to connect (e.g. "http://myapp.local:8000").
    source_name: shown on the page.
    """

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 8765,
        *,
        calibration: Any | None = None,
        calibration_out: str | Path = "calibration.json",
        pad_wh: tuple[int, int] = (960, 540),
        height_hz: float = 5.0,
        height_range_mm: tuple[float, float] = (3.0, 80.0),
        queue_size: int = 8,
        allowed_origins: Iterable[str] = (),
        source_name: str = "",
        static_dir: Path = STATIC_DIR,
    ) -> None:
        if not 0 <= port <= 65535:
            raise OutputError(f"port {port} is out of range; give 0..65535 (0 = any free port)")
        if not 0.0 < height_hz <= 10.0:
            raise OutputError(f"height_hz = {height_hz} is out of range; allowed (0, 10]")
        if pad_wh[0] < 16 or pad_wh[1] < 16:
            raise OutputError(f"pad_wh = {pad_wh} is too small; give at least 16 x 16 pixels")
        self.host = host
        self._port = port
        self.calibration_out = Path(calibration_out)
        self.pad_wh = (int(pad_wh[0]), int(pad_wh[1]))
        self.height_hz = height_hz
        self.height_range_mm = height_range_mm
        self.allowed_origins = {o.rstrip("/") for o in allowed_origins}
        self.source_name = source_name
        self._static = _load_static(static_dir)
        self.broadcaster = Broadcaster(queue_size=queue_size)
        self.sink = WebSocketSink(self.broadcaster)
        self.sink.on_resolution = self.set_resolution
        self.resolution_wh: tuple[int, int] | None = None
        self.calibration: Any | None = None
        self.calibration_error_px: float | None = None
        self.on_calibration: Callable[[Any], None] | None = None
        #: several cameras: camera k's calibration fitted on the page goes here (k, calibration)
        self.on_camera_calibration: Callable[[int, Any], None] | None = None
        self._cameras: dict[str, Any] | None = None  # the last ``cameras`` message
        if calibration is not None:
            self.set_calibration(calibration)
        self._last_height_t: float | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._start_error: BaseException | None = None
        self._runner: web.AppRunner | None = None

    # --- lifecycle ------------------------------------------------------------------------------
    @property
    def port(self) -> int:
        """The bound port (the chosen one when constructed with port 0 and started)."""
        return self._port

    @property
    def url(self) -> str:
        host = "127.0.0.1" if self.host in ("0.0.0.0", "") else self.host
        if ":" in host:
            host = f"[{host}]"
        return f"http://{host}:{self.port}/"

    def start(self) -> WebServer:
        """Bind and serve in a background thread; OutputError when the address cannot be bound."""
        if self._thread is not None:
            return self
        self._thread = threading.Thread(target=self._run, name="depthtouch-web", daemon=True)
        self._thread.start()
        if not self._ready.wait(15.0):
            raise OutputError("the web server did not start within 15 s; check the host and port")
        if self._start_error is not None:
            self._thread.join(2.0)
            self._thread = None
            e = self._start_error
            raise OutputError(
                f"cannot serve on {self.host}:{self._port} ({getattr(e, 'strerror', None) or e}); "
                "choose another --port or --host"
            ) from e
        return self

    def stop(self) -> None:
        """Close all clients and the listening socket; safe to call twice."""
        loop, thread = self._loop, self._thread
        if loop is None or thread is None:
            return
        if not loop.is_closed():
            loop.call_soon_threadsafe(loop.stop)
        thread.join(10.0)
        self._thread = None

    def __enter__(self) -> WebServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        self._loop = loop
        try:
            loop.run_until_complete(self._startup())
        except Exception as e:  # OSError (port taken, unknown host) or a bad host value
            self._start_error = e
            loop.run_until_complete(self._cleanup())
            loop.close()
            self._ready.set()
            return
        self.broadcaster.bind(loop)
        self._ready.set()
        try:
            loop.run_forever()
        finally:
            self.broadcaster.loop = None
            loop.run_until_complete(self.broadcaster.close_all())
            loop.run_until_complete(self._cleanup())
            loop.close()

    async def _startup(self) -> None:
        app = web.Application(client_max_size=256 * 1024)
        app.router.add_get("/", self._index)
        app.router.add_get("/ws", self._ws)
        app.router.add_post("/api/calibration", self._post_calibration)
        app.router.add_get("/{name}", self._file)
        self._runner = web.AppRunner(app, access_log=None, shutdown_timeout=1.0)
        await self._runner.setup()
        site = web.TCPSite(self._runner, self.host, self._port)
        await site.start()
        addresses = self._runner.addresses  # the bound socket tells the port chosen for 0
        if addresses:
            self._port = int(addresses[0][1])

    async def _cleanup(self) -> None:
        if self._runner is not None:
            await self._runner.cleanup()
            self._runner = None

    # --- publishing (any thread) ----------------------------------------------------------------
    def set_resolution(self, resolution_wh: tuple[int, int]) -> None:
        """Tell pages the depth-image size (sent automatically on the first frame)."""
        self.resolution_wh = (int(resolution_wh[0]), int(resolution_wh[1]))
        self.notify({"type": "meta", "resolution_wh": list(self.resolution_wh)})

    def set_calibration(self, calibration: Any | None, error_px: float | None = None) -> None:
        """Use this calibration for sx, sy from now on (``on_calibration`` hands it to the
        pipeline, which maps the events) and tell the pages."""
        self.calibration = calibration
        self.sink.screen_wh = tuple(calibration.screen_wh) if calibration is not None else None
        if self.on_calibration is not None:
            self.on_calibration(calibration)
        if error_px is None and calibration is not None:
            err = getattr(calibration, "reprojection_error_px", None)
            error_px = float(err) if err is not None else None
        self.calibration_error_px = error_px
        self.notify({"type": "calibration", **self._calibration_info()})

    def set_cameras(self, views: list[CameraView], screen_wh: tuple[int, int]) -> None:
        """Several cameras: each one's name, image size and calibration to the shared screen
        ``screen_wh``; the pages get their parts, overlaps and targets (a ``cameras`` message,
        also sent on connect)."""
        self._cameras = cameras_message(views, screen_wh)
        self.notify(self._cameras)

    @property
    def n_cameras(self) -> int:
        return len(self._cameras["cameras"]) if self._cameras is not None else 1

    def notify(self, message: dict[str, Any]) -> None:
        """Send a control message (JSON object with a ``type``) to every page."""
        self.broadcaster.post(TEXT, encode_message(message))

    def height_due(self, t_s: float) -> bool:
        """True when a height image should be sent for a frame at ``t_s`` (rate limit, clients)."""
        if self.broadcaster.n_height_clients == 0:
            return False
        last = self._last_height_t
        return last is None or t_s < last or t_s - last >= 1.0 / self.height_hz

    def send_height(self, result: FrameResult) -> bool:
        """Send the height map of a frame's result if one is due (a few per second, and only
        while a page is connected: the map is computed only then)."""
        if not self.height_due(result.frame.timestamp_s):
            return False
        return self.publish_height(result.frame, result.height_map_mm())

    def publish_height(self, frame: Frame, height_mm: np.ndarray) -> bool:
        """Send the colour height map of ``frame`` if due; returns whether it was sent."""
        if not self.height_due(frame.timestamp_s):
            return False
        self._last_height_t = frame.timestamp_s
        bgr = colorize_height(height_mm, *self.height_range_mm)
        self.broadcaster.post(BINARY, encode_jpeg(bgr))
        return True

    def inject(
        self,
        events: Sequence[TouchEvent],
        frame_index: int | None = None,
        t_s: float | None = None,
    ) -> str:
        """Broadcast touch events as if a frame produced them (tests and demos; no HTTP route)."""
        idx = frame_index if frame_index is not None else (events[0].frame if events else 0)
        t = t_s if t_s is not None else (events[0].t if events else 0.0)
        return self.sink.publish(idx, t, events)

    # --- HTTP handlers (loop thread) ------------------------------------------------------------
    def _own_origins(self, request: web.Request) -> set[str]:
        port = self.port
        hosts = {"127.0.0.1", "localhost", "[::1]"}
        if self.host not in ("", "0.0.0.0", "::"):
            hosts.add(f"[{self.host}]" if ":" in self.host else self.host)
        origins = {f"http://{h}:{port}" for h in hosts} | self.allowed_origins
        # Exposed on all interfaces: the page is reached through some address of this machine;
        # accept it when the browser used an IP literal (a DNS name could be rebound).
        req_host = urlsplit(f"http://{request.host}").hostname or ""
        if self.host in ("", "0.0.0.0", "::") and _is_ip_literal(req_host):
            origins.add(f"http://{request.host}")
        return origins

    def _origin_ok(self, request: web.Request) -> bool:
        origin = request.headers.get("Origin")
        if origin is None:
            return True  # not a browser: browsers always send Origin on WebSocket and POST
        return origin.rstrip("/") in self._own_origins(request)

    def _headers(self, request: web.Request, ctype: str) -> dict[str, str]:
        h = {
            "Cache-Control": "no-store",
            "X-Content-Type-Options": "nosniff",
            "Referrer-Policy": "no-referrer",
        }
        if ctype == "text/html":
            h["Content-Security-Policy"] = (
                "default-src 'self'; img-src 'self' blob: data:; "
                f"connect-src 'self' ws://{request.host}; frame-ancestors 'none'"
            )
        return h

    async def _index(self, request: web.Request) -> web.Response:
        return self._serve("index.html", request)

    async def _file(self, request: web.Request) -> web.Response:
        return self._serve(request.match_info["name"], request)

    def _serve(self, name: str, request: web.Request) -> web.Response:
        item = self._static.get(name)
        if item is None:
            return web.Response(status=404, text="not found\n")
        body, ctype = item
        charset = "utf-8" if ctype.startswith("text/") else None
        return web.Response(
            body=body, content_type=ctype, charset=charset, headers=self._headers(request, ctype)
        )

    def _calibration_info(self) -> dict[str, Any]:
        cal = self.calibration
        screen_wh = getattr(cal, "screen_wh", None) if cal is not None else None
        return {
            "loaded": cal is not None,
            "screen_wh": list(screen_wh) if screen_wh is not None else list(self.pad_wh),
            "error_px": self.calibration_error_px,
        }

    def _hello(self) -> dict[str, Any]:
        targets: list[list[float]] | None
        try:
            from ..calibration import default_targets

            targets = np.asarray(default_targets(self.pad_wh, n=4), dtype=float).tolist()
        except ImportError:
            targets = None
        return {
            "type": "hello",
            "version": PROTOCOL_VERSION,
            "source": self.source_name,
            "resolution_wh": list(self.resolution_wh) if self.resolution_wh else None,
            "pad_wh": list(self.pad_wh),
            "targets": targets,
            "calibration": self._calibration_info(),
            "calibration_out": str(self.calibration_out),
        }

    async def _ws(self, request: web.Request) -> web.StreamResponse:
        if not self._origin_ok(request):
            log.warning("refused a WebSocket from origin %s", request.headers.get("Origin"))
            return web.Response(status=403, text="origin not allowed\n")
        ws = web.WebSocketResponse(heartbeat=15.0, max_msg_size=64 * 1024)
        await ws.prepare(request)
        transport = request.transport
        height = request.query.get("height", "0").lower() in ("1", "true", "yes")
        self.broadcaster.add(ws, abort=transport.abort if transport is not None else None,
                             height=height)
        self.broadcaster.send_to(ws, TEXT, encode_message({**self._hello(), "height": height}))
        if self._cameras is not None:
            self.broadcaster.send_to(ws, TEXT, encode_message(self._cameras))
        try:
            async for msg in ws:
                if msg.type == WSMsgType.ERROR:
                    break
                if msg.type == WSMsgType.TEXT:
                    self._client_message(ws, msg.data)
        finally:
            self.broadcaster.remove(ws)
        return ws

    def _client_message(self, ws: web.WebSocketResponse, data: str) -> None:
        """``{"type": "subscribe", "height": bool}``; anything else (or not JSON) is ignored."""
        try:
            msg = json.loads(data)
        except ValueError:
            return
        if isinstance(msg, dict) and msg.get("type") == "subscribe" and isinstance(
                msg.get("height"), bool):
            self.broadcaster.subscribe(ws, msg["height"])

    async def _post_calibration(self, request: web.Request) -> web.Response:
        if not self._origin_ok(request):
            return web.json_response({"ok": False, "error": "origin not allowed"}, status=403)
        if request.content_type != "application/json":
            return web.json_response(
                {"ok": False, "error": "send the calibration pairs as application/json"},
                status=415,
            )
        out = self.calibration_out
        try:
            payload = await request.json()
            depth_xy, screen_xy, screen_wh = parse_calibration_request(payload)
            shared = self._cameras["screen_wh"] if self._cameras is not None else None
            cam = parse_camera(payload, self.n_cameras, screen_wh, shared)
            out = camera_calibration_path(self.calibration_out, cam)
            loop = asyncio.get_running_loop()
            cal = await loop.run_in_executor(
                None, fit_and_save, depth_xy, screen_xy, screen_wh, out
            )
        except (json.JSONDecodeError, UnicodeDecodeError):
            return web.json_response({"ok": False, "error": "the body is not JSON"}, status=400)
        except (DepthTouchError, ValueError) as e:
            return web.json_response({"ok": False, "error": str(e)}, status=400)
        except OSError as e:
            return web.json_response(
                {"ok": False, "error": f"cannot save {out}: {e.strerror or e}; "
                 "check --calibration-out"},
                status=500,
            )
        err = float(cal.reprojection_error_px)
        if cam is None:
            self.set_calibration(cal, err)
        elif self.on_camera_calibration is not None:
            self.on_camera_calibration(cam, cal)  # the cameras message follows from the loop
        return web.json_response({"ok": True, "error_px": err, "path": str(out), "cam": cam})
