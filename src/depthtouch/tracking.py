"""Tracking: stable ids across frames, with down / move / up.

Touch points are matched to tracks by optimal assignment (``scipy.optimize.linear_sum_assignment``)
on their distance, gated (mm when the surface scale is known, px otherwise): contacts that are down
first, then pending ones on the points left. Fingertips side by side whose regions merged into one
point (a region about twice a tip's area) keep their ids and move with that point, each at its
place in the pair; a contact hidden in a neighbour's region is held. A new contact goes
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


def _assign(cost: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> dict[int, int]:
    """Optimal assignment of tracks ``rows`` to points ``cols`` on ``cost`` (pairs < _BIG)."""
    if rows.size == 0 or cols.size == 0:
        return {}
    sub = cost[np.ix_(rows, cols)]
    best = sub.argmin(axis=1).tolist()
    if len(set(best)) == len(best):
        # every track's nearest point is its own: that is the optimum (no assignment can cost
        # less than each track's own minimum), found without the solver
        return {int(rows[a]): int(cols[b]) for a, b in enumerate(best) if sub[a, b] < _BIG}
    r, c = linear_sum_assignment(sub)
    ok = sub[r, c] < _BIG
    return {int(rows[a]): int(cols[b]) for a, b in zip(r[ok], c[ok], strict=True)}


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

    @property
    def merge_near(self) -> float:
        """Distance within which a contact may be hidden in a neighbour's region (gate units)."""
        mm = self.config.merge_mm
        return mm if self.scale_mm_per_px is not None else mm / 2.0

    def update(self, points: TouchPoints) -> list[TrackUpdate]:
        """Advance one frame with this frame's touch points; returns the reported tracks."""
        if not self.tracks and len(points) == 0:
            return []
        scale = self.scale_mm_per_px if self.scale_mm_per_px is not None else 1.0
        pos = points.xy_px * scale
        h = points.height_mm
        border = ([True] * len(points) if points.hand_at_border is None
                  else [bool(b) for b in points.hand_at_border])
        # (an unknown height, NaN, compares False: never a touch)
        ok_cont = h <= self.touch.touch_off_mm
        ok_new = h <= self.touch.touch_on_mm
        n_t, n_p = len(self.tracks), len(points)
        matched_t: dict[int, int] = {}
        groups: dict[int, list[int]] = {}
        if n_t and n_p:
            # distance to where the contact should be, or to where it was: a sharp turn must
            # not be lost to a prediction that overshoots
            last = np.array([t.pos for t in self.tracks])
            pred = last + np.array([t.vel * (1 + t.missing) for t in self.tracks])
            dp, dl = pred[:, None, :] - pos[None, :, :], last[:, None, :] - pos[None, :, :]
            dist = np.sqrt(np.minimum((dp * dp).sum(axis=2), (dl * dl).sum(axis=2)))
            is_active = np.array([t.active for t in self.tracks])
            allowed = np.where(is_active[:, None], ok_cont[None, :], ok_new[None, :])
            cost = np.where(allowed & (dist <= self.gate), dist, _BIG)
            # Contacts that are down are served first, pending ones get what is left: optimal
            # assignment maximises the number of pairs, so in one joint assignment a noise blip
            # or a finger just arriving next to a contact could take the contact's point and
            # push it onto a farther one (or out, to come back with a new id).
            act = np.flatnonzero(is_active)
            matched_t = _assign(cost, act, np.arange(n_p))
            groups = self._merge_groups(cost, matched_t, act, points.area_px)
            for members in groups.values():
                for i in members:
                    matched_t.pop(i, None)
            if act.size < n_t:
                free = np.ones(n_p, bool)
                free[[*matched_t.values(), *groups]] = False
                matched_t.update(_assign(cost, np.flatnonzero(~is_active), np.flatnonzero(free)))
        out: list[TrackUpdate] = []
        keep: list[Track] = []
        used = set(matched_t.values()) | set(groups)
        shift: dict[int, tuple[int, np.ndarray]] = {}
        for k, members in groups.items():
            centre = np.mean([self.tracks[i].pos for i in members], axis=0)
            for i in members:
                shift[i] = (k, pos[k] - centre)
        for i, t in enumerate(self.tracks):
            j = matched_t.get(i)
            if i in shift:
                # fingertips side by side in one region: its point is where they are together;
                # each keeps its place in the pair and moves with it (no id jumps to the other)
                k, step = shift[i]
                v = step / (1 + t.missing)
                t.vel = 0.5 * t.vel + 0.5 * v
                t.pos = t.pos + step
                t.xy_px = t.pos / scale
                t.height_mm = float(h[k])
                t.hand_at_border = border[k]
                t.seen += 1
                t.missing = 0
                t.merged += 1
                out.append(TrackUpdate(t, "move", True))
                keep.append(t)
                continue
            if j is not None:
                step = (pos[j] - t.pos) / (1 + t.missing)
                # smoothed velocity, from rest: a noisy touch point (or, just after touch-down, a
                # neighbour's tip arriving in the region) must not throw the prediction off
                t.vel = 0.5 * t.vel + 0.5 * step
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

    def _merge_groups(
        self, cost: np.ndarray, matched_t: dict[int, int], act: np.ndarray, area_px: np.ndarray
    ) -> dict[int, list[int]]:
        """Points whose region holds the fingertips of several contacts side by side -> them.

        A contact down is hidden in point k, matched to another contact, when k is the nearest
        point it may take (within ``merge_mm``) but it was left without a point or pushed onto a
        farther one, and k's region is ``merge_area_ratio`` times as large as the largest of
        their fingertips (two tips side by side make one region of about twice the area; a
        finger that only moved keeps its area).
        """
        ratio = self.config.merge_area_ratio
        if ratio <= 0 or act.size < 2 or not matched_t:
            return {}
        owner = {j: i for i, j in matched_t.items()}
        nearest = np.argmin(cost[act], axis=1)
        cand: dict[int, list[int]] = {}
        for b, k in zip(act.tolist(), nearest.tolist(), strict=True):
            a = owner.get(k)
            j = matched_t.get(b)
            if a is None or a == b or cost[b, k] > self.merge_near:
                continue
            if j is not None and cost[b, j] <= cost[b, k]:
                continue
            cand.setdefault(k, [a]).append(b)
        groups: dict[int, list[int]] = {}
        grouped: set[int] = set()
        for k, members in cand.items():
            members = [i for i in members if i not in grouped]  # one group per contact
            tracks = [self.tracks[i] for i in members]
            if (len(members) > 1 and all(t.merged < self.config.merge_frames for t in tracks)
                    and area_px[k] >= ratio * max(t.area_px for t in tracks)):
                groups[k] = members
                grouped.update(members)
        return groups

    def _merged(self, t: Track, pos: np.ndarray, used: set[int]) -> bool:
        """Is a point matched this frame within a finger width of this (unmatched) track?"""
        if not used:
            return False
        d = np.linalg.norm(pos[list(used)] - t.pos, axis=1)
        return bool((d <= self.merge_near).any())

    def _activate(self, t: Track) -> None:
        t.active = True
        t.id = self.next_id
        self.next_id += 1

    def end_all(self) -> list[TrackUpdate]:
        """End every active contact (``up``), e.g. at the end of a stream or on a surface reset."""
        out = [TrackUpdate(t, "up", False) for t in self.tracks if t.active]
        self.tracks = []
        return out
