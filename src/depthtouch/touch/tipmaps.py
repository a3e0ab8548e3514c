"""Window maps for the tip kernel (:mod:`depthtouch.touch.tipkernel`), compiled with numba:
heights above the surface (one pixel, a 3x3 mean, a whole window smoothed), the pixels near a
mask, the distance to a mask, and how level it is behind a tip.

numba's on-disk cache of :func:`tipkernel._frame_points` does not notice edits to this file (a
cached function is keyed on its own file only): after editing here, delete
``src/depthtouch/touch/__pycache__/*.nb[ic]``, or the old code keeps running.
"""

from __future__ import annotations

import numba
import numpy as np

#: where the heights behind a tip are read (mm back along the finger's axis; the sides are
#: read this far back and this far to either side)
_BACK_ALONG_MM = (10.0, 15.0, 20.0, 30.0, 40.0)
_BACK_SIDE_MM = 20.0
_A, _B = 0.955, 1.3693  # OpenCV's 3x3 distance-transform weights (DIST_L2, mask 3)
_INF = 1e30


@numba.njit(cache=True, nogil=True)
def near_mask(mask: np.ndarray, r: int) -> np.ndarray:
    """1 where a pixel of ``mask`` lies within chessboard distance ``r`` (the (2r+1)^2 square
    around), from the mask's summed-area table: two passes whatever r."""
    h, w = mask.shape
    S = np.zeros((h + 1, w + 1), np.int32)
    for y in range(h):
        acc = 0
        for x in range(w):
            acc += mask[y, x] != 0
            S[y + 1, x + 1] = S[y, x + 1] + acc
    out = np.empty((h, w), np.uint8)
    for y in range(h):
        ya, yb = max(0, y - r), min(h, y + r + 1)
        for x in range(w):
            xa, xb = max(0, x - r), min(w, x + r + 1)
            out[y, x] = (S[yb, xb] - S[ya, xb] - S[yb, xa] + S[ya, xa]) > 0
    return out


@numba.njit(cache=True, nogil=True)
def chamfer(mask: np.ndarray) -> np.ndarray:
    """Approximate Euclidean distance (px) to the nearest pixel of ``mask`` (3x3 chamfer)."""
    h, w = mask.shape
    d = np.full((h, w), _INF, np.float64)
    for y in range(h):
        for x in range(w):
            if mask[y, x]:
                d[y, x] = 0.0
                continue
            v = d[y, x]
            if x > 0:
                v = min(v, d[y, x - 1] + _A)
            if y > 0:
                v = min(v, d[y - 1, x] + _A)
                if x > 0:
                    v = min(v, d[y - 1, x - 1] + _B)
                if x < w - 1:
                    v = min(v, d[y - 1, x + 1] + _B)
            d[y, x] = v
    for y in range(h - 1, -1, -1):
        for x in range(w - 1, -1, -1):
            v = d[y, x]
            if x < w - 1:
                v = min(v, d[y, x + 1] + _A)
            if y < h - 1:
                v = min(v, d[y + 1, x] + _A)
                if x < w - 1:
                    v = min(v, d[y + 1, x + 1] + _B)
                if x > 0:
                    v = min(v, d[y + 1, x - 1] + _B)
            d[y, x] = v
    return d


@numba.njit(cache=True, nogil=True, inline="always")
def pixel_height(d: int, surf_mm: float, factor: float, to_mm: float) -> float:
    """Height (mm) above the surface of one known pixel of depth ``d`` (camera units): the
    kernel's form of :func:`depthtouch.surface.bounds.height_mm`."""
    return (surf_mm - d * to_mm) * factor


@numba.njit(cache=True, nogil=True)
def smooth_heights(depth: np.ndarray, surf: np.ndarray, fact: np.ndarray, valid: np.ndarray,
                    to_mm: float, x0: int, y0: int, h: int, w: int) -> np.ndarray:
    """Height (mm) over the window, 3x3 mean of the known pixels of the window; NaN where fewer
    than 3 of 9 are known. (Sums over a copy with a ring of unknown pixels: no edge cases.)"""
    hm = np.zeros((h + 2, w + 2), np.float64)
    ok = np.zeros((h + 2, w + 2), np.float64)
    for y in range(h):
        dr, vr, sr, fr = depth[y0 + y], valid[y0 + y], surf[y0 + y], fact[y0 + y]
        for x in range(w):
            d = dr[x0 + x]
            if d > 0 and vr[x0 + x]:
                hm[y + 1, x + 1] = pixel_height(d, sr[x0 + x], fr[x0 + x], to_mm)
                ok[y + 1, x + 1] = 1.0
    rs = np.empty((h + 2, w), np.float64)
    rc = np.empty((h + 2, w), np.float64)
    for y in range(h + 2):
        a, c, sa, sc = hm[y], ok[y], rs[y], rc[y]
        for x in range(w):
            sa[x] = a[x] + a[x + 1] + a[x + 2]
            sc[x] = c[x] + c[x + 1] + c[x + 2]
    out = np.empty((h, w), np.float64)
    for y in range(h):
        for x in range(w):
            num = rs[y, x] + rs[y + 1, x] + rs[y + 2, x]
            den = rc[y, x] + rc[y + 1, x] + rc[y + 2, x]
            out[y, x] = num / den if den >= 2.5 else np.nan  # at least 3 of 9 known
    return out


