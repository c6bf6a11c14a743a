"""Input preparation of the INS filters: static detection, IMU gap bridging, GNSS fix arrays and the
heading alignment from the GNSS course (moved here from :mod:`aidnav.filters.loose`, names kept there).
"""

from __future__ import annotations

import numpy as np

from aidnav.data import ImuData
from aidnav.io._std import quality_std_factor
from aidnav.jit import njit
from aidnav.nav.alignment import coarse_align_static
from aidnav.nav.earth import radii
from aidnav.nav.rotations import euler_from_dcm, wrap_2pi, wrap_pi
from aidnav.units import DEG, DEG_H, G0, UG

from .layout import RN_LEVER


def velocity_from_positions(gnss, window_s: float = 1.0, std_pos=None):
    """Velocity ENU [m/s] and its 1σ per axis from central differences of the GNSS positions.

    For fix k the difference is taken between the last fix at or before t_k − window_s/2 and the first at
    or after t_k + window_s/2 (so that the baseline T ≥ window_s), v = Δp / T and σ_v = √(σ_i² + σ_j²) / T
    per axis (σ: ``std_pos`` (m, 3), else the file's σ, else 1 m; white position noise assumed).
    Returns (vel (m, 3), std (m, 3)); NaN where no baseline exists.
    """
    t = np.asarray(gnss.time, float)
    m = len(t)
    vel = np.full((m, 3), np.nan)
    sd = np.full((m, 3), np.nan)
    if m < 2:
        return vel, sd
    sp = std_pos if std_pos is not None else (gnss.std_pos if gnss.std_pos is not None else np.ones((m, 3)))
    i = np.clip(np.searchsorted(t, t - 0.5 * window_s, side="right") - 1, 0, m - 1)
    j = np.clip(np.searchsorted(t, t + 0.5 * window_s, side="left"), 0, m - 1)
    T = t[j] - t[i]
    ok = T >= 0.5 * window_s - 1e-9  # one-sided at the ends of the log
    rm, rn = radii(gnss.lat)
    dlon = wrap_pi(gnss.lon[j] - gnss.lon[i])
    d = np.column_stack([dlon * (rn + gnss.height) * np.cos(gnss.lat),
                         (gnss.lat[j] - gnss.lat[i]) * (rm + gnss.height), gnss.height[j] - gnss.height[i]])
    Ts = np.where(ok, T, np.nan)[:, None]
    vel[:] = d / Ts
    sd[:] = np.sqrt(sp[i] ** 2 + sp[j] ** 2) / Ts
    return vel, sd


def gnss_velocity_for_init(gnss, g, window_s: float = 1.0):
    """(velocity, σ) per fix for the initialisation and the static test: the receiver's where it has one
    (``g``: :func:`gnss_arrays`), else from position differences (:func:`velocity_from_positions`)."""
    g_vel, g_svel = g[4], g[6]
    vd, sd = velocity_from_positions(gnss, window_s, g[5])
    has = ~np.isnan(g_vel)
    return np.where(has, g_vel, vd), np.where(has, g_svel, sd)


def visible_fixes(gnss, withheld):
    """The fixes the filter may see: ``gnss`` without the ``withheld`` ones (bool mask, simulated outages).
    Everything that looks at the GNSS (static detection, IMU noise from static samples) takes these, so a
    withheld fix never tells the filter the vehicle stood still inside an outage."""
    if withheld is None or gnss is None:
        return gnss
    return gnss.subset(~np.asarray(withheld, bool))


def static_flags(imu, gnss, cfg, window_s: float = 1.0) -> np.ndarray:
    """Per-IMU-sample static detection: low gyro and accel spread over ``window_s`` and, where GNSS
    velocity exists, GNSS speed below ``cfg.constraints.static_gnss_speed_m_s``."""
    return StaticDetector(gnss, cfg, imu.rate_hz, window_s)(imu.time, imu.dtheta, imu.dv, imu.t0)


F64_MAX = np.finfo(np.float64).max


