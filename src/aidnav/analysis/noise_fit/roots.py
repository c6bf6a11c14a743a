"""Brent's root finder (inverse quadratic interpolation with bisection safeguards), without scipy.

The fit's profile-likelihood intervals need a bracketing root finder; ``scipy.optimize`` costs ~0.2 s of
``aidnav characterise``'s start-up (it imports scipy.linalg). :func:`brentq` takes the steps of
``scipy.optimize.brentq`` (Brent 1973, *Algorithms for minimization without derivatives*, ch. 4, in the
arrangement SciPy uses), so it returns the same root (tests/analysis/test_noise_fit_roots.py).
"""

from __future__ import annotations

import math
from collections.abc import Callable

__all__ = ["brentq"]

_EPS = 2.220446049250313e-16


def brentq(f: Callable[[float], float], a: float, b: float, xtol: float = 2e-12, rtol: float = 4 * _EPS,
           maxiter: int = 100) -> float:
    """A root of ``f`` in [a, b], where f(a) and f(b) have opposite signs, to within xtol + rtol·|x|.

    Raises ValueError when the signs are not opposite, when f returns NaN or a tolerance is too small,
    RuntimeError when ``maxiter`` iterations do not converge (as scipy.optimize.brentq)."""
    if xtol <= 0:
        raise ValueError(f"xtol too small ({xtol:g} <= 0)")
    if rtol < 4 * _EPS:
        raise ValueError(f"rtol too small ({rtol:g} < {4 * _EPS:g})")

    def fx(x):
        v = f(x)
        if math.isnan(v):
            raise ValueError(f"the function value at x={x} is NaN")
        return v

    xpre, xcur = float(a), float(b)
    fpre, fcur = fx(xpre), fx(xcur)
    if fpre == 0:
        return xpre
    if fcur == 0:
        return xcur
    if math.copysign(1.0, fpre) == math.copysign(1.0, fcur):
        raise ValueError("f(a) and f(b) must have different signs")
    xblk = fblk = spre = scur = 0.0
    for _ in range(maxiter):
        if fpre != 0 and fcur != 0 and math.copysign(1.0, fpre) != math.copysign(1.0, fcur):
            xblk, fblk = xpre, fpre  # the bracket is [xcur, xblk]
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):  # xcur: the best estimate so far
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = (xtol + rtol * abs(xcur)) / 2
        sbis = (xblk - xcur) / 2
        if fcur == 0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:  # secant
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:  # inverse quadratic interpolation
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2 * abs(stry) < min(abs(spre), 3 * abs(sbis) - delta):  # a good short step
                spre, scur = scur, stry
            else:
                spre = scur = sbis
        else:
            spre = scur = sbis
        xpre, fpre = xcur, fcur
        xcur += scur if abs(scur) > delta else (delta if sbis > 0 else -delta)
        fcur = fx(xcur)
    raise RuntimeError(f"brentq: no convergence in {maxiter} iterations (last x = {xcur})")
