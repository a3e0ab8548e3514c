"""Gesture precision and recall against simulator truth: the matching rules, and a floor on the
presses scene (every press of 0.1-1.0 s gives a tap or a long press)."""

from __future__ import annotations

import numpy as np
import pytest

from depthtouch.evaluation.gestures import (
    NET_LATENCY_S,
    Press,
    run_press_scenes,
    score_gestures,
    truth_presses,
)
from depthtouch.evaluation.metrics import truth_from_dict
from depthtouch.gestures import GestureConfig, GestureEvent
from depthtouch.sim import render_scene


def press(start_s: float, end_s: float, expected: str, xy=(100.0, 100.0)) -> Press:
    return Press(1, start_s, end_s, np.array([xy]), 0.0, expected)


def g(kind: str, t: float, xy=(100.0, 100.0)) -> GestureEvent:
    return GestureEvent(kind, 0, t, (1,), xy[0], xy[1])


@pytest.mark.parametrize(
    ("presses", "gestures", "want"),
    [
        # kind: (found, correct, truth)
        ([press(1.0, 1.2, "tap")], [g("tap", 1.27)], {"tap": (1, 1, 1)}),
        ([press(1.0, 1.2, "tap")], [g("long_press", 1.5)], {"tap": (0, 0, 1),
                                                             "long_press": (1, 0, 0)}),
        ([press(1.0, 1.2, "tap")], [g("tap", 2.0)], {"tap": (1, 0, 1)}),  # too late
        ([press(1.0, 1.2, "tap")], [g("tap", 1.2, (200.0, 100.0))], {"tap": (1, 0, 1)}),  # far
        ([press(1.0, 1.2, "tap")], [g("tap", 1.2), g("tap", 1.3)], {"tap": (2, 1, 1)}),
        ([press(1.0, 2.0, "drag")], [g("drag_start", 1.3), g("drag", 1.4), g("drag_end", 2.1)],
         {"drag": (1, 1, 1)}),
        ([press(1.0, 1.6, "long_press")], [g("double_tap", 1.6)], {"long_press": (0, 0, 1)}),
    ],
)
def test_matching_rules(presses, gestures, want):
    sc = score_gestures(presses, gestures)
    for kind, (found, correct, truth) in want.items():
        assert (sc.found[kind], sc.correct[kind], sc.truth[kind]) == (found, correct, truth), kind


def test_truth_presses_expect_the_convention():
    rec = render_scene("presses", camera="kinect-v2", seed=1, noise=False, fps=30)
    presses = truth_presses(truth_from_dict(rec.truth))
    assert len(presses) == 8
    durations = sorted(p.duration_s for p in presses)
    assert durations[0] <= 0.15 and durations[-1] >= 0.95  # presses of 0.1-1.0 s
    cfg = GestureConfig()
    for p in presses:
        want = "long_press" if p.duration_s >= cfg.long_press_s - NET_LATENCY_S else "tap"
        assert p.expected == want


def test_every_press_gives_a_tap_or_a_long_press():
    scores = run_press_scenes(scenes=("presses",), cameras=("kinect-v2", "realsense-d435"),
                              seeds=(1,))
    s = scores["all"]
    assert s.presses == 16
    assert s.recognised_fraction >= 0.95, s.to_dict()
    assert s.precision("tap") >= 0.9 and s.precision("long_press") >= 0.9, s.to_dict()
