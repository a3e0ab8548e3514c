"""Surface model: the per-pixel depth of the empty surface (the paper's "virtual touch panel").

Learned from the first frames of a recording: per pixel the mean and the mode (the two statistics
the paper compares) and the median of the valid samples, and the temporal noise sigma. Zeros are
missing measurements, not depth; a pixel valid in fewer than ``min_valid_fraction`` of the samples
is unusable. From the model and K, :func:`height_factor` gives per pixel the factor that turns a
depth difference along the optical axis into a height along the surface normal, so that the
thresholds mean millimetres above the surface also on tilted and curved surfaces.
"""

from __future__ import annotations

import json
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
from numpy.lib.npyio import NpzFile

from ..config import SurfaceConfig
from ..errors import SurfaceError
from ..files import check_output_path
from ..sources.npz import save_npz_atomic
from ..types import Frame

SURFACE_FORMAT = "depthtouch-surface/1"


@dataclass(frozen=True)
class SurfaceModel:
    """A learned surface; arrays are float32 (H, W) in mm unless said otherwise.

    depth_mm: the surface depth by the chosen ``statistic`` (0 where unusable).
    mean_mm, mode_mm, median_mm: the three statistics, kept for comparison.
    sigma_mm: temporal noise per pixel (standard deviation of the valid samples, floored).
    valid: bool (H, W), pixels seen validly often enough to be used.
    """

    depth_mm: np.ndarray
    mean_mm: np.ndarray
    mode_mm: np.ndarray
    median_mm: np.ndarray
    sigma_mm: np.ndarray
    valid: np.ndarray
    statistic: str
    depth_scale_m: float
    K: np.ndarray | None
    n_frames: int

    @property
    def resolution_wh(self) -> tuple[int, int]:
        return int(self.depth_mm.shape[1]), int(self.depth_mm.shape[0])

    def with_statistic(self, statistic: str) -> SurfaceModel:
        """The same model using another statistic as the surface depth."""
        table = {"mean": self.mean_mm, "mode": self.mode_mm, "median": self.median_mm}
        if statistic not in table:
            raise SurfaceError(f"unknown surface statistic {statistic!r}; use mean, mode or median")
        depth = np.where(self.valid, table[statistic], 0).astype(np.float32)
        return SurfaceModel(depth, self.mean_mm, self.mode_mm, self.median_mm, self.sigma_mm,
                            self.valid, statistic, self.depth_scale_m, self.K, self.n_frames)

    def mm_per_px(self) -> float:
        """Typical size of a pixel on the surface in mm (1.0 when K is unknown)."""
        if self.K is None or not self.valid.any():
            return 1.0
        z = float(np.median(self.depth_mm[self.valid]))
        return z / float(np.sqrt(self.K[0, 0] * self.K[1, 1]))

    def save(self, path: str | Path) -> Path:
        """Write to an ``.npz`` file atomically."""
        p = check_output_path(path, what="the surface (.npz)", error=SurfaceError)
        meta = {"format": SURFACE_FORMAT, "statistic": self.statistic,
                "depth_scale_m": self.depth_scale_m, "n_frames": self.n_frames}
        arrays = {"mean_mm": self.mean_mm, "mode_mm": self.mode_mm, "median_mm": self.median_mm,
                  "sigma_mm": self.sigma_mm, "valid": self.valid,
                  "meta": np.asarray(json.dumps(meta))}
        if self.K is not None:
            arrays["K"] = self.K
        return save_npz_atomic(p, arrays, SurfaceError)


