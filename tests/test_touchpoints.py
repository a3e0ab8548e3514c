import numpy as np
import pytest

from depthtouch.config import RegionConfig, TouchPointConfig
from depthtouch.regions import band_bounds, band_masks, find_regions
from depthtouch.surface import learn_surface
from depthtouch.touchpoints import find_touch_points
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
    band, high = band_masks(d, bounds)
    regions = find_regions(band, bounds)
    return find_touch_points(d, high, regions, bounds, TouchPointConfig(method=method))


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
