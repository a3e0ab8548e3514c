"""Bootstrap intervals of a half's figures over its recordings (``eval --half H --ci N``)."""

from __future__ import annotations

import pytest
from test_evaluation import contact, doc, track
from test_halves import _recording

from depthtouch.errors import ConfigError
from depthtouch.evaluation.bootstrap import (
    CI_KEYS,
    bootstrap_intervals,
    check_resamples,
    paired_intervals,
)
from depthtouch.evaluation.halves import (
    HALVES,
    compare_report,
    compare_rows,
    figures,
    halves_markdown,
    halves_report,
    overall_rows,
)
from depthtouch.evaluation.metrics import evaluate, truth_from_dict
from depthtouch.evaluation.suite import suite_from_dict


def _still(offset_px: float):
    """A still contact whose reported point moves by ``offset_px`` half way through (jitter)."""
    c = {f: [contact(1, 300, 200)] for f in range(5, 25)}
    ev = track(1, range(5, 25), lambda f: (300 + (offset_px if f >= 15 else 0.0), 200))
    return evaluate(truth_from_dict(doc(40, c)), ev)


def test_identical_recordings_give_a_point_interval() -> None:
    rs = [_recording(True)] * 6
    iv = bootstrap_intervals(rs, figures, [False] * 6, [False] * 6, resamples=200)
    f = figures(rs, [False] * 6, [False] * 6)
    assert set(iv) == set(CI_KEYS)
    assert iv["recall_working"] == [1.0, 1.0]
    assert iv["error_median_mm"] == [f["error_median_mm"], f["error_median_mm"]]
    assert iv["recall_drift"] is None  # no drift recordings: nothing to resample
    assert iv["angle_error_deg"] is None  # no drags


def test_intervals_follow_the_spread_of_recordings_and_are_reproducible() -> None:
    rs = [_recording(True), _recording(False)] * 4
    far, drift = [False] * 8, [False] * 8
    iv = bootstrap_intervals(rs, figures, far, drift, resamples=500, seed=3)
    lo, hi = iv["recall_working"]
    # 8 recordings, half of them found: the number found in a resample is Binomial(8, 1/2),
    # whose central 95 % runs from 1 to 7
    assert [lo, hi] == [0.125, 0.875]
    assert iv == bootstrap_intervals(rs, figures, far, drift, resamples=500, seed=3)


def test_one_jittery_recording_widens_the_jitter_interval() -> None:
    calm = [_still(0.0) for _ in range(5)]
    assert figures(calm, [False] * 5)["jitter_rms_mm"] == 0.0
    rs = [*calm, _still(6.0)]
    f = figures(rs, [False] * 6)
    lo, hi = bootstrap_intervals(rs, figures, [False] * 6, [False] * 6, resamples=400)[
        "jitter_rms_mm"]
    assert lo == 0.0 and f["jitter_rms_mm"] < hi  # a resample without it is still; more of it
    assert f["jitter_rms_mm"] > 0.0


def test_report_gives_each_half_its_interval_and_the_tables_show_it() -> None:
    suite = suite_from_dict({"suite": {"name": "t"}, "group": [
        {"name": "near", "scenes": ["approach"], "cameras": ["kinect-v2-hard"],
         "distances_m": [1.0], "seeds": [1, 2, 3, 4]},
    ]})
    cases = list(suite.cases)
    results = [_recording(i % 3 != 0) for i in range(len(cases))]
    plain = halves_report(suite, cases, results)
    rep = halves_report(suite, cases, results, ci=200)
    for h in HALVES:
        f = dict(rep["overall"][h])
        iv = f.pop("ci95")
        assert f == plain["overall"][h]
        assert set(iv) == set(CI_KEYS)
    assert all("ci95" not in f for block in rep["situations"].values() for f in block.values())
    recall_row = overall_rows(rep)[2]
    assert recall_row[0] == "contact recall, working range"
    assert all("(" in cell and cell.endswith(")") for cell in recall_row[1:])
    assert "(" not in overall_rows(plain)[2][1]
    assert any("(" in line for line in halves_markdown(rep))
    assert overall_rows(rep)[0] == overall_rows(plain)[0]  # counts get no interval


@pytest.mark.parametrize("n", [0, 99, 100_001])
def test_resamples_out_of_range_are_refused(n: int) -> None:
    with pytest.raises(ConfigError, match="out of range; give 100-100000 resamples"):
        check_resamples(n)
    assert check_resamples(1000) == 1000


def test_paired_intervals_cancel_what_the_draw_adds_to_both() -> None:
    """B finds one contact more than A on one recording of eight: the draw moves both recalls
    by as much as 0.375, their difference only by what that recording adds."""
    a = [_recording(True), _recording(False)] * 4
    b = [_recording(True)] + a[1:]
    b[1] = _recording(True)
    far, drift = [False] * 8, [False] * 8
    alone = bootstrap_intervals(a, figures, far, drift, resamples=500)["recall_working"]
    got = paired_intervals(a, b, figures, far, drift, resamples=500)["recall_working"]
    assert got["a"] == 0.5 and got["b"] == 0.625 and got["diff"] == 0.125
    lo, hi = got["ci"]
    assert 0.0 <= lo <= 0.125 <= hi <= 0.375  # never negative: B is never worse
    assert hi - lo < alone[1] - alone[0]
    same = paired_intervals(a, a, figures, far, drift, resamples=200)
    assert same["recall_working"]["diff"] == 0.0 and same["recall_working"]["ci"] == [0.0, 0.0]
    assert same["recall_drift"] == {"a": None, "b": None, "diff": None, "ci": None}
    with pytest.raises(ValueError, match="differ in length"):
        paired_intervals(a, b[:7], figures, far, drift)


def test_compare_report_and_rows_give_each_half_its_difference() -> None:
    suite = suite_from_dict({"suite": {"name": "t"}, "group": [
        {"name": "near", "scenes": ["approach"], "cameras": ["kinect-v2-hard"],
         "distances_m": [1.0], "seeds": [1, 2, 3, 4]},
    ]})
    cases = list(suite.cases)
    res_a = [_recording(False) for _ in cases]
    res_b = [_recording(True) for _ in cases]
    rep = compare_report(suite, cases, res_a, res_b, ci=200)
    assert set(rep["halves"]) == set(HALVES)
    for h in HALVES:
        rec = rep["halves"][h]["recall_working"]
        assert (rec["a"], rec["b"], rec["diff"], rec["ci"]) == (0.0, 1.0, 1.0, [1.0, 1.0])
    rows = compare_rows(rep)
    assert rows[0] == ["contact recall, working range", "tune", "0.000", "1.000",
                       "+1.000 (+1.000 to +1.000)"]
    assert not any(r[0] == "contact recall under drift" for r in rows)  # defined on neither
    assert ["false touches", "tune", "0", "0", "+0 (+0 to +0)"] in rows  # counts, whole
    with pytest.raises(ConfigError, match="out of range"):
        compare_report(suite, cases, res_a, res_b, ci=10)

