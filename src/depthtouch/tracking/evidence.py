"""Evidence for a new contact: how much one frame of each touch point counts toward ``down``
(see :class:`depthtouch.config.TrackingConfig` and :mod:`depthtouch.tracking.tracker`).

Pure functions of one frame's points: the size of the region, its attachment to the hand, the
height of that attachment, the level heights behind it, whether it lies behind another tip on
that tip's finger, and whether it looks like the top of a finger standing almost upright.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..config import TrackingConfig
from ..types import TouchPoints

XY = tuple[float, float]
# a point this far behind a fingertip on its axis is still on that finger (a finger's length)
_BEHIND_MAX_MM = 150.0
# Tl within this much of its floor: quiet depth (TrackingConfig.weak_quiet_evidence)
_QUIET_MM = 1.0


def behind(xy: list[XY], hand: list[list[float]], tips: list[int], scale: float,
            lat_mm: float, min_mm: float) -> list[int]:
    """The points that lie on the finger of one of the ``tips``, behind it: within ``lat_mm``
    of its axis (the line from its hand to it) and ``min_mm`` to ``_BEHIND_MAX_MM`` back
    toward its hand. (``xy``, ``hand``: image px; ``scale``: mm per px.)"""
    axes = []
    for q in tips:
        (qx, qy), (hx, hy) = xy[q], hand[q]
        nn = math.hypot(qx - hx, qy - hy)
        if nn > 1e-6:
            axes.append((q, qx, qy, (qx - hx) / nn, (qy - hy) / nn))
    out = []
    for j, (px, py) in enumerate(xy):
        for q, qx, qy, ux, uy in axes:
            if q == j:
                continue
            dx, dy = (px - qx) * scale, (py - qy) * scale
            along = dx * ux + dy * uy
            if -_BEHIND_MAX_MM < along < -min_mm and abs(dx * uy - dy * ux) < lat_mm:
                out.append(j)
                break
    return out


def steep_tips(points: TouchPoints, area_px: list[int], scale: float | None,
           cfg: TrackingConfig) -> list[bool]:
    """Which points look like the top of a steep finger's tip (TrackingConfig.steep_*): the
    area, the height of the top, the hand right behind it at the height of a finger rising to
    its knuckles. All False without a scale or the attachment's height, or with
    steep_evidence 0."""
    n = len(area_px)
    ah, hand = points.attach_height_mm, points.hand_xy_px
    if scale is None or cfg.steep_evidence <= 0 or ah is None or hand is None:
        return [False] * n
    a0, a1 = cfg.steep_area_min_mm2 / (scale * scale), cfg.steep_area_max_mm2 / (scale * scale)
    near = cfg.steep_hand_mm / scale
    out = []
    for (x, y), (hx, hy), a, h, st in zip(points.xy_px.tolist(), hand.tolist(), area_px,
                                          points.height_mm.tolist(), ah.tolist(), strict=True):
        out.append(a0 <= a <= a1 and cfg.steep_top_min_mm <= h <= cfg.steep_top_max_mm
                   and cfg.steep_step_min_mm < st <= cfg.steep_step_max_mm
                   and math.hypot(x - hx, y - hy) < near)
    return out


def may_start(height_mm: list[float], steep: list[bool], touch_on_mm: float) -> list[bool]:
    """Which points may start a new contact: their tip within ``touch_on_mm`` of the surface,
    or the top of a steep finger (:func:`steep_tips`); an unknown height (NaN) never does."""
    return [h <= touch_on_mm or s for h, s in zip(height_mm, steep, strict=True)]


def enclosure_asks(points: TouchPoints, config: TrackingConfig) -> np.ndarray | None:
    """The points the enclosure test may refuse for their share and tip height (bool (N,);
    ``enclosed_share_max``, ``enclosed_height_min_mm``; NaN compares False); None when the
    test is off or no share is known. The pipeline measures the recent change only for these
    (:meth:`depthtouch.pipeline.Pipeline.process`)."""
    share = points.attach_share
    if share is None or config.enclosed_share_max >= 1.0:
        return None
    return ((share > _ask_share(config))
            & (points.height_mm >= config.enclosed_height_min_mm))


def _ask_share(config: TrackingConfig) -> float:
    """The share above which the enclosure test asks about a point: ``enclosed_share_max``,
    or ``enclosed_low_share_min`` below it where the low band is on (its change limit and the
    change condition both set)."""
    if config.enclosed_low_change_max_mm > 0.0 and config.enclosed_change_max_mm > 0.0:
        return min(config.enclosed_share_max, config.enclosed_low_share_min)
    return config.enclosed_share_max


def refused_out(weights: list[float], refused: list[bool] | None) -> list[float]:
    """``weights`` with the enclosure test's refusals (from :func:`evidence`) set to 0."""
    if refused is None:
        return weights
    return [0.0 if r else v for v, r in zip(weights, refused, strict=True)]


