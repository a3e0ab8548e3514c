"""`.npz` depth recordings (docs/formats.md, 1a): read and write."""

from __future__ import annotations

import os
import tempfile
import zipfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..errors import SourceError
from ..types import Frame
from .base import SourceBase, validate_depth_scale, validate_K, validate_timestamps


class NpzSource(SourceBase):
    """Frames of an `.npz` recording, validated at open; the depth array is memory-loaded once."""

    def __init__(self, path: str | Path) -> None:
        p = Path(path)
        self.name = str(p)
        if not p.exists():
            raise SourceError(f"{p}: no such file; check the recording path")
        try:
            with np.load(p, allow_pickle=False) as data:
                keys = set(data.files)
                if "depth" not in keys:
                    raise SourceError(
                        f"{p}: not a depth recording (no 'depth' array; has {sorted(keys)}); "
                        "see docs/formats.md"
                    )
                depth = data["depth"]
                ts = data["timestamps"] if "timestamps" in keys else None
                scale = data["depth_scale"] if "depth_scale" in keys else None
                K = data["K"] if "K" in keys else None
        except SourceError:
            raise
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as e:
            raise SourceError(f"{p}: not a readable .npz file ({e}); give a depth recording") from e
        if depth.dtype != np.uint16:
            raise SourceError(
                f"{p}: depth has dtype {depth.dtype}, expected uint16; convert with "
                "depth.astype(np.uint16) in depth_scale units"
            )
        if depth.ndim != 3:
            raise SourceError(
                f"{p}: depth has shape {depth.shape}, expected (N, H, W); stack frames on axis 0"
            )
        if depth.shape[0] == 0:
            raise SourceError(f"{p}: the recording has no frames; record again")
        if depth.shape[1] < 8 or depth.shape[2] < 8:
            raise SourceError(f"{p}: frames of {depth.shape[1:]} are too small; expected H, W >= 8")
        if ts is None:
            raise SourceError(f"{p}: no 'timestamps' array; add float64 seconds, one per frame")
        if scale is None:
            raise SourceError(f"{p}: no 'depth_scale'; add metres per unit, e.g. 0.001")
        self.depth = depth
        self.timestamps = validate_timestamps(ts, depth.shape[0], str(p))
        self.depth_scale_m = validate_depth_scale(np.asarray(scale).reshape(-1)[0]
                                                  if np.asarray(scale).size == 1 else scale, str(p))
        self.K = validate_K(K, str(p))
        self.resolution_wh = (int(depth.shape[2]), int(depth.shape[1]))
        dt = np.diff(self.timestamps)
        self.fps = float(1.0 / np.median(dt)) if dt.size else None

    def __len__(self) -> int:
        return int(self.depth.shape[0])

    def frames(self) -> Iterator[Frame]:
        for i in range(self.depth.shape[0]):
            yield Frame(self.depth[i], float(self.timestamps[i]), i, self.depth_scale_m, self.K)


def write_npz(
    path: str | Path,
    depth: np.ndarray,
    timestamps_s: np.ndarray,
    depth_scale_m: float = 0.001,
    K: np.ndarray | None = None,
) -> Path:
    """Write a recording atomically (a temporary file renamed into place)."""
    p = Path(path)
    if depth.dtype != np.uint16 or depth.ndim != 3:
        raise SourceError(f"write_npz: depth must be uint16 (N, H, W), got {depth.dtype} {depth.shape}")
    arrays: dict[str, np.ndarray] = {
        "depth": depth,
        "timestamps": np.asarray(timestamps_s, dtype=np.float64),
        "depth_scale": np.asarray(depth_scale_m, dtype=np.float64),
    }
    if K is not None:
        arrays["K"] = np.asarray(K, dtype=np.float64)
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise SourceError(f"{p}: folder {parent} does not exist; create it first")
    fd, tmp = tempfile.mkstemp(suffix=".npz", dir=parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez_compressed(fh, **arrays)  # type: ignore[arg-type]
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p
