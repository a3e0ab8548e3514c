"""Match reported touch events to the simulator's ground truth and measure accuracy.

Everything here is a pure function of a :class:`Truth` (parsed from a ``depthtouch-truth/1``
document) and a list of :class:`~depthtouch.types.TouchEvent`:

- per frame, reported touches (``down``/``move`` events) are assigned to true contacts by optimal
  assignment (``scipy.optimize.linear_sum_assignment``) on the distance in mm on the surface: a
  reported pixel (x, y) becomes the ray r = K^-1 [x, y, 1], intersected with the tangent plane at
  the contact point P (normal n): Q = r (n.P) / (n.r); the error is |Q - P|; pairs farther than
  the gate (default 20 mm) are never matched;
- a reported track (id) matched in no frame is a false touch; it is attributed to a hovering
  finger when it comes within the gate of one (by the hover's height), else to "other"; a
  matched track that was down before its first match near a hovering finger went down early,
  in the air (counted apart, by the highest such hover);
- contact episodes (a truth id over consecutive frames) give recall, id switches, touch-down and
  lift latency, the drag-path angle error (over 3-frame steps) and the jitter of a still finger.

:func:`evaluate` returns the raw per-recording numbers (:class:`EvalResult`);
:func:`depthtouch.evaluation.summary.summarize` pools any number of them into one ``Metrics``
(pooled, not averaged per recording).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..errors import ConfigError, SourceError
from ..types import TouchEvent
from .truth import TRUTH_FORMAT, Truth, read_truth, truth_from_dict  # noqa: F401  (re-exported)

GATE_MM = 20.0
_BIG = 1e9


# --- geometry ------------------------------------------------------------------------------------
def rays(xy_px: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Viewing rays r = K^-1 [x, y, 1] of pixels (N, 2) -> (N, 3), with r_z = 1."""
    xy = np.asarray(xy_px, dtype=np.float64).reshape(-1, 2)
    fx, fy, cx, cy, s = K[0, 0], K[1, 1], K[0, 2], K[1, 2], K[0, 1]
    y = (xy[:, 1] - cy) / fy
    x = (xy[:, 0] - cx - s * y) / fx
    return np.stack([x, y, np.ones_like(x)], axis=1)


