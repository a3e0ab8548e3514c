"""``depthtouch merge``: decoding, fusion of senders, the late-frame rule, timeouts, and on
loopback two sensor processes plus a third-party (python-osc) sender, validated strictly."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
from pythonosc.osc_message_builder import OscMessageBuilder
from test_tuio import drain, validate_stream

from depthtouch.calibration import Calibration, save_calibration
from depthtouch.outputs.merge import TuioMerge, decode_bundle
from depthtouch.outputs.tuio import TuioCursor, TuioSink, encode_frame


def osc_frame(alive: list[int], sets: dict[int, tuple[float, float]], fseq: int,
              source: str | None = None) -> bytes:
    """A TUIO bundle built with python-osc directly (a third-party sender)."""
    bb = OscBundleBuilder(IMMEDIATELY)

    def msg(*args: tuple[object, str]) -> None:
        m = OscMessageBuilder(address="/tuio/2Dcur")
        for v, t in args:
            m.add_arg(v, t)
        bb.add_content(m.build())

    if source is not None:
        msg(("source", "s"), (source, "s"))
    msg(("alive", "s"), *[(i, "i") for i in alive])
    for sid, (x, y) in sets.items():
        msg(("set", "s"), (sid, "i"), (x, "f"), (y, "f"), (0.0, "f"), (0.0, "f"), (0.0, "f"))
    msg(("fseq", "s"), (fseq, "i"))
    return bb.build().dgram


def test_decode_reads_our_encoder_and_rejects_garbage():
    [dgram] = encode_frame([TuioCursor(7, 0.25, 0.5)], 9, alive_ids=[7, 8], source="a@h")
    f = decode_bundle(dgram)
    assert f is not None
    assert (f.source, f.alive, f.fseq) == ("a@h", (7, 8), 9)
    assert f.sets == {7: (0.25, 0.5)}
    with pytest.raises(ValueError):
        decode_bundle(b"#bundle\x00garbage")
    other = OscMessageBuilder(address="/tuio/2Dobj")
    other.add_arg("alive", "s")
    assert decode_bundle(other.build().dgram) is None


@pytest.fixture
def receiver():
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(2.0)
    yield sock
    sock.close()


class _Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def merge(receiver):
    clock = _Clock()
    out = TuioSink("127.0.0.1", receiver.getsockname()[1], screen_wh=(1000, 500),
                   source_name="merge")
    m = TuioMerge("127.0.0.1:0", out, screen_wh=(1000, 500), clock=clock)
    m.clock_ = clock  # type: ignore[attr-defined]
    yield m
    m.close()


def test_senders_with_the_same_name_are_told_apart_and_fused(merge, receiver):
    a, b = ("127.0.0.1", 5001), ("127.0.0.1", 5002)
    for k in range(5):
        merge.clock_.t = k / 30
        merge.handle(osc_frame([1], {1: (0.50, 0.5)}, k + 1, "depthtouch@h"), a)
        merge.clock_.t = k / 30 + 0.01
        merge.handle(osc_frame([4], {4: (0.51, 0.5)}, k + 1, "depthtouch@h"), b)
    assert merge.stats.senders == 2
    assert merge.fusion.active_ids == [1]  # one finger seen by both
    merge.handle(osc_frame([], {}, 6, "depthtouch@h"), a)
    merge.handle(osc_frame([], {}, 6, "depthtouch@h"), b)
    # the senders' coverage is unknown, so a lift may have been a finger leaving a view: held
    merge.clock_.t = 1.0
    merge.tick()
    assert merge.fusion.active_ids == []
    parts = validate_stream(drain(receiver, merge.stats.sent_frames))
    assert len({sid for p in parts for sid in p["sets"]}) == 1  # one session id (offset per run)
    assert parts[-1]["alive"] == []


def test_late_bundles_are_dropped_and_malformed_counted(merge):
    a = ("127.0.0.1", 5001)
    merge.handle(osc_frame([1], {1: (0.2, 0.2)}, 50), a)
    merge.handle(osc_frame([], {}, 40), a)  # late: would have lifted the finger
    assert merge.stats.late == 1 and merge.fusion.active_ids == [1]
    merge.handle(b"\x00\x01nonsense", a)
    assert merge.stats.malformed == 1
    merge.handle(osc_frame([], {}, 0), a)  # fseq 0 is always applied
    merge.clock_.t = 1.0  # (past the hand-off wait of a lift at the edge of the seen box)
    merge.tick()
    assert merge.fusion.active_ids == []


def test_a_silent_sender_has_its_cursors_ended(merge):
    merge.handle(osc_frame([3], {3: (0.2, 0.2)}, 1), ("127.0.0.1", 5001))
    merge.clock_.t = 1.0
    merge.tick()
    assert merge.fusion.active_ids == [1]
    merge.clock_.t = 3.0
    merge.tick()
    assert merge.stats.timeouts == 1
    merge.clock_.t = 3.5  # after the hand-off wait
    merge.tick()
    assert merge.fusion.active_ids == []


def test_listening_on_the_output_port_is_refused(receiver):
    from depthtouch.errors import ConfigError

    port = receiver.getsockname()[1]
    receiver.close()
    out = TuioSink("127.0.0.1", port)
    with pytest.raises(ConfigError, match="is the --listen address"):
        TuioMerge(f"127.0.0.1:{port}", out)
    out.close()


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _cut_taps(tmp: Path) -> tuple[list[Path], list[Path]]:
    """The taps scene cut into two overlapping views with their calibrations (see
    tests/test_multicam.py); one tap (x = 409) is in the overlap."""
    from depthtouch.sim import render_scene
    from depthtouch.sources import write_npz
    from test_multicam import cut_views

    rec = render_scene("taps", seed=1)
    _, h, w = rec.depth.shape
    recs, cals = [], []
    for name, (depth, K, H) in zip("ab", cut_views(rec)):
        recs.append(write_npz(tmp / f"{name}.npz", depth, rec.timestamps_s, rec.depth_scale_m, K,
                              compress=False))
        cals.append(save_calibration(Calibration(H, (w, h), 0.0), tmp / f"{name}.json"))
    return recs, cals


def test_loopback_two_sensor_processes_and_a_third_party_sender(tmp_path, receiver):
    receiver.settimeout(5.0)
    listen = _free_port()
    out_port = receiver.getsockname()[1]
    recs, cals = _cut_taps(tmp_path)
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    exe = [sys.executable, "-m", "depthtouch.cli"]
    merge = subprocess.Popen([*exe, "merge", "--listen", f"127.0.0.1:{listen}", "--tuio",
                              f"127.0.0.1:{out_port}"], env=env, stderr=subprocess.PIPE)
    got: list[bytes] = []
    done = threading.Event()

    def collect() -> None:
        receiver.settimeout(0.2)
        while not done.is_set():
            try:
                got.append(receiver.recv(65536))
            except OSError:
                continue

    collector = threading.Thread(target=collect, daemon=True)
    collector.start()
    try:
        time.sleep(1.0)  # the merge is listening
        sensors = [subprocess.Popen([*exe, "replay", str(r), "--calibration", str(c), "--tuio",
                                     f"127.0.0.1:{listen}", "-q"], env=env)
                   for r, c in zip(recs, cals)]
        # a third-party tracker joins: one cursor far from the taps, 20 frames at 30 Hz
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for k in range(20):
                s.sendto(osc_frame([77], {77: (0.9, 0.9)}, k + 1, "other@elsewhere"),
                         ("127.0.0.1", listen))
                time.sleep(1 / 30)
            s.sendto(osc_frame([], {}, 21, "other@elsewhere"), ("127.0.0.1", listen))
        assert [p.wait(60) for p in sensors] == [0, 0]
        time.sleep(0.3)
        merge.send_signal(signal.SIGTERM)
        assert merge.wait(10) == 0
        time.sleep(0.3)
    finally:
        done.set()
        if merge.poll() is None:
            merge.kill()
        collector.join(2.0)
    parts = validate_stream(got)  # strict TUIO 1.1, fseq increasing over the whole stream
    assert all(p["source"] == "depthtouch-merge@127.0.0.1" for p in parts)
    assert parts[-1]["alive"] == []  # the clean stop's final empty alive
    ids = {sid for p in parts for sid in p["sets"]}
    # 5 taps (one in the overlap, seen by both sensors: one cursor) + the third-party cursor
    assert len(ids) == 6, sorted(ids)
    far = [p["sets"][sid] for p in parts for sid in p["sets"] if p["sets"][sid][0] > 0.85]
    assert far and all(abs(x - 0.9) < 1e-6 and abs(y - 0.9) < 1e-6 for x, y, *_ in far)
    assert np.isfinite([v for p in parts for s in p["sets"].values() for v in s]).all()
