"""An articulated hand and arm made of capsules, posed by where its fingertips are.

The lead finger (usually the index) fixes the hand: its tip sphere rests at ``gap_mm`` above a
surface point, its distal part rises at ``pitch_deg`` from the surface and its proximal part
25 deg steeper, up to the knuckle. The palm rises backward from the knuckle line, then the
forearm and upper arm leave the scene. Other extended fingers reach their own targets with
the same distal pitch, pointing from their knuckle toward the target, with the proximal
part bridging to the knuckle; the remaining fingers
are curled under the palm but kept at least ``clearance_mm`` above the surface.
Touch is tip contact: gap 0 means the tip sphere touches the surface at exactly one point.

A second hand model, ``style="anatomic"`` (:class:`Anatomy`), is another hand for the check sets:
three phalanges that taper toward the tip, a distal pad wider than it is thick (two lobes side
by side), a joint at the last phalanx that can lay the pad flatter than the scene's pitch, a
tip that presses 0-1.5 mm into the surface while it touches, and a palm and forearm drawn
apart from the fingers. Its contact point is the centre of the pressed patch (the middle of
the pad's two lobes where it does not sink).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .geometry import Capsule, Primitive, Surface

FINGERS: tuple[str, ...] = ("thumb", "index", "middle", "ring", "little")
PALM, ARM = 5, 6  # label offsets of the palm and the arm; fingers use their FINGERS index
HAND_STYLES: tuple[str, ...] = ("capsule", "anatomic")
#: the body past the shoulder (``HandShape.body``): a capsule of this radius (a torso seen from
#: above or the side is 300-400 mm across) running this far, parallel to the surface, away from
#: the hand: out of the view of every camera the simulator has at up to 2.5 m
BODY_RADIUS_MM, BODY_LENGTH_MM = 160.0, 3000.0


@dataclass(frozen=True)
class Anatomy:
    """What the ``anatomic`` hand adds (mm, deg), drawn per hand.

    phalanges_mm: per finger (proximal, middle, distal) lengths.
    tip_frac: the distal phalanx's radius as a fraction of the finger radius (0.78-0.92); the
        middle one is halfway between.
    pad_offset_frac: the pad's two lobes lie this fraction of the distal radius to either side
        of the finger's axis (0.2-0.4), each with radius 0.85 of it: a pad 2.1-2.5 radii wide
        and 1.7 thick.
    dip_deg: how much flatter the distal phalanx lies than the scene's pitch (-5 to 20).
    press_mm: how far a touching tip sinks into the surface (0-1.5).
    palm_rise_deg: the palm's rise from the surface behind the knuckles (15-30).
    """

    phalanges_mm: dict[str, tuple[float, float, float]]
    tip_frac: float
    pad_offset_frac: float
    dip_deg: float
    press_mm: float
    palm_rise_deg: float

    @classmethod
    def random(cls, rng: np.random.Generator, scale: float) -> Anatomy:
        base = {"thumb": (36.0, 16.0, 18.0), "index": (45.0, 25.0, 21.0),
                "middle": (49.0, 29.0, 22.0), "ring": (46.0, 27.0, 21.0),
                "little": (36.0, 19.0, 18.0)}
        return cls(
            phalanges_mm={k: tuple(x * scale for x in v)  # type: ignore[misc]
                          for k, v in base.items()},
            tip_frac=float(rng.uniform(0.78, 0.92)),
            pad_offset_frac=float(rng.uniform(0.2, 0.4)),
            dip_deg=float(rng.uniform(-5.0, 20.0)),
            press_mm=float(rng.uniform(0.0, 1.5)),
            palm_rise_deg=float(rng.uniform(15.0, 30.0)),
        )


@dataclass(frozen=True)
class HandShape:
    """Dimensions of one hand (mm). ``side`` is +1 for a right hand, -1 for a left one.

    finger_radius_mm: radius of the index/middle/ring finger capsules (6-10 mm; varies per seed).
    segments_mm: per finger (proximal, distal) lengths; distal includes the middle phalanx.
    body: the arm goes on past the shoulder into a body (:data:`BODY_RADIUS_MM`) that leaves
    the view; without it the arm ends at the shoulder, which a far camera sees whole.
    """

    finger_radius_mm: float
    segments_mm: dict[str, tuple[float, float]]
    palm_length_mm: float
    knuckle_spacing_mm: float
    palm_radius_mm: float
    forearm_radius_mm: float
    side: int = 1
    anatomy: Anatomy | None = None
    body: bool = False

    @classmethod
    def random(cls, rng: np.random.Generator, side: int = 1, style: str = "capsule"
               ) -> HandShape:
        """A plausible adult hand; sizes scale together, finger radius 6-10 mm.

        style: "capsule" (the suites' hand) or "anatomic" (:class:`Anatomy`, drawn after the
        capsule hand's values, so both styles share a seed's sizes)."""
        scale = float(rng.uniform(0.88, 1.12))
        r = float(rng.uniform(6.0, 10.0))
        base = {"thumb": (36.0, 32.0), "index": (45.0, 44.0), "middle": (49.0, 48.0),
                "ring": (46.0, 45.0), "little": (36.0, 36.0)}
        anatomy = None
        palm_r, arm_r = r + 4.0, 26.0 * scale
        if style == "anatomic":
            anatomy = Anatomy.random(rng, scale)
            palm_r = r + float(rng.uniform(2.0, 7.0))
            arm_r *= float(rng.uniform(0.85, 1.2))
        elif style != "capsule":
            raise ConfigError(f"unknown hand {style!r}; use one of {', '.join(HAND_STYLES)}")
        return cls(
            finger_radius_mm=r,
            segments_mm={k: (a * scale, b * scale) for k, (a, b) in base.items()},
            palm_length_mm=88.0 * scale,
            knuckle_spacing_mm=max(19.0 * scale, 2.0 * r + 1.0),
            palm_radius_mm=palm_r,
            forearm_radius_mm=arm_r,
            side=side,
            anatomy=anatomy,
        )

    def radius(self, finger: str) -> float:
        if finger == "little":
            return self.finger_radius_mm * 0.85
        if finger == "thumb":
            return self.finger_radius_mm * 1.1
        return self.finger_radius_mm


@dataclass(frozen=True)
class FingerTarget:
    """An extended finger: its surface target (s, t) in mm and the tip's gap above it (>= 0)."""

    finger: str
    st_mm: tuple[float, float]
    gap_mm: float


