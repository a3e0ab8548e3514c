"""Each camera's part of the shared screen, for the web page of several cameras.

A camera's *footprint* is the screen polygon its depth image covers: its image corners through
its calibration (:func:`depthtouch.fusion.view_polygon`). Two footprints meet in an *overlap*
(their intersection; both are convex quadrilaterals). The page draws them, and its calibration
flow for one camera shows targets in the part of the screen that camera sees
(:func:`camera_targets`): away from the other cameras' views, so that the fused touch at a
target is reported in that camera's pixels (``cam``, ``x``, ``y``: the camera whose view it is
deepest in). Before a camera has a footprint (no calibration, or no frame yet), its targets
span the whole screen.

:func:`cameras_message` is the ``cameras`` message of the WebSocket protocol
(docs/websocket.md). Everything here is pure.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from ..calibration import default_targets
from ..fusion import inside_px, view_polygon


@dataclass(frozen=True)
class CameraView:
    """What the page needs of one camera: its index, name, depth image size (None before its
    first frame) and calibration to the shared screen (None: not calibrated)."""

    cam: int
    name: str
    resolution_wh: tuple[int, int] | None
    calibration: Any | None


def footprint(view: CameraView) -> np.ndarray | None:
    """The screen polygon (4, 2) the camera covers, or None without a calibration or a frame."""
    if view.calibration is None or view.resolution_wh is None:
        return None
    poly = view_polygon(view.calibration, view.resolution_wh)
    return poly if np.all(np.isfinite(poly)) else None


def overlap(a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """The intersection (N, 2) of two convex screen polygons, or None when they do not meet."""
    pa = np.asarray(a, np.float32).reshape(-1, 1, 2)
    pb = np.asarray(b, np.float32).reshape(-1, 1, 2)
    if cv2.contourArea(pa, True) < 0:  # intersectConvexConvex wants one orientation for both
        pa = pa[::-1].copy()
    if cv2.contourArea(pb, True) < 0:
        pb = pb[::-1].copy()
    area, inter = cv2.intersectConvexConvex(pa, pb)
    if area <= 0.0 or inter is None:
        return None
    return np.asarray(inter, np.float64).reshape(-1, 2)


def camera_targets(k: int, footprints: Sequence[np.ndarray | None], screen_wh: tuple[int, int],
                   *, edge_px: float = 40.0, grid: int = 48) -> np.ndarray:
    """Four calibration targets (4, 2), screen px, for camera ``k`` in the order to touch.

    They lie on the screen, at least ``max(edge_px, 8 % of the screen's height)`` inside camera
    ``k``'s footprint, and outside every other footprint where the screen has room (else at most
    ``edge_px / 2`` inside it, else anywhere in ``k``'s): the extreme such points toward the
    top-left, top-right, bottom-right and bottom-left. Without a footprint, or with too little
    room, :func:`depthtouch.calibration.default_targets` of the whole screen.
    """
    w, h = screen_wh
    fallback = np.round(default_targets((w, h), n=4), 1)
    own = footprints[k] if 0 <= k < len(footprints) else None
    if own is None:
        return fallback
    xs = np.linspace(0.05 * (w - 1), 0.95 * (w - 1), grid)
    ys = np.linspace(0.05 * (h - 1), 0.95 * (h - 1), grid)
    pts = np.array([(x, y) for y in ys for x in xs])
    depth = max(edge_px, 0.08 * h)
    mine = pts[[inside_px(own, (x, y)) >= depth for x, y in pts]]
    others = [f for j, f in enumerate(footprints) if j != k and f is not None]
    chosen = None
    for limit in (0.0, edge_px / 2.0, np.inf):
        keep = [max((inside_px(f, (x, y)) for f in others), default=-np.inf) < limit
                for x, y in mine] if len(mine) else []
        cand = mine[np.asarray(keep, bool)] if len(mine) else mine
        if len(cand) >= 4 and _spread(cand, w, h):
            chosen = cand
            break
    if chosen is None:
        return fallback
    c = chosen.mean(axis=0)
    out = []
    for dx, dy in ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)):
        score = dx * (chosen[:, 0] - c[0]) / w + dy * (chosen[:, 1] - c[1]) / h
        out.append(chosen[int(np.argmax(score))])
    return np.round(np.asarray(out, np.float64), 1)


def _spread(pts: np.ndarray, w: int, h: int) -> bool:
    """Wide enough in both screen axes for a homography fit (at least 10 % of the screen)."""
    span = pts.max(axis=0) - pts.min(axis=0)
    return bool(span[0] >= 0.1 * w and span[1] >= 0.1 * h)


def _points(poly: np.ndarray | None) -> list[list[float]] | None:
    return None if poly is None else (np.round(poly, 1) + 0.0).tolist()  # no -0.0


def cameras_message(views: Sequence[CameraView], screen_wh: tuple[int, int]) -> dict[str, Any]:
    """The ``cameras`` message: every camera's footprint and targets, and every pair's overlap
    (screen px of ``screen_wh``)."""
    polys = [footprint(v) for v in views]
    cams = [{"cam": v.cam, "name": v.name,
             "resolution_wh": list(v.resolution_wh) if v.resolution_wh else None,
             "calibrated": v.calibration is not None,
             "footprint": _points(polys[i]),
             "targets": camera_targets(i, polys, screen_wh).tolist()}
            for i, v in enumerate(views)]
    overlaps = []
    for i in range(len(views)):
        for j in range(i + 1, len(views)):
            pi, pj = polys[i], polys[j]
            inter = overlap(pi, pj) if pi is not None and pj is not None else None
            if inter is not None:
                overlaps.append({"cams": [views[i].cam, views[j].cam], "polygon": _points(inter)})
    return {"type": "cameras", "screen_wh": [int(screen_wh[0]), int(screen_wh[1])],
            "cameras": cams, "overlaps": overlaps}
