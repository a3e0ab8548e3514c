"""``depthtouch merge``: fuse the TUIO 1.1 streams of several sensors into one TUIO stream.

Every sensor (a depthtouch ``replay``/``run --tuio``, or any TUIO 1.1 tracker) sends
``/tuio/2Dcur`` bundles to one UDP port; this fuses their cursors by the rules of
:mod:`depthtouch.fusion` (x, y in [0, 1] of the shared screen) and sends one stream with its own
session ids through :class:`~depthtouch.outputs.tuio.TuioSink`.

- A sender is keyed by its ``source`` message and its UDP address (two sensors on one host both
  call themselves ``depthtouch@host``; a sender without ``source`` is its address).
- A bundle is applied when it arrives (no batching: the added latency is the processing time,
  well under a millisecond); its time is the arrival time, since senders' clocks differ.
- The reference clients' late-frame rule: a bundle whose ``fseq`` is 1..100 below the last one
  of its sender is dropped; ``fseq`` <= 0 is always applied.
- Malformed datagrams are dropped and counted, never raised. A sender silent for
  ``sender_timeout_s`` with cursors alive has them ended.
- On stop (Ctrl-C, SIGTERM) every cursor is ended and a final empty ``alive`` is sent.
"""

from __future__ import annotations

import logging
import math
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pythonosc.osc_bundle import OscBundle
from pythonosc.osc_message import OscMessage

from ..checks import check_range, parse_address
from ..errors import ConfigError, OutputError
from ..fusion import Fusion, FusionConfig
from ..types import Frame, FrameResult, TouchEvent, TouchPoints
from .tuio import ADDRESS, DEFAULT_PORT, TuioSink

log = logging.getLogger(__name__)
_DEPTH = np.zeros((1, 1), np.uint16)


@dataclass(frozen=True)
class TuioFrame:
    """One decoded ``/tuio/2Dcur`` bundle: source (or None), alive ids, ``set`` positions
    (session id -> x, y in [0, 1]) and fseq (None when absent)."""

    source: str | None
    alive: tuple[int, ...]
    sets: dict[int, tuple[float, float]]
    fseq: int | None


def decode_bundle(dgram: bytes) -> TuioFrame | None:
    """The cursor frame in one datagram (a bundle, or a bare message); None when it carries no
    ``/tuio/2Dcur alive`` (other profiles). Raises ValueError on a malformed datagram."""
    try:
        if OscBundle.dgram_is_bundle(dgram):
            msgs = [m for m in OscBundle(dgram) if isinstance(m, OscMessage)]
        else:
            msgs = [OscMessage(dgram)]
    except Exception as e:  # python-osc raises its own parse errors
        raise ValueError(f"not OSC ({e})") from e
    source, alive, fseq = None, None, None
    sets: dict[int, tuple[float, float]] = {}
    for m in msgs:
        if m.address != ADDRESS or not m.params:
            continue
        kind, args = m.params[0], m.params[1:]
        if kind == "source" and args and isinstance(args[0], str):
            source = args[0]
        elif kind == "alive":
            if not all(isinstance(a, int) for a in args):
                raise ValueError("alive ids are not integers")
            alive = tuple(int(a) for a in args)
        elif kind == "set":
            if len(args) < 3 or not isinstance(args[0], int):
                raise ValueError("set needs s x y")
            x, y = float(args[1]), float(args[2])
            if not (math.isfinite(x) and math.isfinite(y)):
                raise ValueError("set with a non-finite position")
            sets[int(args[0])] = (min(max(x, 0.0), 1.0), min(max(y, 0.0), 1.0))
        elif kind == "fseq" and args and isinstance(args[0], int):
            fseq = int(args[0])
    if alive is None:
        return None
    return TuioFrame(source, alive, {k: v for k, v in sets.items() if k in alive}, fseq)


@dataclass
class _Sender:
    cam: int
    alive: set[int] = field(default_factory=set)  # ids reported down (with a position)
    last_fseq: int | None = None
    last_seen_s: float = 0.0
    pos: dict[int, tuple[float, float]] = field(default_factory=dict)


