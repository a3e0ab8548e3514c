"""The simulator's second hand model (``hand="anatomic"``): its shape, its truth, its plumbing."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from depthtouch.cli import main
from depthtouch.errors import ConfigError
from depthtouch.evaluation.suite import SuiteCase, load_suite, suite_from_dict
from depthtouch.sim import HARD_SCENES, finger_label, load_truth, render_scene
from depthtouch.sim.cameras import get_profile
from depthtouch.sim.geometry import Capsule, Rays, make_surface
from depthtouch.sim.hand import FingerTarget, HandShape, build_hand
from depthtouch.sim.render import assemble_scene
from depthtouch.sim.scenes import SceneContext, build_script
from simcheck import check_contacts_on_fingertips

FPS = 10.0


def _pose(shape: HandShape, gap_mm: float, pitch_deg: float = 40.0
          ) -> tuple[list[Capsule], list[Capsule]]:
    """The index finger's capsules and the others', the tip over (0, 0) of a plane at 1 m."""
    surf = make_surface("plane", 1.0, 0.0)
    prims, _ = build_hand(shape, (FingerTarget("index", (0.0, 0.0), gap_mm),), 0.0, pitch_deg,
                          surf, 10)
    caps = [p for p in prims if isinstance(p, Capsule)]
    index = finger_label(0, "index")
    return [p for p in caps if p.label == index], [p for p in caps if p.label != index]


def _low(p: Capsule) -> float:
    """The capsule's lowest height above the plane z = 1000 (the plane faces the camera)."""
    return 1000.0 - max(p.a[2], p.b[2]) - p.radius_mm


def test_capsule_style_is_the_suites_hand() -> None:
    a = HandShape.random(np.random.default_rng(4))
    b = HandShape.random(np.random.default_rng(4), style="capsule")
    assert a == b and a.anatomy is None
    with pytest.raises(ConfigError, match="unknown hand 'claw'; use one of capsule, anatomic"):
        HandShape.random(np.random.default_rng(4), style="claw")


@pytest.mark.parametrize("seed", range(6))
def test_anatomic_pad_is_wide_tapered_and_presses(seed: int) -> None:
    shape = HandShape.random(np.random.default_rng(seed), style="anatomic")
    a = shape.anatomy
    assert a is not None
    index, _ = _pose(shape, 0.0)
    lobes = index[-2:]
    r = shape.finger_radius_mm
    # two lobes side by side, thinner than the finger: the pad is wider than it is thick
    assert lobes[0].radius_mm == lobes[1].radius_mm < r
    offset = float(np.linalg.norm(lobes[0].b - lobes[1].b)) / 2.0
    width, thick = 2.0 * (offset + lobes[0].radius_mm), 2.0 * lobes[0].radius_mm
    assert 1.2 <= width / thick <= 1.5
    # touching, the pad sinks by press_mm; hovering 3 mm, it is 3 mm up
    assert min(_low(p) for p in lobes) == pytest.approx(-a.press_mm, abs=1e-9)
    hover, _ = _pose(shape, 3.0)
    assert min(_low(p) for p in hover[-2:]) == pytest.approx(3.0, abs=1e-9)
    # the phalanges taper toward the tip
    assert index[0].radius_mm == r > index[1].radius_mm > lobes[0].radius_mm / 0.85 - 1e-9


def test_anatomic_pad_lies_flatter_than_the_scene_pitch() -> None:
    shapes = [HandShape.random(np.random.default_rng(s), style="anatomic") for s in range(40)]
    pitches = []
    for shape in shapes:
        lobe = _pose(shape, 0.0, pitch_deg=25.0)[0][-1]
        axis = lobe.a - lobe.b  # tip -> last joint
        pitches.append(math.degrees(math.asin(-axis[2] / np.linalg.norm(axis))))
    assert min(pitches) == pytest.approx(8.0, abs=1e-6)  # clipped at 8 deg
    assert max(pitches) > 25.0  # a joint bent the other way


