"""RealSense recordings written without a camera, through the SDK's own software device.

:class:`RealSenseRecordingWriter` / :func:`write_realsense_recording` write frames from any
source to a recording the SDK (and the RealSense Viewer) can play: a ``rs.software_device`` with
one Z16 stream (intrinsics and depth units set) and ``rs.recorder``. SDK 2.58+ writes ``.db3``
only; 2.57 writes ``.bag``. ``pyrealsense2`` is imported only when a writer is made.
"""

from __future__ import annotations

import contextlib
import gc
import os
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from ..errors import SourceError
from ..files import temp_beside
from .base import validate_depth_scale, validate_K
from .realsense import _first_line, import_pyrealsense2


class RealSenseRecordingWriter:
    """Write depth frames to a RealSense recording through the SDK's software device.

    path: target file; ``.db3`` for SDK 2.58+ (``.bag`` only with SDK versions that still write
    it). The file is written beside the target under a temporary name and moved into place by
    ``close(commit=True)``.
    resolution_wh, depth_scale_m (metres per unit), K ((3, 3) or None), fps (nominal, > 0).
    Timestamps are stored as given (milliseconds in the file); frame numbers count from 0.
    """

    def __init__(
        self,
        path: str | Path,
        resolution_wh: tuple[int, int],
        depth_scale_m: float = 0.001,
        K: np.ndarray | None = None,
        fps: float = 30.0,
    ) -> None:
        p = Path(path)
        suffix = p.suffix.lower()
        if suffix not in (".db3", ".bag"):
            raise SourceError(f"{p}: a RealSense recording must end in .db3 (or .bag)")
        parent = p.parent if str(p.parent) else Path(".")
        if not parent.is_dir():
            raise SourceError(f"{p}: folder {parent} does not exist; create it first")
        rs = import_pyrealsense2()
        self._rs = rs
        self.path = p
        w, h = int(resolution_wh[0]), int(resolution_wh[1])
        self.resolution_wh = (w, h)
        self.depth_scale_m = validate_depth_scale(depth_scale_m, str(p))
        Kv = validate_K(K, str(p))
        if not fps > 0:
            raise SourceError(f"{p}: fps {fps!r} must be > 0")
        tmp = temp_beside(p, suffix=suffix, error=SourceError)
        tmp.unlink()  # the recorder creates the file itself
        self._tmp = tmp
        intr = rs.intrinsics()
        intr.width, intr.height = w, h
        if Kv is not None:
            intr.fx, intr.fy = float(Kv[0, 0]), float(Kv[1, 1])
            intr.ppx, intr.ppy = float(Kv[0, 2]), float(Kv[1, 2])
        intr.model = rs.distortion.none
        intr.coeffs = [0.0] * 5
        self._has_K = Kv is not None
        self._dev = rs.software_device()
        self._sensor = self._dev.add_sensor("Stereo Module")
        self._sensor.add_read_only_option(rs.option.depth_units, self.depth_scale_m)
        vs = rs.video_stream()
        vs.type = rs.stream.depth
        vs.index, vs.uid = 0, 0
        vs.width, vs.height = w, h
        vs.fps = max(1, int(round(fps)))
        vs.bpp = 2
        vs.fmt = rs.format.z16
        vs.intrinsics = intr
        self._profile = rs.video_stream_profile(self._sensor.add_video_stream(vs))
        try:
            self._recorder: Any = rs.recorder(str(self._tmp), self._dev)
        except RuntimeError as e:
            version = getattr(rs, "__version__", "?")
            if ".db3" in str(e):
                raise SourceError(
                    f"{p}: pyrealsense2 {version} writes only .db3 recordings; use a .db3 name"
                ) from e
            raise SourceError(
                f"{p}: pyrealsense2 {version} cannot write a recording here ({_first_line(e)})"
            ) from e
        self._sensor.open(self._profile)
        self._sensor.start(lambda _frame: None)
        self.count = 0
        self._open = True

    def write(self, depth: np.ndarray, timestamp_s: float) -> None:
        """Append one uint16 (H, W) frame with its timestamp in seconds (strictly increasing)."""
        if not self._open:
            raise SourceError(f"{self.path}: recording already closed")
        w, h = self.resolution_wh
        if depth.dtype != np.uint16 or depth.shape != (h, w):
            raise SourceError(
                f"{self.path}: frame {depth.dtype} {depth.shape} does not match the recording's "
                f"uint16 ({h}, {w})"
            )
        rs = self._rs
        f = rs.software_video_frame()
        f.pixels = np.ascontiguousarray(depth)
        f.bpp = 2
        f.stride = w * 2
        f.timestamp = float(timestamp_s) * 1000.0
        f.domain = rs.timestamp_domain.hardware_clock
        f.frame_number = self.count
        f.profile = self._profile
        f.depth_units = self.depth_scale_m
        self._sensor.on_video_frame(f)
        self.count += 1

    def close(self, commit: bool = True) -> None:
        """Finish the file (the SDK writes it when the recorder is destroyed) and move it."""
        if not self._open:
            return
        self._open = False
        with contextlib.suppress(RuntimeError):
            self._sensor.stop()
        with contextlib.suppress(RuntimeError):
            self._sensor.close()
        del self._recorder, self._sensor, self._profile, self._dev
        gc.collect()
        if commit and self.count > 0:
            os.replace(self._tmp, self.path)
        else:
            self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> RealSenseRecordingWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close(commit=exc_type is None or exc_type is KeyboardInterrupt)


def write_realsense_recording(
    path: str | Path,
    depth: np.ndarray,
    timestamps_s: np.ndarray,
    depth_scale_m: float = 0.001,
    K: np.ndarray | None = None,
    fps: float | None = None,
) -> Path:
    """Write a whole (N, H, W) uint16 recording to ``path`` (``.db3``); returns the path."""
    if depth.dtype != np.uint16 or depth.ndim != 3 or depth.shape[0] == 0:
        raise SourceError(
            f"write_realsense_recording: depth must be uint16 (N, H, W) with N >= 1, got "
            f"{depth.dtype} {depth.shape}"
        )
    ts = np.asarray(timestamps_s, dtype=np.float64)
    if fps is None:
        fps = float(1.0 / np.median(np.diff(ts))) if ts.size > 1 else 30.0
    wh = (int(depth.shape[2]), int(depth.shape[1]))
    with RealSenseRecordingWriter(path, wh, depth_scale_m, K, fps) as writer:
        for i in range(depth.shape[0]):
            writer.write(depth[i], float(ts[i]))
    return Path(path)
