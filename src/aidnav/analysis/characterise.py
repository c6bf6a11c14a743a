"""IMU noise characterisation: Allan deviation of a static log → fitted noise terms → filter settings.

Frames and units. Input increments Δθ [rad], Δv [m/s] (body RFU, :class:`aidnav.data.ImuData`) or rates
[rad/s], [m/s²] on arrays. Inside, everything is SI; the results are given back in the boundary units of
``CONVENTIONS.md``: ARW [deg/√h], VRW [m/s/√h], gyro bias instability [deg/h], accelerometer bias
instability [µg], rate random walk [deg/h/√h], acceleration random walk [µg/√h], correlation times [s],
quantisation noise coefficient Q [rad] / [m/s] (IEEE 952: σ² = 3Q²/τ²; quantum = √12·Q).

Uniform sampling. The Allan deviation needs uniform samples. Increments with their own Δt (jittered time
stamps) are put on a uniform grid of the median interval by **cumulative-sum interpolation**: the
cumulative angle (velocity) at the sample times is interpolated linearly (constant rate within each
interval, as the increment model says) to the grid points and differenced, so no angle is lost or
counted twice. Averaging mixes neighbouring samples, which lowers the Allan variance at m grid intervals
by about 1/(6m) of its white part; when a log is resampled the fit therefore starts at the m where that
bias is below a quarter of the estimate's scatter (:func:`resampled_min_m`: 64 for a 2-h log at 100 Hz,
16 for half a minute; it says so, and quantisation is then out of reach). A gap (an interval longer
than 1.5 × the median) is never bridged: the longest gap-free part is analysed and the gap reported.

Static, motion, vibration (:func:`static_check`, :func:`characterise_imu`). Motion (driving, turning,
tilting) is never analysed: the longest static part is, as with gaps, and the motion is reported with
its time and size; with ``static`` (``--static START:END``) the same holds inside the chosen part. A
slow motion (a small, short rotation: someone leaning on a parked car) is kept and reported as a
warning, with the physics of its bounded effect. Vibration (zero-mean, a large sample spread, often at
one frequency: an engine) is not motion: it is reported per axis (std of the sensor's samples, the
dominant frequency: :func:`vibration_report`) and shows in the Allan deviation at the shortest τ,
which the fit then leaves out.

Short logs (:func:`fit_allan`, ``white_only``). With fewer than ``MIN_FULL_POINTS`` τ to fit, only the
white terms (quantisation and ARW / VRW) are fitted, on the short-τ part where they describe the curve
(from the shortest 3 τ they fit, extended upwards while they still do); the bias instability, its
correlation time and the random walk are reported as not resolvable, and the ``imu:`` section takes grade
defaults for them, saying so. Where no τ range is white noise (vibration or disturbance everywhere),
the white term is not resolved and its upper bound min(σ(τ)·√τ) is given.

Model. Per axis, the Allan variance is fitted with the sum of the standard terms (IEEE Std 952-1997,
Annex C; El-Sheimy, Hou & Niu, "Analysis and modeling of inertial sensors using Allan variance", IEEE
Trans. Instrum. Meas. 57(1), 2008, Table I):

    σ²(τ) = 3Q²/τ²                    quantisation (slope −1 in ADEV)
          + N²/τ                      white rate noise: ARW / VRW N (slope −1/2)
          + σ_GM² g(τ/T)              bias instability as a first-order Gauss-Markov process (σ_GM, T)
          + K²τ/3                     rate / acceleration random walk K (slope +1/2)

    g(x) = (2/x)·[1 − (3 − 4e^{−x} + e^{−2x})/(2x)]   (El-Sheimy 2008, "correlated noise", with the
    driving density q_c² = 2σ_GM²/T). g rises as 2x/3 (RRW-like) for τ ≪ T, falls as 2/x (white-like)
    for τ ≫ T and peaks at x = 1.8926 where √g = 0.6174.

Bias instability ↔ Gauss-Markov. The filter (``imu:`` section) and the simulator (:mod:`aidnav.sim.imu`)
model the bias instability as a first-order Gauss-Markov process (σ_GM, T); data sheets quote the
IEEE 952 bias instability B, defined by the flicker floor of the ADEV, σ_floor = √(2 ln 2/π)·B =
0.6643·B. This module fits (σ_GM, T) directly and reports B as the flicker floor that has the same
height as the GM's ADEV peak, at τ = 1.8926·T:

    B = 0.6174/0.6643 · σ_GM = 0.9294 · σ_GM,      σ_GM = 1.0760 · B,   T = τ_floor / 1.8926.

The same rule converts a data-sheet B and the τ of its ADEV minimum into filter settings.

Likelihood and confidence intervals, from the number of clusters. For Gaussian noise each overlapping
Allan variance is a quadratic form of the phase, so the covariance of the estimates at all τ follows
exactly from the model and from the number of terms M = N + 1 − 2m behind each (Isserlis' theorem; see
``_avar_cov_nb``). It gives each estimate's equivalent degrees of freedom ν (within 1% of Greenhall's
``allantools.edf_greenhall`` for white noise at m ≥ 64) and the correlations between octaves (about 0.5
for white noise, 0.9 for a random walk), which are large and matter: ignoring them makes the intervals
several times too narrow. The fit minimises the correlated (whitened) sum of squares of
(ln σ̂² − E ln(χ²_ν/ν) − ln σ²_model)/sd(ln(χ²_ν/ν)) over Q², N², σ², K² ≥ 0 and ln T (peak of the
GM between max(10 τ_min, 2 s) and the longest fitted τ), with ν and the correlations re-evaluated at the
fit three times. τ with fewer than three independent clusters are shown but not fitted. Each term's 95%
interval is a profile-likelihood interval (rise of the minimum by χ²₁(0.95) = 3.84, times the reduced
χ² when that exceeds 1). On simulated logs the whitened residuals have unit variance and the minimum at
the true parameters follows χ²₅ (tests/analysis/test_characterise.py, benchmarks/characterise.py).

Which terms are reported. All four terms stay in the model (dropping one that the data cannot separate
from another would bias the other's interval). A term other than the white noise is reported ("fitted",
with its interval) only when (i) its interval excludes zero and spans at most a factor ``MAX_CI_RATIO``
in deviation units, and (ii) removing it raises the minimum by more than the ``DETECT_PROB`` = 99% point
of χ² (1 degree of freedom; 2 for the Gauss-Markov σ and T together). T is reported when its own
interval is closed and within a factor ``MAX_CI_RATIO``. Otherwise the term is "not resolved": no
value, only the ends of its interval (an upper bound, or none). The ``imu:`` section then takes the grade
default for it and says so.

Speed (3.6 million samples per axis; benchmarks/characterise.py --speed). allantools computes the
overlapping ADEV from each axis's phase, formed once in place (:func:`aidnav.analysis.allan.allan_deviation`);
the axes run in threads, each Allan deviation followed by its fit (the numba kernels release the GIL),
with glibc keeping allantools' large temporaries for reuse. The covariance of the estimates sums the
short cores exactly over a table of the structure function and integrates long cores and tails in
their continuum form (cost independent of the number of samples). The libraries are imported while the
log is read.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numba import njit

from aidnav.data import ImuData
from aidnav.nav.earth import G0

# ------------------------------------------------------------------------------------------ constants
DEG = math.pi / 180.0
DEG_H = DEG / 3600.0  #: 1 deg/h in rad/s
DEG_SQRT_H = DEG / 60.0  #: 1 deg/√h in rad/√s
UG = G0 * 1e-6  #: 1 µg in m/s²
M_S_SQRT_H = 1.0 / 60.0  #: 1 m/s/√h in m/s/√s
DEG_H_SQRT_H = DEG_H / 60.0  #: 1 deg/h/√h in rad/s/√s
UG_SQRT_H = UG / 60.0  #: 1 µg/√h in m/s²/√s

GM_PEAK_X = 1.8926178354517893  #: τ of the Gauss-Markov ADEV peak / T
GM_PEAK_ADEV = 0.6173642831444415  #: peak ADEV of a Gauss-Markov process / σ_GM
FLICKER_ADEV = math.sqrt(2.0 * math.log(2.0) / math.pi)  #: ADEV of a flicker floor / B (0.6643)
B_PER_GM_SIGMA = GM_PEAK_ADEV / FLICKER_ADEV  #: IEEE 952 bias instability B per σ_GM (0.9294)

CI_PROB = 0.95  #: two-sided probability of the reported intervals
MAX_CI_RATIO = 10.0  #: a term whose 95% interval spans more than this factor is "not resolved"
#: first cluster size fitted when the log was resampled onto a uniform grid: linear interpolation of the
#: cumulative sums mixes neighbouring samples and lowers the Allan variance by about 1/(6m) of its white
#: part at m intervals (0.26% at m = 64, below the scatter of a 2-h log there)
RESAMPLED_MIN_M = 64  #: (at most: shorter logs start lower, see resampled_min_m)
MIN_CLUSTERS = 3  #: a τ is fitted only when the log holds at least this many independent clusters of it
#: fewer fitted τ than this: only the white terms (Q, N) are fitted; the bias instability and the random
#: walk are reported as not resolvable (a short log; see :func:`fit_allan`)
MIN_FULL_POINTS = 8
#: shortest τ of a Gauss-Markov ADEV peak [s] (and at least 10 × the shortest τ): bias instability is drift
#: over seconds and longer; a shorter bump is coloured sensor noise, and letting the fit place a bump
#: anywhere turns chance wiggles of the white-noise region into "bias instability" (look-elsewhere)
GM_MIN_PEAK_S = 2.0
#: a term other than the white noise is reported only when dropping it costs more than this quantile of the
#: likelihood-ratio χ² (1 degree of freedom; 2 for the Gauss-Markov σ and T): fewer false detections than
#: the 95% intervals alone, and T is not defined without the term
DETECT_PROB = 0.99
AXES = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")
#: a moving span of the static check is "motion" (never analysed) when its window means depart by more than
#: this rate [deg/s], rotate by more than this angle [deg] or depart by more than this specific force
#: [m/s²]; smaller ones are "slow motion" (kept with a warning): see :func:`static_check`
MOTION_GYRO_DEG_S = 1.0
MOTION_ANGLE_DEG = 1.0
MOTION_ACCEL_M_S2 = 0.1

__all__ = ["characterise_imu", "characterise_rates", "fit_allan", "merge_gm_rw", "print_characterisation",
            "Characterisation", "AxisFit",
           "TermEstimate", "NotStaticError", "static_check", "uniform_rates", "imu_section", "imu_yaml",
           "noise_dict", "characterise_file", "gm_avar", "B_PER_GM_SIGMA", "GM_PEAK_X", "FLICKER_ADEV"]


class NotStaticError(ValueError):
    """The log (or the chosen part) moves: the message names when and by how much."""


# ----------------------------------------------------------------------------------- model pieces
#: Taylor coefficients of the unit Gauss-Markov Allan variance g(x) = Σ c_k x^(k+1) (x = τ/T < 0.05, where
#: the closed form cancels): c_k = (−1)^k (2^(k+3) − 4) / (k+3)!, i.e. 2/3, −1/2, 7/30, −1/12, …
_GM_SERIES = (2 / 3, -1 / 2, 7 / 30, -1 / 12, 31 / 1260, -1 / 160, 127 / 90720, -17 / 60480, 73 / 1425600,
              -31 / 3628800)


def _gm_shape(x: np.ndarray) -> np.ndarray:
    """Allan variance of a unit-σ first-order Gauss-Markov process at τ = x·T (a series below x = 0.05)."""
    x = np.asarray(x, dtype=float)
    out = np.empty_like(x)
    s = x < 0.05
    xs = x[s]
    acc = np.zeros_like(xs)
    for c in _GM_SERIES[::-1]:  # Horner: Σ c_k x^(k+1)
        acc = (acc + c) * xs
    out[s] = acc
    xl = x[~s]
    out[~s] = (2.0 / xl) * (1.0 - (3.0 - 4.0 * np.exp(-xl) + np.exp(-2.0 * xl)) / (2.0 * xl))
    return out


def gm_avar(tau, sigma: float, t_corr: float) -> np.ndarray:
    """Allan variance of a first-order Gauss-Markov rate error with stationary σ and correlation time T.

    tau [s], sigma [u], t_corr [s] → σ²(τ) [u²] (El-Sheimy et al. 2008, correlated noise)."""
    return sigma**2 * _gm_shape(np.asarray(tau, float) / t_corr)


def model_avar(tau, coef, t_corr: float) -> np.ndarray:
    """Allan variance of the four-term model: coef = (Q², N², σ_GM², K²) [SI], t_corr = T [s]."""
    tau = np.asarray(tau, float)
    q2, n2, s2, k2 = coef
    return 3.0 * q2 / tau**2 + n2 / tau + s2 * _gm_shape(tau / t_corr) + k2 * tau / 3.0


def _logchi2_moments(nu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation of ln(χ²_ν/ν)."""
    from scipy.special import digamma, polygamma

    h = 0.5 * np.asarray(nu, float)
    return digamma(h) - np.log(h), np.sqrt(polygamma(1, h))


