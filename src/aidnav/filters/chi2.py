"""Chi-square gate thresholds without scipy: the upper quantile of χ² with an integer number of degrees
of freedom (``scipy.special.chdtri``), which every filter needs once per run to set its gates.

Importing scipy.special costs ~0.1 s of every command's start-up; for an integer dof m the survival
function has a closed form (Abramowitz & Stegun 26.4.4–26.4.5), with y = x/2:

* m even: Q(x) = e^(−y) Σ_{j=0}^{m/2−1} y^j / j!
* m odd:  Q(x) = erfc(√y) + e^(−y) Σ_{j=1}^{(m−1)/2} y^(j−1/2) / Γ(j + 1/2)

Both are sums of positive terms, accurate to a few ulps in the upper tail where gates live; the quantile
is found by Newton's method on ln Q (log-concave) inside a bisection bracket.
"""

from __future__ import annotations

import math

__all__ = ["chi2_sf", "chi2_isf"]


def chi2_sf(x: float, dof: int) -> float:
    """P(χ²_dof > x) for an integer ``dof`` ≥ 1 (scipy.special.chdtrc)."""
    if x <= 0.0:
        return 1.0
    y = 0.5 * x
    ly = math.log(y)
    if dof % 2 == 0:
        s, j0, a0 = 0.0, 0, 0.0  # terms y^j / j!, j = 0 … dof/2 − 1
    else:
        s, j0, a0 = math.erfc(math.sqrt(y)), 1, 0.5  # terms y^(j−1/2) / Γ(j + 1/2), j = 1 … (dof−1)/2
    for j in range(j0, (dof + 1) // 2 if dof % 2 else dof // 2):
        s += math.exp((j - a0) * ly - math.lgamma(j - a0 + 1.0) - y)
    return s


def _log_pdf(x: float, dof: int) -> float:
    h = 0.5 * dof
    return (h - 1.0) * math.log(x) - 0.5 * x - h * math.log(2.0) - math.lgamma(h)


def chi2_isf(dof: int, alpha: float) -> float:
    """x with P(χ²_dof > x) = alpha: the gate of a test with false-alarm probability ``alpha``
    (scipy.special.chdtri(dof, alpha)); ``dof`` a positive integer, 0 < alpha < 1."""
    if int(dof) != dof or dof < 1:
        raise ValueError(f"chi2_isf: dof must be a positive integer (got {dof})")
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"chi2_isf: alpha must be in (0, 1) (got {alpha})")
    dof = int(dof)
    lo, hi = 0.0, max(1.0, float(dof))
    while chi2_sf(hi, dof) > alpha:
        lo, hi = hi, 2.0 * hi
    x = 0.5 * (lo + hi)
    target = math.log(alpha)
    for _ in range(200):
        q = chi2_sf(x, dof)
        if q > alpha:
            lo = x
        else:
            hi = x
        # Newton on ln Q(x) = ln alpha: d ln Q / dx = −f(x) / Q(x)
        step = (math.log(q) - target) * math.exp(math.log(q) - _log_pdf(x, dof)) if q > 0 else -math.inf
        new = x + step
        if not lo < new < hi:
            new = 0.5 * (lo + hi)
        if abs(new - x) <= 4e-16 * x or hi - lo <= 4e-16 * hi:
            return new
        x = new
    return x
