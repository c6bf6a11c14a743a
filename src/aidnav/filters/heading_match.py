"""Initial heading of an IMU from GNSS velocity changes (velocity matching), without knowing how the IMU is
mounted in the vehicle.

A GNSS course gives the heading of the *velocity*, which is the IMU's heading only when the mounting is
known and the vehicle moves along its axis (cars, not a hand-held phone). Velocity matching uses what the
IMU itself measured: with roll and pitch from a static levelling and the heading set to 0, the specific
force is rotated into a level frame (attitude propagated with the gyros from the start) and summed over
short windows; the GNSS velocity changes over the same windows are the same vectors turned by the initial
heading ψ. In the east–north plane as complex numbers b_k = e^{−iψ} a_k (a_k: IMU horizontal Δv in the
heading-0 frame, b_k: GNSS Δv; heading clockwise from north, :func:`aidnav.nav.rotations.dcm_from_euler`),
so ψ = −arg Σ b_k ā_k (the least-squares rotation). Its σ: the residual scatter s of b_k − e^{−iψ}a_k
per component over the windows, σ_ψ = s / √(Σ|a_k|²) (the cross-track residual of each window divided
by its lever |a_k|).

Neglected, and why it is allowed: the Earth rate (15 deg/h: 0.25° over a minute), the transport rate
(walking and driving speeds), the gyro bias over ``span_s`` (a consumer gyro's 200 deg/h: 3° a minute,
common to all windows and so in ψ at most half that), horizontal accelerometer bias (cancelled by the
levelling while the IMU has not turned; after turns it enters each window as bias·window, covered by the
residual scatter that sets σ). Frames: n = ENU, b = RFU.
"""

from __future__ import annotations

import numpy as np

from aidnav.nav.rotations import dcm_from_euler, dcm_from_rotvec, wrap_2pi

__all__ = ["velocity_match_heading"]


def velocity_match_heading(imu, t_start: float, roll: float, pitch: float, t_gnss, vel_enu,
                           window_s: float = 2.0, span_s: float = 60.0, min_dv_m_s: float = 0.3,
                           min_windows: int = 5, gyro_bias=None):
    """Initial heading [rad] at ``t_start`` from GNSS velocity changes (module doc).

    imu : :class:`aidnav.data.ImuData` (on the GNSS time scale); roll, pitch [rad] at ``t_start``;
    t_gnss (M,) [s], vel_enu (M, 3) GNSS velocities (NaN: none), e.g. SPP Doppler velocities; windows of
    ``window_s`` between GNSS epochs within ``span_s`` after ``t_start``, used when the GNSS Δv exceeds
    ``min_dv_m_s``. gyro_bias : optional (3,) [rad/s] removed from the rates before the attitude is
    propagated (the mean rate over the static levelling window: a consumer gyro's bias tilts the level
    frame by degrees a minute, and g·tilt leaks into the horizontal Δv, the same in every window so not
    seen by the residual scatter). Returns (heading, σ [rad], windows used) or None (fewer than
    ``min_windows`` windows with motion)."""
    t_imu = np.asarray(imu.time, float)
    k0 = int(np.searchsorted(t_imu, t_start, side="right"))
    k1 = int(np.searchsorted(t_imu, t_start + span_s, side="right"))
    if k1 - k0 < 2:
        return None
    C = dcm_from_euler(roll, pitch, 0.0)
    wb = np.zeros(3) if gyro_bias is None else np.asarray(gyro_bias, float)
    dts = np.diff(np.concatenate([[imu.t0], t_imu]))
    # horizontal specific-force sum in the heading-0 level frame, cumulative at each IMU sample
    cum = np.zeros((k1 - k0 + 1, 2))
    for i, k in enumerate(range(k0, k1)):
        C = C @ dcm_from_rotvec(np.asarray(imu.dtheta[k], float) - wb * dts[k])
        cum[i + 1] = cum[i] + (C @ np.asarray(imu.dv[k], float))[:2]
    tt = np.concatenate([[t_start], t_imu[k0:k1]])
    t_g = np.asarray(t_gnss, float)
    v_g = np.asarray(vel_enu, float)[:, :2]
    ok = np.isfinite(v_g).all(axis=1) & (t_g >= t_start) & (t_g <= tt[-1])
    t_g, v_g = t_g[ok], v_g[ok]
    a_l, b_l = [], []
    i = 0
    while i < len(t_g):
        j = int(np.searchsorted(t_g, t_g[i] + window_s - 1e-6))
        if j >= len(t_g):
            break
        b = v_g[j] - v_g[i]
        if np.hypot(*b) >= min_dv_m_s:
            a = np.array([np.interp(t_g[j], tt, cum[:, c]) - np.interp(t_g[i], tt, cum[:, c])
                          for c in (0, 1)])
            a_l.append(a)
            b_l.append(b)
        i = j  # non-overlapping windows: independent GNSS noise
    if len(a_l) < min_windows:
        return None
    a = np.array(a_l)
    b = np.array(b_l)
    za = a[:, 0] + 1j * a[:, 1]
    zb = b[:, 0] + 1j * b[:, 1]
    psi = float(-np.angle(np.sum(zb * np.conj(za))))
    res = zb - np.exp(-1j * psi) * za
    s2 = np.sum(np.abs(res) ** 2) / (2.0 * max(len(za) - 1, 1))  # per-component residual variance
    sig = float(np.sqrt(s2 / np.sum(np.abs(za) ** 2)))
    return float(wrap_2pi(psi)), sig, len(za)
