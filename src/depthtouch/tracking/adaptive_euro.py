"""The ``adaptive_euro`` filter, the pipeline's default: the paper's adaptive filter, a 1€ stage
on its output, a rest lock and a landing (see the class doc; chosen by measurement,
docs/filters.md). Registered by name in :mod:`depthtouch.tracking.filters`.
"""

from __future__ import annotations

import numpy as np

from .eurokernel import FIELD_ORDER, PARAM_ORDER, STILL_CLIP, STILL_NU, euro_step
from .filterbase import FilterBase, Param, smoothing_factor

_HB = 32  # the last measurements kept per touch: the landing's window
# the still models' start: the velocity's variance ((100 mm/s)²) and the still probability
_START_VAR_MM2_S2 = 1e4
_START_STILL = 0.9


class AdaptiveEuroFilter(FilterBase):
    """``adaptive_euro``: the adaptive filter, then a 1€ stage on its output.

    The adaptive stage (``min_cutoff_hz``, ``half_weight_mm``, as :class:`AdaptiveFilter`) follows
    turns and speed changes at once but leaves most of a still finger's noise. The 1€ stage
    smooths its output with the cutoff ``rest_cutoff_hz + beta_per_mm·max(0, s − rest_mm_s)``,
    s the speed of the adaptive stage's output (its step per dt, as a vector low-passed at
    ``speed_cutoff_hz``, then its norm: both axes get one cutoff, so a path keeps its
    direction). Below ``rest_mm_s`` (the speed noise of a finger at rest) the cutoff stays at
    ``rest_cutoff_hz``; a drag raises it so far that the stage adds almost no lag.

    rest_cutoff_hz: cutoff of a finger at rest, range (0, 1000], default 0.3.
    rest_mm_s: speed taken as rest, range [0, 1000], default 40 mm/s.
    beta_per_mm: rise of the cutoff with speed above rest, Hz per mm/s, range [0, 100],
        default 0.2 (at 100 mm/s above rest the cutoff is 20 Hz).
    speed_cutoff_hz: cutoff of the speed estimate, range (0, 1000], default 3.0.
    hold_mm: the stage's weight rises toward 1 with the gap g between its output and the
        adaptive stage's, ``a + (1 − a)·(1 − 2^(−(g/hold_mm)²))``: a gap the noise cannot
        explain (a tip that landed off its first measurement) is closed at once; range
        (0, 1000], default 3.0 mm.
    noise_mm, noise_s: the touch's measured noise σ (mm RMS per axis, from the second
        differences of its measurements, each clipped at 3σ + 1 mm), averaged over ``noise_s``
        (default 1 s) from ``noise_mm`` (default 1 mm); it sets the rest lock's radius.
    The rest lock (lock_frames > 0): a finger proven still is held at the running mean of its
    measurements, ignoring one-frame jumps of its tip estimate.

    - It locks when the weighted least-squares line through its measurements (weights decaying
      by 1 − 1/lock_frames per frame, after at least ``lock_frames``, default 32) moves slower
      than ``lock_mm_s`` (default 5 mm/s): a drag of 10 mm/s and more never locks.
    - The lock starts at the output so far (the 1€ stage's, or the landing's: no jump), with
      a radius of max(``lock_mm``, ``lock_sigmas``·σ) (defaults 4 mm, 3). Its mean then runs
      over the last ``lock_mean_frames`` (default 30) measurements that lie within twice the
      radius: a far outlier moves neither the output nor the mean.
    - It ends when the median of the last three measurements leaves the radius (a move, on its
      second frame); then the 1€ stage, which ran all along, is the output again.
    - Off by default, ``lock_resume_frames`` > 0 (e.g. 10): a lock that ended is remembered
      (an older one is not replaced by one entered during an excursion), and a finger still
      again within that many frames, the median of its last three within that lock's radius
      of its mean, takes it back (mean, count, radius) instead of starting a new lock from the
      1€ output the excursion pulled aside. Off: it failed its rule on the held-out halves
      (docs/accuracy.md section 7, session 37).
    - Ranges: lock_frames [0, 10000] (0 turns the lock off, values under 2 count as 2),
      lock_mm_s (0, 10000], lock_mm (0, 1000], lock_sigmas [0, 100], lock_mean_frames
      [1, 1e6], lock_resume_frames [0, 10000] (0, the default: never taken back),
      noise_mm (0, 100], noise_s (0, 1000].
    The landing (land_frames > 0): from touch-down, a finger is taken as still until its
    measurements show that it moves, and the output is their mean. A tap at range, too short
    for the lock, is held from its first frame.

    - Each touch keeps its last 32 measurements (x, y, time) and the median of each last three.
      The output's mean is the raw measurements' mean, weighted by 1 − 1/max(land_frames,
      lock_frames) per frame of age, over the landing's window (at most the last 32).
    - Each frame, the weighted line through the *medians* gives a speed and its standard
      error (from the touch's noise σ). Their ratio z is tested from the window's third
      measurement on. A one-frame jump of the tip estimate moves no median, so it neither ends
      the landing nor blends it out.
    - The output is the mean plus a·(the 1€ stage's output − the mean), with a rising from 0
      at z = ``land_blend_sigmas`` (default 1.5) to 1 at z = ``land_sigmas`` (default 6). A
      drag from touch-down leaves the mean as soon as its line is steeper than the noise.
    - Restart (once per touch: a finger reported down while it still descends at a slant):
      once the window holds 2·K measurements (K = ``land_restart_frames``, default 8), if the
      last K medians are flat (slope within half ``land_sigmas`` standard errors) and their
      mean lies more than ``land_restart_sigmas`` (default 4) standard errors from the mean of
      the ones before, the window restarts at the last K.
    - It ends for good at z > ``land_sigmas`` or after ``land_frames`` (default 32)
      measurements of its window; then the 1€ stage, which ran all along, is the output (or
      the lock).
    - Cost on a drag from touch-down: at most half a frame's travel on its second frame, under
      1 mm more lag at 10-60 mm/s (docs/filters.md).
    - Ranges: land_frames [0, 10000] (0 turns it off), land_blend_sigmas [0, 100],
      land_sigmas (0, 100], land_restart_frames [0, 16] (under 2 turns the restart off),
      land_restart_sigmas (0, 100].
    The re-landing (reland_frames >= 2, with the landing on; on by default since session 57,
    after its rules on four tune and three held-out halves; docs/filters.md, "The
    re-landing"): a finger that stops after a move lands again, instead of waiting
    ``lock_frames`` for the lock while the 1€ stage closes the last few mm of its lag.

    - A touch that moved faster than ``reland_mm_s`` (default 40 mm/s), neither landing nor
      locked, whose last ``reland_frames`` (default 6) medians lie on a line flatter than
      ``reland_sigmas`` (default 2) standard errors, starts the landing above from those
      measurements; a slower drag is never held (tested).
    - Ranges: reland_frames [0, 16] (under 2 turns it off), reland_sigmas (0, 100],
      reland_mm_s [0, 10000].
    The still models (still_p > 0; on by default since session 39, 0.01): an
    interacting-multiple-model pair that decides, frame by frame, how likely the finger is
    still, and holds it where it is then.

    - A still model (the position holds, a random walk of ``still_q_mm2_s`` mm²/s, default
      0.01) and a moving one (constant velocity, white acceleration of ``move_q_mm2_s3``
      mm²/s³, default 3e5), each a Kalman filter per axis. Each frame, each starts from a mix
      of both (the switch probability ``still_p`` per frame), is updated with the measurement,
      and the still probability follows their likelihoods (Student-t with 3 degrees of
      freedom: a tip estimate's one-frame jumps are not Gaussian). The still model's
      innovation is clipped at 3 standard deviations.
    - Measurement noise: ``still_noise_mul`` (1.5) times a noise level of their own, started
      at ``still_noise_mm`` (1.5 mm) and followed at the slow rate (``noise_s``) only.
    - Output: the output so far plus g·(the still model's position − it), g the still
      probability above ``still_gate`` (0.5) rescaled to [0, 1].
    - Price (docs/filters.md, "The still models"): a move's first frame from rest is held like
      a one-frame jump, and a drag at 10-20 mm/s lags 2.1-2.3 mm.
    - Ranges: still_p [0, 0.5] (0 turns them off), still_q_mm2_s [0, 1e6], move_q_mm2_s3
      (0, 1e9], still_noise_mm (0, 100], still_noise_mul (0, 100], still_gate [0, 0.99].
    Defaults chosen by measurement (docs/filters.md).
    """

    name = "adaptive_euro"
    PARAMS = {
        "min_cutoff_hz": Param(3.0, 0.0, 1000.0),
        "half_weight_mm": Param(6.0, 0.0, 1000.0),
        "rest_cutoff_hz": Param(0.3, 0.0, 1000.0),
        "rest_mm_s": Param(40.0, 0.0, 1000.0, lo_open=False),
        "beta_per_mm": Param(0.2, 0.0, 100.0, lo_open=False),
        "speed_cutoff_hz": Param(3.0, 0.0, 1000.0),
        "hold_mm": Param(3.0, 0.0, 1000.0),
        "lock_mm": Param(4.0, 0.0, 1000.0),
        "lock_frames": Param(32.0, 0.0, 10000.0, lo_open=False),
        "lock_mean_frames": Param(30.0, 1.0, 1e6, lo_open=False),
        "lock_mm_s": Param(5.0, 0.0, 10000.0),
        "lock_sigmas": Param(3.0, 0.0, 100.0, lo_open=False),
        "noise_mm": Param(1.0, 0.0, 100.0),
        "noise_s": Param(1.0, 0.0, 1000.0),
        "land_frames": Param(32.0, 0.0, 10000.0, lo_open=False),
        "land_blend_sigmas": Param(1.5, 0.0, 100.0, lo_open=False),
        "land_sigmas": Param(6.0, 0.0, 100.0),
        "land_restart_frames": Param(8.0, 0.0, _HB / 2, lo_open=False),
        "land_restart_sigmas": Param(4.0, 0.0, 100.0),
        "reland_frames": Param(6.0, 0.0, _HB / 2, lo_open=False),
        "reland_sigmas": Param(2.0, 0.0, 100.0),
        "reland_mm_s": Param(40.0, 0.0, 10000.0, lo_open=False),
        "lock_resume_frames": Param(0.0, 0.0, 10000.0, lo_open=False),
        "still_p": Param(0.01, 0.0, 0.5, lo_open=False),
        "still_q_mm2_s": Param(0.01, 0.0, 1e6, lo_open=False),
        "move_q_mm2_s3": Param(3e5, 0.0, 1e9),
        "still_noise_mm": Param(1.5, 0.0, 100.0),
        "still_noise_mul": Param(1.5, 0.0, 100.0),
        "still_gate": Param(0.5, 0.0, 0.99, lo_open=False),
    }
    # the adaptive stage's position (mm) and velocity (mm/s); the smoothed speed vector (mm/s);
    # the 1€ stage's output (mm); the noise: the last two measurements (mm), how many were seen,
    # the noise estimate (mm RMS per axis); the stillness test: exponentially weighted sums of
    # the measurements over time (weight, Σt, Σt², Σx, Σtx; t in s relative to the last update);
    # the lock: its mean (mm), its frame count (0 = not locked), its squared radius (mm²);
    # the lock remembered when it ended: its mean, count and squared radius, frames since;
    # the landing: its flag, the measurement index its window starts at (0 = not restarted),
    # the last _HB measurements (mm, s) and medians of three (mm), a ring indexed by count;
    # whether it moved faster than reland_mm_s since it last landed
    _FIELDS = {"p": (2,), "v": (2,), "dx": (2,), "e": (2,), "z1": (2,), "z2": (2,), "nz": (1,),
               "sd": (1,), "q0": (1,), "qt": (1,), "qtt": (1,), "qx": (2,), "qtx": (2,),
               "m": (2,), "n": (1,), "r2": (1,), "land": (1,), "ls": (1,),
               "hx": (_HB,), "hy": (_HB,), "ht": (_HB,), "gx": (_HB,), "gy": (_HB,),
               "mv": (1,), "pm": (2,), "pn": (1,), "pr2": (1,), "pt": (1,),
               "ss": (4,), "sc": (6,), "ms": (4,), "mc": (6,), "mu": (1,), "sn": (1,)}

    def __init__(self, **params: float) -> None:
        super().__init__(**params)
        # the compiled step's inputs: the parameters and each field's first column, in order
        self._prm = np.array([self.params[k] for k in PARAM_ORDER], np.float64)
        self._cols = np.array([self._COLS[k].start for k in FIELD_ORDER], np.int64)

    def _init(self, rows: np.ndarray, xy: np.ndarray) -> None:
        st = self._state
        for k in ("v", "dx", "qt", "qtt", "qtx", "m", "n", "r2", "pm", "pn", "pr2", "pt"):
            st[k][rows] = 0.0
        for k in ("p", "e", "z1", "z2", "qx"):
            st[k][rows] = xy
        st["nz"][rows] = 1.0
        st["q0"][rows] = 1.0
        st["sd"][rows] = self.params["noise_mm"]
        st["land"][rows] = 1.0 if self.params["land_frames"] > 0 else 0.0
        st["ls"][rows] = 0.0
        st["mv"][rows] = 0.0
        st["hx"][rows, 0] = xy[:, 0]
        st["hy"][rows, 0] = xy[:, 1]
        st["ht"][rows, 0] = self._t[rows]
        st["gx"][rows, 0] = xy[:, 0]
        st["gy"][rows, 0] = xy[:, 1]
        # the still models start at the measurement, at rest, with the noise assumed so far
        r0 = (self.params["still_noise_mul"] * self.params["still_noise_mm"]) ** 2
        for k in ("ss", "ms"):
            st[k][rows] = 0.0
            st[k][rows, 0], st[k][rows, 2] = xy[:, 0], xy[:, 1]
        for k in ("sc", "mc"):
            st[k][rows] = np.array([r0, 0.0, _START_VAR_MM2_S2, r0, 0.0, _START_VAR_MM2_S2])
        st["mu"][rows] = _START_STILL
        st["sn"][rows] = self.params["still_noise_mm"]

    def _step(self, s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray) -> np.ndarray:
        # one compiled call for the frame (tracking/eurokernel.py); _step_arrays is its oracle
        return euro_step(s, xy, dt_s, self._prm, self._cols, _HB)

    def _step_arrays(self, s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray) -> np.ndarray:
        """The frame step in numpy array calls over all touches: the reference the compiled
        step (:func:`~depthtouch.tracking.eurokernel.euro_step`) is tested against."""
        p_col, v_col, dx_col = self._COLS["p"], self._COLS["v"], self._COLS["dx"]
        prm = self.params
        v, p_old = s[:, v_col], s[:, p_col]
        pred = p_old + v * dt_s[:, None]
        innov = xy - pred
        d_mm = np.hypot(innov[:, 0], innov[:, 1])
        w0 = smoothing_factor(dt_s, prm["min_cutoff_hz"])
        w = w0 + (1.0 - w0) * (1.0 - np.exp2(-((d_mm / prm["half_weight_mm"]) ** 2)))
        beta = w * w / (2.0 - w)
        p = pred + w[:, None] * innov
        dt = dt_s[:, None]
        dx = s[:, dx_col]
        dx = dx + smoothing_factor(dt, prm["speed_cutoff_hz"]) * ((p - p_old) / dt - dx)
        s[:, v_col] = v + (beta / dt_s)[:, None] * innov
        s[:, p_col], s[:, dx_col] = p, dx
        speed = np.hypot(dx[:, 0], dx[:, 1])
        cutoff = prm["rest_cutoff_hz"] + prm["beta_per_mm"] * np.maximum(0.0, speed - prm["rest_mm_s"])
        e_col = self._COLS["e"]
        prev = s[:, e_col]
        gap = p - prev
        a = smoothing_factor(dt_s, cutoff)
        # a gap the noise cannot explain (a tip that landed off its first measurement, a start)
        # is closed at once, as the adaptive stage's weight does
        a = a + (1.0 - a) * (1.0 - np.exp2(-((np.hypot(gap[:, 0], gap[:, 1]) / prm["hold_mm"]) ** 2)))
        e = prev + a[:, None] * gap
        s[:, e_col] = e
        if prm["reland_frames"] >= 2:
            mv_col = self._COLS["mv"]
            s[:, mv_col] = np.maximum(s[:, mv_col], (speed > prm["reland_mm_s"])[:, None])
        models_on = prm["still_p"] > 0
        if prm["lock_frames"] <= 0 and prm["land_frames"] <= 0 and not models_on:
            return e
        sd, med = self._recent(s, xy, dt_s)
        out = self._lock(s, xy, e, dt_s, sd, med)
        if models_on:
            g, still = self._still_models(s, xy, dt_s)
            out = out + g[:, None] * (still - out)
        return out

    def _still_models(self, s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
        """The still models (see the class doc): advances both models and the still
        probability; returns the output's weight on the still model and its position (mm)."""
        c = self._COLS
        prm = self.params
        p = prm["still_p"]
        mu = s[:, c["mu"]][:, 0]
        cs = (1.0 - p) * mu + p * (1.0 - mu)
        cm = 1.0 - cs
        # w[i, j]: the share of model i in model j's start (0 still, 1 moving), per touch
        w = np.stack([np.stack([(1.0 - p) * mu / cs, p * mu / cm], axis=1),
                      np.stack([p * (1.0 - mu) / cs, (1.0 - p) * (1.0 - mu) / cm], axis=1)],
                     axis=1)
        # state (touch, model, axis, pos/vel) and covariance (touch, model, axis, P00/P01/P11)
        x = np.stack([s[:, c["ss"]], s[:, c["ms"]]], axis=1).reshape(-1, 2, 2, 2)
        cov = np.stack([s[:, c["sc"]], s[:, c["mc"]]], axis=1).reshape(-1, 2, 2, 3)
        x0 = np.einsum("nij,niak->njak", w, x)
        d = x[:, :, None] - x0[:, None]  # (touch, i, j, axis, pos/vel)
        spread = np.stack([d[..., 0] * d[..., 0], d[..., 0] * d[..., 1], d[..., 1] * d[..., 1]],
                          axis=-1)
        p0 = np.einsum("nij,nijak->njak", w, cov[:, :, None] + spread)
        dt = dt_s[:, None]
        # still: the position holds (a slow random walk), no velocity
        zero = np.zeros_like(x0[:, 0, :, 0])
        xs = np.stack([x0[:, 0, :, 0], zero], axis=-1)
        ps = np.stack([p0[:, 0, :, 0] + prm["still_q_mm2_s"] * dt, zero, zero], axis=-1)
        # moving: constant velocity, white acceleration noise
        qm = prm["move_q_mm2_s3"]
        pp, pv = x0[:, 1, :, 0], x0[:, 1, :, 1]
        a00, a01, a11 = p0[:, 1, :, 0], p0[:, 1, :, 1], p0[:, 1, :, 2]
        xm = np.stack([pp + dt * pv, pv], axis=-1)
        pm = np.stack([a00 + 2.0 * dt * a01 + dt * dt * a11 + qm * dt**3 / 3.0,
                       a01 + dt * a11 + qm * dt * dt / 2.0, a11 + qm * dt], axis=-1)
        xp, pc = np.stack([xs, xm], axis=1), np.stack([ps, pm], axis=1)
        # (at least 1e-4 mm²: an exactly repeated input must not bring it to 0)
        rr = np.maximum((prm["still_noise_mul"] * s[:, c["sn"]][:, 0]) ** 2, 1e-4)
        sa = pc[..., 0] + rr[:, None, None]  # (touch, model, axis)
        inn = xy[:, None, :] - xp[..., 0]
        m2 = np.sum(inn * inn / sa, axis=2)
        det = np.prod(sa, axis=2)
        clip = np.ones_like(m2)
        clip[:, 0] = np.where(m2[:, 0] > STILL_CLIP**2,
                              STILL_CLIP / np.sqrt(np.maximum(m2[:, 0], 1e-300)), 1.0)
        yv = inn * clip[:, :, None]
        k0, k1 = pc[..., 0] / sa, pc[..., 1] / sa
        xn = np.stack([xp[..., 0] + k0 * yv, xp[..., 1] + k1 * yv], axis=-1)
        pn = np.stack([(1.0 - k0) * pc[..., 0], (1.0 - k0) * pc[..., 1],
                       pc[..., 2] - k1 * pc[..., 1]], axis=-1)
        s[:, c["ss"]], s[:, c["ms"]] = xn[:, 0].reshape(-1, 4), xn[:, 1].reshape(-1, 4)
        s[:, c["sc"]], s[:, c["mc"]] = pn[:, 0].reshape(-1, 6), pn[:, 1].reshape(-1, 6)
        lik = (1.0 + m2 / STILL_NU) ** (-(STILL_NU + 2.0) / 2.0) / np.sqrt(det)
        ls, lm = cs * lik[:, 0], cm * lik[:, 1]
        tot = ls + lm
        mu = np.where(tot > 0, ls / np.where(tot > 0, tot, 1.0), cs)
        s[:, c["mu"]] = mu[:, None]
        gate = prm["still_gate"]
        g = np.clip((mu - gate) / (1.0 - gate), 0.0, 1.0)
        return g, xn[:, 0, :, 0]

    def _recent(self, s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """The touch's measurement noise (mm RMS per axis, from the second differences of its
        measurements) and the median of its last three measurements, with this one."""
        c = self._COLS
        prm = self.params
        z1, z2 = s[:, c["z1"]], s[:, c["z2"]]
        sd, nz = s[:, c["sd"]][:, 0], s[:, c["nz"]][:, 0]
        # white noise of sd per axis gives second differences of RMS sqrt(6)·sd per axis, a
        # mean norm of 3.07·sd; a jump or a turn is clipped so that one does not inflate it
        dd = xy - 2.0 * z1 + z2
        norm = np.hypot(dd[:, 0], dd[:, 1]) / 3.07
        est = np.minimum(norm, 3.0 * sd + 1.0)
        rate_s = smoothing_factor(dt_s, 1.0 / (2.0 * np.pi * prm["noise_s"]))
        rate = np.maximum(1.0 / np.maximum(nz - 1.0, 1.0), rate_s)
        sd = np.where(nz >= 2.0, sd + rate * (est - sd), sd)
        if prm["still_p"] > 0:
            # the still models' own noise level: from its start, at the slow rate only
            sn = s[:, c["sn"]][:, 0]
            sn = np.where(nz >= 2.0, sn + rate_s * (np.minimum(norm, 3.0 * sn + 1.0) - sn), sn)
            s[:, c["sn"]] = sn[:, None]
        med = np.maximum(np.minimum(xy, z1), np.minimum(np.maximum(xy, z1), z2))
        med = np.where((nz >= 2.0)[:, None], med, xy)
        s[:, c["z2"]], s[:, c["z1"]] = z1, xy
        s[:, c["sd"]], s[:, c["nz"]] = sd[:, None], (nz + 1.0)[:, None]
        return sd, med

    @staticmethod
    def _line(hx: np.ndarray, hy: np.ndarray, ht: np.ndarray, w: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Weighted mean (mm), slope (mm/s) and the slope's standard error per mm of noise
        (1/s) of the kept measurements, weights ``w`` (0 outside the window)."""
        win = w > 0
        n = np.maximum(w.sum(axis=1), 1e-12)
        mx, my, mt = ((w * a).sum(axis=1) / n for a in (hx, hy, ht))
        dtt = np.where(win, ht - mt[:, None], 0.0)
        stt = np.maximum(np.sum(w * dtt * dtt, axis=1), 1e-12)
        sx = np.sum(w * dtt * (hx - mx[:, None]), axis=1) / stt
        sy = np.sum(w * dtt * (hy - my[:, None]), axis=1) / stt
        # the slope's standard error as if the weights counted measurements: 1/sqrt(Σw(t−t̄)²)
        # per unit noise (larger than a weighted fit's own: slower to leave the landing)
        se = 1.0 / np.sqrt(stt)
        return np.stack([mx, my], axis=1), np.stack([sx, sy], axis=1), se

    def _remember(self, s: np.ndarray, xy: np.ndarray, t: np.ndarray, med: np.ndarray
                  ) -> np.ndarray:
        """Keeps this measurement (mm, s) and the median of the last three in each touch's
        ring; returns the slot written."""
        c = self._COLS
        k = ((s[:, c["nz"]][:, 0] - 1.0) % _HB).astype(np.intp)
        r = np.arange(len(k))
        s[:, c["hx"]][r, k], s[:, c["hy"]][r, k], s[:, c["ht"]][r, k] = xy[:, 0], xy[:, 1], t
        s[:, c["gx"]][r, k], s[:, c["gy"]][r, k] = med[:, 0], med[:, 1]
        return k

    def _landing(self, s: np.ndarray, xy: np.ndarray, e: np.ndarray, t: np.ndarray,
                 sd: np.ndarray, med: np.ndarray, locked: np.ndarray) -> np.ndarray:
        """The landing and the re-landing (see the class doc): updates their fields, returns the
        output. ``t``: the measurements' time (s); ``sd``: the touch's noise (mm); ``med``: the
        median of its last three measurements; ``locked``: the touches the lock holds."""
        c = self._COLS
        prm = self.params
        cnt = s[:, c["nz"]][:, 0]  # measurements so far, this one included
        k = self._remember(s, xy, t, med)
        hx, hy, ht = s[:, c["hx"]], s[:, c["hy"]], s[:, c["ht"]]
        # the measurement index each slot holds (the newest with that remainder)
        j = (cnt - 1.0)[:, None] - ((k[:, None] - np.arange(_HB)[None, :]) % _HB)
        gx, gy = s[:, c["gx"]], s[:, c["gy"]]
        land = s[:, c["land"]][:, 0] > 0
        ls = s[:, c["ls"]][:, 0]
        kc = prm["land_restart_frames"]
        if kc >= 2:
            # a landing whose last land_restart_frames medians are flat and sit apart from the
            # ones before them (a finger that came down at a slant, then held) starts again
            # from those, once per touch (a slow drag looks flat over a few frames too)
            old = land & (ls == 0.0) & (cnt >= 2.0 * kc)
            if old.any():
                rec = (j > (cnt - 1.0 - kc)[:, None]) & (j >= 0)
                prev = (j >= np.maximum(ls, cnt - _HB)[:, None]) & ~rec & (j >= 0)
                n1, n0 = rec.sum(axis=1), np.maximum(prev.sum(axis=1), 1)
                d = np.hypot(*(((gg * rec).sum(axis=1) / np.maximum(n1, 1))
                               - ((gg * prev).sum(axis=1) / n0) for gg in (gx, gy)))
                zc = d / np.maximum(sd * np.sqrt(1.0 / np.maximum(n1, 1) + 1.0 / n0), 1e-12)
                _, sl, se = self._line(gx, gy, ht, rec.astype(np.float64))
                flat = np.hypot(sl[:, 0], sl[:, 1]) <= 0.5 * prm["land_sigmas"] * se * sd
                go = old & (zc > prm["land_restart_sigmas"]) & flat
                ls = np.where(go, cnt - kc, ls)
        kr = prm["reland_frames"]
        if kr >= 2:
            # a touch that moved, is neither landing nor locked and whose last reland_frames
            # medians are flat lands again from those (a finger that stopped after a move)
            idle = ~land & ~locked & (cnt >= kr + 2.0) & (s[:, c["mv"]][:, 0] > 0)
            if idle.any():
                rec = (j > (cnt - 1.0 - kr)[:, None]) & (j >= 0)
                _, sl, se = self._line(gx, gy, ht, rec.astype(np.float64))
                flat = np.hypot(sl[:, 0], sl[:, 1]) <= prm["reland_sigmas"] * se * sd
                go = idle & flat
                ls = np.where(go, cnt - kr, ls)
                land = land | go
                s[:, c["mv"]] = np.where(go, 0.0, s[:, c["mv"]][:, 0])[:, None]
        if not land.any():  # only the re-landing's test ran, and nothing lands
            return e
        win = (j >= np.maximum(ls, cnt - _HB)[:, None]) & (j >= 0)
        age = np.maximum((cnt - 1.0)[:, None] - j, 0.0)
        keep = 1.0 - 1.0 / max(prm["land_frames"], prm["lock_frames"], 2.0)
        wt = np.where(win, keep ** age, 0.0)
        mean = np.stack([(wt * hx).sum(axis=1), (wt * hy).sum(axis=1)], axis=1) / wt.sum(
            axis=1, keepdims=True)
        _, sl, se = self._line(gx, gy, ht, wt)
        z = np.where(cnt - ls < 3.0, 0.0, np.hypot(sl[:, 0], sl[:, 1]) / np.maximum(se * sd, 1e-12))
        lo, hi = prm["land_blend_sigmas"], prm["land_sigmas"]
        a = np.clip((z - lo) / max(hi - lo, 1e-9), 0.0, 1.0)
        out = np.where(land[:, None], mean + a[:, None] * (e - mean), e)
        land = land & (cnt - ls <= prm["land_frames"] + 1.0) & (z <= hi)
        s[:, c["land"]], s[:, c["ls"]] = land[:, None], ls[:, None]
        return out

    def _lock(self, s: np.ndarray, xy: np.ndarray, e: np.ndarray, dt_s: np.ndarray,
              sd: np.ndarray, med: np.ndarray) -> np.ndarray:
        """The lock of a finger at rest (see the class doc): updates its fields, returns the
        output."""
        c = self._COLS
        prm = self.params
        lock_frames = max(prm["lock_frames"], 2.0)  # a line needs two points
        # the sums' horizon (the landing reads them too)
        frames = max(lock_frames, prm["land_frames"])
        # stillness: the weighted least-squares line through the measurements (weights
        # decaying by 1 - 1/frames per frame; sums kept about the current time, so old times
        # shift by -dt) is slower than lock_mm_s
        q0, qt, qtt = s[:, c["q0"]][:, 0], s[:, c["qt"]][:, 0], s[:, c["qtt"]][:, 0]
        qx, qtx = s[:, c["qx"]], s[:, c["qtx"]]
        keep = 1.0 - 1.0 / frames
        qtt = (qtt - 2.0 * dt_s * qt + dt_s * dt_s * q0) * keep
        qtx = (qtx - dt_s[:, None] * qx) * keep
        qt = (qt - dt_s * q0) * keep
        q0 = q0 * keep + 1.0
        qx = qx * keep + xy
        s[:, c["q0"]], s[:, c["qt"]], s[:, c["qtt"]] = q0[:, None], qt[:, None], qtt[:, None]
        s[:, c["qx"]], s[:, c["qtx"]] = qx, qtx
        den = np.maximum(q0 * qtt - qt * qt, 1e-12)
        slope = (q0[:, None] * qtx - qt[:, None] * qx) / den[:, None]
        seen = s[:, c["nz"]][:, 0] - 1.0  # measurements so far, this one included
        speed = np.hypot(slope[:, 0], slope[:, 1])
        still = (seen >= lock_frames) & (speed <= prm["lock_mm_s"]) & (prm["lock_frames"] > 0)
        locked = s[:, c["n"]][:, 0] > 0
        reland = prm["reland_frames"] >= 2 and prm["land_frames"] > 0
        if (s[:, c["land"]] > 0).any() or (reland and (s[:, c["mv"]][~locked] > 0).any()):
            e = self._landing(s, xy, e, s[:, 2] + dt_s, sd, med, locked)
        elif reland:  # the ring must hold a touch's last measurements when it lands again
            self._remember(s, xy, s[:, 2] + dt_s, med)
        # a lock holds while the median of the last three measurements (a one-frame jump does
        # not move it) stays within its radius
        m, n, r2 = s[:, c["m"]], s[:, c["n"]][:, 0], s[:, c["r2"]][:, 0]
        stay = (n > 0) & (np.sum((med - m) ** 2, axis=1) <= r2)
        # its mean runs over the rest (the last lock_mean_frames), fed only by measurements
        # within twice its radius: a far outlier changes neither output nor mean (a nearer one
        # moves the mean by 1/n of its distance; leaving those out too measured worse, as they
        # are much of a noisy camera's spread)
        near = stay & (np.sum((xy - m) ** 2, axis=1) <= 4.0 * r2)
        n = np.where(near, np.minimum(n + 1.0, prm["lock_mean_frames"]), n)
        m = np.where(near[:, None], m + (xy - m) / np.maximum(n, 1.0)[:, None], m)
        # a new lock starts from the output so far (the 1€ stage's, or the landing's mean: no
        # jump), counted as lock_frames frames of mean (at most lock_mean_frames); its radius
        # follows the touch's noise
        # a lock that ends is remembered, unless one that ended a few frames ago still is (a
        # lock entered during an excursion must not take its place): a finger back within it
        # (a noise excursion of two or three frames, not a move) takes that lock again
        enter = (n <= 0) & still
        back = np.zeros_like(enter)
        pm, pn, pr2 = s[:, c["pm"]], s[:, c["pn"]][:, 0], s[:, c["pr2"]][:, 0]
        if prm["lock_resume_frames"] > 0:
            pt = s[:, c["pt"]][:, 0]
            fresh = (pn > 0) & (pt <= prm["lock_resume_frames"])
            ends = (n > 0) & ~stay & ~fresh
            pm = np.where(ends[:, None], m, pm)
            pn, pr2 = np.where(ends, n, pn), np.where(ends, r2, pr2)
            pt = np.where(ends, 0.0, pt + 1.0)
            s[:, c["pm"]], s[:, c["pn"]], s[:, c["pr2"]], s[:, c["pt"]] = (
                pm, pn[:, None], pr2[:, None], pt[:, None])
            back = (enter & (pn > 0) & (pt <= prm["lock_resume_frames"])
                    & (np.sum((med - pm) ** 2, axis=1) <= pr2))
        m = np.where(back[:, None], pm, np.where(enter[:, None], e, m))
        r2 = np.where(back, pr2, np.where(
            enter, np.maximum(prm["lock_mm"], prm["lock_sigmas"] * sd) ** 2, r2))
        n = np.where(back, pn, np.where(enter, min(lock_frames, prm["lock_mean_frames"]),
                                        np.where(stay, n, 0.0)))
        s[:, c["m"]] = m
        s[:, c["n"]], s[:, c["r2"]] = n[:, None], r2[:, None]
        return np.where((n > 0)[:, None], m, e)
