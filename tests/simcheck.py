"""Checks of a simulated recording's truth, shared by the simulator's tests."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from depthtouch.errors import ConfigError
from depthtouch.evaluation.suite import load_suite
from depthtouch.sim import finger_label


def check_contacts_on_fingertips(rec: Any, behind_mm: float) -> int:
    """Every contact projects through K to its (x, y); where it is not occluded the pixel there
    shows its finger, whose deepest pixel within a finger radius lies at most a finger width
    nearer than the contact and at most ``behind_mm`` behind it. Returns the contacts checked
    that way (a noise-free recording with labels)."""
    assert rec.labels is not None
    K = rec.K
    radius = {i: hnd["finger_radius_mm"] for i, hnd in enumerate(rec.truth["hands"])}
    checked = 0
    for fr in rec.truth["frames"]:
        for c in fr["contacts"]:
            assert abs(K[0, 0] * c["X"] / c["Z"] + K[0, 2] - c["x"]) < 0.01
            assert abs(K[1, 1] * c["Y"] / c["Z"] + K[1, 2] - c["y"]) < 0.01
            if c["occluded"]:
                continue
            i, x, y = fr["frame"], int(round(c["x"])), int(round(c["y"]))
            lab = finger_label(c["hand"], c["finger"])
            assert rec.labels[i, y, x] == lab
            r = radius[c["hand"]]
            r_px = max(int(math.ceil(r * K[0, 0] / c["Z"])), 1)
            win = (slice(max(y - r_px, 0), y + r_px + 1), slice(max(x - r_px, 0), x + r_px + 1))
            deepest = float(rec.depth[i][win][rec.labels[i][win] == lab].max())
            assert c["Z"] - 2.0 * r <= deepest <= c["Z"] + behind_mm
            checked += 1
    return checked


def check_suite_group_key(tmp_path: Path, key: str, good: str, want: float, bad: str,
                          error: str) -> None:
    """A one-group suite file whose group sets ``key = good`` gives one case with
    ``key == want``; with ``key = bad`` loading it is a ConfigError matching ``error``."""
    p = tmp_path / "s.toml"
    head = '[suite]\nname = "s"\n[[group]]\nscenes = ["taps"]\ncameras = ["kinect-v2"]\n'
    p.write_text(f"{head}distances_m = [1.0]\n{key} = {good}\n")
    assert [getattr(c, key) for c in load_suite(str(p)).cases] == [want]
    p.write_text(f"{head}distances_m = [1.0]\n{key} = {bad}\n")
    with pytest.raises(ConfigError, match=error):
        load_suite(str(p))
