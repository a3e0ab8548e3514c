"""Matching and metrics on hand-built truth and events (exact cases, then error rows)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from depthtouch.errors import ConfigError, SourceError
from depthtouch.evaluation.metrics import (
    FrameNotes,
    evaluate,
    match,
    read_truth,
    surface_error_mm,
    truth_from_dict,
)
from depthtouch.evaluation.summary import summarize
from depthtouch.types import TouchEvent
from synth import result_of

FX = 500.0
CX, CY = 320.0, 240.0
Z = 1000.0  # plane facing the camera at 1 m
K = [[FX, 0.0, CX], [0.0, FX, CY], [0.0, 0.0, 1.0]]
MM_PER_PX = Z / FX  # 2 mm per pixel on the plane


def contact(cid: int, x: float, y: float) -> dict[str, Any]:
    return {"id": cid, "x": x, "y": y, "X": (x - CX) * MM_PER_PX, "Y": (y - CY) * MM_PER_PX,
            "Z": Z, "nx": 0.0, "ny": 0.0, "nz": -1.0}


def hover(hid: int, x: float, y: float, h: float) -> dict[str, Any]:
    return {"id": hid, "x": x, "y": y, "X": (x - CX) * MM_PER_PX, "Y": (y - CY) * MM_PER_PX,
            "Z": Z, "height_mm": h}


def doc(n: int, contacts: dict[int, list[dict[str, Any]]],
        hovers: dict[int, list[dict[str, Any]]] | None = None) -> dict[str, Any]:
    hovers = hovers or {}
    return {
        "format": "depthtouch-truth/1", "scene": "hand", "seed": 0,
        "camera": {"profile": "test", "resolution_wh": [640, 480], "K": K,
                   "depth_scale": 0.001, "fps": 30},
        "surface": {"kind": "plane", "distance_m": 1.0, "tilt_deg": 0.0},
        "empty_frames": 0,
        "frames": [{"frame": f, "t": f / 30, "contacts": contacts.get(f, []),
                    "hovers": hovers.get(f, [])} for f in range(n)],
        "events": [],
    }


def track(rid: int, frames: range, xy: Any, up: bool = True) -> list[TouchEvent]:
    """Events of one reported touch: down, moves, then up on the next frame."""
    out = []
    fl = list(frames)
    for k, f in enumerate(fl):
        x, y = xy(f) if callable(xy) else xy
        out.append(TouchEvent(f, f / 30, rid, "down" if k == 0 else "move", x, y))
    if up:
        x, y = xy(fl[-1]) if callable(xy) else xy
        out.append(TouchEvent(fl[-1] + 1, (fl[-1] + 1) / 30, rid, "up", x, y))
    return out


def tap_truth(n: int = 30, frames: range = range(5, 20), xy: tuple[float, float] = (300, 200)):
    return truth_from_dict(doc(n, {f: [contact(1, *xy)] for f in frames}))


def test_perfect_run_has_recall_one_and_zero_error() -> None:
    t = tap_truth()
    m = summarize([evaluate(t, track(9, range(5, 20), (300, 200)))])
    assert m.contact_recall == 1.0
    assert m.frame_recall == 1.0
    assert m.error_median_mm == pytest.approx(0.0, abs=1e-9)
    assert m.error_p95_mm == pytest.approx(0.0, abs=1e-9)
    assert m.false_touches == 0
    assert m.id_switches == 0
    assert m.down_latency_median_frames == 0
    assert m.lift_latency_median_frames == 0
    assert m.jitter_rms_mm == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(
    ("dx_px", "dy_px", "want_mm"),
    [(1.5, 0.0, 3.0), (0.0, -1.5, 3.0), (1.5, 2.0, 5.0), (9.0, 0.0, 18.0)],
)
def test_offset_gives_error_in_mm(dx_px: float, dy_px: float, want_mm: float) -> None:
    t = tap_truth()
    r = evaluate(t, track(9, range(5, 20), (300 + dx_px, 200 + dy_px)))
    m = summarize([r])
    assert m.contact_recall == 1.0
    assert m.error_median_mm == pytest.approx(want_mm, abs=1e-6)
    assert m.false_touches == 0


def test_beyond_gate_is_a_miss_and_a_false_touch() -> None:
    t = tap_truth()
    m = summarize([evaluate(t, track(9, range(5, 20), (300 + 11.0, 200)))])  # 22 mm away
    assert m.contact_recall == 0.0
    assert m.false_touches == 1
    assert m.false_by_hover == {"0-5": 0, "5-10": 0, "10-25": 0, "25-50": 0, "50+": 0,
                                "other": 1}
    assert math.isnan(m.error_median_mm)


def test_a_touch_down_while_its_finger_still_hovers_is_counted_as_early() -> None:
    """A track down from frame 1 over a finger descending 10 mm a frame from 40 mm (at frame
    0), matched once the contact begins at frame 5: found, not false, early from 30 mm. One that goes down on
    the contact's first frame is not early; neither is one near no hover before its match."""
    hov = {f: [hover(1, 300, 200, 40.0 - 10.0 * f)] for f in range(5)}
    t = truth_from_dict(doc(30, {f: [contact(1, 300, 200)] for f in range(5, 20)}, hov))
    m = summarize([evaluate(t, track(9, range(1, 20), (300, 200)))])
    assert m.contact_recall == 1.0 and m.false_touches == 0
    assert m.early_hover_heights_mm == (30.0,)
    assert m.early_from_hover_at_least(25.0) == 1 and m.early_from_hover_at_least(31.0) == 0
    on_time = summarize([evaluate(t, track(9, range(5, 20), (300, 200)))])
    assert on_time.early_hover_heights_mm == ()
    no_hover = summarize([evaluate(tap_truth(), track(9, range(2, 20), (300, 200)))])
    assert no_hover.early_hover_heights_mm == () and no_hover.contact_recall == 1.0


