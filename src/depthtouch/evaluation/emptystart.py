"""A rendered recording whose empty start is shortened: the check of ``eval --empty-s``.

A recording promises an empty surface for its first second only (docs/formats.md); the
simulator's scenes leave it empty for 1.5 s and more, as long as the sensor learns the surface
(``surface.learn_s``). :func:`shorten` takes a recording's first frames away so that something
comes into view ``empty_s`` seconds after its first frame, and numbers its truth again over the
frames that remain: the sensor then meets a hand while it still learns, as it would on such a
recording. Applied to a rendered recording (the cache keeps the recording as rendered), like a
crop in time; the remaining frames keep their timestamps.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

from ..errors import ConfigError

#: the shortest and longest empty start asked for (s)
EMPTY_MIN_S = 0.2
EMPTY_MAX_S = 10.0


def check_empty_s(empty_s: object) -> float:
    """``empty_s`` as a float in [:data:`EMPTY_MIN_S`, :data:`EMPTY_MAX_S`] s, or ConfigError
    naming the range."""
    if isinstance(empty_s, bool) or not isinstance(empty_s, (int, float)) \
            or not EMPTY_MIN_S <= float(empty_s) <= EMPTY_MAX_S:
        raise ConfigError(f"empty start {empty_s!r} s is out of range; allowed "
                          f"[{EMPTY_MIN_S:g}, {EMPTY_MAX_S:g}] s")
    return float(empty_s)


def frames_to_cut(doc: dict[str, Any], timestamps_s: np.ndarray, empty_s: float) -> int:
    """How many first frames go so that the truth's ``empty_frames`` (the frames before
    anything comes into view) last ``empty_s`` seconds (0 when they are no longer)."""
    empty = int(doc.get("empty_frames", 0))
    if empty <= 0 or empty >= timestamps_s.shape[0]:
        return 0
    t_in = float(timestamps_s[empty])
    # the first frame that lies at least empty_s before the one where something comes in
    first = int(np.searchsorted(timestamps_s, t_in - check_empty_s(empty_s) - 1e-9))
    return max(0, min(first, empty))


def shorten(depth: np.ndarray, timestamps_s: np.ndarray, doc: dict[str, Any], empty_s: float
            ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """The recording (depth (N, H, W), timestamps (N,), truth document) without the frames
    :func:`frames_to_cut` names; the truth numbered again from 0 over the rest, its scene
    events and bump moved with them, ``empty_frames`` less by as many, and ``cut_frames`` saying
    how many went (a new document; the arrays are views)."""
    cut = frames_to_cut(doc, timestamps_s, empty_s)
    if cut == 0:
        return depth, timestamps_s, doc
    out = copy.deepcopy(doc)
    out["frames"] = [{**fr, "frame": int(fr["frame"]) - cut} for fr in out["frames"]
                     if int(fr["frame"]) >= cut]
    for ev in out.get("events", []):
        if "frame" in ev:
            ev["frame"] = max(0, int(ev["frame"]) - cut)
    if isinstance(out.get("bump"), dict) and "frame" in out["bump"]:
        out["bump"]["frame"] = max(0, int(out["bump"]["frame"]) - cut)
    out["empty_frames"] = int(out["empty_frames"]) - cut
    out["cut_frames"] = cut
    return depth[cut:], timestamps_s[cut:], out
