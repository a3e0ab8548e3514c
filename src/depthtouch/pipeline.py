"""The pipeline: the only place that wires the per-frame stages together.

source frame -> surface (learned from the first frames) -> band masks -> regions -> touch points
-> tracking -> path filter -> calibration -> :class:`TouchEvent` list.

``Pipeline(config).process(frame)`` returns the events of that frame (none while the surface is
being learned). Bad frames in a live stream (another size, wrong dtype) are skipped, counted and
warned about once, never raised.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from dataclasses import dataclass, field
from typing import Any, Protocol

import cv2
import numpy as np

from .config import PipelineConfig
from .errors import SourceError, SurfaceError
from .surface.adapt import SurfaceAdapter
from .surface.model import SurfaceLearner, SurfaceModel
from .touch.points import find_touch_points
from .touch.regions import BandBounds, band_bounds, band_regions, height_mm
from .tracking.filters import TouchFilter, make_filter
from .tracking.tracker import Tracker, TrackUpdate
from .types import Frame, TouchEvent, TouchPoints

log = logging.getLogger(__name__)
_warm = False


def _warm_up() -> None:
    """Compile the per-frame kernels once per process, before the first frame (a camera
    stream must not stall seconds on its first touch)."""
    global _warm
    if _warm:
        return
    from . import firstrun
    from .surface import adapt
    from .touch import handmap, regions, runs, tipkernel

    # a cold numba cache (the first run after installing) takes ~20 s: firstrun says so
    firstrun.warm_up((tipkernel.warm_up, handmap.warm_up, regions.warm_up, adapt.warm_up),
                     kernels=(tipkernel.frame_points, runs.parts_of_runs))
    _warm = True


class ScreenMapping(Protocol):
    """What the pipeline needs of a calibration: depth px (N, 2) -> screen px (N, 2)."""

    def to_screen(self, xy_px: np.ndarray) -> np.ndarray: ...


@dataclass
class PipelineStats:
    """Counters of a run."""

    frames: int = 0
    learning_frames: int = 0
    skipped_frames: int = 0
    events: int = 0
    relearns: int = 0
    disturbed_frames: int = 0
    skip_reasons: dict[str, int] = field(default_factory=dict)


class Pipeline:
    """Depth frames in, touch events out.

    config: all stage settings (default :class:`PipelineConfig`).
    surface: a saved surface model; when None it is learned from the first frames.
    calibration: maps depth px to screen px; adds ``sx``, ``sy`` to events when given.
    surface_frames: learn the surface from this many frames (overrides the config's seconds).
    strict: raise on a frame that cannot be used (replaying a file: the file is wrong) instead of
        skipping it with one warning (a live camera: the next frame may be fine).
    """

    def __init__(
        self,
        config: PipelineConfig | None = None,
        *,
        surface: SurfaceModel | None = None,
        calibration: ScreenMapping | None = None,
        surface_frames: int | None = None,
        strict: bool = False,
    ) -> None:
        self.config = (config or PipelineConfig()).validate()
        _warm_up()
        self.strict = strict
        self.calibration = calibration
        self._surface_frames = surface_frames
        self.stats = PipelineStats()
        self.last_timing_ms: dict[str, float] = {}
        self.last_points: TouchPoints = TouchPoints.empty()
        self._warned: set[str] = set()
        self._learner = SurfaceLearner(self.config.surface, surface_frames)
        self._filter: TouchFilter = make_filter(self.config.filter)
        self._tracker = Tracker(self.config.tracking, self.config.touchpoints)
        self.surface: SurfaceModel | None = None
        self._bounds: BandBounds | None = None
        self._adapter: SurfaceAdapter | None = None
        self._last_frame: Frame | None = None
        if surface is not None:
            self.set_surface(surface)

    # --- state -----------------------------------------------------------------------------
    @property
    def learning(self) -> bool:
        return self.surface is None

    @property
    def learn_progress(self) -> float:
        return 1.0 if self.surface is not None else self._learner.progress

    @property
    def active_ids(self) -> list[int]:
        return [t.id for t in self._tracker.tracks if t.active]

    def set_surface(self, surface: SurfaceModel) -> None:
        """Use this surface from the next frame on (active touches continue)."""
        if self.config.surface.statistic != surface.statistic:
            surface = surface.with_statistic(self.config.surface.statistic)
        self.surface = surface
        self._bounds = band_bounds(surface, self.config.regions, self.config.touchpoints.tip_radius_mm)
        self._adapter = (SurfaceAdapter(self.config.adapt, self._bounds)
                         if self.config.adapt.enabled else None)
        self._tracker.scale_mm_per_px = surface.mm_per_px() if surface.K is not None else None

    def reset(self) -> None:
        """Forget the surface and all touches (ids keep increasing)."""
        self.surface = None
        self._bounds = None
        self._adapter = None
        self._learner = SurfaceLearner(self.config.surface, self._surface_frames)
        self._tracker.reset()
        self._filter.reset()

    # --- per frame -------------------------------------------------------------------------
    def _prefilter(self, frame: Frame) -> Frame:
        k = self.config.regions.median_px
        if k <= 1:
            return frame
        return Frame(cv2.medianBlur(frame.depth, k), frame.timestamp_s, frame.index,
                     frame.depth_scale_m, frame.K)

    def process(self, frame: Frame) -> list[TouchEvent]:
        """The touch events of one frame (see the module doc)."""
        self.stats.frames += 1
        if self.surface is None:
            self.stats.learning_frames += 1
            if not self._frame_ok(frame, None):
                return []
            frame = self._prefilter(frame)
            try:
                model = self._learner.update(frame)
            except SurfaceError as e:
                if self.strict:
                    raise
                self._skip("learning", str(e))
                self._learner.reset()
                return []
            if model is not None:
                self.set_surface(model)
            self._last_frame = frame
            return []
        if not self._frame_ok(frame, self.surface):
            return []
        b = self._bounds
        assert b is not None
        t0 = time.perf_counter()
        frame = self._prefilter(frame)
        if self._adapter is not None:
            # keep the surroundings of touches of arms reaching in from the border: a finger held
            # still is never absorbed; a "touch" on something standing on the surface is
            touching = [t.xy_px for t in self._tracker.tracks if t.active and t.hand_at_border]
            self._adapter.update(frame.depth, frame.timestamp_s, np.array(touching))
            verdict = self._adapter.check(frame.depth, frame.timestamp_s)
            if verdict == "bump":
                return self._relearn(frame)
            if verdict == "disturbed":
                # most of the surface changed at once: report no touches until it settles
                self.stats.disturbed_frames += 1
                self.last_points = TouchPoints.empty()
                events = self._events(frame, self._tracker.end_all())
                self.stats.events += len(events)
                self._last_frame = frame
                return events
        ta = time.perf_counter()
        regions = band_regions(frame.depth, b)
        t1 = time.perf_counter()
        points = find_touch_points(frame.depth, regions, b, self.config.touchpoints)
        t2 = time.perf_counter()
        updates = self._tracker.update(points)
        t3 = time.perf_counter()
        events = self._events(frame, updates)
        t4 = time.perf_counter()
        self.last_points = points
        self.last_timing_ms = {
            "prefilter_surface_update": (ta - t0) * 1e3, "regions": (t1 - ta) * 1e3,
            "touchpoints": (t2 - t1) * 1e3,
            "tracking": (t3 - t2) * 1e3, "filter_events": (t4 - t3) * 1e3,
            "total": (t4 - t0) * 1e3,
        }
        self._last_frame = frame
        self.stats.events += len(events)
        return events

    def _relearn(self, frame: Frame) -> list[TouchEvent]:
        log.warning(
            "frame %d: most of the surface changed and stays changed (camera moved?); "
            "learning the surface again, no touches meanwhile", frame.index,
        )
        events = self._events(frame, self._tracker.end_all())
        self._filter.reset()
        self.surface = None
        self._bounds = None
        self._adapter = None
        relearn = dataclasses.replace(self.config.surface, learn_s=self.config.surface.relearn_s,
                                      learn_frames=None)
        self._learner = SurfaceLearner(relearn)
        self.stats.relearns += 1
        self.stats.events += len(events)
        self._last_frame = frame
        return events

    def finish(self) -> list[TouchEvent]:
        """End the active touches at the end of a stream (``up`` on the last frame)."""
        if self._last_frame is None:
            return []
        events = self._events(self._last_frame, self._tracker.end_all())
        self.stats.events += len(events)
        return events

    def height_map_mm(self, frame: Frame) -> np.ndarray:
        """Height above the surface in mm, float32 (H, W), NaN where unknown (for views)."""
        if self._bounds is None or frame.depth.shape != self._bounds.valid.shape:
            return np.full(frame.depth.shape, np.nan, np.float32)
        return height_mm(frame.depth, self._bounds)

    # --- helpers ---------------------------------------------------------------------------
    def _events(self, frame: Frame, updates: list[TrackUpdate]) -> list[TouchEvent]:
        if not updates:
            return []
        # a handful of touches: plain floats cost less than array calls here (same arithmetic)
        scale = self._tracker.scale_mm_per_px or 1.0
        measured = [u.track for u in updates if u.measured]
        filtered: list[list[float]] = []  # mm, in the order of the measured updates
        if measured:
            ids = np.array([t.id for t in measured], np.int64)
            xy = np.array([c * scale for t in measured for c in t.xy_px], np.float64).reshape(-1, 2)
            filtered = self._filter.update(ids, xy, frame.timestamp_s).tolist()
        ended = [u.track.id for u in updates if u.state == "up"]
        if ended:
            self._filter.drop(np.array(ended, np.int64))
        events: list[TouchEvent] = []
        index, t_s = frame.index, frame.timestamp_s
        isfinite = math.isfinite
        filtered_it = iter(filtered)
        for u in updates:
            t = u.track
            if u.measured:
                x_mm, y_mm = next(filtered_it)
                xy_px = (x_mm / scale, y_mm / scale)
            else:  # grace frames and up repeat the last filtered position
                xy_px = t.out_xy if t.out_xy is not None else t.xy_px
            t.out_xy = xy_px
            extra: dict[str, Any] = {"area": t.area_px}
            if isfinite(t.height_mm):
                extra["h"] = round(t.height_mm, 2)
            events.append(TouchEvent(index, t_s, t.id, u.state, float(xy_px[0]), float(xy_px[1]),
                                     extra))
        self._add_coordinates(events)
        return events

    def _add_coordinates(self, events: list[TouchEvent]) -> None:
        surf = self.surface
        if not events or surf is None:
            return
        if surf.K is not None:
            # a handful of touches: plain floats cost less than array calls here
            (fx, _, cx), (_, fy, cy), _ = surf.K.tolist()
            dm = surf.depth_mm
            w1, h1 = dm.shape[1] - 1, dm.shape[0] - 1
            at = dm.item
            for e in events:
                x, y = e.x, e.y
                ix, iy = round(x), round(y)  # nearest pixel, clamped to the image
                ix = 0 if ix < 0 else (w1 if ix > w1 else ix)
                iy = 0 if iy < 0 else (h1 if iy > h1 else iy)
                z = float(at(iy, ix))
                if z > 0:
                    extra = e.extra
                    extra["X"] = round((x - cx) * z / fx, 2)
                    extra["Y"] = round((y - cy) * z / fy, 2)
                    extra["Z"] = round(z, 2)
        if self.calibration is not None:
            xy = np.array([[e.x, e.y] for e in events], np.float64)
            sxy = self.calibration.to_screen(xy)
            for e, (sx, sy) in zip(events, sxy.tolist()):
                e.extra.update(sx=round(sx, 2), sy=round(sy, 2))

    def _frame_ok(self, frame: Frame, surface: SurfaceModel | None) -> bool:
        d = frame.depth
        if d.dtype != np.uint16:
            return self._skip("dtype", f"frame {frame.index} has dtype {d.dtype}, expected uint16")
        if surface is not None and d.shape != surface.depth_mm.shape:
            return self._skip(
                "size",
                f"frame {frame.index} is {d.shape[1]}x{d.shape[0]}, the surface "
                f"{surface.depth_mm.shape[1]}x{surface.depth_mm.shape[0]}",
            )
        return True

    def _skip(self, reason: str, message: str) -> bool:
        if self.strict:
            raise SourceError(f"{message}; the recording cannot be used as it is")
        self.stats.skipped_frames += 1
        self.stats.skip_reasons[reason] = self.stats.skip_reasons.get(reason, 0) + 1
        if reason not in self._warned:
            self._warned.add(reason)
            log.warning("skipping bad frames (%s): %s; further ones are counted", reason, message)
        return False
