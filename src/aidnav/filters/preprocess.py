"""Input preparation of the INS filters: static detection, IMU gap bridging, GNSS fix arrays and the
heading alignment from the GNSS course (moved here from :mod:`aidnav.filters.loose`, names kept there).
"""

from __future__ import annotations

import numpy as np


def static_flags(imu, gnss, cfg, window_s: float = 1.0) -> np.ndarray:
    """Per-IMU-sample static detection: low gyro and accel spread over ``window_s`` and, where GNSS
    velocity exists, GNSS speed below ``cfg.constraints.static_gnss_speed_m_s``."""
    c = cfg.constraints
    dt = np.diff(np.concatenate([[imu.t0], imu.time]))
    dt[dt <= 0] = np.nan
    w = imu.dtheta / dt[:, None]
    f = imu.dv / dt[:, None]
    n = max(2, int(round(window_s * imu.rate_hz)))

    def rolling_std(a):
        a = np.nan_to_num(a)
        cs = np.cumsum(np.vstack([np.zeros((1, a.shape[1])), a]), axis=0)
        cs2 = np.cumsum(np.vstack([np.zeros((1, a.shape[1])), a * a]), axis=0)
        idx = np.arange(1, len(a) + 1)
        lo = np.maximum(idx - n, 0)
        cnt = (idx - lo)[:, None]
        mean = (cs[idx] - cs[lo]) / cnt
        var = (cs2[idx] - cs2[lo]) / cnt - mean**2
        return np.sqrt(np.maximum(var, 0.0)).max(axis=1)

    ok = (rolling_std(w) < c.static_gyro_std_deg_s * np.pi / 180) & (rolling_std(f) < c.static_accel_std_m_s2)
    if gnss is not None and gnss.vel is not None and len(gnss) > 0:
        sp = np.hypot(gnss.vel[:, 0], gnss.vel[:, 1])
        j = np.clip(np.searchsorted(gnss.time, imu.time), 0, len(gnss) - 1)
        jp = np.clip(j - 1, 0, len(gnss) - 1)
        near = (np.abs(gnss.time[j] - imu.time) < 1.0) | (np.abs(gnss.time[jp] - imu.time) < 1.0)
        ok &= near & (np.maximum(sp[j], sp[jp]) < c.static_gnss_speed_m_s)
    else:
        ok &= False
    return ok


def bridge_gaps(imu, events: list, factor: float = 5.0, window_s: float = 1.0):
    """Increments ready for the kernel, with IMU time gaps (interval > ``factor`` × median) bridged.

    A sample after a gap either already spans the gap (e.g. rates × Δt from a reader: |Δv|/Δt ≈ g)
    or only covers one nominal interval (a sensor that dropped samples: |Δv|/Δt_nominal ≈ g). In the
    second case the gap is bridged by holding the mean rates of the ``window_s`` before it (holding one
    sample's rates would scale its white noise by the gap length instead of its square root).
    Either way the motion during the gap is unknown: the returned ``gap_var`` (N, 2) holds, for the
    sample after each gap, the variance added to each attitude axis [rad²] and each velocity axis
    [(m/s)²] by holding the rates: (σ_ω T)² and (σ_f T)² with σ the spread of the rates in the window
    before the gap (floors 0.1 deg/s and 0.05 m/s²). Each gap and the decision go into ``events``.
    Returns (dtheta, dv, gap_var); the arrays are copies only when something was changed.
    """
    dt = np.diff(np.concatenate([[imu.t0], imu.time]))
    med = float(np.median(dt))
    gaps = np.flatnonzero(dt > factor * med)
    gap_var = np.zeros((len(imu), 2))
    if len(gaps) == 0:
        return imu.dtheta, imu.dv, gap_var
    dth, dv = imu.dtheta.copy(), imu.dv.copy()
    nwin = max(2, int(round(window_s / med)))
    for k in gaps:
        T = dt[k]
        lo = max(0, k - nwin)
        if k - lo >= 2:
            w = imu.dtheta[lo:k] / dt[lo:k, None]
            f = imu.dv[lo:k] / dt[lo:k, None]
            w_mean, f_mean = w.mean(axis=0), f.mean(axis=0)
            s_w = max(float(np.sqrt(np.mean(np.var(w, axis=0)))), np.radians(0.1))
            s_f = max(float(np.sqrt(np.mean(np.var(f, axis=0)))), 0.05)
        else:
            w_mean, f_mean = imu.dtheta[k] / med, imu.dv[k] / med
            s_w, s_f = np.radians(1.0), 0.5
        f_span = np.linalg.norm(dv[k]) / T
        f_nom = np.linalg.norm(dv[k]) / med
        if abs(f_span - 9.8) < abs(f_nom - 9.8):
            how = "its increments already span the gap"
        else:
            dth[k] = w_mean * T
            dv[k] = f_mean * T
            how = f"bridged with the mean rates of the {nwin * med:.2f} s before it"
        gap_var[k] = [(s_w * T) ** 2, (s_f * T) ** 2]
        events.append(f"IMU gap of {T:.3f} s before t={imu.time[k]:.3f} ({T / med:.0f} nominal intervals); "
                      f"{how}; attitude/velocity variance inflated by ({np.degrees(s_w * T):.2f} deg)^2, "
                      f"({s_f * T:.2f} m/s)^2 for the unknown motion")
    return dth, dv, gap_var


