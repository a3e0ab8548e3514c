"""Gesture accuracy against simulator ground truth: does every press give the gesture it should?

Each truth contact (a run of frames of one contact id) is a *press*. Its expected gesture follows
the recognizer's convention on the truth alone: moved more than ``slop_mm`` on the surface ->
``drag``; in contact at least ``long_press_s - NET_LATENCY_S`` -> ``long_press`` (the
recognizer sees durations as the sensor reports them; the truth has none); else ``tap``.

The recognised single-finger gestures (``tap``, ``long_press``, ``drag_start`` counted as
``drag``) are matched to presses: a gesture belongs to the nearest press (within ``gate_px`` of
its path) whose contact spans its time (from ``EARLY_S`` before the down to ``LATE_S``
after the lift), each press taking at most one. Per kind: precision = gestures of that kind
matched to a press that expects it / gestures of that kind; recall = presses expecting it that
got it / presses expecting it. ``recognised`` = presses expecting a tap or long press that got
either one.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..gestures import GestureConfig, GestureEvent, recognize_all
from ..types import TouchEvent
from .metrics import Truth

# reported minus true contact time: a touch is reported ~0.02 s after it lands and ~0.075 s
# after it lifts (measured on the presses scene, Kinect v2 and D435 at 1 m, 30 fps)
NET_LATENCY_S = 0.05
EARLY_S = 0.1
LATE_S = 0.5
KINDS = ("tap", "long_press", "drag")
PRESS_SCENE = "presses"


@dataclass(frozen=True)
class Press:
    """One truth contact: id, first and last frame time (s), path (M, 2) px, travel (mm)."""

    id: int
    start_s: float
    end_s: float
    path_px: np.ndarray
    move_mm: float
    expected: str

    @property
    def duration_s(self) -> float:
        return self.end_s - self.start_s


def truth_presses(truth: Truth, config: GestureConfig | None = None) -> list[Press]:
    """The presses of a truth, in time order, each with the gesture it should give."""
    cfg = config or GestureConfig()
    out: list[Press] = []
    frames, ids = truth.contact_frame, truth.contact_id
    for cid in np.unique(ids):
        rows = np.flatnonzero(ids == cid)
        # a contact id that lifts and lands again (a gap of frames) is two presses
        breaks = np.flatnonzero(np.diff(frames[rows]) > 2) + 1
        for run in np.split(rows, breaks):
            f0, f1 = int(frames[run[0]]), int(frames[run[-1]])
            p = truth.contact_p_mm[run]
            move = float(np.max(np.linalg.norm(p - p[0], axis=1))) if len(run) else 0.0
            dur = (f1 - f0 + 1) / truth.fps
            kind = ("drag" if move > cfg.slop_mm else
                    "long_press" if dur >= cfg.long_press_s - NET_LATENCY_S else "tap")
            out.append(Press(int(cid), f0 / truth.fps, (f1 + 1) / truth.fps,
                             np.asarray(truth.contact_xy_px[run], dtype=np.float64), move, kind))
    return sorted(out, key=lambda p: p.start_s)


def _kind(g: GestureEvent) -> str | None:
    return {"tap": "tap", "long_press": "long_press", "drag_start": "drag"}.get(g.kind)


@dataclass
class GestureScores:
    """Counts per kind: presses expecting it (``truth``), gestures found, correct ones."""

    truth: dict[str, int] = field(default_factory=lambda: dict.fromkeys(KINDS, 0))
    found: dict[str, int] = field(default_factory=lambda: dict.fromkeys(KINDS, 0))
    correct: dict[str, int] = field(default_factory=lambda: dict.fromkeys(KINDS, 0))
    presses: int = 0  # presses expecting a tap or a long press
    recognised: int = 0  # ... that got a tap or a long press
    confusions: list[tuple[float, str, str | None]] = field(default_factory=list)

    def add(self, other: GestureScores) -> GestureScores:
        for k in KINDS:
            self.truth[k] += other.truth[k]
            self.found[k] += other.found[k]
            self.correct[k] += other.correct[k]
        self.presses += other.presses
        self.recognised += other.recognised
        self.confusions += other.confusions
        return self

    def precision(self, kind: str) -> float:
        return self.correct[kind] / self.found[kind] if self.found[kind] else float("nan")

    def recall(self, kind: str) -> float:
        return self.correct[kind] / self.truth[kind] if self.truth[kind] else float("nan")

    @property
    def recognised_fraction(self) -> float:
        return self.recognised / self.presses if self.presses else float("nan")

    def to_dict(self) -> dict[str, Any]:
        return {
            "kinds": {k: {"truth": self.truth[k], "found": self.found[k],
                          "correct": self.correct[k], "precision": self.precision(k),
                          "recall": self.recall(k)} for k in KINDS},
            "presses": self.presses, "recognised": self.recognised,
            "recognised_fraction": self.recognised_fraction,
            "confusions": [{"duration_s": round(d, 3), "expected": e, "got": g}
                           for d, e, g in self.confusions],
        }


def score_gestures(presses: Sequence[Press], gestures: Iterable[GestureEvent],
                   gate_px: float = 30.0) -> GestureScores:
    """Match gestures to presses (see the module docstring) and count them. Pure."""
    sc = GestureScores()
    got: dict[int, str] = {}
    for g in gestures:
        kind = _kind(g)
        if kind is None:
            continue
        sc.found[kind] += 1
        best, best_d = None, gate_px
        for i, p in enumerate(presses):
            if i in got or not p.start_s - EARLY_S <= g.t <= p.end_s + LATE_S:
                continue
            d = float(np.min(np.hypot(g.x - p.path_px[:, 0], g.y - p.path_px[:, 1])))
            if d <= best_d:
                best, best_d = i, d
        if best is not None:
            got[best] = kind
    for i, p in enumerate(presses):
        sc.truth[p.expected] += 1
        kind = got.get(i)
        if kind == p.expected:
            sc.correct[kind] += 1
        else:
            sc.confusions.append((p.duration_s, p.expected, kind))
        if p.expected in ("tap", "long_press"):
            sc.presses += 1
            sc.recognised += kind in ("tap", "long_press")
    return sc


def evaluate_gestures(truth: Truth, events: Sequence[TouchEvent],
                      config: GestureConfig | None = None,
                      mm_per_px: float | None = None) -> GestureScores:
    """Recognise gestures in a run's events and score them against the truth's presses."""
    from ..gestures import GestureRecognizer

    rec = GestureRecognizer(config, mm_per_px=mm_per_px)
    found: list[GestureEvent] = []
    if mm_per_px is None:
        found = recognize_all(events, config)
    else:
        by_frame: dict[int, list[TouchEvent]] = {}
        for e in events:
            by_frame.setdefault(e.frame, []).append(e)
        last_t = 0.0
        for f in sorted(by_frame):
            evs = by_frame[f]
            last_t = evs[0].t
            found += rec.update(f, last_t, evs)
        found += rec.update(max(by_frame, default=0) + 1, last_t, [])
    return score_gestures(truth_presses(truth, config), found)


def _run_sensor(source: Any, config: Any) -> tuple[list[TouchEvent], float | None]:
    """Events of a run over a source and the surface's mm per pixel (None without
    intrinsics)."""
    from ..driver import drive
    from ..pipeline import Pipeline
    from .suiterun import EventCollector

    pipe, collect = Pipeline(config), EventCollector()
    drive(source, pipe, [collect])
    return collect.events, pipe.surface.mm_per_px


def run_press_scenes(
    *, scenes: Sequence[str] = (PRESS_SCENE, "taps", "drags"),
    cameras: Sequence[str] = ("kinect-v2", "realsense-d435"), seeds: Sequence[int] = (1, 2, 3),
    distance_m: float = 1.0, config: Any = None, gesture_config: GestureConfig | None = None,
    progress: Any = None,
) -> dict[str, GestureScores]:
    """Render each scene per camera and seed, run the sensor, score the gestures.

    Returns one GestureScores per scene and camera, plus ``all``.
    """
    from ..sim import render_scene
    from ..sources.base import ArraySource
    from .metrics import truth_from_dict

    out: dict[str, GestureScores] = {}
    total = GestureScores()
    for scene in scenes:
        for cam in cameras:
            row = GestureScores()
            for seed in seeds:
                rec = render_scene(scene, camera=cam, distance_m=distance_m, seed=seed)
                truth = truth_from_dict(rec.truth, f"{scene}/{cam}/s{seed}")
                events, scale = _run_sensor(ArraySource.of_recording(rec), config)
                row.add(evaluate_gestures(truth, events, gesture_config, scale))
                if progress is not None:
                    progress(f"{scene}/{cam}/s{seed}")
            out[f"{scene}/{cam}"] = row
            total.add(row)
    out["all"] = total
    return out


def gestures_command(
    recording: str | None, truth_path: str | None, *, events_path: str | None = None,
    config: Any = None, progress: Any = None,
) -> dict[str, GestureScores]:
    """``depthtouch eval --gestures``: a recording (or events file) with its truth, or, with
    neither, the simulated press, tap and drag scenes."""
    from ..errors import ConfigError
    from .metrics import read_truth

    if recording is None and events_path is None:
        if truth_path is not None:
            raise ConfigError("--truth needs a recording or --events to evaluate")
        return run_press_scenes(config=config, progress=progress)
    if truth_path is None:
        raise ConfigError("eval --gestures needs --truth TRUTH.json for a recording")
    truth = read_truth(truth_path)
    if events_path is not None:
        from ..outputs.jsonl import read_events

        events, scale = list(read_events(events_path)), None
        name = str(events_path)
    else:
        from ..sources import open_source

        with open_source(str(recording)) as src:
            events, scale = _run_sensor(src, config)
        name = str(recording)
    return {name: evaluate_gestures(truth, events, None, scale)}


def gestures_table(scores: dict[str, GestureScores], title: str = "gestures") -> Any:
    """A rich table: per row, precision / recall per kind and the presses recognised."""
    from rich.table import Table

    t = Table(title=title, header_style="bold")
    t.add_column("case")
    for k in KINDS:
        t.add_column(f"{k} P", justify="right")
        t.add_column(f"{k} R", justify="right")
    t.add_column("presses", justify="right")
    t.add_column("tap or long press", justify="right")

    def f(v: float) -> str:
        return "-" if v != v else f"{v:.3f}"

    for name, s in scores.items():
        t.add_row(name, *(f(x) for k in KINDS for x in (s.precision(k), s.recall(k))),
                  str(s.presses), f"{s.recognised}/{s.presses} ({100 * s.recognised_fraction:.1f} %)"
                  if s.presses else "-")
    return t


def gestures_output(recording: str | None, truth_path: str | None, *,
                    events_path: str | None = None, config: Any = None, as_json: bool = False,
                    progress: Any = None) -> str:
    """The text ``depthtouch eval --gestures`` prints: a table, or JSON."""
    import io
    import json
    import sys

    from rich.console import Console

    scores = gestures_command(recording, truth_path, events_path=events_path, config=config,
                              progress=(lambda msg: progress(msg, None)) if progress else None)
    if as_json:
        return json.dumps({k: s.to_dict() for k, s in scores.items()}, indent=1)
    buf = io.StringIO()
    Console(file=buf, width=None if sys.stdout.isatty() else 160).print(
        gestures_table(scores, title="gestures: precision (P) and recall (R) per kind"))
    return buf.getvalue().rstrip()
