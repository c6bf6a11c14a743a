"""Pseudorange and pseudorange-rate rows (tight coupling) with lever arm and receiver clock states.

Clock states at ``lay[L_CLK]`` (δt_u = b − b̂ [m]) and ``lay[L_CLK] + 1`` (δf = d − d̂ [m/s]), true −
estimated, fed back b̂ += δt̂_u; the measured ρ = range + b (§2.1).
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.nav.earth import dcm_ecef_to_enu, lla_to_ecef
from aidnav.nav.gnss_sat import geo_range, geo_range_rate

from ..layout import L_CLK, NAV, ST_VEL
from .common import W_FIX, W_IN, cross
from .gnss import gnss_position, gnss_velocity

# row of a satellite: r_s ECEF (3) [m], v_s ECEF (3) [m/s], ρ corrected for the satellite clock and the
# atmosphere [m], ρ̇ corrected [m/s] (NaN: no rate), σ_ρ [m], σ_ρ̇ [m/s]
R_SAT, R_VSAT, R_RHO, R_RATE, R_SIG = 0, 3, 6, 7, 8


@njit(cache=True)
def antenna_ecef(nav, lever):
    """INS antenna position and velocity in ECEF at the measurement time (moved back by dt_back)."""
    st = nav.st
    Ce_n = dcm_ecef_to_enu(st[0], st[1])
    l_n = nav.C @ lever
    v_a = st[ST_VEL:ST_VEL + 3] + nav.C @ cross(nav.w[W_FIX], lever) - cross(nav.w[W_IN], l_n)
    x, y, zz = lla_to_ecef(st[0], st[1], st[2])
    r = np.array([x, y, zz]) + Ce_n.T @ (l_n - st[ST_VEL:ST_VEL + 3] * nav.dt_back)
    return r, Ce_n.T @ v_a, Ce_n


@njit(cache=True)
def pseudorange_model(nav, row, par, lay, H, z, R):
    """z_ρ = (|r_s − r_a| + Sagnac + b̂) − ρ, H = −e^nᵀ H_antenna − [δt_u]; and, when row[R_RATE] is
    finite, z_ρ̇ = (e·(v_s − v_a) + Sagnac rate + d̂) − ρ̇, H = −e^nᵀ H_velocity − [δf] (e: unit vector
    antenna → satellite; H_antenna, H_velocity: the rows of :func:`.gnss.gnss_position` and
    :func:`.gnss.gnss_velocity`). par[0:3] = lever arm [m]. Returns 1 or 2 rows."""
    lever = par[0:3].copy()
    r_a, v_a, Ce_n = antenna_ecef(nav, lever)
    rho, e = geo_range(row[R_SAT:R_SAT + 3].copy(), r_a)
    e_n = Ce_n @ e
    ic = lay[L_CLK]
    b = nav.bias[ic - NAV] if ic >= 0 else 0.0
    d = nav.bias[ic - NAV + 1] if ic >= 0 else 0.0
    n = H.shape[1]
    Ha = np.zeros((3, n))
    za = np.zeros(3)
    gnss_position(nav.st, nav.C, lever, nav.st[0], nav.st[1], nav.st[2], nav.dt_back, Ha, za)
    H[0, :] = -(e_n @ Ha)
    z[0] = rho + b - row[R_RHO]
    m = 1
    if not np.isnan(row[R_RATE]):
        gnss_velocity(nav.st, nav.C, lever, nav.w[W_FIX], nav.w[W_IN], np.zeros(3), Ha, za)
        H[1, :] = -(e_n @ Ha)
        z[1] = geo_range_rate(row[R_SAT:R_SAT + 3].copy(), row[R_VSAT:R_VSAT + 3].copy(), r_a, v_a, e) \
            + d - row[R_RATE]
        m = 2
    if ic >= 0:
        H[0, ic] = -1.0
        if m == 2:
            H[1, ic + 1] = -1.0
    for i in range(m):
        for j in range(m):
            R[i, j] = 0.0
        R[i, i] = row[R_SIG + i] ** 2
    return m
