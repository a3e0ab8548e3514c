"""``depthtouch record``: capture a depth stream to a recording, for replay, tuning and bug reports.

The target type follows the name: ``rec.npz`` (docs/formats.md 1a), ``rec_dir/`` (a folder of
16-bit PNGs, 1b) or ``rec.db3`` (a RealSense recording, readable by the SDK and the RealSense
Viewer; ``.bag`` with SDK versions that still write it). Frames are streamed to disk as they
arrive (memory stays flat for long sessions) under a temporary name and moved into place at the
end; Ctrl-C keeps what was recorded. Timestamps are re-based so the recording starts at 0 s.

Any source can be recorded, so this also converts: ``--source rec.npz --out rec.db3``.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Protocol

import cv2
import numpy as np

from ..errors import SourceError
from .base import DepthSource
from .npz import write_npz

OUTPUT_KINDS = "FILE.npz, FOLDER/ (PNG frames) or FILE.db3 (RealSense)"


class RecordingWriter(Protocol):
    count: int

    def write(self, depth: np.ndarray, timestamp_s: float) -> None: ...

    def close(self, commit: bool = True) -> None: ...


def _parent_dir(p: Path) -> Path:
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise SourceError(f"{p}: folder {parent} does not exist; create it first")
    return parent


class NpzRecordingWriter:
    """Streams frames to a raw temporary file; ``close()`` compresses them into ``path``."""

    def __init__(self, path: str | Path, resolution_wh: tuple[int, int], depth_scale_m: float,
                 K: np.ndarray | None) -> None:
        self.path = Path(path)
        parent = _parent_dir(self.path)
        self.resolution_wh, self.depth_scale_m, self.K = resolution_wh, depth_scale_m, K
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".raw", dir=parent)
        self._tmp = Path(tmp)
        self._fh: IO[bytes] | None = os.fdopen(fd, "wb")
        self._ts: list[float] = []
        self.count = 0

    def write(self, depth: np.ndarray, timestamp_s: float) -> None:
        if self._fh is None:
            raise SourceError(f"{self.path}: recording already closed")
        self._fh.write(np.ascontiguousarray(depth, dtype=np.uint16).tobytes())
        self._ts.append(float(timestamp_s))
        self.count += 1

    def close(self, commit: bool = True) -> None:
        fh, self._fh = self._fh, None
        if fh is None:
            return
        fh.close()
        try:
            if commit and self.count:
                w, h = self.resolution_wh
                raw = np.memmap(self._tmp, dtype=np.uint16, mode="r", shape=(self.count, h, w))
                write_npz(self.path, raw, np.asarray(self._ts), self.depth_scale_m, self.K,
                          compress=False)  # stored members replay fastest (memory-mapped)
                del raw
        finally:
            self._tmp.unlink(missing_ok=True)


class PngRecordingWriter:
    """Writes ``depth/NNNNNN.png`` into a temporary sibling folder, renamed on ``close()``."""

    def __init__(self, folder: str | Path, depth_scale_m: float, K: np.ndarray | None,
                 fps: float | None) -> None:
        self.path = Path(folder)
        if self.path.exists() and (not self.path.is_dir() or any(self.path.iterdir())):
            raise SourceError(f"{self.path}: exists and is not an empty folder; choose a new one")
        parent = _parent_dir(self.path)
        self.depth_scale_m, self.K, self.fps = depth_scale_m, K, fps
        self._tmp = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", dir=parent))
        (self._tmp / "depth").mkdir()
        self._ts: list[float] = []
        self.count = 0
        self._open = True

    def write(self, depth: np.ndarray, timestamp_s: float) -> None:
        if not self._open:
            raise SourceError(f"{self.path}: recording already closed")
        name = self._tmp / "depth" / f"{self.count:06d}.png"
        if not cv2.imwrite(str(name), np.ascontiguousarray(depth, dtype=np.uint16)):
            raise SourceError(f"{name}: cannot write the PNG (disk full?); free space and retry")
        self._ts.append(float(timestamp_s))
        self.count += 1

    def close(self, commit: bool = True) -> None:
        if not self._open:
            return
        self._open = False
        if not (commit and self.count):
            shutil.rmtree(self._tmp, ignore_errors=True)
            return
        try:
            ts = np.asarray(self._ts)
            fps = self.fps or (float(1.0 / np.median(np.diff(ts))) if ts.size > 1 else 30.0)
            meta: dict[str, object] = {"depth_scale": self.depth_scale_m, "fps": fps}
            if self.K is not None:
                meta["K"] = np.asarray(self.K, dtype=float).tolist()
            (self._tmp / "meta.json").write_text(json.dumps(meta), encoding="utf-8")
            np.savetxt(self._tmp / "timestamps.txt", ts, fmt="%.6f")
            if self.path.exists():
                self.path.rmdir()
            self._tmp.rename(self.path)
        except BaseException:
            shutil.rmtree(self._tmp, ignore_errors=True)
            raise


def open_writer(out: str | Path, source: DepthSource) -> RecordingWriter:
    """A writer for ``out`` matching the source's resolution, depth scale and intrinsics."""
    text = str(out)
    p = Path(text)
    suffix = p.suffix.lower()
    if suffix == ".npz":
        return NpzRecordingWriter(p, source.resolution_wh, source.depth_scale_m, source.K)
    if suffix in (".db3", ".bag"):
        from .realsense_record import RealSenseRecordingWriter

        return RealSenseRecordingWriter(p, source.resolution_wh, source.depth_scale_m, source.K,
                                        source.fps or 30.0)
    if text.endswith(("/", os.sep)) or p.is_dir() or not suffix:
        return PngRecordingWriter(p, source.depth_scale_m, source.K, source.fps)
    raise SourceError(f"{text}: unknown recording type {suffix!r}; give {OUTPUT_KINDS}")


