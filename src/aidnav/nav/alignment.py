"""Initial attitude: static coarse alignment (levelling + gyrocompassing) and heading from GNSS course.

Frames and conventions (``docs/conventions.md``): body b = RFU (x right, y forward, z up), navigation
n = ENU; ``C_b^n = R3(−heading) · R1(pitch) · R2(roll)``; roll positive right wing down, pitch
positive nose up, heading clockwise from true North in [0, 2π). Angles in radians.

Levelling. At rest the specific force in n is f^n = [0, 0, g] (the reaction to gravity, pointing
up), so f^b = C_n^b f^n = g · (third row of C_b^n) = g · [−cos p sin r, sin p, cos p cos r]. Hence

    roll  = atan2(−f_x, f_z),    pitch = atan2(f_y, √(f_x² + f_z²)).

Example (drive log, first 30 s): f^b = [0.118, 0.032, 1.006] g → roll = −6.7° (the right side is
*up*: x tilted up picks up +0.118 g), pitch = +1.8°.

Gyrocompassing. At rest the gyros measure the Earth rate ω^b = C_n^b ω_ie^n with
ω_ie^n = [0, Ω cos L, Ω sin L]. Levelling the measured rate with the known roll and pitch,
w = R1(p) R2(r) ω^b = R3(heading) ω_ie^n (R3(ψ)ᵀ = R3(heading)), whose horizontal part is
w_x = −sin(heading) Ω cos L, w_y = cos(heading) Ω cos L, so heading = atan2(−w_x, w_y).
This needs the horizontal Earth rate Ω cos L (≈ 11.5 °/h at 40° latitude) to stand well above the
gyro noise and bias: the heading is returned only where the estimated standard deviation is small
enough and the measured horizontal rate is consistent with Ω cos L (see :func:`coarse_align_static`).
"""

from __future__ import annotations

import numpy as np

from aidnav.nav.earth import OMEGA_IE, gravity
from aidnav.nav.rotations import dcm_from_euler, wrap_2pi
from aidnav.units import DEG_H


def _window(imu, start, stop):
    """Samples of ``imu`` with start <= time < stop; returns (time, dtheta, dv, t_prev)."""
    t = imu.time
    lo = -np.inf if start is None else start
    hi = np.inf if stop is None else stop
    idx = np.flatnonzero((t >= lo) & (t < hi))
    if len(idx) < 2:
        raise ValueError(f"coarse_align_static: {len(idx)} IMU samples in [{start}, {stop}), need >= 2")
    i0 = idx[0]
    if i0 > 0:
        t_prev = t[i0 - 1]
    elif imu.t0 is not None:
        t_prev = imu.t0
    else:
        t_prev = t[idx[0]] - (t[idx[1]] - t[idx[0]])
    return t[idx], imu.dtheta[idx], imu.dv[idx], float(t_prev)


def _mean_and_se(t, inc, t_prev, n_blocks):
    """Mean rate of increments ``inc`` over (t_prev, t[-1]] and its standard error by batch means."""
    total = t[-1] - t_prev
    mean = inc.sum(axis=0) / total
    n = len(t)
    if n < 2 * n_blocks:
        return mean, np.full(3, np.nan)
    edges = np.linspace(0, n, n_blocks + 1).astype(int)
    tb = np.r_[t_prev, t]
    means = np.array([inc[a:b].sum(axis=0) / (tb[b] - tb[a])
                      for a, b in zip(edges[:-1], edges[1:], strict=True)])
    return mean, means.std(axis=0, ddof=1) / np.sqrt(n_blocks)


