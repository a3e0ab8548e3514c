"""The recent change around touch points (depthtouch.touch.recent): the compiled kernel against
its array reference, the frames kept, and what it reads on a finger that arrives and stays."""

import numpy as np
import pytest

from depthtouch.config import PipelineConfig, TrackingConfig
from depthtouch.pipeline import Pipeline
from depthtouch.touch.recent import HALF_PX, RecentDepth, recent_change
from depthtouch.types import Frame
from synth import K_640, Finger, make_recording


def _reference(depth: np.ndarray, frames: np.ndarray, xy: np.ndarray, half: int,
               factor: np.ndarray, to_mm: float, cover_mm: float = 0.0) -> np.ndarray:
    """The array version: the median of the known depths of the clamped window, now and then,
    as a height (to_mm times the factor at the point's pixel), without the frames where the
    heights lay more than cover_mm above now's (0 when all known frames are such)."""
    h, w = depth.shape
    out = np.full(len(xy), np.nan)

    def med(img: np.ndarray, x: float, y: float) -> float:
        cx, cy = min(max(round(x), 0), w - 1), min(max(round(y), 0), h - 1)
        win = img[max(cy - half, 0):cy + half + 1, max(cx - half, 0):cx + half + 1]
        v = win[win > 0].astype(np.float64)
        return float(np.median(v)) if v.size else np.nan

    for i, (x, y) in enumerate(xy):
        if np.isnan(x) or np.isnan(y):
            continue
        now = med(depth, x, y)
        cx, cy = min(max(round(x), 0), w - 1), min(max(round(y), 0), h - 1)
        scale = to_mm * float(factor[cy, cx])
        then = np.array([med(f, x, y) for f in frames])
        then = then[~np.isnan(then)]
        if np.isnan(now) or then.size == 0:
            continue
        if cover_mm > 0:
            open_ = then[(now - then) * scale <= cover_mm]
            out[i] = float(np.median(np.abs(open_ - now))) * scale if open_.size else 0.0
        else:
            out[i] = float(np.median(np.abs(then - now))) * scale
    return out


def test_the_kernel_equals_its_array_reference():
    """Random depths with holes, points inside, at the border, outside and unknown."""
    rng = np.random.default_rng(3)
    depth = rng.integers(900, 1100, (40, 60)).astype(np.uint16)
    depth[rng.random(depth.shape) < 0.3] = 0
    depth[0:6, 50:60] = 0  # a window with no depth at all
    frames = rng.integers(900, 1100, (4, 40, 60)).astype(np.uint16)
    frames[rng.random(frames.shape) < 0.3] = 0
    xy = np.array([[10.2, 20.7], [0.0, 0.0], [59.4, 39.6], [-3.0, 45.0], [55.0, 2.0],
                   [np.nan, 4.0], [30.5, 10.5]])
    use = np.array([0, 2, 3])
    factor = rng.uniform(0.8, 1.2, depth.shape).astype(np.float32)
    out = np.empty(len(xy))
    recent_change(depth, frames, use, xy, HALF_PX, factor, 0.5, 0.0, out)
    ref = _reference(depth, frames[use], xy, HALF_PX, factor, 0.5)
    np.testing.assert_allclose(out, ref, equal_nan=True)
    assert np.isnan(out[4]) and np.isnan(out[5]) and np.isfinite(out[[0, 1, 2, 3, 6]]).all()
    # with covers: the frames whose heights lay more than cover_mm above now's are left out
    covered = frames.copy()
    covered[2, 15:26, 5:16] = 700  # point 0 under a cover in one frame used
    covered[:, 8:14, 28:34] = 600  # point 6 under a cover in every frame: 0
    for cover in (0.0, 30.0):
        out = np.empty(len(xy))
        recent_change(depth, covered, use, xy, HALF_PX, factor, 0.5, cover, out)
        ref = _reference(depth, covered[use], xy, HALF_PX, factor, 0.5, cover)
        np.testing.assert_allclose(out, ref, equal_nan=True)
        assert (out[6] == 0.0) == (cover > 0)
        if cover == 0.0:
            uncovered = out[0]
    assert out[0] != uncovered  # the covered frame was left out


