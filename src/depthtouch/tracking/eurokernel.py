"""The ``adaptive_euro`` filter's frame step, compiled: the same arithmetic as the array
methods of :class:`~depthtouch.tracking.adaptive_euro.AdaptiveEuroFilter` (its oracle in the
tests), touch by touch in plain floats.

The array version runs some 150 numpy calls of a few microseconds each per frame, whatever the
number of touches: 0.27 ms of a 1.25 ms frame with five touches (``make bench``). Here one call
does the frame. Compiled by numba on the first run and cached on disk, like the touch kernels.

The state row layout is the filter's (``FilterBase``: output, time, then the fields); the
columns each field starts at are passed in :data:`FIELD_ORDER` order, the parameters in
:data:`PARAM_ORDER` order.
"""

from __future__ import annotations

import math

import numba
import numpy as np

#: the fields whose first column the kernel is given, in this order
FIELD_ORDER = ("p", "v", "dx", "e", "z1", "z2", "nz", "sd", "q0", "qt", "qtt", "qx", "qtx",
               "m", "n", "r2", "land", "ls", "hx", "hy", "ht", "gx", "gy", "mv", "pm", "pn",
               "pr2", "pt", "ss", "sc", "ms", "mc", "mu", "sn")
#: the parameters the kernel reads, in this order
PARAM_ORDER = ("min_cutoff_hz", "half_weight_mm", "rest_cutoff_hz", "rest_mm_s", "beta_per_mm",
               "speed_cutoff_hz", "hold_mm", "lock_mm", "lock_frames", "lock_mean_frames",
               "lock_mm_s", "lock_sigmas", "noise_mm", "noise_s", "land_frames",
               "land_blend_sigmas", "land_sigmas", "land_restart_frames", "land_restart_sigmas",
               "reland_frames", "reland_sigmas", "reland_mm_s", "lock_resume_frames",
               "still_p", "still_q_mm2_s", "move_q_mm2_s3", "still_noise_mm", "still_noise_mul",
               "still_gate")

(_P, _V, _DX, _E, _Z1, _Z2, _NZ, _SD, _Q0, _QT, _QTT, _QX, _QTX, _M, _N, _R2, _LAND, _LS,
 _HX, _HY, _HT, _GX, _GY, _MV, _PM, _PN, _PR2, _PT, _SS, _SC, _MS, _MC,
 _MU, _SN) = range(len(FIELD_ORDER))
(_MIN_CUT, _HALF_W, _REST_CUT, _REST_MM_S, _BETA, _SPEED_CUT, _HOLD, _LOCK_MM, _LOCK_FRAMES,
 _LOCK_MEAN, _LOCK_MM_S, _LOCK_SIG, _NOISE_MM, _NOISE_S, _LAND_FRAMES, _LAND_BLEND, _LAND_SIG,
 _RESTART_FRAMES, _RESTART_SIG, _RELAND_FRAMES, _RELAND_SIG, _RELAND_MM_S,
 _RESUME_FRAMES, _STILL_P, _STILL_Q, _MOVE_Q, _STILL_NOISE, _STILL_MUL,
 _STILL_GATE) = range(len(PARAM_ORDER))
#: the still models' likelihoods are Student-t with this many degrees of freedom (a tip
#: estimate's one-frame jumps are not Gaussian); the still model's innovation is clipped at
#: this many standard deviations
STILL_NU = 3.0
STILL_CLIP = 3.0
#: the least measurement variance the still models take (mm²)
_MIN_VAR_MM2 = 1e-4


@numba.njit(cache=True, nogil=True, inline="always")
def _alpha(dt: float, cutoff_hz: float) -> float:
    """A first-order low-pass's weight of a new sample (``filterbase.smoothing_factor``)."""
    return dt / (dt + 1.0 / (2.0 * math.pi * cutoff_hz))


