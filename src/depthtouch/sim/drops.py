"""Frames a camera never delivers: a recording with dropped frames, and its truth renumbered.

A depth camera on USB loses frames when the bus or the host is busy (a RealSense under load, a
Kinect v2 on a shared controller): the stream goes on, the next frame's timestamp lies 2-4
frame intervals after the last one, and the frame numbers of a recording simply skip. Every
other part of the simulator renders every frame; :func:`drop_frames` takes some away
afterwards, so the sensor meets a stream whose frames are not evenly spaced, while the frames
that remain are exactly those of the full recording.

The drops form a two-state chain over the frames after the first: a kept frame is followed by
a dropped one with probability ``rate``, a dropped frame by another with probability
:data:`BURST_P` (bursts of 1.4 frames on average; the share of frames dropped is about
``rate / (1 - BURST_P + rate)``: 2.8 % at ``rate`` 0.02, 6.7 % at 0.05). The draws come from a
stream of their own (the seed's), so the recording's hands and noise stay as they were.

The truth follows the frames that remain: they are numbered again from 0 (``frame``), keep
their timestamps (``t``), and the scene events and the bump move to the first remaining frame
at or after theirs; ``empty_frames`` counts the remaining empty frames, and ``dropped_frames``
(an optional key) how many were taken out.
"""

from __future__ import annotations

import copy
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ConfigError

if TYPE_CHECKING:
    from .render import SimRecording

#: the chance that a dropped frame is followed by another (a burst)
BURST_P = 0.3
#: the largest ``rate`` (a stream that loses a third of its frames is another problem)
RATE_MAX = 0.2
# the draws' own stream: SeedSequence(seed) spawns the scene's and the noise's (render.py)
_STREAM = 0xD0


def check_drop_rate(rate: object) -> float:
    """``rate`` as a float in [0, :data:`RATE_MAX`], or ConfigError naming the range."""
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) \
            or not 0.0 <= float(rate) <= RATE_MAX:
        raise ConfigError(f"drop rate {rate!r} is out of range; allowed [0, {RATE_MAX:g}] "
                          "(the chance that a frame after a kept one is lost)")
    return float(rate)


def kept_frames(n: int, rate: float, seed: int) -> np.ndarray:
    """Which of ``n`` frames remain (bool (n,)); the first always does (pure, seeded)."""
    rate = check_drop_rate(rate)
    keep = np.ones(n, bool)
    if rate == 0.0 or n < 2:
        return keep
    u = np.random.default_rng([int(seed), _STREAM]).random(n)
    dropped = False
    for i in range(1, n):  # a chain over frames, not pixels: a few hundred steps
        dropped = bool(u[i] < (BURST_P if dropped else rate))
        keep[i] = not dropped
    return keep


def drop_frames(rec: SimRecording, rate: float, seed: int) -> SimRecording:
    """``rec`` without the frames the chain drops (see the module doc); ``rec`` itself is not
    changed. ``rate`` 0 returns it as it is."""
    n = int(rec.depth.shape[0])
    keep = kept_frames(n, rate, seed)
    if keep.all():
        return rec
    idx = np.flatnonzero(keep)
    # new number of each old frame: the first remaining frame at or after it
    first_at = np.searchsorted(idx, np.arange(n + 1))
    truth = _renumbered(rec.truth, keep, first_at, len(idx))
    return replace(rec, depth=rec.depth[idx], timestamps_s=rec.timestamps_s[idx].copy(),
                   truth=truth, labels=None if rec.labels is None else rec.labels[idx])


def _renumbered(doc: dict[str, Any], keep: np.ndarray, first_at: np.ndarray, n_kept: int
                ) -> dict[str, Any]:
    """The truth document of the remaining frames (a new document)."""
    out = copy.deepcopy(doc)
    n = keep.shape[0]

    def moved(f: int) -> int:
        return int(min(first_at[min(max(int(f), 0), n)], n_kept - 1))

    out["frames"] = [{**fr, "frame": int(first_at[fr["frame"]])}
                     for fr in out["frames"] if 0 <= fr["frame"] < n and keep[fr["frame"]]]
    for ev in out.get("events", []):
        if "frame" in ev:
            ev["frame"] = moved(ev["frame"])
    if isinstance(out.get("bump"), dict) and "frame" in out["bump"]:
        out["bump"]["frame"] = moved(out["bump"]["frame"])
    if "empty_frames" in out:
        out["empty_frames"] = int(keep[:int(out["empty_frames"])].sum())
    out["dropped_frames"] = int(n - n_kept)
    return out
