"""TUIO as running clients see it: restarts, SIGTERM mid-touch, split frames, python-tuio at 30
touches. The strict client (tuio_client.py) applies the reference clients' rules."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from tuio_client import StrictTuioClient, UdpListener

from depthtouch.outputs.tuio import TuioCursor, TuioSink, encode_frame
from depthtouch.types import Frame, TouchEvent, TouchState
from synth import Finger, make_recording, result_of, write_recording

DEPTH = np.zeros((480, 640), np.uint16)


def touches(n_frames: int, ids: list[int], t0: float = 0.0, down_at: int = 2
            ) -> list[tuple[Frame, list[TouchEvent]]]:
    """Every id touches from frame ``down_at`` to the last frame but one, then lifts."""
    out = []
    for i in range(n_frames):
        t = t0 + i / 30.0
        evs = []
        if down_at <= i < n_frames - 1:
            for k, tid in enumerate(ids):
                state: TouchState = ("down" if i == down_at else
                                     "up" if i == n_frames - 2 else "move")
                evs.append(TouchEvent(i, t, tid, state, 40.0 + 18.0 * (k % 30) + i,
                                      60.0 + 12.0 * (k // 30) + 30.0 * (k % 3)))
        out.append((Frame(DEPTH, t, i), evs))
    return out


# --- the strict client's own rules -----------------------------------------------------------------
def test_strict_client_drops_late_frames_and_flags_phantoms():
    client = StrictTuioClient()
    for p in encode_frame([TuioCursor(1, 0.5, 0.5)], 500):
        client.feed(p)
    for p in encode_frame([TuioCursor(2, 0.5, 0.5)], 450):  # 50 below: a late frame
        client.feed(p)
    assert client.late == 1 and client.cursors.keys() == {1}
    for p in encode_frame([TuioCursor(3, 0.5, 0.5)], 300):  # 200 below: a new sender
        client.feed(p)
    assert client.cursors.keys() == {3}
    for p in encode_frame([], -1):  # always applied
        client.feed(p)
    assert client.cursors == {} and client.removed() == [1, 3]
    # a new id listed in the first part's alive, its set in the second part: a phantom
    cursors = [TuioCursor(i, 0.5, 0.5) for i in range(20)]
    for p in encode_frame(cursors, 1000, max_packet_bytes=512):
        client.feed(p)
    assert client.violations and "phantom" in client.violations[0]


def test_split_frame_lists_new_ids_with_their_set():
    client = StrictTuioClient()
    cursors = [TuioCursor(i, 0.5, 0.5) for i in range(40)]
    packets = encode_frame(cursors, 10, max_packet_bytes=512, new_ids=range(40))
    assert len(packets) > 2
    for p in packets:
        client.feed(p)
    assert client.violations == [] and sorted(client.cursors) == list(range(40))
    # a later frame with 10 more: the 40 old ones stay alive in every part
    more = cursors + [TuioCursor(i, 0.25, 0.25) for i in range(40, 50)]
    for p in encode_frame(more, 20, max_packet_bytes=512, new_ids=range(40, 50)):
        client.feed(p)
    assert client.violations == [] and client.removed() == [] and len(client.cursors) == 50


# --- restarts ----------------------------------------------------------------------------------
def test_restarted_sender_is_accepted_from_its_first_frame():
    """Two runs one second apart into one client; the second run's ids must all be new."""
    with UdpListener() as lis:
        for run, now in enumerate((1_700_000_000.0, 1_700_000_001.0)):
            clock = [now]

            def tick(c: list[float] = clock) -> float:
                c[0] += 0.002  # 2 ms of wall time per packet: faster than 30 fps
                return c[0]

            with TuioSink("127.0.0.1", lis.port, clock=tick) as sink:
                for frame, evs in touches(120, [1, 2]):
                    sink.send(result_of(frame, evs))
            lis.wait_quiet(0.1)
            with lis.lock:
                assert lis.client.cursors == {}, f"run {run} left cursors"
        c = lis.client
    assert c.violations == [] and c.late == 0
    assert len(c.added()) == 4 and len(set(c.added())) == 4  # ids never reused
    assert sorted(c.removed()) == sorted(c.added())
    assert c.resets == 4  # an empty alive with fseq -1 at each open and close


def test_restart_from_fseq_one_would_be_ignored():
    """What the reference clients did to the old sender (fseq from 1 in every run)."""
    client = StrictTuioClient()
    for run in range(2):
        for f in range(1, 60):
            for p in encode_frame([TuioCursor(10 * run + 1, 0.5, 0.5)], f):
                client.feed(p)
    # the second run is seen only once its count passes the first run's (frame 59 of 59)
    assert client.late == 58 and client.added() == [1, 11]


