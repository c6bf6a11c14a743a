"""Brent's root finder of the noise fit (aidnav.analysis.noise_fit.roots) against scipy.optimize.brentq."""

from __future__ import annotations

import math

import pytest
from scipy.optimize import brentq as scipy_brentq

from aidnav.analysis.noise_fit.roots import brentq

CASES = [
    (lambda x: x**3 - 2 * x - 5, 2.0, 3.0),  # Wallis's cubic
    (lambda x: math.cos(x) - x, 0.0, 1.0),
    (lambda x: math.exp(x) - 10.0, -5.0, 10.0),
    (lambda x: (x - 1e-3) * (x + 50.0) ** 2, -10.0, 1.0),  # flat far side
    (lambda x: math.atan(1e4 * (x - 0.3)), -1.0, 5.0),  # steep
    (lambda x: 1e-30 * (x - 7.0), 0.0, 1e3),  # tiny values
    (lambda x: x - 2.0 if x < 2.5 else 1.0, 0.0, 10.0),  # a jump
]


@pytest.mark.parametrize("i", range(len(CASES)))
@pytest.mark.parametrize("xtol, rtol", [(2e-12, 4 * 2.220446049250313e-16), (1e-4, 1e-4), (1e-6, 1e-4)])
def test_same_root_as_scipy(i, xtol, rtol):
    f, a, b = CASES[i]
    assert brentq(f, a, b, xtol=xtol, rtol=rtol) == scipy_brentq(f, a, b, xtol=xtol, rtol=rtol)
    assert brentq(f, b, a, xtol=xtol, rtol=rtol) == scipy_brentq(f, b, a, xtol=xtol, rtol=rtol)


def test_root_to_tolerance_and_endpoints():
    r = brentq(lambda x: x * x - 2.0, 0.0, 2.0)
    assert abs(r - math.sqrt(2.0)) <= 2e-12 + 4 * 2.220446049250313e-16 * math.sqrt(2.0)
    assert brentq(lambda x: x - 1.0, 1.0, 3.0) == 1.0
    assert brentq(lambda x: x - 3.0, 1.0, 3.0) == 3.0


def test_errors():
    with pytest.raises(ValueError, match="different signs"):
        brentq(lambda x: x * x + 1.0, -1.0, 1.0)
    with pytest.raises(ValueError, match="NaN"):
        brentq(lambda x: math.nan if x > 0.5 else -1.0, 0.0, 1.0)
    with pytest.raises(ValueError):
        brentq(lambda x: x, -1.0, 1.0, xtol=0.0)
    with pytest.raises(RuntimeError):
        brentq(lambda x: math.atan(x - 0.3), -1.0, 5.0, xtol=1e-15, maxiter=3)
