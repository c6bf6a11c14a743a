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
counted twice. Averaging mixes neighbouring samples, which lowers the ADEV at the first few τ; when a log
is resampled the fit therefore starts at τ ≥ 8 grid intervals (and says so). A gap (an interval longer
than 1.5 × the median) is never bridged: the longest gap-free part is analysed and the gap reported.

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

Confidence intervals come from the number of clusters: each overlapping Allan variance has a chi-square
distribution whose equivalent degrees of freedom ν follow from the number of samples N, the cluster size
m = τ·f_s and the noise type that dominates at that τ (Greenhall's EDF, ``allantools.edf_greenhall``;
the noise type is read from the local slope of the fitted model). The fit is a weighted least-squares
fit of ln σ̂²(τ) with the exact mean ψ(ν/2) − ln(ν/2) and variance ψ'(ν/2) of ln(χ²_ν/ν) (a Gaussian
approximation of the chi-square likelihood), over log-parameters; the parameter covariance is the
inverse Fisher matrix, inflated by the reduced χ² when that exceeds 1 (model misfit, correlated
estimates), and the 95% intervals are symmetric in the log-parameters.

Which terms are reported. Every subset of {Q, GM, K} with N is fitted and the one with the lowest BIC
(χ² + k ln n) is kept; a Gauss-Markov term only counts when its ADEV peak (1.8926·T) lies inside the
fitted τ range (otherwise it cannot be told from white noise or a random walk). A term of the chosen
model whose 95% interval spans more than a factor ``MAX_CI_RATIO`` (in deviation units) is "not
resolved". A term that is not resolved is never given a value: it gets an upper bound from the ADEV's
99.5% upper limits (the term alone cannot exceed the total at any τ; for the bias instability the bound
is on the flicker floor B).
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
RESAMPLED_MIN_M = 8  #: first cluster size fitted when the log was resampled onto a uniform grid
AXES = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")

__all__ = ["characterise_imu", "characterise_rates", "fit_allan", "Characterisation", "AxisFit",
           "TermEstimate", "NotStaticError", "static_check", "uniform_rates", "imu_section", "imu_yaml",
           "noise_dict", "characterise_file", "gm_avar", "B_PER_GM_SIGMA", "GM_PEAK_X", "FLICKER_ADEV"]


class NotStaticError(ValueError):
    """The log (or the chosen part) moves: the message names when and by how much."""


# ----------------------------------------------------------------------------------- model pieces
def _gm_shape(x: np.ndarray) -> np.ndarray:
    """Allan variance of a unit-σ first-order Gauss-Markov process at τ = x·T (a series below x = 0.05)."""
    x = np.asarray(x, dtype=float)
    out = np.empty_like(x)
    s = x < 0.05
    xs = x[s]
    out[s] = 2.0 * (xs / 3.0 - xs**2 / 4.0 + 7.0 * xs**3 / 60.0 - xs**4 / 24.0)
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


def _alpha_from_slope(mu: np.ndarray) -> np.ndarray:
    """Power-law noise type α (S_y ∝ f^α) nearest to a local Allan-variance slope μ = −1 − α."""
    return np.clip(np.rint(-1.0 - mu), -2, 2).astype(int)


_EDF_CACHE: dict = {}


def _edf(alpha: int, m: int, n_phase: int) -> float:
    """Greenhall's EDF of the overlapping Allan variance (phase noise types use the white-FM value)."""
    key = (int(alpha), int(m), int(n_phase))
    v = _EDF_CACHE.get(key)
    if v is None:
        import allantools

        a = min(int(alpha), 0)
        v = float(allantools.edf_greenhall(alpha=a, d=2, m=int(m), N=int(n_phase), overlapping=True))
        if len(_EDF_CACHE) > 100_000:
            _EDF_CACHE.clear()
        _EDF_CACHE[key] = v
    return v


