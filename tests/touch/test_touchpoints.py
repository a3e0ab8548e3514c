import numpy as np
import pytest

from depthtouch.config import RegionConfig, TouchPointConfig
from depthtouch.surface.bounds import band_bounds, height_mm
from depthtouch.surface.model import learn_surface
from depthtouch.touch.handmap import hand_map
from depthtouch.touch.points import core_heights_mm, find_touch_points
from depthtouch.touch.regions import band_regions
from reference_touchpoints import band_masks
from synth import K_640, Finger, make_recording, render_heights

MM_PER_PX = 1000 / 600


@pytest.fixture(scope="module")
def bounds():
    d, _ = make_recording(30, [], noise_mm=1.5, seed=1)
    return band_bounds(learn_surface(d, 0.001, K_640), RegionConfig())


def detect(bounds, fingers, method="extremity", seed=0, noise=1.5, flat=None):
    rng = np.random.default_rng(seed)
    hm = render_heights((480, 640), fingers, MM_PER_PX)
    if flat is not None:
        hm = np.maximum(hm, flat)
    d = np.clip(np.rint(1000 - hm + rng.normal(0, noise, hm.shape)), 0, None).astype(np.uint16)
    d[rng.random(d.shape) < 0.01] = 0
    regions = band_regions(d, bounds)
    return find_touch_points(d, regions, bounds, TouchPointConfig(method=method))


@pytest.mark.parametrize("direction", [0, 45, 90, 135, 180, 270, 300])
@pytest.mark.parametrize("radius", [6.0, 7.5, 9.5])
def test_extremity_finds_contact_subpixel(bounds, direction, radius):
    f = Finger(320.3, 240.6, direction, radius_mm=radius)
    errs = []
    for seed in range(3):
        tp = detect(bounds, [f], seed=seed)
        assert len(tp) == 1
        errs.append(np.hypot(*(tp.xy_px[0] - (f.x, f.y))) * MM_PER_PX)
        # the tip's lowest visible part is about its radius above the surface
        assert tp.height_mm[0] < radius + 5
    # measured: ~0.5-1.5 mm on this synthetic finger
    assert np.median(errs) < 2.5


@pytest.mark.parametrize("pitch", [20.0, 45.0, 70.0])
def test_extremity_over_pitch(bounds, pitch):
    f = Finger(300.0, 200.0, 120, pitch_deg=pitch)
    tp = detect(bounds, [f])
    assert len(tp) == 1
    assert np.hypot(*(tp.xy_px[0] - (f.x, f.y))) * MM_PER_PX < 3.0


def test_paper_method_finds_a_pixel_near_the_tip(bounds):
    f = Finger(320.0, 240.0, 90)
    tp = detect(bounds, [f], method="paper")
    assert len(tp) == 1
    assert tp.xy_px[0] == pytest.approx(np.rint(tp.xy_px[0]))  # integer pixel, as the paper
    assert np.hypot(*(tp.xy_px[0] - (f.x, f.y))) * MM_PER_PX < 12.0


def test_hover_at_25mm_and_flat_object_give_no_touch(bounds):
    assert len(detect(bounds, [Finger(320, 240, 90, gap_mm=25)])) == 0
    flat = np.zeros((480, 640), np.float32)
    flat[100:160, 100:200] = 15.0  # a book-like object lying in the band, no hand attached
    assert len(detect(bounds, [], flat=flat)) == 0


def test_hover_at_10mm_is_higher_than_touch(bounds):
    touch = detect(bounds, [Finger(320, 240, 90)])
    hover = detect(bounds, [Finger(320, 240, 90, gap_mm=10)])
    assert len(touch) == 1
    assert len(hover) == 0 or hover.height_mm[0] > touch.height_mm[0] + 6


def test_five_fingers_two_hands(bounds):
    fingers = [Finger(150 + 40 * k, 240 - 10 * (k % 2), 100 - 10 * k) for k in range(3)]
    fingers += [Finger(420 + 40 * k, 200 + 15 * k, 280 - 20 * k) for k in range(2)]
    tp = detect(bounds, fingers)
    assert len(tp) == 5
    truth = np.array([(f.x, f.y) for f in fingers])
    d = np.linalg.norm(tp.xy_px[:, None] - truth[None], axis=2).min(axis=1) * MM_PER_PX
    assert np.all(d < 3.0)