def load_surface(path: str | Path) -> SurfaceModel:
    """Read a surface file written by :meth:`SurfaceModel.save`; SurfaceError when malformed."""
    p = Path(path)
    if not p.is_file():
        raise SurfaceError(f"{p}: no such surface file; learn one with --save-surface")
    try:
        with p.open("rb") as fh:
            data = np.load(fh, allow_pickle=False)
            if not isinstance(data, NpzFile):  # a bare .npy array
                raise KeyError("meta")
            with data:
                meta = json.loads(str(data["meta"]))
                arrays = {k: data[k] for k in ("mean_mm", "mode_mm", "median_mm", "sigma_mm",
                                               "valid")}
                K = data["K"] if "K" in data.files else None
        if not all(isinstance(a, np.ndarray) for a in [*arrays.values(), K]
                   if a is not None):  # zip members without the .npy format
            raise ValueError("not arrays")
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, zlib.error, EOFError,
            RuntimeError) as e:  # RuntimeError: encrypted or unsupported zip, deep JSON
        raise SurfaceError(
            f"{p}: not a depthtouch surface file "
            f"({'damaged data' if isinstance(e, zlib.error) else type(e).__name__}); "
            "learn one with --save-surface"
        ) from None
    if not isinstance(meta, dict) or meta.get("format") != SURFACE_FORMAT:
        raise SurfaceError(f"{p}: not a {SURFACE_FORMAT} file; learn one with --save-surface")
    shape = arrays["mean_mm"].shape
    if len(shape) != 2 or any(a.shape != shape for a in arrays.values()):
        raise SurfaceError(f"{p}: arrays of different shapes; the file is damaged, learn it again")
    if arrays["valid"].dtype != np.bool_ or any(
        arrays[k].dtype != np.float32 for k in ("mean_mm", "mode_mm", "median_mm", "sigma_mm")
    ):
        raise SurfaceError(f"{p}: unexpected array types; the file is damaged, learn it again")
    if not all(np.all(np.isfinite(arrays[k])) for k in ("mean_mm", "mode_mm", "median_mm",
                                                        "sigma_mm")):
        raise SurfaceError(f"{p}: NaN or inf in the surface; the file is damaged, learn it again")
    statistic = meta.get("statistic")
    if statistic not in ("mean", "mode", "median"):
        raise SurfaceError(f"{p}: unknown statistic {statistic!r}; learn the surface again")
    try:
        scale = float(meta["depth_scale_m"])
        n = int(meta["n_frames"])
    except (KeyError, TypeError, ValueError, OverflowError):
        raise SurfaceError(f"{p}: metadata incomplete; learn the surface again") from None
    if not (1e-6 <= scale <= 1.0) or n < 1:
        raise SurfaceError(
            f"{p}: depth_scale_m {scale!r} or n_frames {n} out of range; learn the surface again"
        )
    if K is not None and (K.dtype.kind not in "iuf" or K.shape != (3, 3)
                          or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0):
        raise SurfaceError(
            f"{p}: K is not a finite 3x3 matrix with positive fx, fy; learn the surface again"
        )
    base = SurfaceModel(arrays["median_mm"], arrays["mean_mm"], arrays["mode_mm"],
                        arrays["median_mm"], arrays["sigma_mm"], arrays["valid"], "median",
                        scale, K, n)
    return base.with_statistic(statistic)


def _mode_rows(sorted_rows: np.ndarray) -> np.ndarray:
    """Per-row mode of a row-wise sorted integer array (P, N), ignoring zeros (vectorised).

    Ties go to the larger value (the later run), which is the farther depth: a surface is never
    in front of what the camera sees. The run lengths are accumulated frame by frame over all
    pixels at once (frames-by-pixels layout: numpy accumulates fast across the inner axis).
    """
    p, n = sorted_rows.shape
    if n > 250:
        raise SurfaceError(f"the mode needs at most 250 frames, got {n}; learn from fewer frames")
    cols = np.ascontiguousarray(sorted_rows.T)  # (N, P)
    best_run = np.zeros(p, np.int16)
    best_val = np.zeros(p, sorted_rows.dtype)
    run = np.zeros(p, np.int16)
    for i in range(n):  # a loop over the (few) frames; each step is vectorised over the pixels
        v = cols[i]
        if i:
            same = v == cols[i - 1]
            run = np.where(same, run + 1, 1).astype(np.int16)
        else:
            run = np.ones(p, np.int16)
        better = (run >= best_run) & (v > 0)
        best_run = np.where(better, run, best_run)
        best_val = np.where(better, v, best_val)
    return best_val


