"""The tune / held-out split, the late-after-change count and the per-situation figures."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import pytest
from test_evaluation import contact, doc, hover, track

from depthtouch.errors import ConfigError
from depthtouch.evaluation.halves import (
    HALVES,
    figures,
    half_of,
    halves_markdown,
    halves_report,
    late_false_after_change,
    missed_lines,
    overall_rows,
    placement,
    select_half,
    situation_rows,
)
from depthtouch.evaluation.metrics import evaluate, truth_from_dict
from depthtouch.evaluation.suite import SuiteCase, load_suite, suite_from_dict


def test_split_is_deterministic_and_disjoint() -> None:
    suite = load_suite("hard")
    cases = list(suite.cases)
    assert [half_of(c) for c in cases] == [half_of(c) for c in load_suite("hard").cases]
    tune, held = select_half(cases, "tune"), select_half(cases, "held-out")
    assert len(tune) + len(held) == len(cases) and not set(tune) & set(held)
    assert select_half(cases, "all") == cases
    # a held-out case never shares its seed and its placement with a tuned one
    assert not {(c.seed, placement(c)) for c in tune} & {(c.seed, placement(c)) for c in held}
    # every situation and every placement is on both sides
    for key in (lambda c: c.group, placement):
        assert {key(c) for c in tune} == {key(c) for c in held}


def test_check_set_is_the_hard_suite_with_fresh_seeds() -> None:
    """hard-fresh: the same situations and placements as hard, none of its recordings."""
    hard, fresh = load_suite("hard").cases, load_suite("hard-fresh").cases

    def recording(c: SuiteCase) -> tuple[Any, ...]:
        return dataclasses.astuple(dataclasses.replace(c, group=""))

    def situation(c: SuiteCase) -> tuple[Any, ...]:
        return recording(dataclasses.replace(c, seed=0))

    assert len(fresh) == 50
    assert not {recording(c) for c in fresh} & {recording(c) for c in hard}
    assert {situation(c) for c in fresh} == {situation(c) for c in hard}
    assert {c.group for c in fresh} == {c.group for c in hard}


def test_extra_seeds_are_new_recordings_of_five_hard_situations_on_both_halves() -> None:
    """hard-extra: situations of hard (scene, camera, placement), none of its or hard-fresh's
    recordings, every group on both halves."""
    known = load_suite("hard").cases + load_suite("hard-fresh").cases
    extra = load_suite("hard-extra").cases

    def recording(c: SuiteCase) -> tuple[Any, ...]:
        return dataclasses.astuple(dataclasses.replace(c, group=""))

    def situation(c: SuiteCase) -> tuple[Any, ...]:
        return recording(dataclasses.replace(c, seed=0))

    assert not {recording(c) for c in extra} & {recording(c) for c in known}
    assert {situation(c) for c in extra} <= {situation(c) for c in known}
    assert {c.group for c in extra} == {"still-finger", "forearm-rest", "hovering-fingers",
                                        "drift", "object-handled"}
    tune, held = select_half(extra, "tune"), select_half(extra, "held-out")
    assert {c.group for c in tune} == {c.group for c in held}


def test_half_depends_on_seed_and_placement_only() -> None:
    a = SuiteCase("approach", "kinect-v2-hard", 2.0, tilt_deg=30.0, seed=3, group="x")
    assert half_of(a) == half_of(dataclasses.replace(a, scene="rest", group="y", fps=15.0))
    # the next seed at the same placement is in the other half
    assert half_of(a) != half_of(dataclasses.replace(a, seed=4))
    halves = {half_of(dataclasses.replace(a, distance_m=d)) for d in (0.6, 0.8, 1.0, 1.2, 1.4)}
    assert halves == set(HALVES)  # the placement moves cases between halves too


def test_a_suite_at_another_frame_rate_keeps_its_cases_tags_and_halves() -> None:
    hard = load_suite("hard")
    fast = hard.at_fps(60)
    assert hard.at_fps(None) is hard
    assert [dataclasses.replace(c, fps=30.0) for c in fast.cases] == list(hard.cases)
    assert {c.fps for c in fast.cases} == {60.0}
    assert [half_of(c) for c in fast.cases] == [half_of(c) for c in hard.cases]
    assert fast.select("far") == [dataclasses.replace(c, fps=60.0) for c in hard.select("far")]
    # another rate is another recording
    assert fast.cases[0].cache_key() != hard.cases[0].cache_key()


@pytest.mark.parametrize(("method", "field", "value", "mark", "absent", "bad", "allowed"), [
    ("at_resolution", "resolution_scale", 1.5, "@x1.5/", "@x", 4.0, "allowed \\[0.25, 3\\]"),
    ("at_noise", "noise_scale", 2.0, "/noise2/", "/noise", 5.0, "allowed \\[0.25, 4\\]"),
])
def test_a_suite_rendered_otherwise_keeps_its_cases_tags_and_halves(
        method: str, field: str, value: float, mark: str, absent: str, bad: float,
        allowed: str) -> None:
    """Another resolution or more noise: the same cases, tags and halves, other recordings."""
    hard = load_suite("hard")
    other = getattr(hard, method)(value)
    assert getattr(hard, method)(None) is hard
    assert [dataclasses.replace(c, **{field: 1.0}) for c in other.cases] == list(hard.cases)
    assert [half_of(c) for c in other.cases] == [half_of(c) for c in hard.cases]
    assert other.select("far") == [dataclasses.replace(c, **{field: value})
                                   for c in hard.select("far")]
    assert mark in other.cases[0].label and absent not in hard.cases[0].label
    # another rendering is another recording; as rendered by default a case keeps its cache key
    assert other.cases[0].cache_key() != hard.cases[0].cache_key()
    assert other.cases[0].render_kwargs()[field] == value
    assert field not in hard.cases[0].render_kwargs()
    with pytest.raises(ConfigError, match=allowed):
        getattr(hard, method)(bad)


def test_a_suite_with_bodies_is_the_same_suite_case_for_case() -> None:
    """``--body`` (the hard suite with bodies, session 49): every case of hard, and nothing
    else, with the body on; so the same halves and a paired comparison (same seeds,
    placements, groups and tags)."""
    hard = load_suite("hard")
    assert hard.with_body(False) is hard
    body = hard.with_body()
    assert all(c.body for c in body.cases) and not any(c.body for c in hard.cases)
    assert [dataclasses.replace(c, body=False) for c in body.cases] == list(hard.cases)
    assert [half_of(c) for c in body.cases] == [half_of(c) for c in hard.cases]
    assert [body.tags[c] for c in body.cases] == [hard.tags[c] for c in hard.cases]
    assert body.select("far") == [dataclasses.replace(c, body=True) for c in hard.select("far")]


def test_bad_half_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="use tune, held-out or all"):
        select_half([], "train")


def _with_events(d: dict[str, Any], *events: tuple[str, int]) -> dict[str, Any]:
    d["events"] = [{"kind": k, "frame": f, "t": f / 30} for k, f in events]
    return d


@pytest.mark.parametrize(
    ("frames", "late"),
    [
        (range(40, 50), 0),   # ends within 2 s (60 frames) of the change at frame 30
        (range(40, 95), 1),   # still reported at frame 94 > 30 + 60
        (range(100, 110), 1),  # begins more than 2 s after the change
        (range(10, 95), 0),   # began before any change: not the change's fault
    ],
)
def test_late_false_after_change(frames: range, late: int) -> None:
    t = truth_from_dict(_with_events(doc(120, {}), ("object_placed", 30), ("drift_start", 5)))
    r = evaluate(t, track(9, frames, (100, 100)))
    assert r.change_frames == (30,)
    assert late_false_after_change(r) == late


def test_false_touches_near_a_hovering_finger_are_not_the_surfaces() -> None:
    d = doc(120, {}, {f: [hover(3, 100, 100, 12.0)] for f in range(90, 110)})
    t = truth_from_dict(_with_events(d, ("object_removed", 30)))
    r = evaluate(t, track(9, range(100, 110), (100, 100)))
    assert late_false_after_change(r) == 0


def test_no_change_no_late_false() -> None:
    t = truth_from_dict(_with_events(doc(120, {}), ("arm_rest_start", 30)))
    r = evaluate(t, track(9, range(40, 110), (100, 100)))
    assert r.change_frames == () and late_false_after_change(r) == 0


def _recording(found: bool, false_hover_mm: float | None = None):
    c = {f: [contact(1, 300, 200)] for f in range(5, 20)}
    h = {f: [hover(2, 100, 100, false_hover_mm)] for f in range(25, 40)} if false_hover_mm else {}
    ev = track(1, range(5, 20), (300, 200)) if found else []
    if false_hover_mm:
        ev += track(7, range(30, 35), (100, 100))
    return evaluate(truth_from_dict(doc(60, c, h)), ev)


def test_figures_count_far_and_drift_apart() -> None:
    rs = [_recording(True), _recording(False), _recording(False, 30.0), _recording(True, 8.0)]
    f = figures(rs, far=[False, True, False, False], drift=[False, False, True, True])
    assert f["recordings"] == 4 and f["contacts"] == 4
    assert f["recall_working"] == pytest.approx(2 / 3, abs=1e-4)
    assert f["recall_far"] == 0.0
    assert f["recall_drift"] == 0.5
    assert f["false_touches"] == 2 and f["false_from_hover_25mm"] == 1
    assert f["false_per_min"] == pytest.approx(2 / (4 * 2.0 / 60), abs=1e-4)
    assert f["false_longest_s"] == pytest.approx(5 / 30, abs=1e-4)  # frames 30-34 at 30 fps
    assert figures(rs[:2], far=[False, True])["false_longest_s"] == 0.0
    assert f["recall_far"] is not None
    assert figures(rs[:1], far=[False])["recall_far"] is None


def test_report_puts_halves_side_by_side_per_situation() -> None:
    suite = suite_from_dict({"suite": {"name": "t"}, "group": [
        {"name": "near", "scenes": ["approach"], "cameras": ["kinect-v2-hard"],
         "distances_m": [1.0], "seeds": [1, 2]},
        {"name": "far", "scenes": ["approach"], "cameras": ["realsense-d435-hard"],
         "distances_m": [1.6], "seeds": [1, 2], "tags": ["far"]},
    ]})
    cases = list(suite.cases)
    results = [_recording(True), _recording(True), _recording(False), _recording(False)]
    rep = halves_report(suite, cases, results)
    assert set(rep["overall"]) == set(HALVES)
    assert set(rep["situations"]) == {"near", "far"}
    for h in HALVES:
        assert rep["overall"][h]["recall_working"] == 1.0
        assert rep["overall"][h]["recall_far"] == 0.0
        assert rep["situations"]["far"][h]["recall_working"] is None
    rows = overall_rows(rep)
    assert rows[0] == ["recordings", "2", "2"]
    srows = situation_rows(rep)
    assert [r[:2] for r in srows] == [["near", "tune"], ["near", "held-out"], ["far", "tune"],
                                      ["far", "held-out"]]
    assert all(r[3] in ("1.000", "0.000") for r in srows)
    assert not any(isinstance(v, float) and math.isnan(v) for v in rep["overall"]["tune"].values())


def test_report_rows_pool_by_another_attribute_or_none() -> None:
    suite = suite_from_dict({"suite": {"name": "t"}, "group": [
        {"name": "near", "scenes": ["approach", "taps"], "cameras": ["kinect-v2-hard"],
         "distances_m": [1.0], "seeds": [1, 2]},
    ]})
    cases = list(suite.cases)
    results = [_recording(i % 2 == 0) for i in range(len(cases))]
    by_scene = halves_report(suite, cases, results, by="scene")
    assert by_scene["by"] == "scene"
    assert set(by_scene["situations"]) == {"approach", "taps"}
    assert by_scene["overall"] == halves_report(suite, cases, results)["overall"]
    for name in ("approach", "taps"):
        mine = [r for c, r in zip(cases, results, strict=True) if c.scene == name]
        got = sum(f["contacts"] for f in by_scene["situations"][name].values())
        assert got == sum(int(r.ep_visible.sum()) for r in mine)
    assert halves_markdown(by_scene)[len(overall_rows(by_scene)) + 3].startswith("| scene | half |")
    no_rows = halves_report(suite, cases, results, by="all")
    assert no_rows["situations"] == {}
    assert halves_markdown(no_rows) == halves_markdown(by_scene)[:len(overall_rows(by_scene)) + 2]
    assert "| situation | half |" in "\n".join(halves_markdown(halves_report(suite, cases, results)))
    with pytest.raises(ConfigError, match="cannot group by 'seed'"):
        halves_report(suite, cases, results, by="seed")


@pytest.mark.parametrize(("argv", "needle"), [
    (["eval", "--half", "tune"], "--half needs --suite NAME"),
    (["eval", "--suite", "hard", "--half", "tune", "--by", "seed"], "cannot group by 'seed'"),
    (["eval", "--suite", "hard", "--by", "seed"], "cannot group by 'seed'"),
    (["eval", "--suite", "hard", "--subset", "nope", "--half", "tune"], "has no subset 'nope'"),
    (["eval", "--fps", "60", "x.npz"], "--fps needs --suite NAME"),
    (["eval", "--suite", "hard", "--fps", "500", "--half", "tune"], "fps 500.0 is out of range"),
    (["eval", "--resolution-scale", "1.5", "x.npz"], "--resolution-scale needs --suite NAME"),
    (["eval", "--suite", "hard", "--resolution-scale", "9", "--half", "tune"],
     "resolution scale 9.0 is out of range"),
    (["eval", "--noise-scale", "2", "x.npz"], "--noise-scale needs --suite NAME"),
    (["eval", "--suite", "hard", "--noise-scale", "9", "--half", "tune"],
     "noise scale 9.0 is out of range"),
    (["eval", "--body", "x.npz"], "--body needs --suite NAME"),
    (["eval", "--suite", "hard", "--half", "tune", "--against", "b.toml", "--body"],
     "leave out --fps, --resolution-scale, --noise-scale, --body, --drop-rate and "
     "--breathing-mm"),
    (["eval", "--suite", "hard", "--half", "tune", "--against", "b.toml", "--drop-rate", "0.1"],
     "--drop-rate"),
    (["eval", "--drop-rate", "0.05", "x.npz"], "--drop-rate needs --suite NAME"),
    (["eval", "--suite", "hard", "--drop-rate", "0.5", "--half", "tune"],
     "drop rate 0.5 is out of range"),
    (["eval", "--breathing-mm", "2", "x.npz"], "--breathing-mm needs --suite NAME"),
    (["eval", "--suite", "hard", "--breathing-mm", "12", "--half", "tune"],
     "breathing 12.0 mm is out of range"),
    (["eval", "--suite", "hard", "--half", "tune", "--against", "b.toml", "--breathing-mm", "2"],
     "--breathing-mm"),
    (["eval", "--empty-s", "1", "x.npz"], "--empty-s needs --suite NAME"),
    (["eval", "--suite", "hard", "--empty-s", "0.1", "--half", "tune"],
     "empty start 0.1 s is out of range"),
    (["eval", "--suite", "hard", "--empty-s", "11"], "empty start 11.0 s is out of range"),
    # bootstrap intervals and comparisons (evaluation/bootstrap.py)
    (["eval", "--suite", "hard", "--half", "tune", "--ci", "5"], "--ci 5 is out of range"),
    (["eval", "--suite", "hard", "--ci", "1000"], "--ci needs --suite NAME --half H"),
    (["eval", "--suite", "hard", "--against", "b.toml"], "--against needs --suite NAME --half H"),
    (["eval", "--suite", "hard", "--half", "tune", "--against", "b.toml", "--by", "camera"],
     "leave out --by"),
    (["eval", "--suite", "hard", "--half", "tune", "--against", "b.toml", "--fps", "60"],
     "leave out --fps"),
])
def test_cli_half_errors_are_one_line(argv: list[str], needle: str,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    from depthtouch.cli import main

    assert main(argv) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1


def test_second_check_set_moves_every_mount_but_the_far_stereo_ones() -> None:
    """hard-fresh2: the 12 situations of hard on both halves, new seeds, and placements hard does
    not have, except the far stereo mounts that the issue fixes."""
    known = [c for n in ("hard", "hard-fresh", "hard-extra") for c in load_suite(n).cases]
    fresh2 = load_suite("hard-fresh2").cases

    def placement(c: SuiteCase) -> tuple[Any, ...]:
        return (c.camera, c.distance_m, c.tilt_deg, c.surface)

    assert len(fresh2) == 50
    assert not {c.seed for c in fresh2} & {c.seed for c in known}
    moved = {c.group for c in fresh2 if placement(c) not in {placement(k) for k in known}}
    assert moved == {c.group for c in fresh2} - {"far-stereo"}
    assert {c.group for c in fresh2} == {c.group for c in load_suite("hard").cases}
    tune, held = select_half(fresh2, "tune"), select_half(fresh2, "held-out")
    assert {c.group for c in tune} == {c.group for c in held}


def test_hover_check_set_is_the_approach_scene_at_tof_range_with_both_hands() -> None:
    """hover-tof: hover-then-tap at ToF 2 m and 1.3 m, seeds no other suite uses, each seed with
    both hand models, on both halves."""
    known = [c for n in ("hard", "hard-fresh", "hard-extra", "hard-fresh2", "hard-fresh3")
             for c in load_suite(n).cases]
    cases = load_suite("hover-tof").cases
    assert len(cases) == 40
    assert {c.scene for c in cases} == {"approach"} and {c.camera for c in cases} == {
        "kinect-v2-hard"}
    assert {c.distance_m for c in cases} == {1.3, 2.0}
    assert not {c.seed for c in cases} & {c.seed for c in known}
    for hand in ("capsule", "anatomic"):
        mine = [c for c in cases if c.hand == hand]
        assert len(mine) == 20
        assert {c.group for c in select_half(mine, "tune")} == {
            c.group for c in select_half(mine, "held-out")}


def test_cylinder_check_set_is_new_strokes_on_the_concave_cylinder_with_both_hands() -> None:
    """hard-cylinder: strokes on the concave cylinder (stereo 0.9 m), 12 anatomic and 6 capsule
    seeds that no suite with that placement uses, each hand on both halves."""
    cases = load_suite("hard-cylinder").cases
    assert len(cases) == 18
    assert {(c.scene, c.camera, c.distance_m, c.surface) for c in cases} == {
        ("strokes", "realsense-d435-hard", 0.9, "cylinder-concave")}
    same_place = [c for n in ("hard", "hard-fresh", "hard-extra", "hard-fresh2", "hard-fresh3",
                              "hard-fresh3-capsule", "default")
                  for c in load_suite(n).cases if c.surface == "cylinder-concave"]
    assert same_place  # the placement is the one hard and hard-fresh3 use
    assert not {c.seed for c in cases} & {c.seed for c in same_place}
    for hand, n in (("anatomic", 12), ("capsule", 6)):
        mine = [c for c in cases if c.hand == hand]
        assert len(mine) == n
        assert select_half(mine, "tune") and select_half(mine, "held-out")


def test_steep_check_set_fixes_the_pitch_on_fresh_seeds_and_both_halves() -> None:
    """steep: taps and approaches at 60 and 70 deg, both hands, four placements, seeds no
    other suite uses; a seed's two pitches share a half (the same spots and timings)."""
    cases = load_suite("steep").cases
    assert len(cases) == 128
    assert {c.pitch_deg for c in cases} == {60.0, 70.0}
    assert {c.scene for c in cases} == {"taps", "approach"}
    assert {c.hand for c in cases} == {"capsule", "anatomic"}
    used = {c.seed for n in ("default", "hard", "hard-fresh", "hard-extra", "hard-fresh2",
                             "hard-fresh3", "hard-fresh3-capsule", "hover-tof", "hard-cylinder")
            for c in load_suite(n).cases}
    assert not {c.seed for c in cases} & used
    for c in cases:
        twin = dataclasses.replace(c, pitch_deg=130.0 - c.pitch_deg)
        assert twin in cases and half_of(twin) == half_of(c)
    for p in {placement(c) for c in cases}:
        mine = [c for c in cases if placement(c) == p]
        assert select_half(mine, "tune") and select_half(mine, "held-out")


