"""The calibration endpoint's pure part: validate the page's request, fit and save.

``POST /api/calibration`` (:class:`depthtouch.web.server.WebServer`) takes
``{"screen_wh": [w, h], "pairs": [{"depth": [x, y], "screen": [x, y]}, ...], "cam": k}``
(``cam`` only with several cameras: camera k's calibration to the shared screen, saved beside
the calibration file as ``NAME.camK.json``, see :func:`camera_calibration_path`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import CalibrationError

_MAX_PAIRS = 64


def parse_calibration_request(
    payload: Any,
) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """Validate ``{"screen_wh": [w, h], "pairs": [{"depth": [x, y], "screen": [x, y]}, ...]}``.

    Returns depth_xy (N, 2), screen_xy (N, 2) float64 and screen_wh; CalibrationError naming the
    problem otherwise (at least 4 pairs, finite numbers).
    """
    if not isinstance(payload, dict):
        raise CalibrationError("calibration request must be a JSON object with pairs, screen_wh")
    wh = payload.get("screen_wh")
    if (
        not isinstance(wh, list) or len(wh) != 2
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0 for v in wh)
    ):
        raise CalibrationError(f"screen_wh = {wh!r} must be [width, height] in positive pixels")
    pairs = payload.get("pairs")
    if not isinstance(pairs, list) or not 4 <= len(pairs) <= _MAX_PAIRS:
        n = len(pairs) if isinstance(pairs, list) else pairs
        raise CalibrationError(
            f"calibration needs 4..{_MAX_PAIRS} pairs, got {n!r}; touch all the targets"
        )
    try:
        depth_xy = np.array([p["depth"] for p in pairs], dtype=np.float64)
        screen_xy = np.array([p["screen"] for p in pairs], dtype=np.float64)
    except (TypeError, KeyError, ValueError):
        raise CalibrationError(
            'each calibration pair must be {"depth": [x, y], "screen": [x, y]} numbers'
        ) from None
    if depth_xy.shape != (len(pairs), 2) or screen_xy.shape != (len(pairs), 2):
        raise CalibrationError('each calibration pair must be {"depth": [x, y], "screen": [x, y]}')
    if not (np.all(np.isfinite(depth_xy)) and np.all(np.isfinite(screen_xy))):
        raise CalibrationError("calibration pairs contain NaN or infinity; touch the targets again")
    return depth_xy, screen_xy, (int(round(wh[0])), int(round(wh[1])))


def fit_and_save(
    depth_xy: np.ndarray, screen_xy: np.ndarray, screen_wh: tuple[int, int], path: Path
) -> Any:
    """Fit a calibration from touched targets and save it; returns the Calibration."""
    from ..calibration import fit_calibration, save_calibration

    cal = fit_calibration(depth_xy, screen_xy, screen_wh)
    save_calibration(cal, path)
    return cal


def parse_camera(payload: Any, n_cameras: int, screen_wh: tuple[int, int],
                 shared_wh: Sequence[int] | None = None) -> int | None:
    """The ``cam`` of a calibration request: None when absent (one camera), else an index in
    [0, n_cameras) whose ``screen_wh`` must be the cameras' shared screen ``shared_wh``;
    CalibrationError naming the range otherwise."""
    cam = payload.get("cam") if isinstance(payload, dict) else None
    if cam is None:
        if n_cameras > 1:
            raise CalibrationError(f"there are {n_cameras} cameras; give the camera to "
                                   f"calibrate as \"cam\": 0..{n_cameras - 1}")
        return None
    if not isinstance(cam, int) or isinstance(cam, bool) or not 0 <= cam < max(n_cameras, 1):
        raise CalibrationError(f"cam = {cam!r} is out of range; give 0..{max(n_cameras, 1) - 1}")
    if shared_wh is not None and tuple(screen_wh) != tuple(shared_wh):
        raise CalibrationError(f"screen_wh {list(screen_wh)} is not the cameras' shared screen "
                               f"{list(shared_wh)}; calibrate every camera to the same screen")
    return cam


def camera_calibration_path(out: Path, cam: int | None) -> Path:
    """Where the page's calibration of camera ``cam`` is saved: ``out`` itself for one camera,
    ``NAME.camK.SUFFIX`` beside it with several (calibration.json -> calibration.cam1.json)."""
    if cam is None:
        return out
    return out.with_name(f"{out.stem}.cam{cam}{out.suffix or '.json'}")
