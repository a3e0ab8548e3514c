"""The hard suite's held-out half (issue 13): floors measured with the default configuration.

The sensor was tuned on the ``tune`` half only (evaluation/halves.py); these are the figures of
the other half, as measured (docs/accuracy.md section 6), with a small margin so that a
regression fails and noise of the last digit does not. Slow: the half is 50 recordings,
rendered once into the suite cache (``.cache/depthtouch``, ~8 minutes on 2 cores), then about
a minute.
"""

from __future__ import annotations

from typing import Any

import pytest

from depthtouch.evaluation.halves import DRIFT_TAG, FAR_TAG, HELD_OUT, figures, select_half
from depthtouch.evaluation.suite import cache_root, load_suite
from depthtouch.evaluation.suiterun import run_cases

pytest.importorskip("depthtouch.sim")

# measured on the held-out half with the defaults (2026-11-24, session 11, 50 recordings since
# the suite got seeds 101 and up: recall 0.917, 2.25 false touches per minute, none from hovers
# >= 25 mm, none later than 2 s after a surface change, 1 id switch, error median 1.48 / p95
# 6.88 mm, jitter 1.13 mm, angle error 3.82 deg over 3-frame steps, recall under drift 0.938,
# touch-down latency median 0 frames; session 14, the landing on medians: jitter 0.922 mm,
# error p95 6.93 mm, angle 3.89 deg, the rest unchanged; then tracking.attach_low_mm: recall
# 0.934, jitter 0.915 mm, p95 6.91 mm, the rest unchanged; session 15, the opening by the
# fingertip's size in pixels: recall 0.946, 0 id switches, p95 7.04 mm, angle 4.07 deg, the rest
# unchanged; session 16, the fingertip's area in pixels at range: 1.12 false touches per minute,
# jitter 0.884 mm, the rest unchanged; session 18, a stereo camera's band without depth counts
# as outside the view: recall 0.970, 1.02 false touches per minute, jitter 0.846 mm, p95
# 6.94 mm, the rest unchanged; session 25, tip_tl_shift 0.6: error 1.42 / 5.01 mm, jitter
# 0.817 mm, angle 3.95 deg, the rest unchanged; session 26, tracking.weak_quiet_evidence 0.25:
# 0.82 false touches per minute, no touch down while its finger was >= 25 mm up (4 before),
# jitter 0.934 mm, the rest unchanged; session 39, the still models in the path filter: jitter
# 0.760 mm, error 1.33 / 4.96 mm, angle 3.94 deg, the rest unchanged; session 44, a forearm's
# flank refused while it is laid down: recall 0.970, 0.72 false touches per minute, jitter
# 0.752 mm, error 1.32 / 4.93 mm, the rest unchanged; session 50, the enclosure test's low
# band: jitter 0.756 mm, error p95 4.89 mm, the rest unchanged); "max" floors are upper
# bounds. Some are short of issue 13's
# targets: they guard against regressions, see docs/accuracy.md.
FLOORS_MIN: dict[str, float] = {"recall_working": 0.965, "recall_drift": 0.93}
FLOORS_MAX: dict[str, float] = {
    "false_per_min": 1.5,
    "false_from_hover_25mm": 0,
    "early_from_hover_25mm": 1,
    "id_switches": 1,
    "error_median_mm": 1.7,
    "error_p95_mm": 7.3,
    "jitter_rms_mm": 0.85,
    "angle_error_deg": 4.3,
    "false_late_after_change": 1,
    "down_latency_median_frames": 1.0,
}


# hard-fresh3 (session 25): the same situations with the simulator's other hand
# (hand="anatomic"), held-out half, measured with the defaults of session 23: recall 0.952,
# 2.04 false touches per minute, 2 of them from hovers >= 25 mm, 2 later than 2 s after a
# surface change, 1 id switch, error median 3.63 / p95 8.86 mm, jitter 1.21 mm, angle error
# 8.40 deg, recall under drift 0.875, touch-down latency median 0; then tip_tl_shift 0.6
# (session 25): error 3.35 / 7.96 mm, jitter 1.23 mm, angle 8.51 deg, the rest unchanged;
# then tracking.weak_quiet_evidence 0.25 (session 26): 1.63 false touches per minute, none from
# hovers >= 25 mm, no touch down while its finger was >= 25 mm up (2 before), 0 id switches,
# error 3.34 / 8.05 mm, the rest unchanged; session 39, the still models: jitter 1.15 mm,
# error 2.53 / 7.54 mm, angle 8.70 deg.
# Worse than hard's on most measures: a thin fingertip loses its front to Tl
# (docs/accuracy.md, session 25). Regression guards, not targets.
FRESH3_MIN: dict[str, float] = {"recall_working": 0.94, "recall_drift": 0.87}
FRESH3_MAX: dict[str, float] = {
    "false_per_min": 2.2,
    "false_from_hover_25mm": 0,
    "early_from_hover_25mm": 1,
    "id_switches": 2,
    "error_median_mm": 3.6,
    "error_p95_mm": 8.4,
    "jitter_rms_mm": 1.25,
    "angle_error_deg": 9.0,
    "false_late_after_change": 2,
    "down_latency_median_frames": 1.0,
}


