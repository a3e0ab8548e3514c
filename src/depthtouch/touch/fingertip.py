"""Fingertip estimators inside one touch region (compiled with numba, cached on disk).

Called by :mod:`depthtouch.touch.tipkernel` for each region of a frame, on a window around it:

- :func:`split`: fingertips side by side that merged into one region, told apart by the bumps of
  the region's front seen from the hand.
- :func:`extremity`: the default contact point, the centre of the rounded tip behind its front
  edge (sub-pixel), and the tip's height.
- :func:`paper`: the paper's touch pixel (Lee & Kwon 2019): a search band inside the bounding
  box's edge away from the hand, candidates near the surface, 3x3 block patterns.

Window coordinates throughout; ``hs`` is the window's smoothed height map (mm, NaN unknown).

numba's on-disk cache of :func:`tipkernel._frame_points` does not notice edits to this file (a
cached function is keyed on its own file only): after editing here, delete
``src/depthtouch/touch/__pycache__/*.nb[ic]``, or the old code keeps running.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def split(lat: np.ndarray, s: np.ndarray, r0: float) -> np.ndarray:
    """Part index (0..) of each region pixel: fingertips side by side merged into one region.

    Seen along the finger direction (from the hand), the region's front, per 1-px lateral slice
    (``lat``), has one bump per fingertip (tips are round). Bumps at least 1.6 tip radii apart
    with a notch of at least half a radius between them are separate fingers, cut at the notch.
    The notch is measured below the chord from one bump to the other (the front's convex hull),
    not below the lower bump: a single tip's front is a dome (no point of it lies below a chord)
    and stays whole, and so does a finger seen at a slant (a ramp).
    """
    n = lat.shape[0]
    lmin = lat.min()
    lb = np.empty(n, np.int64)
    for i in range(n):
        lb[i] = int(lat[i] - lmin)
    m = lb.max() + 1
    front = np.full(m, -np.inf)
    for i in range(n):
        if s[i] > front[lb[i]]:
            front[lb[i]] = s[i]
    # a bump is the highest slice within half a tip radius either side: that stays on the tip's
    # own dome, while a wider window reaches the flank of a longer finger beside it
    w = max(1, int(math.ceil(0.5 * r0)))
    cuts = np.empty(m, np.int64)
    n_cuts = 0
    last = -1
    for p in range(m):
        if not np.isfinite(front[p]):
            continue
        top = -np.inf
        for q in range(max(0, p - w), min(m, p + w + 1)):
            top = max(top, front[q])
        if front[p] != top:
            continue  # not a peak
        if last >= 0 and p - last >= 1.6 * r0:
            # the notch below the chord from one bump to the other: fingers of different
            # lengths stand staggered, and the shorter one's tip rises little above the notch
            valley = last
            deepest = -np.inf
            for q in range(last, p + 1):
                chord = front[last] + (front[p] - front[last]) * (q - last) / (p - last)
                if chord - front[q] > deepest:
                    deepest = chord - front[q]
                    valley = q
            if deepest >= 0.5 * r0:
                cuts[n_cuts] = valley
                n_cuts += 1
                last = p
                continue
        if last < 0 or front[p] > front[last]:
            last = p
    part = np.zeros(n, np.int64)
    for i in range(n):
        for c in range(n_cuts):
            if lb[i] > cuts[c]:
                part[i] += 1
    return part


@numba.njit(cache=True, nogil=True)
def project(xs: np.ndarray, ys: np.ndarray, hx: float, hy: float, ux: float, uy: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """(s, lat): pixels along the unit direction (ux, uy) from the hand at (hx, hy), and
    across it."""
    n = xs.shape[0]
    s = np.empty(n)
    lat = np.empty(n)
    for i in range(n):
        px, py = xs[i] - hx, ys[i] - hy
        s[i] = px * ux + py * uy
        lat[i] = py * ux - px * uy
    return s, lat


@numba.njit(cache=True, nogil=True)
def extremity(finger_x: np.ndarray, finger_y: np.ndarray, firm: np.ndarray, hs: np.ndarray,
              hx: float, hy: float, ux: float, uy: float, r0: float
              ) -> tuple[float, float, float]:
    """Contact point (window px) and tip height of one finger's pixels.

    The point comes from the ``firm`` pixels only (the region and the pixels clearly raised
    next to it); the height from all of them: the faint rim that the growth adds around a tip
    (its own mixed pixels, the 3x3 smoothing's spill onto the surface) makes the tip's height
    lower, as it is, but would move its outline by a pixel from frame to frame.
    """
    n = finger_x.shape[0]
    s_all, lat_all = project(finger_x, finger_y, hx, hy, ux, uy)
    s, lat = s_all[firm], lat_all[firm]
    m = s.shape[0]
    # front: the farthest 1-px slice at least half a tip radius wide
    s0 = s.min()
    nb = int(s.max() - s0) + 1
    counts = np.zeros(nb, np.int64)
    for i in range(m):
        counts[int(s[i] - s0)] += 1
    last = nb - 1
    thr = max(1.0, 0.5 * r0)
    for b in range(nb - 1, -1, -1):
        if counts[b] >= thr:
            last = b
            break
    sf = s0 + last + 1.0
    # finger width in a slab behind the tip cap -> radius
    n_slab = 0
    for i in range(m):
        if s[i] > sf - 3.0 * r0 and s[i] <= sf - r0:
            n_slab += 1
    r = min(max(n_slab / (4.0 * r0), 0.6 * r0), 1.5 * r0)
    n_cap = 0
    l_sum = 0.0
    for i in range(m):
        if s[i] > sf - 2.0 * r:
            n_cap += 1
            l_sum += lat[i]
    l_c = l_sum / max(1, n_cap)
    # the tip centre: pixels ahead of it fill half a disc of radius r; the mean of the
    # pi r^2 / 2 front-most lies 4 r / (3 pi) ahead of it (a mean, not the k-th pixel: the
    # pixel grid moves it by a fraction of a pixel, not by one)
    ahead = np.empty(m)
    n_ahead = 0
    for i in range(m):
        if abs(lat[i] - l_c) <= r + 0.5 and s[i] > sf - 3.0 * r:
            ahead[n_ahead] = -s[i]
            n_ahead += 1
    k = int(np.rint(math.pi * r * r / 2.0))
    if n_ahead:
        kk = min(k, n_ahead - 1)
        s_c = -np.sort(ahead[:n_ahead])[:kk + 1].mean() - 4.0 * r / (3.0 * math.pi)
    else:
        s_c = sf - r
    x = hx + s_c * ux - l_c * uy
    y = hy + s_c * uy + l_c * ux
    # the tip's height: the lower quarter of the cap's smoothed heights (all pixels)
    hv = np.empty(n)
    n_h = 0
    for i in range(n):
        if s_all[i] > sf - 2.0 * r:
            v = hs[finger_y[i], finger_x[i]]
            if v == v:
                hv[n_h] = v
                n_h += 1
    if n_h == 0:
        return x, y, np.nan
    return x, y, np.sort(hv[:n_h])[n_h // 4]


@numba.njit(cache=True, nogil=True)
def paper(part: np.ndarray, hs: np.ndarray, hx: float, hy: float, ds: int, tt: float
           ) -> tuple[float, float, float, bool]:
    """The paper's touch pixel of one region (window px) and its height; False when none."""
    h, w = part.shape
    bx0, bx1, by0, by1 = w, -1, h, -1
    sx = 0.0
    sy = 0.0
    n = 0
    for y in range(h):
        for x in range(w):
            if part[y, x]:
                bx0, bx1 = min(bx0, x), max(bx1, x)
                by0, by1 = min(by0, y), max(by1, y)
                sx += x
                sy += y
                n += 1
    if n == 0:
        return 0.0, 0.0, np.nan, False
    dx, dy = sx / n - hx, sy / n - hy
    # the search band: Ds px inside the bounding-box edge away from the hand
    sx0, sx1, sy0, sy1 = bx0, bx1, by0, by1
    if abs(dx) >= abs(dy):
        if dx >= 0:
            sx0 = max(bx1 - ds + 1, bx0)
        else:
            sx1 = min(bx0 + ds - 1, bx1)
    else:
        if dy >= 0:
            sy0 = max(by1 - ds + 1, by0)
        else:
            sy1 = min(by0 + ds - 1, by1)
    norm = max(math.hypot(dx, dy), 1e-9)
    ux, uy = dx / norm, dy / norm
    best = -np.inf
    bxp, byp = -1, -1
    for y in range(sy0, sy1 + 1):
        for x in range(sx0, sx1 + 1):
            if not _candidate(part, hs, x, y, tt):
                continue
            # a 3x3 block around it: full, or a 2x3 / 3x2 half on one side
            c = np.zeros((3, 3), np.bool_)
            for j in range(3):
                for i in range(3):
                    c[j, i] = _candidate(part, hs, x + i - 1, y + j - 1, tt)
            full = c.all()
            top = c[0, :].all() and c[1, :].all()
            bottom = c[1, :].all() and c[2, :].all()
            left = c[:, 0].all() and c[:, 1].all()
            right = c[:, 1].all() and c[:, 2].all()
            if not (full or top or bottom or left or right):
                continue
            sv = (x - hx) * ux + (y - hy) * uy
            if sv > best:
                best, bxp, byp = sv, x, y
    if bxp < 0:
        return 0.0, 0.0, np.nan, False
    return float(bxp), float(byp), hs[byp, bxp], True


@numba.njit(cache=True, nogil=True)
def _candidate(part: np.ndarray, hs: np.ndarray, x: int, y: int, tt: float) -> bool:
    h, w = part.shape
    if x < 0 or y < 0 or x >= w or y >= h or not part[y, x]:
        return False
    v = hs[y, x]
    return v == v and v < tt
