"""Seed-level consistency statistics: how far a coverage figure over a few Monte-Carlo seeds can decide
whether a filter's σ is honest, when the error is dominated by a few random constants per seed.

Setting. A run r of a filter gives, at its epochs t, errors e_r(t) and the σ_r(t) it claims; its
normalised error z_r(t) = e_r(t)/σ_r(t) is N(0, 1) at every epoch for an honest Gaussian σ. The 3σ
*coverage* of a block of R seeds is the fraction of all their epochs with |z| ≤ 3; its expectation is
1 − p₃, p₃ = 2Φ(−3) = 0.0027, but its spread depends on how z is correlated in time. Where the error is
made of constants drawn once per seed (sensor biases, misalignments), z_r(t) barely changes within a
run and a seed is wholly inside or wholly outside 3σ: the number of seeds out is Binomial(R, p₃)
(:func:`constant_block_failure`); where z decorrelates within a run the coverage concentrates on
1 − p₃. Between the two, z is modelled as a stationary unit first-order Gauss–Markov process of
correlation time τ (:func:`correlation_time` estimates it from the runs' own z, pooled;
:func:`honest_block_failure` simulates the block's coverage under it).

Seed-level tests at a fixed epoch (independent across seeds, so the χ² and KS tests are exact, unlike
a pooled test over the correlated epochs of each run): the NEES of an n-dof error state ~ χ²(n) per
seed, so the sum over R seeds ~ χ²(R·n) (:func:`chi2_sum`); the z of one axis ~ N(0, 1)
(:func:`ks_normal`). Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking and
Navigation*, §5.4.
"""

from __future__ import annotations

import numpy as np

__all__ = ["P3", "coverage", "values_at", "chi2_sum", "ks_normal", "autocorrelation", "correlation_time",
           "segment_length",
           "constant_block_failure", "honest_block_failure", "resampled_block_failure", "histogram",
           "effective_tests", "any_failure"]

P3 = 0.0026997960632601866  #: P(|N(0, 1)| > 3) = 2Φ(−3)


def coverage(err, sigma, k: float = 3.0) -> np.ndarray:
    """Per column the fraction of rows with |err| ≤ k·sigma, over the rows where both are finite in every
    column (the pooled coverage of the stacked runs of a block)."""
    e, s = np.atleast_2d(np.asarray(err, float)), np.atleast_2d(np.asarray(sigma, float))
    good = np.all(np.isfinite(e) & np.isfinite(s), axis=1)
    return np.mean(np.abs(e[good]) <= k * s[good], axis=0)


def values_at(times: list, values: list, t: float, max_dt: float = 1.0) -> np.ndarray:
    """Per run the value at the epoch nearest ``t`` (``times[r]`` (K_r,), ``values[r]`` (K_r, ...));
    NaN where the nearest epoch is more than ``max_dt`` away. Returns (R, ...)."""
    out = []
    for tt, v in zip(times, values, strict=True):
        tt, v = np.asarray(tt, float), np.asarray(v, float)
        if len(tt) == 0:
            out.append(np.full(v.shape[1:], np.nan))
            continue
        i = int(np.argmin(np.abs(tt - t)))
        out.append(v[i] if abs(tt[i] - t) <= max_dt else np.full(v.shape[1:], np.nan))
    return np.asarray(out, float)


def chi2_sum(values, dof: int) -> dict:
    """Seed-level χ² test of per-seed quadratic forms ``values`` (each ~ χ²(dof) for an honest filter,
    independent across seeds; NaN ignored): the mean per dof, and the tail probabilities of their sum
    under χ²(R·dof): ``p_upper`` = P(Σ ≥ observed) (small: over-confident σ), ``p_lower`` = P(Σ ≤
    observed) (small: σ too large)."""
    from scipy.stats import chi2  # lazy: scipy only where the statistics are asked for

    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    n = len(v) * int(dof)
    if n == 0:
        return {"n": 0, "mean_per_dof": np.nan, "p_upper": np.nan, "p_lower": np.nan}
    tot = float(v.sum())
    return {"n": len(v), "mean_per_dof": tot / n, "p_upper": float(chi2.sf(tot, n)),
            "p_lower": float(chi2.cdf(tot, n))}


def ks_normal(z) -> tuple[float, float]:
    """One-sample Kolmogorov–Smirnov test of ``z`` (NaN ignored) against N(0, 1): (statistic, p)."""
    from scipy.stats import kstest  # lazy: scipy only where the statistics are asked for

    z = np.asarray(z, float)
    z = z[np.isfinite(z)]
    if len(z) == 0:
        return np.nan, np.nan
    r = kstest(z, "norm")
    return float(r.statistic), float(r.pvalue)


