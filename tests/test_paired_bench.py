"""benchmarks/paired.py: another revision exported as a package of its own, and the ratios."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import paired  # noqa: E402

needs_git = pytest.mark.skipif(
    shutil.which("git") is None or not (ROOT / ".git").exists(),
    reason="needs git and this repository's history")


@needs_git
def test_export_gives_the_revision_as_its_own_package(tmp_path: Path) -> None:
    sha, where = paired.export("HEAD", tmp_path)
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, check=True,
                          capture_output=True, text=True).stdout.strip()
    assert sha == head
    pkg = where / paired.PACKAGE_B
    assert (pkg / "pipeline.py").is_file() and (pkg / "touch" / "tipkernel.py").is_file()
    # the committed file, byte for byte
    committed = subprocess.run(["git", "show", f"{sha}:src/depthtouch/pipeline.py"], cwd=ROOT,
                               check=True, capture_output=True).stdout
    assert (pkg / "pipeline.py").read_bytes() == committed
    # it imports under its own name, beside the installed depthtouch (no compiling needed)
    code = (f"import sys; sys.path.insert(0, {str(where)!r}); "
            f"import {paired.PACKAGE_B}.config as c, depthtouch.config as d; "
            "assert c.__file__ != d.__file__; print(c.PipelineConfig().regions.tu_mm)")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    assert float(out.stdout) > 0
    # a second export of the same commit reuses the folder (a file left in it survives)
    marker = pkg / "left_here.txt"
    marker.write_text("x")
    assert paired.export(sha, tmp_path) == (sha, where)
    assert marker.read_text() == "x"
    # an export interrupted before its package was complete is done again
    (pkg / "__init__.py").unlink()
    assert paired.export(sha, tmp_path) == (sha, where)
    assert (pkg / "__init__.py").is_file() and not marker.exists()
    assert not (where / "tmp").exists()


@needs_git
def test_export_of_an_unknown_revision_says_so(tmp_path: Path) -> None:
    with pytest.raises(SystemExit, match="cannot resolve revision 'no-such-rev'"):
        paired.export("no-such-rev", tmp_path)


def test_ratios_pair_the_blocks_of_each_round() -> None:
    med, lo, hi = paired.ratios([1.0, 2.0, 4.0], [1.1, 1.0, 4.4])
    assert (lo, hi) == pytest.approx((0.5, 1.1))
    assert med == pytest.approx(1.1)


def test_bad_arguments_say_what_to_give() -> None:
    with pytest.raises(SystemExit, match="not WxH"):
        paired.main(["--size", "640by480"])
    with pytest.raises(SystemExit, match="--rounds must be >= 2"):
        paired.main(["--rounds", "1"])