@numba.njit(cache=True, nogil=True)
def _line(row: np.ndarray, c: np.ndarray, w: np.ndarray, hb: int) -> tuple[float, float, float]:
    """Slope (mm/s, x and y) and the slope's standard error per mm of noise (1/s) of the line
    through the ring's medians (``gx``, ``gy`` at times ``ht``) with weights ``w``
    (``AdaptiveEuroFilter._line``)."""
    gx, gy, ht = c[_GX], c[_GY], c[_HT]
    n = 0.0
    sx = sy = st = 0.0
    for m in range(hb):
        n += w[m]
        sx += w[m] * row[gx + m]
        sy += w[m] * row[gy + m]
        st += w[m] * row[ht + m]
    n = max(n, 1e-12)
    mx, my, mt = sx / n, sy / n, st / n
    stt = cx = cy = 0.0
    for m in range(hb):
        if w[m] > 0.0:
            d = row[ht + m] - mt
            stt += w[m] * d * d
            cx += w[m] * d * (row[gx + m] - mx)
            cy += w[m] * d * (row[gy + m] - my)
    stt = max(stt, 1e-12)
    return cx / stt, cy / stt, 1.0 / math.sqrt(stt)


@numba.njit(cache=True, nogil=True)
def _landing(row: np.ndarray, c: np.ndarray, prm: np.ndarray, hb: int, x: float, y: float,
             ex: float, ey: float, t: float, sd: float, medx: float, medy: float, locked: bool,
             reland: bool, j: np.ndarray, w: np.ndarray) -> tuple[float, float]:
    """One touch's landing and re-landing (``AdaptiveEuroFilter._landing``): keeps the
    measurement in the ring, updates the fields, returns the output. ``j``, ``w``: scratch
    arrays of the ring's length (the frame's, reused touch by touch)."""
    cnt = row[c[_NZ]]  # measurements so far, this one included
    k = int((cnt - 1.0) % hb)
    row[c[_HX] + k], row[c[_HY] + k], row[c[_HT] + k] = x, y, t
    row[c[_GX] + k], row[c[_GY] + k] = medx, medy
    land = row[c[_LAND]] > 0.0
    if not (land or reland):  # only the ring is kept (read if the touch lands again)
        return ex, ey
    # the measurement index each slot holds (the newest with that remainder)
    for m in range(hb):
        j[m] = (cnt - 1.0) - ((k - m) % hb)
        w[m] = 0.0
    ls = row[c[_LS]]
    kc = prm[_RESTART_FRAMES]
    if kc >= 2.0 and land and ls == 0.0 and cnt >= 2.0 * kc:
        # flat last medians that sit apart from the ones before: start again from them, once
        n1 = n0 = 0.0
        s1x = s1y = s0x = s0y = 0.0
        lo = max(ls, cnt - hb)
        for m in range(hb):
            if j[m] < 0.0:
                continue
            gx, gy = row[c[_GX] + m], row[c[_GY] + m]
            if j[m] > cnt - 1.0 - kc:
                w[m] = 1.0
                n1 += 1.0
                s1x += gx
                s1y += gy
            elif j[m] >= lo:
                n0 += 1.0
                s0x += gx
                s0y += gy
        n1 = max(n1, 1.0)
        n0 = max(n0, 1.0)
        d = math.hypot(s1x / n1 - s0x / n0, s1y / n1 - s0y / n0)
        zc = d / max(sd * math.sqrt(1.0 / n1 + 1.0 / n0), 1e-12)
        slx, sly, se = _line(row, c, w, hb)
        if zc > prm[_RESTART_SIG] and math.hypot(slx, sly) <= 0.5 * prm[_LAND_SIG] * se * sd:
            ls = cnt - kc
    kr = prm[_RELAND_FRAMES]
    if kr >= 2.0 and not land and not locked and cnt >= kr + 2.0 and row[c[_MV]] > 0.0:
        for m in range(hb):
            w[m] = 1.0 if (j[m] > cnt - 1.0 - kr and j[m] >= 0.0) else 0.0
        slx, sly, se = _line(row, c, w, hb)
        if math.hypot(slx, sly) <= prm[_RELAND_SIG] * se * sd:
            ls = cnt - kr
            land = True
            row[c[_MV]] = 0.0
    if not land:
        return ex, ey
    keep = 1.0 - 1.0 / max(prm[_LAND_FRAMES], prm[_LOCK_FRAMES], 2.0)
    lo = max(ls, cnt - hb)
    wsum = mx = my = 0.0
    for m in range(hb):
        if j[m] >= lo and j[m] >= 0.0:
            w[m] = keep ** max(cnt - 1.0 - j[m], 0.0)
            wsum += w[m]
            mx += w[m] * row[c[_HX] + m]
            my += w[m] * row[c[_HY] + m]
        else:
            w[m] = 0.0
    mx /= wsum
    my /= wsum
    slx, sly, se = _line(row, c, w, hb)
    z = 0.0 if cnt - ls < 3.0 else math.hypot(slx, sly) / max(se * sd, 1e-12)
    lo_s, hi_s = prm[_LAND_BLEND], prm[_LAND_SIG]
    a = min(max((z - lo_s) / max(hi_s - lo_s, 1e-9), 0.0), 1.0)
    still_landing = cnt - ls <= prm[_LAND_FRAMES] + 1.0 and z <= hi_s
    row[c[_LAND]] = 1.0 if still_landing else 0.0
    row[c[_LS]] = ls
    return mx + a * (ex - mx), my + a * (ey - my)