def surface_error_mm(
    xy_px: np.ndarray, K: np.ndarray, p_mm: np.ndarray, n: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Distance in mm on the tangent plane between reported pixels and true points.

    xy_px: (A, 2) reported pixels; p_mm: (B, 3) true points (camera frame); n: (B, 3) unit normals.
    Returns (dist (A, B), Q (A, B, 3)): Q is the reported ray's intersection with the plane
    through P_b with normal n_b; rays parallel to the plane (or hitting it behind the camera) get
    an infinite distance.
    """
    r = rays(xy_px, K)
    p = np.asarray(p_mm, dtype=np.float64).reshape(-1, 3)
    nn = np.asarray(n, dtype=np.float64).reshape(-1, 3)
    num = np.sum(nn * p, axis=1)  # (B,)
    den = r @ nn.T  # (A, B)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = num[None, :] / den
    bad = ~np.isfinite(s) | (s <= 0) | (np.abs(den) < 1e-9)
    s = np.where(bad, 0.0, s)
    q = r[:, None, :] * s[:, :, None]
    d = np.linalg.norm(q - p[None, :, :], axis=2)
    return np.where(bad, np.inf, d), q


def match(dist: np.ndarray, gate: float) -> tuple[np.ndarray, np.ndarray]:
    """Optimal one-to-one assignment of rows to columns with cost ``dist``, keeping pairs <= gate.

    Returns (rows, cols) int arrays of equal length.
    """
    if dist.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    cost = np.where(dist <= gate, dist, _BIG)
    rows, cols = linear_sum_assignment(cost)
    keep = cost[rows, cols] < _BIG
    return rows[keep].astype(np.int64), cols[keep].astype(np.int64)


# --- events --------------------------------------------------------------------------------------
_STATE_CODE = {"down": 0, "move": 1, "up": 2}


@dataclass(frozen=True)
class _Ev:
    frame: np.ndarray
    id: np.ndarray
    state: np.ndarray
    xy: np.ndarray


def _events_arrays(events: Sequence[TouchEvent]) -> _Ev:
    if not events:
        return _Ev(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64),
                   np.zeros((0, 2)))
    frame = np.fromiter((e.frame for e in events), np.int64, len(events))
    ids = np.fromiter((e.id for e in events), np.int64, len(events))
    state = np.fromiter((_STATE_CODE.get(e.state, -1) for e in events), np.int64, len(events))
    if np.any(state < 0):
        bad = next(e.state for e in events if e.state not in _STATE_CODE)
        raise SourceError(f"event state {bad!r} is unknown; expected down, move or up")
    xy = np.array([(e.x, e.y) for e in events], dtype=np.float64)
    order = np.argsort(frame, kind="stable")
    return _Ev(frame[order], ids[order], state[order], xy[order])


def _slices(frames: np.ndarray, n_frames: int) -> np.ndarray:
    """Start offsets (n_frames + 1,) of each frame's rows in a frame-sorted array."""
    return np.searchsorted(frames, np.arange(n_frames + 1), side="left")


# --- evaluation ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class EvalResult:
    """Raw, poolable numbers of one recording (see :func:`~depthtouch.evaluation.summary.summarize`).

    Per contact episode (E,): ep_id, ep_first/ep_last frame, ep_found, ep_visible (the tip is
    not hidden from the camera in at least one frame), ep_frames_scored (visible contact frames
    after the first ``settle_frames``), ep_frames_matched (of those), ep_down_latency and
    ep_lift_latency (frames; NaN when not found / no ``up``), ep_id_switches, ep_path_mm (true
    path length), ep_angle_deg (mean angle error of a drag, NaN otherwise), ep_angle_steps.
    errors_mm: surface error of every matched (reported, contact) pair.
    false_frame, false_id, false_frames, false_hover_height_mm: per false track (F,), its first
    frame, reported id, frames reported, and the height of the hover it came near (NaN = other).
    still_sq_sum_mm2, still_count: pooled squared deviations of still-finger runs (for jitter).
    timing_ms: per-frame processing time when the caller measured it.
    false_last: per false track, its last frame. change_frames: frames of surface changes
    (:data:`SURFACE_CHANGES` events in the truth). ep_merged: per episode, it was first
    reported under an id that an earlier episode, already ended, was reported under: the
    sensor kept the touch down between them (a finger hovering low between two taps), so an app
    saw one touch where there were two. early_hover_height_mm: per matched track that was
    reported down before its first match while near a hovering fingertip, the highest hover
    height on those frames: it went down in the air and then slid into the contact, which the
    false-touch count does not see (an app saw the touch start above the surface).
    ep_miss_reason: per episode, why a contact the camera saw was missed ("" when found or
    hidden throughout; empty without the run's point notes): the most common, over its visible
    frames, of the nearest point's reason within the gate
    (:func:`depthtouch.tracking.evidence.point_reasons`) and, without one, what the band held
    there (:data:`BAND_STATES`; "no point" where the run noted nothing of it).
    """

    label: str
    n_frames: int
    duration_s: float
    ep_id: np.ndarray
    ep_first: np.ndarray
    ep_last: np.ndarray
    ep_found: np.ndarray
    ep_visible: np.ndarray
    ep_frames_scored: np.ndarray
    ep_frames_matched: np.ndarray
    ep_down_latency: np.ndarray
    ep_lift_latency: np.ndarray
    ep_id_switches: np.ndarray
    ep_path_mm: np.ndarray
    ep_angle_deg: np.ndarray
    ep_angle_steps: np.ndarray
    errors_mm: np.ndarray
    false_frame: np.ndarray
    false_id: np.ndarray
    false_frames: np.ndarray
    false_hover_height_mm: np.ndarray
    still_sq_sum_mm2: float
    still_count: int
    timing_ms: np.ndarray
    false_last: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    change_frames: tuple[int, ...] = ()
    ep_merged: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    early_hover_height_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ep_miss_reason: tuple[str, ...] = ()


class FrameNotes(NamedTuple):
    """What a run noted of one frame, for naming missed contacts: its touch points' pixels
    (N, 2) and a reason per point (:func:`depthtouch.tracking.evidence.point_reasons`); and at
    some pixels (M, 2) (the truth's contacts of that frame), what the band held near each,
    when no point did (:data:`BAND_STATES`)."""

    xy_px: np.ndarray
    reasons: Sequence[str]
    probe_xy_px: np.ndarray = np.zeros((0, 2))
    probe_states: Sequence[str] = ()


#: per frame index, a run's notes
PointNotes = Mapping[int, FrameNotes]
#: what lay near a contact that no touch point came near: nothing in the touch band; band pixels
#: that the opening erased (a part thinner than the opening: the front of a steep finger); an
#: opened part that gave no point (under S_min, or no hand attached to it)
BAND_STATES = ("nothing in the band", "band erased by the opening", "a region without a point")
NO_POINT = "no point"


def _miss_reason(rows: np.ndarray, truth: Truth, notes: PointNotes, gate_mm: float) -> str:
    """The most common reason over a missed episode's visible frames (``rows``: its contact
    rows); ties go to the reason seen first."""
    count: dict[str, int] = {}
    for r in rows.tolist():
        if truth.contact_occluded[r]:
            continue
        why = NO_POINT
        note = notes.get(int(truth.contact_frame[r]))
        if note is not None and len(note.xy_px):
            d, _ = surface_error_mm(note.xy_px, truth.K, truth.contact_p_mm[r:r + 1],
                                    truth.contact_n[r:r + 1])
            k = int(np.argmin(d[:, 0]))
            if d[k, 0] <= gate_mm:
                why = str(note.reasons[k])
        if why == NO_POINT and note is not None and len(note.probe_xy_px):
            gap = np.hypot(*(note.probe_xy_px - truth.contact_xy_px[r]).T)
            k = int(np.argmin(gap))
            if gap[k] < 0.5:
                why = str(note.probe_states[k])
        count[why] = count.get(why, 0) + 1
    return max(count, key=lambda k: count[k]) if count else ""


def _episodes(frame: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Episode index per contact row: a truth id over consecutive frames (rows sorted by frame)."""
    order = np.lexsort((frame, ids))
    f, i = frame[order], ids[order]
    new = np.ones(len(f), bool)
    new[1:] = (i[1:] != i[:-1]) | (f[1:] != f[:-1] + 1)
    ep_sorted = np.cumsum(new) - 1
    ep = np.empty(len(f), np.int64)
    ep[order] = ep_sorted
    return ep


def evaluate(
    truth: Truth,
    events: Sequence[TouchEvent],
    *,
    gate_mm: float = GATE_MM,
    settle_frames: int = 2,
    drag_min_path_mm: float = 20.0,
    min_step_mm: float = 0.5,
    angle_step_frames: int = 3,
    still_step_mm: float = 0.05,
    min_still_frames: int = 10,
    timing_ms: Sequence[float] | np.ndarray | None = None,
    label: str = "",
    point_notes: PointNotes | None = None,
) -> EvalResult:
    """Match ``events`` to ``truth`` frame by frame and collect the raw metrics.

    gate_mm: largest surface distance of a match (default 20). settle_frames: contact frames at
    the start of each episode left out of frame recall (the tracker's debounce; default 2).
    drag_min_path_mm: an episode whose true path is at least this long is a drag (default 20).
    min_step_mm: true steps shorter than this are skipped in the angle error (default 0.5).
    angle_step_frames: the angle error compares displacements over this many frames (default 3,
    the issue tracker's "3-frame steps"; 1 is the paper's frame-to-frame measure).
    still_step_mm / min_still_frames: a still run is >= min_still_frames consecutive matched
    frames whose true point moves less than still_step_mm per frame (defaults 0.05, 10).
    """
    if not gate_mm > 0:
        raise ConfigError(f"gate_mm = {gate_mm} is out of range; give a gate > 0 mm")
    if angle_step_frames < 1:
        raise ConfigError(f"angle_step_frames = {angle_step_frames} is out of range; give 1 or more")
    ev = _events_arrays(events)
    # the pipeline's finish() may end touches with an `up` one frame after the last frame
    if ev.frame.size and int(ev.frame.max()) > truth.n_frames:
        raise SourceError(
            f"events reach frame {int(ev.frame.max())} but the truth has {truth.n_frames} "
            "frames; give the truth file of this recording"
        )
    n = truth.n_frames + 1
    K = truth.K
    c_f, h_f = truth.contact_frame, truth.hover_frame
    c_start, h_start = _slices(c_f, n), _slices(h_f, n)
    active = ev.state != _STATE_CODE["up"]
    a_frame, a_id, a_xy = ev.frame[active], ev.id[active], ev.xy[active]
    a_start = _slices(a_frame, n)

    m = len(c_f)
    matched_rid = np.full(m, -1, np.int64)  # reported id matched to each contact row
    q_mm = np.full((m, 3), np.nan)
    err = np.full(m, np.nan)
    a_matched = np.zeros(len(a_frame), bool)
    a_hover_h = np.full(len(a_frame), np.nan)
    for f in range(n):
        a0, a1 = a_start[f], a_start[f + 1]
        if a0 == a1:
            continue
        c0, c1 = c_start[f], c_start[f + 1]
        xy = a_xy[a0:a1]
        free = np.ones(a1 - a0, bool)
        if c1 > c0:
            d, q = surface_error_mm(xy, K, truth.contact_p_mm[c0:c1], truth.contact_n[c0:c1])
            r, c = match(d, gate_mm)
            matched_rid[c0 + c] = a_id[a0 + r]
            q_mm[c0 + c] = q[r, c]
            err[c0 + c] = d[r, c]
            a_matched[a0 + r] = True
            free[r] = False
        h0, h1 = h_start[f], h_start[f + 1]
        if h1 > h0 and free.any():
            d, _ = surface_error_mm(xy[free], K, truth.hover_p_mm[h0:h1], truth.hover_n[h0:h1])
            near = d <= gate_mm
            heights = np.where(near, truth.hover_height_mm[h0:h1][None, :], np.inf).min(axis=1)
            a_hover_h[a0 + np.flatnonzero(free)] = np.where(np.isfinite(heights), heights, np.nan)

    # false tracks: reported ids never matched in any frame
    true_ids = np.unique(a_id[a_matched])
    false_mask = ~np.isin(a_id, true_ids)
    f_ids = np.unique(a_id[false_mask])
    false_first = np.zeros(len(f_ids), np.int64)
    false_frames = np.zeros(len(f_ids), np.int64)
    false_last = np.zeros(len(f_ids), np.int64)
    false_h = np.full(len(f_ids), np.nan)
    for k, rid in enumerate(f_ids):
        sel = a_id == rid
        false_first[k] = a_frame[sel].min()
        false_frames[k] = np.unique(a_frame[sel]).size
        false_last[k] = a_frame[sel].max()
        hs = a_hover_h[sel]
        if np.any(np.isfinite(hs)):
            false_h[k] = np.nanmin(hs)

    # matched tracks that were down before their first match, near a hovering fingertip
    early_h = []
    for rid in true_ids.tolist():
        sel = a_id == rid
        first = a_frame[sel & a_matched].min()
        hs = a_hover_h[sel & (a_frame < first)]
        if np.any(np.isfinite(hs)):
            early_h.append(float(np.nanmax(hs)))

    # contact episodes
    ep = _episodes(c_f, truth.contact_id) if m else np.zeros(0, np.int64)
    n_ep = int(ep.max()) + 1 if m else 0
    up_sel = ev.state == _STATE_CODE["up"]
    up_frame_of = dict(zip(ev.id[up_sel].tolist(), ev.frame[up_sel].tolist(), strict=True))
    out: dict[str, list[Any]] = {k: [] for k in (
        "id", "first", "last", "found", "visible", "scored", "matched", "down", "lift", "switch", "path",
        "angle", "steps")}
    sq_sum, sq_count = 0.0, 0
    # per episode: first matched frame and id, last matched frame, every matched id (merges)
    seen_ids: list[tuple[int, int, int, set[int]]] = []
    for e in range(n_ep):
        rows = np.flatnonzero(ep == e)  # sorted by frame (rows are frame-sorted)
        fr = c_f[rows]
        rid = matched_rid[rows]
        ok = rid >= 0
        p = truth.contact_p_mm[rows]
        steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
        out["id"].append(int(truth.contact_id[rows[0]]))
        out["first"].append(int(fr[0]))
        out["last"].append(int(fr[-1]))
        visible = ~truth.contact_occluded[rows]
        out["found"].append(bool(ok.any()))
        out["visible"].append(bool(visible.any()))
        out["scored"].append(int(visible[settle_frames:].sum()))
        out["matched"].append(int((ok & visible)[settle_frames:].sum()))
        out["path"].append(float(steps.sum()))
        if ok.any():
            out["down"].append(float(fr[ok][0] - fr[0]))
            ids_seq = rid[ok]
            seen_ids.append((int(fr[ok][0]), int(ids_seq[0]), int(fr[ok][-1]),
                             set(ids_seq.tolist())))
            out["switch"].append(int(np.count_nonzero(ids_seq[1:] != ids_seq[:-1])))
            up = up_frame_of.get(int(ids_seq[-1]))
            out["lift"].append(float(up - (fr[-1] + 1)) if up is not None else math.nan)
        else:
            out["down"].append(math.nan)
            out["switch"].append(0)
            out["lift"].append(math.nan)
        # angle error between successive displacement vectors (matched frames only)
        ang, nst = math.nan, 0
        if out["path"][-1] >= drag_min_path_mm and np.count_nonzero(ok) >= angle_step_frames + 2:
            pt, qt, ft = p[ok], q_mm[rows][ok], fr[ok]
            k = angle_step_frames
            span = ft[k:] - ft[:-k] == k  # steps between matched frames k frames apart
            dt, dq = (pt[k:] - pt[:-k])[span], (qt[k:] - qt[:-k])[span]
            lt, lq = np.linalg.norm(dt, axis=1), np.linalg.norm(dq, axis=1)
            use = (lt >= min_step_mm) & (lq > 1e-9)
            if use.any():
                cosv = np.sum(dt[use] * dq[use], axis=1) / (lt[use] * lq[use])
                ang = float(np.degrees(np.arccos(np.clip(cosv, -1.0, 1.0))).mean())
                nst = int(use.sum())
        out["angle"].append(ang)
        out["steps"].append(nst)
        # jitter: runs of consecutive matched frames where the truth is still
        still = np.zeros(len(rows), bool)
        still[1:] = steps < still_step_mm
        still[0] = len(rows) > 1 and steps[0] < still_step_mm
        good = still & ok
        qe = q_mm[rows]
        for r0, r1 in _runs(good):
            if r1 - r0 >= min_still_frames:
                qq = qe[r0:r1]
                sq_sum += float(np.sum((qq - qq.mean(axis=0)) ** 2))
                sq_count += r1 - r0

    def arr(key: str, dtype: type) -> np.ndarray:
        return np.asarray(out[key], dtype=dtype)

    merged = np.zeros(n_ep, bool)
    found_eps = np.flatnonzero(np.asarray(out["found"], bool))
    for e_k, (first_f, first_id, _, _) in zip(found_eps.tolist(), seen_ids, strict=True):
        merged[e_k] = any(first_id in ids and last_f < first_f for _, _, last_f, ids in seen_ids)

    return EvalResult(
        label=label or str(truth.meta.get("scene", "")),
        n_frames=truth.n_frames,
        duration_s=truth.duration_s,
        ep_id=arr("id", np.int64), ep_first=arr("first", np.int64),
        ep_last=arr("last", np.int64), ep_found=arr("found", bool),
        ep_visible=arr("visible", bool),
        ep_frames_scored=arr("scored", np.int64), ep_frames_matched=arr("matched", np.int64),
        ep_down_latency=arr("down", float), ep_lift_latency=arr("lift", float),
        ep_id_switches=arr("switch", np.int64), ep_path_mm=arr("path", float),
        ep_angle_deg=arr("angle", float), ep_angle_steps=arr("steps", np.int64),
        errors_mm=err[np.isfinite(err)],
        false_frame=false_first, false_id=f_ids.astype(np.int64), false_frames=false_frames,
        false_hover_height_mm=false_h,
        still_sq_sum_mm2=sq_sum, still_count=sq_count, ep_merged=merged,
        timing_ms=np.asarray(timing_ms if timing_ms is not None else [], dtype=np.float64),
        false_last=false_last,
        early_hover_height_mm=np.asarray(early_h, np.float64),
        change_frames=_change_frames(truth),
        ep_miss_reason=(() if point_notes is None else tuple(
            _miss_reason(np.flatnonzero(ep == e), truth, point_notes, gate_mm)
            if visible_ep and not found_ep else ""
            for e, (found_ep, visible_ep) in enumerate(zip(out["found"], out["visible"],
                                                           strict=True)))),
    )


SURFACE_CHANGES = ("object_placed", "object_removed", "bump")


def _change_frames(truth: Truth) -> tuple[int, ...]:
    """Frames of the truth's surface-change events (an object put down or taken, a bump)."""
    events = truth.meta.get("events", [])
    return tuple(sorted(int(e["frame"]) for e in events if isinstance(e, dict)
                        and e.get("kind") in SURFACE_CHANGES and isinstance(e.get("frame"), int)))


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) of each run of True in a 1-D boolean array."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))
