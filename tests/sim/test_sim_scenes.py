"""Simulator scenes: each script does what its name promises (timings, counts, events)."""

from __future__ import annotations

import collections
from typing import Any

import numpy as np
import pytest

from depthtouch.sim import SCENES, render_scene
from depthtouch.sim.cameras import get_profile
from depthtouch.sim.geometry import Capsule, Rays, make_surface
from depthtouch.sim.render import assemble_scene
from depthtouch.sim.scenes import LABEL_REST_ARM, SceneContext, build_script

FPS = 10.0


def _episodes(truth: dict[str, Any], kind: str = "contacts") -> dict[int, list[int]]:
    out: dict[int, list[int]] = collections.defaultdict(list)
    for fr in truth["frames"]:
        for c in fr[kind]:
            out[c["id"]].append(fr["frame"])
    return dict(out)


def _max_simultaneous(truth: dict[str, Any]) -> int:
    return max(len(fr["contacts"]) for fr in truth["frames"])


@pytest.fixture(scope="module")
def truths() -> dict[str, dict[str, Any]]:
    """Noise-free truth of every scene at 10 fps on the default camera (rendered once)."""
    return {s: render_scene(s, camera="kinect-v2", seed=5, noise=False, fps=FPS).truth
            for s in SCENES}


@pytest.mark.parametrize("scene", SCENES)
def test_every_scene_starts_empty_and_is_short(scene: str, truths: dict[str, Any]) -> None:
    t = truths[scene]
    assert t["empty_frames"] >= 1.5 * FPS
    first = next((f["frame"] for f in t["frames"] if f["contacts"] or f["hovers"]), None)
    assert first is None or first >= t["empty_frames"]
    assert len(t["frames"]) / FPS <= 16.0


@pytest.mark.parametrize(
    ("scene", "min_contacts", "max_contacts", "max_together", "dur_s"),
    [
        ("taps", 4, 8, 1, (0.25, 0.75)),
        ("drags", 3, 6, 1, (0.3, 8.0)),
        ("multitouch", 5, 5, 5, (0.5, 3.0)),
        ("pinch", 4, 4, 2, (0.6, 1.6)),
        ("cross", 2, 2, 2, (0.5, 3.0)),
        ("hover", 0, 0, 0, (0.0, 0.0)),
        ("distractors", 3, 6, 1, (0.25, 0.75)),
        ("object", 3, 3, 1, (0.25, 0.75)),
        ("drift", 4, 8, 1, (0.25, 0.75)),
        ("bump", 4, 8, 1, (0.25, 0.75)),
        ("hold", 1, 1, 1, (9.9, 10.4)),
    ],
)
def test_scene_contacts(scene: str, min_contacts: int, max_contacts: int, max_together: int,
                        dur_s: tuple[float, float], truths: dict[str, Any]) -> None:
    t = truths[scene]
    eps = _episodes(t)
    assert min_contacts <= len(eps) <= max_contacts
    assert _max_simultaneous(t) == max_together
    for frames in eps.values():
        assert frames == list(range(frames[0], frames[-1] + 1))  # one id per episode
        assert dur_s[0] - 1.0 / FPS <= len(frames) / FPS <= dur_s[1] + 1.0 / FPS


def test_hover_heights_never_touch(truths: dict[str, Any]) -> None:
    t = truths["hover"]
    assert not _episodes(t)
    held = collections.Counter(round(h["height_mm"], 3) for f in t["frames"] for h in f["hovers"])
    for height in (10.0, 25.0, 50.0):
        assert held[height] >= 0.9 * FPS  # held about a second at each height


@pytest.mark.parametrize(
    ("scene", "events"),
    [
        ("object", ["object_placed", "object_removed"]),
        ("distractors", ["object_placed", "arm_rest_start", "arm_rest_end", "body_pass_start",
                         "body_pass_end"]),
        ("drift", ["drift_start"]),
        ("bump", ["bump"]),
    ],
)
def test_scene_events(scene: str, events: list[str], truths: dict[str, Any]) -> None:
    t = truths[scene]
    kinds = [e["kind"] for e in t["events"]]
    assert sorted(kinds) == sorted(events)
    # nothing happens during the 1.5 s the recording contract keeps empty
    assert all(1.5 * FPS <= e["frame"] < len(t["frames"]) for e in t["events"])


