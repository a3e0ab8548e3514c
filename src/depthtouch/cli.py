"""Command line: parses arguments and calls one typed function per command.

Each command has its own ``_add_<name>`` function that declares its arguments and sets
``func``; :data:`_COMMANDS` lists them. A :class:`DepthTouchError` (a user's mistake) becomes one
line on stderr and exit code 2; Ctrl-C exits 130 after the command's own cleanup.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from .errors import DepthTouchError

if TYPE_CHECKING:
    from .config import PipelineConfig
    from .fusion import FusionConfig


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        # argparse's own usage errors follow the one-line rule too
        self.exit(2, f"depthtouch: error: {message} (see depthtouch {self.prog.split()[-1]} -h)\n")


def _load_config(path: str | None) -> PipelineConfig:
    from .config import PipelineConfig, load_config

    return load_config(path) if path else PipelineConfig()


def _add_common_outputs(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", help="TOML config file (see docs/config.md)")
    p.add_argument("--events", help="write touch events to this JSON Lines file")
    p.add_argument(
        "--tuio", metavar="HOST:PORT", nargs="?", const="127.0.0.1:3333",
        help="send TUIO 1.1 /tuio/2Dcur over UDP (default 127.0.0.1:3333)",
    )
    p.add_argument("--calibration", action="append",
                   help="screen calibration file (adds sx, sy to events); several sources: "
                        "one per source, in the same order")
    p.add_argument("--uinput", action="store_true",
                   help="also touch the desktop: a virtual touchscreen (Linux, docs/uinput.md)")
    _add_fusion_gate(p)


def _add_fusion_gate(p: argparse.ArgumentParser) -> None:
    p.add_argument("--fusion-gate-px", type=float, default=60.0, metavar="PX",
                   help="several cameras: touches this close on the screen are one finger "
                        "(screen px, default 60; docs/multicam.md)")


def _fusion(a: argparse.Namespace) -> FusionConfig:
    from .fusion import FusionConfig

    return FusionConfig(gate_px=a.fusion_gate_px)


# --- replay -------------------------------------------------------------------------------------
def _add_replay(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="run the sensor on a depth recording")
    p.add_argument("recording", nargs="+", help="FILE.npz, a PNG folder, FILE.bag or FILE.db3 "
                   "(several: one per camera, fused on one screen; docs/multicam.md)")
    _add_common_outputs(p)
    p.add_argument("--surface", help="load a saved surface model instead of learning one")
    p.add_argument("--save-surface", help="save the learned surface model to this file")
    p.add_argument("--surface-frames", type=int, help="learn the surface from N frames")
    p.add_argument("--filter", help="path filter name (overrides the config)")
    p.add_argument("--realtime", action=argparse.BooleanOptionalAction, default=None,
                   help="play at the recording's own pace (default with --tuio, so that apps "
                        "see the touches as they happened) or as fast as possible (default)")
    p.add_argument("-q", "--quiet", action="store_true", help="print only errors")

    def run(a: argparse.Namespace) -> int:
        from .replay import replay

        cfg = _load_config(a.config)
        paced = a.realtime if a.realtime is not None else bool(a.tuio)
        if paced and a.realtime is None and not a.quiet:
            print("depthtouch: replaying at the recording's own pace for --tuio "
                  "(--no-realtime: as fast as possible)", file=sys.stderr)
        if len(a.recording) > 1 or len(a.calibration or []) > 1:
            from .multicam import check_single_only, replay_multi

            check_single_only(surface=a.surface, save_surface=a.save_surface, filter=a.filter)
            multi = replay_multi(a.recording, a.calibration or [], config=cfg, events_path=a.events,
                                 tuio=a.tuio, uinput=a.uinput, surface_frames=a.surface_frames,
                                 realtime=1.0 if paced else None, fusion=_fusion(a))
            if not a.quiet:
                print(multi.describe())
            return 0
        summary = replay(
            a.recording[0],
            config=cfg,
            events_path=a.events,
            surface_path=a.surface,
            save_surface_path=a.save_surface,
            surface_frames=a.surface_frames,
            filter_name=a.filter,
            tuio=a.tuio,
            uinput=a.uinput,
            calibration_path=a.calibration[0] if a.calibration else None,
            progress=not a.quiet,
            realtime=1.0 if paced else None,
        )
        if not a.quiet:
            print(summary.describe())
        return 0

    p.set_defaults(func=run)


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


# --- serve --------------------------------------------------------------------------------------
def _add_serve(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "serve", help="web page: live height view, drawing pad, pinch zoom, calibration"
    )
    p.add_argument("--source", default="sim:drags",
                   help="FILE.npz, a PNG folder, FILE.bag, realsense or sim:SCENE "
                        "(default sim:drags)")
    p.add_argument("--host", default="127.0.0.1",
                   help="interface to bind (default 127.0.0.1; 0.0.0.0 exposes the page)")
    p.add_argument("--port", type=int, default=8765, help="TCP port (default 8765; 0 = any free)")
    p.add_argument("--config", help="TOML config file (see docs/config.md)")
    p.add_argument("--calibration", help="screen calibration file to start with (adds sx, sy)")
    p.add_argument("--calibration-out", default="calibration.json",
                   help="where the page's calibration flow saves (default calibration.json)")
    p.add_argument("--surface-frames", type=int, help="learn the surface from N frames")
    p.add_argument("--realtime", action=argparse.BooleanOptionalAction, default=True,
                   help="play recordings at their own pace (default) or as fast as possible")
    p.add_argument("--loop", action=argparse.BooleanOptionalAction, default=True,
                   help="start a finished recording again (default) or stop")

    def run(a: argparse.Namespace) -> int:
        try:
            from .web.serve import run_serve
        except ImportError as e:
            from .errors import OutputError

            raise OutputError(
                f"the web page needs aiohttp ({e}); pip install 'depthtouch[web]'"
            ) from e
        run_serve(
            a.source, host=a.host, port=a.port, config_path=a.config,
            calibration_path=a.calibration, calibration_out=a.calibration_out,
            realtime=a.realtime, loop=a.loop, surface_frames=a.surface_frames,
        )
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
    p.add_argument("--by", default="scene",
                   help="suite rows: scene, camera, group, label, distance_m, surface or all")
    p.add_argument("--config", help="TOML config file (see docs/config.md)")
    p.add_argument("--gate-mm", type=float, default=20.0, help="match gate in mm (default 20)")
    p.add_argument("--workers", type=int, help="processes for a suite (default: cores, <= 4)")
    p.add_argument("--cache", action="store_true",
                   help="keep the suite's recordings in .cache/depthtouch/suite (or "
                        "$DEPTHTOUCH_CACHE) and reuse them")
    p.add_argument("--half", choices=("tune", "held-out", "all"),
                   help="with --suite: the tune or held-out half (or all), both side by side")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON")
    p.add_argument("--space", choices=("depth", "screen"), default="depth",
                   help="score --events by x, y (depth) or sx, sy (screen: fused cameras of "
                        "sim --views)")

    def run(a: argparse.Namespace) -> int:
        import json

        from .errors import ConfigError
        from .evaluation.suite import cache_root, eval_recording_command, eval_suite_command

        cfg = _load_config(a.config)
        if a.half:
            from .evaluation.halves import print_halves

            if not a.suite:
                raise ConfigError("--half needs --suite NAME (e.g. --suite hard --half held-out)")
            return print_halves(a.suite, a.half, subset=a.subset, config=cfg,
                                workers=a.workers, cache=cache_root() if a.cache else None,
                                as_json=a.json, progress=None if a.json else _print_case)
        if a.suite:
            if a.recording or a.truth or a.events:
                raise ConfigError("give either --suite or a recording with --truth, not both")
            metrics = eval_suite_command(
                a.suite, subset=a.subset, by=a.by, config=cfg, workers=a.workers,
                cache=cache_root() if a.cache else None,
                progress=None if a.json else _print_case,
            )
        else:
            metrics = eval_recording_command(a.recording, a.truth, events_path=a.events,
                                             config=cfg, gate_mm=a.gate_mm, space=a.space)
        if a.json:
            print(json.dumps({k: m.to_dict() for k, m in metrics.items()}, indent=1))
        else:
            from rich.console import Console

            from .evaluation.report import metrics_table

            wide = None if sys.stdout.isatty() else 200  # no terminal: do not squeeze to 80
            Console(width=wide).print(
                metrics_table(metrics, title=f"accuracy ({a.suite or 'recording'})")
            )
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
    from .sim import CAMERAS, SCENES, SURFACES

    p = sub.add_parser("sim", help="render a simulated depth recording with ground truth")
    p.add_argument("scene", help=f"one of {', '.join(SCENES)}")
    p.add_argument("--out", required=True, help="FILE.npz or a new PNG folder")
    p.add_argument("--truth", required=True, help="ground-truth JSON (docs/simulator.md)")
    p.add_argument("--camera", default="realsense-d435", help=f"one of {', '.join(CAMERAS)}")
    p.add_argument("--distance", type=float, default=1.0, help="surface distance, m [0.5, 2.5]")
    p.add_argument("--tilt", type=float, default=0.0, help="surface tilt, deg [0, 40]")
    p.add_argument("--surface", default="plane", help=f"one of {', '.join(SURFACES)}")
    p.add_argument("--seed", type=int, default=0, help="random seed (>= 0)")
    p.add_argument("--fps", type=float, default=30.0, help="frame rate, Hz [1, 120]")
    p.add_argument("--no-noise", action="store_true", help="exact geometry, no sensor noise")
    p.add_argument("-q", "--quiet", action="store_true", help="print only errors")
    p.add_argument("--views", type=int, metavar="N",
                   help="N cameras (2-3) 0.8 m apart: --out is a folder of viewK.npz, "
                        "viewK.calibration.json and --truth on the shared screen "
                        "(docs/multicam.md)")

    def run(a: argparse.Namespace) -> int:
        if a.views is not None:
            from .sim.multiview import default_poses, render_views, write_views

            mv = render_views(a.scene, default_poses(a.views), camera=a.camera,
                              distance_m=a.distance, seed=a.seed, fps=a.fps,
                              noise=not a.no_noise)
            written = write_views(mv, a.out, truth_path=a.truth)
            if not a.quiet:
                print("\n".join(str(p) for p in written))
            return 0
        from .sim import render_scene, write_recording

        rec = render_scene(
            a.scene, camera=a.camera, distance_m=a.distance, tilt_deg=a.tilt,
            surface=a.surface, seed=a.seed, fps=a.fps, noise=not a.no_noise,
        )
        write_recording(rec, a.out, a.truth)
        if not a.quiet:
            n, h, w = rec.depth.shape
            contacts = {c["id"] for f in rec.truth["frames"] for c in f["contacts"]}
            print(f"{a.out}: {n} frames {w}x{h} at {rec.fps:g} fps, "
                  f"{rec.truth['empty_frames']} empty, {len(contacts)} contacts; truth {a.truth}")
        return 0

    p.set_defaults(func=run)


# --- run / record (live cameras) ------------------------------------------------------------------
def _add_camera_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--resolution", metavar="WxH",
                   help="camera depth resolution (default 848x480 where available)")
    p.add_argument("--fps", type=int,
                   help="camera frame rate (default 90 where available, else 30)")
    p.add_argument("--preset", help="RealSense visual preset (default high_accuracy)")
    p.add_argument("--post-processing", metavar="F1,F2",
                   help="RealSense host filters to apply: spatial, temporal, hole_filling "
                        "(default none)")


def _camera_options(a: argparse.Namespace, source: str) -> dict[str, object]:
    from .errors import ConfigError

    opts: dict[str, object] = {}
    if a.resolution:
        opts["resolution_wh"] = a.resolution
    if a.fps is not None:
        opts["fps"] = a.fps
    realsense = source == "realsense" or source.startswith("realsense:")
    if a.preset:
        opts["preset"] = a.preset
    if a.post_processing:
        opts["post_processing"] = [f for f in a.post_processing.split(",") if f.strip()]
    if not realsense and ("preset" in opts or "post_processing" in opts):
        raise ConfigError("--preset and --post-processing apply to --source realsense only")
    if opts and not (realsense or source == "openni" or source.startswith("openni:")):
        raise ConfigError(
            f"--resolution/--fps/--preset apply to cameras (realsense, openni), not {source}"
        )
    return opts


def _add_run(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="run the sensor live on a depth camera")
    p.add_argument("--source", action="append",
                   help="realsense[:SERIAL], openni[:URI], or a recording / sim:SCENE played "
                        "at its own pace (default realsense); repeat for several cameras, each "
                        "with its --calibration (docs/multicam.md)")
    _add_common_outputs(p)
    p.add_argument("--serve", metavar="HOST:PORT", nargs="?", const="127.0.0.1:8765",
                   help="also serve the web page (default 127.0.0.1:8765)")
    p.add_argument("--surface", help="load a saved surface model instead of learning one")
    p.add_argument("--save-surface", help="save the learned surface model to this file")
    p.add_argument("--countdown", type=float,
                   help="seconds the surface must stay clear before it is learned (default 3 "
                        "for cameras, 0 for recordings)")
    p.add_argument("--seconds", type=float, help="stop after this many seconds (default: Ctrl-C)")
    _add_camera_options(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no status line")

    def run(a: argparse.Namespace) -> int:
        from .live import LiveConfig, run_live
        from .sources import is_live_spec

        sources = a.source or ["realsense"]
        if len(sources) > 1 or len(a.calibration or []) > 1:
            from .multicam import check_single_only
            from .multilive import run_live_multi

            check_single_only(surface=a.surface, save_surface=a.save_surface, serve=a.serve)
            opts = {}
            for s in sources:
                opts = _camera_options(a, s)
            countdown = a.countdown if a.countdown is not None else (
                3.0 if any(is_live_spec(s) for s in sources) else 0.0)
            res = run_live_multi(sources, a.calibration or [], config=_load_config(a.config),
                                 events_path=a.events, tuio=a.tuio, uinput=a.uinput,
                                 source_options=opts, max_seconds=a.seconds,
                                 live_config=LiveConfig(countdown_s=countdown),
                                 show_status=not a.quiet, fusion=_fusion(a))
            if not a.quiet:
                print(res.describe())
            return 0
        a.source, a.calibration = sources[0], (a.calibration or [None])[0]
        opts = _camera_options(a, a.source)
        countdown = a.countdown if a.countdown is not None else (
            3.0 if is_live_spec(a.source) else 0.0)
        result = run_live(
            a.source, config=_load_config(a.config), events_path=a.events, tuio=a.tuio,
            uinput=a.uinput,
            serve=a.serve, calibration_path=a.calibration, surface_path=a.surface,
            save_surface_path=a.save_surface, source_options=opts,
            live_config=LiveConfig(countdown_s=countdown), max_seconds=a.seconds,
            show_status=not a.quiet,
        )
        if not a.quiet:
            print(result.describe())
        return 0

    p.set_defaults(func=run)


def _add_record(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("record", help="record a depth stream (camera or any source) to a file")
    p.add_argument("--source", default="realsense",
                   help="realsense[:SERIAL], openni[:URI], a recording or sim:SCENE "
                        "(default realsense)")
    p.add_argument("--out", required=True,
                   help="FILE.npz, FOLDER/ (16-bit PNGs) or FILE.db3 (RealSense recording)")
    p.add_argument("--seconds", type=float, help="length to record (default: until Ctrl-C)")
    p.add_argument("--frames", type=int, help="stop after this many frames")
    _add_camera_options(p)
    p.add_argument("-q", "--quiet", action="store_true", help="print only errors")

    def run(a: argparse.Namespace) -> int:
        from .sources import open_source
        from .sources.record import record

        source = open_source(a.source, **_camera_options(a, a.source))
        tty = sys.stderr.isatty() and not a.quiet
        last = [-1.0]

        def progress(n: int, t: float) -> None:
            if tty and t - last[0] >= 0.5:
                last[0] = t
                print(f"\rrecording: {n} frames, {t:.1f} s (Ctrl-C stops)", end="",
                      file=sys.stderr, flush=True)

        summary = record(source, a.out, seconds=a.seconds, max_frames=a.frames,
                         progress=progress)
        if tty:
            print(file=sys.stderr)
        if not a.quiet:
            print(summary.describe())
        return 0

    p.set_defaults(func=run)


# --- play ---------------------------------------------------------------------------------------
def _add_play(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("play", help="play a touch-events file into a virtual touchscreen or TUIO")
    p.add_argument("events", help="touch events JSON Lines file (from replay --events)")
    p.add_argument("--uinput", action="store_true",
                   help="touch the desktop through a virtual touchscreen (Linux, docs/uinput.md)")
    p.add_argument("--tuio", metavar="HOST:PORT", nargs="?", const="127.0.0.1:3333",
                   help="send TUIO 1.1 /tuio/2Dcur over UDP (default 127.0.0.1:3333)")
    p.add_argument("--calibration", help="the replay's calibration file (gives the screen size)")
    p.add_argument("--screen", metavar="WxH",
                   help="range of the positions instead of --calibration: the screen (events "
                        "with sx, sy) or the depth image")
    p.add_argument("--fast", action="store_true", help="do not wait between frames")
    p.add_argument("--uinput-settle", type=float, default=0.5, metavar="S",
                   help="seconds to wait for the desktop to open the new device (default 0.5)")
    p.add_argument("-q", "--quiet", action="store_true", help="print only errors")

    def run(a: argparse.Namespace) -> int:
        from .calibration import parse_screen_wh
        from .outputs.play import play

        summary = play(a.events, uinput=a.uinput, tuio=a.tuio, calibration_path=a.calibration,
                       screen_wh_px=parse_screen_wh(a.screen) if a.screen else None,
                       fast=a.fast, uinput_settle_s=a.uinput_settle)
        if not a.quiet:
            print(summary.describe(), flush=True)
        return 0

    p.set_defaults(func=run)


# --- merge --------------------------------------------------------------------------------------
def _add_merge(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("merge", help="fuse the TUIO streams of several sensors into one")
    p.add_argument("--listen", default="127.0.0.1:3333", metavar="HOST:PORT",
                   help="where the sensors send TUIO (default 127.0.0.1:3333; 0.0.0.0:3333 "
                        "hears other machines)")
    p.add_argument("--tuio", default="127.0.0.1:3334", metavar="HOST:PORT",
                   help="where the merged TUIO goes (default 127.0.0.1:3334)")
    _add_fusion_gate(p)

    def run(a: argparse.Namespace) -> int:
        from .outputs.merge import run_merge

        stats = run_merge(a.listen, a.tuio, fusion=_fusion(a))
        print(f"merged {stats.senders} senders: {stats.datagrams} datagrams, "
              f"{stats.malformed} malformed, {stats.late} late", file=sys.stderr)
        return 0

    p.set_defaults(func=run)


_COMMANDS: list[Callable[[argparse._SubParsersAction], None]] = [
    _add_replay,
    _add_play,
    _add_calibrate,
    _add_gestures,
    _add_eval,
    _add_demo,
    _add_serve,
    _add_bench_filters,
    _add_sim,
    _add_run,
    _add_record,
    _add_merge,
]


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="depthtouch",
        description="Turn any surface into a multi-touch screen with one depth camera.",
    )
    from . import __version__

    parser.add_argument("--version", action="version", version=f"depthtouch {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for add in _COMMANDS:
        add(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "func", None) is None:
        parser.print_help()
        return 2
    stopped: list[int] = []
    restore = _stop_on_signals(stopped)
    try:
        return int(args.func(args) or 0)
    except DepthTouchError as e:
        print(f"depthtouch: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        if stopped:  # a service manager's stop: the command's outputs were closed cleanly
            return 0
        print("depthtouch: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0
    finally:
        restore()


def _stop_on_signals(stopped: list[int]) -> Callable[[], None]:
    """SIGTERM and SIGHUP (systemd, docker stop, a closed terminal) end a command the way Ctrl-C
    does: the loop ends the touches still down, the events file is kept, TUIO sends its final
    empty ``alive``, sockets close. Returns a function that restores the previous handlers."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return lambda: None

    def stop(signum: int, frame: object) -> None:
        stopped.append(signum)
        raise KeyboardInterrupt

    sigs = [signal.SIGTERM] + ([signal.SIGHUP] if hasattr(signal, "SIGHUP") else [])
    old = {s: signal.signal(s, stop) for s in sigs}
    def restore() -> None:
        for s, h in old.items():
            signal.signal(s, h)

    return restore


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
