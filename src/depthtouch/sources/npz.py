"""`.npz` depth recordings (docs/formats.md, 1a): read and write."""

from __future__ import annotations

import mmap
import os
import threading
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.lib.npyio import NpzFile

from ..errors import DepthTouchError, SourceError
from ..files import atomic_path
from ..types import Frame
from .base import (
    SourceBase,
    short_repr,
    validate_depth_scale,
    validate_K,
    validate_timestamps,
)


class NpzSource(SourceBase):
    """Frames of an `.npz` recording, validated at open and read when they are needed.

    The small arrays (timestamps, depth scale, K) are read at open; the depth array is not:
    a stored (uncompressed) member is memory-mapped and each frame is a view of the file (or a
    copy when the member's data is not 2-byte aligned), the pages already played are released;
    a compressed member is decompressed frame by frame as the replay goes. Memory stays flat
    whatever the length of the recording. ``depthtouch record`` writes stored members, which
    replay fastest (no decompression, no checksum pass).
    """

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
                ts = _array(data, "timestamps", p) if "timestamps" in keys else None
                scale = _array(data, "depth_scale", p) if "depth_scale" in keys else None
                K = _array(data, "K", p) if "K" in keys else None
            self._member = _depth_member(p)
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
        m = self._member
        if m.dtype != np.uint16:
            raise SourceError(
                f"{p}: depth has dtype {m.dtype}, expected uint16; convert with "
                "depth.astype(np.uint16) in depth_scale units"
            )
        if len(m.shape) != 3:
            raise SourceError(
                f"{p}: depth has shape {m.shape}, expected (N, H, W); stack frames on axis 0"
            )
        if m.shape[0] == 0:
            raise SourceError(f"{p}: the recording has no frames; record again")
        if m.shape[1] < 8 or m.shape[2] < 8:
            raise SourceError(f"{p}: frames of {m.shape[1:]} are too small; expected H, W >= 8")
        if ts is None:
            raise SourceError(f"{p}: no 'timestamps' array; add float64 seconds, one per frame")
        if scale is None:
            raise SourceError(f"{p}: no 'depth_scale'; add metres per unit, e.g. 0.001")
        self.path = p
        self.n_frames = int(m.shape[0])
        self.timestamps = validate_timestamps(ts, self.n_frames, str(p))
        self.depth_scale_m = validate_depth_scale(scale, str(p))
        self.K = validate_K(K, str(p))
        self.resolution_wh = (int(m.shape[2]), int(m.shape[1]))
        dt = np.diff(self.timestamps)
        self.fps = float(1.0 / np.median(dt)) if dt.size else None

    def __len__(self) -> int:
        return self.n_frames

    @property
    def compressed(self) -> bool:
        return self._member.compressed

    def frames(self) -> Iterator[Frame]:
        ts, scale, K = self.timestamps, self.depth_scale_m, self.K
        try:
            for i, depth in enumerate(_read_frames(self.path, self._member)):
                yield Frame(depth, float(ts[i]), i, scale, K)
        except (OSError, ValueError, zipfile.BadZipFile, zlib.error, EOFError) as e:
            raise SourceError(
                f"{self.path}: the depth data is damaged ({_first_line(e)}); record again or "
                "replay the frames before it"
            ) from e

    def read_all(self) -> np.ndarray:
        """The whole depth array (N, H, W), in memory: for short recordings and tests."""
        return np.stack([f.depth for f in self.frames()])


@dataclass(frozen=True)
class _Member:
    """Where the depth array lies in the archive: its .npy header and raw data."""

    name: str
    shape: tuple[int, ...]
    dtype: np.dtype
    compressed: bool
    data_offset: int  # stored members: file offset of the first element; else header length


