"""The hard suite's scenes and camera profiles: exact truth, what each scene promises, artefacts."""

from __future__ import annotations

import collections
from typing import Any

import numpy as np
import pytest

from depthtouch.sim import CAMERAS, HARD_CAMERAS, HARD_SCENES, PROFILES, render_scene
from depthtouch.sim.artefacts import fatten_edges, match_window, multipath, speckle_holes
from depthtouch.sim.cameras import NoiseModel, get_profile
from depthtouch.sim.geometry import Capsule, Rays, make_surface
from depthtouch.sim.hardscenes import LABEL_REST_HAND, free_yaw
from depthtouch.sim.render import assemble_scene
from depthtouch.sim.scenes import LABEL_OBJECT, SceneContext, build_script
from simcheck import check_contacts_on_fingertips

FPS = 10.0


@pytest.fixture(scope="module")
def truths() -> dict[str, dict[str, Any]]:
    """Noise-free truth of every hard scene at 10 fps (rendered once)."""
    return {s: render_scene(s, camera="kinect-v2-hard", distance_m=1.2, tilt_deg=15.0, seed=3,
                            noise=False, fps=FPS).truth for s in HARD_SCENES}


def _episodes(truth: dict[str, Any]) -> dict[int, list[int]]:
    out: dict[int, list[int]] = collections.defaultdict(list)
    for fr in truth["frames"]:
        for c in fr["contacts"]:
            out[c["id"]].append(fr["frame"])
    return dict(out)


@pytest.mark.parametrize(
    ("scene", "n_contacts", "max_together", "events"),
    [
        ("approach", 4, 1, []),
        ("rest", 4, 1, ["arm_rest_start", "arm_rest_end"]),
        ("handled", 4, 1, ["object_placed", "object_removed"]),
        ("fastdrags", 4, 1, []),
        ("strokes", 4, 1, []),
        ("warmup", 4, 1, ["drift_start"]),
        ("stillholds", 2, 1, []),
        ("hovergroup", 3, 2, []),
    ],
)
def test_hard_scene_contacts_and_events(scene: str, n_contacts: int, max_together: int,
                                        events: list[str], truths: dict[str, Any]) -> None:
    t = truths[scene]
    assert t["empty_frames"] >= 1.5 * FPS
    assert len(t["frames"]) / FPS <= 16.0
    eps = _episodes(t)
    assert len(eps) == n_contacts
    assert max(len(fr["contacts"]) for fr in t["frames"]) == max_together
    for frames in eps.values():
        assert frames == list(range(frames[0], frames[-1] + 1))
    assert [e["kind"] for e in t["events"]] == events


@pytest.mark.parametrize("scene", [s for s in HARD_SCENES if s != "hovergroup"])
def test_every_touch_is_preceded_by_a_low_hover(scene: str, truths: dict[str, Any]) -> None:
    """Before each contact the same finger hovered 5-20 mm within the last second."""
    t = truths[scene]
    frames = t["frames"]
    for first in (f[0] for f in _episodes(t).values()):
        c = frames[first]["contacts"][0]
        lows = [h["height_mm"] for fr in frames[max(first - int(FPS), 0):first]
                for h in fr["hovers"] if h["finger"] == c["finger"] and h["hand"] == c["hand"]]
        assert any(5.0 - 1e-6 <= h <= 20.0 + 1e-6 for h in lows), (scene, first)


def test_hovergroup_fingers_hover_low_together(truths: dict[str, Any]) -> None:
    frames = truths["hovergroup"]["frames"]
    low = [fr for fr in frames
           if not fr["contacts"] and sum(h["height_mm"] <= 20.0 for h in fr["hovers"]) == 3]
    assert len(low) >= 5  # three fingers within 20 mm, none touching, for half a second


def test_fast_drags_are_fast(truths: dict[str, Any]) -> None:
    t = truths["fastdrags"]
    speeds = []
    for frames in _episodes(t).values():
        pts = [np.array([c["X"], c["Y"], c["Z"]]) for f in frames
               for c in t["frames"][f]["contacts"]]
        steps = np.linalg.norm(np.diff(pts, axis=0), axis=1) * FPS
        speeds.append(float(steps.max()))
    assert 300.0 * 0.9 <= max(speeds) <= 900.0 * 1.01
    assert min(speeds) >= 250.0


