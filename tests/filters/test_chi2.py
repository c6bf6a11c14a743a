"""χ² gate thresholds without scipy (aidnav.filters.chi2) against scipy.special, and closed forms."""

from __future__ import annotations

import math

import pytest
from scipy.special import chdtrc, chdtri

from aidnav.filters.chi2 import chi2_isf, chi2_sf

ALPHAS = [1e-15, 1e-12, 1e-9, 1e-6, 1e-4, 1e-3, 0.01, 0.05, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99]
DOFS = list(range(1, 13)) + [20, 31, 64, 101]


@pytest.mark.parametrize("dof", DOFS)
def test_quantile_matches_scipy(dof):
    for a in ALPHAS:
        assert chi2_isf(dof, a) == pytest.approx(chdtri(dof, a), rel=1e-12, abs=0), (dof, a)


@pytest.mark.parametrize("dof", DOFS)
def test_survival_matches_scipy(dof):
    for x in (1e-3, 0.1, 1.0, 5.0, 20.0, 80.0, 300.0):
        assert chi2_sf(x, dof) == pytest.approx(chdtrc(dof, x), rel=1e-12, abs=1e-300), (dof, x)


def test_closed_forms():
    # dof 2: Q = exp(−x/2) → x = −2 ln α; dof 1: Q = erfc(√(x/2)); the 3σ gate of one dof is 9
    for a in (1e-9, 0.01, 0.5):
        assert chi2_isf(2, a) == pytest.approx(-2.0 * math.log(a), rel=1e-14)
    assert chi2_isf(1, math.erfc(3.0 / math.sqrt(2.0))) == pytest.approx(9.0, rel=1e-14)
    assert chi2_sf(0.0, 3) == 1.0


@pytest.mark.parametrize("dof, alpha", [(0, 0.1), (1.5, 0.1), (3, 0.0), (3, 1.0), (3, -0.1)])
def test_bad_arguments(dof, alpha):
    with pytest.raises(ValueError):
        chi2_isf(dof, alpha)