def test_suite_pitches_key_multiplies_cases_labels_and_renders_them() -> None:
    doc = {"group": [{"scenes": ["taps"], "cameras": ["kinect-v2"], "distances_m": [1.0],
                      "pitches_deg": [50, 65.5], "seeds": [3]}]}
    cases = suite_from_dict(doc).cases
    assert [c.label for c in cases] == ["taps/kinect-v2/1m/pitch50/s3",
                                        "taps/kinect-v2/1m/pitch65.5/s3"]
    assert [c.render_kwargs()["pitch_deg"] for c in cases] == [50.0, 65.5]
    assert len({c.cache_key() for c in cases}) == 2
    without = {k: v for k, v in doc["group"][0].items() if k != "pitches_deg"}
    drawn = suite_from_dict({"group": [without]}).cases[0]
    assert drawn.pitch_deg is None and "pitch_deg" not in drawn.render_kwargs()
    assert drawn.label == "taps/kinect-v2/1m/s3"
    for bad, needle in (([90], "pitches_deg value 90 is out of range; allowed [10.0, 85.0]"),
                        ([], "pitches_deg must be a non-empty list")):
        with pytest.raises(ConfigError, match=needle.replace("[", r"\[").replace("]", r"\]")):
            suite_from_dict({"group": [{**doc["group"][0], "pitches_deg": bad}]})


