"""The contact under a fingertip: the touch point moved from the tip's image to the surface.

The touch point is found in the image, on the fingertip's pixels: it is the image of a point on
the finger's axis, about a finger radius above the surface, not of the contact beneath it. Where
the camera looks at the surface obliquely (a tilted wall, a camera off to the side, the edge of a
wide view), the surface point on that pixel's ray lies beyond the contact, away from the camera,
by ``h · tan(θ)`` (h the axis' height, θ the angle between the ray and the surface normal):
about 5 mm for h = 9 mm at 30°, far more than the tip's noise. Measured on the hard suite's
tune half, the error along that direction grows with tan θ as if h were 9 mm
(docs/accuracy.md, section 7, session 8).

:func:`foot_px` moves a point to the pixel of the surface point beneath it: the point at height
h on the pixel's ray, dropped along the surface normal. Straight above the surface (θ = 0) the
point does not move. The normals are those of the surface as learned (an object absorbed into
the surface later keeps the normals of the surface under it). Pure; a few points per frame,
compiled with numba (cached on disk) like the fingertip kernel.
"""

from __future__ import annotations

import numba
import numpy as np

from ..surface.bounds import BandBounds


def foot_px(xy_px: np.ndarray, bounds: BandBounds, height_mm: float) -> np.ndarray:
    """The pixels of the surface points beneath the points seen at ``xy_px`` (N, 2) at
    ``height_mm`` above the surface (see the module doc), float64 (N, 2).

    A point stays where it is when the surface has no intrinsics or normals, when the surface is
    unknown at its pixel, or when ``height_mm`` is 0.
    """
    xy = np.ascontiguousarray(np.asarray(xy_px, np.float64).reshape(-1, 2))
    out = xy.copy()
    K, normals = bounds.K, bounds.normals
    if height_mm == 0.0 or K is None or normals is None or xy.shape[0] == 0:
        return out
    (fx, _, cx), (_, fy, cy), _ = K.tolist()
    _foot(xy, fx, fy, cx, cy, bounds.surface_mm, bounds.valid, normals, float(height_mm), out)
    return out


@numba.njit(cache=True, nogil=True)
def _foot(xy: np.ndarray, fx: float, fy: float, cx: float, cy: float, depth: np.ndarray,
          valid: np.ndarray, normals: np.ndarray, height_mm: float, out: np.ndarray) -> None:
    """:func:`foot_px`'s per-point step (``out`` holds the points on entry; a point whose pixel
    has no usable surface, or a NaN point, stays). Compiled: a handful of points, but a Python
    loop over them cost 0.01 ms a frame."""
    h1, w1 = depth.shape[0] - 1, depth.shape[1] - 1
    for i in range(xy.shape[0]):
        x, y = xy[i, 0], xy[i, 1]
        if not (x == x and y == y):
            continue
        # the shift is computed at the centre of the point's pixel, where the surface depth is
        # known, and applied to the point (it changes by far less than a pixel from one pixel
        # to the next)
        ix = min(max(round(x), 0), w1)
        iy = min(max(round(y), 0), h1)
        z = float(depth[iy, ix])
        if not valid[iy, ix] or z <= 0.0:
            continue
        # toward the camera
        nx, ny, nz = float(normals[iy, ix, 0]), float(normals[iy, ix, 1]), float(normals[iy, ix, 2])
        # the ray through the pixel's centre, scaled so that its depth is 1 mm, and the height
        # it gains per mm of depth toward the camera
        rx, ry = (ix - cx) / fx, (iy - cy) / fy
        toward = -(nx * rx + ny * ry + nz)
        if toward <= 1e-3:
            continue
        # the point at height h on the ray (from the surface point, toward the camera), then
        # down along the normal to the surface
        t = z - height_mm / toward
        fx3, fy3, fz3 = rx * t - height_mm * nx, ry * t - height_mm * ny, t - height_mm * nz
        if fz3 <= 0.0:
            continue
        out[i, 0] = x + fx * fx3 / fz3 + cx - ix
        out[i, 1] = y + fy * fy3 / fz3 + cy - iy


def warm_up() -> None:
    """Compile (or load from the on-disk cache) this module's kernel (see
    :func:`tipkernel.warm_up`)."""
    one = np.ones((2, 2), np.float32)
    _foot(np.zeros((1, 2)), 1.0, 1.0, 0.0, 0.0, one, one > 0, np.ones((2, 2, 3), np.float32),
          9.0, np.zeros((1, 2)))
