"""TUIO 1.1 output: golden bytes, a strict validator built on python-osc's parser, a real UDP
socket, the third-party python-tuio client, and failures that must not stop the pipeline."""

from __future__ import annotations

import logging
import math
import os
import socket
import struct
import threading
from pathlib import Path

import numpy as np
import pytest
from pythonosc.osc_bundle import OscBundle
from pythonosc.osc_message import OscMessage
from pythonosc.parsing import osc_types

from depthtouch.calibration import Calibration, apply_calibration
from depthtouch.errors import ConfigError, OutputError
from depthtouch.outputs.base import EventSink
from depthtouch.outputs.tuio import (
    MAX_PACKET_BYTES,
    TuioCursor,
    TuioSink,
    encode_frame,
    parse_hostport,
)
from depthtouch.types import Frame, TouchEvent, TouchState
from synth import result_of

GOLDEN = Path(__file__).parent / "golden"
REGEN = os.environ.get("DEPTHTOUCH_REGEN_GOLDEN") == "1"
DEPTH = np.zeros((480, 640), np.uint16)
FPS = 30.0


# --- a strict validator on python-osc's parser -------------------------------------------------
def _typetag(msg: OscMessage) -> str:
    _, i = osc_types.get_string(msg.dgram, 0)
    tags, _ = osc_types.get_string(msg.dgram, i)
    return tags


def validate(dgram: bytes, max_bytes: int = MAX_PACKET_BYTES) -> dict:
    """Check one datagram against TUIO 1.1 /tuio/2Dcur; returns its parts."""
    assert len(dgram) <= max_bytes, f"packet of {len(dgram)} bytes"
    assert OscBundle.dgram_is_bundle(dgram)
    assert dgram[8:16] == b"\x00" * 7 + b"\x01", "timetag must be 'immediately'"
    msgs = list(OscBundle(dgram))
    assert all(isinstance(m, OscMessage) and m.address == "/tuio/2Dcur" for m in msgs)
    kinds = [m.params[0] for m in msgs]
    source = None
    if kinds[0] == "source":
        assert _typetag(msgs[0]) == ",ss"
        source = msgs[0].params[1]
        assert "@" in source
        msgs, kinds = msgs[1:], kinds[1:]
    assert kinds[0] == "alive" and kinds[-1] == "fseq", kinds
    assert all(k == "set" for k in kinds[1:-1]), kinds
    alive = msgs[0].params[1:]
    assert _typetag(msgs[0]) == ",s" + "i" * len(alive)
    assert len(set(alive)) == len(alive)
    sets = {}
    for m in msgs[1:-1]:
        assert _typetag(m) == ",sifffff"
        sid, x, y, vx, vy, acc = m.params[1:]
        assert sid in alive, f"set {sid} not in alive {alive}"
        assert sid not in sets
        assert 0.0 <= x <= 1.0 and 0.0 <= y <= 1.0
        assert all(math.isfinite(v) for v in (vx, vy, acc))
        sets[sid] = (x, y, vx, vy, acc)
    assert _typetag(msgs[-1]) == ",si"
    return {"source": source, "alive": alive, "sets": sets, "fseq": msgs[-1].params[1]}


def validate_stream(dgrams: list[bytes]) -> list[dict]:
    """Every datagram valid; fseq strictly increasing (except the resets, fseq -1)."""
    parts = [validate(d) for d in dgrams]
    assert all(p["fseq"] > 0 or (p["fseq"] == -1 and p["alive"] == []) for p in parts)
    fseqs = [p["fseq"] for p in parts if p["fseq"] > 0]
    assert all(b > a for a, b in zip(fseqs, fseqs[1:], strict=False)), fseqs
    return parts


# --- an independent OSC encoder for the golden bytes --------------------------------------------
def _pad(b: bytes) -> bytes:
    return b + b"\x00" * (4 - len(b) % 4)


def _osc(kind: str, *args: tuple[str, object]) -> bytes:
    tags = "," + "s" + "".join(t for t, _ in args)
    body = _pad(kind.encode())
    for t, v in args:
        body += {"i": lambda v: struct.pack(">i", v), "f": lambda v: struct.pack(">f", v),
                 "s": lambda v: _pad(v.encode())}[t](v)
    return _pad(b"/tuio/2Dcur") + _pad(tags.encode()) + body


