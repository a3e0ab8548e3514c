"""Command line: parses arguments and calls one typed function per command.

Each command has its own ``_add_<name>`` function that declares its arguments and sets
``func``; :data:`_COMMANDS` lists them. A :class:`DepthTouchError` (a user's mistake) becomes one
line on stderr and exit code 2; Ctrl-C exits 130 after the command's own cleanup.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from .errors import DepthTouchError


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        # argparse's own usage errors follow the one-line rule too
        self.exit(2, f"depthtouch: error: {message} (see depthtouch {self.prog.split()[-1]} -h)\n")


def _load_config(path: str | None):  # type: ignore[no-untyped-def]
    from .config import PipelineConfig, load_config

    return load_config(path) if path else PipelineConfig()


def _add_common_outputs(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", help="TOML config file (see docs/config.md)")
    p.add_argument("--events", help="write touch events to this JSON Lines file")
    p.add_argument(
        "--tuio", metavar="HOST:PORT", nargs="?", const="127.0.0.1:3333",
        help="send TUIO 1.1 /tuio/2Dcur over UDP (default 127.0.0.1:3333)",
    )
    p.add_argument("--calibration", help="screen calibration file (adds sx, sy to events)")


# --- replay -------------------------------------------------------------------------------------
def _add_replay(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="run the sensor on a depth recording")
    p.add_argument("recording", help="FILE.npz, a PNG folder, FILE.bag or FILE.db3")
    _add_common_outputs(p)
    p.add_argument("--surface", help="load a saved surface model instead of learning one")
    p.add_argument("--save-surface", help="save the learned surface model to this file")
    p.add_argument("--surface-frames", type=int, help="learn the surface from N frames")
    p.add_argument("--filter", help="path filter name (overrides the config)")
    p.add_argument("-q", "--quiet", action="store_true", help="print only errors")

    def run(a: argparse.Namespace) -> int:
        from .runner import replay

        cfg = _load_config(a.config)
        summary = replay(
            a.recording,
            config=cfg,
            events_path=a.events,
            surface_path=a.surface,
            save_surface_path=a.save_surface,
            surface_frames=a.surface_frames,
            filter_name=a.filter,
            tuio=a.tuio,
            calibration_path=a.calibration,
            progress=not a.quiet,
        )
        if not a.quiet:
            print(summary.describe())
        return 0

    p.set_defaults(func=run)


_COMMANDS: list[Callable[[argparse._SubParsersAction], None]] = [
    _add_replay,
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
    try:
        return int(args.func(args) or 0)
    except DepthTouchError as e:
        print(f"depthtouch: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("depthtouch: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


def _path_or_none(value: str | None) -> Path | None:
    return Path(value) if value else None


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
