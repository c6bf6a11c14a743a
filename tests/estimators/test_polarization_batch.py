"""The batch (numba) polarization attitude fix agrees with the single-fix API fix by fix."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.estimators.polarization import (
    closed_form_covariance,
    estimate_attitude,
    ml_estimate,
    objective_gradient,
)
from aidnav.estimators.polarization_batch import estimate_attitude_batch, sample_covariance_batch
from aidnav.nav.rotations import dcm_from_euler
from aidnav.nav.wave_frame import enu_rotation_between, steering_vector
from aidnav.sim.dipole_triad import sample_covariance, simulate_snapshots, wave_params_for_attitude

D = np.pi / 180.0
ETA = 27.0 * D


def _cases(k, n, seed=3, snr_db=10.0, eta=ETA):
    rng = np.random.default_rng(seed)
    S = np.empty((k, n, 3), complex)
    geo = []
    for i in range(k):
        rph = (rng.uniform(-30, 30) * D, rng.uniform(-15, 15) * D, rng.uniform(0, 360) * D)
        brg, el, tx = rng.uniform(0, 2 * np.pi), rng.uniform(1, 30) * D, rng.uniform(-0.5, 0.5)
        S[i] = simulate_snapshots(*wave_params_for_attitude(dcm_from_euler(*rph), brg, el, tx), eta, snr_db,
                                  n, rng)
        geo.append((brg, el, tx, rph))
    return S, np.array(geo, dtype=object)


def test_sample_covariance_batch_matches_numpy():
    S, _ = _cases(5, 200)
    np.testing.assert_allclose(sample_covariance_batch(S), sample_covariance(S), rtol=0, atol=1e-14)
    with pytest.raises(ValueError, match="shape"):
        sample_covariance_batch(S[0])
    S[2, 3, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        sample_covariance_batch(S)


@pytest.mark.parametrize("snr_db", [0.0, 10.0, 30.0])
@pytest.mark.slow
def test_batch_equals_single_fix(snr_db):
    n = 500
    S, geo = _cases(40, n, seed=int(snr_db) + 1, snr_db=snr_db)
    R = sample_covariance_batch(S)
    brg, el, tx = (np.array([g[j] for g in geo], float) for j in range(3))
    b = estimate_attitude_batch(R, n, ETA, brg, el, tx)
    assert b.valid.all() and b.converged.all() and len(b) == 40
    for k in range(40):
        f = estimate_attitude(R[k], n, ETA, brg[k], el[k], tx[k])
        ml = ml_estimate(R[k], ETA)
        # the batch optimum is at least as good as BFGS's, and the same point to optimiser precision
        assert b.objective[k] >= ml.objective - 1e-12 * abs(ml.objective)
        np.testing.assert_allclose(b.wave[k], f.wave, atol=1e-6)
        assert b.flipped[k] == f.flipped
        np.testing.assert_allclose(b.rph[k], f.rph, atol=1e-6)
        np.testing.assert_allclose(b.C_bn[k], f.C_bn, atol=1e-6)
        np.testing.assert_allclose(b.snr[k], f.snr, rtol=1e-8)
        for mb, mf in ((b.cov_eps[k], f.cov_eps), (b.cov_rph[k], f.cov_rph)):
            np.testing.assert_allclose(mb, mf, rtol=0, atol=1e-6 * np.abs(mf).max())


def test_batch_prior_and_base_to_local():
    n = 300
    S, geo = _cases(10, n, seed=9)
    R = sample_covariance_batch(S)
    b2l = enu_rotation_between(0.7, 2.0, 0.7 + 1e-3, 2.0 + 2e-3)
    for k in range(10):
        brg, el, tx, rph = geo[k]
        prior = dcm_from_euler(*rph)
        f = estimate_attitude(R[k], n, ETA, brg, el, tx, prior=prior, base_to_local=b2l)
        b = estimate_attitude_batch(R[k:k + 1], n, ETA, brg, el, tx, prior=prior, base_to_local=b2l)
        np.testing.assert_allclose(b.C_bn[0], f.C_bn, atol=1e-6)
        assert b.flipped[0] == f.flipped


def test_noise_free_is_exact_and_starts_at_the_optimum():
    rng = np.random.default_rng(2)
    Rs, truth = [], []
    for _ in range(20):
        p = (rng.uniform(-np.pi, np.pi), rng.uniform(-1.2, 1.2), rng.uniform(-1.5, 1.5))
        A = steering_vector(*p, ETA)
        Rs.append(np.outer(A, A.conj()) + 0.01 * np.eye(3))
        truth.append(p)
    b = estimate_attitude_batch(np.array(Rs), 100, ETA, 0.3, 0.1, 0.0)
    for k in range(20):
        cf = closed_form_covariance(Rs[k], ETA)
        np.testing.assert_allclose(b.wave[k, :2], truth[k][:2], atol=1e-9)
        assert abs(np.sin(b.wave[k, 2] - truth[k][2])) < 1e-9  # γ modulo π (line-of-sight choice)
        np.testing.assert_allclose(cf[:2], truth[k][:2], atol=1e-9)
        assert b.nit[k] <= 1


def test_bad_input():
    R = np.array([np.eye(3, dtype=complex)] * 2)
    for eta, msg in ((0.0, "eta"), (np.pi / 4, "eta")):
        with pytest.raises(ValueError, match=msg):
            estimate_attitude_batch(R, 10, eta, 0.0, 0.1, 0.0)
    with pytest.raises(ValueError, match="shape"):
        estimate_attitude_batch(R[0], 10, ETA, 0.0, 0.1, 0.0)
    with pytest.raises(ValueError, match="bearing"):
        estimate_attitude_batch(R, 10, ETA, [0.0, 1.0, 2.0], 0.1, 0.0)
    with pytest.raises(ValueError, match="trace"):
        estimate_attitude_batch(np.zeros((2, 3, 3), complex), 10, ETA, 0.0, 0.1, 0.0)
    bad = R.copy()
    bad[1, 0, 0] = np.inf
    with pytest.raises(ValueError, match="NaN or inf"):
        estimate_attitude_batch(bad, 10, ETA, 0.0, 0.1, 0.0)
    # a source at the zenith of the triad (a_z = 0): raise naming the fix, or NaN and counted
    A = steering_vector(0.3, np.pi / 2, 0.2, ETA)
    Z = np.array([np.outer(A, A.conj()) + 0.01 * np.eye(3)] * 3)
    A2 = steering_vector(0.3, 0.2, 0.2, ETA)
    Z[0] = np.outer(A2, A2.conj()) + 0.01 * np.eye(3)
    with pytest.raises(ValueError, match="fix 1: .*unobservable"):
        estimate_attitude_batch(Z, 10, ETA, 0.0, 0.1, 0.0)
    b = estimate_attitude_batch(Z, 10, ETA, 0.0, 0.1, 0.0, on_zenith="nan")
    assert b.valid.tolist() == [True, False, False] and np.isnan(b.rph[1:]).all()


def test_objective_gradient_against_finite_differences():
    """AᴴR̂A from the steering vector (independent code) and its analytic gradient vs central differences."""
    S, _ = _cases(3, 200, seed=4)
    R = sample_covariance_batch(S)
    rng = np.random.default_rng(8)
    for k in range(3):
        p = np.array([rng.uniform(-3, 3), rng.uniform(-1.3, 1.3), rng.uniform(-1.5, 1.5)])
        g = np.empty(3)
        f = objective_gradient(p, R[k], np.cos(ETA), np.sin(ETA), g)

        def fa(q, Rk=R[k]):
            A = steering_vector(*q, ETA)
            return float(np.real(np.conj(A) @ Rk @ A))

        assert f == pytest.approx(fa(p), rel=1e-13)
        h = 1e-6
        fd = [(fa(p + h * e) - fa(p - h * e)) / (2 * h) for e in np.eye(3)]
        np.testing.assert_allclose(g, fd, rtol=0, atol=1e-8 * abs(f))
