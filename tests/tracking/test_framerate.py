"""The tracker's frame counts keep their duration at other frame rates (TrackingConfig.reference_fps)."""

import numpy as np
import pytest

from depthtouch.config import TrackingConfig
from depthtouch.errors import ConfigError
from depthtouch.tracking.framerate import FrameRate
from depthtouch.tracking.tracker import Tracker
from depthtouch.types import TouchPoints


def pts(*xyh: tuple[float, float, float]) -> TouchPoints:
    """Points of 50 px regions (below a tip's area at 1 mm per px: weak evidence)."""
    if not xyh:
        return TouchPoints.empty()
    a = np.array(xyh, np.float64)
    return TouchPoints(a[:, :2], a[:, 2], np.full(len(a), 50), np.full((len(a), 2), np.nan))


def _states(tracker: Tracker, frames: list, fps: float) -> list[list[str]]:
    return [[u.state for u in tracker.update(f, i / fps)] for i, f in enumerate(frames)]


def test_frame_length_from_the_median_interval():
    r = FrameRate(30.0)
    assert r.update(None) == 1.0 and r.update(0.0) == 1.0  # nothing to measure yet
    for i in range(1, 20):
        k = r.update(i / 60.0)
    assert k == pytest.approx(0.5)
    # one dropped frame (a 2-frame gap) and one repeated timestamp move no median
    t = 19 / 60.0
    assert r.update(t + 2 / 60.0) == pytest.approx(0.5)
    assert r.update(t + 2 / 60.0) == pytest.approx(0.5)
    r.reset()
    assert r.update(1.0) == 1.0
    for i in range(1, 20):  # a slower stream's frames count as one each
        assert r.update(1.0 + i / 15.0) == 1.0


def test_whole_ms_timestamps_at_the_reference_rate_count_as_frames():
    r = FrameRate(30.0)
    t = 0.0
    for i in range(40):
        t += 0.033 if i % 3 else 0.034
        assert r.update(t) == 1.0


def test_zero_reference_counts_frames_at_any_rate():
    r = FrameRate(0.0)
    assert [r.update(i / 90.0) for i in range(10)] == [1.0] * 10


@pytest.mark.parametrize("fps, down_at", [(30.0, 1), (60.0, 2), (90.0, 3), (15.0, 1)])
def test_down_takes_as_long_and_as_many_frames(fps: float, down_at: int):
    # down_frames 2 at 30 fps: seen in 2 frames, 33 ms apart; as long at 60 fps: 3 frames, at
    # 90 fps 4; at 15 fps 2 frames as at 30. The grace before up stays 3 frames at any rate
    up_after = 3
    cfg = TrackingConfig(weak_evidence=1.0, down_frames=2, up_frames=3, reference_fps=30.0)
    tr = Tracker(cfg, scale_mm_per_px=1.0)
    seen = [pts((10.0 + 0.1 * i, 10.0, 5.0)) for i in range(8)]
    # (three frames without touches first: the rate is known from the second timestamp on)
    out = _states(tr, [pts()] * 3 + seen + [pts()] * 8, fps)[3:]
    assert [i for i, s in enumerate(out) if "down" in s] == [down_at]
    assert [i for i, s in enumerate(out) if "up" in s] == [8 + up_after - 1]


def test_a_speck_as_long_in_time_at_60_fps_stays_a_speck():
    # weak evidence (0.4 a frame) needs 5 frames at 30 fps (133 ms from first to last); the
    # same 5 frames at 60 fps last half as long and are not a touch; 9 are
    cfg = TrackingConfig(down_frames=2, weak_evidence=0.4, reference_fps=30.0)
    empty = [pts()] * 3
    speck = [pts((10.0, 10.0, 5.0))] * 5  # area 50 px at 1 mm/px: below a tip's area
    assert any("down" in s for s in _states(Tracker(cfg, scale_mm_per_px=1.0), empty + speck, 30.0))
    assert not any("down" in s
                   for s in _states(Tracker(cfg, scale_mm_per_px=1.0), empty + speck, 60.0))
    out = _states(Tracker(cfg, scale_mm_per_px=1.0), empty + speck * 2, 60.0)[3:]
    assert [i for i, s in enumerate(out) if "down" in s] == [8]
    # with the scaling off (the default), frames are frames
    off = TrackingConfig(down_frames=2, weak_evidence=0.4)
    assert off.reference_fps == 0.0
    out = _states(Tracker(off, scale_mm_per_px=1.0), empty + speck, 60.0)[3:]
    assert [i for i, s in enumerate(out) if "down" in s] == [4]


