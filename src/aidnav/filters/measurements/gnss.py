"""GNSS antenna position and velocity (loose coupling), with the IMU → antenna lever arm.

Core functions keep their explicit signatures (used by the tight, federated and transfer kernels);
the ``*_model`` functions are their uniform-signature forms (:mod:`.common`).
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.nav.earth import gravity, gravity_dh, radii

from ..layout import BG, DP, DV, L_GPE, L_LEVER, L_TOFF, L_VDEL, NAV, PHI, RN_ACC, RN_VEL, ST_POS, ST_VEL
from .common import W_FIX, W_IE, W_IN, cross, diag_r, skew, skew_into

W_FN = 4  # row of ``Nav.w`` holding the interval's mean specific force f^n [m/s²] (engine)


@njit(cache=True)
def gnss_position(st, Cbn, lever, lat_g, lon_g, h_g, dt_back, H, z):
    """GNSS antenna position (ENU metres residual).

    st : strapdown state (lat, lon, h, v, q) at t_k; the fix is at t_k − dt_back [s] (the INS is
    moved back along its velocity). lever : IMU→antenna in body RFU [m]. H (3×n), z (3,) filled.
    H = [[(C l)×], −dt_back I, D, ...] with D = ∂(ENU metres)/∂(δL, δλ, δh).
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
    skew_into(H, 0, PHI, l_n, 1.0)
    H[0, DP + 1] = (rn + h) * cl
    H[1, DP + 0] = rm + h
    H[2, DP + 2] = 1.0
    for i in range(3):
        H[i, DV + i] = -dt_back


@njit(cache=True)
def gnss_velocity(st, Cbn, lever, w_ib_b, w_in_n, vel_g, H, z):
    """GNSS antenna velocity ENU [m/s]: v_ant = v + C (ω_ib^b × l) − ω_in^n × (C l).

    H = [[(C(ω×l))×] − [ω_in×][(C l)×], I, 0, −C[l×] (gyro bias), 0].
    """
    H[:, :] = 0.0
    cwl = Cbn @ cross(w_ib_b, lever)
    l_n = Cbn @ lever
    corr = cwl - cross(w_in_n, l_n)
    for i in range(3):
        z[i] = st[3 + i] + corr[i] - vel_g[i]
        H[i, DV + i] = 1.0
    skew_into(H, 0, PHI, cwl, 1.0)
    H[:3, PHI:PHI + 3] -= skew(w_in_n) @ skew(l_n)
    H[:3, BG:BG + 3] = -(Cbn @ skew(lever))


@njit(cache=True)
def lever_and_offset(nav, par, lay):
    """The lever arm IMU → antenna in use (par[0:3] plus the lever-arm estimate, body RFU [m]) and the
    time-offset estimate d̂ [s] (0 without the state)."""
    lever = par[0:3].copy()
    if lay[L_LEVER] >= 0:
        for i in range(3):
            lever[i] += nav.bias[lay[L_LEVER] - NAV + i]
    d = nav.bias[lay[L_TOFF] - NAV] if lay[L_TOFF] >= 0 else 0.0
    return lever, d


@njit(cache=True)
def nav_acceleration(nav):
    """a^n = f^n + g^n − (2 ω_ie^n + ω_en^n) × v^n [m/s²] from the interval's mean specific force."""
    st = nav.st
    w2 = 2.0 * nav.w[W_IE] + (nav.w[W_IN] - nav.w[W_IE])
    a = nav.w[W_FN] - cross(w2, st[ST_VEL:ST_VEL + 3])
    a[2] -= gravity(st[0], st[2])
    return a


@njit(cache=True)
def gnss_position_model(nav, row, par, lay, H, z, R):
    """Uniform form of :func:`gnss_position`. row = [lat, lon [rad], h [m], σE, σN, σU [m]] of the
    fix at the node time − ``nav.dt_back``; par[0:3] = lever arm IMU → antenna, body RFU [m].

    Calibration states (when in ``lay``): lever arm residual r_l (true − estimated, body): H = −C_b^n;
    IMU–GNSS time offset residual r_d [s] (the offset is *added* to the IMU stamps): the INS is read
    at the node time − dt_back − d̂ (the fix's time on the IMU clock as estimated), so that
    z ≈ … + v_ant^n r_d: H = v_ant^n = v + C(ω_ib^b × l) − ω_in^n × (C l)."""
    lever, d = lever_and_offset(nav, par, lay)
    gnss_position(nav.st, nav.C, lever, row[0], row[1], row[2], nav.dt_back + d, H, z)
    if lay[L_LEVER] >= 0:
        il = lay[L_LEVER]
        for i in range(3):
            for j in range(3):
                H[i, il + j] = -nav.C[i, j]
    if lay[L_TOFF] >= 0:  # the antenna (not the IMU) moved back: its lever-arm rate too
        tb = nav.dt_back + d
        Hv = np.zeros((3, H.shape[1]))
        zv = np.zeros(3)
        gnss_velocity(nav.st, nav.C, lever, nav.w[W_FIX], nav.w[W_IN], nav.st[ST_VEL:ST_VEL + 3], Hv, zv)
        if lay[L_LEVER] >= 0:
            J = nav.C @ skew(nav.w[W_FIX]) - skew(nav.w[W_IN]) @ nav.C
            for i in range(3):
                for j in range(3):
                    Hv[i, lay[L_LEVER] + j] = -J[i, j]
        for i in range(3):  # zv = the lever-arm rate; Hv its columns (φ, gyro bias, lever)
            z[i] -= zv[i] * tb
            Hv[i, DV + i] = 0.0
            for j in range(H.shape[1]):
                H[i, j] -= tb * Hv[i, j]
            H[i, lay[L_TOFF]] = nav.st[3 + i] + zv[i]
    if lay[L_GPE] >= 0:  # time-correlated fix error b (ENU m): measured = p + b + white; H = −I
        for i in range(3):
            z[i] += nav.bias[lay[L_GPE] - NAV + i]
            H[i, lay[L_GPE] + i] = -1.0
    diag_r(R, 3, row[3:6])
    return 3