def test_tilted_plane_error_is_on_the_tangent_plane() -> None:
    # plane through P tilted 60 deg about the x axis: a 1 px step in y covers 2 mm / cos(60) = 4
    # mm on the plane (to first order; exact value from the ray-plane intersection)
    a = math.radians(60)
    n = np.array([[0.0, math.sin(a), -math.cos(a)]])
    p = np.array([[0.0, 0.0, Z]])
    d, q = surface_error_mm(np.array([[CX, CY + 1.0]]), np.asarray(K), p, n)
    y = 1.0 / FX  # ray direction (0, y, 1)
    s = Z * math.cos(a) / (-math.sin(a) * y + math.cos(a))  # n.P / n.r  (both signs as above)
    assert d[0, 0] == pytest.approx(math.hypot(s * y, s - Z), rel=1e-9)
    assert abs(d[0, 0] - 4.0) < 0.05
    assert q.shape == (1, 1, 3)


def test_hover_false_touch_is_attributed_by_height() -> None:
    hov = {f: [hover(7, 400, 100, 25.0), hover(8, 100, 400, 50.0)] for f in range(30)}
    t = truth_from_dict(doc(30, {}, hov))
    ev = track(3, range(10, 14), (401, 100)) + track(4, range(2, 4), (600, 50))
    m = summarize([evaluate(t, ev)])
    assert m.false_touches == 2
    assert m.false_by_hover["25-50"] == 1
    assert m.false_by_hover["50+"] == 0
    assert m.false_by_hover["other"] == 1
    assert m.false_hover_heights_mm == (25.0,)
    assert m.false_from_hover_at_least(25.0) == 1
    assert m.false_from_hover_at_least(30.0) == 0
    assert m.false_per_min == pytest.approx(2 / (1.0 / 60.0))
    assert math.isnan(m.contact_recall)