def test_warmup_drifts_a_fraction_of_a_mm_per_second(truths: dict[str, Any]) -> None:
    fr = truths["warmup"]["frames"]
    off = [(f["t"], f.get("surface_offset_mm", 0.0)) for f in fr]
    (t0, o0), (t1, o1) = off[int(3 * FPS)], off[-1]
    rate = abs(o1 - o0) / (t1 - t0)
    assert 0.25 <= rate <= 0.55


@pytest.mark.parametrize(("scene", "camera", "surface", "tilt_deg", "distance_m"), [
    ("approach", "kinect-v2-hard", "plane", 30.0, 2.0),
    ("rest", "realsense-d435-hard", "plane", 10.0, 0.95),
    ("handled", "kinect-v2-hard", "plane", 0.0, 1.0),
    ("strokes", "realsense-d435-hard", "cylinder-concave", 0.0, 0.9),
    ("hovergroup", "kinect-v1-hard", "plane", 35.0, 1.8),
])
def test_hard_truth_reprojects_onto_fingertip(scene: str, camera: str, surface: str,
                                              tilt_deg: float, distance_m: float) -> None:
    rec = render_scene(scene, camera=camera, surface=surface, tilt_deg=tilt_deg,
                       distance_m=distance_m, seed=2, noise=False, fps=FPS, keep_labels=True)
    assert check_contacts_on_fingertips(rec, behind_mm=0.5) >= 5


@pytest.mark.parametrize(("scene", "seed"), [(s, seed) for s in HARD_SCENES for seed in (0, 1)])
def test_only_tips_props_and_resting_hands_reach_the_surface(scene: str, seed: int) -> None:
    """Tips reach gap 0 exactly; other parts of the moving hands stay >= 30 mm up; the resting
    hand lies on the surface (0-2 mm) and never sinks into it."""
    prof = get_profile("realsense-d435-hard")
    rays = Rays(prof.K, prof.resolution_wh)
    surf = make_surface("plane", 1.0, 15.0)
    script = build_script(scene, SceneContext(surf, rays, np.random.default_rng(seed)))
    lowest_tip = lowest_other = lowest_rest = np.inf
    for t in np.arange(0.0, script.duration_s, 1.0 / FPS):
        s = surf.moved(script.drift(t) if script.drift else 0.0)
        prims, tips = assemble_scene(script, s, float(t))
        tip_labels = {tip.label for _, _, tip in tips}
        for p in prims:
            if not isinstance(p, Capsule):
                continue
            low = float(min(s.height_mm(p.a)[0], s.height_mm(p.b)[0])) - p.radius_mm
            if p.label == LABEL_REST_HAND:
                lowest_rest = min(lowest_rest, low)
            elif p.label in tip_labels:
                lowest_tip = min(lowest_tip, low)
            elif p.label < 100:
                lowest_other = min(lowest_other, low)
    assert lowest_tip >= -1e-6
    assert lowest_other >= 30.0 - 1e-6
    if scene == "rest":
        assert 0.0 - 1e-6 <= lowest_rest <= 2.0 + 1e-6


def test_arms_come_from_every_side_on_a_level_surface() -> None:
    prof = get_profile("kinect-v2-hard")
    rays = Rays(prof.K, prof.resolution_wh)
    level, tilted = make_surface("plane", 1.3, 0.0), make_surface("plane", 2.0, 30.0)
    yaws = [free_yaw(SceneContext(level, rays, np.random.default_rng(s))) for s in range(40)]
    assert min(yaws) < -120.0 and max(yaws) > 120.0  # from above, below and both sides
    ctx = SceneContext(tilted, rays, np.random.default_rng(0))
    for _ in range(40):
        assert abs(free_yaw(ctx) - ctx.base_yaw) <= 75.0