def evidence(points: TouchPoints, xy: list[XY], area_px: list[int], ok_new: list[bool],
             steep: list[bool], scale: float | None,
             config: TrackingConfig) -> tuple[list[float], list[bool] | None]:
    """How much one frame of each point counts toward ``down`` (see TrackingConfig), before
    the enclosure test, and the points the enclosure test refuses (None when it is off).
    The enclosure test is a test of a touch's start (a touch starts with a finger arriving);
    the tracker applies it to pending contacts, and to contacts that are down only unless
    ``enclosed_pending_only``.

    A region of a fingertip's size (at least ``tip_area_min_mm2`` and ``tip_area_min_px``,
    at most ``tip_area_max_mm2`` or ``tip_area_max_px``) counts a whole frame; a smaller
    one (a speck of noise at a finger's edge, a tip only grazing the band) or a larger one
    (a hovering finger or a forearm's edge lying in the band) counts ``weak_evidence``
    (``weak_quiet_evidence`` where Tl around it is within 1 mm of its floor), so it must
    persist for more frames before it is believed. A region attached to its hand along
    more than ``attach_max_mm`` (the broad edge of a forearm or a palm lying in the band, not
    a fingertip at the end of a finger) counts nothing (``attach_low_evidence`` if it rests
    within ``attach_low_mm`` of the surface: a finger of a hand held low), and so does one
    whose hand surrounds it (``enclosed_share_max``: a patch of a resting palm or forearm
    whose top flickers in and out of the band; with ``enclosed_change_max_mm``, only where
    nothing around it moved in the last seconds, or where it lies low and level behind:
    ``enclosed_flat_*``, the flank of a forearm just laid down; with ``enclosed_low_*``, also
    one whose share lies a little lower, where its surroundings changed even less), and so
    does one whose attached hand pixels lie higher than ``step_max_mm`` (a finger rises from
    the band gradually; mixed pixels at the side of a raised hand jump), and so does one with level
    heights behind it (``flat_max_mm``: the top of a held book, the flank of a forearm; a
    finger rises and is narrow), and so does a point on the axis of another point low
    enough to go down, behind it (``behind_lat_mm``: a finger has one tip; what lies behind
    it on its axis is the finger's flank). The top of a steep finger (``steep``) counts
    ``steep_evidence`` instead of the size test's weight and is exempt from the enclosure,
    step and flat tests. Without a scale (no intrinsics: ``scale`` None) every frame counts whole.
    """
    n = len(area_px)
    if scale is None:
        return [1.0] * n, None
    attach_px, attach_height_mm = points.attach_px, points.attach_height_mm
    back_spread_mm = points.back_spread_mm
    weak, steep_w = config.weak_evidence, config.steep_evidence
    if weak >= 1.0:
        w = [1.0] * n
    else:
        px_mm2 = scale * scale
        lo = max(config.tip_area_min_mm2 / px_mm2, config.tip_area_min_px)
        hi = max(config.tip_area_max_mm2 / px_mm2, config.tip_area_max_px)
        # Tl above its floor around each point; unknown counts as not quiet
        above = ([math.inf] * n if points.tl_above_floor_mm is None
                 else points.tl_above_floor_mm.tolist())
        wq = config.weak_quiet_evidence
        w = [1.0 if lo <= a <= hi else (wq if q <= _QUIET_MM else weak)
             for a, q in zip(area_px, above, strict=True)]
    if any(steep):
        w = [steep_w if s else v for v, s in zip(w, steep, strict=True)]
    # the attachment counts the hand pixels within 2 px of the region: an attachment w mm
    # long gives up to 2 (w / scale + 4) of them (the ring is 2 px deep and reaches 2 px
    # past either end)
    long_px = 2.0 * (config.attach_max_mm / scale + 4.0)
    if attach_px is not None and config.attach_max_mm > 0:
        # ... unless its touching pixel rests lower than such an edge lies (a finger whose
        # hand is held low): then it counts attach_low_evidence at most
        low, low_w = config.attach_low_mm, config.attach_low_evidence
        w = [(min(v, low_w) if h <= low else 0.0) if a > long_px else v
             for v, a, h in zip(w, attach_px.tolist(), points.height_mm.tolist(),
                                strict=True)]
    # with the change condition, a frame whose points the pipeline measured no change for
    # (recent_change_mm None: it asked about none) refuses none; no need to ask again
    asks = (None if config.enclosed_change_max_mm > 0.0 and points.recent_change_mm is None
            else enclosure_asks(points, config))
    refused: list[bool] | None = None
    if asks is not None:
        # (an unknown share, height or change, NaN, compares False: no evidence taken away)
        a_max = config.enclosed_attach_max_mm
        ah = ([math.nan] * n if attach_height_mm is None else attach_height_mm.tolist())
        c_max, low_c = config.enclosed_change_max_mm, config.enclosed_low_change_max_mm
        ch = ([math.nan] * n if points.recent_change_mm is None
              else points.recent_change_mm.tolist())
        still = [c < c_max for c in ch] if c_max > 0.0 else [True] * n
        # a point of the low band (asked about for a share of at most enclosed_share_max) is
        # refused only where its change is under the low band's limit too
        share_max = config.enclosed_share_max
        low_still = [True] * n
        if _ask_share(config) < share_max and points.attach_share is not None:
            low_still = [s > share_max or c < low_c
                         for s, c in zip(points.attach_share.tolist(), ch, strict=True)]
        # ... and, whatever moved, one lying low and level behind (a flank just laid down;
        # an unknown spread, NaN, compares False: not level)
        f_max = config.enclosed_flat_max_mm if back_spread_mm is not None else 0.0
        fa_max, fh_max = config.enclosed_flat_attach_max_mm, config.enclosed_flat_height_max_mm
        back = [math.nan] * n if back_spread_mm is None else back_spread_mm.tolist()
        refused = [q and lo and not s and ((st and not at >= a_max)
                                           or (b < f_max and not at >= fa_max
                                               and not h >= fh_max))
                   for q, lo, at, st, s, b, h in zip(asks.tolist(), low_still, ah, still, steep,
                                                     back, points.height_mm.tolist(),
                                                     strict=True)]
    step = config.step_max_mm
    if attach_height_mm is not None and step > 0:
        # (an unknown height, NaN, compares False: no evidence taken away)
        w = [0.0 if a > step and not s else v
             for v, a, s in zip(w, attach_height_mm.tolist(), steep, strict=True)]
    flat = config.flat_max_mm
    if back_spread_mm is not None and flat > 0:
        w = [0.0 if a < flat and not s else v
             for v, a, s in zip(w, back_spread_mm.tolist(), steep, strict=True)]
    lat = config.behind_lat_mm
    if lat > 0 and n > 1 and points.hand_xy_px is not None:
        tips = [j for j in range(n) if ok_new[j]]
        for j in behind(xy, points.hand_xy_px.tolist(), tips, scale,
                         lat + config.behind_lat_px * scale, config.behind_min_mm):
            w[j] = 0.0
    return w, refused


