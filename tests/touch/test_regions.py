import numpy as np
import pytest

from depthtouch.config import RegionConfig
from depthtouch.surface.bounds import band_bounds, height_mm
from depthtouch.surface.model import learn_surface
from depthtouch.touch.regions import band_regions
from reference_touchpoints import band_masks
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
        assert len(band_regions(frame_with(np.zeros((480, 640), np.float32), seed), b)) == 0


def test_regions_found_and_small_ones_dropped(surface):
    b = band_bounds(surface, RegionConfig())
    hm = render_heights((480, 640), [Finger(200, 240, 90), Finger(400, 240, 90)], 1000 / 600)
    hm[50:53, 50:53] = 15.0  # 9 px: under S_min
    r = band_regions(frame_with(hm), b)
    assert len(r) == 2
    assert np.all(r.area_px >= b.min_area_px)
    for m, (_x, _y, w, h) in zip(r.masks, r.bbox_xywh):
        assert m.shape == (h, w) and m.any()


@pytest.mark.parametrize("open_px", [1, 3, 5, 7])
@pytest.mark.parametrize("seed", [0, 1])
def test_band_core_is_the_eroded_band(open_px, seed):
    """The compiled band + erosion equals OpenCV's, including at the image border."""
    import cv2

    from depthtouch.touch.regions import band_core

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


def _runs_of(core: np.ndarray) -> np.ndarray:
    """(n, 3) runs (y, x0, x1) of a mask in raster order (the layout regions' kernels use)."""
    out = []
    for y in range(core.shape[0]):
        edges = np.diff(np.concatenate([[0], (core[y] > 0).astype(np.int8), [0]]))
        out += [(y, a, b) for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1))]
    return np.array(out, np.int64).reshape(-1, 3)


def _same_regions(got, want) -> None:
    np.testing.assert_array_equal(got.bbox_xywh, want.bbox_xywh.reshape(-1, 4))
    np.testing.assert_array_equal(got.area_px, want.area_px)
    for g, w in zip(got.masks, want.masks, strict=True):
        np.testing.assert_array_equal(g, w)


