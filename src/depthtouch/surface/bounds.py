"""Band bounds: the surface turned into per-pixel depth limits, once per surface.

The thresholds of the touch band (Tl < height < Tu, Tl following each pixel's noise) and of the
hand (Tu < height < hand_max) are millimetres above the surface along its normal; a frame is
compared with them in the camera's own units, so they are converted once, per pixel, into uint16
depth bounds (:class:`BandBounds`). The surface adapter moves the surface and refreshes the bounds
of the rows it changed (:func:`refresh_rows`); :func:`height_mm` gives heights for views.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numba
import numpy as np

from ..config import RegionConfig
from .model import SurfaceModel, height_factor, surface_normals

HAND_SCALE = 4  # the hand map is kept at 1/4 resolution


@dataclass(frozen=True)
class BandBounds:
    """Per-pixel depth bounds (camera units, uint16 (H, W)) derived from a surface.

    band_lo..band_hi: depth of a pixel in the touch band (surface - Tu < d < surface - Tl).
    high_lo..high_hi: depth of hand/arm pixels (higher than Tu, lower than hand_max_mm).
    factor: height per depth difference (see :func:`surface.height_factor`).
    normals: the surface's unit normals toward the camera (H, W, 3), K its intrinsics; both None
    when K is unknown.
    tl_mm: Tl per pixel (float32), surface_units: surface depth in camera units (float32).
    min_area_px: S_min in pixels; open_px: opening size actually used; need_block: whether a
    region must hold a 2x2 block of band pixels (where the opening is not used).
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
    min_hand_mm2: float = 6000.0
    need_block: bool = False
    tl_floor_mm: float = 4.0  # the lowest Tl (RegionConfig.tl_floor_mm): tl_mm = max(it, k σ)
    # Tl averaged over the valid pixels of the (2 TL_AROUND_PX + 1)² square around each pixel
    # (float32; None: not computed, tl_mm stands in)
    tl_around_mm: np.ndarray | None = None
    # the hand map's samples (see handmap.hand_levels): high_lo / high_hi at the 4 middle
    # pixels of each 1/4 block, (4, h/4, w/4), and whether each block's corner pixel is usable
    hand_lo: np.ndarray | None = None
    hand_hi: np.ndarray | None = None
    hand_valid: np.ndarray | None = None
    normals: np.ndarray | None = None
    K: np.ndarray | None = None