@dataclass(frozen=True)
class Tip:
    """Where an extended fingertip is: the surface point under it, the normal there, the gap."""

    finger: str
    point_mm: np.ndarray
    normal: np.ndarray
    gap_mm: float
    label: int


def _unit(v: np.ndarray) -> np.ndarray:
    return np.asarray(v / np.linalg.norm(v), dtype=np.float64)


def build_hand(
    shape: HandShape,
    fingers: tuple[FingerTarget, ...],
    yaw_deg: float,
    pitch_deg: float,
    surface: Surface,
    label_base: int,
    clearance_mm: float = 30.0,
) -> tuple[list[Primitive], list[Tip]]:
    """Capsules of a posed hand and arm (camera frame, mm), and its extended fingertips.

    fingers: extended fingers, the first one leading (it sets the palm). yaw_deg: direction
    the fingers point in the surface, 0 = toward -t (image top; the arm comes from the bottom),
    positive turns toward +s. pitch_deg: lead finger angle to the surface (20-70).
    label_base: labels are label_base + FINGERS index, + PALM, + ARM.
    """
    lead = fingers[0]
    st = np.array([lead.st_mm])
    n = surface.normal(st)[0]
    e_s = surface.u
    e_t = surface.tangent_t(st)[0]
    yaw = math.radians(yaw_deg)
    d = _unit(-math.cos(yaw) * e_t + math.sin(yaw) * e_s)
    lat = _unit(shape.side * np.cross(d, n))
    r = shape.radius(lead.finger)
    phi = math.radians(pitch_deg)
    phi2 = min(phi + math.radians(25.0), math.radians(85.0))
    l1, l2 = shape.segments_mm[lead.finger]
    tip_point = surface.point(st)[0]
    lead_label = label_base + FINGERS.index(lead.finger)
    if shape.anatomy is not None:
        lead_prims, k_lead, patch = _anatomic_finger(shape, lead.finger, tip_point, n, d,
                                                     lead.gap_mm, phi, lead_label)
        tip_point = surface.point(surface.st_of(patch[None, :]))[0]
    else:
        c = tip_point + (r + lead.gap_mm) * n
        mid = c - l2 * math.cos(phi) * d + l2 * math.sin(phi) * n
        k_lead = mid - l1 * math.cos(phi2) * d + l1 * math.sin(phi2) * n
        lead_prims = [Capsule(k_lead, mid, r, lead_label),
                      Capsule(mid, c, r, lead_label, cap_a=False)]

    alpha = math.radians(22.0 if shape.anatomy is None else shape.anatomy.palm_rise_deg)
    pdir = -math.cos(alpha) * d + math.sin(alpha) * n  # knuckles -> wrist
    fwd = -pdir
    down = _unit(-(n - (n @ pdir) * pdir))
    lead_idx = max(FINGERS.index(lead.finger), 1)
    knuckles: dict[str, np.ndarray] = {}
    for j, name in enumerate(FINGERS[1:], start=1):
        back = {"index": 0.0, "middle": -3.0, "ring": 2.0, "little": 9.0}[name]
        knuckles[name] = k_lead + (j - lead_idx) * shape.knuckle_spacing_mm * lat + back * pdir
    wrist = np.mean(list(knuckles.values()), axis=0) + shape.palm_length_mm * pdir
    thumb_base = knuckles["index"] + 0.55 * shape.palm_length_mm * pdir \
        - 0.9 * shape.knuckle_spacing_mm * lat + 0.3 * shape.palm_radius_mm * down

    def lift(p: np.ndarray, radius: float) -> np.ndarray:
        h = float(surface.height_mm(p)[0])
        need = clearance_mm + radius - h
        return p + need * n if need > 0 else p

    prims: list[Primitive] = []
    tips: list[Tip] = []
    targets = {f.finger: f for f in fingers}
    for name in FINGERS:
        label = label_base + FINGERS.index(name)
        fr = shape.radius(name)
        s1, s2 = shape.segments_mm[name]
        base = thumb_base if name == "thumb" else knuckles[name]
        if name == lead.finger:
            prims += lead_prims
            tips.append(Tip(name, tip_point, n, lead.gap_mm, label))
        elif name in targets:
            f = targets[name]
            fst = np.array([f.st_mm])
            fn = surface.normal(fst)[0]
            fp = surface.point(fst)[0]
            fc = fp + (fr + f.gap_mm) * fn
            # the distal part meets the surface like the lead finger's (same pitch), pointing
            # from its knuckle toward its target; the proximal part bridges to the knuckle
            dj = fc - base
            dj = dj - (dj @ fn) * fn
            dj = _unit(dj) if np.linalg.norm(dj) > 1e-6 else d
            pj = min(phi, math.radians(45.0)) if name == "thumb" else phi
            if shape.anatomy is not None:
                fprims, _, patch = _anatomic_finger(shape, name, fp, fn, dj, f.gap_mm, pj,
                                                    label, base)
                prims += fprims
                fp = surface.point(surface.st_of(patch[None, :]))[0]
            else:
                m = fc - s2 * math.cos(pj) * dj + s2 * math.sin(pj) * fn
                prims += [Capsule(base, m, fr, label), Capsule(m, fc, fr, label, cap_a=False)]
            tips.append(Tip(name, fp, fn, f.gap_mm, label))
        elif name == "thumb":
            p1 = lift(base + 0.8 * s1 * fwd + 0.2 * s1 * down + 0.3 * s1 * lat, fr)
            p2 = lift(p1 + 0.7 * s2 * lat + 0.2 * s2 * fwd, fr)
            prims += [Capsule(base, p1, fr, label), Capsule(p1, p2, fr, label, cap_a=False)]
        else:
            p1 = lift(base + 0.35 * s1 * fwd + 0.45 * s1 * down, fr)
            p2 = lift(p1 - 0.3 * s2 * fwd + 0.35 * s2 * down, fr)
            prims += [Capsule(base, p1, fr, label), Capsule(p1, p2, fr, label, cap_a=False)]

    palm = label_base + PALM
    for name in FINGERS[1:]:
        k = knuckles[name]
        prims.append(Capsule(k, k + shape.palm_length_mm * pdir, shape.palm_radius_mm, palm))
    gamma = alpha + math.radians(6.0)
    adir = -math.cos(gamma) * d + math.sin(gamma) * n
    arm = label_base + ARM
    fr_mm = shape.forearm_radius_mm
    w1 = wrist + 140.0 * adir
    elbow = wrist + 270.0 * adir
    shoulder = elbow + 280.0 * (-math.cos(math.radians(55)) * d + math.sin(math.radians(55)) * n)
    shoulder = _in_front(elbow, shoulder)
    prims += [
        Capsule(wrist, w1, fr_mm * 0.95, arm),
        Capsule(w1, elbow, fr_mm * 1.25, arm),
        Capsule(elbow, shoulder, fr_mm * 1.5, arm),
    ]
    if shape.body:
        prims.append(body_capsule(shoulder, -d, arm))
    return prims, tips


