"""Transfer-alignment model (seed 004, §5.1): the 24-state (21-state variant) error state, its process
model F, G with the flexure block discretized exactly, and the velocity + attitude matching
measurement, in numba. Frames and units as :mod:`aidnav.filters.transfer` (ENU, body RFU; radians,
metres, seconds). The driver, the error analysis and the covariance analysis are in that module."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from aidnav.models.distributed_pos import flexure_transition
from aidnav.nav.earth import OMEGA_IE
from aidnav.nav.rotations import (
    dcm_from_quat,
    dcm_from_rotvec,
)

if TYPE_CHECKING:  # the simulator's containers, for annotations only (filters do not import sim)
    pass

from .ins_errors import (
    fill_model,
    increment_buffers,
    interval_means,
    measurement_arrays,
    model_arrays,
    new_accumulator,
    propagate_sample,
    reset_accumulator,
)
from .kalman import discretize, predict, update
from .loose import _apply_correction
from .measurements import attitude as attitude_measurement

__all__ = ["PHI", "DV", "DP", "BG", "BA", "RHO", "THETA", "THETA_DOT", "fill_transfer_model",
           "discretize_transfer", "state_labels", "left_jacobian"]

PHI, DV, DP, BG, BA, RHO, THETA, THETA_DOT = 0, 3, 6, 9, 12, 15, 18, 21
DEG = math.pi / 180.0
N_INS = 15
N_NOISE_INS = 12  # fill_model's noise inputs for 15 states


def state_labels(nstate: int = 24) -> list[str]:
    """Names of the states (with units) of the 24- or 21-state model."""
    names = ["phi_e_rad", "phi_n_rad", "phi_u_rad", "dve_m_s", "dvn_m_s", "dvu_m_s", "dlat_rad", "dlon_rad",
             "dh_m", "gyro_bias_x_rad_s", "gyro_bias_y_rad_s", "gyro_bias_z_rad_s", "accel_bias_x_m_s2",
             "accel_bias_y_m_s2", "accel_bias_z_m_s2", "rho_x_rad", "rho_y_rad", "rho_z_rad", "theta_x_rad",
             "theta_y_rad", "theta_z_rad", "theta_dot_x_rad_s", "theta_dot_y_rad_s", "theta_dot_z_rad_s"]
    return names[:nstate]


# ---------------------------------------------------------------------------------------- model
@njit(cache=True)
def fill_transfer_model(F, G, q, lat, h, v, fn, Cbn, wb, fb, beta, sigma, q_gyro, q_accel):
    """Continuous model of the 24- or 21-state transfer alignment (n = F.shape[0]), filled in place.

    F (n×n), G (n×m) with m = 15 noise inputs [gyro white (3), accel white (3), gyro-bias and
    accel-bias driving (6, zero PSD: random constants), flexure driving (3)], q (m,) PSD.
    lat [rad], h [m], v^n [m/s], fn mean specific force in n [m/s²], Cbn C_bs^n, wb [rad/s], fb [m/s²],
    beta (3,) [1/s], sigma (3,) [rad] flexure parameters, q_gyro [rad²/s], q_accel [m²/s³] white PSDs.
    """
    n = F.shape[0]
    F[:, :] = 0.0
    G[:, :] = 0.0
    F15 = np.zeros((N_INS, N_INS))
    G15 = np.zeros((N_INS, N_NOISE_INS))
    fill_model(F15, G15, lat, h, v, fn, Cbn, wb, fb, (0.0, 0.0, 0.0, 0.0))
    F[:N_INS, :N_INS] = F15
    G[:N_INS, :N_NOISE_INS] = G15
    q[:] = 0.0
    for i in range(3):
        q[i] = q_gyro
        q[3 + i] = q_accel
    for j in range(3):
        if n == 24:
            F[THETA + j, THETA_DOT + j] = 1.0
            F[THETA_DOT + j, THETA + j] = -beta[j] * beta[j]
            F[THETA_DOT + j, THETA_DOT + j] = -2.0 * beta[j]
            G[THETA_DOT + j, 12 + j] = 1.0
            q[12 + j] = 4.0 * beta[j] ** 3 * sigma[j] ** 2
        else:
            tau = 2.146 / beta[j]
            F[THETA + j, THETA + j] = -1.0 / tau
            G[THETA + j, 12 + j] = 1.0
            q[12 + j] = 2.0 * sigma[j] ** 2 / tau


@njit(cache=True)
def discretize_transfer(F, G, q, T, beta, sigma, Phi, Qd):
    """Φ, Qd (n×n) over ``T`` [s] of the model of :func:`fill_transfer_model`.

    INS + ρ block (18 states): :func:`aidnav.filters.kalman.discretize`; flexure block: exact
    (:func:`aidnav.models.distributed_pos.flexure_transition` for 24 states, e^{−T/τ} for 21 states).
    """
    n = F.shape[0]
    m = 18
    Phi[:, :] = 0.0
    Qd[:, :] = 0.0
    Pb = np.zeros((m, m))
    Qb = np.zeros((m, m))
    discretize(np.ascontiguousarray(F[:m, :m]), np.ascontiguousarray(G[:m, :N_NOISE_INS]),
               np.ascontiguousarray(q[:N_NOISE_INS]), T, Pb, Qb)
    Phi[:m, :m] = Pb
    Qd[:m, :m] = Qb
    for j in range(3):
        if n == 24:
            ph, qd = flexure_transition(beta[j], sigma[j], T)
            a, b = THETA + j, THETA_DOT + j
            Phi[a, a], Phi[a, b], Phi[b, a], Phi[b, b] = ph[0, 0], ph[0, 1], ph[1, 0], ph[1, 1]
            Qd[a, a], Qd[a, b], Qd[b, a], Qd[b, b] = qd[0, 0], qd[0, 1], qd[1, 0], qd[1, 1]
        else:
            tau = 2.146 / beta[j]
            e = np.exp(-T / tau)
            Phi[THETA + j, THETA + j] = e
            Qd[THETA + j, THETA + j] = sigma[j] ** 2 * (1.0 - e * e)


@njit(cache=True)
def left_jacobian(v):
    """Left Jacobian of SO(3) at the rotation vector ``v`` [rad]:
    exp([(v + δ)×]) ≈ exp([(J δ)×]) exp([v×]) for small δ.

    J = I + (1 − cos a)/a² [v×] + (a − sin a)/a³ [v×]², a = |v| (series below 1e-4 rad).
    """
    a2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    if a2 < 1e-8:
        c1 = 0.5 - a2 / 24.0
        c2 = 1.0 / 6.0 - a2 / 120.0
    else:
        a = np.sqrt(a2)
        c1 = (1.0 - np.cos(a)) / a2
        c2 = (a - np.sin(a)) / (a2 * a)
    k = np.zeros((3, 3))
    k[0, 1], k[0, 2] = -v[2], v[1]
    k[1, 0], k[1, 2] = v[2], -v[0]
    k[2, 0], k[2, 1] = -v[1], v[0]
    return np.eye(3) + c1 * k + c2 * (k @ k)


@njit(cache=True)
def _measurement(st, x, Cm, vm, wm, lever, Ra, sig_v, H, z, R):
    """Fill the 6-row velocity + attitude matching (H, z, R) for sub state ``st`` and master output.

    The attitude residual is formed about the current mounting estimate α̂ = ρ̂ + θ̂ (EKF):
    D = C̃_bs^n (C̃_bm^n exp(−[α̂×]))ᵀ ≈ I − [(φ + C̃_bm^n J (α − α̂))×] with J the left Jacobian of SO(3)
    at −α̂ (exp(−[α×]) exp([α̂×]) = exp(−[(J(α − α̂))×]) to first order in α − α̂), so the ρ and θ
    columns of H are C̃_bm^n J and z_a = axial(D) + C̃_bm^n J α̂: the innovation z − Hx̂ is axial(D)
    (φ̂ = 0 after feedback). J = I − ½[α̂×] + … differs from I by ≈ 1 % here, but before the heading is
    observable α − α̂ holds ~1° about the vertical, and the term ½ α̂ × (α − α̂) (≈ 8e-5 rad with 0.7°
    of tilt mounting) would otherwise bias the tilt part of ρ̂ by more than its σ.
    """
    n = H.shape[1]
    H3 = np.zeros((3, n))
    z3 = np.zeros(3)
    ahat = x[RHO:RHO + 3] + x[THETA:THETA + 3]
    Cmount = dcm_from_rotvec(-ahat)  # C_bs^bm estimate
    attitude_measurement(dcm_from_quat(st[6:10]), Cm @ Cmount, H3, z3)
    CJ = Cm @ left_jacobian(-ahat)
    ca = CJ @ ahat
    H[:, :] = 0.0
    R[:, :] = 0.0
    for i in range(3):
        z[i] = z3[i] + ca[i]
        for j in range(n):
            H[i, j] = H3[i, j]
        for j in range(3):
            H[i, RHO + j] = CJ[i, j]
            H[i, THETA + j] = CJ[i, j]
            R[i, j] = Ra[i, j]
        H[3 + i, DV + i] = 1.0
        R[3 + i, 3 + i] = sig_v * sig_v
    lat = st[0]
    wie = np.array([0.0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)])
    web = wm - Cm.T @ wie
    wxr = np.array([web[1] * lever[2] - web[2] * lever[1], web[2] * lever[0] - web[0] * lever[2],
                    web[0] * lever[1] - web[1] * lever[0]])
    vs = vm + Cm @ wxr
    for i in range(3):
        z[3 + i] = st[3 + i] - vs[i]


@njit(cache=True)
def _transfer_kernel(dth, dvel, dt, ratio, st0, P0, beta, sigma, q_gyro, q_accel, lever,
                     m_C, m_vel, m_w, m_Ra, sig_v, gate, keep_cov):
    """Forward filter over M epochs (epoch j at sample boundary j·ratio; see the module doc)."""
    M = m_C.shape[0]
    n = P0.shape[0]
    nn = 15
    st = st0.copy()
    bias = np.zeros(6)
    P = P0.copy()
    x = np.zeros(n)
    F, G, Phi, Qd = model_arrays(n, nn)
    q = np.zeros(nn)
    H, z, R, innov, sdiag = measurement_arrays(6, n)  # attitude (3) + velocity (3) matching
    out_st = np.empty((M, 10))
    out_bias = np.empty((M, 6))
    out_x = np.empty((M, n - N_INS))
    out_pd = np.empty((M, n))
    out_P = np.zeros((M if keep_cov else 1, n, n))
    out_nis = np.empty(M)
    out_ok = np.empty(M, np.bool_)
    out_innov = np.empty((M, 6))
    out_s = np.empty((M, 6))
    dthc, dvc, dth_prev, dv_prev = increment_buffers()  # corrected increments: this / previous sample
    acc = new_accumulator()  # sums over the samples of one epoch interval (ins_errors.ACC_*)
    for j in range(M):
        if j > 0:
            reset_accumulator(acc)
            for kk in range(ratio):
                i = (j - 1) * ratio + kk
                propagate_sample(st, acc, dth[i], dvel[i], bias, dt, dthc, dvc, dth_prev, dv_prev)
            # epochs are exactly ``ratio`` samples apart: the interval is ratio·dt (not the summed dt)
            T = ratio * dt
            fn, Cbn, wb, fb = interval_means(acc, T)
            fill_transfer_model(F, G, q, st[0], st[2], st[3:6], fn, Cbn, wb, fb, beta, sigma, q_gyro, q_accel)
            discretize_transfer(F, G, q, T, beta, sigma, Phi, Qd)
            predict(x, P, Phi, Qd)
        _measurement(st, x, m_C[j], m_vel[j], m_w[j], lever, m_Ra[j], sig_v, H, z, R)
        ok, nis = update(x, P, H, R, z, gate, innov, sdiag)
        out_nis[j] = nis
        out_ok[j] = ok
        out_innov[j] = innov
        out_s[j] = sdiag
        _apply_correction(st, bias, x[:N_INS].copy(), N_INS)
        for a in range(N_INS):
            x[a] = 0.0
        out_st[j] = st
        out_bias[j] = bias
        out_x[j] = x[N_INS:]
        for a in range(n):
            out_pd[j, a] = P[a, a]
        if keep_cov:
            out_P[j] = P
    return out_st, out_bias, out_x, out_pd, out_P, out_nis, out_ok, out_innov, out_s