def _depth_bounds(
    surface_mm: np.ndarray, valid: np.ndarray, factor: np.ndarray, tl_mm: np.ndarray,
    to_mm: float, tu_mm: float, hand_max_mm: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """uint16 (band_lo, band_hi, high_lo, high_hi) for a block of pixels (pure)."""
    h, w = surface_mm.shape
    out = np.empty((4, h, w), np.uint16)
    _bounds_kernel(np.ascontiguousarray(surface_mm), np.ascontiguousarray(valid),
                   np.ascontiguousarray(factor), np.ascontiguousarray(tl_mm),
                   float(to_mm), float(tu_mm), float(hand_max_mm), out)
    return out[0], out[1], out[2], out[3]


@numba.njit(cache=True, nogil=True)
def _bounds_kernel(surface_mm: np.ndarray, valid: np.ndarray, factor: np.ndarray,
                   tl_mm: np.ndarray, to_mm: float, tu_mm: float, hand_max_mm: float,
                   out: np.ndarray) -> None:
    """:func:`_depth_bounds` pixel by pixel, in float32 as numpy would do it (bit for bit).

    A pixel is in the band when surface - Tu < d < surface - Tl: the height
    h = (s - d) * to_mm * f, so d = s - h / (to_mm * f). Out of range values are clipped to
    1..65535; unusable pixels get an empty range (lo 1, hi 0)."""
    h, w = surface_mm.shape
    t = np.float32(to_mm)
    tu = np.float32(tu_mm)
    hand_max = np.float32(hand_max_mm)
    eps = np.float32(1e-3)
    one = np.float32(1.0)
    for y in range(h):
        for x in range(w):
            if not valid[y, x]:
                out[0, y, x], out[1, y, x], out[2, y, x], out[3, y, x] = 1, 0, 1, 0
                continue
            s_units = surface_mm[y, x] / t
            per_mm = one / (t * factor[y, x])
            band_lo = np.ceil(s_units - tu * per_mm + eps)
            band_hi = np.floor(s_units - tl_mm[y, x] * per_mm - eps)
            high_lo = np.ceil(s_units - hand_max * per_mm)
            out[0, y, x] = np.uint16(min(max(band_lo, one), np.float32(65535)))
            out[1, y, x] = np.uint16(min(max(band_hi, one), np.float32(65535)))
            out[2, y, x] = np.uint16(min(max(high_lo, one), np.float32(65535)))
            out[3, y, x] = np.uint16(min(max(band_lo - one, one), np.float32(65535)))


#: the half side of the square over which tl_around_mm averages Tl (4: 9x9 pixels, measured best
#: for the touch points' Tl shift on the hard suite's tune half: jitter 0.93 / 0.92 / 0.93 mm at
#: 2 / 4 / 8, 0.95 on the point's own pixel)
TL_AROUND_PX = 4


def tl_around(tl_mm: np.ndarray, valid: np.ndarray, r: int = TL_AROUND_PX) -> np.ndarray:
    """Tl averaged over the valid pixels of the (2r + 1)² square around each pixel (the square
    clipped at the frame's edges), float32; Tl itself where none is valid (pure)."""
    v = valid.astype(np.float32)
    k = (2 * r + 1, 2 * r + 1)
    num = cv2.boxFilter(np.where(valid, tl_mm, 0).astype(np.float32), -1, k, normalize=False,
                        borderType=cv2.BORDER_CONSTANT)
    den = cv2.boxFilter(v, -1, k, normalize=False, borderType=cv2.BORDER_CONSTANT)
    return np.where(den > 0.5, num / np.maximum(den, 1.0), tl_mm).astype(np.float32)


#: a touching fingertip's top stands 12-16 mm above the surface (docs/accuracy.md, session 33):
#: where Tl is this high or higher, a touching tip does not stand out of one frame's noise
TIP_TOP_MM = 16.0


def noisy_share(bounds: BandBounds, tl_mm: float = TIP_TOP_MM) -> float:
    """Share of the usable surface whose Tl is ``tl_mm`` or more (0.0 when none is usable):
    where touches will be missed because the depth there is too noisy (pure)."""
    n = int(np.count_nonzero(bounds.valid))
    if n == 0:
        return 0.0
    return float(np.count_nonzero(bounds.valid & (bounds.tl_mm >= np.float32(tl_mm)))) / n


def band_bounds(surface: SurfaceModel, config: RegionConfig, tip_radius_mm: float = 7.0) -> BandBounds:
    """Precompute the per-pixel depth bounds of the band and of the hand (once per surface).

    The bounds own a copy of the surface depth, so that :func:`refresh_rows` can follow a
    surface that updates itself without touching the caller's model.
    """
    cfg = config
    to_mm = surface.depth_scale_m * 1000.0
    normals = surface_normals(surface)
    f = height_factor(surface, normals)
    tl = np.maximum(np.float32(cfg.tl_floor_mm), np.float32(cfg.noise_k) * surface.sigma_mm)
    # Tl can never reach Tu: a camera this noisy leaves an empty band (reported, not hidden).
    tl = np.minimum(tl, np.float32(cfg.tu_mm)).astype(np.float32)
    surface_mm = surface.depth_mm.astype(np.float32, copy=True)
    bl, bh, hl, hh = _depth_bounds(surface_mm, surface.valid, f, tl, to_mm, cfg.tu_mm,
                                   cfg.hand_max_mm)
    mm_px = surface.mm_per_px()
    min_area = max(cfg.min_area_floor_px, int(round(cfg.min_area_mm2 / (mm_px * mm_px))))
    # an opening nearly as wide as a fingertip would erase the thin band under a finger held at
    # a slant: it is kept only where a fingertip spans open_tip_px; below, down to block_tip_px,
    # a region must hold a 2x2 block instead (one-pixel lines of mixed pixels go)
    tip_px = 2.0 * tip_radius_mm / mm_px
    # ... or where the band is deep: Tu - Tl spans at least open_band_px pixels under a finger
    # at 45 deg, so a slanted finger's band is wider than the opening (ToF at 1.1-1.2 m, where
    # the mixed pixels along a finger's sides join its tip region and make it look attached
    # along the finger; not structured light at 1.7-1.8 m or stereo at 1.2 m, whose Tl is high)
    band_px = (cfg.tu_mm - float(np.median(tl[surface.valid]))) / mm_px if surface.valid.any() \
        else 0.0
    deep = cfg.open_band_px > 0 and tip_px >= cfg.block_tip_px and band_px >= cfg.open_band_px
    open_px = cfg.open_px if tip_px >= cfg.open_tip_px or deep else 1
    need_block = open_px == 1 and cfg.open_px > 1 and tip_px >= cfg.block_tip_px
    return BandBounds(
        band_lo=bl, band_hi=bh, high_lo=hl, high_hi=hh,
        factor=f, tl_mm=tl, surface_mm=surface_mm, sigma_mm=surface.sigma_mm,
        valid=surface.valid, to_mm=to_mm, mm_per_px=mm_px, min_area_px=min_area,
        open_px=open_px, need_block=need_block, tu_mm=cfg.tu_mm, hand_max_mm=cfg.hand_max_mm,
        min_hand_mm2=cfg.min_hand_mm2, tl_floor_mm=cfg.tl_floor_mm,
        tl_around_mm=tl_around(tl, surface.valid), normals=normals,
        K=None if surface.K is None else np.asarray(surface.K, np.float64),
        hand_lo=_hand_samples(hl), hand_hi=_hand_samples(hh),
        hand_valid=np.ascontiguousarray(surface.valid[::HAND_SCALE, ::HAND_SCALE][
            :max(1, surface.valid.shape[0] // HAND_SCALE), :max(1, surface.valid.shape[1] // HAND_SCALE)]),
    )


def _hand_samples(a: np.ndarray, j0: int = 0, j1: int | None = None) -> np.ndarray:
    """``a`` at the 4 middle pixels (rows and columns s/2-1 and s/2) of each 1/s block of the
    block rows j0:j1, as 4 planes (4, rows, w/s): one per sample, so the hand map's loop reads
    each plane in order."""
    s = HAND_SCALE
    H, W = a.shape
    sh, sw = max(1, H // s), max(1, W // s)
    j1 = sh if j1 is None else j1
    c0, c1 = s // 2 - 1, s // 2
    out = np.empty((4, j1 - j0, sw), a.dtype)
    for k, (cy, cx) in enumerate(((c0, c0), (c0, c1), (c1, c0), (c1, c1))):
        if min(H, W) >= s:  # every sample inside: strided views
            out[k] = a[s * j0 + cy:s * j1:s, cx:s * sw:s]
        else:
            jj, ii = np.arange(j0, j1), np.arange(sw)
            out[k] = a[np.ix_(np.minimum(H - 1, s * jj + cy), np.minimum(W - 1, s * ii + cx))]
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
        j1 = min(bounds.hand_lo.shape[1], y1 // HAND_SCALE + 1)
        if j1 > j0:
            bounds.hand_lo[:, j0:j1] = _hand_samples(bounds.high_lo, j0, j1)
            bounds.hand_hi[:, j0:j1] = _hand_samples(bounds.high_hi, j0, j1)


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
