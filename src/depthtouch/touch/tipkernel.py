"""The compiled per-frame kernel of :mod:`depthtouch.touch.points` (numba, cached on disk).

The steps are those described in :mod:`depthtouch.touch.points`; here they run over all regions
of a frame in one compiled call, each on a small window around its region: the attached hand,
the finger's direction, the nearest-region test and the growth into the tip cap are here; the
estimators inside a region (split, extremity, the paper's pixel) in :mod:`depthtouch.touch.fingertip`;
the window maps they read (heights, distances, what lies behind a tip) in
:mod:`depthtouch.touch.tipmaps`.
Done with numpy and OpenCV, the same work is some 150 small array calls per frame whose Python
overhead (2-5 us each) costs more than the pixels; compiled, a frame with five touches takes
about 0.1 ms. ``tests/reference_touchpoints.py`` keeps the array-call version, and the tests
check that both give the same points.

:func:`frame_points` is the boundary: named tuples of arrays in (:class:`KernelSurface`,
:class:`KernelRegions`, :class:`TipParams`), one out (:class:`FramePoints`), units in the names.
Inside, the compiled kernel takes the arrays one by one and returns (N, 11) rows: x, y (image px,
sub-pixel), height (mm, NaN when unknown), area (px), hand x, hand y (px), hand at border (0/1),
attachment (hand pixels within 2 px of the region), their median height (mm), the spread of the
heights behind the tip (mm, see :func:`tipmaps.back_spread`), the attachment's share of the ring
2 px around the region.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from .fingertip import extremity, paper, project, split
from .tipmaps import back_spread, chamfer, near_mask, pixel_height, smooth_heights

N_OUT = 11
#: the growth into the tip cap takes smoothed heights above this fraction of Tl (they give the
#: tip's height); the contact point is placed on those above the firmer fraction
_GROW_TL = 0.5
_FIRM_TL = 0.85


@numba.njit(cache=True, nogil=True)
def _attach(near: np.ndarray, depth: np.ndarray, high_lo: np.ndarray,
            high_hi: np.ndarray, hands: np.ndarray, scale: int, x0: int, y0: int,
            surf: np.ndarray, fact: np.ndarray, to_mm: float
            ) -> tuple[int, float, float, bool, float]:
    """Hand pixels among the ``near`` pixels (those next to a mask, see
    :func:`tipmaps.near_mask`): count, mean x, y (window), whether any belongs to an arm
    reaching in from the border (hand map level 2), and their median height above the surface
    (mm)."""
    h, w = near.shape
    sh, sw = hands.shape
    n = 0
    sx = 0.0
    sy = 0.0
    border = False
    hv = np.empty(h * w, np.float64)
    for y in range(h):
        for x in range(w):
            if not near[y, x]:
                continue
            d = depth[y0 + y, x0 + x]
            if d < high_lo[y0 + y, x0 + x] or d > high_hi[y0 + y, x0 + x]:
                continue  # not above Tu
            cy, cx = (y0 + y) // scale, (x0 + x) // scale
            if cy >= sh or cx >= sw:
                continue
            lev = hands[cy, cx]
            if lev >= 1:
                hv[n] = pixel_height(d, surf[y0 + y, x0 + x], fact[y0 + y, x0 + x], to_mm)
                n += 1
                sx += x
                sy += y
                if lev == 2:
                    border = True
    if n == 0:
        return 0, 0.0, 0.0, False, np.nan
    return n, sx / n, sy / n, border, float(np.median(hv[:n]))


@numba.njit(cache=True, nogil=True)
def _ring_known(near: np.ndarray, reg: np.ndarray, depth: np.ndarray, valid: np.ndarray,
                x0: int, y0: int) -> int:
    """How many of the ``near`` pixels outside the region ``reg`` have a depth on a usable
    pixel: the ring that the attachment's hand pixels are counted in (window at x0, y0)."""
    h, w = near.shape
    n = 0
    for y in range(h):
        for x in range(w):
            if near[y, x] and not reg[y, x] and depth[y0 + y, x0 + x] > 0 \
                    and valid[y0 + y, x0 + x]:
                n += 1
    return n


