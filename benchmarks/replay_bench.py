"""The whole replay, end to end: `depthtouch replay` of a long recording against its first frames.

What a user waits for is not the pipeline alone but the whole command: reading the recording,
the pipeline, the events file. Two recordings of the same frames (640x480, a plane at 1 m with
two fingers drifting over it), 1690 frames (1 GB of depth) and their first 120, are replayed in
fresh processes; the difference of their times over the 1570 extra frames is the marginal cost
of a frame, and the difference of their peak memory shows whether memory grows with the length.
The reference is one OpenCV pass of subtract + band + connected components per frame.
Usage: python benchmarks/replay_bench.py (called by benchmarks/run.py).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from depthtouch.sources import write_npz  # noqa: E402

N_LONG, N_SHORT = 1690, 120
# peak memory from VmHWM: ru_maxrss would carry the parent's peak across fork and exec
RUN = """
import re, sys, time
from depthtouch.replay import replay
t0 = time.perf_counter()
replay(sys.argv[1], surface_frames=45, events_path=sys.argv[2])
hwm = re.search(r"VmHWM:\\s+(\\d+)", open("/proc/self/status").read()).group(1)
print(time.perf_counter() - t0, hwm)
"""


def _recording(folder: Path, n: int, compress: bool) -> Path:
    from run import make_frames

    frames, K = make_frames(640, 480, 2, n_distinct=60)
    empty, touch = frames[:45], frames[45:]
    raw = np.lib.format.open_memmap(folder / "raw.npy", "w+", np.uint16, (n, 480, 640))
    for i in range(n):
        raw[i] = empty[i] if i < 45 else touch[(i - 45) % len(touch)]
    out = write_npz(folder / f"rec{n}{'z' if compress else ''}.npz", raw, np.arange(n) / 30.0,
                    0.001, K, compress=compress)
    del raw
    (folder / "raw.npy").unlink()
    return out


def _replay(path: Path, events: Path) -> tuple[float, float]:
    """(seconds inside replay(), peak memory MB) of a replay in a fresh process (best of 3)."""
    best = (float("inf"), 0.0)
    for _ in range(3):
        out = subprocess.run([sys.executable, "-c", RUN, str(path), str(events)],
                             capture_output=True, text=True, check=True)
        s, kb = out.stdout.split()[-2:]
        best = min(best, (float(s), int(kb) / 1024.0))
    return best


def opencv_pass_ms(n: int = 300) -> float:
    """Median ms of subtract + band (inRange) + connected components on a 640x480 frame, the
    paper's way: the mean of the empty frames as the background, a band of 6-30 mm (4 sigma of
    the 1.5 mm noise above the surface, up to a finger's thickness)."""
    from run import make_frames

    cv2.setNumThreads(1)
    frames, _ = make_frames(640, 480, 2, n_distinct=30)
    bg = np.rint(np.mean(np.stack(frames[:45]).astype(np.float32), axis=0)).astype(np.uint16)
    times = []
    for i in range(n):
        d = frames[45 + i % 30]
        t0 = time.perf_counter()
        h = cv2.subtract(bg, d)
        band = cv2.inRange(h, 6, 30)
        cv2.connectedComponentsWithStats(band, ltype=cv2.CV_16U)
        times.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(times))


def measure() -> dict[str, float]:
    out: dict[str, float] = {"opencv_ms": opencv_pass_ms()}
    with tempfile.TemporaryDirectory(dir=ROOT) as d:
        folder = Path(d)
        for compress, n_long in ((False, N_LONG), (True, 400)):
            tag = "z" if compress else ""
            long = _recording(folder, n_long, compress)
            short = _recording(folder, N_SHORT, compress)
            out[f"size{tag}_mb"] = long.stat().st_size / 2**20
            t_long, m_long = _replay(long, folder / "a.jsonl")
            t_short, m_short = _replay(short, folder / "b.jsonl")
            out[f"n{tag}"] = n_long
            out[f"marginal{tag}_ms"] = (t_long - t_short) / (n_long - N_SHORT) * 1e3
            out[f"peak{tag}_long_mb"], out[f"peak{tag}_short_mb"] = m_long, m_short
            long.unlink()
            short.unlink()
    return out


def section(r: dict[str, float]) -> list[str]:
    return [
        "## The whole replay",
        "",
        f"`depthtouch replay` end to end (reading, pipeline, events file) in a fresh process, best "
        f"of 3: a 640x480 recording with two fingers of {r['n']:.0f} frames "
        f"({r['size_mb']:.0f} MB, stored as `depthtouch record` writes it) against its first "
        f"{N_SHORT}; the same for a compressed recording of {r['nz']:.0f} frames.",
        "",
        "| recording | marginal ms per frame | peak memory, long | peak memory, first 120 |",
        "|---|---|---|---|",
        f"| stored (memory-mapped) | {r['marginal_ms']:.3f} | {r['peak_long_mb']:.0f} MB | "
        f"{r['peak_short_mb']:.0f} MB |",
        f"| compressed (decoded as it plays) | {r['marginalz_ms']:.3f} | "
        f"{r['peakz_long_mb']:.0f} MB | {r['peakz_short_mb']:.0f} MB |",
        "",
        f"One OpenCV pass of subtract + band + connected components takes {r['opencv_ms']:.3f} ms "
        "per 640x480 frame here: the whole replay of a stored recording costs "
        f"{'less' if r['marginal_ms'] < r['opencv_ms'] else 'more'} than that per frame. "
        "Compressed recordings pay the decompression (zlib) of every frame.",
        "",
    ]


if __name__ == "__main__":
    res = measure()
    print("\n".join(section(res)))