def _fingers_mask(tips: list[tuple[float, float, float]], r_px: float) -> np.ndarray:
    """Fingers in the touch band, reaching up from a hand below: a round tip of radius ``r_px``
    and the finger behind it; tips as (x, y, slant in degrees). Neighbours touch (no gap)."""
    import cv2

    m = np.zeros((40, 48), np.uint8)
    for x, y, slant in tips:
        a = np.radians(slant)
        base = (int(round(x - 40 * np.sin(a))), int(round(y + 40 * np.cos(a))))
        cv2.line(m, (int(round(x)), int(round(y))), base, 1, int(round(2 * r_px)))
        cv2.circle(m, (int(round(x)), int(round(y))), int(round(r_px)), 1, -1)
    m[24:] = 0  # above Tu the finger leaves the band
    return m


# (tips, finger radius px, parts expected) with a nominal tip radius r0 of 3 px. The staggered
# rows are the shape measured in the multitouch recordings: the shorter finger's tip half a
# finger behind the longer one's; they stayed one region before (one touch point between the
# two fingers, and an id that changed finger when the region split later).
SPLIT_CASES = {
    "pair, level": ([(20, 12, 0), (28, 12, 0)], 3.5, 2),
    "pair, staggered by 4 px": ([(20, 10, 0), (27, 14, 0)], 3.5, 2),
    "pair, staggered by 3 px": ([(20, 10, 0), (27, 13, 0)], 3.5, 2),
    "pair, staggered by 5 px": ([(20, 9, 0), (27, 14, 0)], 3.5, 2),
    "single": ([(24, 12, 0)], 3.0, 1),
    "single, wide finger": ([(24, 12, 0)], 4.5, 1),
    "single, slanted": ([(24, 12, 15)], 3.0, 1),
}


@pytest.mark.parametrize("tips, r_px, parts", list(SPLIT_CASES.values()), ids=list(SPLIT_CASES))
def test_split_fingers_between_tips_side_by_side(tips, r_px, parts):
    from depthtouch.touch.fingertip import split as _split

    mask = _fingers_mask(tips, r_px)
    ys, xs = np.nonzero(mask)
    # along the direction from the hand (below) to the region's centre, and across it
    d = np.array([xs.mean() - 24.0, ys.mean() - 60.0])
    d /= np.hypot(*d)
    px, py = xs - 24.0, ys - 60.0
    part = _split(py * d[0] - px * d[1], px * d[0] + py * d[1], 3.0)
    assert part.shape == xs.shape
    assert sorted(set(part.tolist())) == list(range(parts))


@pytest.mark.parametrize("scene, camera", [("multitouch", "realsense-d435"), ("pinch", "kinect-v2"),
                                           ("distractors", "kinect-v1")])
def test_compiled_kernel_matches_the_array_reference(scene, camera, monkeypatch):
    """The compiled kernel finds the points of the numpy/OpenCV reference implementation
    (tests/reference_touchpoints.py) on simulated recordings, frame by frame."""
    import depthtouch.pipeline as pipeline_mod
    import reference_touchpoints
    from depthtouch.sim import render_scene
    from depthtouch.types import Frame

    rec = render_scene(scene, camera=camera, distance_m=1.0, seed=1)
    pairs = []
    levels: list[float] = []

    def both(depth, regions, bounds, config):
        _, high = band_masks(depth, bounds)
        ref = reference_touchpoints.find_touch_points(depth, high, regions, bounds, config)
        got = find_touch_points(depth, regions, bounds, config)
        hands_ref = reference_touchpoints.hand_map(high, depth, bounds)
        levels.append(float(np.mean(hand_map(depth, bounds) == hands_ref)))
        pairs.append((ref, got))
        return ref

    monkeypatch.setattr(pipeline_mod, "find_touch_points", both)
    pipe = pipeline_mod.Pipeline()
    for i in range(rec.depth.shape[0]):
        pipe.process(Frame(rec.depth[i], float(rec.timestamps_s[i]), i, rec.depth_scale_m, rec.K))
    assert sum(len(r) for r, _ in pairs) > 50
    assert min(levels) == 1.0  # the hand map is the same, coarse pixel for coarse pixel
    dist = []
    for ref, got in pairs:
        assert len(got) == len(ref)
        if len(ref):
            d = np.linalg.norm(ref.xy_px[:, None] - got.xy_px[None], axis=2)
            dist.extend(d.min(axis=1))
            np.testing.assert_array_equal(np.sort(got.area_px), np.sort(ref.area_px))
            assert got.attach_share is not None and ref.attach_share is not None
            np.testing.assert_allclose(np.sort(got.attach_share), np.sort(ref.attach_share))
    # measured: identical on most frames; up to ~0.9 px apart where fingertips or objects are
    # near each other (the nearest-region test looks at a window instead of the whole frame)
    assert np.median(dist) < 0.01
    assert np.percentile(dist, 99) < 1.0
    assert max(dist) < 1.5