class KernelSurface(NamedTuple):
    """The surface as the kernel reads it (see :class:`depthtouch.surface.bounds.BandBounds`):
    hand bounds in camera units, surface depth in mm, height factor, Tl in mm, usable pixels,
    mm per camera unit. All (H, W) but ``to_mm``."""

    high_lo: np.ndarray
    high_hi: np.ndarray
    surface_mm: np.ndarray
    factor: np.ndarray
    tl_mm: np.ndarray
    valid: np.ndarray
    to_mm: float


class KernelRegions(NamedTuple):
    """The regions of a frame: the opened band (uint8 (H, W)) and the pad of its opening (px),
    boxes (R, 4) int64 (x, y, w, h), all masks (uint8, row-major within the box) one after the
    other, region i starting at ``mask_start[i]``."""

    core: np.ndarray
    open_pad_px: int
    bbox_xywh: np.ndarray
    mask_buf: np.ndarray
    mask_start: np.ndarray


class TipParams(NamedTuple):
    """The fingertip radius (px), the estimator (the paper's pixel or the tip's centre), the
    paper's parameters (search step in px, height threshold in mm), the surface's scale (mm
    per px, where the heights behind a tip are read) and how far beside its region a grown
    pixel may place the contact (px, ``TouchPointConfig.tip_beside_px``)."""

    tip_radius_px: float
    paper: bool
    paper_ds_px: int
    paper_tt_mm: float
    mm_per_px: float
    beside_px: float = 2.0


class FramePoints(NamedTuple):
    """The touch points of a frame, parallel arrays of length N: contact (px, sub-pixel),
    height above the surface (mm, NaN when unknown), region area (px), centre of the attached
    hand (px), whether that hand reaches the image border, how many hand pixels lie within 2 px
    of the region (its attachment: about twice its length in px), their median height above the
    surface (mm; a finger rises from the band gradually, the side of a raised hand does not), and
    the spread of the heights behind the tip (mm, NaN when unknown; a finger's is large, a flat
    object's top is level); and the share of the ring 2 px around the region (pixels with a depth)
    that those hand pixels make (a fingertip hangs on its finger at its back; a patch of a
    resting hand or forearm lies in its hand, which surrounds it)."""

    xy_px: np.ndarray
    height_mm: np.ndarray
    area_px: np.ndarray
    hand_xy_px: np.ndarray
    hand_at_border: np.ndarray
    attach_px: np.ndarray
    attach_height_mm: np.ndarray
    back_spread_mm: np.ndarray
    attach_share: np.ndarray


def frame_points(depth: np.ndarray, hands: np.ndarray, hand_scale: int, surface: KernelSurface,
                 regions: KernelRegions, params: TipParams) -> FramePoints:
    """Touch points of all regions of a frame (one compiled call; see the module doc).

    depth: the uint16 frame; hands: the coarse hand map (uint8, 1/``hand_scale`` resolution,
    1 = hand, 2 = hand reaching the border).
    """
    s, r, p = surface, regions, params
    out = _frame_points(depth, s.high_lo, s.high_hi, hands, hand_scale, s.surface_mm, s.factor,
                        s.tl_mm, s.valid, float(s.to_mm), r.core, int(r.open_pad_px),
                        r.bbox_xywh, r.mask_buf, r.mask_start, float(p.tip_radius_px),
                        1 if p.paper else 0, int(p.paper_ds_px), float(p.paper_tt_mm),
                        float(p.mm_per_px), float(p.beside_px))
    return FramePoints(out[:, 0:2].copy(), out[:, 2].copy(), out[:, 3].astype(np.int64),
                       out[:, 4:6].copy(), out[:, 6] > 0, out[:, 7].astype(np.int64),
                       out[:, 8].copy(), out[:, 9].copy(), out[:, 10].copy())


