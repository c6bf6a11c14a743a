"""INS error-state model in ENU (SPEC §6), numba-compiled.

State layout (indices below), errors defined as computed − true:

====  ==========================================================  =================
0:3   φ, misalignment in n: C_b^n(computed) = (I − [φ×]) C_b^n(true)   rad
3:6   δv^n = [δvE, δvN, δvU]                                         m/s
6:9   δp = [δL, δλ, δh]                                              rad, rad, m
9:12  ε, gyro bias residual in b (RFU)                               rad/s
12:15 ∇, accelerometer bias residual in b                            m/s²
15:18 gyro scale-factor residual (optional, ``nstate`` = 21)        -
18:21 accelerometer scale-factor residual (optional)                 -
====  ==========================================================  =================

Process noise w (continuous, PSD diag ``q``): [gyro white (rad²/s), accel white (m²/s³),
gyro-bias driving, accel-bias driving, (gyro SF driving, accel SF driving)]. A bias with
correlation time τ > 0 is first-order Gauss-Markov (ẋ = −x/τ + w); τ ≤ 0 means a random walk.

Dynamics: φ̇ = M_aa φ + M_av δv + M_ap δp − C_b^n ε;  δv̇ = [f^n×] φ + M_vv δv + M_vp δp + C_b^n ∇;
δṗ = M_pv δv + M_pp δp.  Closed-loop feedback resets the estimated errors after each update
(see :func:`aidnav.filters.loose.apply_correction`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from aidnav.nav.earth import OMEGA_IE, gravity, gravity_dh, radii

PHI, DV, DP, BG, BA, SG, SA = 0, 3, 6, 9, 12, 15, 18


@njit(cache=True)
def noise_count(nstate):
    """Number of process-noise inputs for a 15- or 21-state model."""
    return 12 if nstate == 15 else 18


@njit(cache=True)
def fill_model(F, G, lat, h, v, fn, Cbn, wb, fb, tau_g, tau_a, tau_sg, tau_sa):
    """Fill F (n×n) and G (n×m) in place.

    lat [rad], h [m], v^n [m/s], f^n [m/s²] (mean specific force over the interval, nav frame),
    Cbn (3×3), wb ω_ib^b [rad/s] and fb f^b [m/s²] (body, for the scale-factor columns),
    tau_* correlation times [s] (≤ 0: random walk).
    """
    n = F.shape[0]
    F[:, :] = 0.0
    G[:, :] = 0.0
    rm, rn = radii(lat)
    rmh = rm + h
    rnh = rn + h
    sl, cl = np.sin(lat), np.cos(lat)
    tl = sl / cl
    secl = 1.0 / cl
    ve, vn, vu = v[0], v[1], v[2]
    wie = np.array([0.0, OMEGA_IE * cl, OMEGA_IE * sl])
    wen = np.array([-vn / rmh, ve / rnh, ve * tl / rnh])
    win = wie + wen
    # M_aa = -[win x]
    F[0, 1], F[0, 2] = win[2], -win[1]
    F[1, 0], F[1, 2] = -win[2], win[0]
    F[2, 0], F[2, 1] = win[1], -win[0]
    # M_av
    F[0, 4] = -1.0 / rmh
    F[1, 3] = 1.0 / rnh
    F[2, 3] = tl / rnh
    # M_ap = M_a1 + M_a2
    F[1, 6] = -OMEGA_IE * sl
    F[2, 6] = OMEGA_IE * cl + ve * secl * secl / rnh
    F[0, 8] = vn / rmh**2
    F[1, 8] = -ve / rnh**2
    F[2, 8] = -ve * tl / rnh**2
    # M_va = [f^n x]
    F[3, 1], F[3, 2] = -fn[2], fn[1]
    F[4, 0], F[4, 2] = fn[2], -fn[0]
    F[5, 0], F[5, 1] = -fn[1], fn[0]
    # M_vv = [v x] M_av - [(wie + win) x]
    Mav = np.zeros((3, 3))
    Mav[0, 1] = -1.0 / rmh
    Mav[1, 0] = 1.0 / rnh
    Mav[2, 0] = tl / rnh
    vx = np.zeros((3, 3))
    vx[0, 1], vx[0, 2] = -vu, vn
    vx[1, 0], vx[1, 2] = vu, -ve
    vx[2, 0], vx[2, 1] = -vn, ve
    w2 = wie + win
    wx = np.zeros((3, 3))
    wx[0, 1], wx[0, 2] = -w2[2], w2[1]
    wx[1, 0], wx[1, 2] = w2[2], -w2[0]
    wx[2, 0], wx[2, 1] = -w2[1], w2[0]
    F[3:6, 3:6] = vx @ Mav - wx
    # M_vp = [v x](2 M_a1 + M_a2) + gravity gradient
    Ma = np.zeros((3, 3))
    Ma[1, 0] = -2.0 * OMEGA_IE * sl
    Ma[2, 0] = 2.0 * OMEGA_IE * cl + ve * secl * secl / rnh
    Ma[0, 2] = vn / rmh**2
    Ma[1, 2] = -ve / rnh**2
    Ma[2, 2] = -ve * tl / rnh**2
    F[3:6, 6:9] = vx @ Ma
    # gravity: g^n_U = -g(L, h); d(-g)/dh = -gravity_dh > 0
    dgdl = (gravity(lat + 1e-6, h) - gravity(lat - 1e-6, h)) / 2e-6
    F[5, 6] += -dgdl
    F[5, 8] += -gravity_dh(lat, h)
    # M_pv, M_pp
    F[6, 4] = 1.0 / rmh
    F[7, 3] = secl / rnh
    F[8, 5] = 1.0
    F[6, 8] = -vn / rmh**2
    F[7, 6] = ve * secl * tl / rnh
    F[7, 8] = -ve * secl / rnh**2
    # sensor errors
    for i in range(3):
        for j in range(3):
            F[i, BG + j] = -Cbn[i, j]
            F[3 + i, BA + j] = Cbn[i, j]
            G[i, j] = -Cbn[i, j]
            G[3 + i, 3 + j] = Cbn[i, j]
    for i in range(3):
        if tau_g > 0:
            F[BG + i, BG + i] = -1.0 / tau_g
        if tau_a > 0:
            F[BA + i, BA + i] = -1.0 / tau_a
        G[BG + i, 6 + i] = 1.0
        G[BA + i, 9 + i] = 1.0
    if n >= 21:
        for i in range(3):
            for j in range(3):
                F[i, SG + j] = -Cbn[i, j] * wb[j]
                F[3 + i, SA + j] = Cbn[i, j] * fb[j]
        for i in range(3):
            if tau_sg > 0:
                F[SG + i, SG + i] = -1.0 / tau_sg
            if tau_sa > 0:
                F[SA + i, SA + i] = -1.0 / tau_sa
            G[SG + i, 12 + i] = 1.0
            G[SA + i, 15 + i] = 1.0



@njit(cache=True, inline="always")
def correct_increments(dth, dv, bias, dt, dthc, dvc):
    """IMU increments corrected by the estimated sensor errors of this state layout (in place).

    dth [rad], dv [m/s] (3,): raw increments over dt [s], body RFU; ``bias`` (nb,): [gyro bias (rad/s),
    accel bias (m/s²), gyro scale factor, accel scale factor], as far as the model has them (nb = 0, 6
    or 12). dthc = dth − b_g dt − s_g∘dth, dvc = dv − b_a dt − s_a∘dv.
    """
    nb = bias.shape[0]
    for i in range(3):
        dthc[i] = dth[i]
        dvc[i] = dv[i]
    if nb >= 6:
        for i in range(3):
            dthc[i] -= bias[i] * dt
            dvc[i] -= bias[3 + i] * dt
    if nb >= 12:
        for i in range(3):
            dthc[i] -= bias[6 + i] * dth[i]
            dvc[i] -= bias[9 + i] * dv[i]
