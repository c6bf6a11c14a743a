"""Filter consistency: normalised estimation error squared (NEES) and innovation squared (NIS).

For a consistent (unbiased, correctly-covariant) Gaussian estimator with n-dimensional error e and
covariance P, ε = eᵀ P⁻¹ e ~ χ²(n). Over R independent Monte-Carlo runs, the run-average at one
epoch ε̄ = (1/R) Σ_r ε_r satisfies R·ε̄ ~ χ²(R·n) (Bar-Shalom, Li, Kirubarajan, *Estimation with
Applications to Tracking and Navigation*, §5.4). :func:`chi2_band` gives the two-sided acceptance
interval of ε̄; :func:`consistency_report` checks the per-epoch averages against it and the grand
average over all epochs and runs against the band for R·N·n degrees of freedom.

The grand-average band assumes the N epochs are independent; the errors of a real filter are
correlated in time, so that band is then too narrow and the per-epoch fraction is the more robust
indicator. Units: e and P in any consistent units (e.g. m and m²); NEES/NIS are dimensionless.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def _quadratic_form(e: np.ndarray, p: np.ndarray, what: str) -> np.ndarray:
    e = np.asarray(e, dtype=float)
    p = np.asarray(p, dtype=float)
    if e.ndim not in (1, 2, 3):
        raise ValueError(f"{what}: error must be (n,), (N, n) or (R, N, n), got shape {e.shape}")
    n = e.shape[-1]
    if p.shape[-2:] != (n, n):
        raise ValueError(f"{what}: covariance must end in ({n}, {n}), got shape {p.shape}")
    try:
        p = np.broadcast_to(p, e.shape + (n,))
    except ValueError:
        raise ValueError(f"{what}: covariance shape {p.shape} does not match error shape {e.shape}") from None
    out = np.full(e.shape[:-1], np.nan)
    ok = np.all(np.isfinite(e), axis=-1) & np.all(np.isfinite(p), axis=(-2, -1))
    if np.any(ok):
        ee, pp = e[ok], p[ok]
        x = np.linalg.solve(pp, ee[..., None])[..., 0]
        out[ok] = np.sum(ee * x, axis=-1)
    return out


def nees(err: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Normalised estimation error squared ε = eᵀ P⁻¹ e per epoch (and run).

    err : (N, n) or (R, N, n) estimation errors (estimate − truth), or (n,) for one epoch.
    cov : the filter's covariance of those errors, (N, n, n) or (R, N, n, n); an (N, n, n) covariance
        is shared by all R runs (broadcast), an (n, n) one by all epochs.
    Returns (N,) or (R, N) values (NaN where e or P has non-finite entries); each ~ χ²(n) for a
    consistent estimator. Raises ``numpy.linalg.LinAlgError`` for a singular covariance.
    """
    return _quadratic_form(err, cov, "nees")


def nis(innov: np.ndarray, innov_cov: np.ndarray) -> np.ndarray:
    """Normalised innovation squared ν = yᵀ S⁻¹ y per epoch (and run).

    innov : (N, m) or (R, N, m) innovations (measurement − predicted measurement).
    innov_cov : their predicted covariance S = H P⁻ Hᵀ + R, (N, m, m) or (R, N, m, m).
    Same shapes and NaN handling as :func:`nees`; each value ~ χ²(m) for a consistent filter.
    """
    return _quadratic_form(innov, innov_cov, "nis")


