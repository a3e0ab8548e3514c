"""TUIO 1.1 ``/tuio/2Dcur`` over UDP: a pure encoder and a non-blocking sender sink.

Wire format (tuio.org TUIO 1.1, cursor profile), one OSC bundle per frame, timetag "immediately"::

    /tuio/2Dcur source  "depthtouch@127.0.0.1"        ,ss
    /tuio/2Dcur alive   s1 s2 ...                      ,s + i per id
    /tuio/2Dcur set     s x y X Y m   (one per touch)  ,sifffff
    /tuio/2Dcur fseq    f                              ,si

``x``, ``y`` are normalised to [0, 1] (origin top-left) of the calibrated screen, or of the depth
image without a calibration; ``X``, ``Y`` their velocity in units per second; ``m`` the motion
acceleration (change of speed, units per second squared). Removal is implicit: an id that leaves
``alive`` is gone.

A bundle larger than ``max_packet_bytes`` (1472 = Ethernet MTU minus IP/UDP headers) is split;
every part carries ``source``, the ``alive`` list and its own ``fseq``, and fseq values are
strictly increasing over all datagrams (the reference server reuses one fseq per split frame; a
strictly increasing sequence is equally valid for its client and simpler to check). A touch new
in this frame is listed in ``alive`` only from the part that carries its ``set``: clients such as
python-tuio add a cursor as soon as its id is alive, and would show it at (0, 0) until its
``set`` arrived in a later part.

Restarts (the reference clients keep running while a sensor restarts):

- they drop a bundle whose fseq lies 1..100 below the last one they applied, as a late frame, so
  a sender that starts at 1 again is ignored until it passes its old count. The sink's fseq
  follows a 10 kHz wall clock (``max(previous + 1, clock ticks)``): a new run starts above where
  any earlier run ended unless that run sent more than 10 000 packets per second, and a wrap of
  the int32 range (every 59 h) jumps far more than 100 down, which clients apply.
- an empty ``alive`` with fseq -1 (fseq <= 0 is always applied) is sent when the sink opens and
  when it closes, as the reference server does: cursors left by a killed run are cleared.
- session ids are ``session_base + touch id``, the base a 1 kHz wall clock (mod 2**30), so the
  next run's first touch cannot continue a stale cursor of an earlier run (unless that run made
  more than 1000 touches per second).
"""

from __future__ import annotations

import logging
import math
import socket
import time
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass

import numpy as np
from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
from pythonosc.osc_message import OscMessage
from pythonosc.osc_message_builder import OscMessageBuilder

from ..checks import parse_address
from ..errors import ConfigError, OutputError
from ..types import FrameResult, TouchEvent
from .base import SinkBase

ADDRESS = "/tuio/2Dcur"
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 3333
MAX_PACKET_BYTES = 1472
_INT32_MAX = 2**31 - 1
_BUNDLE_HEADER_BYTES = 16  # "#bundle\0" + 8-byte timetag
FSEQ_TICKS_PER_S = 10_000
SESSION_IDS_PER_S = 1_000
_SESSION_BASE_MOD = 2**30
RESET_FSEQ = -1  # the reference server's fseq for the empty alive at start and stop

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