# ------------------------------------------------------------------------------ fitting kernels (numba)
# Objective: ‖L⁻¹ r‖² with r_j = (y_j − ln M_j(θ))/s_j, y_j = ln σ̂²_j − E ln(χ²_ν/ν), s_j = sd ln(χ²_ν/ν),
# and L the Cholesky factor of the correlation of the estimates (L⁻¹ lower triangular). For a fixed T the
# model M = A c is linear in c = (Q², N², σ², K²) ≥ 0: Gauss-Newton on ln M with an exact non-negative
# least-squares step (all active sets of the ≤ 4 columns enumerated) and step halving; T by a grid and
# golden section. The kernels are plain loops (no BLAS calls: the matrices are at most ~25 × 25, and the
# loops compile in a fraction of the time) and release the GIL, so the six axes are fitted in parallel.
@njit(cache=True, nogil=True)
def _gm_shape_nb(x):
    if x < 0.05:
        acc = 0.0
        for k in range(len(_GM_SERIES) - 1, -1, -1):
            acc = (acc + _GM_SERIES[k]) * x
        return acc
    return (2.0 / x) * (1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))


@njit(cache=True, nogil=True)
def _columns_nb(tau, u):
    n = tau.shape[0]
    A = np.empty((n, 4))
    T = np.exp(u)
    for j in range(n):
        A[j, 0] = 3.0 / tau[j] ** 2
        A[j, 1] = 1.0 / tau[j]
        A[j, 2] = _gm_shape_nb(tau[j] / T)
        A[j, 3] = tau[j] / 3.0
    return A


@njit(cache=True, nogil=True)
def _solve_small(G, r, idx, n):
    """Solve G[idx, idx] x = r[idx] (n ≤ 4) by Gaussian elimination with partial pivoting; ok=False if
    (nearly) singular."""
    M = np.empty((n, n + 1))
    for i in range(n):
        for j in range(n):
            M[i, j] = G[idx[i], idx[j]]
        M[i, n] = r[idx[i]]
    for col in range(n):
        p = col
        for i in range(col + 1, n):
            if abs(M[i, col]) > abs(M[p, col]):
                p = i
        if abs(M[p, col]) < 1e-13:
            return np.zeros(n), False
        if p != col:
            for j in range(n + 1):
                tmp = M[col, j]
                M[col, j] = M[p, j]
                M[p, j] = tmp
        for i in range(col + 1, n):
            f = M[i, col] / M[col, col]
            for j in range(col, n + 1):
                M[i, j] -= f * M[col, j]
    x = np.zeros(n)
    for i in range(n - 1, -1, -1):
        acc = M[i, n]
        for j in range(i + 1, n):
            acc -= M[i, j] * x[j]
        x[i] = acc / M[i, i]
    return x, True


@njit(cache=True, nogil=True)
def _nnls_enum(A, b, free):
    """min ||A c − b|| over c ≥ 0 with c_i = 0 where not free[i] (k ≤ 4: every active set is tried; the
    columns of A should have comparable norms)."""
    n, k = A.shape
    G = np.zeros((k, k))
    r = np.zeros(k)
    for i in range(k):
        for j in range(k):
            acc = 0.0
            for q in range(n):
                acc += A[q, i] * A[q, j]
            G[i, j] = acc
        acc = 0.0
        for q in range(n):
            acc += A[q, i] * b[q]
        r[i] = acc
    bb = 0.0
    for q in range(n):
        bb += b[q] * b[q]
    best = np.zeros(k)
    best_r = bb
    idx = np.empty(k, np.int64)
    for mask in range(1, 1 << k):
        nsel = 0
        ok = True
        for i in range(k):
            if (mask >> i) & 1:
                if not free[i]:
                    ok = False
                idx[nsel] = i
                nsel += 1
        if not ok:
            continue
        x, good = _solve_small(G, r, idx, nsel)
        if not good:
            continue
        neg = False
        for i in range(nsel):
            if x[i] < 0.0:
                neg = True
        if neg:
            continue
        # ||b − A_s x||² = bb − 2 xᵀ r_s + xᵀ G_s x
        rr = bb
        for i in range(nsel):
            rr -= 2.0 * x[i] * r[idx[i]]
            for j in range(nsel):
                rr += x[i] * G[idx[i], idx[j]] * x[j]
        if rr < best_r:
            best_r = rr
            best[:] = 0.0
            for i in range(nsel):
                best[idx[i]] = x[i]
    return best


@njit(cache=True, nogil=True)
def _objective(y, s, Linv, M):
    """‖L⁻¹ (y − ln M)/s‖² (L⁻¹ lower triangular)."""
    n = y.shape[0]
    r = np.empty(n)
    for j in range(n):
        r[j] = (y[j] - np.log(M[j])) / s[j]
    q = 0.0
    for i in range(n):
        acc = 0.0
        for j in range(i + 1):
            acc += Linv[i, j] * r[j]
        q += acc * acc
    return q


@njit(cache=True, nogil=True)
def _model_nb(A, c, off, out):
    """out = max(off + A c, 1e-300)."""
    n, k = A.shape
    for j in range(n):
        acc = off[j]
        for i in range(k):
            acc += A[j, i] * c[i]
        out[j] = max(acc, 1e-300)
    return out


@njit(cache=True, nogil=True)
def _fit_c_nb(A, y, s, Linv, fixed, fixv, c0, iters):
    """Coefficients c ≥ 0 for fixed columns A (n, 4) minimising the correlated log-scale objective
    ‖L⁻¹ (y − ln A c)/s‖²; coefficients where ``fixed`` are held at ``fixv``. Gauss-Newton on the
    linearisation ln M ≈ ln M₀ + (M − M₀)/M₀ with an exact NNLS step and step halving.
    Returns (objective, c)."""
    n, k = A.shape
    free = ~fixed
    off = np.zeros(n)
    c = c0.copy()
    for i in range(k):
        if fixed[i]:
            for j in range(n):
                off[j] += A[j, i] * fixv[i]
            c[i] = 0.0
    M = np.empty(n)
    start = True
    for j in range(n):
        acc = off[j]
        for i in range(k):
            acc += A[j, i] * c[i]
        M[j] = acc
        if acc > 0.0:
            start = False
    if start:  # no usable start: linearise about the data
        for j in range(n):
            M[j] = np.exp(y[j])
        q_old = np.inf
    else:
        for j in range(n):
            M[j] = max(M[j], 1e-300)
        q_old = _objective(y, s, Linv, M)
    scale = np.empty(k)
    Aw = np.empty((n, k))
    bw = np.empty(n)
    xw = np.empty((n, k))
    tw = np.empty(n)
    M_try = np.empty(n)
    for _ in range(iters):
        for j in range(n):
            wj = 1.0 / (M[j] * s[j])
            tw[j] = (M[j] * (y[j] - np.log(M[j]) + 1.0) - off[j]) * wj
            for i in range(k):
                xw[j, i] = A[j, i] * wj
        for r_ in range(n):  # whitening by the lower-triangular L⁻¹
            acc = 0.0
            for j in range(r_ + 1):
                acc += Linv[r_, j] * tw[j]
            bw[r_] = acc
            for i in range(k):
                acc = 0.0
                for j in range(r_ + 1):
                    acc += Linv[r_, j] * xw[j, i]
                Aw[r_, i] = acc
        for i in range(k):
            acc = 0.0
            for j in range(n):
                acc += Aw[j, i] ** 2
            scale[i] = max(np.sqrt(acc), 1e-300)
        for j in range(n):
            for i in range(k):
                Aw[j, i] /= scale[i]
        c_new = _nnls_enum(Aw, bw, free) / scale
        lam = 1.0
        c_try = c_new
        q_try = np.inf
        for _h in range(12):
            c_try = c + lam * (c_new - c) if q_old < np.inf else c_new
            _model_nb(A, c_try, off, M_try)
            q_try = _objective(y, s, Linv, M_try)
            if q_try < q_old:
                break
            lam *= 0.5
        if not q_try < q_old:
            break
        done = lam == 1.0 and q_old - q_try < 1e-10 * (1.0 + q_try)
        c = c_try
        M[:] = M_try
        q_old = q_try
        if done:
            break
    for i in range(k):
        if fixed[i]:
            c[i] = fixv[i]
    return q_old, c


@njit(cache=True, nogil=True)
def _profile_u_nb(tau, y, s, Linv, fixed, fixv, u_lo, u_hi, ngrid, c0, u_hint):
    """min over T (a grid plus ``u_hint`` (NaN: none), then golden section around the best) and the free
    coefficients. Without a Gauss-Markov term (σ² fixed at 0) T is not searched.
    Returns (objective, u, c)."""
    if fixed[2] and fixv[2] == 0.0:
        u = 0.5 * (u_lo + u_hi) if np.isnan(u_hint) else u_hint
        d, c = _fit_c_nb(_columns_nb(tau, u), y, s, Linv, fixed, fixv, c0, 60)
        return d, u, c
    best_d = np.inf
    best_u = u_lo
    best_c = c0.copy()
    step = (u_hi - u_lo) / (ngrid - 1)
    n_c = ngrid + (0 if np.isnan(u_hint) else 1)
    for g in range(n_c):
        u = u_lo + g * step if g < ngrid else u_hint
        d, c = _fit_c_nb(_columns_nb(tau, u), y, s, Linv, fixed, fixv, c0, 60)
        if d < best_d:
            best_d, best_u, best_c = d, u, c
    lo = max(u_lo, best_u - step)
    hi = min(u_hi, best_u + step)
    gr = 0.6180339887498949
    x1 = hi - gr * (hi - lo)
    x2 = lo + gr * (hi - lo)
    d1, c1 = _fit_c_nb(_columns_nb(tau, x1), y, s, Linv, fixed, fixv, best_c, 60)
    d2, c2 = _fit_c_nb(_columns_nb(tau, x2), y, s, Linv, fixed, fixv, best_c, 60)
    for _ in range(30):
        if hi - lo < 5e-3:
            break
        if d1 < d2:
            hi, x2, d2, c2 = x2, x1, d1, c1
            x1 = hi - gr * (hi - lo)
            d1, c1 = _fit_c_nb(_columns_nb(tau, x1), y, s, Linv, fixed, fixv, c1, 60)
        else:
            lo, x1, d1, c1 = x1, x2, d2, c2
            x2 = lo + gr * (hi - lo)
            d2, c2 = _fit_c_nb(_columns_nb(tau, x2), y, s, Linv, fixed, fixv, c2, 60)
    if d1 < best_d:
        best_d, best_u, best_c = d1, x1, c1
    if d2 < best_d:
        best_d, best_u, best_c = d2, x2, c2
    return best_d, best_u, best_c


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
def _avar_cov_nb(m, n_phase, tau0, coef, t_corr):
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


def _estimate_stats(tau, m, n_phase, coef, t_corr):
    """EDF of each Allan variance estimate and the whitener of their correlation, for the model (coef, T).

    ν_j = 2 σ²(τ_j)² / Var(σ̂²(τ_j)) from the exact covariance (see the comment above); the correlation of
    the logs is taken as that of the variances (delta method). Returns (ν, L⁻¹)."""
    tau0 = float(tau[0] / m[0])
    C = _avar_cov_nb(np.asarray(m, np.float64), float(n_phase), tau0, np.asarray(coef, float), float(t_corr))
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


# --------------------------------------------------------------------------------------- results
@dataclass
class TermEstimate:
    """One noise term of one axis, SI units (see :class:`AxisFit` for which).

    status : "fitted" (value with a 95% interval [lo, hi]) or "not resolved" (the data do not support a
    value: the term is not significant, or its interval reaches zero, is open or spans more than
    ``MAX_CI_RATIO``; then no value, only the interval's ends ``lo`` (None = 0) and ``upper``
    (None = unbounded)). ``note`` says why in words.
    """

    status: str
    value: float | None = None
    lo: float | None = None
    hi: float | None = None
    upper: float | None = None
    note: str = ""

    @property
    def fitted(self) -> bool:
        return self.status == "fitted"

    def covers(self, truth: float) -> bool:
        """True if ``truth`` lies in the reported interval ([lo, hi], or [0, upper] when not resolved)."""
        if self.fitted:
            return self.lo <= truth <= self.hi
        return (self.lo is None or self.lo <= truth) and (self.upper is None or truth <= self.upper)

    def scaled(self, f: float) -> dict:
        """JSON-ready dict with every number divided by ``f`` (SI → boundary units)."""
        d = {"status": self.status}
        if self.value is not None:
            d.update(value=self.value / f, ci95=[self.lo / f, self.hi / f])
        else:
            if self.lo is not None:
                d["lower_bound"] = self.lo / f
            d["upper_bound"] = None if self.upper is None else self.upper / f
        if self.note:
            d["note"] = self.note
        return d


