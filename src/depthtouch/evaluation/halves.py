"""Tune on one half of a suite, report on the other: the split, the figures, the side-by-side table.

Every suite case belongs to one half, ``tune`` or ``held-out``, decided by its seed and its
camera placement (camera, distance, surface, tilt)::

    half = tune  if (seed + h(placement)) is even  else held-out

with h a fixed hash (SHA-256) of the placement's text. Two cases with the same seed and the same
placement thus always fall in the same half: a held-out case never shares its seed *and* its
placement with a tuned one (it is another room, or the same mount seen with another hand, noise
pattern and timing). Consecutive seeds at one placement fall in different halves, so a suite
that gives each placement two seeds or more has every placement on both sides.

Each case's *situation* is its suite group's name (the hard suite names them after the rows of
issue 13's "Where it fails" table); cases of groups tagged ``far`` (the far stereo scenes) count
apart in recall. :func:`figures` gives the issue's measures for any set of results, and
:func:`halves_report` both halves side by side, overall and per situation.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..config import PipelineConfig
from ..errors import ConfigError
from .bootstrap import COMPARE_KEYS, bootstrap_intervals, check_resamples, paired_intervals
from .metrics import EvalResult
from .suite import Suite, SuiteCase, load_suite
from .suiterun import check_group_key, default_workers, run_cases, run_grid
from .summary import summarize

if TYPE_CHECKING:  # pragma: no cover
    from rich.table import Table

TUNE, HELD_OUT = "tune", "held-out"
HALVES = (TUNE, HELD_OUT)
FAR_TAG = "far"
DRIFT_TAG = "drift"
LATE_AFTER_CHANGE_S = 2.0


def placement(case: SuiteCase) -> str:
    """The camera placement of a case: camera, distance, surface and tilt, as text."""
    return f"{case.camera}/{case.distance_m:g}m/{case.surface}/{case.tilt_deg:g}deg"


def half_of(case: SuiteCase) -> str:
    """``tune`` or ``held-out`` (see the module docstring); deterministic, no state."""
    h = int(hashlib.sha256(placement(case).encode()).hexdigest()[:8], 16)
    return TUNE if (case.seed + h) % 2 == 0 else HELD_OUT


def select_half(cases: Sequence[SuiteCase], half: str) -> list[SuiteCase]:
    """The cases of ``half`` (``tune``, ``held-out``) or all of them (``all``)."""
    if half == "all":
        return list(cases)
    if half not in HALVES:
        raise ConfigError(f"unknown half {half!r}; use tune, held-out or all")
    return [c for c in cases if half_of(c) == half]


def late_false_after_change(r: EvalResult, after_s: float = LATE_AFTER_CHANGE_S) -> int:
    """False tracks of the changed surface that outlive the change by more than ``after_s``.

    Counted: false tracks near no hovering fingertip (those are the hand's, counted elsewhere)
    that began at or after a surface change (an object put down or taken away, a bump) and were
    still reported more than ``after_s`` seconds after the latest change before their start.
    """
    if not r.change_frames or r.false_frame.size == 0:
        return 0
    fps = r.n_frames / r.duration_s if r.duration_s > 0 else 30.0
    n = 0
    for first, last, h in zip(r.false_frame.tolist(), r.false_last.tolist(),
                              r.false_hover_height_mm.tolist(), strict=True):
        before = [c for c in r.change_frames if c <= first]
        if before and last - before[-1] > after_s * fps and not math.isfinite(h):
            n += 1
    return n


def _num(v: float) -> float | None:
    return None if not math.isfinite(v) else round(float(v), 4)


def figures(results: Sequence[EvalResult], far: Sequence[bool],
            drift: Sequence[bool] | None = None) -> dict[str, Any]:
    """Issue 13's measures over ``results`` (JSON-ready; None where nothing was measured).

    far: per result, whether it counts apart in recall (far stereo); drift: per result, whether
    its recall is also the recall under drift.
    """
    if not results:
        return {"recordings": 0}
    m = summarize(results)
    near = [r for r, f in zip(results, far, strict=True) if not f]
    farr = [r for r, f in zip(results, far, strict=True) if f]
    drifting = [r for r, d in zip(results, drift or [False] * len(results), strict=True) if d]

    def recall(rs: list[EvalResult]) -> float | None:
        return _num(summarize(rs).contact_recall) if rs else None

    return {
        "recordings": m.recordings,
        "minutes": round(m.duration_s / 60.0, 2),
        "contacts": m.contacts,
        "recall_working": recall(near),
        "recall_far": recall(farr),
        "frame_recall": _num(m.frame_recall),
        "false_touches": m.false_touches,
        "false_per_min": _num(m.false_per_min),
        "false_from_hover_25mm": m.false_from_hover_at_least(25.0),
        "false_longest_s": _num(m.false_longest_s),
        "early_from_hover_25mm": m.early_from_hover_at_least(25.0),
        "error_median_mm": _num(m.error_median_mm),
        "error_p95_mm": _num(m.error_p95_mm),
        "id_switches": m.id_switches,
        "down_latency_median_frames": _num(m.down_latency_median_frames),
        "lift_latency_median_frames": _num(m.lift_latency_median_frames),
        "lift_latency_p95_frames": _num(m.lift_latency_p95_frames),
        "merged_contacts": m.merged_contacts,
        "jitter_rms_mm": _num(m.jitter_rms_mm),
        "angle_error_deg": _num(m.angle_error_deg),
        "recall_drift": recall(drifting),
        "false_late_after_change": sum(late_false_after_change(r) for r in results),
        "missed_by_reason": m.missed_by_reason,
    }


def case_tags(suite: Suite, cases: Sequence[SuiteCase]
               ) -> tuple[list[bool], list[bool], list[str]]:
    """Per case: whether it counts apart in recall (far), whether it drifts, and its half."""
    far = [FAR_TAG in suite.tags.get(c, frozenset()) for c in cases]
    drift = [DRIFT_TAG in suite.tags.get(c, frozenset()) for c in cases]
    return far, drift, [half_of(c) for c in cases]


def _half_cases(s: Suite, subset: str | None, half: str) -> list[SuiteCase]:
    """The suite's cases of ``subset`` in ``half``; a ConfigError when there are none."""
    cases = select_half(s.select(subset), half)
    if not cases:
        raise ConfigError(f"suite {s.name} has no {half} cases; give each placement two seeds")
    return cases


def halves_report(suite: Suite, cases: Sequence[SuiteCase],
                  results: Sequence[EvalResult], by: str = "group",
                  ci: int = 0) -> dict[str, Any]:
    """Both halves side by side: ``{"overall": {half: figures}, "by": by, "situations": {name:
    {half: figures}}}`` over the given cases (one result per case, in order). The rows of
    ``situations`` pool the cases by ``by`` (one of :data:`suiterun.GROUP_KEYS`): their suite group (the
    situation, default), scene, camera, label, distance or surface; ``all`` gives no rows.
    ``ci`` > 0: each overall half also gets ``"ci95"``, the 95 % bootstrap interval over its
    recordings of each measure of :data:`bootstrap.CI_KEYS` (``ci`` resamples)."""
    check_group_key(by)
    if ci:
        check_resamples(ci)
    far, drift, halves = case_tags(suite, cases)

    def block(keep: Callable[[int], bool]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for h in HALVES:
            idx = [i for i in range(len(cases)) if halves[i] == h and keep(i)]
            if idx:
                out[h] = figures([results[i] for i in idx], [far[i] for i in idx],
                                 [drift[i] for i in idx])
        return out

    keys = [str(getattr(c, by)) for c in cases] if by != "all" else []

    def in_row(name: str) -> Callable[[int], bool]:
        return lambda i: keys[i] == name

    rows = {name: block(in_row(name)) for name in dict.fromkeys(keys)}
    overall = block(lambda i: True)
    if ci:
        for h, f in overall.items():
            idx = [i for i in range(len(cases)) if halves[i] == h]
            f["ci95"] = bootstrap_intervals([results[i] for i in idx], figures,
                                            [far[i] for i in idx], [drift[i] for i in idx],
                                            resamples=ci)
    return {"suite": suite.name, "overall": overall, "by": by, "situations": rows}


def eval_halves_command(
    suite: str | Path,
    *,
    half: str = "all",
    subset: str | None = None,
    config: PipelineConfig | None = None,
    workers: int | None = None,
    cache: Path | None = None,
    progress: Callable[[SuiteCase, EvalResult], None] | None = None,
    fps: float | None = None,
    resolution_scale: float | None = None,
    noise_scale: float | None = None,
    by: str = "group",
    ci: int = 0,
    body: bool = False,
    drop_rate: float | None = None,
    breathing_mm: float | None = None,
    empty_s: float | None = None,
    edge_mm: float | None = None,
) -> dict[str, Any]:
    """``depthtouch eval --suite NAME --half tune|held-out|all``: :func:`halves_report`, its
    rows pooled ``by``, with ``ci`` bootstrap resamples for the intervals (0: none). ``fps``:
    every case rendered at this frame rate instead of the suite's; ``resolution_scale``: every
    camera at this many times its resolution; ``noise_scale``: every camera's axial noise times
    this; ``body``: every arm goes on into a body that leaves the view; ``drop_rate``: frames
    the camera never delivers (``render_scene(drop_rate=)``); ``breathing_mm``: frames that
    move as a whole (``render_scene(breathing_mm=)``); ``empty_s``: every recording's empty
    start shortened to this (s, :mod:`.emptystart`); ``edge_mm``: the surface ends inside the
    view with this drop beyond its edge (``render_scene(edge_mm=)``)."""
    check_group_key(by)  # before any case is rendered
    if ci:
        check_resamples(ci)
    s = (load_suite(suite).at_fps(fps).at_resolution(resolution_scale).at_noise(noise_scale)
         .with_body(body).with_drops(drop_rate).with_breathing(breathing_mm)
         .with_empty_start(empty_s).with_edge(edge_mm))
    cases = _half_cases(s, subset, half)
    results = run_cases(cases, config, gate_mm=s.gate_mm, workers=workers or default_workers(),
                        cache=cache, progress=progress)
    return halves_report(s, cases, results, by=by, ci=ci)


def compare_report(suite: Suite, cases: Sequence[SuiteCase], results_a: Sequence[EvalResult],
                   results_b: Sequence[EvalResult], ci: int = 1000) -> dict[str, Any]:
    """Configuration B against A on the same cases, per half: ``{"suite": name, "halves":
    {half: {measure: {"a", "b", "diff", "ci"}}}}`` (:func:`bootstrap.paired_intervals` over
    the half's recordings, ``ci`` resamples)."""
    check_resamples(ci)
    far, drift, halves = case_tags(suite, cases)
    out: dict[str, Any] = {}
    for h in HALVES:
        idx = [i for i in range(len(cases)) if halves[i] == h]
        if idx:
            out[h] = paired_intervals([results_a[i] for i in idx], [results_b[i] for i in idx],
                                      figures, [far[i] for i in idx], [drift[i] for i in idx],
                                      resamples=ci)
    return {"suite": suite.name, "halves": out}


def eval_compare_command(
    suite: str | Path,
    config_b: PipelineConfig,
    *,
    half: str = "all",
    subset: str | None = None,
    config: PipelineConfig | None = None,
    workers: int | None = None,
    cache: Path | None = None,
    progress: Callable[[SuiteCase, EvalResult], None] | None = None,
    ci: int = 1000,
    empty_s: float | None = None,
    edge_mm: float | None = None,
) -> dict[str, Any]:
    """``depthtouch eval --suite NAME --half H --against B.toml``: each case rendered once and
    run with both configurations, then :func:`compare_report` (``empty_s``: every recording's
    empty start shortened to this, s; ``edge_mm``: the surface ends inside the view with this
    drop beyond its edge, mm)."""
    check_resamples(ci)  # before any case is rendered
    s = load_suite(suite).with_empty_start(empty_s).with_edge(edge_mm)
    cases = _half_cases(s, subset, half)
    res_a, res_b = run_grid(cases, [config, config_b], gate_mm=s.gate_mm,
                            workers=workers or default_workers(), cache=cache, progress=progress)
    return compare_report(s, cases, res_a, res_b, ci=ci)


# --- tables ----------------------------------------------------------------------------------
ROWS: tuple[tuple[str, str, str], ...] = (
    ("recordings", "recordings", "{:d}"),
    ("contacts", "contacts", "{:d}"),
    ("recall_working", "contact recall, working range", "{:.3f}"),
    ("recall_far", "contact recall, far stereo", "{:.3f}"),
    ("false_per_min", "false touches / min", "{:.1f}"),
    ("false_from_hover_25mm", "false touches from hovers >= 25 mm", "{:d}"),
    ("false_longest_s", "longest false touch (s)", "{:.1f}"),
    ("early_from_hover_25mm", "touches down early, finger still >= 25 mm up", "{:d}"),
    ("error_median_mm", "position error median (mm)", "{:.1f}"),
    ("error_p95_mm", "position error p95 (mm)", "{:.1f}"),
    ("id_switches", "id switches", "{:d}"),
    ("down_latency_median_frames", "touch-down latency median (frames)", "{:.0f}"),
    ("lift_latency_median_frames", "lift latency median (frames)", "{:.0f}"),
    ("lift_latency_p95_frames", "lift latency p95 (frames)", "{:.0f}"),
    ("merged_contacts", "contacts merged into the previous touch", "{:d}"),
    ("jitter_rms_mm", "still-finger jitter RMS (mm)", "{:.2f}"),
    ("angle_error_deg", "path angle error (deg)", "{:.1f}"),
    ("recall_drift", "contact recall under drift", "{:.3f}"),
    ("false_late_after_change", "false touches > 2 s after a surface change", "{:d}"),
)

SITUATION_COLS: tuple[tuple[str, str, str], ...] = (
    ("contacts", "contacts", "{:d}"),
    ("recall", "recall", "{:.3f}"),
    ("false_touches", "false", "{:d}"),
    ("false_per_min", "false/min", "{:.1f}"),
    ("error_median_mm", "err med", "{:.1f}"),
    ("error_p95_mm", "err p95", "{:.1f}"),
    ("id_switches", "id sw", "{:d}"),
    ("jitter_rms_mm", "jitter", "{:.2f}"),
    ("angle_error_deg", "angle", "{:.1f}"),
)


def fmt(v: Any, spec: str) -> str:
    """A figure as text; "-" for None."""
    if v is None:
        return "-"
    return spec.format(v)


def reasons_text(count: dict[str, int]) -> str:
    """Counts per reason as text ("band erased by the opening 3, high step 1"), in their
    order."""
    return ", ".join(f"{k} {n}" for k, n in count.items())


def missed_lines(report: dict[str, Any]) -> list[str]:
    """One line per half: its missed contacts by why (:func:`figures`' ``missed_by_reason``:
    the nearest touch point's reason on most of the contact's visible frames or, without one,
    what the band held there; EvalResult.ep_miss_reason)."""
    out = []
    for h in HALVES:
        why = report["overall"].get(h, {}).get("missed_by_reason")
        if why:
            out.append(f"{h}: missed {sum(why.values())} contacts the camera saw; why: "
                       f"{reasons_text(why)}")
    return out


def situation_recall(f: dict[str, Any]) -> Any:
    """A situation's recall: the working-range one, or the far one for far situations."""
    return f.get("recall_working") if f.get("recall_working") is not None else f.get("recall_far")


def _with_ci(f: dict[str, Any], key: str, spec: str) -> str:
    """A half's figure as text, followed by its bootstrap interval when the report has one."""
    text = fmt(f.get(key), spec)
    iv = f.get("ci95", {}).get(key)
    return f"{text} ({fmt(iv[0], spec)}-{fmt(iv[1], spec)})" if iv and text != "-" else text


def overall_rows(report: dict[str, Any]) -> list[list[str]]:
    """[measure, tune, held-out] rows of the overall figures (with their 95 % intervals in
    brackets when the report has them)."""
    ov = report["overall"]
    return [[label] + [_with_ci(ov.get(h, {}), key, spec) for h in HALVES]
            for key, label, spec in ROWS]


def situation_rows(report: dict[str, Any]) -> list[list[str]]:
    """[situation, half, columns of SITUATION_COLS...] rows."""
    out = []
    for name, block in report["situations"].items():
        for h in HALVES:
            f = block.get(h)
            if not f:
                continue
            vals = [fmt(situation_recall(f) if key == "recall" else f.get(key), spec)
                    for key, _, spec in SITUATION_COLS]
            out.append([name, h, *vals])
    return out


def _row_head(report: dict[str, Any]) -> str:
    """The name of the report's rows: "situation" (a suite group) or what they pool by."""
    by = report.get("by", "group")
    return "situation" if by == "group" else by


def halves_tables(report: dict[str, Any]) -> tuple[Table, Table]:
    """Two rich tables: the overall figures (halves side by side) and the per-situation rows."""
    from rich.table import Table

    a = Table(title=f"suite {report['suite']}: tune vs held-out")
    a.add_column("measure")
    for h in HALVES:
        a.add_column(h, justify="right")
    for row in overall_rows(report):
        a.add_row(*row)
    row_head = _row_head(report)
    b = Table(title=f"per {row_head}")
    b.add_column(row_head)
    b.add_column("half")
    for _, head, _ in SITUATION_COLS:
        b.add_column(head, justify="right")
    for row in situation_rows(report):
        b.add_row(*row)
    return a, b


def print_halves(suite: str | Path, half: str, *, subset: str | None = None,
                 config: PipelineConfig | None = None, workers: int | None = None,
                 cache: Path | None = None, as_json: bool = False,
                 progress: Callable[[SuiteCase, EvalResult], None] | None = None,
                 fps: float | None = None, resolution_scale: float | None = None,
                 noise_scale: float | None = None, by: str = "group", ci: int = 0,
                 body: bool = False, drop_rate: float | None = None,
                 breathing_mm: float | None = None, empty_s: float | None = None,
                 edge_mm: float | None = None) -> int:
    """The CLI's ``eval --suite NAME --half H [--by B] [--ci N]``: print the tables (or JSON);
    returns 0."""
    import json
    import sys

    report = eval_halves_command(suite, half=half, subset=subset, config=config,
                                 workers=workers, cache=cache, progress=progress, fps=fps,
                                 resolution_scale=resolution_scale, noise_scale=noise_scale,
                                 by=by, ci=ci, body=body, drop_rate=drop_rate,
                                 breathing_mm=breathing_mm, empty_s=empty_s,
                                 edge_mm=edge_mm)
    if as_json:
        print(json.dumps(report, indent=1))
        return 0
    from rich.console import Console

    console = Console(width=None if sys.stdout.isatty() else 200)
    overall, rows = halves_tables(report)
    console.print(overall)
    for line in missed_lines(report):
        console.print(line, highlight=False)
    if report["situations"]:
        console.print(rows)
    return 0


def compare_rows(report: dict[str, Any]) -> list[list[str]]:
    """[measure, half, A, B, B - A (95 % interval)] rows of a :func:`compare_report`."""
    spec = {key: sp for key, _, sp in ROWS} | {"false_touches": "{:d}"}
    label = {key: lab for key, lab, _ in ROWS} | {"false_touches": "false touches"}
    out = []
    for key in COMPARE_KEYS:
        for h in HALVES:
            c = report["halves"].get(h, {}).get(key)
            if not c or c["a"] is None and c["b"] is None:
                continue
            sp = spec[key]
            dspec = "{:+.0f}" if sp == "{:d}" else "{:+.3f}"  # a count's difference is whole
            d = "-" if c["diff"] is None else dspec.format(c["diff"])
            if c["ci"]:
                d += f" ({dspec.format(c['ci'][0])} to {dspec.format(c['ci'][1])})"
            out.append([label[key], h, fmt(c["a"], sp), fmt(c["b"], sp), d])
    return out


def print_compare(suite: str | Path, half: str, config_b: PipelineConfig, *,
                  subset: str | None = None, config: PipelineConfig | None = None,
                  workers: int | None = None, cache: Path | None = None,
                  as_json: bool = False, ci: int = 1000,
                  progress: Callable[[SuiteCase, EvalResult], None] | None = None,
                  empty_s: float | None = None, edge_mm: float | None = None) -> int:
    """The CLI's ``eval --suite NAME --half H --against B.toml``: print the table (or JSON);
    returns 0."""
    import json
    import sys

    report = eval_compare_command(suite, config_b, half=half, subset=subset, config=config,
                                  workers=workers, cache=cache, progress=progress, ci=ci,
                                  empty_s=empty_s, edge_mm=edge_mm)
    if as_json:
        print(json.dumps(report, indent=1))
        return 0
    from rich.console import Console
    from rich.table import Table

    t = Table(title=f"suite {report['suite']}: B (--against) against A (--config or defaults), "
                    "paired over the same recordings")
    for head in ("measure", "half", "A", "B", "B - A (95 % interval)"):
        t.add_column(head, justify="left" if head in ("measure", "half") else "right")
    for row in compare_rows(report):
        t.add_row(*row)
    Console(width=None if sys.stdout.isatty() else 200).print(t)
    return 0


def halves_markdown(report: dict[str, Any]) -> list[str]:
    """Markdown lines: the overall figures (halves side by side) and the per-situation table."""
    out = ["| measure | tune | held-out |", "|---|---|---|"]
    out += ["| " + " | ".join(row) + " |" for row in overall_rows(report)]
    missed = missed_lines(report)
    if missed:
        out += ["", *(f"- {line}" for line in missed)]
    if not report["situations"]:
        return out
    heads = [head for _, head, _ in SITUATION_COLS]
    out += ["", f"| {_row_head(report)} | half | " + " | ".join(heads) + " |",
            "|---|---|" + "---|" * len(heads)]
    out += ["| " + " | ".join(row) + " |" for row in situation_rows(report)]
    return out
