"""Tracking: stable ids across frames, with down / move / up.

Touch points are matched to tracks by optimal assignment on their distance (:mod:`.assign`),
gated (mm when the surface scale is known, px otherwise): contacts that are down first, then
pending ones on the points left. The distance is to where a contact was or to where its
velocity takes it over the stream's frame intervals since it was last seen; the intervals are
counted from the frames' timestamps (:attr:`.framerate.FrameRate.step`), so that over a frame
the camera dropped a drag is predicted twice as far and the gates grow as much (an even
stream, or one without timestamps, counts one interval a frame). Fingertips side by side
whose regions merged into one point (a region about twice a tip's area) keep their ids and
move with that point, each at its place in the pair; a contact hidden in a neighbour's region
is held. A new contact goes ``down`` once its evidence reaches ``down_frames``: frames, each
counting 1 when its region has
a fingertip's area (in mm², and in pixels where pixels are large) and ``weak_evidence``
otherwise (a speck at a finger's edge, a hovering finger or a forearm's edge lying in the band),
nothing when it lies behind another point on that point's finger (one finger, one tip), and
``steep_evidence`` when it looks like the top of a finger standing almost upright (see
TrackingConfig); a pending contact survives ``pending_gap_frames`` frames without a point, its
evidence fading (``pending_low_gap_frames`` when its tip was low, where pixels are small); a
contact missing for ``up_frames`` consecutive frames goes ``up`` with its last position (it is
reported as ``move`` at that position during the grace frames). Height hysteresis: a tip must
come below ``touch_on_mm`` to start a contact, and a contact lasts while its tip stays below
``touch_off_mm``, so that a finger resting at the noise limit does not flicker. A contact whose
finger's core rises above its own earlier level (``lift_core_mm``, :mod:`.lift`) counts as
missing though its tip still reads low (at ToF range a hovering finger's outline lies as low as
a touching tip), and a pending one gains no evidence then. A contact that is down does not
jump onto a point that an established pending contact lies much nearer to (``yield_ratio``):
when its own tip drops out for a frame, the nearest point is often a hovering finger or hand
beside it; it counts as missing instead, and nobody takes that point in that frame.
A contact whose point has given no evidence of a touch for ``doubt_frames`` frames in a row
goes ``up`` (it came down on a forearm's edge or a held object, which stays in the band);
with ``enclosed_pending_only`` (the default) the enclosure test's refusals do not count there:
that test judges a touch's start, and a finger held still is as still as a resting hand.
With ``pending_step_max_mm`` set (off by default), a pending contact whose point arrives
sliding under a raised hand gains no evidence in that frame (a time-of-flight camera's mixed
depths along a hand sweeping past); with ``still_step_frames`` (off), a point that stays put
is not refused for the hand's height behind it. Ids are never reused within a run. With
``reference_fps`` set (off by default), the evidence counts frames at that rate: in a faster
stream (from the frames' timestamps, :mod:`.framerate`) a frame counts its length, so that a
contact goes down after as many frames and as much time as at that rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..config import TouchPointConfig, TrackingConfig
from ..types import TouchPoints
from .assign import assign, gated_cost, nearest_index
from .evidence import XY, evidence, may_start, refused_out, steep_tips
from .framerate import FrameRate
from .lift import CoreHistory, held_grace
from .track import Track, TrackUpdate, steer

# a pending contact a contact that is down yields a point to (TrackingConfig.yield_ratio): seen
# in this many frames, with this much evidence
YIELD_SEEN = 3
YIELD_EVIDENCE = 1.0


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
    # the length of this stream's frames for the evidence (TrackingConfig.reference_fps)
    _rate: FrameRate = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._rate = FrameRate(self.config.reference_fps, self.config.gate_fps)

    def reset(self) -> None:
        """Forget all tracks and the stream's frame rate; ids keep increasing (never reused
        within a run)."""
        self.tracks = []
        self._rate.reset()

    def use_scale(self, scale_mm_per_px: float | None) -> None:
        """Gate in mm with this many mm per px from now on (None: gate in pixels)."""
        self.scale_mm_per_px = scale_mm_per_px

    def held_xy_px(self, border_only: bool = False) -> list[XY]:
        """Image positions (px) of the active contacts (``border_only``: only those whose hand
        reaches in from the image border): a finger held still there must never become surface."""
        return [t.xy_px for t in self.tracks if t.active and (t.hand_at_border or not border_only)]

    @property
    def gate(self) -> float:
        """The largest jump between frames that keeps an id (mm, or px without a scale)."""
        return self.config.gate_mm if self.scale_mm_per_px is not None else self.config.gate_px

    @property
    def gate_down(self) -> float:
        """The gate of a contact that is down: grown in a stream slower than gate_fps when set
        (a drag moves farther between frames; a pending contact keeps :attr:`gate`, so that it
        cannot take a point farther away than at gate_fps)."""
        return self.gate * self._rate.gate

    @property
    def merge_near(self) -> float:
        """Distance within which a contact may be hidden in a neighbour's region (gate units)."""
        mm = self.config.merge_mm
        return mm if self.scale_mm_per_px is not None else mm / 2.0

    def update(self, points: TouchPoints, t_s: float | None = None) -> list[TrackUpdate]:
        """Advance one frame with this frame's touch points (``t_s``: its timestamp, s; None
        counts it as a frame at ``reference_fps``); returns the reported tracks."""
        frame = self._rate.update(t_s)
        tracks = self.tracks
        intervals = self._rate.step
        for t in tracks:
            t.since += intervals
        n_t, n_p = len(tracks), len(points)
        if not n_t and not n_p:
            return []
        # a handful of points: plain floats cost less than array calls here (same arithmetic)
        scale = self.scale_mm_per_px if self.scale_mm_per_px is not None else 1.0
        xy: list[XY] = list(map(tuple, points.xy_px.tolist()))
        pos: list[XY] = [(x * scale, y * scale) for x, y in xy]
        h = points.height_mm.tolist()
        area = points.area_px.tolist()
        offset: list[XY] = ([(0.0, 0.0)] * n_p if points.offset_px is None
                            else list(map(tuple, points.offset_px.tolist())))
        lift_mm = self.config.lift_core_mm
        noise_k = self.config.lift_noise_k
        dir_w = self.config.report_dir_weight
        core = ([math.nan] * n_p if points.core_height_mm is None or lift_mm <= 0
                else points.core_height_mm.tolist())
        hb = points.hand_at_border
        border: list[bool] = ([True] * n_p if hb is None else hb.tolist() if hb.dtype.kind == "b"
                              else [bool(b) for b in hb.tolist()])
        # (an unknown height, NaN, compares False: never a touch)
        off, on = self.touch.touch_off_mm, self.touch.touch_on_mm
        ok_cont = [v <= off for v in h]
        steep = steep_tips(points, area, self.scale_mm_per_px, self.config)
        ok_new = may_start(h, steep, on)
        matched_t: dict[int, int] = {}
        groups: dict[int, list[int]] = {}
        if n_t and n_p:
            # the gates are the largest jumps in one frame interval: over a frame the camera
            # dropped, a finger moves as far again
            cost = gated_cost(tracks, pos, ok_cont, ok_new, self.gate * intervals,
                              self.gate_down * intervals)
            # Contacts that are down are served first, pending ones get what is left: optimal
            # assignment maximises the number of pairs, so in one joint assignment a noise blip
            # or a finger just arriving next to a contact could take the contact's point and
            # push it onto a farther one (or out, to come back with a new id).
            nearest = [nearest_index(row) for row in cost]
            act = [i for i, t in enumerate(tracks) if t.active]
            matched_t = assign(cost, act, list(range(n_p)), nearest)
            contested = self._yield(cost, matched_t)
            groups = self._merge_groups(cost, nearest, matched_t, act, area)
            for members in groups.values():
                for i in members:
                    matched_t.pop(i, None)
            if len(act) < n_t:
                taken = {*matched_t.values(), *groups, *contested}
                pending = [i for i, t in enumerate(tracks) if not t.active]
                free = [j for j in range(n_p) if j not in taken]
                matched_t.update(assign(cost, pending, free, nearest))
        out: list[TrackUpdate] = []
        keep: list[Track] = []
        used = set(matched_t.values()) | set(groups)
        shift: dict[int, tuple[int, XY]] = {}
        for k, members in groups.items():
            cx, cy = np.mean([tracks[i].pos for i in members], axis=0).tolist()
            moved = (pos[k][0] - cx, pos[k][1] - cy)
            for i in members:
                shift[i] = (k, moved)
        cfg, low_mm = self.config, self._pending_low_mm()
        n_prior = cfg.land_prior_frames if self.scale_mm_per_px is not None else 0
        down_frames = cfg.down_frames
        # how far a pending contact's point may move in a frame and still count (0: any)
        slide_mm = (cfg.pending_step_max_mm * self._rate.gate
                    if self.scale_mm_per_px is not None else 0.0)
        slide_ath_mm = cfg.pending_step_attach_mm
        # how far a pending contact's point may move in a frame and still count a steep top
        # (0: any)
        steep_still = cfg.steep_still_mm if self.scale_mm_per_px is not None else 0.0
        # the heights behind the points, only when the rule is on (an unknown height counts as
        # raised: the rule applies)
        ath: list[float] = (
            [] if slide_mm <= 0 else [math.inf] * n_p if points.attach_height_mm is None
            else [math.inf if math.isnan(v) else v for v in points.attach_height_mm.tolist()])
        weight, grow, grow_held = self._weights(points, xy, area, ok_new, steep, frame, cfg)
        # still_step_frames: the weights without the step test, for contacts whose point has
        # stayed put long enough (computed only when one needs them)
        still_n = cfg.still_step_frames if self.scale_mm_per_px is not None else 0
        grow_still: tuple[list[float], list[float]] | None = None
        for i, t in enumerate(tracks):
            j = matched_t.get(i)
            if i in shift:
                # fingertips side by side in one region: its point is where they are together;
                # each keeps its place in the pair and moves with it (no id jumps to the other)
                k, (sx, sy) = shift[i]
                m = t.since
                (vx, vy), (ox, oy) = t.vel, t.pos
                t.vel = (0.5 * vx + 0.5 * (sx / m), 0.5 * vy + 0.5 * (sy / m))
                px, py = ox + sx, oy + sy
                t.pos = (px, py)
                t.xy_px = (px / scale, py / scale)
                t.offset_dir, t.offset_px = steer(t.offset_dir, offset[k], dir_w)
                t.height_mm = float(h[k])
                t.hand_at_border = border[k]
                t.seen += 1
                t.missing = 0
                t.since = 0.0
                t.merged += 1
                out.append(TrackUpdate(t, "move", True))
                keep.append(t)
                continue
            if j is not None:
                w_j = grow_held[j] if t.active else grow[j]
                if still_n > 0:
                    sx, sy = t.still_at
                    if math.hypot(pos[j][0] - sx, pos[j][1] - sy) <= cfg.still_step_mm:
                        t.still_n += 1
                    else:
                        t.still_at, t.still_n = pos[j], 1
                    if t.still_n >= still_n and w_j <= 0.0:
                        if grow_still is None:
                            _, g, gh = self._weights(points, xy, area, ok_new, steep, frame,
                                                     replace(cfg, step_max_mm=0.0))
                            grow_still = (g, gh)
                        w_j = grow_still[1][j] if t.active else grow_still[0][j]
                rise = t.core.update(core[j]) if t.core is not None else math.nan
                # (NaN compares False; a contact that is down may rise by its own core's noise
                # besides, lift_noise_k: a steep held tip's core jumps between the tip and the
                # finger behind it; a pending one may not)
                if rise > lift_mm and (not t.active or noise_k <= 0 or t.core is None
                                       or rise > lift_mm + noise_k * t.core.noise()):
                    if t.active:
                        # its core rose above the contact's own level: lifted, though the tip
                        # still reads low; a missing frame, but the point stays taken
                        t.missing += 1
                        if t.missing < cfg.up_frames:
                            out.append(TrackUpdate(t, "move", False))
                            keep.append(t)
                            continue
                        out.append(TrackUpdate(t, "up", False))
                        # the hovering finger goes on as a pending contact that keeps this
                        # history: it goes down again once its core is back at the level
                        t = Track(xy[j], pos[j], float(h[j]), int(area[j]),
                                  hand_at_border=border[j], offset_px=offset[j], core=t.core)
                        keep.append(t)
                        continue
                    w_j = 0.0  # a pending contact whose core rose: not a touch this frame
                m = t.since
                (vx, vy), (ox, oy), (px, py) = t.vel, t.pos, pos[j]
                if (not t.active and slide_mm > 0 and ath[j] > slide_ath_mm
                        and math.hypot(px - ox, py - oy) > slide_mm * m):
                    # a pending contact arriving sliding under a raised hand: no evidence now
                    w_j = 0.0
                if (not t.active and steep_still > 0 and steep[j]
                        and math.hypot(px - ox, py - oy) > steep_still * m):
                    # a steep top where the contact's point did not stand the frame before
                    w_j = 0.0
                # smoothed velocity, from rest: a noisy touch point (or, just after touch-down, a
                # neighbour's tip arriving in the region) must not throw the prediction off
                t.vel = (0.5 * vx + 0.5 * ((px - ox) / m), 0.5 * vy + 0.5 * ((py - oy) / m))
                t.xy_px, t.pos = xy[j], pos[j]
                t.offset_dir, t.offset_px = steer(t.offset_dir, offset[j], dir_w)
                t.height_mm, t.area_px = float(h[j]), int(area[j])
                t.hand_at_border = border[j]
                t.seen += 1
                t.gaps += t.active and t.missing > 0
                t.missing = 0
                t.since = 0.0
                t.merged = 0
                t.evidence += w_j
                t.doubt = t.doubt + 1 if w_j <= 0.0 else 0
                if t.active and 0 < cfg.doubt_frames <= t.doubt:
                    # down, but for doubt_frames frames in a row its point has not looked like
                    # a touch (a forearm's edge the contact came down on): up, and the point
                    # starts over as a pending contact
                    out.append(TrackUpdate(t, "up", False))
                    t = Track(xy[j], pos[j], float(h[j]), int(area[j]),
                              hand_at_border=border[j], offset_px=offset[j], core=t.core)
                    keep.append(t)
                    continue
                if t.active:
                    out.append(TrackUpdate(t, "move", True))
                elif t.evidence >= down_frames - 1e-9:
                    self._activate(t)
                    out.append(TrackUpdate(t, "down", True))
                elif n_prior > 0 and t_s is not None:
                    t.prior.append((*t.report_px, t_s))
                    del t.prior[:-n_prior]
                keep.append(t)
            elif t.active:
                if self._merged(t, pos, used) and t.merged < cfg.merge_frames:
                    # a fingertip side by side with a touching neighbour merged into its region:
                    # it is hidden, not lifted; hold it where it was
                    t.merged += 1
                    out.append(TrackUpdate(t, "move", False))
                    keep.append(t)
                    continue
                t.missing += 1
                if t.missing >= (held_grace(cfg, t.gaps, t.vel, t.pos, pos, ok_cont)
                                 if self.scale_mm_per_px is not None else cfg.up_frames):
                    out.append(TrackUpdate(t, "up", False))
                else:
                    out.append(TrackUpdate(t, "move", False))
                    keep.append(t)
            elif t.missing < (cfg.pending_low_gap_frames if (low := t.height_mm <= low_mm)
                              else cfg.pending_gap_frames):
                # a pending contact unseen this frame (a tip at the band's edge at range flickers
                # in and out of it): kept, its evidence fading, for pending_gap_frames frames
                # (pending_low_gap_frames when its tip was low, where pixels are small)
                t.missing += 1
                t.evidence *= cfg.pending_low_decay if low else cfg.pending_decay
                keep.append(t)
            # otherwise an unmatched pending track is dropped (it never went down)
        for j in range(n_p):
            if j in used or not ok_new[j]:
                continue
            # (a contact starting on a steep top has not yet stood anywhere: no evidence)
            w_new = 0.0 if steep_still > 0 and steep[j] else weight[j]
            t = Track(xy[j], pos[j], float(h[j]), int(area[j]), hand_at_border=border[j],
                      evidence=w_new, offset_px=offset[j], still_at=pos[j], still_n=1)
            if lift_mm > 0:
                t.core = CoreHistory(keep_noise=noise_k > 0)
                t.core.update(core[j])
            if t.evidence >= down_frames - 1e-9:
                self._activate(t)
                out.append(TrackUpdate(t, "down", True))
            elif n_prior > 0 and t_s is not None:
                t.prior.append((*t.report_px, t_s))
            keep.append(t)
        self.tracks = keep
        return out

    def _weights(self, points: TouchPoints, xy: list[XY], area: list[int], ok_new: list[bool],
                 steep: list[bool], frame: float, cfg: TrackingConfig
                 ) -> tuple[list[float], list[float], list[float]]:
        """This frame's evidence weights under ``cfg``: as seen, then grown by ``frame`` for a
        pending contact and for one that is down (``still_step_frames`` asks them again with
        the step test off)."""
        unrefused, refused = evidence(points, xy, area, ok_new, steep, self.scale_mm_per_px,
                                      cfg)
        weight = refused_out(unrefused, refused)
        # the enclosure test refuses a touch's start; a contact that is down keeps the weights
        # without it when enclosed_pending_only (its finger arrived; a held finger is still)
        held = unrefused if cfg.enclosed_pending_only else weight
        # in a stream faster than reference_fps, a contact's first frame counts as one
        # reference frame and each further frame as its length: its evidence is how long it
        # has been seen (exactly the weights at the reference rate and slower)
        grow = weight if frame == 1.0 else [v * frame for v in weight]
        grow_held = grow if held is weight else held if frame == 1.0 else [v * frame for v in held]
        return weight, grow, grow_held

    def _pending_low_mm(self) -> float:
        """How low a pending contact's tip must be for pending_low_gap_frames (mm; -inf where
        pixels are too large for the size test to work in mm, or with pending_low_mm 0)."""
        c, scale = self.config, self.scale_mm_per_px
        if (c.pending_low_mm <= 0 or scale is None or c.tip_area_min_px <= 0
                or c.tip_area_min_mm2 / (scale * scale) < c.tip_area_min_px):
            return -math.inf
        return c.pending_low_mm

    def _yield(self, cost: list[list[float]], matched: dict[int, int]) -> set[int]:
        """Take back the points that contacts down were given while an established pending
        contact lies much nearer to them (TrackingConfig.yield_ratio); returns those points,
        which nobody takes this frame. Edits ``matched`` in place."""
        cfg = self.config
        if cfg.yield_ratio <= 0 or self.scale_mm_per_px is None or not matched:
            return set()
        pend = [cost[q] for q, t in enumerate(self.tracks)
                if not t.active and t.seen >= YIELD_SEEN and t.evidence >= YIELD_EVIDENCE]
        if not pend:
            return set()
        contested: set[int] = set()
        for i, j in list(matched.items()):
            d = cost[i][j]
            if d >= cfg.yield_min_mm and any(row[j] <= cfg.yield_ratio * d for row in pend):
                del matched[i]
                contested.add(j)
        return contested

    def _merge_groups(
        self,
        cost: list[list[float]],
        nearest: list[int],
        matched_t: dict[int, int],
        act: list[int],
        area_px: list[int],
    ) -> dict[int, list[int]]:
        """Points whose region holds the fingertips of several contacts side by side -> them.

        A contact down is hidden in point k, matched to another contact, when k is the nearest
        point it may take (within ``merge_mm``) but it was left without a point or pushed onto a
        farther one, and k's region is ``merge_area_ratio`` times as large as the largest of
        their fingertips (two tips side by side make one region of about twice the area; a
        finger that only moved keeps its area).
        """
        ratio = self.config.merge_area_ratio
        if ratio <= 0 or len(act) < 2 or not matched_t:
            return {}
        owner = {j: i for i, j in matched_t.items()}
        near = self.merge_near
        cand: dict[int, list[int]] = {}
        for b in act:
            row, k = cost[b], nearest[b]
            a = owner.get(k)
            j = matched_t.get(b)
            if a is None or a == b or row[k] > near:
                continue
            if j is not None and row[j] <= row[k]:
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

    def _merged(self, t: Track, pos: list[XY], used: set[int]) -> bool:
        """Is a point matched this frame within a finger width of this (unmatched) track?"""
        near = self.merge_near
        tx, ty = t.pos
        for j in used:
            dx, dy = pos[j][0] - tx, pos[j][1] - ty
            if math.sqrt(dx * dx + dy * dy) <= near:
                return True
        return False

    def _activate(self, t: Track) -> None:
        t.active = True
        t.id = self.next_id
        self.next_id += 1
        if t.prior:
            # the pending points the path filter is given before the down frame's: the last
            # ones in a row within land_prior_mm of it (a finger that slid in gives none)
            scale = self.scale_mm_per_px or 1.0
            r_px = self.config.land_prior_mm / scale
            x0, y0 = t.report_px
            k = len(t.prior)
            while k > 0 and math.hypot(t.prior[k - 1][0] - x0, t.prior[k - 1][1] - y0) <= r_px:
                k -= 1
            del t.prior[:k]

    def end_all(self) -> list[TrackUpdate]:
        """End every active contact (``up``), e.g. at the end of a stream or on a surface reset."""
        out = [TrackUpdate(t, "up", False) for t in self.tracks if t.active]
        self.tracks = []
        return out