def test_attachment_is_a_fingers_width_for_a_tip_and_long_for_a_forearm_edge(bounds):
    """The kernel's attachment (hand pixels within 2 px of a region) measures how long the
    region hangs on the hand, read as (n / 2 - 4) px by TrackingConfig.attach_max_mm: for a
    fingertip only the finger's ridge rises past Tu next to it (measured 1.7 mm here), for the
    edge of a forearm lying in the band its whole length (measured 250 mm)."""
    for pitch in (20.0, 35.0, 60.0):
        tip = detect(bounds, [Finger(320, 240, 90, pitch_deg=pitch)])
        assert len(tip) == 1 and tip.attach_px is not None
        assert tip.attach_px[0] > 0 and (tip.attach_px[0] / 2 - 4) * MM_PER_PX < 15.0
        # a finger rises from the band gradually: its pixels next to the region are just above Tu
        assert tip.attach_height_mm is not None and 25.0 < tip.attach_height_mm[0] < 45.0
    # a forearm resting on its edge: a raised block 70 mm wide, its rounded edge in the band
    arm = np.zeros((480, 640), np.float32)
    w_px, edge_px = int(70 / MM_PER_PX), int(12 / MM_PER_PX)
    arm[200:200 + w_px, 300:] = 45.0
    arm[200 + w_px:200 + w_px + edge_px, 330:] = 12.0
    edge = detect(bounds, [], flat=arm)
    assert len(edge) >= 1 and edge.attach_px is not None
    assert ((edge.attach_px / 2 - 4) * MM_PER_PX > 30.0).all()


def test_a_fingertips_hand_lies_at_its_back_and_a_resting_palms_patch_lies_in_its_hand(bounds):
    """The attachment's share of the ring 2 px around a region (TouchPoints.attach_share, read
    by TrackingConfig.enclosed_share_max): a fingertip's hand pixels are its finger's ridge
    behind it, a small part of the ring (measured 0.10-0.15 here); a patch of a resting palm
    whose top lies just above Tu (a dip of it into the band) is surrounded by the palm
    (measured 0.93)."""
    for pitch in (20.0, 35.0, 60.0):
        tip = detect(bounds, [Finger(320, 240, 90, pitch_deg=pitch)])
        assert len(tip) == 1 and tip.attach_share is not None
        assert 0.0 < tip.attach_share[0] < 0.25
    palm = np.zeros((480, 640), np.float32)
    palm[150:300, 250:450] = 30.0  # a palm lying on the surface, its top 5 mm above Tu
    palm[215:227, 340:352] = 15.0  # a patch of it 12 px wide that dips into the band
    patch = detect(bounds, [], flat=palm)
    assert len(patch) == 1 and patch.attach_share is not None
    assert patch.attach_share[0] > 0.6


def test_mixed_pixels_at_the_side_of_a_raised_hand_sit_next_to_a_high_step(bounds):
    """A speck of the band (mixed pixels) at the side of a hand 150 mm up: its attached pixels
    are the hand's, far higher than a finger rising from the band (TrackingConfig.step_max_mm)."""
    hm = np.zeros((480, 640), np.float32)
    hm[200:300, 300:] = 150.0  # a hand and arm reaching in from the right
    speck = int(15 / MM_PER_PX)
    hm[300:300 + 6, 360:360 + speck] = 12.0
    tp = detect(bounds, [], flat=hm)
    assert len(tp) >= 1 and tp.attach_height_mm is not None
    assert (tp.attach_height_mm > 80.0).all()


