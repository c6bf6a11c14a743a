"""INS error-state model in ENU (§6), numba-compiled.

State layout (indices below), errors defined as computed − true:

====  ==========================================================  =================
0:3   φ, misalignment in n: C_b^n(computed) = (I − [φ×]) C_b^n(true)   rad
3:6   δv^n = [δvE, δvN, δvU]                                         m/s
6:9   δp = [δL, δλ, δh]                                              rad, rad, m
9:12  ε, gyro bias residual in b (RFU)                               rad/s
12:15 ∇, accelerometer bias residual in b                            m/s²
15:18 gyro scale-factor residual (optional, ``nstate`` = 21)        -
18:21 accelerometer scale-factor residual (optional)                 -
21:27 gyro misalignment residual m_xy, m_xz, m_yx, m_yz, m_zx, m_zy  rad
      (optional, ``nstate`` = 27: δω_x = m_xy ω_y + m_xz ω_z, …)
27:33 accelerometer misalignment residual, the same six entries     rad
      (optional, ``nstate`` = 33: δf_x = m_xy f_y + m_xz f_z, …)
====  ==========================================================  =================

Process noise w (continuous, PSD diag ``q``): [gyro white (rad²/s), accel white (m²/s³),
gyro-bias driving, accel-bias driving, (gyro SF driving, accel SF driving), (gyro misalignment driving
×6), (accelerometer misalignment driving ×6)]. Both misalignments are the simulator's
(:mod:`aidnav.sim.imu`): measured = (I + S + M)·true + b, M with zero diagonal, entry (i, j) the input
about/along body axis j read on axis i.
A bias with
correlation time τ > 0 is first-order Gauss-Markov (ẋ = −x/τ + w); τ ≤ 0 means a random walk.

Dynamics: φ̇ = M_aa φ + M_av δv + M_ap δp − C_b^n ε;  δv̇ = [f^n×] φ + M_vv δv + M_vp δp + C_b^n ∇;
δṗ = M_pv δv + M_pp δp.  Closed-loop feedback resets the estimated errors after each update
(see :func:`aidnav.filters.loose.apply_correction`).

Shared building blocks of the filter kernels (loose, tight, federated, transfer, attitude aiding, the
satcom 8-state filter): the strapdown runs at the IMU rate while the covariance is propagated at
*nodes*. Per IMU sample, :func:`propagate_sample` corrects the increments, accumulates the interval
sums and advances the strapdown; at a node, :func:`interval_model` builds F and G from the interval
means and :func:`reset_accumulator` starts the next interval. :func:`model_arrays`,
:func:`measurement_arrays` and :func:`increment_buffers` allocate the usual work arrays;
:func:`set_heading` is the heading (re)initialisation from a GNSS course.
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.nav.earth import OMEGA_IE, gravity, gravity_dh, radii
from aidnav.nav.rotations import dcm_entries, dcm_from_quat, quat_mult, quat_normalize, wrap_pi
from aidnav.nav.strapdown import strapdown_step, strapdown_step_rows

PHI, DV, DP, BG, BA, SG, SA, MG, MA = 0, 3, 6, 9, 12, 15, 18, 21, 27
# strapdown (nominal) state st (N_ST,): lat, lon [rad], h [m]; v^n ENU [m/s]; q_b^n
ST_POS, ST_VEL, ST_Q, N_ST = 0, 3, 6, 10
# misalignment state k (MG + k, gyro; MA + k, accelerometer) couples the rate about (specific force along)
# body axis MIS_IN[k] into axis MIS_OUT[k]
MIS_OUT = (0, 0, 1, 1, 2, 2)
MIS_IN = (1, 2, 0, 2, 0, 1)

# Rows of the per-interval accumulator ``acc`` (7×3 float array, :func:`new_accumulator`) filled by
# :func:`propagate_sample` between two covariance nodes (sums over the samples of the interval):
ACC_C = 0  # rows 0:3: Σ C_b^n (attitude at the start of each sample) [-]
ACC_FN = 3  # Σ C_b^n Δv_c: corrected velocity increments resolved in n [m/s]
ACC_WB = 4  # Σ Δθ_c: corrected angle increments, body [rad]
ACC_FB = 5  # Σ Δv_c: corrected velocity increments, body [m/s]
ACC_TN = 6  # [T = Σ dt [s], number of samples, unused]


@njit(cache=True)
def noise_count(nstate):
    """Number of process-noise inputs for a 15-, 21-, 27- or 33-state model."""
    return 12 if nstate == 15 else (18 if nstate == 21 else (24 if nstate == 27 else 30))


@njit(cache=True)
def fill_model(F, G, lat, h, v, fn, Cbn, wb, fb, tau):
    """Fill F (n×n) and G (n×m) in place.

    lat [rad], h [m], v^n [m/s], f^n [m/s²] (mean specific force over the interval, nav frame),
    Cbn (3×3), wb ω_ib^b [rad/s] and fb f^b [m/s²] (body, for the scale-factor columns),
    tau (4,) correlation times [s] of the gyro bias, accel bias, gyro and accel scale factors (≤ 0:
    random walk; an array or a tuple); the gyro misalignment (n ≥ 27) and the accelerometer misalignment
    (n = 33) are random walks/constants.
    """
    tau_g, tau_a, tau_sg, tau_sa = tau[0], tau[1], tau[2], tau[3]
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
    wie = (0.0, OMEGA_IE * cl, OMEGA_IE * sl)  # (tuples, one 4 × 3 × 3 work array: issue 40, session 18)
    wen = (-vn / rmh, ve / rnh, ve * tl / rnh)
    win = (wie[0] + wen[0], wie[1] + wen[1], wie[2] + wen[2])
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
    wk3 = np.zeros((4, 3, 3))
    Mav, vx, wx, Ma = wk3[0], wk3[1], wk3[2], wk3[3]
    Mav[0, 1] = -1.0 / rmh
    Mav[1, 0] = 1.0 / rnh
    Mav[2, 0] = tl / rnh
    vx[0, 1], vx[0, 2] = -vu, vn
    vx[1, 0], vx[1, 2] = vu, -ve
    vx[2, 0], vx[2, 1] = -vn, ve
    w2 = (wie[0] + win[0], wie[1] + win[1], wie[2] + win[2])
    wx[0, 1], wx[0, 2] = -w2[2], w2[1]
    wx[1, 0], wx[1, 2] = w2[2], -w2[0]
    wx[2, 0], wx[2, 1] = -w2[1], w2[0]
    _product3(F, 3, 3, vx, Mav)  # [v x] M_av (3 × 3 products in loops: no BLAS call per node, issue 40)
    F[3:6, 3:6] -= wx
    # M_vp = [v x](2 M_a1 + M_a2) + gravity gradient
    Ma[1, 0] = -2.0 * OMEGA_IE * sl
    Ma[2, 0] = 2.0 * OMEGA_IE * cl + ve * secl * secl / rnh
    Ma[0, 2] = vn / rmh**2
    Ma[1, 2] = -ve / rnh**2
    Ma[2, 2] = -ve * tl / rnh**2
    _product3(F, 3, 6, vx, Ma)
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
    if n >= 27:  # gyro misalignment: δω_r = m ω_c (random constants, driving noise of zero PSD by default)
        for k in range(6):
            r, c = MIS_OUT[k], MIS_IN[k]
            for i in range(3):
                F[i, MG + k] = -Cbn[i, r] * wb[c]
            G[MG + k, 18 + k] = 1.0
    if n >= 33:  # accelerometer misalignment: δf_r = m f_c, as the gyro's (random constants by default)
        for k in range(6):
            r, c = MIS_OUT[k], MIS_IN[k]
            for i in range(3):
                F[3 + i, MA + k] = Cbn[i, r] * fb[c]
            G[MA + k, 24 + k] = 1.0


@njit(cache=True, inline="always")
def _product3(F, r, c, A, B):
    """F[r:r+3, c:c+3] = A B of two 3 × 3 matrices, in loops (issue 40, session 18: with two BLAS calls
    :func:`fill_model` took 0.89 µs a node, with these 0.57; the same sums in the same order, same bits)."""
    for i in range(3):
        for j in range(3):
            F[r + i, c + j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@njit(cache=True, inline="always")
def correct_increments(dth, dv, bias, dt, dthc, dvc):
    """IMU increments corrected by the estimated sensor errors of this state layout (in place).

    dth [rad], dv [m/s] (3,): raw increments over dt [s], body RFU; ``bias`` (nb,): [gyro bias (rad/s),
    accel bias (m/s²), gyro scale factor, accel scale factor, gyro misalignment (6), accelerometer
    misalignment (6)], as far as the model has them (nb = 0, 6, 12, 18 or 24).
    dthc = dth − b_g dt − s_g∘dth − M_g dth, dvc = dv − b_a dt − s_a∘dv − M_a dv.
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
    if nb >= 18:
        for k in range(6):
            dthc[MIS_OUT[k]] -= bias[12 + k] * dth[MIS_IN[k]]
    if nb >= 24:
        for k in range(6):
            dvc[MIS_OUT[k]] -= bias[18 + k] * dv[MIS_IN[k]]


