"""Why a touch point counted or not toward a new contact (evidence.point_reasons)."""

from __future__ import annotations

import numpy as np
import pytest

from depthtouch.config import TrackingConfig
from depthtouch.tracking.evidence import REASONS, evidence, point_reasons, steep_tips
from depthtouch.types import TouchPoints

CFG = TrackingConfig()
ON_MM = 14.0


def tip(*, height: float = 3.0, area: int = 300, attach_px: int = 6,
        attach_height: float = 40.0, back_spread: float = 30.0, x: float = 100.0
        ) -> TouchPoints:
    """One fingertip at 1 mm per px: hand 40 px behind it, the given measurements."""
    return TouchPoints(np.array([[x, 100.0]]), np.array([height]), np.array([area]),
                       np.array([[x, 140.0]]), attach_px=np.array([attach_px]),
                       attach_height_mm=np.array([attach_height]),
                       back_spread_mm=np.array([back_spread]))


@pytest.mark.parametrize(("kw", "why"), [
    ({}, "counted"),
    ({"height": 20.0}, "tip too high"),
    ({"area": 20}, "weak (size)"),
    ({"attach_px": 200}, "long attachment"),
    ({"attach_height": 95.0}, "high step"),
    ({"back_spread": 3.0}, "level behind"),
    # two tests take its weight away: the first in order names it
    ({"attach_height": 95.0, "back_spread": 3.0}, "high step"),
    ({"attach_px": 200, "attach_height": 95.0, "back_spread": 3.0}, "long attachment"),
])
def test_each_test_names_the_points_it_takes_weight_from(kw: dict, why: str) -> None:
    assert point_reasons(tip(**kw), 1.0, CFG, ON_MM) == [why]


def test_a_point_behind_another_tip_on_its_finger() -> None:
    # the second point lies 20 mm behind a, on a's axis (a's hand is at +y)
    p = TouchPoints(np.array([[100.0, 100.0], [100.0, 120.0]]), np.array([3.0, 3.0]),
                    np.array([300, 300]), np.array([[100.0, 140.0], [100.0, 160.0]]),
                    attach_px=np.array([6, 6]), attach_height_mm=np.array([40.0, 40.0]),
                    back_spread_mm=np.array([30.0, 30.0]))
    assert point_reasons(p, 1.0, CFG, ON_MM) == ["counted", "behind another tip"]


def test_counted_is_a_whole_frame_of_the_trackers_own_weight() -> None:
    """Across random measurements, a point is "counted" exactly when :func:`evidence` gives it
    a whole frame and its tip is low enough, and every reason is one of REASONS."""
    rng = np.random.default_rng(3)
    for _ in range(200):
        n = int(rng.integers(1, 4))
        p = TouchPoints(rng.uniform(0, 200, (n, 2)), rng.uniform(0, 25, n),
                        rng.integers(5, 900, n), rng.uniform(0, 200, (n, 2)),
                        attach_px=rng.integers(0, 120, n),
                        attach_height_mm=rng.uniform(20, 120, n),
                        back_spread_mm=rng.uniform(0, 40, n))
        why = point_reasons(p, 1.0, CFG, ON_MM)
        area = p.area_px.tolist()
        steep = steep_tips(p, area, 1.0, CFG)
        ok_new = [h <= ON_MM or s for h, s in zip(p.height_mm.tolist(), steep, strict=True)]
        w, refused = evidence(p, list(map(tuple, p.xy_px.tolist())), area, ok_new, steep, 1.0,
                              CFG)
        for j in range(n):
            assert why[j] in REASONS
            whole = ok_new[j] and w[j] >= 1.0 and not (refused is not None and refused[j])
            assert (why[j] == "counted") == whole


def test_no_points_no_reasons() -> None:
    assert point_reasons(TouchPoints.empty(), 1.0, CFG, ON_MM) == []
