"""Recordings whose frames move as a whole (sim/breathing.py, render_scene(breathing_mm=))."""

import numpy as np
import pytest

from depthtouch.errors import ConfigError
from depthtouch.evaluation.suite import SuiteCase, load_suite
from depthtouch.evaluation.truth import truth_from_dict
from depthtouch.sim import render_scene
from depthtouch.sim.breathing import breathe, check_breathing, offsets_mm
from simcheck import check_suite_group_key


def test_offsets_are_seeded_wobble_and_jump_at_the_documented_scale():
    assert not offsets_mm(300, 30.0, 0.0, 1).any()
    a, b = offsets_mm(30000, 30.0, 2.0, 5), offsets_mm(30000, 30.0, 2.0, 5)
    assert np.array_equal(a, b) and not np.array_equal(a, offsets_mm(30000, 30.0, 2.0, 6))
    assert 0.7 * 2.0 < a.std() < 1.5 * 2.0
    # jumps: whole frames 2-4 mm off for a while, in both directions, and back again
    far = np.abs(a) > 3.0
    assert 0.03 < far.mean() < 0.3 and (a > 3.0).any() and (a < -3.0).any()
    # the wobble is slow: neighbouring frames differ far less than the offsets do
    step = np.diff(a)
    assert np.median(np.abs(step)) < 0.4 * np.median(np.abs(a))


@pytest.mark.parametrize("bad", [-0.5, 10.5, True, "2", None])
def test_a_bad_scale_is_a_one_line_error(bad):
    with pytest.raises(ConfigError, match=r"breathing .* out of range; allowed \[0, 10\] mm"):
        check_breathing(bad)


@pytest.mark.parametrize("camera, disparity", [("kinect-v2", False), ("realsense-d435", True)])
def test_every_frame_moves_by_its_offset_and_nothing_else_changes(camera, disparity):
    kw = dict(camera=camera, seed=4, resolution_scale=0.5, distance_m=1.2, tilt_deg=25.0)
    full = render_scene("taps", **kw)
    rec = render_scene("taps", breathing_mm=3.0, **kw)
    assert rec.depth.shape == full.depth.shape
    assert np.array_equal(rec.depth == 0, full.depth == 0)  # missing stays missing
    off = np.array([f["global_offset_mm"] for f in rec.truth["frames"]])
    assert np.abs(off).max() > 2.0 and rec.truth["breathing_mm"] == 3.0
    z = full.depth.astype(np.float64)
    moved = rec.depth.astype(np.float64) - z
    ok = full.depth > 0
    for i in range(0, len(off), 7):
        want = off[i] * ((z[i] / 1200.0) ** 2 if disparity else 1.0)
        assert np.abs(moved[i] - want)[ok[i]].max() <= 0.502  # rounding (and the truth to 0.001 mm)
    near, far = z < 1100, z > 1400  # a tilted wall: the far part moves more on a stereo camera
    big = int(np.argmax(np.abs(off)))
    ratio = np.median(moved[big][far[big] & ok[big]]) / np.median(moved[big][near[big] & ok[big]])
    assert bool(ratio > 1.3) == disparity
    assert truth_from_dict(rec.truth) is not None
    for f, g in zip(rec.truth["frames"], full.truth["frames"]):  # the same touches
        assert f["contacts"] == g["contacts"]
    assert "breathing_mm" not in full.truth and breathe(full, 0.0, 4, "tof", 1.2) is full


def test_suites_name_and_render_the_option():
    case = SuiteCase("taps", "kinect-v2", 1.0, seed=3, breathing_mm=2.0)
    assert case.label.endswith("/breathe2/s3")
    assert case.render_kwargs()["breathing_mm"] == 2.0
    assert "breathing_mm" not in SuiteCase("taps", "kinect-v2", 1.0).render_kwargs()
    s = load_suite("hard").with_breathing(1.5)
    assert all(c.breathing_mm == 1.5 for c in s.cases)
    assert load_suite("hard").with_breathing(None).cases == load_suite("hard").cases
    with pytest.raises(ConfigError, match="out of range"):
        load_suite("hard").with_breathing(12.0)


def test_a_suite_group_takes_breathing_mm(tmp_path):
    check_suite_group_key(tmp_path, "breathing_mm", "2.5", 2.5, "11", "breathing_mm")


def test_the_sim_command_writes_a_breathing_recording_and_refuses_it_with_views(tmp_path, capsys):
    from depthtouch.cli import main

    out, truth = tmp_path / "b.npz", tmp_path / "b.json"
    assert main(["sim", "taps", "--camera", "kinect-v2", "--resolution-scale", "0.5",
                 "--breathing-mm", "2", "--out", str(out), "--truth", str(truth), "-q"]) == 0
    import json
    doc = json.loads(truth.read_text())
    assert doc["breathing_mm"] == 2.0 and "global_offset_mm" in doc["frames"][0]
    assert main(["sim", "taps", "--views", "2", "--breathing-mm", "2",
                 "--out", str(tmp_path / "v"), "--truth", str(tmp_path / "v.json")]) == 2
    assert "--breathing-mm applies to one camera" in capsys.readouterr().err