@pytest.mark.parametrize(("scene", "seed"), [(s, seed) for s in HARD_SCENES for seed in (0, 1)])
def test_anatomic_hands_reach_the_surface_only_with_their_pads(scene: str, seed: int) -> None:
    """Only the extended fingers come lower than 30 mm; a pad sinks at most 1.5 mm."""
    prof = get_profile("kinect-v2-hard")
    surf = make_surface("plane", 1.2, 15.0)
    script = build_script(scene, SceneContext(surf, Rays(prof.K, prof.resolution_wh),
                                              np.random.default_rng(seed), "anatomic"))
    lowest_tip = lowest_other = np.inf
    for t in np.arange(0.0, script.duration_s, 1.0 / FPS):
        s = surf.moved(script.drift(t) if script.drift else 0.0)
        prims, tips = assemble_scene(script, s, float(t))
        tip_labels = {tip.label for _, _, tip in tips}
        for p in prims:
            if not isinstance(p, Capsule) or p.label >= 100:
                continue
            low = float(min(s.height_mm(p.a)[0], s.height_mm(p.b)[0])) - p.radius_mm
            if p.label in tip_labels:
                lowest_tip = min(lowest_tip, low)
            else:
                lowest_other = min(lowest_other, low)
    assert -1.5 - 1e-6 <= lowest_tip <= 0.0
    assert lowest_other >= 30.0 - 1e-6


@pytest.mark.parametrize(("scene", "camera", "tilt_deg", "distance_m"), [
    ("approach", "kinect-v2-hard", 30.0, 2.0),
    ("stillholds", "realsense-d435-hard", 10.0, 1.0),
    ("hovergroup", "kinect-v1-hard", 0.0, 1.0),
])
def test_anatomic_truth_lies_under_the_pad(scene: str, camera: str, tilt_deg: float,
                                           distance_m: float) -> None:
    """The contact point is the middle of the pad: the finger is seen there, at most a finger
    width nearer than the surface, and never behind it."""
    rec = render_scene(scene, camera=camera, tilt_deg=tilt_deg, distance_m=distance_m, seed=2,
                       noise=False, fps=FPS, keep_labels=True, hand="anatomic")
    assert all(h["model"] == "anatomic" for h in rec.truth["hands"])
    assert check_contacts_on_fingertips(rec, behind_mm=2.0) >= 5


def test_render_scene_refuses_an_unknown_hand() -> None:
    with pytest.raises(ConfigError, match="unknown hand 'robot'"):
        render_scene("taps", hand="robot", fps=2.0)


def test_suite_hands_key_multiplies_cases_and_labels_them() -> None:
    g = {"name": "g", "scenes": ["taps"], "cameras": ["kinect-v2"], "distances_m": [1.0],
         "seeds": [1, 2], "hands": ["capsule", "anatomic"]}
    cases = suite_from_dict({"group": [g]}).cases
    assert [c.hand for c in cases] == ["capsule", "capsule", "anatomic", "anatomic"]
    assert cases[0].label == "taps/kinect-v2/1m/s1"
    assert cases[2].label == "taps/kinect-v2/1m/anatomic/s1"
    assert "hand" not in cases[0].render_kwargs()
    assert cases[2].render_kwargs()["hand"] == "anatomic"
    with pytest.raises(ConfigError, match="hands has unknown 'claw'; use capsule, anatomic"):
        suite_from_dict({"group": [{**g, "hands": ["claw"]}]})


def test_third_check_set_is_hard_with_the_other_hand() -> None:
    hard, fresh3 = load_suite("hard").cases, load_suite("hard-fresh3").cases

    def placement(c: SuiteCase) -> tuple[object, ...]:
        return (c.scene, c.camera, c.distance_m, c.tilt_deg, c.surface, c.group)

    assert len(fresh3) == 50 and {c.hand for c in fresh3} == {"anatomic"}
    assert {placement(c) for c in fresh3} <= {placement(c) for c in hard}
    assert min(c.seed for c in fresh3) >= 701
    # its control: the same cases with the capsule hand
    control = load_suite("hard-fresh3-capsule").cases
    assert [dataclasses.replace(c, hand="anatomic") for c in control] == list(fresh3)


def test_cli_sim_hand(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out, truth = tmp_path / "a.npz", tmp_path / "a.truth.json"
    assert main(["sim", "taps", "--out", str(out), "--truth", str(truth), "--hand", "anatomic",
                 "--fps", "4"]) == 0
    assert load_truth(truth)["hands"][0]["model"] == "anatomic"
    bad = tmp_path / "b.npz"
    assert main(["sim", "taps", "--out", str(bad), "--truth", str(tmp_path / "b.json"),
                 "--hand", "claw", "--fps", "4"]) == 2
    err = capsys.readouterr().err
    assert "unknown hand 'claw'" in err and err.count("\n") == 1
    assert not bad.exists()