# ------------------------------------------------------------------ shared pieces of the filter kernels
@njit(cache=True)
def model_arrays(n, m):
    """Zeroed work arrays of the time update of an n-state model with m noise inputs.

    Returns (F (n×n), G (n×m), Φ (n×n), Qd (n×n)), as filled by :func:`fill_model` and
    :func:`aidnav.filters.kalman.discretize`.
    """
    return np.zeros((n, n)), np.zeros((n, m)), np.zeros((n, n)), np.zeros((n, n))


@njit(cache=True)
def measurement_arrays(nz, n):
    """Zeroed work arrays of an nz-row measurement update of an n-state filter.

    Returns (H (nz×n), z (nz,), R (nz×nz), innovation (nz,), diag S (nz,)), the arguments of
    :func:`aidnav.filters.kalman.update`.
    """
    return np.zeros((nz, n)), np.zeros(nz), np.zeros((nz, nz)), np.zeros(nz), np.zeros(nz)


@njit(cache=True)
def increment_buffers():
    """Zeroed (3,) buffers of :func:`propagate_sample`: (Δθ_c, Δv_c, Δθ_c previous, Δv_c previous)."""
    return np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3)


@njit(cache=True)
def new_accumulator():
    """Empty per-interval accumulator (7×3; rows ``ACC_*`` above) for :func:`propagate_sample`."""
    return np.zeros((7, 3))


