"""Gestures from tracked touches: tap, double tap, long press, drag, two-finger pinch and rotate.

:class:`GestureRecognizer` is fed each frame's touch events (one per active touch, plus ``up``
on the frame a touch ends) and returns the gestures completed or updated in that frame. Time is
the frames' timestamps; positions are depth-image pixels, or screen pixels (``sx``, ``sy``) with
``space="screen"``, and every distance threshold is in those pixels.

Rules (thresholds in :class:`GestureConfig`):

- A touch that is ever on the surface together with another one is *multi-finger*: it makes no
  tap, long press or drag (a drag in progress ends when a second finger lands).
- Every single-finger press is some gesture (the platforms' convention): lifted before
  ``long_press_s`` it is a ``tap``, held past it a ``long_press``, moved beyond the slop a drag.
  The defaults leave no gap between them (``tap_max_s`` = ``long_press_s``, one slop for all
  three); ``long_press_s`` = 0.7 s as reported is about 0.65 s of contact (a touch is reported
  ~0.02 s after it lands and ~0.075 s, 2-3 frames, after it lifts): longer than a phone's 0.5 s,
  because a tap on a tabletop lasts 0.3-0.6 s in contact (the simulator's taps scene).
- ``tap``: a single touch lifted within ``tap_max_s`` that moved at most ``tap_max_move_px``.
  ``double_tap`` follows the second of two taps (down within ``double_tap_gap_s`` of the first
  one's up, within ``double_tap_max_dist_px``); the second ``tap`` is still reported first, so a
  single tap is never delayed (as DOM ``click`` / ``dblclick``).
- ``long_press``: a single touch held ``long_press_s`` within ``long_press_max_move_px``; once,
  while it is still down (or on its lift, when it lifts on the frame it reaches
  ``long_press_s``); its lift then makes no tap.
- Distances: with a known scale (``mm_per_px`` given to the recognizer, depth space), the three
  movement thresholds are ``slop_mm`` converted to pixels; otherwise the ``*_px`` fields.
- ``drag_start`` when a single touch has moved more than ``drag_min_move_px`` from its down point
  (``dx``, ``dy``: offset from the down point), ``drag`` on each later frame it moves (``dx``,
  ``dy``: motion since the previous drag event), ``drag_end`` when it lifts (``dx``, ``dy``: total
  offset from the down point).
- Two fingers: when exactly two touches are down they form a pair, and the distance and angle
  between them at that moment are the reference. ``pinch`` (``scale`` = distance / reference,
  cumulative) starts once ``|scale - 1| >= pinch_min_change`` and is then reported whenever it
  changed by ``pinch_step``; ``rotate`` (``rotation_deg``, cumulative, positive = clockwise on a
  y-down image) starts at ``rotate_min_deg`` and is reported per ``rotate_step_deg``. Each carries
  ``phase`` ``start``, ``move``, and ``end`` when either finger lifts. ``x``, ``y`` are the
  midpoint of the pair. Neither starts before the pair has been down ``pair_min_s``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from .checks import check_range
from .errors import ConfigError, OutputError
from .types import TouchEvent

GESTURE_KINDS = (
    "tap", "double_tap", "long_press", "drag_start", "drag", "drag_end", "pinch", "rotate",
)


def _range(name: str, value: float, lo: float, hi: float, *, lo_open: bool = False) -> None:
    check_range(f"gestures.{name}", value, lo, hi, lo_open=lo_open)


@dataclass(frozen=True)
class GestureConfig:
    """Gesture thresholds. Distances are pixels of ``space`` (depth image or screen).

    tap_max_s: longest contact that is a tap, seconds (default 0.7 = long_press_s, (0, 5]).
    tap_max_move_px: farthest a tap may move from its down point (default 10, [0, 1000]).
    double_tap_gap_s: longest time from a tap's up to the next tap's down (default 0.3, (0, 5]).
    double_tap_max_dist_px: farthest apart the two taps may be (default 20, [0, 1000]).
    long_press_s: hold time of a long press as the sensor reports it, seconds (default 0.7:
        ~0.65 s of contact plus the sensor's net lift latency, range (0, 30]).
    long_press_max_move_px: farthest a long press may move (default 10, [0, 1000]).
    drag_min_move_px: distance from the down point that starts a drag (default 10, (0, 1000]).
    pinch_min_change: relative distance change that starts a pinch (default 0.08, (0, 10]).
    pinch_step: scale change between two pinch events (default 0.01, (0, 10]).
    rotate_min_deg: angle that starts a rotate (default 8, (0, 180]).
    rotate_step_deg: angle change between two rotate events (default 1, (0, 180]).
    pair_min_s: two touches must be down together this long before a pinch or rotate can start,
        so that a tracker's id switch (one touch replaced by another) is no pinch (default 0.1,
        range [0, 5]).
    slop_mm: movement that makes a press a drag (and no tap or long press), mm, used instead of
        the three ``*_move_px`` thresholds when the recognizer knows ``mm_per_px``
        (default 25, range (0, 200]: the reported position of a still press wanders up to
        ~21 mm with a simulated D435 at 1 m, under 3 mm with a Kinect v2).
    space: "depth" (event x, y) or "screen" (event extra sx, sy, needs a calibration).
    """

    tap_max_s: float = 0.7
    tap_max_move_px: float = 10.0
    double_tap_gap_s: float = 0.3
    double_tap_max_dist_px: float = 20.0
    long_press_s: float = 0.7
    long_press_max_move_px: float = 10.0
    drag_min_move_px: float = 10.0
    pinch_min_change: float = 0.08
    pinch_step: float = 0.01
    rotate_min_deg: float = 8.0
    rotate_step_deg: float = 1.0
    pair_min_s: float = 0.1
    slop_mm: float = 25.0
    space: str = "depth"

    def validate(self) -> GestureConfig:
        _range("tap_max_s", self.tap_max_s, 0.0, 5.0, lo_open=True)
        _range("tap_max_move_px", self.tap_max_move_px, 0.0, 1000.0)
        _range("double_tap_gap_s", self.double_tap_gap_s, 0.0, 5.0, lo_open=True)
        _range("double_tap_max_dist_px", self.double_tap_max_dist_px, 0.0, 1000.0)
        _range("long_press_s", self.long_press_s, 0.0, 30.0, lo_open=True)
        _range("long_press_max_move_px", self.long_press_max_move_px, 0.0, 1000.0)
        _range("drag_min_move_px", self.drag_min_move_px, 0.0, 1000.0, lo_open=True)
        _range("pinch_min_change", self.pinch_min_change, 0.0, 10.0, lo_open=True)
        _range("pinch_step", self.pinch_step, 0.0, 10.0, lo_open=True)
        _range("rotate_min_deg", self.rotate_min_deg, 0.0, 180.0, lo_open=True)
        _range("rotate_step_deg", self.rotate_step_deg, 0.0, 180.0, lo_open=True)
        _range("pair_min_s", self.pair_min_s, 0.0, 5.0)
        _range("slop_mm", self.slop_mm, 0.0, 200.0, lo_open=True)
        if self.space not in ("depth", "screen"):
            raise ConfigError(f"gestures.space = {self.space!r} is unknown; use depth or screen")
        return self


@dataclass(frozen=True)
class GestureEvent:
    """One recognised gesture.

    kind: one of :data:`GESTURE_KINDS`. frame, t: the frame index and timestamp (s) it was
    recognised in. ids: the touch ids involved. x, y: where (pixels of ``space``; a pair's
    midpoint for pinch and rotate). scale (pinch), rotation_deg (rotate), dx, dy (drag,
    pixels), duration_s (tap, long press), phase ("start", "move", "end" for pinch and rotate):
    None when not relevant.
    """

    kind: str
    frame: int
    t: float
    ids: tuple[int, ...]
    x: float
    y: float
    scale: float | None = None
    rotation_deg: float | None = None
    dx: float | None = None
    dy: float | None = None
    duration_s: float | None = None
    phase: str | None = None
    space: str = "depth"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ``{"type": "gesture", "kind": ..., ...}``; None fields are left out."""
        d: dict[str, Any] = {
            "type": "gesture",
            "kind": self.kind,
            "frame": self.frame,
            "t": round(self.t, 6),
            "ids": list(self.ids),
            "x": round(self.x, 3),
            "y": round(self.y, 3),
            "space": self.space,
        }
        for name in ("scale", "rotation_deg", "dx", "dy", "duration_s"):
            v = getattr(self, name)
            if v is not None:
                d[name] = round(float(v), 4)
        if self.phase is not None:
            d["phase"] = self.phase
        return d


