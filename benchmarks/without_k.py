"""Recordings without intrinsics: a suite's cases run with their frames' K taken away.

K is optional in a recording (docs/formats.md); without it the sensor takes a pinhole camera of
``surface.assumed_hfov_deg`` (default 70 deg) and says so once. This runs a suite's half with K
as recorded and without it at each field of view asked for, and prints issue 13's measures side
by side (the evaluation maps the reported pixels to mm through the truth's own K, so the
figures compare). The suites' cameras have 57.8 (Kinect v1), 70.0 (Kinect v2) and 89.9 deg
(D435).

Run: ``.venv/bin/python benchmarks/without_k.py --suite hard --half tune --hfov 60,70,80``
(recordings from the eval cache, rendered there when missing).
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
from collections.abc import Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from depthtouch.config import PipelineConfig
from depthtouch.evaluation.halves import case_tags, figures, select_half
from depthtouch.evaluation.metrics import EvalResult, evaluate
from depthtouch.evaluation.suite import SuiteCase, cache_root, ensure_recording, load_suite
from depthtouch.evaluation.suiterun import run_source
from depthtouch.evaluation.truth import read_truth
from depthtouch.sources import open_source
from depthtouch.types import Frame

ROWS = ("recall_working", "false_per_min", "false_from_hover_25mm", "error_median_mm",
        "error_p95_mm", "id_switches", "jitter_rms_mm", "angle_error_deg", "recall_drift")


class WithoutK:
    """A source's frames with their intrinsics taken away (the rest as recorded)."""

    def __init__(self, source: Any) -> None:
        self.source = source
        self.depth_scale_m, self.fps = source.depth_scale_m, source.fps
        self.resolution_wh, self.name = source.resolution_wh, source.name
        self.K = None

    def frames(self) -> Iterator[Frame]:
        for f in self.source.frames():
            yield dataclasses.replace(f, K=None)

    def close(self) -> None:
        self.source.close()


def _case(job: tuple[SuiteCase, Sequence[float | None], Path]) -> list[EvalResult]:
    """One case, once per variant (None: K as recorded; a number: no K, that field of view)."""
    case, variants, cache = job
    logging.getLogger("depthtouch").setLevel(logging.ERROR)  # the warning, once per run
    rec, truth_path = ensure_recording(case, cache)
    truth = read_truth(truth_path)
    out = []
    for hfov in variants:
        cfg = PipelineConfig()
        if hfov is not None:
            cfg = dataclasses.replace(
                cfg, surface=dataclasses.replace(cfg.surface, assumed_hfov_deg=hfov))
        with open_source(rec) as src:
            events, timing = run_source(src if hfov is None else WithoutK(src), cfg)
        out.append(evaluate(truth, events, settle_frames=cfg.tracking.down_frames,
                            timing_ms=timing, label=case.label))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--suite", default="hard")
    p.add_argument("--half", default="tune", choices=["tune", "held-out", "all"])
    p.add_argument("--hfov", default="60,70,80", help="fields of view to assume, deg")
    p.add_argument("--workers", type=int, default=2)
    a = p.parse_args(argv)
    suite = load_suite(a.suite)
    cases = select_half(suite.cases, a.half)
    variants: list[float | None] = [None, *(float(v) for v in a.hfov.split(","))]
    cache = cache_root()
    jobs = [(c, variants, cache) for c in cases]
    with ProcessPoolExecutor(max_workers=a.workers) as ex:
        per_case = list(ex.map(_case, jobs))
    far, drift, _ = case_tags(suite, cases)
    cols = [figures([rs[k] for rs in per_case], far, drift) for k in range(len(variants))]
    names = ["K as recorded", *(f"no K, {v:g} deg" for v in variants[1:])]
    print(f"{a.suite}, {a.half} half, {len(cases)} recordings")
    print("| measure | " + " | ".join(names) + " |")
    print("|---|" + "---|" * len(names))
    for key in ROWS:
        print(f"| {key} | " + " | ".join(str(c.get(key)) for c in cols) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
