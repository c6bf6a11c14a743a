"""Polarization attitude estimators of seed 002 (§3.3–3.5): closed form, ML, CRBs, attitude."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2

from aidnav.estimators.polarization import (
    attitude_from_wave,
    closed_form,
    closed_form_covariance,
    concentrated_loglik,
    crb_attitude,
    crb_eq7,
    crb_numerical,
    crb_rotation_vector,
    cvae_bound,
    estimate_attitude,
    euler_error_jacobian,
    ml_estimate,
    power_noise,
    resolve_line_of_sight,
)
from aidnav.nav.rotations import dcm_from_euler, euler_from_dcm, rotvec_from_dcm, skew
from aidnav.nav.wave_frame import (
    enu_rotation_between,
    steering_vector,
    wave_dcm,
    wave_params_from_dcm,
    wrap_tilt,
)
from aidnav.sim.dipole_triad import sample_covariance, simulate_snapshots, wave_params_for_attitude

D = np.pi / 180.0


def _angle_err(est, true):
    """(dφ, dθ, dγ) with φ wrapped by 2π and γ by π."""
    return np.array([np.angle(np.exp(1j * (est[0] - true[0]))), est[1] - true[1],
                     0.5 * np.angle(np.exp(2j * (est[2] - true[2])))])


# ----------------------------------------------------------------------------------- closed form
@settings(max_examples=300, deadline=None)
@given(phi=st.floats(-3.14, 3.14), theta=st.floats(-1.45, 1.45), gamma=st.floats(-1.5707, 1.5707),
       eta=st.floats(0.02, 0.76), neg=st.booleans(), ph=st.floats(0, 6.28), amp=st.floats(0.01, 100.0))
def test_closed_form_exact_noise_free(phi, theta, gamma, eta, neg, ph, amp):
    eta = -eta if neg else eta
    A = steering_vector(phi, theta, gamma, eta)
    if abs(A[2]) < 1e-3:  # a_z = 0 (θ = ±90° or horizontal linear polarization): θ undefined
        return
    s = amp * np.exp(1j * ph)  # any complex signal value
    est = closed_form(s * A, eta)
    assert np.max(np.abs(_angle_err(est, (phi, theta, gamma)))) < 1e-9
    # and on the principal eigenvector of a noise-free covariance
    R = 2.0 * np.outer(A, A.conj())
    assert np.max(np.abs(_angle_err(closed_form_covariance(R, eta), (phi, theta, gamma)))) < 1e-9


def test_closed_form_vectorised():
    rng = np.random.default_rng(0)
    p = np.column_stack([rng.uniform(-3, 3, 50), rng.uniform(-1.2, 1.2, 50), rng.uniform(-1.5, 1.5, 50)])
    A = np.array([steering_vector(*q, 0.3) for q in p])
    phi, th, g = closed_form(A, 0.3)
    np.testing.assert_allclose(phi, p[:, 0], atol=1e-12)
    np.testing.assert_allclose(th, p[:, 1], atol=1e-12)
    np.testing.assert_allclose(g, p[:, 2], atol=1e-12)


def test_seed_eq4_valid_only_for_real_signal():
    """§3.6 erratum 4: tan γ = Re{s_z sinφ}/Re{s_z sinθ cosφ + s_x cosθ} needs a real s(t)."""
    phi, th, g, eta = 30 * D, 20 * D, 15 * D, 27 * D
    A = steering_vector(phi, th, g, eta)

    def eq4(s):
        return np.arctan(np.real(s[2] * np.sin(phi)) / np.real(s[2] * np.sin(th) * np.cos(phi)
                                                              + s[0] * np.cos(th)))

    for s in (1.0, -2.3):  # exact for a real s(t)
        assert eq4(s * A) == pytest.approx(g, abs=1e-12)
    # §3.3: γ = 15° comes out as 56.4° when the signal phase is 60°
    assert eq4(np.exp(1j * 60 * D) * A) / D == pytest.approx(56.4, abs=0.05)
    # the corrected (Stokes/Jones) form does not care about the signal phase
    for ph in (0.0, 60 * D, 2.0):
        assert closed_form(np.exp(1j * ph) * A, eta)[2] == pytest.approx(g, abs=1e-12)


# ----------------------------------------------------------------------------------- ML
def test_ml_at_least_as_good_as_closed_form():
    rng = np.random.default_rng(1)
    phi, th, g, eta = 30 * D, 20 * D, 15 * D, 27 * D
    e_cf, e_ml = [], []
    for _ in range(150):
        R = sample_covariance(simulate_snapshots(phi, th, g, eta, 5.0, 200, rng))
        cf = closed_form_covariance(R, eta)
        ml = ml_estimate(R, eta)
        assert ml.success
        # the ML maximises AᴴR̂A: never below the closed form's value, nor its likelihood
        obj_cf = np.real(steering_vector(*cf, eta).conj() @ R @ steering_vector(*cf, eta))
        assert ml.objective >= obj_cf - 1e-12
        assert concentrated_loglik(ml.params, R, eta, 200) >= concentrated_loglik(cf, R, eta, 200) - 1e-9
        e_cf.append(_angle_err(cf, (phi, th, g)))
        e_ml.append(_angle_err(ml.params, (phi, th, g)))
    s_cf = np.sqrt(np.mean(np.square(e_cf), 0))
    s_ml = np.sqrt(np.mean(np.square(e_ml), 0))
    assert np.all(s_ml <= 1.01 * s_cf)


def test_ml_power_noise_and_snr():
    rng = np.random.default_rng(2)
    R = sample_covariance(simulate_snapshots(0.4, -0.3, 1.0, 0.35, 10.0, 20000, rng, power=3.0))
    ml = ml_estimate(R, 0.35)
    assert ml.power == pytest.approx(3.0, rel=0.05)
    assert ml.noise_var == pytest.approx(0.3, rel=0.05)
    assert ml.snr == pytest.approx(10.0, rel=0.08)
    pw, s2 = power_noise(steering_vector(*ml.params, 0.35), R)
    assert (pw, s2) == pytest.approx((ml.power, ml.noise_var))


def test_ml_monte_carlo_attains_crb():
    """At high SNR the ML errors are N(0, CRB): n·MSE/CRB ~ χ²_n for each parameter and each rotation
    component (99.9 % two-sided bounds, 6 checks, fixed seed)."""
    rng = np.random.default_rng(3)
    phi, th, g, eta = 30 * D, 20 * D, 15 * D, 27 * D
    snr_db, n_snap, runs = 20.0, 200, 400
    C0 = wave_dcm(phi, th, g)
    err = np.empty((runs, 3))
    dl = np.empty((runs, 3))
    for r in range(runs):
        R = sample_covariance(simulate_snapshots(phi, th, g, eta, snr_db, n_snap, rng))
        p = ml_estimate(R, eta).params
        err[r] = _angle_err(p, (phi, th, g))
        dl[r] = -rotvec_from_dcm(np.ascontiguousarray(wave_dcm(*p) @ C0.T))
    lo, hi = chi2.ppf(0.0005, runs), chi2.ppf(0.9995, runs)
    crb = np.diag(crb_eq7(phi, th, g, eta, 10 ** (snr_db / 10), n_snap))
    cv = np.diag(cvae_bound(eta, 10 ** (snr_db / 10), n_snap))
    for x, v in ((err, crb), (dl, cv)):
        stat = np.sum(x**2, 0) / v
        assert np.all((stat > lo) & (stat < hi)), (stat / runs, lo / runs, hi / runs)


# ----------------------------------------------------------------------------------- CRB
@pytest.mark.parametrize("p", [(30 * D, 20 * D, 15 * D, 27 * D), (1.0, -0.7, -1.2, -0.3),
                               (2.5, 0.3, 0.4, 0.6),
                               (-2.0, 1.2, 1.5, 0.1)])
@pytest.mark.parametrize("snr", [0.5, 10.0, 1000.0])
def test_crb_eq7_equals_numerical_fim(p, snr):
    a = crb_eq7(*p, snr, 1000)
    b = crb_numerical(*p, snr, 1000, power=2.5)
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12 * np.max(np.abs(a)))


def test_cvae_is_diagonal_and_geometry_free():
    rng = np.random.default_rng(4)
    for _ in range(20):
        p = (rng.uniform(-3, 3), rng.uniform(-1.3, 1.3), rng.uniform(-1.5, 1.5))
        eta = rng.uniform(0.05, 0.75)
        cv = crb_rotation_vector(*p, eta, 10.0, 1000)
        ref = cvae_bound(eta, 10.0, 1000)
        np.testing.assert_allclose(cv, ref, rtol=1e-9, atol=1e-12 * ref.max())
    sig = np.sqrt(np.diag(cvae_bound(27 * D, 10.0, 1000))) / D
    np.testing.assert_allclose(sig, [0.7229, 0.9360, 0.4769], atol=5e-5)  # §3.7


def test_euler_error_jacobian_numerical():
    rng = np.random.default_rng(5)
    for _ in range(10):
        rph = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0, 6)])
        C = dcm_from_euler(*rph)
        J = euler_error_jacobian(*rph)
        h = 1e-6
        for k in range(3):
            e = np.zeros(3)
            e[k] = h
            rp = np.array(euler_from_dcm((np.eye(3) - skew(e)) @ C))
            rm = np.array(euler_from_dcm((np.eye(3) + skew(e)) @ C))
            d = (rp - rm + np.pi) % (2 * np.pi) - np.pi
            np.testing.assert_allclose(J[:, k], d / (2 * h), atol=1e-6)


def test_euler_crb_is_the_chain_of_eq7():
    """cov(roll, pitch, heading) = G CRB(φ,θ,γ) Gᵀ with G = ∂(rph)/∂(φ,θ,γ) by finite differences."""
    C_true = dcm_from_euler(10 * D, 5 * D, 40 * D)
    brg, el, tilt = 200 * D, 4 * D, 0.3
    M = enu_rotation_between(0.55, 2.07, 0.553, 2.07)
    p = np.array(wave_params_for_attitude(C_true, brg, el, tilt, M))
    eta, rho, n = 27 * D, 10.0, 1000
    _, cov_rph, C = crb_attitude(*p, eta, rho, n, brg, el, tilt, M)
    np.testing.assert_allclose(C, C_true, atol=1e-14)
    G = np.empty((3, 3))
    h = 1e-6
    for k in range(3):
        dp = np.zeros(3)
        dp[k] = h
        a = np.array(euler_from_dcm(attitude_from_wave(*(p + dp), brg, el, tilt, M)))
        b = np.array(euler_from_dcm(attitude_from_wave(*(p - dp), brg, el, tilt, M)))
        G[:, k] = ((a - b + np.pi) % (2 * np.pi) - np.pi) / (2 * h)
    np.testing.assert_allclose(cov_rph, G @ crb_eq7(*p, eta, rho, n) @ G.T, rtol=1e-6)


# ----------------------------------------------------------------------------------- attitude
@settings(max_examples=60, deadline=None)
@given(roll=st.floats(-1.3, 1.3), pitch=st.floats(-1.2, 1.2), heading=st.floats(0, 6.28),
       bearing=st.floats(0, 6.28), elev=st.floats(0.0, 1.2), tilt=st.floats(-1.5, 1.5),
       dlat=st.floats(-0.01, 0.01))
def test_attitude_round_trip(roll, pitch, heading, bearing, elev, tilt, dlat):
    """C_b^n from (roll, pitch, heading) → wave seen by the triad → noise-free snapshots → ML and closed
    form → steps 1–4 → the same (roll, pitch, heading)."""
    C = dcm_from_euler(roll, pitch, heading)
    M = enu_rotation_between(0.5, 2.0, 0.5 + dlat, 2.0 + dlat)
    p = wave_params_for_attitude(C, bearing, elev, tilt, M)
    eta = 27 * D
    A = steering_vector(*p, eta)
    if abs(A[2]) < 1e-2 or abs(np.cos(p[1])) < 1e-2:
        return  # θ undefined or over the top (§3.3)
    rng = np.random.default_rng(0)
    s = rng.standard_normal(50) + 1j * rng.standard_normal(50)
    R = sample_covariance(s[:, None] * A)
    for method in ("ml", "closed_form"):
        fix = estimate_attitude(R, 50, eta, bearing, elev, tilt, method=method, prior=C, base_to_local=M)
        ang = np.linalg.norm(rotvec_from_dcm(np.ascontiguousarray(fix.C_bn @ C.T)))
        assert ang < 1e-7
        np.testing.assert_allclose(fix.C_bn, dcm_from_euler(*fix.rph), atol=1e-12)


def test_line_of_sight_ambiguity():
    """γ and γ + π give attitudes 180° apart about the line of sight; a prior (or 'upright') picks one."""
    C = dcm_from_euler(20 * D, 5 * D, 10 * D)
    brg, el, tilt = 185 * D, 3 * D, 0.0
    p = wave_params_for_attitude(C, brg, el, tilt)
    C1 = attitude_from_wave(p[0], p[1], p[2], brg, el, tilt)
    C2 = attitude_from_wave(p[0], p[1], p[2] + np.pi, brg, el, tilt)
    np.testing.assert_allclose(C1, C, atol=1e-14)
    r = rotvec_from_dcm(np.ascontiguousarray(C2 @ C1.T))
    assert np.linalg.norm(r) == pytest.approx(np.pi, abs=1e-9)
    # the rotation axis is the line of sight (aircraft → base) in n
    los = np.array([np.sin(brg) * np.cos(el), np.cos(brg) * np.cos(el), np.sin(el)])
    assert abs(abs(r @ los) / np.linalg.norm(r)) == pytest.approx(1.0, abs=1e-9)
    g_folded = wrap_tilt(p[2] + np.pi)
    # no prior: upright wins
    _, Cu, _ = resolve_line_of_sight(p[0], p[1], g_folded, brg, el, tilt)
    np.testing.assert_allclose(Cu, C, atol=1e-12)
    # an inverted aircraft needs the prior (e.g. the previous epoch)
    Cinv = dcm_from_euler(170 * D, 5 * D, 10 * D)
    q = wave_params_for_attitude(Cinv, brg, el, tilt)
    _, Cp, _ = resolve_line_of_sight(q[0], q[1], wrap_tilt(q[2]), brg, el, tilt,
                                     prior=dcm_from_euler(165 * D, 0.0, 12 * D))
    np.testing.assert_allclose(Cp, Cinv, atol=1e-12)
    _, Cw, _ = resolve_line_of_sight(q[0], q[1], wrap_tilt(q[2]), brg, el, tilt)
    assert not np.allclose(Cw, Cinv, atol=1e-3)


def test_fold_and_params_from_dcm():
    p = wave_params_from_dcm(wave_dcm(0.3, 0.2, 2.0))
    assert p[2] == pytest.approx(2.0 - np.pi)
    assert wrap_tilt(np.pi / 2) == pytest.approx(np.pi / 2)
    assert wrap_tilt(-np.pi / 2) == pytest.approx(np.pi / 2)


def test_attitude_fix_covariance_matches_monte_carlo():
    """The fix's cov_eps (CRB at the estimated SNR) predicts the spread of the attitude error."""
    rng = np.random.default_rng(6)
    C = dcm_from_euler(-10 * D, 2 * D, 350 * D)
    brg, el, tilt, eta = 180 * D, 3 * D, 0.0, 27 * D
    p = wave_params_for_attitude(C, brg, el, tilt)
    eps = []
    covs = []
    for _ in range(200):
        R = sample_covariance(simulate_snapshots(*p, eta, 10.0, 1000, rng))
        fix = estimate_attitude(R, 1000, eta, brg, el, tilt)
        eps.append(rotvec_from_dcm(np.ascontiguousarray(C @ fix.C_bn.T)))
        covs.append(fix.cov_eps)
    eps = np.array(eps)
    P = np.mean(covs, 0)
    nees = np.einsum("ki,ij,kj->k", eps, np.linalg.inv(P), eps)
    # sum of 200 χ²_3 → χ²_600; 99.9 % bounds
    assert chi2.ppf(0.0005, 600) < nees.sum() < chi2.ppf(0.9995, 600)
