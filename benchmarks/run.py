"""Per-stage and end-to-end timing of the per-frame touch path; writes docs/benchmarks.md.

Frames are synthetic (a plane at 1 m seen from above, 1.5 mm noise, 1 % dropouts, fingers with
hands moving across it); each case times >= 300 frames after the surface is learned, on one core
(OpenCV limited to one thread). Usage: python benchmarks/run.py [--out docs/benchmarks.md]
[--frames 300].
"""

from __future__ import annotations

import argparse
import datetime as _dt
import platform
import sys
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from depthtouch.pipeline import Pipeline  # noqa: E402
from depthtouch.types import Frame, FrameResult  # noqa: E402
from synth import Finger, render_heights  # noqa: E402

RESOLUTIONS = [(512, 424), (640, 480), (848, 480), (1280, 720)]
TOUCHES = [0, 2, 5, 10]
WARMUP_FRAMES = 100
ROUNDS = 6  # each case is timed in this many blocks, the cases taking turns
BLOCK_WARMUP = 5  # untimed frames at the start of each block
STAGES = ["prefilter_surface_update", "regions", "touchpoints", "tracking", "filter_events", "total"]


def intrinsics(w: int, h: int) -> np.ndarray:
    f = 0.9 * w  # ~ 58-60 degrees horizontal field of view
    return np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])


