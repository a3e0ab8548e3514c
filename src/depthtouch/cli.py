"""Command line: parses arguments and calls one typed function per command.

Each command has its own ``_add_<name>`` function that declares its arguments and sets
``func``; :data:`_COMMANDS` lists them. A :class:`DepthTouchError` (a user's mistake) becomes one
line on stderr and exit code 2; Ctrl-C exits 130 after the command's own cleanup. The streaming
commands (``replay``, ``run``, ``serve``) take SIGTERM and SIGHUP (a service manager, a closed
terminal) as Ctrl-C, and a stop by any of the three is their normal end: the events file is kept,
the last empty TUIO ``alive`` sent, sockets closed, exit 0.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from .cli_tools import (
    _add_bench_filters,
    _add_calibrate,
    _add_demo,
    _add_eval,
    _add_gestures,
    _add_sim,
)
from .cli_tools import load_config_arg as _load_config
from .errors import DepthTouchError

if TYPE_CHECKING:
    from .fusion import FusionConfig


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        # argparse's own usage errors follow the one-line rule too
        self.exit(2, f"depthtouch: error: {message} (see {self.prog} -h)\n")

    def parse_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> argparse.Namespace:
        # arguments a command does not know are that command's error (argparse reports them
        # from the top parser: "see depthtouch -h" would not name the command)
        ns, extra = self.parse_known_args(args, namespace)
        if extra:
            command = getattr(ns, "command", None)
            sub = self._subparsers_by_name().get(command) if command else None
            (sub or self).error(f"unrecognized arguments: {' '.join(extra)}")
        return ns

    def _subparsers_by_name(self) -> dict[str, argparse.ArgumentParser]:
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                return dict(action.choices)
        return {}


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

    p.set_defaults(func=run, stops_cleanly=True)


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
    p.add_argument("--allow-origin", action="append", default=[], metavar="ORIGIN",
                   help="also accept WebSocket clients from this browser origin, e.g. "
                        "http://localhost:5173 (repeatable; see docs/websocket.md)")

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
            allowed_origins=a.allow_origin,
        )
        return 0

    p.set_defaults(func=run, stops_cleanly=True)


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

            check_single_only(surface=a.surface, save_surface=a.save_surface)
            opts = {}
            for s in sources:
                opts = _camera_options(a, s)
            countdown = a.countdown if a.countdown is not None else (
                3.0 if any(is_live_spec(s) for s in sources) else 0.0)
            res = run_live_multi(sources, a.calibration or [], config=_load_config(a.config),
                                 events_path=a.events, tuio=a.tuio, uinput=a.uinput,
                                 source_options=opts, max_seconds=a.seconds,
                                 live_config=LiveConfig(countdown_s=countdown),
                                 show_status=not a.quiet, fusion=_fusion(a), serve=a.serve)
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

    p.set_defaults(func=run, stops_cleanly=True)


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

    p.set_defaults(func=run, stops_cleanly=True)


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
    from . import stopping

    clean_stop = bool(getattr(args, "stops_cleanly", False))
    stopping.reset()
    old = stopping.stop_on_signals() if clean_stop else {}
    try:
        rc = int(args.func(args) or 0)
        if clean_stop and stopping.requested():
            print("depthtouch: stopped", file=sys.stderr)
        return rc
    except DepthTouchError as e:
        print(f"depthtouch: error: {e}", file=sys.stderr)
        return 2
    except (KeyboardInterrupt, SystemError) as e:
        if not stopping.interrupted(e):
            raise
        if clean_stop:
            print("depthtouch: stopped", file=sys.stderr)
            return 0
        print("depthtouch: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0
    finally:
        stopping.restore(old)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
