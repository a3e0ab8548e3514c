"""Touch points: inside each touch region, the point where the fingertip touches the surface.

Two estimators, selectable by ``TouchPointConfig.method``:

- ``extremity`` (default): the region is attached to the hand (pixels above Tu next to it); the
  direction from that attachment to the region points along the finger to its tip. The region is
  grown into neighbouring pixels that pass a lower threshold on a 3x3-smoothed height map (the
  tip cap that Tl cut away; these give the tip's height). On the firm ones among them (the region
  and those above 0.85 Tl: the faint rim flickers by a pixel from frame to frame; and of those,
  only within ``tip_beside_px`` (2) of the region's own extent across the finger: the growth
  reaches two tip radii, and beside a tip lies another finger or the hand's side) the front edge
  of the tip is found along the finger direction, the finger's width behind the tip gives its
  radius r, and the contact point is the centre of the rounded tip, under which it rests on the
  surface: the mean of the pi r^2 / 2 front-most pixels, less 4 r / (3 pi). Sub-pixel. That
  point is the image of the tip's centre, about a finger radius above the surface; it is then
  moved to the surface point beneath it (:mod:`depthtouch.touch.parallax`), which an oblique
  view would otherwise place beyond the contact. Where the depth is noisy, Tl is higher and
  cuts more of the tip's front away: the reported contact is moved forward along the finger
  by ``tip_tl_shift`` mm per mm of Tl above its floor (:func:`tl_offset_px`; an offset that
  tracking does not use, ``TouchPoints.offset_px``).
- ``paper`` (Lee & Kwon 2019): a search band of Ds pixels inside the bounding-box edge away from
  the hand; candidates are pixels within Tt of the surface; a candidate counts when its 3x3
  neighbourhood matches one of the block patterns; the touch point is the centre of the block
  farthest toward the tip. Integer pixels.

Regions not attached to a hand (a flat object, noise) give no touch point.

Fingertips side by side merge into one region: seen along the finger direction, the region's
front has one bump per fingertip; bumps at least 1.6 tip radii apart with a dip of at least half
a radius between them are separate fingers, and the region is cut at the dips.

Speed: the per-region work runs in one compiled call per frame (:mod:`depthtouch.touch.tipkernel`),
each region on a small window around it; the whole-frame steps (band and regions, hand map) are
compiled too (:mod:`depthtouch.touch.regions`, :mod:`depthtouch.touch.handmap`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..config import TouchPointConfig
from ..surface.bounds import HAND_SCALE, BandBounds
from ..types import TouchPoints
from .handmap import hand_map
from .parallax import foot_px
from .regions import Regions
from .tipkernel import KernelRegions, KernelSurface, TipParams, frame_points
from .tipmaps import core_heights


def find_touch_points(
    depth: np.ndarray,
    regions: Regions,
    bounds: BandBounds,
    config: TouchPointConfig,
) -> TouchPoints:
    """Touch points of the regions of one frame (pure; see the module doc).

    depth: the (prefiltered) uint16 frame; regions: from :func:`regions.band_regions`;
    bounds: the surface's band bounds.
    """
    if len(regions) == 0:
        return TouchPoints.empty()
    hands = hand_map(depth, bounds)
    core = regions.band if regions.band is not None else _core_of(regions, depth.shape)
    pad = bounds.open_px // 2 if regions.band is not None else 0
    b = bounds
    out = frame_points(
        depth, hands, HAND_SCALE,
        KernelSurface(b.high_lo, b.high_hi, b.surface_mm, b.factor, b.tl_mm, b.valid, b.to_mm),
        KernelRegions(core, pad, regions.bbox_xywh, regions.mask_buf, regions.mask_start),
        TipParams(config.tip_radius_mm / b.mm_per_px, config.method == "paper",
                  config.paper_ds_px, config.paper_tt_mm, b.mm_per_px, config.tip_beside_px),
    )
    if out.xy_px.shape[0] == 0:
        return TouchPoints.empty()
    xy, offset = out.xy_px, None
    if config.method == "extremity":
        xy = foot_px(xy, b, config.tip_axis_mm)
    above = tl_above_floor_mm(xy, b)
    if config.method == "extremity" and (config.tip_tl_shift > 0 or config.tip_shift_mm > 0):
        offset = tl_offset_px(xy, out.hand_xy_px, above, b.mm_per_px, config.tip_tl_shift,
                              config.tip_shift_mm)
    return TouchPoints(xy, out.height_mm, out.area_px, out.hand_xy_px, out.hand_at_border,
                       out.attach_px, out.attach_height_mm, out.back_spread_mm, offset,
                       core_heights_mm(depth, xy, b), above, out.attach_share)


def core_heights_mm(depth: np.ndarray, xy_px: np.ndarray, bounds: BandBounds) -> np.ndarray:
    """The height of the finger's core at each point: the 75th percentile (linear, as
    ``np.nanpercentile``) of the known heights of the 3x3 pixels around its nearest pixel,
    clamped to the image (pure, float64 (N,); NaN where none is known).

    The measured tip height is the lowest part of the tip cap, and at ToF range the mixed pixels
    of a hovering finger's outline lie as low as a touching tip's (docs/accuracy.md section 7,
    session 19); the core's height still rises as the finger lifts, which the tracker's lift
    test compares with the same contact's earlier frames.
    """
    xy = np.ascontiguousarray(np.asarray(xy_px, np.float64).reshape(-1, 2))
    out = np.empty(xy.shape[0])
    core_heights(depth, bounds.surface_mm, bounds.factor, bounds.valid, float(bounds.to_mm),
                 xy, out)
    return out


def tl_above_floor_mm(xy_px: np.ndarray, bounds: BandBounds) -> np.ndarray:
    """How far Tl around each point lies above its floor (mm, >= 0; pure, float64 (N,)).

    Tl is averaged over the point's neighbourhood (``BandBounds.tl_around_mm``, 9x9 pixels): a
    pixel's own noise estimate is itself noisy, and a point moving by a pixel must not change
    what is derived from it (the report's forward shift, the evidence of a small region).
    """
    xy = np.ascontiguousarray(np.asarray(xy_px, np.float64).reshape(-1, 2))
    tl_map = bounds.tl_around_mm if bounds.tl_around_mm is not None else bounds.tl_mm
    out = np.zeros(xy.shape[0])
    _tl_above(xy, tl_map, float(bounds.tl_floor_mm), out)
    return out


@numba.njit(cache=True, nogil=True)
def _tl_above(xy: np.ndarray, tl_map: np.ndarray, floor: float, out: np.ndarray) -> None:
    """:func:`tl_above_floor_mm`'s per-point step (``out`` zeros on entry; a NaN point, no
    pixel, stays 0). Compiled, like the other per-point steps: a handful of points a frame."""
    h1, w1 = tl_map.shape[0] - 1, tl_map.shape[1] - 1
    for i in range(xy.shape[0]):
        x, y = xy[i, 0], xy[i, 1]
        if x == x and y == y:
            tl = float(tl_map[min(max(round(y), 0), h1), min(max(round(x), 0), w1)])
            out[i] = max(tl - floor, 0.0)


def tl_offset_px(xy_px: np.ndarray, hand_xy_px: np.ndarray, above_mm: np.ndarray,
                 mm_per_px: float, per_mm: float, const_mm: float = 0.0) -> np.ndarray:
    """How far (px) to move each point forward along its finger, away from its hand: ``per_mm``
    times ``above_mm``, the amount by which Tl around it exceeds its floor
    (:func:`tl_above_floor_mm`), plus ``const_mm``, in mm on the surface (pure, float64
    (N, 2)).

    Where the depth is noisy, Tl rises above its floor (to k σ) and more of the tip's front
    stays out of the band and out of the grown tip cap: the extremity is found behind the
    contact, by 1.4-1.5 mm at the floor and 0.2-0.4 mm more per mm of Tl above it on stereo and
    structured light, and not at all on ToF at the floor (hard suite, tune half;
    docs/accuracy.md section 7, session 11).
    At the floor the offset is ``const_mm`` (TouchPointConfig.tip_shift_mm); it is 0 for
    points without a hand direction.
    """
    xy = np.ascontiguousarray(np.asarray(xy_px, np.float64).reshape(-1, 2))
    out = np.zeros_like(xy)
    if per_mm == 0.0 and const_mm == 0.0:
        return out
    hand = np.ascontiguousarray(np.asarray(hand_xy_px, np.float64).reshape(-1, 2))
    above = np.ascontiguousarray(np.asarray(above_mm, np.float64).reshape(-1))
    if hand.shape[0] != xy.shape[0] or above.shape[0] != xy.shape[0]:
        raise ValueError(f"tl_offset_px: {xy.shape[0]} points, {hand.shape[0]} hand points and "
                         f"{above.shape[0]} heights above the floor; give one of each per point")
    _tl_offset(xy, hand, above, per_mm / mm_per_px, const_mm / mm_per_px, out)
    return out


@numba.njit(cache=True, nogil=True)
def _tl_offset(xy: np.ndarray, hand: np.ndarray, above_mm: np.ndarray, per_px: float,
               const_px: float, out: np.ndarray) -> None:
    """:func:`tl_offset_px`'s per-point step (``out`` zeros on entry): ``per_px`` px per mm of
    Tl above its floor plus ``const_px``, along the direction from the hand to the point."""
    for i in range(xy.shape[0]):
        ux, uy = xy[i, 0] - hand[i, 0], xy[i, 1] - hand[i, 1]
        n = math.hypot(ux, uy)
        if not n > 1e-6:  # also NaN: no hand direction
            continue
        above = above_mm[i]
        above = above if above > 0.0 else 0.0  # (NaN, unknown: no Tl shift)
        if above > 0.0 or const_px > 0.0:
            step = (per_px * above + const_px) / n
            out[i, 0] = ux * step
            out[i, 1] = uy * step


def warm_up() -> None:
    """Compile (or load from the on-disk cache) this module's per-point kernels (see
    :func:`tipkernel.warm_up`)."""
    xy = np.zeros((1, 2))
    _tl_above(xy, np.ones((2, 2), np.float32), 1.0, np.zeros(1))
    _tl_offset(xy, np.ones((1, 2)), np.ones(1), 1.0, 1.0, np.zeros((1, 2)))


def _core_of(regions: Regions, shape: tuple[int, ...]) -> np.ndarray:
    """A band mask made of the regions alone (when the caller has no band mask)."""
    core = np.zeros(shape[:2], np.uint8)
    for (x, y, w, h), m in zip(regions.bbox_xywh.tolist(), regions.masks):
        core[y:y + h, x:x + w] |= m * np.uint8(255)
    return core