def _logchi2_moments(nu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation of ln(χ²_ν/ν)."""
    from scipy.special import digamma, polygamma

    h = 0.5 * np.asarray(nu, float)
    return digamma(h) - np.log(h), np.sqrt(polygamma(1, h))


# ------------------------------------------------------------------ maximum-likelihood kernels (numba)
# The Allan variances a_j are independent Gamma variables with mean M_j(θ) and shape ν_j/2 (ν_j·a_j/M_j ~
# χ²_ν). −2 log L = Σ ν_j (a_j/M_j + ln M_j) + const; the deviance D = Σ ν_j (a_j/M_j − 1 − ln(a_j/M_j)).
# For a fixed T the model is linear in c = (Q², N², σ², K²) ≥ 0: a Gamma GLM with identity link, solved by
# Fisher scoring (iteratively reweighted least squares, weights ν/(2M²)) with an exact non-negative least
# squares step (all active sets of the ≤ 4 columns enumerated).
@njit(cache=True)
def _gm_shape_nb(x):
    if x < 0.05:
        return 2.0 * (x / 3.0 - x * x / 4.0 + 7.0 * x**3 / 60.0 - x**4 / 24.0)
    return (2.0 / x) * (1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))


@njit(cache=True)
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


@njit(cache=True)
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
                M[col, j], M[p, j] = M[p, j], M[col, j]
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


@njit(cache=True)
def _nnls_enum(A, b, free):
    """min ||A c − b|| over c ≥ 0 with c_i = 0 where not free[i] (k ≤ 4: every active set is tried; the
    columns of A should have comparable norms)."""
    k = A.shape[1]
    G = A.T @ A
    r = A.T @ b
    bb = np.sum(b * b)
    best = np.zeros(k)
    best_r = bb
    idx = np.empty(k, np.int64)
    for mask in range(1, 1 << k):
        n = 0
        ok = True
        for i in range(k):
            if (mask >> i) & 1:
                if not free[i]:
                    ok = False
                idx[n] = i
                n += 1
        if not ok:
            continue
        x, good = _solve_small(G, r, idx, n)
        if not good:
            continue
        neg = False
        for i in range(n):
            if x[i] < 0.0:
                neg = True
        if neg:
            continue
        # ||b − A_s x||² = bb − 2 xᵀ r_s + xᵀ G_s x
        rr = bb
        for i in range(n):
            rr -= 2.0 * x[i] * r[idx[i]]
            for j in range(n):
                rr += x[i] * G[idx[i], idx[j]] * x[j]
        if rr < best_r:
            best_r = rr
            best[:] = 0.0
            for i in range(n):
                best[idx[i]] = x[i]
    return best


@njit(cache=True)
def _objective(y, s, Linv, M):
    n = y.shape[0]
    r = np.empty(n)
    for j in range(n):
        r[j] = (y[j] - np.log(M[j])) / s[j]
    z = Linv @ r
    return np.sum(z * z)


@njit(cache=True)
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
            off += A[:, i] * fixv[i]
            c[i] = 0.0
    M = off + A @ c
    start = True
    for j in range(n):
        if M[j] > 0.0:
            start = False
    if start:  # no usable start: linearise about the data
        M = np.exp(y)
        q_old = np.inf
    else:
        for j in range(n):
            M[j] = max(M[j], 1e-300)
        q_old = _objective(y, s, Linv, M)
    scale = np.empty(k)
    for _ in range(iters):
        w = 1.0 / (M * s)
        t = M * (y - np.log(M) + 1.0)
        Aw = Linv @ (A * w[:, None])
        bw = Linv @ ((t - off) * w)
        for i in range(k):
            scale[i] = max(np.sqrt(np.sum(Aw[:, i] ** 2)), 1e-300)
        c_new = _nnls_enum(Aw / scale, bw, free) / scale
        lam = 1.0
        c_try = c_new
        q_try = np.inf
        for _h in range(12):
            c_try = c + lam * (c_new - c) if q_old < np.inf else c_new
            M_try = off + A @ c_try
            for j in range(n):
                M_try[j] = max(M_try[j], 1e-300)
            q_try = _objective(y, s, Linv, M_try)
            if q_try < q_old:
                break
            lam *= 0.5
        if not q_try < q_old:
            break
        done = lam == 1.0 and q_old - q_try < 1e-10 * (1.0 + q_try)
        c = c_try
        M = M_try
        q_old = q_try
        if done:
            break
    for i in range(k):
        if fixed[i]:
            c[i] = fixv[i]
    return q_old, c


@njit(cache=True)
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
    alpha : noise type used for the EDF; used : τ included in the fit. u = rad/s (gyro) or m/s² (accel).
    terms (SI): ``white`` N [u·√s] (ARW rad/√s, VRW m/s/√s); ``quantisation`` Q [u·s] (rad, m/s);
    ``gm_sigma`` [u] and ``gm_tau`` [s]; ``bias_instability`` B = 0.9294 σ_GM [u]; ``rrw`` K [u/√s].
    coef : maximum-likelihood (Q², N², σ_GM², K²) [SI]; t_corr : T [s]; deviance, dof, dispersion : of
    the fit (dispersion = max(1, Pearson χ²/dof) scales the profile threshold).
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

    @property
    def sensor(self) -> str:
        return self.axis.split("_")[0]

    def model_adev(self, taus=None, term: str | None = None) -> np.ndarray:
        """ADEV of the fitted model (or of one term "Q", "N", "GM", "K") at ``taus`` [s] (default: self.taus)."""
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
    :func:`static_check`; notes : what was done and found, in words (gaps, resampling, short log).
    """

    axes: list[AxisFit]
    fs_hz: float
    n_samples: int
    duration_s: float
    span_s: tuple[float, float]
    resampled: bool
    static: dict
    notes: list[str] = field(default_factory=list)

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
        self.u_lo = math.log(tau[0] / GM_PEAK_X)
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


#: correlation of the log Allan variances at neighbouring octaves by noise type α (measured on simulated
#: white FM (0.55), flicker-like (0.75) and random-walk FM (0.88) noise, N = 2^17, 300 runs); pairs further
#: apart get the product of the neighbours' (an exponential kernel on a warped log-τ axis: positive
#: definite, and an over-estimate at larger lags, i.e. conservative)
_RHO_OCTAVE = {2: 0.55, 1: 0.55, 0: 0.55, -1: 0.75, -2: 0.88}


def _whitener(tau, alpha) -> np.ndarray:
    d = np.array([-math.log(_RHO_OCTAVE[int(a)]) for a in alpha])
    step = 0.5 * (d[1:] + d[:-1]) * np.abs(np.diff(np.log2(tau)))
    pos = np.r_[0.0, np.cumsum(step)]
    R = np.exp(-np.abs(pos[:, None] - pos[None, :]))
    L = np.linalg.cholesky(R + 1e-12 * np.eye(len(tau)))
    return np.ascontiguousarray(np.linalg.inv(L))


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


def fit_allan(taus, adev, n_samples: int, fs: float, axis: str = "gyro_x", min_m: int = 1) -> AxisFit:
    """Fit the noise model of the module docstring to one axis's overlapping Allan deviation.

    Parameters
    ----------
    taus : (M,) averaging times [s] (multiples of 1/fs; octave spacing recommended).
    adev : (M,) overlapping ADEV [u] (u = rad/s or m/s²; any consistent unit works).
    n_samples : number of rate samples behind the ADEV (the EDF needs it); fs : their rate [Hz].
    axis : label (one of ``AXES``: its prefix decides the sensor in reports).
    min_m : smallest cluster size fitted (τ below min_m/fs are shown but not fitted).

    Method: maximum likelihood with each Allan variance a chi-square variable of Greenhall's EDF
    (noise type from the local slope of a first fit), all four terms at once (Q², N², σ², K² ≥ 0, T with
    its ADEV peak inside the fitted τ range); 95% profile-likelihood intervals (deviance rise
    χ²₁(0.95) = 3.84, times the dispersion when the fit is worse than its EDFs allow).

    Returns an :class:`AxisFit` with terms in [u·√s] (white), [u·s] (quantisation Q), [u] (σ_GM, B),
    [s] (T), [u/√s] (random walk K), 95% intervals, and notes on what could not be resolved.
    """
    from scipy.stats import chi2 as chi2_dist

    tau = np.asarray(taus, float)
    adev = np.asarray(adev, float)
    m = np.rint(tau * fs).astype(int)
    n_phase = int(n_samples) + 1
    ok = np.isfinite(adev) & (adev > 0) & (m >= 1) & (n_phase - 2 * m >= 1)
    used = ok & (m >= min_m)
    notes: list[str] = []
    if used.sum() < 5:
        raise ValueError(f"{axis}: fewer than 5 usable Allan deviation points (log too short or constant)")
    avar = adev**2
    tu, au = tau[used], avar[used]
    tau_lo, tau_hi = float(tu[0]), float(tu[-1])

    def edfs(alpha_all):
        return np.array([_edf(a, mm, n_phase) if mm >= 1 and n_phase - 2 * mm >= 1 else np.nan
                         for a, mm in zip(alpha_all, m, strict=True)])

    # EDFs: noise type from the local slope of a first fit (white FM to start), twice
    alpha = np.zeros(len(tau), int)
    nu = edfs(alpha)
    for _ in range(3):
        b, sd = _logchi2_moments(nu[used])
        prof = _Profile(tu, np.log(au) - b, sd, _whitener(tu, alpha[used]))
        d_min, u_hat, c_hat = prof.best()
        h = 0.05
        mu = (np.log(model_avar(tau * math.exp(h), c_hat, math.exp(u_hat)))
              - np.log(model_avar(tau * math.exp(-h), c_hat, math.exp(u_hat)))) / (2 * h)
        alpha = _alpha_from_slope(mu)
        nu = edfs(alpha)
    b, sd = _logchi2_moments(nu[used])
    full = _Profile(tu, np.log(au) - b, sd, _whitener(tu, alpha[used]))
    d_full, u_hat, c_hat = full.best()
    full.u_hint, full.c0 = u_hat, c_hat.copy()
    n_pts = len(tu)
    disp = max(1.0, d_full / max(1, n_pts - 5))
    if disp > 2.0:
        notes.append(f"{axis}: the model fits the Allan variance with chi-square {d_full:.3g} for "
                     f"{n_pts - 5} degrees of freedom; intervals widened accordingly")
    crit = float(chi2_dist.ppf(CI_PROB, 1)) * disp
    # backward elimination: drop the least significant of Q, GM, K while its likelihood-ratio statistic
    # is below the 95% point (χ²₁ for Q and K, χ²₂ for the two Gauss-Markov parameters)
    crit_drop = {0: crit, 2: float(chi2_dist.ppf(CI_PROB, 2)) * disp, 3: crit}
    drop: tuple = ()
    prof, d_min = full, d_full
    while True:
        trial = []
        for i in (0, 2, 3):
            if i in drop:
                continue
            p_i = full.with_drop(drop + (i,))
            d_i, u_i, c_i = p_i.best()
            trial.append((d_i - d_min - crit_drop[i], i, p_i, d_i, u_i, c_i))
        trial.sort(key=lambda x: x[0])
        if not trial or trial[0][0] >= 0:
            break
        _, i, prof, d_min, u_i, c_i = trial[0]
        drop = drop + (i,)
        prof.c0 = c_i.copy()
        if i != 2:
            u_hat = u_i
            prof.u_hint = u_i
        c_hat = c_i
    d_min, u_hat, c_hat = prof.best()
    prof.u_hint, prof.c0 = u_hat, c_hat.copy()
    dof = max(1, n_pts - (4 - len(drop)) - (0 if 2 in drop else 1))

    # ADEV intervals (95%)
    nn = np.where(np.isfinite(nu), nu, 1.0)
    adev_lo = adev * np.sqrt(nn / chi2_dist.ppf(0.5 * (1 + CI_PROB), nn))
    adev_hi = adev * np.sqrt(nn / chi2_dist.ppf(0.5 * (1 - CI_PROB), nn))

    caps = np.min(au[:, None] / _columns_nb(tu, u_hat), axis=0)  # each term alone ≤ the data
    caps[2] = float(np.max(au)) / 0.38
    terms: dict[str, TermEstimate] = {}
    for idx, name in ((0, "quantisation"), (1, "white"), (2, "gm_sigma"), (3, "rrw")):
        t = _TERM_ORDER[idx]
        if idx in drop:  # not significant: only an upper bound, from the model with every term free
            _, hi2 = _interval(full, idx, float(full.c0[idx]), d_full, crit, float(caps[idx]))
            terms[name] = TermEstimate("not resolved", upper=_sqrt_or_none(hi2),
                                       note="not significant: " + _why_not(t, tau_lo, tau_hi))
            continue
        lo2, hi2 = _interval(prof, idx, float(c_hat[idx]), d_min, crit, float(caps[idx]))
        v, lo, hi = math.sqrt(max(c_hat[idx], 0.0)), math.sqrt(lo2), _sqrt_or_none(hi2)
        if lo > 0 and hi is not None and hi / lo <= MAX_CI_RATIO:
            terms[name] = TermEstimate("fitted", v, lo, hi)
        elif lo > 0:
            span = "is open above" if hi is None else f"spans a factor {hi / lo:.3g}"
            terms[name] = TermEstimate("not resolved", upper=hi, note=f"its 95% interval {span}")
        else:
            terms[name] = TermEstimate("not resolved", upper=hi, note=_why_not(t, tau_lo, tau_hi))
    gm = terms["gm_sigma"]
    if gm.fitted:
        ulo, uhi = _u_interval(prof, d_min, crit)
        if ulo is None or uhi is None or math.exp(uhi - ulo) > MAX_CI_RATIO**2:
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
    else:
        terms["bias_instability"] = TermEstimate(
            "not resolved", upper=None if gm.upper is None else B_PER_GM_SIGMA * gm.upper, note=gm.note)
    return AxisFit(axis=axis, taus=tau, adev=adev, adev_lo=adev_lo, adev_hi=adev_hi, edf=nu, alpha=alpha,
                   used=used, terms=terms, coef=np.array(c_hat, float), t_corr=math.exp(u_hat),
                   deviance=float(d_min), dof=dof, dispersion=disp, notes=notes)


def _sqrt_or_none(x: float) -> float | None:
    return math.sqrt(x) if np.isfinite(x) else None


# ---------------------------------------------------------------------------- data preparation
def uniform_rates(imu: ImuData, max_gap_ratio: float = 1.5, jitter_tol: float = 1e-3):
    """Uniformly sampled rates from increments with their own intervals.

    Returns (rates (M, 6) [rad/s, m/s²] over uniform intervals of dt, dt [s], t_start [s], resampled
    (bool), notes). Gaps (intervals > ``max_gap_ratio`` × median): the longest gap-free part is used and
    the gaps reported in ``notes``. Jitter (any interval off the median by more than ``jitter_tol``
    relative): increments are averaged onto the uniform grid by cumulative-sum interpolation.
    """
    t = np.asarray(imu.time, float)
    if len(t) < 3:
        raise ValueError("characterise: need at least 3 IMU samples")
    t0 = imu.t0 if imu.t0 is not None else 2 * t[0] - t[1]
    edges = np.concatenate(([t0], t))
    dt = np.diff(edges)
    if np.any(dt <= 0):
        raise ValueError("characterise: sample times are not strictly increasing")
    med = float(np.median(dt))
    inc = np.concatenate((imu.dtheta, imu.dv), axis=1)
    notes: list[str] = []
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
        notes.append(f"{len(big)} gap(s) in the log (intervals longer than {max_gap_ratio:g} x the median "
                     f"{med:.6g} s; the longest {dt[worst]:.6g} s ending at t = {t[worst]:.3f} s): analysed "
                     f"the longest gap-free part t = {edges[a]:.3f}-{t[b - 1]:.3f} s "
                     f"({100.0 * (b - a) / len(t):.1f}% of the samples); gaps are never bridged")
        edges = edges[a:b + 1]
        inc = inc[a:b]
        dt = dt[a:b]
        if len(dt) < 3:
            raise ValueError("characterise: no gap-free part with at least 3 samples")
        med = float(np.median(dt))
    rel = np.max(np.abs(dt - med)) / med
    if rel <= jitter_tol:
        return inc / dt[:, None], med, float(edges[0]), False, notes
    # cumulative-sum interpolation onto the uniform grid t_start + j·med (mean rate removed first, for
    # precision of the running sums; added back after)
    span = edges[-1] - edges[0]
    mean_rate = inc.sum(axis=0) / span
    cum = np.vstack((np.zeros((1, 6)), np.cumsum(inc - mean_rate * dt[:, None], axis=0)))
    n = int(np.floor(span / med + 1e-9))
    grid = edges[0] + med * np.arange(n + 1)
    cg = np.column_stack([np.interp(grid, edges, cum[:, c]) for c in range(6)])
    rates = np.diff(cg, axis=0) / med + mean_rate
    notes.append(f"time stamps jitter by up to {100 * rel:.2g}% of the median interval {med:.6g} s: "
                 f"increments averaged onto a uniform {1 / med:.6g} Hz grid by cumulative-sum "
                 f"interpolation; the fit starts at tau = {RESAMPLED_MIN_M} intervals (resampling lowers "
                 "the first few points)")
    return rates, med, float(edges[0]), True, notes


def static_check(rates, fs: float, t_start: float = 0.0, window_s: float = 1.0,
                 gyro_tol_deg_s: float = 0.05, accel_tol_m_s2: float = 0.05, std_ratio: float = 4.0,
                 max_disturbed_fraction: float = 0.01) -> dict:
    """Is a log static? From window means and window variances of the gyros and accelerometers.

    rates : (M, 6) gyro [rad/s] and accel [m/s²] rates, uniform at ``fs`` [Hz]; t_start [s] of sample 0's
    interval. Windows of ``window_s`` (at least 10 samples). A window **moves** when the mean of any axis
    departs from the log's median window mean by more than max(tolerance, 8 × the robust spread of the
    window means) (tolerances: gyro ``gyro_tol_deg_s`` [deg/s], accel ``accel_tol_m_s2`` [m/s²]: turning
    or tilting); it is **disturbed** when the standard deviation inside the window of any axis exceeds
    ``std_ratio`` × the median window's (vibration, handling). The log is static when no window moves
    and at most ``max_disturbed_fraction`` of the windows are disturbed.

    Returns dict: static (bool), windows (count), moving / disturbed (counts), moving_spans_s /
    disturbed_spans_s (up to 10 [start, end] spans on the input time scale), max_gyro_dev_deg_s,
    max_accel_dev_m_s2, message (str, empty when static).
    """
    y = np.asarray(rates, float)
    w = max(10, int(round(window_s * fs)))
    nw = len(y) // w
    if nw < 3:
        return {"static": True, "windows": nw, "moving": 0, "disturbed": 0, "moving_spans_s": [],
                "disturbed_spans_s": [], "max_gyro_dev_deg_s": 0.0, "max_accel_dev_m_s2": 0.0,
                "message": "", "note": "log too short for the static check (fewer than 3 windows)"}
    blk = y[:nw * w].reshape(nw, w, y.shape[1])
    mean = blk.mean(axis=1)
    std = blk.std(axis=1)
    med = np.median(mean, axis=0)
    dev = np.abs(mean - med)
    mad = 1.4826 * np.median(dev, axis=0)
    tol = np.r_[np.full(3, gyro_tol_deg_s * DEG), np.full(3, accel_tol_m_s2)]
    moving = np.any(dev > np.maximum(tol, 8.0 * mad), axis=1)
    floor = np.r_[np.full(3, 1e-3 * DEG), np.full(3, 1e-3)]
    sref = np.maximum(np.median(std, axis=0), floor / std_ratio)
    disturbed = np.any(std > std_ratio * sref, axis=1)
    wdt = w / fs

    def spans(mask):
        idx = np.flatnonzero(mask)
        out = []
        if len(idx):
            br = np.flatnonzero(np.diff(idx) > 1)
            for s_, e_ in zip(np.r_[idx[0], idx[br + 1]], np.r_[idx[br], idx[-1]], strict=True):
                out.append([t_start + s_ * wdt, t_start + (e_ + 1) * wdt])
        return out

    ms, ds = spans(moving), spans(disturbed)
    static = (not moving.any()) and disturbed.mean() <= max_disturbed_fraction
    res = {"static": bool(static), "windows": int(nw), "moving": int(moving.sum()),
           "disturbed": int(disturbed.sum()), "moving_spans_s": ms[:10], "disturbed_spans_s": ds[:10],
           "max_gyro_dev_deg_s": float(dev[:, :3].max() / DEG), "max_accel_dev_m_s2": float(dev[:, 3:].max()),
           "message": ""}
    if not static:
        parts = []
        if moving.any():
            parts.append(f"it moves in {moving.sum()} of {nw} windows of {wdt:g} s (window means depart from "
                         f"the median by up to {res['max_gyro_dev_deg_s']:.3g} deg/s gyro, "
                         f"{res['max_accel_dev_m_s2']:.3g} m/s2 accel; first spans "
                         + ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in ms[:3]) + ")")
        if disturbed.mean() > max_disturbed_fraction:
            parts.append(f"{disturbed.sum()} of {nw} windows are disturbed (in-window spread above "
                         f"{std_ratio:g} x the typical; first spans "
                         + ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in ds[:3]) + ")")
        res["message"] = ("the log is not static: " + "; ".join(parts)
                          + ". Allan analysis needs a static log: choose a static part with --static START:END")
    return res


