"""The noise model of the characterisation: unit constants, the Gauss-Markov Allan variance, the four-term
model and the log-chi-square moments.

Per axis, the Allan variance is the sum of the standard terms (IEEE Std 952-1997, Annex C; El-Sheimy, Hou &
Niu, "Analysis and modeling of inertial sensors using Allan variance", IEEE Trans. Instrum. Meas. 57(1),
2008, Table I):

    σ²(τ) = 3Q²/τ²                    quantisation (slope −1 in ADEV)
          + N²/τ                      white rate noise: ARW / VRW N (slope −1/2)
          + σ_GM² g(τ/T)              bias instability as a first-order Gauss-Markov process (σ_GM, T)
          + K²τ/3                     rate / acceleration random walk K (slope +1/2)

    g(x) = (2/x)·[1 − (3 − 4e^{−x} + e^{−2x})/(2x)]   (El-Sheimy 2008, "correlated noise", with the
    driving density q_c² = 2σ_GM²/T). g rises as 2x/3 (RRW-like) for τ ≪ T, falls as 2/x (white-like)
    for τ ≫ T and peaks at x = 1.8926 where √g = 0.6174.

Bias instability ↔ Gauss-Markov. The filter and the simulator (:mod:`aidnav.sim.imu`) model the bias
instability as a first-order Gauss-Markov process (σ_GM, T); data sheets quote the IEEE 952 bias
instability B, defined by the flicker floor of the ADEV, σ_floor = √(2 ln 2/π)·B = 0.6643·B. The fit
gives (σ_GM, T) and reports B as the flicker floor with the height of the GM's ADEV peak, at τ = 1.8926·T:

    B = 0.6174/0.6643 · σ_GM = 0.9294 · σ_GM,      σ_GM = 1.0760 · B,   T = τ_floor / 1.8926.

Units: SI inside (rad/s, m/s²); the constants below convert to the boundary units of the outputs.
"""

from __future__ import annotations

import math

import numpy as np

# ------------------------------------------------------------------------------------------ constants
GM_PEAK_X = 1.8926178354517893  #: τ of the Gauss-Markov ADEV peak / T
GM_PEAK_ADEV = 0.6173642831444415  #: peak ADEV of a Gauss-Markov process / σ_GM
FLICKER_ADEV = math.sqrt(2.0 * math.log(2.0) / math.pi)  #: ADEV of a flicker floor / B (0.6643)
B_PER_GM_SIGMA = GM_PEAK_ADEV / FLICKER_ADEV  #: IEEE 952 bias instability B per σ_GM (0.9294)


#: the six axes, in the order of the rates (M, 6) and of :attr:`Characterisation.axes`
AXES = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")


# ----------------------------------------------------------------------------------- model pieces
TERM_ORDER = ("Q", "N", "GM", "K")  #: order of the model coefficients (Q², N², σ_GM², K²)
#: Taylor coefficients of the unit Gauss-Markov Allan variance g(x) = Σ c_k x^(k+1) (x = τ/T < 0.05, where
#: the closed form cancels): c_k = (−1)^k (2^(k+3) − 4) / (k+3)!, i.e. 2/3, −1/2, 7/30, −1/12, …
GM_SERIES = (2 / 3, -1 / 2, 7 / 30, -1 / 12, 31 / 1260, -1 / 160, 127 / 90720, -17 / 60480, 73 / 1425600,
              -31 / 3628800)


def gm_shape(x: np.ndarray) -> np.ndarray:
    """Allan variance of a unit-σ first-order Gauss-Markov process at τ = x·T (a series below x = 0.05)."""
    x = np.asarray(x, dtype=float)
    out = np.empty_like(x)
    s = x < 0.05
    xs = x[s]
    acc = np.zeros_like(xs)
    for c in GM_SERIES[::-1]:  # Horner: Σ c_k x^(k+1)
        acc = (acc + c) * xs
    out[s] = acc
    xl = x[~s]
    out[~s] = (2.0 / xl) * (1.0 - (3.0 - 4.0 * np.exp(-xl) + np.exp(-2.0 * xl)) / (2.0 * xl))
    return out


def gm_avar(tau, sigma: float, t_corr: float) -> np.ndarray:
    """Allan variance of a first-order Gauss-Markov rate error with stationary σ and correlation time T.

    tau [s], sigma [u], t_corr [s] → σ²(τ) [u²] (El-Sheimy et al. 2008, correlated noise)."""
    return sigma**2 * gm_shape(np.asarray(tau, float) / t_corr)


def model_avar(tau, coef, t_corr: float) -> np.ndarray:
    """Allan variance of the four-term model: coef = (Q², N², σ_GM², K²) [SI], t_corr = T [s]."""
    tau = np.asarray(tau, float)
    q2, n2, s2, k2 = coef
    return 3.0 * q2 / tau**2 + n2 / tau + s2 * gm_shape(tau / t_corr) + k2 * tau / 3.0


def logchi2_moments(nu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation of ln(χ²_ν/ν)."""
    from scipy.special import (  # lazy: scipy.special: ~0.1 s to import; the warm-up loads it
        digamma,
        polygamma,
    )

    h = 0.5 * np.asarray(nu, float)
    return digamma(h) - np.log(h), np.sqrt(polygamma(1, h))
