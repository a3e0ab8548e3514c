"""Fusion rules on synthetic per-camera events: overlap -> one id, a drag crossing the seam keeps
its id, cameras out of step are fused by time, ids never reused, duplicates merged."""

from __future__ import annotations

import numpy as np
import pytest

from depthtouch.errors import ConfigError
from depthtouch.fusion import Fusion, FusionConfig, inside_px, predict, view_polygon
from depthtouch.types import TouchEvent

# two cameras side by side on a 1000x500 screen, overlapping in x in [450, 550]
VIEW_A = np.array([[0, 0], [550, 0], [550, 500], [0, 500]], float)
VIEW_B = np.array([[450, 0], [1000, 0], [1000, 500], [450, 500]], float)
CFG = FusionConfig(gate_px=30, blend_px=40, edge_px=20, handoff_s=0.1, max_predict_s=0.1,
                   merge_s=0.1)


def ev(tid: int, state: str, sx: float, sy: float, frame: int = 0) -> TouchEvent:
    return TouchEvent(frame, 0.0, tid, state, sx / 2, sy / 2, {"sx": sx, "sy": sy})  # type: ignore[arg-type]


def fusion() -> Fusion:
    f = Fusion(CFG)
    f.set_view(0, VIEW_A)
    f.set_view(1, VIEW_B)
    return f


def test_a_finger_in_the_overlap_is_one_touch():
    f = fusion()
    out = f.update(0, 0.0, 0, [ev(7, "down", 500, 200)])
    assert [(e.id, e.state) for e in out] == [(1, "down")]
    out = f.update(1, 0.005, 0, [ev(3, "down", 502, 201)])
    assert [(e.id, e.state) for e in out] == [(1, "move")]
    assert 500 <= out[0].extra["sx"] <= 502
    # one camera loses it: the touch goes on with the other
    out = f.update(0, 0.033, 1, [ev(7, "up", 500, 200)])
    assert [(e.id, e.state) for e in out] == [(1, "move")]
    assert out[0].extra["cam"] == 1
    out = f.update(1, 0.038, 1, [ev(3, "up", 502, 201)])
    assert [(e.id, e.state) for e in out] == [(1, "up")]  # deep in B's view: no hold
    assert f.active_ids == []


def test_two_fingers_of_one_camera_stay_two_touches():
    f = fusion()
    out = f.update(0, 0.0, 0, [ev(1, "down", 500, 200), ev(2, "down", 505, 200)])
    assert sorted(e.id for e in out) == [1, 2]
    out = f.update(1, 0.01, 0, [ev(5, "down", 501, 200), ev(6, "down", 506, 200)])
    assert sorted(e.id for e in out) == [1, 2]


def test_a_drag_across_the_seam_keeps_its_id():
    f = fusion()
    ids, cams = set(), []
    a_id, b_id = 11, 21
    a_on, b_on = False, False
    for k in range(60):  # 300 px/s from x = 300 (A only) to x = 890 (B only), both at 30 Hz
        t = k / 30.0
        x = 300 + 10 * k
        for cam, lo, hi in ((0, 0, 550), (1, 450, 1000)):
            tt = t + (0.011 if cam else 0.0)  # out of step
            inside = lo <= x < hi
            on = a_on if cam == 0 else b_on
            tid = a_id if cam == 0 else b_id
            if inside:
                state = "move" if on else "down"
            elif on:
                state = "up"
            else:
                continue
            out = f.update(cam, tt, k, [ev(tid, state, x, 250)])
            if cam == 0:
                a_on = inside
            else:
                b_on = inside
            for e in out:
                ids.add(e.id)
                cams.append(e.extra["cam"])
    assert ids == {1}
    assert cams[0] == 0 and cams[-1] == 1


def test_handoff_without_overlap_waits_for_the_next_camera():
    f = fusion()
    f.update(0, 0.0, 0, [ev(1, "down", 530, 200)])
    f.update(0, 0.033, 1, [ev(1, "move", 540, 200)])
    out = f.update(0, 0.066, 2, [ev(1, "up", 545, 200)])  # 5 px from A's edge: held
    assert [(e.id, e.state) for e in out] == [(1, "move")]
    out = f.update(1, 0.1, 3, [ev(4, "down", 560, 200)])
    assert [(e.id, e.state) for e in out] == [(1, "move")]


