"""Bad input to the seed-002 polarization estimators (issue 16): unobservable cases raise ValueError."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.estimators.polarization import (
    closed_form,
    closed_form_covariance,
    crb_eq7,
    crb_numerical,
    cvae_bound,
    estimate_attitude,
    ml_estimate,
)
from aidnav.nav.wave_frame import steering_vector
from aidnav.sim.dipole_triad import sample_covariance, simulate_snapshots

D = np.pi / 180.0
ETA = 27 * D


def _R(theta=20 * D, eta=ETA, snr_db=10.0, n=200, seed=0):
    rng = np.random.default_rng(seed)
    return sample_covariance(simulate_snapshots(30 * D, theta, 15 * D, eta, snr_db, n, rng))


def _estimators(R, eta):
    """Every public estimator applied to the same data, as zero-argument callables."""
    a = np.linalg.eigh(R)[1][:, -1]
    return {
        "closed_form": lambda: closed_form(a, eta),
        "closed_form_covariance": lambda: closed_form_covariance(R, eta),
        "ml_estimate": lambda: ml_estimate(R, eta),
        "estimate_attitude": lambda: estimate_attitude(R, 200, eta, 0.5, 0.1, 0.0),
    }


@pytest.mark.parametrize("eta", [0.0, -0.0, 1e-12])
def test_eta_zero_unobservable(eta):
    # the data are fine (η = 27°); the known η = 0 makes DOA and tilt unobservable
    for f in _estimators(_R(), eta).values():
        with pytest.raises(ValueError, match="eta = 0.*unobservable.*phi, theta.*gamma"):
            f()


@pytest.mark.parametrize("eta", [np.pi / 4, -np.pi / 4, 45 * D, np.radians(-45.0)])
def test_eta_45_tilt_unobservable(eta):
    R = _R(eta=eta)  # circularly polarized data
    for f in _estimators(R, eta).values():
        with pytest.raises(ValueError, match="45 deg.*gamma.*unobservable"):
            f()


@pytest.mark.parametrize("eta", [0.8, -1.0, np.nan, np.inf, np.array([0.3, 0.4]), 0.3 + 0.1j])
def test_eta_out_of_range(eta):
    for f in _estimators(_R(), eta).values():
        with pytest.raises(ValueError, match="eta"):
            f()


def test_eta_near_limits_still_estimates():
    R = _R(eta=1e-3, snr_db=30.0)
    assert np.all(np.isfinite(closed_form_covariance(R, 1e-3)))
    assert np.isfinite(ml_estimate(_R(eta=44.9 * D), 44.9 * D).phi)


@pytest.mark.parametrize("theta", [np.pi / 2, -np.pi / 2])
def test_source_at_zenith_doa_singular(theta):
    A = steering_vector(30 * D, theta, 15 * D, ETA)
    R = np.outer(A, A.conj()) + 0.01 * np.eye(3)
    for f in _estimators(R, ETA).values():
        with pytest.raises(ValueError, match="theta = \\+-90.*phi.*unobservable"):
            f()
    # a batch with one zenith element is rejected as a whole
    B = np.stack([steering_vector(30 * D, 20 * D, 15 * D, ETA), A])
    with pytest.raises(ValueError, match="theta = \\+-90"):
        closed_form(B, ETA)
    # an ML started (by the caller) at the zenith and staying there is rejected too
    with pytest.raises(ValueError, match="theta = \\+-90"):
        ml_estimate(R, ETA, start=(30 * D, theta, 15 * D), maxiter=0)


def test_near_zenith_still_estimates():
    th = 89.0 * D
    A = steering_vector(30 * D, th, 15 * D, ETA)
    phi, theta, gamma = closed_form(A, ETA)
    assert theta == pytest.approx(th, abs=1e-9) and phi == pytest.approx(30 * D, abs=1e-7)


@pytest.mark.parametrize("shape", [(3,), (2, 3), (3, 4), (1, 3, 3), (9,)])
def test_wrong_covariance_shape(shape):
    R = np.ones(shape, dtype=complex)
    calls = [lambda: ml_estimate(R, ETA), lambda: estimate_attitude(R, 10, ETA, 0.0, 0.1, 0.0)]
    if shape != (1, 3, 3):  # a batch of one is valid for closed_form_covariance
        calls.append(lambda: closed_form_covariance(R, ETA))
    for f in calls:
        with pytest.raises(ValueError, match=r"R must have shape \((\.\.\., )?3, 3\)"):
            f()


@pytest.mark.parametrize("shape", [(), (2,), (4,), (5, 2)])
def test_wrong_snapshot_shape(shape):
    with pytest.raises(ValueError, match=r"a must have shape \(\.\.\., 3\)"):
        closed_form(np.ones(shape, dtype=complex), ETA)


def test_wrong_start_shape():
    with pytest.raises(ValueError, match=r"start must have shape \(3,\)"):
        ml_estimate(_R(), ETA, start=(0.1, 0.2))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_data(bad):
    R = _R()
    R[0, 1] = bad
    for name, f in _estimators(R, ETA).items():
        if name == "closed_form":
            a = np.array([1.0, bad, 0.5j])
            f = lambda a=a: closed_form(a, ETA)  # noqa: E731
        with pytest.raises(ValueError, match="NaN or inf"):
            f()
    S = simulate_snapshots(0.3, 0.2, 0.1, ETA, 10.0, 20, np.random.default_rng(1))
    S[3, 2] = bad
    with pytest.raises(ValueError, match="NaN or inf"):
        sample_covariance(S)


def test_zero_data_and_zero_snapshots():
    for name, f in _estimators(np.zeros((3, 3)), ETA).items():
        with pytest.raises(ValueError, match="zero|non-positive trace"):
            if name == "closed_form":
                closed_form(np.zeros(3), ETA)
            else:
                f()
    with pytest.raises(ValueError, match="N >= 1"):
        sample_covariance(np.empty((0, 3)))
    for n in (0, -5, 2.5, np.nan):
        with pytest.raises(ValueError, match="n .*integer >= 1"):
            estimate_attitude(_R(), n, ETA, 0.5, 0.1, 0.0)
        with pytest.raises(ValueError, match="n .*integer >= 1"):
            simulate_snapshots(0.3, 0.2, 0.1, ETA, 10.0, n, np.random.default_rng(0))


def test_snr_validation():
    # the simulator takes dB: any real value is possible (negative = below the noise, +inf = noise-free)
    rng = np.random.default_rng(2)
    assert simulate_snapshots(0.3, 0.2, 0.1, ETA, -10.0, 5, rng).shape == (5, 3)
    S = simulate_snapshots(0.3, 0.2, 0.1, ETA, np.inf, 5, rng)
    assert np.all(np.isfinite(S))
    for bad in (np.nan, -np.inf):
        with pytest.raises(ValueError, match="snr_db"):
            simulate_snapshots(0.3, 0.2, 0.1, ETA, bad, 5, rng)
    # the bounds take the linear SNR ρ = P/σ²: ρ ≤ 0 or NaN is impossible
    for bad in (0.0, -1.0, np.nan):
        with pytest.raises(ValueError, match="snr"):
            cvae_bound(ETA, bad, 1000)
        with pytest.raises(ValueError, match="snr"):
            crb_eq7(0.3, 0.2, 0.1, ETA, bad, 1000)
        with pytest.raises(ValueError, match="snr"):
            crb_numerical(0.3, 0.2, 0.1, ETA, bad, 1000)
    with pytest.raises(ValueError, match="n .*integer >= 1"):
        cvae_bound(ETA, 10.0, 0)
    # a low (even negative) estimated SNR is not an error for the estimator: the fix comes back
    fix = estimate_attitude(_R(snr_db=-3.0, n=2000, seed=3), 2000, ETA, 0.5, 0.1, 0.0)
    assert np.all(np.isfinite(fix.rph))


def test_unknown_method():
    with pytest.raises(ValueError, match="method"):
        estimate_attitude(_R(), 200, ETA, 0.5, 0.1, 0.0, method="music")
