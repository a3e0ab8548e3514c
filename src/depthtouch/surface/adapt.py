"""Surface adaptation: the surface model follows a changing room while the sensor runs.

The paper's sensor needs a static surface and a new capture after any change. Here, on one
horizontal stripe of the image per frame (so the cost is spread evenly):

- a pixel that differs from the surface by more than its Tl and then stays still for
  ``absorb_s`` becomes surface (an object put down; likewise the table where it was taken away);
- drift is followed: the stripe's unchanged pixels give the median offset of the frame from the
  surface, and the whole stripe (changed pixels too: the table under a hand drifts as well)
  moves by ``drift_gain`` (half) of it at each visit, so a steady drift (a ToF camera warming
  up, 0.5 mm/s) lags by less than a millimetre instead of piling up into the touch band; what
  is left, drift that differs from pixel to pixel, unchanged pixels follow slowly (time
  constant ``drift_tau_s``);
- never absorbed: anything connected to a change that reaches the image border (a hand is
  attached to an arm that enters from outside the view, and the arm rises above the band), and
  anything within ``keep_out_mm`` of an active touch whose hand reaches that border (with
  ``keep_all_touches``: of every active touch, and the whole change that reaches into that
  circle). Within ``drift_hold_mm`` of an active touch, the per-pixel follow of drift stops
  too (the mixed pixels around a held tip at range lie within Tl and would creep up under it).
  A finger held still for minutes stays a finger, as long as its arm reaches the
  border (the simulator's arm ends at the shoulder: from about 1.3 m the whole arm is in view,
  and a hand held still there is absorbed unless ``keep_all_touches``). A pixel that lost its
  depth over a usable surface pixel is a change too (an arm nearer than the camera measures,
  the shadow along its edge), and the unusable pixels that reach the image border (a stereo
  camera's band without depth on its left) are outside the view: an arm that enters across
  them reaches the border;
- when more than ``bump_fraction`` of the surface changes at once, touches are off; when it
  stays so, still, for ``bump_s``, the camera has moved: :meth:`SurfaceAdapter.check` says
  ``"bump"`` and the pipeline learns the surface again.
"""

from __future__ import annotations

import math

import cv2
import numba
import numpy as np

from ..config import AdaptConfig
from ..runs import dilate3x3, part_levels
from .bounds import BandBounds, refresh_rows
from .medians import median_f32

_SCALE = 4  # the whole-frame checks run on a 1/4 resolution view
_BLOCK = 8  # the bump check compares a 1/8 view (2x2 means, every 8th pixel)
# a stripe's median offset moves it only when at least this share of its usable pixels are
# unchanged (else the median would be a hand's or an object's)
_OFFSET_MIN_SHARE = 0.25
# the exclusion map's bits: never absorbed (a person, a touch's keep-out circle); a held tip's
# surroundings that do not follow the per-pixel drift (``drift_hold_mm``)
_KEEP = 1
_HOLD = 2


