"""Filter replay: the events a replay rebuilds are the pipeline's own with that filter."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from depthtouch.config import FilterConfig, PipelineConfig
from depthtouch.evaluation.filterreplay import FilterTap, record_case, replay, replay_events
from depthtouch.evaluation.suite import SuiteCase
from depthtouch.evaluation.suiterun import evaluate_case, run_source
from depthtouch.sim import render_scene
from depthtouch.sources.base import ArraySource
from depthtouch.tracking.filters import make_filter

CASE = SuiteCase(scene="multitouch", camera="kinect-v2", distance_m=1.0, seed=3)


@pytest.fixture(scope="module")
def record():
    return record_case(CASE)


def test_tap_passes_measurements_through_and_keeps_every_call():
    tap = FilterTap()
    ids, xy = np.array([4, 7]), np.array([[1.0, 2.0], [3.0, 4.0]])
    out = tap.update(ids, xy, 0.5)
    out[0, 0] = 99.0  # the caller's copy, not the tap's record
    tap.drop(np.array([4]))
    tap.reset()
    assert [c[0] for c in tap.calls] == ["update", "drop", "reset"]
    assert tap.calls[0][1] == 0.5
    np.testing.assert_array_equal(tap.calls[0][3], [[1.0, 2.0], [3.0, 4.0]])
    np.testing.assert_array_equal(tap.calls[1][1], [4])


@pytest.mark.parametrize("name", ["adaptive_euro", "one_euro", "kalman", "none"])
def test_replay_gives_the_pipelines_own_events(record, name):
    rec = render_scene(CASE.scene, **CASE.render_kwargs())
    cfg = dataclasses.replace(PipelineConfig(), filter=FilterConfig(name))
    want, _ = run_source(ArraySource.of_recording(rec, CASE.label), cfg)
    got = replay_events(record, make_filter(FilterConfig(name)))
    assert len(want) > 20 and any(e.state == "up" for e in want)
    assert [(e.frame, e.id, e.state) for e in got] == [(e.frame, e.id, e.state) for e in want]
    np.testing.assert_allclose([(e.x, e.y) for e in got], [(e.x, e.y) for e in want],
                               rtol=0, atol=1e-9)
    assert all("X" not in e.extra and "area" in e.extra for e in got)


def test_replay_scores_as_the_suite_does(record):
    metrics, results = replay([record], "adaptive_euro")
    (direct,) = evaluate_case(CASE)
    assert results[0].still_count == direct.still_count
    assert results[0].still_sq_sum_mm2 == pytest.approx(direct.still_sq_sum_mm2, rel=1e-9)
    np.testing.assert_allclose(results[0].errors_mm, direct.errors_mm, rtol=0, atol=1e-9)
    assert metrics.contacts == int(direct.ep_visible.sum())


def test_a_different_filter_moves_the_replayed_points(record):
    smooth = replay_events(record, make_filter("lowpass"))
    raw = replay_events(record, make_filter("none"))
    diff = [abs(a.x - b.x) + abs(a.y - b.y) for a, b in zip(smooth, raw, strict=True)]
    assert max(diff) > 0.5


def test_a_record_from_the_suite_cache_is_the_rendered_one(record, tmp_path):
    """``record_case(..., cache=)`` reads the recording the cache holds (writing it there
    first): the same calls to the filter and the same events as a case rendered in memory."""
    cached = record_case(CASE, cache=tmp_path)
    assert any(p.suffix == ".npz" for p in (tmp_path / "suite").iterdir())
    assert [c[0] for c in cached.calls] == [c[0] for c in record.calls]
    for a, b in zip(cached.calls, record.calls, strict=True):
        if a[0] == "update":
            assert a[1] == b[1]
            np.testing.assert_array_equal(a[2], b[2])
            np.testing.assert_allclose(a[3], b[3], rtol=0, atol=1e-9)
    assert [(e.frame, e.id, e.state) for e in cached.events] == [
        (e.frame, e.id, e.state) for e in record.events]
