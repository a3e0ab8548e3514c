"""Frozen per-stage configuration, with units in the names, loadable from and savable to TOML.

Every field has a documented default; ``validate()`` raises :class:`ConfigError` naming the
allowed range. A TOML file has one table per stage (``[surface]``, ``[regions]``, ...), and may
leave out anything that keeps its default.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .checks import check_range as _range
from .checks import show as _show
from .errors import ConfigError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


def _key(key: object, limit: int = 30) -> str:
    """A user's key for a one-line message: unquoted, whitespace collapsed, shortened."""
    text = " ".join(str(key).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


@dataclass(frozen=True)
class SurfaceConfig:
    """Surface model ("virtual touch panel").

    learn_s: seconds of empty-surface frames to learn from (default 1.5, range (0, 60]).
    learn_frames: number of frames instead of seconds when set (range [2, 10000]).
    statistic: per-pixel surface depth: "mean", "mode" (the paper's two), or "median".
    min_valid_fraction: a pixel is usable when at least this share of its learning samples is
        valid (non-zero) (default 0.5, range (0, 1]).
    noise_floor_mm: lower bound of a pixel's noise sigma in mm (default 0.5, range [0, 50]).
    relearn_s: seconds of frames to learn the surface again after a camera bump, shorter than the
        first learning so that touches come back soon (default 0.5, range (0, 60]).
    """

    learn_s: float = 1.5
    learn_frames: int | None = None
    statistic: str = "median"
    min_valid_fraction: float = 0.5
    noise_floor_mm: float = 0.5
    relearn_s: float = 0.5

    def validate(self) -> None:
        _range("surface.learn_s", self.learn_s, 0.0, 60.0, lo_open=True)
        _range("surface.relearn_s", self.relearn_s, 0.0, 60.0, lo_open=True)
        if self.learn_frames is not None:
            _range("surface.learn_frames", self.learn_frames, 2, 10000)
        if self.statistic not in ("mean", "mode", "median"):
            raise ConfigError(
                f"surface.statistic = {self.statistic!r} is unknown; use mean, mode or median"
            )
        _range("surface.min_valid_fraction", self.min_valid_fraction, 0.0, 1.0, lo_open=True)
        _range("surface.noise_floor_mm", self.noise_floor_mm, 0.0, 50.0)


@dataclass(frozen=True)
class RegionConfig:
    """Touch regions: the band Tl < height < Tu, labelled and size-filtered.

    noise_k: Tl of a pixel is max(tl_floor_mm, noise_k * sigma) (default 3.0, range [0, 20]).
    tl_floor_mm: lower bound of Tl in mm (default 4.0, range [0, 50]).
    tu_mm: Tu, finger scale; pixels higher than this are hand/arm (default 25.0, (0, 200]).
    hand_max_mm: pixels higher than this above the surface are not a hand (default 600, > tu).
    min_area_mm2: S_min as an area on the surface (default 40 mm^2); converted to pixels from
        the distance and focal length, and never fewer than min_area_floor_px.
    min_area_floor_px: lower bound of S_min in pixels (default 4).
    open_px: side of the square opening applied to the band mask before labelling, which removes
        one-pixel noise and depth-edge slivers (odd, default 3; 1 = off).
    open_tip_px: the opening is used only where a fingertip (twice the tip radius) spans at
        least this many pixels on the surface (default 5, range [0, 100]). At a coarser scale
        the band under a finger held at a slant can be thinner than the opening, which would
        erase the contact: structured light at 1.8 m, ToF and stereo at 1.2 m (a fingertip
        4.3-5.0 px across) go without it.
    block_tip_px: where the opening is not used and a fingertip still spans at least this many
        pixels, a region must hold a 2x2 block of band pixels: lines one pixel wide (mixed
        pixels along the edge of a finger hovering over ToF) are dropped, and no region is cut
        (default 4, range [0, 100], at most open_tip_px; farther, ToF at 1.3-2 m, every region
        counts).
    open_band_px: the opening is also used where a fingertip spans at least block_tip_px and
        the band is deep: Tu minus the median Tl spans at least this many pixels on the surface
        (a finger at 45 deg leaves a band that wide; default 6.0, twice the opening, range
        [0, 100], 0 = off). ToF at 1.1-1.2 m qualifies (Tl 4 mm, 6-7 px): without the opening
        the mixed pixels along a finger's sides join its tip region, which then looks attached
        along the finger like a forearm's edge. Structured light at 1.7-1.8 m and stereo at
        1.2 m do not (Tl 10-16 mm, 3-5 px): the opening would erase a slanted finger's band.
    min_hand_mm2: a raised part not connected to the image border counts as a hand when at least
        this large (default 6000 mm^2, a palm); see handmap.hand_map.
    median_px: a median filter of this size (1 = off, 3 or 5) on every depth frame, the surface
        frames included, before anything else: it removes isolated missing pixels and flying
        pixels and halves stereo noise, so that Tl (which follows the filtered noise) can be low
        enough for a fingertip on a noisy camera (default 3).
    """

    noise_k: float = 3.0
    tl_floor_mm: float = 4.0
    tu_mm: float = 25.0
    hand_max_mm: float = 600.0
    min_area_mm2: float = 40.0
    min_area_floor_px: int = 4
    open_px: int = 3
    open_tip_px: float = 5.0
    block_tip_px: float = 4.0
    open_band_px: float = 6.0
    median_px: int = 3
    min_hand_mm2: float = 6000.0

    def validate(self) -> None:
        _range("regions.noise_k", self.noise_k, 0.0, 20.0)
        _range("regions.tl_floor_mm", self.tl_floor_mm, 0.0, 50.0)
        _range("regions.tu_mm", self.tu_mm, 0.0, 200.0, lo_open=True)
        if self.tu_mm <= self.tl_floor_mm:
            raise ConfigError(
                f"regions.tu_mm = {self.tu_mm} must be above regions.tl_floor_mm = "
                f"{self.tl_floor_mm}"
            )
        _range("regions.hand_max_mm", self.hand_max_mm, self.tu_mm, 5000.0, lo_open=True)
        _range("regions.min_area_mm2", self.min_area_mm2, 0.0, 10000.0)
        _range("regions.min_area_floor_px", self.min_area_floor_px, 1, 10000)
        _range("regions.open_px", self.open_px, 1, 15)
        if self.open_px % 2 == 0:
            raise ConfigError(
                f"regions.open_px = {self.open_px!r} must be odd (a square with a centre pixel); "
                "allowed [1, 15]: 1, 3, 5, ..."
            )
        _range("regions.open_tip_px", self.open_tip_px, 0.0, 100.0)
        _range("regions.block_tip_px", self.block_tip_px, 0.0, self.open_tip_px)
        _range("regions.open_band_px", self.open_band_px, 0.0, 100.0)
        _range("regions.min_hand_mm2", self.min_hand_mm2, 0.0, 1e6)
        _range("regions.median_px", self.median_px, 1, 5)
        if self.median_px not in (1, 3, 5):
            raise ConfigError(
                f"regions.median_px = {self.median_px!r} must be odd; allowed [1, 5]: 1, 3 or 5"
            )


@dataclass(frozen=True)
class TouchPointConfig:
    """Touch point per region.

    method: "extremity" (fingertip extremity along the direction from the hand, sub-pixel) or
        "paper" (Lee & Kwon: search band Ds from the bounding box edge, candidates within Tt of
        the surface, 3x3 block confirmation).
    tip_radius_mm: fallback fingertip radius when the width cannot be measured (default 7.0).
    touch_on_mm: a region's tip must come this close to the surface to go down (default 14).
    touch_off_mm: a touching tip is lifted above this height (hysteresis; default 18).
    paper_ds_px: Ds of the paper's method (default 6).
    paper_tt_mm: Tt of the paper's method (default 18.0: a fingertip's top seen from above is about
        its diameter, 12-20 mm, above the surface).
    tip_axis_mm: height above the surface of the point on the finger whose image the extremity
        method finds (about a finger's radius); the touch point is moved to the surface point
        beneath it, which matters where the camera sees the surface obliquely
        (:mod:`depthtouch.touch.parallax`); 0 reports the image point as found (default 9).
    tip_tl_shift: where the depth is noisy, Tl rises above its floor and cuts more of the tip's
        front: the extremity method finds the tip behind its contact. The reported contact is
        moved forward along its finger by this many mm per mm of Tl above the floor around its
        pixel (tracking still uses the unmoved point). Default 0.6 (session 25; 0.4 before):
        a thin fingertip loses more of its front to Tl than the capsule hand the 0.4 was chosen
        on (session 11: error median / p95 2.33 / 6.98 mm off, 1.90 / 6.02 at 0.4, 1.70 / 5.75
        at 0.6 on hard's tune half). Tune halves, 0.4 -> 0.6 -> 0.8, error median / p95 and
        jitter: hard 1.76 / 5.19, 0.77 -> 1.58 / 5.05, 0.81 -> 1.49 / 4.91, 0.82 mm;
        hard-fresh2 1.48 / 5.84 -> 1.47 / 5.55 -> 1.68 / 5.44 mm; hard-fresh3 (another hand)
        4.04 / 10.23 -> 3.74 / 9.22 -> 3.41 / 8.97 mm; its capsule control 1.93 / 5.52 -> 1.75 /
        5.56 -> 1.68 / 5.81 mm. Held-out, 0.4 -> 0.6: hard 1.47 / 5.62 -> 1.42 / 5.01 mm,
        jitter 0.776 -> 0.817 mm; hard-fresh2 1.97 / 6.39 -> 1.77 / 6.15 mm; hard-fresh3
        3.63 / 8.86 -> 3.35 / 7.96 mm; recall, false touches and id switches unchanged
        (docs/accuracy.md, session 25; range [0, 5], 0 = off).
    tip_shift_mm: the reported contact is moved forward along its finger by this many mm more,
        wherever its finger's direction is known (the Tl shift above comes on top; tracking
        still uses the unmoved point). The extremity finds the tip's centre behind its contact
        at the Tl floor too: median 0.6 px along the finger on the hard suite's own hand, 1.1 px
        on the other hand (hard-fresh3), 1-3.8 px on stereo cameras. Its direction is the
        contact's smoothed one (``TrackingConfig.report_dir_weight``). Default 1.25, chosen in
        session 36 as the shift whose worse hand does best on the tune halves (the two hand
        models put the contact 2-4 mm apart under one silhouette); held-out error median / p95:
        hard-fresh3 (the other hand) 3.35 / 7.99 -> 2.62 / 7.59 mm, hard-cylinder 2.91 / 6.66 ->
        2.19 / 5.68, hard 1.40 / 4.92 -> 1.35 / 5.04, hard-fresh2 1.72 / 5.98 -> 1.84 / 5.78,
        hard-extra 1.54 / 3.87 -> 1.80 / 4.46 mm; recall, false touches and id switches
        unchanged, jitter +0.02 mm at most, angle +0.1 deg at most (docs/accuracy.md). For a
        hand like the simulator's capsule (a rounded tip that touches under its centre), 0 is
        more exact by 0.1-0.5 mm. Range [0, 20].
    tip_beside_px: the extremity method grows a tip's region into the raised pixels within two
        tip radii (its cap, cut away by Tl); of those, only the ones within this many px of
        the region's own extent across the finger place the contact (all give its height).
        Beside a tip lies another finger or the hand's side: a middle finger hovering 21 mm
        beside a touching index pulled its contact 8 mm toward it. Default 2, chosen on the
        tune sides of the hard suites (1 px: error lower still, but more id switches and false
        touches at ToF range; 3 px: most of the gain gone); docs/accuracy.md section 7,
        session 23 (range [0, 1000]; 1000 = no limit, as before).
    """

    method: str = "extremity"
    tip_radius_mm: float = 7.0
    touch_on_mm: float = 14.0
    touch_off_mm: float = 18.0
    paper_ds_px: int = 6
    paper_tt_mm: float = 18.0
    tip_axis_mm: float = 9.0
    tip_tl_shift: float = 0.6
    tip_shift_mm: float = 1.25
    tip_beside_px: float = 2.0

    def validate(self) -> None:
        if self.method not in ("extremity", "paper"):
            raise ConfigError(
                f"touchpoints.method = {self.method!r} is unknown; use extremity or paper"
            )
        _range("touchpoints.tip_radius_mm", self.tip_radius_mm, 0.0, 30.0, lo_open=True)
        _range("touchpoints.touch_on_mm", self.touch_on_mm, 0.0, 200.0, lo_open=True)
        _range("touchpoints.touch_off_mm", self.touch_off_mm, self.touch_on_mm, 200.0)
        _range("touchpoints.paper_ds_px", self.paper_ds_px, 1, 100)
        _range("touchpoints.paper_tt_mm", self.paper_tt_mm, 0.0, 200.0, lo_open=True)
        _range("touchpoints.tip_axis_mm", self.tip_axis_mm, 0.0, 50.0)
        _range("touchpoints.tip_tl_shift", self.tip_tl_shift, 0.0, 5.0)
        _range("touchpoints.tip_shift_mm", self.tip_shift_mm, 0.0, 20.0)
        _range("touchpoints.tip_beside_px", self.tip_beside_px, 0.0, 1000.0)


@dataclass(frozen=True)
class TrackingConfig:
    """Tracking: optimal assignment, debounce and grace.

    gate_mm: largest jump between frames that keeps an id, when K is known (default 40).
    gate_px: the same when K is unknown (default 25).
    gate_fps: when set (e.g. 30), the frame rate gate_mm and gate_px are meant at. In a
        slower stream (from the frames' timestamps, more than 10 % slower) the gate of a
        contact that is down then grows with the frame interval: 80 mm at 15 fps, where a
        finger that starts a drag from rest jumps 45-50 mm in one frame at ToF 1.2 m and lost
        its id with 40 mm. A pending contact keeps the plain gate (grown for all, it let a
        pending tap take a hand's point at ToF 2 m). Default 0: the gate is per frame at any
        rate. Measured on the hard suite rendered at 15 fps, 30 against 0 (docs/accuracy.md,
        session 27): id switches 7 -> 3 (tune) and 7 -> 0 (held-out), recall 0.964 -> 0.964
        and 0.958 -> 0.964, false touches 6 -> 7 and 12 -> 9; but a false touch on a carried
        box followed it for 59 frames instead of 31, next to a hand 60 mm up, which failed
        the held-out rule (no more false touches from hovers >= 25 mm), so it is off by
        default. For a camera at 15 fps (a Kinect v2 in low light), 30 is the measured
        choice. Range [0, 1000] Hz.
    down_frames: evidence a new contact needs before ``down``, in frames of a fingertip-sized
        region (default 2, >= 1): consecutive frames, each counting 1 when the region's area lies
        in [tip_area_min_mm2, tip_area_max_mm2] and ``weak_evidence`` otherwise.
    tip_area_min_mm2 / tip_area_max_mm2: the area of a touching fingertip's region (default
        150 and 750 mm^2; a speck at a finger's edge is smaller, a hovering finger lying in the
        band or a forearm's edge larger). Only used when the surface scale is known.
    tip_area_min_px / tip_area_max_px: the same range in pixels, where pixels are large: a
        region needs at least tip_area_min_px pixels, and up to tip_area_max_px is never too
        large. At range a fingertip spans few pixels and the ring of mixed pixels around a
        finger lying in the band is most of its region, so its area in mm² says little
        (defaults 16 and 80; they change the range only where a pixel spans more than 3.1 mm,
        e.g. a ToF camera at 1.3-2 m. At 2 m touching fingertips' regions measured 14-73 px,
        5th-95th percentile, the other regions 4-9 px, 5th-75th: specks coming and going beside
        fingers. Chosen on the hard suite's tune half: at ToF 2 m 20 false touches -> 2, recall
        unchanged; ranges [0, 10000] and [0, 1e5], 0 turns either off).
    weak_evidence: what one frame of a region outside that range counts (default 0.4, range
        (0, 1]; 1 turns the size test off): with down_frames 2 it needs 5 frames.
    weak_quiet_evidence: the same where the depth is quiet: Tl around the point within 1 mm
        of its floor (TouchPoints.tl_above_floor_mm). There Tl cuts little of a touching tip,
        whose region is whole, and a small region is most often mixed pixels under the rim of
        a finger hovering above it (ToF at 1.3-2 m: 4-15 px regions under fingers 25-60 mm up,
        which went down after five frames); where Tl is high, a touching tip's region is a
        sliver and weak_evidence applies. Default 0.25 (session 26: 8 frames), chosen on the
        tune halves (0.2 lost a fast drag at stereo 0.6 m, where Tl is at its floor too);
        held-out, 0.4 -> 0.25: false touches hard 11 -> 8, hard-fresh2 8 -> 4, hard-fresh3
        10 -> 8 (from hovers >= 25 mm 2 -> 0), hover-tof 11 -> 2 (4 -> 0); touches down while
        the finger was still >= 25 mm up 21 -> 6 over the four; recall unchanged but one
        contact on hover-tof (0.986 -> 0.972); still-finger jitter on hard 0.82 -> 0.93 mm
        (docs/accuracy.md, session 26). Range (0, 1]; equal to weak_evidence turns it off.
    attach_max_mm: a fingertip hangs on its finger, so its region touches the hand along about a
        finger's width; a region attached along more than this (the edge of a forearm or a palm
        lying in the band) gives no evidence (default 30 mm, chosen on the hard suite's tune
        half; range [0, 10000], 0 turns the test off).
    attach_low_mm / attach_low_evidence: a finger whose hand is held low lies in the band
        along its length, so its region is attached as broadly as a forearm's edge; but its
        pad rests on the surface, lower than the band's noise lets an edge lie. A region that
        the attachment test refuses and whose touching pixel is at most ``attach_low_mm`` above
        the surface counts ``attach_low_evidence`` (at most) instead of nothing (defaults 3 mm
        and 0.25: about 8 frames for a down; chosen on the hard suite's tune half, where the
        refused points at true contacts lie 2.3-4.3 mm high, 5th-95th percentile, and the
        others 2.5-25 mm: recall 0.940 -> 0.964, false touches 36 -> 34; ranges [0, 100] mm,
        0 turns it off, and [0, 1]).
    step_max_mm: a finger rises from the band gradually; a region whose attached hand pixels
        lie higher than this (median, mm above the surface) is mixed or smeared pixels at the
        side of a raised hand, not a fingertip, and gives no evidence (default 80 mm, chosen on
        the hard suite's tune half: 60 lost a contact; range [0, 10000], 0 turns the test off).
    flat_max_mm: a finger rises behind its tip and stands above the surface beside it; a region
        whose heights 10-40 mm behind the tip on the finger's axis, with the nearer of those
        20 mm to either side, spread less than this (max - min, mm) lies at the edge of
        something level (the top of a book held at Tu, the flank of a resting forearm) and gives
        no evidence (default 10 mm, under the thinnest finger's 12; chosen on the hard suite's
        tune half: false touches 36 with the test off, 28 at 6 mm, 25 at 10, 18 at 22, no
        contact lost up to 22; range [0, 100], 0 turns the test off).
    up_frames: frames a contact may be missing before ``up`` (grace, default 3, >= 1): bridges
        the frame or two in which fingertips side by side merge into one region.
    up_held_frames, held_gaps, held_step_mm, held_near_mm: the grace of a flickering contact.
        Where the tip sits at the band's edge (stereo beyond 1 m), a held finger's region comes
        and goes, and each gap of ``up_frames`` ended the touch: a long press broke into
        several. A contact down whose point has already come back after missing frames
        ``held_gaps`` times (default 2; a clean touch keeps the plain grace, and its lift is not
        delayed), whose smoothed velocity is under ``held_step_mm`` per frame (default 4 mm:
        120 mm/s at 30 fps, not a swipe that leaves the surface), and whose point vanished with
        no raised point (too high to continue a contact) within ``held_near_mm`` (default
        15 mm) of it, may be missing ``up_held_frames`` frames before ``up``. 0 (the default)
        turns it off; it needs the camera's intrinsics (ranges [0, 300] frames, [1, 1e5],
        [0, 1000] mm, [0, 1000] mm). Measured with 6 frames and ``held_gaps`` 3 and left off
        (docs/config.md; docs/accuracy.md section 7, session 37).
    merge_mm: a missing contact within this distance of a contact seen this frame is taken as
        merged into its neighbour's region (fingertips side by side), not lifted (default 25 mm;
        half of it in px when K is unknown).
    merge_frames: how many frames such a merged contact is held before it may go up (default
        10, range [0, 300]).
    merge_area_ratio: a touch point whose region is at least this many times as large as the
        fingertips of two contacts near it holds both (their regions merged): both keep their
        ids and move with it, each at its place in the pair (default 1.5: one tip is 1, two
        side by side about 2; range [0, 10], 0 turns it off).
    behind_lat_mm / behind_lat_px / behind_min_mm: one finger, one tip. A point that lies on
        the axis of another point low enough to go down (the line from that point's hand to
        it), within behind_lat_mm + behind_lat_px pixels of it (a finger's radius plus the
        points' noise: 8 mm + 2 px by default, 19 mm at 2 m on a ToF camera) and between
        behind_min_mm (default 10) and 150 mm back toward the hand, is on that finger behind
        its tip: mixed pixels along the finger's flanks, or the finger itself where it dips
        into the band, and gives no evidence. Fingers side by side stand beside each other, not
        behind. Chosen on the hard suite's tune half: false touches 25 with the test off, 19 at
        12 mm + 0 px, 14 at 8 mm + 1.5 px, 12 at 8 mm + 2 px, 11 at 20 mm + 0 px, which lost a
        contact (ToF at 1.3 m); no change on the default suite. behind_lat_mm 0 turns it off
        (ranges [0, 100] mm, [0, 10] px, [0, 100] mm).
    steep_evidence, steep_*: a finger that stands almost upright hides the pad that touches under
        its own tip, so what the camera sees is the top of the tip, a finger's diameter above
        the surface, with the hand right behind it: it fails touch_on_mm, step_max_mm and
        flat_max_mm, which all assume a finger at a slant. A point whose region has the area of
        a steep tip's top (steep_area_min_mm2..steep_area_max_mm2, default 60-150 mm²), whose
        top lies steep_top_min_mm..steep_top_max_mm above the surface (default 10-26 mm), whose
        hand lies within steep_hand_mm of it (default 8 mm) and whose attached hand pixels lie
        steep_step_min_mm..steep_step_max_mm high (default 75-88 mm: the finger rising to its
        knuckles) may start a contact, and counts steep_evidence per frame (default 0.34: six
        frames in a row before down). Chosen on the hard suite's tune half: 1 more contact of
        82 (a resting forearm's steep finger), false touches unchanged; an attached height up
        to 92 or from 70 mm, or a weight of 0.5, each added a false touch (ToF at 1.3-2 m,
        fingers on their way down); a top up to 22 mm lost the contact; no change on the
        default suite. steep_evidence 0 turns it off (ranges [0, 1], areas [0, 10000] mm²,
        heights [0, 200] mm, steps [0, 10000] mm).
    pending_gap_frames: a contact not yet down whose point is missing for up to this many
        frames is kept, its evidence multiplied by pending_decay each such frame, instead of
        being dropped (a tip at range flickers at the band's edge, a fast drag at range is seen
        in half its frames). Default 1 frame and 0.75, chosen on the hard suite's tune half: 1
        more contact found of 82 for 2 more false touches; a decay of 1 found the same contact
        for 10 more, 0.5 none (ranges [0, 10] frames and [0, 1]; 0 frames turns it off).
    pending_low_mm, pending_low_gap_frames, pending_low_decay: a pending contact whose last
        point lay at most pending_low_mm above the surface (default 5 mm) is kept
        pending_low_gap_frames frames instead (default 3), at pending_low_decay (default 0.9),
        where pixels are small enough for the size test to work in mm (tip_area_min_mm2 /
        tip_area_min_px: 3.06 mm per pixel or less). The tip of a steep finger at ToF 1 m is
        a 9-12 px region, 3-5 mm up, that comes back within a pixel every 2-6 frames; at
        range, specks beside fingers lie as low. Chosen on the tune sides of the hard and
        hard-extra suites: 2 more contacts of 70 on hard-extra (a 54-frame hold under drift, a
        still hold), nothing else moved; 4-6 mm and 3-6 frames gave the same, a decay of 1 over
        6 frames 1 more contact for 3 more false touches, and without the pixel-size limit 3
        more false touches at ToF 2 m (ranges [0, 100] mm, [0, 10] frames, [0, 1]; 0 mm turns
        it off).
    lift_core_mm: a contact whose finger's core (TouchPoints.core_height_mm: the 75th
        percentile of the 3x3 heights at its point) lies more than this above the same
        contact's own level (the median over its last 300 frames of the median of its last 3
        core heights; from its 10th frame) counts as lifted in that frame, like a missing
        point: after up_frames such frames it goes ``up``, its history going on with the
        hovering finger as a pending contact; a pending contact gains no evidence in such a
        frame (see tracking/lift.py). At ToF range a hovering finger's measured tip height is
        as low as a touching one's, so the touch stayed down through the lift between two
        taps. Default 15 mm, chosen on the tune sides of hard, hard-extra and hard-fresh2:
        id switches 11 -> 8, taps merged into the previous touch 5 -> 2, false touches and
        contacts unchanged; 10 and 12 mm added 1-3 false touches (a hover-as-touch ended and
        begun again). No change on the default suite (range [0, 200] mm; 0 turns it off).
    doubt_frames: a contact that is down goes ``up`` once its point has given no evidence of a
        touch (weight 0 in evidence_weights: attached like a forearm's edge, the hand behind it
        too high, level heights behind it, or on another finger's axis) for this many frames
        in a row; the point starts over as a pending contact. Nothing else ends a contact that
        came down on the wrong thing while it stays in the band: on hard-fresh3's tune half a
        false touch on a resting hand was held for 8.7 s. Default 45 frames (1.5 s
        at 30 fps), twice the longest such run of a true contact on the tune halves of eight
        suites (22 frames: a stroke on a concave cylinder, stereo 0.9 m; 14 on the default
        suite's multitouch, 6-12 elsewhere); counted in frames like up_frames. Session 33,
        docs/accuracy.md (range [0, 100000]; 0 turns it off).
    yield_ratio / yield_min_mm: a contact that is down does not take a point that lies at
        least yield_min_mm from it when a pending contact seen in 3 frames or more, with
        evidence of at least 1, lies within yield_ratio of that distance from the point; that
        frame it counts as missing, and nobody takes the point (its own tip dropped out for a
        frame, and the nearest point was a hovering hand's beside it). Only where the scale is
        known. Defaults 0.7 and 10 mm, chosen on the tune sides of hard, hard-extra and
        hard-fresh2: id switches 8 -> 6, error p95 at the new placements 8.14 -> 7.82 mm, no
        contact or false touch changed; the held-out sets were unchanged (ranges [0, 1] and
        [0, 1000] mm; a ratio of 0 turns it off).
    report_dir_weight: the direction along which a contact's reported point is moved forward
        (``TouchPointConfig.tip_tl_shift`` and ``tip_shift_mm``) is its finger's direction
        from its hand, smoothed per contact: each frame moves it this fraction of the way to
        the frame's own. The hand's attachment moves 1-2.6 px from frame to frame while it lies
        only 3-12 px behind the tip, so each frame's direction swings 6-10 degrees on a still
        finger and the Tl shift turned that into jitter and a wavering path. Default 0.2
        (session 29; 1 uses each frame's direction, as before). Held-out, 1 -> 0.2: jitter hard
        0.934 -> 0.875, hard-fresh2 0.866 -> 0.859, hard-fresh3 1.231 -> 1.216 mm; path angle
        3.95 -> 3.72, 4.13 -> 3.58, 8.53 -> 8.32 degrees; error median and p95 within
        -0.13..+0.01 mm; recall, false touches and id switches unchanged (docs/accuracy.md).
        Range (0, 1].
    reference_fps: when set, the frame rate the evidence toward down (down_frames and the
        weights) is meant at (every suite was recorded and tuned at 30 fps). In a faster
        stream, measured from the frames' timestamps (the median of the last 15 intervals), a
        contact's first frame then counts as one frame and each further frame as its length,
        so that down takes as long and as many frames as at that rate (reference 30 at 60
        fps: a fingertip seen 33 ms apart, in 3 frames; weak evidence 0.4: 133 ms). A slower
        stream, or one within 10 % of the rate (timestamps in whole ms), counts frames: noise
        comes frame by frame. up_frames, merge_frames and the pending counts stay in frames.
        Default 0: frames count as frames at any rate. Measured on the hard suite rendered at
        60 fps (docs/accuracy.md, session 27), 30 against 0: tune half 30 -> 11 false
        touches, recall 0.994 both; held-out half 42 -> 15 false touches (4.3 -> 1.5 per
        minute) but recall 0.976 -> 0.946, which failed the rule written before that run, so
        it is off by default. Range [0, 1000] Hz.
    """

    gate_mm: float = 40.0
    gate_px: float = 25.0
    down_frames: int = 2
    tip_area_min_mm2: float = 150.0
    tip_area_max_mm2: float = 750.0
    tip_area_min_px: float = 16.0
    tip_area_max_px: float = 80.0
    weak_evidence: float = 0.4
    weak_quiet_evidence: float = 0.25
    attach_max_mm: float = 30.0
    attach_low_mm: float = 3.0
    attach_low_evidence: float = 0.25
    step_max_mm: float = 80.0
    flat_max_mm: float = 10.0
    up_frames: int = 3
    up_held_frames: int = 0
    held_gaps: int = 2
    held_step_mm: float = 4.0
    held_near_mm: float = 15.0
    merge_mm: float = 25.0
    merge_frames: int = 10
    merge_area_ratio: float = 1.5
    behind_lat_mm: float = 8.0
    behind_lat_px: float = 2.0
    behind_min_mm: float = 10.0
    pending_gap_frames: int = 1
    pending_decay: float = 0.75
    pending_low_mm: float = 5.0
    pending_low_gap_frames: int = 3
    pending_low_decay: float = 0.9
    steep_evidence: float = 0.34
    steep_area_min_mm2: float = 60.0
    steep_area_max_mm2: float = 150.0
    steep_top_min_mm: float = 10.0
    steep_top_max_mm: float = 26.0
    steep_hand_mm: float = 8.0
    steep_step_min_mm: float = 75.0
    steep_step_max_mm: float = 88.0
    lift_core_mm: float = 15.0
    doubt_frames: int = 45
    yield_ratio: float = 0.7
    yield_min_mm: float = 10.0
    report_dir_weight: float = 0.2
    reference_fps: float = 0.0
    gate_fps: float = 0.0

    def validate(self) -> None:
        _range("tracking.gate_mm", self.gate_mm, 0.0, 1000.0, lo_open=True)
        _range("tracking.gate_px", self.gate_px, 0.0, 1000.0, lo_open=True)
        _range("tracking.down_frames", self.down_frames, 1, 30)
        _range("tracking.up_frames", self.up_frames, 1, 30)
        _range("tracking.up_held_frames", self.up_held_frames, 0, 300)
        _range("tracking.held_gaps", self.held_gaps, 1, 100000)
        _range("tracking.held_step_mm", self.held_step_mm, 0.0, 1000.0)
        _range("tracking.held_near_mm", self.held_near_mm, 0.0, 1000.0)
        _range("tracking.tip_area_min_mm2", self.tip_area_min_mm2, 0.0, 10000.0)
        _range("tracking.tip_area_max_mm2", self.tip_area_max_mm2, self.tip_area_min_mm2, 1e5)
        _range("tracking.tip_area_min_px", self.tip_area_min_px, 0.0, 10000.0)
        _range("tracking.tip_area_max_px", self.tip_area_max_px, 0.0, 1e5)
        _range("tracking.weak_evidence", self.weak_evidence, 0.0, 1.0, lo_open=True)
        _range("tracking.weak_quiet_evidence", self.weak_quiet_evidence, 0.0, 1.0, lo_open=True)
        _range("tracking.attach_max_mm", self.attach_max_mm, 0.0, 10000.0)
        _range("tracking.attach_low_mm", self.attach_low_mm, 0.0, 100.0)
        _range("tracking.attach_low_evidence", self.attach_low_evidence, 0.0, 1.0)
        _range("tracking.step_max_mm", self.step_max_mm, 0.0, 10000.0)
        _range("tracking.flat_max_mm", self.flat_max_mm, 0.0, 100.0)
        _range("tracking.merge_mm", self.merge_mm, 0.0, 200.0)
        _range("tracking.merge_frames", self.merge_frames, 0, 300)
        _range("tracking.merge_area_ratio", self.merge_area_ratio, 0.0, 10.0)
        _range("tracking.behind_lat_mm", self.behind_lat_mm, 0.0, 100.0)
        _range("tracking.behind_lat_px", self.behind_lat_px, 0.0, 10.0)
        _range("tracking.behind_min_mm", self.behind_min_mm, 0.0, 100.0)
        _range("tracking.pending_gap_frames", self.pending_gap_frames, 0, 10)
        _range("tracking.pending_decay", self.pending_decay, 0.0, 1.0)
        _range("tracking.pending_low_mm", self.pending_low_mm, 0.0, 100.0)
        _range("tracking.pending_low_gap_frames", self.pending_low_gap_frames, 0, 10)
        _range("tracking.pending_low_decay", self.pending_low_decay, 0.0, 1.0)
        _range("tracking.steep_evidence", self.steep_evidence, 0.0, 1.0)
        _range("tracking.steep_area_min_mm2", self.steep_area_min_mm2, 0.0, 10000.0)
        _range("tracking.steep_area_max_mm2", self.steep_area_max_mm2, self.steep_area_min_mm2,
               10000.0)
        _range("tracking.steep_top_min_mm", self.steep_top_min_mm, 0.0, 200.0)
        _range("tracking.steep_top_max_mm", self.steep_top_max_mm, self.steep_top_min_mm, 200.0)
        _range("tracking.steep_hand_mm", self.steep_hand_mm, 0.0, 200.0)
        _range("tracking.steep_step_min_mm", self.steep_step_min_mm, 0.0, 10000.0)
        _range("tracking.steep_step_max_mm", self.steep_step_max_mm, self.steep_step_min_mm,
               10000.0)
        _range("tracking.lift_core_mm", self.lift_core_mm, 0.0, 200.0)
        _range("tracking.doubt_frames", self.doubt_frames, 0, 100000)
        _range("tracking.reference_fps", self.reference_fps, 0.0, 1000.0)
        _range("tracking.gate_fps", self.gate_fps, 0.0, 1000.0)
        _range("tracking.yield_ratio", self.yield_ratio, 0.0, 1.0)
        _range("tracking.yield_min_mm", self.yield_min_mm, 0.0, 1000.0)
        _range("tracking.report_dir_weight", self.report_dir_weight, 0.0, 1.0, lo_open=True)


@dataclass(frozen=True)
class FilterConfig:
    """Touch path correction: ``name`` of the filter and its parameters (see filters.py).

    params: finite numbers by name; which names a filter takes is checked by filters.py.
    The default, ``adaptive_euro`` (the paper's adaptive filter followed by a speed-gated 1€
    stage and a lock of a finger proven at rest), was chosen by measurement on the hard suite's
    tune half (docs/filters.md): lower jitter of a still finger and fewer id switches than the
    adaptive filter alone, the same position error and angle error; the rest lock (on by
    default since issue 13, point 4) ignores one-frame jumps of a resting tip and never
    engages on a drag of 10 mm/s or more.
    """

    name: str = "adaptive_euro"
    params: Mapping[str, float] = field(default_factory=dict)

    def validate(self) -> None:
        for k, v in self.params.items():
            if not isinstance(v, (int, float)) or isinstance(v, bool):
                raise ConfigError(f"filter.params.{k} = {_show(v)} must be a number")
            try:
                finite = math.isfinite(v)
            except OverflowError:  # an integer beyond float range
                finite = False
            if not finite:
                raise ConfigError(f"filter.params.{k} = {_show(v)} must be a finite number")


@dataclass(frozen=True)
class AdaptConfig:
    """Surface adaptation (the paper's static-surface limitation, lifted).

    enabled: update the surface while running (default true).
    absorb_s: a change of the surface that stays still this long becomes surface (an object put
        down, or taken away) (default 0.5 s, range [0.1, 60]); checked once per stripe cycle
        (every 0.8 s at 30 fps), so a change is surface 1.2-1.6 s after it stopped moving.
    still_mm: a pixel is still when it moves less than max(still_mm, 3 sigma) between two visits
        (default 3.0 mm).
    drift_tau_s: time constant of the slow update of unchanged pixels (temperature drift)
        (default 10 s, range [1, 3600]).
    drift_gain: share of a stripe's median offset from the surface (over its unchanged pixels)
        that moves the whole stripe at each visit, so a steady drift does not pile up into the
        band (default 0.5, range [0, 1], 0 = off).
    stripes: the update visits one horizontal stripe of the image per frame, so that its cost is
        spread evenly over frames (default 24, range [1, 64]).
    bump_fraction: share of the surface changed at once that means the camera moved
        (default 0.4, range (0, 1]).
    bump_s: how long such a change must stay, still, before the surface is learned again
        (default 0.5 s).
    keep_out_mm: nothing within this distance of an active touch is absorbed (default 80 mm).
    edge_outside: when deciding what is a person (a change connected to the image border, never
        absorbed), the unusable pixels that reach the border count as outside the view (a
        stereo camera's band without depth on its left), and a usable pixel without depth as a
        change (an arm nearer than the camera measures, its shadow) (default true). Chosen on
        the tune sides of the hard and hard-extra suites: a hovering stereo hand whose arm
        crossed that band was absorbed and its landings lost (+4 contacts of 284, as many false
        touches, 1 more id switch); docs/accuracy.md section 7, session 18.
    """

    enabled: bool = True
    absorb_s: float = 0.5
    still_mm: float = 3.0
    drift_tau_s: float = 10.0
    drift_gain: float = 0.5
    stripes: int = 24
    bump_fraction: float = 0.4
    bump_s: float = 0.5
    keep_out_mm: float = 80.0
    edge_outside: bool = True

    def validate(self) -> None:
        _range("adapt.absorb_s", self.absorb_s, 0.1, 60.0)
        _range("adapt.still_mm", self.still_mm, 0.0, 100.0)
        _range("adapt.drift_tau_s", self.drift_tau_s, 1.0, 3600.0)
        _range("adapt.drift_gain", self.drift_gain, 0.0, 1.0)
        _range("adapt.stripes", self.stripes, 1, 64)
        _range("adapt.bump_fraction", self.bump_fraction, 0.0, 1.0, lo_open=True)
        _range("adapt.bump_s", self.bump_s, 0.0, 60.0)
        _range("adapt.keep_out_mm", self.keep_out_mm, 0.0, 1000.0)


@dataclass(frozen=True)
class PipelineConfig:
    """All stages together; the unit of a TOML config file."""

    surface: SurfaceConfig = field(default_factory=SurfaceConfig)
    regions: RegionConfig = field(default_factory=RegionConfig)
    touchpoints: TouchPointConfig = field(default_factory=TouchPointConfig)
    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    filter: FilterConfig = field(default_factory=FilterConfig)
    adapt: AdaptConfig = field(default_factory=AdaptConfig)

    def validate(self) -> PipelineConfig:
        for f in dataclasses.fields(self):
            getattr(self, f.name).validate()
        return self

    def replace(self, **stages: Any) -> PipelineConfig:
        """A copy with some stage fields changed: ``cfg.replace(regions={"tu_mm": 30})``."""
        changes = {}
        for name, values in stages.items():
            if name not in _STAGES:
                raise ConfigError(f"unknown config section [{name}]; use one of {sorted(_STAGES)}")
            if not isinstance(values, Mapping):
                raise ConfigError(
                    f"replace({name}=...) takes a mapping of field values, got "
                    f"{type(values).__name__}"
                )
            changes[name] = _build(_STAGES[name], name, {**_asdict(getattr(self, name)), **values})
        return dataclasses.replace(self, **changes).validate()


_STAGES: dict[str, type] = {
    "surface": SurfaceConfig,
    "regions": RegionConfig,
    "touchpoints": TouchPointConfig,
    "tracking": TrackingConfig,
    "filter": FilterConfig,
    "adapt": AdaptConfig,
}


def _asdict(obj: Any) -> dict[str, Any]:
    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}


