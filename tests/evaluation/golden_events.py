"""Digests of the sensor's outputs on the default suite: the reference the restructuring (and
any later change that must not change what the sensor reports) is compared with.

``python tests/evaluation/golden_events.py --write`` regenerates ``tests/golden/default_suite_
events.json`` (do it only for a change that is meant to change the events, and say so). For every
case of the default suite it keeps the SHA-256 of the JSON Lines events file that a replay with
a fixed screen calibration writes (so ``sx``, ``sy``, ``X``, ``Y``, ``Z`` are covered), and the
number of events.

The digests were made with the settings of that time; :data:`SETTINGS` gives them back (the
later touch-down by evidence off, the paper's adaptive filter), so that the comparison checks
the machinery, not the tuning that came after.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

GOLDEN = Path(__file__).parent.parent / "golden" / "default_suite_events.json"
#: the defaults of the restructuring's time, as overrides of today's
SETTINGS = {"tracking": {"weak_evidence": 1.0, "attach_max_mm": 0.0, "step_max_mm": 0.0,
                         "flat_max_mm": 0.0, "behind_lat_mm": 0.0, "pending_gap_frames": 0,
                         "pending_low_mm": 0.0, "steep_evidence": 0.0, "lift_core_mm": 0.0,
                         "yield_ratio": 0.0, "report_dir_weight": 1.0, "doubt_frames": 0,
                         "enclosed_share_max": 1.0, "up_held_frames": 0},
            "touchpoints": {"tip_tl_shift": 0.0, "tip_shift_mm": 0.0, "tip_beside_px": 1000.0},
            "regions": {"open_tip_px": 4.0, "block_tip_px": 4.0, "open_band_px": 0.0},
            "filter": {"name": "adaptive"}, "adapt": {"drift_gain": 0.0, "edge_outside": False}}
#: depth px -> screen px: a mild projective map onto a 1920x1080 screen
H = np.array([[3.1, 0.12, -40.0], [-0.05, 2.3, 25.0], [1.0e-5, 2.0e-5, 1.0]])


def case_digest(case: object) -> dict[str, object]:
    """The digests (see :func:`digests`) of one suite case's events."""
    from depthtouch.calibration import Calibration
    from depthtouch.sim import render_scene

    rec = render_scene(case.scene, **case.render_kwargs())  # type: ignore[attr-defined]
    cal = Calibration(H, (1920, 1080), 0.0)
    return digests([e.to_dict() for e in run_events(rec, cal)])


def digests(events: list[dict]) -> dict[str, object]:
    """The number of events and the SHA-256 of their JSON lines, with every field and without
    X, Y, Z (camera coordinates, which since the restructuring come from the adapted surface,
    not the surface as first learned)."""
    def sha(rows: list[dict]) -> str:
        text = "\n".join(json.dumps(r, separators=(", ", ": ")) for r in rows)
        return hashlib.sha256(text.encode()).hexdigest()

    no_xyz = [{k: v for k, v in e.items() if k not in ("X", "Y", "Z")} for e in events]
    return {"events": len(events), "sha256": sha(events), "sha256_no_xyz": sha(no_xyz)}


def run_events(rec: object, cal: object) -> list:
    """The events of a replay of a simulated recording with a calibration."""
    try:  # after the restructuring: the one driver
        from depthtouch import Pipeline, drive
        from depthtouch.sources import ArraySource

        collected: list = []

        class Collect:
            def send(self, result: object) -> None:
                collected.extend(result.events)  # type: ignore[attr-defined]

            def close(self) -> None:
                pass

        from depthtouch import PipelineConfig

        config = PipelineConfig().replace(**SETTINGS)
        drive(ArraySource.of_recording(rec), Pipeline(config, calibration=cal, strict=True),
              [Collect()])
        return collected
    except ImportError:  # before it
        from depthtouch.pipeline import Pipeline as OldPipeline
        from depthtouch.types import Frame

        pipe = OldPipeline(calibration=cal, strict=True)
        out: list = []
        for i in range(rec.depth.shape[0]):  # type: ignore[attr-defined]
            f = Frame(rec.depth[i], float(rec.timestamps_s[i]), i,  # type: ignore[attr-defined]
                      rec.depth_scale_m, rec.K)  # type: ignore[attr-defined]
            out.extend(pipe.process(f))
        out.extend(pipe.finish())
        return out


def suite_cases() -> list:
    from depthtouch.evaluation.suite import load_suite

    return load_suite("default").select()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--write", action="store_true", help="write the golden file")
    a = p.parse_args(argv)
    out = {}
    for case in suite_cases():
        out[case.label] = case_digest(case)
        print(case.label, out[case.label], file=sys.stderr)
    if a.write:
        GOLDEN.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
