"""Command line, the evaluation and tool commands: eval, demo, calibrate, gestures, sim,
bench-filters (argument parsing only; :mod:`depthtouch.cli` has the streaming commands and
``main``)."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .config import PipelineConfig


def load_config_arg(path: str | None) -> PipelineConfig:
    """The ``--config`` file's settings, or the defaults without one."""
    from .config import PipelineConfig, load_config

    return load_config(path) if path else PipelineConfig()


_load_config = load_config_arg


# --- bench-filters ------------------------------------------------------------------------------
def _add_bench_filters(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bench-filters", help="measure the touch path filters on simulated paths"
    )
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    p.add_argument("--seed", type=int, default=1, help="seed of the measured paths (default 1)")
    p.add_argument("--figure", help="also plot true, raw and filtered paths to this PNG")
    p.add_argument("--tune", action="store_true",
                   help="re-tune each filter on the tuning seeds before measuring")

    def run(a: argparse.Namespace) -> int:
        from .evaluation.filterbench import bench_filters, describe, to_json, write_figure

        if a.figure:  # first, so that a bad path fails before the measurement
            write_figure(a.figure, a.seed)
        result = bench_filters(a.seed, tune=a.tune)
        print(to_json(result) if a.json else describe(result))
        return 0

    p.set_defaults(func=run)


