"""Touch regions: the band Tl < height < Tu, opened, labelled, size-filtered.

The per-pixel thresholds are turned once (per surface) into depth bounds in the camera's own
units (:class:`BandBounds`). Per frame, one compiled pass (:func:`band_regions`) tests every pixel
of the raw uint16 frame against its bounds, erodes the band by ``open_px`` and lists the runs of
what is left; the runs are joined into 8-connected parts (:mod:`depthtouch.runs`), each part's
holes are filled and the part is dilated back within its own box, and parts under S_min pixels
are dropped. When the band is empty, that is all. These are the regions that OpenCV's outer
contours of the opened band give (``tests/reference_touchpoints.py`` keeps that version; the
tests check both agree), at a fraction of the cost: a frame's few dozen runs instead of a scan
of a whole mask per step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ..runs import dilate_runs, parts_of_runs, row_runs
from ..surface.bounds import BandBounds


@dataclass(frozen=True)
class Regions:
    """Touch regions of one frame (parallel over the kept regions).

    bbox_xywh: (R, 4) int bounding boxes in the image; area_px: (R,) pixel counts;
    mask_buf: the regions' masks one after the other (uint8, 1 = in, each row-major within its
    box), region i from ``mask_start[i]`` (the layout the fingertip kernel reads);
    band: the eroded band mask of the whole frame (uint8, 255 = in; dilated by ``open_px`` it
    is the opened band), or None when not known.
    """

    bbox_xywh: np.ndarray
    area_px: np.ndarray
    mask_buf: np.ndarray
    mask_start: np.ndarray
    band: np.ndarray | None = None

    @classmethod
    def empty(cls) -> Regions:
        return cls(np.zeros((0, 4), np.int64), np.zeros(0, np.int64), np.zeros(0, np.uint8),
                   np.zeros(0, np.int64))

    @property
    def masks(self) -> tuple[np.ndarray, ...]:
        """Per region its mask (uint8, 1 = in) over its bounding box (views of ``mask_buf``)."""
        return tuple(self.mask_buf[s:s + w * h].reshape(h, w)
                     for s, (w, h) in zip(self.mask_start.tolist(),
                                          self.bbox_xywh[:, 2:].tolist()))

    def __len__(self) -> int:
        return int(self.bbox_xywh.shape[0])


def band_core(depth: np.ndarray, bounds: BandBounds) -> np.ndarray:
    """The band mask of a raw depth frame eroded by ``open_px`` (uint8, 255 = in): equal to
    ``cv2.erode(cv2.inRange(depth, band_lo, band_hi), open_px square)``."""
    return _band_core(depth, bounds.band_lo, bounds.band_hi, bounds.open_px // 2)[0]


def band_regions(depth: np.ndarray, bounds: BandBounds) -> Regions:
    """The touch regions of a raw (prefiltered) depth frame: the band opened by an
    ``open_px`` square, its 8-connected parts with their holes filled, those of at least
    S_min pixels (``min_area_px``).

    The opening is done part by part: the band is eroded once, and each part left is dilated
    back within its own box; only when two parts come so close that their dilations could
    join is the whole core dilated (as runs) and its parts taken as they are.

    Where the opening is not used (``bounds.need_block``: a fingertip spans too few pixels for
    it), a part is kept only if it holds a 2x2 block: lines one pixel wide (mixed pixels along
    a finger's edge) are dropped whole, and a part is never cut.
    """
    pad = bounds.open_px // 2  # odd (see RegionConfig.validate)
    core, runs = _band_core(depth, bounds.band_lo, bounds.band_hi, pad)
    if runs.shape[0] == 0:
        return Regions.empty()
    H, W = core.shape
    boxes, areas, buf, starts = parts_of_runs(runs, H, W, bounds.min_area_px, pad)
    if pad and boxes.shape[0] > 1 and _any_close(boxes):
        boxes, areas, buf, starts = parts_of_runs(dilate_runs(runs, pad, H, W), H, W,
                                                  bounds.min_area_px, 0)
    if bounds.need_block and boxes.shape[0]:
        keep = _has_block(buf, starts, boxes)
        boxes, areas, starts = boxes[keep], areas[keep], starts[keep]
    if boxes.shape[0] == 0:
        return Regions.empty()
    return Regions(boxes, areas, buf, starts, core)


@numba.njit(cache=True, nogil=True)
def _band_core(depth: np.ndarray, lo: np.ndarray, hi: np.ndarray, pad: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """In the band where every pixel within ``pad`` (chessboard) is in it; pixels outside the
    image count as in (as OpenCV's erosion). Rows without band pixels are skipped.

    Returns the core (uint8, 255 = in) and its runs: (n, 3) rows (y, x0, x1), the pixels
    x0..x1-1 of row y, in raster order."""
    H, W = depth.shape
    band = np.empty((H, W), np.uint8)
    rows = np.zeros(H, np.bool_)
    n_band = 0
    for y in range(H):
        n = 0
        for x in range(W):
            v = depth[y, x]
            b = (lo[y, x] <= v) & (v <= hi[y, x])
            band[y, x] = b
            n += b
        rows[y] = n > 0
        n_band += n
    # the erosion is separable: across each row (hm), then down the columns, both over whole
    # rows (the 3x3 case, the default, in a form the compiler vectorises); only rows with core
    # pixels are searched for runs
    hm = np.empty((H, W), np.uint8)
    for y in range(H):
        if not rows[y]:
            continue
        o, r = hm[y], band[y]
        if pad == 1 and W > 1:
            o[0] = r[0] & r[1]
            for x in range(1, W - 1):
                o[x] = r[x - 1] & r[x] & r[x + 1]
            o[W - 1] = r[W - 2] & r[W - 1]
            continue
        for x in range(W):
            v = r[x]
            for xx in range(max(0, x - pad), min(W, x + pad + 1)):
                v &= r[xx]
            o[x] = v
    core = np.zeros((H, W), np.uint8)
    # each run holds at least one band pixel (an array that never has to grow: one that does
    # makes the compiled loops several times slower)
    runs = np.empty((n_band, 3), np.int64)
    n_runs = 0
    for y in range(H):
        ok = True
        for yy in range(max(0, y - pad), min(H, y + pad + 1)):
            ok = ok and rows[yy]
        if not ok:
            continue
        c = core[y]
        if pad == 1 and 0 < y < H - 1:
            u, m, d = hm[y - 1], hm[y], hm[y + 1]
            for x in range(W):
                c[x] = u[x] & m[x] & d[x]
        else:
            for x in range(W):
                v = hm[y, x]
                for yy in range(max(0, y - pad), min(H, y + pad + 1)):
                    v &= hm[yy, x]
                c[x] = v
        seen = np.uint8(0)
        for x in range(W):
            seen |= c[x]
        if seen == 0:
            continue
        for x in range(W):
            c[x] *= 255
        n_runs = row_runs(c, y, runs, n_runs)
    return core, runs[:n_runs]


@numba.njit(cache=True, nogil=True)
def _has_block(buf: np.ndarray, starts: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Per part (masks in ``buf`` from ``starts``, boxes (x, y, w, h)): does it hold a 2x2
    block of pixels?"""
    n = boxes.shape[0]
    out = np.zeros(n, np.bool_)
    for i in range(n):
        w, h = boxes[i, 2], boxes[i, 3]
        m = buf[starts[i]:starts[i] + w * h].reshape((h, w))
        for y in range(h - 1):
            a, b = m[y], m[y + 1]
            for x in range(w - 1):
                if a[x] and a[x + 1] and b[x] and b[x + 1]:
                    out[i] = True
                    break
            if out[i]:
                break
    return out


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


def warm_up() -> None:
    """Compile (or load from cache) this module's kernels (see :func:`tipkernel.warm_up`)."""
    d = np.full((8, 8), 5, np.uint16)
    core, runs = _band_core(d, np.ones_like(d), np.full_like(d, 10), 1)
    parts_of_runs(runs, 8, 8, 1, 1)
    boxes, _, buf, starts = parts_of_runs(dilate_runs(runs, 1, 8, 8), 8, 8, 1, 0)
    _has_block(buf, starts, boxes)
