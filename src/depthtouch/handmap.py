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
from .runs import label_runs, row_runs

_S = HAND_SCALE  # a compile-time constant in the kernels below
_C0 = _S // 2 - 1 if _S % 2 == 0 else _S // 2  # the two middle rows / columns of a block
_C1 = _S // 2


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
    return hand_levels(depth, bounds.hand_lo, bounds.hand_hi, bounds.hand_valid,
                       float(bounds.mm_per_px) ** 2, float(bounds.min_hand_mm2))


@numba.njit(cache=True, nogil=True)
def hand_levels(depth: np.ndarray, hand_lo: np.ndarray, hand_hi: np.ndarray,
                hand_valid: np.ndarray, px_mm2: float, min_hand_mm2: float) -> np.ndarray:
    """Where hands are, at 1/4 resolution (uint8: 2 = part of something reaching in from
    the image border, 1 = a raised part large enough to be a hand, 0 = no hand).

    A coarse pixel is raised when any of the two middle rows and columns of its block is
    above Tu (a bilinear sample between them; thin fingers stay connected; ``hand_lo`` and
    ``hand_hi``: the depth bounds of being above Tu at those 4 pixels, 4 planes (4, h/4, w/4)),
    or when its corner pixel has no depth over a usable surface pixel (``hand_valid``; an arm
    close to the camera is often nearer than the camera measures). The raised map is dilated by
    one coarse pixel, labelled (8-neighbours), and each part is given its level; the level map
    is dilated once more, so that the coarse grid does not cut off the last pixels of an arm
    next to a fingertip. ``px_mm2``: area of one full-resolution pixel on the surface (mm^2).
    """
    return _dilate_max(_levels(_dilate_max(_raised(depth, hand_lo, hand_hi, hand_valid)),
                               px_mm2, min_hand_mm2))


@numba.njit(cache=True, nogil=True)
def _raised(depth: np.ndarray, lo: np.ndarray, hi: np.ndarray, hand_valid: np.ndarray
            ) -> np.ndarray:
    """The raised coarse pixels (see :func:`hand_levels`). The block size is the constant
    ``HAND_SCALE``: with it known when compiling, the sampling loop is vectorised (5x faster)."""
    H, W = depth.shape
    sh, sw = lo.shape[1], lo.shape[2]
    raw = np.empty((sh, sw), np.uint8)
    for j in range(sh):
        ra = depth[min(H - 1, _S * j + _C0)]
        rb = depth[min(H - 1, _S * j + _C1)]
        rc = depth[_S * j]
        lo0, lo1, lo2, lo3 = lo[0, j], lo[1, j], lo[2, j], lo[3, j]
        hi0, hi1, hi2, hi3 = hi[0, j], hi[1, j], hi[2, j], hi[3, j]
        ok = hand_valid[j]
        if W >= _S:
            for i in range(sw):
                xa = _S * i + _C0
                xb = _S * i + _C1
                d0, d1, d2, d3 = ra[xa], ra[xb], rb[xa], rb[xb]
                raw[j, i] = (((lo0[i] <= d0) & (d0 <= hi0[i])) | ((lo1[i] <= d1) & (d1 <= hi1[i]))
                             | ((lo2[i] <= d2) & (d2 <= hi2[i])) | ((lo3[i] <= d3) & (d3 <= hi3[i]))
                             | ((rc[_S * i] == 0) & ok[i]))
        else:  # a frame narrower than one block (tests): clamp the columns
            for i in range(sw):
                xa, xb = min(W - 1, _S * i + _C0), min(W - 1, _S * i + _C1)
                d0, d1, d2, d3 = ra[xa], ra[xb], rb[xa], rb[xb]
                raw[j, i] = (((lo0[i] <= d0) & (d0 <= hi0[i])) | ((lo1[i] <= d1) & (d1 <= hi1[i]))
                             | ((lo2[i] <= d2) & (d2 <= hi2[i])) | ((lo3[i] <= d3) & (d3 <= hi3[i]))
                             | ((rc[_S * i] == 0) & ok[i]))
    return raw


@numba.njit(cache=True, nogil=True)
def _levels(small: np.ndarray, px_mm2: float, min_hand_mm2: float) -> np.ndarray:
    """Level of each part (8-connected) of a coarse mask: 2 when it touches the image border,
    1 when its area is at least ``min_hand_mm2``, else 0. The parts are labelled by runs (see
    :func:`runs.label_runs`): a few hundred runs instead of a flood over every pixel."""
    sh, sw = small.shape
    runs = np.empty((sh * (sw // 2 + 1), 3), np.int64)
    n = 0
    for j in range(sh):
        n = row_runs(small[j], j, runs, n)
    comp, n_comp = label_runs(runs[:n])
    area = np.zeros(n_comp, np.int64)
    border = np.zeros(n_comp, np.bool_)
    for r in range(n):
        c = comp[r]
        area[c] += runs[r, 2] - runs[r, 1]
        if runs[r, 0] == 0 or runs[r, 0] == sh - 1 or runs[r, 1] == 0 or runs[r, 2] == sw:
            border[c] = True
    lev = np.zeros((sh, sw), np.uint8)
    for r in range(n):
        c = comp[r]
        v = 2 if border[c] else (1 if area[c] * _S * _S * px_mm2 >= min_hand_mm2 else 0)
        lev[runs[r, 0], runs[r, 1]:runs[r, 2]] = v
    return lev


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
    zs = np.zeros((4, 2, 2), np.uint16)
    hand_levels(z, zs, zs, np.ones((2, 2), np.bool_), 1.0, 100.0)
