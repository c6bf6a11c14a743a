"""Vehicle aids: zero velocity (ZUPT), zero angular rate (ZARU), non-holonomic constraint (NHC) and
the odometer speed with its scale-factor state.

Vehicle frame v: RFU like the body (x right, y forward, z up), C_b^v from the mounting angles.
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.nav.rotations import dcm_from_rotvec

from ..layout import BG, DV, L_MOUNT, L_ODO, NAV, PHI, ST_VEL
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
    vv = Cbv @ (Cnb @ st[ST_VEL:ST_VEL + 3] + cross(w_nb_b, lever))
    A = Cbv @ Cnb
    B = -(A @ skew(st[ST_VEL:ST_VEL + 3]))
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


# parameters of the NHC and the odometer: σ [m/s], min speed [m/s], lever (3) [m], C_b^v (9), σ of the
# lever arm per axis [m] (NHC: an unknown IMU → constrained-point lever arm l gives the constrained
# velocity ω × l, so its variance (ω_⊥² σ_l²) is added to R)
V_SIG, V_MIN_SPEED, V_LEVER, V_CBV, V_LEVER_SIG = 0, 1, 2, 5, 14


@njit(cache=True)
def mounting_dcm(nav, par, lay):
    """C_b^v in use: par[V_CBV:] (configured) turned by the mounting estimate ρ̂ (vehicle frame, rad):
    Ĉ_b^v = exp(−[ρ̂×]) C_b^v. With the residual r = ρ − ρ̂ (true − estimated), Ĉ ≈ (I + [r×]) C_true,
    so a vehicle-frame velocity v^v predicted with Ĉ is off by −[v^v×] r."""
    Cbv = par[V_CBV:V_CBV + 9].copy().reshape(3, 3)
    if lay[L_MOUNT] >= 0:
        i = lay[L_MOUNT] - NAV
        rho = np.array([-nav.bias[i], -nav.bias[i + 1], -nav.bias[i + 2]])
        Cbv = dcm_from_rotvec(rho) @ Cbv
    return Cbv


@njit(cache=True)
def _left_jacobian(th):
    """Left Jacobian of SO(3) at the rotation vector th: exp([(th + δ)×]) ≈ exp([(J δ)×]) exp([th×])."""
    a2 = th[0] * th[0] + th[1] * th[1] + th[2] * th[2]
    K = skew(th)
    if a2 < 1e-10:
        return np.eye(3) + 0.5 * K + (K @ K) / 6.0
    a = np.sqrt(a2)
    return np.eye(3) + (1.0 - np.cos(a)) / a2 * K + (a - np.sin(a)) / (a2 * a) * (K @ K)


@njit(cache=True)
def _mount_columns(H, r, row_v, vv, nav, lay, scale):
    """H[r, ρ] = scale · (−[v^v×] J_l(−ρ̂))[row_v, :] (mounting residual columns; J_l makes the additive
    feedback ρ̂ += r̂ exact to first order at any ρ̂)."""
    if lay[L_MOUNT] < 0:
        return
    i = lay[L_MOUNT] - NAV
    th = np.array([-nav.bias[i], -nav.bias[i + 1], -nav.bias[i + 2]])
    S = skew(vv) @ _left_jacobian(th)
    for j in range(3):
        H[r, lay[L_MOUNT] + j] = -scale * S[row_v, j]


@njit(cache=True)
def nhc_model(nav, row, par, lay, H, z, R):
    """NHC above par[V_MIN_SPEED] horizontal speed (else 0 rows); par as ``V_*``; row unused."""
    st = nav.st
    if np.sqrt(st[3] ** 2 + st[4] ** 2) <= par[V_MIN_SPEED]:
        return 0
    Cbv = mounting_dcm(nav, par, lay)
    wnb = _w_nb(nav)
    lever = par[V_LEVER:V_LEVER + 3].copy()
    nonholonomic(st, nav.C, Cbv, wnb, lever, H, z)
    if lay[L_MOUNT] >= 0:
        vv = Cbv @ (nav.C.T @ st[ST_VEL:ST_VEL + 3] + cross(wnb, lever))
        _mount_columns(H, 0, 0, vv, nav, lay, 1.0)
        _mount_columns(H, 1, 2, vv, nav, lay, 1.0)
    wv = Cbv @ wnb
    sl2 = par[V_LEVER_SIG] ** 2
    R[0, 0] = par[V_SIG] ** 2 + (wv[1] ** 2 + wv[2] ** 2) * sl2
    R[1, 1] = par[V_SIG] ** 2 + (wv[0] ** 2 + wv[1] ** 2) * sl2
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
    Cbv = mounting_dcm(nav, par, lay)
    vv, A, B = vehicle_velocity(nav.st, nav.C, Cbv, _w_nb(nav), par[V_LEVER:V_LEVER + 3].copy())
    k = nav.bias[lay[L_ODO] - NAV] if lay[L_ODO] >= 0 else 0.0
    H[0, :] = 0.0
    for j in range(3):
        H[0, PHI + j] = (1.0 + k) * B[1, j]
        H[0, DV + j] = (1.0 + k) * A[1, j]
    _mount_columns(H, 0, 1, vv, nav, lay, 1.0 + k)
    if lay[L_ODO] >= 0:
        H[0, lay[L_ODO]] = -vv[1]
    z[0] = (1.0 + k) * vv[1] - row[0]
    R[0, 0] = row[1] ** 2
    return 1
