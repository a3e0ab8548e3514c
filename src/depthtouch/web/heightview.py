"""The colour height view sent to pages that ask for it: a turbo-coloured JPEG of the height map."""

from __future__ import annotations

import cv2
import numpy as np

from ..errors import OutputError


def colorize_height(
    height_mm: np.ndarray, lo_mm: float = 3.0, hi_mm: float = 80.0
) -> np.ndarray:
    """Colour view of a height map: uint8 BGR (H, W, 3), turbo colour map over [lo_mm, hi_mm].

    Heights are clipped to the range, so with the default lo_mm = 3 the sensor noise of the empty
    surface stays one flat colour; NaN (no surface or no depth) is dark grey. The input is not
    modified.
    """
    if height_mm.ndim != 2:
        raise ValueError(f"height_mm: expected shape (H, W), got {height_mm.shape}")
    if not hi_mm > lo_mm:
        raise ValueError(f"height range [{lo_mm}, {hi_mm}] is empty; give lo_mm < hi_mm")
    h = np.asarray(height_mm, dtype=np.float32)
    invalid = ~np.isfinite(h)
    scaled = (np.nan_to_num(h, nan=lo_mm) - lo_mm) * (255.0 / (hi_mm - lo_mm))
    gray = np.clip(scaled, 0.0, 255.0).astype(np.uint8)
    bgr = cv2.applyColorMap(gray, cv2.COLORMAP_TURBO)
    bgr[invalid] = 40
    return bgr


def encode_jpeg(bgr: np.ndarray, quality: int = 80) -> bytes:
    """JPEG bytes of a BGR uint8 image (quality 1..100)."""
    ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:  # pragma: no cover - OpenCV only fails on empty images
        raise OutputError("cannot encode the height view as JPEG; check the image size")
    return bytes(buf)
