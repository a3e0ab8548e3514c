"""The shape checks of the value types that cross stage boundaries."""

from __future__ import annotations

import numpy as np
import pytest

from depthtouch.types import TouchPoints


def _points(n: int = 3, **over: np.ndarray) -> TouchPoints:
    parts = dict(xy_px=np.zeros((n, 2)), height_mm=np.zeros(n), area_px=np.zeros(n, np.int64),
                 hand_xy_px=np.zeros((n, 2)))
    parts.update(over)
    return TouchPoints(**parts)


def test_parallel_arrays_of_one_length_are_taken() -> None:
    p = _points(3, attach_share=np.zeros(3), offset_px=np.zeros((3, 2)))
    assert len(p) == 3
    assert len(p[np.array([True, False, True])]) == 2
    assert len(TouchPoints.empty()) == 0


@pytest.mark.parametrize(("over", "match"), [
    ({"xy_px": np.zeros((3, 3))}, r"TouchPoints\.xy_px: expected shape \(_, 2\), got \(3, 3\)"),
    ({"xy_px": np.zeros(3)}, r"TouchPoints\.xy_px: expected shape \(_, 2\), got \(3,\)"),
    ({"height_mm": np.zeros(2)}, r"TouchPoints\.height_mm: expected shape \(3\), got \(2,\)"),
    ({"height_mm": np.zeros((3, 1))}, r"TouchPoints\.height_mm: expected shape \(3\)"),
    ({"hand_xy_px": np.zeros((3, 1))}, r"TouchPoints\.hand_xy_px: expected shape \(3, 2\)"),
    ({"offset_px": np.zeros((4, 2))}, r"TouchPoints\.offset_px: expected shape \(3, 2\)"),
    ({"recent_change_mm": np.zeros(4)}, r"TouchPoints\.recent_change_mm: expected shape \(3\)"),
])
def test_a_mismatched_array_is_named(over: dict[str, np.ndarray], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        _points(3, **over)
