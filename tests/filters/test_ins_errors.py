"""Tests of the ENU INS error model ``aidnav.filters.ins_errors.fill_model`` (§6).

(a) Continuous time: F against the numerical Jacobian of the nonlinear mechanization equations
    (ṗ, v̇ = C f − (2ω_ie + ω_en) × v + g, Ċ = C[ω_ib×] − [ω_in×]C), written here independently of
    the library, with the error state of the filter: C_computed = (I − [φ×]) C_true (exact rotation
    exp(−[φ×])), δv, δp = (δL, δλ, δh) computed − true, and the sensor residuals entering as
    ω̃_ib = ω_ib + ε, f̃ = f + ∇ (the filter feeds ε̂, ∇̂ back with b̂ += ε̂: the state is what is
    left in the compensated measurement). The same IMU drives the true and the perturbed solution;
    central differences over ±δ per column. φ̇ comes from d/dt(I − C̃Cᵀ) = −(Ċ̃Cᵀ + C̃Ċᵀ).
    With the radii frozen at the test point (the analytic form neglects dR/dL) §6 quotes
    agreement to 1.5e-6 entry-relative; with the radii free, only the δL column moves, by at most
    the dR/dL terms bounded below.
(b) Discrete time, through the library's own ``strapdown_step``: the state-transition matrix of
    100 steps of 10 ms (finite differences of the propagated errors) against the product of
    exp(F_k Δt) along the nominal; this checks signs and conventions of F against the mechanization
    actually used by the filter.

Units: rad, m, s; F in the units of the state layout (φ rad, δv m/s, δL δλ rad, δh m, ε rad/s,
∇ m/s²).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from aidnav.data import ImuData
from aidnav.filters import ins_errors
from aidnav.filters.ins_errors import fill_model, noise_count
from aidnav.nav.earth import E2, OMEGA_IE, gravity, radii
from aidnav.nav.rotations import (
    dcm_from_euler,
    dcm_from_quat,
    dcm_from_rotvec,
    quat_from_dcm,
    rotvec_from_dcm,
)
from aidnav.nav.strapdown import make_state, strapdown_step
from aidnav.sim.imu import ImuSpec, corrupt_imu

H = 2000.0
VEL = np.array([120.0, -80.0, 3.0])  # 144 m/s horizontal
C_BN = dcm_from_euler(*np.radians([5.0, 3.0, 40.0]))


def _point(lat_deg=35.0):
    """Test point: (lat, ω_ib^b, f^b) with the body turning/rolling and accelerating/pulling up."""
    lat = np.radians(lat_deg)
    w_ie = np.array([0.0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)])
    w_ib = C_BN.T @ w_ie + np.array([0.01, -0.02, 0.05])  # [rad/s]
    f_b = C_BN.T @ np.array([1.0, -0.5, gravity(lat, H) + 0.8])  # [m/s²]
    return lat, w_ib, f_b


LAT, W_IB, F_B = _point()


def _skew(a):
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _rhs(lat, h, v, C, w_ib, f_b, frozen):
    """Continuous ENU mechanization: (ṗ = [L̇, λ̇, ḣ], v̇, Ċ)."""
    rm, rn = frozen if frozen is not None else radii(lat)
    wie = np.array([0.0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)])
    wen = np.array([-v[1] / (rm + h), v[0] / (rn + h), v[0] * np.tan(lat) / (rn + h)])
    pdot = np.array([v[1] / (rm + h), v[0] / ((rn + h) * np.cos(lat)), v[2]])
    vdot = C @ f_b - np.cross(2.0 * wie + wen, v) + np.array([0.0, 0.0, -gravity(lat, h)])
    cdot = C @ _skew(w_ib) - _skew(wie + wen) @ C
    return pdot, vdot, cdot


def _error_rate(dx, frozen, pt):
    """d/dt of the error state (φ, δv, δp) when the computed solution is the truth perturbed by dx."""
    lat, w_ib, f_b = pt
    phi, dv, dp, eps, nab = dx[0:3], dx[3:6], dx[6:9], dx[9:12], dx[12:15]
    Ct = dcm_from_rotvec(-phi) @ C_BN  # C_computed = (I − [φ×]) C_true (exact)
    p0, v0, c0 = _rhs(lat, H, VEL, C_BN, w_ib, f_b, frozen)
    p1, v1, c1 = _rhs(lat + dp[0], H + dp[2], VEL + dv, Ct, w_ib + eps, f_b + nab, frozen)
    D = -(c1 @ C_BN.T + Ct @ c0.T)  # d/dt [φ×]
    phidot = 0.5 * np.array([D[2, 1] - D[1, 2], D[0, 2] - D[2, 0], D[1, 0] - D[0, 1]])
    return np.concatenate([phidot, v1 - v0, p1 - p0])


# central-difference steps per column: φ, δv, δL δλ δh, ε, ∇ (round-off and cubic terms both < 1e-8)
STEPS = np.array([1e-4] * 3 + [1.0] * 3 + [1e-5, 1e-5, 100.0] + [1e-5] * 3 + [1e-2] * 3)


def _numerical_jacobian(frozen, pt=(LAT, W_IB, F_B)):
    J = np.zeros((9, 15))
    for j in range(15):
        e = np.zeros(15)
        e[j] = STEPS[j]
        J[:, j] = (_error_rate(e, frozen, pt) - _error_rate(-e, frozen, pt)) / (2.0 * STEPS[j])
    return J


def _analytic(tau_g=0.0, tau_a=0.0, n=15, pt=(LAT, W_IB, F_B)):
    lat, w_ib, f_b = pt
    F, G = np.zeros((n, n)), np.zeros((n, noise_count(n)))
    fill_model(F, G, lat, H, VEL, C_BN @ f_b, C_BN, w_ib, f_b, (tau_g, tau_a, 0.0, 0.0))
    return F, G


def test_f_matches_numerical_jacobian_with_frozen_radii():
    J = _numerical_jacobian(radii(LAT))
    F, _ = _analytic()
    Fa = F[:9]
    nz = Fa != 0.0
    rel = np.abs(J - Fa)[nz] / np.abs(Fa[nz])
    # §6: 1.5e-6 entry-relative (measured here: 7e-9)
    assert rel.max() < 1.5e-6, np.unravel_index(np.argmax(np.where(nz, np.abs(J - Fa), 0)), J.shape)
    # entries the model sets to zero are zero in the Jacobian too (up to round-off: the largest
    # analytic entries are ~10, the Jacobian's zeros come out at ≤ 1e-13)
    assert np.abs(J[~nz]).max() < 1e-12


def test_f_numerical_jacobian_with_varying_radii_differs_only_by_dr_dl():
    """Unfrozen radii: the δL column picks up the neglected dR/dL terms, bounded by
    |dR_M/dL| ≤ 1.5 e² R_M, |dR_N/dL| ≤ 0.5 e² R_N: ≲ 1.5 e² |v| sec²L / R in the attitude and position
    rows and ≲ 1.5 e² |v|² sec²L / R in the velocity rows (§6: ≤ 2e-5 in F(6,7), ≤ 1.2e-7 elsewhere
    at 150 m/s)."""
    J = _numerical_jacobian(None)
    F, _ = _analytic()
    Fa = F[:9]
    d = np.abs(J - Fa)
    other = np.ones(15, bool)
    other[6] = False
    nz = Fa != 0.0
    assert (d[:, other][nz[:, other]] / np.abs(Fa[:, other][nz[:, other]])).max() < 1.5e-6
    assert d[:, other][~nz[:, other]].max() < 1e-12
    rm, _ = radii(LAT)
    sp = np.linalg.norm(VEL)
    sec2 = 1.0 / np.cos(LAT) ** 2
    b_att = 1.5 * E2 * sp * sec2 / rm
    b_vel = 1.5 * E2 * sp**2 * sec2 / rm
    assert d[[0, 1, 2, 6, 7, 8], 6].max() < b_att  # measured 1.2e-7 (bound 3.4e-7)
    assert d[3:6, 6].max() < b_vel  # measured 1.7e-5 (bound 4.9e-5)
    # the numbers of models.md §6: ≤ 2e-5 in F(6,7) (δv_U row), ≤ 1.2e-7 s⁻¹ in the attitude and position rows
    assert d[5, 6] < 2e-5 and d[[0, 1, 2, 6, 7, 8], 6].max() < 1.2e-7


def test_sensor_columns_noise_input_and_markov_states():
    F, G = _analytic(tau_g=300.0, tau_a=600.0)
    assert np.allclose(F[0:3, 9:12], -C_BN) and np.allclose(F[3:6, 12:15], C_BN)
    # white noise enters like the bias it sits beside
    assert np.allclose(G[0:9, 0:3], F[0:9, 9:12]) and np.allclose(G[0:9, 3:6], F[0:9, 12:15])
    assert np.allclose(np.diag(F)[9:12], -1 / 300.0) and np.allclose(np.diag(F)[12:15], -1 / 600.0)
    assert np.allclose(G[9:15, 6:12], np.eye(6))
    assert np.all(F[9:15, :9] == 0) and np.all(G[9:15, :6] == 0)
    # random walk (τ <= 0): no decay
    F0, _ = _analytic()
    assert np.all(np.diag(F0)[9:15] == 0)
    # 21 states: scale-factor columns = bias columns scaled by the measured rate / specific force
    F21, G21 = _analytic(300.0, 600.0, n=21)
    assert np.allclose(F21[:15, :15], F)
    assert np.allclose(F21[0:3, 15:18], -C_BN * W_IB[None, :])
    assert np.allclose(F21[3:6, 18:21], C_BN * F_B[None, :])
    assert G21.shape == (21, 18) and np.allclose(G21[15:21, 12:18], np.eye(6))


def test_transition_matrix_matches_strapdown_step():
    """Φ over 1 s (100 steps of 10 ms of the library's strapdown) from central differences of the
    propagated errors, against Π exp(F_k Δt) with F_k at each step's mid-interval nominal.

    Tolerances per block (relative to the block's largest |Φ − I| entry): 3e-4 for the attitude,
    velocity and sensor columns (measured ≤ 1e-4: the strapdown's discrete Coriolis/transport
    terms and the variation of F within a step, O(ω Δt)), 3e-3 for the position columns (measured
    1.4e-3: the strapdown uses the radii at the current latitude, dR/dL is not in F; see above).
    A wrong sign or factor anywhere gives an O(1) mismatch."""
    dt, nstep = 0.01, 100

    def run(dx, record=False):
        phi, dv, dp, eps, nab = dx[0:3], dx[3:6], dx[6:9], dx[9:12], dx[12:15]
        st = make_state(LAT + dp[0], 0.5 + dp[1], H + dp[2], VEL + dv,
                        quat_from_dcm(dcm_from_rotvec(-phi) @ C_BN))
        th, dvb = (W_IB + eps) * dt, (F_B + nab) * dt
        pt, pv = np.zeros(3), np.zeros(3)
        Phi = np.eye(15)
        for _ in range(nstep):
            if record:
                nxt = st.copy()
                strapdown_step(nxt, th, dvb, pt, pv, dt)
                mid = 0.5 * (st + nxt)
                Cm = 0.5 * (dcm_from_quat(st[6:10]) + dcm_from_quat(nxt[6:10]))
                F, G = np.zeros((15, 15)), np.zeros((15, 12))
                fill_model(F, G, mid[0], mid[2], mid[3:6], Cm @ F_B, Cm, W_IB, F_B, (0.0, 0.0, 0.0, 0.0))
                Phi = expm(F * dt) @ Phi
            strapdown_step(st, th, dvb, pt, pv, dt)
            pt, pv = th, dvb
        return st, Phi

    st0, Phi_model = run(np.zeros(15), record=True)

    def err(st):
        phi = rotvec_from_dcm(dcm_from_quat(st0[6:10]) @ dcm_from_quat(st[6:10]).T)
        return np.concatenate([phi, st[3:6] - st0[3:6], st[0:3] - st0[0:3]])

    steps = np.array([1e-5] * 3 + [1e-2] * 3 + [1e-8, 1e-8, 1.0] + [1e-6] * 3 + [1e-4] * 3)
    Phi_num = np.zeros((9, 15))
    for j in range(15):
        e = np.zeros(15)
        e[j] = steps[j]
        Phi_num[:, j] = (err(run(e)[0]) - err(run(-e)[0])) / (2 * steps[j])
    A = Phi_model[:9] - np.eye(15)[:9]
    D = np.abs(Phi_num - Phi_model[:9])
    for rb in (slice(0, 3), slice(3, 6), slice(6, 9)):
        for cb in (slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15)):
            tol = 3e-3 if cb.start == 6 else 3e-4
            scale = np.abs(A[rb, cb]).max()
            assert D[rb, cb].max() <= tol * scale, (rb, cb, D[rb, cb].max() / scale)


@pytest.mark.parametrize("lat_deg", [0.0, 60.0, -45.0])
def test_f_jacobian_other_latitudes(lat_deg):
    """The frozen-radii comparison at other latitudes (incl. the equator, tan L = 0) and hemispheres."""
    pt = _point(lat_deg)
    J = _numerical_jacobian(radii(pt[0]), pt)
    F, _ = _analytic(pt=pt)
    Fa = F[:9]
    nz = Fa != 0.0
    assert (np.abs(J - Fa)[nz] / np.abs(Fa[nz])).max() < 1.5e-6
    assert np.abs(J[~nz]).max() < 1e-12


# ------------------------------------------------------------------ shared kernel helpers
def test_propagate_sample_accumulates_means_and_matches_strapdown():
    """N constant increments through ``propagate_sample``: the same state as the bias correction +
    ``strapdown_step`` written out, the interval sums/means of the corrected increments, and F, G of
    ``interval_model`` equal to ``fill_model`` of those means; ``reset_accumulator`` clears it."""
    dt, N = 0.01, 50
    dth = W_IB * dt
    dv = F_B * dt
    bias = np.array([1e-4, -2e-4, 3e-4, 0.02, -0.01, 0.03, 1e-3, -2e-3, 5e-4, 2e-3, 1e-3, -1e-3])
    dthc_ref = dth - bias[0:3] * dt - bias[6:9] * dth  # corrected increments [rad], [m/s]
    dvc_ref = dv - bias[3:6] * dt - bias[9:12] * dv
    st0 = make_state(LAT, 1.0, H, VEL, quat_from_dcm(C_BN))
    st, ref = st0.copy(), st0.copy()
    acc = ins_errors.new_accumulator()
    dthc, dvc, dth_prev, dv_prev = ins_errors.increment_buffers()
    r_prev, rv_prev = np.zeros(3), np.zeros(3)
    C_sum, fn_sum = np.zeros((3, 3)), np.zeros(3)
    for k in range(N):
        C = dcm_from_quat(ref[6:10])
        C_sum += C
        fn_sum += C @ dvc_ref
        strapdown_step(ref, dthc_ref, dvc_ref, r_prev, rv_prev, dt)
        r_prev[:], rv_prev[:] = dthc_ref, dvc_ref
        T = ins_errors.propagate_sample(st, acc, dth, dv, bias, dt, dthc, dvc, dth_prev, dv_prev)
        assert T == pytest.approx((k + 1) * dt, rel=1e-12)
    np.testing.assert_array_equal(st, ref)
    for a in (dthc, dth_prev):
        np.testing.assert_allclose(a, dthc_ref, rtol=1e-15, atol=1e-18)
    for a in (dvc, dv_prev):
        np.testing.assert_allclose(a, dvc_ref, rtol=1e-15, atol=1e-18)
    assert acc[ins_errors.ACC_TN, 1] == N
    fn, Cbn, wb, fb = ins_errors.interval_means(acc, T)
    np.testing.assert_allclose(wb, dthc_ref / dt, rtol=1e-12)  # constant increments: mean = rate
    np.testing.assert_allclose(fb, dvc_ref / dt, rtol=1e-12)
    np.testing.assert_allclose(Cbn, C_sum / N, rtol=0, atol=1e-14)
    np.testing.assert_allclose(fn, fn_sum / T, rtol=1e-12, atol=1e-12)
    # the means as fill_model arguments
    n = 21
    F, G, Phi, Qd = ins_errors.model_arrays(n, noise_count(n))
    assert F.shape == Phi.shape == Qd.shape == (n, n) and G.shape == (n, 18) and not F.any()
    w = ins_errors.interval_model(F, G, st, acc, 300.0, 600.0, 0.0, 1000.0)
    F_ref, G_ref = np.zeros((n, n)), np.zeros((n, 18))
    fill_model(F_ref, G_ref, st[0], st[2], st[3:6], fn, Cbn, wb, fb, (300.0, 600.0, 0.0, 1000.0))
    np.testing.assert_array_equal(F, F_ref)
    np.testing.assert_array_equal(G, G_ref)
    np.testing.assert_array_equal(w, wb)
    ins_errors.reset_accumulator(acc)
    assert not acc.any()


def test_propagate_sample_without_sensor_errors_and_work_arrays():
    """nb = 0 (no bias states): the raw increments drive the strapdown; measurement work arrays."""
    dt = 0.005
    st = make_state(LAT, 0.3, H, VEL, quat_from_dcm(C_BN))
    ref = st.copy()
    acc = ins_errors.new_accumulator()
    bufs = [np.zeros(3) for _ in range(4)]
    T = ins_errors.propagate_sample(st, acc, W_IB * dt, F_B * dt, np.zeros(0), dt, *bufs)
    strapdown_step(ref, W_IB * dt, F_B * dt, np.zeros(3), np.zeros(3), dt)
    np.testing.assert_array_equal(st, ref)
    assert T == dt and acc[ins_errors.ACC_TN, 1] == 1
    Hm, z, R, innov, sdiag = ins_errors.measurement_arrays(2, 15)
    assert Hm.shape == (2, 15) and R.shape == (2, 2) and z.shape == innov.shape == sdiag.shape == (2,)


def test_set_heading_keeps_roll_pitch_and_resets_the_heading_variance():
    from aidnav.nav.rotations import euler_from_quat

    rph = np.radians([5.0, -3.0, 40.0])
    st = make_state(LAT, 1.0, H, VEL, quat_from_dcm(dcm_from_euler(*rph)))
    P = np.arange(225.0).reshape(15, 15)
    P = P + P.T
    P0 = P.copy()
    ins_errors.set_heading(st, P, np.radians(250.0), 0.1)
    np.testing.assert_allclose(euler_from_quat(st[6:10]), [rph[0], rph[1], np.radians(250.0)],
                               atol=1e-12)
    assert P[2, 2] == pytest.approx(0.01) and not np.delete(P[2], 2).any() and not np.delete(P[:, 2], 2).any()
    keep = np.delete(np.delete(P, 2, 0), 2, 1)
    np.testing.assert_array_equal(keep, np.delete(np.delete(P0, 2, 0), 2, 1))


def _tilt_error(C_est, C_true):
    """φ of C_est = (I − [φ×]) C_true (small angles), E, N, U."""
    S = np.eye(3) - C_est @ C_true.T
    return 0.5 * np.array([S[2, 1] - S[1, 2], S[0, 2] - S[2, 0], S[1, 0] - S[0, 1]])


@pytest.mark.parametrize("dpsi_deg", [35.0, -120.0, 180.0])
def test_set_heading_turns_the_tilt_error_and_its_covariance_with_the_heading(dpsi_deg):
    """Issue 35: a course alignment that turns the heading keeps the body's roll/pitch error, so the
    navigation-frame tilt error φ_EN turns with the heading; the covariance, given as the outer product of
    one error sample (tilt and a body-frame accelerometer bias it is correlated with), must become the
    outer product of the tilt error computed from the attitudes after the reset (known answer)."""
    r, p, psi_t = np.radians([4.0, -2.0, 70.0])
    d = np.radians([0.3, -0.2])  # roll/pitch error of the estimate
    psi_e = psi_t - np.radians(dpsi_deg)
    C_true = dcm_from_euler(r, p, psi_t)
    C_est = dcm_from_euler(r + d[0], p + d[1], psi_e)
    phi_old = _tilt_error(C_est, dcm_from_euler(r, p, psi_e))  # the tilt part, before: heading apart
    st = make_state(LAT, 1.0, H, VEL, quat_from_dcm(C_est))
    v = np.zeros(15)
    v[0:2] = phi_old[0:2]
    v[12:15] = [0.02, -0.03, 0.0]
    P = np.outer(v, v) + np.diag(np.full(15, 1e-12))
    ins_errors.set_heading(st, P, psi_t, 0.1, 2, 0, 1)
    phi_new = _tilt_error(dcm_from_quat(st[6:10]), C_true)
    assert abs(phi_new[2]) < 0.05 * np.linalg.norm(d)  # the heading is the truth's now (to 2nd order)
    w = v.copy()
    w[0:2] = phi_new[0:2]
    expect = np.outer(w, w)
    keep = [0, 1] + list(range(3, 15))
    np.testing.assert_allclose(P[np.ix_(keep, keep)], expect[np.ix_(keep, keep)],
                               atol=2e-3 * np.max(np.abs(expect)) + 1e-11)
    assert P[2, 2] == pytest.approx(0.01) and not np.delete(P[2], 2).any()


def _off_diagonal(m6):
    """The misalignment matrix (zero diagonal) of the six entries m_xy, m_xz, m_yx, m_yz, m_zx, m_zy."""
    M = np.zeros((3, 3))
    for k, (r, c) in enumerate(((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))):
        M[r, c] = m6[k]
    return M


def _sensor_error_rate(dx, pt=(LAT, W_IB, F_B)):
    """d/dt (φ, δv, δp) with the 27- or 33-state sensor residuals entering the measurements as the truth
    model of :mod:`aidnav.sim.imu` writes them: ω̃ = ω + ε + s_g∘ω + M_g ω, f̃ = f + ∇ + s_a∘f + M_a f
    (M: zero diagonal, its six entries m_xy, m_xz, m_yx, m_yz, m_zx, m_zy; M_a from index 27 on)."""
    lat, w_ib, f_b = pt
    Mg = _off_diagonal(dx[21:27])
    Ma = _off_diagonal(dx[27:33]) if len(dx) >= 33 else np.zeros((3, 3))
    w = w_ib + dx[15:18] * w_ib + Mg @ w_ib
    f = f_b + dx[18:21] * f_b + Ma @ f_b
    return _error_rate(np.concatenate([dx[:9], dx[9:12] + (w - w_ib), dx[12:15] + (f - f_b)]), None, pt)


def test_scale_factor_and_misalignment_columns_match_numerical_jacobian():
    """The 27-state model (issue 35): the scale-factor and gyro-misalignment columns of F against central
    differences of the nonlinear mechanization with those errors in the sensors (the error rate is
    linear in them: exact up to round-off), G's misalignment inputs, and ``noise_count``."""
    steps = np.concatenate([STEPS, [1e-4] * 12])
    J = np.zeros((9, 27))
    for j in range(27):
        e = np.zeros(27)
        e[j] = steps[j]
        J[:, j] = (_sensor_error_rate(e) - _sensor_error_rate(-e)) / (2.0 * steps[j])
    F, G = _analytic(300.0, 600.0, n=27)
    np.testing.assert_allclose(F[:9, 9:27], J[:, 9:27], rtol=1e-6, atol=1e-9)
    assert noise_count(27) == 24 and G.shape == (27, 24)
    np.testing.assert_array_equal(G[21:27, 18:24], np.eye(6))
    assert not F[21:27].any()  # random constants
    F21, _ = _analytic(300.0, 600.0, n=21)
    np.testing.assert_array_equal(F[:21, :21], F21)


def test_correct_increments_removes_the_misalignment():
    """nb = 18: Δθ_c = Δθ − b_g Δt − s_g∘Δθ − M Δθ (misalignment states in ``MIS_OUT``/``MIS_IN`` order)."""
    dt = 0.01
    dth, dv = W_IB * dt, F_B * dt
    bias = np.array([1e-4, -2e-4, 3e-4, 0.02, -0.01, 0.03, 1e-3, -2e-3, 5e-4, 2e-3, 1e-3, -1e-3,
                     1e-3, 2e-3, 3e-3, 4e-3, 5e-3, 6e-3])
    M = np.array([[0.0, 1e-3, 2e-3], [3e-3, 0.0, 4e-3], [5e-3, 6e-3, 0.0]])
    dthc, dvc = np.zeros(3), np.zeros(3)
    ins_errors.correct_increments(dth, dv, bias, dt, dthc, dvc)
    np.testing.assert_allclose(dthc, dth - bias[0:3] * dt - bias[6:9] * dth - M @ dth, rtol=0, atol=1e-18)
    np.testing.assert_allclose(dvc, dv - bias[3:6] * dt - bias[9:12] * dv, rtol=0, atol=1e-18)


def test_accelerometer_misalignment_columns_match_numerical_jacobian():
    """The 33-state model (issue 35, session 11): the accelerometer-misalignment columns of F against
    central differences of the nonlinear mechanization with f̃ = f + M_a f in the accelerometers (the
    simulator's model, :mod:`aidnav.sim.imu`; linear in M_a: exact up to round-off), G's inputs of those
    states, ``noise_count``, and the 27-state block unchanged. The test point has specific force on every
    body axis (a turning, accelerating, pulling-up vehicle), so each of the six columns is nonzero."""
    n = 33
    steps = np.concatenate([STEPS, [1e-4] * 18])
    J = np.zeros((9, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = steps[j]
        J[:, j] = (_sensor_error_rate(e) - _sensor_error_rate(-e)) / (2.0 * steps[j])
    F, G = _analytic(300.0, 600.0, n=n)
    assert np.all(np.abs(J[3:6, 27:33]).max(axis=0) > 0.1)  # f_b ≈ g along each column's input axis
    np.testing.assert_allclose(F[:9, 9:33], J[:, 9:33], rtol=1e-6, atol=1e-9)
    assert not F[:3, 27:33].any() and not F[6:9, 27:33].any()  # a specific-force error: velocity rows only
    assert noise_count(33) == 30 and G.shape == (33, 30)
    np.testing.assert_array_equal(G[27:33, 24:30], np.eye(6))
    assert not np.delete(G[:, 24:30], np.s_[27:33], axis=0).any()
    assert not F[27:33].any()  # random constants
    F27, G27 = _analytic(300.0, 600.0, n=27)
    np.testing.assert_array_equal(F[:27, :27], F27)
    np.testing.assert_array_equal(G[:27, :24], G27)


def test_correct_increments_removes_the_accelerometer_misalignment():
    """nb = 24: Δv_c = Δv − b_a Δt − s_a∘Δv − M_a Δv (M_a in ``MIS_OUT``/``MIS_IN`` order, after the gyro's
    six); the angle increments as with nb = 18."""
    dt = 0.01
    dth, dv = W_IB * dt, F_B * dt
    m_g = np.array([1e-3, 2e-3, 3e-3, 4e-3, 5e-3, 6e-3])
    m_a = np.array([-7e-3, 8e-3, 9e-3, -1e-3, 2e-3, 3e-3])
    bias = np.concatenate([[1e-4, -2e-4, 3e-4, 0.02, -0.01, 0.03, 1e-3, -2e-3, 5e-4, 2e-3, 1e-3, -1e-3],
                           m_g, m_a])
    dthc, dvc = np.zeros(3), np.zeros(3)
    ins_errors.correct_increments(dth, dv, bias, dt, dthc, dvc)
    Mg, Ma = _off_diagonal(m_g), _off_diagonal(m_a)
    np.testing.assert_allclose(dthc, dth - bias[0:3] * dt - bias[6:9] * dth - Mg @ dth, rtol=0, atol=1e-18)
    np.testing.assert_allclose(dvc, dv - bias[3:6] * dt - bias[9:12] * dv - Ma @ dv, rtol=0, atol=1e-17)


def test_correction_with_the_simulators_misalignment_recovers_the_true_increments():
    """Sign and definition against the simulator itself: increments corrupted by :func:`aidnav.sim.imu.
    corrupt_imu` with misalignments only (no bias, noise, scale factor), then corrected with the realised
    misalignment matrices in the state order (``MIS_OUT``/``MIS_IN``): what is left is (I − M)(I + M) − I
    = −M², second order (≤ 3·(3σ)² relative for 3σ entries); with the wrong sign (or transposed M) it
    would be 2M (or M − Mᵀ), first order."""
    rng = np.random.default_rng(5)
    n, sig = 200, np.radians(0.5)
    imu = ImuData(0.01 * np.arange(1, n + 1), rng.normal(size=(n, 3)) * 0.01, rng.normal(size=(n, 3)) * 0.1,
                  t0=0.0)
    out, real = corrupt_imu(imu, ImuSpec.from_units(misalignment_arcsec=sig / (np.pi / 180 / 3600)),
                            np.random.default_rng(6))
    idx = list(zip(ins_errors.MIS_OUT, ins_errors.MIS_IN, strict=True))
    bias = np.zeros(24)
    bias[12:18] = [real["gyro_misalignment"][r, c] for r, c in idx]
    bias[18:24] = [real["accel_misalignment"][r, c] for r, c in idx]
    assert np.abs(bias[12:]).min() > 0.02 * sig  # every entry drawn (seed 6)
    dthc, dvc = np.zeros(3), np.zeros(3)
    for k in range(n):
        ins_errors.correct_increments(out.dtheta[k], out.dv[k], bias, 0.01, dthc, dvc)
        for got, raw, true in ((dthc, out.dtheta[k], imu.dtheta[k]), (dvc, out.dv[k], imu.dv[k])):
            left = np.linalg.norm(got - true)
            assert left <= 3 * (3 * sig) ** 2 * np.linalg.norm(true) + 1e-15
            assert left < 0.05 * np.linalg.norm(raw - true)  # the first-order error is gone