def test_a_held_touch_ends_after_the_handoff_time():
    f = fusion()
    f.update(0, 0.0, 0, [ev(1, "down", 545, 200)])
    assert [e.state for e in f.update(0, 0.033, 1, [ev(1, "up", 545, 200)])] == ["move"]
    out = f.update(0, 0.2, 6, [])
    assert [(e.id, e.state) for e in out] == [(1, "up")]
    out = f.update(1, 0.25, 7, [ev(4, "down", 560, 200)])
    assert [(e.id, e.state) for e in out] == [(2, "down")]  # a new finger, a new id


def test_cameras_out_of_step_are_fused_by_time_not_frame_number():
    f = fusion()
    # the finger moves at 600 px/s along x; camera B reports 50 ms late in frame numbers
    f.update(0, 0.0, 0, [ev(1, "down", 470, 100)])
    f.update(0, 0.05, 1, [ev(1, "move", 500, 100)])
    # B's observation of t = 0.04 (x = 494) arrives; A's prediction to 0.04 is still near
    out = f.update(1, 0.04, 99, [ev(9, "down", 494, 100)])
    assert [e.id for e in out] == [1]
    # a camera's observation is predicted to now: A at t = 0.1 without a new frame from it
    out = f.update(1, 0.1, 100, [ev(9, "move", 530, 100)])
    assert out[0].t == pytest.approx(0.1)
    assert 525 <= out[0].extra["sx"] <= 535


def test_one_update_per_instant_when_cameras_are_in_step():
    f = fusion()
    assert f.update(0, 0.0, 0, [ev(1, "down", 500, 200)], emit=False) == []
    out = f.update(1, 0.0, 0, [ev(2, "down", 500, 200)])
    assert [(e.id, e.state) for e in out] == [(1, "down")]
    assert f.update(0, 0.033, 1, [ev(1, "up", 500, 200)], emit=False) == []
    out = f.update(1, 0.033, 1, [ev(2, "up", 500, 200)])
    assert [(e.id, e.state) for e in out] == [(1, "up")]


def test_duplicates_from_a_late_join_are_merged_into_the_older():
    f = Fusion(FusionConfig(gate_px=10, merge_s=0.05))
    f.set_view(0, VIEW_A)
    f.set_view(1, VIEW_B)
    f.update(0, 0.0, 0, [ev(1, "down", 500, 200)])
    out = f.update(1, 0.01, 0, [ev(2, "down", 515, 200)])  # beyond the gate: a second touch
    assert sorted(e.id for e in out) == [1, 2]
    states: list[tuple[int, str]] = []
    for k in range(1, 6):  # the calibration error shrinks: both report the same place
        t = k / 30.0
        states += [(e.id, e.state) for e in f.update(0, t, k, [ev(1, "move", 500, 200)])]
        states += [(e.id, e.state) for e in f.update(1, t + 0.01, k, [ev(2, "move", 503, 200)])]
    assert (2, "up") in states
    assert f.active_ids == [1]


def test_ids_are_never_reused_even_after_reset():
    f = fusion()
    f.update(0, 0.0, 0, [ev(1, "down", 100, 100)])
    f.update(0, 0.1, 1, [ev(1, "up", 100, 100)])
    f.reset()
    out = f.update(0, 0.2, 2, [ev(1, "down", 100, 100)])
    assert out[0].id == 2


def test_finish_ends_live_and_held_touches():
    f = fusion()
    f.update(0, 0.0, 0, [ev(1, "down", 100, 100), ev(2, "down", 545, 100)])
    f.update(0, 0.033, 1, [ev(2, "up", 545, 100)])  # held at the edge
    out = f.finish(1, 0.033)
    assert sorted((e.id, e.state) for e in out) == [(1, "up"), (2, "up")]


def test_events_without_screen_coordinates_are_refused():
    f = fusion()
    with pytest.raises(ValueError, match="calibration"):
        f.update(0, 0.0, 0, [TouchEvent(0, 0.0, 1, "down", 1.0, 2.0)])


