"""Tracking: stable ids across frames, with down / move / up.

Touch points are matched to tracks by optimal assignment (``scipy.optimize.linear_sum_assignment``)
on their distance, gated (mm when the surface scale is known, px otherwise). A new contact goes
``down`` after ``down_frames`` consecutive frames; a contact missing for ``up_frames`` consecutive
frames goes ``up`` with its last position (it is reported as ``move`` at that position during the
grace frames). Height hysteresis: a tip must come below ``touch_on_mm`` to start a contact, and a
contact lasts while its tip stays below ``touch_off_mm``, so that a finger resting at the noise
limit does not flicker. Ids are never reused within a run.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from .config import TouchPointConfig, TrackingConfig
from .types import TouchPoints, TouchState

_BIG = 1e9


@dataclass
class Track:
    """State of one tracked contact (pending until it goes down; id -1 meanwhile)."""

    xy_px: np.ndarray
    pos: np.ndarray
    height_mm: float
    area_px: int
    id: int = -1
    seen: int = 1
    missing: int = 0
    active: bool = False
    vel: np.ndarray = field(default_factory=lambda: np.zeros(2))
    out_xy: np.ndarray | None = None  # last reported (filtered) position
    hand_at_border: bool = True
    merged: int = 0  # consecutive frames hidden in a neighbour's region

    def predicted(self) -> np.ndarray:
        """Where the contact should be this frame (constant velocity per frame)."""
        return self.pos + self.vel * (1 + self.missing)


@dataclass(frozen=True)
class TrackUpdate:
    """What happened to a track this frame; ``measured`` is False during grace and on up."""

    track: Track
    state: TouchState
    measured: bool


@dataclass
class Tracker:
    """Assigns ids to touch points frame after frame; ``update`` then ``reset`` to start over.

    scale: units of ``pos`` per pixel used for gating: mm per px when known (gate_mm applies),
    None to gate in pixels (gate_px).
    """

    config: TrackingConfig = field(default_factory=TrackingConfig)
    touch: TouchPointConfig = field(default_factory=TouchPointConfig)
    scale_mm_per_px: float | None = None
    next_id: int = 1
    tracks: list[Track] = field(default_factory=list)

    def reset(self) -> None:
        """Forget all tracks; ids keep increasing (never reused within a run)."""
        self.tracks = []

    @property
    def gate(self) -> float:
        return self.config.gate_mm if self.scale_mm_per_px is not None else self.config.gate_px

    def update(self, points: TouchPoints) -> list[TrackUpdate]:
        """Advance one frame with this frame's touch points; returns the reported tracks."""
        if not self.tracks and len(points) == 0:
            return []
        scale = self.scale_mm_per_px if self.scale_mm_per_px is not None else 1.0
        pos = points.xy_px * scale
        h = points.height_mm
        border = ([True] * len(points) if points.hand_at_border is None
                  else [bool(b) for b in points.hand_at_border])
        ok_cont = np.nan_to_num(h, nan=np.inf) <= self.touch.touch_off_mm
        ok_new = np.nan_to_num(h, nan=np.inf) <= self.touch.touch_on_mm
        n_t, n_p = len(self.tracks), len(points)
        matched_t: dict[int, int] = {}
        if n_t and n_p:
            # distance to where the contact should be, or to where it was: a sharp turn must
            # not be lost to a prediction that overshoots
            pred = np.array([t.predicted() for t in self.tracks])
            last = np.array([t.pos for t in self.tracks])
            cost = np.minimum(np.linalg.norm(pred[:, None, :] - pos[None, :, :], axis=2),
                              np.linalg.norm(last[:, None, :] - pos[None, :, :], axis=2))
            allowed = np.where(
                np.array([t.active for t in self.tracks])[:, None], ok_cont[None, :], ok_new[None, :]
            )
            cost = np.where(allowed & (cost <= self.gate), cost, _BIG)
            rows, cols = linear_sum_assignment(cost)
            for r, c in zip(rows, cols):
                if cost[r, c] < _BIG:
                    matched_t[int(r)] = int(c)
        out: list[TrackUpdate] = []
        keep: list[Track] = []
        used = set(matched_t.values())
        for i, t in enumerate(self.tracks):
            j = matched_t.get(i)
            if j is not None:
                step = (pos[j] - t.pos) / (1 + t.missing)
                # smoothed velocity: a noisy touch point must not throw the prediction off
                t.vel = step if t.seen == 1 else 0.5 * t.vel + 0.5 * step
                t.xy_px, t.pos = points.xy_px[j].copy(), pos[j].copy()
                t.height_mm, t.area_px = float(h[j]), int(points.area_px[j])
                t.hand_at_border = border[j]
                t.seen += 1
                t.missing = 0
                t.merged = 0
                if t.active:
                    out.append(TrackUpdate(t, "move", True))
                elif t.seen >= self.config.down_frames:
                    self._activate(t)
                    out.append(TrackUpdate(t, "down", True))
                keep.append(t)
            elif t.active:
                if self._merged(t, pos, used) and t.merged < self.config.merge_frames:
                    # a fingertip side by side with a touching neighbour merged into its region:
                    # it is hidden, not lifted; hold it where it was
                    t.merged += 1
                    out.append(TrackUpdate(t, "move", False))
                    keep.append(t)
                    continue
                t.missing += 1
                if t.missing >= self.config.up_frames:
                    out.append(TrackUpdate(t, "up", False))
                else:
                    out.append(TrackUpdate(t, "move", False))
                    keep.append(t)
            # an unmatched pending track is dropped (it never went down)
        for j in range(n_p):
            if j in used or not ok_new[j]:
                continue
            t = Track(points.xy_px[j].copy(), pos[j].copy(), float(h[j]), int(points.area_px[j]),
                      hand_at_border=border[j])
            if self.config.down_frames <= 1:
                self._activate(t)
                out.append(TrackUpdate(t, "down", True))
            keep.append(t)
        self.tracks = keep
        return out

    def _merged(self, t: Track, pos: np.ndarray, used: set[int]) -> bool:
        """Is a point matched this frame within a finger width of this (unmatched) track?"""
        if not used:
            return False
        scale = self.scale_mm_per_px if self.scale_mm_per_px is not None else None
        near = self.config.merge_mm if scale is not None else self.config.merge_mm / 2.0
        d = np.linalg.norm(pos[list(used)] - t.pos, axis=1)
        return bool((d <= near).any())

    def _activate(self, t: Track) -> None:
        t.active = True
        t.id = self.next_id
        self.next_id += 1

    def end_all(self) -> list[TrackUpdate]:
        """End every active contact (``up``), e.g. at the end of a stream or on a surface reset."""
        out = [TrackUpdate(t, "up", False) for t in self.tracks if t.active]
        self.tracks = []
        return out
