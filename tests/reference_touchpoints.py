"""Reference touch points: the per-region numpy/OpenCV version of the fingertip estimator.

This is how ``depthtouch.touch.points`` worked before its per-region steps were compiled into
``depthtouch.touch.tipkernel``: some 40 small array calls per region. It is kept here as the test
oracle: the compiled kernel must find the same points (tests/test_touchpoints.py). Likewise
:func:`regions_of_core`, the regions from OpenCV's outer contours, is the oracle of the compiled
``depthtouch.touch.regions.band_regions`` (tests/test_regions.py).
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from depthtouch.config import TouchPointConfig
from depthtouch.surface.bounds import HAND_SCALE, BandBounds
from depthtouch.touch.parallax import foot_px
from depthtouch.touch.regions import Regions
from depthtouch.types import TouchPoints

_K3 = np.ones((3, 3), np.uint8)


def _kernel(size: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_RECT, (size, size))
# The paper's 3x3 block patterns: the full block and the four half blocks (a 2x3 or 3x2 side).
_PATTERNS = [
    np.ones((3, 3), np.uint8),
    np.array([[1, 1, 1], [1, 1, 1], [0, 0, 0]], np.uint8),
    np.array([[0, 0, 0], [1, 1, 1], [1, 1, 1]], np.uint8),
    np.array([[1, 1, 0], [1, 1, 0], [1, 1, 0]], np.uint8),
    np.array([[0, 1, 1], [0, 1, 1], [0, 1, 1]], np.uint8),
]


def _smooth_heights(depth: np.ndarray, bounds: BandBounds, roi: tuple[int, int, int, int]) -> np.ndarray:
    """Height in mm over ``roi``, 3x3 mean of the known pixels; NaN where fewer than 3 of 9 are."""
    x, y, w, h = roi
    d = depth[y:y + h, x:x + w]
    ok = ((d > 0) & bounds.valid[y:y + h, x:x + w]).astype(np.float32)
    hm = (bounds.surface_mm[y:y + h, x:x + w] - d * np.float32(bounds.to_mm)) \
        * bounds.factor[y:y + h, x:x + w]
    num = cv2.blur(hm * ok, (3, 3))
    den = cv2.blur(ok, (3, 3))
    out = num / np.maximum(den, np.float32(1e-6))
    out[den < 0.3] = np.nan
    return out


def _centroid(mask: np.ndarray) -> tuple[float, float, float]:
    """(count, x, y) of a binary uint8 mask in one pass."""
    m = cv2.moments(mask, binaryImage=True)
    n = m["m00"]
    if n <= 0:
        return 0.0, 0.0, 0.0
    return n, m["m10"] / n, m["m01"] / n


def find_touch_points(
    depth: np.ndarray,
    high: np.ndarray,
    regions: Regions,
    bounds: BandBounds,
    config: TouchPointConfig,
) -> TouchPoints:
    """Touch points of the regions of one frame (pure; see the module doc)."""
    if len(regions) == 0:
        return TouchPoints.empty()
    hands = hand_map(high, depth, bounds)
    H, W = depth.shape
    r0 = config.tip_radius_mm / bounds.mm_per_px
    margin = int(np.ceil(3.0 * r0)) + 3
    k_attach = cv2.getStructuringElement(cv2.MORPH_RECT, (5, 5))
    min_attach = 3.0
    rr = max(1, int(round(r0)))
    k_reach = cv2.getStructuringElement(cv2.MORPH_RECT, (4 * rr + 1, 4 * rr + 1))
    # the regions' band is eroded (see find_regions): open it back
    band = regions.band
    if band is not None and bounds.open_px > 1:
        band = cv2.dilate(band, cv2.getStructuringElement(
            cv2.MORPH_RECT, (bounds.open_px, bounds.open_px)))
    xy_out: list[tuple[float, float]] = []
    h_out: list[float] = []
    a_out: list[int] = []
    hand_out: list[tuple[float, float]] = []
    border_out: list[bool] = []
    share_out: list[float] = []
    for mask, (bx, by, bw, bh), area in zip(regions.masks, regions.bbox_xywh, regions.area_px):
        x0, y0 = max(0, int(bx) - margin), max(0, int(by) - margin)
        x1, y1 = min(W, int(bx + bw) + margin), min(H, int(by + bh) + margin)
        whole = np.zeros((y1 - y0, x1 - x0), np.uint8)
        whole[by - y0:by - y0 + bh, bx - x0:bx - x0 + bw] = mask
        hs: np.ndarray | None = None
        # Other regions nearby: the finger may grow only into pixels nearer to it than to them.
        own = None
        others = None
        if band is not None and len(regions) > 1:
            others = cv2.bitwise_and(band[y0:y1, x0:x1], cv2.bitwise_not(whole * 255))
        if others is not None and cv2.countNonZero(others):
            seeds = cv2.bitwise_or(whole * 2, (others > 0).view(np.uint8))
            _, nearest = cv2.distanceTransformWithLabels(
                (seeds == 0).view(np.uint8), cv2.DIST_L2, 3, labelType=cv2.DIST_LABEL_PIXEL
            )
            # label of each seed pixel -> whether it belongs to this region
            mine = np.zeros(int(nearest.max()) + 1, np.uint8)
            mine[nearest[whole > 0]] = 1
            own = mine[nearest]
        # The hand: pixels above Tu next to the region that belong to an arm reaching in from
        # the image border (not an object standing on the surface, not a noisy pixel).
        levels = hand_window(hands, x0, y0, x1, y1)
        hand_roi = cv2.bitwise_and(high[y0:y1, x0:x1], cv2.inRange(levels, 1, 255))
        attach_all = cv2.bitwise_and(cv2.dilate(whole, k_attach), hand_roi)
        n_all, hx0, hy0 = _centroid(attach_all)
        if n_all < min_attach:
            continue  # not attached to a hand: a flat object or noise
        pts = cv2.findNonZero(whole).reshape(-1, 2)
        proj = _project(pts, np.array([hx0, hy0]))
        if proj is None or _is_sliver(proj, r0):
            continue  # a thin strip along the side of something raised: an edge, not a finger
        parts = (_split_fingers(whole, pts, proj, r0) if area > 10.0 * r0 * r0 else [whole])
        for reg in parts:
            if len(parts) == 1:
                n_att, hx, hy = n_all, hx0, hy0
            else:
                n_att, hx, hy = _centroid(cv2.bitwise_and(cv2.dilate(reg, k_attach), hand_roi))
                if n_att < min_attach:
                    n_att, hx, hy = n_all, hx0, hy0
            hand = np.array([hx, hy])
            if hs is None:
                hs = _smooth_heights(depth, bounds, (x0, y0, x1 - x0, y1 - y0))
            if config.method == "paper":
                pt = _paper_point(reg, hs, hand, config)
            else:
                part_own = own
                if len(parts) > 1:
                    other_parts = cv2.bitwise_and(whole, cv2.bitwise_not(reg))
                    part_own = _nearest_mask(reg, other_parts, own)
                center = ((float(pts[:, 0].mean()), float(pts[:, 1].mean()))
                          if len(parts) == 1 else None)
                pt = _extremity_point(reg, hs, hand, r0, bounds.tl_mm[y0:y1, x0:x1], k_reach,
                                      part_own, center, config.tip_beside_px)
            if pt is None:
                continue
            xy_out.append((pt[0] + x0, pt[1] + y0))
            h_out.append(pt[2])
            a_out.append(int(area) if len(parts) == 1 else cv2.countNonZero(reg))
            hand_out.append((hx + x0, hy + y0))
            att = attach_all if len(parts) == 1 else cv2.bitwise_and(
                cv2.dilate(reg, k_attach), hand_roi)
            border_out.append(bool(cv2.countNonZero(cv2.bitwise_and(
                att, cv2.inRange(levels, 2, 2)))))
            # the attachment's share of the ring around the region: the pixels within 2 px of
            # it, outside it, with a depth on a usable pixel
            ring = cv2.bitwise_and(cv2.dilate(reg, k_attach), cv2.bitwise_not(reg))
            ring &= (depth[y0:y1, x0:x1] > 0) & bounds.valid[y0:y1, x0:x1]
            share_out.append(cv2.countNonZero(att) / max(1, cv2.countNonZero(ring)))
    if not xy_out:
        return TouchPoints.empty()
    xy = np.asarray(xy_out, np.float64)
    if config.method == "extremity":  # to the surface beneath the tip (tested on its own)
        xy = foot_px(xy, bounds, config.tip_axis_mm)
    return TouchPoints(
        xy, np.asarray(h_out, np.float64),
        np.asarray(a_out, np.int64), np.asarray(hand_out, np.float64),
        np.asarray(border_out, bool), attach_share=np.asarray(share_out, np.float64),
    )


def hand_map(high: np.ndarray, depth: np.ndarray, bounds: BandBounds) -> np.ndarray:
    """Where hands are: parts above Tu connected to the image border, at 1/4 resolution (uint8:
    2 = connected to the border, 1 = large enough to be a hand, 0 = no hand).

    People reach into the view from outside it, so a hand is normally attached, through its arm,
    to the border; an object standing on the surface, tall or not, is not. Where the view is so
    wide that a whole arm is in it, a raised part of at least ``min_hand_mm2`` counts too (a tall
    object that large counts until the surface absorbs it, about a second after it was put
    down). Missing depth over a usable surface pixel counts as raised too: an arm close to the
    camera is often nearer than the camera can measure. Sampled bilinearly and dilated, so that a
    thin finger does not fall apart at 1/4 resolution.
    """
    h, w = high.shape
    size = (max(1, w // HAND_SCALE), max(1, h // HAND_SCALE))
    # bilinear samples between pixels: a sample is non-zero when any of its 2x2 pixels is high
    small_high = cv2.resize(high, size, interpolation=cv2.INTER_LINEAR)
    small_valid = cv2.resize(bounds.valid.astype(np.uint8) * np.uint8(255), size,
                             interpolation=cv2.INTER_NEAREST)
    small_zero = cv2.bitwise_and(
        cv2.inRange(cv2.resize(depth, size, interpolation=cv2.INTER_NEAREST), 0, 0), small_valid)
    small = cv2.dilate(cv2.bitwise_or(cv2.inRange(small_high, 1, 255), small_zero),
                       _kernel(3))
    n, labels = cv2.connectedComponents(small, connectivity=8, ltype=cv2.CV_16U)
    level = np.zeros(n, np.uint8)
    # labels on the view's edge: parts reaching in from outside it (labelling without stats
    # and looking at the four edges costs a third of labelling with stats)
    edge = np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])
    level[edge] = 2
    level[0] = 0
    inner = np.flatnonzero(level[1:] == 0) + 1
    if inner.size:
        # parts inside the view: a hand only when large enough
        area = np.bincount(labels.ravel(), minlength=n)
        big = area * (HAND_SCALE * bounds.mm_per_px) ** 2 >= bounds.min_hand_mm2
        level[inner[big[inner]]] = 1
    # one more coarse pixel around it: the coarse grid must not cut off the last pixels of an
    # arm next to a fingertip (the caller intersects with the full-resolution mask)
    return cv2.dilate(level[labels], _kernel(3))


def hand_window(hands: np.ndarray, x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
    """The hand map's levels (0, 1, 2) over the full-resolution window [y0:y1, x0:x1]."""
    s = HAND_SCALE
    sy0, sx0 = y0 // s, x0 // s
    sy1, sx1 = min(hands.shape[0], -(-y1 // s)), min(hands.shape[1], -(-x1 // s))
    out = np.zeros((y1 - y0, x1 - x0), np.uint8)
    block = hands[sy0:sy1, sx0:sx1]
    if block.size == 0:
        return out
    up = cv2.resize(block, (block.shape[1] * s, block.shape[0] * s),
                    interpolation=cv2.INTER_NEAREST)
    oy, ox = y0 - sy0 * s, x0 - sx0 * s
    part = up[oy:oy + (y1 - y0), ox:ox + (x1 - x0)]
    out[:part.shape[0], :part.shape[1]] = part
    return out


def _project(pts: np.ndarray, hand: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(s, lat): region pixels along the direction from the hand to the region's centre, and
    across it; None when the hand sits at the centre."""
    px = pts[:, 0] - hand[0]
    py = pts[:, 1] - hand[1]
    n_px = px.shape[0]
    dx, dy = float(px.sum()) / n_px, float(py.sum()) / n_px
    n = (dx * dx + dy * dy) ** 0.5
    if n < 1e-6:
        return None
    dx, dy = dx / n, dy / n
    return px * dx + py * dy, py * dx - px * dy


def _is_sliver(proj: tuple[np.ndarray, np.ndarray], r0: float) -> bool:
    """A region that is short away from the hand (under a tip radius), or short away from it but
    long beside it: the band along the edge of an arm or an object (mixed depths at its
    silhouette), not a fingertip, which sticks out of the hand by at least its radius."""
    s, lat = proj
    along = float(s.max() - s.min()) + 1.0
    across = float(lat.max() - lat.min()) + 1.0
    return along < r0 or (along < 1.5 * r0 and across > 3.0 * along)


def _split_fingers(
    reg: np.ndarray, pts: np.ndarray, proj: tuple[np.ndarray, np.ndarray], r0: float
) -> list[np.ndarray]:
    """Fingertips side by side merge into one region; split it between their tips.

    Seen along the finger direction (from the hand), the front of the region, per 1-px lateral
    slice, has one bump per fingertip (tips are round). Bumps at least 1.6 tip radii apart with
    a dip of at least half a radius between them are separate fingers: the region is cut at the
    dips. A single fingertip has one bump and stays whole.
    """
    s, lat = proj
    xs, ys = pts[:, 0], pts[:, 1]
    lb = (lat - lat.min()).astype(np.intp)
    front = np.full(int(lb.max()) + 1, -np.inf)
    np.maximum.at(front, lb, s)
    w = max(1, int(np.ceil(0.5 * r0)))
    padded = np.pad(front, w, constant_values=-np.inf)
    win = np.lib.stride_tricks.sliding_window_view(padded, 2 * w + 1).max(axis=1)
    peaks = np.flatnonzero((front == win) & np.isfinite(front))
    cuts: list[int] = []
    last = None
    for p in peaks:
        if last is not None and p - last >= 1.6 * r0:
            seg = front[last:p + 1]
            notch = np.linspace(front[last], front[p], seg.shape[0]) - seg
            valley = int(np.argmax(notch))
            if notch[valley] >= 0.5 * r0:
                cuts.append(int(last) + valley)
                last = p
                continue
        if last is None or front[p] > front[last]:
            last = p
    if not cuts:
        return [reg]
    edges = [-1, *cuts, int(lb.max()) + 1]
    parts = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (lb > lo) & (lb <= hi) if hi != edges[-1] else (lb > lo)
        part = np.zeros_like(reg)
        part[ys[sel], xs[sel]] = 1
        parts.append(part)
    return parts


def _nearest_mask(reg: np.ndarray, others: np.ndarray, base: np.ndarray | None) -> np.ndarray:
    """Pixels nearer to ``reg`` than to ``others`` (and inside ``base`` when given)."""
    seeds = cv2.bitwise_or(reg * 2, others)
    _, nearest = cv2.distanceTransformWithLabels(
        (seeds == 0).view(np.uint8), cv2.DIST_L2, 3, labelType=cv2.DIST_LABEL_PIXEL
    )
    mine = np.zeros(int(nearest.max()) + 1, np.uint8)
    mine[nearest[reg > 0]] = 1
    out = mine[nearest]
    return out if base is None else cv2.bitwise_and(out, base)


def _extremity_point(
    reg: np.ndarray,
    hs: np.ndarray,
    hand: np.ndarray,
    r0: float,
    tl_mm: np.ndarray,
    k_reach: np.ndarray,
    own: np.ndarray | None = None,
    center: tuple[float, float] | None = None,
    beside: float = 2.0,
) -> tuple[float, float, float] | None:
    # The finger's shape near the tip: the region grown into raised pixels nearby on the
    # smoothed map (noise averaged over 9 px): the tip cap that Tl cut away, and the finger body
    # that rises above Tu behind a steep tip.
    # Only what is connected to the region counts: the noise of stereo cameras is spatially
    # correlated, so a 3x3 mean does not remove blobs of it next to the tip.
    raised = hs > np.maximum(tl_mm * np.float32(0.5), np.float32(2.0))
    # the point is placed on the firm pixels: the region and those clearly raised (the faint
    # rim flickers by a pixel from frame to frame); the height comes from all of them
    firm_map = (hs > np.maximum(tl_mm * np.float32(0.85), np.float32(2.0))) | (reg > 0)
    reach = cv2.dilate(reg, k_reach)
    if own is not None:
        reach = cv2.bitwise_and(reach, own)
    grown = cv2.bitwise_or(reg, cv2.bitwise_and(raised.view(np.uint8), reach))
    n_lab, labels = cv2.connectedComponents(grown, connectivity=4)
    if n_lab > 2:
        keep = np.zeros(n_lab, np.uint8)
        keep[labels[reg > 0]] = 1
        keep[0] = 0
        finger = keep[labels]
    else:
        finger = grown
    if center is None:
        _, cx, cy = _centroid(reg)
    else:
        cx, cy = center
    dx, dy = cx - hand[0], cy - hand[1]
    norm = float(np.hypot(dx, dy))
    if norm < 1e-6:
        return None
    dx, dy = dx / norm, dy / norm
    pts = cv2.findNonZero(finger).reshape(-1, 2).astype(np.float64)
    px = pts[:, 0] - hand[0]
    py = pts[:, 1] - hand[1]
    s_all = px * dx + py * dy
    # ... and only within ``beside`` px of the region's own extent across the finger: beside it
    # lies another finger or the hand's side
    lat_all = py * dx - px * dy
    ry, rx = np.nonzero(reg)
    lat_reg = (ry - hand[1]) * dx - (rx - hand[0]) * dy
    iy, ix = pts[:, 1].astype(np.intp), pts[:, 0].astype(np.intp)
    near = (lat_all >= lat_reg.min() - beside) & (lat_all <= lat_reg.max() + beside)
    firm = (reg[iy, ix] > 0) | (firm_map[iy, ix] & near)
    s = s_all[firm]
    lat = lat_all[firm]
    # Front of the tip: the farthest 1-px slice along the finger that is at least half a tip
    # radius wide (a one-pixel noise spur in front of the tip is not the tip).
    s0 = float(s.min())
    counts = np.bincount((s - s0).astype(np.intp))
    wide = np.flatnonzero(counts >= max(1.0, 0.5 * r0))
    s_front = s0 + float(wide[-1] if wide.size else counts.size - 1) + 1.0
    # finger width in a slab behind the tip cap -> radius (hands differ)
    n_slab = np.count_nonzero((s > s_front - 3.0 * r0) & (s <= s_front - r0))
    r = min(max(n_slab / (4.0 * r0), 0.6 * r0), 1.5 * r0)
    cap = s > s_front - 2.0 * r
    l_cap = lat[cap]
    l_c = float(l_cap.sum()) / max(1, l_cap.shape[0])
    # The contact is under the centre of the rounded tip. Its position along the finger comes
    # from an area, not an edge: pixels of the tip ahead of the centre fill half a disc of radius
    # r, and their mean lies 4 r / (3 pi) ahead of it (sub-pixel: the pixel grid and a stray
    # pixel move it by a fraction of a pixel).
    near = np.abs(lat - l_c) <= r + 0.5
    ahead = np.sort(s[near & (s > s_front - 3.0 * r)])[::-1]
    k = int(round(np.pi * r * r / 2.0))
    s_c = (float(ahead[:min(k, ahead.size - 1) + 1].mean()) - 4.0 * r / (3.0 * np.pi)
           if ahead.size else s_front - r)
    x = hand[0] + s_c * dx - l_c * dy
    y = hand[1] + s_c * dy + l_c * dx
    # the tip's height: from all the finger's pixels in the cap
    cap_all = s_all > s_front - 2.0 * r
    cap_h = hs[pts[cap_all, 1].astype(np.intp), pts[cap_all, 0].astype(np.intp)]
    cap_h = cap_h[cap_h == cap_h]
    if cap_h.size == 0:
        return float(x), float(y), float("nan")
    k = cap_h.size // 4
    return float(x), float(y), float(np.partition(cap_h, k)[k])


def _paper_point(
    reg: np.ndarray, hs: np.ndarray, hand: np.ndarray, config: TouchPointConfig
) -> tuple[float, float, float] | None:
    ry, rx = np.nonzero(reg)
    c = np.array([rx.mean(), ry.mean()])
    d = c - hand
    bx0, bx1, by0, by1 = rx.min(), rx.max(), ry.min(), ry.max()
    ds = config.paper_ds_px
    search = np.zeros_like(reg)
    # the bounding-box edge away from the hand
    if abs(d[0]) >= abs(d[1]):
        if d[0] >= 0:
            search[by0:by1 + 1, max(bx1 - ds + 1, bx0):bx1 + 1] = 1
        else:
            search[by0:by1 + 1, bx0:min(bx0 + ds, bx1 + 1)] = 1
    else:
        if d[1] >= 0:
            search[max(by1 - ds + 1, by0):by1 + 1, bx0:bx1 + 1] = 1
        else:
            search[by0:min(by0 + ds, by1 + 1), bx0:bx1 + 1] = 1
    cand = ((reg > 0) & (np.nan_to_num(hs, nan=np.inf) < config.paper_tt_mm)).astype(np.uint8)
    confirmed = np.zeros_like(cand)
    for pat in _PATTERNS:
        confirmed |= cv2.erode(cand, pat, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    confirmed &= search
    ys, xs = np.nonzero(confirmed)
    if ys.size == 0:
        return None
    dn = d / max(float(np.hypot(d[0], d[1])), 1e-9)
    s = (xs - hand[0]) * dn[0] + (ys - hand[1]) * dn[1]
    i = int(np.argmax(s))
    return float(xs[i]), float(ys[i]), float(hs[ys[i], xs[i]])


def regions_of_core(core: np.ndarray, open_px: int, min_area_px: int) -> Regions:
    """The regions of a band eroded by ``open_px`` (uint8, 0 / 255): the outer contours of its
    parts (OpenCV), each filled and dilated back by ``open_px`` within its box grown by half of
    it, those of at least ``min_area_px`` pixels; when two come so close that their dilations
    could join, the contours of the whole dilated core instead."""
    if not cv2.hasNonZero(core):
        return Regions.empty()
    k = open_px
    contours, _ = cv2.findContours(core, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    pad = k // 2
    regions = _contour_regions(contours, core.shape, min_area_px, pad, k)
    boxes = regions.bbox_xywh.tolist()
    close = any(xi <= xj + wj and xj <= xi + wi and yi <= yj + hj and yj <= yi + hi
                for i, (xi, yi, wi, hi) in enumerate(boxes) for (xj, yj, wj, hj) in boxes[i + 1:])
    if pad and close:
        opened = cv2.dilate(core, _kernel(k))
        contours, _ = cv2.findContours(opened, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        regions = _contour_regions(contours, core.shape, min_area_px, 0, 1)
    return regions


def _contour_regions(contours: Sequence[np.ndarray], shape: tuple[int, ...], min_area: int,
                     pad: int, k: int) -> Regions:
    H, W = shape[:2]
    boxes: list[tuple[int, int, int, int]] = []
    areas: list[int] = []
    masks: list[np.ndarray] = []
    for c in contours:
        x, y, w, h = cv2.boundingRect(c)
        if (w + 2 * pad) * (h + 2 * pad) < min_area:
            continue
        x0, y0 = max(0, x - pad), max(0, y - pad)
        x1, y1 = min(W, x + w + pad), min(H, y + h + pad)
        m: np.ndarray = np.zeros((y1 - y0, x1 - x0), np.uint8)
        cv2.drawContours(m, [c], -1, 1, thickness=cv2.FILLED, offset=(-x0, -y0))
        if pad:
            m = cv2.dilate(m, _kernel(k))
        area = cv2.countNonZero(m)
        if area < min_area:
            continue
        boxes.append((x0, y0, x1 - x0, y1 - y0))
        areas.append(area)
        masks.append(m)
    if not boxes:
        return Regions.empty()
    starts = np.cumsum([0] + [m.size for m in masks[:-1]]).astype(np.int64)
    return Regions(np.asarray(boxes, np.int64), np.asarray(areas, np.int64),
                   np.concatenate([m.ravel() for m in masks]), starts)


def band_masks(depth: np.ndarray, bounds: BandBounds) -> tuple[np.ndarray, np.ndarray]:
    """(band, high) uint8 masks (255 = in) of a raw depth frame; zeros are in neither."""
    band = cv2.inRange(depth, bounds.band_lo, bounds.band_hi)
    high = cv2.inRange(depth, bounds.high_lo, bounds.high_hi)
    return band, high