def autocorrelation(z_runs: list, max_lag: int | None = None) -> np.ndarray:
    """ρ(k), k = 0 … ``max_lag`` (default half the longest run), of normalised errors ``z_runs`` (one (K_r,)
    series per run; NaN allowed), pooled over the runs and *not* demeaned per run (a constant per seed is
    the correlation sought): mean_{r,t} z_r(t) z_r(t+k) / mean z²; NaN past the runs' length."""
    zs = [np.asarray(z, float) for z in z_runs if len(z)]
    if not zs:
        return np.full(1, np.nan)
    kmax = max(len(z) for z in zs) // 2 if max_lag is None else int(max_lag)
    var = np.nanmean(np.concatenate(zs) ** 2)
    rho = np.full(kmax + 1, np.nan)
    if not var > 0:
        return rho
    rho[0] = 1.0
    for k in range(1, kmax + 1):
        prods = [z[:-k] * z[k:] for z in zs if len(z) > k]
        p = np.concatenate(prods) if prods else np.full(0, np.nan)
        if np.any(np.isfinite(p)):
            rho[k] = np.nanmean(p) / var
    return rho


def correlation_time(z_runs: list, dt: float, max_lag: int | None = None) -> float:
    """The correlation time [s] of normalised errors ``z_runs`` (epochs ``dt`` apart,
    :func:`autocorrelation`): τ = dt·(Σ_{k≥0} ρ(k) − ½), the sum up to the first lag with ρ ≤ 0 or
    ``max_lag`` (default half the longest run). For a first-order Gauss–Markov series Σ_k e^(−k·dt/τ) =
    1/(1 − e^(−dt/τ)) ≈ τ/dt + ½, so this returns τ; a series constant over its run returns about half its
    length × dt (capped by the runs)."""
    rho = autocorrelation(z_runs, max_lag)
    if not np.isfinite(rho[0]):
        return np.nan
    bad = np.flatnonzero(~(rho > 0))
    last = bad[0] if len(bad) else len(rho)
    return float(dt * (np.sum(rho[:last]) - 0.5))


def segment_length(z_runs: list, dt: float, max_lag: int | None = None) -> float:
    """The length L [s] of the stretches over which normalised errors ``z_runs`` are constant, in the
    model "z constant within stretches of length L at a random phase, independent between them" (a few
    random constants per seed, each holding until a manoeuvre re-observes it), whose pooled autocorrelation
    is ρ(k) = 1 − k·dt/L for k·dt < L: L = dt / b, b the least-squares slope of 1 − ρ(k) on k over the lags
    with ρ ≥ ½ (up to ``max_lag``, default half the longest run); ∞ where ρ does not fall (a constant per
    run). A first-order Gauss–Markov series of correlation time τ gives L ≈ 1.2 τ."""
    rho = autocorrelation(z_runs, max_lag)
    if not np.isfinite(rho[0]):
        return np.nan
    k = np.arange(len(rho), dtype=float)
    bad = np.flatnonzero(~(rho >= 0.5))
    last = bad[0] if len(bad) else len(rho)
    k, y = k[1:last], 1.0 - rho[1:last]
    if len(k) == 0:
        return float(dt)  # ρ(1) < ½: shorter than an epoch
    b = float(np.sum(k * y) / np.sum(k * k))
    return float(dt / b) if b > 1e-9 else np.inf  # 1e-9: the rounding of a constant's ρ = 1


def constant_block_failure(n_seeds: int, target: float = 0.95, p_out: float = P3) -> float:
    """P(a block of ``n_seeds`` fails ``target``) when each seed is wholly inside or wholly outside (with
    probability ``p_out``) and the seeds weigh equally: the block's coverage is 1 − J/n, J ~ Binomial(n,
    p_out), so it fails when J > n(1 − target) (the τ → ∞ limit of :func:`honest_block_failure`)."""
    from scipy.stats import binom  # lazy: scipy only where the statistics are asked for

    j_max = int(np.floor(n_seeds * (1.0 - target) + 1e-9))  # the most seeds out that still pass
    return float(binom.sf(j_max, n_seeds, p_out))


