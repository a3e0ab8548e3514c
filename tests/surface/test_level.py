"""Levelling: a frame that moved as a whole is moved back (surface/level.py)."""

import numpy as np
import pytest

from depthtouch.config import PipelineConfig
from depthtouch.errors import ConfigError
from depthtouch.pipeline import Pipeline
from depthtouch.sim import render_scene
from depthtouch.surface.level import Leveller, frame_offset, level_depth, reference_stats
from depthtouch.types import Frame

RNG = np.random.default_rng(0)
YY = np.arange(480, dtype=np.float32)[:, None]
TILTED = np.broadcast_to(900.0 + 0.9 * YY, (480, 640)).astype(np.float32)  # 900-1330 mm


def frame(ref, shift, *, noise=2.0, hand=True, missing=0.01, seed=0):
    """uint16 mm: ``ref`` moved by ``shift`` (mm, an array or a number), noisy, with a hand
    50-300 mm up over a fifth of the view and some pixels missing."""
    rng = np.random.default_rng(seed)
    d = ref + shift + rng.normal(0, noise, ref.shape)
    if hand:
        d[100:300, 200:360] -= rng.uniform(50, 300, (200, 160))
    d = np.rint(d).astype(np.uint16)
    d[rng.random(ref.shape) < missing] = 0
    return d


@pytest.mark.parametrize("shift", [-6.0, -0.8, 2.5, 9.0])
def test_a_uniform_shift_is_measured_under_a_hand(shift):
    ref = TILTED.copy()
    a, b = frame_offset(frame(ref, shift), ref, 1.0)
    _, (q0, q1) = reference_stats(ref)
    for q in (q0, q1):  # the fitted offset over the whole view
        assert a + b * q == pytest.approx(shift, abs=0.2)


def test_a_disparity_shift_grows_with_the_depth_squared_and_is_taken_off():
    ref = TILTED.copy()
    med, qr = reference_stats(ref)
    moved = 4.0 * (ref / med) ** 2  # 3.2-7.6 mm across the wall
    d = frame(ref, moved)
    off = frame_offset(d, ref, 1.0)
    assert off is not None and off[1] == pytest.approx(4.0, abs=0.4)
    out = level_depth(d, ref, 1.0, off)
    ok = (d > 0) & ~np.pad(np.ones((200, 160), bool), ((100, 180), (200, 280)))
    resid = out[ok].astype(np.float64) - ref[ok]
    assert abs(float(np.median(resid))) < 0.3
    assert abs(float(np.median(resid[ref[ok] > 1250]))) < 0.6  # the far end too
    assert (out[d == 0] == 0).all()  # missing stays missing


@pytest.mark.parametrize("a", [3.0, -2.5, 1.49, -40.0])
def test_a_plain_shift_is_taken_off_as_the_array_formula_says(a):
    # the compiled pass's shortcut for b = 0 (the reference not read) against numpy
    ref = TILTED.copy()
    d = frame(ref, 0.0)
    d[0, :4] = [0, 1, 2, 65535]
    out = level_depth(d, ref, 1.0, (a, 0.0))
    k = np.floor(a + 0.5)
    expect = np.where(d == 0, 0, np.clip(d.astype(np.int64) - k, 1, 65535))
    assert out.dtype == np.uint16 and np.array_equal(out, expect)


def test_nothing_changes_when_the_offset_rounds_to_no_unit():
    ref = TILTED.copy()
    d = frame(ref, 0.0)
    off = frame_offset(d, ref, 1.0)
    assert off is not None and abs(off[0]) < 0.2
    assert level_depth(d, ref, 1.0, off) is d


def test_levelling_engages_past_its_threshold_and_lets_go_once_nothing_is_left():
    # engage_mm 1.0: a frame 0.6 mm off passes as it is (a drift the adapter follows); one
    # 1.5 mm off engages levelling, which then takes off smaller offsets too, and lets go
    # 3 s after the offset last reached 1 mm, once it rounds to nothing
    ref = TILTED.copy()
    lev = Leveller(15.0, engage_mm=1.0)
    lev.use_reference(ref)
    d = frame(ref, 0.6, seed=2)
    assert lev.update(d, 1.0, 0.1) is d and not lev.engaged
    out = lev.update(frame(ref, 1.5, seed=3), 1.0, 0.2)
    assert lev.engaged and lev.offset_mm[0] == pytest.approx(1.5, abs=0.3)
    assert abs(float(np.median(out[400:].astype(np.float64) - ref[400:]))) <= 0.6
    d = frame(ref, 0.7, seed=4)
    out = lev.update(d, 1.0, 2.0)  # still engaged: 0.7 mm rounds to a unit taken off
    assert lev.engaged and out is not d
    d = frame(ref, 0.7, seed=5)
    out = lev.update(d, 1.0, 3.5)  # 3 s on, but a unit is still to take off: holds
    assert lev.engaged and out is not d
    d = frame(ref, 0.0, seed=6)
    assert lev.update(d, 1.0, 3.6) is d and not lev.engaged
    lev.update(frame(ref, 1.5, seed=8), 1.0, 4.0)
    assert lev.engaged
    d = frame(ref, 0.0, seed=9)
    assert lev.update(d, 1.0, 0.0) is d and not lev.engaged  # a replay from its start
    always = Leveller(15.0)  # engage_mm 0: levels whatever rounds to a unit
    always.use_reference(ref)
    d = frame(ref, 0.7, seed=7)
    assert always.engaged and always.update(d, 1.0, 0.1) is not d