def test_without_a_view_the_seen_box_stands_in():
    f = Fusion(CFG)  # no views: a TUIO sender of unknown coverage
    for k, x in enumerate((100.0, 900.0, 500.0)):
        f.update(0, k * 0.1, k, [ev(k, "down", x, 100 + k * 100)])
    assert len(f.active_ids) == 3


@pytest.mark.parametrize("kw", [{"gate_px": 0}, {"handoff_s": -1}, {"max_predict_s": 2},
                                {"blend_px": float("nan")}])
def test_bad_config_names_the_range(kw):
    with pytest.raises(ConfigError, match="out of range"):
        FusionConfig(**kw)


def test_pure_helpers():
    class Shift:
        def to_screen(self, xy):
            return np.asarray(xy) + [100.0, 0.0]

    poly = view_polygon(Shift(), (640, 480))
    assert poly.tolist() == [[100, 0], [739, 0], [739, 479], [100, 479]]
    assert inside_px(poly, (110, 240)) == pytest.approx(10)
    assert inside_px(poly, (90, 240)) == pytest.approx(-10)
    assert predict((0, 0), (100, 50), 0.5, 0.1) == pytest.approx((10, 5))
    assert predict((0, 0), (100, 50), -1.0, 0.1) == (0, 0)


def test_a_lost_camera_ends_only_the_touches_it_alone_saw():
    f = fusion()
    f.update(0, 0.0, 0, [ev(1, "down", 500, 200)])  # A: a finger in the overlap
    out = f.update(1, 0.01, 0, [ev(5, "down", 501, 200), ev(6, "down", 800, 300),
                                ev(7, "down", 460, 400)])  # B: the same one, and two of its own
    assert sorted(e.id for e in out) == [1, 2, 3]
    out = f.drop_camera(1, 1)  # B unplugged: its own touches end at once, even near its edge
    assert sorted((e.id, e.state) for e in out) == [(2, "up"), (3, "up")]
    out = f.update(0, 0.033, 1, [ev(1, "move", 505, 200)])
    assert [(e.id, e.state) for e in out] == [(1, "move")] and out[0].extra["cam"] == 0
    out = f.update(1, 0.04, 2, [ev(9, "down", 506, 200)])  # B is back: it joins the same touch
    assert [(e.id, e.state) for e in out] == [(1, "move")]
    assert f.drop_camera(0, 3) == [] and f.active_ids == [1]


def test_a_cameras_track_that_moves_to_another_finger_leaves_its_fused_touch():
    """Two fingers cross in the overlap; B sees both, A only one, and A's tracker carries its
    id from the right-moving finger over to the left-moving one. A's track leaves the first
    fused touch (B alone goes on with it) and joins the second."""
    f = fusion()
    right_id = left_id = None
    for k in range(16):
        t = k / 30.0
        xr, xl = 470.0 + 5 * k, 530.0 - 5 * k  # cross at k = 6
        out = f.update(1, t, k, [ev(1, "down" if k == 0 else "move", xr, 230),
                                 ev(2, "down" if k == 0 else "move", xl, 215)], emit=False)
        a_x, a_y = (xr, 230) if k < 6 else (xl, 215)  # camera A switches fingers
        out = f.update(0, t, k, [ev(9, "down" if k == 0 else "move", a_x, a_y)])
        assert len(out) == 2 and {e.state for e in out} <= {"down", "move"}
        if k == 0:
            right_id, left_id = sorted((e.extra["sy"], e.id) for e in out)[1][1], \
                sorted((e.extra["sy"], e.id) for e in out)[0][1]
        got = {e.id: e for e in out}
        assert set(got) == {right_id, left_id}  # no new touch, no end
        if k >= 10:  # A's track left the right-moving finger's touch and joined the other
            assert got[right_id].extra["sx"] == pytest.approx(xr, abs=1.0)
            assert got[left_id].extra["sx"] == pytest.approx(xl, abs=1.0)
            assert got[left_id].extra["sy"] == pytest.approx(215.0, abs=1.0)