def _depth_member(p: Path) -> _Member:
    """Read the depth member's .npy header without reading its data."""
    with zipfile.ZipFile(p) as zf:
        name = "depth.npy" if "depth.npy" in zf.namelist() else "depth"
        info = zf.getinfo(name)
        with zf.open(info) as fh:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
            else:
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
            header_len = fh.tell()
    if fortran and len(shape) > 1:
        raise ValueError("depth is stored in Fortran order")
    if dtype.hasobject:
        raise ValueError("not an array archive")
    compressed = info.compress_type != zipfile.ZIP_STORED
    offset = header_len
    if not compressed:
        with p.open("rb") as fh:  # the local file header: 30 bytes, then name and extra
            fh.seek(info.header_offset)
            local = fh.read(30)
            if len(local) < 30 or local[:4] != b"PK\x03\x04":
                raise zipfile.BadZipFile("bad local file header")
            n_name = int.from_bytes(local[26:28], "little")
            n_extra = int.from_bytes(local[28:30], "little")
            offset = info.header_offset + 30 + n_name + n_extra + header_len
            need = offset + int(np.prod(shape)) * dtype.itemsize
            if fh.seek(0, os.SEEK_END) < need:
                raise EOFError("the depth data is truncated")
    return _Member(name, tuple(int(s) for s in shape), dtype, compressed, offset)


_RELEASE_EVERY = 64  # frames between releases of the mapped pages already played


def _read_frames(p: Path, m: _Member) -> Iterator[np.ndarray]:
    n, h, w = m.shape
    frame_bytes = h * w * m.dtype.itemsize
    if not m.compressed:
        with p.open("rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as mm:
            aligned = m.data_offset % m.dtype.itemsize == 0
            released = 0
            for i in range(n):
                start = m.data_offset + i * frame_bytes
                view = np.frombuffer(mm, m.dtype, h * w, start).reshape(h, w)
                # the view keeps the map open; an unaligned one is copied (compiled kernels
                # take aligned arrays)
                yield view if aligned else view.copy()
                if i - released >= _RELEASE_EVERY and hasattr(mm, "madvise"):
                    # played pages go back to the page cache: a mapped file would otherwise
                    # count whole in this process's memory (re-read from the file if needed)
                    lo = (m.data_offset + released * frame_bytes) // mmap.PAGESIZE * mmap.PAGESIZE
                    hi = start // mmap.PAGESIZE * mmap.PAGESIZE
                    if hi > lo:
                        mm.madvise(mmap.MADV_DONTNEED, lo, hi - lo)
                    released = i
            del view
        return
    with zipfile.ZipFile(p) as zf, zf.open(m.name) as member:
        member.read(m.data_offset)  # the .npy header
        for _ in range(n):
            buf = member.read(frame_bytes)
            if len(buf) != frame_bytes:
                raise EOFError("the depth data is truncated")
            yield np.frombuffer(bytearray(buf), m.dtype).reshape(h, w)


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


# np.load parses each member's header with ast.literal_eval, and CPython 3.11 before 3.11.8
# can fail building two ASTs at once in two threads ("SystemError: AST constructor recursion
# depth mismatch", python/cpython#106905): two sources opened together (multicam) read one at a
# time
_READ_LOCK = threading.Lock()


def _array(data: Any, key: str, p: Path) -> np.ndarray:
    with _READ_LOCK:
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
    *,
    compress: bool = True,
) -> Path:
    """Write a recording atomically (a temporary file renamed into place).

    depth: uint16 (N, H, W) with N >= 1; timestamps_s: (N,) strictly increasing seconds;
    depth_scale_m: metres per unit in [1e-6, 1]; K: (3, 3) or None. compress: deflate the
    members (smaller) or store them (replays fastest: memory-mapped, no decompression).
    Whatever is written here reads back through :class:`NpzSource`; invalid arguments raise
    SourceError before any file is created.
    """
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
    return save_npz_atomic(Path(path), arrays, SourceError, compress=compress,
                           what="the recording (.npz)")


def save_npz_atomic(path: Path, arrays: dict[str, np.ndarray], error: type[DepthTouchError],
                    *, compress: bool = True, what: str = "the output") -> Path:
    """Write an ``.npz`` all or nothing (see :func:`depthtouch.files.atomic_path`); a folder
    or a missing folder, and OS errors, become ``error``."""
    save = np.savez_compressed if compress else np.savez
    with atomic_path(path, what=what, error=error) as tmp, tmp.open("wb") as fh:
        save(fh, **arrays)  # type: ignore[arg-type]
    return path
