"""The pipeline: the only place that wires the per-frame stages together.

source frame -> surface (learned, then kept current) -> regions -> touch points -> tracking ->
path filter -> coordinates (X/Y/Z, screen) -> one :class:`~depthtouch.types.FrameResult`.

``Pipeline(config).process(frame)`` returns what the sensor made of that frame: its events, the
touch points, a status (learning, ok, disturbed, relearned, skipped) and the time per stage. The
coordinates every output needs (the filtered position, X/Y/Z in mm on the surface as it is now,
``sx``/``sy`` on the screen) are computed here, once; sinks read them. Bad frames in a live
stream (another size, wrong dtype) are skipped, counted and warned about once, never raised.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import cv2
import numpy as np

from .config import PipelineConfig
from .errors import SourceError, SurfaceError
from .sources.base import assumed_K
from .surface.gate import LearningGate
from .surface.model import SurfaceModel
from .surface.surface import Surface
from .touch.points import find_touch_points
from .touch.recent import RecentDepth
from .touch.regions import band_regions
from .tracking.evidence import enclosure_asks
from .tracking.filters import TouchFilter, make_filter
from .tracking.track import TrackUpdate
from .tracking.tracker import Tracker
from .types import Frame, FrameResult, FrameStatus, TouchEvent, TouchPoints

log = logging.getLogger(__name__)
_warm = False


def _warm_up() -> None:
    """Compile the per-frame kernels once per process, before the first frame (a camera
    stream must not stall seconds on its first touch)."""
    global _warm
    if _warm:
        return
    from . import firstrun, runs
    from .surface import adapt, model
    from .touch import handmap, parallax, points, recent, regions, tipkernel
    from .tracking import eurokernel

    # a cold numba cache (the first run after installing) takes ~20 s: firstrun says so
    firstrun.warm_up((tipkernel.warm_up, handmap.warm_up, regions.warm_up, adapt.warm_up,
                      eurokernel.warm_up, recent.warm_up, parallax.warm_up, points.warm_up,
                      model.warm_up),
                     kernels=(tipkernel._frame_points, runs.parts_of_runs, eurokernel.euro_step))
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
    """Depth frames in, one :class:`~depthtouch.types.FrameResult` per frame out.

    config: all stage settings (default :class:`PipelineConfig`).
    surface: a saved surface model; when None it is learned from the first frames.
    calibration: maps depth px to screen px; adds ``sx``, ``sy`` to events when given.
    surface_frames: learn the surface from this many frames (overrides the config's seconds).
    strict: raise on a frame that cannot be used (replaying a file: the file is wrong) instead of
        skipping it with one warning (a live camera: the next frame may be fine).
    gate: the learning gate of a live camera (see :mod:`depthtouch.surface.gate`); None learns
        from every frame (recordings).
    path_filter: a path filter to use instead of the one ``config.filter`` names (anything with
        the :class:`~depthtouch.tracking.filters.TouchFilter` methods, e.g. one that records
        what it is given: :mod:`depthtouch.evaluation.filterreplay`).
    """

    def __init__(
        self,
        config: PipelineConfig | None = None,
        *,
        surface: SurfaceModel | None = None,
        calibration: ScreenMapping | None = None,
        surface_frames: int | None = None,
        strict: bool = False,
        gate: LearningGate | None = None,
        path_filter: TouchFilter | None = None,
    ) -> None:
        self.config = (config or PipelineConfig()).validate()
        _warm_up()
        self.strict = strict
        self.calibration = calibration
        self.stats = PipelineStats()
        self._warned: set[str] = set()
        self._assumed_K: dict[tuple[int, int], np.ndarray] = {}  # per resolution, frames without K
        if surface is not None:
            surface = self._with_K(surface)
        self.surface = Surface(self.config, surface, learn_frames=surface_frames, gate=gate)
        self._filter: TouchFilter = (make_filter(self.config.filter) if path_filter is None
                                     else path_filter)
        self._tracker = Tracker(self.config.tracking, self.config.touchpoints)
        # whether contacts going down bring pending points for the filter (land_prior_frames)
        self._land_prior = self.config.tracking.land_prior_frames > 0
        # the frames of the last seconds, kept only where the tracker asks how much the heights
        # around a point changed (TrackingConfig.enclosed_change_max_mm)
        tc = self.config.tracking
        self._recent = (RecentDepth(tc.enclosed_change_window_s) if tc.enclosed_share_max < 1.0
                        and tc.enclosed_change_max_mm > 0.0 else None)
        self._reported: dict[int, tuple[float, float]] = {}  # last position sent per id, px
        self._active: set[int] = set()
        self._last_frame: Frame | None = None
        self._scale_for(self.surface)

    # --- state -----------------------------------------------------------------------------
    @property
    def learning(self) -> bool:
        return self.surface.learning

    @property
    def active_ids(self) -> list[int]:
        """Ids of the touches down now."""
        return sorted(self._active)

    def set_surface(self, surface: SurfaceModel) -> None:
        """Use this surface from the next frame on (active touches continue)."""
        self.surface.use(self._with_K(surface))
        self._scale_for(self.surface)

    def set_calibration(self, calibration: ScreenMapping | None) -> None:
        """Map to this screen from the next frame on (the web page's calibration flow)."""
        self.calibration = calibration

    def reset(self) -> None:
        """Forget the surface and all touches (ids keep increasing)."""
        self.surface.reset()
        self._tracker.reset()
        self._filter.reset()
        if self._recent is not None:
            self._recent.reset()
        self._reported.clear()
        self._active.clear()

    def _scale_for(self, surface: Surface) -> None:
        self._tracker.use_scale(surface.mm_per_px)

    # --- per frame -------------------------------------------------------------------------
    def _prefilter(self, frame: Frame) -> Frame:
        k = self.config.regions.median_px
        if k <= 1:
            return frame
        return Frame(cv2.medianBlur(frame.depth, k), frame.timestamp_s, frame.index,
                     frame.depth_scale_m, frame.K)

    def process(self, frame: Frame) -> FrameResult:
        """What the sensor makes of one frame (see the module doc)."""
        self.stats.frames += 1
        if frame.K is None:
            frame = replace(frame, K=self._assumed(frame.resolution_wh))
        surface = self.surface
        if surface.learning:
            self.stats.learning_frames += 1
            if not self._frame_ok(frame):
                return self._result(frame, [], "skipped")
            frame = self._prefilter(frame)
            try:
                learned = surface.learn(frame)
            except SurfaceError as e:
                if self.strict:
                    raise
                self._skip("learning", str(e))
                surface.reset()
                return self._result(frame, [], "skipped")
            if learned:
                self._scale_for(surface)
            self._last_frame = frame
            return self._result(frame, [], "learning")
        if not self._frame_ok(frame):
            return self._result(frame, [], "skipped")
        t0 = time.perf_counter()
        frame = surface.level(self._prefilter(frame))
        # keep the surroundings of touches of arms reaching in from the border (of every touch
        # with adapt.keep_all_touches): a finger held still is never absorbed; a "touch" on
        # something standing on the surface is
        held = self._tracker.held_xy_px(border_only=not self.config.adapt.keep_all_touches)
        verdict = surface.follow(frame, np.array(held))
        if verdict == "bump":
            return self._relearn(frame)
        if verdict == "disturbed":
            # most of the surface changed at once: report no touches until it settles
            self.stats.disturbed_frames += 1
            return self._result(frame, self._events(frame, self._tracker.end_all()), "disturbed")
        b = surface.bounds
        ta = time.perf_counter()
        regions = band_regions(frame.depth, b)
        t1 = time.perf_counter()
        points = find_touch_points(frame.depth, regions, b, self.config.touchpoints)
        if self._recent is not None:
            change = self._recent_change(frame, points) if len(points) else None
            if change is not None:
                points = replace(points, recent_change_mm=change)
            self._recent.update(frame.depth, frame.timestamp_s)
        t2 = time.perf_counter()
        updates = self._tracker.update(points, frame.timestamp_s)
        t3 = time.perf_counter()
        events = self._events(frame, updates)
        t4 = time.perf_counter()
        timing = {
            "prefilter_surface_update": (ta - t0) * 1e3, "regions": (t1 - ta) * 1e3,
            "touchpoints": (t2 - t1) * 1e3,
            "tracking": (t3 - t2) * 1e3, "filter_events": (t4 - t3) * 1e3,
            "total": (t4 - t0) * 1e3,
        }
        return self._result(frame, events, "ok", points, timing)

    def _with_K(self, surface: SurfaceModel) -> SurfaceModel:
        """A saved surface, with intrinsics for ``surface.assumed_hfov_deg`` when it has none."""
        return surface if surface.K is not None else replace(
            surface, K=self._assumed(surface.resolution_wh))

    def _assumed(self, wh: tuple[int, int]) -> np.ndarray:
        """Intrinsics for ``surface.assumed_hfov_deg`` at this resolution, for frames or a saved
        surface without their own (every size in mm needs the pixel size); said once."""
        K = self._assumed_K.get(wh)
        if K is None:
            hfov = self.config.surface.assumed_hfov_deg
            K = self._assumed_K[wh] = assumed_K(wh, hfov)
            if "K" not in self._warned:
                self._warned.add("K")
                log.warning(
                    "the frames carry no intrinsics (K): sizes in mm assume a %g deg horizontal "
                    "field of view (surface.assumed_hfov_deg), and are off where the camera's "
                    "differs; give the recording its K (the .npz's K, meta.json's \"K\") or set "
                    "surface.assumed_hfov_deg to the camera's (docs/config.md)", hfov,
                )
        return K

    def _recent_change(self, frame: Frame, points: TouchPoints) -> np.ndarray | None:
        """The recent change around the points the enclosure test asks about (its share and
        tip height), NaN (unknown: no evidence taken away) elsewhere; None when it asks about
        none (most frames: the per-frame path pays only for the frames kept)."""
        tc, b = self.config.tracking, self.surface.bounds
        if self._recent is None:
            return None
        asks = enclosure_asks(points, tc)
        if asks is None or not asks.any():
            return None
        ask = np.flatnonzero(asks)
        out = np.full(len(points), np.nan)
        out[ask] = self._recent.change_mm(frame.depth, points.xy_px[ask], frame.timestamp_s,
                                          b.to_mm, b.factor, tc.enclosed_cover_mm)
        return out

    def _relearn(self, frame: Frame) -> FrameResult:
        whole = (self.surface.offset_as_a_whole(frame)
                 if self.config.surface.level_limit_mm == 0 else None)
        if whole is not None and abs(whole) >= 1.0:
            # the frame moved as a whole: a camera that did not move but whose depth steps
            log.warning(
                "frame %d: most of the surface changed at once, the whole frame %.1f mm %s "
                "(camera moved, or its depth stepped as a whole: if it did not move, set "
                "surface.level_limit_mm = 15, docs/config.md); learning the surface again, "
                "no touches meanwhile", frame.index, abs(whole),
                "farther" if whole > 0 else "nearer",
            )
        else:
            log.warning(
                "frame %d: most of the surface changed and stays changed (camera moved?); "
                "learning the surface again, no touches meanwhile", frame.index,
            )
        events = self._events(frame, self._tracker.end_all())
        self.surface.relearn()
        self._filter.reset()
        if self._recent is not None:
            self._recent.reset()
        self.stats.relearns += 1
        return self._result(frame, events, "relearned")

    def finish(self) -> FrameResult | None:
        """End the active touches at the end of a stream (``up`` on the last frame); a surface
        still being learned starts over with the next stream. None before any frame."""
        self.surface.restart_learning()
        last = self._last_frame
        if last is None:
            return None
        events = self._events(last, self._tracker.end_all())
        return self._result(last, events, "ended")

    def _result(self, frame: Frame, events: list[TouchEvent], status: FrameStatus,
                points: TouchPoints | None = None, timing: dict[str, float] | None = None
                ) -> FrameResult:
        if status != "skipped":
            self._last_frame = frame
        self.stats.events += len(events)
        s = self.surface
        return FrameResult(frame, events, TouchPoints.empty() if points is None else points,
                           status, timing or {}, s.learn_progress, s.note, s)

    # --- events and their coordinates ------------------------------------------------------
    def _events(self, frame: Frame, updates: list[TrackUpdate]) -> list[TouchEvent]:
        if not updates:
            return []
        # a handful of touches: plain floats cost less than array calls here (same arithmetic)
        scale = self._tracker.scale_mm_per_px or 1.0
        measured = [u.track for u in updates if u.measured]
        filtered: list[list[float]] = []  # mm, in the order of the measured updates
        if measured:
            if self._land_prior:
                self._give_prior(updates, scale)
            ids = np.array([t.id for t in measured], np.int64)
            xy = np.array([c * scale for t in measured for c in t.report_px],
                          np.float64).reshape(-1, 2)
            filtered = self._filter.update(ids, xy, frame.timestamp_s).tolist()
        ended = [u.track.id for u in updates if u.state == "up"]
        if ended:
            self._filter.drop(np.array(ended, np.int64))
        events: list[TouchEvent] = []
        index, t_s = frame.index, frame.timestamp_s
        isfinite = math.isfinite
        filtered_it = iter(filtered)
        reported, active = self._reported, self._active
        for u in updates:
            t = u.track
            if u.measured:
                x_mm, y_mm = next(filtered_it)
                xy_px = (x_mm / scale, y_mm / scale)
            else:  # grace frames and up repeat the last filtered position
                xy_px = reported.get(t.id, t.report_px)
            if u.state == "up":
                reported.pop(t.id, None)
                active.discard(t.id)
            else:
                reported[t.id] = xy_px
                active.add(t.id)
            extra: dict[str, Any] = {"area": t.area_px}
            if isfinite(t.height_mm):
                extra["h"] = round(t.height_mm, 2)
            events.append(TouchEvent(index, t_s, t.id, u.state, float(xy_px[0]), float(xy_px[1]),
                                     extra))
        self._add_coordinates(events)
        return events

    def _give_prior(self, updates: list[TrackUpdate], scale: float) -> None:
        """The pending points of each contact just down, at their own times, to the path
        filter before its first (TrackingConfig.land_prior_frames)."""
        for u in updates:
            if u.state == "down" and u.track.prior:
                ids = np.array([u.track.id], np.int64)
                for px, py, pt in u.track.prior:
                    self._filter.update(ids, np.array([[px * scale, py * scale]]), pt)

    def _add_coordinates(self, events: list[TouchEvent]) -> None:
        for e, xyz in zip(events, self.surface.xyz_mm([(e.x, e.y) for e in events])):
            if xyz is not None:
                e.extra.update(X=round(xyz[0], 2), Y=round(xyz[1], 2), Z=round(xyz[2], 2))
        if self.calibration is not None:
            xy = np.array([[e.x, e.y] for e in events], np.float64)
            sxy = self.calibration.to_screen(xy)
            for e, (sx, sy) in zip(events, sxy.tolist()):
                e.extra.update(sx=round(sx, 2), sy=round(sy, 2))

    # --- bad frames ------------------------------------------------------------------------
    def _frame_ok(self, frame: Frame) -> bool:
        d = frame.depth
        if d.dtype != np.uint16:
            return self._skip("dtype", f"frame {frame.index} has dtype {d.dtype}, expected uint16")
        wh = self.surface.resolution_wh
        if wh is not None and (d.shape[1], d.shape[0]) != wh:
            return self._skip(
                "size", f"frame {frame.index} is {d.shape[1]}x{d.shape[0]}, the surface "
                f"{wh[0]}x{wh[1]}",
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
