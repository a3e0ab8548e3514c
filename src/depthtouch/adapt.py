"""Surface adaptation: the surface model follows a changing room while the sensor runs.

The paper's sensor needs a static surface and a new capture after any change. Here, on one
horizontal stripe of the image per frame (so the cost is spread evenly):

- a pixel that differs from the surface by more than its Tl and then stays still for
  ``absorb_s`` becomes surface (an object put down; likewise the table where it was taken away);
- unchanged pixels follow the frames slowly (time constant ``drift_tau_s``): drift is absorbed;
- never absorbed: anything connected to a change that reaches the image border (a hand is
  attached to an arm that enters from outside the view, and the arm rises above the band), and
  anything within ``keep_out_mm`` of an active touch. A finger held still for minutes stays a
  finger;
- when more than ``bump_fraction`` of the surface changes at once and stays so, still, for
  ``bump_s``, the camera has moved: :meth:`SurfaceAdapter.update` says ``"bump"`` and the
  pipeline learns the surface again.
"""

from __future__ import annotations

import cv2
import numpy as np

from .config import AdaptConfig
from .regions import BandBounds, refresh_rows

_SCALE = 4  # the whole-frame checks run on a 1/4 resolution view


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
        self._since = np.full((h, w), np.inf, np.float32)
        self._t0: float | None = None
        self._still_tol = np.maximum(np.float32(self.config.still_mm),
                                     3.0 * self.bounds.sigma_mm).astype(np.float32)
        self._visit_t = np.full(len(self._stripes) - 1, np.nan)
        self._exclude = np.zeros((h, w), bool)
        self._bump_since: float | None = None
        self._small_prev: np.ndarray | None = None

    def update(self, depth: np.ndarray, t: float, touch_xy_px: np.ndarray) -> str | None:
        """Visit the next stripe; returns "bump" when the camera has moved, else None."""
        cfg, b = self.config, self.bounds
        k = self._k
        self._k = (k + 1) % (len(self._stripes) - 1)
        verdict = None
        if k == 0:
            verdict = self._whole_frame_checks(depth, t, touch_xy_px)
        y0, y1 = int(self._stripes[k]), int(self._stripes[k + 1])
        rows = slice(y0, y1)
        tt = np.float32(t - self._t0) if self._t0 is not None else np.float32(0)
        if self._t0 is None:
            self._t0 = t
        d = depth[rows]
        dm = d.astype(np.float32)
        dm *= np.float32(b.to_mm)
        s = b.surface_mm[rows]
        ok = (d > 0) & b.valid[rows]
        changed = ok & (np.abs((s - dm) * b.factor[rows]) > b.tl_mm[rows])
        since = self._since[rows]
        if self._have_prev[k]:
            moved = np.abs(dm - self._prev[rows]) > self._still_tol[rows]
            restart = changed & (moved | (since == np.inf))
        else:
            restart = changed
        np.copyto(since, np.inf, where=~changed)
        np.copyto(since, tt, where=restart)
        absorb = changed & ((tt - since) >= np.float32(cfg.absorb_s)) & ~self._exclude[rows]
        n_abs = int(np.count_nonzero(absorb))
        if n_abs:
            np.copyto(s, dm, where=absorb)
            np.copyto(since, np.inf, where=absorb)
            self.absorbed_px += n_abs
        last = self._visit_t[k]
        if np.isfinite(last) and t > last:
            alpha = np.float32(min(1.0, (t - last) / cfg.drift_tau_s))
            np.copyto(s, s + alpha * (dm - s), where=ok & ~changed)
        self._visit_t[k] = t
        self._prev[rows] = dm
        self._have_prev[k] = True
        refresh_rows(b, y0, y1)
        return verdict

    def _whole_frame_checks(self, depth: np.ndarray, t: float, touch_xy_px: np.ndarray) -> str | None:
        cfg, b = self.config, self.bounds
        h, w = depth.shape
        sw, sh = max(1, w // _SCALE), max(1, h // _SCALE)
        ds = cv2.resize(depth, (sw, sh), interpolation=cv2.INTER_NEAREST).astype(np.float32)
        ds *= np.float32(b.to_mm)
        ss = cv2.resize(b.surface_mm, (sw, sh), interpolation=cv2.INTER_NEAREST)
        tl = cv2.resize(b.tl_mm, (sw, sh), interpolation=cv2.INTER_NEAREST)
        ok = (ds > 0) & (cv2.resize(b.valid.view(np.uint8), (sw, sh),
                                     interpolation=cv2.INTER_NEAREST) > 0)
        changed = ok & (np.abs(ss - ds) > tl)
        # Changes connected to the image border are people: never absorbed.
        mask = changed.astype(np.uint8)
        n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        x, y, bw, bh = stats[:, 0], stats[:, 1], stats[:, 2], stats[:, 3]
        border = (x == 0) | (y == 0) | (x + bw >= sw) | (y + bh >= sh)
        border[0] = False
        excl = border[labels].astype(np.uint8)
        excl = cv2.dilate(excl, np.ones((3, 3), np.uint8))
        if len(touch_xy_px):
            r = max(1, int(round(cfg.keep_out_mm / b.mm_per_px / _SCALE)))
            for x_px, y_px in np.asarray(touch_xy_px, np.float64):
                cv2.circle(excl, (int(x_px / _SCALE), int(y_px / _SCALE)), r, 1, thickness=-1)
        self._exclude = cv2.resize(excl, (w, h), interpolation=cv2.INTER_NEAREST) > 0
        # Camera bump: most of the surface changed, and the scene is still.
        share = float(changed.sum()) / max(1, int(ok.sum()))
        prev, self._small_prev = self._small_prev, ds
        still = prev is not None and float(np.mean(np.abs(ds - prev)[ok] > 3 * tl[ok])) < 0.05
        if share >= cfg.bump_fraction and still:
            if self._bump_since is None:
                self._bump_since = t
            elif t - self._bump_since >= cfg.bump_s:
                self._bump_since = None
                return "bump"
        elif share < cfg.bump_fraction:
            self._bump_since = None
        return None
