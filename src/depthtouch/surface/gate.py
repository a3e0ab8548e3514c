"""The learning gate: which frames a live camera's surface is learned from.

A person sets the camera up and walks away; the surface must be learned from an empty, still
scene. Before learning, the scene must stay still for a countdown (frame time); motion during the
countdown restarts it, motion during learning throws the collected frames away and restarts the
countdown. A fast camera (90 Hz) gives the learner at most ``learn_max_hz`` frames a second: more
frames would only lengthen the pause while the surface is computed. Recordings need no gate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

from ..types import Frame

GatePhase = Literal["waiting", "learning"]


@dataclass(frozen=True)
class GateConfig:
    """Settings of the learning gate.

    countdown_s: seconds the scene must stay still before the surface is learned (default 3.0,
        range [0, 60]; frame time). 0 learns from the first frame on, without motion checks.
    motion_threshold_mm: a pixel moved when its depth changed by more than this against the
        reference frame (default 15 mm, range (0, 500]; D435 noise is ~4 mm RMS at 1 m).
    motion_fraction: the scene moves when more than this share of valid pixels moved
        (default 0.01, range (0, 1]).
    learn_max_hz: the surface is learned from at most this many frames per second (default 30,
        range (0, 1000]).
    """

    countdown_s: float = 3.0
    motion_threshold_mm: float = 15.0
    motion_fraction: float = 0.01
    learn_max_hz: float = 30.0

    def __post_init__(self) -> None:
        from ..checks import check_range

        check_range("live.countdown_s", self.countdown_s, 0.0, 60.0)
        check_range("live.motion_threshold_mm", self.motion_threshold_mm, 0.0, 500.0,
                    lo_open=True)
        check_range("live.motion_fraction", self.motion_fraction, 0.0, 1.0, lo_open=True)
        check_range("live.learn_max_hz", self.learn_max_hz, 0.0, 1000.0, lo_open=True)


def motion_fraction(
    reference: np.ndarray, depth: np.ndarray, depth_scale_m: float, threshold_mm: float,
    step_px: int = 2,
) -> float:
    """Share of pixels (valid in both frames) whose depth changed by more than ``threshold_mm``.

    reference, depth: uint16 (H, W) in units of ``depth_scale_m`` metres; 0 = no data.
    step_px: sample every step-th row and column (default 2; motion is never one pixel wide).
    Returns a value in [0, 1]; 0 when no pixel is valid in both.
    """
    if reference.shape != depth.shape:
        return 1.0  # another resolution: certainly not the same scene
    a = reference[::step_px, ::step_px]
    b = depth[::step_px, ::step_px]
    valid = (a > 0) & (b > 0)
    n = int(np.count_nonzero(valid))
    if n == 0:
        return 0.0
    diff = cv2.absdiff(a, b)
    units = threshold_mm / (depth_scale_m * 1000.0)
    moved = np.count_nonzero((diff > units) & valid)
    return float(moved) / n


class StillnessGate:
    """Tells how long (frame time) the scene has been still against a reference frame.

    A frame that differs from the reference by more than the thresholds (see
    :func:`motion_fraction`) becomes the new reference and restarts the still time.
    """

    def __init__(self, threshold_mm: float = 15.0, max_fraction: float = 0.01) -> None:
        self.threshold_mm = threshold_mm
        self.max_fraction = max_fraction
        self.reset()

    def reset(self) -> None:
        self._ref: np.ndarray | None = None
        self._since_s = 0.0
        self.last_motion_s: float | None = None
        self.last_fraction = 0.0
        self.moved = False

    def update(self, frame: Frame) -> float:
        """Seconds the scene has been still up to this frame (0 on the first or a moving one);
        ``moved`` tells whether this frame moved against the reference."""
        self.moved = False
        if self._ref is None:
            self._ref, self._since_s = frame.depth, frame.timestamp_s
            return 0.0
        f = motion_fraction(self._ref, frame.depth, frame.depth_scale_m, self.threshold_mm)
        self.last_fraction = f
        self.moved = f > self.max_fraction
        if self.moved:
            self._ref, self._since_s = frame.depth, frame.timestamp_s
            self.last_motion_s = frame.timestamp_s
            return 0.0
        return frame.timestamp_s - self._since_s


class LearningGate:
    """Decides, frame by frame, whether a frame goes to the surface learner.

    :meth:`update` returns ``"learn"`` (give it to the learner), ``"skip"`` (not now) or
    ``"restart"`` (something moved while learning: throw the collected frames away). ``phase``
    and ``note`` describe the state for a person; ``restarts`` counts the restarts.
    """

    def __init__(self, config: GateConfig | None = None) -> None:
        self.config = config or GateConfig()
        self._still = StillnessGate(self.config.motion_threshold_mm, self.config.motion_fraction)
        self.restarts = 0
        self.reset()

    def reset(self) -> None:
        """Start again with the countdown (a new stream, or the surface is learned again)."""
        self._still.reset()
        self.phase: GatePhase = "waiting" if self.config.countdown_s > 0 else "learning"
        self.note = ""
        self.countdown_left_s: float | None = self.config.countdown_s or None
        self._last_learn_t: float | None = None

    def update(self, frame: Frame) -> Literal["learn", "skip", "restart"]:
        cfg = self.config
        if self.phase == "waiting":
            left = cfg.countdown_s - self._still.update(frame)
            self.countdown_left_s = max(left, 0.0)
            last = self._still.last_motion_s
            moving = last is not None and frame.timestamp_s - last < 0.5
            self.note = ("the scene moves: clear the surface and keep still" if moving else
                         f"keep the surface clear: learning starts in {math.ceil(max(left, 0))} s")
            if left > 0:
                return "skip"
            self.phase, self.countdown_left_s = "learning", None
            self.note = "learning the surface: keep it clear"
            return "skip"  # this frame closed the countdown; learning starts with the next
        if cfg.countdown_s > 0:
            self._still.update(frame)
            if self._still.moved:
                self.restarts += 1  # the moved frame is the new reference of the countdown
                self.phase, self.countdown_left_s = "waiting", cfg.countdown_s
                self.note = "something moved while learning: clear the surface"
                self._last_learn_t = None
                return "restart"
        last_t = self._last_learn_t
        # 5 % slack: a 30 Hz camera's intervals jitter around 1/30 s
        if last_t is not None and frame.timestamp_s - last_t < 0.95 / cfg.learn_max_hz:
            return "skip"
        self._last_learn_t = frame.timestamp_s
        return "learn"
