"""Screen calibration: a homography from depth-image pixels to screen pixels.

The paper's touch-pen set-up: the screen shows targets one after another, the user touches each,
and the pairs (touch point in the depth image, target on the screen) fix a plane-to-plane
homography ``H`` (``cv2.findHomography``; RANSAC when there are more than 4 pairs, so that one
bad touch does not spoil the fit). Its reprojection error is reported in screen pixels.

A calibration file is JSON (see docs/outputs.md)::

    {"format": "depthtouch-calibration", "version": 1,
     "H": [[...], [...], [...]], "screen_wh": [1920, 1080],
     "reprojection_error_px": 1.7, "max_error_px": 3.1, "loo_error_px": 2.4,
     "n_points": 9, "n_inliers": 9,
     "depth_xy": [[x, y], ...], "screen_xy": [[sx, sy], ...]}

``depth_xy`` / ``screen_xy`` (the pairs used) are optional and kept for traceability.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from .errors import CalibrationError
from .files import write_text_atomic
from .types import TouchEvent

CALIBRATION_FORMAT = "depthtouch-calibration"
CALIBRATION_VERSION = 1

# A homography whose matrix is this close to singular folds the plane; no real set-up gives one.
_MIN_ABS_DET = 1e-12
# Point sets flatter than this (smallest / largest principal spread) are treated as collinear.
_MIN_SPREAD_RATIO = 1e-3


def _as_points(name: str, xy: object) -> np.ndarray:
    """float64 (N, 2), finite, or CalibrationError naming the shape that was given."""
    try:
        arr = np.asarray(xy, dtype=np.float64)
    except (TypeError, ValueError):
        raise CalibrationError(f"{name} is not numeric; give an (N, 2) array of pixels") from None
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise CalibrationError(f"{name}: expected shape (N, 2), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise CalibrationError(f"{name} contains NaN or inf; give finite pixel coordinates")
    return arr


def _check_screen_wh(screen_wh: object) -> tuple[int, int]:
    """(width, height) as positive whole pixels, or CalibrationError."""
    bad = CalibrationError(
        f"screen_wh {screen_wh!r} is not two whole numbers in (0, 100000]; "
        "give [width, height] in pixels"
    )
    try:
        vals = [float(v) for v in screen_wh]  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise bad from None
    if len(vals) != 2 or any(isinstance(v, bool) for v in screen_wh):  # type: ignore[attr-defined]
        raise bad
    if not all(v.is_integer() and 0 < v <= 100_000 for v in vals):
        raise bad
    return int(vals[0]), int(vals[1])


def _apply_h(H: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Apply a homography to (N, 2) points; points mapped to infinity come out as NaN."""
    homog = xy @ H[:, :2].T + H[:, 2]
    w = homog[:, 2:3]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = homog[:, :2] / w
    out[np.abs(w[:, 0]) < 1e-12] = np.nan
    return out