def chi2_band(dof: int, n_runs: int = 1, prob: float = 0.95) -> tuple[float, float]:
    """Two-sided ``prob`` acceptance interval (lo, hi) of the average of ``n_runs`` independent
    χ²(dof) values: R·ε̄ ~ χ²(R·dof), so lo = χ²⁻¹((1−prob)/2; R·dof)/R, hi = χ²⁻¹((1+prob)/2; R·dof)/R.
    For dof = 3, R = 1, prob = 0.95: (0.216, 9.348)."""
    if dof <= 0 or n_runs <= 0:
        raise ValueError("chi2_band: dof and n_runs must be positive")
    if not 0.0 < prob < 1.0:
        raise ValueError("chi2_band: prob must be in (0, 1)")
    k = dof * n_runs
    if n_runs == 1 and int(dof) == dof and dof <= 1000:
        # one value's band (the figures' NIS panels): the closed form of filters.chi2, within 2e-12 of
        # scipy's quantiles for dof ≤ 1000, without scipy.stats's import (issue 41)
        from aidnav.filters.chi2 import chi2_isf  # lazy: only here (and small)

        return chi2_isf(int(dof), 0.5 * (1.0 + prob)), chi2_isf(int(dof), 0.5 * (1.0 - prob))
    # scipy.stats.chi2.ppf(q, k) is 2·gammaincinv(k/2, q) (the same numbers): scipy.special only, ~0.1 s
    # of import where scipy.stats takes ~0.4 s (the merge of every `aidnav run` campaign, issue 41)
    from scipy.special import gammaincinv  # lazy: scipy.special (NEES alone does not need it)

    lo = 2.0 * gammaincinv(0.5 * k, 0.5 * (1.0 - prob)) / n_runs
    hi = 2.0 * gammaincinv(0.5 * k, 0.5 * (1.0 + prob)) / n_runs
    return float(lo), float(hi)


def binom_ppf(q: float, n: int, p: float) -> int:
    """The ``q`` quantile of a binomial(n, p) count: the smallest k with P(X ≤ k) ≥ q
    (``scipy.stats.binom.ppf``; a test compares them), by bisection on scipy.special's ``bdtr``."""
    from scipy.special import bdtr  # lazy: scipy.special (scipy.stats: ~0.3 s more of import)

    if not 0.0 < q < 1.0:
        raise ValueError(f"binom_ppf: q must be in (0, 1) (got {q})")
    lo, hi = -1, int(n)  # P(X ≤ lo) < q (lo = −1: nothing), P(X ≤ hi) = 1 ≥ q
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if bdtr(mid, n, p) >= q:
            hi = mid
        else:
            lo = mid
    return hi


@dataclass
class ConsistencyReport:
    """Summary of NEES or NIS values against their χ² bands.

    kind : "NEES" or "NIS"; dof : n per value; n_runs : R; n_epochs : N; prob : band probability.
    epoch_mean : (N,) average over runs at each epoch; band : (lo, hi) for ``epoch_mean``.
    fraction_inside : fraction of epochs (with a finite mean) whose average is inside ``band``;
    fraction_min : the lowest fraction a consistent filter reaches with probability 1 − ``alpha``
        (binomial, epochs independent).
    mean : grand average over all finite values; mean_band : its (lo, hi) band (all values
        independent, dof·count degrees of freedom).
    fraction_above / fraction_below : epochs above / below the band.
    verdict : "consistent", "optimistic" (values too large: covariance too small) or "pessimistic".
    """

    kind: str
    dof: int
    n_runs: int
    n_epochs: int
    prob: float
    epoch_mean: np.ndarray
    band: tuple[float, float]
    fraction_inside: float
    fraction_above: float
    fraction_below: float
    fraction_min: float
    mean: float
    mean_band: tuple[float, float]
    n_values: int
    verdict: str

    @property
    def consistent(self) -> bool:
        return self.verdict == "consistent"

    def to_dict(self) -> dict:
        """JSON-ready summary (no per-epoch arrays)."""
        return {"kind": self.kind, "dof": self.dof, "runs": self.n_runs, "epochs": self.n_epochs,
                "prob": self.prob, "band": list(self.band), "fraction_inside": self.fraction_inside,
                "fraction_above": self.fraction_above, "fraction_below": self.fraction_below,
                "fraction_min": self.fraction_min, "mean": self.mean, "mean_band": list(self.mean_band),
                "values": self.n_values, "verdict": self.verdict}


