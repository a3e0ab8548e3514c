"""Sensor artefacts of the hard camera profiles: ToF multipath, stereo edge fattening, speckle holes.

Pure functions over the arrays of one frame (or of the box of it that differs from the empty
surface); the caller's :class:`~depthtouch.sim.cameras.NoiseModel` decides when they apply. They
model what the unseen recordings showed and the default profiles leave out:

- **multipath** (time of flight): light bouncing between a hand and the surface near it. The
  surface within a few centimetres of a low hand part reads nearer the camera (by up to
  ``bias_mm``, fading with distance), and a hand part less than 20 mm above the surface reads
  lower (by up to ``bias_mm``, never more than 70 % of its height): a few millimetres of bias
  exactly where a fingertip meets the surface.
- **edge fattening** (stereo): block matching spreads the nearer side of a depth edge over the
  farther side by a pixel or two; which pixels take the near depth changes every frame.
- **matching window** (stereo): depth comes from matching a window of pixels, so structures
  thinner than about half the window (a finger seen from afar) fade into what surrounds them
  and a fingertip's end retreats: a median over ``window_px`` x ``window_px`` of the geometry;
- **speckle holes** (stereo at range): small blobs (radius 1-3 px) with no depth, scattered over
  the frame; their number grows with the squared depth (fewer matches at range).
- **motion mixing** (time of flight): a ToF frame is made of several raw exposures taken one
  after the other, so a pixel that a moving hand covers or uncovers during them reads a depth
  between the hand's and the surface's. :func:`exposure_mix` averages renders of the scene at
  instants spread over the exposures, centred on the frame's timestamp
  (``render_scene(motion_ms=...)``); the mix is linear in depth, a simplification of the phase
  mixing a real sensor does.
"""

from __future__ import annotations

import cv2
import numpy as np

_FG_MM = 2.0  # a pixel this much nearer than the empty surface shows something in front of it
_LOW_MM = 40.0  # hand parts lower than this cast multipath onto the surface around them
_NEAR_MM = 20.0  # hand parts lower than this read lower themselves


def multipath(noisy: np.ndarray, z: np.ndarray, static_z: np.ndarray, fx_px: float,
              bias_mm: float, reach_mm: float) -> None:
    """Apply multipath bias in place to ``noisy`` (float32 mm; same shape as ``z``).

    z: noise-free depth of the frame (mm, 0 = none); static_z: the empty surface's depth there.
    bias_mm: largest bias (mm, >= 0); reach_mm: e-folding distance on the surface (mm, > 0).
    """
    if bias_mm <= 0:
        return
    valid = (z > 0) & (static_z > 0)
    height = np.where(valid, static_z - z, np.float32(0.0))
    fg = valid & (height > _FG_MM)
    low = fg & (height < _LOW_MM)
    if not low.any():
        return
    # distance (px) of every pixel to the nearest low hand pixel, then in mm on the surface
    dist_px = cv2.distanceTransform((~low).astype(np.uint8), cv2.DIST_L2, 3)
    d_mm = dist_px * static_z / np.float32(fx_px)
    surf = valid & ~fg
    noisy[surf] -= (np.float32(bias_mm) * np.exp(-d_mm[surf] / np.float32(reach_mm)))
    near = fg & (height < _NEAR_MM)
    h = height[near]
    noisy[near] += np.minimum(np.float32(bias_mm) * (1 - h / np.float32(_NEAR_MM)),
                              np.float32(0.7) * h)


def fatten_edges(noisy: np.ndarray, z: np.ndarray, sigma: np.ndarray, px: int, prob: float,
                 rng: np.random.Generator) -> None:
    """Stereo edge fattening in place: far-side pixels within ``px`` of a nearer edge take the
    near depth (keeping their own noise) with probability ``prob`` per frame."""
    if px <= 0 or prob <= 0:
        return
    zf = np.where(z > 0, z, np.float32(1e5))
    zmin = cv2.erode(zf, np.ones((2 * px + 1, 2 * px + 1), np.uint8))
    far_side = (z > 0) & (z - zmin > np.float32(15.0) + np.float32(4.0) * sigma)
    ys, xs = np.nonzero(far_side)
    if ys.size == 0:
        return
    pick = rng.random(ys.size) < prob
    ys, xs = ys[pick], xs[pick]
    noisy[ys, xs] = zmin[ys, xs] + (noisy[ys, xs] - z[ys, xs])


def speckle_holes(shape: tuple[int, int], per_mpx: float, depth_mm: float,
                  rng: np.random.Generator) -> np.ndarray:
    """Boolean mask of small missing blobs: ``per_mpx`` blobs per megapixel at 1 m, times
    (depth / 1 m)^2; radii 1-3 px."""
    h, w = shape
    mask = np.zeros(shape, np.uint8)
    if per_mpx <= 0:
        return mask.astype(bool)
    k = int(rng.poisson(per_mpx * (depth_mm / 1000.0) ** 2 * h * w / 1e6))
    if k:
        xs = rng.integers(0, w, k)
        ys = rng.integers(0, h, k)
        rs = rng.integers(1, 4, k)
        for x, y, r in zip(xs.tolist(), ys.tolist(), rs.tolist(), strict=True):
            cv2.circle(mask, (x, y), r, 1, -1)
    return mask.astype(bool)


def match_window(z: np.ndarray, window_px: int) -> np.ndarray:
    """The noise-free depth as a stereo matcher with a ``window_px`` window (3 or 5) sees it:
    a median, so that thin structures vanish and edges stay sharp (0 = no surface is kept)."""
    if window_px <= 1:
        return z
    out: np.ndarray = cv2.medianBlur(np.ascontiguousarray(z, dtype=np.float32), window_px)
    return np.where(z > 0, out, np.float32(0.0)).astype(np.float32)


def exposure_mix(subs: list[np.ndarray], box: tuple[int, int, int, int]) -> np.ndarray:
    """The depth of a frame integrated over sub-exposures: the mean of ``subs`` (noise-free
    float32 mm renders of one frame at instants spread over its exposures) inside ``box``
    (x0, y0, x1, y1), where every sub-render has a depth; elsewhere the first. A new array;
    the inputs are not changed."""
    out = subs[0].copy()
    x0, y0, x1, y1 = box
    if x1 <= x0 or y1 <= y0 or len(subs) < 2:
        return out
    sl = (slice(y0, y1), slice(x0, x1))
    stack = np.stack([z[sl] for z in subs])
    seen = np.all(stack > 0, axis=0)
    out[sl] = np.where(seen, stack.mean(axis=0, dtype=np.float32), out[sl])
    return out
