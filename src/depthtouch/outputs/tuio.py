"""TUIO 1.1 ``/tuio/2Dcur`` over UDP: a pure encoder and a non-blocking sender sink.

Wire format (tuio.org TUIO 1.1, cursor profile), one OSC bundle per frame, timetag "immediately"::

    /tuio/2Dcur source  "depthtouch@127.0.0.1"        ,ss
    /tuio/2Dcur alive   s1 s2 ...                      ,s + i per id
    /tuio/2Dcur set     s x y X Y m   (one per touch)  ,sifffff
    /tuio/2Dcur fseq    f                              ,si

``x``, ``y`` are normalised to [0, 1] (origin top-left) of the calibrated screen, or of the depth
image without a calibration; ``X``, ``Y`` their velocity in units per second; ``m`` the motion
acceleration (change of speed, units per second squared). Session ids are the tracker's touch ids
(never reused in a run). Removal is implicit: an id that leaves ``alive`` is gone.

A bundle larger than ``max_packet_bytes`` (1472 = Ethernet MTU minus IP/UDP headers) is split;
every part carries ``source``, the full ``alive`` list and its own ``fseq``, and fseq values are
strictly increasing over all datagrams (the reference server reuses one fseq per split frame; a
strictly increasing sequence is equally valid for its client and simpler to check).
"""

from __future__ import annotations

import logging
import math
import socket
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
from pythonosc.osc_message import OscMessage
from pythonosc.osc_message_builder import OscMessageBuilder

from ..checks import parse_address
from ..errors import ConfigError, OutputError
from ..types import Frame, FrameResult, TouchEvent
from .base import SinkBase

ADDRESS = "/tuio/2Dcur"
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 3333
MAX_PACKET_BYTES = 1472
_INT32_MAX = 2**31 - 1
_BUNDLE_HEADER_BYTES = 16  # "#bundle\0" + 8-byte timetag

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TuioCursor:
    """One ``set`` message: session id, position in [0, 1], velocity (1/s), acceleration (1/s^2)."""

    session_id: int
    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0
    accel: float = 0.0


