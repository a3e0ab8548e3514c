import math

import numpy as np
import pytest

from depthtouch.config import TouchPointConfig, TrackingConfig
from depthtouch.tracking import lift
from depthtouch.tracking.lift import CoreHistory
from depthtouch.tracking.tracker import Tracker
from depthtouch.types import TouchPoints


def _oracle(values: list[float]) -> list[float]:
    """The rise, frame by frame, from arrays: the median of the last RECENT known values, less
    BASE_PCT percentile of those medians over the last HISTORY frames; NaN for an unknown
    value and before MINHIST known ones."""
    known: list[float] = []
    levels: list[float] = []
    out = []
    for v in values:
        if not math.isfinite(v):
            out.append(math.nan)
            continue
        known.append(v)
        level = float(np.median(known[-lift.RECENT:]))
        levels.append(level)
        if len(levels) < lift.MINHIST:
            out.append(math.nan)
        else:
            out.append(level - float(np.percentile(levels[-lift.HISTORY:], lift.BASE_PCT)))
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_rise_is_the_recent_level_above_the_tracks_own(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = lift.HISTORY + 150  # past the bounded history
    values = rng.normal(10.0, 4.0, n)
    values[rng.random(n) < 0.1] = np.nan
    values[200:230] += 25.0  # a lift
    h = CoreHistory()
    got = [h.update(float(v)) for v in values]
    np.testing.assert_allclose(got, _oracle(values.tolist()), atol=1e-9)
    h.reset()
    assert math.isnan(h.base())
    assert math.isnan(h.update(5.0))  # a new history: not yet MINHIST values


def _tip(h: float, core: float, x: float = 100.0) -> TouchPoints:
    return TouchPoints(np.array([[x, 100.0]]), np.array([h]), np.array([300]),
                       np.full((1, 2), np.nan), core_height_mm=np.array([core]))


def _states(tracker: Tracker, frames: list[TouchPoints]) -> list[list[tuple[int, str]]]:
    return [[(u.track.id, u.state) for u in tracker.update(f)] for f in frames]


def _taps(core_between: float, frames_between: int) -> list[TouchPoints]:
    """A tap, the finger lifted while its tip still reads 3 mm up (its core does not), a
    second tap at the same place."""
    contact = [_tip(3.0, 8.0 + (i % 3)) for i in range(20)]
    lifted = [_tip(3.0, core_between)] * frames_between
    return contact + lifted + contact


def _ids_down(frames: list[list[tuple[int, str]]]) -> list[int]:
    return [i for f in frames for i, s in f if s == "down"]


def test_two_taps_whose_core_shows_the_lift_between_them_are_two_touches() -> None:
    tr = Tracker(TrackingConfig(lift_core_mm=15.0), TouchPointConfig(), scale_mm_per_px=1.0)
    frames = _states(tr, _taps(core_between=35.0, frames_between=8))
    assert _ids_down(frames) == [1, 2]
    ups = [k for k, f in enumerate(frames) if any(s == "up" for _, s in f)]
    # the core's median of 3 follows from the second lifted frame; up on the third such frame
    assert ups == [20 + 3]
    # the lifted finger goes down again only once its core is back: not during the lift
    assert all(s != "down" for f in frames[20:28] for _, s in f)


def test_without_the_lift_test_two_taps_with_a_low_tip_between_are_one_touch() -> None:
    tr = Tracker(TrackingConfig(lift_core_mm=0.0), TouchPointConfig(), scale_mm_per_px=1.0)
    assert _ids_down(_states(tr, _taps(core_between=35.0, frames_between=8))) == [1]


@pytest.mark.parametrize(("core_between", "frames_between"), [
    (20.0, 8),   # a rise of 11 mm: within lift_core_mm
    (35.0, 1),   # a rise for one frame: the median of 3 does not follow it
])
def test_a_small_or_brief_rise_of_the_core_keeps_the_touch(core_between: float,
                                                           frames_between: int) -> None:
    tr = Tracker(TrackingConfig(lift_core_mm=15.0), TouchPointConfig(), scale_mm_per_px=1.0)
    frames = _states(tr, _taps(core_between, frames_between))
    assert _ids_down(frames) == [1]
    assert not any(s == "up" for f in frames for _, s in f)


def test_a_pending_contact_whose_core_rose_gains_no_evidence() -> None:
    """A finger hovering with its tip in the band: a pending contact that has seen its core low
    (the descent) does not go down while the core stays above that level."""
    cfg = TrackingConfig(lift_core_mm=15.0, down_frames=13)
    tr = Tracker(cfg, TouchPointConfig(), scale_mm_per_px=1.0)
    frames = [_tip(3.0, 8.0)] * 11 + [_tip(3.0, 40.0)] * 10
    assert _ids_down(_states(tr, frames)) == []
    tr = Tracker(cfg, TouchPointConfig(), scale_mm_per_px=1.0)
    assert _ids_down(_states(tr, [_tip(3.0, 8.0)] * 21)) == [1]  # the same, core low


def test_lift_core_is_validated() -> None:
    from depthtouch.errors import ConfigError
    with pytest.raises(ConfigError, match="lift_core_mm"):
        TrackingConfig(lift_core_mm=-1.0).validate()


@pytest.mark.parametrize("seed", [0, 1])
def test_the_noise_is_the_median_step_of_the_tracks_core(seed: int) -> None:
    rng = np.random.default_rng(seed)
    values = rng.normal(20.0, 8.0, lift.HISTORY + 40)
    values[rng.random(values.size) < 0.1] = np.nan  # unknown values are skipped
    h = CoreHistory()
    assert h.noise() == 0.0
    known: list[float] = []
    for v in values:
        h.update(float(v))
        if math.isfinite(v):
            known.append(float(v))
        steps = np.abs(np.diff(known))[-lift.HISTORY:]
        assert h.noise() == pytest.approx(float(np.median(steps)) if steps.size else 0.0, abs=1e-9)
    h.reset()
    assert h.noise() == 0.0
    h.update(30.0)
    assert h.noise() == 0.0  # one value: no step yet
    # without keep_noise (the tracker's history when lift_noise_k is 0) no step is kept, and
    # the rise is the same
    off, on = CoreHistory(keep_noise=False), CoreHistory()
    for v in values:
        assert off.update(float(v)) == pytest.approx(on.update(float(v)), nan_ok=True)
    assert off.noise() == 0.0 and not off.steps and on.noise() > 0.0


def _flickering_hold(frames: int = 150, seed: int = 0) -> list[TouchPoints]:
    """A steep finger held still at range: its point moves a pixel now and then, and its core
    (the 3x3 heights there) jumps between the tip (12-25 mm) and the finger rising steeply
    behind it (40-56 mm), for one or two frames at a time."""
    rng = np.random.default_rng(seed)
    cores: list[float] = []
    high = False
    while len(cores) < frames:
        lo, hi = (40.0, 56.0) if high else (12.0, 25.0)
        cores.extend(rng.uniform(lo, hi, int(rng.integers(1, 3))).tolist())
        high = not high
    return [_tip(3.0, c) for c in cores[:frames]]


@pytest.mark.parametrize("seed", [2, 3, 4])
def test_a_held_finger_whose_core_flickers_keeps_its_id_with_the_noise(seed: int) -> None:
    frames = _flickering_hold(seed=seed)
    plain = Tracker(TrackingConfig(lift_core_mm=15.0), TouchPointConfig(), scale_mm_per_px=1.0)
    assert len(_ids_down(_states(plain, frames))) > 3  # the plain test breaks the hold up
    cfg = TrackingConfig(lift_core_mm=15.0, lift_noise_k=1.0)
    tr = Tracker(cfg, TouchPointConfig(), scale_mm_per_px=1.0)
    states = _states(tr, frames)
    assert _ids_down(states) == [1]
    assert not any(s == "up" for f in states for _, s in f)


def test_with_the_noise_two_taps_whose_core_shows_the_lift_are_still_two_touches() -> None:
    cfg = TrackingConfig(lift_core_mm=15.0, lift_noise_k=1.0)
    tr = Tracker(cfg, TouchPointConfig(), scale_mm_per_px=1.0)
    frames = _states(tr, _taps(core_between=35.0, frames_between=8))
    assert _ids_down(frames) == [1, 2]
    assert [k for k, f in enumerate(frames) if any(s == "up" for _, s in f)] == [20 + 3]


def test_lift_noise_k_is_validated() -> None:
    from depthtouch.errors import ConfigError
    with pytest.raises(ConfigError, match="lift_noise_k"):
        TrackingConfig(lift_noise_k=-0.5).validate()


def test_the_noise_allowance_is_for_contacts_down_not_for_pending_ones() -> None:
    """A finger hovering after a flickering descent (core 8 / 28 mm, steps of 20 mm, then 50 mm:
    a rise of about 32 mm, within 15 + 1 x 20): a pending contact keeps the plain test and does
    not go down; a contact already down is kept through the same rise by the allowance."""
    frames = [_tip(3.0, 8.0 if i % 2 else 28.0) for i in range(10)] + [_tip(3.0, 50.0)] * 10
    for k in (0.0, 1.0):
        cfg = TrackingConfig(lift_core_mm=15.0, lift_noise_k=k, down_frames=14)
        assert _ids_down(_states(Tracker(cfg, TouchPointConfig(), scale_mm_per_px=1.0),
                                 frames)) == []
    ups = {}
    for k in (0.0, 1.0):
        cfg = TrackingConfig(lift_core_mm=15.0, lift_noise_k=k, down_frames=3)
        states = _states(Tracker(cfg, TouchPointConfig(), scale_mm_per_px=1.0), frames)
        assert _ids_down(states)[0] == 1
        ups[k] = sum(s == "up" for f in states for _, s in f)
    assert ups == {0.0: 1, 1.0: 0}
