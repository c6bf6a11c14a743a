"""Re-initialisation of the filter engine (:func:`aidnav.filters.gate.policy_update`): the χ² band of
an NIS window and the scaling of the navigation block of P that makes a triggering innovation consistent."""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit

from .layout import DV, NAV


@njit(cache=True)
def chi2_quantile(k, z):
    """Wilson–Hilferty approximation of the χ²(k) quantile at the standard normal quantile z
    (at the 99.9 % point it is above the exact quantile by 0.6 % at k = 10, 0.2 % at k = 30)."""
    a = 2.0 / (9.0 * k)
    return k * (1.0 - a + z * np.sqrt(a)) ** 3


@njit(cache=True)
def nis_of(x, P, H, R, z):
    """NIS νᵀ S⁻¹ ν of z − H x with S = H P Hᵀ + R."""
    nu = z - H @ x
    return nu @ np.linalg.solve(H @ P @ H.T + R, nu)


@njit(cache=True)
def inflate_nav(x, P, H, R, z):
    """:func:`inflate` of the navigation block alone (no calibration state takes part)."""
    return inflate(x, P, H, R, z, np.zeros((0, 2)))


@njit(cache=True)
def inflate(x, P, H, R, z, cal):
    """Re-initialisation of the navigation block and the calibration states ``cal`` (K, 2 or 3): rows
    (index in P, prior variance[, 0: only an NIS window's scaling repairs it]): P ← D P D with D = √α on
    δv and δp, √min(α, (π/2)² / P_ii) on φ (attitude σ's never grown past 90°) and √min(α, prior / P_ii)
    on each calibration state of ``cal`` (grown at most back to its prior: a time offset, velocity delay
    or mounting that converged to a wrong value under a wrong navigation solution is part of the
    repair) — grown as P + G P G, G = (D² − I)^½ (:func:`_scaled_nav`: D P D where the factors are equal),
    so no combination of the states is known better than before; α ≥ 1 the
    smallest with NIS(ν, H P(α) Hᵀ + R) ≤ m (bisection in log α up to 1e12). Returns α."""
    m = z.shape[0]
    if nis_of(x, P, H, R, z) <= m:
        return 1.0
    P0 = P.copy()
    lo, hi = 0.0, np.log(1e12)
    for _ in range(50):
        a = np.exp(0.5 * (lo + hi))
        if nis_of(x, _scaled_nav(P0, a, cal, False), H, R, z) > m:
            lo = np.log(a)
        else:
            hi = np.log(a)
    a = np.exp(hi)
    P[:, :] = _scaled_nav(P0, a, cal, False)
    return a


@njit(cache=True)
def scale_nav(P, a, cal):
    """P grown as by :func:`inflate` for the given factor ``a`` (≥ 1): the re-initialisation of an NIS
    window, whose factor is the window's mean NIS per degree of freedom."""
    P[:, :] = _scaled_nav(P.copy(), max(a, 1.0), cal, True)


@njit(cache=True)
def _scaled_nav(P0, a, cal, window):
    """P0 grown by the factor a (:func:`inflate`): P0 + G P0 G, G = (D² − I)^½ — a scaled copy of P0
    added (positive semi-definite), so P0 grows in the Loewner order and no combination of the states is
    known better than before; each variance is the one of D P0 D, and where the factors are equal (the
    navigation block's δv, δp) so is every covariance. The congruence D P0 D itself does not grow P0:
    with unequal factors on two strongly correlated states (at rest, the tilt
    grown by α and the accelerometer bias at most to its prior, their correlation −1 through the one
    observed sum φ·g + b) it keeps the correlation and changes its slope, a new exact relation between
    the two that the next fixes turn into a tilt σ far below what the sensors allow (issue 35, session 12:
    0.25° against the bound of 0.71°, the presets' parked cell). A row of ``cal`` with a third column of
    0 (the IMU's sensor errors, :func:`aidnav.filters.loose._reinit_cal`) is scaled only by an NIS
    ``window``'s factor:
    the mean NIS of N fixes says the whole covariance is λ too small, while the factor that makes one
    rejected innovation consistent (up to 1e12, a jump of the navigation) says nothing of the sensors."""
    d = np.ones(P0.shape[0])
    for i in range(min(NAV, P0.shape[0])):  # a state subset's first states (satcom: never triggered)
        d[i] = np.sqrt(a) if i >= DV else np.sqrt(min(a, max(1.0, (0.5 * np.pi) ** 2 / max(P0[i, i], 1e-30))))
    for r in range(cal.shape[0]):
        if not window and cal.shape[1] > 2 and cal[r, 2] == 0.0:
            continue
        i = int(cal[r, 0])
        d[i] = np.sqrt(min(a, max(1.0, cal[r, 1] / max(P0[i, i], 1e-30))))
    g = np.sqrt(d * d - 1.0)
    return P0 + P0 * np.outer(g, g)