def test_heights_behind_a_fingertip_rise_and_behind_a_held_books_edge_are_level(bounds):
    """The kernel's back spread (heights 10-40 mm behind the tip on the finger's axis and the
    nearer of those 20 mm to its sides, max - min) read by TrackingConfig.flat_max_mm: a finger
    stands above the surface beside it whatever its pitch; a patch of a book's top that dips
    into the band (its top lies just above Tu, so noise and mixed pixels cut it) has the book's
    level top behind it: on four noise seeds its spread stays well under flat_max_mm's 10 mm
    (measured 1.0-5.3 mm; 0.9-5.1 mm before session 23's lateral limit on the tip's firm
    pixels moved its point by up to 0.9 px)."""
    for pitch in (8.0, 15.0, 35.0, 60.0):  # a finger nearly flat still stands above its sides
        tip = detect(bounds, [Finger(320, 240, 90, pitch_deg=pitch)])
        assert len(tip) == 1 and tip.back_spread_mm is not None
        assert tip.back_spread_mm[0] > 10.0, pitch
    book = np.zeros((480, 640), np.float32)
    book[200:320, 300:] = 27.0  # 200 mm wide, from x = 300 to the image border (held there)
    patch = int(15 / MM_PER_PX)
    book[250:250 + patch, 300:300 + patch] = 15.0  # its corner dips into the band
    for seed in range(4):
        tp = detect(bounds, [], flat=book, seed=seed)
        assert len(tp) >= 1 and tp.back_spread_mm is not None
        assert (tp.back_spread_mm < 6.5).all(), seed


def test_the_faint_rim_around_a_tip_lowers_its_height_but_does_not_move_its_point():
    # a finger along +x from a hand at the origin: a 6 px wide body ending in a rounded tip at
    # x = 20; a rim of faint pixels (not firm), two pixels deep, ahead of it and at its sides
    from depthtouch.touch.fingertip import extremity

    yy, xx = np.mgrid[0:20, 0:30]
    body = (np.abs(yy - 10) <= 3) & (xx <= 17)
    cap = (xx - 17) ** 2 + (yy - 10) ** 2 <= 9
    finger = body | cap
    ring = ~finger & ((xx - 17) ** 2 + (yy - 10) ** 2 <= 30) & (xx >= 13)
    hs = np.where(finger, 12.0, np.where(ring, 1.0, 0.0))

    def point(mask, firm_mask):
        ys, xs = np.nonzero(mask)
        return extremity(xs.astype(np.int64), ys.astype(np.int64), firm_mask[ys, xs], hs,
                         0.0, 10.0, 1.0, 0.0, 3.0)

    x0, y0, h0 = point(finger, finger)
    x1, y1, h1 = point(finger | ring, finger)
    assert (x1, y1) == pytest.approx((x0, y0), abs=1e-9)
    assert h0 == 12.0 and h1 == 1.0
    # taken as firm, the rim moves the point forward (what a flickering rim did frame to frame)
    x2, _, _ = point(finger | ring, finger | ring)
    assert x2 > x0 + 0.3
    # the centre of the rounded tip (x = 17), within a pixel
    assert x0 == pytest.approx(17.0, abs=1.0) and y0 == pytest.approx(10.0, abs=0.3)


def test_a_higher_tl_moves_the_reported_contact_forward_along_the_finger(bounds):
    """Tl 5 mm above its floor, 0.4 mm per mm: the contact moves 2 mm away from the hand; at
    the floor, without a hand direction, or with the shift off, it stays."""
    from dataclasses import replace

    from depthtouch.touch.points import tl_above_floor_mm, tl_offset_px

    def tl_shift_px(xy, hand, b, per_mm):  # the points as reported: found + offset
        return xy + tl_offset_px(xy, hand, tl_above_floor_mm(xy, b), b.mm_per_px, per_mm)

    high = replace(bounds, tl_mm=np.full_like(bounds.tl_mm, 9.0), tl_around_mm=None,
                   tl_floor_mm=4.0)
    xy = np.array([[320.0, 240.0], [100.0, 100.0]])
    hand = np.array([[300.0, 240.0], [100.0, 130.0]])  # hands behind: to the left, below
    got = tl_shift_px(xy, hand, high, 0.4)
    step = 2.0 / high.mm_per_px
    np.testing.assert_allclose(got, [[320.0 + step, 240.0], [100.0, 100.0 - step]])
    floor = replace(bounds, tl_mm=np.full_like(bounds.tl_mm, 4.0), tl_around_mm=None,
                    tl_floor_mm=4.0)
    np.testing.assert_array_equal(tl_shift_px(xy, hand, floor, 0.4), xy)
    np.testing.assert_array_equal(tl_shift_px(xy, np.full_like(hand, np.nan), high, 0.4), xy)
    np.testing.assert_array_equal(tl_shift_px(xy, hand, high, 0.0), xy)