def test_a_covered_frame_is_not_measured_and_a_far_jump_is_not_followed():
    ref = TILTED.copy()
    d = frame(ref, 3.0, hand=False)
    d[:400] = np.rint(ref[:400] - 150).astype(np.uint16)  # an arm over 5/6 of the view
    assert frame_offset(d, ref, 1.0) is None
    assert frame_offset(frame(ref, 40.0), ref, 1.0, limit_mm=15.0) is None  # the camera moved
    # ... but followed from an offset near it
    off = frame_offset(frame(ref, 40.0), ref, 1.0, prev=(35.0, 0.0), limit_mm=15.0)
    assert off is not None and off[0] == pytest.approx(40.0, abs=0.3)


def test_the_leveller_takes_its_reference_from_the_first_frame_and_holds_when_covered():
    lev = Leveller(15.0)
    ref = TILTED.copy()
    first = frame(ref, 1.0, hand=False, seed=1)
    assert lev.update(first, 1.0) is first and lev.has_reference
    out = lev.update(frame(ref, 4.0, seed=2), 1.0)
    assert lev.offset_mm[0] == pytest.approx(3.0, abs=0.3)
    assert abs(float(np.median(out[400:].astype(np.float64) - first[400:]))) <= 1.0
    covered = frame(ref, 4.0, hand=False, seed=3)
    covered[:400] = 500
    lev.update(covered, 1.0)
    assert not lev.measured and lev.offset_mm[0] == pytest.approx(3.0, abs=0.3)
    lev.reset()
    assert not lev.has_reference and lev.offset_mm == (0.0, 0.0)


def test_the_setting_is_checked():
    with pytest.raises(ConfigError, match="surface.level_limit_mm"):
        PipelineConfig().replace(surface={"level_limit_mm": -1.0})
    with pytest.raises(ConfigError, match="surface.level_engage_mm"):
        PipelineConfig().replace(surface={"level_engage_mm": 25.0})
    # on, engaged once the frame moved by 1 mm: judged held out in session 53
    assert PipelineConfig().surface.level_limit_mm == 15.0
    assert PipelineConfig().surface.level_engage_mm == 1.0


def _run(rec, limit):
    p = Pipeline(PipelineConfig().replace(surface={"level_limit_mm": limit}))
    downs = 0
    for i in range(rec.depth.shape[0]):
        r = p.process(Frame(rec.depth[i], float(rec.timestamps_s[i]), i, 0.001, rec.K))
        downs += sum(e.state == "down" for e in r.events)
    return p, downs


def test_a_breathing_time_of_flight_frame_keeps_its_touches_only_when_levelled(caplog):
    # a ToF camera's frame steps by 2-4 mm for seconds at a time: the bump check sees the whole
    # surface change and learns it again, touches off meanwhile; levelled, nothing of that
    rec = render_scene("taps", camera="kinect-v2-hard", distance_m=1.2, tilt_deg=20, seed=3,
                       breathing_mm=2.0)
    with caplog.at_level("WARNING"):
        off, _ = _run(rec, 0.0)
    # the message names the setting that would have kept the touches
    assert any("whole frame" in r.message and "surface.level_limit_mm = 15" in r.message
               for r in caplog.records)
    on, downs = _run(rec, 15.0)
    assert off.surface.relearns >= 1 and off.stats.disturbed_frames > 10
    assert on.surface.relearns == 0 and on.stats.disturbed_frames == 0
    assert downs == 5  # the scene's five taps


@pytest.mark.parametrize("level", [0.0, 15.0])
def test_frames_that_move_while_the_surface_is_learned_leave_its_noise_as_it_is(level):
    rng = np.random.default_rng(5)
    K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])
    p = Pipeline(PipelineConfig().replace(surface={"level_limit_mm": level}), surface_frames=45)
    shifts = rng.choice([-3.0, 0.0, 3.0], 45)  # whole frames 3 mm off now and then
    for i in range(45):
        d = np.rint(1000.0 + shifts[i] + rng.normal(0, 1.5, (480, 640))).astype(np.uint16)
        p.process(Frame(d, i / 30.0, i, 0.001, K))
    sigma = float(np.median(p.surface.bounds.sigma_mm))
    assert (sigma < 1.8) is (level > 0)  # 1.5 mm of noise; 2.9 mm with the shifts in it


def _events(rec, **surface):
    p = Pipeline(PipelineConfig().replace(surface=surface))
    events = []
    for i in range(rec.depth.shape[0]):
        r = p.process(Frame(rec.depth[i], float(rec.timestamps_s[i]), i, 0.001, rec.K))
        events += [(i, e) for e in r.events]
    return events, p.surface.level_offset_mm


def test_a_drift_alone_does_not_engage_levelling_and_the_events_stay_those_without_it():
    # a ToF camera warming up (0.3-0.5 mm/s) on a wall tilted 20 deg, taps and a held touch
    # (hard's warmup/kinect-v2-hard/1m/tilt20/s2): the surface adapter follows the drift within
    # a millimetre, so by default levelling never engages and every event is as without
    # levelling; always engaged (level_engage_mm 0), it takes the drift off and events move
    rec = render_scene("warmup", camera="kinect-v2-hard", distance_m=1.0, tilt_deg=20, seed=2)
    off, _ = _events(rec, level_limit_mm=0.0)
    assert sum(e.state == "down" for _, e in off) >= 4
    on, (a, _) = _events(rec)
    assert on == off and abs(a) < 1.0
    always, (a, _) = _events(rec, level_engage_mm=0.0)
    assert always != off and abs(a) > 2.0  # the drift, taken off the frames