#: why a point did or did not count in full toward a new contact (:func:`point_reasons`), in
#: the order the tests are asked: the first test that took its weight away names it
REASONS = ("counted", "tip too high", "long attachment", "enclosed by its hand", "high step",
           "level behind", "behind another tip", "weak (size)")
#: the setting that turns each weight test off (at 0), in the order of :data:`REASONS`
_TESTS_OFF: tuple[tuple[str, str], ...] = (
    ("long attachment", "attach_max_mm"),
    ("high step", "step_max_mm"),
    ("level behind", "flat_max_mm"),
    ("behind another tip", "behind_lat_mm"),
)


def point_reasons(points: TouchPoints, scale: float | None, config: TrackingConfig,
                  touch_on_mm: float) -> list[str]:
    """Why each point of a frame did or did not count in full toward a new contact (one of
    :data:`REASONS`; a diagnosis for the evaluation, not on the per-frame path).

    The weights are those the tracker gives a pending contact (:func:`evidence`, after the
    enclosure test; a tip above ``touch_on_mm`` that is not a steep top cannot start one).
    A point that lost weight is named after the first of those tests that takes weight away
    from it: with every test off, the tests are turned back on in order until its weight falls.
    One that none of them lowers counts part of a frame for its size (``weak_evidence``).
    """
    from dataclasses import replace

    n = len(points)
    if n == 0:
        return []
    xy: list[XY] = list(map(tuple, points.xy_px.tolist()))
    area = points.area_px.tolist()
    steep = steep_tips(points, area, scale, config)
    ok_new = may_start(points.height_mm.tolist(), steep, touch_on_mm)
    weights, refused = evidence(points, xy, area, ok_new, steep, scale, config)
    out = []
    for j in range(n):
        if not ok_new[j]:
            out.append("tip too high")
        elif refused is not None and refused[j]:
            out.append("enclosed by its hand")
        elif weights[j] >= 1.0:
            out.append("counted")
        else:
            out.append("")
    if all(out):
        return out
    fields = [f for _, f in _TESTS_OFF]
    off: dict[str, Any] = {f: 0.0 for f in fields}
    prev, _ = evidence(points, xy, area, ok_new, steep, scale, replace(config, **off))
    for k, (name, _) in enumerate(_TESTS_OFF):
        later: dict[str, Any] = {f: 0.0 for f in fields[k + 1:]}
        w_k, _ = evidence(points, xy, area, ok_new, steep, scale, replace(config, **later))
        for j in range(n):
            if not out[j] and w_k[j] < prev[j]:
                out[j] = name
        prev = w_k
    return [r or "weak (size)" for r in out]
