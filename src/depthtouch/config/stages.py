"""Configs of the detection stages (surface model, touch regions, touch points, surface
adaptation) and of the touch path filter.

Part of :mod:`depthtouch.config`, which re-exports every name.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from ..checks import check_range as _range
from ..checks import show as _show
from ..errors import ConfigError


@dataclass(frozen=True)
class SurfaceConfig:
    """Surface model ("virtual touch panel").

    learn_s: seconds of empty-surface frames to learn from (default 1.5, range (0, 60]).
    learn_frames: number of frames instead of seconds when set (range [2, 10000]).
    learn_min_s: the learning frames after the first this many seconds are read pixel by pixel
        against those before: a pixel that moved there (a hand coming in) is left out of the
        learning in that frame. A recording promises an empty surface for its first second
        only (docs/formats.md), and learn_s is longer (default 1.0, range [0, 60]; at learn_s
        or more: every frame is taken as it is).
    statistic: per-pixel surface depth: "mean", "mode" (the paper's two), or "median".
    min_valid_fraction: a pixel is usable when at least this share of its learning samples is
        valid (non-zero) (default 0.5, range (0, 1]).
    noise_floor_mm: lower bound of a pixel's noise sigma in mm (default 0.5, range [0, 50]).
    relearn_s: seconds of frames to learn the surface again after a camera bump, shorter than the
        first learning so that touches come back soon (default 0.5, range (0, 60]).
    level_limit_mm: levelling (:mod:`depthtouch.surface.level`): each frame's offset as a whole
        from the surface (a shift, and one growing with the depth squared) is measured on a
        sparse grid and taken off before the frame meets the surface, following offsets up to
        this far from the previous frame's (default 15, which follows a 2 mm breathing; 0 = off;
        range [0, 100]).
    level_engage_mm: levelling engages once the frame's shift as a whole reaches this, and
        lets go 3 s after it last did (a slow drift stays under it: the surface adapter's, as
        without levelling; 0 = always engaged; default 1.0, range [0, 20]).
    assumed_hfov_deg: the horizontal field of view taken for frames that carry no intrinsics
        (K is optional in a recording): every size in mm (a fingertip's area, the gates, the
        attachment's length) comes from the pixel size K gives, so without one the sensor
        assumes this, says so once, and reads sizes off by the ratio of the tangents of the
        half angles where the camera's own differs (default 70, a Kinect v2's; range [20, 150]).
    """

    learn_s: float = 1.5
    learn_frames: int | None = None
    learn_min_s: float = 1.0
    statistic: str = "median"
    min_valid_fraction: float = 0.5
    noise_floor_mm: float = 0.5
    relearn_s: float = 0.5
    level_limit_mm: float = 15.0
    level_engage_mm: float = 1.0
    assumed_hfov_deg: float = 70.0

    def validate(self) -> None:
        _range("surface.learn_s", self.learn_s, 0.0, 60.0, lo_open=True)
        _range("surface.relearn_s", self.relearn_s, 0.0, 60.0, lo_open=True)
        _range("surface.learn_min_s", self.learn_min_s, 0.0, 60.0)
        if self.learn_frames is not None:
            _range("surface.learn_frames", self.learn_frames, 2, 10000)
        if self.statistic not in ("mean", "mode", "median"):
            raise ConfigError(
                f"surface.statistic = {self.statistic!r} is unknown; use mean, mode or median"
            )
        _range("surface.min_valid_fraction", self.min_valid_fraction, 0.0, 1.0, lo_open=True)
        _range("surface.noise_floor_mm", self.noise_floor_mm, 0.0, 50.0)
        _range("surface.level_limit_mm", self.level_limit_mm, 0.0, 100.0)
        _range("surface.level_engage_mm", self.level_engage_mm, 0.0, 20.0)
        _range("surface.assumed_hfov_deg", self.assumed_hfov_deg, 20.0, 150.0)


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
    drift_kept_out: the unchanged pixels of what is never absorbed (within ``keep_out_mm`` of
        such a touch, and changes that reach the image border) follow the drift pixel by pixel
        too (``drift_tau_s``; default true). False keeps the surface under and around a held
        fingertip where it was (the stripe's shift, ``drift_gain``, still moves it): at ToF
        range the pixels around a tip lie within Tl, and the surface crept up under a finger
        held 10 s by up to 2.2 mm, moving its point by about 4 mm (docs/accuracy.md section 7,
        session 57).
    drift_hold_mm: within this distance of a touch kept out (as for ``keep_out_mm``) the
        unchanged pixels do not follow the drift pixel by pixel (the stripe's shift still
        moves them): a narrower form of ``drift_kept_out`` false, for the surface under a
        held tip only (default 0 = off; 25 mm failed its rules: still-finger jitter up on held-out
        halves where touches move on after standing a moment, docs/accuracy.md section 7,
        session 58).
    drift_hold_after_s: ``drift_hold_mm`` applies to a touch only once it has stood within
        half that distance of where it was for this long (checked once per stripe cycle;
        default 0: from its first cycle). With 25 mm and 2 s: hard-fresh6's tune jitter 0.90 ->
        0.81 mm and long-hold's 0.59 -> 0.36 mm, nothing else moved, but no fall on a set run
        once (hard-fresh7); off.
    keep_all_touches: keep the surroundings of every active touch from absorption, not only of
        touches whose hand reaches in from the image border, and keep whole every change that
        reaches into such a touch's keep-out circle (its hand and arm) (default false). Where
        the camera sees the whole arm (the simulator's arm ends at the shoulder: about half
        the hands at 1.3 m, most at 1.6-2 m do not reach the border), a finger held still is
        otherwise absorbed with its hand about 1 s into the hold. Off: on the held-out halves
        it added false touches from hovers >= 25 mm on the resting-forearm sets (rest-tof
        9 -> 11 with 2 of them, rest-tof2 5 -> 6 with 1; not traced) (docs/accuracy.md
        section 7, session 48).
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
    drift_kept_out: bool = True
    drift_hold_mm: float = 0.0
    drift_hold_after_s: float = 0.0
    keep_all_touches: bool = False
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
        _range("adapt.drift_hold_mm", self.drift_hold_mm, 0.0, 1000.0)
        _range("adapt.drift_hold_after_s", self.drift_hold_after_s, 0.0, 3600.0)


@dataclass(frozen=True)
class FilterConfig:
    """Touch path correction: ``name`` of the filter and its parameters (see filters.py).

    params: finite numbers by name; which names a filter takes is checked by filters.py.
    The default, ``adaptive_euro`` (the paper's adaptive filter followed by a speed-gated 1€
    stage and a lock of a finger proven at rest), was chosen by measurement on the hard suite's
    tune half (docs/filters.md): lower jitter of a still finger and fewer id switches than the
    adaptive filter alone, the same position error and angle error; the rest lock (on by
    default since issue 13, point 4) ignores one-frame jumps of a resting tip and never
    engages on a drag of 10 mm/s or more; the still models (``still_p`` 0.01, on since
    session 39; 0 turns them off) hold a finger as far as a still and a moving model's
    likelihoods say it is still: hard held-out jitter 0.878 → 0.760 mm, a drag at 10-20 mm/s
    2.1-2.3 mm behind instead of 1.2-1.6 (docs/filters.md, "The still models"); the
    re-landing (``reland_frames`` 6, on since session 57) lets a finger that stops after a
    move land again (docs/filters.md, "The re-landing").
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
