"""Pooled accuracy: :func:`summarize` pools the raw per-recording numbers of
:func:`depthtouch.evaluation.metrics.evaluate` (:class:`~depthtouch.evaluation.metrics.EvalResult`)
into one :class:`Metrics` (pooled, not averaged per recording).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .metrics import EvalResult


@dataclass(frozen=True)
class Metrics:
    """Pooled accuracy over one or more recordings (NaN where nothing was measured).

    contacts: contact episodes the camera can see (the tip is not hidden in every frame);
    occluded_contacts: episodes hidden throughout (left out of recall, as no camera sees them).
    contact_recall: found / visible episodes. frame_recall: matched / scored contact frames
    (visible frames after the debounce).
    false_touches: false tracks; false_per_min: per minute of recording; false_longest_s:
    how long the longest of them was reported (s; 0 without any).
    false_by_hover: false tracks per band of hover height (:func:`hover_band`, mm) and "other".
    false_hover_heights_mm: the hover height of each false track that came near a hover.
    early_hover_heights_mm: for each true track reported down before its contact while near a
    hovering fingertip, the highest such hover (EvalResult.early_hover_height_mm).
    error_*_mm: surface error of matches. id_switches: total.
    down_latency_* / lift_latency_*: frames (0 = on the first contact frame / ``up`` on the
    first frame without contact). merged_contacts: contacts first reported under the id of an
    earlier contact that had ended (EvalResult.ep_merged).
    angle_error_deg: mean angle between reported and true displacement vectors over drag steps
    of ``angle_step_frames`` frames (3 by default, as the issue tracker measures).
    jitter_rms_mm: RMS distance to the mean position of a still finger.
    ms_per_frame_*: the pipeline's processing time per frame.
    missed_by_reason: missed contacts the camera saw, by why (EvalResult.ep_miss_reason; most
    common first; empty where the runs kept no point notes).
    """

    recordings: int
    frames: int
    duration_s: float
    contacts: int
    occluded_contacts: int
    contact_recall: float
    frame_recall: float
    false_touches: int
    false_per_min: float
    false_by_hover: dict[str, int]
    false_hover_heights_mm: tuple[float, ...]
    early_hover_heights_mm: tuple[float, ...]
    error_median_mm: float
    error_p95_mm: float
    error_mean_mm: float
    id_switches: int
    down_latency_median_frames: float
    down_latency_p95_frames: float
    lift_latency_median_frames: float
    lift_latency_p95_frames: float
    merged_contacts: int
    drags: int
    angle_error_deg: float
    jitter_rms_mm: float
    ms_per_frame_median: float
    ms_per_frame_p95: float
    false_longest_s: float = 0.0
    missed_by_reason: dict[str, int] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: NaN becomes None; floats rounded to 4 decimals."""
        d: dict[str, Any] = {}
        for k in self.__dataclass_fields__:
            v = getattr(self, k)
            if isinstance(v, float):
                d[k] = None if not math.isfinite(v) else round(v, 4)
            else:
                d[k] = v
        return d

    def false_from_hover_at_least(self, height_mm: float) -> int:
        """False touches attributed to fingers hovering at ``height_mm`` or higher."""
        return sum(h >= height_mm for h in self.false_hover_heights_mm)

    def early_from_hover_at_least(self, height_mm: float) -> int:
        """True touches reported down while their finger still hovered ``height_mm`` or
        higher (before the contact began)."""
        return sum(h >= height_mm for h in self.early_hover_heights_mm)


def _q(a: np.ndarray, q: float) -> float:
    a = a[np.isfinite(a)]
    return float(np.percentile(a, q)) if a.size else math.nan


HOVER_BANDS_MM = (5.0, 10.0, 25.0, 50.0)


def hover_band(h: float) -> str:
    """The report key of a hover height: "0-5", "5-10", "10-25", "25-50", "50+" (mm), or
    "other" for NaN (a false touch near no hovering finger)."""
    if not math.isfinite(h):
        return "other"
    edges = (0.0, *HOVER_BANDS_MM)
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        if h < hi:
            return f"{lo:g}-{hi:g}"
    return f"{edges[-1]:g}+"


def summarize(results: Sequence[EvalResult]) -> Metrics:
    """Pool raw results of several recordings into one set of metrics."""
    if not results:
        raise ValueError("summarize: no results to pool")

    def cat(name: str) -> np.ndarray:
        return np.concatenate([np.asarray(getattr(r, name)) for r in results])

    visible = cat("ep_visible")
    found = cat("ep_found")[visible]
    scored = int(cat("ep_frames_scored").sum())
    duration = float(sum(r.duration_s for r in results))
    fh = cat("false_hover_height_mm")
    by_hover = {hover_band(h): 0 for h in (0.0, *HOVER_BANDS_MM, math.nan)}
    for h in fh:
        by_hover[hover_band(float(h))] += 1
    errs = cat("errors_mm")
    angles, steps = cat("ep_angle_deg"), cat("ep_angle_steps")
    use = np.isfinite(angles) & (steps > 0)
    angle = float(np.sum(angles[use] * steps[use]) / steps[use].sum()) if use.any() else math.nan
    sq = sum(r.still_sq_sum_mm2 for r in results)
    cnt = sum(r.still_count for r in results)
    timing = cat("timing_ms")
    return Metrics(
        recordings=len(results),
        frames=int(sum(r.n_frames for r in results)),
        duration_s=duration,
        contacts=int(found.size),
        occluded_contacts=int(np.count_nonzero(~visible)),
        contact_recall=float(found.mean()) if found.size else math.nan,
        frame_recall=float(cat("ep_frames_matched").sum() / scored) if scored else math.nan,
        false_touches=int(fh.size),
        false_per_min=float(fh.size / (duration / 60.0)) if duration > 0 else math.nan,
        false_by_hover=by_hover,
        false_hover_heights_mm=tuple(float(h) for h in fh if math.isfinite(h)),
        early_hover_heights_mm=tuple(float(h) for h in cat("early_hover_height_mm")),
        error_median_mm=_q(errs, 50),
        error_p95_mm=_q(errs, 95),
        error_mean_mm=float(errs.mean()) if errs.size else math.nan,
        id_switches=int(cat("ep_id_switches").sum()),
        down_latency_median_frames=_q(cat("ep_down_latency"), 50),
        down_latency_p95_frames=_q(cat("ep_down_latency"), 95),
        lift_latency_median_frames=_q(cat("ep_lift_latency"), 50),
        lift_latency_p95_frames=_q(cat("ep_lift_latency"), 95),
        merged_contacts=int(cat("ep_merged").sum()),
        drags=int(use.sum()),
        angle_error_deg=angle,
        jitter_rms_mm=math.sqrt(sq / cnt) if cnt else math.nan,
        ms_per_frame_median=_q(timing, 50),
        ms_per_frame_p95=_q(timing, 95),
        false_longest_s=max((float(n) * r.duration_s / r.n_frames for r in results
                             if r.n_frames for n in r.false_frames), default=0.0),
        missed_by_reason=missed_by_reason(results),
    )


def missed_by_reason(results: Sequence[EvalResult]) -> dict[str, int]:
    """Missed contacts by why (EvalResult.ep_miss_reason), most common first (ties in the
    order first met)."""
    count: dict[str, int] = {}
    for r in results:
        for why in r.ep_miss_reason:
            if why:
                count[why] = count.get(why, 0) + 1
    return dict(sorted(count.items(), key=lambda kv: -kv[1]))
