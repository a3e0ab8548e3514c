"""`.npz` depth recordings (docs/formats.md, 1a): read and write."""

from __future__ import annotations

import os
import tempfile
import zipfile
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.lib.npyio import NpzFile

from ..errors import DepthTouchError, SourceError
from ..types import Frame
from .base import (
    SourceBase,
    short_repr,
    validate_depth_scale,
    validate_K,
    validate_timestamps,
)


class NpzSource(SourceBase):
    """Frames of an `.npz` recording, validated at open; the depth array is memory-loaded once."""

    def __init__(self, path: str | Path) -> None:
        p = Path(path)
        self.name = str(p)
        if not p.exists():
            raise SourceError(f"{p}: no such file; check the recording path")
        try:
            with p.open("rb") as fh, _open_npz(fh, p) as data:
                keys = set(data.files)
                if "depth" not in keys:
                    raise SourceError(
                        f"{p}: not a depth recording (no 'depth' array; has "
                        f"{short_repr(sorted(keys), 60)}); see docs/formats.md"
                    )
                depth = _array(data, "depth", p)
                ts = _array(data, "timestamps", p) if "timestamps" in keys else None
                scale = _array(data, "depth_scale", p) if "depth_scale" in keys else None
                K = _array(data, "K", p) if "K" in keys else None
        except SourceError:
            raise
        except (OSError, ValueError, zipfile.BadZipFile, zlib.error, EOFError,
                RuntimeError) as e:
            # a damaged member (bad CRC, bad deflate stream, truncated array), not a zip at all,
            # or a zip numpy cannot read (RuntimeError: encrypted; NotImplementedError, its
            # subclass: another compression method or zip version)
            raise SourceError(
                f"{p}: not a readable .npz recording ({_first_line(e)}); give a depth recording "
                "(docs/formats.md)"
            ) from e
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
        self.depth_scale_m = validate_depth_scale(scale, str(p))
        self.K = validate_K(K, str(p))
        self.resolution_wh = (int(depth.shape[2]), int(depth.shape[1]))
        dt = np.diff(self.timestamps)
        self.fps = float(1.0 / np.median(dt)) if dt.size else None

    def __len__(self) -> int:
        return int(self.depth.shape[0])

    def frames(self) -> Iterator[Frame]:
        for i in range(self.depth.shape[0]):
            yield Frame(self.depth[i], float(self.timestamps[i]), i, self.depth_scale_m, self.K)


def _first_line(e: BaseException, limit: int = 80) -> str:
    text = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
    if "pickled" in text or "allow_pickle" in text:
        text = "not an array archive"  # numpy's advice to load pickles is wrong for a user here
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _open_npz(fh: IO[bytes], p: Path) -> Any:
    """np.load on an open file; SourceError when it is a bare .npy array, not an archive."""
    data = np.load(fh, allow_pickle=False)
    if not isinstance(data, NpzFile):
        raise SourceError(
            f"{p}: a single .npy array, not an .npz archive; save with np.savez(depth=..., "
            "timestamps=..., depth_scale=...)"
        )
    return data


def _array(data: Any, key: str, p: Path) -> np.ndarray:
    value = data[key]
    if not isinstance(value, np.ndarray):  # a zip member without the .npy format
        raise SourceError(f"{p}: member {key!r} is not a numpy array; see docs/formats.md")
    return value


def write_npz(
    path: str | Path,
    depth: np.ndarray,
    timestamps_s: np.ndarray,
    depth_scale_m: float = 0.001,
    K: np.ndarray | None = None,
) -> Path:
    """Write a recording atomically (a temporary file renamed into place).

    depth: uint16 (N, H, W) with N >= 1; timestamps_s: (N,) strictly increasing seconds;
    depth_scale_m: metres per unit in [1e-6, 1]; K: (3, 3) or None. Whatever is written here
    reads back through :class:`NpzSource`; invalid arguments raise SourceError before any file
    is created.
    """
    p = Path(path)
    if depth.dtype != np.uint16 or depth.ndim != 3 or depth.shape[0] == 0:
        raise SourceError(
            f"write_npz: depth must be uint16 (N, H, W) with N >= 1, got {depth.dtype} "
            f"{depth.shape}"
        )
    arrays: dict[str, np.ndarray] = {
        "depth": depth,
        "timestamps": validate_timestamps(timestamps_s, depth.shape[0], "write_npz"),
        "depth_scale": np.asarray(validate_depth_scale(depth_scale_m, "write_npz")),
    }
    Kv = validate_K(K, "write_npz")
    if Kv is not None:
        arrays["K"] = Kv
    parent = p.parent if str(p.parent) else Path(".")
    if p.is_dir():
        raise SourceError(f"{p}: is a folder; give a file name ending in .npz")
    if not parent.is_dir():
        raise SourceError(f"{p}: folder {parent} does not exist; create it first")
    return save_npz_atomic(p, arrays, SourceError)


def save_npz_atomic(
    path: Path, arrays: dict[str, np.ndarray], error: type[DepthTouchError]
) -> Path:
    """Write a compressed ``.npz`` to a temporary file beside ``path`` and rename it into place,
    so that a failed write never leaves a half-written file; OS errors become ``error``."""
    parent = path.parent if str(path.parent) else Path(".")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=parent)
    except OSError as e:
        raise error(f"{path}: cannot write here ({e.strerror}); choose another path") from e
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez_compressed(fh, **arrays)  # type: ignore[arg-type]
        os.replace(tmp, path)
    except OSError as e:
        Path(tmp).unlink(missing_ok=True)
        raise error(f"{path}: cannot write ({e.strerror}); choose another path") from e
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