def coarse_align_static(imu, lat, start=None, stop=None, *, height=0.0, gyro_bias_std=None,
                        max_heading_std=np.radians(5.0), n_blocks=10):
    """Roll, pitch and (where observable) heading of a static IMU.

    imu : :class:`aidnav.data.ImuData` (increments, body RFU; time in any scale).
    lat : geodetic latitude [rad]; height : ellipsoidal height [m] (only for the gravity check).
    start, stop : time window [s, same scale as ``imu.time``], samples with start <= t < stop;
        None: from the first / to the last sample. The IMU must be at rest in the window.
    gyro_bias_std : 1σ gyro bias per axis [rad/s] known from the sensor (adds to the heading
        uncertainty; None: only the noise seen in the data counts, plus the consistency check).
    max_heading_std : largest acceptable heading standard deviation [rad] (default 5°).
    n_blocks : number of batches for the standard errors of the means (batch means, robust to
        vibration-correlated noise).

    Returns (roll, pitch, heading, info): roll, pitch [rad]; heading [rad] in [0, 2π) clockwise from
    North, or None when the gyros cannot resolve the Earth rate (the reason in ``info["heading_reason"]``).
    info : dict with ``mean_f`` (mean specific force, body, m/s²), ``mean_w`` (mean rate, body, rad/s),
    ``se_f``, ``se_w`` (their standard errors), ``n``, ``duration`` [s], ``f_norm`` and ``gravity``
    [m/s²], ``roll_pitch_std`` (from the accelerometer noise only, rad; an accelerometer bias b adds
    b/g), ``w_level`` (levelled rate, rad/s), ``earth_rate_h`` (Ω cos L, rad/s), ``heading_std`` (rad),
    ``heading_candidate`` (rad, the gyrocompass value even when rejected) and ``heading_reason``.
    """
    t, dth, dv, t_prev = _window(imu, start, stop)
    f, se_f = _mean_and_se(t, dv, t_prev, n_blocks)
    w, se_w = _mean_and_se(t, dth, t_prev, n_blocks)

    roll = float(np.arctan2(-f[0], f[2]))
    pitch = float(np.arctan2(f[1], np.hypot(f[0], f[2])))
    g_norm = float(np.linalg.norm(f))

    c_level = dcm_from_euler(roll, pitch, 0.0)  # R1(pitch) R2(roll)
    w_l = c_level @ w
    cand = float(wrap_2pi(np.arctan2(-w_l[0], w_l[1])))
    omega_h = OMEGA_IE * np.cos(lat)
    omega_v = OMEGA_IE * np.sin(lat)

    var = np.nan_to_num(se_w, nan=np.inf) ** 2
    if gyro_bias_std is not None:
        var = var + np.broadcast_to(np.asarray(gyro_bias_std, dtype=float) ** 2, (3,))
    cov = c_level @ np.diag(var) @ c_level.T if np.all(np.isfinite(var)) else np.full((3, 3), np.inf)
    sig_h = float(np.sqrt(0.5 * (cov[0, 0] + cov[1, 1])))
    sig_v = float(np.sqrt(cov[2, 2]))
    heading_std = sig_h / omega_h if omega_h > 0 else np.inf
    w_h = float(np.hypot(w_l[0], w_l[1]))

    reasons = []
    if abs(np.cos(lat)) < 0.05:
        reasons.append(f"latitude {np.degrees(lat):.1f}°: horizontal Earth rate too small")
    if not np.isfinite(heading_std):
        reasons.append(f"too few samples ({len(t)}) to estimate the gyro noise")
    elif heading_std > max_heading_std:
        reasons.append(f"heading σ {np.degrees(heading_std):.1f}° > {np.degrees(max_heading_std):.1f}°: "
                       f"gyro uncertainty {sig_h / DEG_H:.2f} °/h vs horizontal Earth rate "
                       f"Ω cos L = {omega_h / DEG_H:.2f} °/h")
    tol_h = 3.0 * sig_h + 0.1 * omega_h
    if np.isfinite(tol_h) and abs(w_h - omega_h) > tol_h:
        reasons.append(f"measured horizontal rate {w_h / DEG_H:.2f} °/h is not the Earth rate "
                       f"Ω cos L = {omega_h / DEG_H:.2f} °/h (gyro bias or motion)")
    tol_v = 3.0 * sig_v + 0.1 * OMEGA_IE
    if np.isfinite(tol_v) and abs(w_l[2] - omega_v) > tol_v:
        reasons.append(f"measured vertical rate {w_l[2] / DEG_H:.2f} °/h is not "
                       f"Ω sin L = {omega_v / DEG_H:.2f} °/h (gyro bias or motion)")
    heading = None if reasons else cand

    info = {
        "mean_f": f, "se_f": se_f, "mean_w": w, "se_w": se_w, "n": int(len(t)),
        "duration": float(t[-1] - t_prev), "f_norm": g_norm, "gravity": float(gravity(lat, height)),
        "roll_pitch_std": float(np.hypot(se_f[0], se_f[1]) / max(g_norm, 1e-12)) if np.all(np.isfinite(se_f))
        else float("nan"),
        "w_level": w_l, "earth_rate_h": float(omega_h), "heading_std": float(heading_std),
        "heading_candidate": cand, "heading_reason": "; ".join(reasons) if reasons else "ok",
    }
    return roll, pitch, heading, info


def heading_from_course(ve, vn, min_speed=1.0):
    """Heading [rad] in [0, 2π), clockwise from North, of the horizontal velocity (course over ground).

    ve, vn : East and North velocity [m/s] (scalars or arrays). Where the horizontal speed is below
    ``min_speed`` [m/s] the course is undefined and NaN is returned. The course equals the vehicle
    heading only for a vehicle moving forwards without side slip (a car, not a walker or a boat in
    a current).
    """
    ve = np.asarray(ve, dtype=float)
    vn = np.asarray(vn, dtype=float)
    h = wrap_2pi(np.arctan2(ve, vn))
    h = np.where(np.hypot(ve, vn) >= min_speed, h, np.nan)
    return float(h) if h.ndim == 0 else h
