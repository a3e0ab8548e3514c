"""The config of tracking (assignment, debounce, grace).

Part of :mod:`depthtouch.config`, which re-exports every name.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..checks import check_range as _range


@dataclass(frozen=True)
class TrackingConfig:
    """Tracking: optimal assignment, debounce and grace.

    gate_mm: largest jump between frames that keeps an id, when K is known (default 40); it is
        meant for one frame interval: across frames the camera dropped (a gap of k intervals in
        the timestamps) the gate is k times this, and the prediction spans them too.
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
    enclosed_share_max: a fingertip hangs on its finger: its hand lies at its back, and in front
        of it and beside it lies the surface. A region whose attachment's hand pixels make more
        than this share of the pixels within 2 px around it (TouchPoints.attach_share) lies in
        its hand, not at a finger's end (a patch of a resting palm, wrist or forearm whose top
        stands near Tu and flickers in and out of the band), and gives no evidence, unless it
        looks like a steep finger's top. With ``enclosed_change_max_mm`` (below), only where
        nothing around it moved: alone, every share tried lost fingers side by side (session
        40). Default 0.25 (session 41; 1.0 turns the test off; range [0, 1]).
    enclosed_height_min_mm: ... and whose tip (TouchPoints.height_mm, the lower quarter of its
        cap) stands at least this high. Default 0: every tip (session 42). At 3.5 mm (session
        41) a patch whose tip flickers around that height got a whole frame of evidence in
        each of its low frames; with the change below, a touching fingertip is not refused
        however low its tip, since it arrives (range [0, 100]).
    enclosed_attach_max_mm: ... and whose attachment (the median height of its hand pixels,
        TouchPoints.attach_height_mm) lies lower than this: the hand around a patch of a
        resting hand is that hand's top, just above Tu; a finger rises steeply behind its tip
        (default 1000: any; range [0, 10000]).
    enclosed_change_max_mm: ... and around which the heights changed by less than this over
        the last seconds (TouchPoints.recent_change_mm, :mod:`depthtouch.touch.recent`): a
        touch starts with a finger arriving, a resting hand's patch lies in a hand that has not
        moved; fingers side by side, whose neighbours fill a touching finger's ring as a
        resting hand does, arrive too. An unknown change (the first 0.15 s after the surface
        was learned) takes no evidence away. Default 4 mm (session 41; 0: no such condition,
        the share alone decides; range [0, 1000]). Chosen on the tune halves: rest-tof's false
        touches 46 -> 27 with no contact lost there, one lost on drift-hold (a stereo still
        hold whose faint tip takes 1.5 s to go down); held-out, no contact lost on eight
        sets, false touches 52 -> 46 (rest-tof 23 -> 20, hard 8 -> 6; docs/accuracy.md
        section 7, session 41).
    enclosed_change_window_s: ... the last this many seconds: the change is the median over
        that window's frames (one kept every 0.15 s) of how much the heights around the point
        differ from now. A faint fingertip gathers its evidence over half a second while the
        finger stays still: the window must reach back before it arrived (default 2.0;
        range [0.3, 10]).
    enclosed_cover_mm: ... leaving out the frames in which the heights around the point lay
        more than this above today's (a cover: the other hand hovering over a resting one); a
        point covered in every frame of the window, uncovered now, counts as unchanged: it did
        not arrive, its cover left. Default 30 mm (session 42; 0: every frame counts; range
        [0, 1000]). With the tip height 0, chosen on the tune halves: rest-tof's false touches
        27 -> 14, no contact lost on 12 sets; held out, 13 sets, no contact lost, false
        touches 74 -> 68 (rest-tof 20 -> 17; docs/accuracy.md section 7, session 42).
    enclosed_pending_only: the enclosure test refuses a touch's start only: a contact that is
        down is not doubted (``doubt_frames``) for lying still in its hand. A finger that is
        held lies as still as a resting hand's patch, and one whose ring its neighbours or
        its own hand fill would be lifted after ``enclosed_change_window_s`` plus
        ``doubt_frames``. Default on (session 43): on the check set `long-hold` (a finger
        held 10 s) the tune half's frame recall 0.984 -> 0.988, id switches 4 -> 3 (a held
        finger at stereo 0.8 m lifted 7 s into its hold); the 13 other sets' tune halves
        unchanged but one false touch's length, every held-out half unchanged
        (docs/accuracy.md section 7, session 43).
    enclosed_low_share_min, enclosed_low_change_max_mm: the low band. A region whose share lies
        above the first but not above ``enclosed_share_max`` (a patch of a resting forearm whose
        ring the surface fills more than the hand does; fingers side by side share theirs less)
        is asked too, and refused only where the heights around it changed by less than the
        second over the window (a tighter limit than ``enclosed_change_max_mm``: a tap after a
        hover at ToF 1.3-2 m changes its surroundings 2.4-7 mm). Needs the change condition
        (``enclosed_change_max_mm`` above 0). Defaults 0.15 and 2.5 mm (session 50; 0 turns
        it off; ranges [0, 1] and [0, 1000]). Chosen on 13 tune halves (false touches 68 ->
        51, recall unchanged on each) and judged once on 17 held-out halves: contacts found
        1605 -> 1605, false touches 69 -> 58 (from hovers >= 25 mm 4 -> 1), id switches 17 ->
        15; hard-fresh5's held-out jitter 0.80 -> 0.92 mm (docs/accuracy.md section 7,
        session 50).
    enclosed_flat_max_mm, enclosed_flat_attach_max_mm, enclosed_flat_height_max_mm: a forearm
        or palm laid onto the surface arrives as a finger does (the heights around its flank
        changed in the last seconds), so the enclosure test's change condition lets the
        patches of its flank that flicker into the band through. A region the enclosure test
        asks about (its share above ``enclosed_share_max``, its tip at least
        ``enclosed_height_min_mm`` high) whose heights behind it spread less than the first
        (TouchPoints.back_spread_mm, as ``flat_max_mm``), whose attachment lies lower than the
        second (TouchPoints.attach_height_mm: a flank's hand pixels are the flank itself,
        just above Tu; an unknown height counts as low) and whose tip lies lower than the third
        (the flank's edge dips into the band; the top of a steep finger the steep test does not
        recognise reads a finger's thickness) is refused whatever moved around it, as the
        enclosure test refuses a still one (steep tips exempt; with
        ``enclosed_pending_only``, a touch's start only). A finger has its hand at its back
        only (a low share), or rises behind its tip, or its attachment rises steeply.
        Defaults 28 mm, 40 mm, 8 mm (session 44; the first 0 turns it off; ranges [0, 100],
        [0, 10000], [0, 1000]). Chosen on the tune halves of eight sets: false touches 54 ->
        38 (rest-tof2 14 -> 2, rest-tof 14 -> 10), one contact lost (a faint ToF tip at 1 m on
        hard-extra); held out: false touches 49 -> 34
        (rest-tof 17 -> 9, rest-tof2 11 -> 5, from hovers >= 25 mm 3 -> 0), one contact lost
        (hard: ToF 2 m, a hand held low) (docs/accuracy.md section 7, session 44). The flat test
        alone at 22 mm (``flat_max_mm``) would refuse a finger laid flat (pitch 15° or less):
        the share condition keeps it for regions in a hand.
    step_max_mm: a finger rises from the band gradually; a region whose attached hand pixels
        lie higher than this (median, mm above the surface) is mixed or smeared pixels at the
        side of a raised hand, not a fingertip, and gives no evidence (default 80 mm, chosen on
        the hard suite's tune half: 60 lost a contact; range [0, 10000], 0 turns the test off).
    still_step_frames, still_step_mm: a contact whose point has stayed within
        ``still_step_mm`` of where its run began (mm; a point that leaves starts a new run
        where it is) for this many frames in a row is not refused by ``step_max_mm``: a pending
        one with its tip low enough to go down gains the frame's evidence, and one that is down
        is not doubted (``doubt_frames``) for it. Mixed pixels beside a raised hand come and go
        with the hand; a finger standing steep on the surface, its hand rising right behind
        its tip, stays. Default 0: off (ranges [0, 100000] frames, [0, 1000] mm); needs the
        camera's intrinsics. Measured in session 47 on ten tune halves: only hard-fresh5's
        moved. 15 frames found 2 more contacts there (recall 0.908 -> 0.938; a finger held
        steep at structured light 1 m, its hand 86-92 mm up behind the tip) but split the
        held one in two (the lift test, its core jumping between the tip and the finger behind
        it); 30 found 1. The rule written before the runs took 15 and asked for no more id
        switches, so it stays off (docs/accuracy.md section 7, session 47).
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
        ``held_gaps`` times (default 3; a clean touch keeps the plain grace, and its lift is not
        delayed), whose smoothed velocity is under ``held_step_mm`` per frame (default 4 mm:
        120 mm/s at 30 fps, not a swipe that leaves the surface), and whose point vanished with
        no raised point (too high to continue a contact) within ``held_near_mm`` (default
        15 mm) of it, may be missing ``up_held_frames`` frames before ``up`` (default 6; 0
        turns it off); it needs the camera's intrinsics (ranges [0, 300] frames, [1, 1e5],
        [0, 1000] mm, [0, 1000] mm). Measured in session 37 and left off; on since session 43,
        after the check set `long-hold` (a finger held 10 s): its held-out half's id switches
        15 -> 9, none more on 13 other held-out halves, lift latency p95 up by 3 frames at most
        (docs/config.md; docs/accuracy.md section 7, sessions 37 and 43).
    pending_step_max_mm: a contact not yet down whose point moved farther than this since it
        was last seen (per frame interval: twice this after a missing or a dropped frame; grown
        with ``gate_fps`` like the gate), while the hand pixels right behind it lie higher than
        ``pending_step_attach_mm`` (default 33 mm; a touching finger rises 26-28 mm there,
        the raised hand over a mixed strip 37-49 mm), gains no evidence in that frame: a
        finger lands, it seldom arrives sliding. What arrives sliding is the strip of mixed
        depths along the edge of a low hand sweeping past a time-of-flight camera (its raw
        exposures see hand, then surface), and a finger still hovering on its way down.
        Default 0: off; needs the camera's intrinsics (ranges [0, 1000] mm, [-1000, 1000]
        mm; -1000 applies it whatever the hand's height). 15 is the measured choice for a
        time-of-flight camera; not the default because one held-out half's jitter rose by
        0.011 mm, past its rule (docs/accuracy.md section 7, session 38).
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
    steep_still_mm: a steep top counts toward a pending contact only where the contact's point
        stood within this many mm of it the frame before (this many per frame interval since
        the contact was last seen): a finger standing on the surface stays put, while the
        specks that a hand's raised edges leave at ToF range, and a neighbour's tip on its way
        down, come and go or move on. A contact that starts on a steep top starts with no
        evidence. 0 (default): off; range [0, 1000] mm (docs/accuracy.md, session 60).
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
    land_prior_frames, land_prior_mm: at down, the path filter is first given the contact's
        pending points (up to land_prior_frames of them, the last ones in a row within
        land_prior_mm of the down point, at their own frames' times), so that the filter's
        landing mean starts from several measurements instead of one; needs the scale (mm
        per px). Off by default (0 frames): with 4 frames and 3 mm, on the tune halves (session
        56, docs/accuracy.md section 7) still-finger jitter went 0.535 -> 0.527 mm (hard),
        0.704 -> 0.726 (hard-fresh3), 0.588 -> 0.574 (hard-fresh5), 0.981 -> 0.982
        (hard-fresh6), error median down by 0.004-0.046 mm on all four; its rule asked a fall
        of 0.03 mm on two halves and no rise over 0.01. A tip-sized point goes down on its
        second frame, so there is one pending point to give, and 73 of hard's 111 tune still
        runs begin one or more frames after their touch's down (ranges [0, 30] frames,
        [0, 100] mm).
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
    lift_noise_k: a contact that is down counts as lifted only when its core rose by more than
        ``lift_core_mm`` plus this many times its own core's noise (the median step of its core
        height from one known value to the next, over its last 300 values); a pending contact
        keeps the plain ``lift_core_mm``. A steep finger held at ToF 1 m has a core that jumps
        between its tip and the finger rising behind it (steps of about 10 mm), and each run of
        three high values ended the touch: one 10 s hold in `long-hold2`'s tune half broke into
        six ids. Measured in session 45 and left off (default 0): 0.75 cut long-hold2's tune id
        switches 12 -> 5 and changed nothing on the tune halves of hard, hard-extra,
        hard-fresh2, long-hold, drift-hold and the default suite (steep: 7 -> 5 false
        touches), but the held-out halves of long-hold2 and long-hold hold no such break and
        did not move, which the rule asked for, and steep's held-out half merged one tap into
        the touch before it (range [0, 100]; docs/accuracy.md section 7, session 45).
    doubt_frames: a contact that is down goes ``up`` once its point has given no evidence of a
        touch (weight 0 in tracking.evidence: attached like a forearm's edge, the hand behind it
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
    enclosed_share_max: float = 0.25
    enclosed_height_min_mm: float = 0.0
    enclosed_attach_max_mm: float = 1000.0
    enclosed_change_max_mm: float = 4.0
    enclosed_change_window_s: float = 2.0
    enclosed_pending_only: bool = True
    enclosed_cover_mm: float = 30.0
    enclosed_low_share_min: float = 0.15
    enclosed_low_change_max_mm: float = 2.5
    enclosed_flat_max_mm: float = 28.0
    enclosed_flat_attach_max_mm: float = 40.0
    enclosed_flat_height_max_mm: float = 8.0
    step_max_mm: float = 80.0
    still_step_frames: int = 0
    still_step_mm: float = 5.0
    flat_max_mm: float = 10.0
    up_frames: int = 3
    up_held_frames: int = 6
    held_gaps: int = 3
    held_step_mm: float = 4.0
    held_near_mm: float = 15.0
    merge_mm: float = 25.0
    merge_frames: int = 10
    merge_area_ratio: float = 1.5
    behind_lat_mm: float = 8.0
    behind_lat_px: float = 2.0
    behind_min_mm: float = 10.0
    pending_gap_frames: int = 1
    pending_step_max_mm: float = 0.0
    pending_step_attach_mm: float = 33.0
    pending_decay: float = 0.75
    pending_low_mm: float = 5.0
    pending_low_gap_frames: int = 3
    pending_low_decay: float = 0.9
    land_prior_frames: int = 0
    land_prior_mm: float = 3.0
    steep_evidence: float = 0.34
    steep_area_min_mm2: float = 60.0
    steep_area_max_mm2: float = 150.0
    steep_top_min_mm: float = 10.0
    steep_top_max_mm: float = 26.0
    steep_hand_mm: float = 8.0
    steep_step_min_mm: float = 75.0
    steep_step_max_mm: float = 88.0
    steep_still_mm: float = 0.0
    lift_core_mm: float = 15.0
    lift_noise_k: float = 0.0
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
        _range("tracking.pending_step_max_mm", self.pending_step_max_mm, 0.0, 1000.0)
        _range("tracking.pending_step_attach_mm", self.pending_step_attach_mm, -1000.0, 1000.0)
        _range("tracking.tip_area_min_mm2", self.tip_area_min_mm2, 0.0, 10000.0)
        _range("tracking.tip_area_max_mm2", self.tip_area_max_mm2, self.tip_area_min_mm2, 1e5)
        _range("tracking.tip_area_min_px", self.tip_area_min_px, 0.0, 10000.0)
        _range("tracking.tip_area_max_px", self.tip_area_max_px, 0.0, 1e5)
        _range("tracking.weak_evidence", self.weak_evidence, 0.0, 1.0, lo_open=True)
        _range("tracking.weak_quiet_evidence", self.weak_quiet_evidence, 0.0, 1.0, lo_open=True)
        _range("tracking.attach_max_mm", self.attach_max_mm, 0.0, 10000.0)
        _range("tracking.attach_low_mm", self.attach_low_mm, 0.0, 100.0)
        _range("tracking.attach_low_evidence", self.attach_low_evidence, 0.0, 1.0)
        _range("tracking.enclosed_share_max", self.enclosed_share_max, 0.0, 1.0)
        _range("tracking.enclosed_height_min_mm", self.enclosed_height_min_mm, 0.0, 100.0)
        _range("tracking.enclosed_attach_max_mm", self.enclosed_attach_max_mm, 0.0, 10000.0)
        _range("tracking.enclosed_change_max_mm", self.enclosed_change_max_mm, 0.0, 1000.0)
        _range("tracking.enclosed_change_window_s", self.enclosed_change_window_s, 0.3, 10.0)
        _range("tracking.enclosed_cover_mm", self.enclosed_cover_mm, 0.0, 1000.0)
        _range("tracking.enclosed_low_share_min", self.enclosed_low_share_min, 0.0, 1.0)
        _range("tracking.enclosed_low_change_max_mm", self.enclosed_low_change_max_mm,
               0.0, 1000.0)
        _range("tracking.enclosed_flat_max_mm", self.enclosed_flat_max_mm, 0.0, 100.0)
        _range("tracking.enclosed_flat_attach_max_mm", self.enclosed_flat_attach_max_mm,
               0.0, 10000.0)
        _range("tracking.enclosed_flat_height_max_mm", self.enclosed_flat_height_max_mm,
               0.0, 1000.0)
        _range("tracking.step_max_mm", self.step_max_mm, 0.0, 10000.0)
        _range("tracking.still_step_frames", self.still_step_frames, 0, 100000)
        _range("tracking.still_step_mm", self.still_step_mm, 0.0, 1000.0)
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
        _range("tracking.land_prior_frames", self.land_prior_frames, 0, 30)
        _range("tracking.land_prior_mm", self.land_prior_mm, 0.0, 100.0)
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
        _range("tracking.steep_still_mm", self.steep_still_mm, 0.0, 1000.0)
        _range("tracking.lift_core_mm", self.lift_core_mm, 0.0, 200.0)
        _range("tracking.lift_noise_k", self.lift_noise_k, 0.0, 100.0)
        _range("tracking.doubt_frames", self.doubt_frames, 0, 100000)
        _range("tracking.reference_fps", self.reference_fps, 0.0, 1000.0)
        _range("tracking.gate_fps", self.gate_fps, 0.0, 1000.0)
        _range("tracking.yield_ratio", self.yield_ratio, 0.0, 1.0)
        _range("tracking.yield_min_mm", self.yield_min_mm, 0.0, 1000.0)
        _range("tracking.report_dir_weight", self.report_dir_weight, 0.0, 1.0, lo_open=True)
