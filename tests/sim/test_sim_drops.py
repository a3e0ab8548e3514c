"""Recordings with frames the camera never delivered (sim/drops.py, render_scene(drop_rate=))."""

import numpy as np
import pytest

from depthtouch.errors import ConfigError
from depthtouch.evaluation.suite import SuiteCase, load_suite
from depthtouch.evaluation.truth import truth_from_dict
from depthtouch.sim import render_scene
from depthtouch.sim.drops import BURST_P, check_drop_rate, drop_frames, kept_frames


def test_kept_frames_is_seeded_keeps_the_first_and_drops_the_documented_share():
    assert kept_frames(500, 0.0, 3).all()
    a, b = kept_frames(20000, 0.05, 7), kept_frames(20000, 0.05, 7)
    assert np.array_equal(a, b) and a[0]
    assert not np.array_equal(a, kept_frames(20000, 0.05, 8))
    share = 1.0 - a.mean()
    assert share == pytest.approx(0.05 / (1.0 - BURST_P + 0.05), abs=0.01)
    # bursts: some drops come two or more in a row
    edges = np.diff(np.r_[0, (~a).astype(int), 0])
    runs = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)  # lengths of the drops
    assert runs.max() >= 2 and runs.mean() == pytest.approx(1.0 / (1.0 - BURST_P), rel=0.1)


@pytest.mark.parametrize("bad", [-0.01, 0.3, True, "0.1", None])
def test_a_bad_drop_rate_is_a_one_line_error(bad):
    with pytest.raises(ConfigError, match=r"drop rate .* out of range; allowed \[0, 0.2\]"):
        check_drop_rate(bad)


def test_the_frames_left_are_the_full_recordings_and_the_truth_follows_them():
    full = render_scene("taps", camera="kinect-v2", seed=4, resolution_scale=0.5)
    rec = render_scene("taps", camera="kinect-v2", seed=4, resolution_scale=0.5, drop_rate=0.15)
    keep = kept_frames(full.depth.shape[0], 0.15, 4)
    assert 0 < (~keep).sum() == rec.truth["dropped_frames"]
    idx = np.flatnonzero(keep)
    assert np.array_equal(rec.depth, full.depth[idx])
    assert np.array_equal(rec.timestamps_s, full.timestamps_s[idx])
    assert np.diff(rec.timestamps_s).max() * full.fps == pytest.approx(
        np.diff(idx).max())  # the gaps are in the timestamps
    t = truth_from_dict(rec.truth)  # a valid truth document
    assert t is not None
    by_t = {round(f["t"], 6): f for f in full.truth["frames"]}
    for f in rec.truth["frames"]:  # each remaining frame keeps its own contacts and time
        assert f["frame"] < rec.depth.shape[0]
        old = by_t[round(f["t"], 6)]
        assert f["contacts"] == old["contacts"] and keep[old["frame"]]
        assert idx[f["frame"]] == old["frame"]
    assert rec.truth["empty_frames"] == keep[:full.truth["empty_frames"]].sum()
    assert "dropped_frames" not in full.truth  # the full recording is left as it was
    assert drop_frames(full, 0.0, 4) is full


def test_scene_events_move_to_the_first_frame_left_at_or_after_them():
    full = render_scene("object", camera="kinect-v2", seed=2, resolution_scale=0.5)
    assert full.truth["events"]
    rec = drop_frames(full, 0.2, 11)
    keep = kept_frames(full.depth.shape[0], 0.2, 11)
    idx = np.flatnonzero(keep)
    for old, new in zip(full.truth["events"], rec.truth["events"], strict=True):
        assert new["kind"] == old["kind"]
        assert idx[new["frame"]] >= old["frame"]
        assert not keep[old["frame"]:idx[new["frame"]]].any()


def test_a_suite_case_with_drops_names_them_and_a_suite_file_takes_them(tmp_path):
    case = SuiteCase("taps", "kinect-v2", 1.0, seed=3, drop_rate=0.05)
    assert case.label.endswith("/drop0.05/s3")
    assert case.render_kwargs()["drop_rate"] == 0.05
    assert "drop_rate" not in SuiteCase("taps", "kinect-v2", 1.0).render_kwargs()
    s = load_suite("hard").with_drops(0.03)
    assert all(c.drop_rate == 0.03 for c in s.cases)
    p = tmp_path / "d.toml"
    p.write_text('[suite]\nname = "d"\n[[group]]\nscenes = ["taps"]\ncameras = ["kinect-v2"]\n'
                 'distances_m = [1.0]\ndrop_rate = 0.04\n')
    assert load_suite(p).cases[0].drop_rate == 0.04
    p.write_text(p.read_text().replace("0.04", "0.5"))
    with pytest.raises(ConfigError, match="drop_rate"):
        load_suite(p)