@dataclass
class AxisFit:
    """Allan deviation and fitted noise terms of one axis.

    taus [s]; adev, adev_lo, adev_hi [u] (95% chi-square interval); edf : equivalent degrees of freedom;
    alpha : power-law noise type of the largest term at each τ (2 quantisation, 0 white, −1 Gauss-Markov,
    −2 random walk); used : τ included in the fit. u = rad/s (gyro) or m/s² (accel).
    terms (SI): ``white`` N [u·√s] (ARW rad/√s, VRW m/s/√s); ``quantisation`` Q [u·s] (rad, m/s);
    ``gm_sigma`` [u] and ``gm_tau`` [s]; ``bias_instability`` B = 0.9294 σ_GM [u]; ``rrw`` K [u/√s].
    coef : maximum-likelihood (Q², N², σ_GM², K²) [SI]; t_corr : T [s]; deviance, dof, dispersion : of
    the fit (dispersion = max(1, minimum/dof) scales the profile threshold); white_only : only Q and N
    were fitted (a short log: σ_GM and K held at zero and reported as not resolvable).
    """

    axis: str
    taus: np.ndarray
    adev: np.ndarray
    adev_lo: np.ndarray
    adev_hi: np.ndarray
    edf: np.ndarray
    alpha: np.ndarray
    used: np.ndarray
    terms: dict[str, TermEstimate]
    coef: np.ndarray
    t_corr: float
    deviance: float
    dof: int
    dispersion: float
    notes: list[str] = field(default_factory=list)
    white_only: bool = False

    @property
    def sensor(self) -> str:
        return self.axis.split("_")[0]

    def model_adev(self, taus=None, term: str | None = None) -> np.ndarray:
        """ADEV of the fitted model (or of one term "Q", "N", "GM", "K") at ``taus`` [s] (default: the
        analysed τ)."""
        tau = self.taus if taus is None else np.asarray(taus, float)
        c = np.array(self.coef, float)
        if term is not None:
            keep = np.array([t == term for t in _TERM_ORDER], float)
            c = c * keep
        return np.sqrt(model_avar(tau, c, self.t_corr))


@dataclass
class Characterisation:
    """Result of :func:`characterise_rates` / :func:`characterise_imu`.

    axes : the six :class:`AxisFit` (gyro x, y, z [rad/s], accel x, y, z [m/s²]); fs_hz : uniform
    sample rate analysed; n_samples; duration_s; span_s : (start, end) of the analysed part on the
    input's time scale [s]; resampled : the log was put on a uniform grid; static : result of
    :func:`static_check`; notes : what was done and found, in words (gaps, resampling, short log);
    warnings : the findings a user must not miss (slow motion kept, motion cut off, vibration), also in
    notes; vibration : :func:`vibration_report` of the analysed part; white_only : only the white terms
    were fitted (a short log).
    """

    axes: list[AxisFit]
    fs_hz: float
    n_samples: int
    duration_s: float
    span_s: tuple[float, float]
    resampled: bool
    static: dict
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    vibration: dict = field(default_factory=dict)
    white_only: bool = False

    def axis(self, name: str) -> AxisFit:
        return self.axes[AXES.index(name)]


# ------------------------------------------------------------------------------------------ fitting
_TERM_ORDER = ("Q", "N", "GM", "K")
_NGRID = 25


class _Profile:
    """Profile objective of one axis: D(ψ) = min over the other parameters with one of them fixed.

    y = ln(σ̂²) − E[ln(χ²_ν/ν)], s = sd of ln(χ²_ν/ν); Linv whitens the correlation of the estimates;
    ``drop`` : terms held at zero (indices into Q, N, GM, K)."""

    def __init__(self, tau, y, s, Linv, drop=()):
        self.tau, self.y, self.s, self.Linv = tau, y, s, Linv
        self.u_lo = math.log(min(max(10.0 * tau[0], GM_MIN_PEAK_S), tau[-1]) / GM_PEAK_X)
        self.u_hi = math.log(tau[-1] / GM_PEAK_X)
        self.c0 = np.zeros(4)
        self.u_hint = math.nan
        self.drop = tuple(drop)

    def with_drop(self, drop) -> _Profile:
        p = _Profile(self.tau, self.y, self.s, self.Linv, drop)
        p.u_hint = self.u_hint
        p.c0 = self.c0.copy()
        p.c0[list(drop)] = 0.0
        return p

    def _mask(self, idx, val):
        fixed = np.zeros(4, np.bool_)
        fixv = np.zeros(4)
        fixed[list(self.drop)] = True
        if idx >= 0:
            fixed[idx] = True
            fixv[idx] = val
        return fixed, fixv

    def best(self, fix_idx=-1, fix_val=0.0):
        fixed, fixv = self._mask(fix_idx, float(fix_val))
        return _profile_u_nb(self.tau, self.y, self.s, self.Linv, fixed, fixv, self.u_lo, self.u_hi, _NGRID,
                             self.c0, self.u_hint)

    def at_u(self, u):
        fixed, fixv = self._mask(-1, 0.0)
        return _fit_c_nb(_columns_nb(self.tau, float(u)), self.y, self.s, self.Linv, fixed, fixv, self.c0, 60)


def _interval(prof: _Profile, idx: int, c_hat: float, d_min: float, crit: float, cap: float):
    """Profile-likelihood interval (lo, hi) of coefficient ``idx``: where D − D_min = crit."""
    from scipy.optimize import brentq

    def f(v):
        return prof.best(idx, v)[0] - d_min - crit

    d_min = min(d_min, prof.best(idx, c_hat)[0])  # the same minimiser as the profile (consistency)

    # upper end: expand from the estimate (or from a tiny value when the estimate is zero)
    start = c_hat if c_hat > 0 else cap * 1e-12
    hi_b = start * 2.0
    hi = None
    while hi_b < cap * 1e4:
        if f(hi_b) > 0:
            lo_b = start if c_hat > 0 else 0.0
            hi = brentq(f, lo_b, hi_b, xtol=1e-4 * hi_b, rtol=1e-4)
            break
        start, hi_b = hi_b, hi_b * 4.0
    if hi is None:
        hi = np.inf
    if c_hat <= 0 or f(0.0) <= 0:
        lo = 0.0
    else:
        lo = brentq(f, 0.0, c_hat, xtol=1e-6 * c_hat, rtol=1e-4)
    return lo, hi


def _u_interval(prof: _Profile, d_min: float, crit: float):
    """Profile interval of u = ln T over the grid range (None at an end that reaches the range end)."""
    from scipy.optimize import brentq

    us = np.linspace(prof.u_lo, prof.u_hi, 4 * _NGRID)
    d = np.array([prof.at_u(u)[0] for u in us]) - d_min - crit
    inside = d <= 0
    if not inside.any():
        return None, None
    i0, i1 = np.flatnonzero(inside)[[0, -1]]

    def g(u):
        return prof.at_u(u)[0] - d_min - crit

    lo = None if i0 == 0 else brentq(g, us[i0 - 1], us[i0], xtol=1e-5)
    hi = None if i1 == len(us) - 1 else brentq(g, us[i1], us[i1 + 1], xtol=1e-5)
    return lo, hi


def _why_not(term: str, tau_lo: float, tau_hi: float) -> str:
    if term == "Q":
        return f"no slope −1 at the shortest τ (from {tau_lo:g} s): quantisation below the white noise"
    if term == "GM":
        return (f"no bias-instability bump resolved with its peak inside the fitted τ range {tau_lo:g}-"
                f"{tau_hi:.4g} s: hidden by the other terms or needs a longer log (the peak is at 1.89 T)")
    if term == "K":
        return f"no slope +1/2 resolved up to τ = {tau_hi:.4g} s: random walk too small to see in this log"
    return "white noise not resolved"