def test_a_constant_shift_moves_the_reported_contact_forward_at_the_floor_too(bounds):
    """tip_shift_mm: 1.5 mm away from the hand wherever the hand's direction is known, Tl at
    its floor or not (the Tl shift adds to it); nothing without a hand direction."""
    from dataclasses import replace

    from depthtouch.touch.points import tl_above_floor_mm, tl_offset_px

    xy = np.array([[320.0, 240.0], [100.0, 100.0]])
    hand = np.array([[300.0, 240.0], [100.0, 130.0]])  # hands behind: to the left, below
    floor = replace(bounds, tl_mm=np.full_like(bounds.tl_mm, 4.0), tl_around_mm=None,
                    tl_floor_mm=4.0)
    mm = floor.mm_per_px
    got = tl_offset_px(xy, hand, tl_above_floor_mm(xy, floor), mm, 0.4, 1.5)
    np.testing.assert_allclose(got, [[1.5 / mm, 0.0], [0.0, -1.5 / mm]])
    high = replace(floor, tl_mm=np.full_like(bounds.tl_mm, 9.0))  # 5 mm above: 2 mm more
    got = tl_offset_px(xy, hand, tl_above_floor_mm(xy, high), mm, 0.4, 1.5)
    np.testing.assert_allclose(got, [[3.5 / mm, 0.0], [0.0, -3.5 / mm]])
    none = tl_offset_px(xy, np.full_like(hand, np.nan), tl_above_floor_mm(xy, high), mm, 0.4,
                        1.5)
    np.testing.assert_array_equal(none, np.zeros((2, 2)))
    # Tl unknown around a point (NaN): the constant shift alone
    got = tl_offset_px(xy, hand, np.array([np.nan, np.nan]), mm, 0.4, 1.5)
    np.testing.assert_allclose(got, [[1.5 / mm, 0.0], [0.0, -1.5 / mm]])


def test_tl_above_its_floor_is_read_around_each_point_and_kept_with_the_points(bounds):
    """tl_above_floor_mm reads Tl's neighbourhood mean at the nearest pixel (clamped to the
    image), less the floor, never below 0; find_touch_points gives it per point, and a subset
    of the points keeps it (and the core heights)."""
    from dataclasses import replace

    from depthtouch.touch.points import tl_above_floor_mm

    tl = np.full_like(bounds.tl_mm, 4.0)
    tl[200:, :] = 9.0
    b = replace(bounds, tl_mm=tl, tl_around_mm=None, tl_floor_mm=4.0)
    got = tl_above_floor_mm(np.array([[10.0, 10.0], [10.0, 250.4], [-5.0, 1e4]]), b)
    np.testing.assert_allclose(got, [0.0, 5.0, 5.0])
    low = replace(b, tl_mm=np.full_like(tl, 3.0))
    np.testing.assert_allclose(tl_above_floor_mm(np.array([[10.0, 10.0]]), low), [0.0])
    f = Finger(320.3, 240.6, 30)
    p = detect(bounds, [f])
    assert p.tl_above_floor_mm is not None
    np.testing.assert_allclose(p.tl_above_floor_mm, tl_above_floor_mm(p.xy_px, bounds))
    sub = p[np.array([0])]
    np.testing.assert_array_equal(sub.tl_above_floor_mm, p.tl_above_floor_mm[:1])
    np.testing.assert_array_equal(sub.core_height_mm, p.core_height_mm[:1])
    assert p.attach_share is not None and sub.attach_share is not None
    np.testing.assert_array_equal(sub.attach_share, p.attach_share[:1])


