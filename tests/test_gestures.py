"""Gestures from synthetic touch streams: tap, double tap, long press, drag, pinch, rotate."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from depthtouch.cli import main
from depthtouch.errors import ConfigError, OutputError
from depthtouch.gestures import (
    GESTURE_KINDS,
    GestureConfig,
    GestureEvent,
    GestureRecognizer,
    recognize_all,
)
from depthtouch.types import TouchEvent, TouchState
from synth import result_of

FPS = 30.0
Track = tuple[int, int, list[tuple[float, float]]]  # id, first frame, one position per frame


def still(n: int, xy=(200.0, 150.0), jitter_px: float = 0.0, seed: int = 0):
    rng = np.random.default_rng(seed)
    return [(xy[0] + rng.normal(0, jitter_px), xy[1] + rng.normal(0, jitter_px))
            if jitter_px else xy for _ in range(n)]


def line(n: int, start=(100.0, 100.0), step=(3.0, 0.0)):
    return [(start[0] + step[0] * k, start[1] + step[1] * k) for k in range(n)]


def two_finger(n: int, centre=(320.0, 240.0), r0=50.0, r1=50.0, a0_deg=0.0, a1_deg=0.0):
    """Two touches on a diameter whose radius and angle change linearly over n frames."""
    a_path, b_path = [], []
    for k in range(n):
        f = k / max(n - 1, 1)
        r, a = r0 + (r1 - r0) * f, math.radians(a0_deg + (a1_deg - a0_deg) * f)
        dx, dy = r * math.cos(a), r * math.sin(a)
        a_path.append((centre[0] - dx, centre[1] - dy))
        b_path.append((centre[0] + dx, centre[1] + dy))
    return a_path, b_path


def stream(tracks: list[Track], extra_frames: int = 3, fps: float = FPS, screen: bool = False):
    """Frames of events: down on a track's first frame, move after, up the frame after its last."""
    n = max(start + len(path) for _, start, path in tracks) + 1 + extra_frames
    frames = []
    for i in range(n):
        evs = []
        for tid, start, path in tracks:
            k = i - start
            if 0 <= k < len(path):
                state: TouchState = "down" if k == 0 else "move"
                x, y = path[k]
            elif k == len(path):
                state, (x, y) = "up", path[-1]
            else:
                continue
            extra = {"sx": 3 * x, "sy": 3 * y} if screen else {}
            evs.append(TouchEvent(i, i / fps, tid, state, x, y, extra))
        frames.append((i, i / fps, evs))
    return frames


def run(frames, config: GestureConfig | None = None) -> list[GestureEvent]:
    rec = GestureRecognizer(config)
    out: list[GestureEvent] = []
    for i, t, evs in frames:
        out.extend(rec.update(i, t, evs))
    return out


def kinds(events: list[GestureEvent]) -> list[str]:
    return [e.kind for e in events]


PINCH_A, PINCH_B = two_finger(26, r0=50.0, r1=100.0)
ROT_A, ROT_B = two_finger(31, a0_deg=160.0, a1_deg=200.0)  # crosses +-180 deg
DRAG = line(20)


@pytest.mark.parametrize(
    ("name", "tracks", "want"),
    [
        ("tap", [(1, 0, still(5))], ["tap"]),
        ("tap with 1 px jitter", [(1, 0, still(5, jitter_px=1.0, seed=4))], ["tap"]),
        # no gap between tap and long press: every press is one of them
        ("lifted just before the long-press time", [(1, 0, still(20))], ["tap"]),
        ("lifted on the frame it reaches the long-press time", [(1, 0, still(21))],
         ["long_press"]),
        ("long press", [(1, 0, still(30))], ["long_press"]),
        ("double tap", [(1, 0, still(5)), (2, 8, still(5))], ["tap", "tap", "double_tap"]),
        ("triple tap", [(1, 0, still(4)), (2, 7, still(4)), (3, 14, still(4))],
         ["tap", "tap", "double_tap", "tap"]),
        ("taps too far apart", [(1, 0, still(5)), (2, 8, still(5, xy=(300.0, 150.0)))],
         ["tap", "tap"]),
        ("taps too slow", [(1, 0, still(5)), (2, 20, still(5))], ["tap", "tap"]),
        ("drag", [(1, 0, DRAG)], ["drag_start"] + ["drag"] * 15 + ["drag_end"]),
        ("second finger ends a drag", [(1, 0, line(20)), (2, 10, still(5))],
         # then the pair pinches; neither finger taps or drags again after
         ["drag_start"] + ["drag"] * 5 + ["drag_end"] + ["pinch"] * 3),
        ("id switch: two touches overlap one frame", [(1, 0, still(6)), (2, 5, line(6))],
         []),
        ("id switch: two frames, fast", [(1, 0, still(6)),
                                          (2, 4, line(6, (150.0, 150.0), (15.0, 0.0)))], []),
    ],
)
def test_gesture_sequences(name, tracks, want):
    assert kinds(run(stream(tracks))) == want, name


