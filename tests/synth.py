"""Seeded synthetic depth frames for the unit tests: a plane seen from above, finger-shaped
capsules with rounded tips (touching or hovering), a hand block above each finger, noise and
missing pixels. Orthographic heights on a fronto-parallel plane: simple and exact enough to know
where each fingertip touches. (The full simulator with camera models lives in depthtouch.sim.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from depthtouch.sources import write_npz

K_640 = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])


@dataclass(frozen=True)
class Finger:
    """A finger whose tip contact (or hover) point is at image (x, y) px; direction toward the
    hand in degrees (0 = hand to the right of the tip); gap_mm = 0 touches."""

    x: float
    y: float
    direction_deg: float = 90.0
    gap_mm: float = 0.0
    radius_mm: float = 7.5
    pitch_deg: float = 35.0
    length_mm: float = 70.0
    arm: bool = True  # an arm from the hand out of the view (people enter from outside)


def render_heights(shape: tuple[int, int], fingers: list[Finger], mm_per_px: float) -> np.ndarray:
    """Height above the plane (mm, float32) of the fingers and their hands."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    out = np.zeros(shape, np.float32)
    for f in fingers:
        th = np.deg2rad(f.direction_deg)
        d = np.array([np.cos(th), np.sin(th)], np.float32)  # from tip toward the hand
        r = f.radius_mm
        px = (xx - f.x) * mm_per_px
        py = (yy - f.y) * mm_per_px
        t = px * d[0] + py * d[1]  # along the finger (mm, on the plane)
        lat = -px * d[1] + py * d[0]
        pitch = np.deg2rad(f.pitch_deg)
        horiz = f.length_mm * np.cos(pitch)
        # capsule axis from the tip-sphere centre (height r + gap) rising toward the hand
        tc = np.clip(t / np.cos(pitch) / f.length_mm, 0, 1) * horiz
        axis_h = r + f.gap_mm + tc * np.tan(pitch)
        dist2 = (t - tc) ** 2 + lat**2
        inside = dist2 < r * r
        hh = np.where(inside, axis_h + np.sqrt(np.maximum(r * r - dist2, 0)), 0)
        # the hand: a block above the end of the finger
        hand = (t > horiz) & (t < horiz + 80) & (np.abs(lat) < 45)
        hand_h = r + f.gap_mm + horiz * np.tan(pitch) + 20
        hh = np.where(hand, np.maximum(hh, hand_h), hh)
        if f.arm:
            arm = (t >= horiz + 80) & (np.abs(lat) < 35)
            hh = np.where(arm, np.maximum(hh, hand_h + 40 + (t - horiz - 80) * 0.3), hh)
        out = np.maximum(out, hh.astype(np.float32))
    return out


def make_recording(
    n_empty: int = 45,
    script: list[list[Finger]] | None = None,
    *,
    shape: tuple[int, int] = (480, 640),
    plane_mm: float = 1000.0,
    noise_mm: float = 1.5,
    dropout: float = 0.01,
    seed: int = 0,
    fps: float = 30.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Depth (N, H, W) uint16 mm and timestamps: n_empty empty frames, then one per script entry."""
    rng = np.random.default_rng(seed)
    script = script or []
    mm_per_px = plane_mm / K_640[0, 0]
    frames = []
    for i in range(n_empty + len(script)):
        fingers = script[i - n_empty] if i >= n_empty else []
        hgt = render_heights(shape, fingers, mm_per_px) if fingers else np.zeros(shape, np.float32)
        d = plane_mm - hgt + rng.normal(0, noise_mm, shape)
        d[rng.random(shape) < dropout] = 0
        frames.append(np.clip(np.rint(d), 0, 65535).astype(np.uint16))
    ts = np.arange(len(frames)) / fps
    return np.stack(frames), ts


def write_recording(path, depth, ts):  # type: ignore[no-untyped-def]
    return write_npz(path, depth, ts, 0.001, K_640)


def result_of(frame, events):  # type: ignore[no-untyped-def]
    """The pipeline's result for a frame with these events (for driving sinks in tests)."""
    from depthtouch.types import FrameResult, TouchPoints

    return FrameResult(frame, list(events), TouchPoints.empty(), "ok", {"total": 0.25})