def gnss_arrays(gnss, cfg):
    """GNSS fixes as kernel arrays with σ floors and quality factors applied (heights as read)."""
    g = cfg.gnss
    m = len(gnss)
    spos = (np.tile(g.default_pos_std_m, (m, 1)) if gnss.std_pos is None else gnss.std_pos.copy())
    svel = (np.tile(g.default_vel_std_m_s, (m, 1)) if gnss.std_vel is None else gnss.std_vel.copy())
    if gnss.quality is not None:
        fac = np.where(gnss.quality == 2, g.float_std_factor,
                       np.where(gnss.quality >= 4, g.single_std_factor, 1.0))
        spos *= fac[:, None]
        svel *= fac[:, None]
    spos = np.maximum(spos, g.min_pos_std_m)
    svel = np.maximum(svel, g.min_vel_std_m_s)
    vel = gnss.vel if gnss.vel is not None else np.full((m, 3), np.nan)
    # heights arrive ellipsoidal: the datum offset is applied once, by the reader (aidnav.io)
    return (gnss.time, gnss.lat, gnss.lon, gnss.height,
            np.ascontiguousarray(vel), np.ascontiguousarray(spos), np.ascontiguousarray(svel))


def course_alignment(gnss, cfg, t_start: float):
    """First GNSS epoch after ``t_start`` with horizontal speed above the threshold.

    Returns (time, course [rad], index of the fix) or None.
    """
    if gnss.vel is None:
        ve = np.gradient(gnss.lon, gnss.time) * 6378137.0 * np.cos(gnss.lat)
        vn = np.gradient(gnss.lat, gnss.time) * 6378137.0
    else:
        ve, vn = gnss.vel[:, 0], gnss.vel[:, 1]
    sp = np.hypot(ve, vn)
    idx = np.flatnonzero((sp > cfg.init.course_min_speed_m_s) & (gnss.time > t_start))
    if len(idx) == 0:
        return None
    i = idx[0]
    return float(gnss.time[i]), float(np.arctan2(ve[i], vn[i]) % (2 * np.pi)), int(i)