# --- eval ---------------------------------------------------------------------------------------
def _add_eval(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("eval", help="measure touch accuracy against simulator ground truth")
    p.add_argument("recording", nargs="?", help="FILE.npz or a PNG folder (with --truth)")
    p.add_argument("--truth", help="the recording's ground truth (depthtouch-truth/1 JSON)")
    p.add_argument("--events", help="evaluate this events file instead of running the sensor")
    p.add_argument("--suite", help="evaluate a suite: a committed name (default) or a .toml")
    p.add_argument("--subset", help="only the suite's cases tagged so (e.g. quick)")
    p.add_argument("--by",
                   help="suite rows: scene, camera, group, label, distance_m, surface or all "
                        "(default scene; with --half, group: the suite's situations)")
    p.add_argument("--config", help="TOML config file (see docs/config.md)")
    p.add_argument("--gate-mm", type=float, default=20.0, help="match gate in mm (default 20)")
    p.add_argument("--workers", type=int, help="processes for a suite (default: cores, <= 4)")
    p.add_argument("--cache", action="store_true",
                   help="keep the suite's recordings in .cache/depthtouch/suite (or "
                        "$DEPTHTOUCH_CACHE) and reuse them; the least recently used go past "
                        "$DEPTHTOUCH_CACHE_MAX_GB (default 50, 0: no limit)")
    p.add_argument("--half", choices=("tune", "held-out", "all"),
                   help="with --suite: the tune or held-out half (or all), both side by side")
    p.add_argument("--ci", type=int, metavar="N", default=0,
                   help="with --half: 95%% bootstrap intervals over the recordings of each half "
                        "for recall, false touches, error, jitter and angle (N resamples, e.g. "
                        "1000)")
    p.add_argument("--against", metavar="B.toml",
                   help="with --half: run each case with this config too and give B - A per "
                        "measure with its paired 95%% bootstrap interval (A: --config or the "
                        "defaults)")
    p.add_argument("--fps", type=float,
                   help="with --suite: render every case at this frame rate (Hz, 1-120) "
                        "instead of the suite's 30")
    p.add_argument("--resolution-scale", type=float, metavar="S",
                   help="with --suite: every camera at S times its resolution, the same field "
                        "of view (0.25-3; 1.5 turns the D435's 848x480 into 1272x720)")
    p.add_argument("--noise-scale", type=float, metavar="S",
                   help="with --suite: every camera's axial noise S times its own (0.25-4)")
    p.add_argument("--body", action="store_true",
                   help="with --suite: every arm goes on past the shoulder into a body that "
                        "leaves the view (the suite's arms end at the shoulder unless it says "
                        "otherwise; docs/simulator.md)")
    p.add_argument("--drop-rate", type=float, metavar="P",
                   help="with --suite: frames the camera never delivers, as a busy USB bus "
                        "drops them: after a kept frame the next is lost with chance P (0-0.2), "
                        "in bursts of 1.4 on average (docs/simulator.md)")
    p.add_argument("--breathing-mm", type=float, metavar="MM",
                   help="with --suite: every frame moves as a whole, as a depth camera's does: "
                        "a wobble of MM/2 and jumps of 1-2 MM held 0.5-3 s (0-10; "
                        "docs/simulator.md)")
    p.add_argument("--empty-s", type=float, metavar="S",
                   help="with --suite: every recording's first frames taken away so that "
                        "something comes into view S s after its start (0.2-10; the scenes "
                        "wait 1.5 s and more, a recording promises 1 s: docs/formats.md)")
    p.add_argument("--edge-mm", type=float, metavar="MM",
                   help="with --suite: the surface ends inside the view, on the side the "
                        "user's arm comes from, and beyond its edge lies a floor MM farther "
                        "(100-1500; docs/simulator.md)")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON")
    p.add_argument("--space", choices=("depth", "screen"), default="depth",
                   help="score --events by x, y (depth) or sx, sy (screen: fused cameras of "
                        "sim --views)")
    p.add_argument("--gestures", action="store_true",
                   help="gesture precision and recall per kind (tap, long press, drag) instead; "
                        "without a recording: on the simulated presses, taps and drags scenes")

    def run(a: argparse.Namespace) -> int:
        import json

        from .errors import ConfigError
        from .evaluation.suite import cache_root
        from .evaluation.suiterun import eval_recording_command, eval_suite_command

        cfg = _load_config(a.config)
        if a.half:
            from .evaluation.halves import print_halves

            if not a.suite:
                raise ConfigError("--half needs --suite NAME (e.g. --suite hard --half held-out)")
            if a.against:
                from .evaluation.halves import print_compare

                if (a.fps is not None or a.resolution_scale is not None
                        or a.noise_scale is not None or a.body or a.drop_rate is not None
                        or a.breathing_mm is not None):
                    raise ConfigError("--against runs the suite as it is; leave out --fps, "
                                      "--resolution-scale, --noise-scale, --body, "
                                      "--drop-rate and --breathing-mm")
                if a.by is not None:
                    raise ConfigError("--against compares the overall figures of each half; "
                                      "leave out --by")
                return print_compare(a.suite, a.half, _load_config(a.against), subset=a.subset,
                                     config=cfg, workers=a.workers,
                                     cache=cache_root() if a.cache else None, as_json=a.json,
                                     ci=a.ci or 1000,
                                     progress=None if a.json else _print_case,
                                     empty_s=a.empty_s, edge_mm=a.edge_mm)
            return print_halves(a.suite, a.half, subset=a.subset, config=cfg,
                                workers=a.workers, cache=cache_root() if a.cache else None,
                                as_json=a.json, progress=None if a.json else _print_case,
                                fps=a.fps, resolution_scale=a.resolution_scale,
                                noise_scale=a.noise_scale, by=a.by or "group", ci=a.ci,
                                body=a.body, drop_rate=a.drop_rate,
                                breathing_mm=a.breathing_mm, empty_s=a.empty_s,
                                edge_mm=a.edge_mm)
        if a.ci or a.against:
            flag = "--ci" if a.ci else "--against"
            raise ConfigError(f"{flag} needs --suite NAME --half H (intervals over a half's "
                              "recordings)")
        if a.fps is not None and not a.suite:
            raise ConfigError("--fps needs --suite NAME (a recording has its own frame rate)")
        if a.resolution_scale is not None and not a.suite:
            raise ConfigError("--resolution-scale needs --suite NAME (a recording has its own "
                              "resolution)")
        if a.noise_scale is not None and not a.suite:
            raise ConfigError("--noise-scale needs --suite NAME (a recording has its own noise)")
        if a.body and not a.suite:
            raise ConfigError("--body needs --suite NAME (a recording has its own arms); render "
                              "one with `depthtouch sim SCENE --body`")
        if a.drop_rate is not None and not a.suite:
            raise ConfigError("--drop-rate needs --suite NAME (a recording has the frames it "
                              "has); render one with `depthtouch sim SCENE --drop-rate P`")
        if a.breathing_mm is not None and not a.suite:
            raise ConfigError("--breathing-mm needs --suite NAME (a recording has its own "
                              "noise); render one with `depthtouch sim SCENE --breathing-mm MM`")
        if a.empty_s is not None and not a.suite:
            raise ConfigError("--empty-s needs --suite NAME (a recording starts as it starts); "
                              "cut a recording's first frames yourself")
        if a.edge_mm is not None and not a.suite:
            raise ConfigError("--edge-mm needs --suite NAME (a recording shows the surface it "
                              "shows); render one with `depthtouch sim SCENE --edge-mm MM`")
        if a.gestures:
            from .evaluation.gestures import gestures_output

            print(gestures_output(a.recording, a.truth, events_path=a.events, config=cfg,
                                  as_json=a.json, progress=None if a.json else _print_case))
            return 0
        if a.suite:
            if a.recording or a.truth or a.events:
                raise ConfigError("give either --suite or a recording with --truth, not both")
            metrics = eval_suite_command(
                a.suite, subset=a.subset, by=a.by or "scene", config=cfg, workers=a.workers,
                cache=cache_root() if a.cache else None,
                progress=None if a.json else _print_case, fps=a.fps,
                resolution_scale=a.resolution_scale, noise_scale=a.noise_scale, body=a.body,
                drop_rate=a.drop_rate, breathing_mm=a.breathing_mm, empty_s=a.empty_s,
                edge_mm=a.edge_mm,
            )
        else:
            metrics = eval_recording_command(a.recording, a.truth, events_path=a.events,
                                             config=cfg, gate_mm=a.gate_mm, space=a.space)
        if a.json:
            print(json.dumps({k: m.to_dict() for k, m in metrics.items()}, indent=1))
        else:
            from rich.console import Console

            from .evaluation.halves import reasons_text
            from .evaluation.report import metrics_table

            wide = None if sys.stdout.isatty() else 200  # no terminal: do not squeeze to 80
            console = Console(width=wide)
            console.print(metrics_table(metrics, title=f"accuracy ({a.suite or 'recording'})"))
            for name, m in metrics.items():
                if m.missed_by_reason:
                    console.print(f"{name}: missed {sum(m.missed_by_reason.values())} contacts "
                                  f"the camera saw; why: {reasons_text(m.missed_by_reason)}",
                                  highlight=False)
        return 0

    p.set_defaults(func=run)


def _print_case(case: object, result: object) -> None:
    print(f"  evaluated {getattr(case, 'label', case)}", file=sys.stderr, flush=True)


# --- demo ---------------------------------------------------------------------------------------
def _add_demo(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="simulate scenes, run the sensor, write an HTML report")
    p.add_argument("--out", default="demo-report", help="report folder (default demo-report)")
    p.add_argument("--camera", default="kinect-v2", help="simulated camera profile")
    p.add_argument("--distance", type=float, default=1.0, help="camera to surface, m (1.0)")
    p.add_argument("--scenes", help="comma-separated scenes (default multitouch,drags,taps,hover)")
    p.add_argument("--seed", type=int, default=1, help="simulator seed (default 1)")
    p.add_argument("--config", help="TOML config file (see docs/config.md)")

    def run(a: argparse.Namespace) -> int:
        from rich.console import Console

        from .evaluation.report import DEMO_SCENES, metrics_table, run_demo

        scenes = [s.strip() for s in a.scenes.split(",") if s.strip()] if a.scenes else None
        res = run_demo(a.out, scenes=scenes or DEMO_SCENES, camera=a.camera,
                       distance_m=a.distance, seed=a.seed, config=_load_config(a.config),
                       progress=lambda msg: print(msg, flush=True))
        wide = None if sys.stdout.isatty() else 200
        Console(width=wide).print(metrics_table(res.metrics, title="demo accuracy"))
        print(f"report written to {res.index.resolve()} ({res.seconds:.1f} s)")
        return 0

    p.set_defaults(func=run)


# --- calibrate ----------------------------------------------------------------------------------
def _add_calibrate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate", help="fit the depth-to-screen homography from touched target points"
    )
    p.add_argument("--points", required=True,
                   help='JSON point pairs: {"pairs": [{"depth_xy": [x, y], "screen_xy": '
                        '[sx, sy]}, ...]} (see docs/outputs.md)')
    p.add_argument("--screen", metavar="WxH",
                   help="screen size in pixels, e.g. 1920x1080 (else screen_wh from the file)")
    p.add_argument("--out", required=True, help="write the calibration JSON here")
    p.add_argument("--ransac-px", type=float, default=25.0,
                   help="outlier threshold in screen pixels with more than 4 pairs (default 25)")

    def run(a: argparse.Namespace) -> int:
        from .calibration import (
            fit_calibration,
            load_point_pairs,
            parse_screen_wh,
            save_calibration,
        )
        from .errors import CalibrationError

        depth_xy, screen_xy, file_wh = load_point_pairs(a.points)
        wh = parse_screen_wh(a.screen) if a.screen else file_wh
        if wh is None:
            raise CalibrationError(
                "screen size unknown; pass --screen WxH or put screen_wh in the points file"
            )
        cal = fit_calibration(depth_xy, screen_xy, wh, ransac_threshold_px=a.ransac_px)
        save_calibration(cal, a.out)
        print(
            f"calibration: {cal.n_inliers}/{cal.n_points} pairs used, reprojection error "
            f"{cal.reprojection_error_px:.2f} px RMS (max {cal.max_error_px:.2f} px), "
            f"leave-one-out {cal.loo_error_px:.2f} px, screen {wh[0]}x{wh[1]} -> {a.out}"
        )
        if cal.n_points == 4:
            print("note: 4 pairs fit exactly (error 0 by construction); use 5 or more targets "
                  "to measure the accuracy")
        return 0

    p.set_defaults(func=run)