def fit_allan(taus, adev, n_samples: int, fs: float, axis: str = "gyro_x", min_m: int = 1,
              white_only: bool | None = None) -> AxisFit:
    """Fit the noise model of the module docstring to one axis's overlapping Allan deviation.

    Parameters
    ----------
    taus : (M,) averaging times [s] (multiples of 1/fs; octave spacing recommended).
    adev : (M,) overlapping ADEV [u] (u = rad/s or m/s²; any consistent unit works).
    n_samples : number of rate samples behind the ADEV (the EDF needs it); fs : their rate [Hz].
    axis : label (one of ``AXES``: its prefix decides the sensor in reports).
    min_m : smallest cluster size fitted (τ below min_m/fs are shown but not fitted).
    white_only : fit only the white terms (quantisation Q and white noise N) and report the bias
        instability and the random walk as not resolvable; None (default) = when fewer than
        ``MIN_FULL_POINTS`` τ can be fitted (a short log: the longer-τ terms are out of its reach, and the
        five parameters of the full model would leave almost no degrees of freedom).

    Method (module docstring): all four terms at once (Q², N², σ², K² ≥ 0, T with its ADEV peak inside
    the fitted τ range) by correlated least squares of the log Allan variances, whose degrees of freedom
    and correlations follow exactly from the model and the number of clusters; 95% profile-likelihood
    intervals; a term is reported only when the data support it.

    Returns an :class:`AxisFit` with terms in [u·√s] (white), [u·s] (quantisation Q), [u] (σ_GM, B),
    [s] (T), [u/√s] (random walk K), 95% intervals, and notes on what could not be resolved.
    """
    from scipy.stats import chi2 as chi2_dist

    tau = np.asarray(taus, float)
    adev = np.asarray(adev, float)
    m = np.rint(tau * fs).astype(int)
    n_phase = int(n_samples) + 1
    ok = np.isfinite(adev) & (adev > 0) & (m >= 1) & (n_phase - 2 * m >= 1)
    # τ with fewer than MIN_CLUSTERS independent clusters are shown but not fitted: their chi-square has
    # one or two degrees of freedom, far from the Gaussian log-likelihood used
    used = ok & (m >= min_m) & (n_samples >= MIN_CLUSTERS * m)
    notes: list[str] = []
    if white_only is None:
        white_only = bool(used.sum() < MIN_FULL_POINTS)
    n_min = 3 if white_only else 5
    if used.sum() < n_min:
        raise ValueError(f"{axis}: fewer than {n_min} usable Allan deviation points (log too short or "
                         "constant)")
    avar = adev**2
    if white_only:  # the white-noise region: the shortest 3 τ that the white terms fit, extended upwards
        idx = np.flatnonzero(used)
        crit_w = float(chi2_dist.ppf(DETECT_PROB, 1))
        d3 = [_white_deviance(tau[idx[j:j + 3]], avar[idx[j:j + 3]], m[idx[j:j + 3]], n_phase)
              for j in range(len(idx) - 2)]
        j0 = next((j for j, d in enumerate(d3) if d <= crit_w), int(np.argmin(d3)))
        k = j0 + 3
        d_prev = d3[j0]
        while k < len(idx):
            d_new = _white_deviance(tau[idx[j0:k + 1]], avar[idx[j0:k + 1]], m[idx[j0:k + 1]], n_phase)
            if d_new - d_prev > crit_w:
                break
            k += 1
            d_prev = d_new
        used[idx[:j0]] = False
        used[idx[k:]] = False
        if j0 or k < len(idx):
            notes.append(f"{axis}: white-noise region tau {tau[idx[j0]]:.3g}-{tau[idx[k - 1]]:.3g} s"
                         + ("; shorter tau depart from the white terms (vibration)" if j0 else "")
                         + (f"; from {tau[idx[k]]:.3g} s on the Allan deviation departs from them (other "
                            "noise or a disturbance)" if k < len(idx) else "") + ": shown, not fitted")
    tu, au = tau[used], avar[used]
    tau_lo, tau_hi = float(tu[0]), float(tu[-1])
    drop = (2, 3) if white_only else ()
    n_par = 2 if white_only else 5

    # EDFs and correlations of the estimates from the model itself (exact for Gaussian noise, see
    # _estimate_stats), re-evaluated at the fit three times starting from white noise
    c_hat, u_hat = np.array([0.0, float(np.min(au * tu)), 0.0, 0.0]), math.log(tu[-1])
    for _ in range(3):
        nu, Linv = _estimate_stats(tu, m[used], n_phase, c_hat, math.exp(u_hat))
        b, sd = _logchi2_moments(nu)
        full = _Profile(tu, np.log(au) - b, sd, Linv, drop=drop)
        d_full, u_hat, c_hat = full.best()
    full.u_hint, full.c0 = u_hat, c_hat.copy()
    nu_all = np.full(len(tau), np.nan)
    nu_all[ok], _ = _estimate_stats(tau[ok], m[ok], n_phase, c_hat, math.exp(u_hat))
    parts = np.column_stack([3.0 * c_hat[0] / tau**2, c_hat[1] / tau,
                             c_hat[2] * _gm_shape(tau / math.exp(u_hat)), c_hat[3] * tau / 3.0])
    alpha = np.array([(2, 0, -1, -2)[k] for k in np.argmax(parts, axis=1)])
    n_pts = len(tu)
    disp = max(1.0, d_full / max(1, n_pts - n_par))  # reduced chi-square of the fit, when above 1
    if disp > 2.0:
        notes.append(f"{axis}: the model fits the Allan variance with chi-square {d_full:.3g} for "
                     f"{n_pts - n_par} degrees of freedom; intervals widened accordingly")
    crit = float(chi2_dist.ppf(CI_PROB, 1)) * disp
    # every term stays in the model (no selection: dropping a term that the data cannot separate from
    # another would bias the other's interval); a term is reported when its own interval allows it
    prof, d_min = full, d_full
    dof = max(1, n_pts - int(np.sum(c_hat > 0)) - (1 if c_hat[2] > 0 else 0))

    # ADEV intervals (95%)
    nn = np.where(ok, nu_all, 1.0)
    adev_lo = adev * np.sqrt(nn / chi2_dist.ppf(0.5 * (1 + CI_PROB), nn))
    adev_hi = adev * np.sqrt(nn / chi2_dist.ppf(0.5 * (1 - CI_PROB), nn))

    caps = np.min(au[:, None] / _columns_nb(tu, u_hat), axis=0)  # each term alone ≤ the data
    caps[2] = float(np.max(au)) / 0.38
    terms: dict[str, TermEstimate] = {}
    span_s = n_samples / fs
    short = (f"not resolvable in {span_s:.3g} s of data: only the white terms were fitted (tau "
             f"{tau_lo:.3g}-{tau_hi:.3g} s); a bias instability or random walk needs a log many times "
             "longer than its correlation time")
    for idx, name in ((0, "quantisation"), (1, "white"), (2, "gm_sigma"), (3, "rrw")):
        t = _TERM_ORDER[idx]
        if idx in drop:
            terms[name] = TermEstimate("not resolved", note=short)
            continue
        lo2, hi2 = _interval(prof, idx, float(c_hat[idx]), d_min, crit, float(caps[idx]))
        v, lo, hi = math.sqrt(max(c_hat[idx], 0.0)), math.sqrt(lo2), _sqrt_or_none(hi2)
        dof_t = 2 if idx == 2 else 1
        if idx != 1 and lo > 0 and prof.best(idx, 0.0)[0] - d_min < chi2_dist.ppf(DETECT_PROB, dof_t) * disp:
            terms[name] = TermEstimate("not resolved", upper=hi, note=f"not significant at {DETECT_PROB:.0%} "
                                       "(likelihood ratio)" + (" of σ and T together" if idx == 2 else ""))
        elif lo > 0 and hi is not None and hi / lo <= MAX_CI_RATIO:
            terms[name] = TermEstimate("fitted", v, lo, hi)
        elif lo > 0:
            span = "is open above" if hi is None else f"spans a factor {hi / lo:.3g}"
            terms[name] = TermEstimate("not resolved", upper=hi, note=f"its 95% interval {span}")
        else:
            terms[name] = TermEstimate("not resolved", upper=hi, note=_why_not(t, tau_lo, tau_hi))
    qt = terms["quantisation"]
    if min_m > 1 and qt.fitted:  # a slope −1 above the resampling's reach is not quantisation
        terms["quantisation"] = TermEstimate(
            "not resolved", upper=qt.hi, note=f"the slope -1 part of the fit from tau {tau_lo:.3g} s on "
            f"({qt.value:.3g}) is not quantisation on a resampled log (vibration's tail or the resampling); "
            "kept in the model as a nuisance")
    if white_only and not terms["white"].fitted:
        # every term adds to the Allan variance: N²/τ ≤ σ²(τ) at each τ, a bound that holds whatever else
        # the curve holds (vibration, disturbance)
        ub = float(np.min(adev_hi[ok] * np.sqrt(tau[ok])))
        w = terms["white"]
        w.upper = ub if w.upper is None else min(w.upper, ub)
        fu, un = (DEG_SQRT_H, "deg/sqrt(h)") if axis.startswith("gyro") else (M_S_SQRT_H, "m/s/sqrt(h)")
        w.note += (f"; white noise below {ub / fu:.4g} {un} (the 95% upper ADEV limits x sqrt(tau): the "
                   f"curve is not white noise anywhere in the {span_s:.3g} s of data)")
    if white_only and terms["white"].fitted:
        terms["white"].note = (f"white noise only: the bias instability and the random walk are not "
                               f"resolvable in {span_s:.3g} s of data (tau {tau_lo:.3g}-{tau_hi:.3g} s "
                               "fitted)")
    gm = terms["gm_sigma"]
    if gm.fitted:
        ulo, uhi = _u_interval(prof, d_min, crit)
        if ulo is None or uhi is None or math.exp(uhi - ulo) > MAX_CI_RATIO:
            span = ("reaches the end of the τ range the log resolves" if (ulo is None or uhi is None)
                    else f"spans a factor {math.exp(uhi - ulo):.3g}")
            terms["gm_tau"] = TermEstimate("not resolved", lo=None if ulo is None else math.exp(ulo),
                                           upper=None if uhi is None else math.exp(uhi),
                                           note=f"Gauss-Markov correlation time: its 95% interval {span}")
        else:
            terms["gm_tau"] = TermEstimate("fitted", math.exp(u_hat), math.exp(ulo), math.exp(uhi))
    else:
        terms["gm_tau"] = TermEstimate("not resolved", note=gm.note)
    if gm.fitted:
        terms["bias_instability"] = TermEstimate("fitted", B_PER_GM_SIGMA * gm.value, B_PER_GM_SIGMA * gm.lo,
                                                 B_PER_GM_SIGMA * gm.hi)
    elif white_only:
        terms["bias_instability"] = TermEstimate("not resolved", note=short)
    else:
        floor = float(np.min(adev_hi[used]) / FLICKER_ADEV)  # a flicker floor would be below every limit
        fu, un = (DEG_H, "deg/h") if axis.startswith("gyro") else (UG, "ug")
        terms["bias_instability"] = TermEstimate(
            "not resolved", upper=None if gm.upper is None else B_PER_GM_SIGMA * gm.upper,
            note=gm.note + f"; a flat flicker floor would be below {floor / fu:.4g} {un} (the ADEV's 95% "
            "upper limits / 0.6643)")
    return AxisFit(axis=axis, taus=tau, adev=adev, adev_lo=adev_lo, adev_hi=adev_hi, edf=nn, alpha=alpha,
                   used=used, terms=terms, coef=np.array(c_hat, float), t_corr=math.exp(u_hat),
                   deviance=float(d_min), dof=dof, dispersion=disp, notes=notes, white_only=white_only)


def _white_deviance(tau, avar, m, n_phase) -> float:
    """Minimum of the white-terms (Q, N) objective on these τ (statistics re-evaluated at the fit)."""
    c_hat, u = np.array([0.0, float(np.min(avar * tau)), 0.0, 0.0]), math.log(tau[-1])
    d = math.inf
    for _ in range(3):
        nu, Linv = _estimate_stats(tau, m, n_phase, c_hat, math.exp(u))
        b, sd = _logchi2_moments(nu)
        d, u, c_hat = _Profile(tau, np.log(avar) - b, sd, Linv, drop=(2, 3)).best()
    return float(d)


def _sqrt_or_none(x: float) -> float | None:
    return math.sqrt(x) if np.isfinite(x) else None


# ---------------------------------------------------------------------------- data preparation
def uniform_rates(imu: ImuData, max_gap_ratio: float = 1.5, jitter_tol: float = 1e-3):
    """Uniformly sampled rates from increments with their own intervals.

    Returns (rates (M, 6) [rad/s, m/s²] over uniform intervals of dt, dt [s], t_start [s], resampled
    (bool), notes). Gaps (intervals > ``max_gap_ratio`` × median): the longest gap-free part is used and
    the gaps reported in ``notes``. Jitter (any interval off the median by more than ``jitter_tol``
    relative): increments are averaged onto the uniform grid by cumulative-sum interpolation.
    Memory: one (M, 6) output array and a few (M,) vectors (no stacked copies of the increments).
    """
    t = np.asarray(imu.time, float)
    if len(t) < 3:
        raise ValueError("characterise: need at least 3 IMU samples")
    t0 = imu.t0 if imu.t0 is not None else 2 * t[0] - t[1]
    dt = np.empty(len(t))
    dt[0] = t[0] - t0
    np.subtract(t[1:], t[:-1], out=dt[1:])
    if np.any(dt <= 0):
        raise ValueError("characterise: sample times are not strictly increasing")
    med = float(np.median(dt))
    notes: list[str] = []
    a, b = 0, len(t)
    t_first = float(t0)
    gap = dt > max_gap_ratio * med
    if gap.any():
        # segments between gaps: a gap interval k starts a new segment at k + 1 (the sample over the gap
        # itself is dropped: its increment spans the gap)
        starts = np.r_[0, np.flatnonzero(gap) + 1]
        ends = np.r_[np.flatnonzero(gap), len(t)]
        lens = ends - starts
        j = int(np.argmax(lens))
        a, b = int(starts[j]), int(ends[j])
        big = np.flatnonzero(gap)
        worst = big[np.argmax(dt[big])]
        t_first = float(t[a - 1]) if a > 0 else float(t0)
        notes.append(f"{len(big)} gap(s) in the log (intervals longer than {max_gap_ratio:g} x the median "
                     f"{med:.6g} s; the longest {dt[worst]:.6g} s ending at t = {t[worst]:.3f} s): analysed "
                     f"the longest gap-free part t = {t_first:.3f}-{t[b - 1]:.3f} s "
                     f"({100.0 * (b - a) / len(t):.1f}% of the samples); gaps are never bridged")
        if b - a < 3:
            raise ValueError("characterise: no gap-free part with at least 3 samples")
        dt = dt[a:b]
        med = float(np.median(dt))
    rel = np.max(np.abs(dt - med)) / med
    n_in = b - a
    if rel <= jitter_tol:
        rates = np.empty((n_in, 6))
        np.divide(imu.dtheta[a:b], dt[:, None], out=rates[:, :3])
        np.divide(imu.dv[a:b], dt[:, None], out=rates[:, 3:])
        return rates, med, t_first, False, notes
    # cumulative-sum interpolation onto the uniform grid t_start + j·med (mean rate removed first, for
    # precision of the running sums; added back after), one channel at a time
    edges = np.empty(n_in + 1)
    edges[0] = t_first
    edges[1:] = t[a:b]
    span = edges[-1] - edges[0]
    n = int(np.floor(span / med + 1e-9))
    grid = edges[0] + med * np.arange(n + 1)
    rates = np.empty((n, 6))
    cum = np.empty(n_in + 1)
    cum[0] = 0.0
    for c in range(6):
        inc = imu.dtheta[a:b, c] if c < 3 else imu.dv[a:b, c - 3]
        mean_rate = inc.sum() / span
        np.cumsum(inc - mean_rate * dt, out=cum[1:])
        cg = np.interp(grid, edges, cum)
        rates[:, c] = np.diff(cg) / med + mean_rate
    notes.append(f"time stamps jitter by up to {100 * rel:.2g}% of the median interval {med:.6g} s: "
                 f"increments averaged onto a uniform {1 / med:.6g} Hz grid by cumulative-sum "
                 "interpolation; the shortest tau are not fitted (resampling lowers them), so quantisation "
                 "cannot be resolved")
    return rates, med, t_first, True, notes


@njit(cache=True, nogil=True)
def _window_stats(y, w, nw):
    """Mean and standard deviation of each of ``nw`` consecutive windows of ``w`` rows of y (M, k)."""
    k = y.shape[1]
    mean = np.empty((nw, k))
    std = np.empty((nw, k))
    acc = np.empty(k)
    for b in range(nw):
        acc[:] = 0.0
        for i in range(b * w, (b + 1) * w):
            for c in range(k):
                acc[c] += y[i, c]
        for c in range(k):
            mean[b, c] = acc[c] / w
        acc[:] = 0.0
        for i in range(b * w, (b + 1) * w):
            for c in range(k):
                d = y[i, c] - mean[b, c]
                acc[c] += d * d
        for c in range(k):
            std[b, c] = np.sqrt(acc[c] / w)
    return mean, std