def test_id_switch_is_counted_once_per_change() -> None:
    t = tap_truth()
    ev = track(1, range(5, 10), (300, 200)) + track(2, range(10, 20), (300, 200))
    r = evaluate(t, ev)
    assert r.ep_id_switches.tolist() == [1]
    # the first track's up comes while the contact persists: its lift is not the episode's lift
    assert r.ep_lift_latency.tolist() == [0.0]
    m = summarize([r])
    assert m.id_switches == 1
    assert m.false_touches == 0


@pytest.mark.parametrize(
    ("start", "end", "down", "lift"),
    [(5, 20, 0, 0), (7, 20, 2, 0), (6, 23, 1, 3), (5, 18, 0, -2)],
)
def test_latency_counting(start: int, end: int, down: int, lift: int) -> None:
    t = tap_truth(frames=range(5, 20))  # contact frames 5..19
    r = evaluate(t, track(9, range(start, end), (300, 200)))
    assert r.ep_down_latency.tolist() == [down]
    assert r.ep_lift_latency.tolist() == [lift]
    assert r.ep_found.tolist() == [True]


def test_frame_recall_skips_settle_frames() -> None:
    t = tap_truth(frames=range(5, 20))  # 15 contact frames, 13 scored
    r = evaluate(t, track(9, range(7, 20), (300, 200)), settle_frames=2)
    assert summarize([r]).frame_recall == 1.0
    r = evaluate(t, track(9, range(8, 20), (300, 200)), settle_frames=2)
    assert summarize([r]).frame_recall == pytest.approx(12 / 13)


def test_missing_episode_lowers_recall() -> None:
    contacts = {f: [contact(1, 300, 200)] for f in range(5, 10)}
    for f in range(15, 20):
        contacts[f] = [contact(2, 100, 100)]
    t = truth_from_dict(doc(30, contacts))
    m = summarize([evaluate(t, track(9, range(5, 10), (300, 200)))])
    assert m.contacts == 2
    assert m.contact_recall == 0.5
    assert math.isnan(m.lift_latency_p95_frames) is False


@pytest.mark.parametrize(("one_track", "merged"), [(True, 1), (False, 0)])
def test_two_taps_under_one_id_count_as_merged(one_track: bool, merged: int) -> None:
    """Two taps at one spot: a touch kept down through the lift between them is one touch to an
    app (a merge); a touch that goes up and comes back with a new id is two."""
    contacts = {f: [contact(1, 300, 200)] for f in range(5, 12)}
    contacts.update({f: [contact(2, 300, 200)] for f in range(20, 27)})
    t = truth_from_dict(doc(35, contacts))
    ev = (track(4, range(5, 27), (300, 200)) if one_track
          else track(4, range(5, 12), (300, 200)) + track(5, range(20, 27), (300, 200)))
    r = evaluate(t, ev)
    assert r.ep_merged.tolist() == [False, bool(merged)]
    m = summarize([r])
    assert m.merged_contacts == merged
    assert m.contact_recall == 1.0
    assert m.lift_latency_median_frames == (7.5 if one_track else 0.0)  # (15 + 0) / 2


def test_two_contacts_are_assigned_optimally() -> None:
    # greedy nearest-first would pair reported A with contact 2 and leave contact 1 unmatched
    contacts = {f: [contact(1, 300, 200), contact(2, 308, 200)] for f in range(5, 10)}
    t = truth_from_dict(doc(20, contacts))
    ev = track(1, range(5, 10), (296, 200)) + track(2, range(5, 10), (305, 200))
    m = summarize([evaluate(t, ev)])
    assert m.contact_recall == 1.0
    assert m.false_touches == 0
    assert m.error_median_mm == pytest.approx(7.0)


def test_match_respects_gate() -> None:
    d = np.array([[1.0, 30.0], [25.0, 2.0], [0.5, 40.0]])
    r, c = match(d, 20.0)
    assert sorted(zip(r.tolist(), c.tolist(), strict=True)) == [(1, 1), (2, 0)]
    r, c = match(np.zeros((0, 3)), 20.0)
    assert r.size == 0 and c.size == 0