def honest_block_failure(n_seeds: int, n_epochs: int, tau_s: float, dt: float = 1.0, target: float = 0.95,
                         k: float = 3.0, n_sim: int = 20000, rng=None, model: str = "segments") -> float:
    """P(the k·σ coverage of a block of ``n_seeds`` runs of ``n_epochs`` epochs ``dt`` apart is below
    ``target``) for an honest filter, by Monte Carlo over ``n_sim`` blocks (``rng``: a numpy Generator or
    seed; standard error √(P(1 − P)/n_sim)); the runs independent, each one's normalised error z(t) N(0, 1)
    at every epoch and, by ``model``:

    * ``"segments"``: constant within stretches of ``tau_s`` seconds (:func:`segment_length`) at a random
      phase, independent between them — a few random constants per seed; ∞: one per run, the binomial
      limit of :func:`constant_block_failure`;
    * ``"gauss-markov"``: a stationary first-order Gauss–Markov series of correlation time ``tau_s``
      (:func:`correlation_time`), which forgets a 3σ draw within τ and so fails a block far less often
      than constants that hold until a manoeuvre."""
    rng = np.random.default_rng(rng)
    if model not in ("segments", "gauss-markov"):
        raise ValueError(f"model {model!r}: 'segments' or 'gauss-markov'")
    if model == "segments" and tau_s < dt:  # stretches shorter than an epoch: white at the epochs
        model, tau_s = "gauss-markov", 0.0
    out = np.zeros(n_sim)
    width = n_epochs + 2 if model == "segments" and not np.isfinite(tau_s) else (
        int(np.ceil(n_epochs * dt / tau_s)) + 2 if model == "segments" else 1)
    chunk = max(1, 2_000_000 // (max(1, n_seeds) * (1 if not np.isfinite(tau_s) else width)))
    for lo in range(0, n_sim, chunk):
        m = min(chunk, n_sim - lo)
        if model == "segments":
            out[lo:lo + m] = _segments_coverage(m, n_seeds, n_epochs * dt, tau_s, k, rng)
            continue
        a = float(np.exp(-dt / tau_s)) if tau_s > 0 else 0.0
        b = float(np.sqrt(1.0 - a * a))
        x = rng.standard_normal((m, n_seeds))
        inside = (np.abs(x) <= k).sum(axis=1).astype(float)
        for _ in range(n_epochs - 1):
            x = a * x + b * rng.standard_normal((m, n_seeds))
            inside += (np.abs(x) <= k).sum(axis=1)
        out[lo:lo + m] = inside / (n_seeds * n_epochs)
    return float(np.mean(out < target))


def _segments_coverage(m: int, n_seeds: int, span: float, length: float, k: float, rng) -> np.ndarray:
    """The coverage of ``m`` blocks of ``n_seeds`` runs of ``span`` seconds whose z is constant within
    stretches of ``length`` seconds at a random phase (:func:`honest_block_failure`)."""
    if not np.isfinite(length) or length >= 1e6 * span:
        return np.mean(np.abs(rng.standard_normal((m, n_seeds))) <= k, axis=1)
    length = max(float(length), 1e-9)
    nseg = int(np.ceil(span / length)) + 1
    u = rng.random((m, n_seeds, 1)) * length
    edges = np.clip(u + length * (np.arange(nseg + 1) - 1.0), 0.0, span)
    inside = np.abs(rng.standard_normal((m, n_seeds, nseg))) <= k
    return np.sum(np.diff(edges, axis=2) * inside, axis=(1, 2)) / (n_seeds * span)


def resampled_block_failure(covered, epochs, block: int, target: float = 0.95, n_draw: int = 20000,
                            rng=None) -> float:
    """The fraction of blocks of ``block`` seeds drawn without replacement from the observed seeds (their
    ``covered`` epoch counts and ``epochs``) whose pooled coverage is below ``target``: how often a block of
    that size of *this* filter fails, from its own seeds (no model)."""
    rng = np.random.default_rng(rng)
    c, n = np.asarray(covered, float), np.asarray(epochs, float)
    if block > len(c):
        raise ValueError(f"block {block} > {len(c)} seeds")
    idx = np.argsort(rng.random((n_draw, len(c))), axis=1)[:, :block]
    return float(np.mean(c[idx].sum(axis=1) / n[idx].sum(axis=1) < target))


def histogram(values, edges=(0.5, 0.9, 0.95, 0.99)) -> list[int]:
    """Counts of ``values`` in [−∞, e₀), [e₀, e₁), …, [e_last, ∞) (the per-seed coverages' distribution)."""
    v = np.asarray(values, float)
    return [int(x) for x in np.bincount(np.searchsorted(np.asarray(edges, float), v, side="right"),
                                         minlength=len(edges) + 1)]


def effective_tests(samples) -> float:
    """The effective number of independent tests among M correlated statistics (``samples`` (R, M): R
    seeds' values of each, e.g. the z of roll and pitch in every cell of a row), Galwey (Genet. Epidemiol.
    33, 2009): from the eigenvalues λ ≥ 0 of their correlation matrix, M_eff = (Σ√λ)² / Σλ. M uncorrelated
    statistics give M, M copies of one give 1, k independent groups of copies give k. Columns constant or
    with NaN are left out."""
    x = np.asarray(samples, float)
    x = x[:, np.all(np.isfinite(x), axis=0) & (np.nanstd(x, axis=0) > 0)]
    if x.shape[1] == 0:
        return 0.0
    if x.shape[1] == 1:
        return 1.0
    lam = np.clip(np.linalg.eigvalsh(np.corrcoef(x, rowvar=False)), 0.0, None)
    return float(np.sum(np.sqrt(lam)) ** 2 / np.sum(lam))


def any_failure(p_each: float, n_tests: float) -> float:
    """P(at least one of ``n_tests`` independent tests fails), each with probability ``p_each``:
    1 − (1 − p)^n (n need not be whole: an effective number, :func:`effective_tests`)."""
    return float(1.0 - (1.0 - p_each) ** n_tests)