@njit(cache=True, nogil=True)
def _spread_flags(time, dtheta, dv, t_prev, ring, k, n, thr_w, thr_f, ok):
    """``ok[i]``: the spread (σ, the largest of the 3 axes) of the gyro rates below ``thr_w`` and of the
    specific forces below ``thr_f`` over the last ``n`` samples (fewer at the log start), for the samples
    ``k``, ``k + 1``, … of a log. The rates are the increments over Δt (NaN where Δt ≤ 0, then 0; ±inf
    the largest float: ``np.nan_to_num``); their running sums and sums of squares from the log start are
    kept for the last n + 1 samples in ``ring`` (4, n + 1, 3): sum ω, sum ω², sum f, sum f² at global
    index g (0: before the first sample) in row g mod (n + 1); updated in place (the next chunk goes on
    from them). The numbers of a cumulative sum over the whole log (``np.cumsum``: added in order)."""
    R = n + 1
    tp = t_prev
    for i in range(time.shape[0]):
        dt = time[i] - tp
        tp = time[i]
        if dt <= 0.0:
            dt = np.nan
        g = k + i + 1
        cur, prv = g % R, (g - 1) % R
        lo = max(g - n, 0)
        lr = lo % R
        cnt = g - lo
        good = True
        for j in range(6):
            q = 2 * (j // 3)
            a = (dtheta[i, j] if j < 3 else dv[i, j - 3]) / dt
            if np.isnan(a):
                a = 0.0
            elif a == np.inf:
                a = F64_MAX
            elif a == -np.inf:
                a = -F64_MAX
            jj = j % 3
            c = ring[q, prv, jj] + a
            c2 = ring[q + 1, prv, jj] + a * a
            ring[q, cur, jj], ring[q + 1, cur, jj] = c, c2
            mean = (c - ring[q, lr, jj]) / cnt
            var = (c2 - ring[q + 1, lr, jj]) / cnt - mean * mean
            if np.isnan(var) or not np.sqrt(max(var, 0.0)) < (thr_w if j < 3 else thr_f):
                good = False
        ok[i] = good


STATIC_BASELINE_MAX_S = 30.0  #: the longest baseline of the position-difference speed of the static test [s]


def static_baseline_s(gnss, speed_m_s: float, std_pos=None) -> float:
    """The baseline [s] of the position-difference speed of the static test (:class:`StaticDetector`) for
    fixes without a receiver velocity: the one at which the fixes' median horizontal σ gives a speed σ of
    a third of the threshold ``speed_m_s`` (√2·σ/T), from 1 s to :data:`STATIC_BASELINE_MAX_S`. ``std_pos``
    (m, 3): the σ the filter uses (:func:`effective_std_pos`); else the file's, else 1 m."""
    sp = std_pos if std_pos is not None else (gnss.std_pos if gnss.std_pos is not None
                                              else np.ones((len(gnss), 3)))
    sig = float(np.nanmedian(np.hypot(sp[:, 0], sp[:, 1]) / np.sqrt(2.0))) if len(gnss) else 1.0
    need = 3.0 * np.sqrt(2.0) * sig / speed_m_s if np.isfinite(sig) else STATIC_BASELINE_MAX_S
    return float(min(max(need, 1.0), STATIC_BASELINE_MAX_S))


class StaticDetector:
    """:func:`static_flags` over consecutive chunks of a log (call it with each chunk in order: the
    running sums carry over, so the flags are the whole-log ones)."""

    def __init__(self, gnss, cfg, rate_hz: float, window_s: float = 1.0):
        c = self.c = cfg.constraints
        self.n = max(2, int(round(window_s * rate_hz)))
        self.gnss, self.k, self.ring = gnss, 0, None
        gv = gnss.vel if gnss is not None else None
        if gnss is not None and len(gnss) > 1 and (gv is None or np.all(np.isnan(gv[:, :2]))):
            # no receiver velocity: from position differences, and "static" only where their σ can tell
            # the threshold apart (σ_v <= threshold / 2): noisy fixes never say static. The baseline is
            # long enough for the fixes' median σ to do so (σ_v = √2·σ/T = threshold / 3: a fix at rest
            # reads above the threshold with probability e^(−4.5) ≈ 1 %), 1 s at least, at most
            # STATIC_BASELINE_MAX_S; a long baseline only shortens the static spans (by T/2 at each end)
            # with the σ the filter uses (quality factors, floors, the first pass's scale): a file that
            # understates it (σ = 0, floored) would otherwise get a baseline too short to tell static
            sp = effective_std_pos(gnss, cfg)
            vd, sd = velocity_from_positions(gnss, static_baseline_s(gnss, c.static_gnss_speed_m_s, sp), sp)
            sig = np.hypot(sd[:, 0], sd[:, 1])
            gv = np.where((sig <= 0.5 * c.static_gnss_speed_m_s)[:, None], vd, np.inf)
            gv = np.where(np.isnan(gv), np.inf, gv)
        self.sp = None if gnss is None or gv is None or len(gnss) == 0 else np.hypot(gv[:, 0], gv[:, 1])
        # no fix of the log below the speed threshold: no sample is static, whatever the IMU's spread (the
        # flags need both), so the spread's running sums are never needed (a flight, a drive without stops)
        self.never = self.sp is None or not np.any(self.sp < c.static_gnss_speed_m_s)

    def __call__(self, time, dtheta, dv, t_prev):
        c = self.c
        if self.never:
            self.k += len(time)
            return np.zeros(len(time), np.bool_)
        ok = np.empty(len(time), np.bool_)
        if self.ring is None:  # running sums of the rates and their squares at the last n + 1 samples
            self.ring = np.zeros((4, self.n + 1, 3))
        _spread_flags(np.ascontiguousarray(time, np.float64), np.ascontiguousarray(dtheta, np.float64),
                      np.ascontiguousarray(dv, np.float64), float(t_prev), self.ring, self.k, self.n,
                      c.static_gyro_std_deg_s * DEG, float(c.static_accel_std_m_s2), ok)
        self.k += len(time)
        gnss = self.gnss
        j = np.clip(np.searchsorted(gnss.time, time), 0, len(gnss) - 1)
        jp = np.clip(j - 1, 0, len(gnss) - 1)
        near = (np.abs(gnss.time[j] - time) < 1.0) | (np.abs(gnss.time[jp] - time) < 1.0)
        ok &= near & (np.maximum(self.sp[j], self.sp[jp]) < c.static_gnss_speed_m_s)
        return ok


#: columns of the gap variance (:func:`bridge_gaps`): roll/pitch [rad²], heading [rad²], velocity per axis
#: [(m/s)²], position per axis [m²]
GAP_TILT, GAP_HEADING, GAP_VEL, GAP_POS = range(4)


#: an IMU interval longer than this many times the log's median interval is a gap (:func:`imu_gaps`)
GAP_FACTOR = 5.0


@njit(cache=True)
def surely_no_gap(t, t0, factor):
    """True where :func:`imu_gaps` can find no gap in the sample times ``t`` (from ``t0``) without their
    median: where at most (n − 1) // 2 of the n intervals are ≤ max/``factor`` (times 1 + 1e-9), the
    median's lower middle value, so the median too, exceeds it and no interval exceeds ``factor`` × the
    median. False where that does not hold (a gap possible: ask :func:`imu_gaps`). Two passes, no array
    (issue 40, session 18: the median's partition of a copy was ~0.2 ms of a tight call)."""
    n = t.shape[0]
    if n < 2:
        return False
    mx = t[0] - t0
    for k in range(1, n):
        mx = max(mx, t[k] - t[k - 1])
    thr = mx / factor * (1.0 + 1e-9)
    c = 1 if t[0] - t0 <= thr else 0
    for k in range(1, n):
        if t[k] - t[k - 1] <= thr:
            c += 1
    return c <= (n - 1) // 2


def imu_gaps(imu, factor: float = GAP_FACTOR, med: float | None = None, empty=None):
    """The sample intervals of ``imu`` (Δt_k = t_k − t_{k−1}, t_{−1} = ``imu.t0``), the nominal interval
    (``med``, default their median) and the indices of the samples after a gap (Δt > ``factor`` × nominal):
    what :func:`bridge_gaps` decides from the sample times alone. ``empty``: an allocator ``(shape) ->
    array`` for the intervals and the median's scratch (:class:`aidnav.filters.tight_input.Arena`; the
    same values)."""
    t = imu.time
    if empty is None or len(t) == 0:
        dt = np.diff(np.concatenate([[imu.t0], t]))
        med = float(np.median(dt)) if med is None else med
        return dt, med, np.flatnonzero(dt > factor * med)
    dt = empty(len(t))
    dt[0] = t[0] - imu.t0
    np.subtract(t[1:], t[:-1], out=dt[1:])
    if med is None:
        scratch = empty(len(t))
        scratch[:] = dt
        med = float(np.median(scratch, overwrite_input=True))  # the same order statistics, in place
    return dt, med, np.flatnonzero(dt > factor * med)


def bridge_gaps(imu, events: list, factor: float = GAP_FACTOR, window_s: float = 1.0,
                med: float | None = None, start: int = 0, bounds=None, empty=None):
    """Increments ready for the kernel, with IMU time gaps (interval > ``factor`` × median) bridged.

    A sample after a gap either already spans the gap (e.g. rates × Δt from a reader: |Δv|/Δt ≈ g)
    or only covers one nominal interval (a sensor that dropped samples: |Δv|/Δt_nominal ≈ g). In the
    second case the gap is bridged by holding the mean rates of the ``window_s`` before it (holding one
    sample's rates would scale its white noise by the gap length instead of its square root).
    Either way the motion during the gap is unknown: the returned ``gap_var`` (N, 4) holds, for the
    sample after each gap, the variance it adds (columns ``GAP_TILT``, ``GAP_HEADING``, ``GAP_VEL``,
    ``GAP_POS``: roll/pitch and heading [rad²], each velocity axis [(m/s)²], each position axis [m²]),
    from the held rates and from what the vehicle can do (``bounds``: a
    :class:`aidnav.filters.config.MotionBounds`, default its defaults; uniform distributions within
    the bounds, σ = bound/√3):

    * rates: σ_ω² = spread² + |ω̄|²/3 (the turn may end anywhere in the gap) + ω_max²/3 (or begin);
      heading σ = σ_ω T, roll/pitch the same, both capped (heading at π: unknown; tilt at the bound);
    * specific force: σ_a² = spread² + a_max²/3 (floors 0.1 deg/s, 0.05 m/s² on the spreads);
      velocity σ = σ_a T (capped at the largest speed), position σ = σ_a T²/2 (capped at v_max T).

    Each gap and the decision go into ``events``. Returns (dtheta, dv, gap_var); the arrays are copies
    only when something was changed.
    Streaming (:mod:`aidnav.filters.stream`): ``med`` the nominal interval (default: the median here),
    ``start`` the first sample to look at (the ones before it are the window of the previous chunk);
    the arrays returned begin at ``start``. ``empty``: an allocator ``(shape) -> array`` for the large
    arrays (:func:`imu_gaps`' intervals, the copies; the same values).
    """
    if bounds is None:
        from .config import MotionBounds  # lazy: pydantic (the filters' kernels do not need it)

        bounds = MotionBounds()
    dt, med, gaps = imu_gaps(imu, factor, med, empty)
    gaps = gaps[gaps >= start]
    gap_var = np.zeros((len(imu) - start, 4))
    if len(gaps) == 0:
        return imu.dtheta[start:], imu.dv[start:], gap_var
    if empty is None:
        dth, dv = imu.dtheta.copy(), imu.dv.copy()
    else:
        dth, dv = empty(imu.dtheta.shape), empty(imu.dv.shape)
        dth[:], dv[:] = imu.dtheta, imu.dv
    nwin = max(2, int(round(window_s / med)))
    w_max, a_max = bounds.max_turn_rate_deg_s * DEG, bounds.max_accel_m_s2
    v_max, tilt_max = bounds.max_speed_m_s, bounds.max_tilt_deg * DEG
    for k in gaps:
        T = dt[k]
        lo = max(0, k - nwin)
        if k - lo >= 2:
            w = imu.dtheta[lo:k] / dt[lo:k, None]
            f = imu.dv[lo:k] / dt[lo:k, None]
            w_mean, f_mean = w.mean(axis=0), f.mean(axis=0)
            s_w0 = max(float(np.sqrt(np.mean(np.var(w, axis=0)) + np.dot(w_mean, w_mean) / 3.0)),
                       np.radians(0.1))
            s_f0 = max(float(np.sqrt(np.mean(np.var(f, axis=0)))), 0.05)
        else:
            w_mean, f_mean = imu.dtheta[k] / med, imu.dv[k] / med
            s_w0, s_f0 = np.radians(1.0), 0.5
        s_w = np.sqrt(s_w0 ** 2 + w_max ** 2 / 3.0)
        s_f = np.sqrt(s_f0 ** 2 + a_max ** 2 / 3.0)
        f_span = np.linalg.norm(dv[k]) / T
        f_nom = np.linalg.norm(dv[k]) / med
        if abs(f_span - 9.8) < abs(f_nom - 9.8):
            how = "its increments already span the gap"
        else:
            dth[k] = w_mean * T
            dv[k] = f_mean * T
            how = f"bridged with the mean rates of the {nwin * med:.2f} s before it"
        sh, st_ = min(s_w * T, np.pi), min(s_w * T, tilt_max / np.sqrt(3.0))
        sv, sp = min(s_f * T, v_max), min(0.5 * s_f * T * T, v_max * T)
        gap_var[k - start] = [st_ ** 2, sh ** 2, sv ** 2, sp ** 2]
        events.append(f"IMU gap of {T:.3f} s before t={imu.time[k]:.3f} ({T / med:.0f} nominal intervals); "
                      f"{how}; variance added for the unknown motion (bounds {v_max:g} m/s, {a_max:g} m/s^2, "
                      f"{np.degrees(w_max):g} deg/s): heading ({np.degrees(sh):.1f} deg)^2, roll/pitch "
                      f"({np.degrees(st_):.2f} deg)^2, velocity ({sv:.2f} m/s)^2, position ({sp:.2f} m)^2")
    return dth[start:], dv[start:], gap_var


def gnss_arrays(gnss, cfg):
    """GNSS fixes as kernel arrays with σ floors and quality factors applied (heights as read)."""
    g = cfg.gnss
    m = len(gnss)
    spos = (np.tile(g.default_pos_std_m, (m, 1)) if gnss.std_pos is None else gnss.std_pos.copy())
    svel = (np.tile(g.default_vel_std_m_s, (m, 1)) if gnss.std_vel is None else gnss.std_vel.copy())
    if gnss.quality is not None:  # the quality rules of aidnav.io._std: float ×f, single ×s, others ×1
        fac = quality_std_factor(gnss.quality, g.float_std_factor, g.single_std_factor)
        spos *= fac[:, None]
        svel *= fac[:, None]
    spos = np.maximum(spos, g.min_pos_std_m)
    svel = np.maximum(svel, g.min_vel_std_m_s)
    vel = gnss.vel if gnss.vel is not None else np.full((m, 3), np.nan)
    # heights arrive ellipsoidal: the datum offset is applied once, by the reader (aidnav.io)
    return (gnss.time, gnss.lat, gnss.lon, gnss.height,
            np.ascontiguousarray(vel), np.ascontiguousarray(spos), np.ascontiguousarray(svel))


def effective_std_pos(gnss, cfg) -> np.ndarray:
    """The position σ (m, 3) [m] the filter gives the fixes: the file's (or the default), the quality
    factors and floors of :func:`gnss_arrays`, times ``gnss.pos_std_scale`` / ``pos_std_scale_up``."""
    return gnss_arrays(gnss, cfg)[5] * np.asarray(cfg.gnss.pos_std_scales)


def course_alignment(gnss, cfg, t_start: float, vel=None, std=None):
    """First GNSS epoch after ``t_start`` where the course is meaningful: horizontal speed above
    ``init.course_min_speed_m_s`` and at least 5 times its σ. ``vel``/``std``: velocities and σ per fix
    (default: the receiver's, else from position differences, :func:`velocity_from_positions`).

    Returns (time, course [rad], index of the fix) or None.
    """
    if vel is None:
        if gnss.vel is not None and not np.all(np.isnan(gnss.vel[:, :2])):
            vel = gnss.vel
            std = gnss.std_vel if gnss.std_vel is not None else np.zeros_like(vel)
        else:
            vel, std = velocity_from_positions(gnss)
    std = np.zeros_like(vel) if std is None else np.nan_to_num(std, nan=np.inf)
    ve, vn = vel[:, 0], vel[:, 1]
    sp = np.nan_to_num(np.hypot(ve, vn))
    idx = np.flatnonzero(_course_ok(sp, np.hypot(std[:, 0], std[:, 1]), cfg) & (gnss.time > t_start))
    if len(idx) == 0:
        return None
    i = idx[0]
    return float(gnss.time[i]), float(wrap_2pi(np.arctan2(ve[i], vn[i]))), int(i)


def initial_state(imu, gnss, cfg, t_imu, g, use, events):
    """Initial strapdown state of the loose filter: given (``init.mode = given``) or automatic from any
    state (issue 26): at the first GNSS fix, static (coarse alignment, gyrocompassing where the gyros
    resolve the Earth rate) or moving (velocity from GNSS, from position differences with their σ when
    the receiver gives none; roll/pitch from the specific force corrected by the GNSS acceleration;
    heading from the course only when it is meaningful, :func:`_course_ok`, else later; heading σ π
    until then).

    g : the arrays of :func:`gnss_arrays`; use : bool mask of the usable fixes. Returns a dict with t0,
    k0 (first IMU sample used), lat0, lon0, h0, v0, rph, att_sig [rad], reset_idx (sample index of the
    course alignment, −1: none; relative to k0), reset_time (its time, inf: never, None: none),
    reset_heading [rad], reset_nav (15,) of the course fix (``layout.RN_*`` up to the lever arm),
    vel_sig (3,) [m/s] of an in-motion start (None: the configured σ), level: (f^b (3,) [m/s²], σ_w [rad])
    where roll and pitch are the specific force's with an unstated σ (:func:`_start_levelling`; the set-up
    then ties the tilt to the accelerometer states), else None.
    """
    if cfg.init.mode == "given":
        return _given_state(imu, cfg)
    g_t, g_lat, g_lon, g_h, g_vel, g_spos, g_svel = g
    ini = cfg.init
    i0, k0, t0 = _first_fix(t_imu, g_t, use, events)
    lat0, lon0, h0 = g_lat[i0], g_lon[i0], g_h[i0]
    # velocity at the fixes: the receiver's, else from position differences with their σ
    gsub = gnss.subset(use)
    iu = np.flatnonzero(use)
    gs = (g_t[iu], g_lat[iu], g_lon[iu], g_h[iu], g_vel[iu], g_spos[iu], g_svel[iu])
    vel_u, svel_u = gnss_velocity_for_init(gsub, gs)
    j0 = int(np.searchsorted(iu, i0))
    rph, att_sig, v0, vsig0, known_h, level = _automatic_attitude(imu, t_imu, k0, gsub, vel_u, svel_u, j0,
                                                                  cfg, events, lat0, h0)
    reset_idx, reset_heading, reset_time = -1, 0.0, None
    reset_nav = np.full(RN_LEVER, np.nan)
    if ini.heading_deg is None and not known_h:
        reset_idx, reset_heading, reset_time, reset_nav = _course_reset(gsub, cfg, t0, vel_u, svel_u, iu, g,
                                                                        t_imu, k0, events)
        att_sig[2] = np.pi  # unknown until the course alignment
    if vsig0 is not None:
        events.append(f"in-motion start: velocity from GNSS {np.round(v0, 2)} m/s (sigma "
                      f"{np.round(vsig0, 3)} m/s)")
    return dict(t0=t0, k0=k0, lat0=lat0, lon0=lon0, h0=h0, v0=v0, rph=rph, att_sig=att_sig,
                reset_idx=reset_idx, reset_heading=reset_heading, reset_nav=reset_nav, vel_sig=vsig0,
                reset_time=reset_time, level=level)


def _given_state(imu, cfg) -> dict:
    """:func:`initial_state` of ``init.mode = given``: the configured position, velocity and attitude at
    the start of the log."""
    ini = cfg.init
    missing = [k for k in ("lat_deg", "lon_deg", "height_m", "roll_deg", "pitch_deg", "heading_deg")
               if getattr(ini, k) is None]
    if missing:
        raise ValueError(f"init.mode = given needs init.{', init.'.join(missing)}")
    return dict(t0=float(imu.t0 + cfg.imu.time_offset_s), k0=0, lat0=ini.lat_deg * DEG,
                lon0=ini.lon_deg * DEG, h0=ini.height_m, v0=np.array(ini.velocity_m_s, float),
                rph=np.array([ini.roll_deg, ini.pitch_deg, ini.heading_deg]) * DEG,
                att_sig=np.array(ini.attitude_sigma_deg) * DEG, reset_idx=-1, reset_heading=0.0,
                reset_nav=np.full(RN_LEVER, np.nan), vel_sig=None, reset_time=None, level=None)


def _first_fix(t_imu, g_t, use, events):
    """The automatic start at the first usable GNSS fix inside the IMU span: (its index, the first IMU
    sample used k0, t0)."""
    first = np.flatnonzero(use & (g_t >= t_imu[0]))
    if len(first) == 0:
        raise ValueError("no GNSS fix inside the IMU time span: cannot initialise")
    i0 = first[0]
    k0 = int(np.searchsorted(t_imu, g_t[i0], side="right"))
    if k0 >= len(t_imu) - 1:  # e.g. --outage withholding every fix but the last ones
        raise ValueError(f"the first GNSS fix the filter may use (t={g_t[i0]:.3f} s; {int((~use).sum())} "
                         f"fixes withheld or unusable before it) is at the end of the IMU log "
                         f"({t_imu[0]:.3f}…{t_imu[-1]:.3f} s): nothing is left to initialise from — "
                         "shorten or move the --outage, or give a GNSS file that overlaps the IMU log")
    if k0 > 0:
        events.append(f"initialisation at the first GNSS fix t={g_t[i0]:.3f}: {k0} IMU samples before it "
                      "are not used")
    return i0, k0, float(g_t[i0]) if k0 == 0 else float(t_imu[k0 - 1])


def _automatic_attitude(imu, t_imu, k0, gsub, vel_u, svel_u, j0, cfg, events, lat0, h0):
    """Roll, pitch and heading of an automatic start at sample k0 (fix j0 of the usable ones): static
    coarse alignment and gyrocompassing (:mod:`aidnav.nav.alignment`), or the in-motion start
    (:func:`_moving_start`); the configured angles win. Returns (rph, att_sig, v0, vel_sig or None,
    whether the heading is known now, the levelling (f^b [m/s²], σ_w [rad]) or None).

    Roll and pitch from the specific force (static or in motion) whose σ is not stated are a
    *levelling* (:func:`_start_levelling`)."""
    ini = cfg.init
    v_first = vel_u[j0]
    # static coarse alignment (aidnav.nav.alignment): roll/pitch from the mean specific force over
    # the static window; heading by gyrocompassing where the gyro grade resolves the Earth rate
    t_a = t_imu[k0]
    win_imu = ImuData(t_imu, imu.dtheta, imu.dv, t0=imu.t0 + cfg.imu.time_offset_s)
    gb = cfg.imu.gyro_bias_sigma_deg_h * DEG_H
    roll, pitch, gc_heading, ainfo = coarse_align_static(win_imu, lat0, t_a, t_a + ini.static_window_s,
                                                         height=h0, gyro_bias_std=gb)
    heading = 0.0
    att_sig = np.array(ini.attitude_sigma_deg) * DEG
    gw = (gsub.time >= t_a) & (gsub.time < t_a + ini.static_window_s)
    sp_w = np.hypot(vel_u[gw, 0], vel_u[gw, 1])
    ss_w = np.hypot(svel_u[gw, 0], svel_u[gw, 1])
    thr = cfg.constraints.static_gnss_speed_m_s
    # moving: a speed above the static threshold by 3σ (noisy fixes at a standstill do not count)
    moving = bool(np.any(sp_w > thr + 3.0 * np.nan_to_num(ss_w, nan=np.inf)))
    v0 = np.zeros(3)
    vsig0 = None
    heading_now = None
    if moving or abs(ainfo["f_norm"] - ainfo["gravity"]) > 0.02 * ainfo["gravity"]:
        roll, pitch, gc_heading, heading_now, vsig0, f_move = _moving_start(
            imu, t_imu, k0, gsub, vel_u, svel_u, j0, cfg, events, ainfo)
        att_sig[0:2] = np.maximum(att_sig[0:2], _moving_tilt_sigma(gsub, vel_u, svel_u, j0, cfg))
        if np.all(np.isfinite(v_first)):
            v0 = v_first.copy()
        elif np.any(np.isfinite(v_first)):
            v0 = np.nan_to_num(v_first)
    if ini.heading_deg is not None:
        heading = ini.heading_deg * DEG
    elif heading_now is not None:
        heading = heading_now[0]
    elif gc_heading is not None:
        heading = gc_heading
    if ini.roll_deg is not None:
        roll = ini.roll_deg * DEG
    if ini.pitch_deg is not None:
        pitch = ini.pitch_deg * DEG
    rph = np.array([roll, pitch, heading])
    f = ainfo["mean_f"] / G0
    if not moving:
        events.append(f"coarse alignment over {ini.static_window_s:g} s: roll {np.degrees(roll):.2f} "
                      f"deg, pitch {np.degrees(pitch):.2f} deg (mean specific force {np.round(f, 4)} g)")
    stated = "attitude_sigma_deg" in ini.model_fields_set
    if ini.heading_deg is None and gc_heading is not None:
        events.append(f"heading by gyrocompassing: {np.degrees(gc_heading):.2f} deg "
                      f"(sigma {np.degrees(ainfo['heading_std']):.2f} deg)")
        att_sig[2] = max(att_sig[2], ainfo["heading_std"]) if stated else ainfo["heading_std"]
    elif ini.heading_deg is None and heading_now is not None:
        att_sig[2] = heading_now[1]
    elif ini.heading_deg is None:
        events.append(f"no gyrocompass heading ({ainfo['heading_reason']}): heading from GNSS course")
    level = None
    if not stated and ini.roll_deg is None and ini.pitch_deg is None:
        level = _start_levelling(ainfo, cfg, att_sig, f_move if vsig0 is not None else None)
    return rph, att_sig, v0, vsig0, gc_heading is not None or heading_now is not None, level


def _start_levelling(ainfo, cfg, att_sig, f_move):
    """(f^b [m/s²], σ_w [rad]) of a start whose roll and pitch are the specific force's (issue 35).

    Its tilt error is what the accelerometer errors do to that force (−b/g, …) plus the levelling's own
    error σ_w: one combination with the accelerometer states, which the fixes observe (at rest, as the sum
    φ·g + C b) and nothing but turns separates. The loose set-up's prior holds it so
    (:func:`aidnav.filters.prior.levelled_tilt_covariance`). An independent tilt σ (main until session 14:
    the configured 2°, or b/g itself where that was below a tenth of it) lets the first fixes read the one
    observed sum as two pieces of information: of the size of b/g, the tilt's variance halves in seconds
    and a bias draw of 2–3σ escapes the tilt's 3σ (the matrix's parked row, seed 10: −36 mg on x, roll
    2.5° off at σ 0.55°); and where the prior leaves the split loose, a heading held unknown at rest spins
    the tilt's frame and moves the split (parked × ship, seed 0: tilt 6–14° off at σ 1–2°).

    σ_w, the part that stays independent: the tilt σ the start would have had alone (in motion: the
    in-motion σ, :func:`_moving_tilt_sigma`, with the 1-s force ``f_move`` the roll and pitch came from;
    at rest the configured ``init.attitude_sigma_deg``) less the accelerometer's part,
    √(σ_tilt² − (σ_b/g)²): the marginal tilt σ stays what it was, only its correlation is new, and the
    first fixes (not the prior) decide how well the sum is known. The static window's standard error of
    the mean force alone (0.009° on the real drive) claimed the sum to 0.15 mg before any fix: on the
    drive with its GNSS tags 0.2 s early (the time offset still unknown when the car moves off) the first
    outage's RMS error became 49 m (1.7 m with the configured part). Where the levelling ⊕ the
    accelerometer's part is below a tenth of the configured σ (a navigation-grade IMU: 0.002°), that
    levelling is used as σ_w instead, so the configured 2° does not decide the σ of the first epochs of a
    run whose tilt error is 0.01° (grade navigation × no option, roll RMS(err)/RMS(σ) 0.23 with it; the
    rule of session 12's ``_levelling_sigma``)."""
    b = _accel_sigma(cfg) / G0
    rest = float(np.sqrt(max(float(np.max(att_sig[0:2])) ** 2 - b * b, 0.0)))
    if f_move is not None:
        return np.array(f_move, float), rest
    se_f = ainfo["se_f"]
    se = float(np.hypot(se_f[0], se_f[1])) / G0 if np.all(np.isfinite(se_f)) else np.inf
    fine = float(np.hypot(se, b)) < 0.1 * float(np.max(att_sig[0:2]))
    return np.array(ainfo["mean_f"], float), se if fine else rest


def _accel_sigma(cfg) -> float:
    """The model's horizontal accelerometer error σ at rest [m/s²]: the bias σ ⊕ the misalignment σ × g
    where the misalignment is a state."""
    im = cfg.imu
    b = im.accel_bias_sigma_ug * UG
    if im.accel_misalignment:
        b = float(np.hypot(b, np.radians(im.accel_misalignment_sigma_deg) * G0))
    return b


def _course_reset(gsub, cfg, t0, vel_u, svel_u, iu, g, t_imu, k0, events):
    """The course alignment of a start whose heading is unknown: the first meaningful GNSS course after
    t0 (:func:`course_alignment`) → (reset_idx relative to k0, reset_heading [rad], reset_time, reset_nav
    of the fix (``layout.RN_*`` up to the lever arm)); never found: reset_idx past the log, time inf."""
    g_t, g_lat, g_lon, g_h, g_vel, g_spos, g_svel = g
    ca = course_alignment(gsub, cfg, t0, vel=vel_u, std=svel_u)
    if ca is None:
        events.append("heading never aligned: no GNSS course above init.course_min_speed_m_s with "
                      "a speed well above its sigma")
        # never: the heading stays unknown (engine: no information)
        return len(t_imu) + 1, 0.0, np.inf, np.full(RN_LEVER, np.nan)
    tca, course, ica_u = ca[:3]
    ica = iu[ica_u]
    meas = ~np.isnan(vel_u[ica_u])
    vel_g = np.where(meas, np.nan_to_num(vel_u[ica_u]), 0.0)
    svel = np.where(meas, svel_u[ica_u], 1.0)
    acc = fix_acceleration(gsub.time, vel_u, ica_u)
    reset_nav = np.array([*vel_g, g_lat[ica], g_lon[ica], g_h[ica], *svel, *g_spos[ica], *acc])
    mount_h = cfg.imu.mounting_rph_deg[2] * DEG
    # vehicle heading = course; IMU heading = vehicle heading + mounting heading
    reset_heading = float(wrap_2pi(course + mount_h))
    reset_idx = int(np.searchsorted(t_imu[k0:], tca, side="left"))
    events.append(f"heading from GNSS course at t={tca:.3f}: {np.degrees(reset_heading):.2f} deg")
    return reset_idx, reset_heading, float(tca), reset_nav


def fix_acceleration(t, vel, i, span_s: float = 1.0) -> np.ndarray:
    """The vehicle's acceleration ENU [m/s²] at fix ``i`` from the velocities ``vel`` (n, 3) of the fixes
    at times ``t``: the central difference of its neighbours, else the one-sided difference with the
    fix's one neighbour, each within ``span_s`` (a fix after an outage has only the next one); 0 where
    none is (or a component is not measured)."""
    lo = i - 1 if i > 0 and t[i] - t[i - 1] <= span_s else i
    hi = i + 1 if i + 1 < len(t) and t[i + 1] - t[i] <= span_s else i
    if hi == lo:
        return np.zeros(3)
    a = (np.asarray(vel[hi], float) - np.asarray(vel[lo], float)) / (t[hi] - t[lo])
    return np.where(np.isfinite(a), a, 0.0)


def _course_ok(speed, sig_h, cfg):
    """A GNSS course is meaningful above ``init.course_min_speed_m_s`` and where the speed is at least
    5 times its σ (course σ below about 11°; a parked vehicle's noisy fixes never qualify)."""
    return (speed > cfg.init.course_min_speed_m_s) & (speed > 5.0 * sig_h)


def _moving_start(imu, t_imu, k0, gsub, vel, svel, j0, cfg, events, ainfo):
    """In-motion start at fix j0: heading from the course now when it is meaningful (:func:`_course_ok`),
    roll and pitch from the mean specific force over 1 s corrected by the GNSS-derived acceleration
    (rotated into the IMU's level frame with that heading; without it only the magnitude is known and
    enters the tilt σ). Returns (roll, pitch, None, (heading, σ) or None, σ_v (3,), the 1-s mean specific
    force f^b (3,) [m/s², uncorrected])."""
    sp = float(np.hypot(vel[j0, 0], vel[j0, 1]))
    sg = float(np.hypot(svel[j0, 0], svel[j0, 1])) if np.all(np.isfinite(svel[j0, :2])) else np.inf
    heading_now = None
    if np.isfinite(sp) and _course_ok(sp, sg, cfg):
        course = float(wrap_2pi(np.arctan2(vel[j0, 0], vel[j0, 1])))
        h = wrap_2pi(course + cfg.imu.mounting_rph_deg[2] * DEG)
        hs = float(np.hypot(cfg.init.course_heading_sigma_deg * DEG, np.arctan2(sg, sp)))
        heading_now = (h, hs)
    a_n = _gnss_acceleration(gsub, vel, j0)
    t_a = t_imu[k0]
    m = (t_imu >= t_a) & (t_imu < t_a + 1.0)
    dt = np.diff(np.concatenate([[imu.t0 + cfg.imu.time_offset_s], t_imu]))[m]
    f_b = imu.dv[m].sum(axis=0) / max(dt.sum(), 1e-9) if m.any() else ainfo["mean_f"]
    g_b = np.array(f_b, float)
    if heading_now is not None and np.all(np.isfinite(a_n)):
        h = heading_now[0]
        right, fwd = np.array([np.cos(h), -np.sin(h), 0.0]), np.array([np.sin(h), np.cos(h), 0.0])
        g_b = g_b - np.array([a_n @ right, a_n @ fwd, a_n[2]])
    roll = float(np.arctan2(-g_b[0], g_b[2]))
    pitch = float(np.arctan2(g_b[1], np.hypot(g_b[0], g_b[2])))
    events.append(f"in-motion start (GNSS speed {sp:.2f} m/s): roll {np.degrees(roll):.2f}, pitch "
                  f"{np.degrees(pitch):.2f} deg from the specific force"
                  + (" corrected by the GNSS acceleration" if heading_now is not None else "")
                  + (f"; heading {np.degrees(heading_now[0]):.2f} deg from the course (sigma "
                     f"{np.degrees(heading_now[1]):.2f} deg)" if heading_now is not None else
                     "; heading unknown until the course is meaningful"))
    return roll, pitch, None, heading_now, np.nan_to_num(svel[j0], nan=1.0), f_b


def _gnss_acceleration(gsub, vel, j0, window_s: float = 1.0):
    """Acceleration ENU [m/s²] at fix j0 from the velocities about ``window_s`` apart (NaN: unknown)."""
    t = gsub.time
    j1 = int(np.searchsorted(t, t[j0] + window_s))
    if j1 >= len(t) or t[j1] <= t[j0]:
        return np.full(3, np.nan)
    return (vel[j1] - vel[j0]) / (t[j1] - t[j0])


def _moving_tilt_sigma(gsub, vel, svel, j0, cfg):
    """Roll/pitch σ of an in-motion start [rad]: the error of the acceleration correction (velocity σ
    over the 1 s baseline) and the accelerometer bias, over g; with no heading the whole horizontal
    acceleration (its direction in the body is unknown); at least 2°."""
    g = G0
    a = _gnss_acceleration(gsub, vel, j0)
    sa = float(np.nan_to_num(np.hypot(svel[j0, 0], svel[j0, 1]), nan=1.0)) * np.sqrt(2.0)
    sig = np.hypot(sa, cfg.imu.accel_bias_sigma_ug * UG) / g
    sp = float(np.hypot(vel[j0, 0], vel[j0, 1]))
    sg = float(np.hypot(svel[j0, 0], svel[j0, 1]))
    if not (np.isfinite(sp) and _course_ok(sp, sg, cfg)):
        sig = np.hypot(sig, float(np.hypot(a[0], a[1])) / g if np.all(np.isfinite(a)) else 10.0 * DEG)
    return max(float(np.arctan(sig)), 2.0 * DEG)


def coarse_mounting(imu, t_imu, gnss, vel, min_speed_m_s: float = 3.0, window_s: float = 1.0):
    """Coarse IMU → vehicle mounting of a car from the log itself (no configuration): the vehicle frame's
    horizontal acceleration [lateral, longitudinal] = [s·χ̇, ṡ] from the GNSS speed s and course χ, the
    body's from the specific force with the mean specific force over the log as "up" (a car is level on
    average); the mounting heading is the rotation about up that best maps one onto the other
    (θ = arg Σ z_v z̄_b, z = right + i·forward). Returns (C_b^v (3, 3), roll, pitch, heading [rad] of
    C_b^v = C(r, p, h) as the NHC uses it, the number of epochs used) or None with fewer than 20 epochs
    above ``min_speed_m_s`` or a fit that does not explain the acceleration (|Σ z_v z̄_b| < 0.5 Σ|z_v||z_b|).
    """
    t = np.asarray(gnss.time, float)
    s = np.hypot(vel[:, 0], vel[:, 1])
    chi = np.unwrap(np.arctan2(vel[:, 0], np.where(np.isfinite(vel[:, 1]), vel[:, 1], 0.0)))
    ok = np.isfinite(s) & (s > min_speed_m_s)
    if ok.sum() < 20:
        return None
    dt_i = np.diff(np.concatenate([[imu.t0], imu.time]))
    csum_v = np.vstack([np.zeros((1, 3)), np.cumsum(imu.dv, axis=0)])
    csum_t = np.concatenate([[0.0], np.cumsum(dt_i)])
    up = imu.dv.sum(axis=0)
    up = up / np.linalg.norm(up)
    e1 = np.cross(np.array([0.0, 1.0, 0.0]), up)
    if np.linalg.norm(e1) < 0.5:
        e1 = np.cross(up, np.array([0.0, 0.0, 1.0]))
        e1 = np.cross(e1, up)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    zs_v, zs_b = [], []
    for k in np.flatnonzero(ok):
        i = np.searchsorted(t, t[k] - 0.5 * window_s)
        j = np.searchsorted(t, t[k] + 0.5 * window_s) - 1
        if i < 0 or j >= len(t) or j <= i or not (ok[i] and ok[j]):
            continue
        T = t[j] - t[i]
        a_long = (s[j] - s[i]) / T
        a_lat = s[k] * (chi[j] - chi[i]) / T
        a = int(np.searchsorted(t_imu, t[i]))
        b = int(np.searchsorted(t_imu, t[j]))
        if b - a < 5:
            continue
        f = (csum_v[b] - csum_v[a]) / (csum_t[b] - csum_t[a])
        zs_v.append(a_lat + 1j * a_long)
        zs_b.append(f @ e1 + 1j * (f @ e2))
    if len(zs_v) < 20:
        return None
    zv, zb = np.array(zs_v), np.array(zs_b)
    c = np.sum(zv * np.conj(zb))
    if abs(c) < 0.5 * np.sum(np.abs(zv) * np.abs(zb)):
        return None
    th = float(np.angle(c))
    Rz = np.array([[np.cos(th), -np.sin(th), 0.0], [np.sin(th), np.cos(th), 0.0], [0.0, 0.0, 1.0]])
    cbv = Rz @ np.vstack([e1, e2, up])
    r, p, h = euler_from_dcm(np.ascontiguousarray(cbv))
    return cbv, float(r), float(p), float(wrap_2pi(h)), len(zv)


def noise_from_static(imu, static, cfg, events, min_s: float = 5.0):
    """Online IMU white-noise estimate (``imu.noise_from_static``): over the samples where both the IMU
    and GNSS say static (``static``, :func:`static_flags`), in runs of at least 1 s each with its own mean
    removed (bias, gravity, tilt), the variance of the sampled rates and specific forces per axis; its
    white-noise equivalent σ √dt (RMS over the axes, dt the median sample interval) raises the ARW / VRW
    the configuration did not state (a running engine's vibration, invisible in a datasheet, is noise
    to the filter). Needs ``min_s`` seconds of static samples. Returns the configuration."""
    im = cfg.imu
    todo = [k for k in ("arw_deg_sqrt_h", "vrw_m_s_sqrt_h") if k not in im.model_fields_set]
    if not im.noise_from_static or not todo or len(imu) < 2:
        return cfg
    dt = np.diff(np.concatenate([[imu.t0], imu.time]))
    dtm = float(np.median(dt))
    n1 = max(2, int(round(1.0 / dtm)))
    st = np.asarray(static, bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], st.astype(np.int8), [0]])))
    ss, n = np.zeros(2), 0
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        if b - a < n1:
            continue
        for j, x in enumerate((imu.dtheta[a:b] / dt[a:b, None], imu.dv[a:b] / dt[a:b, None])):
            ss[j] += float(((x - x.mean(axis=0)) ** 2).sum()) / 3.0
        n += b - a
    if n * dtm < min_s:
        events.append(f"IMU noise not estimated from the log: {n * dtm:.1f} s static (at least {min_s:g} s)")
        return cfg
    sig = np.sqrt(ss / n)  # rad/s, m/s² (RMS over the axes)
    est = {"arw_deg_sqrt_h": float(np.degrees(sig[0]) * np.sqrt(dtm) * 60.0),
           "vrw_m_s_sqrt_h": float(sig[1] * np.sqrt(dtm) * 60.0)}
    upd = {k: max(getattr(im, k), est[k]) for k in todo}
    events.append(f"IMU noise from {n * dtm:.1f} s static in the log (white-noise equivalent of the sample "
                  f"spread {np.degrees(sig[0]):.3f} deg/s, {sig[1]:.4f} m/s^2 at {1 / dtm:.0f} Hz): ARW "
                  f"{est['arw_deg_sqrt_h']:.2f} deg/sqrt(h), VRW {est['vrw_m_s_sqrt_h']:.3f} m/s/sqrt(h); "
                  "used: " + ", ".join(f"{k} {v:.3g}" for k, v in upd.items()))
    return cfg.model_copy(update={"imu": im.model_copy(update=upd)})