def test_angle_error_of_a_drag() -> None:
    # true path along +x at 2 px (4 mm) per frame; reported path along a 10 deg line
    n = 40
    contacts = {f: [contact(1, 200 + 2 * (f - 5), 200)] for f in range(5, 30)}
    t = truth_from_dict(doc(n, contacts))
    tan = math.tan(math.radians(10))
    ev = track(1, range(5, 30), lambda f: (200 + 2 * (f - 5), 200 + 2 * (f - 5) * tan))
    m = summarize([evaluate(t, ev)])
    assert m.drags == 1
    assert m.angle_error_deg == pytest.approx(10.0, abs=1e-6)
    exact = summarize([evaluate(t, track(1, range(5, 30), lambda f: (200 + 2 * (f - 5), 200)))])
    assert exact.angle_error_deg == pytest.approx(0.0, abs=1e-4)


def test_angle_error_steps_span_three_frames_by_default() -> None:
    # true path along +x at 2 px per frame; the report zig-zags 1 px across it with period 3,
    # so every 3-frame step is exact while the frame-to-frame steps turn by 26.6 or 45 deg
    n = 40
    contacts = {f: [contact(1, 200 + 2 * (f - 5), 200)] for f in range(5, 30)}
    t = truth_from_dict(doc(n, contacts))
    zig = (0.0, 1.0, -1.0)
    ev = track(1, range(5, 30), lambda f: (200 + 2 * (f - 5), 200 + zig[(f - 5) % 3]))
    assert summarize([evaluate(t, ev)]).angle_error_deg == pytest.approx(0.0, abs=1e-6)
    one = summarize([evaluate(t, ev, angle_step_frames=1)]).angle_error_deg
    want = (math.degrees(math.atan(0.5)) * 2 + 45.0) / 3  # +1, -2, +1 px per 2 px step
    assert one == pytest.approx(want, abs=0.5)
    with pytest.raises(ConfigError, match="angle_step_frames"):
        evaluate(t, ev, angle_step_frames=0)


def test_jitter_of_a_still_finger() -> None:
    rng = np.random.default_rng(1)
    noise = rng.normal(0.0, 0.5, size=(60, 2))  # px -> 1 mm per axis
    t = tap_truth(n=70, frames=range(5, 65))
    ev = track(1, range(5, 65), lambda f: (300 + noise[f - 5, 0], 200 + noise[f - 5, 1]))
    m = summarize([evaluate(t, ev)])
    want = math.sqrt(np.mean(np.sum((noise - noise.mean(axis=0)) ** 2, axis=1))) * MM_PER_PX
    assert m.jitter_rms_mm == pytest.approx(want, rel=1e-6)


def test_pooling_over_recordings() -> None:
    t = tap_truth()
    a = evaluate(t, track(1, range(5, 20), (300, 200)), timing_ms=[1.0, 2.0, 3.0])
    b = evaluate(t, [], timing_ms=[5.0])
    m = summarize([a, b])
    assert m.recordings == 2
    assert m.contacts == 2
    assert m.contact_recall == 0.5
    assert m.ms_per_frame_median == 2.5
    d = m.to_dict()
    assert json.loads(json.dumps(d))["contact_recall"] == 0.5
    assert d["angle_error_deg"] is None


def _bad(mutate: Any) -> dict[str, Any]:
    d = doc(3, {1: [contact(1, 300, 200)]}, {2: [hover(7, 1, 1, 25.0)]})
    mutate(d)
    return d


