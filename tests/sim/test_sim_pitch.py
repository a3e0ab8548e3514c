"""A fixed finger pitch (``render_scene(pitch_deg=...)``, ``depthtouch sim --pitch``): every lead
finger at that angle, the rest of the seed's scene unchanged."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from depthtouch.cli import main
from depthtouch.errors import ConfigError
from depthtouch.sim import ALL_SCENES, MULTIVIEW_SCENES, load_truth, render_scene
from depthtouch.sim.cameras import get_profile
from depthtouch.sim.geometry import Rays, make_surface
from depthtouch.sim.scenes import SceneContext, build_script

FPS = 4.0


def _script(scene: str, seed: int, pitch_deg: float | None):
    prof = get_profile("realsense-d435")
    surf = make_surface("plane", 1.0, 0.0)
    ctx = SceneContext(surf, Rays(prof.K, prof.resolution_wh), np.random.default_rng(seed),
                       pitch_deg=pitch_deg)
    return build_script(scene, ctx)


def _pitches(script) -> set[float]:
    out = set()
    for hand in script.hands:
        for t in np.linspace(hand.track.start_s, hand.track.end_s, 25):
            pose = hand.pose(float(t))
            if pose is not None:
                out.add(round(float(pose[2]), 6))
    return out


@pytest.mark.parametrize("scene", [s for s in ALL_SCENES if s not in MULTIVIEW_SCENES])
def test_every_scene_takes_the_fixed_pitch_and_keeps_the_rest(scene: str) -> None:
    drawn, fixed = _script(scene, 3, None), _script(scene, 3, 77.0)
    assert drawn.duration_s == fixed.duration_s
    assert len(drawn.hands) == len(fixed.hands)
    for a, b in zip(drawn.hands, fixed.hands, strict=True):
        assert a.shape == b.shape and a.fingers == b.fingers
        for t in np.linspace(a.track.start_s, a.track.end_s, 25):
            pa, pb = a.pose(float(t)), b.pose(float(t))
            assert (pa is None) == (pb is None)
            if pa is not None and pb is not None:
                assert pa[0] == pb[0] and pa[1] == pb[1]  # targets, gaps and yaw
    if drawn.hands:
        assert _pitches(fixed) == {77.0}
        assert 77.0 not in _pitches(drawn)


def test_render_scene_with_a_fixed_pitch_keeps_the_truths_timing() -> None:
    a = render_scene("taps", seed=5, fps=FPS, noise=False)
    b = render_scene("taps", seed=5, fps=FPS, noise=False, pitch_deg=75.0)
    assert a.depth.shape == b.depth.shape
    assert not np.array_equal(a.depth, b.depth)  # the finger stands steeper
    frames = [[(c["id"], c["x"], c["y"]) for c in f["contacts"]] for f in a.truth["frames"]]
    assert frames == [[(c["id"], c["x"], c["y"]) for c in f["contacts"]]
                      for f in b.truth["frames"]]


@pytest.mark.parametrize("bad", [5.0, 90.0, float("nan"), "60"])
def test_render_scene_refuses_a_pitch_out_of_range(bad: object) -> None:
    with pytest.raises(ConfigError, match=r"pitch_deg .* is out of range; allowed \[10, 85\]"):
        render_scene("taps", fps=FPS, pitch_deg=bad)  # type: ignore[arg-type]


def test_cli_sim_pitch(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out, truth = tmp_path / "a.npz", tmp_path / "a.truth.json"
    assert main(["sim", "taps", "--out", str(out), "--truth", str(truth), "--pitch", "65",
                 "--fps", str(FPS), "-q"]) == 0
    assert load_truth(truth)["frames"]
    bad = tmp_path / "b.npz"
    assert main(["sim", "taps", "--out", str(bad), "--truth", str(tmp_path / "b.json"),
                 "--pitch", "88", "--fps", str(FPS)]) == 2
    err = capsys.readouterr().err
    assert "pitch_deg 88.0 is out of range" in err and err.count("\n") == 1
    assert not bad.exists()
    assert main(["sim", "cross", "--out", str(tmp_path / "v"), "--truth",
                 str(tmp_path / "v.json"), "--views", "2", "--pitch", "50", "--fps", "2"]) == 2
    assert "--pitch applies to one camera" in capsys.readouterr().err