@dataclass(frozen=True, eq=False)
class Calibration:
    """A fitted depth-to-screen mapping.

    H: (3, 3) float64 homography, depth-image pixels (x = column, y = row) -> screen pixels.
    screen_wh: screen size in pixels (width, height); TUIO normalises by it.
    reprojection_error_px: RMS distance, in screen pixels, between the targets and the mapped
        touches over the pairs used by the fit (the RANSAC inliers).
    max_error_px: the largest such distance (NaN when unknown, e.g. a hand-written file).
        With exactly 4 pairs the homography passes through every pair, so both errors are 0 by
        construction and say nothing about accuracy: use 5 or more targets.
    loo_error_px: leave-one-out RMS error in screen pixels (each inlier predicted by the fit to
        the others), an honest estimate of the accuracy at an untouched point; NaN with fewer
        than 8 inliers (with fewer, dropping a corner target leaves a wild extrapolation).
    n_points: pairs given to the fit; n_inliers: pairs kept by RANSAC (== n_points without).
    depth_xy, screen_xy: the pairs, (N, 2) each, or None when not kept.
    """

    H: np.ndarray
    screen_wh: tuple[int, int]
    reprojection_error_px: float
    max_error_px: float = math.nan
    loo_error_px: float = math.nan
    n_points: int = 0
    n_inliers: int = 0
    depth_xy: np.ndarray | None = field(default=None, repr=False)
    screen_xy: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        H = np.asarray(self.H, dtype=np.float64)
        if H.shape != (3, 3) or not np.all(np.isfinite(H)):
            raise CalibrationError(
                f"H must be a finite 3x3 matrix, got shape {H.shape}; refit the calibration"
            )
        scale = float(np.max(np.abs(H)))
        if scale == 0.0 or abs(float(np.linalg.det(H / scale))) < _MIN_ABS_DET:
            raise CalibrationError("H is singular (it folds the plane); refit the calibration")
        H = H.copy()
        H.setflags(write=False)
        object.__setattr__(self, "H", H)
        object.__setattr__(self, "screen_wh", _check_screen_wh(self.screen_wh))
        object.__setattr__(self, "_H_inv", np.linalg.inv(H))

    def to_screen(self, xy_px: np.ndarray) -> np.ndarray:
        """Depth-image pixels (N, 2) -> screen pixels (N, 2); a (2,) point gives (2,). Pure."""
        xy = np.asarray(xy_px, dtype=np.float64)
        if xy.shape == (2,):
            return _apply_h(self.H, xy[None, :])[0]
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"to_screen: expected shape (N, 2), got {xy.shape}")
        return _apply_h(self.H, xy)

    def to_depth(self, sxy: np.ndarray) -> np.ndarray:
        """Screen pixels (N, 2) -> depth-image pixels (N, 2); a (2,) point gives (2,). Pure."""
        xy = np.asarray(sxy, dtype=np.float64)
        H_inv: np.ndarray = self._H_inv  # type: ignore[attr-defined]
        if xy.shape == (2,):
            return _apply_h(H_inv, xy[None, :])[0]
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"to_depth: expected shape (N, 2), got {xy.shape}")
        return _apply_h(H_inv, xy)

    def to_unit(self, xy_px: np.ndarray) -> np.ndarray:
        """Depth-image pixels (N, 2) -> screen coordinates normalised to [0, 1] (not clipped)."""
        return self.to_screen(xy_px) / np.asarray(self.screen_wh, dtype=np.float64)


def _check_not_degenerate(name: str, xy: np.ndarray) -> None:
    """CalibrationError when the points are (nearly) collinear or, for 4 points, any 3 are."""
    centred = xy - xy.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    if s[0] == 0.0 or s[1] / s[0] < _MIN_SPREAD_RATIO:
        raise CalibrationError(
            f"{name} points are collinear or coincide; spread the targets over the screen"
        )
    if len(xy) == 4:
        # With exactly 4 pairs, three on a line leave the homography undetermined.
        extent = float(np.max(np.ptp(xy, axis=0)))
        for skip in range(4):
            a, b, c = xy[[i for i in range(4) if i != skip]]
            area2 = abs(float((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])))
            if area2 < _MIN_SPREAD_RATIO * extent * extent:
                raise CalibrationError(
                    f"three of the four {name} points are on a line; spread the targets over "
                    "the screen"
                )


