"""Attitude measurements: a full attitude (DCM) fix and velocity + attitude matching."""

from __future__ import annotations

import numpy as np
from numba import njit

from aidnav.nav.rotations import dcm_from_rotvec

from ..layout import DV, PHI
from .common import W_FIX, diag_r


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
def velocity_attitude_matching(nav, row, par, lay, H, z, R):
    """Velocity + attitude matching (transfer alignment against a master INS): 6 rows
    z = [v_slave − v_master, φ(C_slave C_masterᵀ)], H = [[0, I], [I, 0]] on (φ, δv).

    row = [v_master ENU (3) [m/s], C_b^n master (9), σ_v (3) [m/s], σ_φ (3) [rad]]. H, z, R need 6 rows.
    """
    attitude(nav.C, row[3:12].copy().reshape(3, 3), H[3:6], z[3:6])
    for i in range(3):
        H[i, :] = 0.0
        H[i, DV + i] = 1.0
        z[i] = nav.st[3 + i] - row[i]
    sig = np.empty(6)
    sig[:] = row[12:18]
    diag_r(R, 6, sig)
    return 6
