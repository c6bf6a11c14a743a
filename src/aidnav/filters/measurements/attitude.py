"""Attitude measurements: a full attitude (DCM) fix and velocity + attitude matching."""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.nav.rotations import dcm_from_rotvec

from ..layout import DV, L_FLEX, L_MOUNT, NAV, PHI
from .common import W_FIX, W_IE, cross, diag_r, skew


@njit(cache=True)
def attitude(st_q_dcm, C_meas, H, z):
    """Attitude measurement (full DCM): z = φ from C_computed C_measuredᵀ ≈ I − [φ×]; H = [I, 0...]."""
    H[:, :] = 0.0
    D = st_q_dcm @ C_meas.T
    z[0] = 0.5 * (D[1, 2] - D[2, 1])
    z[1] = 0.5 * (D[2, 0] - D[0, 2])
    z[2] = 0.5 * (D[0, 1] - D[1, 0])
    for i in range(3):
        H[i, PHI + i] = 1.0


@njit(cache=True)
def attitude_model(nav, row, par, lay, H, z, R):
    """Uniform form of :func:`attitude`: row = [C_b^n measured (9, row-major), covariance of its
    misalignment ε in n (9, row-major) [rad²]], C_b^n(fix) = (I − [ε×]) C_b^n(true). A fix older than the
    node by ``nav.dt_back`` is carried to the node with the last sample's body rate,
    C(t_k) ≈ C(t_fix) exp([ω dt_back ×]) (Earth and transport rate over < 1 sample neglected)."""
    Cm = row[0:9].copy().reshape(3, 3)
    if nav.dt_back != 0.0:
        Cm = Cm @ dcm_from_rotvec(nav.w[W_FIX] * nav.dt_back)
    attitude(nav.C, Cm, H, z)
    for i in range(3):
        for j in range(3):
            R[i, j] = row[9 + 3 * i + j]
    return 3


@njit(cache=True)
def left_jacobian(v):
    """Left Jacobian of SO(3) at the rotation vector ``v`` [rad]:
    exp([(v + δ)×]) ≈ exp([(J δ)×]) exp([v×]) for small δ.

    J = I + (1 − cos a)/a² [v×] + (a − sin a)/a³ [v×]², a = |v| (series below 1e-4 rad).
    """
    a2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    if a2 < 1e-8:
        c1, c2 = 0.5 - a2 / 24.0, 1.0 / 6.0 - a2 / 120.0
    else:
        a = np.sqrt(a2)
        c1, c2 = (1.0 - np.cos(a)) / a2, (a - np.sin(a)) / (a2 * a)
    k = skew(v)
    return np.eye(3) + c1 * k + c2 * (k @ k)


@njit(cache=True)
def velocity_attitude_matching(nav, row, par, lay, H, z, R):
    """Velocity + attitude matching (transfer alignment against a master INS): 6 rows
    z = [v_slave − v_master, φ(C_slave C_masterᵀ)], H = [[0, I], [I, 0]] on (φ, δv).

    row = [v_master ENU (3) [m/s], C_b^n master (9), σ_v (3) [m/s], σ_φ (3) [rad]] and, when the row has
    30 entries, [R_φ (9, row-major) [rad²] replacing σ_φ, ω_ib^b of the master (3) [rad/s]]: then the
    master velocity is carried to the slave through the lever arm par[0:3] = r [m] (slave in the master
    body frame), v_master + C_bm^n (ω_eb^bm × r), ω_eb^bm = ω_ib^bm − C_n^bm ω_ie^n.
    Mounting: with a mounting block (``lay[L_MOUNT]``) and/or a flexure block (``lay[L_FLEX]``),
    C_bs^bm = exp(−[α×]), α = ρ + θ (slave body to master body); the attitude residual is formed about
    the current estimate α̂: D = C_slave (C_master exp(−[α̂×]))ᵀ ≈ I − [(φ + C_master J δα)×], J the
    left Jacobian of SO(3) at −α̂ (:func:`left_jacobian`), so the ρ and θ columns are C_master J (a
    first-order J = I biases the tilt of ρ̂ by more than its σ while the heading is still unknown).
    H, z, R need 6 rows.
    """
    ext = row.shape[0] >= 30
    Cm = row[3:12].copy().reshape(3, 3)
    im, iflex = lay[L_MOUNT], lay[L_FLEX]
    ah = np.zeros(3)
    for blk in (im, iflex):
        if blk >= 0:
            ah += nav.bias[blk - NAV:blk - NAV + 3]
    attitude(nav.C, Cm @ dcm_from_rotvec(-ah), H[3:6], z[3:6])
    CJ = Cm @ left_jacobian(-ah)
    vm = row[0:3].copy()
    if ext:
        web = row[27:30] - Cm.T @ nav.w[W_IE]
        vm += Cm @ cross(web, par[0:3])
    for i in range(3):
        H[i, :] = 0.0
        H[i, DV + i] = 1.0
        z[i] = nav.st[3 + i] - vm[i]
        for blk in (im, iflex):
            for j in range(3 if blk >= 0 else 0):
                H[3 + i, blk + j] = CJ[i, j]
    sig = np.empty(6)
    sig[:] = row[12:18]
    diag_r(R, 6, sig)
    for i in range(3 if ext else 0):
        for j in range(3):
            R[3 + i, 3 + j] = row[18 + 3 * i + j]
    return 6