@njit(cache=True)
def reset_accumulator(acc):
    """Start a new propagation interval: all sums (and T, the sample count) to zero, in place."""
    acc[:, :] = 0.0


@njit(cache=True, inline="always")
def propagate_sample(st, acc, dth, dv, bias, dt, dthc, dvc, dth_prev, dv_prev):
    """One IMU sample of a filter kernel: correct, accumulate, strapdown (all in place).

    st (10,): strapdown state [lat, lon (rad), h (m), v^n (m/s), q_b^n], advanced over the sample.
    acc (7, 3): interval accumulator (rows ``ACC_*``): Σ C_b^n, Σ C_b^n Δv_c, Σ Δθ_c, Σ Δv_c, and
    [T, count]; C_b^n is the attitude *before* this sample's strapdown step.
    dth [rad], dv [m/s] (3,): raw increments of the sample, body RFU; bias (nb,): sensor-error
    estimates as in :func:`correct_increments` (nb = 0, 6, 12, 18 or 24); dt [s]: sample interval.
    dthc, dvc (3,): out, the corrected increments of this sample; dth_prev, dv_prev (3,): the corrected
    increments of the previous sample (coning/sculling), replaced by this sample's.
    Returns T [s], the length of the interval accumulated so far.

    Inlined into the kernels (numba IR): as a call it costs ~25 % of the loose filter's throughput.
    Scalar code only (C_b^n element by element, no temporary arrays, no BLAS call for C Δv_c): the
    per-sample path allocates nothing.
    """
    correct_increments(dth, dv, bias, dt, dthc, dvc)
    _accumulate(acc, st, dthc[0], dthc[1], dthc[2], dvc[0], dvc[1], dvc[2], dt)
    strapdown_step(st, dthc, dvc, dth_prev, dv_prev, dt)
    for i in range(3):
        dth_prev[i] = dthc[i]
        dv_prev[i] = dvc[i]
    return acc[ACC_TN, 0]