@dataclass
class _Contact:
    id: int
    start_xy: tuple[float, float]
    start_t: float
    xy: tuple[float, float]
    t: float
    max_move: float = 0.0
    multi: bool = False
    dragging: bool = False
    long_pressed: bool = False
    drag_xy: tuple[float, float] = (0.0, 0.0)


@dataclass
class _Pair:
    ids: tuple[int, int]
    d0: float
    angle_deg: float  # last raw angle, to accumulate rotation across the +-180 wrap
    rotation_deg: float = 0.0
    pinching: bool = False
    rotating: bool = False
    scale_sent: float = 1.0
    rotation_sent: float = 0.0
    scale: float = 1.0
    mid: tuple[float, float] = (0.0, 0.0)
    start_t: float = 0.0


@dataclass
class _LastTap:
    t_up: float
    xy: tuple[float, float]
    id: int


def _dist(a: tuple[float, float], b: tuple[float, float]) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


def _wrap_deg(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


class GestureRecognizer:
    """Stateful recogniser: ``update(frame_index, t, events)`` per frame, ``reset()`` to start over.

    ``events`` are one frame's :class:`~depthtouch.types.TouchEvent` list; a live touch missing
    from a frame's events is treated as lifted at its last position. ``config`` is validated
    here (ConfigError naming the allowed range). ``mm_per_px``: the depth image's scale on the
    surface (e.g. ``Surface.mm_per_px()``), > 0; with it and ``space="depth"`` the movement
    thresholds are ``config.slop_mm`` (default None: the ``*_move_px`` fields).
    """

    def __init__(self, config: GestureConfig | None = None,
                 mm_per_px: float | None = None) -> None:
        self.config = (config if config is not None else GestureConfig()).validate()
        if mm_per_px is not None and not (mm_per_px > 0 and math.isfinite(mm_per_px)):
            raise ConfigError(f"mm_per_px = {mm_per_px!r} must be a positive number")
        cfg = self.config
        slop = cfg.slop_mm / mm_per_px if mm_per_px and cfg.space == "depth" else None
        self._tap_move = slop if slop is not None else cfg.tap_max_move_px
        self._long_move = slop if slop is not None else cfg.long_press_max_move_px
        self._drag_move = slop if slop is not None else cfg.drag_min_move_px
        self._contacts: dict[int, _Contact] = {}
        self._pair: _Pair | None = None
        self._last_tap: _LastTap | None = None

    def reset(self) -> None:
        """Forget every touch, pair and pending double tap."""
        self._contacts.clear()
        self._pair = None
        self._last_tap = None

    # --- helpers --------------------------------------------------------------------------------
    def _xy(self, e: TouchEvent) -> tuple[float, float]:
        if self.config.space == "depth":
            return float(e.x), float(e.y)
        if "sx" not in e.extra or "sy" not in e.extra:
            raise ConfigError(
                "gestures.space = screen needs events with sx, sy; load a calibration or use "
                "space = depth"
            )
        return float(e.extra["sx"]), float(e.extra["sy"])

    def _ev(self, kind: str, frame: int, t: float, ids: Sequence[int],
            xy: tuple[float, float], **kw: Any) -> GestureEvent:
        return GestureEvent(kind, frame, t, tuple(ids), xy[0], xy[1], space=self.config.space,
                            **kw)

    # --- per frame ------------------------------------------------------------------------------
    def update(
        self, frame_index: int, t: float, events: Sequence[TouchEvent]
    ) -> list[GestureEvent]:
        """Feed one frame; returns the gestures recognised in it, in a stable order."""
        out: list[GestureEvent] = []
        t = float(t)
        seen: set[int] = set()
        ups: list[tuple[_Contact, tuple[float, float]]] = []
        for e in events:
            seen.add(e.id)
            xy = self._xy(e)
            c = self._contacts.get(e.id)
            if e.state == "up":
                if c is not None:
                    ups.append((c, xy))
                continue
            if c is None or e.state == "down":
                if c is not None:  # a repeated down: start the contact over
                    self._contacts.pop(e.id)
                self._add(e.id, xy, t, frame_index, out)
            else:
                c.xy, c.t = xy, t
                c.max_move = max(c.max_move, _dist(xy, c.start_xy))
        # a live touch absent from this frame's events has ended without an up
        ups.extend((c, c.xy) for cid, c in self._contacts.items()
                   if cid not in seen and all(c is not u for u, _ in ups))

        out.extend(self._update_pair(frame_index, t, {c.id for c, _ in ups}))
        for c in self._contacts.values():
            if any(c is u for u, _ in ups):
                continue
            out.extend(self._update_single(c, frame_index, t))
        for c, xy in ups:
            out.extend(self._lift(c, xy, frame_index, t))
        return out

    def _add(self, cid: int, xy: tuple[float, float], t: float, frame: int,
             out: list[GestureEvent]) -> None:
        c = _Contact(cid, xy, t, xy, t)
        if self._contacts:
            c.multi = True
            for other in self._contacts.values():
                other.multi = True
                if other.dragging:
                    other.dragging = False
                    out.append(self._drag_end(other, frame, t))
        self._contacts[cid] = c

    def _drag_end(self, c: _Contact, frame: int, t: float) -> GestureEvent:
        return self._ev("drag_end", frame, t, [c.id], c.xy,
                        dx=c.xy[0] - c.start_xy[0], dy=c.xy[1] - c.start_xy[1])

    def _update_single(self, c: _Contact, frame: int, t: float) -> list[GestureEvent]:
        cfg = self.config
        if c.multi:
            return []
        out: list[GestureEvent] = []
        if c.dragging:
            dx, dy = c.xy[0] - c.drag_xy[0], c.xy[1] - c.drag_xy[1]
            if dx != 0.0 or dy != 0.0:
                out.append(self._ev("drag", frame, t, [c.id], c.xy, dx=dx, dy=dy))
                c.drag_xy = c.xy
        elif c.max_move > self._drag_move:
            c.dragging = True
            c.drag_xy = c.xy
            out.append(self._ev("drag_start", frame, t, [c.id], c.xy,
                                dx=c.xy[0] - c.start_xy[0], dy=c.xy[1] - c.start_xy[1]))
        if (not c.long_pressed and not c.dragging and t - c.start_t >= cfg.long_press_s
                and c.max_move <= self._long_move):
            c.long_pressed = True
            out.append(self._ev("long_press", frame, t, [c.id], c.xy,
                                duration_s=t - c.start_t))
        return out

    def _update_pair(self, frame: int, t: float, lifting: set[int]) -> list[GestureEvent]:
        cfg = self.config
        p = self._pair
        if p is not None and (lifting & set(p.ids) or not all(i in self._contacts for i in p.ids)):
            return []  # ended by a lift in this frame; _lift reports the end
        if p is None:
            if len(self._contacts) != 2:
                return []
            a, b = self._contacts.values()
            d0 = _dist(a.xy, b.xy)
            if d0 <= 1e-6:
                return []
            ang = math.degrees(math.atan2(b.xy[1] - a.xy[1], b.xy[0] - a.xy[0]))
            self._pair = _Pair((a.id, b.id), d0, ang, mid=self._mid(a.xy, b.xy), start_t=t)
            return []
        a, b = self._contacts[p.ids[0]], self._contacts[p.ids[1]]
        p.mid = self._mid(a.xy, b.xy)
        ang = math.degrees(math.atan2(b.xy[1] - a.xy[1], b.xy[0] - a.xy[0]))
        p.rotation_deg += _wrap_deg(ang - p.angle_deg)
        p.angle_deg = ang
        p.scale = _dist(a.xy, b.xy) / p.d0
        out: list[GestureEvent] = []
        settled = t - p.start_t >= cfg.pair_min_s
        if settled and not p.pinching and abs(p.scale - 1.0) >= cfg.pinch_min_change:
            p.pinching, p.scale_sent = True, p.scale
            out.append(self._ev("pinch", frame, t, p.ids, p.mid, scale=p.scale, phase="start"))
        elif p.pinching and abs(p.scale - p.scale_sent) >= cfg.pinch_step:
            p.scale_sent = p.scale
            out.append(self._ev("pinch", frame, t, p.ids, p.mid, scale=p.scale, phase="move"))
        if settled and not p.rotating and abs(p.rotation_deg) >= cfg.rotate_min_deg:
            p.rotating, p.rotation_sent = True, p.rotation_deg
            out.append(self._ev("rotate", frame, t, p.ids, p.mid, rotation_deg=p.rotation_deg,
                                phase="start"))
        elif p.rotating and abs(p.rotation_deg - p.rotation_sent) >= cfg.rotate_step_deg:
            p.rotation_sent = p.rotation_deg
            out.append(self._ev("rotate", frame, t, p.ids, p.mid, rotation_deg=p.rotation_deg,
                                phase="move"))
        return out

    @staticmethod
    def _mid(a: tuple[float, float], b: tuple[float, float]) -> tuple[float, float]:
        return (a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0

    def _lift(self, c: _Contact, xy: tuple[float, float], frame: int,
              t: float) -> list[GestureEvent]:
        cfg = self.config
        out: list[GestureEvent] = []
        c.xy, c.max_move = xy, max(c.max_move, _dist(xy, c.start_xy))
        p = self._pair
        if p is not None and c.id in p.ids:
            if p.pinching:
                out.append(self._ev("pinch", frame, t, p.ids, p.mid, scale=p.scale, phase="end"))
            if p.rotating:
                out.append(self._ev("rotate", frame, t, p.ids, p.mid,
                                    rotation_deg=p.rotation_deg, phase="end"))
            self._pair = None
        self._contacts.pop(c.id, None)
        if c.dragging:
            out.append(self._drag_end(c, frame, t))
            return out
        duration = t - c.start_t
        if c.multi or c.long_pressed:
            return out
        if duration >= cfg.long_press_s and c.max_move <= self._long_move:
            # reached the hold time on the frame it lifted: still a long press, not nothing
            out.append(self._ev("long_press", frame, t, [c.id], c.xy, duration_s=duration))
            return out
        if duration > cfg.tap_max_s or c.max_move > self._tap_move:
            return out
        out.append(self._ev("tap", frame, t, [c.id], c.start_xy, duration_s=duration))
        last = self._last_tap
        if (last is not None and c.start_t - last.t_up <= cfg.double_tap_gap_s
                and _dist(c.start_xy, last.xy) <= cfg.double_tap_max_dist_px):
            out.append(self._ev("double_tap", frame, t, [last.id, c.id], c.start_xy))
            self._last_tap = None
        else:
            self._last_tap = _LastTap(t, c.start_xy, c.id)
        return out


def recognize_all(
    events: Iterable[TouchEvent], config: GestureConfig | None = None
) -> list[GestureEvent]:
    """Gestures of a whole event stream (e.g. an events file), fed frame by frame. Pure.

    ``events`` must be in frame order (as written by the pipeline; else OutputError). Touches
    still down when the stream ends are lifted after its last frame.
    """
    rec = GestureRecognizer(config)
    out: list[GestureEvent] = []
    frame: list[TouchEvent] = []
    for e in events:
        if frame and e.frame != frame[0].frame:
            if e.frame < frame[0].frame:
                raise OutputError(
                    f"events are not in frame order (frame {e.frame} after {frame[0].frame}); "
                    "sort them by frame"
                )
            out.extend(rec.update(frame[0].frame, frame[0].t, frame))
            frame = []
        frame.append(e)
    if frame:
        out.extend(rec.update(frame[0].frame, frame[0].t, frame))
        out.extend(rec.update(frame[0].frame + 1, frame[0].t, []))  # touches never lifted
    return out
