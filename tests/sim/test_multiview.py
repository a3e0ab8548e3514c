"""One scene seen by two cameras 0.8 m apart (parallax, each camera's own noise), truth on the
shared screen (the reference image): the fused touches against each camera alone."""

from __future__ import annotations

import collections

import numpy as np
import pytest

from depthtouch.calibration import Calibration
from depthtouch.errors import ConfigError
from depthtouch.evaluation.multiview import score_views
from depthtouch.evaluation.summary import Metrics
from depthtouch.fusion import view_polygon
from depthtouch.sim.multiview import ViewPose, render_views
from depthtouch.types import TouchEvent

POSES = [ViewPose((-400.0, 0.0, 0.0)), ViewPose((400.0, 0.0, 0.0))]


def _scores(scene: str, poses: list[ViewPose] = POSES
            ) -> tuple[list[Metrics], Metrics, list[TouchEvent]]:
    s = score_views(scene, poses, camera="kinect-v1", seed=1)
    return s.singles, s.fused, s.fused_events


def _one_per_frame(events: list[TouchEvent]) -> bool:
    keys = [(e.frame, e.id) for e in events]
    return len(keys) == len(set(keys))


def test_a_drag_across_the_seam_one_id_no_duplicates_no_worse_than_the_better_camera():
    singles, fused, events = _scores("drags")
    assert fused.id_switches == 0 and fused.false_touches == 0
    cams = collections.defaultdict(set)
    for e in events:
        cams[e.id].add(e.extra["cam"])
    assert {0, 1} in cams.values()  # a drag crossed the seam under one id
    assert fused.frame_recall >= max(s.frame_recall for s in singles)
    assert fused.contact_recall >= max(s.contact_recall for s in singles)
    # measured: singles 1.33 / 1.09 mm, fused 1.30 mm (median; with touchpoints.tip_shift_mm 0,
    # before session 36: 1.38 / 1.25 and 1.38 mm; 1.37 before the landing tested its line on
    # medians of three, which ends it a frame later on a drag from touch-down); the fused drag
    # also covers the frames near each view's edge, seen by the worse camera. (Before the touch
    # point was moved to the surface beneath the tip, the two cameras' opposite parallax
    # cancelled in the fused point: 3.40 / 4.05 -> 1.68.)
    assert fused.error_median_mm <= 1.25 * min(s.error_median_mm for s in singles)
    assert fused.error_median_mm <= max(s.error_median_mm for s in singles)
    assert fused.error_p95_mm <= max(s.error_p95_mm for s in singles)


def test_two_hands_one_in_each_view():
    singles, fused, events = _scores("multitouch")
    assert max(s.contact_recall for s in singles) < 1.0  # neither camera sees both hands
    assert fused.contact_recall == 1.0 and fused.false_touches == 0
    assert fused.id_switches == 0
    assert {e.extra["cam"] for e in events} == {0, 1}


def test_an_arm_hiding_the_overlap_from_one_camera_the_touch_goes_on_with_the_other():
    """``occlude``: the other arm, held high, hides the finger in the overlap from the left
    camera (not from the right one) while it drags, then during a tap."""
    singles, fused, events = _scores("occlude")
    left, right = singles
    assert left.frame_recall < 0.5 and left.contact_recall < 1.0  # the left camera is blind
    assert right.contact_recall == 1.0
    assert fused.contact_recall == 1.0 and fused.frame_recall >= right.frame_recall
    assert fused.id_switches == 0 and fused.false_touches == 0 and _one_per_frame(events)
    assert fused.error_median_mm <= right.error_median_mm
    downs = [e.id for e in events if e.state == "down"]
    assert len(downs) == 2  # the drag (seen by both, then by the right camera alone) and the tap
    assert {e.extra["cam"] for e in events if e.id == downs[0]} == {0, 1}


@pytest.mark.parametrize("poses", [
    # one camera turned 90 deg about its optical axis, the other upside down
    [ViewPose((-400.0, 0.0, 0.0), (0.0, 0.0, 90.0)), ViewPose((400.0, 0.0, 0.0), (0.0, 0.0, 180.0))],
    # upside down, and the other yawed 12 deg toward the middle (a projective map)
    [ViewPose((-400.0, 0.0, 0.0), (0.0, 0.0, 180.0)), ViewPose((400.0, 0.0, 0.0), (0.0, 12.0, 0.0))],
], ids=["rot90-rot180", "rot180-yaw12"])
def test_rotated_cameras_a_drag_across_the_seam_keeps_its_id(poses):
    mv = render_views("taps", poses, camera="kinect-v1", seed=1, noise=False)
    for v in mv.views:  # the calibrations are far from a translation
        corners = view_polygon(Calibration(v.H_to_screen, mv.screen_wh, 0.0), (640, 480))
        assert np.abs(corners[1] - corners[0] - [639.0, 0.0]).max() > 50.0
    singles, fused, events = _scores("drags", poses)
    assert fused.id_switches == 0 and fused.false_touches == 0 and _one_per_frame(events)
    cams = collections.defaultdict(set)
    for e in events:
        cams[e.id].add(e.extra["cam"])
    assert {0, 1} in cams.values()  # a drag crossed the seam under one id
    assert fused.contact_recall >= max(s.contact_recall for s in singles)
    assert fused.frame_recall >= max(s.frame_recall for s in singles)


def test_views_calibrate_exactly_and_refuse_moving_scenes():
    mv = render_views("taps", POSES[:1], camera="kinect-v1", seed=2, noise=False)
    H = mv.views[0].H_to_screen
    # 400 mm to the left at 1 m: the same surface point is 400 * fx / 1000 px further right
    fx = mv.views[0].K[0, 0]
    p = Calibration(H, mv.screen_wh, 0.0).to_screen(np.array([[320.0, 240.0]]))[0]
    assert p == pytest.approx([320.0 - 400.0 * fx / 1000.0, 240.0], abs=1e-6)
    with pytest.raises(ConfigError, match="bump or drift"):
        render_views("bump", POSES, camera="kinect-v1")


def test_cli_sim_views_replay_fused_eval_in_screen(tmp_path, cli):
    """``sim --views 2`` -> ``replay`` of both views fused -> ``eval --space screen``."""
    import json

    out, truth = tmp_path / "views", tmp_path / "truth.json"
    r = cli("sim", "taps", "--views", "2", "--camera", "kinect-v1", "--fps", "15", "--out", out,
            "--truth", truth, "-q")
    assert r.rc == 0, r.err
    fused = tmp_path / "fused.jsonl"
    r = cli("replay", out / "view0.npz", out / "view1.npz", "--calibration",
            out / "view0.calibration.json", "--calibration", out / "view1.calibration.json",
            "--events", fused, "-q")
    assert r.rc == 0, r.err
    r = cli("eval", "--truth", truth, "--events", fused, "--space", "screen", "--json")
    assert r.rc == 0, r.err
    m = next(iter(json.loads(r.out).values()))
    assert m["contact_recall"] == 1.0 and m["false_touches"] == 0 and m["id_switches"] == 0
    # scored by x, y (one camera's pixels each) the same events are wrong
    r = cli("eval", "--truth", truth, "--events", fused, "--json")
    assert next(iter(json.loads(r.out).values()))["frame_recall"] < 0.9
    assert cli("sim", "taps", "--views", "5", "--out", tmp_path / "x", "--truth", truth).rc == 2
