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

from dataclasses import dataclass, replace

import cv2
import numpy as np

from ..errors import ConfigError
from .artefacts import fatten_edges, match_window, multipath, speckle_holes


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
    edge_jitter_prob: probability that a depth-edge pixel takes its neighbour's side (fore- or
        background, 50/50) in a frame: lateral noise, edges wander by about a pixel.
    edge_dropout_prob: probability that a depth-edge pixel is missing.
    noise_scale_range: (lo, hi) factor on sigma, drawn once per recording from the seed (a
        different unit of the same camera, or a warmer room); (1, 1) = the nominal sigma.
    multipath_mm, multipath_reach_mm: ToF multipath bias near low hand parts (sim/artefacts.py).
    fatten_px, fatten_prob: stereo edge fattening: reach (px) and probability per frame.
    speckle_per_mpx: stereo speckle holes per megapixel and frame at 1 m (grows with z^2).
    window_px: stereo matching window (3 or 5; 0 = none): thin structures fade.
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
    edge_jitter_prob: float = 0.0
    edge_dropout_prob: float = 0.0
    noise_scale_range: tuple[float, float] = (1.0, 1.0)
    multipath_mm: float = 0.0
    multipath_reach_mm: float = 20.0
    fatten_px: int = 0
    fatten_prob: float = 0.0
    speckle_per_mpx: float = 0.0
    window_px: int = 0

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
        dropout_rate=0.004, edge_jitter_prob=0.3, edge_dropout_prob=0.3,
    ),
    "kinect-v1": CameraProfile(
        name="kinect-v1", kind="structured-light", resolution_wh=(640, 480),
        fx_px=580.0, fy_px=580.0, cx_px=319.5, cy_px=239.5,
        min_range_mm=400.0, max_range_mm=4000.0, baseline_mm=75.0, disparity_step_px=0.125,
        bias_fraction=0.3, correlated_fraction=0.2, correlation_px=1.5,
        dropout_rate=0.002, edge_jitter_prob=0.5, edge_dropout_prob=0.2,
    ),
}

CAMERAS: tuple[str, ...] = tuple(PROFILES)

# The hard suite's profiles (docs/simulator.md): the same sensors with the artefacts the default
# profiles leave out, and a noise level drawn per seed. Kept apart from CAMERAS so that suites
# saying cameras = "all" (the default suite, a regression reference) do not change.
HARD_PROFILES: dict[str, CameraProfile] = {
    "kinect-v2-hard": replace(
        PROFILES["kinect-v2"], name="kinect-v2-hard", flying_prob=0.75, edge_dropout_prob=0.1,
        noise_scale_range=(0.9, 1.4), multipath_mm=3.0, multipath_reach_mm=25.0,
    ),
    "realsense-d435-hard": replace(
        PROFILES["realsense-d435"], name="realsense-d435-hard", noise_scale_range=(0.9, 1.5),
        fatten_px=2, fatten_prob=0.6, speckle_per_mpx=150.0, window_px=5,
    ),
    "kinect-v1-hard": replace(
        PROFILES["kinect-v1"], name="kinect-v1-hard", noise_scale_range=(0.9, 1.3),
        fatten_px=1, fatten_prob=0.4,
    ),
}
HARD_CAMERAS: tuple[str, ...] = tuple(HARD_PROFILES)
PROFILES.update(HARD_PROFILES)


def scaled_profile(profile: CameraProfile, scale: float) -> CameraProfile:
    """The same camera at ``scale`` times its resolution (the same field of view): image size
    and focal lengths scaled, the principal point kept at the same place in the image. The
    per-pixel artefacts (matching window, edge fattening, correlation length) stay in the
    sensor's pixels; stereo and structured-light depth noise follows the focal length."""
    if scale == 1.0:
        return profile
    w, h = profile.resolution_wh
    return replace(
        profile, resolution_wh=(max(1, round(w * scale)), max(1, round(h * scale))),
        fx_px=profile.fx_px * scale, fy_px=profile.fy_px * scale,
        cx_px=(profile.cx_px + 0.5) * scale - 0.5, cy_px=(profile.cy_px + 0.5) * scale - 0.5,
    )


def get_profile(name: str) -> CameraProfile:
    """The profile called ``name``; ConfigError listing the valid names otherwise."""
    try:
        return PROFILES[name]
    except KeyError:
        raise ConfigError(
            f"unknown camera {name!r}; use one of {', '.join(CAMERAS + HARD_CAMERAS)}"
        ) from None


