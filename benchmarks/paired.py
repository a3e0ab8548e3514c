"""Two versions of the per-frame path timed in one process, taking turns: a change's cost
without the machine's luck.

On the shared VMs these benchmarks run on, the same code reads very differently from one
process to the next: `make bench`'s 640x480 case with 5 touches read 0.84 and 1.34 ms in two
processes started minutes apart in session 55, the tracking stage (plain Python, no arrays)
0.093 and 0.154 ms, so the whole process runs slower, not one stage. Runs of two versions in
separate processes, even taking turns, compare those processes as much as the code. Here both
versions run in one process: this checkout's ``depthtouch`` (A) and another revision's
``src/depthtouch``, exported with ``git archive`` and imported under the name ``depthtouch_b``
(B; the package imports itself relatively, so it runs as it is). Each has its own pipeline on
the same synthetic frames as ``benchmarks/run.py``, and they take turns in blocks (the order
flipped every round). Reported per stage: the median of each (ms) and, per round, the ratio
of B's block median to A's (median and range over the rounds).

B's kernels compile once into the export (kept in ``.cache/depthtouch/paired/<commit>``).
Usage: python benchmarks/paired.py [--against REV] [--touches 5] [--size 640x480]
[--rounds 20] [--block 60].
"""

from __future__ import annotations

import argparse
import importlib
import io
import shutil
import subprocess
import sys
import tarfile
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))

import run as bench  # noqa: E402

PACKAGE_B = "depthtouch_b"


def export(rev: str, cache: Path) -> tuple[str, Path]:
    """Export ``src/depthtouch`` of revision ``rev`` as the package ``depthtouch_b`` under
    ``cache/<commit>`` (once per commit); returns the commit and the folder to put on
    ``sys.path``."""
    try:
        sha = subprocess.run(["git", "rev-parse", "--verify", f"{rev}^{{commit}}"], cwd=ROOT,
                             check=True, capture_output=True, text=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError) as e:
        raise SystemExit(f"paired: cannot resolve revision {rev!r} in {ROOT} ({e}); "
                         "give a commit, branch or tag of this repository") from e
    where = cache / sha
    pkg = where / PACKAGE_B
    if not (pkg / "__init__.py").is_file():
        tar = subprocess.run(["git", "archive", "--format=tar", sha, "src/depthtouch"], cwd=ROOT,
                             check=True, capture_output=True).stdout
        tmp = where / "tmp"
        shutil.rmtree(tmp, ignore_errors=True)  # what an interrupted export left
        shutil.rmtree(pkg, ignore_errors=True)
        with tarfile.open(fileobj=io.BytesIO(tar)) as tf:
            tf.extractall(tmp, filter="data")
        (tmp / "src" / "depthtouch").rename(pkg)
        shutil.rmtree(tmp)
    return sha, where


def ratios(a_blocks: list[float], b_blocks: list[float]) -> tuple[float, float, float]:
    """B / A of paired block medians: (median, lowest, highest) over the rounds."""
    r = np.asarray(b_blocks, np.float64) / np.asarray(a_blocks, np.float64)
    return float(np.median(r)), float(r.min()), float(r.max())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--against", default="HEAD", help="revision B (default HEAD)")
    ap.add_argument("--touches", type=int, default=5)
    ap.add_argument("--size", default="640x480", help="WxH (default 640x480)")
    ap.add_argument("--rounds", type=int, default=20)
    ap.add_argument("--block", type=int, default=60, help="frames per block")
    a = ap.parse_args(argv)
    try:
        w, h = (int(v) for v in a.size.lower().split("x"))
    except ValueError:
        raise SystemExit(f"paired: --size {a.size!r} is not WxH, e.g. 640x480") from None
    if a.rounds < 2 or a.block < 1 or a.touches < 0:
        raise SystemExit("paired: --rounds must be >= 2, --block >= 1 and --touches >= 0")
    sha, where = export(a.against, ROOT / ".cache" / "depthtouch" / "paired")
    sys.path.insert(0, str(where))
    cv2.setNumThreads(1)
    import depthtouch.pipeline as pipe_a

    pipe_b = importlib.import_module(f"{PACKAGE_B}.pipeline")
    cases = {}
    for name, mod in (("A", pipe_a), ("B", pipe_b)):
        bench.Pipeline = mod.Pipeline  # type: ignore[attr-defined]
        cases[name] = bench.BenchCase(w, h, a.touches)
    samples: dict[str, dict[str, list[float]]] = {n: {s: [] for s in bench.STAGES} for n in cases}
    blocks: dict[str, dict[str, list[float]]] = {n: {s: [] for s in bench.STAGES} for n in cases}
    for r in range(a.rounds):
        for name in ("A", "B") if r % 2 == 0 else ("B", "A"):
            case = cases[name]
            case.samples = {s: [] for s in bench.STAGES}
            case.block(a.block)
            for s in bench.STAGES:
                samples[name][s] += case.samples[s]
                blocks[name][s].append(float(np.median(case.samples[s])))
    print(f"A: this checkout ({ROOT}); B: {a.against} ({sha[:10]}); {w}x{h}, {a.touches} "
          f"touches, {a.rounds} rounds of {a.block} frames each, in one process")
    print(f"{'stage':26s} {'A ms':>8s} {'B ms':>8s}  B/A per round: median [range]")
    for s in bench.STAGES:
        ma, mb = float(np.median(samples["A"][s])), float(np.median(samples["B"][s]))
        med, lo, hi = ratios(blocks["A"][s], blocks["B"][s])
        print(f"{s:26s} {ma:8.3f} {mb:8.3f}  {med:.3f} [{lo:.3f}-{hi:.3f}]")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
