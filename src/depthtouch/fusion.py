"""Fusion: several cameras' touches on one shared screen -> one stream of touches.

Each camera's pipeline reports its own touches with its own ids; with a calibration each event
carries ``sx``, ``sy`` in the shared screen. :class:`Fusion` turns them into one stream:

- a camera's new touch within ``gate_px`` of a fused touch (its position predicted to now) that
  this camera does not already see is the same finger: one touch, one id, wherever the views
  overlap;
- a drag leaving one camera's view keeps its id: the camera that sees it next joins the same
  fused touch (while both see it in the overlap, or within ``handoff_s`` when the first camera
  lost it near the edge of its view);
- cameras are not synchronised: every camera's latest observation is kept with its own time
  and predicted (constant velocity, at most ``max_predict_s``) to the time of the frame being
  fused; nothing is paired by frame number;
- the fused position blends the cameras that see the touch, each weighted by how far inside its
  own view the point is (0 at the edge, 1 from ``blend_px`` in), so that a drag crossing the
  seam moves smoothly; ``cam`` is the camera with the largest weight (the newest on a tie) and
  ``x``, ``y`` (and ``X``, ``Y``, ``Z``, ``area``, ``h``) are that camera's;
- fused ids count from 1 and are never reused (not even after :meth:`Fusion.reset`).

A camera's view is the polygon its image covers on the screen (:func:`view_polygon`, from its
calibration); without one (TUIO senders of unknown coverage) the box of the points seen from it
so far stands in.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from .checks import check_range
from .errors import ConfigError
from .types import TouchEvent


@dataclass(frozen=True)
class FusionConfig:
    """Rules of the fusion, in pixels of the shared screen and seconds.

    gate_px: a camera's new touch this close to a fused touch joins it (default 60, a finger
        width on a 1920-wide screen over 1 m; range (0, 10000]). Scale it with the screen.
    blend_px: a camera's weight rises from 0 at the edge of its view to 1 this far inside
        (default 40, range (0, 10000]).
    edge_px: a touch lost this close to the edge of its camera's view may have left the view:
        it is held ``handoff_s`` for another camera (default 40, range [0, 10000]).
    handoff_s: how long such a touch waits; 0 ends it at once (default 0.15 s, [0, 2]).
    max_predict_s: an observation is predicted forward at most this long (default 0.1 s,
        [0, 1]); older ones keep their last predicted place.
    merge_s: two fused touches seen by different cameras within ``gate_px / 2`` of each other
        for this long become one (the younger ends); default 0.1 s, range [0, 5].
    """

    gate_px: float = 60.0
    blend_px: float = 40.0
    edge_px: float = 40.0
    handoff_s: float = 0.15
    max_predict_s: float = 0.1
    merge_s: float = 0.1

    def __post_init__(self) -> None:
        check_range("fusion.gate_px", self.gate_px, 0.0, 10000.0, lo_open=True)
        check_range("fusion.blend_px", self.blend_px, 0.0, 10000.0, lo_open=True)
        check_range("fusion.edge_px", self.edge_px, 0.0, 10000.0)
        check_range("fusion.handoff_s", self.handoff_s, 0.0, 2.0)
        check_range("fusion.max_predict_s", self.max_predict_s, 0.0, 1.0)
        check_range("fusion.merge_s", self.merge_s, 0.0, 5.0)


def view_polygon(calibration: Any, resolution_wh: tuple[int, int]) -> np.ndarray:
    """The screen polygon (4, 2) a camera's image covers: its corners through the calibration's
    ``to_screen`` (a homography maps the image rectangle to a quadrilateral)."""
    w, h = resolution_wh
    corners = np.array([[0.0, 0.0], [w - 1.0, 0.0], [w - 1.0, h - 1.0], [0.0, h - 1.0]])
    return np.asarray(calibration.to_screen(corners), np.float64)


def inside_px(polygon: np.ndarray, sxy: tuple[float, float]) -> float:
    """Signed distance (screen px) of a point to a polygon's border: > 0 inside, < 0 outside."""
    poly = np.asarray(polygon, np.float32).reshape(-1, 1, 2)
    return float(cv2.pointPolygonTest(poly, (float(sxy[0]), float(sxy[1])), True))


def predict(sxy: tuple[float, float], v: tuple[float, float], dt_s: float,
            max_predict_s: float) -> tuple[float, float]:
    """Constant-velocity prediction ``dt_s`` ahead, clipped to [0, max_predict_s]. Pure."""
    dt = min(max(dt_s, 0.0), max_predict_s)
    return sxy[0] + v[0] * dt, sxy[1] + v[1] * dt


