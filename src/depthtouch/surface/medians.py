"""Exact medians of float32 arrays without a branch on the data, for the per-frame passes.

The surface adapter takes the median of a stripe's offsets every frame (640x20 values), the
leveller three or four medians of its grid (about 4800 values). A quickselect's comparisons
depend on the data, and a new array each frame defeats the branch predictor: the stripe's
median took 0.13-0.16 ms per frame that way in ``make bench``, against 0.03 ms when timed on one
array again and again. :func:`median_f32` gives numba's ``np.median`` exactly, by histograms
(:func:`_two_ranks`).
"""

from __future__ import annotations

import numba
import numpy as np

_BINS = 1024


@numba.njit(cache=True, nogil=True)
def _two_ranks(a: np.ndarray, k: int, lo: np.float32, hi: np.float32
               ) -> tuple[np.float32, np.float32]:
    """The values of rank k and k + 1 (0-based; k + 1 < len(a)) of a float32 array whose
    values lie in [lo, hi], with no branch on the data in the passes over it: a histogram of
    1024 bins finds the bins of the two ranks; in two bins, they are the greatest value of the
    first and the least of the second; in one, its values are gathered (without a branch) and
    narrowed the same way until they are one value or few (values in whole mm: at once)."""
    counts = np.zeros(_BINS, np.int64)
    sel = np.empty(a.shape[0], np.float32)
    while True:
        if lo == hi:
            return lo, lo
        n = a.shape[0]
        if n <= 32:
            s = np.sort(a)
            return s[k], s[k + 1]
        scale = np.float32(_BINS / (float(hi) - float(lo)))
        counts[:] = 0
        for v in a:
            counts[min(int((v - lo) * scale), _BINS - 1)] += 1
        acc = 0
        b1 = 0
        for b1 in range(_BINS):
            if acc + counts[b1] > k:
                break
            acc += counts[b1]
        b2, acc2 = b1, acc + counts[b1]
        while acc2 <= k + 1:
            b2 += 1
            acc2 += counts[b2]
        if b2 != b1:  # rank k is the greatest value of its bin, rank k + 1 the least of its own
            x, y = hi, lo
            for v in a:
                b = min(int((v - lo) * scale), _BINS - 1)
                x = min(x, v) if b == b2 else x
                y = max(y, v) if b == b1 else y
            return y, x
        m = 0
        nlo, nhi = hi, lo
        for v in a:
            inside = min(int((v - lo) * scale), _BINS - 1) == b1
            sel[m] = v
            m += inside
            nlo = min(nlo, v) if inside else nlo
            nhi = max(nhi, v) if inside else nhi
        a = sel[:m].copy()
        k, lo, hi = k - acc, nlo, nhi


@numba.njit(cache=True, nogil=True)
def median_f32(a: np.ndarray, lo: np.float32, hi: np.float32) -> float:
    """The median of a non-empty float32 array whose values lie in [lo, hi], exactly as
    numba's ``np.median`` gives it (the mean of the two middle values, in float32, for an even
    count).

    The median of a stripe's offsets (640x20 values) by quickselect took 0.13-0.16 ms per frame
    in ``make bench``, against 0.03 ms when timed on one array again and again: its
    comparisons depend on the data, and a new stripe each frame defeats the branch predictor.
    :func:`_two_ranks` does not branch on the data.
    """
    n = a.shape[0]
    if n == 1:
        return float(a[0])
    half = n >> 1
    if n & 1:
        return float(_two_ranks(a, half, lo, hi)[0])
    x, y = _two_ranks(a, half - 1, lo, hi)
    return float(np.float32(x + y) / 2)