def test_frames_are_kept_one_per_step_within_the_window():
    """A frame is kept every step_s; the change is the median over the frames min_age_s to
    window_s old; time going back starts over; nothing kept yet is unknown."""
    r = RecentDepth(window_s=1.0, step_s=0.25, min_age_s=0.2)
    factor = np.full((10, 12), 2.0, np.float32)
    xy = np.array([[5.0, 5.0]])
    level = np.full((10, 12), 1000, np.uint16)
    assert np.isnan(r.change_mm(level, xy, 0.0, 1.0, factor)[0])
    r.update(level, 0.0)
    assert np.isnan(r.change_mm(level, xy, 0.1, 1.0, factor)[0])  # kept, but too recent
    r.update(level - 5, 0.1)  # not kept: less than a step after the last one
    assert r.change_mm(level - 3, xy, 0.3, 0.5, factor)[0] == pytest.approx(3 * 0.5 * 2.0)
    for k in range(1, 5):
        r.update(level - 10 * k, 0.25 * k)
    # at 1.21 s: frames from 0.25 (990) to 1.0 (960) are 0.21-0.96 s old, 0.0 (1000) is too
    # old: changes 30, 20, 10, 0 mm, their median 15 mm
    assert r.change_mm(level - 40, xy, 1.21, 1.0, factor)[0] == pytest.approx(15 * 2.0)
    r.update(level, 0.5)  # time went back: a new stream
    assert np.isnan(r.change_mm(level, xy, 0.6, 1.0, factor)[0])
    r.update(np.zeros((4, 4), np.uint16), 5.0)  # another size: starts over
    assert np.isnan(r.change_mm(level, xy, 5.5, 1.0, factor)[0])
    with pytest.raises(ValueError, match="window"):
        RecentDepth(window_s=0.1, step_s=0.2)


def _points_over(script: list[list[Finger]], config: PipelineConfig) -> list:
    depth, ts = make_recording(75, script, noise_mm=1.0, seed=5)
    p = Pipeline(config)
    out = []
    for i, (d, t) in enumerate(zip(depth, ts, strict=True)):
        r = p.process(Frame(d, float(t), i, 0.001, K_640))
        if i >= 75:
            out.append(r.points)
    return out


def test_a_finger_that_arrives_changed_its_heights_and_one_held_still_did_not():
    """The pipeline measures the change where the tracker asks for it: a finger coming down
    from 40 mm changed the heights around its tip by tens of mm; after it rests for over a
    second they changed by no more than the noise. Without the question nothing is kept; the
    points the enclosure test cannot refuse (its share, its tip height) are not measured."""
    x, y = 320.0, 240.0
    script = [[Finger(x, y, 90, gap_mm=max(0.0, 40.0 - 4.0 * k))] for k in range(15)]
    script += [[Finger(x, y, 90)]] * 45
    # (asked of every point: any share, any tip height)
    on = PipelineConfig(tracking=TrackingConfig(enclosed_share_max=0.0, enclosed_height_min_mm=0.0,
                                                enclosed_change_max_mm=5.0))
    pts = _points_over(script, on)
    first = next(k for k, p in enumerate(pts) if len(p))
    assert first <= 12
    arriving = pts[first].recent_change_mm
    assert arriving is not None and arriving[0] > 15.0, arriving
    resting = pts[-1].recent_change_mm
    assert len(pts[-1]) == 1 and resting is not None and resting[0] < 2.0, resting
    off = _points_over(script, PipelineConfig(tracking=TrackingConfig(enclosed_change_max_mm=0.0)))
    unasked = _points_over(script, PipelineConfig(tracking=TrackingConfig(
        enclosed_share_max=0.99, enclosed_change_max_mm=5.0)))
    assert len(unasked[-1]) == 1 and unasked[-1].recent_change_mm is None
    assert len(off[-1]) == 1 and off[-1].recent_change_mm is None


def test_a_point_uncovered_by_a_hand_that_hovered_over_it_did_not_arrive():
    """A finger lying still while another hand hovers 100 mm over it for 2.7 s, then leaves:
    against the frames of the last 2 s its heights changed by the hand's height, unless the
    covered frames are left out (enclosed_cover_mm): then it counts as unchanged."""
    x, y = 320.0, 240.0
    still = Finger(x, y, 90)
    cover = Finger(x, y + 4, 270, gap_mm=100.0, arm=True)
    script = [[still, cover]] * 80 + [[still]] * 10

    def after(cover_mm: float) -> float:
        pts = _points_over(script, PipelineConfig(tracking=TrackingConfig(
            enclosed_share_max=0.0, enclosed_height_min_mm=0.0, enclosed_change_max_mm=5.0,
            enclosed_cover_mm=cover_mm)))
        p = pts[83]
        assert len(p) == 1 and p.recent_change_mm is not None
        return float(p.recent_change_mm[0])

    assert after(0.0) > 50.0
    assert after(30.0) == 0.0
