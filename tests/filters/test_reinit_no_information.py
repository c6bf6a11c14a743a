"""A re-initialisation inflates, it never informs (issue 35, session 12: parked then driving, presets).

At rest with position fixes the tilt and the accelerometer bias are seen only as their sum: the filter's
P then holds them almost perfectly anti-correlated, each with a σ near its prior and the sum known. The
NIS window's re-initialisation grows the navigation block by its factor α and each sensor error at most
back to its prior. Done as the congruence D P D with unequal factors on those two states, it keeps their
correlation of −1 but changes its slope: the scaled P says the tilt is *exactly* a different multiple of
the bias, and the next fixes, which give the sum, then fix both — the tilt σ fell from 0.71° (the bound of
one observed sum of the two priors) to 0.25° with the error at 1.5° (aircraft preset, seed 1), and the
preset cells' roll/pitch 3σ coverage to 66–76 %. A re-initialisation must not lower the variance of any
combination of the states (P_new − P_old positive semi-definite): it adds variance, never information.

Closed forms, no filter run: the re-initialised P against the old one in the Loewner order, and the tilt σ
after one exact observation of the sum against the bound of the two priors.
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.filters.reinit import inflate, scale_nav

DEG = np.pi / 180.0
S_TILT, S_BIAS = 2.0 * DEG, 0.762 * DEG  # the default model's priors (the bias as its tilt equivalent)


def _parked_p():
    """P of (φ_E, δv (3), δp (3), dummies to 9, b_a,x) after the sum φ_E + b was observed to 1e-4 rad:
    the first state the tilt, the tenth the accelerometer bias (as an angle)."""
    n = 10
    P = np.diag(np.r_[S_TILT ** 2, 1e-4 * np.ones(8), S_BIAS ** 2])
    H = np.zeros((1, n))
    H[0, 0], H[0, 9] = 1.0, 1.0
    S = H @ P @ H.T + 1e-8
    K = P @ H.T / S
    return P - K @ H @ P


@pytest.mark.parametrize("alpha", [2.0, 9.0, 100.0])
def test_window_reinitialisation_adds_no_information(alpha):
    P = _parked_p()
    Pn = P.copy()
    scale_nav(Pn, alpha, np.array([[9.0, S_BIAS ** 2, 0.0]]))
    assert np.linalg.eigvalsh(Pn - P).min() >= -1e-15  # no combination's variance fell
    assert Pn[0, 0] == pytest.approx(alpha * P[0, 0])  # the navigation block grown by α
    assert Pn[9, 9] <= S_BIAS ** 2 * (1 + 1e-12)  # the bias at most back to its prior
    # the next fix gives the sum again: the tilt cannot be known better than one sum of the two priors
    H = np.zeros((1, 10))
    H[0, 0], H[0, 9] = 1.0, 1.0
    K = Pn @ H.T / (H @ Pn @ H.T + 1e-8)
    tilt = np.sqrt((Pn - K @ H @ Pn)[0, 0])
    bound = 1.0 / np.sqrt(1.0 / S_TILT ** 2 + 1.0 / S_BIAS ** 2)
    assert tilt >= 0.97 * bound, (tilt / DEG, bound / DEG)


def test_rejection_reinitialisation_adds_no_information():
    P = _parked_p()
    Pn = P.copy()
    H = np.zeros((3, 10))
    H[:, 6:9] = np.eye(3)
    a = inflate(np.zeros(10), Pn, H, 1e-4 * np.eye(3), np.array([1.0, -2.0, 0.5]),
                np.array([[9.0, S_BIAS ** 2, 1.0]]))
    assert a > 1.0
    assert np.linalg.eigvalsh(Pn - P).min() >= -1e-15
