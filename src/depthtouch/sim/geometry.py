"""Analytic scene geometry and vectorised ray casting.

Camera frame: X right, Y down, Z along the optical axis, millimetres. A pixel's ray is
``(x', y', 1)`` with ``x' = (col - cx) / fx``; a hit at range t along the unit ray has depth
``Z = t * dz``. Surfaces fill a whole depth map at once; primitives (capsules, spheres, boxes)
render only inside their projected bounding box and keep the nearest depth (a z-buffer) and a
label per pixel. Boxes are exact for spheres and capsules (tangent planes through the camera).

Surfaces are parametrised by (s, t) in mm on the surface: s along ``u`` (image right), t along
the surface in the ``v`` direction (image down; arc length on a cylinder).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import ConfigError

SURFACES: tuple[str, ...] = ("plane", "cylinder-convex", "cylinder-concave")


class Rays:
    """Per-pixel rays of a pinhole camera: normalised image coordinates and unit directions."""

    def __init__(self, K: np.ndarray, resolution_wh: tuple[int, int]) -> None:
        w, h = resolution_wh
        self.K = np.asarray(K, dtype=np.float64)
        self.w, self.h = int(w), int(h)
        fx, fy, cx, cy = self.K[0, 0], self.K[1, 1], self.K[0, 2], self.K[1, 2]
        self.fx, self.fy, self.cx, self.cy = float(fx), float(fy), float(cx), float(cy)
        xn = (np.arange(w, dtype=np.float64) - cx) / fx
        yn = (np.arange(h, dtype=np.float64) - cy) / fy
        self.xn, self.yn = np.meshgrid(xn, yn)
        inv = 1.0 / np.sqrt(self.xn**2 + self.yn**2 + 1.0)
        # unit directions in float32: primitives intersect in well-conditioned float32 forms
        self.dx = (self.xn * inv).astype(np.float32)
        self.dy = (self.yn * inv).astype(np.float32)
        self.dz = inv.astype(np.float32)

    def project(self, p_mm: np.ndarray) -> np.ndarray:
        """(N, 3) camera points -> (N, 2) pixel coordinates (x = column, y = row)."""
        p = np.atleast_2d(np.asarray(p_mm, dtype=np.float64))
        z = p[:, 2]
        return np.stack([self.fx * p[:, 0] / z + self.cx, self.fy * p[:, 1] / z + self.cy], 1)

    def ray(self, x_px: float, y_px: float) -> np.ndarray:
        """Unit direction of the ray through pixel (x, y) (sub-pixel)."""
        r = np.array([(x_px - self.cx) / self.fx, (y_px - self.cy) / self.fy, 1.0])
        return r / np.linalg.norm(r)


def rotation_x(deg: float) -> np.ndarray:
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rotation_xyz(deg_xyz: tuple[float, float, float]) -> np.ndarray:
    """Rotation by small angles about X, then Y, then Z (degrees)."""
    ax, ay, az = (math.radians(v) for v in deg_xyz)
    rx = np.array([[1, 0, 0], [0, math.cos(ax), -math.sin(ax)], [0, math.sin(ax), math.cos(ax)]])
    ry = np.array([[math.cos(ay), 0, math.sin(ay)], [0, 1, 0], [-math.sin(ay), 0, math.cos(ay)]])
    rz = np.array([[math.cos(az), -math.sin(az), 0], [math.sin(az), math.cos(az), 0], [0, 0, 1]])
    return rz @ ry @ rx


@dataclass(frozen=True)
class Surface:
    """The touch surface: a plane or a cylinder section (axis along ``u``), camera frame.

    kind: one of :data:`SURFACES`.
    origin_mm: the surface point (s, t) = (0, 0) (on the optical axis when built).
    u, v, n: orthonormal; n is the normal at the origin, pointing toward the camera.
    radius_mm: cylinder radius (inf for a plane). Convex bulges toward the camera, concave
        curves away from it at the middle (a trough seen from above).
    """

    kind: str
    origin_mm: np.ndarray
    u: np.ndarray
    v: np.ndarray
    n: np.ndarray
    radius_mm: float = math.inf

    @property
    def axis_point_mm(self) -> np.ndarray:
        sign = -1.0 if self.kind == "cylinder-convex" else 1.0
        return self.origin_mm + sign * self.radius_mm * self.n

    def point(self, st: np.ndarray) -> np.ndarray:
        """(N, 2) surface coordinates (mm) -> (N, 3) camera points (mm)."""
        st = np.atleast_2d(np.asarray(st, dtype=np.float64))
        s, t = st[:, :1], st[:, 1:2]
        if self.kind == "plane":
            return self.origin_mm + s * self.u + t * self.v
        r = self.radius_mm
        a = t / r
        c = self.axis_point_mm + s * self.u
        if self.kind == "cylinder-convex":
            return c + r * (np.cos(a) * self.n + np.sin(a) * self.v)
        return c + r * (-np.cos(a) * self.n + np.sin(a) * self.v)

    def normal(self, st: np.ndarray) -> np.ndarray:
        """(N, 3) unit normals at (N, 2) surface coordinates, toward the camera side."""
        st = np.atleast_2d(np.asarray(st, dtype=np.float64))
        if self.kind == "plane":
            return np.repeat(self.n[None, :], st.shape[0], axis=0)
        a = st[:, 1:2] / self.radius_mm
        if self.kind == "cylinder-convex":
            return np.cos(a) * self.n + np.sin(a) * self.v
        return np.cos(a) * self.n - np.sin(a) * self.v

    def tangent_t(self, st: np.ndarray) -> np.ndarray:
        """(N, 3) unit tangents along increasing t."""
        st = np.atleast_2d(np.asarray(st, dtype=np.float64))
        if self.kind == "plane":
            return np.repeat(self.v[None, :], st.shape[0], axis=0)
        a = st[:, 1:2] / self.radius_mm
        if self.kind == "cylinder-convex":
            return np.cos(a) * self.v - np.sin(a) * self.n
        return np.cos(a) * self.v + np.sin(a) * self.n

    def st_of(self, p_mm: np.ndarray) -> np.ndarray:
        """(N, 3) points on (or near) the surface -> (N, 2) surface coordinates."""
        p = np.atleast_2d(np.asarray(p_mm, dtype=np.float64))
        if self.kind == "plane":
            d = p - self.origin_mm
            return np.stack([d @ self.u, d @ self.v], 1)
        d = p - self.axis_point_mm
        s = d @ self.u
        if self.kind == "cylinder-convex":
            a = np.arctan2(d @ self.v, d @ self.n)
        else:
            a = np.arctan2(d @ self.v, -(d @ self.n))
        return np.stack([s, a * self.radius_mm], 1)

    def height_mm(self, p_mm: np.ndarray) -> np.ndarray:
        """Signed distance (mm) of (N, 3) points from the surface, positive on the camera side."""
        p = np.atleast_2d(np.asarray(p_mm, dtype=np.float64))
        if self.kind == "plane":
            return (p - self.origin_mm) @ self.n
        d = p - self.axis_point_mm
        d = d - np.outer(d @ self.u, self.u)
        rho = np.linalg.norm(d, axis=1)
        return rho - self.radius_mm if self.kind == "cylinder-convex" else self.radius_mm - rho

    def moved(self, offset_mm: float) -> Surface:
        """The same surface shifted by ``offset_mm`` along its normal (toward the camera)."""
        if offset_mm == 0.0:
            return self
        return replace(self, origin_mm=self.origin_mm + offset_mm * self.n)

    def rotated(self, R: np.ndarray) -> Surface:
        """The surface seen from a camera rotated so that camera points are ``R @ p``."""
        return replace(self, origin_mm=R @ self.origin_mm, u=R @ self.u, v=R @ self.v,
                       n=R @ self.n)

    def hit(self, ray_dir: np.ndarray) -> np.ndarray | None:
        """First intersection of one ray from the camera centre, or None."""
        r = np.asarray(ray_dir, dtype=np.float64)
        z = self._depth(np.array([[r[0] / r[2]]]), np.array([[r[1] / r[2]]]))[0, 0]
        return None if z <= 0 else r / r[2] * z

    def depth_map(self, rays: Rays) -> np.ndarray:
        """float32 (H, W) depth Z (mm) of the surface at every pixel; 0 where a ray misses."""
        return self._depth(rays.xn, rays.yn).astype(np.float32)

    def _depth(self, xn: np.ndarray, yn: np.ndarray) -> np.ndarray:
        n = self.n
        if self.kind == "plane":
            den = n[0] * xn + n[1] * yn + n[2]
            with np.errstate(divide="ignore", invalid="ignore"):
                z = (n @ self.origin_mm) / den
            return np.where(np.isfinite(z) & (z > 0), z, 0.0)
        # |Z r_perp - c_perp|^2 = R^2 with r = (x', y', 1), perp = without the axis component
        u, c = self.u, self.axis_point_mm
        ru = u[0] * xn + u[1] * yn + u[2]
        rpx, rpy, rpz = xn - ru * u[0], yn - ru * u[1], 1.0 - ru * u[2]
        cp = c - (c @ u) * u
        a = rpx * rpx + rpy * rpy + rpz * rpz
        b = rpx * cp[0] + rpy * cp[1] + rpz * cp[2]
        cc = cp @ cp - self.radius_mm**2
        disc = b * b - a * cc
        with np.errstate(invalid="ignore", divide="ignore"):
            root = np.sqrt(disc)
            z = (b - root) / a if self.kind == "cylinder-convex" else (b + root) / a
        return np.where((disc >= 0) & (z > 0), z, 0.0)


def make_surface(kind: str, distance_m: float, tilt_deg: float, radius_mm: float = 1000.0
                 ) -> Surface:
    """A surface whose origin is on the optical axis at ``distance_m``, tilted by ``tilt_deg``.

    Tilt rotates the surface about the camera's X axis so that the image bottom comes nearer
    (a table seen from its front edge; a wall seen from below). Distance 0.5-2.5 m, tilt 0-40 deg.
    """
    if kind not in SURFACES:
        raise ConfigError(f"unknown surface {kind!r}; use one of {', '.join(SURFACES)}")
    if not (0.5 <= distance_m <= 2.5):
        raise ConfigError(f"distance {distance_m!r} m is out of range; allowed [0.5, 2.5] m")
    if not (0.0 <= tilt_deg <= 40.0):
        raise ConfigError(f"tilt {tilt_deg!r} deg is out of range; allowed [0, 40] deg")
    R = rotation_x(-tilt_deg)
    return Surface(
        kind=kind,
        origin_mm=np.array([0.0, 0.0, distance_m * 1000.0]),
        u=np.array([1.0, 0.0, 0.0]),
        v=R @ np.array([0.0, 1.0, 0.0]),
        n=R @ np.array([0.0, 0.0, -1.0]),
        radius_mm=math.inf if kind == "plane" else float(radius_mm),
    )


# --- primitives -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Capsule:
    """Segment a-b (mm, camera frame) swept by a sphere of ``radius_mm``; ``label`` > 0.

    cap_a / cap_b: draw the end sphere; a chain of capsules needs each joint's sphere once.
    """

    a: np.ndarray
    b: np.ndarray
    radius_mm: float
    label: int
    cap_a: bool = True
    cap_b: bool = True

    def rotated(self, R: np.ndarray) -> Capsule:
        return replace(self, a=R @ self.a, b=R @ self.b)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        r = self.radius_mm
        return np.minimum(self.a, self.b) - r, np.maximum(self.a, self.b) + r

    def ray_t(self, dx: np.ndarray, dy: np.ndarray, dz: np.ndarray) -> np.ndarray:
        """Range along unit rays to the first hit (inf where none).

        Body: with w the unit axis, |t d_perp - a_perp|^2 = r^2 has discriminant
        |d_perp|^2 r^2 - (d . (a x w))^2 (Lagrange's identity), so every per-pixel term is a dot
        product of the ray with a constant vector: cheap and well conditioned in float32.
        """
        a, b, r = self.a, self.b, self.radius_mm
        if self.cap_a:
            t = _sphere_t(dx, dy, dz, a, r)
            if self.cap_b:
                np.minimum(t, _sphere_t(dx, dy, dz, b, r), out=t)
        elif self.cap_b:
            t = _sphere_t(dx, dy, dz, b, r)
        else:
            t = np.full(dx.shape, np.inf, np.float32)
        length = float(np.linalg.norm(b - a))
        if length < 1e-6:
            return t
        w = (b - a) / length
        m = (a[1] * w[2] - a[2] * w[1], a[2] * w[0] - a[0] * w[2], a[0] * w[1] - a[1] * w[0])
        aw = float(a @ w)
        f = np.float32
        dw = f(w[0]) * dx + f(w[1]) * dy + f(w[2]) * dz
        dm = f(m[0]) * dx + f(m[1]) * dy + f(m[2]) * dz
        da = f(a[0]) * dx + f(a[1]) * dy + f(a[2]) * dz
        q = f(1.0) - dw * dw
        h = q * f(r * r) - dm * dm
        ok = (h >= 0) & (q > f(1e-7))
        with np.errstate(invalid="ignore", divide="ignore"):
            tb = (da - dw * f(aw) - np.sqrt(h)) / q
        y = tb * dw - f(aw)
        ok &= (y >= 0) & (y <= f(length)) & (tb > 0) & (tb < t)
        np.copyto(t, tb, where=ok)
        return t


@dataclass(frozen=True)
class Sphere:
    """A sphere (mm, camera frame)."""

    center: np.ndarray
    radius_mm: float
    label: int

    def rotated(self, R: np.ndarray) -> Sphere:
        return replace(self, center=R @ self.center)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.center - self.radius_mm, self.center + self.radius_mm

    def ray_t(self, dx: np.ndarray, dy: np.ndarray, dz: np.ndarray) -> np.ndarray:
        return _sphere_t(dx, dy, dz, self.center, self.radius_mm)


@dataclass(frozen=True)
class Box:
    """An oriented box: centre, axes (3, 3) with unit columns, half sizes (mm)."""

    center: np.ndarray
    axes: np.ndarray
    half_mm: np.ndarray
    label: int

    def rotated(self, R: np.ndarray) -> Box:
        return replace(self, center=R @ self.center, axes=R @ self.axes)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        ext = np.abs(self.axes) @ self.half_mm
        return self.center - ext, self.center + ext

    def ray_t(self, dx: np.ndarray, dy: np.ndarray, dz: np.ndarray) -> np.ndarray:
        # slab test in box coordinates; the ray origin is the camera centre
        o = -(self.axes.T @ self.center)
        tnear = np.full(dx.shape, -np.inf, np.float32)
        tfar = np.full(dx.shape, np.inf, np.float32)
        for i in range(3):
            ax = self.axes[:, i]
            d = ax[0] * dx + ax[1] * dy + ax[2] * dz
            with np.errstate(divide="ignore", invalid="ignore"):
                t1 = (-self.half_mm[i] - o[i]) / d
                t2 = (self.half_mm[i] - o[i]) / d
            par = np.abs(d) < 1e-12
            inside = abs(o[i]) <= self.half_mm[i]
            # a ray parallel to a slab is inside it for all t, or never
            t1 = np.where(par, -np.inf if inside else np.inf, t1)
            t2 = np.where(par, np.inf, t2)
            np.maximum(tnear, np.minimum(t1, t2), out=tnear)
            np.minimum(tfar, np.maximum(t1, t2), out=tfar)
        ok = (tnear <= tfar) & (tnear > 0)
        return np.where(ok, tnear, np.inf)


Primitive = Capsule | Sphere | Box


def _sphere_t(dx: np.ndarray, dy: np.ndarray, dz: np.ndarray, c: np.ndarray, r: float
              ) -> np.ndarray:
    """Range along unit rays to a sphere (inf where missed), float32.

    |c|^2 - (d.c)^2 is formed as (|c| - d.c)(|c| + d.c), which keeps float32 accurate to
    ~0.01 mm at a metre.
    """
    f = np.float32
    dc = f(c[0]) * dx + f(c[1]) * dy + f(c[2]) * dz
    nc = f(np.linalg.norm(c))
    h = f(r * r) - (nc - dc) * (nc + dc)
    with np.errstate(invalid="ignore"):
        t = dc - np.sqrt(h)
    return np.where((h >= 0) & (t > 0), t, f(np.inf))


def bbox_px(prim: Primitive, rays: Rays) -> tuple[int, int, int, int] | None:
    """Pixel box (x0, y0, x1, y1), exclusive ends, covering the primitive; None if off-image."""
    if isinstance(prim, (Capsule, Sphere)):
        # a capsule's image is the hull of its end spheres' images; a sphere's image spans
        # x' = (cx cz +- r sqrt(cx^2 + cz^2 - r^2)) / (cz^2 - r^2) (the two tangent planes
        # through the camera), the same in y
        ends = (prim.a, prim.b) if isinstance(prim, Capsule) else (prim.center,)
        r = prim.radius_mm
        if min(float(e[2]) for e in ends) - r <= 1.0:
            return 0, 0, rays.w, rays.h
        xs: list[float] = []
        ys: list[float] = []
        for e in ends:
            cx, cy, cz = float(e[0]), float(e[1]), float(e[2])
            den = cz * cz - r * r
            for c, out in ((cx, xs), (cy, ys)):
                root = r * math.sqrt(c * c + cz * cz - r * r)
                out += [(c * cz - root) / den, (c * cz + root) / den]
        x0 = max(int(math.floor(rays.fx * min(xs) + rays.cx)) - 1, 0)
        y0 = max(int(math.floor(rays.fy * min(ys) + rays.cy)) - 1, 0)
        x1 = min(int(math.ceil(rays.fx * max(xs) + rays.cx)) + 2, rays.w)
        y1 = min(int(math.ceil(rays.fy * max(ys) + rays.cy)) + 2, rays.h)
        if x0 >= x1 or y0 >= y1:
            return None
        return x0, y0, x1, y1
    lo, hi = prim.bounds()
    if lo[2] <= 1.0:
        return 0, 0, rays.w, rays.h
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    px = rays.project(corners)
    x0 = max(int(math.floor(px[:, 0].min())), 0)
    y0 = max(int(math.floor(px[:, 1].min())), 0)
    x1 = min(int(math.ceil(px[:, 0].max())) + 1, rays.w)
    y1 = min(int(math.ceil(px[:, 1].max())) + 1, rays.h)
    if x0 >= x1 or y0 >= y1:
        return None
    return x0, y0, x1, y1


def render_primitives(
    rays: Rays, prims: list[Primitive], zbuf: np.ndarray, labels: np.ndarray
) -> tuple[int, int, int, int] | None:
    """Draw primitives into ``zbuf`` (float32 depth mm, updated in place) and ``labels``.

    Depth 0 in ``zbuf`` means "nothing", so anything in front of it wins there. Returns the
    pixel box (x0, y0, x1, y1) that holds every change, None when nothing was drawn.
    """
    union: list[int] | None = None
    for prim in prims:
        box = bbox_px(prim, rays)
        if box is None:
            continue
        x0, y0, x1, y1 = box
        sl = (slice(y0, y1), slice(x0, x1))
        t = prim.ray_t(rays.dx[sl], rays.dy[sl], rays.dz[sl])
        z = t * rays.dz[sl]
        cur = zbuf[sl]
        win = np.isfinite(z) & ((z < cur) | (cur <= 0))
        if not win.any():
            continue
        cur[win] = z[win]
        labels[sl][win] = prim.label
        if union is None:
            union = [x0, y0, x1, y1]
        else:
            union = [min(union[0], x0), min(union[1], y0), max(union[2], x1),
                     max(union[3], y1)]
    return None if union is None else (union[0], union[1], union[2], union[3])
