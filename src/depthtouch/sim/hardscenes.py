"""Scenes of the hard suite: the situations where the unseen recordings of issue 13 failed.

They add to :mod:`depthtouch.sim.scenes` (whose scenes stay as they are: the default suite is a
regression reference) and draw more per seed, so that different seeds are different rooms:

- the arm comes from **any side**: on a surface seen head-on any direction, on an oblique one
  within 75 deg of the side away from the camera (beyond that the camera sees the back of the
  hand and no fingertip), and a left or a right hand;
- before every tap the fingertip **hovers 5-20 mm** up for 0.2-0.6 s, descends at a speed
  drawn per tap, rests, lifts to a hover again and leaves;
- ``rest``: a forearm and palm **lying on the surface** while the other hand taps next to them;
- ``handled``: a hand **carries a book in**, puts it down, taps beside it, takes it away;
- ``fastdrags``: strokes at **300-900 mm/s**; ``strokes``: slower ones (curved surfaces);
- ``warmup``: the depth **drifts 0.3-0.5 mm/s** (either way) during taps and a held touch;
- ``stillholds``: fingers held still 2.5-3.5 s (the jitter of a still finger);
- ``hovergroup``: three fingers hover 5-20 mm, then land one or two at a time.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .geometry import Box, Capsule, Primitive
from .hand import body_capsule, lateral_forward_st
from .scenes import (
    EMPTY_S,
    LABEL_OBJECT,
    UP_MM,
    HandTrack,
    Prop,
    SceneContext,
    Script,
    Track,
)

LABEL_REST_HAND = 104  # a forearm and palm lying on the surface (not a touch)


def free_yaw(ctx: SceneContext) -> float:
    """The arm's direction (deg): any on a surface seen head-on, else within 75 deg of the side
    away from the camera."""
    if ctx.base_yaw == 0.0:
        return float(ctx.rng.uniform(-180.0, 180.0))
    return ctx.base_yaw + float(ctx.rng.uniform(-75.0, 75.0))


def _side(ctx: SceneContext) -> int:
    return 1 if ctx.rng.random() < 0.7 else -1


def approach_tap(tr: Track, rng: np.random.Generator, st: np.ndarray,
                 fingers: tuple[str, ...] = ()) -> Track:
    """Move over ``st``, hover 5-20 mm, descend, rest 0.3-0.6 s, lift to a hover, go up.

    fingers: other extended fingers, kept 15-40 mm higher than the lead while it taps.
    """
    others = {f + ".gap": UP_MM for f in fingers}
    tr.to(0.3, s=float(st[0]), t=float(st[1]), gap=UP_MM, **others)
    hover = float(rng.uniform(5.0, 20.0))
    up = {f + ".gap": hover + float(rng.uniform(15.0, 40.0)) for f in fingers}
    tr.to(float(rng.uniform(0.15, 0.3)), gap=hover, **up).hold(float(rng.uniform(0.2, 0.6)))
    tr.to(float(rng.uniform(0.06, 0.2)), gap=0.0).hold(float(rng.uniform(0.3, 0.6)))
    tr.to(float(rng.uniform(0.06, 0.2)), gap=float(rng.uniform(5.0, 20.0)))
    tr.hold(float(rng.uniform(0.1, 0.4)))
    return tr.to(0.2, gap=UP_MM, **others)


def _pitch(ctx: SceneContext) -> float:
    return ctx.pitch(25.0, 65.0)


def _far_from(ctx: SceneContext, centre: np.ndarray, lo_mm: float, hi_mm: float,
              avoid: Callable[[np.ndarray], bool] | None = None) -> np.ndarray:
    """A visible spot lo-hi mm from ``centre`` (and not ``avoid``-ed); any spot if none found."""
    for _ in range(300):
        st = ctx.spot(0.12, 0.88)
        d = float(np.linalg.norm(st - centre))
        if lo_mm <= d <= hi_mm and (avoid is None or not avoid(st)):
            return st
    return ctx.spot()


def scene_approach(ctx: SceneContext) -> Script:
    rng = ctx.rng
    yaw, pitch = free_yaw(ctx), _pitch(ctx)
    spots = [ctx.spot(0.2, 0.8) for _ in range(4)]
    tr = ctx.enter(spots[0], yaw, pitch, EMPTY_S)
    for st in spots:
        approach_tap(tr, rng, st)
    ctx.leave(tr)
    return Script(tr.end_s + 0.3, hands=[HandTrack(ctx.hand(_side(ctx)), ("index",), tr)])


def _resting_hand(ctx: SceneContext, palm_st: np.ndarray, yaw: float, t_in: float,
                  t_out: float) -> Prop:
    """A forearm and a palm (fingers curled) lying on the surface, lowered from 80 mm in 0.6 s
    at ``t_in`` and raised again from ``t_out``."""
    rng = ctx.rng
    lat, fwd = lateral_forward_st(yaw, 1)
    r_arm = float(rng.uniform(25.0, 35.0))
    r_palm = float(rng.uniform(11.0, 15.0))
    gap = float(rng.uniform(0.0, 2.0))
    s = ctx.surface
    parts: list[tuple[np.ndarray, np.ndarray, float]] = [
        (palm_st - 60 * fwd, palm_st - 340 * fwd, r_arm),  # forearm, wrist to elbow
        (palm_st - 70 * fwd, palm_st - 20 * fwd, r_arm * 0.8),  # wrist
        (palm_st + 45 * fwd - 30 * lat, palm_st + 45 * fwd + 30 * lat, 10.0),  # curled fingers
    ]
    parts += [(palm_st - 45 * fwd + k * lat, palm_st + 35 * fwd + k * lat, r_palm)
              for k in (-20.0, 0.0, 20.0)]
    elbow = palm_st - 340 * fwd

    def build(t: float) -> list[Primitive]:
        if not (t_in <= t <= t_out + 0.6):
            return []
        drop = 80.0 * max(0.0, 1.0 - (t - t_in) / 0.6, (t - t_out) / 0.6)
        out: list[Primitive] = []
        for a_st, b_st, r in parts:
            pa, pb = s.point(np.stack([a_st, b_st]))
            na, nb = s.normal(np.stack([a_st, b_st]))
            out.append(Capsule(pa + (r + gap + drop) * na, pb + (r + gap + drop) * nb, r,
                               LABEL_REST_HAND))
        # the upper arm rises 45 deg from the elbow, out of view
        pe, ne = s.point(elbow[None])[0], s.normal(elbow[None])[0]
        de = s.point((elbow - fwd)[None])[0] - pe
        e = pe + (1.2 * r_arm + gap + drop) * ne
        up = de / np.linalg.norm(de) * math.cos(math.radians(45.0)) + \
            ne * math.sin(math.radians(45.0))
        out.append(Capsule(e, e + 320.0 * up, r_arm * 1.2, LABEL_REST_HAND))
        if ctx.body:
            out.append(body_capsule(e + 320.0 * up, de / np.linalg.norm(de), LABEL_REST_HAND))
        return out

    return Prop(build)


def scene_rest(ctx: SceneContext) -> Script:
    rng = ctx.rng
    palm = ctx.spot(0.35, 0.65)
    rest_yaw = free_yaw(ctx)
    _, fwd = lateral_forward_st(rest_yaw, 1)
    t_in = EMPTY_S + 0.2

    def on_arm(st: np.ndarray) -> bool:
        # within 70 mm of the forearm's axis behind the palm, or of the palm itself
        rel = st - palm
        along = float(rel @ fwd)
        across = float(np.linalg.norm(rel - along * fwd))
        return (along < 60.0 and across < 70.0) or float(np.linalg.norm(rel)) < 75.0

    spots = [_far_from(ctx, palm, 75.0, 170.0, on_arm) for _ in range(4)]
    tr = ctx.enter(spots[0], free_yaw(ctx), _pitch(ctx), t_in + 0.8)
    for st in spots:
        approach_tap(tr, rng, st)
    ctx.leave(tr)
    t_out = tr.end_s - 0.3
    prop = _resting_hand(ctx, palm, rest_yaw, t_in, t_out)
    return Script(t_out + 0.9, hands=[HandTrack(ctx.hand(_side(ctx)), ("index",), tr)],
                  props=[prop], events=[("arm_rest_start", t_in + 0.6),
                                        ("arm_rest_end", t_out)])


def scene_handled(ctx: SceneContext) -> Script:
    """A hand carries a box in (fingertip at its side), puts it down, taps 4 times beside it,
    then lifts it 150 mm and carries it out of view."""
    rng = ctx.rng
    s = ctx.surface
    size = np.array([rng.uniform(120, 180), rng.uniform(60, 90), rng.uniform(15, 40)])
    centre = ctx.spot(0.35, 0.65)
    yaw, pitch = free_yaw(ctx), ctx.pitch(40.0, 65.0)
    lat, fwd = lateral_forward_st(yaw, 1)
    ang = math.atan2(float(fwd[1]), float(fwd[0]))  # the box's long side across the hand
    e1_st = np.array([math.cos(ang), math.sin(ang)])
    grab = centre - e1_st * (size[0] / 2 + 12.0)  # the fingertip just outside the near end
    off = grab - centre
    hold_gap = float(size[2]) * 0.5
    t0 = EMPTY_S
    tr = ctx.enter(grab, yaw, pitch, t0)
    t_carry_in = t0
    tr.to(0.6, gap=hold_gap)
    t_placed = tr.end_s
    tr.hold(0.3).to(0.3, gap=UP_MM)

    def near_box(st: np.ndarray) -> bool:
        rel = st - centre
        return abs(float(rel @ e1_st)) < size[0] / 2 + 10 and \
            abs(float(rel @ np.array([-e1_st[1], e1_st[0]]))) < size[1] / 2 + 10

    for _ in range(4):
        st = _far_from(ctx, centre, size[0] / 2 + 15.0, size[0] / 2 + 70.0, near_box)
        approach_tap(tr, rng, st)
    tr.to(0.4, s=float(grab[0]), t=float(grab[1]), gap=UP_MM).to(0.3, gap=hold_gap).hold(0.3)
    t_pick = tr.end_s
    tr.to(0.5, gap=hold_gap + 150.0)
    ctx.leave(tr)

    def build(t: float) -> list[Primitive]:
        if t < t_carry_in or t > tr.end_s:
            return []
        if t_placed <= t <= t_pick:
            st, lift = centre, 0.0
        else:
            c = tr.at(t)
            st = np.array([c["s"], c["t"]]) - off
            lift = max(0.0, c["gap"] - hold_gap)
        n = s.normal(st[None])[0]
        e1 = math.cos(ang) * s.u + math.sin(ang) * s.tangent_t(st[None])[0]
        axes = np.stack([e1, np.cross(n, e1), n], 1)
        c3 = s.point(st[None])[0] + (size[2] / 2 + lift) * n
        return [Box(c3, axes, size / 2, LABEL_OBJECT)]

    return Script(tr.end_s + 0.3, hands=[HandTrack(ctx.hand(_side(ctx)), ("index",), tr)],
                  props=[Prop(build)],
                  events=[("object_placed", t_placed), ("object_removed", t_pick)])


def _strokes(ctx: SceneContext, n: int, v_lo: float, v_hi: float, zigzag: bool) -> Script:
    rng = ctx.rng
    yaw, pitch = free_yaw(ctx), _pitch(ctx)
    size = min(0.35 * ctx.mm_per_frac(), 300.0)
    tr: Track | None = None
    for k in range(n):
        centre = ctx.spot(0.35, 0.65)
        a = rng.uniform(0, 2 * math.pi)
        d = np.array([math.cos(a), math.sin(a)]) * size / 2
        if zigzag and k % 2 == 1:
            nrm = np.array([-d[1], d[0]]) * 0.4
            pts = centre + np.stack([-d, -d / 3 + nrm, d / 3 - nrm, d])
        else:
            pts = centre + np.stack([-d, d])
        speed = float(rng.uniform(v_lo, v_hi))
        if tr is None:
            tr = ctx.enter(pts[0], yaw, pitch, EMPTY_S)
        tr.to(0.3, s=float(pts[0, 0]), t=float(pts[0, 1]), gap=UP_MM)
        tr.to(0.2, gap=float(rng.uniform(5.0, 20.0))).hold(float(rng.uniform(0.1, 0.4)))
        tr.to(float(rng.uniform(0.06, 0.15)), gap=0.0).hold(0.1)
        for p, q in zip(pts[:-1], pts[1:], strict=True):
            tr.to(float(np.linalg.norm(q - p)) / speed, s=float(q[0]), t=float(q[1]))
        tr.hold(0.1).to(0.15, gap=UP_MM)
    assert tr is not None
    ctx.leave(tr)
    return Script(tr.end_s + 0.3, hands=[HandTrack(ctx.hand(_side(ctx)), ("index",), tr)])


def scene_fastdrags(ctx: SceneContext) -> Script:
    return _strokes(ctx, 4, 300.0, 900.0, zigzag=True)


def scene_strokes(ctx: SceneContext) -> Script:
    return _strokes(ctx, 4, 100.0, 400.0, zigzag=False)


def scene_warmup(ctx: SceneContext) -> Script:
    rng = ctx.rng
    tr = ctx.enter(ctx.spot(), free_yaw(ctx), _pitch(ctx), EMPTY_S + 0.3)
    for st in [ctx.spot(0.2, 0.8) for _ in range(3)]:
        approach_tap(tr, rng, st)
    st = ctx.spot()
    tr.to(0.3, s=float(st[0]), t=float(st[1]), gap=UP_MM)
    tr.to(0.25, gap=float(rng.uniform(5.0, 20.0))).to(0.12, gap=0.0)
    tr.hold(float(rng.uniform(1.5, 2.5))).to(0.15, gap=UP_MM)
    ctx.leave(tr)
    rate = float(rng.uniform(0.3, 0.5)) * (1.0 if rng.random() < 0.5 else -1.0)

    def drift(t: float) -> float:
        return rate * max(0.0, t - EMPTY_S)

    return Script(tr.end_s + 0.3, hands=[HandTrack(ctx.hand(_side(ctx)), ("index",), tr)],
                  events=[("drift_start", EMPTY_S)], drift=drift)


def scene_stillholds(ctx: SceneContext) -> Script:
    rng = ctx.rng
    tr = ctx.enter(ctx.spot(), free_yaw(ctx), _pitch(ctx), EMPTY_S)
    for _ in range(2):
        st = ctx.spot(0.25, 0.75)
        tr.to(0.35, s=float(st[0]), t=float(st[1]), gap=UP_MM)
        tr.to(0.25, gap=float(rng.uniform(5.0, 20.0))).hold(0.2).to(0.12, gap=0.0)
        tr.hold(float(rng.uniform(2.5, 3.5))).to(0.15, gap=UP_MM)
    ctx.leave(tr)
    return Script(tr.end_s + 0.3, hands=[HandTrack(ctx.hand(_side(ctx)), ("index",), tr)])


def scene_hovergroup(ctx: SceneContext) -> Script:
    """Index, middle and ring hover 5-20 mm for ~1.2 s; the index lands alone, then middle and
    ring together; between, everything hovers again."""
    from .scenes import _spread

    rng = ctx.rng
    shape = ctx.hand(_side(ctx))
    fingers = ("index", "middle", "ring")
    offs = _spread(shape, fingers)
    centre = ctx.spot(0.35, 0.65)
    tr = ctx.enter(centre, free_yaw(ctx), ctx.pitch(35.0, 60.0), EMPTY_S, offs)

    def hover() -> dict[str, float]:
        return {"gap": float(rng.uniform(5.0, 20.0)),
                **{f + ".gap": float(rng.uniform(5.0, 20.0)) for f in fingers[1:]}}

    tr.to(0.3, **hover()).hold(float(rng.uniform(0.8, 1.4)))
    tr.to(0.15, gap=0.0).hold(float(rng.uniform(0.4, 0.7)))
    tr.to(0.15, **hover()).hold(float(rng.uniform(0.5, 1.0)))
    h = hover()
    h.update({"middle.gap": 0.0, "ring.gap": 0.0})
    tr.to(0.15, **h).hold(float(rng.uniform(0.4, 0.7)))
    tr.to(0.15, **hover()).hold(0.4)
    tr.to(0.2, gap=UP_MM, **{f + ".gap": UP_MM for f in fingers[1:]})
    ctx.leave(tr)
    return Script(tr.end_s + 0.3, hands=[HandTrack(shape, fingers, tr)])


HARD_SCENE_BUILDERS: dict[str, Callable[[SceneContext], Script]] = {
    "approach": scene_approach,
    "rest": scene_rest,
    "handled": scene_handled,
    "fastdrags": scene_fastdrags,
    "strokes": scene_strokes,
    "warmup": scene_warmup,
    "stillholds": scene_stillholds,
    "hovergroup": scene_hovergroup,
}

HARD_SCENES: tuple[str, ...] = tuple(HARD_SCENE_BUILDERS)