def test_the_shift_is_an_offset_tracking_does_not_use(bounds):
    """find_touch_points keeps the tip where it was found and gives the shift apart."""
    f = Finger(320.3, 240.6, 30)
    on = detect(bounds, [f])
    off = find_touch_points(*_frame(bounds, [f]),
                            TouchPointConfig(tip_tl_shift=0.0, tip_shift_mm=0.0))
    np.testing.assert_array_equal(on.xy_px, off.xy_px)
    assert off.offset_px is None and on.offset_px is not None
    x, y = np.rint(on.xy_px[0]).astype(int)
    win = bounds.tl_mm[y - 4:y + 5, x - 4:x + 5][bounds.valid[y - 4:y + 5, x - 4:x + 5]]
    tl = max(float(win.mean()) - bounds.tl_floor_mm, 0.0)  # Tl around the point, above its floor
    assert tl > 0
    per_mm = TouchPointConfig().tip_tl_shift  # the defaults, which detect() uses
    const_mm = TouchPointConfig().tip_shift_mm
    assert per_mm > 0
    assert np.hypot(*on.offset_px[0]) == pytest.approx((per_mm * tl + const_mm)
                                                        / bounds.mm_per_px, rel=1e-4)


def test_tl_around_is_the_mean_over_the_valid_pixels_of_the_square() -> None:
    """The box sums equal the clipped 9x9 window's mean over valid pixels, edges included."""
    from depthtouch.surface.bounds import tl_around

    rng = np.random.default_rng(0)
    tl = rng.uniform(4, 20, (30, 40)).astype(np.float32)
    valid = rng.random((30, 40)) > 0.2
    valid[10:20, 10:20] = False
    got = tl_around(tl, valid)
    for y, x in [(0, 0), (29, 39), (5, 17), (15, 15), (12, 3)]:
        win, ok = tl[max(y - 4, 0):y + 5, max(x - 4, 0):x + 5], valid[max(y - 4, 0):y + 5,
                                                                     max(x - 4, 0):x + 5]
        want = win[ok].mean() if ok.any() else tl[y, x]
        assert got[y, x] == pytest.approx(want, rel=1e-5)


def _frame(bounds, fingers, seed=0, noise=1.5):
    rng = np.random.default_rng(seed)
    hm = render_heights((480, 640), fingers, MM_PER_PX)
    d = np.clip(np.rint(1000 - hm + rng.normal(0, noise, hm.shape)), 0, None).astype(np.uint16)
    d[rng.random(d.shape) < 0.01] = 0
    return d, band_regions(d, bounds), bounds


def test_core_height_is_the_75th_percentile_of_the_known_3x3_heights(bounds) -> None:
    """core_heights_mm against np.nanpercentile over the height map's 3x3 windows: the image
    edge clamps the window, unknown pixels (depth 0) are left out, and a window with no known
    pixel gives NaN."""
    rng = np.random.default_rng(4)
    hm = render_heights((480, 640), [Finger(320, 240, 90, gap_mm=12)], MM_PER_PX)
    d = np.clip(np.rint(1000 - hm + rng.normal(0, 1.5, hm.shape)), 0, None).astype(np.uint16)
    d[rng.random(d.shape) < 0.2] = 0
    d[100:103, 200:203] = 0  # a window with nothing known
    xy = np.vstack([rng.uniform([-3, -3], [643, 483], (200, 2)), [[201.2, 101.4], [0, 479]]])
    got = core_heights_mm(d, xy, bounds)
    heights = height_mm(d, bounds).astype(np.float64)
    for (x, y), g in zip(xy.tolist(), got.tolist(), strict=True):
        cx, cy = min(max(round(x), 0), 639), min(max(round(y), 0), 479)
        win = heights[[min(max(cy + k, 0), 479) for k in (-1, 0, 1)]][
            :, [min(max(cx + k, 0), 639) for k in (-1, 0, 1)]]
        if np.isnan(win).all():
            assert np.isnan(g)
        else:
            assert g == pytest.approx(float(np.nanpercentile(win, 75)), abs=1e-3)
    assert np.isnan(got[-2])


def test_the_core_of_a_hovering_finger_lies_higher_than_its_tip(bounds) -> None:
    """What the lift test reads: near the tip, a finger 12 mm up has its core well above a
    touching one's (the points carry it as core_height_mm)."""
    touch = detect(bounds, [Finger(320, 240, 90)])
    assert touch.core_height_mm is not None and len(touch) == 1
    core_touch = float(touch.core_height_mm[0])
    rng = np.random.default_rng(0)
    hm = render_heights((480, 640), [Finger(320, 240, 90, gap_mm=12)], MM_PER_PX)
    d = np.clip(np.rint(1000 - hm + rng.normal(0, 1.5, hm.shape)), 0, None).astype(np.uint16)
    core_hover = float(core_heights_mm(d, touch.xy_px, bounds)[0])
    assert core_hover > core_touch + 10
