"""A surface that ends inside the view: a table's edge with the floor beyond it.

Every other scene's surface fills the whole view. A camera 1.3 m above a table with a 70 deg
field of view sees 1.8 m of it: most tables end inside such a view, and the user stands at
the edge, so the arm comes over it. Beyond the edge the camera sees the floor (or, for a wall,
what lies behind it) ``drop_mm`` farther; at the edge, a depth step of that size, with what
the camera makes of one: flying (mixed) pixels at a time-of-flight camera, a band the second
view of a stereo or structured-light camera cannot see, pixels that come and go.

:func:`place_edge` puts the edge behind every place the scene's hands and props reach near the
surface, on the side the first hand comes from (across its forward axis at its first
keyframe), by a margin drawn from the seed's own stream; the contacts' truth stays as it was.
:func:`edge_depth_map` renders the surface with the edge: the surface where ``dir . (s, t) >=
c_mm``, beyond it the same surface moved ``drop_mm`` away from the camera. The camera model
gives the step its artefacts every frame (:meth:`~depthtouch.sim.cameras.NoiseModel.set_static`
with ``live_edges``). The truth document gets ``edge`` (see :func:`edge_doc`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError
from .geometry import Box, Capsule, Rays, Sphere, Surface
from .hand import build_hand, lateral_forward_st
from .script import HOVER_MAX_MM, Script

#: the largest drop beyond the edge (mm)
DROP_MAX_MM = 1500.0
#: the smallest drop: a step the camera separates from the surface at any range (mm)
DROP_MIN_MM = 100.0
#: the edge lies this far behind the rear-most place a hand or prop reaches (mm, uniform)
MARGIN_MM = (40.0, 150.0)
#: hands and props nearer the surface than this count as reaching it (mm)
_NEAR_MM = 40.0
#: the scene is sampled this often to find where it reaches (s)
_SAMPLE_S = 0.1
# the draws' own stream (drops.py uses 0xD0, breathing.py 0xB7)
_STREAM = 0xED


def check_edge(drop_mm: object) -> float:
    """``drop_mm`` as a float, 0 (no edge) or in [:data:`DROP_MIN_MM`, :data:`DROP_MAX_MM`],
    or ConfigError naming the range."""
    if isinstance(drop_mm, bool) or not isinstance(drop_mm, (int, float)) or not (
            float(drop_mm) == 0.0 or DROP_MIN_MM <= float(drop_mm) <= DROP_MAX_MM):
        raise ConfigError(f"edge drop {drop_mm!r} mm is out of range; allowed 0 (no edge) or "
                          f"[{DROP_MIN_MM:g}, {DROP_MAX_MM:g}] mm")
    return float(drop_mm)


@dataclass(frozen=True)
class Edge:
    """The surface's edge: points with ``dir_st . (s, t) < c_mm`` lie beyond it, where the
    camera sees the surface moved ``drop_mm`` away; ``margin_mm``: how far behind the scene's
    rear-most reach it was put."""

    dir_st: tuple[float, float]
    c_mm: float
    drop_mm: float
    margin_mm: float


def _prim_points(prim: Any) -> list[np.ndarray]:
    """Points of a primitive that stand for where it reaches (camera frame, mm)."""
    if isinstance(prim, Capsule):
        return [prim.a, prim.b]
    if isinstance(prim, Sphere):
        return [prim.center]
    if isinstance(prim, Box):
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        return [prim.center + prim.axes @ (s * prim.half_mm) for s in signs]
    return []


def reach_st(script: Script, surface: Surface) -> np.ndarray:
    """(N, 2) surface coordinates of where the scene's fingertips (in contact or hovering up
    to the hover limit) and its props' points nearer than 40 mm to the surface come, sampled
    every 0.1 s."""
    pts: list[np.ndarray] = []
    for t in np.arange(0.0, script.duration_s + 1e-9, _SAMPLE_S):
        for k, hand in enumerate(script.hands):
            pose = hand.pose(float(t))
            if pose is None:
                continue
            fingers, yaw, pitch = pose
            _, tips = build_hand(hand.shape, fingers, yaw, pitch, surface, 10 * (k + 1))
            pts += [surface.st_of(tip.point_mm)[0] for tip in tips if tip.gap_mm <= HOVER_MAX_MM]
        for prop in script.props:
            for prim in prop.build(float(t)):
                for p in _prim_points(prim):
                    if float(surface.height_mm(p)[0]) < _NEAR_MM + getattr(prim, "radius_mm", 0.0):
                        pts.append(surface.st_of(p)[0])
    return np.array(pts, dtype=np.float64).reshape(-1, 2)


def place_edge(script: Script, surface: Surface, drop_mm: float, seed: int) -> Edge | None:
    """The edge behind the scene's reach (see the module doc), or None when the scene has no
    hand to say from which side the user comes."""
    if not script.hands:
        return None
    first = script.hands[0]
    yaw = float(first.track.keys[0]["yaw"])
    _, fwd = lateral_forward_st(yaw, first.shape.side)
    reach = reach_st(script, surface)
    if reach.shape[0] == 0:
        return None
    rng = np.random.default_rng([int(seed), _STREAM])
    margin = float(rng.uniform(*MARGIN_MM))
    c = float((reach @ fwd).min()) - margin
    return Edge((float(fwd[0]), float(fwd[1])), c, float(drop_mm), margin)


def _beyond(surface: Surface, rays: Rays, edge: Edge) -> tuple[np.ndarray, np.ndarray]:
    """The surface's depth map (float32 (H, W), 0 where a ray misses) and where its pixels lie
    beyond the edge (bool (H, W))."""
    near = surface.depth_map(rays)
    p = np.stack([rays.xn * near, rays.yn * near, near.astype(np.float64)], -1).reshape(-1, 3)
    beyond = (surface.st_of(p) @ np.asarray(edge.dir_st) < edge.c_mm).reshape(near.shape)
    return near, beyond


def edge_depth_map(surface: Surface, rays: Rays, edge: Edge) -> np.ndarray:
    """float32 (H, W) depth (mm): the surface on its side of the edge, beyond it the surface
    moved ``drop_mm`` away from the camera; 0 where a ray misses."""
    near, beyond = _beyond(surface, rays, edge)
    far = surface.moved(-edge.drop_mm).depth_map(rays)
    return np.where(beyond | (near <= 0), far, near).astype(np.float32)


def edge_doc(edge: Edge, surface: Surface, rays: Rays) -> dict[str, Any]:
    """The truth document's ``edge``: the direction and offset in surface mm, the drop, the
    margin, and the share of the view beyond the edge."""
    near, beyond = _beyond(surface, rays, edge)
    ok = near > 0
    return {"dir_st": [round(v, 9) for v in edge.dir_st], "c_mm": round(edge.c_mm, 3),
            "drop_mm": edge.drop_mm, "margin_mm": round(edge.margin_mm, 3),
            "share_beyond": round(float(beyond[ok].mean()) if ok.any() else 0.0, 4)}