@dataclass
class RecordSummary:
    """What was recorded: frames, duration (s, frame time), mean fps, frames the timestamps say
    were lost on the way (gaps longer than 1.5 frame intervals), and whether Ctrl-C ended it."""

    path: Path
    frames: int
    duration_s: float
    fps: float
    missing_frames: int
    interrupted: bool = False

    def describe(self) -> str:
        end = " (stopped with Ctrl-C)" if self.interrupted else ""
        return (f"recorded {self.frames} frames, {self.duration_s:.2f} s at {self.fps:.1f} fps "
                f"to {self.path}; {self.missing_frames} frames missing{end}")


def missing_frames(timestamps_s: np.ndarray) -> int:
    """Frames lost between timestamps: sum over gaps of round(gap / median interval) - 1."""
    dt = np.diff(np.asarray(timestamps_s, dtype=np.float64))
    if dt.size == 0:
        return 0
    med = float(np.median(dt))
    if med <= 0:
        return 0
    return int(np.sum(np.maximum(np.rint(dt / med) - 1, 0)))


def record(
    source: DepthSource | str,
    out: str | Path,
    *,
    seconds: float | None = None,
    max_frames: int | None = None,
    stop_event: threading.Event | None = None,
    progress: Callable[[int, float], None] | None = None,
) -> RecordSummary:
    """Record ``source`` (a source or a spec for open_source) to ``out`` until ``seconds`` of
    frame time, ``max_frames``, the end of the source, ``stop_event`` or Ctrl-C.

    progress: called with (frames, seconds recorded) after every frame.
    A source error mid-way keeps the frames so far and raises SourceError saying so.
    """
    if seconds is not None and not seconds > 0:
        raise SourceError(f"--seconds {seconds!r} must be > 0")
    if max_frames is not None and max_frames < 1:
        raise SourceError(f"max_frames {max_frames!r} must be at least 1")
    if isinstance(source, str):
        from . import open_source

        source = open_source(source)
    interrupted = False
    ts: list[float] = []
    with source:
        writer = open_writer(out, source)
        try:
            w, h = source.resolution_wh
            t0: float | None = None
            for frame in source.frames():
                if frame.depth.shape != (h, w) or frame.depth.dtype != np.uint16:
                    raise SourceError(
                        f"{source.name}: frame {frame.index} is {frame.depth.dtype} "
                        f"{frame.depth.shape}, expected uint16 ({h}, {w}); record one size"
                    )
                if t0 is None:
                    t0 = frame.timestamp_s
                t = frame.timestamp_s - t0
                if seconds is not None and t >= seconds:
                    break
                writer.write(frame.depth, t)
                ts.append(t)
                if progress is not None:
                    progress(writer.count, t)
                if (max_frames is not None and writer.count >= max_frames) or (
                        stop_event is not None and stop_event.is_set()):
                    break
        except KeyboardInterrupt:
            interrupted = True
        except SourceError as e:
            writer.close(commit=True)
            kept = f"; the {writer.count} frames before it are in {out}" if writer.count else ""
            raise SourceError(f"{e}{kept}") from e
        except BaseException:
            writer.close(commit=False)
            raise
        writer.close(commit=True)
    if not ts:
        raise SourceError(f"{source.name}: no frames arrived; nothing was recorded")
    arr = np.asarray(ts)
    duration = float(arr[-1]) if arr.size > 1 else 0.0
    fps = (arr.size - 1) / duration if duration > 0 else 0.0
    return RecordSummary(Path(out), len(ts), duration, fps, missing_frames(arr), interrupted)