def sender_events(sender: _Sender, f: TuioFrame, screen_wh: tuple[int, int], frame: int,
                  t_s: float) -> list[TouchEvent]:
    """The touch events of one sender's bundle (positions in screen px as ``sx``, ``sy``);
    updates the sender's alive set. Pure but for ``sender``."""
    w, h = screen_wh
    out: list[TouchEvent] = []
    for sid in sorted(sender.alive - set(f.alive)):
        sx, sy = sender.pos.pop(sid, (0.0, 0.0))
        out.append(TouchEvent(frame, t_s, sid, "up", sx, sy, {"sx": sx, "sy": sy}))
    sender.alive &= set(f.alive)
    for sid, (x, y) in f.sets.items():
        sx, sy = x * w, y * h
        state = "move" if sid in sender.alive else "down"
        sender.alive.add(sid)
        sender.pos[sid] = (sx, sy)
        out.append(TouchEvent(frame, t_s, sid, state, sx, sy, {"sx": sx, "sy": sy}))  # type: ignore[arg-type]
    return out


@dataclass
class MergeStats:
    datagrams: int = 0
    malformed: int = 0
    late: int = 0
    senders: int = 0
    timeouts: int = 0
    sent_frames: int = 0


class TuioMerge:
    """Receives TUIO from any number of senders, fuses, sends one stream (see module doc).

    listen: "HOST:PORT" to bind (default 127.0.0.1:3333; 0.0.0.0 listens on every interface,
        port 0 picks a free one: see ``address``). out: the :class:`TuioSink` to send to.
    screen_wh: pixels of the virtual shared screen that the fusion's gates are measured in
        (default 1920x1080). sender_timeout_s: a silent sender's cursors end after this long
        (default 2.0 s, (0, 60]).
    """

    def __init__(self, listen: str, out: TuioSink, *, fusion: FusionConfig | None = None,
                 screen_wh: tuple[int, int] = (1920, 1080), sender_timeout_s: float = 2.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        check_range("merge.sender_timeout_s", sender_timeout_s, 0.0, 60.0, lo_open=True)
        host, port = parse_address(listen, what="--listen address", default_port=DEFAULT_PORT,
                                   default_host="127.0.0.1", allow_port_zero=True)
        try:
            family, kind, proto, _, addr = socket.getaddrinfo(host, port, 0,
                                                              socket.SOCK_DGRAM)[0]
            sock = socket.socket(family, kind, proto)
            sock.bind(addr)
        except (OSError, UnicodeError) as e:
            raise OutputError(f"cannot listen on {listen} ({e}); pick a free port with --listen"
                              ) from e
        out_addr = (socket.gethostbyname(out.host) if family == socket.AF_INET else out.host,
                    out.port)
        if out_addr[1] == sock.getsockname()[1] and out_addr[0] in ("127.0.0.1", host, "0.0.0.0"):
            sock.close()
            raise ConfigError(f"--tuio {out.host}:{out.port} is the --listen address; send the "
                              "merged stream to another port")
        sock.settimeout(0.1)
        self._sock: socket.socket | None = sock
        self.address: tuple[str, int] = sock.getsockname()[:2]
        self.out, self.screen_wh, self.clock = out, screen_wh, clock
        self.sender_timeout_s = sender_timeout_s
        self.fusion = Fusion(fusion)
        self.stats = MergeStats()
        self._senders: dict[tuple[str, object], _Sender] = {}
        self._frame = 0
        self._t0 = clock()
        self._warned = False

    # --- per datagram -------------------------------------------------------------------------
    def handle(self, dgram: bytes, addr: object) -> None:
        """Apply one datagram from ``addr`` (malformed or late ones are counted and dropped)."""
        self.stats.datagrams += 1
        try:
            f = decode_bundle(dgram)
        except ValueError as e:
            self.stats.malformed += 1
            if not self._warned:
                self._warned = True
                log.warning("merge: dropped a malformed datagram from %s (%s); further ones are "
                            "counted", addr, e)
            return
        if f is None:
            return
        key = (f.source or "", addr)
        sender = self._senders.get(key)
        if sender is None:
            sender = self._senders[key] = _Sender(len(self._senders))
            self.stats.senders += 1
        if f.fseq is not None and f.fseq > 0:
            if sender.last_fseq is not None and 0 < sender.last_fseq - f.fseq <= 100:
                self.stats.late += 1
                return
            sender.last_fseq = f.fseq
        now = self.clock() - self._t0
        sender.last_seen_s = now
        events = sender_events(sender, f, self.screen_wh, self._frame, now)
        self._send(self.fusion.update(sender.cam, now, self._frame, events), now)

    def tick(self) -> None:
        """End the cursors of senders silent for ``sender_timeout_s`` (call now and then)."""
        now = self.clock() - self._t0
        for sender in self._senders.values():
            if sender.alive and now - sender.last_seen_s > self.sender_timeout_s:
                self.stats.timeouts += 1
                gone = TuioFrame(None, (), {}, None)
                events = sender_events(sender, gone, self.screen_wh, self._frame, now)
                self._send(self.fusion.update(sender.cam, now, self._frame, events), now)
        if self.fusion.held:  # touches waiting for another sender: end them in time
            self._send(self.fusion.update(-1, now, self._frame, []), now)

    def _send(self, events: list[TouchEvent], t_s: float) -> None:
        frame = Frame(_DEPTH, t_s, self._frame)
        self.out.send(FrameResult(frame, events, TouchPoints.empty(), "ok"))
        self.stats.sent_frames += 1
        self._frame += 1

    # --- loop -----------------------------------------------------------------------------------
    def serve(self, stop: threading.Event | None = None) -> MergeStats:
        """Receive until ``stop`` is set (or Ctrl-C / SIGTERM, raised again after closing)."""
        stop = stop or threading.Event()
        sock = self._sock
        if sock is None:
            raise OutputError("the merge is closed; make a new one")
        last_tick = self.clock()
        from .. import stopping

        try:
            # SIGTERM, SIGHUP, Ctrl-C (depthtouch.stopping) set ``stop``: the loop ends between
            # datagrams, and the close sends the final empty alive
            with stopping.listen(stop.set):
                while not stop.is_set():
                    try:
                        dgram, addr = sock.recvfrom(65536)
                    except TimeoutError:
                        dgram = b""
                    except OSError as e:  # e.g. ICMP errors surfacing on some systems: go on
                        log.debug("merge: receive failed (%s)", e)
                        continue
                    if dgram:
                        self.handle(dgram, addr)
                    if self.clock() - last_tick >= 0.1:
                        last_tick = self.clock()
                        self.tick()
        finally:
            self.close()
        return self.stats

    def close(self) -> None:
        """End every fused cursor (a final ``up`` and an empty ``alive``), close the sockets."""
        if self._sock is None:
            return
        now = self.clock() - self._t0
        self._send(self.fusion.finish(self._frame, now), now)
        self.out.close()
        self._sock.close()
        self._sock = None


def run_merge(listen: str, tuio: str, *, fusion: FusionConfig | None = None,
              screen_wh: tuple[int, int] = (1920, 1080),
              on_ready: Callable[[TuioMerge], None] | None = None) -> MergeStats:
    """``depthtouch merge --listen HOST:PORT --tuio HOST:PORT`` until Ctrl-C or SIGTERM."""
    host, port = parse_address(tuio, what="TUIO address", default_port=DEFAULT_PORT)
    out = TuioSink(host, port, screen_wh=screen_wh, source_name="depthtouch-merge")
    try:
        merge = TuioMerge(listen, out, fusion=fusion, screen_wh=screen_wh)
    except BaseException:
        out.close()
        raise
    if on_ready is not None:
        on_ready(merge)
    return merge.serve()