@numba.njit(cache=True, nogil=True)
def _still_models(row: np.ndarray, c: np.ndarray, prm: np.ndarray, x: float, y: float,
                  dt: float, st: np.ndarray, cv: np.ndarray, inn: np.ndarray, m2: np.ndarray,
                  det: np.ndarray) -> tuple[float, float, float]:
    """The still models' step (``AdaptiveEuroFilter._still_models``): advances both models and
    the still probability in ``row``; returns the output's weight on the still model and the
    still model's position (mm). ``st`` (2, 2, 2), ``cv`` (2, 2, 3), ``inn`` (2, 2), ``m2``
    and ``det`` (2,): scratch, reused touch by touch (model, axis, then pos/vel or P00/P01/P11)."""
    p = prm[_STILL_P]
    mu = row[c[_MU]]
    cs = (1.0 - p) * mu + p * (1.0 - mu)
    cm = 1.0 - cs
    # mixing weights: w[i][j], the share of model i in model j's start (0 still, 1 moving)
    w00, w10 = (1.0 - p) * mu / cs, p * (1.0 - mu) / cs
    w01, w11 = p * mu / cm, (1.0 - p) * (1.0 - mu) / cm
    r = prm[_STILL_MUL] * row[c[_SN]]
    rr = max(r * r, _MIN_VAR_MM2)  # an exactly repeated input must not bring it to 0
    qs, qm = prm[_STILL_Q] * dt, prm[_MOVE_Q]
    # per axis: each model's state (position, velocity) and covariance after the prediction
    for j in range(2):
        m2[j], det[j] = 0.0, 1.0
        wa = w00 if j == 0 else w01
        wb = w10 if j == 0 else w11
        for a in range(2):
            sp, sv = row[c[_SS] + 2 * a], row[c[_SS] + 2 * a + 1]
            mp, mv = row[c[_MS] + 2 * a], row[c[_MS] + 2 * a + 1]
            x0p, x0v = wa * sp + wb * mp, wa * sv + wb * mv
            dsp, dsv, dmp, dmv = sp - x0p, sv - x0v, mp - x0p, mv - x0v
            ks, km = c[_SC] + 3 * a, c[_MC] + 3 * a
            p00 = wa * (row[ks] + dsp * dsp) + wb * (row[km] + dmp * dmp)
            p01 = wa * (row[ks + 1] + dsp * dsv) + wb * (row[km + 1] + dmp * dmv)
            p11 = wa * (row[ks + 2] + dsv * dsv) + wb * (row[km + 2] + dmv * dmv)
            if j == 0:  # still: the position holds (a slow random walk), no velocity
                x0v = 0.0
                p00, p01, p11 = p00 + qs, 0.0, 0.0
            else:  # moving: constant velocity, white acceleration noise
                x0p = x0p + dt * x0v
                p00 = p00 + 2.0 * dt * p01 + dt * dt * p11 + qm * dt * dt * dt / 3.0
                p01 = p01 + dt * p11 + qm * dt * dt / 2.0
                p11 = p11 + qm * dt
            z = x if a == 0 else y
            inn[j, a] = z - x0p
            sa = p00 + rr
            m2[j] += inn[j, a] * inn[j, a] / sa
            det[j] *= sa
            st[j, a, 0], st[j, a, 1] = x0p, x0v
            cv[j, a, 0], cv[j, a, 1], cv[j, a, 2] = p00, p01, p11
    for j in range(2):
        clip = 1.0
        if j == 0 and m2[0] > STILL_CLIP * STILL_CLIP:
            clip = STILL_CLIP / math.sqrt(m2[0])
        base = c[_SS] if j == 0 else c[_MS]
        cb = c[_SC] if j == 0 else c[_MC]
        for a in range(2):
            p00, p01, p11 = cv[j, a, 0], cv[j, a, 1], cv[j, a, 2]
            sa = p00 + rr
            k0, k1 = p00 / sa, p01 / sa
            yv = inn[j, a] * clip
            row[base + 2 * a] = st[j, a, 0] + k0 * yv
            row[base + 2 * a + 1] = st[j, a, 1] + k1 * yv
            row[cb + 3 * a] = (1.0 - k0) * p00
            row[cb + 3 * a + 1] = (1.0 - k0) * p01
            row[cb + 3 * a + 2] = p11 - k1 * p01
    ls = cs * (1.0 + m2[0] / STILL_NU) ** (-(STILL_NU + 2.0) / 2.0) / math.sqrt(det[0])
    lm = cm * (1.0 + m2[1] / STILL_NU) ** (-(STILL_NU + 2.0) / 2.0) / math.sqrt(det[1])
    mu = ls / (ls + lm) if ls + lm > 0.0 else cs
    row[c[_MU]] = mu
    g = min(1.0, max(0.0, (mu - prm[_STILL_GATE]) / (1.0 - prm[_STILL_GATE])))
    return g, row[c[_SS]], row[c[_SS] + 2]