def _bundle(*msgs: bytes) -> bytes:
    return b"#bundle\x00" + b"\x00" * 7 + b"\x01" + b"".join(
        struct.pack(">i", len(m)) + m for m in msgs)


GOLDEN_CASES = {
    "tuio_idle": (dict(cursors=[], fseq=1, source="depthtouch@127.0.0.1"),
                  [_bundle(_osc("source", ("s", "depthtouch@127.0.0.1")), _osc("alive"),
                           _osc("fseq", ("i", 1)))]),
    "tuio_two_cursors": (
        dict(cursors=[TuioCursor(7, 0.25, 0.5, 0.125, -0.5, 2.0), TuioCursor(9, 1.0, 0.0)],
             fseq=42, source="depthtouch@10.0.0.2"),
        [_bundle(_osc("source", ("s", "depthtouch@10.0.0.2")),
                 _osc("alive", ("i", 7), ("i", 9)),
                 _osc("set", ("i", 7), ("f", 0.25), ("f", 0.5), ("f", 0.125), ("f", -0.5),
                      ("f", 2.0)),
                 _osc("set", ("i", 9), ("f", 1.0), ("f", 0.0), ("f", 0.0), ("f", 0.0),
                      ("f", 0.0)),
                 _osc("fseq", ("i", 42)))]),
    "tuio_no_source": (dict(cursors=[TuioCursor(1, 0.5, 0.5)], fseq=3, source=None),
                       [_bundle(_osc("alive", ("i", 1)),
                                _osc("set", ("i", 1), ("f", 0.5), ("f", 0.5), ("f", 0.0),
                                     ("f", 0.0), ("f", 0.0)),
                                _osc("fseq", ("i", 3)))]),
}


def _split_case() -> dict:
    cursors = [TuioCursor(i, i / 12, 1 - i / 12, 0.01 * i, -0.02 * i, 0.5) for i in range(12)]
    return dict(cursors=cursors, fseq=100, source="depthtouch@127.0.0.1", max_packet_bytes=512)


@pytest.mark.parametrize("name", [*GOLDEN_CASES, "tuio_split_512"])
def test_golden_bytes(name):
    if name == "tuio_split_512":
        kwargs, expected = _split_case(), None
    else:
        kwargs, expected = GOLDEN_CASES[name]
    kw = dict(kwargs)
    packets = encode_frame(kw.pop("cursors"), kw.pop("fseq"), **kw)
    if expected is not None:
        assert packets == expected  # independent construction of the same bytes
    files = sorted(GOLDEN.glob(f"{name}_*.bin"))
    if REGEN:
        for f in files:
            f.unlink()
        for k, p in enumerate(packets):
            (GOLDEN / f"{name}_{k:02d}.bin").write_bytes(p)
        files = sorted(GOLDEN.glob(f"{name}_*.bin"))
    assert [f.read_bytes() for f in files] == packets, f"golden {name} changed"


def test_split_keeps_full_alive_and_every_set():
    kw = _split_case()
    packets = encode_frame(kw.pop("cursors"), kw.pop("fseq"), **kw)
    assert len(packets) > 1
    parts = [validate(p, 512) for p in packets]
    assert [p["fseq"] for p in parts] == list(range(100, 100 + len(parts)))
    assert all(p["alive"] == list(range(12)) for p in parts)
    ids = [sid for p in parts for sid in p["sets"]]
    assert ids == list(range(12))  # every set once, in order
    # default limit: 1472 bytes, about 45 cursors per packet with 150 alive ids
    big = [TuioCursor(i, 0.5, 0.5) for i in range(150)]
    packets = encode_frame(big, 1, source="depthtouch@127.0.0.1")
    parts = validate_stream(packets)
    assert len(packets) >= 4 and max(len(p) for p in packets) <= 1472
    assert sorted(s for p in parts for s in p["sets"]) == list(range(150))


