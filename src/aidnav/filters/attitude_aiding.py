"""INS aided by sparse attitude fixes (e.g. the dipole-triad polarization attitude of seed 002).

A closed-loop 15-state error-state Kalman filter: the strapdown of :mod:`aidnav.nav.strapdown` at the
IMU rate (numba kernel :func:`_propagate` between nodes), the error model of
:mod:`aidnav.filters.ins_errors`, ``discretize``/``predict``/``update`` of the one Kalman core
(:mod:`aidnav.filters.kalman`) and the attitude measurement :func:`aidnav.filters.measurements.attitude`
(z from C_computed C_measuredᵀ ≈ I − [z×], z ≈ φ − ε). Fixes are sparse, so the node loop (covariance
propagation every ``prop_dt`` and at every fix) is plain Python.

Frames and units (``CONVENTIONS.md``): n = ENU, b = RFU, positions (lat, lon [rad], h [m]), velocity
ENU [m/s], attitude q_b^n; misalignment φ in n with C_b^n(computed) = (I − [φ×]) C_b^n(true); the
measurement noise of a fix is the covariance of ε with C_b^n(fix) = (I − [ε×]) C_b^n(true).
Closed-loop feedback after an update (as the loosely coupled filter, same function):
C_b^n ← (I + [φ̂×]) C_b^n, v ← v − δv̂, p ← p − δp̂, biases ← biases + ε̂, ∇̂.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from aidnav.nav.rotations import dcm_from_quat, dcm_from_rotvec, quat_to_euler_batch

from .ins_errors import (
    interval_model,
    measurement_arrays,
    model_arrays,
    new_accumulator,
    noise_count,
    propagate_sample,
    reset_accumulator,
)
from .kalman import discretize, predict, update
from .loose import _apply_correction
from .measurements import attitude

__all__ = ["AttitudeFusionResult", "fuse_attitude_fixes", "imu_noise_psd", "initial_covariance_15"]

DEG = np.pi / 180.0
DEG_H = DEG / 3600.0
UG = 9.80665e-6


@njit(cache=True)
def _propagate(st, bias, time, dth, dvel, k0, k1, tprev, dth_prev, dv_prev, out, acc, hold_h, hold_vu):
    """Strapdown over samples k0..k1 (inclusive) with bias-corrected increments; in place.

    bias = [gyro bias (3) rad/s, accel bias (3) m/s²]; ``acc`` is reset, then accumulates the interval
    (:func:`aidnav.filters.ins_errors.propagate_sample`); height and up velocity are held to
    ``hold_h``/``hold_vu`` after each step when given. Returns (T [s], t_last).
    """
    reset_accumulator(acc)
    T = 0.0
    dthc = np.empty(3)
    dvc = np.empty(3)
    hold = hold_h.shape[0] == time.shape[0]
    for k in range(k0, k1 + 1):
        dt = time[k] - tprev
        tprev = time[k]
        T = propagate_sample(st, acc, dth[k], dvel[k], bias, dt, dthc, dvc, dth_prev, dv_prev)
        if hold:
            st[2] = hold_h[k]
            st[5] = hold_vu[k]
        out[k] = st
    return T, tprev


@dataclass
class AttitudeFusionResult:
    """Output of :func:`fuse_attitude_fixes`.

    time : (N,) IMU times [s]; states : (N, 10) strapdown states [lat, lon, h, vE, vN, vU, q_b^n];
    rph : (N, 3) roll, pitch, heading [rad]; std_att : (N, 3) 1σ of the misalignment φ (E, N, U) [rad]
    (of the last covariance node); gyro_bias : (N, 3) [rad/s]; accel_bias : (N, 3) [m/s²];
    fix_time : (M,) [s]; fix_innovation : (M, 3) [rad]; fix_nis : (M,); fix_accepted : (M,) bool.
    """

    time: np.ndarray
    states: np.ndarray
    rph: np.ndarray
    std_att: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    fix_time: np.ndarray
    fix_innovation: np.ndarray
    fix_nis: np.ndarray
    fix_accepted: np.ndarray


def imu_noise_psd(arw_deg_sqrt_h, vrw_m_s_sqrt_h, gyro_bias_instability_deg_h, accel_bias_instability_ug,
                  tau_s):
    """Continuous process-noise PSD vector (12,) of the 15-state model from boundary units.

    [ARW² ×3 (rad²/s), VRW² ×3 (m²/s³), 2σ_g²/τ ×3, 2σ_a²/τ ×3] (first-order Gauss–Markov biases).
    """
    arw = arw_deg_sqrt_h * DEG / 60.0
    vrw = vrw_m_s_sqrt_h / 60.0
    qg = 2.0 * (gyro_bias_instability_deg_h * DEG_H) ** 2 / tau_s
    qa = 2.0 * (accel_bias_instability_ug * UG) ** 2 / tau_s
    return np.array([arw**2] * 3 + [vrw**2] * 3 + [qg] * 3 + [qa] * 3)


def initial_covariance_15(att_sigma_rad, vel_sigma_m_s, pos_sigma_m, gyro_bias_deg_h, accel_bias_ug, lat, h):
    """Diagonal P0 (15×15): attitude [rad] (3 or scalar), velocity [m/s], position [m] (E, N, U →
    δL, δλ, δh), gyro bias [deg/h], accelerometer bias [µg]."""
    from aidnav.nav.earth import radii

    rm, rn = radii(lat)
    ps = np.broadcast_to(np.asarray(pos_sigma_m, float), (3,))
    d = np.zeros(15)
    d[0:3] = np.broadcast_to(np.asarray(att_sigma_rad, float), (3,)) ** 2
    d[3:6] = np.broadcast_to(np.asarray(vel_sigma_m_s, float), (3,)) ** 2
    d[6] = (ps[1] / (rm + h)) ** 2
    d[7] = (ps[0] / ((rn + h) * np.cos(lat))) ** 2
    d[8] = ps[2] ** 2
    d[9:12] = (np.broadcast_to(np.asarray(gyro_bias_deg_h, float), (3,)) * DEG_H) ** 2
    d[12:15] = (np.broadcast_to(np.asarray(accel_bias_ug, float), (3,)) * UG) ** 2
    return np.diag(d)


def fuse_attitude_fixes(imu, state0, fix_time, fix_C_bn, fix_cov, q_psd, P0, tau_g=3600.0, tau_a=3600.0,
                        prop_dt=1.0, gate=0.0, hold_h=None, hold_vu=None,
                        use_fixes=True) -> AttitudeFusionResult:
    """Strapdown INS with attitude fixes in a closed-loop 15-state error-state Kalman filter.

    Parameters
    ----------
    imu : :class:`aidnav.data.ImuData` (increments, body RFU; sample k covers (t_{k-1}, t_k], t_{-1}=imu.t0).
    state0 : (10,) strapdown state at ``imu.t0`` (:func:`aidnav.nav.strapdown.make_state`).
    fix_time : (M,) [s]; fix_C_bn : (M, 3, 3) measured C_b^n; fix_cov : (M, 3, 3) covariance [rad²] of the
        fix's misalignment ε in n (e.g. :attr:`aidnav.estimators.polarization.AttitudeFix.cov_eps`).
        A fix is applied at the first IMU sample at or after its time; the body rotation over the gap is
        taken from that sample's gyro increment (C(t_k) ≈ C(t_fix) exp([ω (t_k − t_fix)×]), Earth and
        transport rate over < 1 interval neglected).
    q_psd : (12,) continuous noise PSD (:func:`imu_noise_psd`); P0 : (15, 15) initial covariance
        (:func:`initial_covariance_15`); tau_g, tau_a : bias correlation times [s] (≤ 0: random walk).
    prop_dt : covariance propagation interval [s]; gate : chi-square gate on the fix NIS (≤ 0: off).
    hold_h, hold_vu : (N,) arrays to hold height and up velocity to (a baro-like aid), or None.
    use_fixes : False runs the free INS (same code path, the "INS only" reference).
    """
    time = np.ascontiguousarray(imu.time, dtype=float)
    dth = np.ascontiguousarray(imu.dtheta, dtype=float)
    dvel = np.ascontiguousarray(imu.dv, dtype=float)
    N = time.shape[0]
    n = 15
    m = noise_count(n)
    fix_time = np.asarray(fix_time, dtype=float).reshape(-1)
    fix_C = np.asarray(fix_C_bn, dtype=float).reshape(-1, 3, 3)
    fix_R = np.asarray(fix_cov, dtype=float).reshape(-1, 3, 3)
    M = fix_time.shape[0]
    fix_idx = np.searchsorted(time, fix_time - 1e-9, side="left")
    ok_fix = (fix_idx < N) & (fix_time > imu.t0) if use_fixes else np.zeros(M, bool)
    # nodes: every prop_dt and at every fix
    grid = np.searchsorted(time, imu.t0 + prop_dt * np.arange(1, int((time[-1] - imu.t0) / prop_dt) + 1)
                           - 1e-9, side="left")
    nodes = np.unique(np.concatenate([grid[grid < N], fix_idx[ok_fix], [N - 1]])).astype(np.int64)
    fixes_at = {}
    for j in np.flatnonzero(ok_fix):
        fixes_at.setdefault(int(fix_idx[j]), []).append(int(j))

    st = np.asarray(state0, dtype=float).copy()
    bias = np.zeros(6)
    P = np.asarray(P0, dtype=float).copy()
    x = np.zeros(n)
    F, G, Phi, Qd = model_arrays(n, m)
    H, z, _, innov, sdiag = measurement_arrays(3, n)  # R: the covariance of each fix
    q_psd = np.asarray(q_psd, dtype=float)
    hh = np.zeros(0) if hold_h is None else np.ascontiguousarray(hold_h, dtype=float)
    hv = np.zeros(0) if hold_vu is None else np.ascontiguousarray(hold_vu, dtype=float)

    out = np.empty((N, 10))
    std_att = np.empty((N, 3))
    gb = np.empty((N, 3))
    ab = np.empty((N, 3))
    f_innov = np.full((M, 3), np.nan)
    f_nis = np.full(M, np.nan)
    f_acc = np.zeros(M, bool)
    dth_prev = np.zeros(3)
    dv_prev = np.zeros(3)
    tprev = float(imu.t0)
    sums = new_accumulator()  # sums over the samples of the current interval (ins_errors.ACC_*)
    k0 = 0
    for k1 in nodes:
        T, tprev = _propagate(st, bias, time, dth, dvel, k0, int(k1), tprev, dth_prev, dv_prev, out, sums,
                              hh, hv)
        if T > 0.0:
            interval_model(F, G, st, sums, tau_g, tau_a, 0.0, 0.0)
            discretize(F, G, q_psd, T, Phi, Qd)
            x[:] = 0.0
            predict(x, P, Phi, Qd)
        for j in fixes_at.get(int(k1), []):
            dtk = time[k1] - (time[k1 - 1] if k1 > 0 else imu.t0)
            w = (dth[k1] - bias[0:3] * dtk) / dtk
            Cm = fix_C[j] @ dcm_from_rotvec(w * (time[k1] - fix_time[j]))
            C = dcm_from_quat(st[6:10])
            attitude(C, Cm, H, z)  # z = φ − ε, H = [I 0 ...]
            x[:] = 0.0
            acc, nis = update(x, P, H, fix_R[j], z, gate, innov, sdiag)
            f_innov[j] = innov
            f_nis[j] = nis
            f_acc[j] = acc
            if acc:
                _apply_correction(st, bias, x, n)
                out[k1] = st
        s = np.sqrt(np.maximum(np.diag(P)[0:3], 0.0))
        std_att[k0:k1 + 1] = s
        gb[k0:k1 + 1] = bias[0:3]
        ab[k0:k1 + 1] = bias[3:6]
        k0 = int(k1) + 1
    rph = quat_to_euler_batch(np.ascontiguousarray(out[:, 6:10]))
    return AttitudeFusionResult(time, out, rph, std_att, gb, ab, fix_time, f_innov, f_nis, f_acc)
