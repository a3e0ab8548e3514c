"""The path filters compared on full simulated depth frames (not only on point noise).

Every filter, with its default parameters, runs in the whole pipeline on the simulator's drags,
pinch and hold scenes for the three camera profiles at 1 m; the evaluation reports the paper's
angle error, the position error of the filtered touches (lag shows here), and the jitter of a
still finger. Writes the table into docs/filters.md between the markers
``<!-- frames:start -->`` and ``<!-- frames:end -->``.

Run: ``.venv/bin/python benchmarks/filters_on_frames.py [--workers 2]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from depthtouch.config import PipelineConfig
from depthtouch.evaluation.suite import SuiteCase
from depthtouch.evaluation.suiterun import run_grid
from depthtouch.evaluation.summary import summarize
from depthtouch.tracking.filters import FILTERS

ROOT = Path(__file__).resolve().parents[1]
CAMERAS = ("kinect-v2", "realsense-d435", "kinect-v1")
START, END = "<!-- frames:start -->", "<!-- frames:end -->"


def _fmt(v: object) -> str:
    return "–" if v is None or (isinstance(v, float) and v != v) else f"{v:.2f}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=str(ROOT / "docs" / "filters.md"))
    a = ap.parse_args(argv)
    moving = [SuiteCase(s, c, 1.0, seed=1, group="filters") for s in ("drags", "pinch")
              for c in CAMERAS]
    still = [SuiteCase("hold", c, 1.0, seed=1, group="filters") for c in CAMERAS]
    configs = [PipelineConfig().replace(filter={"name": f}) for f in FILTERS]
    res = run_grid(moving + still, configs, workers=a.workers)
    rows = ["| filter | angle error ° (drags, pinch) | error median / p95 mm (moving) | "
            "jitter mm RMS (held still) | frame recall |", "|---|---|---|---|---|"]
    for name, rs in zip(FILTERS, res):
        m = summarize(rs[: len(moving)]).to_dict()
        h = summarize(rs[len(moving):]).to_dict()
        rows.append(f"| {name} | {_fmt(m['angle_error_deg'])} | {_fmt(m['error_median_mm'])} / "
                    f"{_fmt(m['error_p95_mm'])} | {_fmt(h['jitter_rms_mm'])} | "
                    f"{_fmt(m['frame_recall'])} |")
        print(rows[-1], flush=True)
    table = "\n".join(rows)
    out = Path(a.out)
    text = out.read_text(encoding="utf-8") if out.exists() else ""
    block = (f"{START}\n{table}\n\n(`benchmarks/filters_on_frames.py`: drags and pinch for the "
             f"moving columns, hold for jitter; kinect-v2, realsense-d435 and kinect-v1 at 1 m, "
             f"seed 1, 30 fps.)\n{END}")
    if START in text and END in text:
        text = text[: text.index(START)] + block + text[text.index(END) + len(END):]
    else:
        text += "\n## On full depth frames\n\n" + block + "\n"
    out.write_text(text, encoding="utf-8")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