def blend(points: Sequence[tuple[float, float]], weights: Sequence[float]) -> tuple[float, float]:
    """Weighted mean of screen points (weights > 0). Pure."""
    total = float(sum(weights))
    x = sum(w * p[0] for p, w in zip(points, weights, strict=True)) / total
    y = sum(w * p[1] for p, w in zip(points, weights, strict=True)) / total
    return x, y


@dataclass
class _Obs:
    """One camera's latest observation of one of its touches."""

    sxy: tuple[float, float]
    t_s: float
    x: float
    y: float
    extra: dict[str, Any]
    inside_px: float
    v: tuple[float, float] = (0.0, 0.0)


@dataclass
class _Fused:
    id: int
    born_s: float
    members: dict[int, int] = field(default_factory=dict)  # cam -> that camera's touch id
    announced: bool = False
    hold_until_s: float | None = None
    last: _Obs | None = None  # the observation that gave the last output (x, y, extra)
    last_cam: int = 0
    last_sxy: tuple[float, float] = (0.0, 0.0)
    lost: list[tuple[float, float]] = field(default_factory=list)  # (t_s, inside_px) lost


class Fusion:
    """Per-camera touch events in, fused events out (see the module doc).

    ``update(cam, t_s, frame, events)`` takes one camera frame's events (each with ``sx``,
    ``sy``) and returns the fused events at time ``t_s``: ``down`` for new fused touches, ``move``
    for every other live one, ``up`` for the ones that ended. ``frame`` is copied into the
    events. ``set_view(cam, polygon)`` gives a camera's screen polygon.
    """

    def __init__(self, config: FusionConfig | None = None) -> None:
        self.config = config or FusionConfig()
        self._next_id = 1
        self._views: dict[int, np.ndarray] = {}
        self._boxes: dict[int, list[float]] = {}  # cam -> [x0, y0, x1, y1] of points seen
        self.reset()

    def reset(self) -> None:
        """Forget all touches (fused ids keep increasing)."""
        self._obs: dict[tuple[int, int], _Obs] = {}
        self._owner: dict[tuple[int, int], int] = {}
        self._fused: dict[int, _Fused] = {}
        self._close_since: dict[tuple[int, int], float] = {}
        self._ended: list[_Fused] = []  # ended, their ``up`` not reported yet
        self._now_s = -math.inf

    def set_view(self, cam: int, polygon: np.ndarray | None) -> None:
        """The screen polygon (N, 2) camera ``cam`` covers, or None (learn it from its points)."""
        if polygon is None:
            self._views.pop(cam, None)
        else:
            self._views[cam] = np.asarray(polygon, np.float64).reshape(-1, 2)

    @property
    def active_ids(self) -> list[int]:
        """Ids of the fused touches down now (held ones included)."""
        return sorted(self._fused)

    @property
    def held(self) -> bool:
        """Some touch lost by every camera waits for another one (see ``handoff_s``)."""
        return any(not f.members for f in self._fused.values())

    # --- per frame ----------------------------------------------------------------------------
    def update(self, cam: int, t_s: float, frame: int, events: Iterable[TouchEvent],
               *, emit: bool = True) -> list[TouchEvent]:
        """Fuse one camera frame's events; returns the fused events at ``t_s`` (see class doc).

        emit: False when more frames of the same instant follow (cameras in step): the state is
        updated, nothing is returned yet; the next emitting call reports it all, so that each
        fused touch appears once per instant. Raises ValueError when an event has no ``sx``,
        ``sy`` (the camera has no calibration).
        """
        now = max(float(t_s), self._now_s)
        self._now_s = now
        ended: list[_Fused] = []
        for e in events:
            key = (cam, e.id)
            if e.state == "up":
                self._lose(key, now, ended)
                continue
            obs = self._observe(cam, float(t_s), e)
            fid = self._owner.get(key)
            if fid is None or fid not in self._fused:
                f = self._join(cam, obs, now)
                f.members[cam] = e.id
                self._owner[key] = f.id
            else:
                self._split(key, obs, now)
        self._merge_duplicates(now, ended)
        for f in list(self._fused.values()):
            if not f.members and f.hold_until_s is not None and now >= f.hold_until_s:
                self._end(f)
                ended.append(f)
        self._ended += [f for f in ended if f.announced]
        if not emit:
            return []
        out = [self._event(f, frame, now, "up") for f in self._ended]
        self._ended = []
        for f in self._fused.values():
            out.append(self._emit(f, frame, now))
        return out

    def finish(self, frame: int, t_s: float) -> list[TouchEvent]:
        """End every fused touch (``up``), e.g. at the end of the streams."""
        now = max(float(t_s), self._now_s)
        out = [self._event(f, frame, now, "up") for f in self._ended]
        out += [self._event(f, frame, now, "up") for f in self._fused.values() if f.announced]
        self.reset()
        self._now_s = now
        return out

    def drop_camera(self, cam: int, frame: int) -> list[TouchEvent]:
        """Camera ``cam`` was lost: forget its observations. The fused touches it alone saw end
        now (their ``up`` is returned, at the latest time fused); those another camera sees
        keep their ids. Held touches wait as before."""
        now = self._now_s if math.isfinite(self._now_s) else 0.0
        ended: list[_Fused] = []
        for key in [k for k in self._obs if k[0] == cam]:
            self._obs.pop(key, None)
        for key in [k for k in self._owner if k[0] == cam]:
            f = self._fused.get(self._owner.pop(key))
            if f is None:
                continue
            f.members.pop(cam, None)
            if not f.members and f.hold_until_s is None:
                self._end(f)
                ended.append(f)
        self._close_since = {k: v for k, v in self._close_since.items()
                             if k[0] in self._fused and k[1] in self._fused}
        return [self._event(f, frame, now, "up") for f in ended if f.announced]

    # --- observations -------------------------------------------------------------------------
    def _observe(self, cam: int, t_s: float, e: TouchEvent) -> _Obs:
        sx, sy = e.extra.get("sx"), e.extra.get("sy")
        if sx is None or sy is None:
            raise ValueError(
                f"touch {e.id} of camera {cam} has no sx, sy; give every camera a calibration"
            )
        sxy = (float(sx), float(sy))
        prev = self._obs.get((cam, e.id))
        v = (0.0, 0.0)
        if prev is not None:
            dt = t_s - prev.t_s
            v = ((sxy[0] - prev.sxy[0]) / dt, (sxy[1] - prev.sxy[1]) / dt) if dt > 0 else prev.v
        obs = _Obs(sxy, t_s, e.x, e.y, dict(e.extra), self._inside(cam, sxy), v)
        self._obs[(cam, e.id)] = obs
        return obs

    def _inside(self, cam: int, sxy: tuple[float, float]) -> float:
        poly = self._views.get(cam)
        if poly is not None:
            return inside_px(poly, sxy)
        box = self._boxes.get(cam)
        if box is None:
            box = self._boxes[cam] = [sxy[0], sxy[1], sxy[0], sxy[1]]
        box[0], box[1] = min(box[0], sxy[0]), min(box[1], sxy[1])
        box[2], box[3] = max(box[2], sxy[0]), max(box[3], sxy[1])
        return min(sxy[0] - box[0], sxy[1] - box[1], box[2] - sxy[0], box[3] - sxy[1])

    def _predicted(self, f: _Fused, now: float) -> tuple[float, float]:
        if f.members:
            return self._position(f, now)[0]
        o = f.last  # held: from where it was last reported, on at its last velocity
        v, t = (o.v, o.t_s) if o is not None else ((0.0, 0.0), now)
        return predict(f.last_sxy, v, now - t, self.config.max_predict_s)

    def _nearest(self, cam: int, obs: _Obs, now: float) -> _Fused | None:
        """The nearest fused touch within ``gate_px`` that camera ``cam`` does not see."""
        best: _Fused | None = None
        best_d = self.config.gate_px
        for f in self._fused.values():
            if cam in f.members:
                continue  # one camera's two touches are two fingers
            p = self._predicted(f, now)
            d = math.hypot(p[0] - obs.sxy[0], p[1] - obs.sxy[1])
            if d <= best_d:
                best, best_d = f, d
        return best

    def _split(self, key: tuple[int, int], obs: _Obs, now: float) -> None:
        """A camera's touch that has left where the other cameras see its fused touch (its
        tracker moved on to a nearby finger) leaves it: beyond ``gate_px / 2`` of them it joins
        another fused touch within the gate; beyond ``gate_px`` it becomes a new one."""
        cam = key[0]
        f = self._fused[self._owner[key]]
        if len(f.members) < 2:
            return
        p = self._position(f, now, skip=cam)[0]
        d = math.hypot(p[0] - obs.sxy[0], p[1] - obs.sxy[1])
        if d <= self.config.gate_px / 2.0:
            return
        other = self._nearest(cam, obs, now)
        if other is None and d <= self.config.gate_px:
            return
        f.members.pop(cam)
        g = other if other is not None else self._join(cam, obs, now)
        g.hold_until_s = None
        g.members[cam] = key[1]
        self._owner[key] = g.id

    def _join(self, cam: int, obs: _Obs, now: float) -> _Fused:
        """The fused touch this camera's new touch belongs to (a new one when none is near)."""
        best = self._nearest(cam, obs, now)
        if best is not None:
            best.hold_until_s = None
            return best
        f = _Fused(self._next_id, now)
        self._next_id += 1
        self._fused[f.id] = f
        return f

    def _lose(self, key: tuple[int, int], now: float, ended: list[_Fused]) -> None:
        """A camera's touch ended: the fused touch ends with it unless another camera sees it,
        or it may have left this camera's view (held ``handoff_s`` for the next camera)."""
        obs = self._obs.pop(key, None)
        fid = self._owner.pop(key, None)
        f = self._fused.get(fid) if fid is not None else None
        if f is None:
            return
        f.members.pop(key[0], None)
        horizon = self.config.max_predict_s
        f.lost = [(t, d) for t, d in f.lost if now - t <= horizon]
        if obs is not None:
            f.lost.append((now, obs.inside_px))
        if f.members:
            return
        # left the view only if every camera that lost it just now lost it near its edge
        recent = [d for _, d in f.lost]
        near_edge = bool(recent) and max(recent) < self.config.edge_px
        if near_edge and self.config.handoff_s > 0 and f.announced:
            f.hold_until_s = now + self.config.handoff_s
        else:
            self._end(f)
            ended.append(f)

    def _merge_duplicates(self, now: float, ended: list[_Fused]) -> None:
        """Two fused touches seen by different cameras, close for ``merge_s``: one finger."""
        live = [f for f in self._fused.values() if f.members]
        close: set[tuple[int, int]] = set()
        half = self.config.gate_px / 2.0
        for i, a in enumerate(live):
            pa = self._position(a, now)[0]
            for b in live[i + 1:]:
                if set(a.members) & set(b.members):
                    continue
                pb = self._position(b, now)[0]
                if math.hypot(pa[0] - pb[0], pa[1] - pb[1]) <= half:
                    close.add((a.id, b.id))
        self._close_since = {k: self._close_since.get(k, now) for k in close}
        for (ia, ib), since in list(self._close_since.items()):
            if now - since < self.config.merge_s:
                continue
            fa, fb = self._fused.get(ia), self._fused.get(ib)
            if fa is None or fb is None or set(fa.members) & set(fb.members):
                continue
            keep, drop = (fa, fb) if fa.born_s <= fb.born_s else (fb, fa)
            for cam, tid in drop.members.items():
                keep.members[cam] = tid
                self._owner[(cam, tid)] = keep.id
            drop.members.clear()
            self._end(drop)
            ended.append(drop)
            self._close_since.pop((ia, ib), None)

    # --- output -------------------------------------------------------------------------------
    def _position(self, f: _Fused, now: float, skip: int | None = None
                  ) -> tuple[tuple[float, float], int, _Obs]:
        """Blended screen position of a live fused touch, its best camera and observation
        (leaving camera ``skip`` out)."""
        cfg = self.config
        pts, ws, cands = [], [], []
        for cam, tid in f.members.items():
            if cam == skip:
                continue
            o = self._obs[(cam, tid)]
            w = min(max(o.inside_px / cfg.blend_px, 0.0), 1.0)
            pts.append(predict(o.sxy, o.v, now - o.t_s, cfg.max_predict_s))
            ws.append(max(w, 1e-3))
            cands.append((w, o.t_s, -cam, cam, o))
        _, _, _, cam, obs = max(cands, key=lambda c: c[:3])
        return blend(pts, ws), cam, obs

    def _emit(self, f: _Fused, frame: int, now: float) -> TouchEvent:
        if f.members:
            sxy, cam, obs = self._position(f, now)
            f.last, f.last_cam, f.last_sxy = obs, cam, sxy
        state = "move" if f.announced else "down"
        f.announced = True
        return self._event(f, frame, now, state)

    def _end(self, f: _Fused) -> None:
        """Drop a fused touch (the caller sends its ``up`` when it was announced)."""
        self._fused.pop(f.id, None)
        for cam, tid in f.members.items():
            self._owner.pop((cam, tid), None)

    def _event(self, f: _Fused, frame: int, now: float, state: str) -> TouchEvent:
        o = f.last
        extra: dict[str, Any] = dict(o.extra) if o is not None else {}
        extra.update(sx=round(f.last_sxy[0], 2), sy=round(f.last_sxy[1], 2), cam=f.last_cam)
        x, y = (o.x, o.y) if o is not None else (math.nan, math.nan)
        return TouchEvent(frame, now, f.id, state, x, y, extra)  # type: ignore[arg-type]


def in_screen(events: Iterable[TouchEvent]) -> list[TouchEvent]:
    """The events with ``x``, ``y`` replaced by their ``sx``, ``sy`` (to score fused events
    against truth in screen pixels); ConfigError when one has none."""
    out = []
    for e in events:
        if "sx" not in e.extra or "sy" not in e.extra:
            raise ConfigError(f"event of touch {e.id} (frame {e.frame}) has no sx, sy; score "
                             "events of a calibrated or fused replay")
        out.append(TouchEvent(e.frame, e.t, e.id, e.state, float(e.extra["sx"]),
                              float(e.extra["sy"]), e.extra))
    return out
