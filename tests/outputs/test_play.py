"""``depthtouch play``: grouping, pacing, outputs, SIGTERM, and that it loads no compiled kernels."""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pythonosc.osc_bundle import OscBundle

from depthtouch.calibration import Calibration, save_calibration
from depthtouch.errors import CalibrationError, ConfigError, OutputError
from depthtouch.outputs.play import group_frames, play
from depthtouch.types import TouchEvent


def write_events(path: Path, rows: list[tuple[int, float, int, str, float, float]]) -> Path:
    with path.open("w") as fh:
        for frame, t, tid, state, x, y in rows:
            fh.write(json.dumps({"frame": frame, "t": t, "id": tid, "state": state, "x": x,
                                 "y": y, "sx": x * 3, "sy": y * 2}) + "\n")
    return path


# a touch for 3 frames, 0.5 s apart; a second one joins in frame 2
ROWS = [(10, 1.0, 1, "down", 10.0, 20.0), (11, 1.5, 1, "move", 11.0, 20.0),
        (11, 1.5, 2, "down", 50.0, 60.0), (12, 2.0, 1, "up", 12.0, 20.0),
        (12, 2.0, 2, "up", 50.0, 60.0)]


@pytest.fixture
def receiver():
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(5.0)
    yield sock
    sock.close()


def alive_lists(packets: list[bytes]) -> list[list[int]]:
    """The ``alive`` lists sent, session ids renumbered 1, 2, ... by first appearance (a sender
    offsets them by a per-run base so that ids are never reused across runs)."""
    out: list[list[int]] = []
    order: dict[int, int] = {}
    for p in packets:
        for msg in OscBundle(p):
            if msg.params and msg.params[0] == "alive":
                out.append([order.setdefault(s, len(order) + 1) for s in msg.params[1:]])
    return out


def recv_all(sock: socket.socket) -> list[bytes]:
    got = []
    sock.settimeout(0.3)
    try:
        while True:
            got.append(sock.recv(65536))
    except OSError:
        pass
    return got


def test_group_frames_keeps_file_order():
    evs = [TouchEvent(f, 0.0, i, "move", 0.0, 0.0) for f, i in ((1, 1), (1, 2), (2, 1), (1, 3))]
    assert [[e.id for e in b] for b in group_frames(evs)] == [[1, 2], [1], [3]]
    assert list(group_frames([])) == []


def test_paced_play_waits_for_each_frame_and_reaches_tuio(tmp_path, receiver):
    events = write_events(tmp_path / "ev.jsonl", ROWS)
    now = [100.0]
    waits: list[float] = []

    def sleep(s: float) -> None:
        waits.append(round(s, 6))
        now[0] += s

    port = receiver.getsockname()[1]
    summary = play(events, tuio=f"127.0.0.1:{port}", screen_wh_px=(1920, 1080),
                   sleep=sleep, clock=lambda: now[0])
    assert waits == [0.5, 0.5]
    assert (summary.frames, summary.events, summary.touches) == (3, 5, 2)
    assert not summary.terminated and summary.outputs == (f"TUIO 127.0.0.1:{port}",)
    alive = alive_lists(recv_all(receiver))
    # opening and closing with an empty alive (a restarted sender's stale cursors go)
    assert alive == [[], [1], [1, 2], [], []]


def test_fast_play_does_not_wait(tmp_path, receiver):
    events = write_events(tmp_path / "ev.jsonl", ROWS)

    def no_sleep(s: float) -> None:
        raise AssertionError("fast play slept")

    port = receiver.getsockname()[1]
    assert play(events, tuio=f"127.0.0.1:{port}", screen_wh_px=(640, 480), fast=True,
                sleep=no_sleep).frames == 3


def test_calibration_gives_the_screen(tmp_path, receiver):
    events = write_events(tmp_path / "ev.jsonl", ROWS[:1])
    cal = save_calibration(Calibration(np.eye(3), (40, 80), 0.0), tmp_path / "cal.json")
    port = receiver.getsockname()[1]
    play(events, tuio=f"127.0.0.1:{port}", calibration_path=cal, fast=True)
    sets = [m.params for p in recv_all(receiver) for m in OscBundle(p) if m.params[0] == "set"]
    assert sets[0][2:4] == pytest.approx([30 / 40, 40 / 80])  # sx, sy of the event / screen


@pytest.mark.parametrize("kw, exc, match", [
    ({"screen_wh_px": (640, 480)}, ConfigError, "play has no output; give --uinput"),
    ({"tuio": "127.0.0.1:9"}, ConfigError, "--calibration FILE .* or --screen WxH"),
    ({"tuio": "127.0.0.1:9", "screen_wh_px": (1, 1), "calibration_path": "c.json"},
     ConfigError, "not both"),
    ({"tuio": "127.0.0.1:9", "calibration_path": "missing.json"}, CalibrationError, "missing"),
    ({"tuio": "nohost:", "screen_wh_px": (640, 480)}, ConfigError, "HOST:PORT"),
])
def test_play_errors(tmp_path, kw, exc, match):
    events = write_events(tmp_path / "ev.jsonl", ROWS)
    with pytest.raises(exc, match=match):
        play(events, **kw)


def test_bad_events_file_is_one_line(cli, tmp_path):
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"frame": 0}\n')
    r = cli("play", bad, "--tuio", "--screen", "640x480")
    assert r.rc == 2 and len(r.err_lines) == 1 and "bad.jsonl:1: not a touch event" in r.err
    r = cli("play", tmp_path / "none.jsonl", "--tuio", "--screen", "640x480")
    assert r.rc == 2 and "cannot read events" in r.err
    with pytest.raises(OutputError):
        play(bad, tuio="127.0.0.1:9", screen_wh_px=(640, 480))


def _play_process(events: Path, port: int, *extra: str) -> subprocess.Popen:
    code = ("import sys\nfrom depthtouch.cli import main\nrc = main(sys.argv[1:])\n"
            "heavy = sorted(m for m in sys.modules if m == 'numba' or m.startswith("
            "('depthtouch.touch', 'depthtouch.pipeline', 'depthtouch.tracking')))\n"
            "print('heavy modules:', heavy, flush=True)\nsys.exit(rc)\n")
    return subprocess.Popen(
        [sys.executable, "-c", code, "play", str(events), "--tuio", f"127.0.0.1:{port}",
         "--screen", "1920x1080", *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True)


def test_play_loads_no_compiled_kernels(tmp_path, receiver):
    events = write_events(tmp_path / "ev.jsonl", ROWS)
    proc = _play_process(events, receiver.getsockname()[1], "--fast")
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert "heavy modules: []" in out


def test_sigterm_mid_touch_lifts_every_contact_and_exits_0(tmp_path, receiver):
    rows = [(i, float(i), 1, "down" if i == 0 else "move", 10.0 + i, 20.0) for i in range(60)]
    events = write_events(tmp_path / "ev.jsonl", rows)  # one touch, a frame per second
    proc = _play_process(events, receiver.getsockname()[1])
    receiver.settimeout(60)
    opening = receiver.recv(65536)  # the sender's opening empty alive
    first = receiver.recv(65536)  # the touch is down
    assert alive_lists([opening, first]) == [[], [1]]
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "stopped by SIGTERM" in out and "heavy modules: []" in out
    assert alive_lists(recv_all(receiver))[-1] == []
