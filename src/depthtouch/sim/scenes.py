"""Scene scripts: what moves where and when, as keyframed hand tracks, props and camera events.

Every scene starts with :data:`EMPTY_S` seconds of empty surface (the recording contract needs
at least one second to learn the surface). Positions are chosen in image terms (fractions of
the frame) and turned into surface coordinates (s, t) by casting a ray, so a scene works for
any camera, distance, tilt and surface. Lengths and speeds are in mm and m/s on the surface.
Random choices come from the scene's own generator, so a seed gives one exact recording.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..errors import ConfigError
from .geometry import Box, Capsule, Primitive, Sphere
from .hand import HandShape, lateral_forward_st
from .script import (  # noqa: F401  (re-exported: the scenes' vocabulary)
    EMPTY_S,
    HOVER_MAX_MM,
    UP_MM,
    HandTrack,
    Prop,
    SceneContext,
    Script,
    Track,
)


def _tap(tr: Track, rng: np.random.Generator, st: np.ndarray) -> Track:
    tr.to(0.35, s=float(st[0]), t=float(st[1]), gap=UP_MM)
    tr.to(float(rng.uniform(0.12, 0.2)), gap=0.0)
    tr.hold(float(rng.uniform(0.3, 0.6)))
    return tr.to(float(rng.uniform(0.12, 0.2)), gap=UP_MM)


def _pitch(ctx: SceneContext) -> float:
    return ctx.pitch(20.0, 70.0)


def _yaw(ctx: SceneContext, centre: float = 0.0) -> float:
    """A hand direction within 30 deg of ``centre`` (relative to the scene's base yaw)."""
    return ctx.base_yaw + centre + float(ctx.rng.uniform(-30.0, 30.0))


def scene_taps(ctx: SceneContext) -> Script:
    rng = ctx.rng
    yaw, pitch = _yaw(ctx), _pitch(ctx)
    spots = [ctx.spot(0.2, 0.8) for _ in range(5)]
    tr = ctx.enter(spots[0], yaw, pitch, EMPTY_S)
    for st in spots:
        _tap(tr, rng, st)
    ctx.leave(tr)
    return Script(tr.end_s + 0.3, hands=[HandTrack(ctx.hand(), ("index",), tr)])


def _path(kind: str, rng: np.random.Generator, size_mm: float) -> np.ndarray:
    """(N, 2) path in mm around (0, 0): a line, a circle or a sharp zig-zag."""
    if kind == "line":
        a = rng.uniform(0, 2 * math.pi)
        d = np.array([math.cos(a), math.sin(a)]) * size_mm / 2
        return np.stack([-d, d])
    if kind == "circle":
        a0 = rng.uniform(0, 2 * math.pi)
        ang = a0 + np.linspace(0, 2 * math.pi, 41)
        return np.stack([np.cos(ang), np.sin(ang)], 1) * size_mm / 2
    xs = np.linspace(-size_mm / 2, size_mm / 2, 6)
    ys = np.array([-1, 1, -1, 1, -1, 1]) * size_mm / 5
    return np.stack([xs, ys], 1)


def scene_drags(ctx: SceneContext) -> Script:
    rng = ctx.rng
    yaw, pitch = _yaw(ctx), _pitch(ctx)
    size = min(0.3 * ctx.mm_per_frac(), 280.0)
    kinds = [("line", 0.05, 0.3), ("circle", 0.2, 0.5), ("zigzag", 0.3, 1.0), ("line", 0.5, 1.0)]
    tr: Track | None = None
    for kind, vlo, vhi in kinds:
        centre = ctx.spot(0.35, 0.65)
        pts = centre + _path(kind, rng, size)
        speed_mm_s = float(rng.uniform(vlo, vhi)) * 1000.0
        if tr is None:
            tr = ctx.enter(pts[0], yaw, pitch, EMPTY_S)
        tr.to(0.35, s=float(pts[0, 0]), t=float(pts[0, 1]), gap=UP_MM)
        tr.to(0.15, gap=0.0).hold(0.1)
        for p, q in zip(pts[:-1], pts[1:]):
            tr.to(float(np.linalg.norm(q - p)) / speed_mm_s, s=float(q[0]), t=float(q[1]))
        tr.hold(0.1).to(0.15, gap=UP_MM)
    assert tr is not None
    ctx.leave(tr)
    return Script(tr.end_s + 0.3, hands=[HandTrack(ctx.hand(), ("index",), tr)])


def _spread(shape: HandShape, fingers: tuple[str, ...]) -> dict[str, tuple[float, float]]:
    fwd = {"index": 0.0, "middle": 6.0, "ring": 0.0, "little": -14.0, "thumb": -45.0}
    k = shape.knuckle_spacing_mm * 1.15
    pos = {"index": 0.0, "middle": 1.0, "ring": 2.0, "little": 3.0, "thumb": -1.6}
    lead = fingers[0]
    return {f: ((pos[f] - pos[lead]) * k, fwd[f] - fwd[lead]) for f in fingers[1:]}


def _multi_hand(ctx: SceneContext, side: int, fingers: tuple[str, ...], t0: float,
                centre: np.ndarray, yaw: float, t_down: float, hold_s: float) -> HandTrack:
    rng = ctx.rng
    shape = ctx.hand(side)
    offs = _spread(shape, fingers)
    tr = ctx.enter(centre, yaw, ctx.pitch(35.0, 60.0), t0, offs)
    tr.hold(max(t_down - tr.end_s, 0.01))
    gaps = {f + ".gap": 0.0 for f in fingers[1:]}
    # fingers land a few frames apart, like real hands
    tr.to(0.15, gap=0.0)
    for f in fingers[1:]:
        tr.to(float(rng.uniform(0.03, 0.08)), **{f + ".gap": 0.0})
    move = rng.normal(0, 1, 2)
    move = move / np.linalg.norm(move) * 40.0
    tr.hold(0.2).to(hold_s, s=float(centre[0] + move[0]), t=float(centre[1] + move[1]), **gaps)
    tr.to(0.15, gap=UP_MM, **{f + ".gap": UP_MM for f in fingers[1:]})
    ctx.leave(tr)
    return HandTrack(shape, fingers, tr)


def scene_multitouch(ctx: SceneContext) -> Script:
    ca, cb = ctx.st_at(0.33, 0.5), ctx.st_at(0.67, 0.5)
    if ca is None or cb is None:
        ca, cb = ctx.spot(), ctx.spot()
    a = _multi_hand(ctx, 1, ("index", "middle", "ring"), EMPTY_S, ca, _yaw(ctx, 20.0),
                    EMPTY_S + 1.2, 1.6)
    b = _multi_hand(ctx, -1, ("index", "middle"), EMPTY_S + 0.4, cb, _yaw(ctx, -20.0),
                    EMPTY_S + 2.0, 0.9)
    return Script(max(a.track.end_s, b.track.end_s) + 0.3, hands=[a, b])


def scene_pinch(ctx: SceneContext) -> Script:
    rng = ctx.rng
    shape = ctx.hand(1)
    yaw = _yaw(ctx)
    centre = ctx.spot(0.4, 0.6)
    lat, fwd = lateral_forward_st(yaw, shape.side)
    e = -0.55 * lat - 0.83 * fwd  # index -> thumb direction (thumb side, toward the wrist)

    def at(dist: float) -> dict[str, float]:
        lead = centre - e * dist / 2
        return {"s": float(lead[0]), "t": float(lead[1]), "thumb.dl": -0.55 * shape.side * dist
                * shape.side, "thumb.df": -0.83 * dist}

    open_mm, closed_mm = float(rng.uniform(80.0, 110.0)), float(rng.uniform(22.0, 32.0))
    tr = ctx.enter(centre - e * open_mm / 2, yaw, ctx.pitch(35.0, 55.0), EMPTY_S,
                   {"thumb": (at(open_mm)["thumb.dl"], at(open_mm)["thumb.df"])})
    for a_mm, b_mm in ((open_mm, closed_mm), (closed_mm, open_mm)):
        tr.to(0.3, **at(a_mm))
        tr.to(0.15, gap=0.0, **{"thumb.gap": 0.0}).hold(0.1)
        tr.to(float(rng.uniform(0.6, 1.0)), **at(b_mm)).hold(0.1)
        tr.to(0.15, gap=UP_MM, **{"thumb.gap": UP_MM})
    ctx.leave(tr)
    return Script(tr.end_s + 0.3, hands=[HandTrack(shape, ("index", "thumb"), tr)])


def scene_cross(ctx: SceneContext) -> Script:
    rng = ctx.rng
    mid = ctx.spot(0.45, 0.55)
    span = min(0.25 * ctx.mm_per_frac(), 220.0)
    sep = float(rng.uniform(18.0, 30.0))
    hands = []
    # the two hands face each other (one from each side), each within 10 deg of straight
    jitter = rng.uniform(-10.0, 10.0, 2)
    for side, yaw, sign in ((1, ctx.base_yaw + jitter[0], 1.0),
                            (-1, ctx.base_yaw + 180.0 + jitter[1], -1.0)):
        start = mid + np.array([-sign * span / 2, sign * sep / 2])
        end = mid + np.array([sign * span / 2, sign * sep / 2])
        tr = ctx.enter(start, yaw, _pitch(ctx), EMPTY_S)
        tr.to(0.3, s=float(start[0]), t=float(start[1])).hold(0.2)
        tr.to(0.15, gap=0.0).hold(0.15)
        tr.to(span / (float(rng.uniform(0.15, 0.35)) * 1000.0), s=float(end[0]), t=float(end[1]))
        tr.hold(0.15).to(0.15, gap=UP_MM)
        ctx.leave(tr)
        hands.append(HandTrack(ctx.hand(side), ("index",), tr))
    return Script(max(h.track.end_s for h in hands) + 0.3, hands=hands)


def scene_hover(ctx: SceneContext) -> Script:
    tr = ctx.enter(ctx.spot(), _yaw(ctx), _pitch(ctx), EMPTY_S)
    for h in (50.0, 25.0, 10.0):
        st = ctx.spot()
        tr.to(0.4, s=float(st[0]), t=float(st[1]), gap=h).hold(1.0)
    tr.to(0.2, gap=UP_MM)
    ctx.leave(tr)
    return Script(tr.end_s + 0.3, hands=[HandTrack(ctx.hand(), ("index",), tr)])


LABEL_OBJECT, LABEL_REST_ARM, LABEL_BODY = 101, 102, 103


def _object(ctx: SceneContext, st: np.ndarray, t_in: float, t_out: float | None) -> Prop:
    """A box (a book or phone, ~ 150 x 80 x 25 mm) set down on the surface and maybe lifted."""
    rng = ctx.rng
    size = np.array([rng.uniform(120, 180), rng.uniform(60, 90), rng.uniform(15, 40)])
    ang = float(rng.uniform(0, math.pi))
    s = ctx.surface
    n = s.normal(st[None])[0]
    e1 = math.cos(ang) * s.u + math.sin(ang) * s.tangent_t(st[None])[0]
    axes = np.stack([e1, np.cross(n, e1), n], 1)
    base = s.point(st[None])[0]
    # on a curved surface the box bottom corners would sink: rest it on the lowest corner
    corners = [base + a * size[0] / 2 * e1 + b * size[1] / 2 * axes[:, 1]
               for a in (-1, 1) for b in (-1, 1)]
    sink = max(0.0, -min(float(s.height_mm(c)[0]) for c in corners))
    end = math.inf if t_out is None else t_out

    def build(t: float) -> list[Primitive]:
        if t < t_in or t > end + 0.4:
            return []
        lift = 150.0 * max(0.0, 1.0 - (t - t_in) / 0.4, (t - end) / 0.4)
        c = base + (size[2] / 2 + sink + lift) * n
        return [Box(c, axes, size / 2, LABEL_OBJECT)]

    return Prop(build)


def _resting_arm(ctx: SceneContext, t_in: float, t_out: float) -> Prop:
    """A forearm lying above the surface (bottom >= 40 mm up), sliding in from the right."""
    rng = ctx.rng
    st_in, st_edge = ctx.st_at(0.7, 0.75), ctx.st_at(1.0, 0.9)
    if st_in is None or st_edge is None:
        st_in, st_edge = ctx.spot(), ctx.spot()
    radius = float(rng.uniform(25.0, 35.0))
    height = float(rng.uniform(42.0, 60.0))
    s = ctx.surface
    along = st_edge - st_in
    along = along / np.linalg.norm(along)

    def build(t: float) -> list[Primitive]:
        if not (t_in <= t <= t_out):
            return []
        slide = 600.0 * max(0.0, 1.0 - (t - t_in) / 0.5, 1.0 - (t_out - t) / 0.5)
        a_st = st_in + along * slide
        b_st = a_st + along * 600.0
        pa, pb = s.point(np.stack([a_st, b_st]))
        na, nb = s.normal(np.stack([a_st, b_st]))
        return [Capsule(pa + (height + radius) * na, pb + (height + radius + 40.0) * nb,
                        radius, LABEL_REST_ARM)]

    return Prop(build)


def _passing_body(ctx: SceneContext, t_in: float, dur_s: float) -> Prop:
    """A person's torso between camera and surface, crossing the view left to right."""
    z = 0.55 * float(ctx.surface.origin_mm[2])
    rays = ctx.rays
    half_w = z * rays.cx / rays.fx + 400.0
    half_h = z * rays.cy / rays.fy

    def build(t: float) -> list[Primitive]:
        if not (t_in <= t <= t_in + dur_s):
            return []
        x = -half_w + 2 * half_w * (t - t_in) / dur_s
        a = np.array([x, -half_h - 300.0, z])
        b = np.array([x, half_h * 0.3, z + 100.0])
        return [Capsule(a, b, 220.0, LABEL_BODY)]

    return Prop(build)


def scene_distractors(ctx: SceneContext) -> Script:
    rng = ctx.rng
    yaw, pitch = _yaw(ctx), _pitch(ctx)
    spots = [ctx.spot(0.2, 0.5) for _ in range(4)]
    tr = ctx.enter(spots[0], yaw, pitch, EMPTY_S)
    for st in spots:
        _tap(tr, rng, st)
    ctx.leave(tr)
    t_obj = EMPTY_S + 1.0
    t_arm = EMPTY_S + 2.0
    t_body = tr.end_s + 0.2
    obj_st = ctx.st_at(0.75, 0.3)
    props = [
        _object(ctx, obj_st if obj_st is not None else ctx.spot(), t_obj, None),
        _resting_arm(ctx, t_arm, t_arm + 2.5),
        _passing_body(ctx, t_body, 1.2),
    ]
    events = [("object_placed", t_obj + 0.4), ("arm_rest_start", t_arm),
              ("arm_rest_end", t_arm + 2.5), ("body_pass_start", t_body),
              ("body_pass_end", t_body + 1.2)]
    return Script(t_body + 1.6, hands=[HandTrack(ctx.hand(), ("index",), tr)], props=props,
                  events=events)


def scene_object(ctx: SceneContext) -> Script:
    rng = ctx.rng
    t_in = EMPTY_S + 0.3
    t_out = t_in + 0.4 + 3.0
    obj_st = ctx.st_at(0.3, 0.4)
    prop = _object(ctx, obj_st if obj_st is not None else ctx.spot(), t_in, t_out)
    spots = [ctx.spot(0.55, 0.8) for _ in range(3)]
    tr = ctx.enter(spots[0], _yaw(ctx), _pitch(ctx), t_in + 0.6)
    for st in spots:
        _tap(tr, rng, st)
    ctx.leave(tr)
    events = [("object_placed", t_in + 0.4), ("object_removed", t_out)]
    return Script(max(t_out + 1.5, tr.end_s + 0.3),
                  hands=[HandTrack(ctx.hand(), ("index",), tr)], props=[prop], events=events)


def scene_drift(ctx: SceneContext) -> Script:
    rng = ctx.rng
    tr = ctx.enter(ctx.spot(), _yaw(ctx), _pitch(ctx), EMPTY_S + 0.5)
    for st in [ctx.spot(0.2, 0.8) for _ in range(5)]:
        _tap(tr, rng, st)
    ctx.leave(tr)
    dur = tr.end_s + 0.5
    total_mm = float(rng.uniform(3.0, 5.0))

    def drift(t: float) -> float:
        return -total_mm * max(0.0, t - EMPTY_S) / (dur - EMPTY_S)

    return Script(dur, hands=[HandTrack(ctx.hand(), ("index",), tr)],
                  events=[("drift_start", EMPTY_S)], drift=drift)


def scene_bump(ctx: SceneContext) -> Script:
    rng = ctx.rng
    tr = ctx.enter(ctx.spot(), _yaw(ctx), _pitch(ctx), EMPTY_S)
    spots = [ctx.spot(0.2, 0.8) for _ in range(5)]
    for st in spots[:2]:
        _tap(tr, rng, st)
    t_bump = tr.end_s + 0.3
    tr.hold(0.6)
    for st in spots[2:]:
        _tap(tr, rng, st)
    ctx.leave(tr)
    sign = rng.choice([-1.0, 1.0], 3)
    deg = (float(sign[0] * rng.uniform(0.4, 0.8)), float(sign[1] * rng.uniform(0.3, 0.6)),
           float(sign[2] * rng.uniform(0.0, 0.5)))
    return Script(tr.end_s + 0.3, hands=[HandTrack(ctx.hand(), ("index",), tr)],
                  events=[("bump", t_bump)], bump_s=t_bump, bump_deg_xyz=deg)


def scene_hold(ctx: SceneContext) -> Script:
    st = ctx.spot()
    tr = ctx.enter(st, _yaw(ctx), _pitch(ctx), EMPTY_S)
    tr.to(0.15, gap=0.0).hold(10.0).to(0.15, gap=UP_MM)
    ctx.leave(tr)
    return Script(tr.end_s + 0.3, hands=[HandTrack(ctx.hand(), ("index",), tr)])


def scene_presses(ctx: SceneContext) -> Script:
    """Eight one-finger presses held 0.1-1.0 s (shuffled): the tap / long-press boundary."""
    rng = ctx.rng
    yaw, pitch = _yaw(ctx), _pitch(ctx)
    holds = rng.permutation(np.linspace(0.1, 1.0, 8)) + rng.uniform(-0.03, 0.03, 8)
    spots = [ctx.spot(0.2, 0.8) for _ in holds]
    tr = ctx.enter(spots[0], yaw, pitch, EMPTY_S)
    for st, hold in zip(spots, holds, strict=True):
        tr.to(0.35, s=float(st[0]), t=float(st[1]), gap=UP_MM)
        tr.to(0.08, gap=0.0)
        tr.hold(float(max(hold, 0.05)))
        tr.to(0.08, gap=UP_MM)
    ctx.leave(tr)
    return Script(tr.end_s + 0.3, hands=[HandTrack(ctx.hand(), ("index",), tr)])


def _occluding_arm(ctx: SceneContext, st: np.ndarray, t_in: float, t_out: float) -> Prop:
    """The other arm held still high over the surface beside ``st`` (see :func:`scene_occlude`),
    sliding in from the left over 0.5 s at ``t_in`` and out from ``t_out``."""
    rng = ctx.rng
    s = ctx.surface
    dist_mm = float(s.origin_mm[2])
    height = 0.4 * dist_mm
    radius = float(rng.uniform(36.0, 44.0))
    hand_st = st + np.array([-0.16 * dist_mm, -float(rng.uniform(100.0, 140.0))])
    elbow_st = hand_st + np.array([-150.0, 650.0])  # toward the body, lower left

    def build(t: float) -> list[Primitive]:
        if not (t_in <= t <= t_out + 0.5):
            return []
        slide = np.array([-700.0, 0.0]) * max(0.0, 1.0 - (t - t_in) / 0.5, (t - t_out) / 0.5)
        pa, pb = s.point(np.stack([hand_st + slide, elbow_st + slide]))
        na, nb = s.normal(np.stack([hand_st + slide, elbow_st + slide]))
        hand = pa + height * na
        return [Capsule(hand, pb + (height + 150.0) * nb, radius, LABEL_REST_ARM),
                Sphere(hand, radius + 12.0, LABEL_REST_ARM)]

    return Prop(build)


def scene_occlude(ctx: SceneContext) -> Script:
    """A finger touches the middle of the frame and drags while the other arm is held over the
    surface, 0.4 x the camera distance up and 0.16 x to the left of the finger: from a camera
    0.4 x the distance to the left (the left view of two 0.8 m apart at 1 m) it hides the finger,
    not from the camera in the middle or one to the right. A tap follows while it is hidden."""
    rng = ctx.rng
    centre = ctx.st_at(0.5, 0.5)
    centre = ctx.spot(0.45, 0.55) if centre is None else centre
    start = centre + np.array([-30.0, 0.0])
    tr = ctx.enter(start, ctx.base_yaw + float(rng.uniform(-15.0, 15.0)),
                   ctx.pitch(35.0, 60.0), EMPTY_S)
    tr.to(0.15, gap=0.0).hold(0.4)  # down before the arm comes: both cameras see it
    t_in = tr.end_s
    tr.hold(0.8)  # the arm slides in, the finger stays
    tr.to(1.0, s=float(centre[0] + 30.0), t=float(centre[1] + 15.0)).hold(0.3)
    tr.to(0.15, gap=UP_MM)
    _tap(tr, rng, centre + np.array([0.0, 25.0]))  # a tap the left camera cannot see
    t_out = tr.end_s + 0.2
    tr.hold(1.0)
    ctx.leave(tr)
    events = [("occluder_in", t_in + 0.5), ("occluder_out", t_out)]
    return Script(tr.end_s + 0.3, hands=[HandTrack(ctx.hand(), ("index",), tr)],
                  props=[_occluding_arm(ctx, centre, t_in, t_out)], events=events)


SCENE_BUILDERS: dict[str, Callable[[SceneContext], Script]] = {
    "taps": scene_taps,
    "drags": scene_drags,
    "multitouch": scene_multitouch,
    "pinch": scene_pinch,
    "cross": scene_cross,
    "hover": scene_hover,
    "distractors": scene_distractors,
    "object": scene_object,
    "drift": scene_drift,
    "bump": scene_bump,
    "hold": scene_hold,
    "presses": scene_presses,
    "occlude": scene_occlude,
}

#: Scenes measured apart (``depthtouch eval --gestures``): not in ``scenes = "all"`` of a suite,
#: so that the default suite, and the numbers measured on it, stay as they are.
GESTURE_SCENES: tuple[str, ...] = ("presses",)
#: Scenes made for several cameras (``depthtouch sim --views``), measured apart likewise.
MULTIVIEW_SCENES: tuple[str, ...] = ("occlude",)
SCENES: tuple[str, ...] = tuple(n for n in SCENE_BUILDERS
                                if n not in GESTURE_SCENES + MULTIVIEW_SCENES)


def build_script(scene: str, ctx: SceneContext) -> Script:
    """The script of ``scene``; ConfigError listing the valid names otherwise."""
    from .hardscenes import HARD_SCENE_BUILDERS, HARD_SCENES  # they build on this module

    builder = SCENE_BUILDERS.get(scene) or HARD_SCENE_BUILDERS.get(scene)
    if builder is None:
        names = ", ".join(SCENES + GESTURE_SCENES + MULTIVIEW_SCENES + HARD_SCENES)
        raise ConfigError(f"unknown scene {scene!r}; use one of {names}")
    return builder(ctx)