@pytest.mark.parametrize(
    ("mutate", "needle"),
    [
        (lambda d: d.update(format="other/1"), "format"),
        (lambda d: d.pop("camera"), "camera"),
        (lambda d: d["camera"].update(K=[[1, 0], [0, 1]]), "camera.K"),
        (lambda d: d["camera"].update(K="abc"), "camera.K"),
        (lambda d: d["camera"].update(fps=0), "fps"),
        (lambda d: d.update(frames=[]), "frames"),
        (lambda d: d["frames"][1].update(frame=0), "frame"),
        (lambda d: d["frames"][1]["contacts"][0].pop("nz"), "'nz'"),
        (lambda d: d["frames"][1]["contacts"][0].update(X="a"), "X"),
        (lambda d: d["frames"][1]["contacts"][0].update(nx=0, ny=0, nz=0), "normal"),
        (lambda d: d["frames"][2].update(hovers={"id": 1}), "hovers"),
        (lambda d: d["frames"][2]["hovers"][0].pop("height_mm"), "height_mm"),
        (lambda d: d.update(empty_frames=-1), "empty_frames"),
    ],
)
def test_bad_truth_documents_raise_one_line_source_error(mutate: Any, needle: str) -> None:
    with pytest.raises(SourceError) as ei:
        truth_from_dict(_bad(mutate))
    msg = str(ei.value)
    assert needle in msg
    assert "\n" not in msg


@pytest.mark.parametrize(
    ("content", "needle"),
    [(None, "no such truth file"), ("{not json", "not valid JSON"), ("[1, 2]", "JSON object"),
     (b"\xff\xfe\x00", "cannot read")],
)
def test_bad_truth_files_raise_one_line_source_error(
    tmp_path: Path, content: str | bytes | None, needle: str
) -> None:
    p = tmp_path / "t.json"
    if isinstance(content, bytes):
        p.write_bytes(content)
    elif content is not None:
        p.write_text(content)
    with pytest.raises(SourceError) as ei:
        read_truth(p)
    assert needle in str(ei.value)
    assert "\n" not in str(ei.value)


def test_read_truth_round_trip(tmp_path: Path) -> None:
    p = tmp_path / "t.json"
    p.write_text(json.dumps(doc(3, {1: [contact(1, 300, 200)]})))
    t = read_truth(p)
    assert t.n_frames == 3
    assert t.contact_frame.tolist() == [1]
    assert t.hover_n.shape == (0, 3)


def test_unknown_event_state_is_an_error() -> None:
    with pytest.raises(SourceError, match="unknown"):
        evaluate(tap_truth(), [TouchEvent(1, 0.0, 1, "hold", 1.0, 1.0)])  # type: ignore[arg-type]


