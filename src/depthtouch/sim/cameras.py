"""Depth-camera profiles (intrinsics, range) and their noise models.

Each profile gives the axial noise ``sigma_mm(z)`` of its sensor family, from the literature
(docs/simulator.md lists the sources):

- ``kinect-v2`` (time of flight, Fankhauser et al. 2015): sigma = 1.5 - 0.5 z + 0.3 z^2 mm,
  z in m; flying pixels (depths mixed between foreground and background) at depth edges.
- ``realsense-d435`` (active stereo, Intel's RMS formula): sigma = z^2 * 0.08 / (f_px * 50 mm),
  z in mm; part of the noise is spatially correlated; holes where the second imager cannot see
  (occlusion shadows on the left of near objects, and the left image band with no match).
- ``kinect-v1`` (structured light, Nguyen, Izadi, Lovell 2012): sigma = 1.2 + 1.9 (z - 0.4)^2 mm,
  z in m; depth comes from a disparity quantised to 1/8 px, so depth steps grow with z^2;
  projector shadows.

All profiles add a fixed per-pixel bias (a seeded pattern with ``bias_fraction`` of sigma),
independent temporal noise, and random dropouts. The temporal noise is scaled so that the
*output* (after disparity quantisation and rounding to whole millimetres) has the profile's
sigma: quantisation variance q^2/12 is taken out of the added Gaussian noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import ConfigError


@dataclass(frozen=True)
class CameraProfile:
    """A depth camera: pinhole intrinsics, valid range and noise parameters.

    kind: "tof", "stereo" or "structured-light".
    resolution_wh: image size in pixels.
    fx_px, fy_px, cx_px, cy_px: intrinsics of the depth image.
    min_range_mm, max_range_mm: depths outside this range read 0 (missing).
    baseline_mm: stereo / projector baseline (0 for ToF); drives occlusion shadows.
    disparity_step_px: disparity quantum (kinect-v1: 1/8 px), 0 = none.
    bias_fraction: std of the fixed per-pixel bias as a fraction of sigma (0.2-0.5).
    correlated_fraction: share of the temporal noise variance that is spatially correlated.
    correlation_px: Gaussian correlation length of that share, pixels.
    dropout_rate: fraction of pixels randomly missing in each frame.
    flying_prob: probability that a depth-edge pixel is a flying pixel (ToF).
    edge_dropout_prob: probability that a depth-edge pixel is missing.
    """

    name: str
    kind: str
    resolution_wh: tuple[int, int]
    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    min_range_mm: float
    max_range_mm: float
    baseline_mm: float = 0.0
    disparity_step_px: float = 0.0
    bias_fraction: float = 0.3
    correlated_fraction: float = 0.0
    correlation_px: float = 2.0
    dropout_rate: float = 0.002
    flying_prob: float = 0.0
    edge_dropout_prob: float = 0.0

    @property
    def K(self) -> np.ndarray:
        """(3, 3) float64 pinhole matrix."""
        return np.array(
            [[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px], [0.0, 0.0, 1.0]]
        )

    def sigma_mm(self, z_mm: np.ndarray) -> np.ndarray:
        """Axial noise std (mm) of the output depth at depth ``z_mm`` (any shape, float)."""
        z = np.asarray(z_mm, dtype=np.float32)
        if self.kind == "tof":
            zm = z * np.float32(1e-3)
            return np.float32(1.5) - np.float32(0.5) * zm + np.float32(0.3) * zm * zm
        if self.kind == "stereo":
            return z * z * np.float32(0.08 / (self.fx_px * self.baseline_mm))
        zm = z * np.float32(1e-3) - np.float32(0.4)
        return np.float32(1.2) + np.float32(1.9) * zm * zm

    def quantum_mm(self, z_mm: np.ndarray) -> np.ndarray:
        """Depth step (mm) of the output at ``z_mm``: disparity quantum and the 1 mm unit."""
        z = np.asarray(z_mm, dtype=np.float32)
        if self.disparity_step_px > 0:
            step = z * z * np.float32(self.disparity_step_px / (self.fx_px * self.baseline_mm))
            return np.sqrt(step * step + np.float32(1.0))
        return np.ones_like(z)


PROFILES: dict[str, CameraProfile] = {
    "kinect-v2": CameraProfile(
        name="kinect-v2", kind="tof", resolution_wh=(512, 424),
        fx_px=365.5, fy_px=365.5, cx_px=256.3, cy_px=208.0,
        min_range_mm=500.0, max_range_mm=4500.0,
        bias_fraction=0.3, dropout_rate=0.002, flying_prob=0.6, edge_dropout_prob=0.15,
    ),
    "realsense-d435": CameraProfile(
        name="realsense-d435", kind="stereo", resolution_wh=(848, 480),
        fx_px=425.0, fy_px=425.0, cx_px=423.5, cy_px=239.5,
        min_range_mm=195.0, max_range_mm=10000.0, baseline_mm=50.0,
        bias_fraction=0.4, correlated_fraction=0.4, correlation_px=2.0,
        dropout_rate=0.004, edge_dropout_prob=0.3,
    ),
    "kinect-v1": CameraProfile(
        name="kinect-v1", kind="structured-light", resolution_wh=(640, 480),
        fx_px=580.0, fy_px=580.0, cx_px=319.5, cy_px=239.5,
        min_range_mm=400.0, max_range_mm=4000.0, baseline_mm=75.0, disparity_step_px=0.125,
        bias_fraction=0.3, correlated_fraction=0.2, correlation_px=1.5,
        dropout_rate=0.002, edge_dropout_prob=0.2,
    ),
}

CAMERAS: tuple[str, ...] = tuple(PROFILES)


def get_profile(name: str) -> CameraProfile:
    """The profile called ``name``; ConfigError listing the valid names otherwise."""
    try:
        return PROFILES[name]
    except KeyError:
        raise ConfigError(
            f"unknown camera {name!r}; use one of {', '.join(CAMERAS)}"
        ) from None


class NoiseModel:
    """Turns noise-free depth (float32 mm, 0 = no surface) into a sensor frame (uint16 mm).

    Holds the per-recording state: the fixed bias pattern and pools of Gaussian samples. Each
    frame's temporal noise is two pool slices at random offsets (a view, no copy) summed, so that
    a pixel's samples over time are independent draws from ~10^7 values at a fraction of the
    cost of drawing a fresh field (4-5 ms for 848x480 on this machine).
    """

    _POOL_FACTOR = 6

    def __init__(self, profile: CameraProfile, rng: np.random.Generator) -> None:
        self.profile = profile
        self.rng = rng
        w, h = profile.resolution_wh
        self.shape = (h, w)
        n = h * w
        self._n = n
        self._pools = [
            rng.standard_normal(n * self._POOL_FACTOR, dtype=np.float32) for _ in range(2)
        ]
        self._mix: tuple[float, float, int] | None = None
        if profile.correlated_fraction > 0:
            size = int(2 * round(3 * profile.correlation_px) + 1)
            k1 = cv2.getGaussianKernel(size, profile.correlation_px, cv2.CV_64F)
            k2 = k1 @ k1.T
            s2 = float(np.sum(k2 * k2))
            kc = float(k2[size // 2, size // 2])
            a = np.sqrt(1.0 - profile.correlated_fraction)
            b = np.sqrt(profile.correlated_fraction / s2)
            norm = 1.0 / np.sqrt(a * a + b * b * s2 + 2.0 * a * b * kc)
            self._mix = (float(a * norm), float(b * norm), size)
        bias = self._correlate(rng.standard_normal(self.shape, dtype=np.float32))
        self.bias = bias * np.float32(profile.bias_fraction)
        # column index of every pixel, for the stereo occlusion test
        self._cols = np.broadcast_to(np.arange(w, dtype=np.float32), self.shape)

    def _correlate(self, white: np.ndarray) -> np.ndarray:
        """Unit-variance field with the profile's share of spatial correlation.

        white + Gaussian-blurred white, weighted so that the blurred part carries
        ``correlated_fraction`` of the variance and the sum has variance 1 (exact, from the
        kernel's sum of squares and its centre weight).
        """
        if self._mix is None:
            return white
        a, b, size = self._mix
        sd = self.profile.correlation_px
        blurred = cv2.GaussianBlur(white, (size, size), sd)
        out: np.ndarray = white * np.float32(a) + blurred * np.float32(b)
        return out

    def _temporal(self) -> np.ndarray:
        n = self._n
        hi = n * (self._POOL_FACTOR - 1)
        o1, o2 = (int(v) for v in self.rng.integers(0, hi, 2))
        eps = self._pools[0][o1:o1 + n] + self._pools[1][o2:o2 + n]
        eps *= np.float32(np.sqrt(0.5))
        return self._correlate(eps.reshape(self.shape))

    def set_static(self, z_mm: np.ndarray) -> None:
        """Precompute what depends only on the static scene (the surface depth map)."""
        z = np.asarray(z_mm, dtype=np.float32)
        self._static_z = z
        self._static = self._maps(z)
        missing = self._edge_effects(z, self._static[0], None)[0]
        if self.profile.baseline_mm > 0:
            missing |= self._occluded(np.where(z > 0, z, np.float32(np.inf)))
        self._static_missing = missing

    def _maps(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """sigma, the Gaussian std to add, and the range-invalid mask for depths z."""
        p = self.profile
        valid = z > 0
        zs = np.where(valid, z, np.float32(p.min_range_mm))
        sigma = p.sigma_mm(zs)
        q = p.quantum_mm(zs)
        # leave room for the quantisation variance so the output std equals sigma
        add = np.sqrt(np.maximum(sigma * sigma - q * q * np.float32(1.0 / 12.0),
                                 np.float32(0.09) * sigma * sigma))
        bad = ~valid | (z < p.min_range_mm) | (z > p.max_range_mm)
        return sigma, add, bad

    def apply(self, z_mm: np.ndarray, box: tuple[int, int, int, int] | None = None
              ) -> np.ndarray:
        """Noisy uint16 depth (mm) for one noise-free float32 depth map (mm, 0 = nothing).

        box: (x0, y0, x1, y1) outside which ``z_mm`` equals the depth given to
        :meth:`set_static` (the surface); only that part is re-analysed. None = whole frame.
        """
        p = self.profile
        z = np.asarray(z_mm, dtype=np.float32)
        if box is None or getattr(self, "_static_z", None) is None:
            self.set_static(z)
            box = None
        sigma_s, add_s, bad_s = self._static
        eps = self._temporal()
        noisy = add_s * eps
        noisy += sigma_s * self.bias
        noisy += z
        missing = self._static_missing.copy()
        missing |= bad_s
        if box is not None and box[2] > box[0] and box[3] > box[1]:
            h, w = self.shape
            x0, y0 = max(box[0] - 2, 0), max(box[1] - 2, 0)
            x1, y1 = min(box[2] + 2, w), min(box[3] + 2, h)
            sl = (slice(y0, y1), slice(x0, x1))
            zb = z[sl]
            sigma, add, bad = self._maps(zb)
            noisy[sl] = zb + add * eps[sl] + sigma * self.bias[sl]
            edge_missing, fly = self._edge_effects(zb, sigma, noisy[sl])
            if fly is not None:
                noisy[sl] = fly
            missing[sl] |= bad | edge_missing
            if p.baseline_mm > 0:
                # shadows fall to the left of near objects: rows of the box, columns up to it
                rows = (slice(y0, y1), slice(0, w))
                zr = z[rows]
                missing[rows] |= self._occluded(np.where(zr > 0, zr, np.float32(np.inf)))
        if p.disparity_step_px > 0:
            fb = np.float32(p.fx_px * p.baseline_mm / p.disparity_step_px)
            disp = np.rint(fb / np.maximum(noisy, np.float32(1.0)))
            noisy = fb / np.maximum(disp, np.float32(1.0))
        k = self.rng.poisson(p.dropout_rate * self._n)
        if k:
            missing.reshape(-1)[self.rng.integers(0, self._n, k)] = True
        noisy += np.float32(0.5)
        np.clip(noisy, 0.0, 65535.0, out=noisy)
        np.copyto(noisy, np.float32(0.0), where=missing)
        return noisy.astype(np.uint16)

    def _edge_effects(
        self, z: np.ndarray, sigma: np.ndarray, noisy: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Missing pixels at depth edges, and (ToF) ``noisy`` with flying pixels mixed in."""
        p = self.profile
        if p.flying_prob <= 0 and p.edge_dropout_prob <= 0:
            return np.zeros(z.shape, bool), None
        edges, zmin, zmax = self._depth_edges(z, sigma)
        missing = np.zeros(z.shape, bool)
        ey, ex = np.nonzero(edges)
        if ey.size == 0:
            return missing, None
        out = None
        if p.flying_prob > 0 and noisy is not None:
            fly = self.rng.random(ey.size) < p.flying_prob
            fy, fx = ey[fly], ex[fly]
            alpha = self.rng.random(fy.size, dtype=np.float32)
            out = noisy.copy()
            out[fy, fx] = zmin[fy, fx] + alpha * (zmax[fy, fx] - zmin[fy, fx])
            ey, ex = ey[~fly], ex[~fly]
        if p.edge_dropout_prob > 0:
            drop = self.rng.random(ey.size) < p.edge_dropout_prob
            missing[ey[drop], ex[drop]] = True
        return missing, out

    def _depth_edges(
        self, z: np.ndarray, sigma: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pixels whose 3x3 neighbourhood spans a depth jump (> 20 mm + 6 sigma)."""
        kernel = np.ones((3, 3), np.uint8)
        zf = np.where(z > 0, z, np.float32(self.profile.max_range_mm))
        zmax = cv2.dilate(zf, kernel)
        zmin = cv2.erode(zf, kernel)
        edges = (zmax - zmin) > (np.float32(20.0) + np.float32(6.0) * sigma)
        return edges, zmin, zmax

    def _occluded(self, z: np.ndarray) -> np.ndarray:
        """Pixels the second imager (or the projector) cannot see, and the unmatched left band.

        The second view sits ``baseline_mm`` to the right: a pixel at column x appears there at
        x - d with d = f b / z; it is hidden when a pixel to its right lands further left.
        """
        p = self.profile
        disp = np.float32(p.fx_px * p.baseline_mm) / z
        r = self._cols[: disp.shape[0]] - disp
        # suffix minimum of r over the pixels strictly to the right
        rev = np.minimum.accumulate(r[:, ::-1], axis=1)[:, ::-1]
        right_min = np.empty_like(r)
        right_min[:, :-1] = rev[:, 1:]
        right_min[:, -1] = np.inf
        hidden = right_min < r - np.float32(0.5)
        if p.kind == "stereo":
            hidden |= r < 0
        return hidden
