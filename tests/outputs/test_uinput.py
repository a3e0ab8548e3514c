"""The uinput touchscreen: exact evdev event streams from touch events, and the error rows.

No device is needed: :class:`TouchEncoder` is pure, and :class:`UinputSink` is exercised with a
fake python-evdev module. The real kernel is in test_uinput_vm.py.
"""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

from depthtouch.calibration import Calibration
from depthtouch.errors import ConfigError, OutputError
from depthtouch.outputs import uinput as u
from depthtouch.outputs.uinput import TouchEncoder, UinputConfig, UinputSink
from depthtouch.types import Frame, TouchEvent
from synth import result_of

SYN = (0, 0, 0)
ABS, KEY = 3, 1
SLOT, TID, PX, PY, MAJOR, AX, AY, BTN = 0x2F, 0x39, 0x35, 0x36, 0x30, 0, 1, 0x14A


def ev(frame: int, tid: int, state: str, x: float, y: float, **extra: float) -> TouchEvent:
    return TouchEvent(frame, frame / 30, tid, state, x, y, dict(extra))  # type: ignore[arg-type]


def enc(**kw: object) -> TouchEncoder:
    return TouchEncoder(UinputConfig((1920, 1080), **kw))  # type: ignore[arg-type]


def test_two_finger_stream_is_exact():
    e = enc()
    # frame 1: one finger down (sx, sy win over x, y; rounded half up)
    assert e.update([ev(1, 7, "down", 1, 2, sx=100.5, sy=200.4)]) == [
        (ABS, TID, 0), (ABS, PX, 101), (ABS, PY, 200), (ABS, AX, 101), (ABS, AY, 200),
        (KEY, BTN, 1), SYN]
    # frame 2: the first moves in x only, a second finger goes down in slot 1
    assert e.update([ev(2, 7, "move", 1, 2, sx=110.0, sy=200.0),
                     ev(2, 9, "down", 1, 2, sx=500.0, sy=600.0)]) == [
        (ABS, PX, 110), (ABS, SLOT, 1), (ABS, TID, 1), (ABS, PX, 500), (ABS, PY, 600),
        (ABS, AX, 110), SYN]
    # frame 3: a move that rounds to the same pixel writes nothing at all
    assert e.update([ev(3, 7, "move", 1, 2, sx=110.2, sy=199.8)]) == []
    # frame 4: the first finger lifts at a new place; the pointer moves to the one left
    assert e.update([ev(4, 7, "up", 1, 2, sx=120.0, sy=200.0)]) == [
        (ABS, SLOT, 0), (ABS, PX, 120), (ABS, TID, -1), (ABS, AX, 500), (ABS, AY, 600), SYN]
    # frame 5: a new finger takes the free slot 0 and a new tracking id
    assert e.update([ev(5, 11, "down", 1, 2, sx=5.0, sy=6.0)]) == [
        (ABS, TID, 2), (ABS, PX, 5), (ABS, PY, 6), SYN]
    assert e.active == 2
    # stop: every contact lifted in one report, BTN_TOUCH released
    assert e.release_all() == [(ABS, SLOT, 1), (ABS, TID, -1), (ABS, SLOT, 0), (ABS, TID, -1),
                               (KEY, BTN, 0), SYN]
    assert e.release_all() == []
    assert e.active == 0


@pytest.mark.parametrize("x, y, want", [
    (-40.0, 20.0, (0, 20)),          # clipped to the axis range
    (1919.6, 1079.5, (1919, 1079)),  # max is size - 1
    (float("nan"), 3.0, (959, 3)),   # a broken value lands mid-screen instead of raising
])
def test_positions_are_rounded_and_clipped(x, y, want):
    out = enc().update([ev(0, 1, "down", 0, 0, sx=x, sy=y)])
    assert (out[1][2], out[2][2]) == want


def test_without_sx_sy_depth_pixels_or_the_calibration_are_used():
    raw = TouchEncoder(UinputConfig((640, 480)))
    assert raw.update([ev(0, 1, "down", 320.4, 239.6)])[1:3] == [(ABS, PX, 320), (ABS, PY, 240)]
    cal = Calibration(np.diag([3.0, 2.25, 1.0]), (1920, 1080), 0.0)
    mapped = TouchEncoder(UinputConfig((1920, 1080)), cal)
    assert mapped.update([ev(0, 1, "down", 320, 240)])[1:3] == [(ABS, PX, 960), (ABS, PY, 540)]


