"""Several cameras in the one loop: one simulated recording cut into two overlapping views (two
cameras with the same viewpoint), each calibrated back to the original image, replayed fused,
gives the touches of the single recording; merged sources; the CLI's checks."""

from __future__ import annotations

import collections
import threading
from pathlib import Path

import numpy as np
import pytest

from depthtouch.calibration import Calibration, save_calibration
from depthtouch.cli import main
from depthtouch.evaluation.metrics import evaluate, truth_from_dict
from depthtouch.evaluation.summary import Metrics, summarize
from depthtouch.fusion import in_screen
from depthtouch.multicam import CameraFrame, MultiPipeline, merge_by_time
from depthtouch.multilive import LiveMerge, NewestPerCamera
from depthtouch.outputs.jsonl import read_events
from depthtouch.pipeline import Pipeline
from depthtouch.sim import render_scene
from depthtouch.sources import write_npz
from depthtouch.sources.base import ArraySource
from depthtouch.sources.camera import CameraStream
from depthtouch.types import StreamGap, TouchEvent

SEAM_X, HALF_OVERLAP_PX = 400, 30  # the drags scene's paths cross x = 400


def cut_views(rec: object, seam_x: int = SEAM_X, half: int = HALF_OVERLAP_PX
              ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(depth, K, H to the original image) of the left and right view: columns [0, seam + half)
    and [seam - half, W); the right view's principal point moves left by its offset."""
    depth, K = rec.depth, rec.K  # type: ignore[attr-defined]
    off = seam_x - half
    k_right = K.copy()
    k_right[0, 2] -= off
    shift = np.array([[1.0, 0.0, off], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    return [(np.ascontiguousarray(depth[:, :, :seam_x + half]), K.copy(), np.eye(3)),
            (np.ascontiguousarray(depth[:, :, off:]), k_right, shift)]


def metrics(rec: object, events: list[TouchEvent]) -> Metrics:
    truth = truth_from_dict(rec.truth)  # type: ignore[attr-defined]
    return summarize([evaluate(truth, in_screen(events))])


def replay_single(rec: object) -> list[TouchEvent]:
    """The events of the whole recording, one camera, screen = its own image."""
    n, h, w = rec.depth.shape  # type: ignore[attr-defined]
    p = Pipeline(calibration=Calibration(np.eye(3), (w, h), 0.0), strict=True)
    events: list[TouchEvent] = []
    for frame in ArraySource.of_recording(rec).frames():
        events += p.process(frame).events
    end = p.finish()
    return events + (end.events if end is not None else [])


def assert_same_touches(single: Metrics, fused: Metrics) -> None:
    assert fused.contact_recall >= single.contact_recall - 0.02
    assert fused.frame_recall >= single.frame_recall - 0.02
    assert fused.false_touches <= single.false_touches + 1
    assert fused.id_switches <= single.id_switches + 1


def test_cut_views_replayed_fused_give_the_single_recordings_touches(tmp_path: Path) -> None:
    """The required end-to-end test; the fused replay through the command line."""
    rec = render_scene("drags", seed=1)
    n, h, w = rec.depth.shape
    args = []
    for name, (depth, K, H) in zip("ab", cut_views(rec)):
        write_npz(tmp_path / f"{name}.npz", depth, rec.timestamps_s, rec.depth_scale_m, K,
                  compress=False)
        save_calibration(Calibration(H, (w, h), 0.0), tmp_path / f"{name}.json")
        args += [str(tmp_path / f"{name}.npz")]
    assert main(["replay", *args, "--calibration", str(tmp_path / "a.json"), "--calibration",
                 str(tmp_path / "b.json"), "--events", str(tmp_path / "fused.jsonl"), "-q"]) == 0
    for name in "ab":
        (tmp_path / f"{name}.npz").unlink()
    single_events = replay_single(rec)
    single = metrics(rec, single_events)
    fused_events = list(read_events(tmp_path / "fused.jsonl"))
    fused = metrics(rec, fused_events)
    assert single.contact_recall > 0.9  # the scene is a fair test
    assert_same_touches(single, fused)
    # the drags crossed the seam: some touch was seen by both cameras, under one id
    cams = collections.defaultdict(set)
    for e in fused_events:
        cams[e.id].add(e.extra["cam"])
    assert {0, 1} in cams.values()
    assert fused.id_switches == 0
    # each id appears at most once per frame (cameras in step: one fused update per instant)
    keys = [(e.frame, e.id) for e in fused_events]
    assert len(keys) == len(set(keys))


def test_two_hands_one_in_each_view() -> None:
    rec = render_scene("multitouch", seed=1)  # fingers near x = 285 and x = 560
    n, h, w = rec.depth.shape
    sources, pipes = [], []
    for depth, K, H in cut_views(rec):
        sources.append(ArraySource(depth, rec.timestamps_s, rec.depth_scale_m, K))
        pipes.append(Pipeline(calibration=Calibration(H, (w, h), 0.0), strict=True))
    multi = MultiPipeline(pipes)
    events: list[TouchEvent] = []
    for frame in merge_by_time(sources).frames():
        events += multi.process(frame).events  # type: ignore[arg-type]
    tail = multi.finish()
    events += tail.events if tail is not None else []
    single_events = replay_single(rec)
    assert_same_touches(metrics(rec, single_events), metrics(rec, events))
    assert {e.extra["cam"] for e in events} == {0, 1}
    downs = [e for e in events if e.state == "down"]
    assert len({e.id for e in events}) == len(downs)  # every id went down once


def test_a_lost_camera_ends_only_the_touches_it_alone_saw() -> None:
    """Camera 0 sees the whole image, camera 1 its right part (x >= 340): the hand near
    x = 560 is seen by both, the one near x = 285 by camera 0 alone. Camera 0 is unplugged
    (a gap in the one loop) while both are down: the left touch ends, the right one goes on
    under its id with camera 1; camera 0, back, joins it again."""
    from depthtouch.driver import drive
    from depthtouch.types import FrameResult

    rec = render_scene("multitouch", seed=1)
    n, h, w = rec.depth.shape
    off = 340
    k_right = rec.K.copy()
    k_right[0, 2] -= off
    shift = np.array([[1.0, 0.0, off], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    sources = [ArraySource.of_recording(rec),
               ArraySource(np.ascontiguousarray(rec.depth[:, :, off:]), rec.timestamps_s,
                           rec.depth_scale_m, k_right)]
    multi = MultiPipeline([Pipeline(calibration=Calibration(np.eye(3), (w, h), 0.0),
                                    strict=True),
                           Pipeline(calibration=Calibration(shift, (w, h), 0.0), strict=True)])
    results: list[FrameResult] = []
    down: dict[int, int] = {}  # fused id -> instants it has been down (one result each)
    sx: dict[int, float] = {}  # fused id -> its last sx

    def seen(r: FrameResult) -> None:
        results.append(r)
        for e in r.events:
            if e.state == "up":
                down.pop(e.id, None)
            else:
                down[e.id] = down.get(e.id, 0) + 1
                sx[e.id] = e.extra["sx"]

    def both_hands() -> bool:
        settled = [i for i, k in down.items() if k >= 5]
        return any(sx[i] < off for i in settled) and any(sx[i] > off + 60 for i in settled)

    class WithGap:
        gap_at: int | None = None

        def frames(self):  # type: ignore[no-untyped-def]
            for f in merge_by_time(sources).frames():
                if self.gap_at is None and both_hands():
                    self.gap_at = len(results)
                    yield StreamGap("camera 0: unplugged", cam=0)
                yield f

    src = WithGap()
    drive(src, multi, [], on_result=seen)
    assert src.gap_at is not None
    before = {e.id: e for r in results[:src.gap_at] for e in r.events}
    gap = results[src.gap_at]
    assert gap.status == "ended"
    live = [i for i, e in before.items() if e.state != "up"]
    left = {i for i in live if before[i].extra["sx"] < off}
    right = {i for i in live if before[i].extra["sx"] > off + 60}
    assert left and right
    assert {(e.id, e.state) for e in gap.events} == {(i, "up") for i in left}  # camera 0's alone
    for i in right:  # seen by both: the same id goes on with camera 1
        after = [e for r in results[src.gap_at + 1:] for e in r.events if e.id == i]
        assert after[0].state == "move" and after[0].extra["cam"] == 1
        assert [e.state for e in after].count("up") == 1 and after[-1].state == "up"
    assert any(e.extra["cam"] == 0 for r in results[src.gap_at + 1:] for e in r.events
               if e.id in right)  # camera 0, back, joins them again


def test_merged_sources_are_in_time_order_with_instants_counted() -> None:
    d = np.zeros((3, 4, 4), np.uint16)
    a = ArraySource(d, np.array([0.0, 0.1, 0.2]))
    b = ArraySource(d, np.array([0.05, 0.1, 0.3]))
    got = [(f.cam, f.timestamp_s, f.index, f.last_of_instant)  # type: ignore[union-attr]
           for f in merge_by_time([a, b]).frames()]
    assert got == [(0, 0.0, 0, True), (1, 0.05, 1, True), (0, 0.1, 2, False),
                   (1, 0.1, 2, True), (0, 0.2, 3, True), (1, 0.3, 4, True)]


def test_live_merge_tags_frames_by_camera_in_arrival_order() -> None:
    d = np.zeros((20, 4, 4), np.uint16)
    stop = threading.Event()
    streams = [CameraStream(lambda: ArraySource(d, np.arange(20) / 30.0), stop=stop)
               for _ in range(2)]
    frames = list(LiveMerge(streams, stop).frames())
    assert all(isinstance(f, CameraFrame) for f in frames)
    assert {f.cam for f in frames} == {0, 1}  # type: ignore[union-attr]
    ts = [f.timestamp_s for f in frames]  # type: ignore[union-attr]
    assert ts == sorted(ts)
    assert [f.index for f in frames] == list(range(len(frames)))  # type: ignore[union-attr]


def test_newest_per_camera_keeps_a_gap_and_takes_the_earliest() -> None:
    box = NewestPerCamera(2)
    box.put(0, 1.0, "a1")
    box.put(0, 2.0, "a2")  # replaces a1
    box.put(1, 1.5, StreamGap("lost"))
    box.put(1, 2.5, "b1")  # the gap is kept, b1 dropped
    assert box.dropped == 2
    assert box.get(0.0) == (1, StreamGap("lost"))
    assert box.get(0.0) == (0, "a2")
    assert box.get(0.0) is None
    box.finish(0)
    box.finish(1)
    assert box.get(0.0)[0] == -1  # type: ignore[index]


@pytest.mark.parametrize("argv, match", [
    (["replay", "A.npz", "B.npz", "--calibration", "a.json"], "one --calibration per source"),
    (["replay", "A.npz", "B.npz", "--calibration", "a.json", "--calibration", "b.json",
      "--surface", "s.npz"], "--surface applies to one camera"),
    (["run", "--source", "sim:taps", "--source", "sim:drags"], "one --calibration per source"),
])
def test_cli_several_sources_one_line_errors(argv, match, capsys) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1


def test_calibrations_must_share_the_screen() -> None:
    from depthtouch.errors import ConfigError

    pipes = [Pipeline(calibration=Calibration(np.eye(3), wh, 0.0)) for wh in ((640, 480),
                                                                               (800, 600))]
    with pytest.raises(ConfigError, match="same screen"):
        MultiPipeline(pipes)
    with pytest.raises(ConfigError, match="no calibration"):
        MultiPipeline([Pipeline()])


def test_run_two_sources_fuses_live(tmp_path: Path, npz_recording: Path, cli) -> None:
    """``run`` with two sources (the same small recording twice, played at its own pace as two
    cameras would deliver it, each calibrated to the same screen): one finger, one touch."""
    cal = save_calibration(Calibration(np.eye(3), (80, 60), 0.0), tmp_path / "cal.json")
    out = tmp_path / "live.jsonl"
    r = cli("run", "--source", npz_recording, "--source", npz_recording, "--calibration", cal,
            "--calibration", cal, "--events", out, "-q")
    assert r.rc == 0, r.err
    events = list(read_events(out))
    assert {e.id for e in events} == {1}
    assert [e.state for e in events].count("down") == 1 and events[-1].state == "up"
    assert {e.extra["cam"] for e in events} <= {0, 1}


def test_run_two_sources_with_the_web_page(tmp_path: Path, npz_recording: Path, cli) -> None:
    """``run --serve`` takes several sources: the page (each camera's part) beside the outputs."""
    cal = save_calibration(Calibration(np.eye(3), (80, 60), 0.0), tmp_path / "cal.json")
    out = tmp_path / "live.jsonl"
    r = cli("run", "--source", npz_recording, "--source", npz_recording, "--calibration", cal,
            "--calibration", cal, "--serve", "127.0.0.1:0", "--events", out, "-q")
    assert r.rc == 0, r.err
    assert {e.id for e in read_events(out)} == {1}
