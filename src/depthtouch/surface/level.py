"""Levelling: a depth frame that moved as a whole is moved back before it meets the surface.

A depth camera's whole frame moves from frame to frame besides each pixel's own noise (its
projector and calibration follow the temperature: all depths of a still scene step together by
a few millimetres and stay so for seconds, or wobble; :mod:`depthtouch.sim.breathing`). The
touch band is a few millimetres thick, so such a step lifts the whole surface into it or sinks
the fingertips under it, and the bump check sees most of the surface change at once and turns
touches off. The surface adapter follows a slow drift one stripe at a time (a cycle takes
24 frames); a step is over before it has visited the stripes.

Each frame, before the surface adapter and the band see it, :func:`frame_offset` measures how
far the frame lies from a reference (the learned surface; while learning, the first learning
frame) on a sparse grid of pixels (every 4th pixel of every 16th row): the depth differences
within ``limit_mm`` of the previous frame's offset, then those within 3 robust standard
deviations of their median, as ``a + b q`` with ``q = (S / S_ref)^2 - 1``, ``S`` the reference
depth at the pixel and ``S_ref`` its median: ``a`` is a shift of every depth, ``b`` one that
grows with the square of the depth, as a disparity offset of a stereo or structured-light
camera does. ``b`` comes from the medians of the pixels nearer and farther than ``S_ref`` (the
surface is each pixel's median over the learning frames; where the noise grows with the depth
and is skewed, means would drift from it with q), and is left at 0 where the reference spans
too little depth to tell the two apart. Hands, arms and objects lie outside the window or are
a minority of the grid. A change from the previous offset is taken only where it stands out
of its own uncertainty (6 standard errors of a median): on a still camera the offset stays at
0 and the frames pass unchanged. :func:`level_depth` then subtracts the offset from every
pixel (rounded to the camera's units; missing pixels stay missing), only when it reaches half
a unit somewhere.

Levelling engages only once the shift ``a`` (the offset at the reference's median depth)
reaches ``engage_mm``, and stays engaged while the frames keep moving: until :data:`HOLD_S`
seconds have passed without ``|a|`` reaching ``engage_mm`` and the offset rounds to nothing
everywhere (so the frames do not jump when it lets go). The surface adapter follows a slow
drift within a millimetre (``|a|`` up to 0.92 mm behind a ToF camera's 0.5 mm/s warm-up), so a
drift alone does not engage it and such recordings pass unchanged, the adapter's as before.
The shift, not the offset at the view's nearest or farthest pixel: ``b`` rests on the medians
of two halves of integer depths, which step by a unit at a time, and a hand arriving in one
half moves it (on a ToF recording, ``b`` read -1.8 .. +1.0 mm while the frame drifted by 0.5 mm).

A frame too covered to measure (fewer than a quarter of the usable grid pixels left) keeps the
previous offset. An offset farther than ``limit_mm`` from the previous one is not followed:
the camera moved, and the bump check learns the surface again. :class:`Leveller` keeps the
reference and the previous offset.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .medians import median_f32

#: the grid: every STEP_PX / 2-th pixel of every 2 STEP_PX-th row (as many pixels as every 8th
#: of every 8th row, from half as many rows: fewer cache lines read)
STEP_PX = 8
#: inliers lie within this many robust standard deviations of the median difference
_K_SIGMA = 3.0
#: a change of the offset is followed when it exceeds this many of its standard errors (of a
#: median, 1.25 robust sigma / sqrt(n), as if the pixels were independent; a least-squares fit
#: of still recordings spread 0.9-1.3 times its own such error from frame to frame, and a hand
#: arriving moved its ``b`` by up to 5)
_K_CHANGE = 6.0
#: the share of the usable grid pixels a frame must leave to be measured
_MIN_SHARE = 0.25
#: levelling stays engaged this long after the offset last reached ``engage_mm`` (s)
HOLD_S = 3.0
#: ``b`` is measured only where the mean q of the farther half lies at least twice this above
#: the nearer half's (else the offset is a plain shift, b = 0)
_MIN_Q_SPREAD = 0.02


@numba.njit(cache=True, nogil=True)
def _fit(depth: np.ndarray, ref_mm: np.ndarray, ref_median_mm: float, to_mm: float,
         prev_a: float, prev_b: float, limit_mm: float, step: int
         ) -> tuple[float, float, int, int]:
    """(a, b, inliers, usable grid pixels) of the frame's offset from ``ref_mm`` (see the
    module doc); a = b = NaN when too few pixels are left."""
    h, w = depth.shape
    sy, sx = 2 * step, max(step // 2, 1)  # fewer rows, more columns: fewer cache lines read
    m = ((h + sy - 1) // sy) * ((w + sx - 1) // sx)
    dv = np.empty(m, np.float32)
    qv = np.empty(m, np.float64)
    inv2 = 1.0 / (ref_median_mm * ref_median_mm)
    n = 0
    usable = 0
    for y in range(sy // 2, h, sy):
        for x in range(sx // 2, w, sx):
            s = ref_mm[y, x]
            if not (s > 0.0):
                continue
            usable += 1
            d = depth[y, x]
            if d == 0:
                continue
            q = s * s * inv2 - 1.0
            r = d * to_mm - s - (prev_a + prev_b * q)  # from the previous offset
            if abs(r) > limit_mm:
                continue
            dv[n] = r
            qv[n] = q
            n += 1
    if n < 8 or n < _MIN_SHARE * usable:
        return np.nan, np.nan, n, usable
    # medians without a branch on the data (a quickselect's cost several times more here)
    lo_mm, hi_mm = np.float32(-limit_mm - 1.0), np.float32(limit_mm + 1.0)
    med = median_f32(dv[:n], lo_mm, hi_mm)
    av = np.empty(n, np.float32)
    for i in range(n):
        av[i] = abs(dv[i] - med)
    mad = median_f32(av, np.float32(0.0), np.float32(2.0 * limit_mm + 2.0))
    tol = max(_K_SIGMA * 1.4826 * mad, 0.5)
    # medians, not means: the surface is each pixel's median over the learning frames, and where
    # the noise is skewed (it grows with the depth) a mean would drift away from it with q
    lo = np.empty(n, np.float32)
    hi = np.empty(n, np.float32)
    nl = 0
    nh = 0
    sql = 0.0
    sqh = 0.0
    for i in range(n):
        if av[i] > tol:
            continue
        if qv[i] < 0.0:
            lo[nl] = dv[i]
            sql += qv[i]
            nl += 1
        else:
            hi[nh] = dv[i]
            sqh += qv[i]
            nh += 1
    k = nl + nh
    if k < 8:
        return np.nan, np.nan, k, usable
    # the change from the previous offset, kept only where it stands out of its own
    # uncertainty (_K_CHANGE standard errors of a median, 1.25 sigma / sqrt(n)): the offset
    # does not flicker with the noise
    sigma = 1.4826 * mad
    db = 0.0
    ml = 0.0
    if nl >= 8 and nh >= 8 and sqh / nh - sql / nl >= 2.0 * _MIN_Q_SPREAD:
        ml = median_f32(lo[:nl], lo_mm, hi_mm)
        mh = median_f32(hi[:nh], lo_mm, hi_mm)
        dq = sqh / nh - sql / nl
        db = (mh - ml) / dq
        se_b = 1.2533 * sigma * math.sqrt(1.0 / nl + 1.0 / nh) / dq
        if abs(db) < _K_CHANGE * se_b:
            db = 0.0
    if db != 0.0:
        da = ml - db * sql / nl
    else:
        for i in range(nh):
            lo[nl + i] = hi[i]
        da = median_f32(lo[:k], lo_mm, hi_mm)
        if abs(da) < _K_CHANGE * 1.2533 * sigma / math.sqrt(k):
            da = 0.0
    return prev_a + da, prev_b + db, k, usable


@numba.njit(cache=True, nogil=True)
def _level(depth: np.ndarray, ref_mm: np.ndarray, ref_median_mm: float, a: float, b: float,
           to_units: float, out: np.ndarray) -> None:
    h, w = depth.shape
    # in units, rounded half up: c = a' + b' s^2 (+ 0.5), s the reference depth
    a0 = (a - b) * to_units + 0.5
    b2 = b * to_units / (ref_median_mm * ref_median_mm)
    if b == 0.0:  # a plain shift (a ToF camera, a flat view): the reference is not read
        k = np.int64(math.floor(a0))
        for y in range(h):
            for x in range(w):
                d = np.int64(depth[y, x])
                out[y, x] = 0 if d == 0 else min(max(d - k, 1), 65535)
        return
    for y in range(h):
        for x in range(w):
            d = np.int64(depth[y, x])
            s = np.float64(ref_mm[y, x])
            c = a0 + b2 * s * s if s > 0.0 else a0 + b * to_units
            v = d - np.int64(math.floor(c))
            out[y, x] = 0 if d == 0 else min(max(v, 1), 65535)


def frame_offset(depth: np.ndarray, ref_mm: np.ndarray, to_mm: float, *,
                 prev: tuple[float, float] = (0.0, 0.0), limit_mm: float = 15.0,
                 ref_median_mm: float | None = None) -> tuple[float, float] | None:
    """The frame's offset from the reference as (a, b) mm (pure; see the module doc), or None
    when too little of the surface is left to measure it.

    depth: uint16 (H, W) in camera units (``to_mm`` mm each); ref_mm: float32 (H, W) reference
    depth in mm, 0 or NaN where unusable; prev: the previous frame's (a, b); limit_mm: the
    farthest a frame's difference may lie from the previous offset and count."""
    med = float(ref_median_mm) if ref_median_mm is not None else reference_stats(ref_mm)[0]
    if not med > 0.0:
        return None
    a, b, _, _ = _fit(depth, ref_mm, med, float(to_mm), float(prev[0]), float(prev[1]),
                      float(limit_mm), STEP_PX)
    if math.isnan(a):
        return None
    return float(a), float(b)


