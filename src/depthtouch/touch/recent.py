"""Recent change: how much the depth around each touch point changed over the last seconds.

A touch starts with a finger arriving: the heights around a contact's first frames differ
from those of the last second's frames by 11-12 mm (median over the frames; median of
contacts on the hard and rest-tof tune halves). A patch of a resting palm or forearm lies in a
body that has not moved: 2 mm (docs/accuracy.md section 7, sessions 40-41). The tracker reads the
change (``TouchPoints.recent_change_mm``) together with the attachment's share of the ring
(``TrackingConfig.enclosed_change_max_mm``): a region its hand surrounds gives no evidence
when nothing around it moved. Frames in which something far higher lay over the point (the other
hand hovering over a resting one, ``enclosed_cover_mm``) are left out: a patch uncovered when
that hand leaves did not arrive (session 42).

:class:`RecentDepth` keeps a few frames of the last seconds (one every ``step_s``, in a ring
of preallocated frames: a copy every 5th frame at 30 fps); :func:`recent_change` is the pure
per-point measure, compiled with numba (cached on disk) like the fingertip kernel.
"""

from __future__ import annotations

import math

import numba
import numpy as np

# the median of the depths of (2 HALF + 1)^2 pixels around a point (5x5: a fingertip's width
# at 1 m; the median ignores a pixel or two of a finger's edge)
HALF_PX = 2


class RecentDepth:
    """The frames of the last ``window_s`` seconds, one every ``step_s`` (the owner calls
    :meth:`change_mm` for a frame's points, then :meth:`update` with that frame)."""

    def __init__(self, window_s: float = 2.0, step_s: float = 0.15, min_age_s: float = 0.15
                 ) -> None:
        if not (0.0 < step_s <= window_s and 0.0 <= min_age_s < window_s):
            raise ValueError(f"RecentDepth: window {window_s} s, step {step_s} s and minimum age "
                             f"{min_age_s} s must satisfy 0 < step <= window, 0 <= age < window")
        self.window_s, self.step_s, self.min_age_s = window_s, step_s, min_age_s
        self._n = int(math.ceil(window_s / step_s)) + 1
        self._frames: np.ndarray | None = None
        self.reset()

    def reset(self) -> None:
        """Forget the frames kept (the surface was learned again, the stream restarted)."""
        self._t = np.full(self._n, np.nan)
        self._next = 0
        self._last_t = -math.inf

    def update(self, depth: np.ndarray, t_s: float) -> None:
        """Keep this frame if ``step_s`` passed since the last one kept (time goes forward;
        a frame earlier than the last one kept, a restarted stream, starts over)."""
        if t_s < self._last_t:
            self.reset()
        if t_s - self._last_t < self.step_s:
            return
        if self._frames is None or self._frames.shape[1:] != depth.shape:
            self._frames = np.zeros((self._n,) + depth.shape, depth.dtype)
            self.reset()
        np.copyto(self._frames[self._next], depth)
        self._t[self._next] = t_s
        self._next = (self._next + 1) % self._n
        self._last_t = t_s

    def change_mm(self, depth: np.ndarray, xy_px: np.ndarray, t_s: float, to_mm: float,
                  factor: np.ndarray, cover_mm: float = 0.0) -> np.ndarray:
        """The typical change of the height around each point between this frame and the
        frames kept that are ``min_age_s`` to ``window_s`` old: the median over those frames
        (mm, float64 (N,); NaN where none is kept yet or no depth is known; see
        :func:`recent_change`). ``factor``: the surface's height per depth difference
        (BandBounds.factor); ``cover_mm`` > 0: frames in which the point lay under something
        that much higher are left out (see :func:`recent_change`)."""
        xy = np.ascontiguousarray(np.asarray(xy_px, np.float64).reshape(-1, 2))
        out = np.full(xy.shape[0], np.nan)
        if self._frames is None or xy.shape[0] == 0 or self._frames.shape[1:] != depth.shape:
            return out
        age = t_s - self._t  # NaN for a slot never filled: compares False below
        use = np.flatnonzero((age >= self.min_age_s) & (age <= self.window_s))
        if use.size == 0:
            return out
        recent_change(depth, self._frames, use.astype(np.int64), xy, HALF_PX,
                      np.ascontiguousarray(factor), float(to_mm), float(cover_mm), out)
        return out