def _own_check_set(name: str, n: int, leave_out: tuple[str, ...] = ()) -> tuple[list, list]:
    """A check set's cases and every other suite's (but ``leave_out``), after checking that it
    has ``n`` cases and that no other suite uses its seeds or its placements."""
    from depthtouch.evaluation.suite import SUITES_DIR

    cases = list(load_suite(name).cases)
    others = [c for p in SUITES_DIR.glob("*.toml") if p.stem not in (name, *leave_out)
              for c in load_suite(p.stem).cases]
    assert len(cases) == n
    assert not {c.seed for c in cases} & {c.seed for c in others}
    assert not {placement(c) for c in cases} & {placement(c) for c in others}
    return cases, others


def _bodies_and_both_hands_on_both_halves(cases: list) -> None:
    """Every case with the body on, both hand models in every group, every group on both
    halves (the check sets from hard-fresh6 on)."""
    assert all(c.body for c in cases)
    for g in {c.group for c in cases}:
        assert {c.hand for c in cases if c.group == g} == {"capsule", "anatomic"}
    _every_group_on_both_halves(cases)


def _every_group_on_both_halves(cases: list) -> None:
    """Each of the cases' groups (situations) has cases on the tune and on the held-out half."""
    for group in {c.group for c in cases}:
        mine = [c for c in cases if c.group == group]
        assert select_half(mine, "tune") and select_half(mine, "held-out"), group