def test_touch_major_from_area():
    e = enc(touch_major=True)
    out = e.update([ev(0, 1, "down", 0, 0, sx=1, sy=1, area=50)])
    assert (ABS, MAJOR, 8) in out  # 2 * sqrt(50 / pi) = 7.98
    assert e.update([ev(1, 1, "move", 0, 0, sx=1, sy=1, area=51)]) == []  # still 8
    assert e.update([ev(2, 1, "move", 0, 0, sx=1, sy=1, area=80)]) == [(ABS, MAJOR, 10), SYN]
    assert all(code != MAJOR for _, code, _ in enc().update([ev(0, 1, "down", 0, 0, area=50)]))


def test_more_touches_than_slots_are_dropped_and_counted():
    e = enc(slots=10)
    downs = [ev(0, i, "down", 0, 0, sx=i, sy=i) for i in range(12)]
    out = e.update(downs)
    assert e.active == 10 and e.dropped == 2
    assert [v for _, c, v in out if c == SLOT] == list(range(1, 10))
    # the dropped ones' moves and ups are ignored, the others go on
    assert e.update([ev(1, 11, "move", 0, 0, sx=50, sy=50), ev(1, 11, "up", 0, 0)]) == []
    assert e.update([ev(2, 3, "up", 0, 0, sx=3, sy=3)]) == [(ABS, SLOT, 3), (ABS, TID, -1), SYN]


def test_repeated_down_restarts_the_contact_and_reset_forgets():
    e = enc()
    e.update([ev(0, 1, "down", 0, 0, sx=10, sy=10)])
    assert e.update([ev(1, 1, "down", 0, 0, sx=10, sy=10)]) == [
        (ABS, TID, -1), (ABS, TID, 1), (ABS, PX, 10), (ABS, PY, 10), SYN]
    e.reset()
    assert e.active == 0 and e.release_all() == []
    assert e.update([ev(2, 1, "down", 0, 0, sx=1, sy=1)])[0] == (ABS, TID, 0)


def test_tracking_ids_wrap_within_the_declared_range():
    e = enc()
    e._next_tracking_id = u.TRACKING_ID_MAX
    assert e.update([ev(0, 1, "down", 0, 0)])[0] == (ABS, TID, u.TRACKING_ID_MAX)
    assert e.update([ev(1, 2, "down", 0, 0)])[1] == (ABS, TID, 0)


@pytest.mark.parametrize("kw, match", [
    ({"screen_wh_px": (0, 1080)}, "two whole numbers in \\[1, 65535\\]"),
    ({"screen_wh_px": (1920.0, 1080)}, "two whole numbers"),
    ({"screen_wh_px": (1920, 1080, 3)}, "two whole numbers"),
    ({"screen_wh_px": (1920, 1080), "slots": 9}, "slots = 9 is out of range; allowed \\[10, 64\\]"),
    ({"screen_wh_px": (1920, 1080), "slots": 65}, "slots = 65"),
    ({"screen_wh_px": (1920, 1080), "settle_s": -1.0}, "settle_s"),
    ({"screen_wh_px": (1920, 1080), "name": "x" * 80}, "name must be 1 to 79 bytes"),
])
def test_config_errors_name_the_range(kw, match):
    with pytest.raises(ConfigError, match=match):
        UinputConfig(**kw)  # type: ignore[arg-type]


# --- the sink, with a fake python-evdev ------------------------------------------------------------
class FakeUInput:
    instances: list[FakeUInput] = []

    def __init__(self, caps, **kw):
        self.caps, self.kw, self.written, self.closed = caps, kw, [], False
        FakeUInput.instances.append(self)

    def write(self, t, c, v):
        if getattr(self, "fail", False):
            raise OSError(19, "No such device")
        self.written.append((t, c, v))

    def close(self):
        self.closed = True


@pytest.fixture
def fake_evdev(monkeypatch, tmp_path):
    mod = types.ModuleType("evdev")
    mod.UInput = FakeUInput  # type: ignore[attr-defined]
    mod.UInputError = type("UInputError", (Exception,), {})  # type: ignore[attr-defined]
    mod.AbsInfo = lambda *a, **k: (a, k)  # type: ignore[attr-defined]
    mod.ecodes = types.SimpleNamespace(EV_KEY=1, EV_ABS=3)  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "evdev", mod)
    node = tmp_path / "uinput"
    node.write_bytes(b"")
    FakeUInput.instances = []
    return str(node)


