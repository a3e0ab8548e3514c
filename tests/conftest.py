"""Shared fixtures: small seeded recordings on disk and an in-process CLI runner.

Recordings here are 80x60 px (fast) with a 1.5 s empty start at 30 fps followed by one finger
touching for half a second, so that a replay learns the surface and produces events.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from depthtouch.sources import write_png_folder
from synth import Finger, make_recording, write_recording

SMALL_SHAPE = (60, 80)
N_EMPTY = 50  # 50 frames at 30 fps: 1.63 s, more than the default 1.5 s of surface learning
N_TOUCH = 15


@dataclass(frozen=True)
class CliResult:
    """What one in-process ``depthtouch`` call did."""

    rc: int
    out: str
    err: str

    @property
    def err_lines(self) -> list[str]:
        return self.err.splitlines()


@pytest.fixture(scope="session")
def small_arrays() -> tuple[np.ndarray, np.ndarray]:
    """(depth uint16 (65, 60, 80), timestamps (65,)): empty surface, then one touching finger."""
    script = [[Finger(40.0, 20.0)]] * N_TOUCH
    return make_recording(N_EMPTY, script, shape=SMALL_SHAPE, seed=7)


@pytest.fixture
def npz_recording(tmp_path: Path, small_arrays: tuple[np.ndarray, np.ndarray]) -> Path:
    """The small recording as ``rec.npz`` (with K) in a fresh folder."""
    depth, ts = small_arrays
    return Path(write_recording(tmp_path / "rec.npz", depth, ts))


@pytest.fixture
def png_recording(tmp_path: Path, small_arrays: tuple[np.ndarray, np.ndarray]) -> Path:
    """The small recording as a PNG folder ``rec_png/`` (with K and timestamps.txt)."""
    from synth import K_640

    depth, ts = small_arrays
    return write_png_folder(tmp_path / "rec_png", depth, ts, 0.001, K_640)


@pytest.fixture
def cli(capsys: pytest.CaptureFixture[str]) -> Callable[..., CliResult]:
    """Run ``depthtouch ARGS...`` in-process; returns rc, stdout and stderr of that call."""
    from depthtouch.cli import main

    def run(*args: object) -> CliResult:
        capsys.readouterr()  # drop what earlier calls printed
        try:
            rc = main([str(a) for a in args])
        except SystemExit as e:  # argparse's own usage errors
            rc = int(e.code) if isinstance(e.code, int) else 2
        captured = capsys.readouterr()
        return CliResult(rc, captured.out, captured.err)

    return run


def leftovers(folder: Path) -> list[str]:
    """Temporary files a writer may have left behind in ``folder`` (``*.part``, hidden or
    ``tmp*`` names from :mod:`tempfile`)."""
    return sorted(p.name for p in folder.iterdir()
                  if p.name.endswith(".part") or p.name.startswith((".", "tmp")))