@pytest.fixture(scope="module")
def touch_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """80x60, 1.6 s empty, then three fingers down for 40 frames, then 10 empty frames."""
    script = [[Finger(20.0, 20.0), Finger(45.0, 25.0), Finger(60.0, 40.0)]] * 40 + [[]] * 10
    depth, ts = make_recording(50, script, shape=(60, 80), seed=3)
    return Path(write_recording(tmp_path_factory.mktemp("rec") / "rec.npz", depth, ts))


def test_two_replays_in_a_row_into_one_client(touch_recording, cli):
    with UdpListener() as lis:
        for _ in range(2):
            r = cli("replay", touch_recording, "--tuio", f"127.0.0.1:{lis.port}", "-q")
            assert r.rc == 0, r.err
            lis.wait_quiet(0.2)
        c = lis.client
    assert c.violations == [] and c.late == 0
    assert len(c.added()) == 6 and len(set(c.added())) == 6, c.added()
    assert sorted(c.removed()) == sorted(c.added()) and c.cursors == {}


# --- SIGTERM -----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def long_press_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    script = [[Finger(40.0, 30.0)]] * 2500  # a long press: the command is still in it when killed
    depth, ts = make_recording(50, script, shape=(60, 80), seed=5)
    return Path(write_recording(tmp_path_factory.mktemp("long") / "long.npz", depth, ts))


@pytest.mark.parametrize(("command", "sig"), [
    ("replay", signal.SIGTERM), ("replay", signal.SIGHUP), ("replay", signal.SIGINT),
    ("run", signal.SIGTERM), ("run", signal.SIGINT),
])
def test_signal_mid_touch_exits_0_and_clears_the_client(tmp_path, long_press_recording,
                                                        command, sig):
    events = tmp_path / "ev.jsonl"
    seen_touch = threading.Event()

    class Watch(StrictTuioClient):
        def feed(self, dgram: bytes) -> None:
            super().feed(dgram)
            if self.cursors:
                seen_touch.set()

    source = ([str(long_press_recording)] if command == "replay" else
              ["--source", str(long_press_recording)])  # run: paced at the recording's 30 fps
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    with UdpListener(Watch()) as lis:
        proc = subprocess.Popen(
            [sys.executable, "-m", "depthtouch.cli", command, *source, "--tuio",
             f"127.0.0.1:{lis.port}", "--events", str(events), "-q"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True)
        try:
            assert seen_touch.wait(120), "no touch reached the client"
            proc.send_signal(sig)
            out, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
        lis.wait_quiet(0.2)
        c = lis.client
    assert proc.returncode == 0, err
    assert "stopped" in err
    assert c.violations == [] and c.cursors == {} and len(c.removed()) == len(c.added()) >= 1
    lines = events.read_text().splitlines()  # the events file was kept, the touch ended
    assert lines and '"state": "down"' in lines[0] and '"state": "up"' in lines[-1]


def test_serve_stops_on_sigterm_with_exit_0():
    proc = subprocess.Popen(
        [sys.executable, "-m", "depthtouch.cli", "serve", "--source", "sim:taps", "--port", "0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()  # "depthtouch: serving ... (Ctrl-C to stop)"
        assert "serving" in line
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err


# --- python-tuio at 30 simultaneous touches ----------------------------------------------------
def test_python_tuio_sees_no_phantom_at_30_touches():
    pytest.importorskip("pythontuio")
    from pythonosc.osc_server import BlockingOSCUDPServer
    from pythontuio import TuioClient, TuioListener

    adds: dict[int, tuple[float, float]] = {}
    removed: list[int] = []

    class Listener(TuioListener):
        def add_tuio_cursor(self, cur):
            adds[cur.session_id] = tuple(cur.position)

        def remove_tuio_cursor(self, cur):
            removed.append(cur.session_id)

    client = TuioClient(("127.0.0.1", 0))
    client.add_listener(Listener())
    BlockingOSCUDPServer.__init__(client, ("127.0.0.1", 0), client)
    port = client.server_address[1]
    thread = threading.Thread(target=client.serve_forever, kwargs={"poll_interval": 0.05},
                              daemon=True)
    thread.start()
    try:
        with TuioSink("127.0.0.1", port) as sink:
            rec = touches(20, list(range(1, 31)))
            # ten more fingers land while the 30 are down: new ids in a split frame again
            for i, (frame, evs) in enumerate(rec):
                if 6 <= i < 18:
                    evs = evs + [TouchEvent(i, frame.timestamp_s, 100 + k,
                                            "down" if i == 6 else "up" if i == 17 else "move",
                                            50.0 + 20.0 * k, 400.0) for k in range(10)]
                sink.send(result_of(frame, evs))
            packets = sink.packets_sent
        assert packets > 20  # frames of 30-40 touches are split
        for _ in range(250):
            if len(removed) >= 40:
                break
            time.sleep(0.02)
    finally:
        client.shutdown()
        client.server_close()
        thread.join(5)
    assert len(adds) == 40 and sorted(removed) == sorted(adds)
    phantoms = [sid for sid, xy in adds.items() if xy == (0, 0) or xy == (0.0, 0.0)]
    assert phantoms == []