@njit(cache=True, inline="always")
def _accumulate(acc, st, w0, w1, w2, v0, v1, v2, dt):
    """The sample's corrected increments Δθ_c = (w0, w1, w2), Δv_c = (v0, v1, v2) and C_b^n (before the
    strapdown step) into the interval accumulator ``acc`` (:func:`propagate_sample`)."""
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = dcm_entries(st[6], st[7], st[8], st[9])
    acc[ACC_C, 0] += c00
    acc[ACC_C, 1] += c01
    acc[ACC_C, 2] += c02
    acc[ACC_C + 1, 0] += c10
    acc[ACC_C + 1, 1] += c11
    acc[ACC_C + 1, 2] += c12
    acc[ACC_C + 2, 0] += c20
    acc[ACC_C + 2, 1] += c21
    acc[ACC_C + 2, 2] += c22
    acc[ACC_FN, 0] += c00 * v0 + c01 * v1 + c02 * v2
    acc[ACC_FN, 1] += c10 * v0 + c11 * v1 + c12 * v2
    acc[ACC_FN, 2] += c20 * v0 + c21 * v1 + c22 * v2
    acc[ACC_WB, 0] += w0
    acc[ACC_FB, 0] += v0
    acc[ACC_WB, 1] += w1
    acc[ACC_FB, 1] += v1
    acc[ACC_WB, 2] += w2
    acc[ACC_FB, 2] += v2
    acc[ACC_TN, 0] += dt
    acc[ACC_TN, 1] += 1.0


@njit(cache=True, inline="always")
def propagate_sample_rows(st, acc, dth, dv, k, bias, dt, buf):
    """:func:`propagate_sample` of sample ``k`` of the raw increments ``dth``, ``dv`` (N, 3), its four
    increment buffers as the rows of one array ``buf`` (4, 3): Δθ_c, Δv_c of this sample, then of the
    previous one. In the engine's per-sample loop the row views ``dth[k]``, ``dv[k]`` and the four buffer
    views cost an atomic reference-count increment and decrement each per sample, inlined as they are
    (issue 40, session 16: 7 pairs per sample, ~9 % of the tight filter's time). The same arithmetic in
    the same order as :func:`propagate_sample`, so the same bits."""
    nb = bias.shape[0]
    for i in range(3):
        buf[0, i] = dth[k, i]
        buf[1, i] = dv[k, i]
    if nb >= 6:
        for i in range(3):
            buf[0, i] -= bias[i] * dt
            buf[1, i] -= bias[3 + i] * dt
    if nb >= 12:
        for i in range(3):
            buf[0, i] -= bias[6 + i] * dth[k, i]
            buf[1, i] -= bias[9 + i] * dv[k, i]
    if nb >= 18:
        for j in range(6):
            buf[0, MIS_OUT[j]] -= bias[12 + j] * dth[k, MIS_IN[j]]
    if nb >= 24:
        for j in range(6):
            buf[1, MIS_OUT[j]] -= bias[18 + j] * dv[k, MIS_IN[j]]
    _accumulate(acc, st, buf[0, 0], buf[0, 1], buf[0, 2], buf[1, 0], buf[1, 1], buf[1, 2], dt)
    strapdown_step_rows(st, buf, dt)
    for i in range(3):
        buf[2, i] = buf[0, i]
        buf[3, i] = buf[1, i]
    return acc[ACC_TN, 0]