class NoiseModel:
    """Turns noise-free depth (float32 mm, 0 = no surface) into a sensor frame (uint16 mm).

    Holds the per-recording state: the fixed bias pattern, pools of Gaussian samples and the
    maps of the static scene (:meth:`set_static`). A frame's temporal noise is the sum of two
    pool slices at random offsets (views, no copy): a white pool, and either a second white pool
    or, for profiles with spatially correlated noise, a pool blurred once at start (its slices
    start on a row so the blur's 2-D structure survives). A pixel's samples over time are thus
    independent draws from ~10^7 values, at a fraction of the cost of drawing a fresh field
    (4-5 ms for 848x480 on this machine).
    """

    _POOL_FRAMES = 6

    def __init__(self, profile: CameraProfile, rng: np.random.Generator,
                 skin_noise: float = 1.0) -> None:
        self.profile = profile
        self.rng = rng
        # the returned amplitude's share in the noise (render_scene's skin_noise; 1: none)
        self.skin_noise = float(skin_noise)
        w, h = profile.resolution_wh
        self.shape = (h, w)
        self._n = h * w
        pool_shape = (h * self._POOL_FRAMES, w)
        self._white = rng.standard_normal(pool_shape, dtype=np.float32).reshape(-1)
        second = rng.standard_normal(pool_shape, dtype=np.float32)
        rho = profile.correlated_fraction
        if rho > 0:
            # unit-variance blurred field carries rho of the variance, white the rest
            self._second = self._blur_unit(second).reshape(-1)
            self._weights = (np.float32(np.sqrt(1.0 - rho)), np.float32(np.sqrt(rho)))
        else:
            self._second = second.reshape(-1)
            self._weights = (np.float32(np.sqrt(0.5)), np.float32(np.sqrt(0.5)))
        bias: np.ndarray = rng.standard_normal(self.shape, dtype=np.float32)
        if rho > 0:
            a, b = self._weights
            blurred = self._blur_unit(rng.standard_normal(self.shape, dtype=np.float32))
            bias = (a * bias + b * blurred).astype(np.float32)
        self.bias = (bias * np.float32(profile.bias_fraction)).astype(np.float32)
        # column index of every pixel, for the occlusion test
        self._cols = np.broadcast_to(np.arange(w, dtype=np.float32), self.shape)
        self._static_z: np.ndarray | None = None
        self._edge_box: tuple[int, int, int, int] | None = None
        # drawn last, and only for profiles that vary, so the other profiles' streams stay as
        # they were (the default suite is a regression reference)
        lo, hi = profile.noise_scale_range
        self.noise_scale = np.float32(rng.uniform(lo, hi)) if hi > lo else np.float32(lo)
        self._depth_mm = 1000.0

    def _blur_unit(self, white: np.ndarray) -> np.ndarray:
        """Gaussian-blurred white noise rescaled to unit variance (by the kernel's norm)."""
        sd = self.profile.correlation_px
        size = int(2 * round(3 * sd) + 1)
        k1 = cv2.getGaussianKernel(size, sd, cv2.CV_64F)
        norm = float(np.sqrt(np.sum((k1 @ k1.T) ** 2)))
        out: np.ndarray = cv2.GaussianBlur(white, (size, size), sd) * np.float32(1.0 / norm)
        return out

    def _temporal(self) -> np.ndarray:
        h, w = self.shape
        n = self._n
        o1 = int(self.rng.integers(0, n * (self._POOL_FRAMES - 1)))
        o2 = int(self.rng.integers(0, h * (self._POOL_FRAMES - 1))) * w
        a, b = self._weights
        eps = self._white[o1:o1 + n] * a
        eps += self._second[o2:o2 + n] * b
        return eps.reshape(self.shape)

    def set_static(self, z_mm: np.ndarray, live_edges: bool = False) -> None:
        """Precompute what depends only on the static scene (the surface depth map).

        live_edges: the static scene's own depth edges (a table's edge, :mod:`.edge`) get
        their artefacts drawn again every frame, as a hand's do, instead of once."""
        z = np.asarray(z_mm, dtype=np.float32)
        self._static_z = z
        sigma, add, bad = self._maps(z, self._amplitude(z, None))
        self._static_add = add
        self._static_bias = sigma * self.bias
        # surface pixels whose noise can cross a range limit are checked every frame
        p = self.profile
        near = ~bad & ((z - 6 * sigma < p.min_range_mm) | (z + 6 * sigma > p.max_range_mm))
        self._near_limit = np.flatnonzero(near)
        edge_missing = self._edge_effects(z, sigma, None)[0]
        self._edge_box = None
        if live_edges:
            ys, xs = np.nonzero(self._jumps(z, sigma)[0])
            if ys.size:
                self._edge_box = (int(xs.min()), int(ys.min()), int(xs.max()) + 1,
                                  int(ys.max()) + 1)
                edge_missing = np.zeros(z.shape, bool)
        missing = bad | edge_missing
        if self.profile.baseline_mm > 0:
            r = self._cols - np.float32(self.profile.fx_px * self.profile.baseline_mm) / \
                np.where(z > 0, z, np.float32(np.inf))
            self._static_rmin = self._right_min(r)
            missing |= self._hidden(r, self._static_rmin)
        self._static_missing = missing
        self._depth_mm = float(np.median(z[z > 0])) if np.any(z > 0) else 1000.0

    def _amplitude(self, z: np.ndarray, static: np.ndarray | None) -> np.ndarray | None:
        """The temporal noise's factor where the returned amplitude is lower (None without
        ``skin_noise``): 1/cos of the angle between the surface's normal and the optical axis
        (from the noise-free depth's gradient; at most 4), times ``skin_noise`` where something
        stands nearer than the static surface ``static`` by more than 3 mm."""
        if self.skin_noise == 1.0:
            return None
        gy, gx = np.gradient(z)
        scale = np.float32(self.profile.fx_px) / np.where(z > 0, z, np.float32(np.inf))
        slope2 = (gx * gx + gy * gy) * scale * scale
        factor = np.minimum(np.sqrt(np.float32(1.0) + slope2), np.float32(4.0))
        if static is not None:
            near = (z > 0) & (z < static - np.float32(3.0))
            factor = np.where(near, factor * np.float32(self.skin_noise), factor)
        return factor.astype(np.float32)

    def _maps(self, z: np.ndarray, factor: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """sigma, the Gaussian std to add, and the range-invalid mask for depths z; ``factor``
        (per pixel, from :meth:`_amplitude`) scales the temporal noise only (the bias, edges and
        range checks keep sigma)."""
        p = self.profile
        valid = z > 0
        zs = np.where(valid, z, np.float32(p.min_range_mm))
        sigma = p.sigma_mm(zs)
        if self.noise_scale != 1.0:
            sigma = sigma * self.noise_scale
        q = p.quantum_mm(zs)
        s_add = sigma if factor is None else sigma * factor
        # leave room for the quantisation variance so the output std equals sigma
        add = np.sqrt(np.maximum(s_add * s_add - q * q * np.float32(1.0 / 12.0),
                                 np.float32(0.09) * s_add * s_add))
        bad = ~valid | (z < p.min_range_mm) | (z > p.max_range_mm)
        return sigma, add, bad

    def apply(self, z_mm: np.ndarray, box: tuple[int, int, int, int] | None = None
              ) -> np.ndarray:
        """Noisy uint16 depth (mm) for one noise-free float32 depth map (mm, 0 = nothing).

        box: (x0, y0, x1, y1) outside which ``z_mm`` equals the depth given to
        :meth:`set_static` (the surface); only that part is re-analysed. None = the whole
        frame is new (it becomes the static scene).
        """
        p = self.profile
        z = np.asarray(z_mm, dtype=np.float32)
        if box is None or self._static_z is None:
            self.set_static(z)
            box = None
        eps = self._temporal()
        noisy = self._static_add * eps
        noisy += self._static_bias
        noisy += z
        missing = self._static_missing.copy()
        if self._edge_box is not None:  # the static scene's edges, drawn again every frame
            self._apply_box(z, eps, noisy, missing, self._edge_box)
        if box is not None and box[2] > box[0] and box[3] > box[1]:
            self._apply_box(z, eps, noisy, missing, box)
        if p.disparity_step_px > 0:
            fb = np.float32(p.fx_px * p.baseline_mm / p.disparity_step_px)
            # pixels with no surface (z = 0) give inf or negative values here; they are masked
            with np.errstate(divide="ignore", invalid="ignore"):
                disp = np.rint(fb / noisy)
                noisy = fb / disp
        if self._near_limit.size:
            vals = noisy.reshape(-1)[self._near_limit]
            out_of_range = (vals < p.min_range_mm) | (vals > p.max_range_mm)
            missing.reshape(-1)[self._near_limit[out_of_range]] = True
        if p.speckle_per_mpx > 0:
            missing |= speckle_holes(self.shape, p.speckle_per_mpx, self._depth_mm, self.rng)
        k = self.rng.poisson(p.dropout_rate * self._n)
        if k:
            missing.reshape(-1)[self.rng.integers(0, self._n, k)] = True
        # every unmasked value is a depth within the profile's range (< 10 m): no clipping
        np.copyto(noisy, np.float32(0.0), where=missing)
        noisy += np.float32(0.5)
        return noisy.astype(np.uint16)

    def _apply_box(self, z: np.ndarray, eps: np.ndarray, noisy: np.ndarray, missing: np.ndarray,
                   box: tuple[int, int, int, int]) -> None:
        """Redo noise, edge effects and shadows where the scene differs from the static one."""
        p = self.profile
        h, w = self.shape
        x0, y0 = max(box[0] - 2, 0), max(box[1] - 2, 0)
        x1, y1 = min(box[2] + 2, w), min(box[3] + 2, h)
        sl = (slice(y0, y1), slice(x0, x1))
        zb = z[sl] if p.window_px <= 1 else match_window(z[sl], p.window_px)
        static = self._static_z[sl] if self._static_z is not None else None
        sigma, add, bad = self._maps(zb, self._amplitude(zb, static))
        nb = zb + add * eps[sl] + sigma * self.bias[sl]
        edge_missing, fly = self._edge_effects(zb, sigma, nb)
        nb = nb if fly is None else fly
        if p.multipath_mm > 0 and self._static_z is not None:
            multipath(nb, zb, self._static_z[sl], p.fx_px, p.multipath_mm, p.multipath_reach_mm)
        if p.fatten_px > 0:
            fatten_edges(nb, zb, sigma, p.fatten_px, p.fatten_prob, self.rng)
        noisy[sl] = nb
        # mixed or moved edge pixels can leave the range too
        missing[sl] |= bad | edge_missing | (nb < p.min_range_mm) | (nb > p.max_range_mm)
        if p.baseline_mm > 0:
            # a pixel at x is hidden from the second view by a nearer pixel x' > x when
            # x' - x < d(x') - d(x) <= d(x'): only columns within the largest disparity to the
            # left of the box can change; right of the box the static suffix minimum holds
            fb = np.float32(p.fx_px * p.baseline_mm)
            zpos = zb[zb > 0]
            shift = int(np.ceil(fb / float(zpos.min()))) + 1 if zpos.size else 0
            c0 = max(x0 - shift, 0)
            rows = slice(y0, y1)
            zr = z[rows, c0:x1]
            r = self._cols[: y1 - y0, c0:x1] - fb / np.where(zr > 0, zr, np.float32(np.inf))
            rmin = self._right_min(r, self._static_rmin[rows, x1 - 1])
            missing[rows, c0:x1] |= self._hidden(r, rmin)

    @staticmethod
    def _right_min(r: np.ndarray, boundary: np.ndarray | None = None) -> np.ndarray:
        """Minimum of ``r`` over the pixels strictly to the right (``boundary`` beyond the end)."""
        rev = np.minimum.accumulate(r[:, ::-1], axis=1)[:, ::-1]
        out = np.empty_like(r)
        out[:, :-1] = rev[:, 1:]
        out[:, -1] = np.inf if boundary is None else boundary
        if boundary is not None:
            np.minimum(out, boundary[:, None], out=out)
        return out

    def _hidden(self, r: np.ndarray, right_min: np.ndarray) -> np.ndarray:
        """Hidden from the second view (which sits ``baseline_mm`` to the right): the pixel lands
        at r = x - d there, and a pixel to its right lands further left. Stereo also has no
        match for the left band where r < 0."""
        hidden = right_min < r - np.float32(0.5)
        if self.profile.kind == "stereo":
            hidden |= r < 0
        return hidden

    def _jumps(self, z: np.ndarray, sigma: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Depth edges (a jump well beyond the noise inside a 3x3 neighbourhood; missing
        depths read as the profile's range limit), and the 3x3 minimum and maximum depth."""
        kernel = np.ones((3, 3), np.uint8)
        zf = np.where(z > 0, z, np.float32(self.profile.max_range_mm))
        zmax = cv2.dilate(zf, kernel)
        zmin = cv2.erode(zf, kernel)
        return (zmax - zmin) > (np.float32(20.0) + np.float32(6.0) * sigma), zmin, zmax

    def _edge_effects(
        self, z: np.ndarray, sigma: np.ndarray, noisy: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Missing pixels at depth edges, and (ToF) ``noisy`` with flying pixels mixed in."""
        p = self.profile
        if p.flying_prob <= 0 and p.edge_jitter_prob <= 0 and p.edge_dropout_prob <= 0:
            return np.zeros(z.shape, bool), None
        edges, zmin, zmax = self._jumps(z, sigma)
        missing = np.zeros(z.shape, bool)
        # next to a missing pixel there is no far side to mix with: such edge pixels go missing
        beside_hole = edges & (zmax >= np.float32(p.max_range_mm))
        missing |= beside_hole
        ey, ex = np.nonzero(edges & ~beside_hole)
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
        if p.edge_jitter_prob > 0 and noisy is not None and ey.size:
            jit = self.rng.random(ey.size) < p.edge_jitter_prob
            jy, jx = ey[jit], ex[jit]
            side = np.where(self.rng.random(jy.size) < 0.5, zmin[jy, jx], zmax[jy, jx])
            if out is None:
                out = noisy.copy()
            # keep the pixel's own noise, move it to the other side of the edge
            out[jy, jx] = side + (noisy[jy, jx] - z[jy, jx])
            ey, ex = ey[~jit], ex[~jit]
        if p.edge_dropout_prob > 0:
            drop = self.rng.random(ey.size) < p.edge_dropout_prob
            missing[ey[drop], ex[drop]] = True
        return missing, out