def _build(cls: type, section: str, values: Mapping[str, Any]) -> Any:
    if not isinstance(values, Mapping):
        raise ConfigError(
            f"config section [{section}] must be a table, got {type(values).__name__}"
        )
    names = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(values) - set(names), key=str)
    if unknown:
        raise ConfigError(
            f"unknown key {section}.{_key(unknown[0])}; allowed: {', '.join(sorted(names))}"
        )
    kwargs: dict[str, Any] = {}
    for k, v in values.items():
        default = getattr(cls(), k)
        if k == "params":
            if not isinstance(v, Mapping):
                raise ConfigError(f"{section}.params must be a table of numbers")
            kwargs[k] = dict(v)
        elif isinstance(default, bool) or (default is not None and isinstance(default, str)):
            if type(v) is not type(default):
                raise ConfigError(f"{section}.{k} = {_show(v)} must be a {type(default).__name__}")
            kwargs[k] = v
        elif isinstance(default, int) or (default is None and k.endswith("frames")):
            if v is not None and (not isinstance(v, int) or isinstance(v, bool)):
                raise ConfigError(f"{section}.{k} = {_show(v)} must be a whole number")
            kwargs[k] = v
        elif isinstance(default, float):
            if not isinstance(v, (int, float)) or isinstance(v, bool):
                raise ConfigError(f"{section}.{k} = {_show(v)} must be a number")
            try:
                kwargs[k] = float(v)
            except OverflowError:  # an integer beyond float range: validate() names the range
                kwargs[k] = float("inf") if v > 0 else float("-inf")
        else:
            kwargs[k] = v
    return cls(**kwargs)


