import numpy as np
import pytest

from depthtouch.config import SurfaceConfig
from depthtouch.errors import SurfaceError
from depthtouch.surface.model import SurfaceLearner, height_factor, learn_surface
from depthtouch.types import Frame

K = np.array([[500.0, 0, 31.5], [0, 500.0, 23.5], [0, 0, 1]])


def stack(values: list[int], shape=(4, 5)) -> np.ndarray:
    return np.stack([np.full(shape, v, np.uint16) for v in values])


@pytest.mark.parametrize(
    "values, mean, mode, median",
    [
        ([1000, 1000, 1000, 1003], 1000.75, 1000, 1000),
        ([1000, 1002, 1002, 1010], 1003.5, 1002, 1002),
        # zeros are missing measurements, not depth
        ([0, 0, 1000, 1002, 1002], 1001.3333, 1002, 1002),
        # a tie goes to the farther depth
        ([1000, 1000, 1004, 1004], 1002, 1004, 1002),
    ],
)
def test_statistics_per_pixel(values, mean, mode, median):
    m = learn_surface(stack(values), 0.001, None, SurfaceConfig(min_valid_fraction=0.3))
    assert m.mean_mm[0, 0] == pytest.approx(mean, abs=1e-3)
    assert m.mode_mm[0, 0] == pytest.approx(mode)
    assert m.median_mm[0, 0] == pytest.approx(median)
    assert m.valid.all()


def test_depth_scale_converts_to_mm():
    m = learn_surface(stack([4000, 4000, 4002]), 0.00025)
    assert m.mean_mm[0, 0] == pytest.approx(1000.1667, abs=1e-3)
    assert m.mode_mm[0, 0] == pytest.approx(1000.0)


def test_sigma_matches_noise_and_is_floored():
    rng = np.random.default_rng(1)
    d = np.rint(1500 + rng.normal(0, 4.0, (200, 20, 20))).astype(np.uint16)
    m = learn_surface(d, 0.001)
    assert float(np.median(m.sigma_mm)) == pytest.approx(4.0, rel=0.1)
    flat = learn_surface(stack([1000] * 5), 0.001, config=SurfaceConfig(noise_floor_mm=0.7))
    assert np.all(flat.sigma_mm == pytest.approx(0.7))


def test_pixels_rarely_seen_are_unusable():
    d = stack([1000] * 10)
    d[:8, 0, 0] = 0  # seen in 2 of 10 frames
    m = learn_surface(d, 0.001)
    assert not m.valid[0, 0] and m.valid[1, 1]
    assert m.depth_mm[0, 0] == 0


@pytest.mark.parametrize(
    "depth, message",
    [
        (np.zeros((1, 4, 4), np.uint16), "at least 2 frames"),
        (np.zeros((5, 4, 4), np.uint16), "no pixel had valid depth"),
        (np.zeros((5, 4, 4), np.float32), "expected uint16"),
    ],
)
def test_learn_errors(depth, message):
    with pytest.raises(SurfaceError, match=message):
        learn_surface(depth, 0.001)


def test_with_statistic_switches_depth():
    m = learn_surface(stack([1000, 1002, 1002, 1010]), 0.001)
    assert m.with_statistic("mean").depth_mm[0, 0] == pytest.approx(1003.5)
    assert m.with_statistic("mode").depth_mm[0, 0] == pytest.approx(1002)
    with pytest.raises(SurfaceError, match="unknown surface statistic"):
        m.with_statistic("max")


def _plane_depth(shape, tilt_deg, z0=1000.0):
    """Depth of a plane through (0, 0, z0) tilted about the x axis, seen through K."""
    h, w = shape
    v = (np.arange(h) - K[1, 2]) / K[1, 1]
    t = np.tan(np.deg2rad(tilt_deg))
    # plane: Z = z0 + t * Y, with Y = v Z  =>  Z = z0 / (1 - t v)
    z = z0 / (1 - t * v)
    return np.repeat(z[:, None], w, axis=1)


@pytest.mark.parametrize("tilt", [0.0, 20.0, 40.0])
def test_height_factor_gives_height_along_normal(tilt):
    z = _plane_depth((48, 64), tilt)
    d = np.stack([np.rint(z).astype(np.uint16)] * 3)
    m = learn_surface(d, 0.001, K)
    f = height_factor(m)
    # for a ray along the optical axis the factor is cos(tilt)
    c = f[24, 32]
    assert c == pytest.approx(np.cos(np.deg2rad(tilt)), abs=0.02)


def test_learner_uses_timestamps_and_frames():
    lr = SurfaceLearner(SurfaceConfig(learn_s=0.1))
    out = None
    for i in range(10):
        out = lr.update(Frame(np.full((4, 4), 900, np.uint16), i / 30, i))
        if out is not None:
            break
    assert out is not None and i == 3  # t = 0.1 s reached at the 4th frame
    lr2 = SurfaceLearner(SurfaceConfig(), n_frames=5)
    results = [lr2.update(Frame(np.full((4, 4), 900, np.uint16), i, i)) for i in range(5)]
    assert results[-1] is not None and all(r is None for r in results[:-1])


def test_learner_rejects_changed_size():
    lr = SurfaceLearner(n_frames=5)
    lr.update(Frame(np.full((4, 4), 900, np.uint16), 0.0, 0))
    with pytest.raises(SurfaceError, match="one resolution"):
        lr.update(Frame(np.full((4, 5), 900, np.uint16), 0.1, 1))