def test_object_scene_leaves_the_object_three_seconds(truths: dict[str, Any]) -> None:
    ev = {e["kind"]: e["frame"] for e in truths["object"]["events"]}
    assert abs((ev["object_removed"] - ev["object_placed"]) / FPS - 3.0) <= 1.0 / FPS


def test_drift_moves_the_surface_a_few_mm() -> None:
    rec = render_scene("drift", camera="kinect-v1", seed=1, noise=False, fps=FPS)
    offsets = [f.get("surface_offset_mm", 0.0) for f in rec.truth["frames"]]
    assert offsets[0] == 0.0 and 2.5 <= abs(offsets[-1]) <= 5.5
    # the rendered surface follows: the centre pixel moves by the offset (surface is tilt 0)
    h, w = rec.depth.shape[1:]
    moved = float(rec.depth[-1, h // 2, w // 2]) - float(rec.depth[0, h // 2, w // 2])
    assert abs(moved + offsets[-1]) <= 1.0


def test_bump_changes_the_view_and_stays() -> None:
    rec = render_scene("bump", camera="kinect-v1", seed=1, noise=False, fps=FPS)
    k = rec.truth["bump"]["frame"]
    d = rec.depth.astype(np.float64)
    before, after, last = d[k - 1], d[k], d[-1]
    assert np.mean(before[:40] != after[:40]) > 0.5  # the top rows see another depth
    assert np.array_equal(after[:40], last[:40])  # and keep it


def test_multitouch_uses_two_hands(truths: dict[str, Any]) -> None:
    t = truths["multitouch"]
    hands = {c["hand"] for f in t["frames"] for c in f["contacts"]}
    assert hands == {0, 1}
    assert len(t["hands"]) == 2 and {h["side"] for h in t["hands"]} == {"left", "right"}


def test_cross_contacts_pass_close() -> None:
    t = render_scene("cross", camera="kinect-v2", seed=3, noise=False, fps=30).truth
    gaps = [np.hypot(f["contacts"][0]["X"] - f["contacts"][1]["X"],
                     f["contacts"][0]["Y"] - f["contacts"][1]["Y"])
            for f in t["frames"] if len(f["contacts"]) == 2]
    assert min(gaps) < 40.0  # mm apart at the crossing


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_finger_radius_varies_with_seed(seed: int) -> None:
    t = render_scene("hold", camera="kinect-v2", seed=seed, noise=False, fps=2).truth
    assert 6.0 <= t["hands"][0]["finger_radius_mm"] <= 10.0


@pytest.mark.parametrize(("scene", "seed"), [(s, seed) for s in SCENES for seed in (0, 1)])
def test_only_tips_come_near_the_surface(scene: str, seed: int) -> None:
    """Touching tips reach gap 0 exactly; every other hand part stays >= 30 mm up, the resting
    arm >= 40 mm up."""
    prof = get_profile("realsense-d435")
    rays = Rays(prof.K, prof.resolution_wh)
    surf = make_surface("plane", 1.0, 15.0)
    script = build_script(scene, SceneContext(surf, rays, np.random.default_rng(seed)))
    lowest_tip, lowest_other = np.inf, np.inf
    for t in np.arange(0.0, script.duration_s, 1.0 / FPS):
        s = surf.moved(script.drift(t) if script.drift else 0.0)
        prims, tips = assemble_scene(script, s, float(t))
        tip_labels = {tip.label for _, _, tip in tips}
        for p in prims:
            if not isinstance(p, Capsule):
                continue
            low = float(min(s.height_mm(p.a)[0], s.height_mm(p.b)[0])) - p.radius_mm
            if p.label == LABEL_REST_ARM:
                assert low >= 40.0
            elif p.label in tip_labels:
                lowest_tip = min(lowest_tip, low)
            elif p.label < 100:
                lowest_other = min(lowest_other, low)
    assert lowest_tip >= -1e-6
    assert lowest_other >= 30.0 - 1e-6


@pytest.mark.parametrize("tilt_deg", [0.0, 30.0])
def test_fingertips_mostly_visible(tilt_deg: float) -> None:
    n = occluded = 0
    for scene in ("taps", "multitouch", "pinch"):
        t = render_scene(scene, camera="kinect-v1", tilt_deg=tilt_deg, seed=2, noise=False,
                         fps=FPS).truth
        for f in t["frames"]:
            n += len(f["contacts"])
            occluded += sum(c["occluded"] for c in f["contacts"])
    assert n > 50 and occluded <= 0.05 * n
