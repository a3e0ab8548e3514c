"""Render a scene to a depth recording with per-frame ground truth, write it, read truth back.

Per frame: the surface depth map (cached while the camera and surface stay put), then every
primitive of the hands and props inside its projected bounding box (z-buffer), then the camera's
noise model. The truth document is described in docs/simulator.md.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError, SourceError
from ..files import write_text_atomic
from .artefacts import exposure_mix
from .breathing import breathe, check_breathing
from .cameras import NoiseModel, get_profile, scaled_profile
from .drops import check_drop_rate, drop_frames
from .edge import check_edge, edge_depth_map, edge_doc, place_edge
from .geometry import Primitive, Rays, Surface, make_surface, render_primitives, rotation_xyz
from .hand import FINGERS, HAND_STYLES, build_hand
from .scenes import HOVER_MAX_MM, SceneContext, Script, build_script

TRUTH_FORMAT = "depthtouch-truth/1"


@dataclass(frozen=True)
class SimRecording:
    """A rendered recording.

    depth: uint16 (N, H, W), millimetres along the optical axis, 0 = missing.
    timestamps_s: float64 (N,), frame / fps.
    depth_scale_m: 0.001.
    K: (3, 3) intrinsics.
    truth: the truth document (docs/simulator.md).
    labels: uint8 (N, H, W) what each pixel shows (0 surface, 10 + finger / 15 palm / 16 arm for
        the first hand, 20.. the second, 101 object, 102 resting arm, 103 passing body), only
        when rendered with ``keep_labels=True``.
    """

    depth: np.ndarray
    timestamps_s: np.ndarray
    depth_scale_m: float
    K: np.ndarray
    truth: dict[str, Any]
    labels: np.ndarray | None = None

    @property
    def fps(self) -> float:
        return float(self.truth["camera"]["fps"])


def _frame_of(t_s: float, fps: float) -> int:
    """First frame whose timestamp is at or after ``t_s``."""
    return int(math.ceil(t_s * fps - 1e-9))


class _TruthBuilder:
    """Per-frame contacts and hovers with episode ids (one counter for both kinds)."""

    def __init__(self) -> None:
        self.frames: list[dict[str, Any]] = []
        self._active: dict[tuple[int, str, str], int] = {}
        self._next_id = 1

    def add(self, index: int, t: float, items: list[tuple[int, str, str, dict[str, Any]]]
            ) -> None:
        now: dict[tuple[int, str, str], int] = {}
        contacts: list[dict[str, Any]] = []
        hovers: list[dict[str, Any]] = []
        for hand, finger, kind, rec in items:
            key = (hand, finger, kind)
            if key in self._active:
                now[key] = self._active[key]
            else:
                now[key] = self._next_id
                self._next_id += 1
            (contacts if kind == "contact" else hovers).append({"id": now[key], **rec})
        self._active = now
        self.frames.append({"frame": index, "t": round(t, 6), "contacts": contacts,
                            "hovers": hovers})


#: the fixed finger pitches a scene may be rendered at (deg; render_scene's pitch_deg)
PITCH_RANGE_DEG = (10.0, 85.0)


def check_render_args(fps: float, seed: int) -> None:
    """ConfigError unless fps is in [1, 120] Hz and seed an integer >= 0 (every renderer)."""
    if not (isinstance(fps, (int, float)) and 1.0 <= fps <= 120.0):
        raise ConfigError(f"fps {fps!r} is out of range; allowed [1, 120]")
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"seed {seed!r} must be an integer >= 0")


def render_scene(
    scene: str,
    *,
    camera: str = "realsense-d435",
    distance_m: float = 1.0,
    tilt_deg: float = 0.0,
    surface: str = "plane",
    seed: int = 0,
    fps: float = 30.0,
    noise: bool = True,
    keep_labels: bool = False,
    hand: str = "capsule",
    resolution_scale: float = 1.0,
    pitch_deg: float | None = None,
    noise_scale: float = 1.0,
    motion_ms: float = 0.0,
    skin_noise: float = 1.0,
    body: bool = False,
    drop_rate: float = 0.0,
    breathing_mm: float = 0.0,
    edge_mm: float = 0.0,
) -> SimRecording:
    """Render ``scene`` (see :data:`~depthtouch.sim.SCENES`) as seen by ``camera``.

    distance_m: surface distance on the optical axis, [0.5, 2.5] m (default 1.0).
    tilt_deg: surface tilt about the camera X axis, [0, 40] deg (default 0).
    surface: "plane", "cylinder-convex" or "cylinder-concave" (radius 1 m).
    seed: picks hand sizes, positions, timings and noise; equal seeds give equal recordings.
    fps: frame rate, [1, 120] Hz (default 30). noise: False gives exact geometry rounded to mm.
    keep_labels: also return a per-pixel label stack (for tests and figures; N*H*W bytes).
    hand: the hand model, "capsule" (default) or "anatomic" (tapered phalanges, a flattened pad
    that presses into the surface; :class:`~depthtouch.sim.hand.Anatomy`).
    resolution_scale: the camera at this many times its resolution, same field of view,
    [0.25, 3] (default 1: 848x480 for the D435 profiles; 1.5 gives 1272x720).
    pitch_deg: every lead finger at this angle to the surface, [10, 85] deg, instead of the
    scene's random pitch (20-70 deg for most scenes); the seed's spots, timings and hand sizes
    stay as they were (default None: drawn).
    noise_scale: the camera's axial noise (sigma, and the range a hard profile draws it from)
    times this, [0.25, 4] (default 1); the seed's draws stay the same, the artefacts (flying
    and mixed pixels, multipath, holes) too.
    motion_ms: the span of the camera's raw exposures, [0, 50] ms (default 0: none). A pixel
    that a moving hand covers or uncovers within it reads a depth between the hand's and what
    lies behind (a time-of-flight camera's motion artefact; sim/artefacts.py): each frame is
    the mean of renders at 4 instants spread over ``motion_ms`` centred on its timestamp (as a
    camera stamps a frame at the middle of its exposure), with or without noise; the truth is
    the timestamp's.
    skin_noise: the temporal noise of whatever stands nearer than the surface (hand, arm, an
    object) times this, [1, 4] (default 1: none of what follows). A time-of-flight camera's
    noise follows the infrared amplitude it gets back: less from skin than from a white wall,
    and less from a surface turned away. So with it, every pixel's temporal noise also grows
    as 1/cos of the angle between its surface's normal and the optical axis (from the
    noise-free depth's gradient; at most 4x: a tilted wall, a finger's flank). The bias, the
    edge artefacts and every random draw stay as they were.
    body: every arm goes on past the shoulder into a body that leaves the view (a torso-sized
    capsule parallel to the surface, :func:`~depthtouch.sim.hand.body_capsule`), as a person
    does; without it (default) the arm ends at the shoulder, and a camera from about 1.3 m
    sees it whole. Every random draw stays as it was.
    drop_rate: frames the camera never delivers, [0, 0.2] (default 0: none): after a frame
    that remains, the next is dropped with this chance, and a dropped frame takes the next with
    it with chance 0.3 (:mod:`~depthtouch.sim.drops`); the remaining frames keep their
    timestamps, and the truth is numbered again over them. The frames that remain are exactly
    those rendered without it.
    breathing_mm: the whole frame moves at once, [0, 10] mm (default 0: none): a wobble of
    half this (standard deviation, 0.5 s time constant) and jumps of 1-2 times it held for
    0.5-3 s, at the surface's distance; a disparity camera's pixels by the offset times
    (z / distance)^2 (:mod:`~depthtouch.sim.breathing`). The hands, the scene and each pixel's
    noise stay as they were; applied before ``drop_rate``.
    Unknown names or out-of-range values raise ConfigError naming the valid ones.
    """
    if not (isinstance(resolution_scale, (int, float)) and 0.25 <= resolution_scale <= 3.0):
        raise ConfigError(f"resolution_scale {resolution_scale!r} is out of range; "
                          "allowed [0.25, 3]")
    if not (isinstance(noise_scale, (int, float)) and 0.25 <= noise_scale <= 4.0):
        raise ConfigError(f"noise_scale {noise_scale!r} is out of range; allowed [0.25, 4]")
    if not (isinstance(motion_ms, (int, float)) and 0.0 <= motion_ms <= 50.0):
        raise ConfigError(f"motion_ms {motion_ms!r} is out of range; allowed [0, 50]")
    if not (isinstance(skin_noise, (int, float)) and 1.0 <= skin_noise <= 4.0):
        raise ConfigError(f"skin_noise {skin_noise!r} is out of range; allowed [1, 4]")
    profile = scaled_profile(get_profile(camera), float(resolution_scale))
    if noise_scale != 1.0:
        lo_n, hi_n = profile.noise_scale_range
        profile = replace(
            profile, noise_scale_range=(lo_n * noise_scale, hi_n * noise_scale))
    world_surface = make_surface(surface, distance_m, tilt_deg)
    check_render_args(fps, seed)
    lo, hi = PITCH_RANGE_DEG
    if pitch_deg is not None and not (isinstance(pitch_deg, (int, float)) and lo <= pitch_deg <= hi):
        raise ConfigError(f"pitch_deg {pitch_deg!r} is out of range; allowed [{lo:g}, {hi:g}] deg")
    if not isinstance(body, bool):
        raise ConfigError(f"body {body!r} must be true or false")
    drop_rate = check_drop_rate(drop_rate)
    breathing_mm = check_breathing(breathing_mm)
    edge_mm = check_edge(edge_mm)
    if hand not in HAND_STYLES:
        raise ConfigError(f"unknown hand {hand!r}; use one of {', '.join(HAND_STYLES)}")
    rays = Rays(profile.K, profile.resolution_wh)
    # independent streams for the script and the noise (SeedSequence works on numpy < 1.25)
    scene_rng, noise_rng = (np.random.default_rng(s)
                            for s in np.random.SeedSequence(int(seed)).spawn(2))
    script = build_script(scene, SceneContext(world_surface, rays, scene_rng, hand, pitch_deg,
                                                body))
    edge = place_edge(script, world_surface, edge_mm, int(seed)) if edge_mm > 0 else None
    n = max(int(round(script.duration_s * fps)), 1)
    w, h = profile.resolution_wh
    depth = np.empty((n, h, w), np.uint16)
    labels_out = np.empty((n, h, w), np.uint8) if keep_labels else None
    model = NoiseModel(profile, noise_rng, float(skin_noise)) if noise else None
    bump_R = rotation_xyz(script.bump_deg_xyz)
    truth = _TruthBuilder()
    cache: tuple[tuple[bool, float], np.ndarray] | None = None
    first_busy: int | None = None
    for i in range(n):
        t = i / fps
        bumped = script.bump_s is not None and t >= script.bump_s
        R = bump_R if bumped else np.eye(3)
        # drift moves in 0.1 mm steps so the surface (and its noise maps) can be cached
        offset = round(script.drift(t) * 10.0) / 10.0 if script.drift is not None else 0.0
        surf_w = world_surface.moved(offset)
        key = (bumped, round(offset, 4))
        if cache is None or cache[0] != key:
            seen = surf_w.rotated(R)
            cache = (key, seen.depth_map(rays) if edge is None
                     else edge_depth_map(seen, rays, edge))
            if model is not None:
                model.set_static(cache[1], live_edges=edge is not None)
        zbuf = cache[1].copy()
        labels = np.zeros((h, w), np.uint8)
        prims, items_3d = assemble_scene(script, surf_w, t)
        if bumped:
            prims = [p.rotated(R) for p in prims]
        box = render_primitives(rays, prims, zbuf, labels)
        if motion_ms > 0:
            zbuf, box = _exposures(script, surf_w, R if bumped else None, rays, cache[1], t,
                                   motion_ms / 1000.0)
        if first_busy is None and box is not None:
            first_busy = i
        items = _truth_items(items_3d, R, rays, labels)
        truth.add(i, t, items)
        if offset != 0.0:
            truth.frames[-1]["surface_offset_mm"] = round(offset, 4)
        if model is not None:
            depth[i] = model.apply(zbuf, box if box is not None else (0, 0, 0, 0))
        else:
            depth[i] = np.rint(np.clip(zbuf, 0, 65535)).astype(np.uint16)
        if labels_out is not None:
            labels_out[i] = labels
    doc = _truth_doc(scene, seed, profile.name, rays, fps, world_surface, distance_m, tilt_deg,
                     script, truth, n if first_busy is None else first_busy)
    if edge is not None:
        doc["edge"] = edge_doc(edge, world_surface, rays)
    rec = SimRecording(depth, np.arange(n, dtype=np.float64) / fps, 0.001, rays.K.copy(), doc,
                       labels_out)
    if breathing_mm > 0:
        rec = breathe(rec, breathing_mm, seed, profile.kind, distance_m)
    return drop_frames(rec, drop_rate, seed) if drop_rate > 0 else rec


_SUB_EXPOSURES = 4


def _exposures(script: Script, surf: Surface, R: np.ndarray | None, rays: Rays,
               static: np.ndarray, t: float, span_s: float
               ) -> tuple[np.ndarray, tuple[int, int, int, int] | None]:
    """The frame at ``t`` integrated over ``span_s`` centred on it (see ``motion_ms``): the
    depth and the box that holds every change from ``static``."""
    subs: list[np.ndarray] = []
    union: tuple[int, int, int, int] | None = None
    scratch = np.zeros(static.shape, np.uint8)
    for k in range(_SUB_EXPOSURES):
        zk = static.copy()
        prims, _ = assemble_scene(script, surf, t + span_s * (k / (_SUB_EXPOSURES - 1) - 0.5))
        if R is not None:
            prims = [p.rotated(R) for p in prims]
        bk = render_primitives(rays, prims, zk, scratch)
        if bk is not None:
            union = bk if union is None else (min(union[0], bk[0]), min(union[1], bk[1]),
                                               max(union[2], bk[2]), max(union[3], bk[3]))
        subs.append(zk)
    if union is None:
        return subs[0], None
    return exposure_mix(subs, union), union


def assemble_scene(script: Script, surf: Surface, t: float
                   ) -> tuple[list[Primitive], list[tuple[int, str, Any]]]:
    """The scene at time ``t`` s on surface ``surf``: its primitives (hands and props) and its
    fingertips as (hand index, finger, Tip). Pure; every renderer poses these for its camera."""
    prims: list[Primitive] = []
    tips: list[tuple[int, str, Any]] = []
    for k, hand in enumerate(script.hands):
        pose = hand.pose(t)
        if pose is None:
            continue
        fingers, yaw, pitch = pose
        p, hand_tips = build_hand(hand.shape, fingers, yaw, pitch, surf, 10 * (k + 1))
        prims += p
        tips += [(k, tip.finger, tip) for tip in hand_tips]
    for prop in script.props:
        prims += prop.build(t)
    return prims, tips


def _truth_items(tips: list[tuple[int, str, Any]], R: np.ndarray, rays: Rays,
                 labels: np.ndarray) -> list[tuple[int, str, str, dict[str, Any]]]:
    out: list[tuple[int, str, str, dict[str, Any]]] = []
    for hand, finger, tip in tips:
        if tip.gap_mm > HOVER_MAX_MM:
            continue
        p = R @ tip.point_mm
        if p[2] <= 0:
            continue
        x, y = rays.project(p)[0]
        if not (0.0 <= x <= rays.w - 1 and 0.0 <= y <= rays.h - 1):
            continue
        rec: dict[str, Any] = {"x": round(float(x), 3), "y": round(float(y), 3),
                               "X": round(float(p[0]), 3), "Y": round(float(p[1]), 3),
                               "Z": round(float(p[2]), 3)}
        if tip.gap_mm <= 1e-6:
            nrm = R @ tip.normal
            rec.update({"nx": round(float(nrm[0]), 6), "ny": round(float(nrm[1]), 6),
                        "nz": round(float(nrm[2]), 6)})
            kind = "contact"
        else:
            rec["height_mm"] = round(float(tip.gap_mm), 3)
            kind = "hover"
        seen = int(labels[int(round(y)), int(round(x))])
        rec.update({"hand": hand, "finger": finger, "occluded": seen != tip.label})
        out.append((hand, finger, kind, rec))
    return out


def _truth_doc(scene: str, seed: int, camera: str, rays: Rays, fps: float, surf: Surface,
               distance_m: float, tilt_deg: float, script: Script, truth: _TruthBuilder,
               empty_frames: int) -> dict[str, Any]:
    surface: dict[str, Any] = {
        "kind": surf.kind, "distance_m": float(distance_m), "tilt_deg": float(tilt_deg),
        "origin_mm": surf.origin_mm.round(6).tolist(), "u": surf.u.round(9).tolist(),
        "v": surf.v.round(9).tolist(), "normal": surf.n.round(9).tolist(),
    }
    if surf.kind != "plane":
        surface["radius_mm"] = surf.radius_mm
        surface["axis_point_mm"] = surf.axis_point_mm.round(6).tolist()
    events = [{"kind": kind, "frame": _frame_of(t, fps), "t": round(t, 6)}
              for kind, t in script.events]
    doc: dict[str, Any] = {
        "format": TRUTH_FORMAT,
        "scene": scene,
        "seed": int(seed),
        "camera": {"profile": camera, "resolution_wh": [rays.w, rays.h],
                   "K": rays.K.tolist(), "depth_scale": 0.001, "fps": float(fps)},
        "surface": surface,
        "empty_frames": int(empty_frames),
        "frames": truth.frames,
        "events": sorted(events, key=lambda e: e["frame"]),
        "hands": [{"side": "right" if hnd.shape.side > 0 else "left",
                   "finger_radius_mm": round(hnd.shape.finger_radius_mm, 3),
                   "fingers": list(hnd.fingers),
                   **({} if hnd.shape.anatomy is None else {"model": "anatomic"})}
                  for hnd in script.hands],
    }
    if script.bump_s is not None:
        doc["bump"] = {"frame": _frame_of(script.bump_s, fps),
                       "rotation_deg_xyz": list(script.bump_deg_xyz)}
    return doc


# --- files ----------------------------------------------------------------------------------------
def write_truth(path: str | Path, doc: dict[str, Any]) -> None:
    """Write a truth document as compact JSON, atomically (SourceError naming the fix)."""
    write_text_atomic(path, json.dumps(doc, separators=(",", ":")), what="the truth",
                      error=SourceError)


def write_recording(rec: SimRecording, out: str | Path, truth_path: str | Path) -> None:
    """Write the depth as ``.npz`` (when ``out`` ends in .npz) or a PNG folder, and the truth JSON.

    Both targets are checked first; each write is atomic (temporary file or folder renamed into
    place), and the truth is written last.
    """
    from ..sources import write_npz, write_png_folder

    out_p, truth_p = Path(out), Path(truth_path)
    if out_p.resolve() == truth_p.resolve():
        raise SourceError(f"{out_p}: recording and truth need different paths; name them apart")
    if truth_p.suffix.lower() != ".json":
        raise SourceError(f"{truth_p}: the truth file must end in .json; e.g. taps.truth.json")
    is_npz = out_p.suffix.lower() == ".npz"
    if out_p.suffix and not is_npz:
        raise SourceError(
            f"{out_p}: unknown recording type {out_p.suffix!r}; give FILE.npz or a folder name"
        )
    # check both targets before writing anything, so that a failure leaves nothing behind
    for p in (out_p, truth_p):
        parent = p.parent if str(p.parent) else Path(".")
        if not parent.is_dir():
            raise SourceError(f"{p}: folder {parent} does not exist; create it first")
    if not is_npz and out_p.exists() and (not out_p.is_dir() or any(out_p.iterdir())):
        raise SourceError(f"{out_p}: exists and is not an empty folder; choose a new folder")
    if is_npz:
        write_npz(out_p, rec.depth, rec.timestamps_s, rec.depth_scale_m, rec.K)
    else:
        write_png_folder(out_p, rec.depth, rec.timestamps_s, rec.depth_scale_m, rec.K, rec.fps)
    write_truth(truth_p, rec.truth)  # last: a truth file means the pair is complete


def _need(cond: bool, where: str, what: str) -> None:
    if not cond:
        raise SourceError(f"{where}: {what}; see docs/simulator.md (truth format)")


def _is_num(v: object) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def load_truth(path: str | Path) -> dict[str, Any]:
    """Read and validate a truth file; SourceError with a one-line reason otherwise."""
    p = Path(path)
    if not p.is_file():
        raise SourceError(f"{p}: no such truth file; check the path")
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise SourceError(f"{p}: not valid JSON ({e}); regenerate it with depthtouch sim") from e
    except RecursionError:
        raise SourceError(f"{p}: JSON nested too deeply; regenerate it with depthtouch sim") from None
    where = str(p)
    _need(isinstance(doc, dict), where, "must be a JSON object")
    _need(doc.get("format") == TRUTH_FORMAT, where,
          f"format is {doc.get('format')!r}, expected {TRUTH_FORMAT!r}")
    for key in ("scene", "seed", "camera", "surface", "empty_frames", "frames", "events"):
        _need(key in doc, where, f"missing key {key!r}")
    cam = doc["camera"]
    _need(isinstance(cam, dict) and {"profile", "resolution_wh", "K", "fps"} <= set(cam), where,
          "camera needs profile, resolution_wh, K and fps")
    K = np.asarray(cam["K"], dtype=object)
    _need(K.shape == (3, 3) and all(_is_num(v) for v in K.ravel()), where,
          "camera.K must be a 3x3 matrix of numbers")
    _need(isinstance(doc["surface"], dict) and "kind" in doc["surface"], where,
          "surface needs a kind")
    _need(isinstance(doc["empty_frames"], int) and doc["empty_frames"] >= 0, where,
          "empty_frames must be an integer >= 0")
    _need(isinstance(doc["frames"], list), where, "frames must be a list")
    for i, fr in enumerate(doc["frames"]):
        _need(isinstance(fr, dict) and fr.get("frame") == i and _is_num(fr.get("t")), where,
              f"frames[{i}] needs frame = {i} and a time t")
        for kind, keys in (("contacts", ("id", "x", "y", "X", "Y", "Z", "nx", "ny", "nz")),
                           ("hovers", ("id", "x", "y", "X", "Y", "Z", "height_mm"))):
            items = fr.get(kind)
            _need(isinstance(items, list), where, f"frames[{i}].{kind} must be a list")
            for item in items:
                _need(isinstance(item, dict) and all(_is_num(item.get(k)) for k in keys), where,
                      f"frames[{i}].{kind} entries need numbers {', '.join(keys)}")
    _need(isinstance(doc["events"], list)
          and all(isinstance(e, dict) and "kind" in e and isinstance(e.get("frame"), int)
                  for e in doc["events"]), where, "events must be a list of {kind, frame}")
    return dict(doc)


def finger_label(hand: int, finger: str) -> int:
    """The label value of ``finger`` of hand ``hand`` (0-based) in :attr:`SimRecording.labels`."""
    return 10 * (hand + 1) + FINGERS.index(finger)
