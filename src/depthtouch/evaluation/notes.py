"""What a run shows of each frame, for naming the contacts it missed (the evaluation's notes).

:class:`NotingCollector` is a sink that keeps a run's events and, per frame, a
:class:`~depthtouch.evaluation.metrics.FrameNotes`: the touch points' pixels with why each did
or did not count toward a new contact (:func:`depthtouch.tracking.evidence.point_reasons`), and
at given pixels (the truth's contacts) what the touch band held near each
(:func:`band_states`): nothing, pixels the opening erased, or an opened part. The evaluation
names a missed contact by the most common of these over its frames
(:func:`depthtouch.evaluation.metrics.evaluate`'s ``point_notes``). Nothing here is on the
sensor's own path.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from ..surface.bounds import BandBounds
from ..tracking.evidence import point_reasons
from ..types import FrameResult, TouchEvent
from .metrics import BAND_STATES, FrameNotes, Truth

if TYPE_CHECKING:  # pragma: no cover
    from ..pipeline import Pipeline

#: the band is looked at within this distance of a probed pixel (mm on the surface; at least
#: 2 px): a fingertip's region lies within about its radius of its contact
NEAR_MM = 10.0


def contact_pixels(truth: Truth) -> dict[int, np.ndarray]:
    """Per frame with contacts, their pixels (M, 2) in the truth's order."""
    out: dict[int, list[np.ndarray]] = {}
    for f, xy in zip(truth.contact_frame.tolist(), truth.contact_xy_px, strict=True):
        out.setdefault(int(f), []).append(np.asarray(xy, np.float64))
    return {f: np.array(v).reshape(-1, 2) for f, v in out.items()}


def band_states(depth: np.ndarray, bounds: BandBounds, xy_px: np.ndarray) -> list[str]:
    """What the touch band of a (prefiltered) frame holds within :data:`NEAR_MM` of each pixel
    (one of :data:`~depthtouch.evaluation.metrics.BAND_STATES`; pure).

    "nothing in the band": no pixel there lies in it (Tl < height < Tu); "band erased by the
    opening": some do, but none survives the erosion by ``open_px`` (a part thinner than the
    opening); "a region without a point": some does (the opened part was dropped under S_min,
    or gave no point: no hand attached to it, or it joined another region).
    """
    h, w = depth.shape
    r = max(2, math.ceil(NEAR_MM / bounds.mm_per_px))
    pad = bounds.open_px // 2
    out = []
    for x, y in np.asarray(xy_px, np.float64).reshape(-1, 2).tolist():
        cx, cy = int(round(x)), int(round(y))
        y0, y1 = max(cy - r - pad, 0), min(cy + r + pad + 1, h)
        x0, x1 = max(cx - r - pad, 0), min(cx + r + pad + 1, w)
        if y0 >= y1 or x0 >= x1:
            out.append(BAND_STATES[0])
            continue
        d = depth[y0:y1, x0:x1]
        band = (bounds.band_lo[y0:y1, x0:x1] <= d) & (d <= bounds.band_hi[y0:y1, x0:x1])
        # the pixels within r of the probe (the window holds the erosion's pad around them)
        iy, ix = np.mgrid[y0:y1, x0:x1]
        near = (np.abs(iy - cy) <= r) & (np.abs(ix - cx) <= r)
        if not (band & near).any():
            out.append(BAND_STATES[0])
            continue
        core = band.copy()
        if pad:  # the erosion by an open_px square; outside the image counts as in, as the
            # sensor's (outside the window elsewhere: no pixel within r reaches it)
            hh, ww = band.shape
            p = np.ones((hh + 2 * pad, ww + 2 * pad), bool)
            p[pad:pad + hh, pad:pad + ww] = band
            for dy in range(-pad, pad + 1):
                for dx in range(-pad, pad + 1):
                    core &= p[pad + dy:pad + dy + hh, pad + dx:pad + dx + ww]
        out.append(BAND_STATES[2] if (core & near).any() else BAND_STATES[1])
    return out


class NotingCollector:
    """A sink that keeps every event of a run and the notes of its frames (see the module
    doc): with ``probes`` (per frame index, pixels (M, 2) whose band to note: the truth's
    contacts, the only frames the evaluation asks about), the frames it lists; without, every
    frame with touch points."""

    def __init__(self, pipeline: Pipeline, probes: Mapping[int, np.ndarray] | None) -> None:
        self.events: list[TouchEvent] = []
        self.notes: dict[int, FrameNotes] = {}
        self._pipeline = pipeline
        self._probes = probes

    def send(self, result: FrameResult) -> None:
        self.events.extend(result.events)
        if result.learning:
            return
        points = result.points
        if self._probes is None:
            if not len(points):
                return
            probe = None
        else:
            probe = self._probes.get(result.frame.index)
            if probe is None:  # a frame without contacts: never asked about
                return
        surface, cfg = self._pipeline.surface, self._pipeline.config
        reasons = point_reasons(points, surface.mm_per_px, cfg.tracking,
                                cfg.touchpoints.touch_on_mm)
        probe_xy = np.zeros((0, 2)) if probe is None else probe
        states = (band_states(result.frame.depth, surface.bounds, probe_xy)
                  if len(probe_xy) and surface.bounds is not None else [])
        if len(states) != len(probe_xy):
            probe_xy = np.zeros((0, 2))
        self.notes[result.frame.index] = FrameNotes(points.xy_px.copy(), reasons, probe_xy,
                                                    states)

    def close(self) -> None:
        """Nothing to release."""
