import numpy as np
import pytest

from depthtouch.config import RegionConfig
from depthtouch.regions import band_bounds, band_masks, find_regions, height_mm
from depthtouch.surface import learn_surface
from synth import K_640, Finger, make_recording, render_heights


@pytest.fixture(scope="module")
def surface():
    d, _ = make_recording(30, [], noise_mm=1.5, seed=1)
    return learn_surface(d, 0.001, K_640)


def frame_with(heights: np.ndarray, seed: int = 0, noise: float = 1.5) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = 1000 - heights + rng.normal(0, noise, heights.shape)
    return np.clip(np.rint(d), 0, 65535).astype(np.uint16)


def test_band_thresholds_follow_noise_with_floor(surface):
    b = band_bounds(surface, RegionConfig(noise_k=3.0, tl_floor_mm=4.0, tu_mm=25.0))
    assert np.all(b.tl_mm >= 4.0)
    assert float(np.median(b.tl_mm)) == pytest.approx(max(4.0, 3 * 1.5), rel=0.15)
    # S_min in pixels follows the distance: 40 mm^2 at 1.667 mm/px is ~14 px
    assert b.min_area_px == round(40 / (1000 / 600) ** 2)


@pytest.mark.parametrize(
    "height_mm, in_band, in_high",
    [(0.0, False, False), (12.0, True, False), (20.0, True, False), (40.0, False, True),
     (900.0, False, False)],
)
def test_masks_by_height(surface, height_mm, in_band, in_high):
    b = band_bounds(surface, RegionConfig())
    hm = np.zeros((480, 640), np.float32)
    hm[200:260, 300:360] = height_mm
    band, high = band_masks(frame_with(hm, noise=0.0), b)
    assert bool(band[230, 330]) is in_band
    assert bool(high[230, 330]) is in_high


def test_missing_depth_is_in_no_mask(surface):
    b = band_bounds(surface, RegionConfig())
    d = frame_with(np.zeros((480, 640), np.float32))
    d[100:200, 100:200] = 0
    band, high = band_masks(d, b)
    assert not band[100:200, 100:200].any() and not high[100:200, 100:200].any()
    assert np.isnan(height_mm(d, b)[150, 150])


def test_noise_alone_gives_no_region(surface):
    b = band_bounds(surface, RegionConfig())
    for seed in range(5):
        band, _ = band_masks(frame_with(np.zeros((480, 640), np.float32), seed), b)
        assert len(find_regions(band, b)) == 0


def test_regions_found_and_small_ones_dropped(surface):
    b = band_bounds(surface, RegionConfig())
    hm = render_heights((480, 640), [Finger(200, 240, 90), Finger(400, 240, 90)], 1000 / 600)
    hm[50:53, 50:53] = 15.0  # 9 px: under S_min
    band, _ = band_masks(frame_with(hm), b)
    r = find_regions(band, b)
    assert len(r) == 2
    assert np.all(r.area_px >= b.min_area_px)
    for m, (_x, _y, w, h) in zip(r.masks, r.bbox_xywh):
        assert m.shape == (h, w) and m.any()


@pytest.mark.parametrize("open_px", [1, 3, 4, 5])
@pytest.mark.parametrize("seed", [0, 1])
def test_band_core_is_the_eroded_band(open_px, seed):
    """The compiled band + erosion equals OpenCV's, including at the image border."""
    import cv2

    from depthtouch.regions import band_core

    b = band_bounds(learn_surface(make_recording(20, [], noise_mm=1.5, seed=seed)[0], 0.001, K_640),
                    RegionConfig(open_px=open_px))
    rng = np.random.default_rng(seed)
    hm = render_heights((480, 640), [Finger(100, 5, 270), Finger(630, 200, 0), Finger(320, 240, 45)],
                        1000 / 600)
    d = np.clip(np.rint(1000 - hm + rng.normal(0, 3.0, hm.shape)), 0, None).astype(np.uint16)
    d[rng.random(d.shape) < 0.01] = 0
    band, _ = band_masks(d, b)
    k = cv2.getStructuringElement(cv2.MORPH_RECT, (b.open_px, b.open_px))
    want = cv2.erode(band, k) if b.open_px > 1 else band
    np.testing.assert_array_equal(band_core(d, b), want)
