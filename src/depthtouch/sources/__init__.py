"""Depth sources: recordings (npz, PNG folder, RealSense .bag/.db3), live cameras, simulator.

:func:`open_source` turns what a user types into a source:

- ``rec.npz`` -> :class:`NpzSource`; ``rec_dir/`` -> :class:`PngFolderSource`
- ``session.bag`` / ``session.db3`` -> RealSense playback (needs the ``realsense`` extra)
- ``realsense`` / ``realsense:SERIAL`` -> a live RealSense camera; ``openni`` -> an OpenNI 2 device
- ``sim:SCENE`` -> the built-in simulator rendering scene SCENE (e.g. ``sim:drags``)

Camera and simulator modules are imported only when asked for.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..errors import SourceError
from .base import ArraySource, DepthSource, SourceBase
from .npz import NpzSource, write_npz
from .png import PngFolderSource, write_png_folder

__all__ = [
    "ArraySource",
    "DepthSource",
    "NpzSource",
    "PngFolderSource",
    "SourceBase",
    "is_live_spec",
    "open_source",
    "write_npz",
    "write_png_folder",
]

#: Every kind of source a user can name, in one place.
SOURCE_KINDS = ("FILE.npz", "FOLDER/", "FILE.bag", "FILE.db3", "realsense", "openni", "sim:SCENE")
#: Source specs that are cameras: frames arrive at the device's pace. Anything else is a
#: recording or the simulator, which a live run plays at its recorded pace, like a camera.
CAMERA_KINDS = ("realsense", "openni")


def is_live_spec(spec: str | Path) -> bool:
    """True for camera specs (``realsense[:SERIAL]``, ``openni[:URI]``)."""
    text = str(spec)
    return any(text == p or text.startswith(p + ":") for p in CAMERA_KINDS)


def open_source(spec: str | Path, **options: Any) -> DepthSource:
    """Open a depth source from a path or a name (see the module doc); SourceError if unknown."""
    text = str(spec)
    if text.startswith("sim:") or text == "sim":
        from .simulated import open_sim_source

        return open_sim_source(text.partition(":")[2] or "taps", **options)
    if text == "realsense" or text.startswith("realsense:"):
        from .realsense import RealSenseSource

        return RealSenseSource(serial=text.partition(":")[2] or None, **options)
    if text == "openni" or text.startswith("openni:"):
        from .openni import OpenNISource

        return OpenNISource(uri=text.partition(":")[2] or None, **options)
    p = Path(text)
    suffix = p.suffix.lower()
    if suffix in (".bag", ".db3"):
        from .realsense import RealSensePlaybackSource

        return RealSensePlaybackSource(p, **options)
    if p.is_dir():
        return PngFolderSource(p)
    if suffix == ".npz":
        return NpzSource(p)
    if not p.exists():
        raise SourceError(
            f"{text}: no such file or folder; give one of {', '.join(SOURCE_KINDS)}"
        )
    raise SourceError(
        f"{text}: unknown recording type {suffix or '(no extension)'!r}; give one of "
        f"{', '.join(SOURCE_KINDS)}"
    )