def fit_calibration(
    depth_xy: np.ndarray,
    screen_xy: np.ndarray,
    screen_wh: tuple[int, int],
    *,
    ransac_threshold_px: float = 25.0,
) -> Calibration:
    """Fit the depth -> screen homography from >= 4 point pairs.

    depth_xy: (N, 2) touch points in depth-image pixels; screen_xy: (N, 2) target positions in
    screen pixels, same order. screen_wh: screen size in pixels.
    ransac_threshold_px: with more than 4 pairs, a pair whose reprojection error exceeds this
        many screen pixels is an outlier (default 25, range (0, 1000]).
    Raises CalibrationError on fewer than 4 pairs, mismatched or non-finite input, collinear or
    coincident points, or when no homography fits (fewer than 4 inliers).
    """
    d = _as_points("depth_xy", depth_xy)
    s = _as_points("screen_xy", screen_xy)
    wh = _check_screen_wh(screen_wh)
    if len(d) != len(s):
        raise CalibrationError(
            f"{len(d)} depth points but {len(s)} screen points; give one depth point per target"
        )
    if len(d) < 4:
        raise CalibrationError(f"{len(d)} point pairs are too few; touch at least 4 targets")
    if not (0.0 < ransac_threshold_px <= 1000.0):
        raise CalibrationError(
            f"ransac_threshold_px = {ransac_threshold_px!r} is out of range; allowed (0, 1000]"
        )
    _check_not_degenerate("depth", d)
    _check_not_degenerate("screen", s)

    method = cv2.RANSAC if len(d) > 4 else 0
    H, mask = cv2.findHomography(
        d.astype(np.float32).reshape(-1, 1, 2), s.astype(np.float32).reshape(-1, 1, 2),
        method, ransac_threshold_px,
    )
    if H is None or not np.all(np.isfinite(H)):
        raise CalibrationError(
            "no homography fits these point pairs; redo the calibration touching each target"
        )
    inliers = np.ones(len(d), bool) if mask is None else mask.reshape(-1).astype(bool)
    if int(inliers.sum()) < 4:
        raise CalibrationError(
            f"only {int(inliers.sum())} of {len(d)} pairs agree; redo the calibration"
        )
    # findHomography works in float32; refine on the inliers in float64 for sub-pixel accuracy.
    H_ref, _ = cv2.findHomography(d[inliers], s[inliers], 0)
    if H_ref is not None and np.all(np.isfinite(H_ref)):
        H = H_ref
    err = np.linalg.norm(_apply_h(H, d[inliers]) - s[inliers], axis=1)
    if not np.all(np.isfinite(err)):
        raise CalibrationError(
            "the fitted homography sends a target to infinity; redo the calibration"
        )
    return Calibration(
        H=H / H[2, 2] if abs(H[2, 2]) > 1e-12 else H,
        screen_wh=wh,
        reprojection_error_px=float(np.sqrt(np.mean(err**2))),
        max_error_px=float(err.max()),
        loo_error_px=_leave_one_out_px(d[inliers], s[inliers]),
        n_points=len(d),
        n_inliers=int(inliers.sum()),
        depth_xy=d.copy(),
        screen_xy=s.copy(),
    )


def _leave_one_out_px(d: np.ndarray, s: np.ndarray) -> float:
    """RMS error of predicting each pair from a plain least-squares fit to all the others."""
    if len(d) < 8:
        return math.nan
    errs = []
    for i in range(len(d)):
        keep = np.arange(len(d)) != i
        H_i, _ = cv2.findHomography(d[keep], s[keep], 0)
        if H_i is None:
            return math.nan
        errs.append(float(np.linalg.norm(_apply_h(H_i, d[i:i + 1])[0] - s[i])))
    e = np.asarray(errs)
    return float(np.sqrt(np.mean(e**2))) if np.all(np.isfinite(e)) else math.nan


def default_targets(screen_wh: tuple[int, int], n: int = 4, margin: float = 0.1) -> np.ndarray:
    """Target points (n, 2) in screen pixels for the calibration flow, in the order to show.

    n = 4: the corners (top-left, top-right, bottom-right, bottom-left), inset by ``margin``;
    n = 5: the corners and the centre; n = k*k (k >= 3): a k x k grid, row by row in a serpentine.
    margin: inset as a fraction of the screen size (default 0.1, range [0, 0.45]).
    """
    w, h = _check_screen_wh(screen_wh)
    if not (0.0 <= margin <= 0.45):
        raise CalibrationError(f"margin = {margin!r} is out of range; allowed [0, 0.45]")
    k = math.isqrt(n) if n >= 9 else 0
    if n not in (4, 5) and k * k != n:
        raise CalibrationError(
            f"n = {n} targets is not supported; use 4, 5 or a square number >= 9"
        )
    x0, x1 = margin * (w - 1), (1.0 - margin) * (w - 1)
    y0, y1 = margin * (h - 1), (1.0 - margin) * (h - 1)
    if n in (4, 5):
        pts = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        if n == 5:
            pts.append(((x0 + x1) / 2, (y0 + y1) / 2))
        return np.asarray(pts, dtype=np.float64)
    xs, ys = np.linspace(x0, x1, k), np.linspace(y0, y1, k)
    rows = [[(x, y) for x in (xs if r % 2 == 0 else xs[::-1])] for r, y in enumerate(ys)]
    return np.asarray(rows, dtype=np.float64).reshape(-1, 2)