def test_fourth_check_set_has_its_own_seeds_and_placements_and_both_hands() -> None:
    """hard-fresh4: hard's scenes at placements and seeds no other suite uses, every group with
    both hand models."""
    cases, _ = _own_check_set("hard-fresh4", 56)
    assert {c.scene for c in cases} == {c.scene for c in load_suite("hard").cases}
    for g in {c.group for c in cases}:
        assert {c.hand for c in cases if c.group == g} == {"capsule", "anatomic"}
    assert select_half(cases, "tune") and select_half(cases, "held-out")


def test_held_stereo_check_set_repeats_the_held_fingers_at_new_placements() -> None:
    """hold-stereo: fingers held still on stereo at 1.05 and 1.15 m, both hands, at placements
    no other suite uses (so no recording of another suite), on both halves."""
    from depthtouch.evaluation.suite import SUITES_DIR

    cases = load_suite("hold-stereo").cases
    assert len(cases) == 16
    assert {(c.scene, c.camera) for c in cases} == {("stillholds", "realsense-d435-hard")}
    assert {c.distance_m for c in cases} == {1.05, 1.15}
    assert {c.hand for c in cases} == {"capsule", "anatomic"}
    others = {placement(c) for p in SUITES_DIR.glob("*.toml") if p.stem != "hold-stereo"
              for c in load_suite(p.stem).cases}
    assert not {placement(c) for c in cases} & others
    assert select_half(cases, "tune") and select_half(cases, "held-out")


