"""Recordings stream: memory stays flat with the length of an `.npz`, stored or compressed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from depthtouch.sources import NpzSource, write_npz

H, W = 480, 640


def _write(path: Path, n: int, compress: bool) -> Path:
    rng = np.random.default_rng(0)
    noise = rng.normal(0, 1.5, (16, H, W))
    # frames are written in chunks through a memory map: the test itself stays small
    raw = np.lib.format.open_memmap(path.with_suffix(".tmp.npy"), "w+", np.uint16, (n, H, W))
    for i in range(0, n, 16):
        k = min(16, n - i)
        raw[i:i + k] = np.rint(1000 + noise[:k]).astype(np.uint16)
    out = write_npz(path, raw, np.arange(n) / 30.0, 0.001, None, compress=compress)
    del raw
    path.with_suffix(".tmp.npy").unlink()
    return out


# VmHWM, not ru_maxrss: that one carries the parent's (pytest's) peak across fork and exec
PEAK = """
import re, sys
from depthtouch.replay import replay
replay(sys.argv[1], surface_frames=30)
print(re.search(r"VmHWM:\\s+(\\d+)", open("/proc/self/status").read()).group(1))
"""


def _peak_mb(path: Path) -> float:
    out = subprocess.run([sys.executable, "-c", PEAK, str(path)], capture_output=True, text=True,
                         check=True, timeout=600)
    return int(out.stdout.strip().splitlines()[-1]) / 1024.0


@pytest.mark.parametrize("compress", [False, True])
def test_memory_is_flat_with_the_length_of_the_recording(tmp_path: Path, compress: bool) -> None:
    short = _write(tmp_path / "short.npz", 120, compress)
    long = _write(tmp_path / "long.npz", 600, compress)  # 369 MB of depth
    grow = _peak_mb(long) - _peak_mb(short)
    # loading the whole array would add the 480 frames' 295 MB
    print(f"peak memory grew {grow:.1f} MB for 480 more frames")
    assert grow < 60.0, f"peak memory grew {grow:.0f} MB for 480 more frames"


@pytest.mark.parametrize("compress", [False, True])
def test_frames_read_back_exactly(tmp_path: Path, compress: bool) -> None:
    rng = np.random.default_rng(1)
    depth = rng.integers(0, 65535, (70, 12, 9), dtype=np.uint16)  # > one release period
    src = NpzSource(write_npz(tmp_path / "r.npz", depth, np.arange(70) / 30.0,
                              compress=compress))
    assert src.compressed == compress and len(src) == 70
    frames = list(src.frames())
    assert [f.index for f in frames] == list(range(70))
    assert all(f.depth.flags.aligned for f in frames)
    np.testing.assert_array_equal(np.stack([f.depth for f in frames]), depth)
