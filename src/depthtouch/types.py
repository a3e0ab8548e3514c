"""Shared value types that cross stage boundaries.

Arrays are numpy; every container of per-item arrays is parallel (same first dimension) and has
an ``empty()`` constructor. Nothing here mutates its inputs.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field, fields
from types import TracebackType
from typing import Any, Literal, Protocol, TypeVar

import numpy as np

TouchState = Literal["down", "move", "up"]
#: What the pipeline made of a frame: ``learning`` the surface (no touches yet), ``ok``,
#: ``disturbed`` (most of the surface changed at once: touches off until it settles),
#: ``relearned`` (the camera moved: touches ended, the surface is learned again), ``skipped``
#: (an unusable frame, counted), ``ended`` (the touches still down were ended at a stream's end).
FrameStatus = Literal["learning", "ok", "disturbed", "relearned", "skipped", "ended"]


_C = TypeVar("_C", bound="Closing")


def close_quietly(obj: object) -> None:
    """Close ``obj`` if it has ``close()`` (a frame generator, a source), ignoring what that
    raises: for ``finally`` blocks that must not hide the error that got them there."""
    close = getattr(obj, "close", None)
    if close is not None:
        with contextlib.suppress(Exception):
            close()


class Closing:
    """Context-manager plumbing for anything with ``close()``: ``with x:`` closes x at the end,
    on every path (sources, sinks)."""

    def close(self) -> None:
        """Release what is held; safe to call twice."""

    def __enter__(self: _C) -> _C:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def _check_shape(name: str, arr: np.ndarray, shape: tuple[int | None, ...]) -> None:
    # (a plain loop: called some 14 times per frame, a generator in all() costs twice as much)
    got = arr.shape
    if len(got) == len(shape):
        for s, d in zip(shape, got):
            if s is not None and s != d:
                break
        else:
            return
    want = "(" + ", ".join("_" if s is None else str(s) for s in shape) + ")"
    raise ValueError(f"{name}: expected shape {want}, got {arr.shape}")


@dataclass(frozen=True)
class Frame:
    """One depth frame with its time.

    depth: uint16 (H, W), units of ``depth_scale_m`` metres along the optical axis; 0 = no data.
    timestamp_s: seconds, from the recording or the device (never the wall clock of a stage).
    index: 0-based frame number in the stream.
    depth_scale_m: metres per depth unit (0.001 = millimetres).
    K: pinhole intrinsics (3, 3) or None when unknown.
    """

    depth: np.ndarray
    timestamp_s: float
    index: int
    depth_scale_m: float = 0.001
    K: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.depth.ndim != 2:
            raise ValueError(f"Frame.depth: expected shape (H, W), got {self.depth.shape}")
        if self.K is not None:
            _check_shape("Frame.K", self.K, (3, 3))

    @property
    def resolution_wh(self) -> tuple[int, int]:
        return int(self.depth.shape[1]), int(self.depth.shape[0])


@dataclass(frozen=True)
class TouchPoints:
    """Touch points found in one frame (before tracking), parallel arrays of length N.

    xy_px: (N, 2) float64 sub-pixel image coordinates (x = column, y = row).
    height_mm: (N,) height of the touching pixel above the surface.
    area_px: (N,) pixel count of the touch region.
    hand_xy_px: (N, 2) centroid of the attached hand/arm part (NaN when none was seen).
    hand_at_border: (N,) bool, the hand is connected to the image border (an arm reaching in);
        None means unknown (taken as True).
    attach_px: (N,) hand pixels within 2 px of the region, its attachment to the hand (about
        twice the attached length in px); None means unknown.
    attach_height_mm: (N,) median height of those hand pixels above the surface (NaN when
        none); None means unknown.
    back_spread_mm: (N,) spread of the heights behind the tip, along and beside the finger
        (NaN when unknown; a finger rises behind its tip, a flat object's top is level); None
        means unknown.
    offset_px: (N, 2) what to add to xy_px for the reported contact (a correction of the
        tip's position that tracking does not need: its matching uses xy_px); None means none.
    core_height_mm: (N,) the height of the finger's core at the point: the 75th percentile of
        the heights of the 3x3 pixels around it (NaN when none is known; the lift test in
        tracking compares it with the same contact's earlier frames); None means unknown.
    tl_above_floor_mm: (N,) how far Tl around the point (the mean over the 9x9 pixels around
        it) lies above its floor: 0 where the depth is quiet enough that Tl is the floor; None
        means unknown.
    attach_share: (N,) the share of the pixels within 2 px around the region (those with a
        depth) that are its attachment's hand pixels: a fingertip's hand lies at its back only,
        a patch of a resting hand or forearm is surrounded by its hand; None means unknown.
    recent_change_mm: (N,) how much the height around the point (the median of its 5x5
        pixels) differs from the same in the frames of the last seconds (the median over them)
        (:mod:`depthtouch.touch.recent`): a finger arrives, a resting hand's patch lies in a
        hand that has not moved (NaN when unknown); None means not measured.
    """

    xy_px: np.ndarray
    height_mm: np.ndarray
    area_px: np.ndarray
    hand_xy_px: np.ndarray
    hand_at_border: np.ndarray | None = None
    attach_px: np.ndarray | None = None
    attach_height_mm: np.ndarray | None = None
    back_spread_mm: np.ndarray | None = None
    offset_px: np.ndarray | None = None
    core_height_mm: np.ndarray | None = None
    tl_above_floor_mm: np.ndarray | None = None
    attach_share: np.ndarray | None = None
    recent_change_mm: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = self.xy_px.shape[0] if self.xy_px.ndim == 2 else -1
        _check_shape("TouchPoints.xy_px", self.xy_px, (None, 2))
        _check_shape("TouchPoints.height_mm", self.height_mm, (n,))
        _check_shape("TouchPoints.area_px", self.area_px, (n,))
        _check_shape("TouchPoints.hand_xy_px", self.hand_xy_px, (n, 2))
        if self.hand_at_border is not None:
            _check_shape("TouchPoints.hand_at_border", self.hand_at_border, (n,))
        if self.attach_px is not None:
            _check_shape("TouchPoints.attach_px", self.attach_px, (n,))
        if self.attach_height_mm is not None:
            _check_shape("TouchPoints.attach_height_mm", self.attach_height_mm, (n,))
        if self.back_spread_mm is not None:
            _check_shape("TouchPoints.back_spread_mm", self.back_spread_mm, (n,))
        if self.offset_px is not None:
            _check_shape("TouchPoints.offset_px", self.offset_px, (n, 2))
        if self.core_height_mm is not None:
            _check_shape("TouchPoints.core_height_mm", self.core_height_mm, (n,))
        if self.tl_above_floor_mm is not None:
            _check_shape("TouchPoints.tl_above_floor_mm", self.tl_above_floor_mm, (n,))
        if self.attach_share is not None:
            _check_shape("TouchPoints.attach_share", self.attach_share, (n,))
        if self.recent_change_mm is not None:
            _check_shape("TouchPoints.recent_change_mm", self.recent_change_mm, (n,))

    @classmethod
    def empty(cls) -> TouchPoints:
        return cls(np.zeros((0, 2)), np.zeros(0), np.zeros(0, np.int64), np.zeros((0, 2)))

    def __len__(self) -> int:
        return int(self.xy_px.shape[0])

    def __getitem__(self, index: np.ndarray | slice) -> TouchPoints:
        """The points ``index`` selects, with every per-point array."""
        parts: dict[str, Any] = {f.name: None if (v := getattr(self, f.name)) is None
                                 else v[index] for f in fields(self)}
        return TouchPoints(**parts)


@dataclass(frozen=True)
class TouchEvent:
    """One line of the JSON Lines contract (docs/formats.md section 2).

    ``extra`` holds optional fields (``sx``, ``sy``, ``X``, ``Y``, ``Z``, ``area``...), written after
    the required ones.
    """

    frame: int
    t: float
    id: int
    state: TouchState
    x: float
    y: float
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {
            "frame": self.frame,
            "t": round(self.t, 6),
            "id": self.id,
            "state": self.state,
            "x": round(self.x, 3),
            "y": round(self.y, 3),
        }
        for k, v in self.extra.items():
            d[k] = round(v, 3) if isinstance(v, float) else v
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TouchEvent:
        required = ("frame", "t", "id", "state", "x", "y")
        extra = {k: v for k, v in d.items() if k not in required}
        return cls(
            int(d["frame"]), float(d["t"]), int(d["id"]), d["state"], float(d["x"]),
            float(d["y"]), extra,
        )


@dataclass(frozen=True)
class StreamGap:
    """Yielded by a live source between frames when the stream broke (a camera was lost and
    reopened): touches down before it are ended; ``reason`` says why, for a person. ``cam``:
    the camera that broke when several feed one loop (only its touches end), None for the only
    one."""

    reason: str
    cam: int | None = None


class HeightView(Protocol):
    """What a result needs of the surface to draw a frame: height above it in mm."""

    def height_map_mm(self, depth: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True)
class FrameResult:
    """Everything the pipeline made of one frame; what every sink receives.

    frame: the frame as processed (after the pre-filter).
    events: the touch events (``sx``, ``sy`` from the calibration and ``X``, ``Y``, ``Z`` in mm
        already added; sinks read them, never recompute them).
    points: the touch points found before tracking (empty while learning).
    status: see :data:`FrameStatus`.
    timing_ms: milliseconds per stage of this frame, with ``total`` (empty while learning).
    learn_progress: share of the surface learning done, in [0, 1] (1 once learned).
    note: a line for a person while learning ("keep the surface clear..."), else "".
    surface: the surface as it was for this frame (draws height maps on demand), or None.
    """

    frame: Frame
    events: list[TouchEvent]
    points: TouchPoints
    status: FrameStatus
    timing_ms: dict[str, float] = field(default_factory=dict)
    learn_progress: float = 1.0
    note: str = ""
    surface: HeightView | None = field(default=None, repr=False)

    @property
    def learning(self) -> bool:
        return self.status == "learning"

    def height_map_mm(self) -> np.ndarray:
        """Height above the surface in mm, float32 (H, W), NaN where unknown."""
        if self.surface is None:
            return np.full(self.frame.depth.shape, np.nan, np.float32)
        return self.surface.height_map_mm(self.frame.depth)
