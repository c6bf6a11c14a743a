"""Covariance of overlapping Allan variance estimates under the noise model (exact for Gaussian noise).

It gives each estimate's equivalent degrees of freedom ν (within 1% of Greenhall's approximation for white
noise at m ≥ 64) and the correlations between octaves (about 0.5 for white noise, 0.9 for a random walk),
which are large and matter: ignoring them makes the intervals several times too narrow. The cost does not
depend on the number of samples (see the comment below).
"""

from __future__ import annotations

import numpy as np

from aidnav.analysis.noise_fit.model import model_avar
from aidnav.jit import njit

# ------------------------------------------------------- covariance of the Allan variance estimates
# For Gaussian noise the overlapping Allan variances are quadratic forms of the phase x (the running
# integral of the rate), so their covariances follow exactly from the model: with the second differences
# D_m(k) = x_{k+2m} − 2x_{k+m} + x_k and the phase structure function S(h) = E[(x(t+h) − x(t))²],
#   c₁₂(ℓ) = Cov(D_m₁(k), D_m₂(k+ℓ)) = −½ Σᵢ Σⱼ aᵢ aⱼ S(τ₀(ℓ + j m₂ − i m₁)),  a = (1, −2, 1),
#   Cov(σ̂²(τ₁), σ̂²(τ₂)) = 2 Σ_ℓ n(ℓ) c₁₂(ℓ)² / (4 τ₁² τ₂² M₁ M₂)   (Isserlis),
# with M = N + 1 − 2m terms per estimate and n(ℓ) the number of index pairs at lag ℓ. S for the model:
# white PM (Q) 2Q² (h ≠ 0), white FM N²|h|, Gauss-Markov 2σ²T²(|h|/T − 1 + e^(−|h|/T)); random-walk FM has
# no stationary phase increments, but second differences filter it (an intrinsic random function of
# order 1, generalised covariance K²|h|³/12), so it enters as S = −2·K²|h|³/12 = −K²|h|³/6.
#
# Cost. c₁₂ vanishes outside the core |ℓ| ≤ 2(m₁ + m₂) (without a Gauss-Markov term; with one, it decays
# as e^(−|ℓ|τ₀/T) beyond), and has kinks at the integers i m₁ − j m₂ inside. A short core (≤ EXACT_LAGS
# lags) is summed exactly over the integers, with S read from a table of its values at the integer lags
# (S is even and the arguments are integers, so one table serves every pair of cluster sizes). A longer
# core and the Gauss-Markov tails use the continuum form of the sum, ∫ n(ℓ) c₁₂(ℓ)² dℓ, by Gauss-Legendre
# quadrature on the smooth pieces between the kinks; its relative error falls as 1/m² for the white FM
# term (Euler-Maclaurin: the kinks of c₁₂ at integer lags; 1.2/m², about 1e-7 where the core is first
# integrated) and faster for the others (tests/analysis/test_characterise.py checks it against the exact
# sum). Nothing scales with the number of samples: n(ℓ) enters in closed form.
EXACT_LAGS = 6000.0  #: cores of c₁₂ up to this many lags are summed exactly
_XG = np.array([-0.9061798459386640, -0.5384693101056831, 0.0, 0.5384693101056831, 0.9061798459386640])
_WG = np.array([0.2369268850561891, 0.4786286704993665, 0.5688888888888889, 0.4786286704993665,
                0.2369268850561891])
_A2 = np.array([1.0, -2.0, 1.0])


@njit(cache=True, nogil=True)
def _phase_sf(h, coef, t_corr):
    a = abs(h)
    v = coef[1] * a - coef[3] * a * a * a / 6.0
    if coef[2] > 0.0:
        x = a / t_corr
        v += 2.0 * coef[2] * t_corr * t_corr * (x + np.expm1(-x))
    if a > 0.0:
        v += 2.0 * coef[0]
    return v


@njit(cache=True, nogil=True)
def _c12(lag, m1, m2, tau0, coef, t_corr):
    v = 0.0
    for i in range(3):
        for j in range(3):
            v += _A2[i] * _A2[j] * _phase_sf(tau0 * (lag + j * m2 - i * m1), coef, t_corr)
    return -0.5 * v


@njit(cache=True, nogil=True)
def _pair_count(lag, M1, M2):
    lo = max(0.0, -lag)
    hi = min(float(M1), M2 - lag)
    return max(0.0, hi - lo)