def apply_calibration(events: Sequence[TouchEvent], cal: Calibration | None) -> list[TouchEvent]:
    """The events with ``sx``, ``sy`` (screen pixels) added to ``extra``; new objects, pure.

    With ``cal`` None the events are returned unchanged (as a new list).
    """
    if cal is None or not events:
        return list(events)
    sxy = cal.to_screen(np.array([[e.x, e.y] for e in events], dtype=np.float64))
    return [
        replace(e, extra={**e.extra, "sx": float(p[0]), "sy": float(p[1])})
        for e, p in zip(events, sxy, strict=True)
    ]


# --- files --------------------------------------------------------------------------------------
def calibration_to_dict(cal: Calibration) -> dict[str, Any]:
    d: dict[str, Any] = {
        "format": CALIBRATION_FORMAT,
        "version": CALIBRATION_VERSION,
        "H": [[float(v) for v in row] for row in cal.H],
        "screen_wh": list(cal.screen_wh),
        "reprojection_error_px": float(cal.reprojection_error_px),
        "max_error_px": None if math.isnan(cal.max_error_px) else float(cal.max_error_px),
        "loo_error_px": None if math.isnan(cal.loo_error_px) else float(cal.loo_error_px),
        "n_points": int(cal.n_points),
        "n_inliers": int(cal.n_inliers),
    }
    if cal.depth_xy is not None and cal.screen_xy is not None:
        d["depth_xy"] = [[float(a), float(b)] for a, b in cal.depth_xy]
        d["screen_xy"] = [[float(a), float(b)] for a, b in cal.screen_xy]
    return d


def calibration_from_dict(data: object, where: str = "calibration") -> Calibration:
    """Build a Calibration from parsed JSON; any problem is a one-line CalibrationError."""
    if not isinstance(data, dict):
        raise CalibrationError(f"{where}: not a calibration object; expected a JSON object")
    if data.get("format") != CALIBRATION_FORMAT:
        raise CalibrationError(
            f"{where}: format is {data.get('format')!r}, not {CALIBRATION_FORMAT!r}; "
            "give a file written by depthtouch calibrate"
        )
    if data.get("version") != CALIBRATION_VERSION:
        raise CalibrationError(
            f"{where}: version {data.get('version')!r} is not supported; expected "
            f"{CALIBRATION_VERSION}, recalibrate with this depthtouch"
        )
    missing = [k for k in ("H", "screen_wh", "reprojection_error_px") if k not in data]
    if missing:
        raise CalibrationError(f"{where}: missing key {missing[0]!r}; recalibrate")
    try:
        H = np.asarray(data["H"], dtype=np.float64)
        err = float(data["reprojection_error_px"])
        max_err = math.nan if data.get("max_error_px") is None else float(data["max_error_px"])
        loo_err = math.nan if data.get("loo_error_px") is None else float(data["loo_error_px"])
        n_points, n_inliers = int(data.get("n_points", 0)), int(data.get("n_inliers", 0))
    except (TypeError, ValueError):
        raise CalibrationError(
            f"{where}: H, errors or counts are not numbers; recalibrate"
        ) from None
    if not (math.isfinite(err) and err >= 0.0):
        raise CalibrationError(f"{where}: reprojection_error_px = {err!r} must be >= 0")
    depth_xy = screen_xy = None
    if "depth_xy" in data or "screen_xy" in data:
        try:
            depth_xy = _as_points("depth_xy", data.get("depth_xy"))
            screen_xy = _as_points("screen_xy", data.get("screen_xy"))
        except CalibrationError as e:
            raise CalibrationError(f"{where}: {e}") from None
        if len(depth_xy) != len(screen_xy):
            raise CalibrationError(f"{where}: depth_xy and screen_xy differ in length; recalibrate")
    try:
        return Calibration(H, tuple(data["screen_wh"]), err, max_err, loo_err, n_points,
                           n_inliers, depth_xy, screen_xy)
    except CalibrationError as e:
        raise CalibrationError(f"{where}: {e}") from None
    except TypeError:
        raise CalibrationError(f"{where}: screen_wh must be [width, height]; recalibrate") from None


