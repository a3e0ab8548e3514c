"""The simulator's ground truth (``depthtouch-truth/1``, docs/simulator.md): read and checked.

:func:`read_truth` / :func:`truth_from_dict` turn a truth document into a :class:`Truth` of
parallel arrays (contacts and hovers per frame, the surface normal at each contact, K); any
problem in the document is a one-line SourceError naming it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SourceError

TRUTH_FORMAT = "depthtouch-truth/1"


@dataclass(frozen=True)
class Truth:
    """Ground truth of one recording as parallel arrays (one row per contact or hover per frame).

    K: (3, 3) intrinsics of the depth image. fps: nominal frame rate (Hz). n_frames: frames in
    the recording (frame indices count from 0, including the empty frames). empty_frames: leading
    frames of the empty surface. contact_*: frame (M,), id (M,), xy_px (M, 2) projection,
    p_mm (M, 3) contact point in the camera frame, n (M, 3) unit surface normal there.
    contact_occluded (M,): the truth marks the tip hidden from the camera in that frame.
    hover_*: frame (H,), id (H,), xy_px (H, 2), p_mm (H, 3) (the tip's closest point projected
    onto the surface), n (H, 3) (the optical axis, -z, when the truth gives none), height_mm (H,).
    meta: scene, seed, camera, surface and events of the document, as given.
    """

    K: np.ndarray
    fps: float
    n_frames: int
    empty_frames: int
    contact_frame: np.ndarray
    contact_id: np.ndarray
    contact_xy_px: np.ndarray
    contact_p_mm: np.ndarray
    contact_n: np.ndarray
    contact_occluded: np.ndarray
    hover_frame: np.ndarray
    hover_id: np.ndarray
    hover_xy_px: np.ndarray
    hover_p_mm: np.ndarray
    hover_n: np.ndarray
    hover_height_mm: np.ndarray
    meta: Mapping[str, Any] = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        return self.n_frames / self.fps


def _num(v: Any, where: str, key: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise SourceError(f"{where}: {key} = {v!r} is not a finite number; fix the truth file")
    return float(v)


def _rows(items: Any, keys: tuple[str, ...], where: str) -> list[list[float]]:
    if not isinstance(items, list):
        raise SourceError(f"{where} must be a list; fix the truth file")
    out = []
    for j, item in enumerate(items):
        if not isinstance(item, dict):
            raise SourceError(f"{where}[{j}] must be an object; fix the truth file")
        missing = [k for k in keys if k not in item]
        if missing:
            raise SourceError(f"{where}[{j}] has no {missing[0]!r}; regenerate the truth file")
        out.append([_num(item[k], f"{where}[{j}]", k) for k in keys])
    return out


_CONTACT_KEYS = ("id", "x", "y", "X", "Y", "Z", "nx", "ny", "nz")
_HOVER_KEYS = ("id", "x", "y", "X", "Y", "Z", "height_mm")


def truth_from_dict(doc: Any, where: str = "truth") -> Truth:
    """Validate a truth document (already parsed JSON) and convert it to arrays.

    Raises SourceError with a one-line message naming the bad key.
    """
    if not isinstance(doc, dict):
        raise SourceError(f"{where}: a truth document must be a JSON object; regenerate it")
    if doc.get("format") != TRUTH_FORMAT:
        raise SourceError(
            f"{where}: format is {doc.get('format')!r}, expected {TRUTH_FORMAT!r}; "
            "give a truth file written by `depthtouch sim`"
        )
    cam = doc.get("camera")
    if not isinstance(cam, dict) or "K" not in cam or "fps" not in cam:
        raise SourceError(f"{where}: camera must have K and fps; regenerate the truth file")
    try:
        K = np.asarray(cam["K"], dtype=np.float64)
    except (TypeError, ValueError):
        raise SourceError(f"{where}: camera.K is not numeric; give a 3x3 matrix") from None
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise SourceError(f"{where}: camera.K must be 3x3 with positive fx, fy, got {K.shape}")
    fps = _num(cam["fps"], where, "camera.fps")
    if fps <= 0:
        raise SourceError(f"{where}: camera.fps = {fps} must be > 0; fix the truth file")
    frames = doc.get("frames")
    if not isinstance(frames, list) or not frames:
        raise SourceError(f"{where}: frames must be a non-empty list; regenerate the truth file")
    c_rows: list[list[float]] = []
    h_rows: list[list[float]] = []
    h_normals: list[list[float]] = []
    c_occ: list[bool] = []
    last = -1
    for i, fr in enumerate(frames):
        if not isinstance(fr, dict) or "frame" not in fr:
            raise SourceError(f"{where}: frames[{i}] has no 'frame'; regenerate the truth file")
        f = fr["frame"]
        if isinstance(f, bool) or not isinstance(f, int) or f <= last:
            raise SourceError(
                f"{where}: frames[{i}].frame = {f!r} must be an integer above {last}; "
                "list frames in order"
            )
        last = f
        contacts = fr.get("contacts", [])
        for j, r in enumerate(_rows(contacts, _CONTACT_KEYS, f"{where}: frames[{i}].contacts")):
            c_rows.append([f, *r])
            occ = contacts[j].get("occluded", False)
            if not isinstance(occ, bool):
                raise SourceError(
                    f"{where}: frames[{i}].contacts[{j}].occluded = {occ!r} must be true or false"
                )
            c_occ.append(occ)
        hovers = fr.get("hovers", [])
        for j, r in enumerate(_rows(hovers, _HOVER_KEYS, f"{where}: frames[{i}].hovers")):
            h_rows.append([f, *r])
            h = hovers[j]
            has_n = all(k in h for k in ("nx", "ny", "nz"))
            h_normals.append(
                [_num(h[k], f"{where}: frames[{i}].hovers[{j}]", k) for k in ("nx", "ny", "nz")]
                if has_n else [0.0, 0.0, -1.0]
            )
    c = np.asarray(c_rows, dtype=np.float64).reshape(-1, 10)
    h = np.asarray(h_rows, dtype=np.float64).reshape(-1, 8)
    cn = _unit(c[:, 7:10], f"{where}: a contact normal")
    hn = _unit(np.asarray(h_normals, dtype=np.float64).reshape(-1, 3), f"{where}: a hover normal")
    empty = doc.get("empty_frames", 0)
    if isinstance(empty, bool) or not isinstance(empty, int) or empty < 0:
        raise SourceError(f"{where}: empty_frames = {empty!r} must be a whole number >= 0")
    meta = {k: doc[k] for k in ("scene", "seed", "camera", "surface", "events") if k in doc}
    return Truth(
        K=K, fps=fps, n_frames=last + 1, empty_frames=empty,
        contact_frame=c[:, 0].astype(np.int64), contact_id=c[:, 1].astype(np.int64),
        contact_xy_px=c[:, 2:4], contact_p_mm=c[:, 4:7], contact_n=cn,
        contact_occluded=np.asarray(c_occ, dtype=bool),
        hover_frame=h[:, 0].astype(np.int64), hover_id=h[:, 1].astype(np.int64),
        hover_xy_px=h[:, 2:4], hover_p_mm=h[:, 4:7], hover_n=hn, hover_height_mm=h[:, 7],
        meta=meta,
    )


def _unit(n: np.ndarray, what: str) -> np.ndarray:
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    if np.any(norm < 1e-9):
        raise SourceError(f"{what} is zero; give unit normals (nx, ny, nz) in the truth file")
    return n / norm


def read_truth(path: str | Path) -> Truth:
    """Read and validate a truth JSON file; any problem is a one-line SourceError."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SourceError(f"{p}: no such truth file; check the path (see depthtouch sim)") from None
    except (OSError, UnicodeDecodeError) as e:
        raise SourceError(f"{p}: cannot read the truth file ({e}); give a UTF-8 JSON file") from e
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise SourceError(f"{p}: not valid JSON ({e.msg} at line {e.lineno}); fix the file") from e
    except RecursionError:
        raise SourceError(f"{p}: JSON nested too deeply; regenerate it with depthtouch sim") from None
    return truth_from_dict(doc, str(p))
