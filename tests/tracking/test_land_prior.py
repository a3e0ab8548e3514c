"""A contact's pending points given to the path filter at down (TrackingConfig.land_prior_*)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from depthtouch.config import PipelineConfig, TrackingConfig
from depthtouch.evaluation.filterreplay import record_case
from depthtouch.evaluation.suite import SuiteCase
from depthtouch.tracking.tracker import Tracker
from depthtouch.types import TouchPoints


def _pt(x: float) -> TouchPoints:
    a = np.array([[x, 100.0]])
    return TouchPoints(a, np.array([5.0]), np.array([50]), np.full((1, 2), np.nan))


def _downs(frames: list[float], **kw: object) -> list[tuple[float, float, float]]:
    """The prior points of the contact that goes down over these x positions (px, 1 mm/px),
    one frame each 1/30 s (every frame counts whole: weak_evidence 1)."""
    kw.setdefault("down_frames", 3)
    cfg = TrackingConfig(weak_evidence=1.0, **kw)  # type: ignore[arg-type]
    tr = Tracker(cfg, scale_mm_per_px=1.0)
    for i, x in enumerate(frames):
        for u in tr.update(_pt(x), i / 30):
            if u.state == "down":
                return list(u.track.prior)
    raise AssertionError("no down")


def test_the_pending_points_before_down_are_kept_with_their_times() -> None:
    prior = _downs([10.0, 11.0, 12.0], land_prior_frames=4, land_prior_mm=3.0)
    assert prior == [(10.0, 100.0, 0.0), (11.0, 100.0, pytest.approx(1 / 30))]


def test_only_the_last_ones_within_the_radius_in_a_row() -> None:
    # the first lies 10 mm from the down point: it and all before it are left out
    assert [p[0] for p in _downs([2.0, 11.0, 12.0], land_prior_frames=4,
                                 land_prior_mm=3.0)] == [11.0]
    # at most land_prior_frames of them
    assert [p[0] for p in _downs([12.0, 12.5, 12.0, 12.0], land_prior_frames=1,
                                 land_prior_mm=3.0, down_frames=4)] == [12.0]


def test_off_by_default_and_without_a_scale() -> None:
    assert _downs([10.0, 11.0, 12.0]) == []
    tr = Tracker(TrackingConfig(down_frames=3, weak_evidence=1.0, land_prior_frames=4))
    downs = [u for i in range(3) for u in tr.update(_pt(10.0 + i), i / 30)]
    assert [u.state for u in downs] == ["down"] and downs[0].track.prior == []


@pytest.mark.parametrize("field", ["land_prior_frames", "land_prior_mm"])
def test_out_of_range_is_a_config_error(field: str) -> None:
    from depthtouch.errors import ConfigError

    with pytest.raises(ConfigError, match=f"tracking.{field}"):
        TrackingConfig(**{field: -1}).validate()  # type: ignore[arg-type]


def test_the_filter_gets_them_before_the_down_frame() -> None:
    case = SuiteCase(scene="multitouch", camera="kinect-v2", distance_m=1.0, seed=3)
    on = dataclasses.replace(PipelineConfig(), tracking=dataclasses.replace(
        TrackingConfig(), land_prior_frames=4, land_prior_mm=3.0))
    base, primed = record_case(case), record_case(case, on)
    downs = {e.id: e.t for e in primed.events if e.state == "down"}
    assert downs == {e.id: e.t for e in base.events if e.state == "down"}

    def first_seen(calls: tuple) -> dict[int, list[float]]:
        seen: dict[int, list[float]] = {}
        for c in calls:
            if c[0] == "update":
                for i in c[2].tolist():
                    seen.setdefault(i, []).append(c[1])
        return seen

    before = {i: [t for t in ts if t < downs[i]] for i, ts in first_seen(primed.calls).items()}
    assert all(not [t for t in ts if t < downs[i]] for i, ts in first_seen(base.calls).items())
    # every contact but one that went down on its first frame got 1-4 earlier points, in order
    assert sum(1 <= len(ts) <= 4 for ts in before.values()) >= len(downs) - 1
    assert all(ts == sorted(ts) and len(ts) <= 4 for ts in before.values())
    # and the events, ids and states are the same: only the filter's input grew
    assert [(e.frame, e.id, e.state) for e in primed.events] == \
        [(e.frame, e.id, e.state) for e in base.events]
