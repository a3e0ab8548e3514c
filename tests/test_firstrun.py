"""The first-run notice: one line on stderr only when the kernels' cache is cold."""

from __future__ import annotations

import io
import os
import subprocess
import sys
from pathlib import Path

from depthtouch import firstrun
from depthtouch.touch import tipkernel


class _Cache:
    def __init__(self, folder: Path, exists: bool) -> None:
        self.cache_path = str(folder)
        index = folder / "k.nbi"
        if exists:
            index.write_bytes(b"")
        self._cache_file = type("F", (), {"_index_path": str(index)})()


class _Kernel:
    def __init__(self, folder: Path, exists: bool) -> None:
        self._cache = _Cache(folder, exists)


def test_notice_only_with_a_cold_cache(tmp_path):
    calls: list[int] = []
    out = io.StringIO()
    assert firstrun.warm_up([lambda: calls.append(1)], [_Kernel(tmp_path, True)], out) is None
    assert out.getvalue() == "" and calls == [1]
    (tmp_path / "x").mkdir()
    took = firstrun.warm_up([lambda: calls.append(2)] * 2, [_Kernel(tmp_path / "x", False)], out)
    assert took is not None and calls == [1, 2, 2]
    text = out.getvalue()
    assert "compiling the touch kernels once" in text and str(tmp_path / "x") in text
    assert len(text.splitlines()) == 2  # the notice, then "compiled (N s)"


def test_unknown_numba_internals_mean_warm(tmp_path):
    assert firstrun.cache_state([object()]) == (False, None)
    cold, folder = firstrun.cache_state([tipkernel._frame_points])  # the real locator works
    assert isinstance(cold, bool) and folder is not None


def test_a_warm_process_prints_nothing():
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    for _ in range(2):  # the first one fills the cache if it was cold
        r = subprocess.run([sys.executable, "-c", "from depthtouch.pipeline import Pipeline; "
                            "Pipeline()"], env=env, capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr
    assert "compiling" not in r.stderr
