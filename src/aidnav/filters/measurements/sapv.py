"""Satellite-antenna pointing vector (SAPV) angles of a GEO satellite (seed 000, SPEC §1.1)."""

from __future__ import annotations

import numpy as np
from numba import njit

from aidnav.nav.geo_pointing import az_el_jacobians

from ..layout import DP, PHI


@njit(cache=True)
def sapv_angles(st, Cbn, sat_ecef, az_meas, el_meas, use_position, H, z):
    """Satellite-antenna pointing vector (seed 000, SPEC §1.1 eq. 29): antenna azimuth and elevation.

    st : strapdown state (lat, lon [rad], h [m], v, q); Cbn : its C_b^n; sat_ecef : GEO satellite ECEF [m];
    az_meas, el_meas : the antenna's axis angles [rad] (az clockwise from body forward, el above the body
    x-y plane, :func:`aidnav.nav.geo_pointing.az_el_from_body`).
    z = [wrap(az_computed − az_meas) to (−π, π], el_computed − el_meas] [rad] ≈ H δx, with the exact
    Jacobians of :func:`aidnav.nav.geo_pointing.az_el_jacobians` at the computed state:
    H = [−A C_n^b [r_n×], 0, A C_n^b (C_e^n B + [r_n×] D) (only if ``use_position``), 0] (SPEC eq. 23;
    the seed drops the position columns, eq. 26). Fills H (2×n) and z (2,).
    """
    az, el, H_phi, H_pos = az_el_jacobians(st[0], st[1], st[2], Cbn, sat_ecef)
    H[:, :] = 0.0
    d = az - az_meas
    d = d - 2.0 * np.pi * np.floor((d + np.pi) / (2.0 * np.pi))
    if d == -np.pi:
        d = np.pi
    z[0] = d
    z[1] = el - el_meas
    for i in range(2):
        for j in range(3):
            H[i, PHI + j] = H_phi[i, j]
            if use_position:
                H[i, DP + j] = H_pos[i, j]


@njit(cache=True)
def sapv_model(nav, row, par, lay, H, z, R):
    """Uniform form of :func:`sapv_angles`: row = [satellite ECEF (3) [m], az, el, σ_az, σ_el [rad]];
    par[0] > 0: use the position columns."""
    sapv_angles(nav.st, nav.C, row[0:3].copy(), row[3], row[4], par[0] > 0, H[:2], z[:2])
    R[0, 0], R[0, 1], R[1, 0], R[1, 1] = row[5] ** 2, 0.0, 0.0, row[6] ** 2
    return 2