class SurfaceAdapter:
    """Updates ``bounds.surface_mm`` (and the depth bounds) in place, frame by frame."""

    def __init__(self, config: AdaptConfig, bounds: BandBounds) -> None:
        self.config = config
        self.bounds = bounds
        h, w = bounds.surface_mm.shape
        self._stripes = np.linspace(0, h, min(config.stripes, h) + 1).astype(int)
        self.absorbed_px = 0
        self.reset()

    def reset(self) -> None:
        h, w = self.bounds.surface_mm.shape
        self._k = 0
        self._prev = np.zeros((h, w), np.float32)
        self._have_prev = np.zeros(len(self._stripes) - 1, bool)
        self._visits = np.zeros(len(self._stripes) - 1, np.int64)
        self._since = np.full((h, w), np.inf, np.float32)
        self._t0: float | None = None
        self._still_tol = np.maximum(np.float32(self.config.still_mm),
                                     3.0 * self.bounds.sigma_mm).astype(np.float32)
        self._visit_t = np.full(len(self._stripes) - 1, np.nan)
        # the 1/4 view of the exclusions: which pixels it samples (OpenCV's nearest-neighbour
        # resize), and back
        sh, sw = max(1, h // _SCALE), max(1, w // _SCALE)
        self._view_y, self._view_x = _nearest(sh, h), _nearest(sw, w)
        self._up_y, self._up_x = _nearest(h, sh), _nearest(w, sw)
        view = np.ix_(self._view_y, self._view_x)
        self._view_tl = np.ascontiguousarray(self.bounds.tl_mm[view])
        self._view_ok = np.ascontiguousarray(self.bounds.valid[view])
        # the unusable pixels that reach the image border: outside the view, as the border is
        self._outside = ((part_levels((~self._view_ok).view(np.uint8), 1.0, math.inf) == 2)
                         & self.config.edge_outside).view(np.uint8)
        self._exclude = np.zeros((sh, sw), np.uint8)
        # the touches of the last stripe cycle (px) and since when each stood there (s)
        self._held_pts = np.zeros((0, 2))
        self._held_since = np.zeros(0)
        self._bump_since: float | None = None
        # the bump check's 1/8 views: of the surface (refreshed each stripe cycle) and of the
        # fixed usable mask and threshold
        self._coarse: tuple[np.ndarray, np.ndarray] | None = None
        self._block_valid = self._sample(self.bounds.valid.view(np.uint8) * np.uint8(255)) == 255
        self._block_thr = np.maximum(np.float32(2.0), 0.5 * self._sample(self.bounds.tl_mm))
        self._ref: np.ndarray | None = None
        self._ref_t: float | None = None
        self._prev_blocks: np.ndarray | None = None
        self.changed_share = 0.0
        self._n_checks = 0

    @staticmethod
    def _sample(img: np.ndarray) -> np.ndarray:
        """A 1/8 view: bilinear samples halfway between pixels, each the mean of 2x2 pixels
        (OpenCV's area resampling costs twenty times more here, and this runs every frame)."""
        h, w = img.shape
        return cv2.resize(img, (max(1, w // _BLOCK), max(1, h // _BLOCK)),
                          interpolation=cv2.INTER_LINEAR)

    def _frame_blocks(self, depth: np.ndarray) -> np.ndarray:
        """The 1/8 view of a frame in mm; NaN where a sample touched a missing pixel."""
        return _blocks(depth, _BLOCK, float(self.bounds.to_mm), self._block_valid)

    def check(self, depth: np.ndarray, t: float) -> str | None:
        """Every frame: "bump" when the camera moved and the scene has settled (learn the
        surface again), "disturbed" while touches are not to be trusted, else None.

        Compares a 1/8 view of the frame (2x2 means: half the noise) with a reference that
        follows the frames with a 2 s time constant. A sudden shift of most
        blocks is a bump (or something large in front of the camera); a slow drift never is,
        as the reference follows it. Touches stay off until the surface is learned again, or
        until the frames match the surface once more (it was only passing by).
        """
        # every other frame while all is calm (a bump is then seen one frame later); every
        # frame once something happened
        self._n_checks += 1
        if self._bump_since is None and self._n_checks % 2 == 0:
            return None
        b = self.bounds
        if self._coarse is None:
            self._coarse = (self._sample(b.surface_mm), self._block_thr)
        ss, thr = self._coarse
        ds = self._frame_blocks(depth)
        ref, last_t, prev = self._ref, self._ref_t, self._prev_blocks
        self._prev_blocks = ds
        if ref is None or last_t is None:
            self._ref, self._ref_t = ds.copy(), t
            return None
        alpha = min(1.0, max(0.0, t - last_t) / 2.0)
        n_ok, n_sudden, n_surface = _compare_blocks(ds, ref, ss, thr, alpha)  # ref follows ds
        self._ref_t = t
        if n_ok == 0:
            return None
        sudden = n_sudden / n_ok
        vs_surface = n_surface / n_ok
        self.changed_share = vs_surface
        cfg = self.config
        if sudden >= cfg.bump_fraction and self._bump_since is None:
            self._bump_since = t
        if self._bump_since is None:
            return None
        if vs_surface < cfg.bump_fraction:
            self._bump_since = None  # it went away again
            return None
        # still: few samples jump by more than twice the threshold from one frame to the next
        # (structured light flickers between quantisation steps; a person moves far more)
        ok = np.isfinite(ds) & np.isfinite(ss)
        both = ok & np.isfinite(prev) if prev is not None else None
        still = both is not None and float(
            np.mean(np.abs(ds - prev)[both] > 2 * thr[both])
        ) < 0.1
        if not still:
            self._bump_since = t
        elif t - self._bump_since >= cfg.bump_s:
            self._bump_since = None
            return "bump"
        return "disturbed"

    def update(self, depth: np.ndarray, t: float, touch_xy_px: np.ndarray) -> None:
        """Visit the next stripe: absorb still changes, follow drift (see the module doc)."""
        cfg, b = self.config, self.bounds
        k = self._k
        self._k = (k + 1) % (len(self._stripes) - 1)
        if k == 0:
            self._coarse = None  # the surface moved on: refresh its 1/8 view
            self._exclusions(depth, touch_xy_px, t)
        y0, y1 = int(self._stripes[k]), int(self._stripes[k + 1])
        tt = float(np.float32(t - self._t0)) if self._t0 is not None else 0.0
        if self._t0 is None:
            self._t0 = t
        last = float(self._visit_t[k])
        alpha = (min(1.0, (t - last) / cfg.drift_tau_s)
                 if math.isfinite(last) and t > last else -1.0)
        shifted = False
        if alpha >= 0.0 and cfg.drift_gain > 0.0:
            off, n_un, n_ok = _stripe_offset(depth, b.surface_mm, b.factor, b.tl_mm, b.valid,
                                             y0, y1, float(b.to_mm))
            if n_ok and n_un >= _OFFSET_MIN_SHARE * n_ok and abs(off) > 1e-3:
                _shift_rows(b.surface_mm, b.valid, y0, y1, np.float32(cfg.drift_gain * off))
                shifted = True
        n_abs = _stripe_update(
            depth, b.surface_mm, b.factor, b.tl_mm, b.valid, self._since, self._prev,
            self._still_tol, _upsample(self._exclude, self._up_y[y0:y1], self._up_x), y0, y1,
            float(b.to_mm), tt, float(cfg.absorb_s), bool(self._have_prev[k]), alpha,
            np.uint8(_KEEP | _HOLD if not cfg.drift_kept_out else _HOLD),
        )
        self.absorbed_px += n_abs
        self._visit_t[k] = t
        self._have_prev[k] = True
        self._visits[k] += 1
        # the slow follow moves the bounds by fractions of a unit: refreshing them every 8th
        # visit is enough; an absorbed object or a stripe moved by its offset must count at once
        # (the offset's pass and this refresh cost about 0.2 ms per frame, docs/benchmarks.md)
        if n_abs or shifted or self._visits[k] % 8 == 0:
            refresh_rows(b, y0, y1)

    def _exclusions(self, depth: np.ndarray, touch_xy_px: np.ndarray, t: float) -> None:
        """What must never be absorbed: changes connected to the image border, and the
        surroundings of active touches (a 1/4 resolution view, once per stripe cycle); and
        where the per-pixel drift follow stops (``drift_hold_mm`` around touches held for
        ``drift_hold_after_s``)."""
        cfg, b = self.config, self.bounds
        pts = np.asarray(touch_xy_px, np.float64).reshape(-1, 2)
        hold_px = cfg.drift_hold_mm / b.mm_per_px
        if hold_px > 0.0:  # only where the hold is on: the record is its alone
            self._held_since = held_since(pts, self._held_pts, self._held_since, t,
                                          max(1.0, 0.5 * hold_px))
            self._held_pts = pts
        changed = _changed_view(depth, b.surface_mm, self._view_tl, self._view_ok, self._view_y,
                                self._view_x, float(b.to_mm), cfg.edge_outside)
        # Changes connected to the image border are people: never absorbed. A stereo camera's
        # band without depth is outside the view too: a hand whose arm enters across it (and
        # whose shadow, without depth, separates it from the rest) is still a person's.
        lev = part_levels(changed | self._outside, 1.0, math.inf)
        person = (lev == 2) & (changed > 0)
        near = np.zeros_like(changed)
        hold = np.zeros_like(changed)
        if len(touch_xy_px):
            r = max(1, int(round(cfg.keep_out_mm / b.mm_per_px / _SCALE)))
            r_hold = int(round(hold_px / _SCALE))
            for i, (x_px, y_px) in enumerate(pts):
                centre = (int(x_px / _SCALE), int(y_px / _SCALE))
                cv2.circle(near, centre, r, _KEEP, thickness=-1)
                if hold_px > 0.0 and t - self._held_since[i] >= cfg.drift_hold_after_s:
                    cv2.circle(hold, centre, r_hold, _HOLD, thickness=-1)
            if cfg.keep_all_touches:
                # a touch's hand is a person's also where its arm ends inside the view: every
                # change that reaches into a touch's circle is kept whole
                _, labels = cv2.connectedComponents(changed, connectivity=8)
                held = np.unique(labels[(near > 0) & (changed > 0)])
                person |= np.isin(labels, held[held > 0])
        self._exclude = dilate3x3(person.view(np.uint8)) | near | hold


def held_since(pts: np.ndarray, prev_pts: np.ndarray, prev_since: np.ndarray, t: float,
               radius_px: float) -> np.ndarray:
    """Since when each of ``pts`` (N, 2) has stood where it is: the time of the nearest of
    the last call's points ``prev_pts`` within ``radius_px`` (its ``prev_since``), else ``t``."""
    out = np.full(len(pts), float(t))
    if len(pts) and len(prev_pts):
        d = np.hypot(pts[:, None, 0] - prev_pts[None, :, 0], pts[:, None, 1] - prev_pts[None, :, 1])
        j = np.argmin(d, axis=1)
        near = d[np.arange(len(pts)), j] <= radius_px
        out[near] = prev_since[j[near]]
    return out


def _nearest(n_out: int, n_in: int) -> np.ndarray:
    """The input index each of n_out outputs takes in OpenCV's nearest-neighbour resize
    (floor(i * n_in / n_out), computed as OpenCV does)."""
    inv = 1.0 / (n_out / n_in)
    return np.array([min(math.floor(i * inv), n_in - 1) for i in range(n_out)], np.int64)


@numba.njit(cache=True, nogil=True)
def _upsample(small: np.ndarray, up_y: np.ndarray, up_x: np.ndarray) -> np.ndarray:
    """A coarse map at full resolution: pixel (y, x) takes small[up_y[y], up_x[x]] (a row the
    same as the one above is copied)."""
    h, w = up_y.shape[0], up_x.shape[0]
    out = np.empty((h, w), np.uint8)
    for y in range(h):
        if y > 0 and up_y[y] == up_y[y - 1]:
            out[y] = out[y - 1]
            continue
        src, dst = small[up_y[y]], out[y]
        for x in range(w):
            dst[x] = src[up_x[x]]
    return out


@numba.njit(cache=True, nogil=True)
def _changed_view(depth: np.ndarray, surface_mm: np.ndarray, view_tl: np.ndarray,
                  view_ok: np.ndarray, view_y: np.ndarray, view_x: np.ndarray, to_mm: float,
                  missing: bool) -> np.ndarray:
    """The 1/4 view of what differs from the surface by more than Tl, or (``missing``) has no
    depth where the surface is usable (uint8 0/1): the pixels (view_y[j], view_x[i]) of the
    frame and the surface; ``view_tl`` and ``view_ok`` are Tl and the usable mask at the same
    pixels."""
    sh, sw = view_y.shape[0], view_x.shape[0]
    out = np.zeros((sh, sw), np.uint8)
    t = np.float32(to_mm)
    for j in range(sh):
        dr, sr, tr, okr = depth[view_y[j]], surface_mm[view_y[j]], view_tl[j], view_ok[j]
        for i in range(sw):
            x = view_x[i]
            d = np.float32(dr[x]) * t
            if okr[i] and ((d == 0 and missing) or (d > 0 and abs(sr[x] - d) > tr[i])):
                out[j, i] = 1
    return out


@numba.njit(cache=True, nogil=True)
def _stripe_offset(depth: np.ndarray, surface_mm: np.ndarray, factor: np.ndarray,
                   tl_mm: np.ndarray, valid: np.ndarray, y0: int, y1: int, to_mm: float
                   ) -> tuple[float, int, int]:
    """The median of frame minus surface (mm along the optical axis) over the unchanged
    pixels of rows y0:y1 (within their Tl of the surface); returns (median, how many unchanged,
    how many usable)."""
    w = depth.shape[1]
    res = np.empty((y1 - y0) * w, np.float32)
    n = 0
    n_ok = 0
    t = np.float32(to_mm)
    lo, hi = np.float32(np.inf), np.float32(-np.inf)
    for y in range(y0, y1):
        dr, sr, fr, tr, vr = depth[y], surface_mm[y], factor[y], tl_mm[y], valid[y]
        for x in range(w):
            d = dr[x]
            if d == 0 or not vr[x]:
                continue
            n_ok += 1
            r = np.float32(d) * t - sr[x]
            if abs(r * fr[x]) <= tr[x]:
                res[n] = r
                n += 1
                lo, hi = min(lo, r), max(hi, r)
    if n == 0:
        return 0.0, 0, n_ok
    return median_f32(res[:n], lo, hi), n, n_ok


@numba.njit(cache=True, nogil=True)
def _shift_rows(surface_mm: np.ndarray, valid: np.ndarray, y0: int, y1: int,
                off: np.float32) -> None:
    """Move the usable surface pixels of rows y0:y1 by ``off`` mm (in place)."""
    w = surface_mm.shape[1]
    for y in range(y0, y1):
        sr, vr = surface_mm[y], valid[y]
        for x in range(w):
            if vr[x]:
                sr[x] += off


@numba.njit(cache=True, nogil=True)
def _stripe_update(
    depth: np.ndarray, surface_mm: np.ndarray, factor: np.ndarray, tl_mm: np.ndarray,
    valid: np.ndarray, since: np.ndarray, prev: np.ndarray, still_tol: np.ndarray,
    exclude: np.ndarray, y0: int, y1: int, to_mm: float, tt: float, absorb_s: float,
    have_prev: bool, alpha: float, drift_skip: np.uint8,
) -> int:
    """The stripe of rows y0:y1 of :meth:`SurfaceAdapter.update`, pixel by pixel in one
    compiled pass (updates ``surface_mm``, ``since`` and ``prev`` in place; returns the pixels
    absorbed). ``exclude``: the stripe's rows of the exclusion map (bit ``_KEEP``: never absorb).

    A pixel off the surface by more than its Tl is "changed"; its ``since`` restarts when it
    moved by more than ``still_tol`` since the last visit; a change still for ``absorb_s`` and
    not excluded becomes surface. Unchanged pixels follow the frame by ``alpha`` (drift;
    alpha < 0: not this visit), except those whose exclusion bits meet ``drift_skip``.
    """
    w = depth.shape[1]
    n_abs = 0
    a = np.float32(alpha)
    drift_on = alpha >= 0.0
    t32 = np.float32(tt)
    inf = np.float32(np.inf)
    keep = np.uint8(_KEEP)
    # without branches (selects), row by row: the compiler vectorises it
    for y in range(y0, y1):
        dr, sr, fr, tr, vr = depth[y], surface_mm[y], factor[y], tl_mm[y], valid[y]
        since_r, prev_r, tol_r, excl_r = since[y], prev[y], still_tol[y], exclude[y - y0]
        for x in range(w):
            d = dr[x]
            dm = np.float32(d) * np.float32(to_mm)
            s = sr[x]
            ok = (d > 0) & vr[x]
            changed = ok & (abs((s - dm) * fr[x]) > tr[x])
            si = since_r[x]
            moved = (not have_prev) | (si == inf) | (abs(dm - prev_r[x]) > tol_r[x])
            si = t32 if moved else si
            absorb = changed & (tt - si >= absorb_s) & ((excl_r[x] & keep) == 0)
            drift = (not changed) & ok & drift_on & ((excl_r[x] & drift_skip) == 0)
            sr[x] = dm if absorb else (s + a * (dm - s) if drift else s)
            since_r[x] = si if (changed & (not absorb)) else inf
            prev_r[x] = dm
            n_abs += absorb
    return n_abs


@numba.njit(cache=True, nogil=True)
def _blocks(depth: np.ndarray, block: int, to_mm: float, block_valid: np.ndarray) -> np.ndarray:
    """The 1/``block`` view of a frame in mm, sampled as :meth:`SurfaceAdapter._sample` does
    (the mean of the 2x2 pixels halfway in each block); NaN where one of them is missing or
    the block's surface is not usable."""
    H, W = depth.shape
    bh, bw = max(1, H // block), max(1, W // block)
    out = np.full((bh, bw), np.nan, np.float32)
    c = block // 2 - 1
    for j in range(bh):
        ya, yb = min(H - 1, block * j + c), min(H - 1, block * j + c + 1)
        for i in range(bw):
            if not block_valid[j, i]:
                continue
            xa, xb = min(W - 1, block * i + c), min(W - 1, block * i + c + 1)
            a, b_, c_, d = depth[ya, xa], depth[ya, xb], depth[yb, xa], depth[yb, xb]
            if a == 0 or b_ == 0 or c_ == 0 or d == 0:
                continue
            out[j, i] = np.float32((np.float64(a) + b_ + c_ + d) * 0.25 * to_mm)
    return out


def warm_up() -> None:
    """Compile (or load from cache) this module's kernels (see :func:`tipkernel.warm_up`)."""
    z16 = np.zeros((8, 8), np.uint16)
    f = np.zeros((8, 8), np.float32)
    b = np.ones((8, 8), np.bool_)
    _blocks(z16, 4, 1.0, b)
    _compare_blocks(f, f.copy(), f, f, 0.5)
    idx = np.arange(8)
    excl = _upsample(_changed_view(z16, f, f, b, idx, idx, 1.0, True), idx, idx)
    _stripe_update(z16, f, f + 1, f + 1, b, f.copy(), f.copy(), f + 1, excl, 0, 8, 1.0, 0.0, 0.5,
                   False, -1.0, np.uint8(_HOLD))
    _stripe_offset(z16, f, f + 1, f + 1, b, 0, 8, 1.0)
    median_f32(np.array([1.0, 2.0, 2.0, 3.5], np.float32), np.float32(1.0), np.float32(3.5))
    _shift_rows(f.copy(), b, 0, 8, np.float32(0.5))


@numba.njit(cache=True, nogil=True)
def _compare_blocks(ds: np.ndarray, ref: np.ndarray, ss: np.ndarray, thr: np.ndarray,
                    alpha: float) -> tuple[int, int, int]:
    """One pass of :meth:`SurfaceAdapter.check` over the 1/8 view: the samples known in the
    frame, the reference and the surface; how many of them moved away from the reference and
    from the surface by more than ``thr``. The reference then follows the frame by ``alpha``
    (in place; an unknown reference sample takes the frame's)."""
    h, w = ds.shape
    n_ok = 0
    n_sudden = 0
    n_surface = 0
    a = np.float32(alpha)
    for y in range(h):
        for x in range(w):
            d, r, s = ds[y, x], ref[y, x], ss[y, x]
            if np.isfinite(d) and np.isfinite(r) and np.isfinite(s):
                n_ok += 1
                if abs(d - r) > thr[y, x]:
                    n_sudden += 1
                if abs(d - s) > thr[y, x]:
                    n_surface += 1
            if np.isfinite(r):
                ref[y, x] = r + a * (d - r)
            else:
                ref[y, x] = d
    return n_ok, n_sudden, n_surface