# --- gestures -----------------------------------------------------------------------------------
def _add_gestures(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "gestures", help="tap, double tap, long press, drag, pinch, rotate from an events file"
    )
    p.add_argument("events", help="touch events JSON Lines file (from replay --events)")
    p.add_argument("--out", help="write gesture JSON Lines here (default: stdout)")
    p.add_argument("--space", choices=("depth", "screen"), default="depth",
                   help="pixels of the gestures: depth image, or screen (needs sx, sy)")

    def run(a: argparse.Namespace) -> int:
        import json

        from .files import write_text_atomic
        from .gestures import GestureConfig, recognize_all
        from .outputs.jsonl import read_events

        found = recognize_all(read_events(a.events), GestureConfig(space=a.space))
        lines = "".join(json.dumps(g.to_dict()) + "\n" for g in found)
        if not a.out:
            sys.stdout.write(lines)
            return 0
        out = write_text_atomic(a.out, lines, what="the gestures")
        print(f"{len(found)} gestures -> {out}")
        return 0

    p.set_defaults(func=run)


# --- sim ----------------------------------------------------------------------------------------
def _add_sim(sub: argparse._SubParsersAction) -> None:
    from .sim import ALL_SCENES, CAMERAS, SURFACES
    from .sim.hand import HAND_STYLES

    p = sub.add_parser("sim", help="render a simulated depth recording with ground truth")
    p.add_argument("scene", help=f"one of {', '.join(ALL_SCENES)}")
    p.add_argument("--out", required=True, help="FILE.npz or a new PNG folder")
    p.add_argument("--truth", required=True, help="ground-truth JSON (docs/simulator.md)")
    p.add_argument("--camera", default="realsense-d435", help=f"one of {', '.join(CAMERAS)}")
    p.add_argument("--distance", type=float, default=1.0, help="surface distance, m [0.5, 2.5]")
    p.add_argument("--tilt", type=float, default=0.0, help="surface tilt, deg [0, 40]")
    p.add_argument("--surface", default="plane", help=f"one of {', '.join(SURFACES)}")
    p.add_argument("--hand", default="capsule",
                   help=f"hand model, one of {', '.join(HAND_STYLES)} (docs/simulator.md)")
    p.add_argument("--seed", type=int, default=0, help="random seed (>= 0)")
    p.add_argument("--fps", type=float, default=30.0, help="frame rate, Hz [1, 120]")
    p.add_argument("--resolution-scale", type=float, default=1.0, metavar="S",
                   help="the camera at S times its resolution, same field of view [0.25, 3]")
    p.add_argument("--noise-scale", type=float, default=1.0, metavar="S",
                   help="the camera's axial noise S times its own [0.25, 4]; artefacts unchanged")
    p.add_argument("--pitch", type=float, metavar="DEG",
                   help="every lead finger at DEG to the surface [10, 85] instead of the "
                        "scene's random pitch (20-70 for most); the rest of the seed's scene "
                        "stays the same")
    p.add_argument("--motion-ms", type=float, default=0.0, metavar="MS",
                   help="ToF motion mixing: each frame integrated over MS ms [0, 50] centred on "
                        "its timestamp, so pixels a moving hand covers or uncovers read mixed "
                        "depths")
    p.add_argument("--skin-noise", type=float, default=1.0, metavar="K",
                   help="the temporal noise of the hand (and anything on the surface) x K "
                        "[1, 4], and every pixel's growing with its incidence angle: a ToF "
                        "camera's noise follows the infrared amplitude it gets back")
    p.add_argument("--body", action="store_true",
                   help="arms go on past the shoulder into a body that leaves the view, as a "
                        "person's do (without: the arm ends at the shoulder, seen whole from "
                        "about 1.3 m)")
    p.add_argument("--drop-rate", type=float, default=0.0, metavar="P",
                   help="frames the camera never delivers [0, 0.2]: after a kept frame the "
                        "next is lost with chance P, in bursts of 1.4 on average; the rest keep "
                        "their timestamps and the truth is numbered over them")
    p.add_argument("--breathing-mm", type=float, default=0.0, metavar="MM",
                   help="the whole frame moves at once [0, 10]: a wobble of MM/2 (0.5 s) and "
                        "jumps of 1-2 MM held 0.5-3 s, as a depth camera's frame does; a "
                        "disparity camera's pixels by (z / distance)^2 of it")
    p.add_argument("--edge-mm", type=float, default=0.0, metavar="MM",
                   help="the surface ends inside the view (a table's edge, across the way the "
                        "first arm comes in) and beyond it lies a floor MM farther: 0 (none) or "
                        "[100, 1500]")
    p.add_argument("--no-noise", action="store_true", help="exact geometry, no sensor noise")
    p.add_argument("--views", type=int, metavar="N",
                   help="N cameras (2-3) 0.8 m apart: --out is a folder of viewK.npz, "
                        "viewK.calibration.json and --truth on the shared screen "
                        "(docs/multicam.md)")
    p.add_argument("-q", "--quiet", action="store_true", help="print only errors")

    def run(a: argparse.Namespace) -> int:
        from .errors import ConfigError
        from .sim import render_scene, write_recording

        if a.views is not None and a.resolution_scale != 1.0:
            raise ConfigError("--resolution-scale applies to one camera; leave it out with "
                              "--views")
        if a.views is not None and a.noise_scale != 1.0:
            raise ConfigError("--noise-scale applies to one camera; leave it out with --views")
        if a.views is not None and a.pitch is not None:
            raise ConfigError("--pitch applies to one camera; leave it out with --views")
        if a.views is not None and a.motion_ms != 0.0:
            raise ConfigError("--motion-ms applies to one camera; leave it out with --views")
        if a.views is not None and a.skin_noise != 1.0:
            raise ConfigError("--skin-noise applies to one camera; leave it out with --views")
        if a.views is not None and a.body:
            raise ConfigError("--body applies to one camera; leave it out with --views")
        if a.views is not None and a.drop_rate != 0.0:
            raise ConfigError("--drop-rate applies to one camera; leave it out with --views")
        if a.views is not None and a.breathing_mm != 0.0:
            raise ConfigError("--breathing-mm applies to one camera; leave it out with --views")
        if a.views is not None and a.edge_mm != 0.0:
            raise ConfigError("--edge-mm applies to one camera; leave it out with --views")
        if a.views is not None:
            from .sim.multiview import default_poses, render_views, write_views

            mv = render_views(a.scene, default_poses(a.views), camera=a.camera,
                              distance_m=a.distance, seed=a.seed, fps=a.fps,
                              noise=not a.no_noise)
            written = write_views(mv, a.out, truth_path=a.truth)
            if not a.quiet:
                print("\n".join(str(p) for p in written))
            return 0

        rec = render_scene(
            a.scene, camera=a.camera, distance_m=a.distance, tilt_deg=a.tilt,
            surface=a.surface, seed=a.seed, fps=a.fps, noise=not a.no_noise, hand=a.hand,
            resolution_scale=a.resolution_scale, pitch_deg=a.pitch, noise_scale=a.noise_scale,
            motion_ms=a.motion_ms, skin_noise=a.skin_noise, body=a.body,
            drop_rate=a.drop_rate, breathing_mm=a.breathing_mm, edge_mm=a.edge_mm,
        )
        write_recording(rec, a.out, a.truth)
        if not a.quiet:
            n, h, w = rec.depth.shape
            contacts = {c["id"] for f in rec.truth["frames"] for c in f["contacts"]}
            print(f"{a.out}: {n} frames {w}x{h} at {rec.fps:g} fps, "
                  f"{rec.truth['empty_frames']} empty, {len(contacts)} contacts; truth {a.truth}")
        return 0

    p.set_defaults(func=run)
