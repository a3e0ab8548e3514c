"""Touch regions: the band Tl < height < Tu, labelled, size-filtered, attached to a hand.

The per-pixel thresholds are turned once (per surface) into depth bounds in the camera's own
units, so that the per-frame work is two ``cv2.inRange`` calls on the raw uint16 frame, one small
opening and one labelling, and nothing at all when the band is empty.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numba
import numpy as np

from .config import RegionConfig
from .surface import SurfaceModel, height_factor

HAND_SCALE = 4  # the hand map is kept at 1/4 resolution


@dataclass(frozen=True)
class BandBounds:
    """Per-pixel depth bounds (camera units, uint16 (H, W)) derived from a surface.

    band_lo..band_hi: depth of a pixel in the touch band (surface - Tu < d < surface - Tl).
    high_lo..high_hi: depth of hand/arm pixels (higher than Tu, lower than hand_max_mm).
    factor: height per depth difference (see :func:`surface.height_factor`).
    tl_mm: Tl per pixel (float32), surface_units: surface depth in camera units (float32).
    min_area_px: S_min in pixels; open_px: opening size actually used.
    """

    band_lo: np.ndarray
    band_hi: np.ndarray
    high_lo: np.ndarray
    high_hi: np.ndarray
    factor: np.ndarray
    tl_mm: np.ndarray
    surface_mm: np.ndarray
    sigma_mm: np.ndarray
    valid: np.ndarray
    to_mm: float
    mm_per_px: float
    min_area_px: int
    open_px: int
    tu_mm: float
    hand_max_mm: float
    valid_u8: np.ndarray | None = None
    min_hand_mm2: float = 6000.0
    small_valid: np.ndarray | None = None  # valid_u8 at the hand map's 1/4 resolution
    # the hand map's samples (see handmap.hand_levels): high_lo / high_hi at the 4 middle
    # pixels of each 1/4 block, (h/4, w/4, 4), and whether each block's corner pixel is usable
    hand_lo: np.ndarray | None = None
    hand_hi: np.ndarray | None = None
    hand_valid: np.ndarray | None = None


def _depth_bounds(
    surface_mm: np.ndarray, valid: np.ndarray, factor: np.ndarray, tl_mm: np.ndarray,
    to_mm: float, tu_mm: float, hand_max_mm: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """uint16 (band_lo, band_hi, high_lo, high_hi) for a block of pixels (pure)."""
    s_units = surface_mm / np.float32(to_mm)
    # height h = (s - d) * to_mm * f  <=>  d = s - h / (to_mm * f)
    per_mm = 1.0 / (np.float32(to_mm) * factor)
    band_lo = np.ceil(s_units - np.float32(tu_mm) * per_mm + 1e-3)
    band_hi = np.floor(s_units - tl_mm * per_mm - 1e-3)
    high_hi = band_lo - 1
    high_lo = np.ceil(s_units - np.float32(hand_max_mm) * per_mm)
    def clip(a: np.ndarray, empty: int) -> np.ndarray:
        out = np.clip(a, 1, 65535, out=a).astype(np.uint16)
        np.copyto(out, np.uint16(empty), where=~valid)
        return out

    return clip(band_lo, 1), clip(band_hi, 0), clip(high_lo, 1), clip(high_hi, 0)


def band_bounds(surface: SurfaceModel, config: RegionConfig, tip_radius_mm: float = 7.0) -> BandBounds:
    """Precompute the per-pixel bounds for :func:`band_masks` (once per surface).

    The bounds own a copy of the surface depth, so that :func:`refresh_rows` can follow a
    surface that updates itself without touching the caller's model.
    """
    cfg = config
    to_mm = surface.depth_scale_m * 1000.0
    f = height_factor(surface)
    tl = np.maximum(np.float32(cfg.tl_floor_mm), np.float32(cfg.noise_k) * surface.sigma_mm)
    # Tl can never reach Tu: a camera this noisy leaves an empty band (reported, not hidden).
    tl = np.minimum(tl, np.float32(cfg.tu_mm)).astype(np.float32)
    surface_mm = surface.depth_mm.astype(np.float32, copy=True)
    bl, bh, hl, hh = _depth_bounds(surface_mm, surface.valid, f, tl, to_mm, cfg.tu_mm,
                                   cfg.hand_max_mm)
    mm_px = surface.mm_per_px()
    min_area = max(cfg.min_area_floor_px, int(round(cfg.min_area_mm2 / (mm_px * mm_px))))
    # an opening wider than a finger would erase it: keep it only where fingers span >= 4 px
    finger_px = 2.0 * tip_radius_mm / mm_px
    open_px = cfg.open_px if finger_px >= cfg.open_px + 1 else 1
    return BandBounds(
        band_lo=bl, band_hi=bh, high_lo=hl, high_hi=hh,
        factor=f, tl_mm=tl, surface_mm=surface_mm, sigma_mm=surface.sigma_mm,
        valid=surface.valid, to_mm=to_mm, mm_per_px=mm_px, min_area_px=min_area,
        open_px=open_px, tu_mm=cfg.tu_mm, hand_max_mm=cfg.hand_max_mm,
        valid_u8=surface.valid.astype(np.uint8) * np.uint8(255), min_hand_mm2=cfg.min_hand_mm2,
        hand_lo=_hand_samples(hl), hand_hi=_hand_samples(hh),
        hand_valid=np.ascontiguousarray(surface.valid[::HAND_SCALE, ::HAND_SCALE][
            :max(1, surface.valid.shape[0] // HAND_SCALE), :max(1, surface.valid.shape[1] // HAND_SCALE)]),
        small_valid=cv2.resize(surface.valid.astype(np.uint8) * np.uint8(255),
                               (max(1, surface.valid.shape[1] // HAND_SCALE),
                                max(1, surface.valid.shape[0] // HAND_SCALE)),
                               interpolation=cv2.INTER_NEAREST),
    )


def _hand_samples(a: np.ndarray, j0: int = 0, j1: int | None = None) -> np.ndarray:
    """``a`` at the 4 middle pixels (rows and columns s/2-1 and s/2) of each 1/s block of the
    block rows j0:j1, as (rows, w/s, 4)."""
    s = HAND_SCALE
    H, W = a.shape
    sh, sw = max(1, H // s), max(1, W // s)
    j1 = sh if j1 is None else j1
    jj, ii = np.arange(j0, j1), np.arange(sw)
    c0, c1 = s // 2 - 1, s // 2
    out = np.empty((j1 - j0, sw, 4), a.dtype)
    for k, (cy, cx) in enumerate(((c0, c0), (c0, c1), (c1, c0), (c1, c1))):
        out[:, :, k] = a[np.ix_(np.minimum(H - 1, s * jj + cy), np.minimum(W - 1, s * ii + cx))]
    return out


def refresh_rows(bounds: BandBounds, y0: int, y1: int) -> None:
    """Recompute the depth bounds of rows y0:y1 after ``bounds.surface_mm`` changed there."""
    rows = slice(y0, y1)
    bl, bh, hl, hh = _depth_bounds(
        bounds.surface_mm[rows], bounds.valid[rows], bounds.factor[rows], bounds.tl_mm[rows],
        bounds.to_mm, bounds.tu_mm, bounds.hand_max_mm,
    )
    bounds.band_lo[rows], bounds.band_hi[rows] = bl, bh
    bounds.high_lo[rows], bounds.high_hi[rows] = hl, hh
    if bounds.hand_lo is not None and bounds.hand_hi is not None:
        j0 = max(0, (y0 - HAND_SCALE) // HAND_SCALE)
        j1 = min(bounds.hand_lo.shape[0], y1 // HAND_SCALE + 1)
        if j1 > j0:
            bounds.hand_lo[j0:j1] = _hand_samples(bounds.high_lo, j0, j1)
            bounds.hand_hi[j0:j1] = _hand_samples(bounds.high_hi, j0, j1)


def band_mask(depth: np.ndarray, bounds: BandBounds) -> np.ndarray:
    """The band mask (uint8, 255 = Tl < height < Tu) of a raw depth frame; zeros are not in it."""
    return cv2.inRange(depth, bounds.band_lo, bounds.band_hi)


def band_masks(depth: np.ndarray, bounds: BandBounds) -> tuple[np.ndarray, np.ndarray]:
    """(band, high) uint8 masks (255 = in) of a raw depth frame; zeros are in neither."""
    band = cv2.inRange(depth, bounds.band_lo, bounds.band_hi)
    high = cv2.inRange(depth, bounds.high_lo, bounds.high_hi)
    return band, high


@dataclass(frozen=True)
class Regions:
    """Touch regions of one frame (parallel over the kept regions).

    bbox_xywh: (R, 4) int bounding boxes in the image; area_px: (R,) pixel counts;
    masks: per region a uint8 mask (1 = in) of its bounding box;
    band: the eroded band mask of the whole frame (uint8, 255 = in; dilated by ``open_px`` it
    is the opened band), or None when not known.
    """

    bbox_xywh: np.ndarray
    area_px: np.ndarray
    masks: tuple[np.ndarray, ...]
    band: np.ndarray | None = None

    @classmethod
    def empty(cls) -> Regions:
        return cls(np.zeros((0, 4), np.int64), np.zeros(0, np.int64), ())

    def __len__(self) -> int:
        return int(self.bbox_xywh.shape[0])


_KERNELS: dict[int, np.ndarray] = {}


def _kernel(size: int) -> np.ndarray:
    k = _KERNELS.get(size)
    if k is None:
        k = _KERNELS[size] = cv2.getStructuringElement(cv2.MORPH_RECT, (size, size))
    return k


def find_regions(band: np.ndarray, bounds: BandBounds) -> Regions:
    """Open the band mask, find its connected regions and keep those of at least S_min pixels.

    Regions are the outer contours of the opened mask (``cv2.findContours`` costs a tenth of a
    full labelling); each region's mask is its filled contour within its bounding box, so a hole
    inside a region counts as region. The opening is done region by region where it can: the
    band is eroded once, and each remaining part is dilated back within its own box; only when
    two parts come so close that their dilations could join is the whole frame dilated.
    """
    k = bounds.open_px
    return regions_of_core(cv2.erode(band, _kernel(k)) if k > 1 else band, bounds)


def band_core(depth: np.ndarray, bounds: BandBounds) -> np.ndarray:
    """The band mask of a raw depth frame eroded by ``open_px`` (uint8, 255 = in), in one
    compiled pass: equal to ``cv2.erode(band_mask(depth, bounds), open_px square)``."""
    k = bounds.open_px
    if k % 2 == 0:  # an even square has no centre: OpenCV's anchor decides
        return cv2.erode(band_mask(depth, bounds), _kernel(k))
    return _band_core(depth, bounds.band_lo, bounds.band_hi, k // 2)


def regions_of_core(core: np.ndarray, bounds: BandBounds) -> Regions:
    """:func:`find_regions` from the band already eroded by ``open_px`` (see :func:`band_core`)."""
    if not cv2.hasNonZero(core):
        return Regions.empty()
    k = bounds.open_px
    contours, _ = cv2.findContours(core, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    pad = k // 2
    regions = _contour_regions(contours, core.shape, bounds.min_area_px, pad, k)
    if pad and len(regions) > 1 and _any_close(regions.bbox_xywh):
        opened = cv2.dilate(core, _kernel(k))
        contours, _ = cv2.findContours(opened, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        regions = _contour_regions(contours, core.shape, bounds.min_area_px, 0, 1)
    if len(regions) == 0:
        return regions
    return Regions(regions.bbox_xywh, regions.area_px, regions.masks, core)


@numba.njit(cache=True, nogil=True)
def _band_core(depth: np.ndarray, lo: np.ndarray, hi: np.ndarray, pad: int) -> np.ndarray:
    """In the band where every pixel within ``pad`` (chessboard) is in it; pixels outside the
    image count as in (as OpenCV's erosion). Rows without band pixels are skipped."""
    H, W = depth.shape
    band = np.empty((H, W), np.uint8)
    rows = np.zeros(H, np.bool_)
    for y in range(H):
        n = 0
        for x in range(W):
            v = depth[y, x]
            b = (lo[y, x] <= v) & (v <= hi[y, x])
            band[y, x] = b
            n += b
        rows[y] = n > 0
    core = np.zeros((H, W), np.uint8)
    for y in range(H):
        if not rows[y]:
            continue
        ok = True
        for yy in range(max(0, y - pad), min(H, y + pad + 1)):
            ok = ok and rows[yy]
        if not ok:
            continue
        for x in range(W):
            if not band[y, x]:
                continue
            keep = True
            for yy in range(max(0, y - pad), min(H, y + pad + 1)):
                for xx in range(max(0, x - pad), min(W, x + pad + 1)):
                    if not band[yy, xx]:
                        keep = False
                        break
                if not keep:
                    break
            if keep:
                core[y, x] = 255
    return core


def _any_close(boxes: np.ndarray) -> bool:
    """Do any two boxes (x, y, w, h) touch or overlap (8-connected)? (A few boxes: plain
    Python costs less than array calls.)"""
    b = boxes.tolist()
    for i in range(len(b)):
        xi, yi, wi, hi = b[i]
        for j in range(i + 1, len(b)):
            xj, yj, wj, hj = b[j]
            if xi <= xj + wj and xj <= xi + wi and yi <= yj + hj and yj <= yi + hi:
                return True
    return False


def _contour_regions(contours: Sequence[np.ndarray], shape: tuple[int, ...], min_area: int,
                     pad: int, k: int) -> Regions:
    """Regions of filled outer contours, each dilated by ``pad`` px (kernel k) when pad > 0."""
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
    return Regions(np.asarray(boxes, np.int64), np.asarray(areas, np.int64), tuple(masks))


def height_mm(
    depth: np.ndarray, bounds: BandBounds, roi: tuple[int, int, int, int] | None = None
) -> np.ndarray:
    """Height above the surface in mm (float32), NaN where depth or surface is missing.

    With ``roi`` = (x, y, w, h), only that window is computed (the per-region path).
    """
    if roi is None:
        ys, xs = slice(None), slice(None)
    else:
        x, y, w, h = roi
        ys, xs = slice(y, y + h), slice(x, x + w)
    d = depth[ys, xs]
    h_mm = (bounds.surface_mm[ys, xs] - d.astype(np.float32) * np.float32(bounds.to_mm)) \
        * bounds.factor[ys, xs]
    bad = (d == 0) | ~bounds.valid[ys, xs]
    h_mm[bad] = np.nan
    return h_mm


def warm_up() -> None:
    """Compile (or load from cache) this module's kernel (see :func:`tipkernel.warm_up`)."""
    z = np.zeros((8, 8), np.uint16)
    _band_core(z, z, z, 1)