def static_check(rates, fs: float, t_start: float = 0.0, window_s: float = 1.0,
                 gyro_tol_deg_s: float = 0.05, accel_tol_m_s2: float = 0.1, std_ratio: float = 4.0,
                 max_disturbed_fraction: float = 0.01, motion_gyro_deg_s: float = MOTION_GYRO_DEG_S,
                 motion_angle_deg: float = MOTION_ANGLE_DEG,
                 motion_accel_m_s2: float = MOTION_ACCEL_M_S2) -> dict:
    """Is a log static? From window means and window variances of the gyros and accelerometers.

    rates : (M, 6) gyro [rad/s] and accel [m/s²] rates, uniform at ``fs`` [Hz]; t_start [s] of sample 0's
    interval. Windows of ``window_s`` (at least 10 samples). A window **moves** when the mean of any axis
    departs from the log's median window mean by more than max(tolerance, 8 × the robust spread of the
    window means, 6 × the white-noise scatter of a window mean) (tolerances: gyro ``gyro_tol_deg_s``
    [deg/s], accel ``accel_tol_m_s2`` [m/s²]: turning or tilting); it is **disturbed** when the standard
    deviation inside the window of any axis exceeds ``std_ratio`` × the median window's (vibration bursts,
    handling).

    Consecutive moving windows form an event, sized by its largest window-mean departure (gyro [deg/s],
    accel [m/s²]) and the rotation over it (the departures integrated, largest axis [deg]). An event is
    **motion** when any exceeds ``motion_gyro_deg_s``, ``motion_angle_deg`` or ``motion_accel_m_s2`` (the
    platform is moved: driving, turning, tilting), otherwise **slow motion** (a small, short rotation or
    rocking: someone leaning on a parked car). Why the two are treated differently (see
    :func:`characterise_imu`): the Allan variance at τ is the mean square change between successive
    τ-averages over the whole log, so a short rate excursion a of duration D adds about a²τ²/(D·T_log) at
    τ ≲ D (and a²D/T_log around τ ~ D): for a slow motion (a ≲ 1 deg/s, a fraction of a degree) that is a
    small, reported bias of the white-noise region of a short log and is kept with a warning; motion
    adds a rate change far above the sensor noise at every τ and is never analysed.

    The log is static when no window moves and at most ``max_disturbed_fraction`` of the windows are
    disturbed; it is **usable** when it holds no motion event and at most that fraction is disturbed
    (slow motion only: kept, with the warning in ``warnings``).

    Returns dict: static, usable (bool), windows (count), window_s, moving / disturbed (counts),
    moving_spans_s / disturbed_spans_s (up to 10 [start, end] spans on the input time scale), events
    (list of dicts: start_s, end_s, kind "motion" | "slow motion", peak_gyro_deg_s, angle_deg,
    peak_accel_m_s2), motion_free_spans_s (the spans between motion events, each shortened by one window
    at a motion event; longest first), max_gyro_dev_deg_s, max_accel_dev_m_s2, warnings (list of str),
    message (str, empty when usable).
    """
    y = np.ascontiguousarray(rates, dtype=float)
    w = max(10, int(round(window_s * fs)))
    nw = len(y) // w
    wdt = w / fs
    t_end = t_start + len(y) / fs
    if nw < 3:
        return {"static": True, "usable": True, "windows": nw, "window_s": wdt, "moving": 0, "disturbed": 0,
                "moving_spans_s": [], "disturbed_spans_s": [], "events": [],
                "motion_free_spans_s": [[t_start, t_end]], "max_gyro_dev_deg_s": 0.0,
                "max_accel_dev_m_s2": 0.0, "warnings": [], "message": "",
                "note": "log too short for the static check (fewer than 3 windows)"}
    mean, std = _window_stats(y, w, nw)
    med = np.median(mean, axis=0)
    sdev = mean - med
    dev = np.abs(sdev)
    mad = 1.4826 * np.median(dev, axis=0)
    tol = np.r_[np.full(3, gyro_tol_deg_s * DEG), np.full(3, accel_tol_m_s2)]
    floor = np.r_[np.full(3, 1e-3 * DEG), np.full(3, 1e-3)]
    sref = np.maximum(np.median(std, axis=0), floor / std_ratio)
    # a window mean of white noise with the log's typical in-window spread scatters by sref/√w: a
    # vibrating (but parked) vehicle is not "moving" because of that scatter (6σ)
    moving = np.any(dev > np.maximum(np.maximum(tol, 8.0 * mad), 6.0 * sref / np.sqrt(w)), axis=1)
    disturbed = np.any(std > std_ratio * sref, axis=1)

    def runs(mask):
        idx = np.flatnonzero(mask)
        if not len(idx):
            return []
        br = np.flatnonzero(np.diff(idx) > 1)
        return list(zip(np.r_[idx[0], idx[br + 1]].tolist(), np.r_[idx[br], idx[-1]].tolist(), strict=True))

    def spans(mask):
        return [[t_start + a * wdt, t_start + (b + 1) * wdt] for a, b in runs(mask)]

    events = []
    motion = np.zeros(nw, bool)
    for a, b in runs(moving):
        pg = float(dev[a:b + 1, :3].max() / DEG)
        ang = float(np.abs(sdev[a:b + 1, :3].sum(axis=0)).max() * wdt / DEG)
        pa = float(dev[a:b + 1, 3:].max())
        kind = "motion" if (pg > motion_gyro_deg_s or ang > motion_angle_deg or pa > motion_accel_m_s2) \
            else "slow motion"
        if kind == "motion":
            motion[max(0, a - 1):b + 2] = True  # one window of margin on each side
        events.append({"start_s": t_start + a * wdt, "end_s": t_start + (b + 1) * wdt, "kind": kind,
                       "peak_gyro_deg_s": pg, "angle_deg": ang, "peak_accel_m_s2": pa})
    free = []
    for a, b in runs(~motion):
        lo = t_start if a == 0 else t_start + a * wdt
        hi = t_end if b == nw - 1 else t_start + (b + 1) * wdt
        free.append([lo, hi])
    free.sort(key=lambda s: s[0] - s[1])
    ms, ds = spans(moving), spans(disturbed)
    static = (not moving.any()) and disturbed.mean() <= max_disturbed_fraction
    usable = (not motion.any()) and disturbed.mean() <= max_disturbed_fraction
    res = {"static": bool(static), "usable": bool(usable), "windows": int(nw), "window_s": wdt,
           "moving": int(moving.sum()), "disturbed": int(disturbed.sum()), "moving_spans_s": ms[:10],
           "disturbed_spans_s": ds[:10], "events": events[:20], "motion_free_spans_s": free[:10],
           "max_gyro_dev_deg_s": float(dev[:, :3].max() / DEG), "max_accel_dev_m_s2": float(dev[:, 3:].max()),
           "warnings": [], "message": ""}
    for e in events:
        if e["kind"] == "slow motion":
            res["warnings"].append(
                f"slow motion at {e['start_s']:.1f}-{e['end_s']:.1f} s: window means depart by up to "
                f"{e['peak_gyro_deg_s']:.3g} deg/s gyro ({e['angle_deg']:.2g} deg of rotation) and "
                f"{e['peak_accel_m_s2']:.3g} m/s2 accel (thresholds of motion {motion_gyro_deg_s:g} deg/s, "
                f"{motion_angle_deg:g} deg, {motion_accel_m_s2:g} m/s2): kept; it raises the Allan deviation "
                f"of the affected axes at tau of about {e['end_s'] - e['start_s']:.3g} s and longer")
    if not usable:
        parts = []
        mot = [e for e in events if e["kind"] == "motion"]
        if mot:
            parts.append(f"it moves in {len(mot)} span(s) (window means depart from the median by up to "
                         f"{max(e['peak_gyro_deg_s'] for e in mot):.3g} deg/s gyro, "
                         f"{max(e['peak_accel_m_s2'] for e in mot):.3g} m/s2 accel; first spans "
                         + ", ".join(f"{e['start_s']:.1f}-{e['end_s']:.1f} s" for e in mot[:3]) + ")")
        if disturbed.mean() > max_disturbed_fraction:
            parts.append(f"{disturbed.sum()} of {nw} windows are disturbed (in-window spread above "
                         f"{std_ratio:g} x the typical; first spans "
                         + ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in ds[:3]) + ")")
        sugg = ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in free[:3])
        res["message"] = ("the log is not static: " + "; ".join(parts)
                          + ". Allan analysis needs a static log: the longest parts without motion are "
                          f"{sugg}; choose a static part with --static START:END")
    return res


# ------------------------------------------------------------------------------------------ drivers
def resampled_min_m(n: int) -> int:
    """First cluster size fitted on a resampled log of ``n`` samples.

    Cumulative-sum resampling lowers the white part of the Allan variance at m intervals by about
    1/(6m); the estimate at m scatters by about √(2/ν) with ν ≈ 1.5 n/m degrees of freedom (white noise).
    The bias stays below a quarter of that scatter from m³ ≥ n/3 on: the smallest power of two with it,
    at least 8 (a 2% bias) and at most ``RESAMPLED_MIN_M`` (64: a 2-h log at 100 Hz)."""
    m = 8
    while m < RESAMPLED_MIN_M and m**3 < n / 3.0:
        m *= 2
    return m


def trapezoid_samples(imu: ImuData) -> np.ndarray:
    """The sensor's point samples (N, 6) [rad/s, m/s²] behind trapezoid increments.

    Raw logs of point-sampled rates are read as Δθ_k = ½(ω_{k−1} + ω_k)(t_k − t_{k−1}) and Δθ_0 = ω_0
    (t_0 − t0) (:func:`aidnav.io.logs.read_rtklibexplorer_imu`); the exact inverse is
    ω_k = 2Δθ_k/Δt_k − ω_{k−1}, i.e. ω_k = (−1)^k Σ_{j≤k} (−1)^j r_j with r_0 = Δθ_0/Δt_0 and
    r_j = 2Δθ_j/Δt_j (rounding error ~1e-16 × |r| × √k). The trapezoid averages neighbouring samples
    (gain cos(π f Δt) at frequency f): a vibration near the Nyquist frequency is much weaker in the
    increments than in the sensor's output, which is what a data sheet or a vibration spec quotes."""
    t = np.asarray(imu.time, float)
    dt = np.diff(t, prepend=imu.t0 if imu.t0 is not None else 2 * t[0] - t[1])
    out = np.empty((len(t), 6))
    sign = np.where(np.arange(len(t)) % 2 == 0, 1.0, -1.0)
    for c in range(6):
        inc = imu.dtheta[:, c] if c < 3 else imu.dv[:, c - 3]
        r = 2.0 * inc / dt
        r[0] = inc[0] / dt[0]
        out[:, c] = sign * np.cumsum(sign * r)
    return out


def _psd_peak(x: np.ndarray, fs: float, f_min: float = 1.0, nseg: int = 512, max_segs: int = 256):
    """Dominant frequency [Hz] above ``f_min`` of one channel (Welch: Hann windows of ``nseg`` samples, at
    most ``max_segs`` of them spread over the record) and the fraction of the variance above ``f_min``
    that lies within ±1 Hz of it. (nan, nan) when the record is too short."""
    x = np.asarray(x, float)
    nseg = min(nseg, 1 << int(math.floor(math.log2(max(len(x), 2)))))
    if nseg < 32:
        return math.nan, math.nan
    n_avail = (len(x) - nseg) // (nseg // 2) + 1
    starts = np.linspace(0, len(x) - nseg, min(max_segs, n_avail)).astype(np.int64)
    seg = x[starts[:, None] + np.arange(nseg)]
    seg = seg - seg.mean(axis=1, keepdims=True)
    p = (np.abs(np.fft.rfft(seg * np.hanning(nseg), axis=1)) ** 2).mean(axis=0)
    f = np.fft.rfftfreq(nseg, 1.0 / fs)
    hi = f > f_min
    if not hi.any() or p[hi].sum() <= 0:
        return math.nan, math.nan
    fp = float(f[hi][np.argmax(p[hi])])
    share = float(p[hi & (np.abs(f - fp) <= 1.0)].sum() / p[hi].sum())
    return fp, share


VIBRATION_RATIO = 2.0  #: sample spread above this × the white noise's (N·√fs) is reported as vibration
#: ... and so is a spectrum with more than this share of its variance above 1 Hz within ±1 Hz of its peak
#: (white noise: about 2 Hz / (fs/2), 4% at 100 Hz; an engine's vibration: most of it)
VIBRATION_SHARE = 0.25


