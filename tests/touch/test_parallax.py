"""The touch point moved from the tip's image to the surface beneath it (touch/parallax.py)."""

import numpy as np
import pytest

from depthtouch.config import RegionConfig
from depthtouch.surface.bounds import band_bounds
from depthtouch.surface.model import SurfaceModel, height_factor, surface_normals
from synth import K_640


def plane(normal: np.ndarray, through_mm: np.ndarray, K: np.ndarray | None = K_640,
          shape: tuple[int, int] = (480, 640)) -> SurfaceModel:
    """The surface model of a plane (exact depths, no noise)."""
    h, w = shape
    Kd = K_640 if K is None else K
    u = (np.arange(w) - Kd[0, 2]) / Kd[0, 0]
    v = (np.arange(h) - Kd[1, 2]) / Kd[1, 1]
    uu, vv = np.meshgrid(u, v)
    n = normal / np.linalg.norm(normal)
    z = (n @ through_mm) / (n[0] * uu + n[1] * vv + n[2])
    z = z.astype(np.float32)
    sig = np.full(shape, 1.0, np.float32)
    return SurfaceModel(z, z, z, z, sig, np.ones(shape, bool), "mean", 0.001, K, 30)


def project(p: np.ndarray, K: np.ndarray = K_640) -> np.ndarray:
    return np.array([K[0, 0] * p[0] / p[2] + K[0, 2], K[1, 1] * p[1] / p[2] + K[1, 2]])


def tilted(deg: float) -> tuple[SurfaceModel, np.ndarray, np.ndarray]:
    """A wall 1 m away tilted by ``deg`` about the x axis; its normal toward the camera and a
    point on it."""
    t = np.radians(deg)
    n = np.array([0.0, np.sin(t), -np.cos(t)])  # toward the camera (z grows away from it)
    p0 = np.array([0.0, 0.0, 1000.0])
    return plane(-n, p0), n, p0


def test_normals_of_a_tilted_plane_point_toward_the_camera():
    s, n, _ = tilted(30.0)
    normals = surface_normals(s)
    assert normals is not None
    inner = normals[20:-20, 20:-20].reshape(-1, 3)
    assert np.allclose(inner, n, atol=2e-3)
    # the height factor is unchanged by taking the normals once
    assert np.array_equal(height_factor(s, normals), height_factor(s))


@pytest.mark.parametrize("deg", [0.0, 20.0, 35.0])
@pytest.mark.parametrize("at", [(0.0, 0.0), (150.0, -100.0), (-200.0, 120.0)])
def test_a_point_seen_above_the_surface_is_moved_to_the_surface_point_beneath_it(deg, at):
    from depthtouch.touch.parallax import foot_px

    s, n, p0 = tilted(deg)
    b = band_bounds(s, RegionConfig())
    # a point on the wall (in the wall's plane: x across, y up the tilt) and one 9 mm above it
    t = np.radians(deg)
    foot = p0 + np.array([at[0], at[1] * np.cos(t), at[1] * np.sin(t)])
    seen = foot + 9.0 * n
    got = foot_px(project(seen)[None], b, 9.0)[0]
    want = project(foot)
    assert np.hypot(*(got - want)) < 0.05, (got, want)
    # uncorrected, the pixel's ray meets the wall 9 mm tan(theta) beyond the contact
    ray = seen / np.linalg.norm(seen)
    hit = ray * (n @ p0) / (n @ ray)
    tan = np.sqrt(1.0 - (ray @ n) ** 2) / abs(ray @ n)
    assert np.linalg.norm(hit - foot) == pytest.approx(9.0 * tan, abs=1e-6)


def test_the_point_stays_where_it_is_without_height_intrinsics_or_surface():
    from depthtouch.touch.parallax import foot_px

    s, _, _ = tilted(30.0)
    xy = np.array([[100.25, 200.5], [400.0, 300.75]])
    b = band_bounds(s, RegionConfig())
    assert np.array_equal(foot_px(xy, b, 0.0), xy)
    no_k = plane(np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 1000.0]), K=None)
    assert np.array_equal(foot_px(xy, band_bounds(no_k, RegionConfig()), 9.0), xy)
    hole = SurfaceModel(s.depth_mm, s.mean_mm, s.mode_mm, s.median_mm, s.sigma_mm,
                        np.zeros_like(s.valid), "mean", 0.001, s.K, 30)
    assert np.array_equal(foot_px(xy, band_bounds(hole, RegionConfig()), 9.0), xy)
    assert foot_px(np.zeros((0, 2)), b, 9.0).shape == (0, 2)
    # straight under the camera on a wall facing it, a point does not move (to within the
    # shift's change between the point and its pixel's centre, half a pixel away here)
    flat = band_bounds(tilted(0.0)[0], RegionConfig())
    c = np.array([[K_640[0, 2], K_640[1, 2]]])
    assert np.allclose(foot_px(c, flat, 9.0), c, atol=0.01)