def config_from_dict(data: Mapping[str, Any]) -> PipelineConfig:
    """Build and validate a config from nested mappings (as parsed from TOML)."""
    if not isinstance(data, Mapping):
        raise ConfigError("a config must be a table of sections")
    unknown = sorted(set(data) - set(_STAGES), key=str)
    if unknown:
        raise ConfigError(
            f"unknown config section [{_key(unknown[0])}]; use one of {sorted(_STAGES)}"
        )
    stages = {name: _build(cls, name, data.get(name, {})) for name, cls in _STAGES.items()}
    return PipelineConfig(**stages).validate()


def config_to_dict(cfg: PipelineConfig) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for name in _STAGES:
        d = _asdict(getattr(cfg, name))
        out[name] = {k: (dict(v) if isinstance(v, Mapping) else v) for k, v in d.items()
                     if v is not None}
    return out


def load_config(path: str | Path) -> PipelineConfig:
    """Read a TOML config file; a missing or malformed file raises ConfigError."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"config file {p} does not exist; check the path") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"cannot read config file {p}: {e}; give a UTF-8 TOML file") from e
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"config file {p} is not valid TOML ({e}); fix the syntax") from e
    except RecursionError:  # absurdly deep nesting of arrays or inline tables
        raise ConfigError(f"config file {p} nests too deeply; fix the syntax") from None
    return config_from_dict(data)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return _toml_string(v)
    raise ConfigError(f"cannot write {_show(v)} to TOML")


_TOML_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f",
                 "\r": "\\r"}


def _toml_string(text: str) -> str:
    """A TOML basic string: quotes, backslashes and control characters escaped."""
    out = []
    for c in text:
        if c in _TOML_ESCAPES:
            out.append(_TOML_ESCAPES[c])
        elif ord(c) < 0x20 or ord(c) == 0x7F:
            out.append(f"\\u{ord(c):04x}")
        else:
            out.append(c)
    return '"' + "".join(out) + '"'


def _toml_key(key: str) -> str:
    """A bare key when TOML allows one, else a quoted key."""
    bare = key != "" and all(c.isascii() and (c.isalnum() or c in "-_") for c in key)
    return key if bare else _toml_string(key)


def dump_config(cfg: PipelineConfig) -> str:
    """The config as TOML text (round-trips through :func:`load_config`)."""
    lines: list[str] = []
    for section, values in config_to_dict(cfg).items():
        lines.append(f"[{section}]")
        nested = {k: v for k, v in values.items() if isinstance(v, dict)}
        for k, v in values.items():
            if k not in nested:
                lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
        for k, v in nested.items():
            lines.append(f"[{section}.{_toml_key(k)}]")
            lines.extend(f"{_toml_key(kk)} = {_toml_value(vv)}" for kk, vv in v.items())
        lines.append("")
    return "\n".join(lines)