def vibration_report(rates, fs: float, axes: list[AxisFit], sensor: dict | None = None) -> dict:
    """Spread of the samples against the fitted white noise, per axis: vibration, reported.

    rates : (M, 6) analysed uniform rates [rad/s, m/s²] at ``fs``; axes : the fits (their white term N);
    sensor : optional {"std": (6,), "peak_hz": (6,), "share": (6,), "what": str} of the sensor's own
    samples when they differ from the analysed rates (resampled or trapezoid increments).

    White rate noise of density N sampled at fs has a standard deviation N·√fs. A sample spread well above
    it (ratio > ``VIBRATION_RATIO``; N: the fitted value or its upper bound), or a spectrum concentrated at
    one frequency (share > ``VIBRATION_SHARE``), is vibration (engine, pumps, fans): zero-mean, at
    frequencies above the τ the fit uses, so it shows in the Allan deviation at the shortest τ (a hump
    near τ ~ 1/(2f), then a −1 slope) and not in the fitted terms. Reported per axis: std [deg/s | m/s²]
    of the analysed rates and of the sensor samples, the white-noise std, their ratio, the dominant
    frequency above 1 Hz and the share of the variance within ±1 Hz of it."""
    y = np.ascontiguousarray(rates, dtype=float)
    _, std_a = _window_stats(y, len(y), 1)
    std_a = std_a[0]
    if sensor is None:
        std_s = std_a
        pk = [_psd_peak(y[:, c], fs) for c in range(6)]
        what = "analysed rates (the sensor's samples)"
    else:
        std_s = np.asarray(sensor["std"], float)
        pk = list(zip(sensor["peak_hz"], sensor["share"], strict=True))
        what = sensor["what"]
    out = {"samples": what, "ratio_threshold": VIBRATION_RATIO, "axes": {}, "detected": []}
    for c, a in enumerate(axes):
        g = a.sensor == "gyro"
        f, unit = (DEG, "deg_s") if g else (1.0, "m_s2")
        w = a.terms["white"]
        n_ref = w.value if w.fitted else (w.upper if w.upper is not None else math.sqrt(max(a.coef[1], 0.0)))
        white_std = n_ref * math.sqrt(fs)
        ratio = float(std_s[c] / white_std) if white_std > 0 else None
        share = pk[c][1]
        vib = bool((ratio is not None and ratio > VIBRATION_RATIO)
                   or (math.isfinite(share) and share > VIBRATION_SHARE))
        d = {f"std_{unit}": float(std_s[c] / f), f"analysed_std_{unit}": float(std_a[c] / f),
             f"white_noise_std_{unit}": float(white_std / f), "ratio": ratio,
             "peak_hz": _json_float(pk[c][0]), "peak_share": _json_float(share), "vibration": vib}
        out["axes"][a.axis] = d
        if d["vibration"]:
            out["detected"].append(a.axis)
    return out


def _vibration_text(vib: dict) -> str:
    parts = []
    for ax in vib["detected"]:
        d = vib["axes"][ax]
        unit = "deg/s" if ax.startswith("gyro") else "m/s2"
        k = "std_deg_s" if ax.startswith("gyro") else "std_m_s2"
        pk = "" if d["peak_hz"] is None else \
            f" at {d['peak_hz']:.3g} Hz ({d['peak_share']:.0%} of it within 1 Hz)"
        rt = "" if d["ratio"] is None else f", {d['ratio']:.3g} x the white noise"
        parts.append(f"{ax} {d[k]:.3g} {unit}{pk}{rt}")
    return ("vibration (zero-mean, above the fitted tau; it shows as the hump and -1 slope of the Allan "
            f"deviation at the shortest tau, not in the fitted terms), std of the {vib['samples']}: "
            + "; ".join(parts))


def characterise_rates(rates, fs: float, t_start: float = 0.0, min_m: int = 1, check_static: bool = True,
                       notes: list[str] | None = None, resampled: bool = False,
                       white_only: bool | None = None, sensor: dict | None = None,
                       warnings: list[str] | None = None,
                       workers: int | None = None, time_origin: float = 0.0,
                       timings: dict | None = None) -> Characterisation:
    """Characterise uniformly sampled rates (the Python API on arrays).

    rates : (M, 6) gyro x, y, z [rad/s] then accel x, y, z [m/s²], body frame, uniform at ``fs`` [Hz]
    (sample k is the average over (t_start + k/fs, t_start + (k+1)/fs]).
    min_m : smallest cluster size fitted. check_static : raise :class:`NotStaticError` when
    :func:`static_check` finds motion (slow motion is kept, with a warning). white_only : see
    :func:`fit_allan`. sensor : statistics of the sensor's own samples for :func:`vibration_report`.
    workers : threads (None: one per CPU); each axis's Allan deviation (allantools) and fit run together.
    time_origin : the static check's spans and messages are in seconds after it [s]
    (``static["time_origin_s"]``). timings : a dict that receives the wall time of the stages [s].
    Returns a :class:`Characterisation` (ADEV at octave-spaced τ = 2^j/fs and the fitted terms, SI).
    """
    import os
    from concurrent.futures import ThreadPoolExecutor

    from aidnav.analysis.allan import allan_deviation, reuse_freed_memory

    y = np.asarray(rates, float)
    if y.ndim != 2 or y.shape[1] != 6:
        raise ValueError(f"characterise_rates: rates must be (M, 6), got {y.shape}")
    notes = list(notes or [])
    warns = list(warnings or [])
    n = len(y)
    dur = n / fs
    if n < 64:
        raise ValueError(f"characterise: only {n} samples ({dur:.3g} s); need at least 64")
    if not np.isfinite(y).all():
        raise ValueError("characterise_rates: rates contain NaN or inf")
    stg = _Stages(timings)
    st = static_check(y, fs, t_start - time_origin)
    st["time_origin_s"] = float(time_origin)
    if check_static and not st["usable"]:
        raise NotStaticError(st["message"])
    if st.get("note"):
        notes.append(st["note"])
    warns += st["warnings"]
    if st["disturbed"] and st["usable"]:
        notes.append(f"{st['disturbed']} of {st['windows']} one-second windows are disturbed (vibration or "
                     "handling); kept")
    stg.lap("static check")
    if white_only is None:
        n_fit = sum(1 for k in range(int(math.log2(n)) + 1) if 2**k >= min_m and n >= MIN_CLUSTERS * 2**k)
        white_only = n_fit < MIN_FULL_POINTS

    def one_axis(c):
        taus, adev, _, _ = allan_deviation(y[:, c], fs, taus="octave", workers=1)
        return fit_allan(taus, adev, n, fs, axis=AXES[c], min_m=min_m, white_only=white_only)

    nw = max(1, min(6, workers if workers is not None else (os.cpu_count() or 1)))
    with reuse_freed_memory():  # allantools' full-length temporaries: no page faults for each
        if nw == 1:
            axes = [one_axis(c) for c in range(6)]
        else:
            with ThreadPoolExecutor(max_workers=nw) as ex:
                axes = list(ex.map(one_axis, range(6)))
    stg.lap("Allan deviation (allantools) + fit, per axis in threads")
    for a in axes:
        notes += a.notes
    t_fit = max(float(a.taus[a.used][-1]) for a in axes)
    if white_only:
        t0_fit = min(float(a.taus[a.used][0]) for a in axes)
        warns.append(f"white noise only: {dur:.3g} s of data resolve the white terms (ARW / VRW, fitted on "
                     f"tau {t0_fit:.3g}-{t_fit:.3g} s); the bias instability and the random walk are not "
                     f"resolvable in {dur:.3g} s (they need a log many times longer than their correlation "
                     "time): imu.yaml takes grade defaults for them")
    else:
        notes.append(f"{dur:.6g} s of data: terms whose Allan signature lies beyond tau ~ {t_fit:.4g} s (the "
                     f"longest tau with {MIN_CLUSTERS} independent clusters, the last one fitted) cannot be "
                     "resolved")
    vib = vibration_report(y, fs, axes, sensor)
    if vib["detected"]:
        warns.append(_vibration_text(vib))
        for a in axes:  # with vibration, a slope −1 at the short τ is its tail, not quantisation
            qt = a.terms["quantisation"]
            if a.axis in vib["detected"] and qt.fitted:
                a.terms["quantisation"] = TermEstimate(
                    "not resolved", upper=qt.hi, note=f"the slope -1 part of the fit ({qt.value:.3g}) is the "
                    "vibration's tail, not quantisation; kept in the model as a nuisance")
    notes += [w for w in warns if w not in notes]
    stg.lap("vibration report")
    return Characterisation(axes=axes, fs_hz=float(fs), n_samples=n, duration_s=dur,
                            span_s=(float(t_start), float(t_start + dur)), resampled=resampled, static=st,
                            notes=notes, warnings=warns, vibration=vib, white_only=bool(white_only))


def _longest_static(rates, fs: float, t_rel: float, resampled: bool, st: dict,
                    chosen: bool = False) -> tuple[int, int]:
    """Sample range [i0, i1) of the longest static part of ``rates`` (not usable as a whole: ``st``).

    chosen : the rates are a part the user chose as static: its own motion-free spans (``st``) are
    candidates too (its median level is the parked one; small disturbances in it are kept and reported).
    Candidates are (also) the runs of quiet one-second windows (the in-window spread of every axis within
    4 × its 5th percentile over the windows: a moving vehicle shakes far more than a parked one,
    engine vibration included), less one window at each end that borders a loud one; each is checked
    with :func:`static_check` on its own level (the median window of a mostly moving log says nothing of
    the parked level) and cut down to its longest part without motion. Raises :class:`NotStaticError`
    (naming the candidates) when none is long enough to fit."""
    y = np.ascontiguousarray(rates, dtype=float)
    n = len(y)
    w = max(10, int(round(fs)))
    nw = n // w
    cands = []
    if nw >= 3:
        _, std = _window_stats(y, w, nw)
        floor = np.r_[np.full(3, 1e-3 * DEG), np.full(3, 1e-3)] / 4.0
        ref = np.maximum(np.percentile(std, 5, axis=0), floor)
        quiet = np.all(std <= 4.0 * ref, axis=1)
        idx = np.flatnonzero(quiet)
        if len(idx):
            br = np.flatnonzero(np.diff(idx) > 1)
            for a, b in zip(np.r_[idx[0], idx[br + 1]], np.r_[idx[br], idx[-1]], strict=True):
                s0 = int(a + (a > 0)) * w
                s1 = n if b == nw - 1 else int(b) * w
                if s1 > s0:
                    cands.append((s0, s1))
    if chosen:
        for lo, hi in st["motion_free_spans_s"]:
            cands.append((max(0, int(round((lo - t_rel) * fs))), min(n, int(round((hi - t_rel) * fs)))))
    cands.sort(key=lambda c: c[0] - c[1])
    best = None
    for s0, s1 in cands:
        if best is not None and s1 - s0 <= best[1] - best[0]:
            break
        for _ in range(3):
            sub = static_check(y[s0:s1], fs, t_rel + s0 / fs)
            if sub["usable"] or not any(e["kind"] == "motion" for e in sub["events"]):
                break
            lo, hi = sub["motion_free_spans_s"][0]
            s0, s1 = max(s0, int(round((lo - t_rel) * fs))), min(s1, int(round((hi - t_rel) * fs)))
        need = max(64, 12 * (resampled_min_m(s1 - s0) if resampled else 1))
        if sub["usable"] and s1 - s0 >= need and (best is None or s1 - s0 > best[1] - best[0]):
            best = (s0, s1)
    if best is None:
        spans = ", ".join(f"{t_rel + a / fs:.1f}-{t_rel + b / fs:.1f} s" for a, b in cands[:3]) or "none"
        raise NotStaticError(st["message"].split(". Allan analysis")[0]
                             + f". No static part is long enough to analyse (quiet parts: {spans}; times in "
                             "s after the first sample); choose a static part with --static START:END")
    return best