@numba.njit(cache=True, nogil=True)
def euro_step(s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray, prm: np.ndarray,
              c: np.ndarray, hb: int) -> np.ndarray:
    """Advance the state rows ``s`` (one per touch, updated in place) by ``dt_s`` (s, > 0) to
    the measurements ``xy`` (mm); returns the outputs (N, 2) mm. ``prm``: the parameters in
    :data:`PARAM_ORDER` order; ``c``: each field's first column, :data:`FIELD_ORDER` order;
    ``hb``: the ring's length."""
    out = np.empty((s.shape[0], 2))
    lock_on = prm[_LOCK_FRAMES] > 0.0
    land_on = prm[_LAND_FRAMES] > 0.0
    reland = prm[_RELAND_FRAMES] >= 2.0 and land_on
    resume_on = prm[_RESUME_FRAMES] > 0.0 and lock_on
    models_on = prm[_STILL_P] > 0.0
    lock_frames = max(prm[_LOCK_FRAMES], 2.0)  # a line needs two points
    frames = max(lock_frames, prm[_LAND_FRAMES])  # the sums' horizon (the landing reads them)
    keep = 1.0 - 1.0 / frames
    ring_j, ring_w = np.empty(hb), np.empty(hb)  # the landing's scratch, reused touch by touch
    # the still models' scratch, the same way
    m_st, m_cv, m_inn = np.empty((2, 2, 2)), np.empty((2, 2, 3)), np.empty((2, 2))
    m_m2, m_det = np.empty(2), np.empty(2)
    for i in range(s.shape[0]):
        row = s[i]
        x, y, dt = xy[i, 0], xy[i, 1], dt_s[i]
        # the adaptive stage
        px0, py0 = row[c[_P]], row[c[_P] + 1]
        vx, vy = row[c[_V]], row[c[_V] + 1]
        predx, predy = px0 + vx * dt, py0 + vy * dt
        ix, iy = x - predx, y - predy
        w0 = _alpha(dt, prm[_MIN_CUT])
        w = w0 + (1.0 - w0) * (1.0 - np.exp2(-((math.hypot(ix, iy) / prm[_HALF_W]) ** 2)))
        beta = w * w / (2.0 - w)
        px, py = predx + w * ix, predy + w * iy
        ws = _alpha(dt, prm[_SPEED_CUT])
        dxx = row[c[_DX]] + ws * ((px - px0) / dt - row[c[_DX]])
        dxy = row[c[_DX] + 1] + ws * ((py - py0) / dt - row[c[_DX] + 1])
        row[c[_V]], row[c[_V] + 1] = vx + (beta / dt) * ix, vy + (beta / dt) * iy
        row[c[_P]], row[c[_P] + 1] = px, py
        row[c[_DX]], row[c[_DX] + 1] = dxx, dxy
        # the 1€ stage, its cutoff from the speed, a gap the noise cannot explain closed at once
        speed = math.hypot(dxx, dxy)
        a = _alpha(dt, prm[_REST_CUT] + prm[_BETA] * max(0.0, speed - prm[_REST_MM_S]))
        ex0, ey0 = row[c[_E]], row[c[_E] + 1]
        gx, gy = px - ex0, py - ey0
        a = a + (1.0 - a) * (1.0 - np.exp2(-((math.hypot(gx, gy) / prm[_HOLD]) ** 2)))
        ex, ey = ex0 + a * gx, ey0 + a * gy
        row[c[_E]], row[c[_E] + 1] = ex, ey
        if prm[_RELAND_FRAMES] >= 2.0 and speed > prm[_RELAND_MM_S]:
            row[c[_MV]] = 1.0
        if not lock_on and not land_on and not models_on:
            out[i, 0], out[i, 1] = ex, ey
            continue
        # the noise (second differences) and the median of the last three measurements
        z1x, z1y, z2x, z2y = row[c[_Z1]], row[c[_Z1] + 1], row[c[_Z2]], row[c[_Z2] + 1]
        sd, nz = row[c[_SD]], row[c[_NZ]]
        if nz >= 2.0:
            dd = math.hypot(x - 2.0 * z1x + z2x, y - 2.0 * z1y + z2y) / 3.07
            rate_s = _alpha(dt, 1.0 / (2.0 * math.pi * prm[_NOISE_S]))
            noise_rate = max(1.0 / max(nz - 1.0, 1.0), rate_s)
            sd = sd + noise_rate * (min(dd, 3.0 * sd + 1.0) - sd)
            if models_on:
                sn = row[c[_SN]]
                row[c[_SN]] = sn + rate_s * (min(dd, 3.0 * sn + 1.0) - sn)
            medx = max(min(x, z1x), min(max(x, z1x), z2x))
            medy = max(min(y, z1y), min(max(y, z1y), z2y))
        else:
            medx, medy = x, y
        row[c[_Z2]], row[c[_Z2] + 1], row[c[_Z1]], row[c[_Z1] + 1] = z1x, z1y, x, y
        row[c[_SD]], row[c[_NZ]] = sd, nz + 1.0
        # stillness: the weighted least-squares line through the measurements (sums kept about
        # the current time, so old times shift by -dt) slower than lock_mm_s
        q0, qt, qtt = row[c[_Q0]], row[c[_QT]], row[c[_QTT]]
        qxx, qxy, qtxx, qtxy = row[c[_QX]], row[c[_QX] + 1], row[c[_QTX]], row[c[_QTX] + 1]
        qtt = (qtt - 2.0 * dt * qt + dt * dt * q0) * keep
        qtxx, qtxy = (qtxx - dt * qxx) * keep, (qtxy - dt * qxy) * keep
        qt = (qt - dt * q0) * keep
        q0 = q0 * keep + 1.0
        qxx, qxy = qxx * keep + x, qxy * keep + y
        row[c[_Q0]], row[c[_QT]], row[c[_QTT]] = q0, qt, qtt
        row[c[_QX]], row[c[_QX] + 1], row[c[_QTX]], row[c[_QTX] + 1] = qxx, qxy, qtxx, qtxy
        den = max(q0 * qtt - qt * qt, 1e-12)
        slope = math.hypot((q0 * qtxx - qt * qxx) / den, (q0 * qtxy - qt * qxy) / den)
        still = nz >= lock_frames and slope <= prm[_LOCK_MM_S] and lock_on
        n = row[c[_N]]
        locked = n > 0.0
        if land_on:
            ex, ey = _landing(row, c, prm, hb, x, y, ex, ey, row[2] + dt, sd, medx, medy,
                              locked, reland and row[c[_MV]] > 0.0 and not locked, ring_j, ring_w)
        # the lock holds while the median of the last three stays within its radius; its mean
        # is fed only by measurements within twice the radius
        mx, my, r2 = row[c[_M]], row[c[_M] + 1], row[c[_R2]]
        stay = n > 0.0 and (medx - mx) ** 2 + (medy - my) ** 2 <= r2
        if stay and (x - mx) ** 2 + (y - my) ** 2 <= 4.0 * r2:
            n = min(n + 1.0, prm[_LOCK_MEAN])
            mx, my = mx + (x - mx) / max(n, 1.0), my + (y - my) / max(n, 1.0)
        if resume_on:
            # a lock that ends is remembered for a quick return, unless one that ended a few
            # frames ago still is (a lock entered during an excursion must not take its place)
            fresh = row[c[_PN]] > 0.0 and row[c[_PT]] <= prm[_RESUME_FRAMES]
            if n > 0.0 and not stay and not fresh:
                row[c[_PM]], row[c[_PM] + 1], row[c[_PN]], row[c[_PR2]] = mx, my, n, r2
                row[c[_PT]] = 0.0
            else:
                row[c[_PT]] += 1.0
        if n <= 0.0 and still:
            pmx, pmy = row[c[_PM]], row[c[_PM] + 1]
            if (resume_on and row[c[_PN]] > 0.0 and row[c[_PT]] <= prm[_RESUME_FRAMES]
                    and (medx - pmx) ** 2 + (medy - pmy) ** 2 <= row[c[_PR2]]):
                # back within the lock it left a few frames ago: that lock again
                mx, my, n, r2 = pmx, pmy, row[c[_PN]], row[c[_PR2]]
            else:  # a new lock starts from the output so far
                mx, my = ex, ey
                r2 = max(prm[_LOCK_MM], prm[_LOCK_SIG] * sd) ** 2
                n = min(lock_frames, prm[_LOCK_MEAN])
        elif not stay:
            n = 0.0
        row[c[_M]], row[c[_M] + 1], row[c[_N]], row[c[_R2]] = mx, my, n, r2
        if n > 0.0:
            ex, ey = mx, my
        if models_on:
            g, sx, sy = _still_models(row, c, prm, x, y, dt, m_st, m_cv, m_inn, m_m2,
                                      m_det)
            ex, ey = ex + g * (sx - ex), ey + g * (sy - ey)
        out[i, 0], out[i, 1] = ex, ey
    return out


def warm_up() -> None:
    """Compile (or load from the on-disk cache) the kernel on one touch."""
    from .adaptive_euro import AdaptiveEuroFilter

    f = AdaptiveEuroFilter()
    for k in range(3):
        f.update(np.array([1]), np.array([[10.0 + k, 20.0]]), k / 30.0)
