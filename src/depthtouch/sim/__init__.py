"""Depth-scene simulator: surfaces, an articulated hand and arm, camera noise, ground truth.

Render a scene to a recording with per-frame ground truth::

    from depthtouch.sim import render_scene, write_recording
    rec = render_scene("taps", camera="kinect-v2", distance_m=1.2, tilt_deg=10, seed=3)
    write_recording(rec, "taps.npz", "taps.truth.json")

See docs/simulator.md for the camera profiles, the scenes and the truth format.
"""

from __future__ import annotations

from .cameras import CAMERAS, HARD_CAMERAS, PROFILES, CameraProfile, get_profile
from .geometry import SURFACES
from .hardscenes import HARD_SCENES
from .render import PITCH_RANGE_DEG, SimRecording, finger_label, load_truth, render_scene, write_recording
from .scenes import GESTURE_SCENES, MULTIVIEW_SCENES, SCENES

#: Every scene name the simulator renders (the default suite's "all" is :data:`SCENES` alone).
ALL_SCENES: tuple[str, ...] = SCENES + GESTURE_SCENES + MULTIVIEW_SCENES + HARD_SCENES

__all__ = [
    "ALL_SCENES",
    "GESTURE_SCENES",
    "CAMERAS",
    "HARD_CAMERAS",
    "HARD_SCENES",
    "MULTIVIEW_SCENES",
    "PITCH_RANGE_DEG",
    "PROFILES",
    "SCENES",
    "SURFACES",
    "CameraProfile",
    "SimRecording",
    "finger_label",
    "get_profile",
    "load_truth",
    "render_scene",
    "write_recording",
]