@numba.njit(cache=True, nogil=True)
def recent_change(depth: np.ndarray, frames: np.ndarray, use: np.ndarray, xy: np.ndarray,
                  half: int, factor: np.ndarray, to_mm: float, cover_mm: float,
                  out: np.ndarray) -> None:
    """For each point (``xy``, image px): the median, over ``frames[use]``, of the absolute
    difference between the median of the known depths (> 0) of the (2 half + 1)^2 pixels
    around its nearest pixel in ``depth`` and the same median in that frame, as a height in mm
    (times ``to_mm`` and the surface's height per depth difference ``factor`` at that pixel;
    the window is clamped to the image; frames where the window has no depth are left out).
    NaN where no median is known now or in none of those frames.

    ``cover_mm`` > 0: a frame in which the heights there lay more than ``cover_mm`` above
    today's (the other hand over a resting one) says nothing about what lies beneath and is
    left out; a point under such a cover in every frame with a median (now uncovered: the
    hand over it left) counts as unchanged, 0. A finger that arrives comes from its hover
    height above the contact, not from a cover over it for the whole window.

    The median over the frames, not the largest change: the other hand passing over a resting
    one changes its heights for a moment by 50-200 mm; a finger that arrives changed them in
    most of the last second's frames.
    """
    h, w = depth.shape
    buf = np.empty((2 * half + 1) ** 2, np.float64)
    diffs = np.empty(use.shape[0], np.float64)
    for i in range(xy.shape[0]):
        out[i] = np.nan
        x, y = xy[i, 0], xy[i, 1]
        if not (x == x and y == y):
            continue
        cx = min(max(int(round(x)), 0), w - 1)
        cy = min(max(int(round(y)), 0), h - 1)
        y0, y1 = max(cy - half, 0), min(cy + half + 1, h)
        x0, x1 = max(cx - half, 0), min(cx + half + 1, w)
        now = _median_known(depth, y0, y1, x0, x1, buf)
        if now != now:
            continue
        scale = to_mm * float(factor[cy, cx])
        n = 0
        covered = 0
        for k in use:
            then = _median_known(frames[k], y0, y1, x0, x1, buf)
            if then == then:
                # (depth units; a cover lies nearer the camera: a smaller depth)
                if cover_mm > 0.0 and (now - then) * scale > cover_mm:
                    covered += 1
                    continue
                n = _insert(diffs, n, abs(then - now))
        if n > 0:
            med = diffs[n // 2] if n % 2 == 1 else 0.5 * (diffs[n // 2 - 1] + diffs[n // 2])
            out[i] = med * scale
        elif covered > 0:
            out[i] = 0.0


@numba.njit(cache=True, nogil=True)
def _insert(buf: np.ndarray, n: int, v: float) -> int:
    """Insert ``v`` into the sorted ``buf[:n]`` (insertion sort: 25 values at most, no
    allocation); returns n + 1."""
    j = n
    while j > 0 and buf[j - 1] > v:
        buf[j] = buf[j - 1]
        j -= 1
    buf[j] = v
    return n + 1


@numba.njit(cache=True, nogil=True)
def _median_known(img: np.ndarray, y0: int, y1: int, x0: int, x1: int, buf: np.ndarray
                  ) -> float:
    """The median (the mean of the two middle values for an even count) of the pixels > 0 of
    img[y0:y1, x0:x1]; NaN when none."""
    n = 0
    for yy in range(y0, y1):
        for xx in range(x0, x1):
            v = img[yy, xx]
            if v > 0:
                n = _insert(buf, n, float(v))
    if n == 0:
        return np.nan
    if n % 2 == 1:
        return buf[n // 2]
    return 0.5 * (buf[n // 2 - 1] + buf[n // 2])


def warm_up() -> None:
    """Compile (or load from the on-disk cache) this module's kernel (see
    :func:`tipkernel.warm_up`)."""
    z = np.ones((8, 8), np.uint16)
    recent_change(z, z[None], np.zeros(1, np.int64), np.zeros((1, 2)), HALF_PX,
                  np.ones((8, 8), np.float32), 1.0, 0.0, np.empty(1))
