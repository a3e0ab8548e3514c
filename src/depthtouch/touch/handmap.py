"""The hand map: where hands and arms are, at 1/4 resolution, for the touch points.

A touch region counts only when it is attached to a hand; a hand is something raised above the
band (or too near for the camera to measure) that reaches into the view from its border, or a
raised part as large as a palm. The map is kept at 1/4 resolution, labelled, and each part gets
a level (2 = reaching in from the border, 1 = palm-sized, 0 = no hand); the fingertip kernel
(:mod:`depthtouch.touch.tipkernel`) looks up the level of the hand pixels next to each region.
Compiled with numba (cached on disk) like the kernel.
"""

from __future__ import annotations

import numba
import numpy as np

from ..runs import dilate3x3, part_levels
from ..surface.bounds import HAND_SCALE, BandBounds

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
    level = part_levels(dilate3x3(_raised(depth, hand_lo, hand_hi, hand_valid)),
                        _S * _S * px_mm2, min_hand_mm2)
    return dilate3x3(level)


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


def warm_up() -> None:
    """Compile (or load from the on-disk cache) this module's kernels (see
    :func:`tipkernel.warm_up`)."""
    z = np.zeros((8, 8), np.uint16)
    zs = np.zeros((4, 2, 2), np.uint16)
    hand_levels(z, zs, zs, np.ones((2, 2), np.bool_), 1.0, 100.0)