@pytest.mark.parametrize("seed", range(6))
def test_regions_of_runs_match_opencv_contours(seed):
    """The runs version (parts, filled holes, dilation box by box, the close-parts fallback,
    OpenCV's order) gives OpenCV's regions, on random masks with holes, parts inside holes,
    specks, parts at the border and parts close to each other."""
    import cv2

    import reference_touchpoints as ref
    from depthtouch.runs import dilate_runs, parts_of_runs
    from depthtouch.touch.regions import Regions, _any_close

    rng = np.random.default_rng(seed)
    n_close = 0
    for _ in range(300):
        H, W = (int(v) for v in rng.integers(5, 60, 2))
        core = np.zeros((H, W), np.uint8)
        for _ in range(int(rng.integers(1, 8))):
            x, y = int(rng.integers(0, W)), int(rng.integers(0, H))
            w, h = (int(v) for v in rng.integers(1, 15, 2))
            kind = rng.integers(0, 4)
            if kind == 0:
                core[y:y + h, x:x + w] = 255
            elif kind == 1:  # a ring, sometimes with a part inside its hole
                core[y:y + h, x:x + w] = 255
                core[y + 2:y + h - 2, x + 2:x + w - 2] = 0
                if rng.random() < 0.5:
                    core[y + 4:y + h - 4, x + 4:x + w - 4] = 255
            elif kind == 2:
                cv2.circle(core, (x, y), w, 255, -1)
            else:
                core[rng.random((H, W)) < 0.05] = 255
        k = int(rng.choice([1, 3, 5]))
        min_area = int(rng.integers(1, 40))
        want = ref.regions_of_core(core, k, min_area)
        runs = _runs_of(core)
        if len(runs) == 0:
            assert len(want) == 0
            continue
        boxes, areas, buf, starts = parts_of_runs(runs, H, W, min_area, k // 2)
        if k > 1 and len(boxes) > 1 and _any_close(boxes):
            n_close += 1
            boxes, areas, buf, starts = parts_of_runs(dilate_runs(runs, k // 2, H, W), H, W,
                                                      min_area, 0)
        _same_regions(Regions(boxes, areas, buf, starts), want)
    assert n_close > 20  # the fallback was exercised


@pytest.mark.parametrize("scene, camera", [("multitouch", "realsense-d435"), ("pinch", "kinect-v2"),
                                           ("object", "kinect-v1")])
def test_band_regions_match_opencv_on_recordings(scene, camera):
    """Frame by frame on simulated recordings: the compiled regions are OpenCV's."""
    import cv2

    import reference_touchpoints as ref
    from depthtouch.config import PipelineConfig
    from depthtouch.sim import render_scene
    from depthtouch.touch.regions import band_core

    rec = render_scene(scene, camera=camera, distance_m=1.0, seed=3)
    cfg = PipelineConfig()
    depth = np.stack([cv2.medianBlur(d, 3) for d in rec.depth])
    n = int(cfg.surface.learn_s * 30)
    b = band_bounds(learn_surface(depth[:n], rec.depth_scale_m, rec.K), cfg.regions)
    found = 0
    for d in depth[n:]:
        got = band_regions(d, b)
        _same_regions(got, ref.regions_of_core(band_core(d, b), b.open_px, b.min_area_px))
        found += len(got)
    assert found > 30


def _depth_bounds_numpy(surface_mm, valid, factor, tl_mm, to_mm, tu_mm, hand_max_mm):
    """The depth bounds as whole-array numpy float32 operations (the compiled kernel's oracle)."""
    s_units = surface_mm / np.float32(to_mm)
    per_mm = 1.0 / (np.float32(to_mm) * factor)
    band_lo = np.ceil(s_units - np.float32(tu_mm) * per_mm + 1e-3)
    band_hi = np.floor(s_units - tl_mm * per_mm - 1e-3)
    high_hi = band_lo - 1
    high_lo = np.ceil(s_units - np.float32(hand_max_mm) * per_mm)

    def clip(a, empty):
        out = np.clip(a, 1, 65535).astype(np.uint16)
        out[~valid] = empty
        return out

    return clip(band_lo, 1), clip(band_hi, 0), clip(high_lo, 1), clip(high_hi, 0)


def test_depth_bounds_bit_for_bit_as_numpy():
    from depthtouch.surface.bounds import _depth_bounds

    rng = np.random.default_rng(0)
    for _ in range(200):
        h, w = (int(v) for v in rng.integers(1, 40, 2))
        to_mm = float(rng.choice([1.0, 0.1, 0.125, 0.25]))
        surf = rng.uniform(200, 5000, (h, w)).astype(np.float32)
        if rng.random() < 0.3:
            surf = np.rint(surf)  # whole numbers meet the rounding edges
        factor = rng.uniform(0.5, 1.5, (h, w)).astype(np.float32)
        if rng.random() < 0.3:
            factor[:] = 1.0
        args = (surf, rng.random((h, w)) > 0.1, factor,
                rng.uniform(1, 20, (h, w)).astype(np.float32), to_mm,
                float(rng.uniform(21, 40)), float(rng.uniform(100, 800)))
        for got, want in zip(_depth_bounds(*args), _depth_bounds_numpy(*args), strict=True):
            assert got.dtype == np.uint16
            np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("tip_radius_mm, open_px, need_block", [
    (7.0, 3, False),   # a fingertip 8.4 px across: the 3x3 opening
    (4.0, 3, False),   # 4.8 px
    (3.5, 1, True),    # 4.2 px: no opening, regions need a 2x2 block
    (2.5, 1, False),   # 3.0 px: every region counts
])
def test_the_opening_follows_the_fingertips_size_in_pixels(surface, tip_radius_mm, open_px,
                                                            need_block):
    cfg = RegionConfig(open_tip_px=4.5, block_tip_px=3.5, open_band_px=0.0)
    b = band_bounds(surface, cfg, tip_radius_mm=tip_radius_mm)
    assert (b.open_px, b.need_block) == (open_px, need_block)


@pytest.mark.parametrize("tl_floor_mm, open_band_px, open_px", [
    (4.0, 6.0, 3),    # Tu - Tl = 21 mm: 12.6 px, a deep band: the opening
    (16.0, 6.0, 1),   # 9 mm: 5.4 px, a slanted finger's band is too thin for it
    (16.0, 5.0, 3),   # ... unless 5 px is deep enough
    (4.0, 0.0, 1),    # the rule off: the fingertip's size alone
])
def test_between_the_sizes_a_deep_band_is_opened(surface, tl_floor_mm, open_band_px, open_px):
    """A fingertip 4.2 px across (between block_tip_px and open_tip_px): the opening is used
    when Tu - Tl spans at least open_band_px pixels (ToF at 1.1 m, whose mixed pixels along a
    finger's sides would join its tip region), not when Tl is high (structured light at 1.8 m)."""
    cfg = RegionConfig(open_tip_px=4.5, block_tip_px=3.5, open_band_px=open_band_px,
                       tl_floor_mm=tl_floor_mm, noise_k=0.0)
    b = band_bounds(surface, cfg, tip_radius_mm=3.5)
    assert (b.open_px, b.need_block) == (open_px, open_px == 1)


def test_without_the_opening_one_pixel_lines_go_and_thin_slivers_stay(surface):
    """At a coarse scale (a fingertip 4-5 px across) the 3x3 opening would erase the 2-px band
    under a finger held at a slant; instead, a region must hold a 2x2 block, which drops the
    one-pixel lines of mixed pixels along a finger's edge and never cuts a region."""
    import dataclasses

    b = band_bounds(surface, RegionConfig())
    assert b.open_px == 3 and not b.need_block
    hm = np.zeros((480, 640), np.float32)
    hm[100:102, 100:130] = 12.0            # a sliver 2 px thick, 30 px long
    hm[200, 100:140] = 12.0                # a line 1 px wide
    hm[300:330, 300] = 12.0                # a line 1 px wide, upright
    hm[300 + np.arange(25), 400 + np.arange(25)] = 12.0  # a diagonal line
    hm[400:402, 500:520] = 12.0            # a sliver with a one-pixel tail
    hm[402, 519:540] = 12.0
    d = frame_with(hm, noise=0.0)
    assert len(band_regions(d, b)) == 0    # the opening takes every one of them
    coarse = dataclasses.replace(b, open_px=1, need_block=True)
    r = band_regions(d, coarse)
    assert sorted(map(tuple, r.bbox_xywh[:, :2].tolist())) == [(100, 100), (500, 400)]
    tail = [m for m, (x, _y, _w, _h) in zip(r.masks, r.bbox_xywh) if x == 500][0]
    assert tail.sum() == 40 + 21           # kept whole, the tail included
    assert len(band_regions(d, dataclasses.replace(b, open_px=1))) == 5
