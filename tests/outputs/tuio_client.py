"""A strict TUIO 1.1 ``/tuio/2Dcur`` client for tests: the reference clients' rules, as they behave.

Rules (TUIO11_CPP / JAVA / NET TuioClient, see /work/shared/NOTES.md):

- late frames: a bundle whose ``fseq`` is 1..100 below the last applied one is dropped; a bundle
  with ``fseq <= 0`` is always applied (and does not move the current fseq);
- a bundle is ``source`` (optional), ``alive``, ``set``\\*, ``fseq``, in that order; ``alive`` lists
  every live id once; a ``set`` (typetags ``,sifffff``, x and y in [0, 1]) is for an alive id;
- applying a bundle removes the cursors missing from ``alive``, adds those whose ``set`` came, and
  updates the others; an alive id with neither a cursor nor a ``set`` in the bundle is a
  *phantom* (python-tuio shows it at (0, 0)).

Wire-format violations and phantoms are kept in ``violations`` (a test asserts it is empty);
the client never raises on a datagram.
"""

from __future__ import annotations

import math
import socket
import threading
from dataclasses import dataclass, field

from pythonosc.osc_bundle import OscBundle
from pythonosc.osc_message import OscMessage
from pythonosc.parsing import osc_types

LATE_WINDOW = 100


def _typetag(msg: OscMessage) -> str:
    _, i = osc_types.get_string(msg.dgram, 0)
    tags, _ = osc_types.get_string(msg.dgram, i)
    return str(tags)


@dataclass
class StrictTuioClient:
    """Feed datagrams with :meth:`feed`; read ``cursors`` (id -> (x, y)), ``log`` and counters."""

    current_fseq: int = 0
    cursors: dict[int, tuple[float, float]] = field(default_factory=dict)
    log: list[tuple[str, int]] = field(default_factory=list)  # ("add" | "update" | "remove", id)
    violations: list[str] = field(default_factory=list)
    late: int = 0
    applied: int = 0
    resets: int = 0  # applied bundles with fseq <= 0

    def added(self) -> list[int]:
        return [sid for kind, sid in self.log if kind == "add"]

    def removed(self) -> list[int]:
        return [sid for kind, sid in self.log if kind == "remove"]

    def feed(self, dgram: bytes) -> None:
        parsed = self._parse(dgram)
        if parsed is None:
            return
        alive, sets, fseq = parsed
        if fseq > 0:
            if fseq >= self.current_fseq or self.current_fseq - fseq > LATE_WINDOW:
                self.current_fseq = fseq
            else:
                self.late += 1
                return
        else:
            self.resets += 1
        self.applied += 1
        for sid in [s for s in self.cursors if s not in alive]:
            del self.cursors[sid]
            self.log.append(("remove", sid))
        for sid in alive:
            if sid in sets:
                self.log.append(("update" if sid in self.cursors else "add", sid))
                self.cursors[sid] = sets[sid]
            elif sid not in self.cursors:
                self.violations.append(f"fseq {fseq}: id {sid} alive without a set (phantom)")

    def _parse(self, dgram: bytes) -> tuple[list[int], dict[int, tuple[float, float]], int] | None:
        try:
            if not OscBundle.dgram_is_bundle(dgram):
                self.violations.append("datagram is not a bundle")
                return None
            msgs = list(OscBundle(dgram))
        except Exception as e:  # a malformed datagram is a violation, not a crash
            self.violations.append(f"unparsable datagram: {e}")
            return None
        if not all(isinstance(m, OscMessage) and m.address == "/tuio/2Dcur" for m in msgs):
            self.violations.append("bundle holds something other than /tuio/2Dcur messages")
            return None
        kinds = [m.params[0] if m.params else "" for m in msgs]
        if kinds and kinds[0] == "source":
            if _typetag(msgs[0]) != ",ss":
                self.violations.append(f"source typetags {_typetag(msgs[0])}")
            msgs, kinds = msgs[1:], kinds[1:]
        if len(kinds) < 2 or kinds[0] != "alive" or kinds[-1] != "fseq" or any(
                k != "set" for k in kinds[1:-1]):
            self.violations.append(f"message order {kinds}; want alive, set*, fseq")
            return None
        alive = list(msgs[0].params[1:])
        if _typetag(msgs[0]) != ",s" + "i" * len(alive) or len(set(alive)) != len(alive):
            self.violations.append(f"alive {alive} with typetags {_typetag(msgs[0])}")
            return None
        if _typetag(msgs[-1]) != ",si":
            self.violations.append(f"fseq typetags {_typetag(msgs[-1])}")
            return None
        fseq = int(msgs[-1].params[1])
        sets: dict[int, tuple[float, float]] = {}
        for m in msgs[1:-1]:
            if _typetag(m) != ",sifffff":
                self.violations.append(f"set typetags {_typetag(m)}; want ,sifffff")
                continue
            sid, x, y, vx, vy, acc = m.params[1:]
            if sid not in alive:
                self.violations.append(f"fseq {fseq}: set {sid} not in alive {alive}")
            elif sid in sets:
                self.violations.append(f"fseq {fseq}: two sets for {sid}")
            elif not (0.0 <= x <= 1.0 and 0.0 <= y <= 1.0) or not all(
                    math.isfinite(v) for v in (vx, vy, acc)):
                self.violations.append(f"fseq {fseq}: set {sid} values out of range")
            else:
                sets[sid] = (float(x), float(y))
        return alive, sets, fseq


class UdpListener:
    """A UDP socket on 127.0.0.1 (ephemeral port) whose datagrams a thread feeds to a client."""

    def __init__(self, client: StrictTuioClient | None = None) -> None:
        self.client = client if client is not None else StrictTuioClient()
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.port = int(self.sock.getsockname()[1])
        self.datagrams = 0
        self.lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> UdpListener:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            with self.lock:
                self.client.feed(data)
                self.datagrams += 1

    def wait_quiet(self, quiet_s: float = 0.3) -> None:
        """Until no datagram arrived for ``quiet_s`` seconds."""
        last = -1
        while True:
            with self.lock:
                n = self.datagrams
            if n == last:
                return
            last = n
            self._stop.wait(quiet_s)

    def close(self) -> None:
        self.wait_quiet(0.1)
        self._stop.set()
        self._thread.join(2.0)
        self.sock.close()
