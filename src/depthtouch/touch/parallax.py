"""The contact under a fingertip: the touch point moved from the tip's image to the surface.

The touch point is found in the image, on the fingertip's pixels: it is the image of a point on
the finger's axis, about a finger radius above the surface, not of the contact beneath it. Where
the camera looks at the surface obliquely (a tilted wall, a camera off to the side, the edge of a
wide view), the surface point on that pixel's ray lies beyond the contact, away from the camera,
by ``h · tan(θ)`` (h the axis' height, θ the angle between the ray and the surface normal):
about 5 mm for h = 9 mm at 30°, far more than the tip's noise. Measured on the hard suite's
tune half, the error along that direction grows with tan θ as if h were 9 mm
(docs/accuracy.md, section 8).

:func:`foot_px` moves a point to the pixel of the surface point beneath it: the point at height
h on the pixel's ray, dropped along the surface normal. Straight above the surface (θ = 0) the
point does not move. Pure; a few points per frame, plain arrays.
"""

from __future__ import annotations

import numpy as np

from ..surface.bounds import BandBounds


def foot_px(xy_px: np.ndarray, bounds: BandBounds, height_mm: float) -> np.ndarray:
    """The pixels of the surface points beneath the points seen at ``xy_px`` (N, 2) at
    ``height_mm`` above the surface (see the module doc), float64 (N, 2).

    A point stays where it is when the surface has no intrinsics or normals, when the surface is
    unknown at its pixel, or when ``height_mm`` is 0.
    """
    xy = np.asarray(xy_px, np.float64).reshape(-1, 2)
    K, normals = bounds.K, bounds.normals
    if height_mm == 0.0 or K is None or normals is None or xy.shape[0] == 0:
        return xy.copy()
    h, w = bounds.surface_mm.shape
    ix = np.clip(np.rint(xy[:, 0]).astype(np.int64), 0, w - 1)
    iy = np.clip(np.rint(xy[:, 1]).astype(np.int64), 0, h - 1)
    z = bounds.surface_mm[iy, ix].astype(np.float64)
    n = normals[iy, ix].astype(np.float64)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    # the shift is computed at the centre of the point's pixel, where the surface depth is known,
    # and applied to the point (it changes by far less than a pixel from one pixel to the next)
    px, py = ix.astype(np.float64), iy.astype(np.float64)
    # the ray through the pixel, scaled so that its depth is 1 mm; n points toward the camera
    ray = np.stack([(px - cx) / fx, (py - cy) / fy, np.ones(len(xy))], axis=1)
    toward = -np.sum(n * ray, axis=1)  # height gained per mm of depth toward the camera
    ok = bounds.valid[iy, ix] & (z > 0) & (toward > 1e-3)
    # the point at height h on the ray (from the surface point, toward the camera), then down
    # along the normal to the surface
    s = np.where(ok, z - height_mm / np.where(ok, toward, 1.0), 1.0)
    foot = ray * s[:, None] - height_mm * n
    out = xy.copy()
    zf = foot[:, 2]
    ok &= zf > 0
    out[ok, 0] += fx * foot[ok, 0] / zf[ok] + cx - px[ok]
    out[ok, 1] += fy * foot[ok, 1] / zf[ok] + cy - py[ok]
    return out