def characterise_imu(imu: ImuData, static: tuple[float | None, float | None] | None = None,
                     check_static: bool = True, increments: str = "interval",
                     workers: int | None = None, timings: dict | None = None) -> Characterisation:
    """Characterise an IMU log (increments with their own Δt; rates, any rate, jitter and gaps allowed).

    static : (start, end) [s] after the log's first time stamp (either None = open) to analyse only that
    part; None = the whole log. Gaps → the longest gap-free part (reported); jitter → cumulative-sum
    resampling (reported).

    Motion (check_static). The part is checked by :func:`static_check`. Motion (driving, turning,
    tilting: rates or tilts far above the sensor noise) is never analysed: the longest part without it is
    (the part chosen with ``static`` included), and the motion is reported with its time and size, as
    gaps are; with no part long enough, :class:`NotStaticError` names the spans. Slow motion (a small,
    short rotation or rocking, below ``MOTION_GYRO_DEG_S`` / ``MOTION_ANGLE_DEG`` / ``MOTION_ACCEL_M_S2``)
    is kept with a warning: cutting it out would shorten a short log further (or split it), and its effect
    is bounded and stated: a rate excursion a of duration D adds about a²τ²/(D·T_log) to the Allan
    variance at τ ≲ D, a small part of the white-noise region that a short log's fit uses, and it enters
    the reported intervals through the fit's dispersion. Vibration (zero-mean, large sample spread) is
    not motion: it is kept and reported by :func:`vibration_report` (std per axis, dominant frequency).

    workers, timings : see :func:`characterise_rates` (timings: wall time of the stages [s]).
    increments : how the increments relate to the sensor's samples, for the vibration report only:
    "interval" (Δθ/Δt is the sensor's output: rate logs, simulated increments) or "trapezoid"
    (Δθ_k = ½(ω_{k−1} + ω_k)Δt_k, as raw rtklibexplorer logs are read; :func:`trapezoid_samples`).
    """
    if increments not in ("interval", "trapezoid"):
        raise ValueError(f"increments must be 'interval' or 'trapezoid', got {increments!r}")
    stg = _Stages(timings)
    notes = list(imu.events)
    warns: list[str] = []
    base0 = float(imu.time[0])
    samples = trapezoid_samples(imu) if increments == "trapezoid" else None
    if static is not None:
        a, b = static
        base = float(imu.time[0])
        lo = base + (a or 0.0)
        hi = base + b if b is not None else np.inf
        m = (imu.time > lo) & (imu.time <= hi)
        if m.sum() < 3:
            raise ValueError(f"--static {a}:{b}: fewer than 3 samples in that part of the log")
        idx = np.flatnonzero(m)
        t0 = imu.time[idx[0] - 1] if idx[0] > 0 else imu.t0
        imu = ImuData(imu.time[m], imu.dtheta[m], imu.dv[m], t0=t0)
        if samples is not None:
            samples = samples[m]
        notes.append(f"static part {a or 0:g}-{'end' if b is None else f'{b:g}'} s after the first sample "
                     "analysed")
    rates, dt, t_start, resampled, n2 = uniform_rates(imu)
    notes += n2
    fs = 1.0 / dt
    stg.lap("uniform rates")
    if check_static:
        st = static_check(rates, fs, t_start - base0)
        if not st["usable"]:
            i0, i1 = _longest_static(rates, fs, t_start - base0, resampled, st, chosen=static is not None)
            why = st["message"].split(": ", 1)[1].split(". Allan analysis")[0]
            what = "chosen part" if static is not None else "log"
            warns.append(f"the {what} is not static ({why}; times in s after the first sample): analysed "
                         "its longest static part, "
                         f"{t_start - base0 + i0 * dt:.1f}-{t_start - base0 + i1 * dt:.1f} s "
                         f"({100.0 * (i1 - i0) / len(rates):.0f}% of its samples); motion is never analysed")
            rates = rates[i0:i1]
            t_start = t_start + i0 * dt
    stg.lap("static check")
    min_m = resampled_min_m(len(rates)) if resampled else 1
    if resampled:
        notes.append(f"resampled log of {len(rates)} samples: the fit starts at tau = {min_m} intervals (the "
                     "resampling bias 1/(6m) of the white part is then below a quarter of the scatter)")
    sensor = None
    if samples is not None or resampled:
        t_hi = t_start + len(rates) * dt
        sel = (imu.time > t_start + 0.5 * dt) & (imu.time <= t_hi + 0.5 * dt)
        if samples is not None:
            x = samples[sel]
            what = "sensor's samples (trapezoid increments inverted)"
        else:
            dts = np.diff(imu.time, prepend=imu.t0)[sel]
            x = np.column_stack([imu.dtheta[sel], imu.dv[sel]]) / dts[:, None]
            what = "sensor's samples (increments / their own intervals)"
        if len(x) >= 3:
            pk = [_psd_peak(x[:, c], fs) for c in range(6)]
            sensor = {"std": x.std(axis=0), "peak_hz": [p[0] for p in pk], "share": [p[1] for p in pk],
                      "what": what}
        stg.lap("sensor samples")
    imu = samples = None  # the log is no longer needed (memory: the caller holds no reference either)
    return characterise_rates(rates, fs, t_start=t_start, min_m=min_m, check_static=check_static, notes=notes,
                              resampled=resampled, sensor=sensor, warnings=warns, workers=workers,
                              time_origin=base0, timings=timings)


# ------------------------------------------------------------------------------------------ outputs
_UNITS = {
    "gyro": {"white": ("arw_deg_sqrt_h", DEG_SQRT_H), "quantisation": ("quantisation_rad", 1.0),
             "bias_instability": ("bias_instability_deg_h", DEG_H), "gm_sigma": ("gm_sigma_deg_h", DEG_H),
             "gm_tau": ("gm_tau_s", 1.0), "rrw": ("rrw_deg_h_sqrt_h", DEG_H_SQRT_H)},
    "accel": {"white": ("vrw_m_s_sqrt_h", M_S_SQRT_H), "quantisation": ("quantisation_m_s", 1.0),
              "bias_instability": ("bias_instability_ug", UG), "gm_sigma": ("gm_sigma_ug", UG),
              "gm_tau": ("gm_tau_s", 1.0), "rrw": ("accel_rw_ug_sqrt_h", UG_SQRT_H)},
}
_ADEV_UNIT = {"gyro": ("deg_h", DEG_H), "accel": ("ug", UG)}


def _json_float(x):
    x = float(x)
    return x if math.isfinite(x) else None


def noise_dict(ch: Characterisation) -> dict:
    """noise.json content: per axis, every term in the boundary units of CONVENTIONS with its status and
    95% interval, the maximum-likelihood model (all four terms, resolved or not), the ADEV table (deg/h
    for gyros, µg for accelerometers, with 95% limits and EDFs) and the notes."""
    axes = {}
    for a in ch.axes:
        units = _UNITS[a.sensor]
        d = {units[k][0]: a.terms[k].scaled(units[k][1]) for k in
             ("white", "quantisation", "bias_instability", "gm_sigma", "gm_tau", "rrw")}
        un, f = _ADEV_UNIT[a.sensor]
        q2, n2, s2, k2 = a.coef
        d["best_fit"] = {units["quantisation"][0]: math.sqrt(q2) / units["quantisation"][1],
                         units["white"][0]: math.sqrt(n2) / units["white"][1],
                         units["gm_sigma"][0]: math.sqrt(s2) / units["gm_sigma"][1],
                         "gm_tau_s": a.t_corr, units["rrw"][0]: math.sqrt(k2) / units["rrw"][1],
                         "chi2": a.deviance, "dof": a.dof, "dispersion": a.dispersion}
        d["allan"] = {"tau_s": a.taus.tolist(), f"adev_{un}": (a.adev / f).tolist(),
                      f"adev_lo_{un}": [_json_float(v) for v in a.adev_lo / f],
                      f"adev_hi_{un}": [_json_float(v) for v in a.adev_hi / f],
                      "edf": [_json_float(v) for v in a.edf], "fitted": a.used.tolist()}
        axes[a.axis] = d
    return {
        "samples": ch.n_samples, "rate_hz": ch.fs_hz, "duration_s": ch.duration_s, "span_s": list(ch.span_s),
        "resampled": ch.resampled,
        "fit": ("white noise only: quantisation and white noise (ARW / VRW) fitted on the short-tau part; "
                "the bias instability and the random walk are not resolvable in "
                f"{ch.duration_s:.3g} s of data"
                if ch.white_only else "full model: quantisation, white noise, Gauss-Markov bias instability, "
                "random walk"),
        "warnings": ch.warnings, "vibration": ch.vibration, "static_check": ch.static,
        "conventions": {
            "units": "gyro: deg/sqrt(h), deg/h, deg/h/sqrt(h), rad; accel: m/s/sqrt(h), ug, ug/sqrt(h), m/s",
            "ci95": "95% profile-likelihood interval; each Allan variance a chi-square variable whose "
                    "degrees of freedom and correlations follow from the number of clusters and the model",
            "bias_instability": "IEEE 952 B (flicker floor ADEV = 0.6643 B) with the height of the fitted "
                                "Gauss-Markov's ADEV peak: B = 0.9294 gm_sigma, peak at tau = 1.8926 gm_tau",
            "quantisation": "IEEE 952 Q (AVAR = 3 Q^2 / tau^2); quantum = sqrt(12) Q",
            "status": "fitted (value, ci95) | not resolved (no value: lower_bound/upper_bound of its "
                      "interval; upper_bound null = unbounded)",
        },
        "axes": axes, "notes": ch.notes,
    }


def _grade_units(grade: str) -> dict:
    from aidnav.sim.imu import ImuSpec

    u = ImuSpec.grade(grade).to_units()
    return {k: (float(np.max(v)) if isinstance(v, list) else v) for k, v in u.items()}


def auto_grade(ch: Characterisation) -> str:
    """The preset (navigation, tactical, mems, consumer) whose ARW and VRW are nearest (in log) to the fit."""
    best, dist = "mems", np.inf
    arw = [a.terms["white"].value for a in ch.axes[:3] if a.terms["white"].fitted]
    vrw = [a.terms["white"].value for a in ch.axes[3:] if a.terms["white"].fitted]
    for g in ("navigation", "tactical", "mems", "consumer"):
        u = _grade_units(g)
        d = 0.0
        if arw:
            d += abs(math.log(max(arw) / DEG_SQRT_H / u["arw_deg_sqrt_h"]))
        if vrw:
            d += abs(math.log(max(vrw) / M_S_SQRT_H / u["vrw_m_s_sqrt_h"]))
        if d < dist:
            best, dist = g, d
    return best


def _fmt(x: float) -> str:
    return f"{x:.4g}"


def _fitted_max(axes, key, unit):
    """(largest fitted value [SI] or None, text listing every axis in ``unit``)."""
    vals, txt = [], []
    for a in axes:
        t = a.terms[key]
        if t.fitted:
            vals.append(t.value)
            txt.append(f"{a.axis[-1]} {_fmt(t.value / unit)} [{_fmt(t.lo / unit)}, {_fmt(t.hi / unit)}]")
        else:
            ub = "unbounded" if t.upper is None else f"< {_fmt(t.upper / unit)}"
            txt.append(f"{a.axis[-1]} not resolved ({ub})")
    return (max(vals) if vals else None), ", ".join(txt)


MERGE_HORIZON_S = 3600.0  #: horizon over which a merged bias process keeps the bias variance of GM + RW


def merge_gm_rw(sigma: float, t_corr: float, k: float,
                horizon: float = MERGE_HORIZON_S) -> tuple[float, float]:
    """One first-order Gauss-Markov (σ_eff, T_eff) for a bias that is a GM (σ, T) plus a random walk K (SI).

    The filter has one bias process per triad. The merged process keeps (i) the driving noise,
    q = 2σ²/T + K² (the bias drift over short intervals, what the filter needs between fixes), and (ii)
    the variance of the bias change over ``horizon`` [s], 2σ²(1 − e^(−H/T)) + K²H; with q fixed, the
    GM's variance over H, q·T_eff·(1 − e^(−H/T_eff)), grows with T_eff, so T_eff is found by bisection
    and σ_eff² = q·T_eff/2. Returns (σ_eff, T_eff)."""
    q = 2.0 * sigma**2 / t_corr + k**2
    want = 2.0 * sigma**2 * (-math.expm1(-horizon / t_corr)) + k**2 * horizon

    def var_h(t):
        return q * t * (-math.expm1(-horizon / t))

    lo, hi = 1e-9 * horizon, 1e9 * horizon
    for _ in range(200):
        mid = math.sqrt(lo * hi)
        if var_h(mid) < want:
            lo = mid
        else:
            hi = mid
    t_eff = math.sqrt(lo * hi)
    return math.sqrt(q * t_eff / 2.0), t_eff


