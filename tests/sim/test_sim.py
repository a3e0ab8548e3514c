"""Simulator: geometry against closed forms, noise against each profile's model, truth, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from depthtouch.errors import ConfigError
from depthtouch.sim import CAMERAS, GESTURE_SCENES, PROFILES, SCENES, finger_label, render_scene
from depthtouch.sim.cameras import NoiseModel
from depthtouch.sim.geometry import Box, Capsule, Rays, Sphere, make_surface, render_primitives


def _pixel_rays(camera: str) -> tuple[np.ndarray, np.ndarray, float]:
    """Normalised image coordinates x', y' (H, W) and fx, computed here from K alone."""
    K = PROFILES[camera].K
    w, h = PROFILES[camera].resolution_wh
    xs = (np.arange(w) - K[0, 2]) / K[0, 0]
    ys = (np.arange(h) - K[1, 2]) / K[1, 1]
    xn, yn = np.meshgrid(xs, ys)
    return xn, yn, float(K[0, 0])


# --- geometry, noise-free -------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("camera", "distance_m", "tilt_deg"),
    [
        ("realsense-d435", 1.0, 0.0),
        ("kinect-v2", 0.8, 25.0),
        ("kinect-v1", 1.7, 40.0),
        ("realsense-d435", 2.5, 12.0),
    ],
)
def test_plane_depth_matches_closed_form(camera: str, distance_m: float, tilt_deg: float) -> None:
    rec = render_scene("hover", camera=camera, distance_m=distance_m, tilt_deg=tilt_deg,
                       noise=False, fps=5)
    xn, yn, _ = _pixel_rays(camera)
    th = math.radians(tilt_deg)
    # plane through (0, 0, D) whose normal (0, -sin, -cos) faces the camera
    z = distance_m * 1000.0 * math.cos(th) / (math.cos(th) + math.sin(th) * yn)
    d = rec.depth[0].astype(np.float64)
    assert np.all(d > 0)
    assert np.max(np.abs(d - z)) <= 0.5 + 1e-6


@pytest.mark.parametrize(("surface", "distance_m"), [("cylinder-convex", 1.0),
                                                      ("cylinder-concave", 1.3)])
def test_cylinder_depth_matches_closed_form(surface: str, distance_m: float) -> None:
    rec = render_scene("hover", camera="kinect-v2", distance_m=distance_m, surface=surface,
                       noise=False, fps=5)
    _, yn, _ = _pixel_rays("kinect-v2")
    R, D = 1000.0, distance_m * 1000.0
    zc = D + R if surface == "cylinder-convex" else D - R  # axis along X at (0, 0, zc)
    # (Z y')^2 + (Z - zc)^2 = R^2
    a, b, c = yn**2 + 1.0, -2.0 * zc, zc * zc - R * R
    disc2 = b * b - 4 * a * c
    hit = disc2 >= 1e-6 * np.abs(b * b)
    disc = np.sqrt(np.where(hit, disc2, 0.0))
    z = (-b - disc) / (2 * a) if surface == "cylinder-convex" else (-b + disc) / (2 * a)
    d = rec.depth[0].astype(np.float64)
    assert hit.mean() > 0.9
    assert np.max(np.abs(d - z)[hit]) <= 0.5 + 1e-6
    assert np.all(d[disc2 < 0] == 0)  # rays that miss the cylinder read "no data"
    assert rec.truth["surface"]["radius_mm"] == R


@pytest.mark.parametrize(
    ("prim", "x", "y", "z_expected"),
    [
        # sphere centred on the axis: front at Z = 1000 - 50
        (Sphere(np.array([0.0, 0.0, 1000.0]), 50.0, 1), 256.3, 208.0, 950.0),
        # capsule along X at depth 800, radius 20: body front at 780
        (Capsule(np.array([-100.0, 0.0, 800.0]), np.array([100.0, 0.0, 800.0]), 20.0, 2),
         256.3, 208.0, 780.0),
        # axis-aligned box, front face at 900 - 10
        (Box(np.array([0.0, 0.0, 900.0]), np.eye(3), np.array([40.0, 40.0, 10.0]), 3),
         256.3, 208.0, 890.0),
    ],
)
def test_primitive_ray_cast(prim: Sphere | Capsule | Box, x: float, y: float,
                            z_expected: float) -> None:
    p = PROFILES["kinect-v2"]
    rays = Rays(p.K, p.resolution_wh)
    zbuf = np.full((rays.h, rays.w), 2000.0, np.float32)
    labels = np.zeros((rays.h, rays.w), np.uint8)
    box = render_primitives(rays, [prim], zbuf, labels)
    assert box is not None
    # the optical axis passes between pixels; interpolate the 2x2 around it
    xi, yi = int(math.floor(x)), int(math.floor(y))
    assert abs(float(zbuf[yi:yi + 2, xi:xi + 2].mean()) - z_expected) < 0.3
    assert labels[yi, xi] == prim.label
    assert zbuf[0, 0] == 2000.0 and labels[0, 0] == 0


# --- noise ----------------------------------------------------------------------------------------
@pytest.mark.parametrize(("camera", "distance_m"), [
    ("kinect-v2", 0.8), ("kinect-v2", 2.0),
    ("realsense-d435", 0.7), ("realsense-d435", 1.5),
    ("kinect-v1", 1.0), ("kinect-v1", 2.2),
])
def test_noise_matches_profile_model(camera: str, distance_m: float) -> None:
    p = PROFILES[camera]
    rays = Rays(p.K, p.resolution_wh)
    # a tilted plane, so that quantisation phases vary over the image (as on any real scene)
    z = make_surface("plane", distance_m, 20.0).depth_map(rays)
    model = NoiseModel(p, np.random.default_rng(11))
    frames = np.stack([model.apply(z) for _ in range(40)]).astype(np.float64)
    ok = (frames > 0).all(axis=0)
    assert ok.mean() > 0.8
    std = frames.std(axis=0, ddof=1)[ok]
    sigma = p.sigma_mm(z[ok]).astype(np.float64)
    ratio = math.sqrt(float(np.mean(std**2) / np.mean(sigma**2)))
    assert 0.9 <= ratio <= 1.1, f"temporal std / model = {ratio:.3f}"
    # the fixed per-pixel bias exists and is a fraction of sigma
    bias = (frames.mean(axis=0) - z)[ok]
    frac = float(np.std(bias) / np.mean(sigma))
    assert 0.5 * p.bias_fraction < frac < 1.5 * p.bias_fraction + 0.2
    assert abs(float(np.mean(bias))) < 0.1 * float(np.mean(sigma)) + 0.1
    # dropouts: random zeros at about the profile's rate (plus the stereo left band)
    zeros = float((frames == 0).mean())
    assert zeros >= 0.5 * p.dropout_rate


def test_noise_sigma_formulas() -> None:
    z = np.array([500.0, 1000.0, 2000.0], np.float32)
    v2 = PROFILES["kinect-v2"].sigma_mm(z)
    np.testing.assert_allclose(v2, [1.5 - 0.25 + 0.075, 1.3, 1.5 - 1.0 + 1.2], rtol=1e-5)
    d435 = PROFILES["realsense-d435"].sigma_mm(z)
    np.testing.assert_allclose(d435, z.astype(np.float64) ** 2 * 0.08 / (425.0 * 50.0), rtol=1e-5)
    assert abs(float(d435[1]) - 3.76) < 0.01  # ~3.8 mm at 1 m, Intel's figure
    v1 = PROFILES["kinect-v1"].sigma_mm(z)
    np.testing.assert_allclose(v1, [1.2 + 1.9 * 0.01, 1.2 + 1.9 * 0.36, 1.2 + 1.9 * 2.56],
                               rtol=1e-5)


def test_kinect_v1_depth_steps_grow_with_distance() -> None:
    p = PROFILES["kinect-v1"]
    rays = Rays(p.K, p.resolution_wh)
    steps = []
    for d in (0.8, 2.4):
        z = make_surface("plane", d, 30.0).depth_map(rays)
        out = NoiseModel(p, np.random.default_rng(0)).apply(z)
        levels = np.unique(out[out > 0])
        steps.append(float(np.median(np.diff(levels))))
    assert steps[0] <= 2.0 and steps[1] >= 10.0  # z^2 growth: 1.8 mm vs 16 mm model steps


@pytest.mark.parametrize("camera", ["realsense-d435", "kinect-v1"])
def test_occlusion_shadow_left_of_near_object(camera: str) -> None:
    p = PROFILES[camera]
    rays = Rays(p.K, p.resolution_wh)
    z = make_surface("plane", 1.0, 0.0).depth_map(rays)
    model = NoiseModel(p, np.random.default_rng(0))
    model.set_static(z)
    near = z.copy()
    h, w = near.shape
    near[h // 2 - 20:h // 2 + 20, w // 2:w // 2 + 40] = 800.0  # a block 200 mm up
    out = model.apply(near, (w // 2, h // 2 - 20, w // 2 + 40, h // 2 + 20))
    row = out[h // 2]
    shadow = p.fx_px * p.baseline_mm * (1 / 800.0 - 1 / 1000.0)  # px
    left = row[w // 2 - int(shadow) + 2:w // 2]
    right = row[w // 2 + 41:w // 2 + 41 + int(shadow)]
    assert (left == 0).mean() > 0.9  # hidden from the second view
    assert (right == 0).mean() < 0.2


def test_tof_flying_pixels_between_fore_and_background() -> None:
    p = PROFILES["kinect-v2"]
    rays = Rays(p.K, p.resolution_wh)
    z = make_surface("plane", 1.2, 0.0).depth_map(rays)
    model = NoiseModel(p, np.random.default_rng(0))
    model.set_static(z)
    near = z.copy()
    near[100:200, 100:200] = 900.0
    out = model.apply(near, (100, 100, 200, 200)).astype(np.float64)
    edge = np.concatenate([out[100:200, 99], out[100:200, 100], out[100:200, 199],
                           out[100:200, 200]])
    between = (edge > 930) & (edge < 1170)
    assert between.mean() > 0.2


# --- ground truth ---------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("scene", "camera", "surface", "tilt_deg"),
    [
        ("taps", "realsense-d435", "plane", 0.0),
        ("multitouch", "kinect-v2", "plane", 15.0),
        ("pinch", "kinect-v1", "cylinder-convex", 0.0),
        ("cross", "realsense-d435", "cylinder-concave", 0.0),
        ("taps", "kinect-v2", "plane", 35.0),
    ],
)
def test_truth_reprojects_onto_fingertip(scene: str, camera: str, surface: str,
                                         tilt_deg: float) -> None:
    rec = render_scene(scene, camera=camera, surface=surface, tilt_deg=tilt_deg, seed=2,
                       noise=False, fps=15, keep_labels=True)
    assert rec.labels is not None
    K = rec.K
    radius = {i: hnd["finger_radius_mm"] for i, hnd in enumerate(rec.truth["hands"])}
    checked = occluded = 0
    for fr in rec.truth["frames"]:
        for c in fr["contacts"]:
            # x, y is the projection of X, Y, Z; the normal is unit and faces the camera
            assert abs(K[0, 0] * c["X"] / c["Z"] + K[0, 2] - c["x"]) < 0.01
            assert abs(K[1, 1] * c["Y"] / c["Z"] + K[1, 2] - c["y"]) < 0.01
            nrm = np.array([c["nx"], c["ny"], c["nz"]])
            assert abs(np.linalg.norm(nrm) - 1.0) < 1e-5
            assert float(nrm @ -np.array([c["X"], c["Y"], c["Z"]])) > 0
            if c["occluded"]:
                occluded += 1
                continue
            i, x, y = fr["frame"], int(round(c["x"])), int(round(c["y"]))
            lab = finger_label(c["hand"], c["finger"])
            assert rec.labels[i, y, x] == lab
            # the contact itself is hidden under the tip; the finger's deepest visible pixel
            # within a tip radius is the tip's silhouette, less than a finger width above it
            r = radius[c["hand"]] * (1.1 if c["finger"] == "thumb" else 1.0)
            r_px = max(int(math.ceil(r * K[0, 0] / c["Z"])), 1)
            win = (slice(max(y - r_px, 0), y + r_px + 1), slice(max(x - r_px, 0), x + r_px + 1))
            d = rec.depth[i][win].astype(np.float64)
            mine = rec.labels[i][win] == lab
            deepest = float(d[mine].max())
            assert c["Z"] - 2.0 * r <= deepest <= c["Z"] + 0.5, (deepest, c["Z"], r)
            checked += 1
    assert checked > 10
    assert occluded <= 0.2 * (checked + occluded)


def test_contact_ids_are_episodes_and_hovers_have_heights() -> None:
    rec = render_scene("hover", camera="kinect-v1", seed=1, noise=False, fps=10)
    frames = rec.truth["frames"]
    assert all(not f["contacts"] for f in frames)
    heights = {round(h["height_mm"], 3) for f in frames for h in f["hovers"]}
    assert {10.0, 25.0, 50.0} <= heights
    assert all(0.0 < h <= 100.0 for h in heights)
    taps = render_scene("taps", camera="kinect-v1", seed=1, noise=False, fps=10)
    seen: dict[int, list[int]] = {}
    for f in taps.truth["frames"]:
        for c in f["contacts"]:
            seen.setdefault(c["id"], []).append(f["frame"])
    assert len(seen) == 5
    for frames_of_id in seen.values():  # one contiguous episode per id
        assert frames_of_id == list(range(frames_of_id[0], frames_of_id[-1] + 1))


def test_determinism_per_seed() -> None:
    a = render_scene("taps", camera="kinect-v2", seed=7, fps=10)
    b = render_scene("taps", camera="kinect-v2", seed=7, fps=10)
    c = render_scene("taps", camera="kinect-v2", seed=8, fps=10)
    assert np.array_equal(a.depth, b.depth) and a.truth == b.truth
    assert a.truth != c.truth


# --- errors ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"scene": "tapz"}, "unknown scene 'tapz'; use one of taps, drags"),
        ({"camera": "kinect-v3"}, "unknown camera 'kinect-v3'; use one of kinect-v2"),
        ({"surface": "sphere"}, "unknown surface 'sphere'; use one of plane"),
        ({"distance_m": 0.4}, "allowed [0.5, 2.5] m"),
        ({"distance_m": 2.6}, "allowed [0.5, 2.5] m"),
        ({"tilt_deg": -1.0}, "allowed [0, 40] deg"),
        ({"tilt_deg": 41.0}, "allowed [0, 40] deg"),
        ({"fps": 0.0}, "allowed [1, 120]"),
        ({"seed": -1}, "seed -1 must be an integer >= 0"),
        ({"resolution_scale": 0.1}, "resolution_scale 0.1 is out of range; allowed [0.25, 3]"),
    ],
)
def test_bad_arguments_raise_config_error(kwargs: dict[str, object], message: str) -> None:
    args: dict[str, object] = {"scene": "taps", "fps": 5.0}
    args.update(kwargs)
    scene = str(args.pop("scene"))
    with pytest.raises(ConfigError) as err:
        render_scene(scene, **args)  # type: ignore[arg-type]
    assert message in str(err.value)
    assert "\n" not in str(err.value)


def test_public_names() -> None:
    assert CAMERAS == ("kinect-v2", "realsense-d435", "kinect-v1")
    assert {"taps", "drags", "multitouch", "pinch", "cross", "hover", "distractors", "object",
            "drift", "bump", "hold"} == set(SCENES)
    assert GESTURE_SCENES == ("presses",)  # rendered, measured apart: not in a suite's "all"


@pytest.mark.parametrize("camera", CAMERAS)
def test_bounding_boxes_hold_every_hit(camera: str) -> None:
    """Primitives are ray cast only inside their pixel box: it must cover the whole image of
    the primitive, also off-axis and near the camera (random capsules and spheres, seeded)."""
    from depthtouch.sim.geometry import bbox_px

    p = PROFILES[camera]
    rays = Rays(p.K, p.resolution_wh)
    rng = np.random.default_rng(4)
    for _ in range(40):
        z = rng.uniform(250.0, 2500.0)
        a = np.array([rng.uniform(-1.2, 1.2) * z, rng.uniform(-0.8, 0.8) * z, z])
        b = a + rng.normal(0, 150.0, 3)
        r = float(rng.uniform(5.0, 60.0))
        for prim in (Capsule(a, b, r, 1), Sphere(a, r, 2)):
            if prim.bounds()[0][2] <= 1.0:
                continue  # reaches behind the camera: drawn over the whole image anyway
            full = np.isfinite(prim.ray_t(rays.dx, rays.dy, rays.dz))
            box = bbox_px(prim, rays)
            inside = np.zeros_like(full)
            if box is not None:
                inside[box[1]:box[3], box[0]:box[2]] = True
            assert not np.any(full & ~inside)


@pytest.mark.parametrize(("camera", "jitter"), [("kinect-v1", True), ("realsense-d435", True),
                                                 ("kinect-v2", False)])
def test_edges_wander_between_frames(camera: str, jitter: bool) -> None:
    """Lateral edge noise: an edge pixel shows the near side in some frames, the far in others."""
    p = PROFILES[camera]
    rays = Rays(p.K, p.resolution_wh)
    z = make_surface("plane", 1.0, 0.0).depth_map(rays)
    model = NoiseModel(p, np.random.default_rng(3))
    model.set_static(z)
    near = z.copy()
    near[100:200, 300:340] = 900.0  # 100 mm above the surface
    frames = np.stack([model.apply(near, (300, 100, 340, 200)) for _ in range(30)])
    edge = frames[:, 120:180, 339].astype(np.float64)  # the block's right edge column
    near_side = ((edge > 0) & (edge < 950)).mean()
    far_side = (edge > 950).mean()
    if jitter:
        assert 0.05 < far_side < 0.6 and near_side > 0.2
    else:
        assert far_side < 0.6  # ToF: flying pixels instead, tested above
    inner = frames[:, 120:180, 320].astype(np.float64)
    assert ((inner > 0) & (inner < 950)).mean() > 0.95  # well inside, no wandering


@pytest.mark.parametrize("camera", CAMERAS)
def test_output_depth_stays_in_the_profile_range(camera: str) -> None:
    """Arms nearer than the minimum range, flying and wandering edge pixels: all read 0 when
    out of range; nothing outside [min, max] range reaches the output."""
    p = PROFILES[camera]
    rec = render_scene("multitouch", camera=camera, distance_m=0.6, tilt_deg=20.0, seed=2,
                       fps=6)
    v = rec.depth[rec.depth > 0]
    assert v.min() >= p.min_range_mm and v.max() <= p.max_range_mm


def test_a_camera_at_another_resolution_sees_the_same_scene() -> None:
    """At 1.5 times the resolution (the D435's 848x480 -> 1272x720) the frames are 1.5 times
    larger, the field of view and the scene are the same: each contact lies at the same point
    in the camera frame (within 0.5 mm: the script places hands through the camera's rays) and
    projects to 1.5 times its pixel, about the pixel centres."""
    a = render_scene("taps", camera="realsense-d435", seed=3, fps=10, noise=False)
    b = render_scene("taps", camera="realsense-d435", seed=3, fps=10, noise=False,
                     resolution_scale=1.5)
    assert a.depth.shape[1:] == (480, 848) and b.depth.shape[1:] == (720, 1272)
    assert b.K[0, 0] == pytest.approx(1.5 * a.K[0, 0])
    ca = [c for f in a.truth["frames"] for c in f["contacts"]]
    cb = [c for f in b.truth["frames"] for c in f["contacts"]]
    assert len(ca) == len(cb) > 10
    for p, q in zip(ca, cb, strict=True):
        assert (q["X"], q["Y"], q["Z"]) == pytest.approx((p["X"], p["Y"], p["Z"]), abs=0.5)
        assert q["x"] + 0.5 == pytest.approx(1.5 * (p["x"] + 0.5), abs=0.4)
        assert q["y"] + 0.5 == pytest.approx(1.5 * (p["y"] + 0.5), abs=0.4)
    # the surface's depth at the image centre is the same
    assert abs(float(a.depth[0, 240, 424]) - float(b.depth[0, 360, 636])) <= 2.0


def test_a_noisier_camera_sees_the_same_scene_with_the_noise_scaled() -> None:
    """noise_scale multiplies the axial noise: the same seed's scene, truth and draws, and
    the depth's departure from the exact geometry about twice as large at 2."""
    kw = {"camera": "kinect-v2-hard", "distance_m": 1.3, "seed": 3, "fps": 10}
    exact = render_scene("taps", noise=False, **kw)  # type: ignore[arg-type]
    a = render_scene("taps", **kw)  # type: ignore[arg-type]
    b = render_scene("taps", noise_scale=2.0, **kw)  # type: ignore[arg-type]
    assert a.truth == b.truth
    ok = (exact.depth[3] > 0) & (a.depth[3] > 0) & (b.depth[3] > 0)
    ref = exact.depth[3][ok].astype(float)
    sa = np.std(a.depth[3][ok] - ref)
    sb = np.std(b.depth[3][ok] - ref)
    assert 1.8 < sb / sa < 2.2
    with pytest.raises(ConfigError, match="noise_scale 5 is out of range"):
        render_scene("taps", noise_scale=5, **kw)  # type: ignore[arg-type]

