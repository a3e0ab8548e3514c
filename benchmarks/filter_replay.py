"""Path filter variants compared on a suite half in seconds (depthtouch.evaluation.filterreplay).

The suite half is rendered and run once with a tap in place of the path filter (about 3 minutes
for 50 recordings on 2 cores); every variant then replays the taps' calls, which gives the same
events as a pipeline run with it. Prints still-finger jitter, position error and path angle per
variant, overall and per camera placement.

Run: ``.venv/bin/python benchmarks/filter_replay.py --suite hard --half tune
[--cache] [--records FILE] [--variant '{"name": "adaptive_euro", "params": {"land_sigmas": 8}}' ...]``.
``--records`` keeps the recorded taps in FILE (a pickle, read back if it exists): delete it
when anything before the filter changes.
"""

from __future__ import annotations

import argparse
import json
import pickle
from collections import defaultdict
from pathlib import Path

from depthtouch.config import FilterConfig
from depthtouch.evaluation.filterreplay import TrackRecord, record_cases, replay
from depthtouch.evaluation.halves import placement, select_half
from depthtouch.evaluation.suite import cache_root, load_suite
from depthtouch.evaluation.summary import summarize
from depthtouch.tracking.filters import make_filter


def _records(suite: str, half: str, path: str | None, workers: int | None,
             cache: Path | None) -> list[TrackRecord]:
    if path and Path(path).exists():
        with open(path, "rb") as f:
            return list(pickle.load(f))
    cases = select_half(load_suite(suite).select(None), half)
    records = record_cases(cases, workers=workers, cache=cache)
    if path:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        with open(path, "wb") as f:
            pickle.dump(records, f)
    return records


def _variant(text: str) -> FilterConfig:
    doc = json.loads(text)
    cfg = FilterConfig(doc.get("name", "adaptive_euro"), doc.get("params", {}))
    make_filter(cfg)  # an unknown name or parameter fails here, naming the valid ones
    return cfg


def _fmt(v: float, spec: str) -> str:
    return "-".rjust(int(spec.split(".")[0])) if v != v else format(v, spec)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite", default="hard")
    ap.add_argument("--half", default="tune", choices=("tune", "held-out", "all"))
    ap.add_argument("--records", help="keep / read the recorded taps here (pickle)")
    ap.add_argument("--variant", action="append", default=[],
                    help='a filter as JSON: {"name": ..., "params": {...}} (repeatable)')
    ap.add_argument("--by-placement", action="store_true", help="a row per camera placement")
    ap.add_argument("--workers", type=int)
    ap.add_argument("--cache", action="store_true",
                    help="read the recordings from the suite cache (as depthtouch eval --cache)")
    args = ap.parse_args()
    records = _records(args.suite, args.half, args.records, args.workers,
                       cache_root() if args.cache else None)
    variants = [FilterConfig("none"), FilterConfig()] + [_variant(v) for v in args.variant]
    print(f"{args.suite}, {args.half} half: {len(records)} recordings")
    print(f"{'filter':60s} {'jitter mm':>9s} {'err med':>8s} {'err p95':>8s} {'angle':>6s}")
    for cfg in variants:
        m, results = replay(records, cfg)
        label = cfg.name + (" " + json.dumps(dict(cfg.params)) if cfg.params else "")
        print(f"{label:60s} {_fmt(m.jitter_rms_mm, '9.3f')} {_fmt(m.error_median_mm, '8.2f')} "
              f"{_fmt(m.error_p95_mm, '8.2f')} {_fmt(m.angle_error_deg, '6.2f')}")
        if args.by_placement:
            groups = defaultdict(list)
            for r, res in zip(records, results, strict=True):
                groups[placement(r.case)].append(res)
            for key, rs in sorted(groups.items()):
                g = summarize(rs)
                print(f"  {key:58s} {_fmt(g.jitter_rms_mm, '9.3f')} "
                      f"{_fmt(g.error_median_mm, '8.2f')} {_fmt(g.error_p95_mm, '8.2f')} "
                      f"{_fmt(g.angle_error_deg, '6.2f')}")


if __name__ == "__main__":
    main()
