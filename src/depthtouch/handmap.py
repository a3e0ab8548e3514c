"""The hand map: where hands and arms are, at 1/4 resolution, for the touch points.

A touch region counts only when it is attached to a hand; a hand is something raised above the
band (or too near for the camera to measure) that reaches into the view from its border, or a
raised part as large as a palm. The map is kept at 1/4 resolution, labelled, and each part gets
a level (2 = reaching in from the border, 1 = palm-sized, 0 = no hand); the fingertip kernel
(:mod:`depthtouch.tipkernel`) looks up the level of the hand pixels next to each region.
Compiled with numba (cached on disk) like the kernel.
"""

from __future__ import annotations

import numba
import numpy as np

from .regions import HAND_SCALE, BandBounds

_DY8 = np.array([-1, -1, -1, 0, 0, 1, 1, 1])
_DX8 = np.array([-1, 0, 1, -1, 1, -1, 0, 1])


def hand_map(depth: np.ndarray, bounds: BandBounds) -> np.ndarray:
    """Where hands are, at 1/4 resolution (uint8: 2 = connected to the image border, 1 = large
    enough to be a hand, 0 = no hand); see :func:`hand_levels`.

    People reach into the view from outside it, so a hand is normally attached, through its arm,
    to the border; an object standing on the surface, tall or not, is not. Where the view is so
    wide that a whole arm is in it, a raised part of at least ``min_hand_mm2`` counts too (a tall
    object that large counts until the surface absorbs it, about a second after it was put down).
    """
    if bounds.hand_lo is None or bounds.hand_hi is None or bounds.hand_valid is None:
        raise ValueError("hand_map: bounds without hand samples (made by regions.band_bounds)")
    return hand_levels(depth, bounds.hand_lo, bounds.hand_hi, bounds.hand_valid, HAND_SCALE,
                       float(bounds.mm_per_px) ** 2, float(bounds.min_hand_mm2))


@numba.njit(cache=True, nogil=True)
def hand_levels(depth: np.ndarray, hand_lo: np.ndarray, hand_hi: np.ndarray,
                hand_valid: np.ndarray, scale: int, px_mm2: float, min_hand_mm2: float
                ) -> np.ndarray:
    """Where hands are, at 1/scale resolution (uint8: 2 = part of something reaching in from
    the image border, 1 = a raised part large enough to be a hand, 0 = no hand).

    A coarse pixel is raised when any of the two middle rows and columns of its block is
    above Tu (a bilinear sample between them; thin fingers stay connected; ``hand_lo`` and
    ``hand_hi``: the depth bounds of being above Tu at those 4 pixels, (h/s, w/s, 4)), or when
    its corner pixel has no depth over a usable surface pixel (``hand_valid``; an arm close to
    the camera is often nearer than the camera measures). The raised map is dilated by one
    coarse pixel, labelled (8-neighbours), and each part is given its level; the level map is
    dilated once more, so that the coarse grid does not cut off the last pixels of an arm next
    to a fingertip. ``px_mm2``: area of one full-resolution pixel on the surface (mm^2).
    """
    H, W = depth.shape
    sh, sw = hand_lo.shape[0], hand_lo.shape[1]
    raw = np.zeros((sh, sw), np.uint8)
    c0 = scale // 2 - 1 if scale % 2 == 0 else scale // 2
    c1 = scale // 2
    for j in range(sh):
        ya, yb = min(H - 1, scale * j + c0), min(H - 1, scale * j + c1)
        for i in range(sw):
            xa, xb = min(W - 1, scale * i + c0), min(W - 1, scale * i + c1)
            d0, d1, d2, d3 = depth[ya, xa], depth[ya, xb], depth[yb, xa], depth[yb, xb]
            hit = ((hand_lo[j, i, 0] <= d0 and d0 <= hand_hi[j, i, 0])
                   or (hand_lo[j, i, 1] <= d1 and d1 <= hand_hi[j, i, 1])
                   or (hand_lo[j, i, 2] <= d2 and d2 <= hand_hi[j, i, 2])
                   or (hand_lo[j, i, 3] <= d3 and d3 <= hand_hi[j, i, 3]))
            if not hit:
                hit = depth[scale * j, scale * i] == 0 and hand_valid[j, i]
            if hit:
                raw[j, i] = 1
    small = _dilate_max(raw)
    labels = np.zeros((sh, sw), np.int32)
    stack_y = np.empty(sh * sw, np.int64)
    stack_x = np.empty(sh * sw, np.int64)
    level_of = np.zeros(sh * sw + 1, np.uint8)
    n_lab = 0
    for j in range(sh):
        for i in range(sw):
            if not small[j, i] or labels[j, i]:
                continue
            n_lab += 1
            labels[j, i] = n_lab
            stack_y[0], stack_x[0] = j, i
            top = 1
            area = 0
            border = False
            while top > 0:
                top -= 1
                y, x = stack_y[top], stack_x[top]
                area += 1
                if y == 0 or x == 0 or y == sh - 1 or x == sw - 1:
                    border = True
                for k in range(8):
                    yy = y + _DY8[k]
                    xx = x + _DX8[k]
                    if 0 <= yy < sh and 0 <= xx < sw and small[yy, xx] and not labels[yy, xx]:
                        labels[yy, xx] = n_lab
                        stack_y[top], stack_x[top] = yy, xx
                        top += 1
            if border:
                level_of[n_lab] = 2
            elif area * scale * scale * px_mm2 >= min_hand_mm2:
                level_of[n_lab] = 1
    lev = np.zeros((sh, sw), np.uint8)
    for j in range(sh):
        for i in range(sw):
            lev[j, i] = level_of[labels[j, i]]
    return _dilate_max(lev)


@numba.njit(cache=True, nogil=True)
def _dilate_max(a: np.ndarray) -> np.ndarray:
    """3x3 maximum filter (pixels outside count as 0); a row pass then a column pass."""
    h, w = a.shape
    t = np.empty((h, w), np.uint8)
    for y in range(h):
        for x in range(w):
            v = a[y, x]
            if x > 0 and a[y, x - 1] > v:
                v = a[y, x - 1]
            if x < w - 1 and a[y, x + 1] > v:
                v = a[y, x + 1]
            t[y, x] = v
    out = np.empty((h, w), np.uint8)
    for y in range(h):
        for x in range(w):
            v = t[y, x]
            if y > 0 and t[y - 1, x] > v:
                v = t[y - 1, x]
            if y < h - 1 and t[y + 1, x] > v:
                v = t[y + 1, x]
            out[y, x] = v
    return out


def warm_up() -> None:
    """Compile (or load from the on-disk cache) this module's kernels (see
    :func:`tipkernel.warm_up`)."""
    z = np.zeros((8, 8), np.uint16)
    zs = np.zeros((2, 2, 4), np.uint16)
    hand_levels(z, zs, zs, np.ones((2, 2), np.bool_), HAND_SCALE, 1.0, 100.0)
