"""Signed position error of the touch points along and across their fingers (a diagnostic).

The suites report the error's size; this splits it into its direction. For every contact frame
of a suite half whose tip the camera sees, the nearest touch point within 20 mm (as reported:
the point plus its forward shift, before tracking and filtering) is compared with the truth,
in mm on the surface: ``along`` its finger (positive: ahead of the contact, away from the hand;
the finger's direction is the sensor's own, from the attached hand to the point) and
``across`` it (positive: to the finger's right as seen in the image, y down). A median far
from 0 is a bias that the tip model leaves, not noise: the ``anatomic`` hand's points lie
1.7-4.5 mm behind their contacts where the capsule hand's lie within 1 mm (docs/accuracy.md,
session 32).

Rows: camera profile, hand model and side (the truth's ``hands``).

Run: ``.venv/bin/python benchmarks/tip_bias.py --suite hard-fresh3 --half tune [--workers 2]``
(recordings come from the suite cache, ``depthtouch eval --suite NAME --cache`` fills it).
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from depthtouch.evaluation.halves import select_half
from depthtouch.evaluation.suite import SuiteCase, ensure_recording, load_suite
from depthtouch.evaluation.suiterun import default_workers
from depthtouch.pipeline import Pipeline
from depthtouch.sources import open_source

#: a touch point farther than this from a contact is not that contact's
MATCH_MM = 20.0

Row = tuple[str, float, float]  # group, along mm, across mm


def case_rows(case: SuiteCase) -> list[Row]:
    """(group, along, across) per seen contact frame of one case with a point near it."""
    rec, truth_path = ensure_recording(case)
    doc = json.loads(truth_path.read_text(encoding="utf-8"))
    sides = {i: h.get("side", "?") for i, h in enumerate(doc.get("hands", []))}
    frames = doc["frames"]
    pipe = Pipeline()
    rows: list[Row] = []
    for i, frame in enumerate(open_source(rec).frames()):
        res = pipe.process(frame)
        p = res.points
        if res.status != "ok" or len(p.area_px) == 0 or i >= len(frames):
            continue
        scale = pipe.surface.bounds.mm_per_px
        shown = p.xy_px + (p.offset_px if p.offset_px is not None else 0.0)
        for c in frames[i]["contacts"]:
            if c.get("occluded"):
                continue
            d = np.hypot(shown[:, 0] - c["x"], shown[:, 1] - c["y"]) * scale
            k = int(d.argmin())
            u = p.xy_px[k] - p.hand_xy_px[k]
            n = float(np.hypot(u[0], u[1]))
            if d[k] > MATCH_MM or not n > 0.0:
                continue
            ux, uy = u / n
            ex, ey = (shown[k] - (c["x"], c["y"])) * scale
            group = f"{case.camera} / {case.hand} / {sides.get(c.get('hand', 0), '?')}"
            rows.append((group, float(ex * ux + ey * uy), float(ux * ey - uy * ex)))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite", default="hard-fresh3")
    ap.add_argument("--half", default="tune", choices=("tune", "held-out", "all"))
    ap.add_argument("--workers", type=int, default=None)
    a = ap.parse_args()
    cases = select_half(load_suite(a.suite).cases, a.half)
    with ProcessPoolExecutor(a.workers or default_workers()) as pool:
        parts = list(pool.map(case_rows, cases))
    by: dict[str, list[tuple[float, float]]] = defaultdict(list)
    for group, along, across in (r for part in parts for r in part):
        by[group].append((along, across))
    print(f"suite {a.suite}, half {a.half}: signed error of the touch points, mm\n")
    print("| camera / hand / side | frames | along median | along p10 / p90 | across median |"
          " distance median |\n|---|---|---|---|---|---|")
    for group in sorted(by):
        v = np.array(by[group])
        p10, p90 = np.percentile(v[:, 0], [10, 90])
        print(f"| {group} | {len(v)} | {np.median(v[:, 0]):+.2f} | {p10:+.2f} / {p90:+.2f} | "
              f"{np.median(v[:, 1]):+.2f} | {np.median(np.hypot(v[:, 0], v[:, 1])):.2f} |")


if __name__ == "__main__":
    main()