@numba.njit(cache=True, nogil=True)
def core_heights(depth: np.ndarray, surf: np.ndarray, fact: np.ndarray, valid: np.ndarray,
                 to_mm: float, xy: np.ndarray, out: np.ndarray) -> None:
    """``out[i]``: the 75th percentile (linear, as ``np.nanpercentile``) of the known heights of
    the 3x3 pixels around point ``xy[i]``'s nearest pixel, the window clamped to the image; NaN
    where none is known (:func:`depthtouch.touch.points.core_heights_mm`)."""
    H, W = depth.shape
    vals = np.empty(9)
    for i in range(xy.shape[0]):
        cx = min(max(int(round(xy[i, 0])), 0), W - 1)
        cy = min(max(int(round(xy[i, 1])), 0), H - 1)
        k = 0
        for dy in range(-1, 2):
            yy = min(max(cy + dy, 0), H - 1)
            for dx in range(-1, 2):
                xx = min(max(cx + dx, 0), W - 1)
                d = depth[yy, xx]
                if d == 0 or not valid[yy, xx]:
                    continue
                v = pixel_height(d, surf[yy, xx], fact[yy, xx], to_mm)
                j = k  # insertion sort: 9 values at most
                while j > 0 and vals[j - 1] > v:
                    vals[j] = vals[j - 1]
                    j -= 1
                vals[j] = v
                k += 1
        if k == 0:
            out[i] = np.nan
            continue
        pos = 0.75 * (k - 1)
        lo = int(pos)
        hi = min(lo + 1, k - 1)
        out[i] = vals[lo] + (pos - lo) * (vals[hi] - vals[lo])


@numba.njit(cache=True, nogil=True)
def height_at(depth: np.ndarray, surf: np.ndarray, fact: np.ndarray, valid: np.ndarray,
               to_mm: float, x: float, y: float) -> float:
    """Height (mm) at image point (x, y): the mean of the known pixels of the 3x3 around it;
    NaN outside the image or where fewer than 3 of 9 are known."""
    H, W = depth.shape
    xi, yi = int(round(x)), int(round(y))
    if xi < 1 or yi < 1 or xi > W - 2 or yi > H - 2:
        return np.nan
    acc = 0.0
    n = 0
    for yy in range(yi - 1, yi + 2):
        for xx in range(xi - 1, xi + 2):
            d = depth[yy, xx]
            if d > 0 and valid[yy, xx]:
                acc += pixel_height(d, surf[yy, xx], fact[yy, xx], to_mm)
                n += 1
    return acc / n if n >= 3 else np.nan


@numba.njit(cache=True, nogil=True)
def back_spread(depth: np.ndarray, surf: np.ndarray, fact: np.ndarray, valid: np.ndarray,
                 to_mm: float, tx: float, ty: float, ux: float, uy: float, mm_px: float
                 ) -> float:
    """How level it is behind a tip at (tx, ty) whose finger points along (ux, uy): the spread
    (max - min, mm) of the heights 10, 15, 20, 30 and 40 mm back on its axis, and of the one of
    the two heights 20 mm back and 20 mm to either side that is nearer to them. A finger rises
    behind its tip and is narrow: beside it lies the surface, so its spread is at least the
    finger's height there (>= 12 mm, flat or steep). The top of a flat object held at Tu (a
    book) or the flank of a resting forearm is level along the axis and on at least one side
    (0-3 mm). NaN when fewer than 4 of the 5 heights on the axis are known."""
    lo = np.inf
    hi = -np.inf
    acc = 0.0
    n = 0
    for a in _BACK_ALONG_MM:
        v = height_at(depth, surf, fact, valid, to_mm, tx - a * ux / mm_px, ty - a * uy / mm_px)
        if v == v:
            lo = min(lo, v)
            hi = max(hi, v)
            acc += v
            n += 1
    if n < 4:
        return np.nan
    mid = acc / n
    bx, by = tx - _BACK_SIDE_MM * ux / mm_px, ty - _BACK_SIDE_MM * uy / mm_px
    side = np.nan
    for sgn in (-1.0, 1.0):
        v = height_at(depth, surf, fact, valid, to_mm, bx - sgn * _BACK_SIDE_MM * uy / mm_px,
                       by + sgn * _BACK_SIDE_MM * ux / mm_px)
        if v == v and not abs(side - mid) <= abs(v - mid):
            side = v
    if side != side:  # nothing known beside the axis: take it as not level
        return np.inf
    return max(hi, side) - min(lo, side)