def _check_id(value: object, what: str, lo: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{what} {value!r} is not an integer")
    v = int(value)
    if not lo <= v <= _INT32_MAX:
        raise ValueError(f"{what} {v} is out of range; allowed [{lo}, {_INT32_MAX}]")
    return v


def clock_fseq(now_s: float) -> int:
    """The fseq a sink opened at wall time ``now_s`` (s since the epoch) starts from, in
    [1, 2**31 - 1]: 10 kHz ticks, wrapped."""
    return int(now_s * FSEQ_TICKS_PER_S) % (_INT32_MAX - 1) + 1


def session_base(now_s: float) -> int:
    """Offset of a run's session ids from its tracker's touch ids: 1 kHz ticks mod 2**30."""
    return int(now_s * SESSION_IDS_PER_S) % _SESSION_BASE_MOD


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
    new_ids: Collection[int] = (),
) -> list[bytes]:
    """The datagram(s) for one frame. Pure: values in, bytes out.

    cursors: the ``set`` messages, in order. fseq: frame sequence number of the first datagram
        (the k-th part gets ``fseq + k``), in [-1, 2**31 - 1]; a value <= 0 (always applied by
        clients) is kept for every part.
    alive_ids: every live session id, in order (default: the cursors' ids); each cursor's id must
        be in it. source: ``name@address`` for the ``source`` message, or None to leave it out.
    max_packet_bytes: largest datagram (default 1472, range [256, 65507]).
    new_ids: ids of touches that start in this frame; when the frame is split, each is listed in
        ``alive`` only from the part that carries its ``set`` on (default: none).
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
    _check_id(fseq, "fseq", lo=RESET_FSEQ)

    head = []
    if source is not None:
        head.append(_message("source", [(source, "s")]))
    alive_size = _message("alive", [(i, "i") for i in alive]).size
    fseq_size = _message("fseq", [(0, "i")]).size
    base = (_BUNDLE_HEADER_BYTES + sum(4 + m.size for m in head) + 4 + alive_size
            + 4 + fseq_size)

    parts: list[list[OscMessage]] = [[]]
    part_ids: list[set[int]] = [set()]
    used = base
    for c, m in zip(cursors, sets, strict=True):
        need = 4 + m.size
        if base + need > max_packet_bytes:
            raise ValueError(
                f"{len(alive)} alive ids leave no room for a set message in "
                f"{max_packet_bytes} bytes"
            )
        if used + need > max_packet_bytes:
            parts.append([])
            part_ids.append(set())
            used = base
        parts[-1].append(m)
        part_ids[-1].add(int(c.session_id))
        used += need
    if base > max_packet_bytes:
        raise ValueError(f"{len(alive)} alive ids do not fit in {max_packet_bytes} bytes")
    if fseq > 0:
        _check_id(fseq + len(parts) - 1, "fseq")

    # a new id waits in alive for the part with its set (an earlier part would add a phantom)
    new = {int(i) for i in new_ids} & set().union(*part_ids)
    sent: set[int] = set()
    out: list[bytes] = []
    for k, part in enumerate(parts):
        sent |= part_ids[k]
        listed = [i for i in alive if i not in new or i in sent]
        fk = fseq + k if fseq > 0 else fseq
        bb = OscBundleBuilder(IMMEDIATELY)
        for m in (*head, _message("alive", [(i, "i") for i in listed]), *part,
                  _message("fseq", [(fk, "i")])):
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
    clock: wall clock in seconds since the epoch (default ``time.time``), read when the sink
        opens and for each fseq; tests inject a fixed one for deterministic bytes.

    Session ids on the wire are ``session_base + touch id`` (see the module docstring for why).
    The socket never blocks and a failed send (port unreachable, ICMP refused, no route) never
    raises: failures are counted in ``errors`` and logged once. Opening sends an empty ``alive``
    with fseq -1 (clients drop the cursors a previous run left); ``close()`` sends it again so
    clients drop every cursor.
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
        clock: Callable[[], float] = time.time,
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
        self._clock = clock
        now = float(clock())
        self.fseq = clock_fseq(now)
        self.session_base = session_base(now)
        self.packets_sent = 0
        self.bytes_sent = 0
        self.errors = 0
        self.last_error: str | None = None
        self._tracks: dict[int, _Track] = {}
        self._new: set[int] = set()
        self._last_send_t: float | None = None
        self._emit_reset()

    # --- state ----------------------------------------------------------------------------------
    def _unit_xy(self, resolution_wh: tuple[int, int],
                 events: Sequence[TouchEvent]) -> np.ndarray:
        """(N, 2) positions in [0, 1] for the events, in the calibrated screen or depth image."""
        screen = self.screen_wh
        if screen is None:
            xy = np.array([[e.x, e.y] for e in events], dtype=np.float64).reshape(-1, 2)
            w, h = resolution_wh
            unit = xy / np.array([max(w, 1), max(h, 1)], dtype=np.float64)
        else:
            sxy = np.array([[float(e.extra.get("sx", math.nan)), float(e.extra.get("sy", math.nan))]
                            for e in events], dtype=np.float64).reshape(-1, 2)
            unit = sxy / np.asarray(screen, dtype=np.float64)
        return np.clip(np.nan_to_num(unit, nan=0.5), 0.0, 1.0)

    def _update(self, t: float, resolution_wh: tuple[int, int],
                events: Sequence[TouchEvent]) -> list[TuioCursor]:
        live = [e for e in events if e.state != "up"]
        for e in events:
            if e.state == "up":
                self._tracks.pop(e.id, None)
        cursors: list[TuioCursor] = []
        for e, (x, y) in zip(live, self._unit_xy(resolution_wh, live), strict=True):
            tr = self._tracks.get(e.id)
            if tr is None or e.state == "down":
                tr = _Track((float(x), float(y)), t)
                self._tracks[e.id] = tr
                self._new.add(self._sid(e.id))
            else:
                dt = t - tr.t
                if dt > 0.0:  # a repeated timestamp keeps the last velocity
                    v = ((x - tr.xy[0]) / dt, (y - tr.xy[1]) / dt)
                    tr.accel = (math.hypot(*v) - math.hypot(*tr.v)) / dt
                    tr.v = (float(v[0]), float(v[1]))
                    tr.t = t
                tr.xy = (float(x), float(y))
            cursors.append(TuioCursor(self._sid(e.id), tr.xy[0], tr.xy[1], tr.v[0], tr.v[1],
                                      tr.accel))
        return cursors

    def _sid(self, touch_id: int) -> int:
        return (self.session_base + int(touch_id)) & _INT32_MAX

    # --- sink -----------------------------------------------------------------------------------
    def __enter__(self) -> TuioSink:
        return self

    def send(self, result: FrameResult) -> None:
        """Update the live touches from this frame's events and send what the frame needs."""
        if self._sock is None:
            return
        frame = result.frame
        self.send_events(float(frame.timestamp_s), frame.resolution_wh, result.events)

    def send_events(self, t: float, resolution_wh: tuple[int, int],
                    events: Sequence[TouchEvent]) -> None:
        """The logic of :meth:`send` on a frame's timestamp (s), depth image size and events."""
        if self._sock is None:
            return
        cursors = self._update(t, resolution_wh, events)
        last = self._last_send_t
        idle_due = last is None or t < last or t - last >= self.idle_interval_s
        if not events and not idle_due:
            return
        self._emit(cursors, t)

    def _emit(self, cursors: list[TuioCursor], t: float) -> None:
        # follow the wall clock (see the module docstring): a later run starts above this one
        fseq = max(self.fseq, clock_fseq(float(self._clock())))
        try:
            packets = encode_frame(
                cursors, fseq, alive_ids=[self._sid(i) for i in self._tracks],
                source=self.source, max_packet_bytes=self.max_packet_bytes, new_ids=self._new,
            )
        except ValueError as e:  # e.g. more live ids than one packet can list
            self._fail(f"cannot encode frame: {e}")
            return
        finally:
            self._new.clear()
        # past int32: start again at 1, a drop of more than 100 that clients apply
        self.fseq = fseq + len(packets) if fseq + len(packets) <= _INT32_MAX else 1
        self._last_send_t = t
        for p in packets:
            self._send_packet(p)

    def _emit_reset(self) -> None:
        """The reference server's empty ``alive`` with fseq -1: clients drop every cursor."""
        self._send_packet(encode_frame([], RESET_FSEQ, source=self.source)[0])

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
        """Send an empty ``alive`` with fseq -1 (clients remove every cursor), then close."""
        if self._sock is None:
            return
        self._tracks.clear()
        self._emit_reset()
        sock, self._sock = self._sock, None
        sock.close()