def imu_section(ch: Characterisation, grade: str | None = None) -> tuple[dict, dict]:
    """The ``imu:`` section of an ``aidnav process`` configuration from a characterisation.

    One value per triad (the filter's keys are scalars): the largest fitted axis value of each noise
    density and σ (conservative) and the shortest fitted correlation time. The filter has one bias process
    per triad: when both a Gauss-Markov (σ, T) and a random walk K are fitted they are merged into one
    Gauss-Markov (:func:`merge_gm_rw`: same driving noise and same bias variance after an hour); a random
    walk alone makes a random-walk bias (tau 0). The turn-on (run-to-run)
    bias cannot be seen in one static log: its σ is the grade default, combined with the bias
    instability as √(b² + σ²) for the filter's initial bias σ. Terms the log does not resolve take the grade
    default (``grade``; None = :func:`auto_grade`), and the comment says so.

    Returns (values, comments): dicts keyed by the configuration key; comments say each value's source.
    """
    grade = grade or auto_grade(ch)
    gu = _grade_units(grade)
    vals: dict = {}
    com: dict = {}
    for g, axes in ((True, ch.axes[:3]), (False, ch.axes[3:])):
        p = "gyro" if g else "accel"
        wkey, wunit = ("arw_deg_sqrt_h", DEG_SQRT_H) if g else ("vrw_m_s_sqrt_h", M_S_SQRT_H)
        bunit, bname, bsuf = (DEG_H, "deg/h", "deg_h") if g else (UG, "ug", "ug")
        rwunit, rwsuf = (DEG_H_SQRT_H, "deg_h_sqrt_h") if g else (UG_SQRT_H, "ug_sqrt_h")
        ikey, tkey = f"{p}_bias_instability_{bsuf}", f"{p}_bias_tau_s"
        rkey, skey = f"{p}_bias_rw_{rwsuf}", f"{p}_bias_sigma_{bsuf}"

        w, wtxt = _fitted_max(axes, "white", wunit)
        wo = (f" (white noise only, from the short-tau part of {ch.duration_s:.3g} s of data)"
              if ch.white_only else "")
        if w is not None:
            vals[wkey], com[wkey] = w / wunit, f"fitted, largest axis: {wtxt}{wo}"
        else:
            vals[wkey] = gu[wkey]
            com[wkey] = f"grade default ({grade}): not resolved on any axis ({wtxt})"

        sig, stxt = _fitted_max(axes, "gm_sigma", bunit)
        tau, ttxt = _fitted_max(axes, "gm_tau", 1.0)
        taus = [a.terms["gm_tau"].value for a in axes if a.terms["gm_tau"].fitted]
        tau = min(taus) if taus else None
        kk, ktxt = _fitted_max(axes, "rrw", rwunit)
        t_def = gu[f"{p}_bias_corr_time_s"]
        if sig is not None:
            t_use = tau if tau is not None else t_def
            t_src = (f"fitted, shortest axis: {ttxt}" if tau is not None else
                     f"grade default ({grade}): the log does not resolve T ({ttxt})")
            if kk is not None:
                s_eff, t_eff = merge_gm_rw(sig, t_use, kk)
                vals[ikey] = s_eff / bunit
                com[ikey] = (f"fitted Gauss-Markov sigma {_fmt(sig / bunit)} {bname}, T {_fmt(t_use)} s "
                             f"({stxt}) merged with the fitted random walk into one Gauss-Markov (same "
                             f"driving noise, same bias variance after {MERGE_HORIZON_S:g} s)")
                vals[rkey] = kk / rwunit
                com[rkey] = (f"fitted ({ktxt}); the filter uses it only when {tkey} <= 0: here merged into "
                             "the Gauss-Markov above")
                t_use, t_src = t_eff, f"merged Gauss-Markov correlation time (fitted T: {t_src})"
            else:
                vals[ikey] = sig / bunit
                com[ikey] = f"fitted Gauss-Markov sigma, largest axis: {stxt}"
                vals[rkey] = 0.0
                com[rkey] = f"random walk not resolved ({ktxt}); unused while {tkey} > 0"
            vals[tkey], com[tkey] = t_use, t_src
        elif kk is not None:
            vals[ikey], vals[tkey], vals[rkey] = 0.0, 0.0, kk / rwunit
            com[ikey] = f"Gauss-Markov bias instability not resolved ({stxt}): the bias is a random walk"
            com[tkey] = "0: random-walk bias"
            com[rkey] = f"fitted, largest axis: {ktxt}"
        else:
            vals[ikey] = gu[f"{p}_bias_instability_{bsuf}"]
            vals[tkey] = t_def
            vals[rkey] = 0.0
            ubs = [a.terms["bias_instability"].upper for a in axes]
            bound = ("B below " + _fmt(max(ubs) / bunit) + f" {bname} (95%)") if None not in ubs else \
                "no upper bound on B"
            com[ikey] = (f"grade default ({grade}): not resolvable in {ch.duration_s:.3g} s of data (white "
                         "noise only was fitted)" if ch.white_only else
                         f"grade default ({grade}): the log is too short (or too noisy) to resolve the bias "
                         f"instability ({stxt}; {bound})")
            com[tkey] = f"grade default ({grade})" + (" (not resolvable in this log)" if ch.white_only
                                                       else "")
            com[rkey] = (f"random walk not resolvable in {ch.duration_s:.3g} s of data; unused while "
                         f"{tkey} > 0" if ch.white_only else
                         f"random walk not resolved ({ktxt}); unused while {tkey} > 0")
        tb = gu[f"{p}_bias_{bsuf}"]
        vals[skey] = math.hypot(tb, vals[ikey])
        com[skey] = (f"turn-on bias {_fmt(tb)} {bname}: grade default ({grade}), one static log cannot show "
                     "the run-to-run bias; combined with the instability above as sqrt(b^2 + sigma^2)")
    order = ["arw_deg_sqrt_h", "vrw_m_s_sqrt_h", "gyro_bias_sigma_deg_h", "accel_bias_sigma_ug",
             "gyro_bias_instability_deg_h", "accel_bias_instability_ug", "gyro_bias_tau_s",
             "accel_bias_tau_s", "gyro_bias_rw_deg_h_sqrt_h", "accel_bias_rw_ug_sqrt_h"]
    return {k: float(vals[k]) for k in order}, {k: com[k] for k in order}


def imu_yaml(ch: Characterisation, grade: str | None = None, source: str = "") -> str:
    """YAML text of the ``imu:`` section with each number's source in a comment (see :func:`imu_section`)."""
    vals, com = imu_section(ch, grade)
    head = [f"# imu: section for `aidnav process`, from `aidnav characterise` of {source or 'a static log'}",
            f"# ({ch.n_samples} samples at {ch.fs_hz:.6g} Hz, {ch.duration_s:.6g} s). Values per axis in "
            "brackets are 95% intervals.",
            "# One value per triad: the largest axis noise and sigma, the shortest correlation time."]
    if ch.white_only:
        head.append(f"# White noise only: {ch.duration_s:.3g} s of data resolve ARW / VRW; the bias "
                    "instability, its correlation time and the random walk are grade defaults (not "
                    "resolvable in this log).")
    for w in ch.warnings:
        if not w.startswith("white noise only"):
            head.append("# warning: " + w)
    lines = ["imu:"]
    for k, v in vals.items():
        lines.append(f"  {k}: {v!r}  # {com[k]}")
    return "\n".join(head + lines) + "\n"


def _increment_rule(path) -> str:
    """How :func:`aidnav.process.read_imu_any` forms the increments of this file: "trapezoid" for a raw
    rtklibexplorer CSV (point samples of the rates; :func:`aidnav.io.logs.read_rtklibexplorer_imu`),
    "interval" for interchange files (rates × Δt or increments as given)."""
    path = Path(path)
    if path.suffix.lower() in (".parquet", ".pq"):
        return "interval"
    try:
        with open(path, "rb") as f:
            head = f.read(4096).decode("utf-8", "replace")
    except OSError:
        return "interval"
    first = next((ln for ln in head.splitlines() if ln.strip() and not ln.startswith("#")), "")
    return "interval" if "time" in first else "trapezoid"


def _warm_up() -> None:
    """Import the analysis and plotting libraries and load the compiled kernels (numba's first call costs
    a few tenths of a second): run in a thread while the log is read, so that it overlaps the reading."""
    try:
        import allantools  # noqa: F401  (scipy.stats, scipy.interpolate)
        import matplotlib.backends.backend_agg  # noqa: F401
        import matplotlib.figure  # noqa: F401
        from scipy.optimize import brentq  # noqa: F401

        import aidnav.report.allan_plot  # noqa: F401

        tau = np.array([0.01, 0.02, 0.04])
        _window_stats(np.zeros((20, 6)), 10, 2)
        _avar_cov_nb(tau / 0.01, 100.0, 0.01, np.array([0.0, 1.0, 0.0, 0.0]), 1.0)
        _profile_u_nb(tau, np.zeros(3), np.ones(3), np.eye(3), np.zeros(4, np.bool_), np.zeros(4), -1.0, 1.0,
                      3, np.zeros(4), math.nan)
    except Exception:  # noqa: BLE001  (a warm-up only: the analysis imports and compiles what it needs)
        pass


class _Stages:
    """Wall time of the stages of :func:`characterise_file` into a dict (None: not recorded)."""

    def __init__(self, out: dict | None):
        import time

        self.out, self._clock = out, time.perf_counter
        self._t = self._clock()

    def lap(self, name: str) -> None:
        now = self._clock()
        if self.out is not None:
            self.out[name] = self.out.get(name, 0.0) + now - self._t
        self._t = now


def characterise_file(imu_path, out_dir, static: str | None = None, grade: str | None = None,
                      timings: dict | None = None) -> tuple:
    """``aidnav characterise``: read any IMU log, characterise it, write allan.png, noise.json, imu.yaml.

    static : "START:END" seconds after the first sample (either may be empty); None: the whole log (its
    longest static part when it moves: see :func:`characterise_imu`). timings : a dict that receives the
    wall time of each stage [s]. Returns (Characterisation, list of written paths). Raises
    :class:`NotStaticError` / ValueError with a clear message for a moving log, bad option or unusable data.

    Speed: the analysis libraries are imported (and the compiled kernels loaded) in a thread while the
    log is read; the reader holds no reference to the log after the analysis has taken its rates.
    """
    import sys
    import threading

    from aidnav.process import read_imu_any

    st = _Stages(timings)
    rng = None
    if static:
        parts = static.split(":")
        try:
            if len(parts) != 2:
                raise ValueError
            rng = tuple(float(x) if x.strip() else None for x in parts)
        except ValueError:
            raise ValueError(f"--static {static!r}: expected START:END in seconds after the first sample"
                             ) from None
        if rng[0] is not None and rng[1] is not None and rng[1] <= rng[0]:
            raise ValueError(f"--static {static!r}: END must be after START")
    warm = threading.Thread(target=_warm_up, name="aidnav-characterise-warm-up", daemon=True)
    warm.start()
    st.lap("start")

    def read():
        imu = read_imu_any(imu_path)
        pa = sys.modules.get("pyarrow")
        if pa is not None and hasattr(pa, "default_memory_pool"):  # the Parquet/CSV buffers the reader freed
            try:
                pa.default_memory_pool().release_unused()
            except AttributeError:
                pass
        st.lap("read")
        warm.join()
        st.lap("imports not overlapped by the reading")
        return imu

    # no reference to the log is held here: characterise_imu lets it go once it has the rates
    ch = characterise_imu(read(), static=rng, increments=_increment_rule(imu_path), timings=timings)
    st.lap("characterise")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    nd = noise_dict(ch)
    nd["imu"] = str(imu_path)
    nd["grade_for_defaults"] = grade or auto_grade(ch)
    p_json = out / "noise.json"
    p_json.write_text(json.dumps(nd, indent=2, allow_nan=False))
    p_yaml = out / "imu.yaml"
    p_yaml.write_text(imu_yaml(ch, nd["grade_for_defaults"], source=str(imu_path)))
    st.lap("noise.json + imu.yaml")
    from aidnav.report.allan_plot import plot_allan

    p_png = plot_allan(ch, out / "allan.png", title=f"Allan deviation: {Path(imu_path).name}")
    st.lap("allan.png")
    return ch, [p_png, p_json, p_yaml]


def print_characterisation(ch: Characterisation, console=None) -> None:
    """A rich table of the fitted terms per axis (boundary units) and the notes."""
    from rich.console import Console
    from rich.table import Table

    console = console or Console()
    tab = Table(title=f"IMU noise ({ch.n_samples} samples at {ch.fs_hz:.6g} Hz, {ch.duration_s:.6g} s; "
                      "95% intervals)")
    cols = (("white", "ARW deg/√h | VRW m/s/√h"), ("bias_instability", "bias instab. deg/h | µg"),
            ("gm_tau", "GM T s"), ("rrw", "RRW deg/h/√h | µg/√h"), ("quantisation", "Q rad | m/s"))
    tab.add_column("axis")
    for _, name in cols:
        tab.add_column(name)
    for a in ch.axes:
        units = _UNITS[a.sensor]
        row = [a.axis]
        for key, _ in cols:
            t = a.terms[key]
            f = units[key][1]
            if t.fitted:
                row.append(f"{t.value / f:.4g} [{t.lo / f:.3g}, {t.hi / f:.3g}]")
            elif t.upper is not None:
                row.append(f"n.r. (< {t.upper / f:.3g})")
            else:
                row.append("n.r.")
        tab.add_row(*row)
    console.print(tab)
    for n in ch.notes:
        if n not in ch.warnings:
            console.print(f"note: {n}")
    for w in ch.warnings:
        console.print(f"[bold yellow]warning:[/] {w}")
