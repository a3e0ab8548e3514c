"""The compiled per-point steps (parallax.foot_px, points.tl_above_floor_mm,
points.tl_offset_px) against their test oracles: the foot as array operations, the Tl steps as
the plain Python loops they replaced."""

import math

import numpy as np
import pytest
from test_parallax import tilted

from depthtouch.config import RegionConfig
from depthtouch.surface.bounds import BandBounds, band_bounds
from depthtouch.touch.parallax import foot_px
from depthtouch.touch.points import tl_above_floor_mm, tl_offset_px


def foot_reference(xy_px: np.ndarray, bounds: BandBounds, height_mm: float) -> np.ndarray:
    """foot_px as array operations over all points at once (the same arithmetic, in the same
    order, as the compiled per-point step; an independent form of it)."""
    xy = np.asarray(xy_px, np.float64).reshape(-1, 2)
    out = xy.copy()
    K, normals = bounds.K, bounds.normals
    if height_mm == 0.0 or K is None or normals is None or not len(xy):
        return out
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    known = ~np.isnan(xy).any(axis=1)
    h, w = bounds.surface_mm.shape
    ix = np.clip(np.rint(np.where(known, xy[:, 0], 0.0)), 0, w - 1).astype(np.int64)
    iy = np.clip(np.rint(np.where(known, xy[:, 1], 0.0)), 0, h - 1).astype(np.int64)
    z = bounds.surface_mm[iy, ix].astype(np.float64)
    n = normals[iy, ix].astype(np.float64)
    rx, ry = (ix - cx) / fx, (iy - cy) / fy
    with np.errstate(divide="ignore", invalid="ignore"):
        toward = -(n[:, 0] * rx + n[:, 1] * ry + n[:, 2])
        t = z - height_mm / toward
        fx3, fy3, fz3 = rx * t - height_mm * n[:, 0], ry * t - height_mm * n[:, 1], \
            t - height_mm * n[:, 2]
        keep = known & bounds.valid[iy, ix] & (z > 0.0) & (toward > 1e-3) & (fz3 > 0.0)
        out[keep, 0] = (xy[:, 0] + fx * fx3 / fz3 + cx - ix)[keep]
        out[keep, 1] = (xy[:, 1] + fy * fy3 / fz3 + cy - iy)[keep]
    return out


def tl_above_reference(xy_px: np.ndarray, bounds: BandBounds) -> np.ndarray:
    xy = np.asarray(xy_px, np.float64).reshape(-1, 2)
    tl_map = bounds.tl_around_mm if bounds.tl_around_mm is not None else bounds.tl_mm
    h1, w1 = tl_map.shape[0] - 1, tl_map.shape[1] - 1
    out = np.zeros(xy.shape[0])
    for i, (x, y) in enumerate(xy.tolist()):
        if x == x and y == y:
            tl = float(tl_map[min(max(round(y), 0), h1), min(max(round(x), 0), w1)])
            out[i] = max(tl - bounds.tl_floor_mm, 0.0)
    return out


def tl_offset_reference(xy_px: np.ndarray, hand_xy_px: np.ndarray, above_mm: np.ndarray,
                        mm_per_px: float, per_mm: float, const_mm: float) -> np.ndarray:
    xy = np.asarray(xy_px, np.float64).reshape(-1, 2)
    out = np.zeros_like(xy)
    if per_mm == 0.0 and const_mm == 0.0:
        return out
    k = per_mm / mm_per_px
    for i, ((x, y), (hx, hy), above) in enumerate(zip(
            xy.tolist(), np.asarray(hand_xy_px).reshape(-1, 2).tolist(),
            np.asarray(above_mm, np.float64).reshape(-1).tolist())):
        ux, uy = x - hx, y - hy
        n = math.hypot(ux, uy)
        if not n > 1e-6:
            continue
        above = above if above > 0.0 else 0.0
        if above > 0.0 or const_mm > 0.0:
            step = (k * above + const_mm / mm_per_px) / n
            out[i, 0] = ux * step
            out[i, 1] = uy * step
    return out


def _points(rng: np.random.Generator, n: int = 60) -> np.ndarray:
    """Points inside the 640x480 image, on and beyond its border, and unknown ones."""
    xy = np.column_stack([rng.uniform(-20, 660, n), rng.uniform(-20, 500, n)])
    xy[:4] = [[0.0, 0.0], [639.0, 479.0], [319.5, 239.5], [640.4, -0.6]]
    xy[4] = [np.nan, 100.0]
    return xy


@pytest.mark.parametrize("deg", [0.0, 30.0, 60.0])
def test_the_compiled_foot_equals_the_python_loop(deg):
    rng = np.random.default_rng(int(deg))
    s, _, _ = tilted(deg)
    valid = s.valid.copy()
    valid[100:140, 200:260] = False  # points over an unusable surface stay
    s = type(s)(s.depth_mm, s.mean_mm, s.mode_mm, s.median_mm, s.sigma_mm, valid, "mean",
                0.001, s.K, 30)
    b = band_bounds(s, RegionConfig())
    xy = _points(rng)
    xy[5] = [230.0, 120.0]
    for h in (9.0, 0.0, 25.0):
        got, want = foot_px(xy, b, h), foot_reference(xy, b, h)
        np.testing.assert_array_equal(got, want)
    assert foot_px(xy, b, 9.0)[5].tolist() == [230.0, 120.0]
    if deg:
        assert np.abs(foot_px(xy, b, 9.0) - xy)[6:].max() > 1.0  # it moved points


def test_the_compiled_tl_steps_equal_the_python_loops():
    rng = np.random.default_rng(7)
    s, _, _ = tilted(20.0)
    sigma = rng.uniform(0.5, 4.0, s.sigma_mm.shape).astype(np.float32)
    s = type(s)(s.depth_mm, s.mean_mm, s.mode_mm, s.median_mm, sigma, s.valid, "mean", 0.001,
                s.K, 30)
    b = band_bounds(s, RegionConfig())
    xy = _points(rng)
    above = tl_above_floor_mm(xy, b)
    np.testing.assert_array_equal(above, tl_above_reference(xy, b))
    assert above[4] == 0.0 and (above > 0).sum() > 10
    hand = xy + rng.normal(0, 30, xy.shape)
    hand[6] = xy[6]  # no hand direction
    hand[7] = np.nan
    above_in = above.copy()
    above_in[8] = np.nan
    for per_mm, const_mm in ((0.4, 1.5), (0.3, 0.0), (0.0, 2.0), (0.0, 0.0)):
        got = tl_offset_px(xy, hand, above_in, b.mm_per_px, per_mm, const_mm)
        want = tl_offset_reference(xy, hand, above_in, b.mm_per_px, per_mm, const_mm)
        np.testing.assert_array_equal(got, want)
    assert tl_offset_px(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), 1.0, 0.4, 1.5).shape \
        == (0, 2)
    with pytest.raises(ValueError, match="one of each per point"):
        tl_offset_px(xy, hand[:3], above_in, b.mm_per_px, 0.4, 1.5)