def fingers_at(k: int, n: int, w: int, h: int, mm_per_px: float) -> list[Finger]:
    """n fingers spread over the image, drifting with frame k (two rows of hands)."""
    out = []
    for i in range(n):
        row = i % 2
        x = w * (0.12 + 0.76 * (i // 2) / max(1, (n - 1) // 2)) + 3 * np.sin(k / 7 + i)
        y = h * (0.35 if row == 0 else 0.65) + 3 * np.cos(k / 5 + i)
        out.append(Finger(float(x), float(y), 270.0 if row == 0 else 90.0))
    return out


def make_frames(w: int, h: int, n_touch: int, n_distinct: int, seed: int = 0) -> tuple[list, np.ndarray]:
    rng = np.random.default_rng(seed)
    K = intrinsics(w, h)
    mm_per_px = 1000.0 / K[0, 0]

    def noisy(heights: np.ndarray) -> np.ndarray:
        d = 1000.0 - heights + rng.normal(0, 1.5, heights.shape)
        d[rng.random(heights.shape) < 0.01] = 0
        return np.clip(np.rint(d), 0, 65535).astype(np.uint16)

    empty = [noisy(np.zeros((h, w), np.float32)) for _ in range(45)]
    touch = [noisy(render_heights((h, w), fingers_at(k, n_touch, w, h, mm_per_px), mm_per_px))
             if n_touch else noisy(np.zeros((h, w), np.float32)) for k in range(n_distinct)]
    return empty + touch, K


class BenchCase:
    """One case (resolution, touches): a pipeline with its surface learned and warmed up,
    timed in blocks of frames so that the cases can take turns (see :func:`main`)."""

    def __init__(self, w: int, h: int, n_touch: int) -> None:
        self.frames, self.K = make_frames(w, h, n_touch, n_distinct=30)
        self.pipe = Pipeline(surface_frames=45)
        self.t = 0.0
        self.i = 0
        for d in self.frames[:45]:
            self._step(d)
        self.touch = self.frames[45:]
        # warm-up (not timed): the first frames with touches allocate the tracks and the caches
        # settle; a case measured cold runs ~20 % slower for its first few hundred frames
        self.block(WARMUP_FRAMES, timed=False)
        self.samples: dict[str, list[float]] = {s: [] for s in STAGES}
        self.found: list[int] = []

    def _step(self, d: np.ndarray) -> FrameResult:
        result = self.pipe.process(Frame(d, self.t, self.i, 0.001, self.K))
        self.t += 1 / 30
        self.i += 1
        return result

    def block(self, n: int, timed: bool = True) -> None:
        """Process n frames (after a few untimed ones that bring the caches back)."""
        for _ in range(BLOCK_WARMUP if timed else 0):
            self._step(self.touch[self.i % len(self.touch)])
        for _ in range(n):
            result = self._step(self.touch[self.i % len(self.touch)])
            if timed:
                self.found.append(len(result.points))
                for s in STAGES:
                    self.samples[s].append(result.timing_ms[s])

    def result(self) -> dict[str, tuple[float, float]]:
        res = {s: (float(np.median(v)), float(np.percentile(v, 95)))
               for s, v in self.samples.items()}
        res["found"] = (float(np.median(self.found)), 0.0)
        return res


def bench_case(w: int, h: int, n_touch: int, n_frames: int) -> dict[str, tuple[float, float]]:
    """Time one case on its own (n_frames frames after the warm-up)."""
    case = BenchCase(w, h, n_touch)
    case.block(n_frames)
    return case.result()


def machine() -> str:
    cpu = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import os

    return (f"{cpu}; {os.cpu_count()} cores; Python {platform.python_version()}; "
            f"numpy {np.__version__}; OpenCV {cv2.__version__}; {platform.system()} "
            f"{platform.machine()}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default=str(ROOT / "docs" / "benchmarks.md"))
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--quick", action="store_true", help="640x480 only")
    a = ap.parse_args(argv)
    cv2.setNumThreads(1)
    keys = [(w, h, n) for w, h in ([(640, 480)] if a.quick else RESOLUTIONS) for n in TOUCHES]
    cases = [BenchCase(*k) for k in keys]
    # The cases take turns, a block of frames each, so that a slow spell of the machine (a
    # shared VM: tens of seconds at times) is spread over all cases instead of one case's whole
    # measurement.
    per = max(1, a.frames // ROUNDS)
    for _ in range(ROUNDS):
        for case in cases:
            case.block(per)
    rows = []
    for (w, h, n), case in zip(keys, cases):
        r = case.result()
        rows.append((w, h, n, r))
        print(f"{w}x{h} {n:2d} touches: total median {r['total'][0]:.3f} ms, "
              f"p95 {r['total'][1]:.3f} ms (found {r['found'][0]:.0f})", flush=True)
    lines = [
        "# Benchmarks",
        "",
        f"Measured {_dt.date.today().isoformat()} with `make bench` on: {machine()}.",
        "",
        f"The per-frame path (3x3 median and surface adaptation → band masks + regions → touch "
        f"points → tracking → filter and events), timed inside `Pipeline.process` over "
        f"{a.frames} frames per case after the "
        f"surface was learned and {WARMUP_FRAMES} untimed warm-up frames, in {ROUNDS} blocks per "
        f"case with the cases taking turns ({BLOCK_WARMUP} untimed frames before each block), "
        "OpenCV on one thread. "
        "Synthetic frames: a plane at 1 m seen from "
        "above, 1.5 mm noise, 1 % missing pixels, fingers with hands drifting over it (see "
        "`benchmarks/run.py`). Times in ms, median / p95. The paper needed 20 ms per frame.",
        "",
        "| resolution | touches | found | median + surface update | band + regions | touch points "
        "| tracking | filter + events | **total** |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for w, h, n, r in rows:
        cells = [f"{r[s][0]:.3f} / {r[s][1]:.3f}" for s in STAGES]
        cells[-1] = f"**{cells[-1]}**"
        lines.append(f"| {w}x{h} | {n} | {r['found'][0]:.0f} | " + " | ".join(cells) + " |")
    from replay_bench import measure, section

    lines += [""] + _analysis(rows) + section(measure()) + _latency_sections() + _cold_start_section()
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {a.out}")
    return 0


def _analysis(rows: list) -> list[str]:
    """What the table says against the 1 ms target, with the numbers of this run."""
    at = {(w, h, n): r for w, h, n, r in rows}
    out = ["## Against the target", ""]
    if (640, 480, 0) in at and (640, 480, 5) in at:
        t0, t5 = at[(640, 480, 0)]["total"][0], at[(640, 480, 5)]["total"][0]
        t2 = at.get((640, 480, 2), {"total": (float("nan"), 0)})["total"][0]
        ok = "met" if max(t0, t2, t5) <= 1.0 else "not met"
        out += [
            f"Issue 2 asks for at most 1.0 ms median at 640x480 with 0-5 touches: {ok} "
            f"({t0:.2f} ms with none, {t2:.2f} ms with 2, {t5:.2f} ms with 5; about "
            f"{(t5 - t0) / 5:.2f} ms per touch).",
            "",
        ]
    out += [
        "- Without touches the cost is the 3x3 median (OpenCV), one stripe of the surface "
        "adaptation and, every other frame, the 1/8 bump check (compiled), and the band with "
        "its erosion (one compiled pass over the frame).",
        "- With touches: the same band pass lists the runs of the eroded band; the runs are "
        "joined into parts, holes filled and each part dilated back in its own box "
        "(`regions.py`, `runs.py`: OpenCV's contour regions, exactly); the 1/4 resolution hand "
        "map (`handmap.py`); every region's fingertip (`tipkernel.py`, one compiled call per "
        "frame); tracking (plain floats), the path filter (`eurokernel.py`, one compiled call "
        "per frame) and the events.",
        "- Session 28 (same VM, same evening, 640x480 with 5 touches): the path filter's step "
        "compiled instead of some 150 numpy calls a frame took filter + events from 0.27 to "
        "0.07 ms; the surface's drift offset, a median of a 640x20 stripe, taken by a histogram "
        "instead of quickselect, took median + surface update from 0.35 to 0.24 ms "
        "(quickselect's comparisons depend on the data, and a new stripe each frame defeats the "
        "branch predictor: 0.13-0.16 ms against 0.03 ms on one array timed again and again). "
        "Total 1.25 -> 0.91 ms.",
        "- Session 42 (640x480 with 5 touches, quick runs on the same VM): the per-point steps "
        "after the fingertip kernel (the foot of the point on an oblique surface, Tl above its "
        "floor, the forward shift), Python loops over a handful of points, compiled: touch "
        "points 0.371 -> 0.336 ms, total 1.004 -> 0.968 ms. Session 41's recent change had "
        "taken it from 0.959 to 1.004 ms; `make bench` with session 42's defaults read 0.985 and "
        "0.987 ms (two runs): under the 1.0 ms target, by little.",
        "- Session 43: the shape checks of the per-point arrays (some 14 a frame) run as a plain "
        "loop instead of a generator in `all()` (1.2 -> 0.5 µs a call, about 0.01 ms a frame); "
        "with the session's two tracking defaults (a held contact's grace, the enclosure test "
        "for a touch's start only) `make bench` read 0.966 ms (p95 1.142) against 0.987 in "
        "session 42, within the spread between runs; after the review (the enclosure test not "
        "asked twice in a frame) 0.957 ms (p95 1.182).",
        "- Session 44 ran on another machine (an AMD EPYC VM instead of a Xeon): 640x480 with 5 "
        "touches 0.630 ms (p95 0.813) against 0.957 ms, from the machine, not the code; the "
        "session's one change (the enclosure test also refuses a level flank while it arrives) "
        "adds a list comprehension over the few points that test asks about, none in this "
        "scene. After the review (the flank test folded into the enclosure test's one list) "
        "0.662 ms (p95 1.515), within the spread between runs. Compare runs on one machine only.",
        "- Session 45: the lift test's history keeps its core's steps only when "
        "`tracking.lift_noise_k` is on (off by default); kept always, they read the tracking step "
        "0.076 -> 0.081 ms with 5 touches. After the review 640x480 with 5 touches 0.624 ms "
        "(p95 1.368), the same machine as session 44; with the two rolling windows of the lift "
        "test sharing one class (the review), 0.633 ms (p95 0.889), within the spread.",
        "- Session 46: no change to the per-frame path (the filter's class doc only); run again "
        "at the session's end, 640x480 with 5 touches 0.625 ms (p95 0.831) and 0.627 ms (p95 "
        "0.852) in two runs, tracking 0.074-0.076 ms, the same machine.",
        "- Session 47: the tracker asks `tracking.still_step_frames` (off by default) once per "
        "matched track; 640x480 with 5 touches 0.625 ms (p95 0.794), tracking 0.075 ms, the "
        "same machine; after the review (a redundant test dropped) 0.605 ms (p95 0.766), "
        "tracking 0.074 ms, within the spread between runs.",
        "- Session 48: the surface adapter asks `adapt.keep_all_touches` (off by default) once "
        "per stripe cycle (every 24 frames); nothing else on the per-frame path changed. A first "
        "run read 640x480 with 5 touches 0.638 ms (p95 0.856), with OpenCV's reference pass "
        "0.623 -> 0.639 ms and the compressed replay 1.85 -> 2.40 ms in the same run: the "
        "machine that hour, not the code: a second run read 0.666 ms (p95 1.582), and "
        "session 47's code (bde74ad) run right after it on the same machine read "
        "0.661 ms (p95 1.231). After the review (the tracker's evidence weights in one method, "
        "no other change) 0.631 ms (p95 0.804), tracking 0.076 ms: the table above.",
        "- Session 50 ran on another machine again (an Intel Xeon VM, Emerald Rapids at 2.1 "
        "GHz): 640x480 with 5 touches 1.13 ms (p95 1.38) in a first `make bench` and, after the "
        "review (the low band's per-point check only where it is on), 1.30 ms (p95 1.78), the "
        "table above; the frame without touches 0.45 and 0.53 ms against 0.20 ms on the EPYC "
        "of sessions 44-49, while OpenCV's reference pass below read 0.640 and 0.732 ms "
        "against 0.621 (a 640x480 float32 copy "
        "takes 0.074 ms here, OpenCV's 3x3 median of the uint16 frame 0.13 ms; why the "
        "pipeline's stages run 2-2.6 times slower here was not looked into). The session's "
        "change (the enclosure test's low band: the recent "
        "change measured for points whose ring holds more than 15 % of their hand, not 25 %) "
        "against session 49's code (8f3f7ac), `--quick` runs taking turns in the same hour: "
        "1.248, 1.364 ms (session 49) and 1.357, 1.282 ms (session 50), within the spread "
        "between runs. Over the 1.0 ms target on this machine, with either code; compare "
        "runs on one machine only.",
        "- Session 51 (the same Xeon VM): the tracker's count of frame intervals (a loop over "
        "the tracks adding each frame's step) against session 50's code, paired runs taking "
        "turns (4 rounds of 360 frames): 640x480 with 5 touches 1.321 against 1.325 ms, "
        "tracking 0.155 against 0.152 ms. The machine ran "
        "slower this session (the unchanged code read 1.14-1.79 ms in back-to-back `--quick` "
        "runs). Two tries on the fingertip kernel changed nothing and were taken out: reading "
        "each region's windows of the seven per-pixel arrays first, one load per cache line "
        "(touch points 0.669 against 0.668 ms, paired), and the surface's per-pixel arrays in 2 "
        "MB pages (1.456 against 1.500 ms in alternating blocks). The kernel takes 0.17-0.20 ms "
        "for 5 regions on one frame's input repeated, 0.27-0.32 ms on 30 frames' inputs in turn "
        "or with the cache flushed, and 0.28-0.36 ms inside the pipeline: part of what the warm "
        "figure saves is the branch predictor trained on one repeated input, not only memory."
        " `make bench` at the session's end (the table above): 640x480 with 5 touches 1.79 ms"
        " (p95 2.46), 0.64 ms without touches, against 1.30 and 0.53 ms in session 50's table,"
        " while OpenCV's reference pass below read 1.045 ms against 0.732: the machine that"
        " hour, about 40 % slower across the board, not the code (the paired runs above).",
        "- Session 52 ran on an AMD EPYC VM again (as sessions 44-49; this checkout's fresh "
        "install brought OpenCV 5.1.0 instead of 5.0.0): `make bench` read 640x480 with 5 "
        "touches 0.827 ms (p95 1.296) and 0.291 ms without touches in a first run, and after "
        "the review (the default path unchanged: levelling off) 1.118 ms (p95 1.491) and "
        "0.317 ms, the table above (touch points 0.32 -> 0.46 ms, OpenCV's reference pass "
        "0.711 -> 0.720 ms: the machine that hour), against 0.605-0.666 ms in sessions 44-49 "
        "on that kind of machine, while OpenCV's reference pass below read 0.711 ms against "
        "0.621-0.639: the machine that hour and the library, under the 1.0 ms target in the "
        "first run, over it in the second. The "
        "session's change on the per-frame path is one call that returns at once while "
        "levelling (`surface.level_limit_mm`, off by default) is off. On, paired blocks "
        "taking turns (640x480, 5 touches, 8 rounds of 55 frames): 0.99 ms off, 1.15 ms on "
        "(the offset measured on ~4800 pixels, every 4th of every 16th row, with three "
        "histogram medians), 1.31 ms on with every frame 3 mm off (the compiled correction "
        "pass over the frame as well); an earlier version with numpy's quickselect medians "
        "took 0.20 ms for the measurement alone on an 848x480 frame against 0.06-0.08 ms with"
        " histograms.",
        '- Session 53 (an AMD EPYC VM, OpenCV 5.1.0): levelling is on by default now '
        "(`surface.level_limit_mm = 15`, engaged once the frame's shift reaches 1 mm). Not "
        'engaged it measures the offset every frame on ~4800 grid pixels with four exact medians '
        '(about 18 µs each); the level stage timed inside the pipeline (640x480, 5 touches, 540 '
        'frames): 0.120 ms a frame not engaged, 0.279 ms engaged with every frame 3 mm off, '
        'before the correction pass for a plain shift stopped reading the reference (that pass '
        'alone 109 -> 43 µs, the same output; after it 0.133-0.162 ms engaged). `make bench` at '
        "the session's start (levelling off, the code of 2fee989) read 640x480 with 5 touches "
        '1.174 ms (p95 1.844) and 0.324 ms without touches, median + surface update 0.266 ms; '
        'with levelling on, a second run: 1.219 ms (p95 1.625) and 0.400 ms, median + surface '
        'update 0.377 ms (+0.11 ms, the measurement), over the 1.0 ms target on this machine that'
        ' hour either way; after the review (the offset where it is largest asked through one '
        'helper, the same behaviour) that run\'s table: 0.853 ms (p95 1.170) and 0.358 ms, median +'
        " surface update 0.287 ms, with OpenCV's reference pass at 0.669 ms: the machine faster "
        "that hour; OpenCV's reference pass read 0.931 ms in the first run against "
        '0.62-0.64 ms in sessions 44-49 (and 2.214 ms in the second run, the neighbours during '
        'that part).',
        '- Session 54 (the same AMD EPYC VM, OpenCV 5.1.0): one change on the per-frame path, '
        "the tracker's test of which points may start a contact moved into one function that "
        "the evaluation's reasons share (the same arithmetic). `make bench` (the table above) "
        'read 640x480 with 5 touches 1.146 ms (p95 1.571) and 0.426 ms without touches, over '
        "the 1.0 ms target, with OpenCV's reference pass at 0.930 ms against 0.669 ms in "
        "session 53's last run: the machine about 40 % slower that hour. Against the session's "
        'starting code (37ed8c4), `--quick` runs taking turns in the same hour: 1.045, 1.300, '
        '1.312 ms (37ed8c4) and 1.329, 1.325, 1.259 ms (this code), tracking 0.122-0.156 '
        'against 0.147-0.157 ms: within the spread between runs.',
        '- Session 55 (the same AMD EPYC VM, OpenCV 5.1.0): no change to the per-frame path. '
        'The same code read 640x480 with 5 touches 0.84-0.89 ms in some processes and 1.06-1.34'
        ' ms in others started minutes apart, every stage slower together (tracking, plain '
        'Python, 0.093 against 0.134-0.154 ms): the whole process runs slower, not one stage, '
        'so separate processes compare their luck as much as the code. `benchmarks/paired.py '
        '--against REV` times this checkout and another revision (exported with `git archive` '
        'as the package `depthtouch_b`) in one process, taking turns in blocks of 60 frames: '
        'the same code against itself read 0.793 / 0.777 ms, per-round ratios 0.77-1.04 with a '
        'median of 0.99. Measured with it and not kept: the surface arrays in 2 MB pages (one '
        '`madvise`d map) 0.829 ms against 0.834 ms in plain pages, and 1.317 against 1.268 ms '
        "in a second run; every kernel compiled with numpy's error model (no division checks) "
        "0.838 against 0.855 ms, and 0.889 against 0.853 ms: no change either way. "
        "The fingertip kernel's call on a frame "
        'took 0.268 ms in the pipeline and 0.215 ms called again at once on the same frame: the'
        ' cold cache costs it about a fifth.',
        '- Session 56 (an AMD EPYC VM, OpenCV 5.1.0, a new machine): one change on the '
        "per-frame path, the tracker's pending points given to the path filter at down "
        '(`tracking.land_prior_frames`, off by default: the tracker and the pipeline each test '
        'one flag). `make bench` (the table above) read 640x480 with 5 touches 1.175 ms (p95 '
        '1.762) and 0.566 ms without touches, over the 1.0 ms target, with OpenCV\'s reference '
        'pass at 0.746 ms. `benchmarks/paired.py --against 7017c3e` (the session\'s starting '
        'code, 8 rounds of 60 frames in one process): 1.340 ms (this code) against 1.305 ms, '
        'per-round ratio B/A median 1.022 (0.765-1.069), tracking 0.152 against 0.145 ms: '
        'within the spread between rounds.',
        '- Session 57 (the same AMD EPYC VM, OpenCV 5.1.0): two changes on the per-frame path: '
        "the path filter's re-landing on by default (`filter.params.reland_frames` 6; its test "
        "runs inside the compiled filter step), and one more test per pixel in the surface "
        "adapter's stripe pass (`adapt.drift_kept_out`, on by default, as before). After the "
        'first, `make bench` read 640x480 with 5 touches 1.748 ms and then 1.665 ms (p95 2.033),'
        ' 0.696 ms without touches, with OpenCV\'s reference pass at 1.104 and 1.038 ms against '
        '0.746 ms in session 56: the machine about 40 % slower this hour. After the second, the '
        'table above: 1.955 ms (p95 2.455) and 0.713 ms, the reference pass 0.962 ms. '
        "`benchmarks/paired.py` (8 rounds of 60 frames in one process) against the session's "
        'starting code (204b25e), twice: 1.684 against 1.502 ms with per-round ratio B/A median '
        '1.025 (0.660-1.267), and 1.755 against 1.811 ms, median 1.036 (0.943-1.128); the '
        "adapter's test against 6673f81, the code before it: 1.604 against 1.863 ms, median "
        '1.124 (0.838-1.332), median + surface update 0.485 against 0.540 ms. No cost the rounds '
        'can tell from their spread; over the 1.0 ms target on this machine this hour either way.',
        '- Session 58 (an AMD EPYC VM, OpenCV 5.1.0; measured on a new machine the session after): '
        "two options in the surface adapter's stripe pass, off by default (`adapt.drift_hold_mm`, "
        "`adapt.drift_hold_after_s`): one more bit in the exclusion map it already builds, and "
        "when on, a small list of the last cycle's touches. `make bench` (that session's table) read "
        '640x480 with 5 touches 1.183 ms (p95 1.637) and 0.401 ms without touches, over the 1.0 '
        "ms target, with OpenCV's reference pass at 0.859 ms. `benchmarks/paired.py --against "
        "038c37b` (the session's starting code, 8 rounds of 60 frames in one process): 1.126 ms "
        '(this code) against 1.163 ms, per-round ratio B/A median 1.012 (0.879-1.327), median + '
        'surface update 0.357 against 0.361 ms: no cost the rounds can tell.',
        '- Session 60 (the same AMD EPYC VM, OpenCV 5.1.0): one more comparison per matched '
        "pending contact in the tracker (`tracking.steep_still_mm`, off by default). `make bench` "
        '(the table above) read 640x480 with 5 touches 0.787 ms (p95 2.405) and 0.346 ms without '
        "touches, under the 1.0 ms target, with OpenCV's reference pass at 0.683 ms against "
        "0.859 ms in session 59's run of nearly the same code (1.183 ms): the machine that hour. "
        "`benchmarks/paired.py --against 61cbc38` (session 59's last code, 20 rounds of 60 "
        'frames in one process): 0.825 ms (this code) against 0.822 ms, per-round ratio B/A '
        'median 0.996 (0.751-1.334). On this machine the 5-touch frame lies on either side of the '
        "target depending on the hour. Timed inside the pipeline in one process (300 frames, "
        "three rounds, an hour when the whole frame took about 1.0 ms): the 3x3 median 79-91 us, "
        "levelling 92-107 us, the surface follow 127-157 us, band and regions 98-117 us, the hand "
        "map 47-59 us, the fingertip kernel 224-271 us (105 us on one frame's input repeated), "
        "the tracker 117-148 us, filter and events 81-107 us: no part holds the excess alone.",
        '- Session 61 (the same AMD EPYC VM, OpenCV 5.1.0): on the per-frame path one test of a '
        "frame's intrinsics (frames without K get assumed ones, `surface.assumed_hfov_deg`); the "
        'learning leaves out what moved after its first second (`surface.learn_min_s`; one '
        'compiled pass at the end of the learning, 44 ms at 848x480 for 46 frames, the learning '
        'itself about 0.4 s). `make bench` (a first run) read 640x480 with 5 touches 1.380 ms'
        " (p95 2.008) and 0.439 ms without touches, over the 1.0 ms target, with OpenCV's "
        "reference pass at 0.919 ms against 0.683 ms in session 60's run (0.787 ms): every stage "
        'slower together, tracking (plain Python) 0.159 against 0.089 ms. `benchmarks/paired.py '
        "--against 874bb79` (session 60's last code, 20 rounds of 60 frames in one process): "
        '1.014 ms (this code) against 1.017 ms, per-round ratio B/A median 1.001 (0.705-1.484): '
        "the machine that hour and the process's luck, not the code. After the review (the same "
        "arithmetic on the per-frame path), the table above: 1.216 ms (p95 1.623) and 0.445 ms "
        "without touches, OpenCV's reference pass 0.957 ms.",
        "- The fingertip kernel reads small windows of six per-pixel surface arrays that the "
        "full-frame passes (median, band) push out of the cache each frame: the same call takes "
        "about half the time on warm data. Memory, not arithmetic, is most of what is left.",
        "- Before the compiled kernels (numpy/OpenCV array calls only; the same points, see "
        "`tests/reference_touchpoints.py`) the 5-touch frame took 2.5-3.2 ms: some 40 calls of "
        "a few microseconds per region, Python overhead rather than pixels.",
        "- The kernels are compiled by numba on the first run (~15-30 s, cached on disk; "
        "`Pipeline()` compiles or loads them before the first frame).",
        "- All of it stays far under a camera's frame interval (33 ms at 30 fps, 11 ms at 90 fps) "
        "and the paper's 20 ms, up to 10 touches at 1280x720.",
        "- The machine is a shared 2-core VM: medians move by up to ±30 % between runs, and the p95 "
        "column carries the neighbours' noise.",
        "",
    ]
    return out


def _tuio_latency(n: int = 300) -> dict[str, float]:
    """Frame processed -> TUIO bundle received on 127.0.0.1 (and time spent in the sink)."""
    import socket

    from depthtouch.outputs.tuio import TuioSink
    from depthtouch.types import FrameResult, TouchEvent, TouchPoints

    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(1.0)
    port = rx.getsockname()[1]
    send_ms, recv_ms = [], []
    img = np.zeros((480, 640), np.uint16)
    with TuioSink("127.0.0.1", port) as sink:
        rx.recv(65536)  # the empty alive (fseq -1) sent when the sink opens
        for i in range(n):
            f = Frame(img, i / 60, i, 0.001, None)
            evs = [TouchEvent(i, i / 60, k + 1, "down" if i == 0 else "move",
                              100.0 + k * 50 + i % 7, 200.0 + i % 5) for k in range(2)]
            result = FrameResult(f, evs, TouchPoints.empty(), "ok")
            t0 = time.perf_counter()
            sink.send(result)
            t1 = time.perf_counter()
            rx.recv(65536)
            t2 = time.perf_counter()
            send_ms.append((t1 - t0) * 1e3)
            recv_ms.append((t2 - t0) * 1e3)
    rx.close()
    return {"median_ms": float(np.median(recv_ms)), "p95_ms": float(np.percentile(recv_ms, 95)),
            "send_median_ms": float(np.median(send_ms)), "n": n}


def _latency_sections() -> list[str]:
    """Event latency from a processed frame to the network outputs (2 touches per frame)."""
    from depthtouch.web.latency import measure_ws_latency

    t = _tuio_latency(300)
    w = measure_ws_latency(300)
    return [
        "## Event latency to the outputs",
        "",
        "From the moment a processed frame's 2 touch events are handed to the sink (300 frames, "
        "127.0.0.1):",
        "",
        "| output | median ms | p95 ms |",
        "|---|---|---|",
        f"| TUIO bundle received by a UDP socket | {t['median_ms']:.3f} | {t['p95_ms']:.3f} |",
        f"| WebSocket message sent by the server | {w['median_ms']:.3f} | {w['p95_ms']:.3f} |",
        f"| WebSocket message received by an aiohttp client | {w['recv_median_ms']:.3f} | "
        f"{w['recv_p95_ms']:.3f} |",
        "",
        f"Time spent in the sink's `send` on the pipeline thread: TUIO {t['send_median_ms']:.3f} ms, "
        f"WebSocket {w['publish_median_ms']:.3f} ms (median).",
        "",
    ]


def _start_s(cache_dir: str) -> float:
    """Wall time of a fresh process that imports depthtouch and builds a Pipeline."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "from depthtouch.pipeline import Pipeline; Pipeline()"],
                   env=env, check=True, capture_output=True)
    return time.perf_counter() - t0


def _cold_start_section() -> list[str]:
    """First run after installing (an empty numba cache) and the next run (cache warm)."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="depthtouch-numba-") as d:
        cold = _start_s(d)
        warm = _start_s(d)
    print(f"start: cold cache {cold:.1f} s, warm {warm:.1f} s", flush=True)
    return [
        "## Start-up",
        "",
        "A fresh process importing depthtouch and building a `Pipeline` (kernels compiled or "
        "loaded), with an empty `NUMBA_CACHE_DIR` (the first run after installing; it prints "
        "\"compiling the touch kernels once\") and then with that cache filled:",
        "",
        "| numba cache | start s |",
        "|---|---|",
        f"| cold | {cold:.1f} |",
        f"| warm | {warm:.1f} |",
        "",
    ]


if __name__ == "__main__":
    raise SystemExit(main())