def consistency_report(values: np.ndarray, dof: int, prob: float = 0.95, kind: str = "NEES",
                       alpha: float = 1e-3) -> ConsistencyReport:
    """Check NEES/NIS ``values`` ((N,) one run, or (R, N) R runs) of ``dof`` dimensions.

    Per epoch: the run-average against :func:`chi2_band` (dof, R, prob); the fraction inside should
    be about ``prob`` and a consistent filter falls below ``fraction_min`` (binomial quantile
    ``alpha``) with probability ≤ ``alpha`` when epochs are independent.
    Overall: the grand mean against the band for all finite values together.
    Verdict, two tests at level ``alpha`` (so a consistent filter with independent epochs is wrongly
    flagged with probability ≲ 2·alpha): "optimistic" if the grand mean is above its 1 − ``alpha``
    band, or the per-epoch fraction is below ``fraction_min`` with more epochs above than below the
    band (covariance too small); "pessimistic" in the mirrored case; else "consistent".
    ``mean_band`` (reported) is the ``prob`` band of the grand mean.
    """
    v = np.asarray(values, dtype=float)
    if v.ndim == 1:
        v = v[None, :]
    if v.ndim != 2:
        raise ValueError(f"consistency_report: values must be (N,) or (R, N), got shape {v.shape}")
    r, n_ep = v.shape
    with np.errstate(invalid="ignore"):
        cnt = np.sum(np.isfinite(v), axis=0)
        epoch_mean = np.where(cnt > 0, np.nansum(v, axis=0) / np.maximum(cnt, 1), np.nan)
    # an epoch with fewer than R finite runs gets the band of its own run count
    lo = np.full(n_ep, np.nan)
    hi = np.full(n_ep, np.nan)
    for c in np.unique(cnt[cnt > 0]):
        lo[cnt == c], hi[cnt == c] = chi2_band(dof, int(c), prob)
    fin = cnt > 0
    inside = fin & (epoch_mean >= lo) & (epoch_mean <= hi)
    above = fin & (epoch_mean > hi)
    below = fin & (epoch_mean < lo)
    allv = v[np.isfinite(v)]
    nv = int(allv.size)
    return report_from_counts(kind, dof, r, n_ep, prob, epoch_mean, int(fin.sum()), int(inside.sum()),
                              int(above.sum()), int(below.sum()), float(allv.mean()) if nv else np.nan, nv,
                              alpha)


def report_from_counts(kind: str, dof: int, r: int, n_ep: int, prob: float, epoch_mean: np.ndarray,
                       n_fin: int, n_in: int, n_above: int, n_below: int, mean: float, nv: int,
                       alpha: float = 1e-3) -> ConsistencyReport:
    """The :class:`ConsistencyReport` of :func:`consistency_report` from its counts: ``n_fin`` epochs with
    a finite average, ``n_in``/``n_above``/``n_below`` of them inside/above/below the band, the grand
    ``mean`` of the ``nv`` finite values (a streamed evaluation accumulates these chunk by chunk)."""
    band = chi2_band(dof, r, prob)
    f_in = float(n_in / n_fin) if n_fin else np.nan
    f_above = float(n_above / n_fin) if n_fin else np.nan
    f_below = float(n_below / n_fin) if n_fin else np.nan
    f_min = float(binom_ppf(alpha, n_fin, prob) / n_fin) if n_fin else np.nan
    mean_band = chi2_band(dof, nv, prob) if nv else (np.nan, np.nan)

    verdict = "consistent"
    if nv:
        t_lo, t_hi = chi2_band(dof, nv, 1.0 - alpha)  # the test, at level alpha
        if mean > t_hi or (f_in < f_min and f_above > f_below):
            verdict = "optimistic"
        elif mean < t_lo or (f_in < f_min and f_below >= f_above):
            verdict = "pessimistic"
    return ConsistencyReport(kind=kind, dof=int(dof), n_runs=r, n_epochs=n_ep, prob=prob,
                             epoch_mean=epoch_mean, band=band, fraction_inside=f_in,
                             fraction_above=f_above, fraction_below=f_below, fraction_min=f_min,
                             mean=mean, mean_band=mean_band, n_values=nv, verdict=verdict)
