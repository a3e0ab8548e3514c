"""Recall, false touches and position error against the finger's pitch (a check, not a tuning set).

Every scene of the simulator draws its lead finger's angle to the surface at random (20-70 deg
for most); ``render_scene(pitch_deg=...)`` fixes it and leaves the rest of each seed's scene as
it was, so the rows below differ in the pitch alone. The seeds (1001 and up) belong to no suite.
Prints one row per camera placement, hand and pitch, and the pooled rows per pitch.

Run: ``.venv/bin/python benchmarks/pitch_sweep.py [--pitches 30,45,60,70,80] [--seeds 3]
[--scenes taps,approach] [--workers 2]`` (about 8 minutes on 2 cores with the defaults).
"""

from __future__ import annotations

import argparse
import itertools
from collections import defaultdict

from depthtouch.evaluation.metrics import EvalResult
from depthtouch.evaluation.suite import SuiteCase
from depthtouch.evaluation.suiterun import default_workers, run_cases
from depthtouch.evaluation.summary import summarize

#: (camera profile, distance m, tilt deg): the nominal cameras at 1 m, and two of the hard
#: suite's placements (stereo 0.95 m, ToF 1.3 m)
PLACEMENTS = (("realsense-d435", 1.0, 0.0), ("kinect-v2", 1.0, 0.0),
              ("realsense-d435-hard", 0.95, 10.0), ("kinect-v2-hard", 1.3, 0.0))
HANDS = ("capsule", "anatomic")


def _row(name: str, results: list[EvalResult]) -> str:
    m = summarize(results)
    err = "-" if m.error_median_mm != m.error_median_mm else f"{m.error_median_mm:.2f}"
    return (f"| {name} | {m.contacts} | {m.occluded_contacts} | {m.contact_recall:.3f} | "
            f"{m.false_touches} | {sum(m.false_by_hover.get(k, 0) for k in ('25-50', '50+'))} | "
            f"{err} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pitches", default="30,45,60,70,80", help="deg, comma-separated")
    ap.add_argument("--seeds", type=int, default=3, help="seeds per case, from 1001")
    ap.add_argument("--scenes", default="taps,approach")
    ap.add_argument("--workers", type=int, default=None)
    a = ap.parse_args()
    pitches = [float(p) for p in a.pitches.split(",")]
    cases = [SuiteCase(scene, cam, dist, tilt_deg=tilt, seed=1001 + k, hand=hand, pitch_deg=pitch)
             for scene, (cam, dist, tilt), hand, pitch, k in itertools.product(
                 a.scenes.split(","), PLACEMENTS, HANDS, pitches, range(a.seeds))]
    # rendered in memory, not cached: the sweep's recordings belong to no suite
    results = run_cases(cases, workers=a.workers or default_workers())
    by: dict[tuple[str, str, float], list[EvalResult]] = defaultdict(list)
    by_pitch: dict[tuple[str, float], list[EvalResult]] = defaultdict(list)
    for c, res in zip(cases, results, strict=True):
        by[(f"{c.camera} {c.distance_m:g} m", c.hand, c.pitch_deg or 0.0)].append(res)
        by_pitch[(c.hand, c.pitch_deg or 0.0)].append(res)
    head = ("| {} | contacts seen | hidden | recall | false | from hovers >= 25 mm | "
            "error median mm |\n|---|---|---|---|---|---|---|")
    print(f"scenes {a.scenes}, seeds 1001-{1000 + a.seeds}\n")
    print(head.format("placement, hand, pitch"))
    for (place, hand, pitch), res in by.items():
        print(_row(f"{place}, {hand}, {pitch:g} deg", res))
    print()
    print(head.format("all placements: hand, pitch"))
    for (hand, pitch), res in sorted(by_pitch.items()):
        print(_row(f"{hand}, {pitch:g} deg", res))


if __name__ == "__main__":
    main()
