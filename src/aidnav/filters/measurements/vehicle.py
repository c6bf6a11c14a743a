"""Vehicle aids: zero velocity (ZUPT), zero angular rate (ZARU), non-holonomic constraint (NHC) and
the odometer speed with its scale-factor state.

Vehicle frame v: RFU like the body (x right, y forward, z up), C_b^v from the mounting angles.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..layout import BG, DV, L_ODO, NAV, PHI
from .common import W_IB, W_IE, cross, skew


@njit(cache=True)
def zero_velocity(st, H, z):
    """Zero-velocity update: z = v^n (true velocity 0), H = [0, I, 0...]."""
    H[:, :] = 0.0
    for i in range(3):
        z[i] = st[3 + i]
        H[i, DV + i] = 1.0


@njit(cache=True)
def vehicle_velocity(st, Cbn, Cbv, w_nb_b, lever):
    """Velocity of a point of the vehicle in the vehicle frame, v^v = C_b^v (C_n^b v^n + ω_nb^b × l),
    and its Jacobians: A = ∂v^v/∂δv = C_b^v C_n^b and B = ∂v^v/∂φ = −A [v×] (ω_nb and l exact)."""
    Cnb = Cbn.T
    vv = Cbv @ (Cnb @ st[3:6] + cross(w_nb_b, lever))
    A = Cbv @ Cnb
    B = -(A @ skew(st[3:6]))
    return vv, A, B


@njit(cache=True)
def nonholonomic(st, Cbn, Cbv, w_nb_b, lever, H, z):
    """Non-holonomic constraint: the vehicle's lateral (x) and vertical (z) velocity are zero.

    Cbv : IMU body → vehicle frame (both RFU) rotation; lever : IMU → constrained point (e.g. the
    rear axle centre) in body RFU [m]; w_nb_b : body rate relative to n [rad/s].
    v^v = Cbv (C_n^b v^n + ω_nb^b × l); δv^b = C_n^b δv − C_n^b [v×] φ. Fills H (2×n), z (2,).
    """
    H[:, :] = 0.0
    vv, A, B = vehicle_velocity(st, Cbn, Cbv, w_nb_b, lever)
    rows = (0, 2)
    for r in range(2):
        i = rows[r]
        z[r] = vv[i]
        for j in range(3):
            H[r, PHI + j] = B[i, j]
            H[r, DV + j] = A[i, j]


@njit(cache=True)
def _w_nb(nav):
    """ω_nb^b ≈ ω_ib^b − C_n^b ω_ie^n (transport rate neglected, as the constraints always did)."""
    return nav.w[W_IB] - nav.C.T @ nav.w[W_IE]


@njit(cache=True)
def zupt_model(nav, row, par, lay, H, z, R):
    """ZUPT: par[0] = σ [m/s]; row unused."""
    zero_velocity(nav.st, H, z)
    for i in range(3):
        for j in range(3):
            R[i, j] = 0.0
        R[i, i] = par[0] ** 2
    return 3


@njit(cache=True)
def zaru_model(nav, row, par, lay, H, z, R):
    """ZARU: the mean measured rate minus the Earth rate in body, z = ω̂_ib^b − Ĉ_n^b ω_ie^n (true: 0),
    ≈ ε + C_n^b [ω_ie×] φ. par[0] = σ [rad/s]."""
    wie_b = nav.C.T @ nav.w[W_IE]
    H[:3, :] = 0.0
    Hphi = nav.C.T @ skew(nav.w[W_IE])
    for i in range(3):
        H[i, BG + i] = 1.0
        for j in range(3):
            H[i, PHI + j] = Hphi[i, j]
            R[i, j] = 0.0
        z[i] = nav.w[W_IB, i] - wie_b[i]
        R[i, i] = par[0] ** 2
    return 3


# parameters of the NHC and the odometer
V_SIG, V_MIN_SPEED, V_LEVER, V_CBV = 0, 1, 2, 5  # σ [m/s], min speed [m/s], lever (3) [m], C_b^v (9)


@njit(cache=True)
def nhc_model(nav, row, par, lay, H, z, R):
    """NHC above par[V_MIN_SPEED] horizontal speed (else 0 rows); par as ``V_*``; row unused."""
    st = nav.st
    if np.sqrt(st[3] ** 2 + st[4] ** 2) <= par[V_MIN_SPEED]:
        return 0
    Cbv = par[V_CBV:V_CBV + 9].copy().reshape(3, 3)
    nonholonomic(st, nav.C, Cbv, _w_nb(nav), par[V_LEVER:V_LEVER + 3].copy(), H, z)
    R[0, 0] = par[V_SIG] ** 2
    R[1, 1] = par[V_SIG] ** 2
    R[0, 1] = 0.0
    R[1, 0] = 0.0
    return 2


@njit(cache=True)
def odometer_model(nav, row, par, lay, H, z, R):
    """Odometer speed s = (1 + k) v_y^v (forward speed of the wheel point; k the scale factor).

    row = [speed [m/s], σ [m/s]]; par as ``V_*`` (lever IMU → wheel, mounting). State
    ``lay[L_ODO]`` = k − k̂ (residual, fed back as k̂ += r̂); k̂ from ``nav.bias`` (0 without the state).
    z = (1 + k̂) v̂_y − s ≈ (1 + k̂)(A δv + B φ)_y − v_y r.
    """
    Cbv = par[V_CBV:V_CBV + 9].copy().reshape(3, 3)
    vv, A, B = vehicle_velocity(nav.st, nav.C, Cbv, _w_nb(nav), par[V_LEVER:V_LEVER + 3].copy())
    k = nav.bias[lay[L_ODO] - NAV] if lay[L_ODO] >= 0 else 0.0
    H[0, :] = 0.0
    for j in range(3):
        H[0, PHI + j] = (1.0 + k) * B[1, j]
        H[0, DV + j] = (1.0 + k) * A[1, j]
    if lay[L_ODO] >= 0:
        H[0, lay[L_ODO]] = -vv[1]
    z[0] = (1.0 + k) * vv[1] - row[0]
    R[0, 0] = row[1] ** 2
    return 1