@njit(cache=True, nogil=True)
def _gauss_piece(a0, hh, m1, m2, M1, M2, tau0, coef, t_corr):
    """5-point Gauss-Legendre ∫ n(ℓ) c₁₂(ℓ)² dℓ over [a0, a0 + hh]."""
    s = 0.0
    for g in range(5):
        ell = a0 + 0.5 * hh * (_XG[g] + 1.0)
        c = _c12(ell, m1, m2, tau0, coef, t_corr)
        s += 0.5 * hh * _WG[g] * _pair_count(ell, M1, M2) * c * c
    return s


@njit(cache=True, nogil=True)
def _quad_lags(a, b, m1, m2, M1, M2, tau0, coef, t_corr, seg_max):
    """∫ n(ℓ) c₁₂(ℓ)² dℓ over [a, b] (5-point Gauss-Legendre on the smooth pieces between the kinks)."""
    if b <= a:
        return 0.0
    # break points: the ends, the kinks of n(ℓ) (0, M₂ − M₁) and of c₁₂ (i m₁ − j m₂), clipped and sorted
    pts = np.empty(13)
    pts[0] = a
    pts[1] = b
    pts[2] = 0.0
    pts[3] = float(M2 - M1)
    q = 4
    for i in range(3):
        for j in range(3):
            pts[q] = float(i * m1 - j * m2)
            q += 1
    for q in range(13):
        pts[q] = min(max(pts[q], a), b)
    for q in range(1, 13):  # insertion sort (13 values)
        v = pts[q]
        r = q - 1
        while r >= 0 and pts[r] > v:
            pts[r + 1] = pts[r]
            r -= 1
        pts[r + 1] = v
    s = 0.0
    for k in range(12):
        lo = pts[k]
        hi = pts[k + 1]
        if hi - lo <= 0.0:
            continue
        # graded sub-segments: seg_max next to both ends (Gauss-Markov transients at the kinks decay on
        # that scale), doubling towards the middle (the polynomial parts are exact on any segment)
        mid = 0.5 * (lo + hi)
        nl = 0
        h = seg_max
        x = lo + h
        while x < mid:
            nl += 1
            h *= 2.0
            x += h
        sub = np.empty(2 * nl + 2)
        sub[0] = lo
        sub[2 * nl + 1] = hi
        h = seg_max
        x = lo + h
        for i in range(nl):
            sub[1 + i] = x
            sub[2 * nl - i] = lo + hi - x
            h *= 2.0
            x += h
        for i in range(2 * nl + 1):
            a0 = sub[i]
            hh = sub[i + 1] - a0
            if hh <= 0.0:
                continue
            s += _gauss_piece(a0, hh, m1, m2, M1, M2, tau0, coef, t_corr)
    return s


@njit(cache=True, nogil=True)
def _core_sum(i_lo, i_hi, m1, m2, M1, M2, S, tau0, coef, t_corr):
    """Σ_ℓ n(ℓ) c₁₂(ℓ)² over the integer lags i_lo..i_hi, with S[|h|] = S(τ₀ h) from the table (computed
    beyond its end)."""
    s = 0.0
    ns = S.shape[0]
    for ell in range(i_lo, i_hi + 1):
        v = 0.0
        for i in range(3):
            for j in range(3):
                h = abs(ell + j * m2 - i * m1)
                v += _A2[i] * _A2[j] * (S[h] if h < ns else _phase_sf(tau0 * float(h), coef, t_corr))
        c = -0.5 * v
        s += _pair_count(float(ell), M1, M2) * c * c
    return s


@njit(cache=True, nogil=True)
def _lag_sum(m1, m2, M1, M2, tau0, coef, t_corr, tail, S):
    """Σ_ℓ n(ℓ) c₁₂(ℓ)² over the integer lags where c₁₂ ≠ 0 (plus ``tail`` lags of Gauss-Markov decay).
    The core |ℓ| ≲ 2(m₁ + m₂), where c₁₂ has kinks at the integers i m₁ − j m₂, is summed exactly when
    short (``S``: the structure function at the integer lags, long enough for it); longer cores and the
    smooth exponential tails are integrated (the midpoint rule of the sum)."""
    lo = max(-2.0 * m2 - tail, -(M1 - 1.0))
    hi = min(2.0 * m1 + tail, M2 - 1.0)
    c_lo = max(lo, -2.0 * m2 - 1.0)
    c_hi = min(hi, 2.0 * m1 + 1.0)
    seg_max = max(16.0, t_corr / tau0 / 4.0) if coef[2] > 0.0 else 1e18  # pieces are polynomial without GM
    if c_hi - c_lo > EXACT_LAGS:
        return _quad_lags(lo, hi, m1, m2, M1, M2, tau0, coef, t_corr, seg_max)
    i_lo = int(np.floor(c_lo))
    i_hi = int(np.ceil(c_hi))
    s = _core_sum(i_lo, i_hi, int(m1), int(m2), M1, M2, S, tau0, coef, t_corr)
    s += _quad_lags(lo - 0.5, i_lo - 0.5, m1, m2, M1, M2, tau0, coef, t_corr, seg_max)
    s += _quad_lags(i_hi + 0.5, hi + 0.5, m1, m2, M1, M2, tau0, coef, t_corr, seg_max)
    return s