def body_capsule(shoulder: np.ndarray, away: np.ndarray, label: int) -> Capsule:
    """The body past ``shoulder`` (:data:`BODY_RADIUS_MM`): its axis runs from the shoulder
    along ``away`` (a direction in the surface, away from the hand) for
    :data:`BODY_LENGTH_MM`, kept in front of the camera. Its near end lies a radius behind the
    shoulder, so that the body hides no more of the arm than a shoulder would."""
    a = shoulder + BODY_RADIUS_MM * away
    return Capsule(a, _in_front(a, a + BODY_LENGTH_MM * away), BODY_RADIUS_MM, label)


def _anatomic_finger(shape: HandShape, name: str, tip_point: np.ndarray, n: np.ndarray,
                     d: np.ndarray, gap_mm: float, phi: float, label: int,
                     base: np.ndarray | None = None
                     ) -> tuple[list[Primitive], np.ndarray, np.ndarray]:
    """An extended finger of the ``anatomic`` hand (:class:`Anatomy`) whose pad's middle lies
    ``gap_mm`` above ``tip_point`` (normal ``n``), pointing along ``d`` (in the surface) at the
    scene's pitch ``phi`` (rad): its capsules, its knuckle (``base`` when given: the proximal
    phalanx then bridges to it) and its contact point (the centre of the pressed patch)."""
    a = shape.anatomy
    assert a is not None
    r = shape.radius(name)
    rd = r * a.tip_frac
    rl, w = 0.85 * rd, a.pad_offset_frac * rd
    lp, lm, ld = a.phalanges_mm[name]
    sink = a.press_mm if gap_mm <= 0.0 else 0.0
    c = tip_point + (rl + gap_mm - sink) * n
    lat = _unit(np.cross(d, n))
    phd = math.radians(min(max(math.degrees(phi) - a.dip_deg, 8.0), 80.0))
    phm = min(phi + math.radians(8.0), math.radians(80.0))
    php = min(phi + math.radians(30.0), math.radians(85.0))
    dip = c - ld * math.cos(phd) * d + ld * math.sin(phd) * n
    pip = dip - lm * math.cos(phm) * d + lm * math.sin(phm) * n
    if base is None:
        base = pip - lp * math.cos(php) * d + lp * math.sin(php) * n
    prims: list[Primitive] = [Capsule(base, pip, r, label),
                              Capsule(pip, dip, 0.5 * (r + rd), label, cap_a=False)]
    # the pad: two lobes side by side from the last joint to the tip
    lobes = [Capsule(dip + k * w * lat, c + k * w * lat, rl, label) for k in (-1.0, 1.0)]
    return prims + lobes, base, _patch_centre(lobes, tip_point, d, lat, ld + rl)