def learn_surface(
    depth: np.ndarray,
    depth_scale_m: float,
    K: np.ndarray | None = None,
    config: SurfaceConfig | None = None,
) -> SurfaceModel:
    """Learn a surface from a stack of empty-surface frames, uint16 (N, H, W); pure.

    Works on a pixels-by-frames copy so that every per-pixel statistic runs over contiguous
    memory (the sort for the mode and median dominates: ~0.5 s for 45 frames at 848x480).
    Raises SurfaceError when fewer than 2 frames are given or no pixel is usable.
    """
    cfg = config or SurfaceConfig()
    if depth.ndim != 3 or depth.dtype != np.uint16:
        raise SurfaceError(f"learn_surface: expected uint16 (N, H, W), got {depth.dtype} {depth.shape}")
    n, h, w = depth.shape
    if n < 2:
        raise SurfaceError(f"the surface needs at least 2 frames, got {n}; record a longer empty start")
    to_mm = np.float32(depth_scale_m * 1000.0)
    rows = np.sort(depth.reshape(n, -1).T, axis=1)  # (P, N), zeros first
    count = np.count_nonzero(rows, axis=1)
    safe = np.maximum(count, 1)
    mean_u = rows.sum(axis=1, dtype=np.uint64) / safe
    dev = rows.astype(np.float32) - mean_u.astype(np.float32)[:, None]
    dev[rows == 0] = 0
    var = (dev * dev).sum(axis=1) / np.maximum(count - 1, 1)
    sigma = np.maximum(np.sqrt(var) * to_mm, np.float32(cfg.noise_floor_mm)).astype(np.float32)
    mean = (mean_u * to_mm).astype(np.float32)
    mode = _mode_rows(rows).astype(np.float32) * to_mm
    # median of the valid samples: zeros sort first, so the valid ones start at n - count
    lo = np.minimum((n - count) + np.maximum(count - 1, 0) // 2, n - 1)
    hi = np.minimum((n - count) + count // 2, n - 1)
    pix = np.arange(rows.shape[0])
    med = 0.5 * (rows[pix, lo].astype(np.float32) + rows[pix, hi].astype(np.float32)) * to_mm
    mean, mode, med, sigma = (a.reshape(h, w) for a in (mean, mode, med, sigma))
    count = count.reshape(h, w)
    valid = (count >= max(2, int(np.ceil(cfg.min_valid_fraction * n)))) & (mean > 0)
    if not valid.any():
        raise SurfaceError(
            "no pixel had valid depth during surface learning; check the camera sees the surface"
        )
    zeros = np.zeros_like(mean)
    model = SurfaceModel(
        zeros, np.where(valid, mean, 0).astype(np.float32),
        np.where(valid, mode, 0).astype(np.float32), np.where(valid, med, 0).astype(np.float32),
        np.where(valid, sigma, 0).astype(np.float32), valid, cfg.statistic,
        float(depth_scale_m), None if K is None else np.asarray(K, np.float64), n,
    )
    return model.with_statistic(cfg.statistic)


def _ray_slopes(K: np.ndarray, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel (H, W), x / z and y / z of its ray through the camera centre (float32)."""
    h, w = shape[:2]
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    u = (np.arange(w, dtype=np.float32) - cx) / fx
    v = (np.arange(h, dtype=np.float32) - cy) / fy
    uu, vv = np.meshgrid(u, v)
    return uu, vv


def surface_normals(surface: SurfaceModel) -> np.ndarray | None:
    """Per pixel, the surface's unit normal in camera coordinates, pointing toward the camera,
    float32 (H, W, 3); None without K. Zero where the surface is unusable.

    From central differences of the back-projected surface depth, smoothed (Gaussian, sigma 3 px)
    to tame its noise.
    """
    if surface.K is None:
        return None
    import cv2

    uu, vv = _ray_slopes(surface.K, surface.depth_mm.shape)
    z = surface.depth_mm
    zs = cv2.GaussianBlur(np.where(surface.valid, z, 0).astype(np.float32), (0, 0), 3.0)
    ws = cv2.GaussianBlur(surface.valid.astype(np.float32), (0, 0), 3.0)
    zsm = np.where(ws > 1e-3, zs / np.maximum(ws, 1e-3), 0).astype(np.float32)
    pts = np.stack([uu * zsm, vv * zsm, zsm], axis=-1)
    n = np.cross(np.gradient(pts, axis=1), np.gradient(pts, axis=0))
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    ray = np.stack([uu, vv, np.ones_like(uu)], axis=-1)
    # toward the camera: against the pixel's ray
    n = np.where((n * ray).sum(-1, keepdims=True) > 0, -n, n)
    ok = surface.valid[..., None] & (norm > 0) & np.isfinite(n).all(-1, keepdims=True)
    return np.where(ok, n / np.maximum(norm, 1e-12), 0.0).astype(np.float32)


def height_factor(surface: SurfaceModel, normals: np.ndarray | None = None) -> np.ndarray:
    """Per pixel, height along the surface normal per mm of depth difference, float32 (H, W).

    For a pixel's ray r (unit) and the surface normal n there, a point moved toward the camera by
    dz along the optical axis moves dz / r_z along the ray and dz * |n . r| / r_z along the
    normal. Without K the factor is 1 (heights are depth differences). ``normals``: those of
    :func:`surface_normals`, when the caller has them already.
    """
    n = surface_normals(surface) if normals is None else normals
    if surface.K is None or n is None:
        return np.ones(surface.depth_mm.shape, np.float32)
    uu, vv = _ray_slopes(surface.K, surface.depth_mm.shape)
    ray = np.stack([uu, vv, np.ones_like(uu)], axis=-1)
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    cos = np.abs((n * ray).sum(-1))
    f = cos / ray[..., 2]
    ok = surface.valid & (np.abs(n).sum(-1) > 0) & np.isfinite(f)
    return np.where(ok, np.clip(f, 0.2, 2.0), 1.0).astype(np.float32)


#: a learning frame's pixel after ``learn_min_s`` moved when it lies farther than this from its
#: mean over the frames before ``learn_min_s``, and than MOTION_SIGMAS of their standard
#: deviation (mm)
MOTION_MM = 20.0
MOTION_SIGMAS = 5.0


def mask_moved(depth: np.ndarray, sure: int, to_mm: float) -> tuple[np.ndarray, int]:
    """The learning frames (uint16 (N, H, W)) with what moved after the first ``sure`` frames
    taken out (set to 0, a missing sample), and how many samples that was (pure; ``depth``
    itself when none). A pixel moved in a later frame when it lies farther than MOTION_MM, and
    than MOTION_SIGMAS of its standard deviation, from its mean over the ``sure`` frames; a
    pixel with fewer than 2 valid samples there keeps its later ones. (One compiled pass per
    pixel; ``tests/surface/test_surface.py`` keeps the array version as its oracle.)"""
    n = depth.shape[0]
    if sure < 2 or sure >= n:
        return depth, 0
    flat = depth.reshape(n, -1)
    moved = _moved_samples(flat, int(sure), float(MOTION_MM / to_mm), float(MOTION_SIGMAS))
    k = int(moved.sum())
    if k == 0:
        return depth, 0
    out = flat.copy()
    out[moved] = 0
    return out.reshape(depth.shape), k


@numba.njit(cache=True, nogil=True)
def _moved_samples(flat: np.ndarray, sure: int, lim_units: float, k_sigma: float) -> np.ndarray:
    """(N, P) bool: the samples of frames ``sure`` on that moved (see :func:`mask_moved`)."""
    n, p = flat.shape
    s1 = np.zeros(p, np.float64)
    s2 = np.zeros(p, np.float64)
    cnt = np.zeros(p, np.int64)
    for i in range(sure):
        row = flat[i]
        for j in range(p):
            v = row[j]
            if v > 0:
                s1[j] += v
                s2[j] += np.float64(v) * v
                cnt[j] += 1
    lim = np.empty(p, np.float64)
    mean = np.empty(p, np.float64)
    for j in range(p):
        c = cnt[j]
        if c < 2:
            lim[j] = np.inf
            mean[j] = 0.0
            continue
        m = s1[j] / c
        var = max((s2[j] - c * m * m) / (c - 1), 0.0)
        mean[j] = m
        lim[j] = max(lim_units, k_sigma * np.sqrt(var))
    out = np.zeros((n, p), np.bool_)
    for i in range(sure, n):
        row, o = flat[i], out[i]
        for j in range(p):
            v = row[j]
            o[j] = v > 0 and abs(v - mean[j]) > lim[j]
    return out


def warm_up() -> None:
    """Compile (or load from cache) the learning's kernel (see :func:`tipkernel.warm_up`)."""
    mask_moved(np.ones((3, 2, 2), np.uint16), 2, 1.0)


class SurfaceLearner:
    """Collects the first frames of a stream and learns the surface from them.

    ``update(frame)`` returns the model once enough frames (``learn_frames`` or ``learn_s``
    seconds, measured on the frame timestamps) have been seen, else None. A recording promises
    an empty surface for its first second only (docs/formats.md): what moves in the frames
    after ``learn_min_s`` (a hand coming in) is left out of the learning, pixel by pixel
    (:func:`mask_moved`; ``masked`` counts those samples).
    """

    def __init__(self, config: SurfaceConfig | None = None, n_frames: int | None = None) -> None:
        self.config = config or SurfaceConfig()
        self.n_frames = n_frames if n_frames is not None else self.config.learn_frames
        self.reset()

    def reset(self) -> None:
        self._frames: list[np.ndarray] = []
        self._t0: float | None = None
        self._last: Frame | None = None
        self._times: list[float] = []
        self.masked = 0

    @property
    def progress(self) -> float:
        """0..1 share of the learning done (by frames or by time)."""
        if not self._frames or self._last is None or self._t0 is None:
            return 0.0
        if self.n_frames is not None:
            return min(1.0, len(self._frames) / self.n_frames)
        return min(1.0, (self._last.timestamp_s - self._t0) / self.config.learn_s)

    def update(self, frame: Frame) -> SurfaceModel | None:
        if self._frames and frame.depth.shape != self._frames[0].shape:
            raise SurfaceError(
                f"frame {frame.index} is {frame.depth.shape[1]}x{frame.depth.shape[0]} but the "
                "surface frames before it were not; give a stream of one resolution"
            )
        if self._t0 is None:
            self._t0 = frame.timestamp_s
        self._frames.append(frame.depth)
        self._times.append(frame.timestamp_s)
        self._last = frame
        done = (len(self._frames) >= self.n_frames if self.n_frames is not None
                else frame.timestamp_s - self._t0 >= self.config.learn_s - 1e-9
                and len(self._frames) >= 2)
        if not done:
            return None
        return self._learn(frame)

    def _learn(self, frame: Frame) -> SurfaceModel:
        assert self._t0 is not None
        stack = np.stack(self._frames)
        if self.config.learn_min_s < self.config.learn_s:
            sure = sum(t - self._t0 < self.config.learn_min_s - 1e-9 for t in self._times)
            stack, self.masked = mask_moved(stack, sure, frame.depth_scale_m * 1000.0)
        model = learn_surface(stack, frame.depth_scale_m, frame.K, self.config)
        self._frames, self._times = [], []
        return model
