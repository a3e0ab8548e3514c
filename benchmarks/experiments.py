"""The paper's experiments, reproduced on the simulator, and the default suite's accuracy table.

Writes docs/accuracy.md and docs/figures/accuracy-*.png:

1. the default suite (``depthtouch eval --suite default``) by scene, camera and group;
2. touch detection probability and position error against camera distance (0.6-2.0 m), for each
   camera profile (Lee & Kwon measured both against the distance);
3. surface learned by mean versus mode (the paper's two) versus median;
4. a sweep of the band thresholds Tl (tl_floor_mm) and Tu (tu_mm);
5. curved (convex / concave cylinder) versus flat surfaces;
6. the hard suite (``--suite hard``), its tune and held-out halves side by side, per situation.

Run: ``.venv/bin/python benchmarks/experiments.py [--quick] [--workers 2] [--only hard]`` (with
``--only``, the other generated sections of the existing file are kept as they were). The
hand-written sections (0, where the sensor stands, and 7, issue 13 session by session) are never
generated: every run keeps them from the existing file. Recordings are rendered once and cached
(.cache/depthtouch/suite); ``--quick`` uses fewer distances and seeds.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import textwrap
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from depthtouch import __version__
from depthtouch.config import PipelineConfig
from depthtouch.evaluation.halves import reasons_text
from depthtouch.evaluation.metrics import EvalResult
from depthtouch.evaluation.report import metrics_markdown, plot_xy
from depthtouch.evaluation.suite import SuiteCase, load_suite
from depthtouch.evaluation.suiterun import group_metrics, run_cases, run_grid
from depthtouch.evaluation.summary import Metrics, summarize

CAMERAS = ("kinect-v2", "realsense-d435", "kinect-v1")
ROOT = Path(__file__).resolve().parents[1]


def _cases(scenes: Sequence[str], cameras: Sequence[str], distances: Sequence[float],
           seeds: Sequence[int], surface: str = "plane", tilt: float = 0.0) -> list[SuiteCase]:
    return [SuiteCase(s, c, d, surface, tilt, seed, 30.0, "exp")
            for s in scenes for c in cameras for d in distances for seed in seeds]


def _pool(
    cases: Sequence[SuiteCase], results: Sequence[EvalResult], key: str
) -> dict[str, Metrics]:
    groups: dict[str, list[EvalResult]] = {}
    for c, r in zip(cases, results, strict=True):
        groups.setdefault(key.format(c=c), []).append(r)
    return {k: summarize(v) for k, v in groups.items()}


def _fmt(v: float, f: str = "{:.3f}") -> str:
    return "-" if not math.isfinite(v) else f.format(v)


def _nz(v: float) -> float:
    return v if math.isfinite(v) else 0.0


def _ranges(ok: Sequence[float], all_d: Sequence[float]) -> str:
    """The distances in ``ok`` as runs of consecutive entries of ``all_d``: "0.6-1.2 m"."""
    if not ok:
        return "no distance"
    runs: list[list[float]] = []
    for d in all_d:
        if d in ok:
            if runs and all_d.index(d) == all_d.index(runs[-1][-1]) + 1:
                runs[-1].append(d)
            else:
                runs.append([d])
    return ", ".join(f"{r[0]:g}-{r[-1]:g} m" if len(r) > 1 else f"{r[0]:g} m" for r in runs)


def _git_head() -> str:
    import subprocess

    try:  # works in a git worktree too, where .git is a file
        out = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True,
                             text=True, check=True, timeout=10)
        return out.stdout.strip()[:10]
    except (OSError, subprocess.SubprocessError):
        return "unknown"


TARGETS = (
    ("contact recall", "contact_recall", ">=", 0.98),
    ("false touches from fingers hovering >= 25 mm", "hover_ge25", "<=", 0),
    ("median position error (mm)", "error_median_mm", "<=", 4.0),
    ("p95 position error (mm)", "error_p95_mm", "<=", 10.0),
    ("id switches", "id_switches", "<=", 0),
    ("median touch-down latency (frames at 30 fps)", "down_latency_median_frames", "<=", 2.0),
)


def _get(m: Metrics, key: str) -> float:
    return float(m.false_from_hover_at_least(25.0) if key == "hover_ge25" else getattr(m, key))


def _meets(v: float, op: str, lim: float) -> bool:
    return v >= lim if op == ">=" else v <= lim


def _acceptance(m: Metrics) -> list[str]:
    rows = ["| target | wanted | measured | met |", "|---|---|---|---|"]
    for name, key, op, lim in TARGETS:
        v = _get(m, key)
        rows.append(f"| {name} | {op} {lim:g} | {v:.3g} | {'yes' if _meets(v, op, lim) else 'NO'} |")
    return rows


def _failures(cases: Sequence[SuiteCase], results: Sequence[EvalResult]) -> list[str]:
    bad: list[tuple[float, str]] = []
    for c, r in zip(cases, results, strict=True):
        m = summarize([r])
        why = []
        if m.contact_recall < 0.98:
            missed = reasons_text(m.missed_by_reason)
            why.append(f"recall {m.contact_recall:.2f}" + (f" (missed: {missed})" if missed else ""))
        if m.false_touches:
            bands = ", ".join(f"{k} mm: {v}" if k != "other" else f"other: {v}"
                              for k, v in m.false_by_hover.items() if v)
            why.append(f"{m.false_touches} false ({bands})")
        if m.error_median_mm > 4.0:
            why.append(f"err med {m.error_median_mm:.1f} mm")
        if m.error_p95_mm > 10.0:
            why.append(f"err p95 {m.error_p95_mm:.1f} mm")
        if m.id_switches:
            why.append(f"{m.id_switches} id switches")
        if m.down_latency_median_frames > 2.0:
            why.append(f"down latency {m.down_latency_median_frames:.1f} frames")
        if why:
            score = ((1 - m.contact_recall) * 100 if math.isfinite(m.contact_recall) else 0.0)
            score += m.false_touches + m.id_switches
            bad.append((score, f"- `{c.label}`: " + "; ".join(why)))
    if not bad:
        return ["(none)"]
    return [line for _, line in sorted(bad, key=lambda x: -x[0])]


#: what the sessions changed in section 6's tables (a history note the generator keeps)
_HARD_HISTORY = (
    'Session 41 turned on the test of resting-hand patches '
    '(`tracking.enclosed_change_max_mm`, section 7): false touches 13 -> 12 on the tune half, '
    '**8 -> 6 (0.6 a minute) held out**; recall, error, id switches and latencies unchanged, '
    'jitter 0.759 -> 0.762 mm held out. The table was from the defaults before it (both '
    'configurations on the same recordings: section 7, session 41). Session 42 widened the '
    'test (every tip height, and frames under a cover left out) and regenerated the tables '
    "below with its defaults (`--half all --ci 1000`): against session 40's, false touches 13 "
    '-> 12 tune and 8 -> 6 held out, the longest held-out false touch 3.0 -> 0.7 s, none '
    'later than 2 s after a surface change (1 -> 0 on the tune half), forearm-rest held out 3 '
    '-> 1 false touches; recall, error, id switches, latencies and the path angle as before. '
    'Session 43 regenerated them again with its defaults (the grace for a held, flickering '
    "contact on, the enclosure test for a touch's start only): lift latency p95 19 -> 21 "
    'frames on the tune half and 21 -> 22 held out; every other figure as before. Session 44 '
    'regenerated them with its defaults (a region its hand surrounds that lies low and level '
    'behind refused while it arrives, `tracking.enclosed_flat_max_mm`; '
    '`benchmarks/experiments.py --only hard --cache`): held out, recall 0.976 -> **0.970** '
    '(one contact of a hand held low at ToF 2 m, `approach/kinect-v2-hard/2m/tilt30/s2`, lost '
    'and reported as a false touch instead), 0.6 -> 0.7 false touches a minute, jitter 0.76 '
    '-> 0.75 mm, error p95 5.0 -> 4.9 mm; tune half, the longest false touch 3.6 -> 2.1 s, '
    'and one false touch later than 2 s after a surface change (0 before): the same false '
    'touch on a handled box (`handled/kinect-v2-hard/1m/tilt20/s2`) now starts 1.4 s later, '
    '4.6 s into the recording instead of 3.2 s, and lasts 64 frames instead of 107. Session '
    "50 regenerated them with its defaults (the enclosure test's low band, "
    '`tracking.enclosed_low_change_max_mm` 2.5: points whose ring holds 15-25 % of their hand '
    'refused where their surroundings changed less than 2.5 mm in 2 s; section 7, session '
    '50). Session 57 regenerated them with the re-landing on (`filter.params.reland_frames` '
    '6, section 7, session 57): held out, jitter 0.76 -> 0.75 mm, angle and error as before '
    "(one recording's error p95, `fastdrags/kinect-v2-hard/1.2m/tilt25/s101`, 10.4 -> 11.7 "
    'mm); tune half, jitter 0.54 -> 0.52 mm, error p95 5.1 -> 5.2 mm. This paragraph is kept '
    'by the generator (benchmarks/experiments.py).'
)


class Experiments:
    def __init__(self, out: Path, figures: Path, workers: int, quick: bool) -> None:
        self.out, self.figures, self.workers, self.quick = out, figures, workers, quick
        self.md: list[str] = []
        self.keep_others = False  # --only: keep the sections of the steps not run
        self.timings: dict[str, float] = {}
        self.cache: Path | None = None  # --cache: the suites' recordings rendered once

    def run(self, cases: list[SuiteCase], config: PipelineConfig | None = None) -> list[EvalResult]:
        return run_cases(cases, config, workers=self.workers, cache=self.cache)

    def fig(self, name: str) -> str:
        return f"figures/{name}"

    # --- 1 ------------------------------------------------------------------------------------
    def suite(self) -> None:
        t0 = time.perf_counter()
        s = load_suite("default")
        cases = s.select("all")
        res = self.run(cases)
        self.timings["suite"] = time.perf_counter() - t0
        self.suite_results = (cases, res)
        overall = summarize(res)
        self.md += [
            "## 1. The default suite",
            "",
            f"`depthtouch eval --suite default`: {len(cases)} recordings "
            f"({overall.duration_s / 60:.1f} min of simulated video, {overall.contacts} visible "
            f"contact episodes, {overall.occluded_contacts} hidden), default configuration. "
            "Rows pool all matches of the recordings in them. The issue's targets:",
            "",
            *_acceptance(overall),
            "",
            "### Where it fails",
            "",
            "Recordings that miss a target (recall < 0.98, a false touch, median error > 4 mm, "
            "p95 > 10 mm, an id switch, median touch-down latency > 2 frames), worst first:",
            "",
            *_failures(cases, res),
            "",
            "### By scene", "", metrics_markdown(group_metrics(cases, res, "scene") |
                                                {"all": overall}, "scene"), "",
            "### By camera", "", metrics_markdown(group_metrics(cases, res, "camera"), "camera"),
            "",
            "### By group (see src/depthtouch/sim/suites/default.toml)", "",
            metrics_markdown(group_metrics(cases, res, "group"), "group"), "",
            "### Every recording", "",
            metrics_markdown(group_metrics(cases, res, "label"), "recording"), "",
        ]

    # --- 2 ------------------------------------------------------------------------------------
    def distance(self) -> None:
        dists = [0.6, 1.0, 1.4, 2.0] if self.quick else [0.6, 0.8, 1.0, 1.2, 1.4, 1.6, 1.8, 2.0]
        seeds = [11] if self.quick else [11, 12]
        cases = _cases(["taps", "drags"], CAMERAS, dists, seeds)
        t0 = time.perf_counter()
        res = self.run(cases)
        self.timings["distance"] = time.perf_counter() - t0
        m = _pool(cases, res, "{c.camera}|{c.distance_m}")
        rec, fr, med, p95 = {}, {}, {}, {}
        for cam in CAMERAS:
            ms = [m[f"{cam}|{float(d)}"] for d in dists]
            rec[cam] = (dists, [x.contact_recall for x in ms])
            fr[cam] = (dists, [x.frame_recall for x in ms])
            med[cam] = (dists, [x.error_median_mm for x in ms])
            p95[cam] = (dists, [x.error_p95_mm for x in ms])
        plot_xy(rec, self.figures / "accuracy-distance-recall.png", xlabel="camera distance (m)",
                ylabel="contact recall", title="touch detection probability vs distance",
                hline=0.98)
        plot_xy(fr, self.figures / "accuracy-distance-frame-recall.png",
                xlabel="camera distance (m)", ylabel="frame recall",
                title="contact frames detected vs distance")
        plot_xy(med, self.figures / "accuracy-distance-error.png", xlabel="camera distance (m)",
                ylabel="median position error (mm)", title="position error vs distance",
                hline=4.0)
        rows = ["| camera | distance m | recall | frame recall | false | err med mm | err p95 mm "
                "| down lat | ms/frame |", "|---|---|---|---|---|---|---|---|---|"]
        for cam in CAMERAS:
            for d in dists:
                x = m[f"{cam}|{float(d)}"]
                rows.append(
                    f"| {cam} | {d:g} | {_fmt(x.contact_recall)} | {_fmt(x.frame_recall)} | "
                    f"{x.false_touches} | {_fmt(x.error_median_mm, '{:.2f}')} | "
                    f"{_fmt(x.error_p95_mm, '{:.2f}')} | "
                    f"{_fmt(x.down_latency_median_frames, '{:.1f}')} | "
                    f"{_fmt(x.ms_per_frame_median, '{:.1f}')} |"
                )
        notes = []
        for cam in CAMERAS:
            ok_rec = [d for d in dists if m[f"{cam}|{float(d)}"].contact_recall >= 0.95]
            ok_err = [d for d in dists if m[f"{cam}|{float(d)}"].error_median_mm <= 4.0]
            notes.append(
                f"- {cam}: recall >= 0.95 at {_ranges(ok_rec, dists)}; median error <= 4 mm at "
                f"{_ranges(ok_err, dists)}."
            )
        self.md += [
            "## 2. Detection probability and position error against distance",
            "",
            f"Scenes taps and drags, seeds {seeds}, plane facing the camera, each profile at "
            f"{', '.join(f'{d:g}' for d in dists)} m (the paper measured both quantities against "
            "the camera-to-surface distance).",
            "",
            f"![recall]({self.fig('accuracy-distance-recall.png')}) "
            f"![error]({self.fig('accuracy-distance-error.png')}) "
            f"![frame recall]({self.fig('accuracy-distance-frame-recall.png')})",
            "", *notes, "", *rows, "",
        ]

    # --- 3 ------------------------------------------------------------------------------------
    def statistic(self) -> None:
        cases = _cases(["taps", "drags"], CAMERAS, [1.0, 1.6], [21])
        out: dict[str, Metrics] = {}
        t0 = time.perf_counter()
        stats = ("mean", "mode", "median")
        grid = run_grid(cases, [PipelineConfig().replace(surface={"statistic": st})
                                for st in stats], workers=self.workers)
        for stat, res in zip(stats, grid, strict=True):
            for cam in CAMERAS:
                sel = [r for c, r in zip(cases, res, strict=True) if c.camera == cam]
                out[f"{stat} / {cam}"] = summarize(sel)
        self.timings["statistic"] = time.perf_counter() - t0
        self.md += [
            "## 3. Surface by mean, mode or median",
            "",
            "Scenes taps and drags at 1.0 and 1.6 m, seed 21; the surface depth of each pixel "
            "is learned from the empty frames by the given statistic (the paper compares mean "
            "and mode).",
            "", metrics_markdown(out, "statistic / camera"), "",
        ]

    # --- 4 ------------------------------------------------------------------------------------
    def thresholds(self) -> None:
        tls = [2.0, 4.0, 6.0, 8.0] if self.quick else [2.0, 3.0, 4.0, 6.0, 8.0, 10.0]
        tus = [15.0, 25.0, 40.0] if self.quick else [12.0, 15.0, 20.0, 25.0, 35.0, 50.0]
        cases = _cases(["taps", "drags", "hover"], ["kinect-v2", "realsense-d435"], [1.2], [31])
        t0 = time.perf_counter()
        base = PipelineConfig()
        pairs = [(tl, tu) for tl in tls for tu in tus if tu > tl]
        runs = run_grid(cases, [base.replace(regions={"tl_floor_mm": tl, "tu_mm": tu})
                                for tl, tu in pairs], workers=self.workers)
        grid = {pair: summarize(res) for pair, res in zip(pairs, runs, strict=True)}
        self.timings["thresholds"] = time.perf_counter() - t0
        def series(key: str) -> dict[str, tuple[list[float], list[float]]]:
            out = {}
            for tl in tls:
                tu_ok = [tu for tu in tus if (tl, tu) in grid]
                out[f"Tl {tl:g} mm"] = (tu_ok, [float(getattr(grid[(tl, tu)], key))
                                                for tu in tu_ok])
            return out

        plot_xy(series("frame_recall"), self.figures / "accuracy-tl-tu-recall.png",
                xlabel="Tu (mm)", ylabel="frame recall", title="contact frames found over Tu, Tl")
        plot_xy(series("false_touches"), self.figures / "accuracy-tl-tu-false.png",
                xlabel="Tu (mm)", ylabel="false touches",
                title="false touches (taps, drags, hover) over Tu, Tl")
        rows = ["| Tl mm | Tu mm | recall | frame recall | false | from hover >= 25 mm | "
                "err med mm | err p95 mm | down lat |", "|---|---|---|---|---|---|---|---|---|"]
        for (tl, tu), x in grid.items():
            rows.append(
                f"| {tl:g} | {tu:g} | {_fmt(x.contact_recall)} | {_fmt(x.frame_recall)} | "
                f"{x.false_touches} | {x.false_from_hover_at_least(25.0)} | "
                f"{_fmt(x.error_median_mm, '{:.2f}')} | {_fmt(x.error_p95_mm, '{:.2f}')} | "
                f"{_fmt(x.down_latency_median_frames, '{:.1f}')} |"
            )
        def rank(pair: tuple[float, float]) -> tuple[float, float, float]:
            x = grid[pair]
            err = x.error_median_mm if math.isfinite(x.error_median_mm) else 1e9
            return (-_nz(x.contact_recall) - _nz(x.frame_recall), x.false_touches, err)

        best = min(grid, key=rank)
        default = (base.regions.tl_floor_mm, base.regions.tu_mm)
        self.md += [
            "## 4. Sweep of Tl and Tu",
            "",
            "Scenes taps, drags and hover on kinect-v2 and realsense-d435 at 1.2 m, seed 31. "
            "Tl is the lower band threshold's floor (`regions.tl_floor_mm`; a pixel's Tl is "
            "max(floor, noise_k * sigma)), Tu the upper (`regions.tu_mm`).",
            "",
            f"Best pair (recall and frame recall, then fewest false touches, then error): "
            f"Tl {best[0]:g} mm, Tu {best[1]:g} mm; the default is Tl {default[0]:g}, "
            f"Tu {default[1]:g}.",
            "",
            f"![frame recall]({self.fig('accuracy-tl-tu-recall.png')}) "
            f"![false touches]({self.fig('accuracy-tl-tu-false.png')})",
            "", *rows, "",
        ]

    # --- 5 ------------------------------------------------------------------------------------
    def curved(self) -> None:
        out: dict[str, Metrics] = {}
        t0 = time.perf_counter()
        for surf in ("plane", "cylinder-convex", "cylinder-concave"):
            cases = _cases(["taps", "drags"], CAMERAS, [1.0], [41], surface=surf)
            res = self.run(cases)
            out[surf] = summarize(res)
            for cam in CAMERAS:
                sel = [r for c, r in zip(cases, res, strict=True) if c.camera == cam]
                out[f"{surf} / {cam}"] = summarize(sel)
        self.timings["curved"] = time.perf_counter() - t0
        self.md += [
            "## 5. Curved versus flat",
            "",
            "Scenes taps and drags at 1.0 m, seed 41, on a plane and on convex and concave "
            "cylinder sections (the paper shows touches on a curved panel). The error is "
            "measured on the tangent plane at each true contact.",
            "", metrics_markdown(out, "surface"), "",
        ]

    # --- 6 ------------------------------------------------------------------------------------
    def hard(self) -> None:
        from depthtouch.evaluation.halves import halves_markdown, halves_report

        t0 = time.perf_counter()
        s = load_suite("hard")
        cases = s.select("all")
        res = self.run(cases)
        self.timings["hard"] = time.perf_counter() - t0
        report = halves_report(s, cases, res, ci=1000)
        overall = summarize(res)
        self.md += [
            "## 6. The hard suite, tune and held-out halves",
            "",
            f"`depthtouch eval --suite hard --half all`: {len(cases)} recordings "
            f"({overall.duration_s / 60:.1f} min, {overall.contacts} visible contact episodes), "
            "default configuration. One situation per row of issue 13's \"Where it fails\" "
            "table (src/depthtouch/sim/suites/hard.toml, docs/simulator.md). Cases are split "
            "by seed and camera placement (evaluation/halves.py): tune on `tune`, report "
            "`held-out`. The far stereo scenes (1.1 m wall 20 deg, 1.6 m table 32 deg) count "
            "apart in recall. *false > 2 s after change*: false touches that began at or after "
            "a book was put down or taken away and were still reported 2 s after it.",
            "",
            "The second table's rows are the situations; `--by camera` (or `scene`, `label`, "
            "`distance_m`, `surface`) pools them by another attribute of the cases, both halves "
            "side by side, and `--by all` leaves that table out.",
            "",
            "In brackets (`--ci 1000`), each overall figure's 95 % percentile-bootstrap "
            "interval over the half's recordings (1000 resamples of the recordings with "
            "replacement, seeded; `evaluation/bootstrap.py`). A half has 50 recordings, and a "
            "few of them carry some figures (one recording of the tune half holds 23 % of its "
            "squared jitter): the interval says how far another set of recordings, such as the "
            "maintainers', could move a figure by the draw alone. A figure at its bound "
            "(recall 1.000) gets a zero-width interval: the bootstrap cannot show misses it "
            "never saw.",
            "",
            "`--against B.toml` renders each case once, runs it with both configurations (A: "
            "`--config` or the defaults) and gives, per half and measure, A, B and B - A with "
            "the 95 % interval of the difference over the same resamples "
            "(`bootstrap.paired_intervals`). What a draw of recordings adds to both figures "
            "cancels, so the interval of a difference is much narrower than either figure's "
            "own: on hard-fresh3's tune half, `touchpoints.tip_shift_mm` 0 -> 1.25 moved the "
            "error median by -0.835 mm (-1.096 to -0.432), while that median's own interval "
            "runs from 2.6 to 5.0 mm. An interval that holds 0 is a change the recordings "
            "cannot tell from none.",
            "",
            *textwrap.wrap("".join(_HARD_HISTORY), 95),
            "",
            *halves_markdown(report),
            "",
            "### Where it fails (hard suite, both halves)",
            "",
            *_failures(cases, res),
            "",
        ]

    def write(self, total_s: float) -> None:
        head = [
            "# Accuracy",
            "",
            "Measured on the built-in simulator (exact ground truth) by "
            "`benchmarks/experiments.py`; regenerate with "
            "`.venv/bin/python benchmarks/experiments.py`. Every number in sections 1-6 comes "
            "from that run; nothing there is edited by hand. Sections 0 (where the sensor stands "
            "against issue 13) and 7 (issue 13, session by session) are written by hand, and the "
            "generator keeps them.",
            "",
            "**How it is measured** (`src/depthtouch/evaluation/metrics.py`). Per frame, reported "
            "touches (`down`/`move` events) are assigned to true contacts by optimal assignment "
            "on the distance on the surface in mm: a reported pixel is back-projected through K "
            "and intersected with the tangent plane at the true contact point; pairs farther "
            "than 20 mm never match.",
            "",
            "- *contacts*: true contact episodes whose fingertip the camera sees in at least one "
            "frame; *hidden*: episodes whose tip the hand hides throughout (the simulator marks "
            "them; no depth camera can see them, so they are left out);",
            "- *recall*: visible contact episodes matched in at least one frame; *frame rec*: "
            "matched / visible contact frames, leaving out the first `down_frames` (2) "
            "frames of each contact (the tracker's debounce);",
            "- *false*: reported ids matched to no contact in any frame (and per minute); "
            "*hover>=25*: those that came within 20 mm of a finger hovering 25 mm or higher;",
            "- *err*: surface distance of matches (median, p95); *id sw*: changes of the "
            "reported id during one contact;",
            "- *down lat*: frames from the first contact frame to the first matched frame "
            "(0 = same frame); *lift lat*: frame of the `up` minus the first frame without "
            "contact (0 = immediate);",
            "- *angle*: mean angle between reported and true displacement vectors over "
            "3-frame steps of drags (as issue 13 measures it; true steps under 0.5 mm "
            "skipped; the paper's frame-to-frame steps give larger angles); *jitter*: RMS "
            "distance to the mean of a finger that is still for 10+ frames;",
            "- *ms/frame*: the pipeline's own time per frame on this machine (no rendering).",
            "",
            f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python "
            f"{platform.python_version()}, numpy {np.__version__}, depthtouch {__version__}; "
            f"run at {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} on the working tree "
            f"of commit {_git_head()}; "
            f"{self.workers} worker processes; run took {total_s:.0f} s "
            f"({', '.join(f'{k} {v:.0f} s' for k, v in self.timings.items())})"
            + ("; the other sections were kept from an earlier run." if self.keep_others
               else "."),
            "",
        ]
        body = self.md
        if self.out.exists():
            old = self.out.read_text(encoding="utf-8")
            body = _splice(old, self.md, keep=None if self.keep_others else HAND_WRITTEN)
        self.out.write_text("\n".join(head + body) + "\n", encoding="utf-8")


def _sections(lines: Sequence[str]) -> dict[str, list[str]]:
    """Level-2 sections ("## 6. ...") of markdown lines, keyed by their number."""
    out: dict[str, list[str]] = {}
    key = None
    for line in lines:
        if line.startswith("## "):
            key = line[3:].split(".")[0]
            out[key] = []
        if key is not None:
            out[key].append(line)
    return out


#: the sections written by hand, which no step generates: a run keeps them from the old file
HAND_WRITTEN = frozenset({"0", "7"})


def _splice(old_text: str, new: Sequence[str], keep: frozenset[str] | None = None
            ) -> list[str]:
    """The new sections, with the old file's other sections kept, by number: all of them
    (``keep`` None: ``--only``), or only those in ``keep`` (a whole run: the hand-written ones,
    so that regenerating the tables never drops them)."""
    old = _sections(old_text.rstrip("\n").split("\n"))
    if keep is not None:
        old = {k: v for k, v in old.items() if k in keep}
    merged = old | _sections(new)
    keys = sorted(merged, key=lambda k: (not k.isdigit(), int(k) if k.isdigit() else 0, k))
    return [line for k in keys for line in merged[k]]


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=str(ROOT / "docs" / "accuracy.md"))
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--quick", action="store_true", help="fewer distances, seeds and thresholds")
    p.add_argument("--cache", action="store_true",
                   help="read the suites' recordings from the eval cache (render missing ones)")
    p.add_argument("--only",
                   help="comma-separated: suite,distance,statistic,thresholds,curved,hard")
    a = p.parse_args(argv)
    out = Path(a.out)
    figures = out.parent / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    ex = Experiments(out, figures, a.workers, a.quick)
    ex.keep_others = bool(a.only)
    if a.cache:
        from depthtouch.evaluation.suite import cache_root

        ex.cache = cache_root()
    steps = (a.only or "suite,distance,statistic,thresholds,curved,hard").split(",")
    t0 = time.perf_counter()
    for step in steps:
        print(f"experiment {step} ...", file=sys.stderr, flush=True)
        getattr(ex, step.strip())()
        ex.write(time.perf_counter() - t0)  # after every step: a later failure keeps the rest
    print(f"wrote {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