def test_sink_creates_a_direct_touch_device_and_lifts_every_contact(fake_evdev):
    with UinputSink((1920, 1080), settle_s=0, path=fake_evdev) as sink:
        (dev,) = FakeUInput.instances
        assert dev.kw["input_props"] == [u.INPUT_PROP_DIRECT] and dev.kw["bustype"] == 0x06
        abs_codes = [c for c, _ in dev.caps[3]]
        assert abs_codes == [AX, AY, SLOT, TID, PX, PY]
        assert dev.caps[3][2][1][0] == (0, 0, 9, 0, 0, 0)  # 10 slots
        sink.send(result_of(Frame(np.zeros((4, 4), np.uint16), 0.0, 0),
                            [ev(0, 1, "down", 0, 0, sx=3, sy=4), ev(0, 2, "down", 0, 0, sx=5, sy=6)]))
    assert dev.closed
    assert dev.written[-6:] == [(ABS, SLOT, 0), (ABS, TID, -1), (ABS, SLOT, 1), (ABS, TID, -1),
                                (KEY, BTN, 0), SYN]
    sink.close()  # twice is fine
    assert len([w for w in dev.written if w == SYN]) == 2


def test_sink_without_a_size_takes_the_depth_image_at_the_first_frame(fake_evdev):
    sink = UinputSink(settle_s=0, path=fake_evdev)
    assert FakeUInput.instances == []
    sink.send(result_of(Frame(np.zeros((480, 640), np.uint16), 0.0, 0), []))
    (dev,) = FakeUInput.instances
    assert dev.caps[3][0][1][1]["max"] == 639 and dev.caps[3][1][1][1]["max"] == 479
    sink.close()


def test_sink_write_errors_are_counted_not_raised(fake_evdev, caplog):
    sink = UinputSink((100, 100), settle_s=0, path=fake_evdev)
    FakeUInput.instances[0].fail = True  # type: ignore[attr-defined]
    frame = Frame(np.zeros((4, 4), np.uint16), 0.0, 0)
    sink.send(result_of(frame, [ev(0, 1, "down", 0, 0, sx=1, sy=1)]))
    sink.send(result_of(frame, [ev(1, 1, "move", 0, 0, sx=2, sy=1)]))
    sink.close()
    assert sink.errors == 3
    assert caplog.text.count("write failed") == 1


def test_missing_uinput_names_modprobe_and_the_udev_rule(tmp_path):
    with pytest.raises(OutputError) as err:
        UinputSink((1920, 1080), path=str(tmp_path / "uinput"))
    msg = str(err.value)
    assert "does not exist" in msg and "modprobe uinput" in msg and 'GROUP="input"' in msg
    assert "\n" not in msg


def test_unwritable_uinput_names_the_fix(tmp_path, monkeypatch):
    node = tmp_path / "uinput"
    node.write_bytes(b"")
    monkeypatch.setattr(u.os, "access", lambda p, mode: False)  # root may write anything
    with pytest.raises(OutputError, match="not writable by this user; .*modprobe uinput"):
        UinputSink((1920, 1080), path=str(node))


def test_bad_size_is_reported_before_the_device(tmp_path):
    with pytest.raises(ConfigError, match="screen size"):
        UinputSink((0, 0), path=str(tmp_path / "missing"))


@pytest.mark.parametrize("command", [
    ["replay", "{rec}", "--uinput"],
    ["run", "--source", "{rec}", "--uinput", "-q"],
    ["play", "{events}", "--uinput", "--screen", "640x480"],
])
def test_cli_without_uinput_exits_2_with_one_line(cli, npz_recording, tmp_path, monkeypatch,
                                                   command):
    monkeypatch.setattr(u, "UINPUT_PATH", str(tmp_path / "no-uinput"))
    events = tmp_path / "ev.jsonl"
    events.write_text('{"frame": 0, "t": 0.0, "id": 1, "state": "down", "x": 1, "y": 2}\n')
    r = cli(*[a.format(rec=npz_recording, events=events) for a in command])
    assert r.rc == 2
    assert len(r.err_lines) == 1 and "modprobe uinput" in r.err, r.err