def test_pitch55_check_set_fixes_the_pitch_at_placements_of_its_own() -> None:
    """pitch55: approaches at 55 deg, both hands, at placements and seeds no other suite uses,
    on both halves."""
    from depthtouch.evaluation.suite import SUITES_DIR

    cases = load_suite("pitch55").cases
    assert len(cases) == 16
    assert {c.pitch_deg for c in cases} == {55.0} and {c.scene for c in cases} == {"approach"}
    assert {c.hand for c in cases} == {"capsule", "anatomic"}
    others = [c for p in SUITES_DIR.glob("*.toml") if p.stem != "pitch55"
              for c in load_suite(p.stem).cases]
    assert not {placement(c) for c in cases} & {placement(c) for c in others}
    assert not {c.seed for c in cases} & {c.seed for c in others}
    assert select_half(cases, "tune") and select_half(cases, "held-out")


def test_motion_check_set_mixes_every_tof_frame_at_placements_of_its_own() -> None:
    """motion-tof: the hard ToF situations with 13 ms of motion mixing, both hands, at
    placements and seeds no other suite uses, every situation on both halves."""
    cases, others = _own_check_set("motion-tof", 36)
    assert {c.motion_ms for c in cases} == {13.0} and {c.camera for c in cases} == {"kinect-v2-hard"}
    assert {c.hand for c in cases} == {"capsule", "anatomic"}
    assert all("/motion13/" in c.label for c in cases)
    assert all(c.motion_ms == 0.0 for c in others)  # no other suite changed
    _every_group_on_both_halves(cases)