def initial_state(imu, gnss, cfg, t_imu, g, use, events):
    """Initial strapdown state of the loose filter: given (``init.mode = given``) or automatic (first GNSS
    fix, static coarse alignment, gyrocompassing or the heading from the GNSS course later).

    g : the arrays of :func:`gnss_arrays`; use : bool mask of the usable fixes. Returns a dict with t0,
    k0 (first IMU sample used), lat0, lon0, h0, v0, rph, att_sig [rad], reset_idx (sample index of the
    course alignment, −1: none; relative to k0), reset_heading [rad], reset_nav (12,) of the course fix.
    """
    from aidnav.data import ImuData

    from .config import DEG

    g_t, g_lat, g_lon, g_h, g_vel, g_spos, g_svel = g
    ini = cfg.init
    # ---- initial state
    if ini.mode == "given":
        missing = [k for k in ("lat_deg", "lon_deg", "height_m", "roll_deg", "pitch_deg", "heading_deg")
                   if getattr(ini, k) is None]
        if missing:
            raise ValueError(f"init.mode = given needs init.{', init.'.join(missing)}")
        t0 = float(imu.t0 + cfg.imu.time_offset_s)
        lat0, lon0, h0 = ini.lat_deg * DEG, ini.lon_deg * DEG, ini.height_m
        v0 = np.array(ini.velocity_m_s, float)
        rph = np.array([ini.roll_deg, ini.pitch_deg, ini.heading_deg]) * DEG
        att_sig = np.array(ini.attitude_sigma_deg) * DEG
        reset_idx, reset_heading = -1, 0.0
        reset_nav = np.full(12, np.nan)
        k0 = 0
    else:
        # start at the first GNSS fix inside the IMU span
        first = np.flatnonzero(use & (g_t >= t_imu[0]))
        if len(first) == 0:
            raise ValueError("no GNSS fix inside the IMU time span: cannot initialise")
        i0 = first[0]
        k0 = int(np.searchsorted(t_imu, g_t[i0], side="right"))
        if k0 > 0:
            events.append(f"initialisation at the first GNSS fix t={g_t[i0]:.3f}: {k0} IMU samples before it "
                          "are not used")
        t0 = float(g_t[i0]) if k0 == 0 else float(t_imu[k0 - 1])
        lat0, lon0, h0 = g_lat[i0], g_lon[i0], g_h[i0]
        v0 = np.nan_to_num(g_vel[i0]) if not np.isnan(g_vel[i0, 0]) else np.zeros(3)
        # static coarse alignment (aidnav.nav.alignment): roll/pitch from the mean specific force over
        # the static window; heading by gyrocompassing where the gyro grade resolves the Earth rate
        from aidnav.nav.alignment import coarse_align_static

        t_a = t_imu[k0]
        win_imu = ImuData(t_imu, imu.dtheta, imu.dv, t0=imu.t0 + cfg.imu.time_offset_s)
        gb = cfg.imu.gyro_bias_sigma_deg_h * DEG / 3600.0
        roll, pitch, gc_heading, ainfo = coarse_align_static(win_imu, lat0, t_a, t_a + ini.static_window_s,
                                                             height=h0, gyro_bias_std=gb)
        heading = 0.0
        att_sig = np.array(ini.attitude_sigma_deg) * DEG
        gw = use & (g_t >= t_a) & (g_t < t_a + ini.static_window_s)
        moving = bool(np.any(np.hypot(g_vel[gw, 0], g_vel[gw, 1]) > cfg.constraints.static_gnss_speed_m_s))
        if moving or abs(ainfo["f_norm"] - ainfo["gravity"]) > 0.02 * ainfo["gravity"]:
            # not static: in-motion start, level from zero with a wide sigma (the filter converges)
            events.append(f"in-motion start (GNSS speed above {cfg.constraints.static_gnss_speed_m_s} m/s or "
                          f"mean specific force {ainfo['f_norm']:.3f} m/s^2 not gravity "
                          f"{ainfo['gravity']:.3f}): roll and pitch start at 0 with sigma 10 deg")
            roll, pitch, gc_heading = 0.0, 0.0, None
            att_sig[0:2] = np.maximum(att_sig[0:2], 10.0 * DEG)
        if ini.heading_deg is not None:
            heading = ini.heading_deg * DEG
        elif gc_heading is not None:
            heading = gc_heading
        if ini.roll_deg is not None:
            roll = ini.roll_deg * DEG
        if ini.pitch_deg is not None:
            pitch = ini.pitch_deg * DEG
        rph = np.array([roll, pitch, heading])
        f = ainfo["mean_f"] / 9.80665
        events.append(f"coarse alignment over {ini.static_window_s:g} s: roll {np.degrees(roll):.2f} deg, "
                      f"pitch {np.degrees(pitch):.2f} deg (mean specific force {np.round(f, 4)} g)")
        if ini.heading_deg is None and gc_heading is not None:
            events.append(f"heading by gyrocompassing: {np.degrees(gc_heading):.2f} deg "
                          f"(sigma {np.degrees(ainfo['heading_std']):.2f} deg)")
            att_sig[2] = max(att_sig[2], ainfo["heading_std"])
        elif ini.heading_deg is None:
            events.append(f"no gyrocompass heading ({ainfo['heading_reason']}): heading from GNSS course")
        reset_idx, reset_heading = -1, 0.0
        reset_nav = np.full(12, np.nan)
        if ini.heading_deg is None and gc_heading is None:
            ca = course_alignment(gnss.subset(use), cfg, t0)
            if ca is None:
                events.append("heading never aligned: no GNSS speed above init.course_min_speed_m_s")
            else:
                tca, course, ica = ca
                ica = np.flatnonzero(use)[ica]
                # a component the receiver did not measure (NaN) resets to 0 with σ 1 m/s
                meas = ~np.isnan(g_vel[ica])
                vel_g = np.where(meas, np.nan_to_num(g_vel[ica]), 0.0)
                svel = np.where(meas, g_svel[ica], 1.0)
                reset_nav = np.array([*vel_g, g_lat[ica], g_lon[ica], g_h[ica], *svel, *g_spos[ica]])
                mount_h = cfg.imu.mounting_rph_deg[2] * DEG
                # vehicle heading = course; IMU heading = vehicle heading + mounting heading
                reset_heading = (course + mount_h) % (2 * np.pi)
                reset_idx = int(np.searchsorted(t_imu[k0:], tca, side="left"))
                events.append(f"heading from GNSS course at t={tca:.3f}: {np.degrees(reset_heading):.2f} deg")
            att_sig[2] = np.pi  # unknown until the course alignment
    return dict(t0=t0, k0=k0, lat0=lat0, lon0=lon0, h0=h0, v0=v0, rph=rph, att_sig=att_sig,
                reset_idx=reset_idx, reset_heading=reset_heading, reset_nav=reset_nav)
