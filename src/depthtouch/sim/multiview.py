"""One scene seen by several cameras from different poses, with exact truth on a shared screen.

The scene is built as for :func:`~depthtouch.sim.render_scene` (same seed: same script) in the
frame of a *reference* camera; its image is the shared screen, and its truth (a normal
``depthtouch-truth/1`` document, rendered without noise) is the truth in screen coordinates.
Every view is a camera of the same profile at its own pose (centre ``center_mm`` and rotation
``rotation_deg_xyz`` relative to the reference camera), rendered with its own noise: parallax
of hands and arms, each camera's own missing data. Each view comes with the exact calibration
to the screen: the homography through the (planar) surface from its pixels to the reference
image's pixels.

Plane surfaces, scenes without bump or drift (the views would need the same motion).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from ..errors import ConfigError, SourceError
from .cameras import NoiseModel, get_profile
from .geometry import (
    Box,
    Capsule,
    Primitive,
    Rays,
    Sphere,
    Surface,
    make_surface,
    render_primitives,
    rotation_xyz,
)
from .render import SimRecording, assemble_scene, check_render_args, render_scene, write_truth
from .scenes import SceneContext, build_script


@dataclass(frozen=True)
class ViewPose:
    """A camera's pose relative to the reference camera: centre in mm (x right, y down, z along
    the optical axis) and rotation in degrees about x, y, z (camera points are R (p - c))."""

    center_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation_deg_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class View:
    """One camera's recording: depth uint16 (N, H, W) mm, K (3, 3), and H_to_screen (3, 3)
    from its pixels to the shared screen (the reference image's pixels)."""

    depth: np.ndarray
    K: np.ndarray
    H_to_screen: np.ndarray
    pose: ViewPose


@dataclass(frozen=True)
class MultiViewRecording:
    """The views, the reference recording (noise-free; its truth is the screen truth) and the
    shared timestamps; ``screen_wh`` is the reference image's size."""

    views: list[View]
    reference: SimRecording
    timestamps_s: np.ndarray
    screen_wh: tuple[int, int]


def _posed(p: Primitive, R: np.ndarray, c: np.ndarray) -> Primitive:
    if isinstance(p, Capsule):
        q: Primitive = replace(p, a=p.a - c, b=p.b - c)
    elif isinstance(p, (Sphere, Box)):
        q = replace(p, center=p.center - c)
    else:  # pragma: no cover - every primitive kind is listed above
        raise TypeError(f"unknown primitive {type(p).__name__}")
    return q.rotated(R)


def _surface_posed(s: Surface, R: np.ndarray, c: np.ndarray) -> Surface:
    return replace(s, origin_mm=s.origin_mm - c).rotated(R)


def plane_homography(surface: Surface, K: np.ndarray, R: np.ndarray, c: np.ndarray,
                     K_ref: np.ndarray) -> np.ndarray:
    """The homography from a posed camera's pixels to the reference camera's pixels through a
    plane surface (exact: fitted to 16 projected plane points)."""
    st = np.array([[s, t] for s in (-600.0, -200.0, 200.0, 600.0)
                   for t in (-400.0, -130.0, 130.0, 400.0)])
    p = surface.point(st)  # (16, 3) reference camera frame

    def project(K_: np.ndarray, q: np.ndarray) -> np.ndarray:
        h = q @ K_.T
        return h[:, :2] / h[:, 2:3]

    H, _ = cv2.findHomography(project(K, (p - c) @ R.T), project(K_ref, p), 0)
    return np.asarray(H, np.float64)


def render_views(
    scene: str,
    poses: list[ViewPose],
    *,
    camera: str = "kinect-v1",
    distance_m: float = 1.0,
    seed: int = 0,
    fps: float = 30.0,
    noise: bool = True,
) -> MultiViewRecording:
    """Render ``scene`` from every pose (see the module doc). ConfigError on a scene with a
    bump or drift, or no pose."""
    if not poses:
        raise ConfigError("render_views needs at least one pose")
    check_render_args(fps, seed)
    reference = render_scene(scene, camera=camera, distance_m=distance_m, seed=seed, fps=fps,
                             noise=False)
    profile = get_profile(camera)
    world = make_surface("plane", distance_m, 0.0)
    rays = Rays(profile.K, profile.resolution_wh)
    streams = np.random.SeedSequence(int(seed)).spawn(2 + len(poses))
    script = build_script(scene, SceneContext(world, rays, np.random.default_rng(streams[0])))
    if script.bump_s is not None or script.drift is not None:
        raise ConfigError(f"scene {scene!r} moves the camera or surface; pick one without "
                          "bump or drift for several views")
    n = reference.depth.shape[0]
    w, h = profile.resolution_wh
    views = []
    for k, pose in enumerate(poses):
        R = rotation_xyz(pose.rotation_deg_xyz)
        c = np.asarray(pose.center_mm, np.float64)
        surf = _surface_posed(world, R, c)
        static = surf.depth_map(rays)
        model = NoiseModel(profile, np.random.default_rng(streams[2 + k])) if noise else None
        if model is not None:
            model.set_static(static)
        depth = np.empty((n, h, w), np.uint16)
        for i in range(n):
            prims, _ = assemble_scene(script, world, i / fps)
            zbuf = static.copy()
            labels = np.zeros((h, w), np.uint8)
            box = render_primitives(rays, [_posed(p, R, c) for p in prims], zbuf, labels)
            if model is not None:
                depth[i] = model.apply(zbuf, box if box is not None else (0, 0, 0, 0))
            else:
                depth[i] = np.rint(np.clip(zbuf, 0, 65535)).astype(np.uint16)
        H = plane_homography(world, rays.K, R, c, rays.K)
        views.append(View(depth, rays.K.copy(), H, pose))
    return MultiViewRecording(views, reference, reference.timestamps_s, (w, h))


def default_poses(n: int, spacing_mm: float = 800.0) -> list[ViewPose]:
    """``n`` cameras side by side along x, ``spacing_mm`` apart, centred on the reference
    (2 cameras 0.8 m apart at 1 m with a Kinect v1 profile overlap by about 0.3 m)."""
    if not 1 <= n <= 3:
        raise ConfigError(f"--views {n} is out of range; allowed [1, 3]")
    return [ViewPose(((k - (n - 1) / 2) * spacing_mm, 0.0, 0.0)) for k in range(n)]


def write_views(mv: MultiViewRecording, folder: str | Path,
                truth_path: str | Path | None = None) -> list[Path]:
    """Write ``view{k}.npz`` and ``view{k}.calibration.json`` per view into a new or empty
    folder, and the screen truth to ``truth_path`` (default ``folder/truth.json``); returns the
    written paths."""
    from ..calibration import Calibration, save_calibration
    from ..sources import write_npz

    out = Path(folder)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise SourceError(f"{out}: exists and is not an empty folder; choose a new folder")
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for k, v in enumerate(mv.views):
        written.append(write_npz(out / f"view{k}.npz", v.depth, mv.timestamps_s, 0.001, v.K))
        written.append(save_calibration(Calibration(v.H_to_screen, mv.screen_wh, 0.0),
                                        out / f"view{k}.calibration.json"))
    truth = Path(truth_path) if truth_path is not None else out / "truth.json"
    write_truth(truth, mv.reference.truth)
    written.append(truth)
    return written
