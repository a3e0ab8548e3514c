"""The depth-source protocol: anything that yields :class:`~depthtouch.types.Frame` in order.

A source knows its resolution, depth scale and (when available) intrinsics before the first
frame, and is a context manager so that files and devices are closed on every path.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from types import TracebackType
from typing import Protocol, runtime_checkable

import numpy as np

from ..errors import SourceError
from ..types import Closing, Frame


@runtime_checkable
class DepthSource(Protocol):
    """A stream of depth frames.

    Attributes: ``depth_scale_m`` (metres per unit), ``K`` ((3, 3) or None), ``fps`` (nominal
    frames per second, or None when unknown), ``resolution_wh``, ``name`` (for messages).
    """

    depth_scale_m: float
    K: np.ndarray | None
    fps: float | None
    resolution_wh: tuple[int, int]
    name: str

    def frames(self) -> Iterator[Frame]: ...

    def close(self) -> None: ...

    def __enter__(self) -> DepthSource: ...

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...


class SourceBase(Closing):
    """Shared plumbing: context management and a length when the source knows it."""

    depth_scale_m: float = 0.001
    K: np.ndarray | None = None
    fps: float | None = None
    resolution_wh: tuple[int, int] = (0, 0)
    name: str = "source"

    def frames(self) -> Iterator[Frame]:  # pragma: no cover - abstract
        raise NotImplementedError

    def close(self) -> None:
        """Release files or devices; safe to call twice."""

    def __iter__(self) -> Iterator[Frame]:
        return self.frames()


def short_repr(value: object, limit: int = 40) -> str:
    """A one-line repr of a user's value for an error message (numpy scalars as Python ones)."""
    if isinstance(value, np.generic):
        value = value.item()
    r = " ".join(repr(value).split())
    return r if len(r) <= limit else r[: limit - 3] + "..."


def _is_real(value: object) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_)
    )


def validate_depth_scale(value: object, where: str) -> float:
    """A positive, finite depth scale in metres per unit (a number or a 1-element array), or
    SourceError."""
    v = value
    if isinstance(v, np.ndarray):
        if v.size != 1:
            raise SourceError(
                f"{where}: depth_scale has shape {v.shape}; give one number in metres per unit, "
                "e.g. 0.001"
            )
        v = v.reshape(-1)[0]
    if not _is_real(v):
        raise SourceError(
            f"{where}: depth_scale {short_repr(v)} is not a number; give metres per unit, "
            "e.g. 0.001"
        )
    scale = float(v)  # type: ignore[arg-type]
    if not (np.isfinite(scale) and 1e-6 <= scale <= 1.0):
        raise SourceError(
            f"{where}: depth_scale {scale!r} is out of range; give metres per unit in "
            "[1e-6, 1] (0.001 for millimetres)"
        )
    return scale


def validate_K(value: object, where: str) -> np.ndarray | None:
    """Intrinsics as a float64 (3, 3) with positive focal lengths, None when absent."""
    if value is None:
        return None
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        raw = np.asarray(None)
    if raw.dtype.kind not in "iuf":
        raise SourceError(f"{where}: K is not numeric; give [[fx,0,cx],[0,fy,cy],[0,0,1]]")
    K = raw.astype(np.float64)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise SourceError(
            f"{where}: K must be a finite 3x3 matrix with positive fx, fy, got shape {K.shape}; "
            "give [[fx,0,cx],[0,fy,cy],[0,0,1]]"
        )
    return K


def assumed_K(resolution_wh: tuple[int, int], hfov_deg: float) -> np.ndarray:
    """Pinhole intrinsics for a camera whose own are unknown: square pixels, the principal
    point at the image centre, a horizontal field of view of ``hfov_deg`` degrees."""
    w, h = resolution_wh
    f = (w / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
    return np.array([[f, 0.0, (w - 1) / 2.0], [0.0, f, (h - 1) / 2.0], [0.0, 0.0, 1.0]])


def validate_timestamps(ts: object, n: int, where: str) -> np.ndarray:
    """float64 (n,), finite and strictly increasing, or SourceError.

    An array of another shape with exactly n elements (e.g. (n, 1)) is flattened.
    """
    try:
        raw = np.asarray(ts)
    except (TypeError, ValueError):
        raw = np.asarray(None)
    if raw.dtype.kind not in "iuf":
        raise SourceError(f"{where}: timestamps are not numbers; give seconds as floats")
    if raw.size != n:
        raise SourceError(
            f"{where}: {raw.size} timestamps (shape {raw.shape}) for {n} frames; give one "
            "timestamp per frame"
        )
    t = raw.astype(np.float64).reshape(-1)
    if not np.all(np.isfinite(t)):
        raise SourceError(f"{where}: timestamps contain NaN or inf; give finite seconds")
    if n > 1 and not np.all(np.diff(t) > 0):
        i = int(np.argmin(np.diff(t) > 0))
        raise SourceError(
            f"{where}: timestamps are not strictly increasing (frame {i + 1}: {t[i + 1]!r} after "
            f"{t[i]!r}); fix or drop the repeated frames"
        )
    return t


class ArraySource(SourceBase):
    """Frames held in memory: depth uint16 (N, H, W), timestamps_s (N,) seconds; for rendered
    simulator recordings and tests. The arrays are read, never copied or changed."""

    def __init__(self, depth: np.ndarray, timestamps_s: np.ndarray, depth_scale_m: float = 0.001,
                 K: np.ndarray | None = None, *, fps: float | None = None,
                 name: str = "arrays") -> None:
        if depth.ndim != 3:
            raise SourceError(f"{name}: depth has shape {depth.shape}; expected (N, H, W)")
        self.depth = depth
        self.timestamps_s = validate_timestamps(timestamps_s, depth.shape[0], name)
        self.depth_scale_m = validate_depth_scale(depth_scale_m, name)
        self.K = validate_K(K, name)
        self.fps, self.name = fps, name
        self.resolution_wh = (int(depth.shape[2]), int(depth.shape[1]))

    @classmethod
    def of_recording(cls, rec: object, name: str = "recording") -> ArraySource:
        """A source over a rendered recording (anything with depth, timestamps_s,
        depth_scale_m, K and fps, e.g. :class:`depthtouch.sim.SimRecording`)."""
        return cls(rec.depth, rec.timestamps_s, rec.depth_scale_m, rec.K,  # type: ignore[attr-defined]
                   fps=getattr(rec, "fps", None), name=name)

    def __len__(self) -> int:
        return int(self.depth.shape[0])

    def frames(self) -> Iterator[Frame]:
        depth, ts, scale, K = self.depth, self.timestamps_s, self.depth_scale_m, self.K
        for i in range(depth.shape[0]):
            yield Frame(depth[i], float(ts[i]), i, scale, K)