def test_handled_box_moves_with_the_hand() -> None:
    prof = get_profile("kinect-v2-hard")
    rays = Rays(prof.K, prof.resolution_wh)
    surf = make_surface("plane", 1.0, 0.0)
    script = build_script("handled", SceneContext(surf, rays, np.random.default_rng(4)))
    placed, removed = (t for _, t in script.events)
    heights = {}
    for t in (placed - 0.3, placed + 0.5, removed + 0.45):
        boxes = [p for p in script.props[0].build(t) if p.label == LABEL_OBJECT]
        assert len(boxes) == 1
        heights[t] = float(surf.height_mm(boxes[0].center)[0])
    h_rest = heights[placed + 0.5]
    assert heights[placed - 0.3] > h_rest + 20.0  # still carried, coming down
    assert heights[removed + 0.45] > h_rest + 100.0  # lifted away


# --- camera profiles -------------------------------------------------------------------------
def test_hard_profiles_are_apart_from_the_default_ones() -> None:
    assert set(HARD_CAMERAS).isdisjoint(CAMERAS)
    for name in CAMERAS:  # the default suite's profiles draw no noise level, no artefacts
        p = PROFILES[name]
        assert p.noise_scale_range == (1.0, 1.0)
        assert p.multipath_mm == p.fatten_px == p.speckle_per_mpx == 0


def test_noise_level_varies_with_seed_within_the_profile_range() -> None:
    p = PROFILES["realsense-d435-hard"]
    scales = [float(NoiseModel(p, np.random.default_rng(s)).noise_scale) for s in range(8)]
    lo, hi = p.noise_scale_range
    assert all(lo <= s <= hi for s in scales) and max(scales) - min(scales) > 0.1
    assert float(NoiseModel(PROFILES["kinect-v2"], np.random.default_rng(0)).noise_scale) == 1.0


def _plane_with_finger(z_mm: float = 1000.0, height_mm: float = 8.0) -> tuple[np.ndarray, ...]:
    static = np.full((60, 60), z_mm, np.float32)
    z = static.copy()
    z[25:35, 10:40] = z_mm - height_mm  # a finger lying 8 mm above the surface
    return static, z


def test_multipath_raises_the_surface_near_a_low_finger_and_lowers_the_finger() -> None:
    static, z = _plane_with_finger()
    noisy = z.copy()
    multipath(noisy, z, static, 500.0, 3.0, 20.0)
    assert noisy[30, 20] > z[30, 20]  # the finger reads lower (deeper)
    assert noisy[30, 20] - z[30, 20] <= 0.7 * 8.0
    near, far = static[22, 20] - noisy[22, 20], static[0, 20] - noisy[0, 20]
    assert 1.5 < near <= 3.0 and far < near  # the surface beside it reads nearer, fading out
    untouched = z.copy()
    multipath(untouched, z, static, 500.0, 0.0, 20.0)
    assert np.array_equal(untouched, z)


def test_fattening_spreads_the_near_side_over_the_far_side() -> None:
    static, z = _plane_with_finger(height_mm=60.0)
    noisy = z.copy()
    fatten_edges(noisy, z, np.ones_like(z), 2, 1.0, np.random.default_rng(0))
    assert np.all(noisy[23:25, 10:40] == 940.0)  # two rows above the finger took its depth
    assert np.all(noisy[22, 10:40] == 1000.0) and np.all(noisy[30, 12:38] == 940.0)


def test_speckle_holes_grow_with_depth() -> None:
    near = sum(speckle_holes((480, 848), 150.0, 600.0, np.random.default_rng(s)).sum()
               for s in range(5))
    far = sum(speckle_holes((480, 848), 150.0, 1600.0, np.random.default_rng(s)).sum()
              for s in range(5))
    assert far > 4 * near > 0


def test_matching_window_loses_thin_structures_and_keeps_wide_ones() -> None:
    z = np.full((40, 40), 1600.0, np.float32)
    z[5:35, 5:7] = 1580.0  # 2 px wide: a finger at range
    z[5:35, 20:26] = 1580.0  # 6 px wide
    z[0, 0] = 0.0  # no surface stays no surface
    out = match_window(z, 5)
    assert np.all(out[8:32, 5:7] == 1600.0)
    assert np.all(out[8:32, 21:25] == 1580.0)
    assert out[0, 0] == 0.0 and match_window(z, 0) is z