def test_tap_fields():
    (tap,) = run(stream([(7, 3, still(5, xy=(123.0, 45.0)))]))
    assert (tap.kind, tap.frame, tap.ids, tap.x, tap.y) == ("tap", 8, (7,), 123.0, 45.0)
    assert tap.duration_s == pytest.approx(5 / FPS)
    tap1, tap2, dbl = run(stream([(1, 0, still(5)), (2, 8, still(5))]))
    assert dbl.ids == (1, 2) and dbl.frame == tap2.frame == 13


def test_long_press_fires_once_while_down():
    (lp,) = run(stream([(1, 0, still(40))]))
    assert lp.frame == 21  # 0.7 s after the down at 30 fps
    assert lp.duration_s == pytest.approx(0.7)


@pytest.mark.parametrize("n_frames", range(1, 45))
def test_every_still_press_is_a_tap_or_a_long_press(n_frames):
    got = kinds(run(stream([(1, 0, still(n_frames, jitter_px=1.0, seed=n_frames))])))
    assert got == (["tap"] if n_frames < 21 else ["long_press"])


def test_slop_in_mm_with_a_known_scale():
    # 4 mm per pixel: the 25 mm slop is 6.25 px; a press wandering 8 px is a drag
    path = [(200.0 + min(k, 8), 150.0) for k in range(12)]
    assert kinds(run(stream([(1, 0, path)])))[0] == "tap"  # px thresholds: 10 px
    rec = GestureRecognizer(mm_per_px=4.0)
    got = [e.kind for i, t, evs in stream([(1, 0, path)]) for e in rec.update(i, t, evs)]
    assert got[0] == "drag_start"
    with pytest.raises(ConfigError, match="mm_per_px"):
        GestureRecognizer(mm_per_px=0.0)


def test_drag_offsets_add_up():
    got = run(stream([(1, 0, line(20, step=(3.0, -1.0)))]))
    start, *drags, end = got
    assert start.kind == "drag_start" and end.kind == "drag_end"
    assert math.hypot(start.dx, start.dy) > 10.0  # type: ignore[arg-type]
    total_x = start.dx + sum(d.dx for d in drags)  # type: ignore[operator, misc]
    total_y = start.dy + sum(d.dy for d in drags)  # type: ignore[operator, misc]
    assert (total_x, total_y) == pytest.approx((end.dx, end.dy))
    assert (end.dx, end.dy) == pytest.approx((57.0, -19.0))


def test_pinch_reports_cumulative_scale():
    got = run(stream([(1, 0, PINCH_A), (2, 0, PINCH_B)]))
    assert set(kinds(got)) == {"pinch"}  # no rotate, no tap, no drag
    phases = [e.phase for e in got]
    assert phases[0] == "start" and phases[-1] == "end" and set(phases[1:-1]) == {"move"}
    assert abs(got[0].scale - 1.0) >= 0.08  # type: ignore[operator]
    assert got[-1].scale == pytest.approx(2.0, abs=1e-6)
    scales = [float(e.scale or 0.0) for e in got]
    assert scales == sorted(scales)  # monotone while the fingers spread
    assert (got[-1].x, got[-1].y) == pytest.approx((320.0, 240.0))
    assert got[-1].ids == (1, 2)
    # pinch in
    a, b = two_finger(26, r0=100.0, r1=40.0)
    assert run(stream([(1, 0, a), (2, 0, b)]))[-1].scale == pytest.approx(0.4)


def test_rotate_reports_cumulative_angle_across_wrap():
    got = run(stream([(1, 0, ROT_A), (2, 0, ROT_B)]))
    assert set(kinds(got)) == {"rotate"}
    assert got[0].phase == "start" and got[-1].phase == "end"
    assert got[0].rotation_deg == pytest.approx(8.0, abs=1.5)
    assert got[-1].rotation_deg == pytest.approx(40.0, abs=1e-6)  # clockwise in y-down
    a, b = two_finger(31, a0_deg=10.0, a1_deg=-80.0)
    assert run(stream([(1, 0, a), (2, 0, b)]))[-1].rotation_deg == pytest.approx(-90.0)


def test_pinch_and_rotate_together_and_fingers_make_no_taps():
    a, b = two_finger(31, r0=60.0, r1=90.0, a0_deg=0.0, a1_deg=45.0)
    got = run(stream([(1, 0, a), (2, 0, b)]))
    assert {"pinch", "rotate"} == set(kinds(got))
    ends = {e.kind: e for e in got if e.phase == "end"}
    assert ends["pinch"].scale == pytest.approx(1.5)
    assert ends["rotate"].rotation_deg == pytest.approx(45.0)


def test_quick_two_finger_tap_is_not_a_tap():
    assert run(stream([(1, 0, still(4)), (2, 0, still(4, xy=(260.0, 150.0)))])) == []