# ------------------------------------------------------------------------------------------ drivers
def characterise_rates(rates, fs: float, t_start: float = 0.0, min_m: int = 1, check_static: bool = True,
                       notes: list[str] | None = None, resampled: bool = False) -> Characterisation:
    """Characterise uniformly sampled rates (the Python API on arrays).

    rates : (M, 6) gyro x, y, z [rad/s] then accel x, y, z [m/s²], body frame, uniform at ``fs`` [Hz]
    (sample k is the average over (t_start + k/fs, t_start + (k+1)/fs]).
    min_m : smallest cluster size fitted. check_static : raise :class:`NotStaticError` when
    :func:`static_check` says the log moves.
    Returns a :class:`Characterisation` (ADEV at octave-spaced τ = 2^j/fs and the fitted terms, SI).
    """
    from aidnav.analysis.allan import allan_deviation

    y = np.asarray(rates, float)
    if y.ndim != 2 or y.shape[1] != 6:
        raise ValueError(f"characterise_rates: rates must be (M, 6), got {y.shape}")
    if not np.all(np.isfinite(y)):
        raise ValueError("characterise_rates: rates contain NaN or inf")
    notes = list(notes or [])
    n = len(y)
    dur = n / fs
    if n < 64:
        raise ValueError(f"characterise: only {n} samples ({dur:.3g} s); need at least 64")
    st = static_check(y, fs, t_start)
    if check_static and not st["static"]:
        raise NotStaticError(st["message"])
    if st.get("note"):
        notes.append(st["note"])
    if st["disturbed"] and st["static"]:
        notes.append(f"{st['disturbed']} of {st['windows']} one-second windows are disturbed (vibration or "
                     "handling); kept")
    taus, adev, _, _ = allan_deviation(y, fs, taus="octave")
    axes = [fit_allan(taus, adev[:, c], n, fs, axis=AXES[c], min_m=min_m) for c in range(6)]
    for a in axes:
        notes += a.notes
    notes.append(f"{dur:.6g} s of data: terms whose Allan signature lies beyond tau ~ {taus[-1]:.4g} s "
                 "(the longest tau with two clusters) cannot be seen")
    return Characterisation(axes=axes, fs_hz=float(fs), n_samples=n, duration_s=dur,
                            span_s=(float(t_start), float(t_start + dur)), resampled=resampled, static=st,
                            notes=notes)


