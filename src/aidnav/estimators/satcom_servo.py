"""Satcom antenna servos (seed 003): servo (az, el, pol) commands from a navigation or antenna-control
attitude, a rate- and acceleration-limited second-order servo model per axis, the pointing and
polarization errors of the beam against the true line of sight, and the received-signal loss.
Angles [rad], body frame RFU, the GEO satellite from :mod:`aidnav.nav.geo_pointing`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aidnav.jit import njit
from aidnav.nav.geo_pointing import beam_body, geo_sat_ecef, servo_angles_rad, wrap_pol
from aidnav.nav.rotations import dcm_from_euler, dcm_from_quat, wrap_2pi, wrap_pi
from aidnav.units import DEG

__all__ = ["servo_commands", "ServoAxis", "default_servo_axes", "servo_track", "ServoResult", "beam_errors",
           "signal_loss_db"]


@njit(cache=True)
def _servo_cmd_kernel(lat, lon, h, q, sat, horizontal):
    n = q.shape[0]
    out = np.empty((n, 3))
    for k in range(n):
        az, el, pol = servo_angles_rad(lat[k], lon[k], h[k], dcm_from_quat(q[k]), sat, horizontal)
        out[k, 0], out[k, 1], out[k, 2] = az, el, pol
    return out


def servo_commands(state: np.ndarray, q: np.ndarray, sat_lon: float, horizontal: bool = False,
                   radius: float | None = None) -> np.ndarray:
    """Servo (az, el, pol) commands [rad] (N, 3) from the navigation position ``state[:, 0:3]`` and the
    attitude quaternions ``q`` (N, 4): pass the antenna-control quaternion (dual-quaternion control) or the
    navigation quaternion (direct pointing). ``sat_lon`` [rad]; ``radius`` [m] default R_GEO."""
    sat = geo_sat_ecef(sat_lon) if radius is None else geo_sat_ecef(sat_lon, radius)
    return _servo_cmd_kernel(np.ascontiguousarray(state[:, 0]), np.ascontiguousarray(state[:, 1]),
                             np.ascontiguousarray(state[:, 2]), np.ascontiguousarray(q), sat,
                             bool(horizontal))


# ========================================================================================= servo model
@dataclass
class ServoAxis:
    """One servo axis: rate limit [deg/s], acceleration limit [deg/s²], loop bandwidth (natural frequency
    ω_n = 2π·bandwidth_hz) and damping ζ of the second-order response."""

    rate_max_deg_s: float = 60.0
    accel_max_deg_s2: float = 200.0
    bandwidth_hz: float = 4.0
    damping: float = 0.8


def default_servo_axes() -> tuple[ServoAxis, ServoAxis, ServoAxis]:
    """Azimuth, elevation and polarization axes of a typical mechanically steered Ku-band terminal."""
    return (ServoAxis(60.0, 200.0, 4.0, 0.8), ServoAxis(40.0, 150.0, 4.0, 0.8),
            ServoAxis(30.0, 100.0, 3.0, 0.8))


@njit(cache=True)
def _wrapdiff(a, mode):
    if mode == 1:
        return wrap_pi(a)
    if mode == 2:
        return (a + 0.5 * np.pi) % np.pi - 0.5 * np.pi
    return a


@njit(cache=True)
def _servo_kernel(dts, cmd, theta0, rate_max, acc_max, wn, zeta, mode, n_sub):
    n, m = cmd.shape
    th = theta0.copy()
    om = np.zeros(m)
    prev = theta0.copy()
    out_th = np.empty((n, m))
    out_om = np.empty((n, m))
    out_acc = np.empty((n, m))  # largest |applied acceleration| within the interval
    out_dem = np.empty((n, m))  # largest |demanded acceleration| within the interval (before limits)
    n_sat = np.zeros(m, np.int64)
    for k in range(n):
        dt = dts[k]
        hs = dt / n_sub
        for i in range(m):
            dc = _wrapdiff(cmd[k, i] - prev[i], mode[i])
            wc = dc / dt  # command rate (first-order hold over the interrupt)
            amax = 0.0
            dmax = 0.0
            for j in range(n_sub):
                c = prev[i] + wc * (j + 1) * hs
                e = _wrapdiff(c - th[i], mode[i])
                ad = wn[i] * wn[i] * e + 2.0 * zeta[i] * wn[i] * (wc - om[i])
                a = min(acc_max[i], max(-acc_max[i], ad))
                if a != ad:
                    n_sat[i] += 1
                om_new = min(rate_max[i], max(-rate_max[i], om[i] + a * hs))
                aa = abs(om_new - om[i]) / hs
                if aa > amax:
                    amax = aa
                if abs(ad) > dmax:
                    dmax = abs(ad)
                th[i] += om_new * hs
                om[i] = om_new
            if mode[i] == 1:
                th[i] = wrap_2pi(th[i])
            elif mode[i] == 2:
                th[i] = (th[i] + 0.5 * np.pi) % np.pi - 0.5 * np.pi
            prev[i] = cmd[k, i]
            out_th[k, i] = th[i]
            out_om[k, i] = om[i]
            out_acc[k, i] = amax
            out_dem[k, i] = dmax
    return out_th, out_om, out_acc, out_dem, n_sat


@dataclass
class ServoResult:
    """Servo response (per interrupt): angle (N, 3) [rad], rate (N, 3) [rad/s], accel (N, 3) largest applied
    |acceleration| in the interval [rad/s²], demand (N, 3) largest demanded |acceleration| before the limit
    [rad/s²], saturated_fraction (3,) share of sub-steps at the acceleration limit."""

    angle: np.ndarray
    rate: np.ndarray
    accel: np.ndarray
    demand: np.ndarray
    saturated_fraction: np.ndarray


def servo_track(dts: np.ndarray, cmd: np.ndarray, axes=None, theta0=None, n_sub: int = 4) -> ServoResult:
    """Second-order, rate- and acceleration-limited servos following the commands (az, el, pol) [rad].

    Each axis: θ̈ = ω_n² e + 2ζω_n(ω_c − θ̇) with e the (wrapped) error to the command (linearly
    interpolated over each interrupt, ω_c its rate), |θ̈| ≤ accel_max, |θ̇| ≤ rate_max; semi-implicit Euler
    with ``n_sub`` sub-steps per interrupt. Azimuth wraps modulo 2π, polarization modulo π, elevation not.
    dts (N,) interrupt periods [s]; cmd (N, 3) [rad]; theta0 (3,) initial angles (default: the first
    command, at rest). The limits are never exceeded (up to rounding).
    """
    axes = axes or default_servo_axes()
    cmd = np.ascontiguousarray(cmd, dtype=float)
    m = cmd.shape[1]
    if len(axes) != m:
        raise ValueError(f"servo_track: {m} command columns but {len(axes)} axes")
    rate = np.array([a.rate_max_deg_s for a in axes]) * DEG
    acc = np.array([a.accel_max_deg_s2 for a in axes]) * DEG
    wn = np.array([2 * np.pi * a.bandwidth_hz for a in axes])
    zeta = np.array([a.damping for a in axes], float)
    mode = np.array([1, 0, 2][:m] if m == 3 else [0] * m, dtype=np.int64)
    th0 = cmd[0].copy() if theta0 is None else np.asarray(theta0, float).copy()
    th, om, aa, dem, n_sat = _servo_kernel(np.ascontiguousarray(dts, float), cmd, th0, rate, acc, wn, zeta,
                                           mode, int(n_sub))
    return ServoResult(th, om, aa, dem, n_sat / (len(cmd) * n_sub))


@njit(cache=True)
def _beam_kernel(lat, lon, h, rph, ant, sat, horizontal):
    n = lat.shape[0]
    err = np.empty(n)
    perr = np.empty(n)
    for k in range(n):
        C = dcm_from_euler(rph[k, 0], rph[k, 1], rph[k, 2])
        az, el, pol = servo_angles_rad(lat[k], lon[k], h[k], C, sat, horizontal)
        b = beam_body(ant[k, 0], ant[k, 1])
        los = beam_body(az, el)
        cx = b[1] * los[2] - b[2] * los[1]
        cy = b[2] * los[0] - b[0] * los[2]
        cz = b[0] * los[1] - b[1] * los[0]
        err[k] = np.arctan2(np.sqrt(cx * cx + cy * cy + cz * cz), b @ los)
        perr[k] = wrap_pol(ant[k, 2] - pol)
    return err, perr


def beam_errors(truth_lat, truth_lon, truth_h, truth_rph, ant: np.ndarray, sat_lon: float,
                horizontal: bool = False, radius: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Pointing error [rad] = angle between the antenna beam (servo angles ``ant`` (N, 3) [az, el, pol] in
    the body frame) and the **true** line of sight (true position (rad, rad, m) and attitude rph [rad]),
    and the polarization mismatch [rad] in (−π/2, π/2] against the true required polarization."""
    sat = geo_sat_ecef(sat_lon) if radius is None else geo_sat_ecef(sat_lon, radius)
    return _beam_kernel(np.ascontiguousarray(truth_lat, float), np.ascontiguousarray(truth_lon, float),
                        np.ascontiguousarray(truth_h, float), np.ascontiguousarray(truth_rph, float),
                        np.ascontiguousarray(ant, float), sat, bool(horizontal))


def signal_loss_db(pointing_error, beamwidth_3db, pol_error=None):
    """Received-signal loss [dB, ≥ 0] for a pointing error [rad] and a full half-power beamwidth θ_3dB [rad]:
    Gaussian-beam approximation 12·(θ/θ_3dB)² (3 dB at θ = θ_3dB/2), plus the polarization mismatch loss
    −20·log10|cos Δp| of a linearly polarized link when ``pol_error`` [rad] is given."""
    loss = 12.0 * (np.asarray(pointing_error, float) / beamwidth_3db) ** 2
    if pol_error is not None:
        c = np.maximum(np.abs(np.cos(np.asarray(pol_error, float))), 1e-12)
        loss = loss - 20.0 * np.log10(c)
    return loss