def test_skin_check_set_raises_the_hands_noise_at_placements_of_its_own() -> None:
    """skin-tof: the hard ToF situations with the hand's noise x 1.5 (and the incidence angle's),
    both hands, at placements and seeds no other suite uses (but rest-tof, made after it ran to
    try its forearm placement with other seeds), every situation on both halves; the hand's
    noise is raised nowhere else but in the resting-forearm sets made after it (rest-tof,
    rest-tof2, rest-tof3, hard-fresh6's forearm before ToF and hard-fresh7's)."""
    cases, others = _own_check_set("skin-tof", 40, leave_out=("rest-tof", "rest-tof2", "rest-tof3",
                                                               "hard-fresh6", "hard-fresh7"))
    assert {c.skin_noise for c in cases} == {1.5} and {c.camera for c in cases} == {"kinect-v2-hard"}
    assert {c.hand for c in cases} == {"capsule", "anatomic"}
    assert all("/skin1.5/" in c.label for c in cases)
    assert all(c.skin_noise == 1.0 for c in others)  # no other suite changed
    _every_group_on_both_halves(cases)


def test_fifth_check_set_has_its_own_seeds_and_placements_and_both_hands() -> None:
    """hard-fresh5: hard's scenes at placements and seeds no other suite uses, every group with
    both hand models (but drift-hold, made after it ran to try its placements with other
    seeds)."""
    cases, _ = _own_check_set("hard-fresh5", 56, leave_out=("drift-hold",))
    assert {c.scene for c in cases} == {c.scene for c in load_suite("hard").cases}
    for g in {c.group for c in cases}:
        assert {c.hand for c in cases if c.group == g} == {"capsule", "anatomic"}
    assert select_half(cases, "tune") and select_half(cases, "held-out")