@pytest.mark.parametrize(
    ("cursors", "kw", "match"),
    [
        ([TuioCursor(-1, 0.5, 0.5)], {}, "out of range"),
        ([TuioCursor(2**31, 0.5, 0.5)], {}, "out of range"),
        ([TuioCursor(True, 0.5, 0.5)], {}, "not an integer"),
        ([TuioCursor(1, math.nan, 0.5)], {}, "finite"),
        ([TuioCursor(1, 0.5, 0.5, math.inf)], {}, "finite"),
        ([TuioCursor(1, 1.5, 0.5)], {}, r"outside \[0, 1\]"),
        ([TuioCursor(1, 0.5, -0.01)], {}, r"outside \[0, 1\]"),
        ([TuioCursor(1, 0.5, 0.5)], {"alive_ids": [2]}, "not in alive"),
        ([], {"alive_ids": [2, 2]}, "repeat"),
        ([], {"fseq": -2}, "fseq"),
        ([], {"max_packet_bytes": 100}, "max_packet_bytes"),
        ([TuioCursor(1, 0.5, 0.5)], {"alive_ids": list(range(400))}, "no room|do not fit"),
    ],
)
def test_encoder_rejects_bad_values(cursors, kw, match):
    fseq = kw.pop("fseq", 1)
    with pytest.raises(ValueError, match=match):
        encode_frame(cursors, fseq, **kw)


def test_encoder_accepts_numpy_scalars_as_explicit_types():
    c = TuioCursor(np.int64(5), np.float32(0.5), np.float64(0.25), np.float32(1.0))  # type: ignore[arg-type]
    (p,) = encode_frame([c], 1)
    part = validate(p)
    assert part["sets"][5][:3] == (0.5, 0.25, 1.0)


@pytest.mark.parametrize(
    ("text", "want"),
    [
        ("127.0.0.1:3333", ("127.0.0.1", 3333)),
        ("localhost:9000", ("localhost", 9000)),
        ("[::1]:3334", ("::1", 3334)),
        ("[::1]", ("::1", 3333)),
        ("192.168.1.20", ("192.168.1.20", 3333)),
        (" 10.0.0.1:1 ", ("10.0.0.1", 1)),
        ("127.0.0.1:0", None),
        ("127.0.0.1:65536", None),
        ("127.0.0.1:abc", None),
        (":3333", None),
        ("", None),
        ("::1:3333", None),
        ("[::1]x", None),
    ],
)
def test_parse_hostport(text, want):
    if want is None:
        with pytest.raises(ConfigError) as ei:
            parse_hostport(text)
        assert "\n" not in str(ei.value)
    else:
        assert parse_hostport(text) == want


# --- the sink on a real socket ------------------------------------------------------------------
def recording(n_frames: int = 121) -> list[tuple[Frame, list[TouchEvent]]]:
    """Idle 0.5 s, touch 1 slides right 5 px/frame (frames 15-60), touch 2 (30-45), idle 2 s."""
    out = []
    for i in range(n_frames):
        t = i / FPS
        evs = []
        for tid, start, end, y in ((1, 15, 60, 200.0), (2, 30, 45, 300.0)):
            if start <= i <= end:
                state: TouchState = "down" if i == start else ("up" if i == end else "move")
                x = 100.0 + 5.0 * (min(i, end - 1) - start)
                evs.append(TouchEvent(i, t, tid, state, x, y))
        out.append((Frame(DEPTH, t, i), evs))
    return out


@pytest.fixture
def receiver():
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(2.0)
    yield sock
    sock.close()


def drain(sock: socket.socket, n: int) -> list[bytes]:
    got = []
    for _ in range(n):
        got.append(sock.recv(65536))
    sock.settimeout(0.05)
    try:
        while True:
            got.append(sock.recv(65536))
    except OSError:
        pass
    return got


def test_sink_stream_is_valid_tuio(receiver):
    port = receiver.getsockname()[1]
    rec = recording()
    with TuioSink("127.0.0.1", port, source_name="dt", clock=lambda: 0.0) as sink:
        assert isinstance(sink, EventSink)
        for frame, evs in rec:
            sink.send(result_of(frame, evs))
        sent = sink.packets_sent
        assert sink.errors == 0
    packets = drain(receiver, sent + 1)  # + the empty alive sent by close()
    assert len(packets) == sent + 1
    parts = validate_stream(packets)
    assert all(p["source"] == "dt@127.0.0.1" for p in parts)
    # the reference server's reset, an empty alive with fseq -1, when the sink opens and closes
    assert (parts[0]["fseq"], parts[-1]["fseq"]) == (-1, -1)
    assert parts[1]["fseq"] == 1  # the clock at 0 s: fseq from 1, session ids = touch ids
    parts = parts[1:]
    # one bundle per frame with events (frames 15..60), alive follows down..up
    event_parts = parts[1:47]
    assert [p["alive"] for p in event_parts[:15]] == [[1]] * 15
    assert [p["alive"] for p in event_parts[15:30]] == [[1, 2]] * 15
    assert event_parts[30]["alive"] == [1]  # touch 2 lifted at frame 45
    assert event_parts[-1]["alive"] == [] and event_parts[-1]["sets"] == {}
    # positions normalised by the depth image, velocity in units per second
    x, y, vx, vy, acc = event_parts[5]["sets"][1]
    assert x == pytest.approx((100 + 25) / 640, abs=1e-6) and y == pytest.approx(200 / 480)
    assert vx == pytest.approx(5 * FPS / 640, rel=1e-5) and vy == 0.0
    assert event_parts[0]["sets"][1][2:] == (0.0, 0.0, 0.0)  # a new touch has no velocity yet
    assert event_parts[1]["sets"][1][4] > 0  # it accelerated from rest
    # idle: alive (empty) resent, about once per second of frame time, never every frame
    idle_head, idle_tail = parts[:1], parts[47:-1]
    assert idle_head[0]["alive"] == [] and 1 <= len(idle_tail) <= 3
    assert all(p["alive"] == [] for p in idle_tail)
    assert parts[-1]["alive"] == []