def test_touch_missing_from_events_counts_as_lifted():
    frames = stream([(1, 0, still(4))], extra_frames=2)
    frames = [(i, t, [e for e in evs if e.state != "up"]) for i, t, evs in frames]
    (tap,) = run(frames)
    assert tap.frame == 4


def test_reset_forgets_touches_and_pending_double_tap():
    rec = GestureRecognizer()
    frames = stream([(1, 0, still(5)), (2, 8, still(5))])
    out = []
    for i, t, evs in frames[:7]:
        out.extend(rec.update(i, t, evs))
    assert kinds(out) == ["tap"]
    rec.reset()
    for i, t, evs in frames[7:]:
        out.extend(rec.update(i, t, evs))
    assert kinds(out) == ["tap", "tap"]  # the first tap was forgotten: no double tap


def test_screen_space_uses_sx_sy_and_its_thresholds():
    frames = stream([(1, 0, line(20, step=(1.0, 0.0)))], screen=True)
    # 19 depth px = 57 screen px: a drag in screen space, and a tap-like hold in depth space
    assert kinds(run(frames, GestureConfig(space="screen")))[0] == "drag_start"
    got = run(frames, GestureConfig(space="screen"))
    assert got[0].space == "screen" and got[-1].dx == pytest.approx(57.0)
    assert "drag_start" in kinds(run(frames))  # 19 px in depth space too
    with pytest.raises(ConfigError, match="sx, sy"):
        run(stream([(1, 0, still(3))]), GestureConfig(space="screen"))


def test_to_dict_is_json():
    got = run(stream([(1, 0, PINCH_A), (2, 0, PINCH_B)]))
    d = got[-1].to_dict()
    assert d["type"] == "gesture" and d["kind"] == "pinch" and d["phase"] == "end"
    assert d["ids"] == [1, 2] and d["scale"] == pytest.approx(2.0)
    assert "dx" not in d and "rotation_deg" not in d
    assert json.loads(json.dumps(d)) == d
    assert all(e.kind in GESTURE_KINDS for e in got)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("tap_max_s", 0.0), ("tap_max_s", 6.0), ("tap_max_move_px", -1.0),
        ("double_tap_gap_s", 0.0), ("long_press_s", 0.0), ("drag_min_move_px", 0.0),
        ("pinch_min_change", 0.0), ("pinch_step", -0.1), ("rotate_min_deg", 200.0),
        ("rotate_step_deg", 0.0), ("double_tap_max_dist_px", math.nan), ("space", "world"),
        ("pair_min_s", -0.1),
    ],
)
def test_bad_config_raises_one_line(field, value):
    cfg = GestureConfig(**{field: value})
    with pytest.raises(ConfigError, match=f"gestures.{field}") as ei:
        GestureRecognizer(cfg)
    assert "\n" not in str(ei.value)


def _write_events(path, frames) -> None:
    from depthtouch.outputs.jsonl import JsonlSink
    from depthtouch.types import Frame

    depth = np.zeros((4, 4), np.uint16)
    with JsonlSink(path) as sink:
        for i, t, evs in frames:
            sink.send(result_of(Frame(depth, t, i), evs))


def test_recognize_all_matches_frame_by_frame_and_lifts_at_the_end():
    frames = stream([(1, 0, still(5)), (2, 8, still(5)), (3, 20, PINCH_A), (4, 20, PINCH_B)])
    flat = [e for _, _, evs in frames for e in evs]
    assert recognize_all(flat) == run(frames)
    # a stream cut while a touch is down: it is lifted after the last frame
    cut = [e for e in flat if e.frame < 3]
    assert kinds(recognize_all(cut)) == ["tap"]
    with pytest.raises(OutputError, match="frame order"):
        recognize_all(flat[::-1])


def test_cli_gestures(tmp_path, capsys):
    frames = stream([(1, 0, still(5)), (2, 8, still(5)), (3, 20, DRAG)], screen=True)
    _write_events(tmp_path / "ev.jsonl", frames)
    assert main(["gestures", str(tmp_path / "ev.jsonl")]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [d["kind"] for d in lines][:3] == ["tap", "tap", "double_tap"]
    assert lines[-1]["kind"] == "drag_end" and lines[-1]["space"] == "depth"
    out = tmp_path / "g.jsonl"
    assert main(["gestures", str(tmp_path / "ev.jsonl"), "--space", "screen", "--out",
                 str(out)]) == 0
    assert json.loads(out.read_text().splitlines()[-1])["dx"] == pytest.approx(3 * 57.0)
    # no sx, sy in the events: one line, exit 2
    _write_events(tmp_path / "plain.jsonl", stream([(1, 0, still(5))]))
    capsys.readouterr()
    assert main(["gestures", str(tmp_path / "plain.jsonl"), "--space", "screen"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "sx, sy" in err
    assert main(["gestures", str(tmp_path / "missing.jsonl")]) == 2