def level_depth(depth: np.ndarray, ref_mm: np.ndarray, to_mm: float, offset: tuple[float, float],
                ref_median_mm: float | None = None,
                q_range: tuple[float, float] | None = None) -> np.ndarray:
    """``depth`` with ``a + b q`` mm taken off every pixel (pure; a new array, or ``depth``
    itself when the offset rounds to 0 units everywhere). ``ref_median_mm``, ``q_range``: the
    reference's median and the span of q over it (:func:`reference_stats`), when known."""
    if ref_median_mm is None or q_range is None:
        ref_median_mm, q_range = reference_stats(ref_mm)
    a, b = offset
    if not ref_median_mm > 0.0 or abs(extreme_offset_mm(offset, q_range)) / to_mm < 0.5:
        return depth
    out = np.empty_like(depth)
    _level(depth, ref_mm, float(ref_median_mm), float(a), float(b), 1.0 / float(to_mm), out)
    return out


def extreme_offset_mm(offset: tuple[float, float], q_range: tuple[float, float]) -> float:
    """The offset ``a + b q`` (mm) where it is largest over the reference (at one end of
    ``q_range``), with its sign."""
    a, b = offset
    return max(a + b * q_range[0], a + b * q_range[1], key=abs)


def reference_stats(ref_mm: np.ndarray) -> tuple[float, tuple[float, float]]:
    """The median reference depth (mm) on the levelling grid, and the span of q there; NaN and
    (0, 0) when none is usable."""
    g = ref_mm[STEP_PX // 2::STEP_PX, STEP_PX // 2::STEP_PX]
    g = g[np.isfinite(g) & (g > 0)]
    if not g.size:
        return math.nan, (0.0, 0.0)
    med = float(np.median(g))
    return med, (float((g.min() / med) ** 2 - 1.0), float((g.max() / med) ** 2 - 1.0))


class Leveller:
    """Keeps the reference and the previous offset; :meth:`update` levels each frame.

    limit_mm: the farthest a frame's offset may lie from the previous one and be followed.
    engage_mm: levelling engages once the shift ``|a|`` reaches this, and lets go
    :data:`HOLD_S` after it last did, once the offset rounds to nothing (0: always engaged).
    """

    def __init__(self, limit_mm: float, engage_mm: float = 0.0) -> None:
        self.limit_mm = float(limit_mm)
        self.engage_mm = float(engage_mm)
        self.reset()

    def reset(self) -> None:
        """Forget the reference (the next frame, or :meth:`use_reference`, sets one)."""
        self._ref: np.ndarray | None = None
        self._med = math.nan
        self._q_range = (0.0, 0.0)
        self.offset_mm: tuple[float, float] = (0.0, 0.0)
        self.measured = False
        self._last_reach_s = -math.inf
        self.engaged = self.engage_mm <= 0.0

    @property
    def has_reference(self) -> bool:
        return self._ref is not None

    def use_reference(self, ref_mm: np.ndarray) -> None:
        """Level against this depth map (mm; 0 or NaN where unusable) from now on, from offset
        0. The array is read, never written; it may change in place (the adapted surface)."""
        self._ref = ref_mm
        self._med, self._q_range = reference_stats(ref_mm)
        self.offset_mm = (0.0, 0.0)
        self._last_reach_s = -math.inf
        self.engaged = self.engage_mm <= 0.0

    def update(self, depth: np.ndarray, to_mm: float, t: float = 0.0) -> np.ndarray:
        """The frame (taken at ``t`` s) levelled against the reference (``depth`` itself when
        nothing moves or levelling is not engaged). The first frame without a reference becomes
        it (in mm), and comes back as it is."""
        if self._ref is None:
            self.use_reference(np.where(depth > 0, depth.astype(np.float32) * np.float32(to_mm),
                                        np.float32(0.0)))
            self.measured = False
            return depth
        off = frame_offset(depth, self._ref, to_mm, prev=self.offset_mm,
                           limit_mm=self.limit_mm, ref_median_mm=self._med)
        self.measured = off is not None
        if off is not None:
            self.offset_mm = off
        if self.engage_mm > 0.0:
            if abs(self.offset_mm[0]) >= self.engage_mm:
                self._last_reach_s = t
                self.engaged = True
            elif (self.engaged and not 0.0 <= t - self._last_reach_s <= HOLD_S
                  and abs(extreme_offset_mm(self.offset_mm, self._q_range)) / to_mm < 0.5):
                self.engaged = False  # (time going back too: a replay from its start)
            if not self.engaged:
                return depth
        return level_depth(depth, self._ref, to_mm, self.offset_mm, self._med, self._q_range)