def characterise_imu(imu: ImuData, static: tuple[float | None, float | None] | None = None,
                     check_static: bool = True) -> Characterisation:
    """Characterise an IMU log (increments with their own Δt; rates, any rate, jitter and gaps allowed).

    static : (start, end) [s] after the log's first time stamp (either None = open) to analyse only that
    part. Gaps → the longest gap-free part (reported); jitter → cumulative-sum resampling (reported).
    """
    notes = list(imu.events)
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
        notes.append(f"static part {a or 0:g}-{'end' if b is None else f'{b:g}'} s after the first sample "
                     "analysed")
    rates, dt, t_start, resampled, n2 = uniform_rates(imu)
    notes += n2
    return characterise_rates(rates, 1.0 / dt, t_start=t_start, min_m=RESAMPLED_MIN_M if resampled else 1,
                              check_static=check_static, notes=notes, resampled=resampled)


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


def noise_dict(ch: Characterisation) -> dict:
    """noise.json content: per axis, every term in the boundary units of CONVENTIONS with its status and
    95% interval, plus the ADEV table (deg/h for gyros, µg for accelerometers) and the notes."""
    axes = {}
    for a in ch.axes:
        units = _UNITS[a.sensor]
        d = {units[k][0]: a.terms[k].scaled(units[k][1]) for k in
             ("white", "quantisation", "bias_instability", "gm_sigma", "gm_tau", "rrw")}
        un, f = _ADEV_UNIT[a.sensor]
        d["model"] = list(a.model)
        d["fit"] = {"chi2": a.chi2, "dof": a.dof}
        d["allan"] = {"tau_s": a.taus.tolist(), f"adev_{un}": (a.adev / f).tolist(),
                      f"adev_lo_{un}": (a.adev_lo / f).tolist(), f"adev_hi_{un}": (a.adev_hi / f).tolist(),
                      "edf": a.edf.tolist(), "fitted": a.used.tolist()}
        axes[a.axis] = d
    return {
        "samples": ch.n_samples, "rate_hz": ch.fs_hz, "duration_s": ch.duration_s, "span_s": list(ch.span_s),
        "resampled": ch.resampled, "static_check": ch.static,
        "conventions": {
            "ci": "95% two-sided; from chi-square EDF (Greenhall) of each Allan variance",
            "bias_instability": "IEEE 952 B (flicker floor sigma = 0.6643 B) equivalent of the fitted "
                                "Gauss-Markov: B = 0.9294 gm_sigma; gm_tau = tau_peak / 1.8926",
            "quantisation": "IEEE 952 Q (AVAR = 3 Q^2 / tau^2); quantum = sqrt(12) Q",
            "status": "fitted | not resolved | not detected (then only upper_bound)",
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


def imu_section(ch: Characterisation, grade: str | None = None) -> tuple[dict, dict]:
    """The ``imu:`` section of an ``aidnav process`` configuration from a characterisation.

    One value per triad (the filter's keys are scalars): the largest axis value of each noise density
    and σ (conservative), the shortest correlation time. A triad whose Gauss-Markov and random walk are
    both fitted gets one Gauss-Markov bias with the same T and the driving noise of both,
    σ² = σ_GM² + K²T/2 (the filter has one bias process per sensor). The turn-on bias (run-to-run) cannot
    be seen in one static log: its σ is the grade default, combined with the fitted σ as √(σ_b² + σ²).
    Terms the log does not resolve take the grade default (``grade``; None = :func:`auto_grade`).

    Returns (values, comments): dicts keyed by the configuration key; comments say each value's source.
    """
    grade = grade or auto_grade(ch)
    gu = _grade_units(grade)
    vals: dict = {}
    com: dict = {}
    for sensor, axes in (("gyro", ch.axes[:3]), ("accel", ch.axes[3:])):
        g = sensor == "gyro"
        wkey, wdef, wunit = (("arw_deg_sqrt_h", gu["arw_deg_sqrt_h"], DEG_SQRT_H) if g
                             else ("vrw_m_s_sqrt_h", gu["vrw_m_s_sqrt_h"], M_S_SQRT_H))
        bunit, bname = (DEG_H, "deg/h") if g else (UG, "ug")
        rwunit, rwname = (DEG_H_SQRT_H, "deg/h/sqrt(h)") if g else (UG_SQRT_H, "ug/sqrt(h)")
        white = [a.terms["white"] for a in axes]
        if all(t.fitted for t in white):
            vals[wkey] = max(t.value for t in white) / wunit
            com[wkey] = "fitted (largest axis): " + ", ".join(
                f"{a.axis[-1]} {_fmt(t.value / wunit)} [{_fmt(t.lo / wunit)}, {_fmt(t.hi / wunit)}]"
                for a, t in zip(axes, white, strict=True))
        else:
            vals[wkey] = wdef
            com[wkey] = f"grade default ({grade}): the white noise is not resolved on every axis"
        p = "gyro" if g else "accel"
        ikey, tkey, rkey, skey = ((f"{p}_bias_instability_deg_h", f"{p}_bias_tau_s", f"{p}_bias_rw_deg_h_sqrt_h",
                                   f"{p}_bias_sigma_deg_h") if g else
                                  (f"{p}_bias_instability_ug", f"{p}_bias_tau_s", f"{p}_bias_rw_ug_sqrt_h",
                                   f"{p}_bias_sigma_ug"))
        gm_ok = all(a.terms["gm_sigma"].fitted for a in axes)
        rw_ok = all(a.terms["rrw"].fitted for a in axes)
        sig = max(a.terms["gm_sigma"].value for a in axes) if gm_ok else None
        tau = min(a.terms["gm_tau"].value for a in axes) if gm_ok else None
        kk = max(a.terms["rrw"].value for a in axes) if rw_ok else None
        gm_list = ", ".join(
            f"{a.axis[-1]} {_fmt(a.terms['gm_sigma'].value / bunit)} {bname} / "
            f"{_fmt(a.terms['gm_tau'].value)} s" for a in axes) if gm_ok else ""
        if gm_ok and rw_ok:
            s_eff = math.sqrt(sig**2 + kk**2 * tau / 2.0)
            vals[ikey], vals[tkey], vals[rkey] = s_eff / bunit, tau, kk / rwunit
            com[ikey] = (f"fitted Gauss-Markov sigma {_fmt(sig / bunit)} (largest axis; {gm_list}) merged with "
                         f"the fitted random walk: sqrt(sigma^2 + K^2 T/2)")
            com[tkey] = "fitted Gauss-Markov correlation time (shortest axis)"
            com[rkey] = (f"fitted random walk (largest axis); used by the filter only when {tkey} <= 0, here "
                         "merged into the Gauss-Markov above")
        elif gm_ok:
            vals[ikey], vals[tkey], vals[rkey] = sig / bunit, tau, 0.0
            com[ikey] = f"fitted Gauss-Markov sigma (largest axis; {gm_list})"
            com[tkey] = "fitted Gauss-Markov correlation time (shortest axis)"
            com[rkey] = "no random walk fitted (" + axes[0].terms["rrw"].status + "); unused while tau > 0"
        elif rw_ok:
            vals[ikey], vals[tkey], vals[rkey] = 0.0, 0.0, kk / rwunit
            com[ikey] = "no Gauss-Markov bias instability fitted: bias modelled as a random walk"
            com[tkey] = "0: random-walk bias"
            com[rkey] = "fitted random walk (largest axis): " + ", ".join(
                f"{a.axis[-1]} {_fmt(a.terms['rrw'].value / rwunit)}" for a in axes)
        else:
            di = gu["gyro_bias_instability_deg_h" if g else "accel_bias_instability_ug"]
            dt_ = gu["gyro_bias_corr_time_s" if g else "accel_bias_corr_time_s"]
            vals[ikey], vals[tkey], vals[rkey] = di, dt_, 0.0
            bound = max(a.terms["bias_instability"].upper or 0.0 for a in axes) / bunit
            com[ikey] = (f"grade default ({grade}): the log is too short (or too noisy) to resolve the bias "
                         f"instability; it bounds the flicker floor B below {_fmt(bound)} {bname}")
            com[tkey] = f"grade default ({grade})"
            com[rkey] = "not resolved; unused while tau > 0"
        tb = gu["gyro_bias_deg_h" if g else "accel_bias_ug"]
        vals[skey] = math.hypot(tb, vals[ikey])
        com[skey] = (f"turn-on bias {_fmt(tb)} {bname}: grade default ({grade}), one static log cannot show "
                     f"the run-to-run bias; combined with the instability above as sqrt(b^2 + sigma^2)")
    order = ["arw_deg_sqrt_h", "vrw_m_s_sqrt_h", "gyro_bias_sigma_deg_h", "accel_bias_sigma_ug",
             "gyro_bias_instability_deg_h", "accel_bias_instability_ug", "gyro_bias_tau_s", "accel_bias_tau_s",
             "gyro_bias_rw_deg_h_sqrt_h", "accel_bias_rw_ug_sqrt_h"]
    return {k: float(vals[k]) for k in order}, {k: com[k] for k in order}


def imu_yaml(ch: Characterisation, grade: str | None = None, source: str = "") -> str:
    """YAML text of the ``imu:`` section with each number's source in a comment (see :func:`imu_section`)."""
    vals, com = imu_section(ch, grade)
    head = [f"# imu: section for `aidnav process`, from `aidnav characterise` of {source or 'a static log'}",
            f"# ({ch.n_samples} samples at {ch.fs_hz:.6g} Hz, {ch.duration_s:.6g} s). Values per axis in "
            "brackets are 95% intervals.",
            "# One value per triad: the largest axis noise and sigma, the shortest correlation time."]
    lines = ["imu:"]
    for k, v in vals.items():
        lines.append(f"  {k}: {v!r}  # {com[k]}")
    return "\n".join(head + lines) + "\n"


def characterise_file(imu_path, out_dir, static: str | None = None, grade: str | None = None) -> tuple:
    """``aidnav characterise``: read any IMU log, characterise it, write allan.png, noise.json, imu.yaml.

    static : "START:END" seconds after the first sample (either may be empty). Returns
    (Characterisation, list of written paths). Raises :class:`NotStaticError` / ValueError with a clear
    message for a moving log, bad option or unusable data.
    """
    from aidnav.process import read_imu_any
    from aidnav.report.allan_plot import plot_allan

    rng = None
    if static:
        parts = static.split(":")
        try:
            if len(parts) != 2:
                raise ValueError
            rng = (float(parts[0]) if parts[0].strip() else None, float(parts[1]) if parts[1].strip() else None)
        except ValueError:
            raise ValueError(f"--static {static!r}: expected START:END in seconds after the first sample"
                             ) from None
        if rng[0] is not None and rng[1] is not None and rng[1] <= rng[0]:
            raise ValueError(f"--static {static!r}: END must be after START")
    imu = read_imu_any(imu_path)
    ch = characterise_imu(imu, static=rng)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    nd = noise_dict(ch)
    nd["imu"] = str(imu_path)
    nd["grade_for_defaults"] = grade or auto_grade(ch)
    p_json = out / "noise.json"
    p_json.write_text(json.dumps(nd, indent=2))
    p_yaml = out / "imu.yaml"
    p_yaml.write_text(imu_yaml(ch, nd["grade_for_defaults"], source=str(imu_path)))
    p_png = plot_allan(ch, out / "allan.png", title=f"Allan deviation: {Path(imu_path).name}")
    return ch, [p_png, p_json, p_yaml]
