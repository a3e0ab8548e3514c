"""The committed suite: loading (with error rows), caching, and the accuracy floors.

The floors are the levels measured on this simulator and pipeline (docs/accuracy.md), asserted
with a small margin. By default the ``quick`` subset runs; ``pytest -m slow`` runs the full
default suite against the issue's acceptance levels.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import pytest

from depthtouch.errors import ConfigError
from depthtouch.evaluation.metrics import evaluate
from depthtouch.evaluation.suite import (
    SuiteCase,
    ensure_recording,
    load_suite,
    recording_paths,
    suite_from_dict,
)
from depthtouch.evaluation.suiterun import group_metrics, run_cases
from depthtouch.evaluation.summary import Metrics, summarize

sim = pytest.importorskip("depthtouch.sim")


def _group(**kw: Any) -> dict[str, Any]:
    g: dict[str, Any] = {"name": "g", "scenes": ["taps"], "cameras": ["kinect-v2"],
                         "distances_m": [1.0], "seeds": [1]}
    g.update(kw)
    return g


@pytest.mark.parametrize(
    ("data", "needle"),
    [
        ({"group": [_group()]}, None),
        ({"suite": {"gate_mm": 0}, "group": [_group()]}, "gate_mm"),
        ({"suite": []}, "[suite]"),
        ({}, "no [[group]]"),
        ({"group": [_group(scenes=["nosuch"])]}, "unknown 'nosuch'"),
        ({"group": [_group(cameras=["kinect-v9"])]}, "unknown 'kinect-v9'"),
        ({"group": [_group(scenes=[])]}, "non-empty list"),
        ({"group": [_group(distances_m=[9.0])]}, "out of range"),
        ({"group": [_group(tilts_deg=["a"])]}, "out of range"),
        ({"group": [_group(surfaces=["sphere"])]}, "unknown 'sphere'"),
        ({"group": [_group(seeds=[-1])]}, "seeds"),
        ({"group": [_group(colour="red")]}, "unknown key 'colour'"),
        ({"group": [_group(tags="quick")]}, "tags"),
        ({"group": [{"name": "x", "scenes": ["taps"]}]}, "cameras is missing"),
    ],
)
def test_suite_from_dict(data: dict[str, Any], needle: str | None) -> None:
    if needle is None:
        s = suite_from_dict(data)
        assert s.cases == (SuiteCase("taps", "kinect-v2", 1.0, "plane", 0.0, 1, 30.0, "g"),)
        return
    with pytest.raises(ConfigError) as ei:
        suite_from_dict(data)
    assert needle in str(ei.value)
    assert "\n" not in str(ei.value)


def test_duplicate_cases_merge_and_keep_tags() -> None:
    s = suite_from_dict({"group": [_group(), _group(name="q", tags=["quick"])]})
    assert len(s.cases) == 1
    assert s.select("quick") == list(s.cases)
    with pytest.raises(ConfigError, match="no subset 'nope'"):
        s.select("nope")


@pytest.mark.parametrize(
    ("text", "needle"),
    [("[suite\n", "not valid TOML"), (None, "does not exist")],
)
def test_load_suite_file_errors(tmp_path: Path, text: str | None, needle: str) -> None:
    p = tmp_path / "s.toml"
    if text is not None:
        p.write_text(text)
    with pytest.raises(ConfigError, match=needle):
        load_suite(p)


def test_default_suite_covers_scenes_cameras_and_surfaces() -> None:
    s = load_suite("default")
    cases = s.select()
    assert {c.scene for c in cases} == set(sim.SCENES)
    assert {c.camera for c in cases} == set(sim.CAMERAS)
    assert {c.surface for c in cases} >= {"plane", "cylinder-convex", "cylinder-concave"}
    assert any(c.tilt_deg > 0 for c in cases)
    assert len({c.distance_m for c in cases}) >= 3
    quick = s.select("quick")
    assert 0 < len(quick) < len(cases)
    assert len({c.cache_key() for c in cases}) == len(cases)


def test_cache_key_depends_on_parameters() -> None:
    a = SuiteCase("taps", "kinect-v2", 1.0, seed=1)
    assert a.cache_key() == SuiteCase("taps", "kinect-v2", 1.0, seed=1, group="x").cache_key()
    assert a.cache_key() != SuiteCase("taps", "kinect-v2", 1.0, seed=2).cache_key()
    assert a.cache_key() != SuiteCase("taps", "kinect-v2", 1.2, seed=1).cache_key()


@pytest.mark.slow  # writing a compressed recording takes ~25 s of CPU
def test_recording_is_rendered_once_and_cached(tmp_path: Path) -> None:
    case = SuiteCase("taps", "kinect-v2", 1.0, seed=5)
    rec, truth = ensure_recording(case, tmp_path)
    assert rec.is_file() and truth.is_file()
    assert (rec, truth) == recording_paths(case, tmp_path)
    ino, mtime = rec.stat().st_ino, rec.stat().st_mtime_ns
    assert ensure_recording(case, tmp_path) == (rec, truth)
    # not written again (a new recording is renamed into place: another inode), marked used
    assert rec.stat().st_ino == ino and rec.stat().st_mtime_ns >= mtime


# --- floors --------------------------------------------------------------------------------------
# FLOOR_*: the levels measured on this simulator and pipeline (docs/accuracy.md), with a margin;
# a regression below them fails. ACCEPTANCE: the targets for the full default suite.
# measured 06:45 UTC (quick: recall 1.00, frame recall 0.98, 0 false, err 2.88 / 7.50 mm, 1 id
# switch, down latency 1; full: recall 0.985, frame recall 0.98, 28 false, err 2.63 / 7.72 mm,
# 7 id switches, down latency 1); after merged fingertips are split and tracked as pairs,
# measured 07:55 UTC (quick: recall 1.00, frame recall 1.00, 0 false, err 2.61 / 5.61 mm, 0 id
# switches, down latency 1; full: recall 0.985, frame recall 0.989, 27 false, err 2.62 / 7.11 mm,
# 0 id switches, down latency 1); with the point moved beneath the tip (session 8), full: err
# 1.26 / 4.79 mm
FLOOR_QUICK = {"recall": 0.98, "frame_recall": 0.95, "err_med": 3.3, "err_p95": 8.5,
               "id_switches": 1, "down": 1.5, "false": 2}
FLOOR_FULL = {"recall": 0.97, "frame_recall": 0.96, "err_med": 1.6, "err_p95": 5.5,
              "id_switches": 2, "down": 1.5, "false": 40}
ACCEPTANCE = {"recall": 0.98, "frame_recall": 0.0, "err_med": 4.0, "err_p95": 10.0,
              "id_switches": 0, "down": 2.0, "false": 10**9}


def _failures(m: Metrics, floor: dict[str, float]) -> list[str]:
    checks = [
        ("contact recall", m.contact_recall, ">=", floor["recall"]),
        ("frame recall", m.frame_recall, ">=", floor["frame_recall"]),
        ("false touches from hovers >= 25 mm", m.false_from_hover_at_least(25.0), "<=", 0),
        ("false touches", m.false_touches, "<=", floor["false"]),
        ("median error mm", m.error_median_mm, "<=", floor["err_med"]),
        ("p95 error mm", m.error_p95_mm, "<=", floor["err_p95"]),
        ("id switches", m.id_switches, "<=", floor["id_switches"]),
        ("median touch-down latency frames", m.down_latency_median_frames, "<=", floor["down"]),
    ]
    return [f"{name} = {v:.3f}, want {op} {lim}" for name, v, op, lim in checks
            if not (v >= lim if op == ">=" else v <= lim)]


@functools.lru_cache(maxsize=2)  # the two slow tests share one run of the full suite
def _run(subset: str | None) -> Metrics:
    s = load_suite("default")
    cases = s.select(subset)
    results = run_cases(cases, gate_mm=s.gate_mm, workers=2)
    assert set(group_metrics(cases, results, "scene")) == {c.scene for c in cases}
    return summarize(results)


def test_quick_subset_meets_the_measured_floors() -> None:
    assert _failures(_run("quick"), FLOOR_QUICK) == []


@pytest.mark.slow
def test_full_default_suite_meets_the_measured_floors() -> None:
    assert _failures(_run(None), FLOOR_FULL) == []


@pytest.mark.slow
def test_full_default_suite_meets_the_acceptance_levels() -> None:
    assert _failures(_run(None), ACCEPTANCE) == []


def test_cli_eval_of_a_recording_file_matches_the_in_memory_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    import numpy as np

    from depthtouch.cli import main
    from depthtouch.evaluation.metrics import truth_from_dict
    from depthtouch.evaluation.suiterun import run_source
    from depthtouch.sources import ArraySource, write_npz

    rec = sim.render_scene("taps", camera="kinect-v2", distance_m=1.0, seed=7)
    n = 90  # the empty surface and the first taps; keeps the compressed file quick to write
    doc = dict(rec.truth, frames=rec.truth["frames"][:n])
    truth = truth_from_dict(doc)
    assert truth.contact_frame.size > 0
    write_npz(tmp_path / "r.npz", rec.depth[:n], rec.timestamps_s[:n], rec.depth_scale_m, rec.K)
    (tmp_path / "r.truth.json").write_text(json.dumps(doc))
    assert main(["eval", str(tmp_path / "r.npz"), "--truth", str(tmp_path / "r.truth.json"),
                 "--json"]) == 0
    got = json.loads(capsys.readouterr().out)["r.npz"]
    short = type(rec)(rec.depth[:n], rec.timestamps_s[:n], rec.depth_scale_m, rec.K, doc)
    events, _ = run_source(ArraySource.of_recording(short), None)
    want = summarize([evaluate(truth, events)]).to_dict()
    for k in ("contacts", "contact_recall", "frame_recall", "false_touches", "error_median_mm",
              "id_switches", "down_latency_median_frames"):
        assert got[k] == want[k], k
    assert got["contact_recall"] > 0
    assert np.isfinite(got["ms_per_frame_median"])
