"""Masks as runs: the connected parts of a binary mask, from the runs of its rows.

A mask with a few small parts (the touch band after its erosion, the coarse hand map) is
listed as runs, (n, 3) rows (y, x0, x1) covering the pixels x0..x1-1 of row y in raster order;
its 8-connected parts are found by joining the runs that touch from one row to the next
(union-find), a few hundred steps instead of a scan of the whole mask per step. Also here: the
level of each part of a coarse mask (does it reach the border, is it large) and a 3x3 maximum
filter, for the coarse maps of the hand and of the surface adaptation. Compiled with numba
(cached on disk) like the other per-frame kernels.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def row_runs(row: np.ndarray, y: int, runs: np.ndarray, n: int) -> int:
    """Append the runs of non-zero pixels of ``row`` (row y of a mask) to ``runs`` from index
    n as (y, x0, x1); returns the new count. Eight zero pixels at a time are skipped as one
    64-bit word."""
    w = row.shape[0]
    n_words = w // 8
    words = row[:n_words * 8].view(np.uint64)
    x = 0
    while x < w:
        if row[x] == 0:
            if x % 8 == 0 and x // 8 < n_words and words[x // 8] == 0:
                x += 8
            else:
                x += 1
            continue
        a = x
        while x < w and row[x]:
            x += 1
        runs[n, 0], runs[n, 1], runs[n, 2] = y, a, x
        n += 1
    return n


@numba.njit(cache=True, nogil=True)
def dilate_runs(runs: np.ndarray, pad: int, H: int, W: int) -> np.ndarray:
    """The runs of a mask dilated by a square of half-width ``pad`` (raster order)."""
    n = runs.shape[0]
    out = np.empty((n * (2 * pad + 1), 3), np.int64)  # each run adds at most one per row
    n_out = 0
    cand = np.empty((n, 2), np.int64)
    y_first = max(0, runs[0, 0] - pad) if n else 0
    y_last = min(H - 1, runs[n - 1, 0] + pad) if n else -1
    r0 = 0
    for y in range(y_first, y_last + 1):
        while r0 < n and runs[r0, 0] < y - pad:
            r0 += 1
        k = 0
        r = r0
        while r < n and runs[r, 0] <= y + pad:
            cand[k, 0] = max(0, runs[r, 1] - pad)
            cand[k, 1] = min(W, runs[r, 2] + pad)
            k += 1
            r += 1
        if k == 0:
            continue
        # by start (insertion sort: a few runs; np.argsort would add seconds of compiling)
        for t in range(1, k):
            a, b = cand[t, 0], cand[t, 1]
            u = t - 1
            while u >= 0 and cand[u, 0] > a:
                cand[u + 1, 0], cand[u + 1, 1] = cand[u, 0], cand[u, 1]
                u -= 1
            cand[u + 1, 0], cand[u + 1, 1] = a, b
        a, b = cand[0, 0], cand[0, 1]
        for t in range(1, k + 1):
            if t < k and cand[t, 0] <= b:
                b = max(b, cand[t, 1])
                continue
            out[n_out, 0], out[n_out, 1], out[n_out, 2] = y, a, b
            n_out += 1
            if t < k:
                a, b = cand[t, 0], cand[t, 1]
    return out[:n_out]


@numba.njit(cache=True, nogil=True)
def _root(parent: np.ndarray, a: int) -> int:
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


@numba.njit(cache=True, nogil=True)
def label_runs(runs: np.ndarray) -> tuple[np.ndarray, int]:
    """8-connected parts of a mask given as runs ((n, 3) rows y, x0, x1 in raster order):
    the part of each run (0.., numbered in the order of their first run) and how many."""
    n = runs.shape[0]
    parent = np.arange(n)
    # a run touches the runs of the row above that overlap it widened by one pixel
    q0 = 0
    for r in range(n):
        y = runs[r, 0]
        while q0 < r and (runs[q0, 0] < y - 1
                          or (runs[q0, 0] == y - 1 and runs[q0, 2] < runs[r, 1])):
            q0 += 1
        q = q0
        while q < r and runs[q, 0] == y - 1 and runs[q, 1] <= runs[r, 2]:
            a, b = _root(parent, q), _root(parent, r)
            if a != b:
                parent[max(a, b)] = min(a, b)  # the root stays the part's first run
            q += 1
    comp = np.empty(n, np.int64)
    n_comp = 0
    index = np.full(n, -1, np.int64)
    for r in range(n):
        root = _root(parent, r)
        if index[root] < 0:
            index[root] = n_comp
            n_comp += 1
        comp[r] = index[root]
    return comp, n_comp


@numba.njit(cache=True, nogil=True)
def filled_part(runs: np.ndarray, comp: np.ndarray, c: int, x0: int, y0: int, h: int, w: int
            ) -> np.ndarray:
    """The pixels of component ``c`` (runs whose ``comp`` is c) and its holes, in the box
    (x0, y0, w, h) (uint8, 1 = in): what OpenCV's filled outer contour covers. The background
    reached from the box's edge through 4-neighbours is outside; the rest is a hole."""
    m = np.zeros((h, w), np.uint8)
    for r in range(runs.shape[0]):
        if comp[r] == c:
            m[runs[r, 0] - y0, runs[r, 1] - x0:runs[r, 2] - x0] = 1
    seen = np.zeros((h, w), np.uint8)
    stack = np.empty((h * w, 2), np.int64)
    top = 0
    for y in range(h):
        for x in range(w):
            if (y == 0 or x == 0 or y == h - 1 or x == w - 1) and not m[y, x]:
                seen[y, x] = 1
                stack[top, 0], stack[top, 1] = y, x
                top += 1
    while top > 0:
        top -= 1
        y, x = stack[top, 0], stack[top, 1]
        for k in range(4):
            yy = y + (1 if k == 0 else -1 if k == 1 else 0)
            xx = x + (1 if k == 2 else -1 if k == 3 else 0)
            if 0 <= yy < h and 0 <= xx < w and not m[yy, xx] and not seen[yy, xx]:
                seen[yy, xx] = 1
                stack[top, 0], stack[top, 1] = yy, xx
                top += 1
    for y in range(h):
        for x in range(w):
            if not seen[y, x]:
                m[y, x] = 1
    return m