def save_calibration(cal: Calibration, path: str | Path) -> Path:
    """Write the calibration as JSON, atomically (temporary file + rename). Returns the path."""
    text = json.dumps(calibration_to_dict(cal), indent=2) + "\n"
    return write_text_atomic(path, text, what="the calibration", error=CalibrationError)


def load_calibration(path: str | Path) -> Calibration:
    """Read a calibration file; a missing, unreadable or invalid file is a CalibrationError."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise CalibrationError(
            f"calibration file {p} does not exist; run depthtouch calibrate first"
        ) from None
    except (OSError, UnicodeDecodeError) as e:
        raise CalibrationError(f"cannot read calibration file {p} ({e}); check the path") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise CalibrationError(
            f"calibration file {p} is not valid JSON (line {e.lineno}); recalibrate"
        ) from None
    except RecursionError:
        raise CalibrationError(f"calibration file {p} is nested too deeply; recalibrate") from None
    return calibration_from_dict(data, str(p))


def load_point_pairs(path: str | Path) -> tuple[np.ndarray, np.ndarray, tuple[int, int] | None]:
    """Read calibration point pairs: ``(depth_xy, screen_xy, screen_wh or None)``.

    Accepted JSON: ``{"screen_wh": [w, h], "pairs": [{"depth_xy": [x, y], "screen_xy": [sx, sy]},
    ...]}`` (``screen_wh`` optional), or a bare list of ``[x, y, sx, sy]`` rows.
    """
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CalibrationError(f"point-pairs file {p} does not exist; check the path") from None
    except (OSError, UnicodeDecodeError) as e:
        raise CalibrationError(f"cannot read point-pairs file {p} ({e}); check the path") from None
    except json.JSONDecodeError as e:
        raise CalibrationError(
            f"point-pairs file {p} is not valid JSON (line {e.lineno}); fix the syntax"
        ) from None
    except RecursionError:
        raise CalibrationError(f"point-pairs file {p} is nested too deeply; fix it") from None
    screen_wh: tuple[int, int] | None = None
    try:
        if isinstance(data, list):
            rows = np.asarray(data, dtype=np.float64)
            if rows.ndim != 2 or rows.shape[1] != 4:
                raise CalibrationError(
                    f"{p}: expected rows of [x, y, sx, sy], got shape {rows.shape}"
                )
            return _as_points("depth_xy", rows[:, :2]), _as_points("screen_xy", rows[:, 2:]), None
        if not isinstance(data, dict) or not isinstance(data.get("pairs"), list):
            raise CalibrationError(
                f"{p}: expected {{\"pairs\": [{{\"depth_xy\": [x, y], \"screen_xy\": "
                "[sx, sy]}, ...]}"
            )
        if data.get("screen_wh") is not None:
            screen_wh = _check_screen_wh(data["screen_wh"])
        pairs = data["pairs"]
        if not pairs:
            raise CalibrationError(f"{p}: has no point pairs; touch at least 4 targets")
        depth = _as_points("depth_xy", [q["depth_xy"] for q in pairs])
        screen = _as_points("screen_xy", [q["screen_xy"] for q in pairs])
    except (KeyError, TypeError, ValueError) as e:
        raise CalibrationError(
            f"{p}: pair without numeric depth_xy / screen_xy ({e.__class__.__name__}); "
            "give [x, y] for each"
        ) from None
    except CalibrationError as e:
        raise CalibrationError(f"{p}: {e}" if not str(e).startswith(str(p)) else str(e)) from None
    return depth, screen, screen_wh


def parse_screen_wh(text: str) -> tuple[int, int]:
    """``"1920x1080"`` -> ``(1920, 1080)``; anything else is a CalibrationError."""
    parts = text.lower().replace("×", "x").split("x")
    if len(parts) != 2 or not all(s.strip().isdigit() for s in parts):
        raise CalibrationError(f"screen size {text!r} is not WIDTHxHEIGHT; e.g. 1920x1080")
    return _check_screen_wh((int(parts[0]), int(parts[1])))
