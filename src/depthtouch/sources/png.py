"""Folders of 16-bit PNG frames (docs/formats.md, 1b): read and write."""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from ..errors import SourceError
from ..types import Frame
from .base import (
    SourceBase,
    short_repr,
    validate_depth_scale,
    validate_K,
    validate_timestamps,
)


class PngFolderSource(SourceBase):
    """Frames from ``folder/depth/*.png`` with ``meta.json`` and optional ``timestamps.txt``."""

    def __init__(self, folder: str | Path) -> None:
        root = Path(folder)
        self.name = str(root)
        if not root.is_dir():
            raise SourceError(
                f"{root}: not a folder; give a PNG recording folder (docs/formats.md)"
            )
        meta_path = root / "meta.json"
        if not meta_path.is_file():
            raise SourceError(f"{root}: no meta.json; add {{\"depth_scale\": 0.001, \"fps\": 30}}")
        try:
            meta = json.loads(meta_path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as e:
            raise SourceError(
                f"{meta_path}: not valid JSON ({_first_line(e)}); fix the file"
            ) from e
        if not isinstance(meta, dict):
            raise SourceError(f"{meta_path}: must be a JSON object with depth_scale and fps")
        if "depth_scale" not in meta:
            raise SourceError(f"{meta_path}: no depth_scale; add metres per unit, e.g. 0.001")
        self.depth_scale_m = validate_depth_scale(meta["depth_scale"], str(meta_path))
        self.K = validate_K(meta.get("K"), str(meta_path))
        self.paths = sorted((root / "depth").glob("*.png"))
        if not self.paths:
            raise SourceError(f"{root}: no frames in depth/*.png; the recording is empty")
        n = len(self.paths)
        ts_path = root / "timestamps.txt"
        if ts_path.is_file():
            ts = read_timestamps_txt(ts_path)
        else:
            fps = meta.get("fps")
            if not isinstance(fps, (int, float)) or isinstance(fps, bool) or not fps > 0:
                raise SourceError(
                    f"{meta_path}: fps {short_repr(fps)} must be a positive number when there "
                    "is no timestamps.txt"
                )
            ts = np.arange(n, dtype=np.float64) / float(fps)
        self.timestamps = validate_timestamps(ts, n, str(root))
        first = self._read(0)
        if first.shape[0] < 8 or first.shape[1] < 8:
            raise SourceError(
                f"{self.paths[0]}: frames of {first.shape} are too small; expected H, W >= 8"
            )
        self.resolution_wh = (int(first.shape[1]), int(first.shape[0]))
        dt = np.diff(self.timestamps)
        self.fps = float(1.0 / np.median(dt)) if dt.size else None

    def __len__(self) -> int:
        return len(self.paths)

    def _read(self, i: int) -> np.ndarray:
        p = self.paths[i]
        img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise SourceError(f"{p}: not a readable PNG; re-export the frame")
        if img.dtype != np.uint16 or img.ndim != 2:
            raise SourceError(
                f"{p}: {img.dtype} with shape {img.shape}, expected a 16-bit single-channel PNG"
            )
        return img

    def frames(self) -> Iterator[Frame]:
        w, h = self.resolution_wh
        for i in range(len(self.paths)):
            img = self._read(i)
            if img.shape != (h, w):
                raise SourceError(
                    f"{self.paths[i]}: size {img.shape[1]}x{img.shape[0]} differs from the first "
                    f"frame's {w}x{h}; all frames must have one size"
                )
            yield Frame(img, float(self.timestamps[i]), i, self.depth_scale_m, self.K)


def _first_line(e: BaseException, limit: int = 80) -> str:
    text = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def read_timestamps_txt(path: Path) -> np.ndarray:
    """One float (seconds) per non-empty line, float64 (N,); SourceError naming the bad line."""
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise SourceError(f"{path}: cannot read ({_first_line(e)}); give a UTF-8 text file") from e
    values: list[float] = []
    for n, line in enumerate(lines, 1):
        text = line.strip()
        if not text:
            continue
        try:
            values.append(float(text))
        except ValueError:
            raise SourceError(
                f"{path}:{n}: {short_repr(text)} is not a number; give one float (seconds) per line"
            ) from None
    return np.asarray(values, dtype=np.float64)


def write_png_folder(
    folder: str | Path,
    depth: np.ndarray,
    timestamps_s: np.ndarray,
    depth_scale_m: float = 0.001,
    K: np.ndarray | None = None,
    fps: float | None = None,
) -> Path:
    """Write a recording folder; written to a temporary sibling and renamed, never half-done.

    Arguments as for :func:`~depthtouch.sources.npz.write_npz`; fps (> 0) goes to meta.json
    (default: from the timestamps). The folder must not exist or be empty.
    """
    root = Path(folder)
    if depth.dtype != np.uint16 or depth.ndim != 3 or depth.shape[0] == 0:
        raise SourceError(
            f"write_png_folder: depth must be uint16 (N, H, W) with N >= 1, got {depth.dtype} "
            f"{depth.shape}"
        )
    ts = validate_timestamps(timestamps_s, depth.shape[0], "write_png_folder")
    scale = validate_depth_scale(depth_scale_m, "write_png_folder")
    Kv = validate_K(K, "write_png_folder")
    if fps is None:
        fps = float(1.0 / np.median(np.diff(ts))) if ts.size > 1 else 30.0
    if not (isinstance(fps, (int, float)) and np.isfinite(fps) and fps > 0):
        raise SourceError(f"write_png_folder: fps {fps!r} must be a positive number")
    if root.exists() and (not root.is_dir() or any(root.iterdir())):
        raise SourceError(f"{root}: exists and is not an empty folder; choose a new folder")
    parent = root.parent if str(root.parent) else Path(".")
    if not parent.is_dir():
        raise SourceError(f"{root}: parent folder {parent} does not exist; create it first")
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{root.name}.", suffix=".part", dir=parent))
    except OSError as e:
        raise SourceError(f"{root}: cannot write here ({e.strerror}); choose another path") from e
    try:
        (tmp / "depth").mkdir()
        for i in range(depth.shape[0]):
            target = tmp / "depth" / f"{i:06d}.png"
            if not cv2.imwrite(str(target), depth[i]):
                raise SourceError(f"{target}: OpenCV could not write the frame; check the disk")
        meta: dict[str, object] = {"depth_scale": scale, "fps": float(fps)}
        if Kv is not None:
            meta["K"] = Kv.tolist()
        (tmp / "meta.json").write_text(json.dumps(meta), encoding="utf-8")
        # repr-exact seconds: the folder reads back the timestamps it was given
        (tmp / "timestamps.txt").write_text("".join(f"{t!r}\n" for t in ts.tolist()),
                                            encoding="utf-8")
        if root.exists():
            root.rmdir()
        tmp.rename(root)
    except OSError as e:
        shutil.rmtree(tmp, ignore_errors=True)
        raise SourceError(f"{root}: cannot write ({e.strerror}); choose another path") from e
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return root