def test_sink_uses_the_events_screen_coordinates(receiver):
    """With a calibrated screen, TUIO normalises the sx, sy the pipeline put on the events (it
    never maps them again)."""
    port = receiver.getsockname()[1]
    H = np.array([[3.0, 0.0, 0.0], [0.0, 2.25, 0.0], [0.0, 0.0, 1.0]])
    cal = Calibration(H, (1920, 1080), 0.0)
    frame = Frame(DEPTH, 0.0, 0)
    evs = [TouchEvent(0, 0.0, 4, "down", 320.0, 240.0),
           TouchEvent(0, 0.0, 5, "down", 10.0, 10.0),
           TouchEvent(0, 0.0, 6, "down", 900.0, -50.0)]  # off screen: clipped
    evs = apply_calibration(evs, cal)
    with TuioSink("127.0.0.1", port, screen_wh=cal.screen_wh, clock=lambda: 0.0) as sink:
        sink.send(result_of(frame, evs))
    (_, p, _) = [validate(d) for d in drain(receiver, 3)]
    assert p["sets"][4][:2] == pytest.approx((0.5, 0.5))
    assert p["sets"][5][:2] == pytest.approx((30 / 1920, 22.5 / 1080))
    assert p["sets"][6][:2] == (1.0, 0.0)


def test_repeated_timestamp_does_not_divide_by_zero(receiver):
    port = receiver.getsockname()[1]
    with TuioSink("127.0.0.1", port, clock=lambda: 0.0) as sink:
        sink.send(result_of(Frame(DEPTH, 1.0, 0), [TouchEvent(0, 1.0, 1, "down", 10.0, 10.0)]))
        sink.send(result_of(Frame(DEPTH, 1.1, 1), [TouchEvent(1, 1.1, 1, "move", 20.0, 10.0)]))
        sink.send(result_of(Frame(DEPTH, 1.1, 2), [TouchEvent(2, 1.1, 1, "move", 30.0, 10.0)]))
    parts = validate_stream(drain(receiver, 5))[1:]
    vx2, vx3 = parts[1]["sets"][1][2], parts[2]["sets"][1][2]
    assert vx2 == pytest.approx(10 / 640 / 0.1, rel=1e-4) and vx3 == vx2
    assert parts[2]["sets"][1][0] == pytest.approx(30 / 640)