def test_reference_fps_is_validated():
    with pytest.raises(ConfigError, match="reference_fps"):
        TrackingConfig(reference_fps=-1.0).validate()


@pytest.mark.parametrize("fps, gate_fps, same_id", [(15.0, 30.0, True), (30.0, 30.0, False),
                                                    (15.0, 0.0, False), (60.0, 30.0, False)])
def test_gate_grows_in_a_slower_stream(fps: float, gate_fps: float, same_id: bool):
    # a still finger (2 frames) then a 60 mm jump in one frame: beyond the 40 mm gate at
    # 30 fps (1.8 m/s), within it at 15 fps (0.9 m/s, gate 80 mm)
    cfg = TrackingConfig(weak_evidence=1.0, down_frames=1, up_frames=2, gate_fps=gate_fps)
    tr = Tracker(cfg, scale_mm_per_px=1.0)
    frames = [pts()] * 3 + [pts((100.0, 100.0, 5.0))] * 2 + [pts((160.0, 100.0, 5.0))]
    ids = [{u.track.id for u in tr.update(f, i / fps) if u.measured}
           for i, f in enumerate(frames)]
    assert (ids[-1] == ids[-2] == {1}) is same_id


def test_gate_fps_is_validated():
    with pytest.raises(ConfigError, match="gate_fps"):
        TrackingConfig(gate_fps=-3.0).validate()


def test_step_counts_the_intervals_since_the_last_frame_whatever_the_settings():
    for ref, gate in ((0.0, 0.0), (30.0, 0.0), (0.0, 30.0)):
        r = FrameRate(ref, gate)
        r.update(None)
        assert r.step == 1.0  # no timestamp: one interval
        for i in range(10):  # an even stream, timestamps in whole ms
            r.update(round(i / 30.0, 3))
            assert r.step == 1.0
        t = round(9 / 30.0, 3)
        r.update(t + 2 / 30.0)  # one frame dropped
        assert r.step == 2.0
        r.update(t + 5 / 30.0)  # two dropped
        assert r.step == 3.0
        r.update(t + 5 / 30.0)  # a repeated timestamp: one interval
        assert r.step == 1.0
        r.update(t + 5 / 30.0 + 2.0)  # the stream stopped for 2 s: at most STEP_MAX
        assert r.step == 4.0
        r.update(t + 5 / 30.0 + 2.0 + 1 / 30.0)
        assert r.step == 1.0
        r.reset()
        assert r.step == 1.0


def test_a_drag_keeps_its_id_across_dropped_frames():
    # 30 mm per frame at 1 mm/px against the default 40 mm gate; frames 6 and 7 are dropped
    # (the camera never delivered them): the finger moves 90 mm between two frames
    kept = [i for i in range(14) if i not in (6, 7)]
    for t_of in (lambda i: i / 30.0, lambda i: None):
        tr = Tracker(TrackingConfig(weak_evidence=1.0, down_frames=1), scale_mm_per_px=1.0)
        ids = set()
        for i in kept:
            ids.update(u.track.id for u in tr.update(pts((100.0 + 30 * i, 50.0, 5.0)), t_of(i)))
        # with timestamps the gap is seen and the id kept; without them it is not
        assert (ids == {1}) == (t_of(0) is not None)


def test_the_prediction_spans_the_dropped_frames():
    # a drag at 30 mm per frame with a neighbour 60 mm ahead of where it was: after one
    # dropped frame the drag's own point (at +60) is the nearest to its prediction, not the one
    # a frame's step away
    tr = Tracker(TrackingConfig(weak_evidence=1.0, down_frames=1), scale_mm_per_px=1.0)
    for i in range(5):
        tr.update(pts((100.0 + 30 * i, 50.0, 5.0)), i / 30.0)
    (u,) = tr.update(pts((100.0 + 30 * 6, 50.0, 5.0)), 6 / 30.0)
    assert u.track.id == 1 and u.state == "move"
    assert u.track.since == 0.0