@njit(cache=True)
def set_heading(st, P, heading, sigma, iu=PHI + 2, ie=-1, inn=-1):
    """Heading (re)initialisation, in place: keep roll and pitch of q_b^n in ``st``, set the heading to
    ``heading`` [rad, from North, clockwise] and reset the row and column of φ_U (index ``iu`` of the
    covariance ``P`` (n×n); 2 in the full layout, −1: P has no φ_U) to the variance sigma² [rad²] (no
    correlation with the other errors).

    ``ie``, ``inn``: indices of φ_E, φ_N in P (−1: not rotated). The tilt error belongs to the body's
    roll and pitch, which the heading change keeps: in the navigation frame it turns with the heading,
    φ_EN ← R φ_EN (R the rotation applied to C_b^n), so its rows and columns of P are rotated with it.
    Without that the covariance of the tilt with the body-frame accelerometer biases (the coarse
    alignment's b − g·φ, known to the noise while the bias and the tilt are not) would be applied with
    the old heading: after a course alignment that turns the heading by tens of degrees the filter would
    claim a tilt accuracy it does not have.
    """
    Cn = dcm_from_quat(st[ST_Q:ST_Q + 4])
    from_h = np.arctan2(Cn[0, 1], Cn[1, 1])
    dpsi = -(heading - from_h)  # rotation about Up by yaw = -heading change
    qz = np.array([np.cos(0.5 * dpsi), 0.0, 0.0, np.sin(0.5 * dpsi)])
    st[ST_Q:ST_Q + 4] = quat_normalize(quat_mult(qz, st[ST_Q:ST_Q + 4]))
    if ie >= 0 and inn >= 0:
        R = dcm_from_quat(st[ST_Q:ST_Q + 4]) @ Cn.T  # C_new = R C_old
        turn_tilt(P, ie, inn, R[0, 0], R[0, 1], R[1, 0], R[1, 1])
    if iu < 0:
        return
    for j in range(P.shape[0]):
        P[iu, j] = 0.0
        P[j, iu] = 0.0
    P[iu, iu] = sigma * sigma


@njit(cache=True)
def turn_tilt(P, ie, inn, a, b, c, d):
    """The tilt's rows and columns of ``P`` (φ_E, φ_N at ``ie``, ``inn``) turned with a rotation about Up
    of the computed frame, in place: P ← T P Tᵀ with T = [[a, b], [c, d]] on those rows (the horizontal
    block of R, C_b^n ← R C_b^n; dimensionless). The tilt belongs to the body's roll and pitch, so in the
    navigation frame it turns with the heading (:func:`set_heading`, the engine's tilt turns)."""
    for j in range(P.shape[0]):  # rows, then columns
        pe, pn = P[ie, j], P[inn, j]
        P[ie, j], P[inn, j] = a * pe + b * pn, c * pe + d * pn
    for j in range(P.shape[0]):
        pe, pn = P[j, ie], P[j, inn]
        P[j, ie], P[j, inn] = a * pe + b * pn, c * pe + d * pn


@njit(cache=True)
def turn_tilt_by(P, ie, inn, dh):
    """:func:`turn_tilt` for a heading change ``dh`` [rad, clockwise from North] of the computed frame: the
    rotation about Up by −dh."""
    y = -wrap_pi(dh)
    turn_tilt(P, ie, inn, np.cos(y), -np.sin(y), np.sin(y), np.cos(y))


@njit(cache=True)
def interval_means(acc, T):
    """Means over the accumulated interval of length T [s] (> 0).

    Returns (f^n [m/s²], mean C_b^n (3×3), ω_ib^b [rad/s], f^b [m/s²]): the nav-frame specific force,
    the mean attitude (sum / sample count) and the body rates, the arguments of :func:`fill_model`.
    """
    return acc[ACC_FN] / T, acc[ACC_C:ACC_C + 3] / acc[ACC_TN, 1], acc[ACC_WB] / T, acc[ACC_FB] / T


@njit(cache=True)
def interval_model(F, G, st, acc, tau_g, tau_a, tau_sg, tau_sa):
    """F and G (in place, :func:`fill_model`) of the interval accumulated in ``acc`` (T > 0).

    The nominal is the strapdown state ``st`` at the node (lat, h, v^n); the sensor errors act through
    the mean C_b^n of the interval (the body turns within it). tau_* [s]: bias and scale-factor
    correlation times (≤ 0: random walk). Returns the mean body rate ω_ib^b [rad/s] (3,).
    """
    fn, Cbn, wb, fb = interval_means(acc, acc[ACC_TN, 0])
    fill_model(F, G, st[ST_POS], st[ST_POS + 2], st[ST_VEL:ST_VEL + 3], fn, Cbn, wb, fb,
               (tau_g, tau_a, tau_sg, tau_sa))
    return wb
