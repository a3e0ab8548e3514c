"""Matching touch points to tracks: the gated distance of every track to every point, and the
optimal assignment on it (``scipy.optimize.linear_sum_assignment``, skipped when every track's
nearest point is its own). Pure functions; :class:`~depthtouch.tracking.tracker.Tracker` calls
them once or twice a frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from scipy.optimize import linear_sum_assignment

from .evidence import XY

if TYPE_CHECKING:  # pragma: no cover
    from .track import Track

#: the cost of a pair that may not be matched
BIG = 1e9
#: cost matrices up to this many entries are built with floats, larger ones with arrays (the
#: break-even on one core: about 10 tracks x 10 points when they are close together)
PY_COST_MAX = 100


def nearest_index(row: list[float]) -> int:
    """Index of the smallest entry, the first of equal ones (as ``np.argmin``)."""
    return row.index(min(row))


def assign(
    cost: list[list[float]], rows: list[int], cols: list[int], nearest: list[int]
) -> dict[int, int]:
    """Optimal assignment of tracks ``rows`` to points ``cols`` (increasing) on ``cost`` (pairs
    < BIG); ``nearest``: :func:`nearest_index` of every row of ``cost``."""
    if not rows or not cols:
        return {}
    if len(cols) == len(cost[0]):  # all the points
        sub = [cost[r] for r in rows]
        best = [nearest[r] for r in rows]
    else:
        sub = [[cost[r][c] for c in cols] for r in rows]
        best = [nearest_index(row) for row in sub]
    if len(set(best)) == len(best):
        # every track's nearest point is its own: that is the optimum (no assignment can cost
        # less than each track's own minimum), found without the solver
        return {r: cols[b] for r, b, row in zip(rows, best, sub, strict=True) if row[b] < BIG}
    ri, ci = linear_sum_assignment(np.array(sub))
    return {rows[a]: cols[b] for a, b in zip(ri.tolist(), ci.tolist(), strict=True)
            if sub[a][b] < BIG}


def gated_cost(tracks: Sequence[Track], pos: list[XY], ok_cont: list[bool], ok_new: list[bool],
               gate: float, gate_down: float) -> list[list[float]]:
    """Gated distance of each track to each point (BIG where it may not take the point):
    ``gate`` for a pending track, ``gate_down`` for a contact that is down (pos units).

    The distance is to where the contact should be, or to where it was, whichever is nearer:
    a sharp turn must not be lost to a prediction that overshoots. A contact down may take a
    point below touch_off_mm, a pending one only below touch_on_mm.
    """
    if len(tracks) * len(pos) > PY_COST_MAX:
        return gated_cost_array(tracks, pos, ok_cont, ok_new, gate, gate_down)
    gates = (gate, gate_down)
    sqrt = math.sqrt
    cost: list[list[float]] = []
    for t in tracks:
        g = gates[t.active]
        # a point farther than this on one axis, from both the prediction and the last
        # position, is beyond the gate: the margin keeps that exact through the rounding
        far = g * (1.0 + 1e-6)
        lx, ly = t.pos
        k = t.since
        px, py = lx + t.vel[0] * k, ly + t.vel[1] * k
        row: list[float] = []
        for (x, y), ok in zip(pos, ok_cont if t.active else ok_new, strict=True):
            ax, bx = px - x, lx - x
            ay, by = py - y, ly - y
            if (not ok or (ax > far and bx > far) or (ax < -far and bx < -far)
                    or (ay > far and by > far) or (ay < -far and by < -far)):
                row.append(BIG)
                continue
            a, b = ax * ax + ay * ay, bx * bx + by * by
            d = sqrt(a if a <= b else b)
            row.append(d if d <= g else BIG)
        cost.append(row)
    return cost


def gated_cost_array(tracks: Sequence[Track], pos: list[XY], ok_cont: list[bool],
                     ok_new: list[bool], gate: float, gate_down: float) -> list[list[float]]:
    """:func:`gated_cost` in array operations: the same numbers, faster for many touches."""
    last = np.array([t.pos for t in tracks])
    pred = last + np.array([(t.vel[0] * t.since, t.vel[1] * t.since)
                            for t in tracks])
    p = np.array(pos)
    dp, dl = pred[:, None, :] - p[None, :, :], last[:, None, :] - p[None, :, :]
    dist = np.sqrt(np.minimum((dp * dp).sum(axis=2), (dl * dl).sum(axis=2)))
    is_active = np.array([t.active for t in tracks])
    allowed = np.where(is_active[:, None], np.array(ok_cont)[None, :], np.array(ok_new)[None, :])
    g = np.where(is_active, gate_down, gate)[:, None]
    cost: list[list[float]] = np.where(allowed & (dist <= g), dist, BIG).tolist()
    return cost