def test_cli_eval_events_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from depthtouch.cli import main
    from depthtouch.outputs.jsonl import JsonlSink
    from depthtouch.types import Frame

    truth = tmp_path / "t.json"
    truth.write_text(json.dumps(doc(30, {f: [contact(1, 300, 200)] for f in range(5, 20)})))
    events = tmp_path / "e.jsonl"
    with JsonlSink(events) as sink:
        frame = Frame(np.zeros((8, 8), np.uint16), 0.0, 0)
        sink.send(result_of(frame, track(4, range(6, 20), (301.5, 200))))
    assert main(["eval", "--events", str(events), "--truth", str(truth), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    m = out["e.jsonl"]
    assert m["contact_recall"] == 1.0
    assert m["error_median_mm"] == pytest.approx(3.0)
    assert m["down_latency_median_frames"] == 1.0


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["eval"], "needs --truth"),
        (["eval", "x.npz"], "needs --truth"),
        (["eval", "--events", "e.jsonl", "--truth", "missing.json"], "no such truth file"),
        (["eval", "--suite", "nosuch"], "unknown suite"),
        (["eval", "--suite", "default", "--truth", "t.json"], "not both"),
    ],
)
def test_cli_eval_errors_are_one_line(
    argv: list[str], needle: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from depthtouch.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert needle in err
    assert err.count("\n") == 1


def test_events_beyond_the_truth_are_an_error() -> None:
    with pytest.raises(SourceError, match="events reach frame 39 but the truth has 30 frames"):
        evaluate(tap_truth(n=30), track(1, range(35, 40), (300, 200), up=False))


@pytest.mark.parametrize("gate", [0.0, -1.0, float("nan")])
def test_bad_gate_is_a_config_error(gate: float) -> None:
    from depthtouch.errors import ConfigError

    with pytest.raises(ConfigError, match="gate_mm"):
        evaluate(tap_truth(), [], gate_mm=gate)


def test_occluded_contacts_leave_recall_and_frame_recall() -> None:
    contacts = {f: [contact(1, 300, 200)] for f in range(5, 15)}
    for f in range(20, 30):
        contacts[f] = [dict(contact(2, 100, 100), occluded=True)]
    for f in range(10, 15):  # the first contact is hidden in its last 5 frames
        contacts[f][0]["occluded"] = True
    t = truth_from_dict(doc(40, contacts))
    m = summarize([evaluate(t, track(9, range(5, 10), (300, 200)), settle_frames=2)])
    assert m.contacts == 1
    assert m.occluded_contacts == 1
    assert m.contact_recall == 1.0
    assert m.frame_recall == 1.0  # frames 7, 8, 9 scored; the hidden 10..14 are not


def test_occluded_must_be_a_bool() -> None:
    d = doc(3, {1: [dict(contact(1, 300, 200), occluded="yes")]})
    with pytest.raises(SourceError, match="occluded"):
        truth_from_dict(d)


def test_a_missed_contact_is_named_by_its_frames_notes() -> None:
    """Each missed contact takes the reason most of its frames give: the nearest point's
    within the gate, or what the band held there; a found one gets none."""
    contacts = {f: [contact(1, 300, 200)] for f in range(5, 15)}
    for f in range(20, 30):
        contacts[f] = [contact(2, 100, 100)]
    for f in range(35, 45):
        contacts[f] = [contact(3, 500, 300)]
    t = truth_from_dict(doc(50, contacts))
    far = np.array([[300.0, 260.0]])  # 60 px = 120 mm away: beyond the gate
    notes = {f: FrameNotes(np.array([[301.0, 200.0], [50.0, 50.0]]), ["high step", "counted"])
             for f in range(5, 12)}
    notes |= {f: FrameNotes(np.array([[301.0, 200.0]]), ["level behind"]) for f in range(12, 15)}
    notes |= {f: FrameNotes(far, ["counted"], np.array([[100.0, 100.0]]),
                            ["band erased by the opening"]) for f in range(20, 27)}
    notes |= {f: FrameNotes(far, ["counted"]) for f in range(27, 30)}
    notes |= {f: FrameNotes(np.array([[500.0, 300.0]]), ["counted"]) for f in range(35, 45)}
    res = evaluate(t, track(7, range(35, 45), (500, 300)), point_notes=notes)
    assert res.ep_miss_reason == ("high step", "band erased by the opening", "")
    m = summarize([res, res])
    assert m.missed_by_reason == {"high step": 2, "band erased by the opening": 2}
    # frames noted without a probe of the contact: "no point"
    notes |= {f: FrameNotes(far, ["counted"]) for f in range(20, 27)}
    assert evaluate(t, [], point_notes=notes).ep_miss_reason[1] == "no point"
    # without notes: no reasons, and the other figures the same
    plain = evaluate(t, track(7, range(35, 45), (500, 300)))
    assert plain.ep_miss_reason == ()
    assert summarize([plain]).missed_by_reason == {}
    assert summarize([plain]).contact_recall == summarize([res]).contact_recall


def test_a_contact_hidden_in_some_frames_is_named_by_its_visible_ones() -> None:
    contacts = {f: [contact(1, 300, 200) | {"occluded": f < 10}] for f in range(5, 15)}
    t = truth_from_dict(doc(30, contacts))
    notes = {f: FrameNotes(np.array([[300.0, 200.0]]), ["tip too high"]) for f in range(5, 10)}
    notes |= {f: FrameNotes(np.array([[300.0, 200.0]]), ["weak (size)"]) for f in range(10, 12)}
    res = evaluate(t, [], point_notes=notes)
    # frames 5-9 are hidden (their notes do not count); of 10-14: weak 2, no point 3
    assert res.ep_miss_reason == ("no point",)