def _check_id(value: object, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{what} {value!r} is not an integer")
    v = int(value)
    if not 0 <= v <= _INT32_MAX:
        raise ValueError(f"{what} {v} is out of range; allowed [0, {_INT32_MAX}]")
    return v


def _message(kind: str, args: Sequence[tuple[str | int | float, str]]) -> OscMessage:
    b = OscMessageBuilder(address=ADDRESS)
    b.add_arg(kind, "s")
    for value, tag in args:
        b.add_arg(value, tag)
    return b.build()


def _set_message(c: TuioCursor) -> OscMessage:
    sid = _check_id(c.session_id, "session id")
    vals = [float(c.x), float(c.y), float(c.vx), float(c.vy), float(c.accel)]
    if not all(math.isfinite(v) for v in vals):
        raise ValueError(f"cursor {sid}: position, velocity and acceleration must be finite")
    if not (0.0 <= vals[0] <= 1.0 and 0.0 <= vals[1] <= 1.0):
        raise ValueError(f"cursor {sid}: x, y = {vals[0]}, {vals[1]} outside [0, 1]")
    # explicit typetags: a Python int would become "i", which TUIO clients reject for a float
    return _message("set", [(sid, "i")] + [(v, "f") for v in vals])


def encode_frame(
    cursors: Sequence[TuioCursor],
    fseq: int,
    *,
    alive_ids: Sequence[int] | None = None,
    source: str | None = None,
    max_packet_bytes: int = MAX_PACKET_BYTES,
) -> list[bytes]:
    """The datagram(s) for one frame. Pure: values in, bytes out.

    cursors: the ``set`` messages, in order. fseq: frame sequence number of the first datagram
        (the k-th part gets ``fseq + k``), in [0, 2**31 - 1].
    alive_ids: every live session id, in order (default: the cursors' ids); each cursor's id must
        be in it. source: ``name@address`` for the ``source`` message, or None to leave it out.
    max_packet_bytes: largest datagram (default 1472, range [256, 65507]).
    Returns at least one datagram (an idle frame is ``alive`` with no ids, then ``fseq``).
    Raises ValueError on ids outside int32, non-finite values, x or y outside [0, 1], a cursor
    missing from ``alive_ids``, or an ``alive`` list too long for one packet.
    """
    if not 256 <= max_packet_bytes <= 65507:
        raise ValueError(f"max_packet_bytes = {max_packet_bytes} is out of range; [256, 65507]")
    alive = [_check_id(i, "alive id") for i in
             (alive_ids if alive_ids is not None else [c.session_id for c in cursors])]
    if len(set(alive)) != len(alive):
        raise ValueError("alive ids repeat; give each live session id once")
    alive_set = set(alive)
    sets = [_set_message(c) for c in cursors]
    missing = [c.session_id for c in cursors if c.session_id not in alive_set]
    if missing:
        raise ValueError(f"cursor {missing[0]} has a set message but is not in alive")
    _check_id(fseq, "fseq")

    head = []
    if source is not None:
        head.append(_message("source", [(source, "s")]))
    head.append(_message("alive", [(i, "i") for i in alive]))
    fseq_size = _message("fseq", [(0, "i")]).size
    base = _BUNDLE_HEADER_BYTES + sum(4 + m.size for m in head) + 4 + fseq_size

    parts: list[list[OscMessage]] = [[]]
    used = base
    for m in sets:
        need = 4 + m.size
        if base + need > max_packet_bytes:
            raise ValueError(
                f"{len(alive)} alive ids leave no room for a set message in "
                f"{max_packet_bytes} bytes"
            )
        if used + need > max_packet_bytes:
            parts.append([])
            used = base
        parts[-1].append(m)
        used += need
    if base > max_packet_bytes:
        raise ValueError(f"{len(alive)} alive ids do not fit in {max_packet_bytes} bytes")
    _check_id(fseq + len(parts) - 1, "fseq")

    out: list[bytes] = []
    for k, part in enumerate(parts):
        bb = OscBundleBuilder(IMMEDIATELY)
        for m in (*head, *part, _message("fseq", [(fseq + k, "i")])):
            bb.add_content(m)
        out.append(bb.build().dgram)
    return out


def parse_hostport(text: str) -> tuple[str, int]:
    """``"HOST:PORT"`` (``"[::1]:3333"`` for IPv6) -> ``(host, port)``; a bare host gets 3333.

    Raises ConfigError (one line) on an empty host or a port outside [1, 65535].
    """
    return parse_address(text, what="TUIO address", default_port=DEFAULT_PORT)


@dataclass
class _Track:
    xy: tuple[float, float]
    t: float
    v: tuple[float, float] = (0.0, 0.0)
    accel: float = 0.0


class TuioSink(SinkBase):
    """Sends one TUIO bundle per frame with touches to ``host:port`` over UDP.

    screen_wh: the calibrated screen's size in pixels: positions are the events' ``sx``, ``sy``
        (added by the pipeline) normalised to it; None: ``x``, ``y`` normalised to the depth
        image. Positions outside the screen are clipped to [0, 1].
    source_name: the application name in the ``source`` message (``@address`` is appended).
    idle_interval_s: while no touch is reported, ``alive`` (empty) is resent once per this many
        seconds of frame time (default 1.0, range (0, 60]).
    max_packet_bytes: datagram limit before splitting (default 1472).

    The socket never blocks and a failed send (port unreachable, ICMP refused, no route) never
    raises: failures are counted in ``errors`` and logged once. ``close()`` sends a last empty
    ``alive`` so clients drop every cursor.
    """

    def __init__(
        self,
        host: str = DEFAULT_HOST,
        port: int = DEFAULT_PORT,
        *,
        screen_wh: tuple[int, int] | None = None,
        source_name: str = "depthtouch",
        idle_interval_s: float = 1.0,
        max_packet_bytes: int = MAX_PACKET_BYTES,
    ) -> None:
        if not 1 <= int(port) <= 65535:
            raise ConfigError(f"TUIO port {port} is out of range; allowed [1, 65535]")
        if not 0.0 < idle_interval_s <= 60.0:
            raise ConfigError(f"idle_interval_s = {idle_interval_s!r} is out of range; (0, 60]")
        if not 256 <= max_packet_bytes <= 65507:
            raise ConfigError(
                f"max_packet_bytes = {max_packet_bytes} is out of range; allowed [256, 65507]"
            )
        try:
            family, kind, proto, _, addr = socket.getaddrinfo(host, int(port), 0,
                                                              socket.SOCK_DGRAM)[0]
        except (socket.gaierror, UnicodeError) as e:
            raise OutputError(f"TUIO host {host!r} cannot be resolved ({e}); check --tuio") from e
        try:
            sock = socket.socket(family, kind, proto)
            if family == socket.AF_INET:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            sock.setblocking(False)
            # connected UDP: the kernel reports ICMP "port unreachable" on a later send
            sock.connect(addr)
            local = str(sock.getsockname()[0])
        except OSError as e:
            raise OutputError(
                f"TUIO socket to {host}:{port} cannot be opened ({e.strerror}); check --tuio"
            ) from e
        self._sock: socket.socket | None = sock
        self.host, self.port = host, int(port)
        self.screen_wh = screen_wh
        self.source = source_name if "@" in source_name else f"{source_name}@{local}"
        self.idle_interval_s = float(idle_interval_s)
        self.max_packet_bytes = int(max_packet_bytes)
        self.fseq = 1
        self.packets_sent = 0
        self.bytes_sent = 0
        self.errors = 0
        self.last_error: str | None = None
        self._tracks: dict[int, _Track] = {}
        self._last_send_t: float | None = None

    # --- state ----------------------------------------------------------------------------------
    def _unit_xy(self, frame: Frame, events: Sequence[TouchEvent]) -> np.ndarray:
        """(N, 2) positions in [0, 1] for the events, in the calibrated screen or depth image."""
        screen = self.screen_wh
        if screen is None:
            xy = np.array([[e.x, e.y] for e in events], dtype=np.float64).reshape(-1, 2)
            w, h = frame.resolution_wh
            unit = xy / np.array([max(w, 1), max(h, 1)], dtype=np.float64)
        else:
            sxy = np.array([[float(e.extra.get("sx", math.nan)), float(e.extra.get("sy", math.nan))]
                            for e in events], dtype=np.float64).reshape(-1, 2)
            unit = sxy / np.asarray(screen, dtype=np.float64)
        return np.clip(np.nan_to_num(unit, nan=0.5), 0.0, 1.0)

    def _update(self, frame: Frame, events: Sequence[TouchEvent]) -> list[TuioCursor]:
        t = float(frame.timestamp_s)
        live = [e for e in events if e.state != "up"]
        for e in events:
            if e.state == "up":
                self._tracks.pop(e.id, None)
        cursors: list[TuioCursor] = []
        for e, (x, y) in zip(live, self._unit_xy(frame, live), strict=True):
            tr = self._tracks.get(e.id)
            if tr is None or e.state == "down":
                tr = _Track((float(x), float(y)), t)
                self._tracks[e.id] = tr
            else:
                dt = t - tr.t
                if dt > 0.0:  # a repeated timestamp keeps the last velocity
                    v = ((x - tr.xy[0]) / dt, (y - tr.xy[1]) / dt)
                    tr.accel = (math.hypot(*v) - math.hypot(*tr.v)) / dt
                    tr.v = (float(v[0]), float(v[1]))
                    tr.t = t
                tr.xy = (float(x), float(y))
            cursors.append(TuioCursor(e.id, tr.xy[0], tr.xy[1], tr.v[0], tr.v[1], tr.accel))
        return cursors

    # --- sink -----------------------------------------------------------------------------------
    def __enter__(self) -> TuioSink:
        return self

    def send(self, result: FrameResult) -> None:
        """Update the live touches from this frame's events and send what the frame needs."""
        if self._sock is None:
            return
        frame, events = result.frame, result.events
        cursors = self._update(frame, events)
        t = float(frame.timestamp_s)
        last = self._last_send_t
        idle_due = last is None or t < last or t - last >= self.idle_interval_s
        if not events and not idle_due:
            return
        self._emit(cursors, t)

    def _emit(self, cursors: list[TuioCursor], t: float) -> None:
        try:
            packets = encode_frame(
                cursors, self.fseq, alive_ids=list(self._tracks), source=self.source,
                max_packet_bytes=self.max_packet_bytes,
            )
        except ValueError as e:  # e.g. more live ids than one packet can list
            self._fail(f"cannot encode frame: {e}")
            return
        self.fseq += len(packets)
        self._last_send_t = t
        for p in packets:
            self._send_packet(p)

    def _send_packet(self, packet: bytes) -> None:
        sock = self._sock
        if sock is None:
            return
        try:
            sock.send(packet)
        except OSError as e:  # refused, unreachable, buffer full: drop, count, go on
            self._fail(f"send to {self.host}:{self.port} failed ({e.strerror or e})")
            return
        self.packets_sent += 1
        self.bytes_sent += len(packet)

    def _fail(self, message: str) -> None:
        self.errors += 1
        self.last_error = message
        if self.errors == 1:
            log.warning("TUIO output: %s; dropping packets and carrying on (warned once)", message)

    def close(self) -> None:
        """Send an empty ``alive`` (clients remove every cursor), then close the socket."""
        if self._sock is None:
            return
        self._tracks.clear()
        self._emit([], self._last_send_t if self._last_send_t is not None else 0.0)
        sock, self._sock = self._sock, None
        sock.close()