#: correlation time of a receiver's position errors when the configuration states none [s]: multipath and
#: the residual atmospheric errors of a moving receiver decorrelate over tens of seconds (Groves 2013,
#: §9.3–9.4); physics of the error sources, not fitted on any log
GNSS_ERROR_TAU_S = 30.0
#: below this median horizontal σ the fixes are carrier-phase (RTK) solutions, whose errors (centimetres)
#: cannot make the navigation σ dishonest by more than that: white errors, as the receiver states them
CARRIER_PHASE_SIGMA_M = 0.1


def correlated_gnss_errors(cfg, gnss, events):
    """The automatic choice of ``gnss.error_tau_s`` (when the configuration does not state it): fixes
    faster than 1 Hz carry errors correlated over many fixes (a white-error filter would take 10 Hz fixes
    as 10× the information they hold), so they get three Gauss–Markov position-error states with
    τ :data:`GNSS_ERROR_TAU_S` and, unless ``gnss.error_sigma_m`` is stated, the median σ the fixes give
    per axis (after the floors; the rows then the white part: the total σ is overstated by at most √2, a
    cautious choice); at 1 Hz or slower, and for carrier-phase fixes (median horizontal σ below
    :data:`CARRIER_PHASE_SIGMA_M`), the errors are treated as white. The decision goes into
    ``events``. Returns the configuration to use."""
    g = cfg.gnss
    if "error_tau_s" in g.model_fields_set or g.use == "velocity" or len(gnss) < 3:
        return cfg
    dt = float(np.median(np.diff(np.asarray(gnss.time, float))))
    rate = 1.0 / dt if dt > 0 else 0.0
    med = np.nanmedian(gnss_arrays(gnss, cfg)[5], axis=0) * np.asarray(g.pos_std_scales)
    if not rate > 1.0 + 1e-6:
        events.append(f"GNSS at {rate:.2g} Hz: position errors treated as white (correlated-error states "
                      "only above 1 Hz; gnss.error_tau_s sets them)")
        return cfg
    if np.nanmax(med[:2]) < CARRIER_PHASE_SIGMA_M:
        events.append(f"GNSS at {rate:.2g} Hz with a median horizontal sigma of {np.nanmax(med[:2]):.3g} m "
                      "(carrier-phase fixes: errors of centimetres): position errors treated as white; "
                      "gnss.error_tau_s sets correlated-error states")
        return cfg
    upd = {"error_tau_s": GNSS_ERROR_TAU_S}
    if "error_sigma_m" not in g.model_fields_set:
        upd["error_sigma_m"] = tuple(float(v) for v in med)
    sig = upd.get("error_sigma_m", g.error_sigma_m)
    events.append(f"GNSS at {rate:.2g} Hz: position errors modelled as correlated (3 Gauss-Markov states, "
                  f"tau {GNSS_ERROR_TAU_S:g} s, sigma E/N/U {sig[0]:.3g}/{sig[1]:.3g}/{sig[2]:.3g} m; the "
                  "fixes' own sigma is the white part); gnss.error_tau_s: 0 treats them as white")
    return cfg.model_copy(update={"gnss": g.model_copy(update=upd)})