def test_drift_hold_check_set_tries_fresh5s_misses_elsewhere_and_with_other_seeds() -> None:
    """drift-hold: drift and still fingers next to hard-fresh5's placements and at them, with
    seeds no other suite uses, both hands, every group on both halves."""
    from depthtouch.evaluation.suite import SUITES_DIR

    cases = load_suite("drift-hold").cases
    assert len(cases) == 60
    assert {c.scene for c in cases} == {"warmup", "stillholds"}
    others = [c for p in SUITES_DIR.glob("*.toml") if p.stem != "drift-hold"
              for c in load_suite(p.stem).cases]
    assert not {c.seed for c in cases} & {c.seed for c in others}
    fresh5 = {placement(c) for c in load_suite("hard-fresh5").cases}
    shared = {placement(c) for c in cases} & {placement(c) for c in others}
    assert shared and shared <= fresh5
    for group in {c.group for c in cases}:
        assert {c.hand for c in cases if c.group == group} == {"capsule", "anatomic"}
    _every_group_on_both_halves(cases)


def test_rest_tof_check_set_rests_forearms_before_every_camera_kind() -> None:
    """rest-tof: a forearm resting on the table before ToF (with and without the hand's noise
    x 1.5), structured light and a near stereo camera, at placements no other suite uses but
    skin-tof's own (whose held-out forearm rest it tries with other seeds), seeds no other
    suite uses, both hands, every group on both halves."""
    cases, others = _own_check_set("rest-tof", 48, leave_out=("skin-tof",))
    assert {c.scene for c in cases} == {"rest"}
    assert {c.camera for c in cases} == {"kinect-v2-hard", "kinect-v1-hard", "realsense-d435"}
    assert {c.hand for c in cases} == {"capsule", "anatomic"}
    skin = {placement(c) for c in load_suite("skin-tof").cases if c.group == "forearm-rest-skin"}
    assert {placement(c) for c in cases if c.group == "rest-at-skin"} == skin
    _every_group_on_both_halves(cases)


def test_long_hold_check_set_holds_one_finger_ten_seconds_before_every_camera_kind() -> None:
    """long-hold: the default suite's `hold` scene (one finger held 10 s, longer than the
    enclosure test's window and the doubt after it) at the hard profiles, at placements and
    seeds no other suite uses, both hands, every group on both halves."""
    cases, _ = _own_check_set("long-hold", 44)
    assert {c.scene for c in cases} == {"hold"}
    assert {c.camera for c in cases} == {"kinect-v2-hard", "realsense-d435-hard", "kinect-v1-hard"}
    for group in {c.group for c in cases}:
        assert {c.hand for c in cases if c.group == group} == {"capsule", "anatomic"}
    assert {c.pitch_deg for c in cases if c.group == "hold-steep"} == {55.0}
    _every_group_on_both_halves(cases)


@pytest.mark.parametrize(("name", "farthest_m"), [("rest-tof2", 1.22), ("rest-tof3", 1.3)])
def test_rest_tof_check_sets_rest_forearms_at_placements_of_their_own(name: str,
                                                                      farthest_m: float) -> None:
    """rest-tof2, and rest-tof3 (session 48's study set, up to 1.3 m): a forearm resting before
    ToF (with and without the hand's noise x 1.5) and structured light, at placements and seeds
    no other suite uses, both hands, every group on both halves."""
    cases, _ = _own_check_set(name, 36)
    assert {c.scene for c in cases} == {"rest"}
    assert {c.camera for c in cases} == {"kinect-v2-hard", "kinect-v1-hard"}
    for group in {c.group for c in cases}:
        assert {c.hand for c in cases if c.group == group} == {"capsule", "anatomic"}
    assert {c.skin_noise for c in cases if c.group == "rest-tof-skin"} == {1.5}
    assert max(c.distance_m for c in cases) == farthest_m
    _every_group_on_both_halves(cases)


