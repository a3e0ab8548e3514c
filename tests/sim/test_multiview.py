"""One scene seen by two cameras 0.8 m apart (parallax, each camera's own noise), truth on the
shared screen (the reference image): the fused touches against each camera alone."""

from __future__ import annotations

import collections

import numpy as np
import pytest

from depthtouch.calibration import Calibration
from depthtouch.errors import ConfigError
from depthtouch.evaluation.metrics import Metrics, evaluate, summarize, truth_from_dict
from depthtouch.fusion import in_screen
from depthtouch.multicam import MultiPipeline, merge_by_time
from depthtouch.pipeline import Pipeline
from depthtouch.sim.multiview import MultiViewRecording, ViewPose, render_views
from depthtouch.sources.base import ArraySource
from depthtouch.types import TouchEvent

POSES = [ViewPose((-400.0, 0.0, 0.0)), ViewPose((400.0, 0.0, 0.0))]


def _pipe(mv: MultiViewRecording, k: int) -> Pipeline:
    v = mv.views[k]
    return Pipeline(calibration=Calibration(v.H_to_screen, mv.screen_wh, 0.0), strict=True)


def _source(mv: MultiViewRecording, k: int) -> ArraySource:
    v = mv.views[k]
    return ArraySource(v.depth, mv.timestamps_s, 0.001, v.K)


def _run(pipe: object, source: object) -> list[TouchEvent]:
    events: list[TouchEvent] = []
    for frame in source.frames():  # type: ignore[attr-defined]
        events += pipe.process(frame).events  # type: ignore[attr-defined]
    end = pipe.finish()  # type: ignore[attr-defined]
    return events + (end.events if end is not None else [])


def _scores(scene: str) -> tuple[list[Metrics], Metrics, list[TouchEvent]]:
    mv = render_views(scene, POSES, camera="kinect-v1", seed=1)
    truth = truth_from_dict(mv.reference.truth)

    def score(events: list[TouchEvent]) -> Metrics:
        return summarize([evaluate(truth, in_screen(events))])

    singles = [score(_run(_pipe(mv, k), _source(mv, k))) for k in range(2)]
    fused_events = _run(MultiPipeline([_pipe(mv, 0), _pipe(mv, 1)]),
                        merge_by_time([_source(mv, 0), _source(mv, 1)]))
    return singles, score(fused_events), fused_events


def test_a_drag_across_the_seam_one_id_no_duplicates_no_worse_than_the_better_camera():
    singles, fused, events = _scores("drags")
    assert fused.id_switches == 0 and fused.false_touches == 0
    cams = collections.defaultdict(set)
    for e in events:
        cams[e.id].add(e.extra["cam"])
    assert {0, 1} in cams.values()  # a drag crossed the seam under one id
    assert fused.frame_recall >= max(s.frame_recall for s in singles)
    assert fused.contact_recall >= max(s.contact_recall for s in singles)
    assert fused.error_median_mm <= min(s.error_median_mm for s in singles)


def test_two_hands_one_in_each_view():
    singles, fused, events = _scores("multitouch")
    assert max(s.contact_recall for s in singles) < 1.0  # neither camera sees both hands
    assert fused.contact_recall == 1.0 and fused.false_touches == 0
    assert fused.id_switches == 0
    assert {e.extra["cam"] for e in events} == {0, 1}


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
