"""A depth frame that moves as a whole: frame-global offsets ("breathing") of a depth camera.

Besides each pixel's own noise, a depth camera's whole frame moves from frame to frame: a
RealSense's laser projector and its calibration follow the temperature, and users report all
depths of a still scene jumping together by a few millimetres and staying there for a hundred
frames or more before they come back ("a trimodal distribution", nearer objects moving less:
librealsense issue 3116), or a flat wall that "breathes" and waves (issues 7919, 9150). A
time-of-flight camera's phase offset wanders in the same way. Every other part of the
simulator gives each pixel its own noise only, and the drift scene moves the surface slowly;
:func:`breathe` adds what moves the whole frame at once, after rendering, so the hands, the
scene and each pixel's noise stay exactly as they were.

The offset of frame ``i`` at the surface's distance on the optical axis, in mm (positive: the
frame reads farther), is the sum of

- a wobble: a first-order autoregressive process with a time constant of :data:`WOBBLE_TAU_S`
  and a standard deviation of half the scale;
- jumps: at a rate of :data:`JUMP_RATE_HZ`, the whole frame steps by 1-2 times the scale
  (either sign) and stays there for 0.5-3 s, then steps back.

A disparity camera (stereo, structured light) gets the offset as a disparity: a pixel at depth
z moves by the offset times (z / distance)^2; a time-of-flight camera by the offset itself.
Missing pixels stay missing. The draws come from a stream of their own (the seed's). The
truth document gets ``breathing_mm`` (the scale) and, per frame, ``global_offset_mm`` (the
offset at the surface's distance), both optional keys.
"""

from __future__ import annotations

import copy
import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ConfigError

if TYPE_CHECKING:
    from .render import SimRecording

#: the largest scale, mm (a camera whose frame jumps by 2 cm is broken, not breathing)
SCALE_MAX_MM = 10.0
#: the wobble's time constant, s
WOBBLE_TAU_S = 0.5
#: jumps per second, on average
JUMP_RATE_HZ = 0.2
#: how long a jump stays, s (uniform)
JUMP_STAY_S = (0.5, 3.0)
#: a jump's size in units of the scale (uniform, either sign)
JUMP_SIZE = (1.0, 2.0)
# the draws' own stream (drops.py uses 0xD0)
_STREAM = 0xB7


def check_breathing(scale_mm: object) -> float:
    """``scale_mm`` as a float in [0, :data:`SCALE_MAX_MM`], or ConfigError naming the range."""
    if isinstance(scale_mm, bool) or not isinstance(scale_mm, (int, float)) \
            or not 0.0 <= float(scale_mm) <= SCALE_MAX_MM:
        raise ConfigError(f"breathing {scale_mm!r} mm is out of range; allowed "
                          f"[0, {SCALE_MAX_MM:g}] mm (the scale of the frame-global offsets)")
    return float(scale_mm)


def offsets_mm(n: int, fps: float, scale_mm: float, seed: int) -> np.ndarray:
    """The frame-global offset of each of ``n`` frames at the surface's distance, mm (float64
    (n,); pure, seeded; see the module doc)."""
    scale_mm = check_breathing(scale_mm)
    out = np.zeros(n, np.float64)
    if scale_mm == 0.0 or n == 0:
        return out
    rng = np.random.default_rng([int(seed), _STREAM])
    dt = 1.0 / float(fps)
    rho = math.exp(-dt / WOBBLE_TAU_S)
    sd = 0.5 * scale_mm
    w = rng.normal(0.0, sd, n)
    innov = rng.normal(0.0, sd * math.sqrt(1.0 - rho * rho), n)
    u_start = rng.random(n)
    stay = rng.uniform(*JUMP_STAY_S, n)
    size = rng.uniform(*JUMP_SIZE, n) * np.where(rng.random(n) < 0.5, -1.0, 1.0)
    wobble = w[0]
    level, until = 0.0, -1.0
    p_jump = 1.0 - math.exp(-JUMP_RATE_HZ * dt)
    for i in range(n):  # a chain over frames, not pixels: a few hundred steps
        t = i * dt
        if i:
            wobble = rho * wobble + innov[i]
        if level != 0.0 and t >= until:
            level = 0.0
        elif level == 0.0 and u_start[i] < p_jump:
            level, until = size[i] * scale_mm, t + stay[i]
        out[i] = wobble + level
    return out


def breathe(rec: SimRecording, scale_mm: float, seed: int, kind: str, distance_m: float
            ) -> SimRecording:
    """``rec`` with every frame offset as a whole (see the module doc); ``rec`` itself is not
    changed. ``kind``: the camera profile's ("tof", "stereo", "structured-light"); scale 0
    returns ``rec`` as it is."""
    scale_mm = check_breathing(scale_mm)
    if scale_mm == 0.0:
        return rec
    n = int(rec.depth.shape[0])
    fps = float(rec.truth["camera"]["fps"])
    off = offsets_mm(n, fps, scale_mm, seed)
    unit_mm = float(rec.depth_scale_m) * 1000.0
    z_ref = float(distance_m) * 1000.0
    disparity = kind != "tof"
    depth = np.empty_like(rec.depth)
    for i in range(n):  # one array step per frame
        z = rec.depth[i].astype(np.float32) * np.float32(unit_mm)
        move = np.float32(off[i]) * (z / np.float32(z_ref)) ** 2 if disparity \
            else np.float32(off[i])
        moved = np.rint((z + move) / np.float32(unit_mm))
        depth[i] = np.where(rec.depth[i] > 0, np.clip(moved, 1, 65535), 0).astype(np.uint16)
    doc = copy.deepcopy(rec.truth)
    doc["breathing_mm"] = scale_mm
    for fr in doc["frames"]:
        k = int(fr["frame"])
        if 0 <= k < n:
            fr["global_offset_mm"] = round(float(off[k]), 3)
    return replace(rec, depth=depth, truth=doc)
