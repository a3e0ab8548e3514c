"""One tracked contact: its state (:class:`Track`), what a frame did to it
(:class:`TrackUpdate`), and how its reported offset turns with the finger (:func:`steer`).

The :class:`~.tracker.Tracker` owns the tracks and is the only one that changes them; the
pipeline reads them through the updates it returns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

from ..types import TouchState
from .evidence import XY
from .lift import CoreHistory


@dataclass(slots=True)
class Track:
    """State of one tracked contact (pending until it goes down; id -1 meanwhile).

    Positions are pairs of plain floats: a frame updates a handful of tracks, and a numpy call on
    a 2-vector costs as much as twenty float operations. xy_px: image px; pos: xy_px times the
    tracker's scale (mm when known); vel: per frame interval, in the units of pos. report_px:
    where the contact is reported, xy_px plus its point's offset (TouchPoints.offset_px).
    """

    xy_px: XY
    pos: XY
    height_mm: float
    area_px: int
    id: int = -1
    seen: int = 1
    missing: int = 0
    active: bool = False
    vel: XY = (0.0, 0.0)
    hand_at_border: bool = True
    merged: int = 0  # consecutive frames hidden in a neighbour's region
    evidence: float = 0.0  # pending: frames of touch seen, each weighted by how tip-like it was
    doubt: int = 0  # down: consecutive frames whose point gave no evidence of a touch
    gaps: int = 0  # down: how often its point came back after missing frames
    offset_px: XY = (0.0, 0.0)
    offset_dir: XY = (0.0, 0.0)  # the smoothed direction of offset_px (0, 0: none yet)
    core: CoreHistory | None = None  # its finger's core heights (TrackingConfig.lift_core_mm)
    still_at: XY = (math.nan, math.nan)  # where its point's still run began (pos units)
    still_n: int = 0  # frames in a row its point stayed near still_at
    # the stream's frame intervals since its point was last seen, this frame's included (1 +
    # missing in an even stream; a frame the camera dropped adds one: FrameRate.step)
    since: float = 0.0
    # pending: its reported points (report_px) and their times (s) in the frames it was seen,
    # the last TrackingConfig.land_prior_frames of them (given to the path filter at down)
    prior: list[tuple[float, float, float]] = field(default_factory=list)

    @property
    def report_px(self) -> XY:
        return (self.xy_px[0] + self.offset_px[0], self.xy_px[1] + self.offset_px[1])

    def predicted(self) -> XY:
        """Where the contact should be this frame (constant velocity per frame interval, over
        the intervals since it was last seen)."""
        k = self.since
        return (self.pos[0] + self.vel[0] * k, self.pos[1] + self.vel[1] * k)


def steer(prev_dir: XY, offset: XY, weight: float) -> tuple[XY, XY]:
    """(direction, offset): a point's reported offset turned onto its contact's smoothed
    direction (TrackingConfig.report_dir_weight): ``prev_dir`` moved ``weight`` of the way to
    the offset's own direction, and the offset's length along it. A contact without a direction
    yet (``prev_dir`` (0, 0)) takes the offset's; a zero offset, or ``weight`` 1, is returned as
    it is (pure)."""
    ox, oy = offset
    mag = math.hypot(ox, oy)
    if mag <= 1e-12 or weight >= 1.0:
        return ((ox / mag, oy / mag) if mag > 1e-12 else prev_dir), offset
    ux, uy = ox / mag, oy / mag
    px, py = prev_dir
    if px != 0.0 or py != 0.0:
        nx, ny = px + weight * (ux - px), py + weight * (uy - py)
        nn = math.hypot(nx, ny)
        if nn > 1e-9:  # (opposite directions cancel: take the new one)
            ux, uy = nx / nn, ny / nn
    return (ux, uy), (mag * ux, mag * uy)


class TrackUpdate(NamedTuple):
    """What happened to a track this frame; ``measured`` is False during grace and on up.

    (A named tuple: immutable like a frozen dataclass, at half the cost to make.)
    """

    track: Track
    state: TouchState
    measured: bool
