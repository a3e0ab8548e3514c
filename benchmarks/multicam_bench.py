"""What fusing several cameras costs: the added latency of ``depthtouch merge`` on loopback,
and the fusion's time per frame in a fused replay.

merge: a sender sends a TUIO bundle (two cursors moving, 60 Hz) to the merge, which runs in
this process's thread and forwards to a receiver; the time from send to the merged bundle's
arrival, minus the same path sent straight to the receiver (plain loopback UDP), is the added
latency. fusion: the ``fusion`` share of the per-frame timing of the cut-view replay (the drags
scene cut into two overlapping views, as in tests/test_multicam.py).

Usage: python benchmarks/multicam_bench.py [--frames 600]
"""

from __future__ import annotations

import argparse
import platform
import socket
import sys
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "tests" / "outputs"))

from test_merge import osc_frame  # noqa: E402

from depthtouch.outputs.merge import TuioMerge  # noqa: E402
from depthtouch.outputs.tuio import TuioSink  # noqa: E402


def _recv_socket() -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.settimeout(1.0)
    return s


def merge_latency_ms(frames: int) -> tuple[np.ndarray, np.ndarray]:
    """(added latency per bundle, plain loopback latency per bundle), ms."""
    rx = _recv_socket()
    merge = TuioMerge("127.0.0.1:0", TuioSink("127.0.0.1", rx.getsockname()[1]))
    stop = threading.Event()
    worker = threading.Thread(target=merge.serve, args=(stop,), daemon=True)
    worker.start()
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    via, direct = [], []
    for k in range(frames):
        x = 0.2 + 0.5 * k / frames
        d = osc_frame([1, 2], {1: (x, 0.4), 2: (x, 0.6)}, k + 1, "bench@here")
        t0 = time.perf_counter()
        tx.sendto(d, merge.address)
        rx.recv(65536)
        via.append((time.perf_counter() - t0) * 1e3)
        t0 = time.perf_counter()
        tx.sendto(d, rx.getsockname())
        rx.recv(65536)
        direct.append((time.perf_counter() - t0) * 1e3)
        time.sleep(1 / 60)
    stop.set()
    worker.join(2.0)
    tx.close()
    rx.close()
    return np.array(via) - np.array(direct), np.array(direct)


def fusion_ms() -> tuple[float, float, float]:
    """(median fusion ms, median total ms fused, median total ms single) per frame."""
    from depthtouch.calibration import Calibration
    from depthtouch.driver import drive
    from depthtouch.multicam import MultiPipeline, merge_by_time
    from depthtouch.pipeline import Pipeline
    from depthtouch.sim import render_scene
    from depthtouch.sources.base import ArraySource
    from test_multicam import cut_views

    rec = render_scene("drags", seed=1)
    _, h, w = rec.depth.shape
    srcs, pipes = [], []
    for depth, K, H in cut_views(rec):
        srcs.append(ArraySource(depth, rec.timestamps_s, rec.depth_scale_m, K))
        pipes.append(Pipeline(calibration=Calibration(H, (w, h), 0.0), strict=True))
    fus: list[float] = []

    def keep(r: object) -> None:
        t = r.timing_ms  # type: ignore[attr-defined]
        if "fusion" in t:
            fus.append(t["fusion"])

    stats = drive(merge_by_time(srcs), MultiPipeline(pipes), on_result=keep)
    single = drive(ArraySource.of_recording(rec),
                   Pipeline(calibration=Calibration(np.eye(3), (w, h), 0.0), strict=True))
    return float(np.median(fus)), stats.median_ms, single.median_ms


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=600)
    a = ap.parse_args()
    added, direct = merge_latency_ms(a.frames)
    print(f"machine: {platform.processor() or platform.machine()}, Python "
          f"{platform.python_version()}")
    print(f"merge added latency over loopback: median {np.median(added):.3f} ms, p95 "
          f"{np.percentile(added, 95):.3f} ms, max {added.max():.3f} ms "
          f"(plain loopback median {np.median(direct):.3f} ms; {a.frames} bundles at 60 Hz)")
    f, fused, single = fusion_ms()
    print(f"fusion per camera frame: median {f:.3f} ms; touch path per frame: fused "
          f"{fused:.3f} ms (each camera frame: its pipeline + fusion), single camera "
          f"{single:.3f} ms")


if __name__ == "__main__":
    main()