def test_second_long_hold_check_set_holds_fingers_at_placements_of_its_own() -> None:
    """long-hold2: the `hold` scene (one finger held 10 s) at the hard profiles, at placements
    and seeds no other suite uses, both hands, steep fingers at 50 and 60 deg on ToF and
    stereo, every group on both halves."""
    cases, _ = _own_check_set("long-hold2", 52)
    assert {c.scene for c in cases} == {"hold"}
    assert {c.camera for c in cases} == {"kinect-v2-hard", "realsense-d435-hard", "kinect-v1-hard"}
    for group in {c.group for c in cases}:
        assert {c.hand for c in cases if c.group == group} == {"capsule", "anatomic"}
    steep = [c for c in cases if c.group == "hold-steep"]
    assert {c.pitch_deg for c in steep} == {50.0, 60.0}
    assert {c.camera for c in steep} == {"kinect-v2-hard", "realsense-d435-hard"}
    _every_group_on_both_halves(cases)


def test_sixth_check_set_brings_every_arm_in_with_a_body_at_placements_of_its_own() -> None:
    """hard-fresh6: hard's scenes (and a 10 s hold) with the body on, at placements and seeds no
    other suite uses, both hands, every situation on both halves."""
    cases, others = _own_check_set("hard-fresh6", 88)
    assert all("/body/" in c.label for c in cases)
    assert {c.scene for c in cases} == {c.scene for c in load_suite("hard").cases} | {"hold"}
    _bodies_and_both_hands_on_both_halves(cases)


def test_seventh_check_set_has_its_own_seeds_and_placements_and_two_harder_groups() -> None:
    """hard-fresh7: hard-fresh6's situations at placements and seeds no other suite uses, both
    hands, the body on, every situation on both halves; fingers at 55 deg, and a breathing ToF
    camera that drops frames and stereo over noisier skin beside them."""
    cases, _ = _own_check_set("hard-fresh7", 100)
    assert all("/body/" in c.label for c in cases)
    assert {c.scene for c in cases} == {c.scene for c in load_suite("hard").cases} | {"hold"}
    _bodies_and_both_hands_on_both_halves(cases)
    assert {c.pitch_deg for c in cases} == {None, 55.0}
    breathing = [c for c in cases if c.breathing_mm > 0]
    assert breathing and all(c.drop_rate == 0.05 and c.camera == "kinect-v2-hard"
                             for c in breathing)
    assert {c.skin_noise for c in cases if c.group == "noisy-skin-stereo"} == {2.0}


def test_missed_contacts_are_named_on_a_rendered_recording_and_in_the_report() -> None:
    """Stereo at 1.6 m over a table tilted 32 deg (a far scene of the hard suite, where Tl
    lies above a fingertip): every contact is missed, mostly with nothing in the band near
    it; each gets a reason, and the report prints them per half."""
    from depthtouch.evaluation.metrics import BAND_STATES
    from depthtouch.evaluation.suiterun import evaluate_case
    from depthtouch.tracking.evidence import REASONS

    case = SuiteCase("approach", "realsense-d435-hard", 1.6, "plane", 32.0, 1)
    (res,) = evaluate_case(case)
    assert not res.ep_found.any() and res.ep_visible.all()
    assert len(res.ep_miss_reason) == len(res.ep_found) == 4
    assert set(res.ep_miss_reason) <= {*REASONS, *BAND_STATES}
    assert res.ep_miss_reason.count("nothing in the band") >= 2
    suite = suite_from_dict({"suite": {"name": "t"}, "group": [
        {"name": "far", "scenes": ["approach"], "cameras": ["realsense-d435-hard"],
         "distances_m": [1.6], "tilts_deg": [32.0], "seeds": [1], "tags": ["far"]}]})
    rep = halves_report(suite, list(suite.cases), [res])
    lines = missed_lines(rep)
    assert len(lines) == 1 and lines[0].startswith(f"{half_of(case)}: missed 4 contacts")
    assert "nothing in the band" in lines[0]
    assert any("nothing in the band" in line for line in halves_markdown(rep))


def test_lift_check_set_holds_and_taps_at_its_own_placements() -> None:
    """lift-check: 10 s holds (ToF at range, steep fingers) and taps after a hover, at
    placements and seeds no other suite uses, bodies on, both hands in every group, every group
    on both halves."""
    cases, _ = _own_check_set("lift-check", 56)
    assert {c.scene for c in cases} == {"hold", "taps", "approach", "hovergroup"}
    _bodies_and_both_hands_on_both_halves(cases)
    assert {c.pitch_deg for c in cases if c.group in ("hold-steep", "taps-steep")} == {55.0, 60.0,
                                                                                       65.0}
