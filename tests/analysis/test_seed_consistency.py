"""Seed-level consistency statistics (:mod:`aidnav.analysis.seed_consistency`, issue 35 session 16):
known answers — closed forms of the normal, χ² and binomial laws, synthetic series of a known correlation
time, counts by construction. Fixed seeds; every tolerance is a stated multiple of the Monte-Carlo
standard error."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import binom, norm

from aidnav.analysis import seed_consistency as sc


def test_p3_is_the_normal_two_sided_tail():
    assert sc.P3 == pytest.approx(2.0 * norm.sf(3.0), rel=1e-12)


def test_pooled_coverage_of_honest_normal_errors():
    """N(0, σ²) errors with their own σ: 3σ coverage 1 − P3 within 4 binomial standard errors; 1σ coverage
    0.6827; errors of twice the claimed σ: 2Φ(1.5) − 1 = 0.8664."""
    rng = np.random.default_rng(1)
    n = 200_000
    sig = rng.uniform(0.5, 2.0, (n, 2))
    e = rng.standard_normal((n, 2)) * sig
    se = np.sqrt(sc.P3 * (1 - sc.P3) / n)
    np.testing.assert_allclose(sc.coverage(e, sig), 1 - sc.P3, atol=4 * se)
    np.testing.assert_allclose(sc.coverage(e, sig, k=1.0), 0.6827, atol=0.005)
    np.testing.assert_allclose(sc.coverage(2 * e, sig), 2 * norm.cdf(1.5) - 1, atol=0.004)
    e[0] = [100.0, np.nan]  # a row with a NaN is left out on every axis (its 100σ not counted out)
    np.testing.assert_allclose(sc.coverage(e, sig), sc.coverage(e[1:], sig[1:]))


def test_chi2_sum_closed_forms():
    """One seed of a 1-dof NEES of 9 (z = 3): P(χ²₁ ≥ 9) = P3; a sum equal to its dof count over many seeds:
    p_upper → ½ (χ²(n) median ≈ n − ⅔); NaN seeds ignored; p_upper + p_lower = 1."""
    r = sc.chi2_sum([9.0], 1)
    assert r["p_upper"] == pytest.approx(sc.P3, rel=1e-9)
    assert r["mean_per_dof"] == 9.0
    r = sc.chi2_sum([3.0] * 400 + [np.nan], 3)
    assert r["n"] == 400 and r["mean_per_dof"] == 1.0
    assert 0.45 < r["p_upper"] < 0.55
    assert r["p_upper"] + r["p_lower"] == pytest.approx(1.0)


def test_chi2_sum_rejects_an_overconfident_sigma():
    """NEES of 9-dof errors whose σ is claimed 1.2× too small (NEES scaled by 1.44), 40 seeds: p_upper
    far below 1e-3; the honest draw of the same seeds is not rejected at 1 %."""
    rng = np.random.default_rng(2)
    x = rng.chisquare(9, 40)
    assert sc.chi2_sum(x, 9)["p_upper"] > 0.01 and sc.chi2_sum(x, 9)["p_lower"] > 0.01
    assert sc.chi2_sum(1.44 * x, 9)["p_upper"] < 1e-3


def test_ks_normal_accepts_n01_and_rejects_a_wider_law():
    rng = np.random.default_rng(3)
    assert sc.ks_normal(rng.standard_normal(400))[1] > 0.01
    assert sc.ks_normal(1.5 * rng.standard_normal(400))[1] < 1e-3
    assert np.isnan(sc.ks_normal([np.nan])[1])


def _ar1(rng, runs, n, tau, dt=1.0):
    a = np.exp(-dt / tau)
    x = np.empty((runs, n))
    x[:, 0] = rng.standard_normal(runs)
    for k in range(1, n):
        x[:, k] = a * x[:, k - 1] + np.sqrt(1 - a * a) * rng.standard_normal(runs)
    return x


def test_correlation_time_of_a_gauss_markov_series():
    """200 runs of 280 epochs of a unit first-order Gauss–Markov series, τ = 10 s at 1 s: estimate within
    15 %; white noise: about ½ dt; a constant per run: capped near half the run (140 s)."""
    rng = np.random.default_rng(4)
    tau = sc.correlation_time(list(_ar1(rng, 200, 280, 10.0)), 1.0)
    assert tau == pytest.approx(10.0, rel=0.15)
    assert sc.correlation_time(list(rng.standard_normal((200, 280))), 1.0) < 1.0
    const = [np.full(280, z) for z in rng.standard_normal(40)]
    assert sc.correlation_time(const, 1.0) == pytest.approx(140.5, rel=1e-9)


def test_constant_block_failure_is_binomial():
    """A block of 10 seeds wholly in or out fails 95 % with one seed out: 1 − (1 − P3)^10 = 2.67 %; 40
    seeds need 3 out: P(J ≥ 3)."""
    assert sc.constant_block_failure(10) == pytest.approx(1 - (1 - sc.P3) ** 10, rel=1e-9)
    assert sc.constant_block_failure(10) == pytest.approx(0.0267, abs=1e-4)
    assert sc.constant_block_failure(40) == pytest.approx(binom.sf(2, 40, sc.P3), rel=1e-9)
    assert sc.constant_block_failure(40) < 2e-4


def _segments(rng, runs, n, length):
    """Runs of n epochs (1 s) whose value is a fresh N(0, 1) every ``length`` s, at a random phase."""
    out = np.empty((runs, n))
    for r in range(runs):
        u = rng.uniform(0, length)
        idx = np.floor((np.arange(n) - u) / length).astype(int) + 1
        out[r] = rng.standard_normal(idx.max() + 1)[idx]
    return out


def test_segment_length_known_answers():
    """Stretches of 100 s at a random phase: L within 15 %; a constant per run: ∞; a Gauss–Markov series of
    τ 20 s: between 0.8 τ and 1.6 τ (the doc's ≈ 1.2 τ)."""
    rng = np.random.default_rng(10)
    assert sc.segment_length(list(_segments(rng, 400, 280, 100.0)), 1.0) == pytest.approx(100.0, rel=0.15)
    assert sc.segment_length([np.full(280, z) for z in rng.standard_normal(40)], 1.0) == np.inf
    lg = sc.segment_length(list(_ar1(rng, 400, 280, 20.0)), 1.0)
    assert 16.0 < lg < 32.0


@pytest.mark.parametrize("model", ["segments", "gauss-markov"])
def test_honest_block_failure_limits(model):
    """τ → ∞: the binomial limit within 4 Monte-Carlo standard errors; white errors (τ → 0): a 10 × 280
    block's coverage is 1 − P3 ± 0.001, never below 95 %; in between, monotone in τ."""
    p_const = sc.constant_block_failure(10)
    n = 20000
    p_inf = sc.honest_block_failure(10, 280, np.inf if model == "segments" else 1e12, n_sim=n, rng=5,
                                    model=model)
    assert p_inf == pytest.approx(p_const, abs=4 * np.sqrt(p_const * (1 - p_const) / n))
    assert sc.honest_block_failure(10, 280, 1e-3, n_sim=2000, rng=6, model=model) == 0.0
    p30 = sc.honest_block_failure(10, 280, 30.0, n_sim=n, rng=7, model=model)
    p300 = sc.honest_block_failure(10, 280, 300.0, n_sim=n, rng=7, model=model)
    assert p30 < p300 < p_inf + 4 * np.sqrt(p_const / n)


def test_segments_model_needs_one_long_stretch_out():
    """A block of 10 runs of 280 s fails when more than 140 s are out: with stretches of 2× the run a
    run is whole or split in two, and its longer piece (≥ 140 s) alone decides — the binomial limit within
    4 standard errors; with stretches of 70 s a run needs 2 or more of its 4–5 stretches out: P ≈ 0."""
    p_const = sc.constant_block_failure(10)
    n = 40000
    p2 = sc.honest_block_failure(10, 280, 560.0, n_sim=n, rng=11)
    assert p2 == pytest.approx(p_const, abs=4 * np.sqrt(p_const * (1 - p_const) / n))
    assert sc.honest_block_failure(10, 280, 70.0, n_sim=n, rng=11) < 1e-3
    with pytest.raises(ValueError):
        sc.honest_block_failure(10, 280, 10.0, n_sim=10, model="ar2")


def test_resampled_block_failure_counts_the_blocks_holding_the_bad_seed():
    """40 seeds, one wholly outside 3σ, the others wholly inside: a block of 10 fails iff it holds that
    seed, P = 10/40 (within 4 standard errors); a block of all 40 passes with 2 bad seeds (38/40 = 95 %)
    and fails with 3."""
    covered = np.full(40, 280)
    covered[4] = 0
    n = 20000
    p = sc.resampled_block_failure(covered, np.full(40, 280), 10, n_draw=n, rng=8)
    assert p == pytest.approx(0.25, abs=4 * np.sqrt(0.25 * 0.75 / n))
    covered[9] = 0
    assert sc.resampled_block_failure(covered, np.full(40, 280), 40, n_draw=10, rng=8) == 0.0
    covered[19] = 0
    assert sc.resampled_block_failure(covered, np.full(40, 280), 40, n_draw=10, rng=8) == 1.0
    with pytest.raises(ValueError):
        sc.resampled_block_failure(covered, np.full(40, 280), 41)


def test_values_at_and_histogram():
    t = [np.arange(0.0, 10.0), np.arange(0.0, 5.0), np.zeros(0)]
    v = [np.arange(10.0)[:, None] * [1, 2], np.arange(5.0)[:, None] * [1, 2], np.zeros((0, 2))]
    out = sc.values_at(t, v, 7.2)
    np.testing.assert_allclose(out[0], [7.0, 14.0])
    assert np.all(np.isnan(out[1])) and np.all(np.isnan(out[2]))  # nearest 4.0: 3.2 s away; empty run
    assert sc.histogram([0.1, 0.5, 0.92, 0.95, 0.999, 1.0]) == [1, 1, 1, 1, 2]


def test_effective_tests_known_answers():
    """Uncorrelated columns: M; copies of one column (and its negative): 1; two independent pairs of copies:
    2 (within the sampling noise of the correlation estimate over 2000 rows); 1 − (1 − p)^n."""
    rng = np.random.default_rng(9)
    x = rng.standard_normal((2000, 4))
    assert sc.effective_tests(x) == pytest.approx(4.0, abs=0.1)
    a = x[:, :1]
    assert sc.effective_tests(np.hstack([a, a, -a, 2 * a])) == pytest.approx(1.0, abs=1e-6)
    pairs = np.hstack([x[:, :1], x[:, :1], x[:, 1:2], x[:, 1:2]])
    assert sc.effective_tests(pairs) == pytest.approx(2.0, abs=0.1)
    assert sc.effective_tests(np.hstack([x[:, :1], np.ones((2000, 1))])) == 1.0
    assert sc.any_failure(0.0267, 1) == pytest.approx(0.0267)
    assert sc.any_failure(0.5, 2) == pytest.approx(0.75)