@numba.njit(cache=True, nogil=True)
def parts_of_runs(runs: np.ndarray, H: int, W: int, min_area: int, pad: int
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The parts of a mask given as runs (at least ``min_area`` pixels, the box grown by pad
    first), as OpenCV's filled outer contours give them: 8-connected parts with their holes
    filled, each dilated by ``pad`` (a square) within its box grown by pad; a part inside
    another's hole is not a part of its own; the order is OpenCV's (the last part found in
    raster order first).

    Returns boxes (R, 4) (x, y, w, h), areas (R,), the masks one after the other (uint8,
    1 = in, row-major in the box) and where each starts."""
    n = runs.shape[0]
    comp, n_comp = label_runs(runs)
    bx0 = np.full(n_comp, W, np.int64)
    by0 = np.full(n_comp, H, np.int64)
    bx1 = np.zeros(n_comp, np.int64)
    by1 = np.zeros(n_comp, np.int64)
    first = np.full(n_comp, -1, np.int64)
    for r in range(n):
        c = comp[r]
        bx0[c] = min(bx0[c], runs[r, 1])
        bx1[c] = max(bx1[c], runs[r, 2])
        by0[c] = min(by0[c], runs[r, 0])
        by1[c] = max(by1[c], runs[r, 0] + 1)
        if first[c] < 0:
            first[c] = r
    boxes = np.empty((n_comp, 4), np.int64)
    areas = np.empty(n_comp, np.int64)
    starts = np.empty(n_comp, np.int64)
    size = 0  # room for the masks of every part that may be kept
    for c in range(n_comp):
        size += ((min(W, bx1[c] + pad) - max(0, bx0[c] - pad))
                 * (min(H, by1[c] + pad) - max(0, by0[c] - pad)))
    buf = np.empty(size, np.uint8)
    used = 0
    n_out = 0
    for c in range(n_comp - 1, -1, -1):  # OpenCV lists the last found first
        x, y, w, h = bx0[c], by0[c], bx1[c] - bx0[c], by1[c] - by0[c]
        if (w + 2 * pad) * (h + 2 * pad) < min_area:
            continue
        # a part inside another part's hole has no outer contour of its own
        fy, fx = runs[first[c], 0], runs[first[c], 1]
        inside = False
        for d in range(n_comp):
            if d != c and bx0[d] < x and by0[d] < y and bx1[d] > x + w and by1[d] > y + h:
                outer = filled_part(runs, comp, d, bx0[d], by0[d], by1[d] - by0[d], bx1[d] - bx0[d])
                if outer[fy - by0[d], fx - bx0[d]]:
                    inside = True
                    break
        if inside:
            continue
        m = filled_part(runs, comp, c, x, y, h, w)
        X0, Y0 = max(0, x - pad), max(0, y - pad)
        X1, Y1 = min(W, x + w + pad), min(H, y + h + pad)
        mh, mw = Y1 - Y0, X1 - X0
        out = buf[used:used + mh * mw].reshape((mh, mw))
        out[:] = 0
        area = 0
        for yy in range(mh):
            for xx in range(mw):
                # the square of half-width pad around (yy, xx) meets the part
                on = False
                for j in range(max(0, yy + Y0 - pad - y), min(h, yy + Y0 + pad - y + 1)):
                    for i in range(max(0, xx + X0 - pad - x), min(w, xx + X0 + pad - x + 1)):
                        if m[j, i]:
                            on = True
                            break
                    if on:
                        break
                if on:
                    out[yy, xx] = 1
                    area += 1
        if area < min_area:
            continue
        boxes[n_out, 0], boxes[n_out, 1], boxes[n_out, 2], boxes[n_out, 3] = X0, Y0, mw, mh
        areas[n_out] = area
        starts[n_out] = used
        used += mh * mw
        n_out += 1
    return boxes[:n_out], areas[:n_out], buf[:used], starts[:n_out]


@numba.njit(cache=True, nogil=True)
def part_levels(mask: np.ndarray, px_area: float, min_area: float) -> np.ndarray:
    """Level of each 8-connected part of a (coarse) mask: 2 when it touches the mask's border
    (something reaching in from outside the view), 1 when its area (pixels x ``px_area``) is at
    least ``min_area``, else 0; as a map of the mask's shape."""
    sh, sw = mask.shape
    runs = np.empty((sh * (sw // 2 + 1), 3), np.int64)
    n = 0
    for j in range(sh):
        n = row_runs(mask[j], j, runs, n)
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
        v = 2 if border[c] else (1 if area[c] * px_area >= min_area else 0)
        lev[runs[r, 0], runs[r, 1]:runs[r, 2]] = v
    return lev


@numba.njit(cache=True, nogil=True)
def dilate3x3(a: np.ndarray) -> np.ndarray:
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
