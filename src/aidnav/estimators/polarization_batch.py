"""Batch polarization attitude fixes (seed 002, §3) in numba: many fixes per call.

:func:`estimate_attitude_batch` does for K fixes what :func:`aidnav.estimators.polarization.
estimate_attitude` (method "ml") does for one, with the same conventions and results (tested against it
fix by fix), without a Python call per fix:

1. principal eigenvector of R̂ and the closed form (§3.3, corrected seed eqs. 2–4) as the start;
2. concentrated ML: maximise f(φ, θ, γ) = AᴴR̂A by Newton steps with the analytic gradient
   2 Re{DᴴR̂A} and a Hessian from central differences of that gradient (h = 1e-5 rad, error ~1e-10
   relative); a step that does not increase f is replaced by a backtracked gradient step. From the closed
   form (within ~1e-4 rad of the optimum) 2–4 steps reach a gradient norm (of f / tr R̂) below 1e-10;
3. canonical ranges (θ ∈ [−π/2, π/2], γ ∈ (−π/2, π/2]) through the wave-frame DCM;
4. line-of-sight resolution (γ or γ + π: the candidate closest to ``prior``, or the upright one),
   C_b^n = base_to_local · P C_W^B C_I^W Pᵀ, (roll, pitch, heading);
5. the attitude CRB at the estimated SNR: the CVAE bound (1+ρ)/(2Nρ²)·diag(1/cos²2η, 1/sin²η, 1/cos²η)
   of the wave-frame rotation (the same for every DOA and tilt, §3.5) mapped to the misalignment ε
   in n and to (roll, pitch, heading).

:func:`sample_covariance_batch` forms R̂ = (1/N) Σ S(t) S(t)ᴴ for K snapshot blocks.

Bad input raises ValueError as the single-fix API does (η = 0 or |η| ≥ 45°, non-finite input, wrong
shapes, n < 1); a fix whose estimated source is at θ = ±90° (φ and γ unobservable) raises ValueError
naming the fix index, unless ``on_zenith="nan"``, which returns NaN for that fix and counts it.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from aidnav.estimators.polarization import (
    ZENITH_TOL,
    check_eta,
    check_snapshots,
    zenith_error,
)
from aidnav.estimators.polarization import objective_gradient as _objective_gradient
from aidnav.jit import njit
from aidnav.nav.rotations import euler_from_dcm
from aidnav.nav.wave_frame import P_SEED

__all__ = ["AttitudeFixBatch", "estimate_attitude_batch", "sample_covariance_batch"]

_FD_H = 1e-5  #: step of the central-difference Hessian [rad]
_GTOL = 1e-10  #: convergence: |∇(f / tr R̂)| below this
_MAXIT = 50


# ------------------------------------------------------------------------------------ kernels
@njit(cache=True)
def sample_covariance_kernel(S, out):
    """R̂_k = (1/N) Σ_t S[k, t] S[k, t]ᴴ for S (K, N, 3) complex → out (K, 3, 3)."""
    K, N = S.shape[0], S.shape[1]
    for k in range(K):
        acc = np.zeros((3, 3), np.complex128)
        for t in range(N):
            s0, s1, s2 = S[k, t, 0], S[k, t, 1], S[k, t, 2]
            acc[0, 0] += s0 * np.conj(s0)
            acc[0, 1] += s0 * np.conj(s1)
            acc[0, 2] += s0 * np.conj(s2)
            acc[1, 1] += s1 * np.conj(s1)
            acc[1, 2] += s1 * np.conj(s2)
            acc[2, 2] += s2 * np.conj(s2)
        for i in range(3):
            for j in range(i, 3):
                out[k, i, j] = acc[i, j] / N
                if j > i:
                    out[k, j, i] = np.conj(acc[i, j]) / N


@njit(cache=True)
def _wave_dcm(phi, theta, gamma):
    """C_I^W = Rx(γ) Ry(θ) Rz(φ): rows u, ṽ1, ṽ2 (:func:`aidnav.nav.wave_frame.wave_dcm`)."""
    cp, sp = np.cos(phi), np.sin(phi)
    ct, st = np.cos(theta), np.sin(theta)
    cg, sg = np.cos(gamma), np.sin(gamma)
    C = np.empty((3, 3))
    v1 = np.array([-sp, cp, 0.0])
    v2 = np.array([-cp * st, -sp * st, ct])
    C[0, 0], C[0, 1], C[0, 2] = cp * ct, sp * ct, st
    for i in range(3):
        C[1, i] = cg * v1[i] - sg * v2[i]
        C[2, i] = sg * v1[i] + cg * v2[i]
    return C


@njit(cache=True)
def _closed_form(a, eta):
    """Closed form (φ, θ, γ) from a steering-vector estimate a (3,) (:func:`polarization.closed_form`);
    returns (φ, θ, γ, ok) with ok False at θ = ±90° (a_z ≈ 0)."""
    nrm2 = 0.0
    for i in range(3):
        nrm2 += a[i].real ** 2 + a[i].imag ** 2
    ax, ay, az = a[0], a[1], a[2]
    az2 = az.real ** 2 + az.imag ** 2
    if az2 <= ZENITH_TOL**2 * nrm2:
        return 0.0, 0.0, 0.0, False
    xz = ax * np.conj(az)
    yz = ay * np.conj(az)
    sgn = 1.0 if eta > 0 else -1.0
    phi = np.arctan2(sgn * xz.imag, -sgn * yz.imag)
    cp, sp = np.cos(phi), np.sin(phi)
    theta = np.arctan(-(xz.real * cp + yz.real * sp) / az2)
    ct, st = np.cos(theta), np.sin(theta)
    j1 = -sp * ax + cp * ay
    j2 = -cp * st * ax - sp * st * ay + ct * az
    s1 = (j1.real ** 2 + j1.imag ** 2) - (j2.real ** 2 + j2.imag ** 2)
    s2 = 2.0 * (j1 * np.conj(j2)).real
    c2 = 1.0 if np.cos(2.0 * eta) >= 0 else -1.0
    return phi, theta, _wrap_tilt(0.5 * np.arctan2(-s2 * c2, s1 * c2)), True


@njit(cache=True)
def _wrap_tilt(g):
    """Fold a tilt [rad] into (−π/2, π/2]."""
    w = (g + 0.5 * np.pi) % np.pi - 0.5 * np.pi
    if w <= -0.5 * np.pi + 1e-15:
        w += np.pi
    return w


@njit(cache=True)
def _canonical(p):
    """(φ, θ, γ) in the canonical ranges through the wave-frame DCM (wave_params_from_dcm)."""
    C = _wave_dcm(p[0], p[1], p[2])
    phi = np.arctan2(C[0, 1], C[0, 0])
    u2 = min(1.0, max(-1.0, C[0, 2]))
    theta = np.arcsin(u2)
    cp, sp = np.cos(phi), np.sin(phi)
    ct, st = np.cos(theta), np.sin(theta)
    t1v1 = -sp * C[1, 0] + cp * C[1, 1]
    t1v2 = -cp * st * C[1, 0] - sp * st * C[1, 1] + ct * C[1, 2]
    return phi, theta, _wrap_tilt(np.arctan2(-t1v2, t1v1))


@njit(cache=True)
def _ml(R, eta, p):
    """Newton maximisation of AᴴR̂A from p (3,), in place; returns (f, iterations, converged)."""
    ce, se = np.cos(eta), np.sin(eta)
    scale = 1.0 / (R[0, 0].real + R[1, 1].real + R[2, 2].real)
    g = np.empty(3)
    gp = np.empty(3)
    gm = np.empty(3)
    H = np.empty((3, 3))
    q = np.empty(3)
    f = _objective_gradient(p, R, ce, se, g)
    it = 0
    while it < _MAXIT:
        if np.sqrt(g[0] ** 2 + g[1] ** 2 + g[2] ** 2) * scale < _GTOL:
            return f, it, True
        it += 1
        for j in range(3):
            q[:] = p
            q[j] += _FD_H
            _objective_gradient(q, R, ce, se, gp)
            q[j] -= 2.0 * _FD_H
            _objective_gradient(q, R, ce, se, gm)
            for i in range(3):
                H[i, j] = (gp[i] - gm[i]) / (2.0 * _FD_H)
        H = 0.5 * (H + H.T)
        step = np.zeros(3)
        newton = True
        # a maximum needs −H positive definite (Cholesky succeeds)
        if -H[0, 0] <= 0.0:
            newton = False
        else:
            l00 = np.sqrt(-H[0, 0])
            l10 = -H[1, 0] / l00
            d1 = -H[1, 1] - l10 * l10
            if d1 <= 0.0:
                newton = False
            else:
                l11 = np.sqrt(d1)
                l20 = -H[2, 0] / l00
                l21 = (-H[2, 1] - l20 * l10) / l11
                d2 = -H[2, 2] - l20 * l20 - l21 * l21
                if d2 <= 0.0:
                    newton = False
                else:
                    l22 = np.sqrt(d2)
                    # solve (−H) step = g with L Lᵀ
                    y0 = g[0] / l00
                    y1 = (g[1] - l10 * y0) / l11
                    y2 = (g[2] - l20 * y0 - l21 * y1) / l22
                    step[2] = y2 / l22
                    step[1] = (y1 - l21 * step[2]) / l11
                    step[0] = (y0 - l10 * step[1] - l20 * step[2]) / l00
        if not newton:
            gn = np.sqrt(g[0] ** 2 + g[1] ** 2 + g[2] ** 2)
            for i in range(3):
                step[i] = 0.1 * g[i] / gn  # ascent direction, 0.1 rad, backtracked below
        alpha = 1.0
        accepted = False
        for _ in range(40):
            for i in range(3):
                q[i] = p[i] + alpha * step[i]
            fq = _objective_gradient(q, R, ce, se, gp)
            if fq >= f - 1e-15 * abs(f):
                p[:] = q
                g[:] = gp
                f = fq
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            return f, it, np.sqrt(g[0] ** 2 + g[1] ** 2 + g[2] ** 2) * scale < 1e-7
    return f, it, False


@njit(cache=True)
def _attitude(phi, theta, gamma, bwd, B2L):
    """C_b^n = B2L · P · C_W^B · C_I^W(φ, θ, γ) · Pᵀ (bwd = C_W^B)."""
    return B2L @ P_SEED @ bwd @ _wave_dcm(phi, theta, gamma) @ P_SEED.T


@njit(cache=True)
def _euler_jacobian(roll, pitch, heading):
    """J_E of :func:`aidnav.estimators.polarization.euler_error_jacobian`."""
    psi = -heading
    cy, sy = np.cos(psi), np.sin(psi)
    cp, sp = np.cos(pitch), np.sin(pitch)
    M = np.array([[-sy * cp, cy, 0.0], [cy * cp, sy, 0.0], [sp, 0.0, 1.0]])
    J = -np.linalg.inv(M)
    for j in range(3):
        J[2, j] = -J[2, j]
    return J


# the batch kernel's inputs and (preallocated) outputs
BatchIn = namedtuple("BatchIn", ["R", "n", "eta", "bearing", "elevation", "tx_tilt", "B2L", "prior",
                                 "has_prior"])
BatchOut = namedtuple("BatchOut", ["wave", "snr", "objective", "nit", "converged", "flipped", "C_out", "rph",
                                   "cov_eps", "cov_rph", "status"])


@njit(cache=True)
def batch_kernel(inp, out):
    """K fixes; ``inp`` :data:`BatchIn`: R (K, 3, 3) complex; n snapshots; bearing/elevation/tx_tilt (K,)
    [rad]; B2L (K, 3, 3); prior (K, 3, 3) used where has_prior. ``out`` :data:`BatchOut`: outputs per
    fix, filled in place; status 0 ok, 1 source at θ = ±90°."""
    R, n, eta, bearing, elevation, tx_tilt, B2L, prior, has_prior = inp
    wave, snr, objective, nit, converged, flipped, C_out, rph, cov_eps, cov_rph, status = out
    K = R.shape[0]
    ce2 = np.cos(2.0 * eta) ** 2
    se2, c2e = np.sin(eta) ** 2, np.cos(eta) ** 2
    p = np.empty(3)
    for k in range(K):
        Rk = R[k]
        w, V = np.linalg.eigh(Rk)
        a = V[:, 2].copy()
        phi0, th0, g0, ok = _closed_form(a, eta)
        if not ok:
            status[k] = 1
            continue
        p[0], p[1], p[2] = phi0, th0, g0
        f, it, conv = _ml(Rk, eta, p)
        phi, theta, gamma = _canonical(p)
        if abs(np.cos(theta)) <= ZENITH_TOL:
            status[k] = 1
            continue
        status[k] = 0
        tr = Rk[0, 0].real + Rk[1, 1].real + Rk[2, 2].real
        s2 = 0.5 * (tr - f)
        pw = f - s2
        rho = pw / s2 if s2 > 0 else np.inf
        # line of sight: γ or γ ± π
        bwd = _wave_dcm(-bearing[k] + np.pi, -elevation[k], tx_tilt[k]).T
        g2 = gamma + np.pi if gamma <= 0 else gamma - np.pi
        C1 = _attitude(phi, theta, gamma, bwd, B2L[k])
        C2 = _attitude(phi, theta, g2, bwd, B2L[k])
        if has_prior:
            s1 = np.trace(C1 @ prior[k].T)
            s2_ = np.trace(C2 @ prior[k].T)
        else:
            s1 = C1[2, 2]
            s2_ = C2[2, 2]
        if s2_ > s1:
            gamma, C = g2, C2
            flipped[k] = True
        else:
            C = C1
            flipped[k] = False
        wave[k, 0], wave[k, 1], wave[k, 2] = phi, theta, gamma
        snr[k] = rho
        objective[k] = f
        nit[k] = it
        converged[k] = conv
        C_out[k] = C
        e = euler_from_dcm(C)
        rph[k, 0], rph[k, 1], rph[k, 2] = e[0], e[1], e[2]
        # CRB: factor · G diag(1/cos²2η, 1/sin²η, 1/cos²η) Gᵀ, G = B2L P C_W^B
        r = 1.0 / max(rho, 1e-6)
        fac = (r + r * r) / (2.0 * n)
        G = B2L[k] @ P_SEED @ bwd
        d = np.array([1.0 / ce2, 1.0 / se2, 1.0 / c2e]) * fac
        ce_ = np.zeros((3, 3))
        for i in range(3):
            for j in range(3):
                s = 0.0
                for m in range(3):
                    s += G[i, m] * d[m] * G[j, m]
                ce_[i, j] = s
        cov_eps[k] = ce_
        JE = _euler_jacobian(e[0], e[1], e[2])
        cov_rph[k] = JE @ ce_ @ JE.T


# ------------------------------------------------------------------------------------ API
@dataclass
class AttitudeFixBatch:
    """K polarization attitude fixes (the fields of :class:`~aidnav.estimators.polarization.AttitudeFix`
    stacked): rph (K, 3) [rad]; C_bn (K, 3, 3); cov_eps, cov_rph (K, 3, 3) [rad²]; wave (K, 3) (φ, θ, γ)
    [rad]; snr (K,) linear; flipped (K,) bool; objective (K,) the maximised AᴴR̂A; nit (K,) Newton
    steps; converged (K,) bool; valid (K,) False where the source was at θ = ±90° (then NaN, only with
    ``on_zenith="nan"``); n snapshots."""

    rph: np.ndarray
    C_bn: np.ndarray
    cov_eps: np.ndarray
    cov_rph: np.ndarray
    wave: np.ndarray
    snr: np.ndarray
    flipped: np.ndarray
    objective: np.ndarray
    nit: np.ndarray
    converged: np.ndarray
    valid: np.ndarray
    n: int

    def __len__(self) -> int:
        return len(self.snr)


def sample_covariance_batch(S) -> np.ndarray:
    """R̂ = (1/N) Σ S(t) S(t)ᴴ for snapshot blocks S (K, N, 3) complex → (K, 3, 3).

    ValueError for a wrong shape (N ≥ 1 needed) or NaN/inf entries."""
    S = np.asarray(S, dtype=np.complex128)
    if S.ndim != 3 or S.shape[2] != 3 or S.shape[1] < 1:
        raise ValueError(f"S must have shape (K, N, 3) with N >= 1 snapshots, got {S.shape}")
    if not np.all(np.isfinite(S)):
        raise ValueError("S (snapshots) contains NaN or inf")
    out = np.empty((S.shape[0], 3, 3), np.complex128)
    sample_covariance_kernel(np.ascontiguousarray(S), out)
    return out


def _per_fix(x, K, name):
    a = np.asarray(x, dtype=float)
    if a.ndim == 0:
        a = np.full(K, float(a))
    if a.shape != (K,):
        raise ValueError(f"{name} must be a scalar or have shape ({K},), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or inf")
    return np.ascontiguousarray(a)


def _per_fix_dcm(x, K, name, default):
    if x is None:
        return np.ascontiguousarray(np.broadcast_to(default, (K, 3, 3))), False
    a = np.asarray(x, dtype=float)
    if a.shape == (3, 3):
        a = np.broadcast_to(a, (K, 3, 3))
    if a.shape != (K, 3, 3):
        raise ValueError(f"{name} must have shape (3, 3) or ({K}, 3, 3), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or inf")
    return np.ascontiguousarray(a), True


def estimate_attitude_batch(R, n, eta, bearing, elevation, tx_tilt, prior=None, base_to_local=None,
                            on_zenith: str = "raise") -> AttitudeFixBatch:
    """Concentrated-ML attitude fixes for K sample covariances R̂ (K, 3, 3) of n snapshots each.

    eta : known ellipticity [rad] (0 < |η| < π/4); bearing, elevation, tx_tilt : [rad], scalars or (K,)
    (bearing clockwise from North, as :func:`~aidnav.estimators.polarization.estimate_attitude`);
    prior : C_b^n (3, 3) or (K, 3, 3) to resolve the line-of-sight ambiguity (None: upright);
    base_to_local : C_{n_base}^{n}, (3, 3) or (K, 3, 3) (None: identity, the seed's flat Earth);
    on_zenith : "raise" (ValueError naming the first fix whose source is at θ = ±90°) or "nan".
    """
    eta = check_eta(eta)
    n = check_snapshots(n)
    R = np.asarray(R)
    if R.ndim != 3 or R.shape[1:] != (3, 3):
        raise ValueError(f"R must have shape (K, 3, 3), got {R.shape}")
    if not np.all(np.isfinite(R)):
        raise ValueError("R contains NaN or inf")
    R = np.ascontiguousarray(R, dtype=np.complex128)
    tr = np.trace(R, axis1=1, axis2=2).real
    if np.any(tr <= 0):
        raise ValueError(f"R has a non-positive trace (no signal) at fix {int(np.argmax(tr <= 0))}")
    if on_zenith not in ("raise", "nan"):
        raise ValueError(f"on_zenith must be 'raise' or 'nan', got {on_zenith!r}")
    K = R.shape[0]
    brg = _per_fix(bearing, K, "bearing")
    el = _per_fix(elevation, K, "elevation")
    tx = _per_fix(tx_tilt, K, "tx_tilt")
    B2L, _ = _per_fix_dcm(base_to_local, K, "base_to_local", np.eye(3))
    pri, has_prior = _per_fix_dcm(prior, K, "prior", np.eye(3))
    wave = np.full((K, 3), np.nan)
    snr = np.full(K, np.nan)
    obj = np.full(K, np.nan)
    nit = np.zeros(K, np.int64)
    conv = np.zeros(K, np.bool_)
    flipped = np.zeros(K, np.bool_)
    C = np.full((K, 3, 3), np.nan)
    rph = np.full((K, 3), np.nan)
    cov_eps = np.full((K, 3, 3), np.nan)
    cov_rph = np.full((K, 3, 3), np.nan)
    status = np.zeros(K, np.int64)
    batch_kernel(BatchIn(R, float(n), float(eta), brg, el, tx, B2L, pri, has_prior),
                 BatchOut(wave, snr, obj, nit, conv, flipped, C, rph, cov_eps, cov_rph, status))
    valid = status == 0
    if on_zenith == "raise" and not np.all(valid):
        k = int(np.argmin(valid))
        raise ValueError(f"fix {k}: {zenith_error()}")
    return AttitudeFixBatch(rph, C, cov_eps, cov_rph, wave, snr, flipped, obj, nit, conv, valid, n)

