"""Magnetometer heading: the heading of the IMU's forward axis, already true (declination applied by the
reader, :mod:`aidnav.io.magnetometer`)."""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.nav.rotations import wrap_pi

from ..layout import BG, L_NINS, PHI
from .common import W_IB


@njit(cache=True)
def mag_heading_model(nav, row, par, lay, H, z, R):
    """Heading ψ of the body forward axis f = C_b^n[:, 1] (RFU), clockwise from true North:
    ψ = atan2(f_E, f_N). The computed C is (I − [φ×]) C_true, so δf = f × φ and
    δψ = (h² φ_U − f_U (f_E φ_E + f_N φ_N)) / h², h² = f_E² + f_N².

    row = [ψ_m [rad], σ [rad]]; the INS heading is moved back to the measurement time with the body rate
    (ψ̇ = −(C ω_ib^b)_U, Earth rate neglected; ω_ib^b the raw rate less the gyro-bias estimate, hence
    the gyro-bias columns). z = wrap(ψ̂ − ψ_m). No rows when the forward axis is
    within 0.5° of the vertical (heading undefined).
    """
    C, dt = nav.C, nav.dt_back
    fe, fn, fu = C[0, 1], C[1, 1], C[2, 1]
    h2 = fe * fe + fn * fn
    if h2 < 7.6e-5:  # sin²(0.5°)
        return 0
    u = C @ nav.w[W_IB]  # body rate in n (its up component turns the heading)
    psi = np.arctan2(fe, fn) + u[2] * dt
    H[0, :] = 0.0
    H[0, PHI + 0] = -fu * fe / h2 - u[1] * dt  # δu = u × φ
    H[0, PHI + 1] = -fu * fn / h2 + u[0] * dt
    H[0, PHI + 2] = 1.0
    if lay[L_NINS] >= 15:  # the rate is the raw one less the gyro-bias estimate b̂ (BG)
        for j in range(3):
            H[0, BG + j] = C[2, j] * dt
    z[0] = wrap_pi(psi - row[0])
    R[0, 0] = row[1] ** 2
    return 1
