"""Lift test: a contact whose finger's core rises above the same contact's own earlier frames
has lifted, even where its measured tip height has not. And the other side: how long a contact
whose point vanished may stay down (:func:`held_grace`).

At ToF range the measured tip height of a finger hovering 15 mm up is as low as a touching
tip's (the lowest pixels of the tip cap are the mixed pixels of its outline, between finger and
surface), so the height hysteresis alone keeps a touch down 15-25 frames after the finger
lifts, and two taps with a low hover between them become one touch (docs/accuracy.md section 7,
session 19). The height of the finger's core near the tip (``TouchPoints.core_height_mm``)
overlaps between contact and hover across contacts and placements, but within one contact it
rises when the finger lifts. So each track keeps the history of its core height: the median of
its last ``RECENT`` values (its level), against ``BASE_PCT`` percentile of those levels over its
last ``HISTORY`` frames (the track's own level), from its ``MINHIST``-th known value; the
tracker reads a rise of more than ``TrackingConfig.lift_core_mm`` as a lift.

Chosen on the tune sides of the hard, hard-extra and hard-fresh2 suites (docs/accuracy.md
section 7, session 20). With the 20th percentile as the track's level, or without the wait for
10 values, the test also ended touches that had gone down while the finger hovered (at ToF 2 m
a finger 60 mm up can be down) just before the finger landed, and so turned one touch into a
false tap and a touch.

Each history also keeps its core's noise (:meth:`CoreHistory.noise`: the median step between
consecutive known values); with ``TrackingConfig.lift_noise_k`` above 0, a contact that is down
must rise by that many times its noise besides (a steep finger's core flickers between the tip
and the finger behind it). Measured in session 45 and off by default.
"""

from __future__ import annotations

import math
from bisect import bisect_left, insort
from collections import deque
from dataclasses import dataclass, field

from ..config import TrackingConfig

# the median of this many last core heights (one frame's is noisy)
RECENT = 3
# the track's own level: this percentile of those medians
BASE_PCT = 50.0
# ... over this many of its last frames (a touch held for minutes keeps a bounded history)
HISTORY = 300
# no rise is read before this many known values (the level of a new track is not yet known)
MINHIST = 10


@dataclass(slots=True)
class RankedWindow:
    """The last HISTORY values pushed, in order and sorted, for their percentiles."""

    order: deque[float] = field(default_factory=lambda: deque(maxlen=HISTORY))
    ranked: list[float] = field(default_factory=list)  # ``order`` sorted

    def push(self, v: float) -> None:
        if len(self.order) == HISTORY:
            del self.ranked[bisect_left(self.ranked, self.order[0])]
        self.order.append(v)
        insort(self.ranked, v)

    def pct(self, pct: float) -> float:
        """``pct`` percentile of the values (linear, as ``np.percentile``); NaN when none."""
        r = self.ranked
        if not r:
            return math.nan
        pos = pct / 100.0 * (len(r) - 1)
        lo = int(pos)
        hi = min(lo + 1, len(r) - 1)
        return r[lo] + (pos - lo) * (r[hi] - r[lo])

    def __len__(self) -> int:
        return len(self.order)

    def clear(self) -> None:
        self.order.clear()
        self.ranked.clear()


@dataclass(slots=True)
class CoreHistory:
    """The core heights of one track, frame after frame (``update``; ``reset`` to forget)."""

    recent: deque[float] = field(default_factory=lambda: deque(maxlen=RECENT))
    levels: RankedWindow = field(default_factory=RankedWindow)  # the medians of ``recent``
    keep_noise: bool = True  # keep the steps for :meth:`noise` (off: no cost per frame)
    last: float = math.nan  # the last known core height
    steps: RankedWindow = field(default_factory=RankedWindow)  # |change| between known values

    def update(self, core_mm: float) -> float:
        """Take one frame's core height (mm; NaN: unknown, ignored) and return how far the
        recent level lies above the track's base (mm; NaN when this frame's is unknown and
        before MINHIST known values)."""
        if not math.isfinite(core_mm):
            return math.nan
        self.recent.append(core_mm)
        if self.keep_noise:
            if math.isfinite(self.last):
                self.steps.push(abs(core_mm - self.last))
            self.last = core_mm
        r = self.recent
        # the median (numpy's: the mean of the middle two of an even count)
        level = sorted(r)[len(r) // 2] if len(r) != 2 else 0.5 * (r[0] + r[1])
        self.levels.push(level)
        if len(self.levels) < MINHIST:
            return math.nan
        return level - self.base()

    def base(self) -> float:
        """The track's own level (mm): BASE_PCT percentile of its recent levels (linear, as
        ``np.percentile``); NaN when none is known."""
        return self.levels.pct(BASE_PCT)

    def noise(self) -> float:
        """How far the track's core jumps from one known value to the next (mm): the median of
        those steps over its last HISTORY values; 0 before two are known (always 0 without
        ``keep_noise``)."""
        return self.steps.pct(50.0) if len(self.steps) else 0.0

    def reset(self) -> None:
        self.recent.clear()
        self.levels.clear()
        self.last = math.nan
        self.steps.clear()


def held_grace(cfg: TrackingConfig, gaps: int, vel: tuple[float, float], at: tuple[float, float],
               points: list[tuple[float, float]], low: list[bool]) -> int:
    """Frames a contact down whose point is missing this frame may stay missing before ``up``
    (pure): ``cfg.up_frames``, or ``cfg.up_held_frames`` for a held contact whose point
    flickers (TrackingConfig.up_held_frames): its point came back after missing frames
    ``gaps`` times (at least ``held_gaps``), its smoothed velocity ``vel`` (mm per frame) is
    under ``held_step_mm``, and no raised point (``low`` False: too high to continue a
    contact) of this frame's ``points`` (mm) lies within ``held_near_mm`` of it (``at``, mm):
    a finger lifting shows there. The caller applies it only where mm are known."""
    if (cfg.up_held_frames <= cfg.up_frames or gaps < cfg.held_gaps
            or math.hypot(*vel) > cfg.held_step_mm):
        return cfg.up_frames
    near = cfg.held_near_mm
    x, y = at
    for (px, py), ok in zip(points, low, strict=True):
        if not ok and abs(px - x) <= near and abs(py - y) <= near:
            return cfg.up_frames  # its finger is there, above the surface: lifted
    return cfg.up_held_frames
