"""The surface as the sensor knows it now: the one owner of the learned and adapted surface.

:class:`Surface` learns the empty surface (through a :class:`~.gate.LearningGate` on a live
camera), turns it into the band bounds the touch stage reads, keeps it current with the
:class:`~.adapt.SurfaceAdapter` (objects put down become surface, drift is followed, a camera bump
makes it learn again), answers heights and X/Y/Z, and saves what it knows *now*: after a box was
absorbed, the saved surface has the box in it.
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path
from typing import Literal

import numpy as np

from ..config import PipelineConfig
from ..errors import SurfaceError
from ..types import Frame
from .adapt import SurfaceAdapter
from .bounds import TIP_TOP_MM, BandBounds, band_bounds, height_mm, noisy_share
from .gate import LearningGate
from .level import Leveller, extreme_offset_mm, frame_offset, reference_stats
from .model import SurfaceLearner, SurfaceModel

log = logging.getLogger(__name__)

#: warn when Tl reaches a touching fingertip's height (TIP_TOP_MM) on this share of the surface
#: or more. Measured on the hard suite's tune halves (hard, hard-fresh3; 75 recordings): the
#: three stereo recordings at 1.6 m have 0.59-0.93 of their surface there and find 2 of 12
#: contacts; every other one has at most 0.47 there and finds 253 of 261.
NOISY_WARN_SHARE = 0.5


class Surface:
    """Learns, adapts, answers and saves the surface.

    config: the pipeline settings (surface, regions, adapt and the fingertip radius are read).
    model: a saved surface to start from; when None it is learned from the first frames.
    learn_frames: learn from this many frames (overrides the config's seconds).
    gate: decides which frames a live camera learns from (None: every frame, for recordings).
    """

    def __init__(
        self,
        config: PipelineConfig,
        model: SurfaceModel | None = None,
        *,
        learn_frames: int | None = None,
        gate: LearningGate | None = None,
    ) -> None:
        self.config = config
        self.gate = gate
        self._learn_frames = learn_frames
        self._learner = SurfaceLearner(config.surface, learn_frames)
        self._learned: SurfaceModel | None = None
        self._bounds: BandBounds | None = None
        self._adapter: SurfaceAdapter | None = None
        lim = config.surface.level_limit_mm
        self._leveller = (Leveller(lim, config.surface.level_engage_mm) if lim > 0
                          else None)
        self.relearns = 0
        if model is not None:
            self.use(model)

    # --- what it knows ---------------------------------------------------------------------
    @property
    def learning(self) -> bool:
        return self._bounds is None

    @property
    def learn_progress(self) -> float:
        """Share of the learning done, in [0, 1] (1 once learned)."""
        return 1.0 if self._bounds is not None else self._learner.progress

    @property
    def note(self) -> str:
        """A line for a person while learning, else ""."""
        if self._bounds is not None:
            return ""
        if self.gate is not None and self.gate.note:
            if self.gate.phase == "learning" and self._learner.progress > 0:
                return f"learning the surface {100 * self._learner.progress:.0f}%: keep it clear"
            return self.gate.note
        return "learning the surface: keep it clear"

    @property
    def bounds(self) -> BandBounds:
        """The band bounds of the current surface (read by the touch stage)."""
        if self._bounds is None:
            raise SurfaceError("the surface is still being learned")
        return self._bounds

    @property
    def resolution_wh(self) -> tuple[int, int] | None:
        if self._learned is None:
            return None
        return self._learned.resolution_wh

    @property
    def mm_per_px(self) -> float | None:
        """Typical size of a pixel on the surface in mm; None without intrinsics."""
        if self._learned is None or self._learned.K is None:
            return None
        return self._bounds.mm_per_px if self._bounds is not None else None

    @property
    def adapter(self) -> SurfaceAdapter | None:
        """The adapter keeping the surface current (None while learning or when switched off);
        read it, never change it."""
        return self._adapter

    @property
    def absorbed_px(self) -> int:
        """Pixels that became surface since it was learned (objects put down or taken away)."""
        return self._adapter.absorbed_px if self._adapter is not None else 0

    def model(self) -> SurfaceModel:
        """The surface as it is now (adapted), as a model that can be saved and used again.

        The adapted depth replaces the chosen statistic; the other statistics move with it by
        the same amount per pixel, so that a model loaded with another statistic also has the
        absorbed objects.
        """
        learned, b = self._learned, self._bounds
        if learned is None or b is None:
            raise SurfaceError("no surface learned yet; let the sensor see the empty surface first")
        now = np.where(learned.valid, b.surface_mm, 0).astype(np.float32)
        delta = (now - learned.depth_mm).astype(np.float32)
        if not delta.any():
            return learned
        return SurfaceModel(
            now, learned.mean_mm + delta, learned.mode_mm + delta, learned.median_mm + delta,
            learned.sigma_mm, learned.valid, learned.statistic, learned.depth_scale_m,
            learned.K, learned.n_frames,
        )

    def save(self, path: str | Path) -> Path:
        """Write the surface as it is now (see :meth:`model`) to an ``.npz`` file atomically."""
        return self.model().save(path)

    def height_map_mm(self, depth: np.ndarray) -> np.ndarray:
        """Height above the surface in mm, float32 (H, W), NaN where unknown (for views)."""
        b = self._bounds
        if b is None or depth.shape != b.valid.shape:
            return np.full(depth.shape, np.nan, np.float32)
        return height_mm(depth, b)

    def xyz_mm(self, xy_px: list[tuple[float, float]]) -> list[tuple[float, float, float] | None]:
        """Camera coordinates (X, Y, Z in mm) of image points on the surface as it is now; None
        for a point without intrinsics or surface depth there. Nearest pixel, clamped."""
        learned, b = self._learned, self._bounds
        if learned is None or b is None or learned.K is None:
            return [None] * len(xy_px)
        # a handful of touches: plain floats cost less than array calls here
        (fx, _, cx), (_, fy, cy), _ = learned.K.tolist()
        dm = b.surface_mm  # as it is now: 0 where unusable, as learned
        w1, h1 = dm.shape[1] - 1, dm.shape[0] - 1
        at = dm.item
        out: list[tuple[float, float, float] | None] = []
        for x, y in xy_px:
            ix, iy = round(x), round(y)
            ix = 0 if ix < 0 else (w1 if ix > w1 else ix)
            iy = 0 if iy < 0 else (h1 if iy > h1 else iy)
            z = float(at(iy, ix))
            out.append(((x - cx) * z / fx, (y - cy) * z / fy, z) if z > 0 else None)
        return out

    # --- changing it -----------------------------------------------------------------------
    def use(self, model: SurfaceModel) -> None:
        """Use this surface from now on (learning ends)."""
        if self.config.surface.statistic != model.statistic:
            model = model.with_statistic(self.config.surface.statistic)
        self._learned = model
        self._bounds = band_bounds(model, self.config.regions, self.config.touchpoints.tip_radius_mm)
        self._warn_if_noisy(self._bounds)
        self._adapter = (SurfaceAdapter(self.config.adapt, self._bounds)
                         if self.config.adapt.enabled else None)
        if self._leveller is not None:
            self._leveller.use_reference(self._bounds.surface_mm)

    def _warn_if_noisy(self, bounds: BandBounds) -> None:
        """One warning when the surface is too noisy on most of it for a touch to stand out."""
        if self.config.regions.tl_floor_mm >= TIP_TOP_MM:
            return  # Tl was set that high on purpose, not by the noise
        share = noisy_share(bounds)
        if share < NOISY_WARN_SHARE:
            return
        tl = float(np.median(bounds.tl_mm[bounds.valid]))
        log.warning(
            "the depth is too noisy for touches on %.0f%% of the surface: Tl (%g sigma of its "
            "noise) is %g mm or more there (median %.1f mm), above a touching fingertip's "
            "12-16 mm, so touches there will be missed; mount the camera closer to the surface "
            "(stereo noise grows with the square of the distance) or use a less noisy camera",
            100.0 * share, self.config.regions.noise_k, TIP_TOP_MM, tl)

    def learn(self, frame: Frame) -> bool:
        """Give a frame (pre-filtered) to the learner; True when the surface was just learned.

        SurfaceError when the frames cannot make a surface (e.g. their size changed)."""
        if self.gate is not None:
            verdict = self.gate.update(frame)
            if verdict == "restart":
                self._learner.reset()
                if self._leveller is not None:
                    self._leveller.reset()
                return False
            if verdict == "skip":
                return False
        if self._leveller is not None:
            frame = dataclasses.replace(
                frame, depth=self._leveller.update(frame.depth, frame.depth_scale_m * 1000.0,
                                                   frame.timestamp_s))
        model = self._learner.update(frame)
        if model is None:
            return False
        if self._learner.masked:
            log.info("frame %d: something moved in the surface's learning frames after the first "
                     "%g s; %d samples of it were left out (surface.learn_min_s)", frame.index,
                     self.config.surface.learn_min_s, self._learner.masked)
        self.use(model)
        return True

    def level(self, frame: Frame) -> Frame:
        """The frame (pre-filtered) with its offset as a whole from the surface taken off
        (``surface.level_limit_mm``; :mod:`.level`), before :meth:`follow` and the band see it;
        the frame itself when levelling is off or nothing moved."""
        lev = self._leveller
        if lev is None or self._bounds is None:
            return frame
        depth = lev.update(frame.depth, frame.depth_scale_m * 1000.0, frame.timestamp_s)
        return frame if depth is frame.depth else dataclasses.replace(frame, depth=depth)

    def offset_as_a_whole(self, frame: Frame, limit_mm: float = 50.0) -> float | None:
        """How far (mm, the largest over the surface) the frame lies from the surface as a
        whole (:func:`.level.frame_offset`, a shift and a part growing with the depth squared),
        or None when it cannot be measured (too much covered, or farther than ``limit_mm``).
        A read-only question, for a message when the surface changed at once."""
        if self._bounds is None:
            return None
        ref = self._bounds.surface_mm
        to_mm = frame.depth_scale_m * 1000.0
        med, q_range = reference_stats(ref)
        off = frame_offset(frame.depth, ref, to_mm, limit_mm=limit_mm, ref_median_mm=med)
        return None if off is None else extreme_offset_mm(off, q_range)

    @property
    def level_offset_mm(self) -> tuple[float, float]:
        """The last frame's offset as a whole (a, b) mm (see :mod:`.level`); (0, 0) when
        levelling is off."""
        return self._leveller.offset_mm if self._leveller is not None else (0.0, 0.0)

    def follow(self, frame: Frame, keep_xy_px: np.ndarray
               ) -> Literal["ok", "disturbed", "bump"]:
        """Adapt to a frame (pre-filtered) of the running sensor.

        keep_xy_px: (N, 2) image points whose surroundings must not be absorbed (active touches).
        Returns "disturbed" while most of the surface differs at once (touches are not to be
        trusted) and "bump" when the camera moved and the scene settled: the caller ends the
        touches, then calls :meth:`relearn`.
        """
        adapter = self._adapter
        if adapter is None:
            return "ok"
        adapter.update(frame.depth, frame.timestamp_s, keep_xy_px)
        verdict = adapter.check(frame.depth, frame.timestamp_s)
        if verdict == "bump":
            return "bump"
        return "disturbed" if verdict == "disturbed" else "ok"

    def relearn(self) -> None:
        """Learn the surface again (the camera moved), for ``surface.relearn_s`` seconds."""
        cfg = dataclasses.replace(self.config.surface, learn_s=self.config.surface.relearn_s,
                                  learn_frames=None)
        self._forget(SurfaceLearner(cfg))
        self.relearns += 1

    def reset(self) -> None:
        """Forget the surface and learn it again from the next frames."""
        self._forget(SurfaceLearner(self.config.surface, self._learn_frames))

    def restart_learning(self) -> None:
        """A stream ended while learning: the frames collected so far are not used."""
        if self._bounds is None:
            self._learner.reset()
            if self._leveller is not None:
                self._leveller.reset()
            if self.gate is not None:
                self.gate.reset()

    def _forget(self, learner: SurfaceLearner) -> None:
        self._learned, self._bounds, self._adapter = None, None, None
        self._learner = learner
        if self._leveller is not None:
            self._leveller.reset()
        if self.gate is not None:
            self.gate.reset()
