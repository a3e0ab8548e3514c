"""The stream's frame rate, from the frames' timestamps, for the tracker's evidence, and the
frame intervals each frame spans (a frame the camera dropped makes a gap of two: ``step``).

The evidence a new contact needs before ``down`` was chosen at one frame rate,
``TrackingConfig.reference_fps``. A camera at 60 fps sees a speck of mixed pixels under a
descending finger's rim for as long, but in twice as many frames: counted in frames, it would
go down in half the time. :class:`FrameRate` gives the length of a frame in reference frames
(at most 1), so that the evidence takes at least as long and at least as many frames as at the
reference rate. (The grace before ``up`` and the pending and merged contacts' counts stay in
frames: a dropout comes frame by frame. Scaling them too held a false touch at 60 fps for 33
frames instead of 5; docs/accuracy.md, session 27.) Off by default (``reference_fps`` 0): at
60 fps it cut the hard suite's held-out false touches from 42 to 15 but lost 5 of its 183
contacts.
"""

from __future__ import annotations

import math
from collections import deque
from statistics import median

# intervals the rate is the median of: a dropped frame or a late timestamp moves no median
_INTERVALS = 15
# within this share of the reference interval, frames count as reference frames (timestamps
# in whole ms at 30 fps give 33 and 34 ms)
_SAME_RATE = 0.1
#: the most frame intervals one frame's step counts (a stream that stopped for longer than
#: this has no motion to extrapolate: a contact is predicted where this many frames take it)
STEP_MAX = 4


class FrameRate:
    """``update(t_s)`` once per frame returns ``frame`` (``gate`` is read after it);
    ``reset()`` forgets the stream.

    ``frame``: the frame's length in reference frames. 1.0 until two timestamps are known, with
    ``reference_fps`` 0, or while the median interval is longer than 90 % of the reference
    interval; otherwise median interval x ``reference_fps`` (0.5 at 60 fps against 30).

    ``gate``: how many frames at ``gate_fps`` one frame lasts when that is more than 1.1
    (else 1): in a slower stream a finger moves farther between frames, and the tracker's gate
    grows by this factor.

    ``step``: how many of the stream's own frame intervals (the median) lie between this
    frame and the one before, rounded, from 1 to :data:`STEP_MAX`: 1 in an even stream, 2
    after a frame the camera dropped (a busy USB bus), whatever the settings above. The
    tracker's motion model counts these instead of frames, so that a drag keeps its id across
    a dropped frame (docs/accuracy.md section 7, session 51).

    A slower stream's frames count as one each, not more: noise comes frame by frame, and a
    speck seen in three frames at 15 fps is as unlikely as one seen in three at 30 fps. At 15
    fps, counting frames by their length raised the hard suite's false touches on its tune
    half from 6 to 27 (docs/accuracy.md, session 27).
    """

    def __init__(self, reference_fps: float, gate_fps: float = 0.0) -> None:
        self.reference_fps = reference_fps
        self.gate_fps = gate_fps
        self._dt: deque[float] = deque(maxlen=_INTERVALS)
        self._last: float | None = None
        self.frame = 1.0
        self.gate = 1.0
        self.step = 1.0

    def reset(self) -> None:
        self._dt.clear()
        self._last = None
        self.frame = 1.0
        self.gate = 1.0
        self.step = 1.0

    def update(self, t_s: float | None) -> float:
        self.step = 1.0
        if t_s is None or not math.isfinite(t_s):
            return self.frame
        last, self._last = self._last, t_s
        if last is None or t_s <= last:  # the first frame, a repeated or a reordered timestamp
            return self.frame
        gap = t_s - last
        self._dt.append(gap)
        dt = median(self._dt)
        if gap > 1.5 * dt:
            self.step = float(min(STEP_MAX, round(gap / dt)))
        if self.reference_fps <= 0 and self.gate_fps <= 0:
            return self.frame
        k = dt * self.reference_fps
        self.frame = 1.0 if k <= 0.0 or k >= 1.0 - _SAME_RATE else k
        g = dt * self.gate_fps
        self.gate = g if g > 1.0 + _SAME_RATE else 1.0
        return self.frame