@numba.njit(cache=True, nogil=True)
def _frame_points(
    depth: np.ndarray, high_lo: np.ndarray, high_hi: np.ndarray, hands: np.ndarray, scale: int,
    surf: np.ndarray, fact: np.ndarray, tl: np.ndarray, valid: np.ndarray, to_mm: float,
    core: np.ndarray, open_pad: int, boxes: np.ndarray, masks: np.ndarray, mask_start: np.ndarray,
    r0: float, method: int, paper_ds: int, paper_tt: float, mm_px: float, beside_px: float,
) -> np.ndarray:
    """Touch points of all regions of a frame: (N, 11) rows (see the module doc).

    Each region is worked on in a window 2 rr + 2 px around its box (the growth reaches 2 rr,
    the hand attaches within 2 px); the band 3 r0 + 3 px around it is looked at only when other
    regions (or other fingertips of the same region) are near, for the nearest-region test.
    """
    H, W = depth.shape
    R = boxes.shape[0]
    rr = max(1, int(np.rint(r0)))
    m_in = 2 * rr + 2
    m_out = int(math.ceil(3.0 * r0)) + 3
    out = np.empty((4 * R + 4, N_OUT))
    n_out = 0
    for i in range(R):
        bx, by, bw, bh = boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3]
        x0, y0 = max(0, bx - m_in), max(0, by - m_in)
        x1, y1 = min(W, bx + bw + m_in), min(H, by + bh + m_in)
        h, w = y1 - y0, x1 - x0
        reg = np.zeros((h, w), np.uint8)
        area = 0
        k = mask_start[i]
        for yy in range(bh):
            for xx in range(bw):
                if masks[k + yy * bw + xx]:
                    reg[by - y0 + yy, bx - x0 + xx] = 1
                    area += 1
        if area == 0:
            continue
        # --- the hand: hand pixels next to the region (a flat object or noise has none) ----
        near = near_mask(reg, 2)
        n_att, hx, hy, border, att_h = _attach(near, depth, high_lo, high_hi, hands, scale, x0,
                                               y0, surf, fact, to_mm)
        if n_att < 3:
            continue
        share = n_att / max(1, _ring_known(near, reg, depth, valid, x0, y0))
        ex = np.empty(area, np.int64)
        ey = np.empty(area, np.int64)
        k = 0
        for y in range(h):
            for x in range(w):
                if reg[y, x]:
                    ex[k], ey[k] = x, y
                    k += 1
        cx, cy = ex.mean(), ey.mean()
        dx, dy = cx - hx, cy - hy
        norm = math.hypot(dx, dy)
        if norm < 1e-6:
            continue
        ux, uy = dx / norm, dy / norm
        s, lat = project(ex, ey, hx, hy, ux, uy)
        along = s.max() - s.min() + 1.0
        across = lat.max() - lat.min() + 1.0
        # a thin strip along the side of something raised: an edge, not a finger
        if along < r0 or (along < 1.5 * r0 and across > 3.0 * along):
            continue
        part_of = split(lat, s, r0) if area > 10.0 * r0 * r0 else np.zeros(area, np.int64)
        n_parts = part_of.max() + 1
        # other regions near (or other fingertips of this one): the finger grows only into
        # pixels nearer to it than to them
        ox0, oy0 = max(0, bx - m_out), max(0, by - m_out)
        ox1, oy1 = min(W, bx + bw + m_out), min(H, by + bh + m_out)
        if R > 1 or n_parts > 1:
            band = _band_near(core, open_pad, reg, x0, y0, ox0, oy0, ox1, oy1, n_parts > 1)
        else:  # alone in the frame: specks of noise nearby do not count
            band = np.zeros((0, 0), np.uint8)
        hs = smooth_heights(depth, surf, fact, valid, to_mm, x0, y0, h, w)
        for p in range(n_parts):
            part = np.zeros((h, w), np.uint8)
            n_p = 0
            sx = 0.0
            sy = 0.0
            for j in range(area):
                if part_of[j] == p:
                    part[ey[j], ex[j]] = 1
                    n_p += 1
                    sx += ex[j]
                    sy += ey[j]
            if n_p == 0:
                continue
            phx, phy, pborder, patt, pshare = hx, hy, border, n_att, share
            if n_parts > 1:
                pnear = near_mask(part, 2)
                na, ax, ay, ab, _ = _attach(pnear, depth, high_lo, high_hi, hands,
                                            scale, x0, y0, surf, fact, to_mm)
                if na >= 3:
                    phx, phy, pborder = ax, ay, ab
                pshare = na / max(1, _ring_known(pnear, part, depth, valid, x0, y0))
                # a long edge cut into "fingertips" is still one long attachment: each part
                # gets at least its share of the whole region's
                patt = max(na, n_att // n_parts)
            # the finger's direction: from its hand to the part's centre
            ddx, ddy = sx / n_p - phx, sy / n_p - phy
            nn = math.hypot(ddx, ddy)
            if method == 1:
                px_, py_, ph, ok = paper(part, hs, phx, phy, paper_ds, paper_tt)
                if not ok:
                    continue
            else:
                if nn < 1e-6:
                    continue
                own = _own(part, band, x0 - ox0, y0 - oy0)
                fx, fy, firm = _grow(part, own, hs, tl, x0, y0, rr, phx, phy, ddx / nn,
                                     ddy / nn, beside_px)
                px_, py_, ph = extremity(fx, fy, firm, hs, phx, phy, ddx / nn, ddy / nn, r0)
            out[n_out, 0] = px_ + x0
            out[n_out, 1] = py_ + y0
            out[n_out, 2] = ph
            out[n_out, 3] = n_p
            out[n_out, 4] = phx + x0
            out[n_out, 5] = phy + y0
            out[n_out, 6] = 1.0 if pborder else 0.0
            out[n_out, 7] = patt
            out[n_out, 8] = att_h
            out[n_out, 9] = (back_spread(depth, surf, fact, valid, to_mm, px_ + x0, py_ + y0,
                                          ddx / nn, ddy / nn, mm_px) if nn > 1e-6 else np.nan)
            out[n_out, 10] = pshare
            n_out += 1
            if n_out == out.shape[0]:
                return out[:n_out]
    return out[:n_out]


@numba.njit(cache=True, nogil=True)
def _band_near(core: np.ndarray, pad: int, reg: np.ndarray, x0: int, y0: int,
               ox0: int, oy0: int, ox1: int, oy1: int, force: bool) -> np.ndarray:
    """The band (the eroded ``core`` dilated by ``pad``) over the outer window [oy0:oy1,
    ox0:ox1], or an empty (0, 0) array when it holds nothing but the region itself (``reg``,
    at x0, y0) and ``force`` is False."""
    H, W = core.shape
    h, w = reg.shape
    if not force:
        # anything else there: more core pixels in the window than in the region
        n_all = 0
        for gy in range(oy0, oy1):
            row = core[gy]
            for gx in range(ox0, ox1):
                n_all += row[gx] != 0
        n_reg = 0
        for y in range(h):
            for x in range(w):
                if reg[y, x] and core[y0 + y, x0 + x]:
                    n_reg += 1
        if n_all == n_reg:
            return np.zeros((0, 0), np.uint8)
    band = np.zeros((oy1 - oy0, ox1 - ox0), np.uint8)
    for gy in range(oy0, oy1):
        for gx in range(ox0, ox1):
            if not core[gy, gx]:
                continue
            for yy in range(max(oy0, gy - pad), min(oy1, gy + pad + 1)):
                for xx in range(max(ox0, gx - pad), min(ox1, gx + pad + 1)):
                    band[yy - oy0, xx - ox0] = 1
    return band


@numba.njit(cache=True, nogil=True)
def _own(part: np.ndarray, band: np.ndarray, dx: int, dy: int) -> np.ndarray:
    """Pixels of the part's window nearer to the part than to any other band pixel (all, when
    ``band`` is empty); the part's window sits at (dx, dy) in the band's."""
    h, w = part.shape
    own = np.ones((h, w), np.bool_)
    if band.shape[0] == 0:
        return own
    bh, bw = band.shape
    mine = np.zeros((bh, bw), np.uint8)
    for y in range(h):
        for x in range(w):
            if part[y, x]:
                mine[y + dy, x + dx] = 1
    others = np.zeros((bh, bw), np.uint8)
    n_o = 0
    for y in range(bh):
        for x in range(bw):
            if band[y, x] and not mine[y, x]:
                others[y, x] = 1
                n_o += 1
    if n_o == 0:
        return own
    d_own = chamfer(mine)
    d_oth = chamfer(others)
    for y in range(h):
        for x in range(w):
            own[y, x] = d_own[y + dy, x + dx] <= d_oth[y + dy, x + dx]
    return own


@numba.njit(cache=True, nogil=True)
def _grow(part: np.ndarray, own: np.ndarray, hs: np.ndarray, tl: np.ndarray, x0: int, y0: int,
          rr: int, hx: float, hy: float, ux: float, uy: float, beside: float
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The finger's pixels near its tip: the part grown into raised pixels within 2 rr of it
    that are its ``own``, and connected to it (4-neighbours). Returns their x, y and whether
    each is firm: in the part, or raised above ``_FIRM_TL`` Tl and within ``beside`` px of
    the part's extent across the finger (the finger runs from the hand at (hx, hy) along the
    unit (ux, uy)); the others are the faint rim above ``_GROW_TL`` Tl and the raised pixels
    beside the finger, which give the tip's height but not its point (see
    :func:`fingertip.extremity`)."""
    h, w = part.shape
    lat_lo, lat_hi = np.inf, -np.inf
    for y in range(h):
        for x in range(w):
            if part[y, x]:
                lat = (y - hy) * ux - (x - hx) * uy
                lat_lo, lat_hi = min(lat_lo, lat), max(lat_hi, lat)
    lat_lo -= beside
    lat_hi += beside
    reach = near_mask(part, 2 * rr)
    grown = np.zeros((h, w), np.uint8)
    for y in range(h):
        for x in range(w):
            if part[y, x]:
                grown[y, x] = 1
            elif reach[y, x] and own[y, x]:
                v = hs[y, x]
                if v == v and v > max(_GROW_TL * tl[y0 + y, x0 + x], 2.0):
                    grown[y, x] = 1
    # keep what is connected to the part
    stack_y = np.empty(h * w, np.int64)
    stack_x = np.empty(h * w, np.int64)
    top = 0
    for y in range(h):
        for x in range(w):
            if part[y, x]:
                grown[y, x] = 2
                stack_y[top], stack_x[top] = y, x
                top += 1
    fx = np.empty(h * w, np.int64)
    fy = np.empty(h * w, np.int64)
    firm = np.empty(h * w, np.bool_)
    n = 0
    while top > 0:
        top -= 1
        y, x = stack_y[top], stack_x[top]
        fx[n], fy[n] = x, y
        if part[y, x]:
            firm[n] = True
        else:
            lat = (y - hy) * ux - (x - hx) * uy
            firm[n] = (hs[y, x] > max(_FIRM_TL * tl[y0 + y, x0 + x], 2.0)
                       and lat_lo <= lat <= lat_hi)
        n += 1
        for k in range(4):
            yy = y + (1 if k == 0 else -1 if k == 1 else 0)
            xx = x + (1 if k == 2 else -1 if k == 3 else 0)
            if 0 <= yy < h and 0 <= xx < w and grown[yy, xx] == 1:
                grown[yy, xx] = 2
                stack_y[top], stack_x[top] = yy, xx
                top += 1
    return fx[:n], fy[:n], firm[:n]


def warm_up() -> None:
    """Compile (or load from the on-disk cache) every kernel on a tiny frame, so that the
    first real frame does not wait for the compiler (seconds on a first run)."""
    h, w = 32, 32
    depth = np.full((h, w), 1000, np.uint16)
    depth[10:20, 10:20] = 990
    lo = np.full((h, w), 975, np.uint16)
    hi = np.full((h, w), 995, np.uint16)
    f32 = np.ones((h, w), np.float32)
    valid = np.ones((h, w), np.bool_)
    core = np.zeros((h, w), np.uint8)
    boxes = np.array([[10, 10, 10, 10]], np.int64)
    masks = np.ones(100, np.uint8)
    start = np.zeros(1, np.int64)
    hands = np.zeros((h // 4, w // 4), np.uint8)
    hands[2:5, 2:5] = 2
    for method in (0, 1):
        frame_points(depth, hands, 4, KernelSurface(lo, hi, f32 * 1000, f32, f32 * 4, valid, 1.0),
                     KernelRegions(core, 1, boxes, masks, start),
                     TipParams(3.0, method == 1, 6, 18.0, 2.0))
