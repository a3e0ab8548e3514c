import dataclasses
import logging

import numpy as np
import pytest

from depthtouch.config import PipelineConfig, RegionConfig, SurfaceConfig
from depthtouch.errors import SurfaceError
from depthtouch.surface.bounds import TIP_TOP_MM, band_bounds, noisy_share
from depthtouch.surface.model import SurfaceLearner, SurfaceModel, height_factor, learn_surface
from depthtouch.surface.surface import Surface
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


def _noisy_model(sigma_far_mm: float, far_share: float, shape=(20, 40)) -> SurfaceModel:
    """A flat surface 1 m away, its left ``far_share`` of columns with noise sigma_far_mm."""
    z = np.full(shape, 1000.0, np.float32)
    sig = np.full(shape, 1.0, np.float32)
    sig[:, : int(round(far_share * shape[1]))] = sigma_far_mm
    return SurfaceModel(z, z, z, z, sig, np.ones(shape, bool), "mean", 0.001, K, 30)


def test_noisy_share_counts_usable_pixels_whose_tl_reaches_a_fingertip():
    # Tl = 3 sigma: 6 mm sigma gives 18 mm (at or above TIP_TOP_MM) on the left 60 %
    b = band_bounds(_noisy_model(6.0, 0.6), RegionConfig())
    assert noisy_share(b) == pytest.approx(0.6)
    assert noisy_share(b, tl_mm=19.0) == 0.0
    assert noisy_share(b, tl_mm=3.0) == 1.0
    # exactly at the limit counts (Tl 16 mm = 3 x 5.333 mm)
    at = band_bounds(_noisy_model(TIP_TOP_MM / 3.0 + 1e-4, 1.0), RegionConfig())
    assert noisy_share(at) == 1.0
    # no usable pixel: nothing is noisy
    m = _noisy_model(6.0, 1.0)
    none = SurfaceModel(m.depth_mm, m.mean_mm, m.mode_mm, m.median_mm, m.sigma_mm,
                        np.zeros_like(m.valid), "mean", 0.001, K, 30)
    assert noisy_share(band_bounds(none, RegionConfig())) == 0.0


@pytest.mark.parametrize("far_share, warns", [(0.6, True), (0.5, True), (0.4, False), (0.0, False)])
def test_a_surface_too_noisy_for_touches_is_warned_about_once(caplog, far_share, warns):
    caplog.set_level(logging.WARNING, logger="depthtouch.surface.surface")
    Surface(PipelineConfig(), _noisy_model(6.0, far_share))
    msgs = [r.getMessage() for r in caplog.records if r.name == "depthtouch.surface.surface"]
    if not warns:
        assert msgs == []
        return
    assert len(msgs) == 1 and "\n" not in msgs[0]
    assert f"on {100 * far_share:.0f}% of the surface" in msgs[0]
    assert "16 mm or more" in msgs[0] and "mount the camera closer" in msgs[0]


def test_no_noise_warning_when_tl_was_raised_on_purpose(caplog):
    caplog.set_level(logging.WARNING, logger="depthtouch.surface.surface")
    cfg = PipelineConfig()
    cfg = dataclasses.replace(cfg, regions=dataclasses.replace(cfg.regions, tl_floor_mm=16.0))
    Surface(cfg, _noisy_model(1.0, 0.0))
    assert [r for r in caplog.records if r.name == "depthtouch.surface.surface"] == []


def test_a_hand_coming_in_after_the_first_second_is_left_out_of_the_learning():
    """A recording promises an empty surface for its first second only: what moves in the
    learning frames after it is left out, pixel by pixel; what moved before it is learned."""
    rng = np.random.default_rng(5)

    def learn(hand_from: int, learn_min_s: float):
        learner = SurfaceLearner(SurfaceConfig(learn_s=1.5, learn_min_s=learn_min_s))
        for i in range(60):
            d = (1000 + rng.normal(0, 2, (120, 160))).astype(np.uint16)
            if i >= hand_from:
                d[40:100, 60:110] = 800  # a hand 200 mm above the surface
            model = learner.update(Frame(d, i / 30.0, i, 0.001, None))
            if model is not None:
                return model, learner.masked

    hand = (slice(40, 100), slice(60, 110))
    model, masked = learn(20, 1.5)  # (0.67 s of the 1.5 s: the median's majority is the hand)
    assert float(np.median(model.depth_mm[hand])) == 800 and masked == 0
    model, masked = learn(36, 1.0)  # in after 1.2 s: left out
    assert masked == 60 * 50 * (46 - 36)
    assert abs(float(np.median(model.depth_mm[hand])) - 1000) < 1
    assert float(np.median(model.sigma_mm[hand])) < 3  # the noise of the table, not the hand's
    model, masked = learn(36, 1.5)  # taken as it is: the median holds (a minority of frames),
    assert abs(float(np.median(model.depth_mm[hand])) - 1000) < 3
    assert float(np.median(model.sigma_mm[hand])) > 50  # but the noise there is the hand's
    model, masked = learn(99, 1.0)  # the noise alone: nothing left out
    assert masked == 0


def _mask_moved_oracle(depth, sure, to_mm):
    """The array version of model.mask_moved (the compiled pass's oracle)."""
    from depthtouch.surface.model import MOTION_MM, MOTION_SIGMAS

    first = depth[:sure].astype(np.float64)
    ok = first > 0
    cnt = ok.sum(axis=0)
    mean = first.sum(axis=0) / np.maximum(cnt, 1)
    var = (np.where(ok, first - mean, 0.0) ** 2).sum(axis=0) / np.maximum(cnt - 1, 1)
    lim = np.maximum(MOTION_MM / to_mm, MOTION_SIGMAS * np.sqrt(var))
    later = depth[sure:]
    moved = (later > 0) & (cnt >= 2) & (np.abs(later.astype(np.float64) - mean) > lim)
    out = depth.copy()
    out[sure:][moved] = 0
    return out, int(moved.sum())


@pytest.mark.parametrize("scale_m", [0.001, 0.0001])
def test_moved_samples_match_the_array_version(scale_m):
    from depthtouch.surface.model import mask_moved

    rng = np.random.default_rng(11)
    to_mm = scale_m * 1000.0
    mm = 1000 + rng.normal(0, 4, (40, 30, 50))
    mm[rng.random(mm.shape) < 0.05] = 0  # missing samples
    mm[:, :3, :3] = 0  # never valid
    mm[30:, 10:20, 10:30] = 930  # a hand 70 mm up after the first 30 frames
    mm[33:, 0, :] += rng.normal(0, 30, (7, 50))  # a noisy row: some beyond 20 mm, some not
    depth = np.where(mm > 0, np.round(mm / to_mm), 0).astype(np.uint16)
    out, k = mask_moved(depth, 30, to_mm)
    want, k_want = _mask_moved_oracle(depth, 30, to_mm)
    assert k == k_want > 10 * 20 * 9 and np.array_equal(out, want)
    out40, k40 = mask_moved(depth, 40, to_mm)  # every frame sure: nothing to read
    assert out40 is depth and k40 == 0