# hover-tof (session 26): hover-then-tap at ToF 2 m and 1.3 m with both hands, held-out half,
# with tracking.weak_quiet_evidence 0.25: recall 0.972, 0.52 false touches per minute (2.85
# before it), none from hovers >= 25 mm (4 before), 6 touches down while the finger was still
# >= 25 mm up (12 before), error 2.51 / 6.08 mm, 0 id switches, touch-down latency median 0.
HOVER_MIN: dict[str, float] = {"recall_working": 0.95}
HOVER_MAX: dict[str, float] = {
    "false_per_min": 1.0,
    "false_from_hover_25mm": 0,
    "early_from_hover_25mm": 8,
    "id_switches": 1,
    "error_median_mm": 2.8,
    "error_p95_mm": 6.6,
    "down_latency_median_frames": 1.0,
}


# steep (session 31): taps and approaches with the finger at 60 and 70 deg, both hands, held-out
# half, defaults: recall 0.744 (219 contacts), 0.45 false touches per minute, none from hovers
# >= 25 mm, no touch down while its finger was >= 25 mm up, error 2.38 / 5.26 mm, 0 id
# switches, touch-down latency median 2 frames, jitter 0.81 mm. Far short of issue 13's recall:
# the steep tip's crescent is lost to the opening (docs/accuracy.md, session 31). A regression
# guard, and a floor to raise.
STEEP_MIN: dict[str, float] = {"recall_working": 0.72}
STEEP_MAX: dict[str, float] = {
    "false_per_min": 0.8,
    "false_from_hover_25mm": 0,
    "early_from_hover_25mm": 1,
    "id_switches": 1,
    "error_median_mm": 2.6,
    "error_p95_mm": 5.8,
    "down_latency_median_frames": 2.0,
}


# hard with bodies (session 49, `--suite hard --body`: each arm goes on out of the view, as a
# person's does; Suite.with_body), held-out half, defaults: recall 0.982,
# 0.51 false touches per minute, none from hovers >= 25 mm, 1 touch down while its finger was
# >= 25 mm up, none later than 2 s after a surface change, 0 id switches, error 1.36 / 4.99 mm,
# jitter 0.575 mm, angle error 3.93 deg, recall under drift 0.938, touch-down latency median 0;
# session 50, the enclosure test's low band: 0.41 false touches per minute, jitter 0.574 mm.
BODY_MIN: dict[str, float] = {"recall_working": 0.975, "recall_drift": 0.93}
BODY_MAX: dict[str, float] = {
    "false_per_min": 1.0,
    "false_from_hover_25mm": 0,
    "early_from_hover_25mm": 1,
    "id_switches": 1,
    "error_median_mm": 1.6,
    "error_p95_mm": 5.5,
    "jitter_rms_mm": 0.65,
    "angle_error_deg": 4.3,
    "false_late_after_change": 1,
    "down_latency_median_frames": 1.0,
}


def _held_out_figures(name: str = "hard", body: bool = False) -> dict[str, Any]:
    s = load_suite(name).with_body(body)
    cases = select_half(s.cases, HELD_OUT)
    res = run_cases(cases, gate_mm=s.gate_mm, workers=2, cache=cache_root())
    far = [FAR_TAG in s.tags.get(c, frozenset()) for c in cases]
    drift = [DRIFT_TAG in s.tags.get(c, frozenset()) for c in cases]
    return figures(res, far, drift)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "body", "floors_min", "floors_max"), [
    ("hard", False, FLOORS_MIN, FLOORS_MAX),
    ("hard-fresh3", False, FRESH3_MIN, FRESH3_MAX),
    ("hover-tof", False, HOVER_MIN, HOVER_MAX),
    ("steep", False, STEEP_MIN, STEEP_MAX),
    ("hard", True, BODY_MIN, BODY_MAX),
])
def test_held_out_half_meets_the_measured_floors(name: str, body: bool,
                                                 floors_min: dict[str, float],
                                                 floors_max: dict[str, float]) -> None:
    f = _held_out_figures(name, body)
    bad = [f"{k} = {f[k]} < {v}" for k, v in floors_min.items() if f[k] is None or f[k] < v]
    bad += [f"{k} = {f[k]} > {v}" for k, v in floors_max.items() if f[k] is None or f[k] > v]
    assert not bad, "; ".join(bad)