def test_third_party_client_sees_add_update_remove():
    pytest.importorskip("pythontuio")
    from pythonosc.osc_server import BlockingOSCUDPServer
    from pythontuio import TuioClient, TuioListener

    seen: list[tuple[str, int]] = []
    positions: dict[int, tuple[float, float]] = {}

    class Listener(TuioListener):
        def add_tuio_cursor(self, cur):
            seen.append(("add", cur.session_id))

        def update_tuio_cursor(self, cur):
            seen.append(("update", cur.session_id))
            positions[cur.session_id] = tuple(cur.position)

        def remove_tuio_cursor(self, cur):
            seen.append(("remove", cur.session_id))

    client = TuioClient(("127.0.0.1", 0))
    client.add_listener(Listener())
    # what TuioClient.start() does, without blocking this thread (and with an ephemeral port)
    BlockingOSCUDPServer.__init__(client, ("127.0.0.1", 0), client)
    port = client.server_address[1]
    thread = threading.Thread(target=client.serve_forever, kwargs={"poll_interval": 0.05},
                              daemon=True)
    thread.start()
    try:
        with TuioSink("127.0.0.1", port, clock=lambda: 0.0) as sink:
            for frame, evs in recording():
                sink.send(result_of(frame, evs))
        pause = threading.Event()
        for _ in range(250):  # until the client thread has handled the last removal (<= 5 s)
            if sum(1 for k, _ in seen if k == "remove") >= 2:
                break
            pause.wait(0.02)
    finally:
        client.shutdown()
        client.server_close()
        thread.join(5)
    assert seen.count(("add", 1)) == 1 and seen.count(("add", 2)) == 1
    assert seen.count(("remove", 1)) == 1 and seen.count(("remove", 2)) == 1
    assert seen.count(("update", 1)) >= 40 and seen.count(("update", 2)) >= 10
    assert seen.index(("add", 1)) < seen.index(("update", 1)) < seen.index(("remove", 1))
    assert seen.index(("add", 2)) < seen.index(("remove", 2)) < seen.index(("remove", 1))
    x, y = positions[1]
    assert x == pytest.approx((100 + 5 * 44) / 640, abs=1e-5) and y == pytest.approx(200 / 480)


# --- failures never stall or crash the pipeline --------------------------------------------------
def _free_port() -> int:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def test_unreachable_port_is_counted_and_warned_once(caplog):
    caplog.set_level(logging.WARNING, logger="depthtouch.outputs.tuio")
    sink = TuioSink("127.0.0.1", _free_port())  # nobody listens: ICMP port unreachable
    for frame, evs in recording(70):
        sink.send(result_of(frame, evs))
    sink.close()
    assert sink.errors >= 1 and "failed" in (sink.last_error or "")
    assert sink.packets_sent >= 1
    warnings = [r for r in caplog.records if r.name == "depthtouch.outputs.tuio"]
    assert len(warnings) == 1 and "warned once" in warnings[0].getMessage()


class _FailingSocket:
    def __init__(self, exc: OSError) -> None:
        self.exc, self.calls = exc, 0

    def send(self, data: bytes) -> int:
        self.calls += 1
        raise self.exc

    def close(self) -> None:
        pass


@pytest.mark.parametrize(
    "exc",
    [ConnectionRefusedError(111, "Connection refused"), BlockingIOError(11, "would block"),
     OSError(113, "No route to host"), PermissionError(1, "not permitted")],
)
def test_send_errors_never_raise(receiver, caplog, exc):
    caplog.set_level(logging.WARNING, logger="depthtouch.outputs.tuio")
    sink = TuioSink("127.0.0.1", receiver.getsockname()[1])
    real = sink._sock
    sink._sock = _FailingSocket(exc)  # type: ignore[assignment]
    rec = recording(40)
    for frame, evs in rec:
        sink.send(result_of(frame, evs))
    assert sink.errors == sink._sock.calls >= 20  # type: ignore[union-attr]
    assert sink.packets_sent == 1  # the reset sent when the sink opened
    sink.close()
    real.close()  # type: ignore[union-attr]
    assert len([r for r in caplog.records if r.name == "depthtouch.outputs.tuio"]) == 1


def test_unencodable_frame_is_counted_not_raised(receiver):
    sink = TuioSink("127.0.0.1", receiver.getsockname()[1])
    evs = [TouchEvent(0, 0.0, i, "down", 10.0, 10.0) for i in range(400)]
    sink.send(result_of(Frame(DEPTH, 0.0, 0), evs))  # 400 alive ids do not fit one packet
    assert sink.errors == 1 and "encode" in (sink.last_error or "")
    sink.close()
    sink.close()  # twice is fine
    sink.send(result_of(Frame(DEPTH, 1.0, 1), []))  # after close: a no-op


@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        ({"host": "no-such-host.invalid"}, OutputError, "cannot be resolved"),
        ({"port": 0}, ConfigError, "port"),
        ({"port": 70000}, ConfigError, "port"),
        ({"idle_interval_s": 0.0}, ConfigError, "idle_interval_s"),
        ({"max_packet_bytes": 70000}, ConfigError, "max_packet_bytes"),
    ],
)
def test_sink_bad_settings_raise_one_line(kwargs, exc, match):
    with pytest.raises(exc, match=match) as ei:
        TuioSink(**kwargs)
    assert "\n" not in str(ei.value)