@njit(cache=True, nogil=True)
def avar_cov_nb(m, n_phase, tau0, coef, t_corr):
    """Covariance matrix of the overlapping Allan variance estimates at cluster sizes m (model coef, T)."""
    k = m.shape[0]
    C = np.zeros((k, k))
    tail = 12.0 * t_corr / tau0 if coef[2] > 0.0 else 0.0  # e^(−24) of the squared covariance left
    # table of S at the integer lags that the exactly summed cores reach (|h| ≤ 2(m₁ + m₂) + 1)
    h_max = 0
    for p in range(k):
        for r in range(p, k):
            if 2.0 * (m[p] + m[r]) + 2.0 <= EXACT_LAGS:
                h_max = max(h_max, int(2.0 * (m[p] + m[r])) + 2)
    S = np.empty(h_max + 1)
    for h in range(h_max + 1):
        S[h] = _phase_sf(tau0 * float(h), coef, t_corr)
    for p in range(k):
        for r in range(p, k):
            m1 = float(m[p])
            m2 = float(m[r])
            M1 = n_phase - 2.0 * m1
            M2 = n_phase - 2.0 * m2
            t1 = m1 * tau0
            t2 = m2 * tau0
            v = 2.0 * _lag_sum(m1, m2, M1, M2, tau0, coef, t_corr, tail, S) / (
                4.0 * t1 * t1 * t2 * t2 * M1 * M2)
            C[p, r] = v
            C[r, p] = v
    return C


@njit(cache=True, nogil=True)
def avar_var_nb(m, n_phase, tau0, coef, t_corr):
    """The diagonal of :func:`avar_cov_nb` (the variances of the estimates), each entry the same number:
    the same lag sums, with the table of S over the lags the diagonal's exact cores reach."""
    k = m.shape[0]
    out = np.zeros(k)
    tail = 12.0 * t_corr / tau0 if coef[2] > 0.0 else 0.0
    h_max = 0
    for p in range(k):
        if 4.0 * m[p] + 2.0 <= EXACT_LAGS:
            h_max = max(h_max, int(4.0 * m[p]) + 2)
    S = np.empty(h_max + 1)
    for h in range(h_max + 1):
        S[h] = _phase_sf(tau0 * float(h), coef, t_corr)
    for p in range(k):
        m1 = float(m[p])
        M1 = n_phase - 2.0 * m1
        t1 = m1 * tau0
        out[p] = 2.0 * _lag_sum(m1, m1, M1, M1, tau0, coef, t_corr, tail, S) / (
            4.0 * t1 * t1 * t1 * t1 * M1 * M1)
    return out


def estimate_edf(tau, m, n_phase, coef, t_corr):
    """ν of :func:`estimate_stats` alone (the variances only: the same numbers, without the covariances)."""
    tau0 = float(tau[0] / m[0])
    var = avar_var_nb(np.asarray(m, np.float64), float(n_phase), tau0, np.asarray(coef, float),
                       float(t_corr))
    avar = model_avar(tau, coef, t_corr)
    return 2.0 * avar**2 / np.maximum(var, 1e-300)


def estimate_stats(tau, m, n_phase, coef, t_corr):
    """EDF of each Allan variance estimate and the whitener of their correlation, for the model (coef, T).

    ν_j = 2 σ²(τ_j)² / Var(σ̂²(τ_j)) from the exact covariance (see the comment above); the correlation of
    the logs is taken as that of the variances (delta method). Returns (ν, L⁻¹)."""
    tau0 = float(tau[0] / m[0])
    C = avar_cov_nb(np.asarray(m, np.float64), float(n_phase), tau0, np.asarray(coef, float), float(t_corr))
    avar = model_avar(tau, coef, t_corr)
    var = np.maximum(np.diag(C), 1e-300)
    nu = 2.0 * avar**2 / var
    sd = np.sqrt(var)
    R = C / np.outer(sd, sd)
    w, V = np.linalg.eigh(0.5 * (R + R.T))
    w = np.maximum(w, 1e-6)
    R = (V * w) @ V.T
    d = np.sqrt(np.diag(R))
    R = R / np.outer(d, d)
    L = np.linalg.cholesky(R)
    return nu, np.ascontiguousarray(np.linalg.inv(L))
