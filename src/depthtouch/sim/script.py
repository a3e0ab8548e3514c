"""Scene scripts as data: keyframed hand tracks, props and camera events, and the context that
places them (see :mod:`depthtouch.sim.scenes` for the scenes themselves).

Positions are chosen in image terms (fractions of the frame) and turned into surface
coordinates (s, t) by casting a ray, so a scene works for any camera, distance, tilt and
surface. Lengths and speeds are in mm and m/s on the surface.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import ConfigError
from .geometry import Primitive, Rays, Surface
from .hand import FingerTarget, HandShape, lateral_forward_st

EMPTY_S = 1.5
HOVER_MAX_MM = 100.0  # extended fingertips at most this high are listed as hovers
UP_MM = 60.0  # fingertip height between touches


class Track:
    """Piecewise-linear keyframes of named channels; ``at(t)`` interpolates all of them."""

    def __init__(self, t0: float, **values: float) -> None:
        self.times: list[float] = [t0]
        self.keys: list[dict[str, float]] = [dict(values)]

    @property
    def end_s(self) -> float:
        return self.times[-1]

    @property
    def start_s(self) -> float:
        return self.times[0]

    def to(self, dt_s: float, **changes: float) -> Track:
        """Move linearly to the changed values over ``dt_s`` seconds (> 0)."""
        key = dict(self.keys[-1])
        key.update(changes)
        self.times.append(self.times[-1] + max(dt_s, 1e-3))
        self.keys.append(key)
        return self

    def hold(self, dt_s: float) -> Track:
        return self.to(dt_s)

    def at(self, t: float) -> dict[str, float]:
        times = np.asarray(self.times)
        names = self.keys[-1].keys()
        return {k: float(np.interp(t, times, [key.get(k, 0.0) for key in self.keys]))
                for k in names}


@dataclass
class HandTrack:
    """One hand over time: which fingers are extended (first leads) and their track.

    Channels: s, t (lead target, mm), gap (lead tip, mm), yaw, pitch (deg), and for every other
    extended finger f: ``f.dl``, ``f.df`` (offset from the lead target along the hand's lateral
    and forward axes, mm) and ``f.gap``.
    """

    shape: HandShape
    fingers: tuple[str, ...]
    track: Track

    def pose(self, t: float) -> tuple[tuple[FingerTarget, ...], float, float] | None:
        if not (self.track.start_s <= t <= self.track.end_s):
            return None
        c = self.track.at(t)
        lat, fwd = lateral_forward_st(c["yaw"], self.shape.side)
        lead_st = np.array([c["s"], c["t"]])
        out = [FingerTarget(self.fingers[0], (c["s"], c["t"]), max(c["gap"], 0.0))]
        for f in self.fingers[1:]:
            st = lead_st + c[f + ".dl"] * lat + c[f + ".df"] * fwd
            out.append(FingerTarget(f, (float(st[0]), float(st[1])), max(c[f + ".gap"], 0.0)))
        return tuple(out), c["yaw"], c["pitch"]


@dataclass
class Prop:
    """Something else in the scene: ``build(t)`` gives its primitives at time t (or none)."""

    build: Callable[[float], list[Primitive]]


@dataclass
class Script:
    """A scene: duration, hands, props, camera bump, surface drift and named events (s)."""

    duration_s: float
    hands: list[HandTrack] = field(default_factory=list)
    props: list[Prop] = field(default_factory=list)
    events: list[tuple[str, float]] = field(default_factory=list)
    bump_s: float | None = None
    bump_deg_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    drift: Callable[[float], float] | None = None


class SceneContext:
    """What a scene script needs: the world surface, the camera rays, a generator, which hand
    model its hands are (:data:`~depthtouch.sim.hand.HAND_STYLES`), a finger pitch that
    replaces the scenes' random ones (None: drawn; see :meth:`pitch`), and whether arms go on
    into a body that leaves the view (``HandShape.body``)."""

    def __init__(self, surface: Surface, rays: Rays, rng: np.random.Generator,
                 hand_style: str = "capsule", pitch_deg: float | None = None,
                 body: bool = False) -> None:
        self.surface = surface
        self.rays = rays
        self.rng = rng
        self.hand_style = hand_style
        self.pitch_deg = pitch_deg
        self.body = body
        self.base_yaw = self._base_yaw()

    def _base_yaw(self) -> float:
        """Arms come from the image bottom (yaw 0) when the camera looks at the surface nearly
        head-on; when it looks obliquely (> 12 deg), from the side away from the camera (the
        camera would otherwise see the back of the hand and no fingertip at all)."""
        s = self.surface
        to_cam = -s.origin_mm / np.linalg.norm(s.origin_mm)
        cs, ct = float(to_cam @ s.u), float(to_cam @ s.v)
        if math.hypot(cs, ct) < math.sin(math.radians(12.0)):
            return 0.0
        return math.degrees(math.atan2(cs, -ct))

    def pitch(self, lo_deg: float, hi_deg: float) -> float:
        """A lead finger's pitch (deg): drawn uniformly in [lo_deg, hi_deg], or ``pitch_deg``
        when set. The draw is made either way, so a fixed pitch leaves every other part of a
        seed's scene (spots, timings, hand sizes) as it was."""
        drawn = float(self.rng.uniform(lo_deg, hi_deg))
        return drawn if self.pitch_deg is None else float(self.pitch_deg)

    def st_at(self, fx: float, fy: float) -> np.ndarray | None:
        """Surface coordinates seen at the image point (fx * W, fy * H); None if off-surface."""
        p = self.surface.hit(self.rays.ray(fx * (self.rays.w - 1), fy * (self.rays.h - 1)))
        return None if p is None else self.surface.st_of(p)[0]

    def spot(self, lo: float = 0.3, hi: float = 0.7) -> np.ndarray:
        """A random surface point seen inside the central [lo, hi] part of the frame."""
        for _ in range(100):
            st = self.st_at(float(self.rng.uniform(lo, hi)), float(self.rng.uniform(lo, hi)))
            if st is not None:
                return st
        raise ConfigError("the surface is not visible in the frame; reduce tilt or distance")

    def mm_per_frac(self) -> float:
        """Rough surface size (mm) of the frame's shorter side, to size paths."""
        a, b = self.st_at(0.5, 0.3), self.st_at(0.5, 0.7)
        if a is None or b is None:
            return 300.0
        return float(np.linalg.norm(a - b)) / 0.4

    def hand(self, side: int = 1) -> HandShape:
        """A hand of the scene's style; with ``body`` its arm goes on into a body (the same
        draws either way, so a seed's scene is the same but for the body)."""
        shape = HandShape.random(self.rng, side, self.hand_style)
        return replace(shape, body=True) if self.body else shape

    def outside(self, st: np.ndarray, yaw: float) -> np.ndarray:
        """The first surface point behind ``st`` (against the finger direction) out of view.

        Steps back until the point projects outside the image (by 5 %) or comes nearer to the
        camera than 40 % of the surface distance (a tilted or curved surface runs toward it).
        """
        _, fwd = lateral_forward_st(yaw, 1)
        rays = self.rays
        z_min = 0.4 * float(self.surface.origin_mm[2])
        mx, my = 0.05 * rays.w, 0.05 * rays.h
        dist = 0.0
        while dist < 4000.0:
            dist += 25.0
            p = self.surface.point(st - fwd * dist)[0]
            if p[2] < z_min:
                break
            x, y = rays.project(p)[0]
            if x < -mx or x > rays.w - 1 + mx or y < -my or y > rays.h - 1 + my:
                break
        return np.asarray(st - fwd * dist, dtype=np.float64)

    def enter(self, st: np.ndarray, yaw: float, pitch: float, t0: float,
              fingers: dict[str, tuple[float, float]] | None = None) -> Track:
        """A track that brings a hand from outside the view to hover above ``st``."""
        far = self.outside(st, yaw)
        extra: dict[str, float] = {}
        for f, (dl, df) in (fingers or {}).items():
            extra.update({f + ".dl": dl, f + ".df": df, f + ".gap": 250.0})
        tr = Track(t0, s=float(far[0]), t=float(far[1]), gap=250.0, yaw=yaw, pitch=pitch,
                   **extra)
        ups = {f + ".gap": UP_MM for f in (fingers or {})}
        return tr.to(0.9, s=float(st[0]), t=float(st[1]), gap=UP_MM, **ups)

    def leave(self, tr: Track, dt_s: float = 0.7) -> Track:
        c = tr.keys[-1]
        far = self.outside(np.array([c["s"], c["t"]]), c["yaw"])
        ups = {k: 250.0 for k in c if k.endswith(".gap")}
        return tr.to(dt_s, s=float(far[0]), t=float(far[1]), gap=250.0, **ups)