@njit(cache=True)
def gnss_velocity_model(nav, row, par, lay, H, z, R):
    """Uniform form of :func:`gnss_velocity`. row = [vE, vN, vU [m/s], σE, σN, σU [m/s]]; a NaN
    component was not measured: only the measured rows enter (returns their number, 0 if none).
    par[0:3] = lever arm [m]. The lever-arm rate uses ω_ib^b of the last sample (``W_FIX``).

    Calibration states: lever arm residual: H = −(C[ω×] − [ω_in×] C); time offset residual: the INS
    velocity is moved back by (dt_back + d̂) along a^n (:func:`nav_acceleration`), H = a^n; velocity
    delay τ (the receiver's velocity describes the time stamp − τ, e.g. a Doppler average): moved back
    by τ̂ more, H = a^n too (τ and d are told apart by the positions, which only d moves)."""
    lever, d = lever_and_offset(nav, par, lay)
    gnss_velocity(nav.st, nav.C, lever, nav.w[W_FIX], nav.w[W_IN], row[0:3], H, z)
    if lay[L_LEVER] >= 0:
        il = lay[L_LEVER]
        J = nav.C @ skew(nav.w[W_FIX]) - skew(nav.w[W_IN]) @ nav.C
        for i in range(3):
            for j in range(3):
                H[i, il + j] = -J[i, j]
    if lay[L_TOFF] >= 0 or lay[L_VDEL] >= 0:
        a = nav_acceleration(nav)
        tau = nav.bias[lay[L_VDEL] - NAV] if lay[L_VDEL] >= 0 else 0.0
        tb = nav.dt_back + d + tau
        for i in range(3):
            z[i] -= a[i] * tb
            if lay[L_TOFF] >= 0:
                H[i, lay[L_TOFF]] = a[i]
            if lay[L_VDEL] >= 0:
                H[i, lay[L_VDEL]] = a[i]
        H[2, DP + 2] += tb * gravity_dh(nav.st[0], nav.st[2])
    r = 0
    for i in range(3):
        if not np.isnan(row[i]):
            if r != i:
                H[r, :] = H[i, :]
                z[r] = z[i]
            r += 1
    k = 0
    for i in range(3):
        if not np.isnan(row[i]):
            for j in range(r):
                R[k, j] = 0.0
            R[k, k] = row[3 + i] * row[3 + i]
            k += 1
    return r


@njit(cache=True)
def reset_time_tag(st, P, rn_, ix, cal):
    """The time tag of a fix whose velocity and position the INS has just taken (the engine's course
    re-initialisation: δv and δp set to the fix's σ, uncorrelated). ``rn_``: the fix (``layout.RN_*``: its
    velocity v and acceleration a ENU); ``ix``: index in P of each INS state; ``cal``: (index of the time
    offset, of the velocity delay (−1: not estimated), the estimate vector ``bias``).

    The fix describes the vehicle at its tag, which is on the IMU clock at tag − d (the time offset) and
    its velocity at tag − d − τ (the velocity delay), as :func:`gnss_position_model` and
    :func:`gnss_velocity_model` read the INS: the INS is moved by v·d̂ and a·(d̂ + τ̂) so that those models
    see the reset agree with its own fix, and the unknown part of d and τ is carried: δp = ε_p − v r_d,
    δv = ε_v − a (r_d + r_τ) (r = true − estimated), P ← J P Jᵀ. Without it the reset ties the INS to
    the fix as if d̂ were exact, and the fixes after it, all read with the same d̂, agree with it whatever
    d is: they "confirm" a wrong offset to the fix σ / speed (the drive, issue 35: σ 0.013 s at 4σ off)."""
    itoff, ivd, bias = cal
    d = bias[itoff - NAV] if itoff >= 0 else 0.0
    tau = bias[ivd - NAV] if ivd >= 0 else 0.0
    if itoff < 0 and ivd < 0:
        return
    v = np.zeros(3)
    a = np.zeros(3)
    for i in range(3):
        if not np.isnan(rn_[RN_VEL + i]):
            v[i] = rn_[RN_VEL + i]
        a[i] = rn_[RN_ACC + i]
    rm, rn = radii(st[ST_POS])
    h = st[ST_POS + 2]
    # metres → δL, δλ, δh
    sc = np.array([1.0 / ((rn + h) * np.cos(st[ST_POS])), 1.0 / (rm + h), 1.0])
    st[ST_POS] += v[1] * d * sc[1]
    st[ST_POS + 1] += v[0] * d * sc[0]
    st[ST_POS + 2] += v[2] * d
    for i in range(3):
        st[ST_VEL + i] += a[i] * (d + tau)
    n = P.shape[0]
    J = np.eye(n)
    for i in range(3):
        jv, jp = ix[DV + i], ix[DP + i]
        if jv >= 0:
            if itoff >= 0:
                J[jv, itoff] = -a[i]
            if ivd >= 0:
                J[jv, ivd] = -a[i]
        if jp >= 0 and itoff >= 0:  # δp rows: δL (north), δλ (east), δh
            k = 1 if i == 0 else (0 if i == 1 else 2)
            J[jp, itoff] = -v[k] * sc[k]
    P[:, :] = J @ P @ J.T