def _patch_centre(lobes: list[Capsule], foot: np.ndarray, d: np.ndarray, lat: np.ndarray,
                  reach_mm: float, step_mm: float = 0.25) -> np.ndarray:
    """The centroid of the pad's contact patch: the points of the surface's tangent plane at
    ``foot`` that lie inside a lobe (a pressed pad flattens over an area that runs back from
    the tip; the flatter the pad, the farther). ``foot`` itself where the pad does not sink."""
    half = max(float(np.linalg.norm(lobes[0].a - lobes[1].a)) / 2.0 + lobes[0].radius_mm, step_mm)
    u = np.arange(-lobes[0].radius_mm, reach_mm + step_mm, step_mm)  # behind the tip, along -d
    v = np.arange(-half, half + step_mm, step_mm)
    uu, vv = np.meshgrid(u, v)
    q = foot - uu[..., None] * d + vv[..., None] * lat
    inside = np.zeros(uu.shape, bool)
    for cap in lobes:
        ab = cap.b - cap.a
        f = np.clip(((q - cap.a) @ ab) / float(ab @ ab), 0.0, 1.0)
        gap = q - (cap.a + f[..., None] * ab)
        inside |= np.einsum("...k,...k->...", gap, gap) < cap.radius_mm ** 2
    if not inside.any():
        return foot
    return np.asarray(q[inside].mean(axis=0), dtype=np.float64)


def _in_front(a: np.ndarray, b: np.ndarray, min_z_mm: float = 250.0) -> np.ndarray:
    """``b``, pulled back along a-b so that it stays ``min_z_mm`` in front of the camera.

    On a concave surface near the image border "up" can point at the camera; an arm that
    reached behind it would be nonsense (and would cover the whole image).
    """
    if b[2] >= min_z_mm or a[2] <= min_z_mm:
        return b
    f = (a[2] - min_z_mm) / (a[2] - b[2])
    return np.asarray(a + f * (b - a), dtype=np.float64)


def lateral_forward_st(yaw_deg: float, side: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit (s, t) directions of the hand's lateral (index -> little) and forward axes."""
    yaw = math.radians(yaw_deg)
    forward = np.array([math.sin(yaw), -math.cos(yaw)])
    lateral = side * np.array([math.cos(yaw), math.sin(yaw)])
    return lateral, forward
