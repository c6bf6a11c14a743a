"""Measurement models of the INS error-state filters (numba): each fills H, z (and the caller sets R).

Conventions: state layout of :mod:`aidnav.filters.ins_errors`; innovations are
z = (value predicted from the INS) − (measured value), so that z ≈ H δx with δx = computed − true.
Position residuals are in local metres ENU (not radians) so that R is in m².
"""

from __future__ import annotations

import numpy as np
from numba import njit

from aidnav.nav.earth import radii
from aidnav.nav.geo_pointing import az_el_jacobians

from .ins_errors import BA, BG, DP, DV, PHI


@njit(cache=True, inline="always")
def _skew_into(H, r0, c0, a, sign):
    """H[r0:r0+3, c0:c0+3] += sign·[a×]."""
    H[r0 + 0, c0 + 1] += -sign * a[2]
    H[r0 + 0, c0 + 2] += sign * a[1]
    H[r0 + 1, c0 + 0] += sign * a[2]
    H[r0 + 1, c0 + 2] += -sign * a[0]
    H[r0 + 2, c0 + 0] += -sign * a[1]
    H[r0 + 2, c0 + 1] += sign * a[0]


@njit(cache=True)
def gnss_position(st, Cbn, lever, lat_g, lon_g, h_g, dt_back, H, z):
    """GNSS antenna position (ENU metres residual).

    st : strapdown state (lat, lon, h, v, q) at t_k; the fix is at t_k − dt_back [s] (the INS is
    moved back along its velocity). lever : IMU→antenna in body RFU [m]. H (3×n), z (3,) filled.
    H = [[(C l)×], 0, D, ...] with D = ∂(ENU metres)/∂(δL, δλ, δh).
    """
    lat, lon, h = st[0], st[1], st[2]
    rm, rn = radii(lat)
    cl = np.cos(lat)
    l_n = Cbn @ lever
    H[:, :] = 0.0
    # INS antenna minus GNSS, local metres
    dlon = lon - lon_g
    if dlon > np.pi:
        dlon -= 2 * np.pi
    elif dlon < -np.pi:
        dlon += 2 * np.pi
    z[0] = dlon * (rn + h) * cl + l_n[0] - st[3] * dt_back
    z[1] = (lat - lat_g) * (rm + h) + l_n[1] - st[4] * dt_back
    z[2] = (h - h_g) + l_n[2] - st[5] * dt_back
    _skew_into(H, 0, PHI, l_n, 1.0)
    H[0, DP + 1] = (rn + h) * cl
    H[1, DP + 0] = rm + h
    H[2, DP + 2] = 1.0


@njit(cache=True)
def gnss_velocity(st, Cbn, lever, w_ib_b, w_in_n, vel_g, H, z):
    """GNSS antenna velocity ENU [m/s]: v_ant = v + C (ω_ib^b × l) − ω_in^n × (C l).

    H = [[(C(ω×l))×], I, 0, −C[l×] (gyro bias), 0].
    """
    H[:, :] = 0.0
    wl = np.array([w_ib_b[1] * lever[2] - w_ib_b[2] * lever[1],
                   w_ib_b[2] * lever[0] - w_ib_b[0] * lever[2],
                   w_ib_b[0] * lever[1] - w_ib_b[1] * lever[0]])
    cwl = Cbn @ wl
    l_n = Cbn @ lever
    corr = cwl - np.array([w_in_n[1] * l_n[2] - w_in_n[2] * l_n[1],
                           w_in_n[2] * l_n[0] - w_in_n[0] * l_n[2],
                           w_in_n[0] * l_n[1] - w_in_n[1] * l_n[0]])
    for i in range(3):
        z[i] = st[3 + i] + corr[i] - vel_g[i]
        H[i, DV + i] = 1.0
    _skew_into(H, 0, PHI, cwl, 1.0)
    # -C [l x] for the gyro bias
    lx = np.zeros((3, 3))
    lx[0, 1], lx[0, 2] = -lever[2], lever[1]
    lx[1, 0], lx[1, 2] = lever[2], -lever[0]
    lx[2, 0], lx[2, 1] = -lever[1], lever[0]
    H[:, BG:BG + 3] = -(Cbn @ lx)


@njit(cache=True)
def zero_velocity(st, H, z):
    """Zero-velocity update: z = v^n (true velocity 0), H = [0, I, 0...]."""
    H[:, :] = 0.0
    for i in range(3):
        z[i] = st[3 + i]
        H[i, DV + i] = 1.0


@njit(cache=True)
def nonholonomic(st, Cbn, Cbv, w_nb_b, lever, H, z):
    """Non-holonomic constraint: the vehicle's lateral (x) and vertical (z) velocity are zero.

    Cbv : IMU body → vehicle frame (both RFU) rotation; lever : IMU → constrained point (e.g. the
    rear axle centre) in body RFU [m]; w_nb_b : body rate relative to n [rad/s].
    v^v = Cbv (C_n^b v^n + ω_nb^b × l); δv^b = C_n^b δv − C_n^b [v×] φ. Fills H (2×n), z (2,).
    """
    H[:, :] = 0.0
    v = st[3:6]
    Cnb = Cbn.T
    vb = Cnb @ v
    wl = np.array([w_nb_b[1] * lever[2] - w_nb_b[2] * lever[1],
                   w_nb_b[2] * lever[0] - w_nb_b[0] * lever[2],
                   w_nb_b[0] * lever[1] - w_nb_b[1] * lever[0]])
    vv = Cbv @ (vb + wl)
    vx = np.zeros((3, 3))
    vx[0, 1], vx[0, 2] = -v[2], v[1]
    vx[1, 0], vx[1, 2] = v[2], -v[0]
    vx[2, 0], vx[2, 1] = -v[1], v[0]
    A = Cbv @ Cnb
    B = -(A @ vx)
    rows = (0, 2)
    for r in range(2):
        i = rows[r]
        z[r] = vv[i]
        for j in range(3):
            H[r, PHI + j] = B[i, j]
            H[r, DV + j] = A[i, j]


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


__all__ = ["gnss_position", "gnss_velocity", "zero_velocity", "nonholonomic", "attitude", "BA"]


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


__all__ += ["sapv_angles"]
