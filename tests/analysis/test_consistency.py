"""Tests of aidnav.analysis.consistency with synthetic Gaussian samples (fixed seeds).

Every statistical assertion uses bounds at probability 1e-9 from the exact χ² / binomial
distributions, so a correct implementation cannot fail them by chance.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import binom, chi2, kstest

from aidnav.analysis.consistency import binom_ppf, chi2_band, consistency_report, nees, nis

P_TAIL = 1e-9


def random_covariances(rng, n_epochs, n):
    a = rng.normal(size=(n_epochs, n, n))
    return a @ np.swapaxes(a, -1, -2) + 0.1 * np.eye(n)


def gaussian_errors(rng, cov, n_runs):
    """(R, N, n) samples e ~ N(0, P_k) per epoch k."""
    chol = np.linalg.cholesky(cov)
    z = rng.normal(size=(n_runs,) + cov.shape[:-1])
    return np.einsum("kij,rkj->rki", chol, z)


def test_nees_exact_values_and_shapes():
    assert nees(np.array([1.0, 0.0, 0.0]), np.diag([4.0, 1.0, 1.0])) == pytest.approx(0.25)
    e = np.array([[1.0, 2.0], [3.0, -1.0]])
    p = np.array([[[2.0, 0.5], [0.5, 1.0]], [[1.0, 0.0], [0.0, 4.0]]])
    want = [e[k] @ np.linalg.solve(p[k], e[k]) for k in range(2)]
    np.testing.assert_allclose(nees(e, p), want)
    # (R, N, n) errors with an (N, n, n) covariance shared by the runs
    er = np.stack([e, 2 * e, -e])
    v = nees(er, p)
    assert v.shape == (3, 2)
    np.testing.assert_allclose(v, np.array([1.0, 4.0, 1.0])[:, None] * np.array(want)[None, :])
    np.testing.assert_allclose(nees(er, np.broadcast_to(p, (3, 2, 2, 2))), v)
    # NaN rows give NaN, others unaffected
    e2 = e.copy()
    e2[1, 0] = np.nan
    out = nees(e2, p)
    assert np.isnan(out[1]) and out[0] == pytest.approx(want[0])
    with pytest.raises(ValueError):
        nees(e, np.eye(3))
    np.testing.assert_allclose(nis(e, p), nees(e, p))


def test_chi2_band_known_values():
    lo, hi = chi2_band(3, 1, 0.95)
    assert lo == pytest.approx(0.2158, abs=1e-4) and hi == pytest.approx(9.3484, abs=1e-4)
    lo, hi = chi2_band(1, 1, 0.95)
    assert lo == pytest.approx(0.000982, abs=1e-6) and hi == pytest.approx(5.0239, abs=1e-4)
    # R runs: band of the average, (R·ε̄ ~ χ²(R·n)); Bar-Shalom's example n=4, R=50 → [3.2, 4.8]
    lo, hi = chi2_band(4, 50, 0.95)
    assert lo == pytest.approx(3.25, abs=0.03) and hi == pytest.approx(4.83, abs=0.03)
    # the band narrows around n as R grows
    widths = [np.subtract(*chi2_band(3, r)[::-1]) for r in (1, 10, 100, 1000)]
    assert all(a > b for a, b in zip(widths, widths[1:], strict=False))
    with pytest.raises(ValueError):
        chi2_band(0, 1)


def test_nees_of_consistent_gaussian_samples():
    rng = np.random.default_rng(20240601)
    n, n_epochs, n_runs = 3, 400, 25
    cov = random_covariances(rng, n_epochs, n)
    err = gaussian_errors(rng, cov, n_runs)
    v = nees(err, cov)
    assert v.shape == (n_runs, n_epochs)

    # grand mean: R·N·mean ~ χ²(R·N·n)
    lo, hi = chi2_band(n, v.size, 1 - P_TAIL)
    assert lo < v.mean() < hi
    # individual values ~ χ²(n): KS p-value is uniform under the null
    assert kstest(v.ravel(), chi2(n).cdf).pvalue > P_TAIL

    rep = consistency_report(v, n, prob=0.95, alpha=P_TAIL)
    assert rep.verdict == "consistent" and rep.consistent
    assert rep.band == pytest.approx(chi2_band(n, n_runs, 0.95))
    # epochs inside the 95% band: Binomial(N, 0.95) (epochs independent here)
    k_lo, k_hi = binom.ppf(P_TAIL, n_epochs, 0.95), binom.isf(P_TAIL, n_epochs, 0.95)
    assert k_lo <= rep.fraction_inside * n_epochs <= k_hi
    assert rep.n_values == v.size and rep.epoch_mean.shape == (n_epochs,)
    assert rep.mean_band[0] < n < rep.mean_band[1]


def test_single_run_report():
    rng = np.random.default_rng(7)
    n, n_epochs = 2, 2000
    cov = random_covariances(rng, n_epochs, n)
    v = nees(gaussian_errors(rng, cov, 1)[0], cov)
    rep = consistency_report(v, n, alpha=P_TAIL)
    assert rep.n_runs == 1 and rep.verdict == "consistent"
    k_lo, k_hi = binom.ppf(P_TAIL, n_epochs, 0.95), binom.isf(P_TAIL, n_epochs, 0.95)
    assert k_lo <= rep.fraction_inside * n_epochs <= k_hi


def test_covariance_too_small_is_flagged():
    rng = np.random.default_rng(11)
    n, n_epochs, n_runs = 3, 200, 10
    cov = random_covariances(rng, n_epochs, n)
    err = gaussian_errors(rng, cov, n_runs)
    rep = consistency_report(nees(err, cov / 100.0), n, alpha=P_TAIL)
    assert rep.verdict == "optimistic" and not rep.consistent
    assert rep.mean > rep.mean_band[1]
    assert rep.fraction_inside < 0.05 and rep.fraction_above > 0.95
    # and too large a covariance is flagged the other way
    rep2 = consistency_report(nees(err, cov * 100.0), n, alpha=P_TAIL)
    assert rep2.verdict == "pessimistic"
    assert rep2.fraction_below > 0.95


def test_nis_consistent_and_inconsistent():
    rng = np.random.default_rng(3)
    m, n_epochs, n_runs = 2, 300, 5
    s = random_covariances(rng, n_epochs, m)
    y = gaussian_errors(rng, s, n_runs)
    rep = consistency_report(nis(y, s), m, kind="NIS", alpha=P_TAIL)
    assert rep.kind == "NIS" and rep.verdict == "consistent"
    assert consistency_report(nis(y, s / 100.0), m, kind="NIS", alpha=P_TAIL).verdict == "optimistic"


def test_report_handles_nan_and_dict():
    v = np.array([[1.0, np.nan, 3.0], [np.nan, np.nan, 2.0]])
    rep = consistency_report(v, 2)
    assert rep.n_values == 3
    np.testing.assert_allclose(rep.epoch_mean, [1.0, np.nan, 2.5])
    d = rep.to_dict()
    assert d["kind"] == "NEES" and d["runs"] == 2 and d["epochs"] == 3


def test_bands_and_binomial_quantile_are_scipy_stats():
    """chi2_band through scipy.special gives scipy.stats's numbers exactly; binom_ppf is binom.ppf (away
    from exact ties of the CDF with q, e.g. q = 0.5 with p = 0.5, where rounding decides)."""
    for dof in (1, 3, 6, 15):
        for n in (2, 100, 5001, 10**6):
            for prob in (0.95, 0.999):
                want = tuple(float(chi2.ppf(0.5 * (1 + s * prob), dof * n) / n) for s in (-1, 1))
                assert chi2_band(dof, n, prob) == want
    for n in [*range(1, 40), 100, 1800, 12345, 10**6]:
        for p in (0.05, 0.5, 0.95, 0.999):
            for q in (1e-6, 1e-3, 0.9):
                assert binom_ppf(q, n, p) == binom.ppf(q, n, p), (q, n, p)
