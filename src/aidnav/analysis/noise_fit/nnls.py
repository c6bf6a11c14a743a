"""Numba kernels of the fit: the model's columns, exact small NNLS, Gauss-Newton on the log scale, T search.

Objective: ‖L⁻¹ r‖² with r_j = (y_j − ln M_j(θ))/s_j, y_j = ln σ̂²_j − E ln(χ²_ν/ν), s_j = sd ln(χ²_ν/ν), and
L the Cholesky factor of the correlation of the estimates (L⁻¹ lower triangular). For a fixed correlation
time T the model M = A c is linear in c = (Q², N², σ², K²) ≥ 0: Gauss-Newton on ln M with an exact
non-negative least-squares step (all active sets of the ≤ 4 columns enumerated) and step halving; T by a
grid and golden section. The kernels are plain loops (no BLAS calls: the matrices are at most ~25 × 25, and
the loops compile in a fraction of the time) and release the GIL, so the six axes are fitted in parallel.
"""

from __future__ import annotations

import numpy as np

from aidnav.analysis.noise_fit.model import GM_SERIES
from aidnav.jit import njit


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
        for k in range(len(GM_SERIES) - 1, -1, -1):
            acc = (acc + GM_SERIES[k]) * x
        return acc
    return (2.0 / x) * (1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))


@njit(cache=True, nogil=True)
def columns_nb(tau, u):
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
def _solve_small(G, r, idx, n, M, x):
    """Solve G[idx, idx] x = r[idx] (n ≤ 4) by Gaussian elimination with partial pivoting into x[:n]
    (M: a work array of at least n × (n + 1)); False if (nearly) singular (x[:n] = 0)."""
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
            x[:n] = 0.0
            return False
        if p != col:
            for j in range(n + 1):
                tmp = M[col, j]
                M[col, j] = M[p, j]
                M[p, j] = tmp
        for i in range(col + 1, n):
            f = M[i, col] / M[col, col]
            for j in range(col, n + 1):
                M[i, j] -= f * M[col, j]
    for i in range(n):
        x[i] = 0.0
    for i in range(n - 1, -1, -1):
        acc = M[i, n]
        for j in range(i + 1, n):
            acc -= M[i, j] * x[j]
        x[i] = acc / M[i, i]
    return True


@njit(cache=True, nogil=True)
def _nnls_enum(A, b, free, G, r, M, x, idx):
    """min ||A c − b|| over c ≥ 0 with c_i = 0 where not free[i] (k ≤ 4: every active set is tried; the
    columns of A should have comparable norms). G (k, k), r (k), M (k, k + 1), x (k), idx (k, int64):
    work arrays."""
    n, k = A.shape
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
        if not _solve_small(G, r, idx, nsel, M, x):
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
def _objective(y, s, Linv, M, r):
    """‖L⁻¹ (y − ln M)/s‖² (L⁻¹ lower triangular; r: a work array of n values)."""
    n = y.shape[0]
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
def fit_c_nb(A, y, s, Linv, fixed, fixv, c0, iters):
    """Coefficients c ≥ 0 for fixed columns A (n, 4) minimising the correlated log-scale objective
    ‖L⁻¹ (y − ln A c)/s‖²; coefficients where ``fixed`` are held at ``fixv``. Gauss-Newton on the
    linearisation ln M ≈ ln M₀ + (M − M₀)/M₀ with an exact NNLS step and step halving.
    Returns (objective, c)."""
    n, k = A.shape
    free = ~fixed
    res = np.empty(n)  # the objective's residuals
    G = np.empty((k, k))  # the NNLS's work arrays
    rg = np.empty(k)
    Ms = np.empty((k, k + 1))
    xs = np.empty(k)
    idx = np.empty(k, np.int64)
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
        q_old = _objective(y, s, Linv, M, res)
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
        c_new = _nnls_enum(Aw, bw, free, G, rg, Ms, xs, idx) / scale
        lam = 1.0
        c_try = c_new
        q_try = np.inf
        for _h in range(12):
            c_try = c + lam * (c_new - c) if q_old < np.inf else c_new
            _model_nb(A, c_try, off, M_try)
            q_try = _objective(y, s, Linv, M_try, res)
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
def profile_u_nb(tau, y, s, Linv, fixed, fixv, u_lo, u_hi, ngrid, c0, u_hint):
    """min over T (a grid plus ``u_hint`` (NaN: none), then golden section around the best) and the free
    coefficients. Without a Gauss-Markov term (σ² fixed at 0) T is not searched.
    Returns (objective, u, c)."""
    if fixed[2] and fixv[2] == 0.0:
        u = 0.5 * (u_lo + u_hi) if np.isnan(u_hint) else u_hint
        d, c = fit_c_nb(columns_nb(tau, u), y, s, Linv, fixed, fixv, c0, 60)
        return d, u, c
    best_d = np.inf
    best_u = u_lo
    best_c = c0.copy()
    step = (u_hi - u_lo) / (ngrid - 1)
    n_c = ngrid + (0 if np.isnan(u_hint) else 1)
    for g in range(n_c):
        u = u_lo + g * step if g < ngrid else u_hint
        d, c = fit_c_nb(columns_nb(tau, u), y, s, Linv, fixed, fixv, c0, 60)
        if d < best_d:
            best_d, best_u, best_c = d, u, c
    lo = max(u_lo, best_u - step)
    hi = min(u_hi, best_u + step)
    gr = 0.6180339887498949
    x1 = hi - gr * (hi - lo)
    x2 = lo + gr * (hi - lo)
    d1, c1 = fit_c_nb(columns_nb(tau, x1), y, s, Linv, fixed, fixv, best_c, 60)
    d2, c2 = fit_c_nb(columns_nb(tau, x2), y, s, Linv, fixed, fixv, best_c, 60)
    for _ in range(30):
        if hi - lo < 5e-3:
            break
        if d1 < d2:
            hi, x2, d2, c2 = x2, x1, d1, c1
            x1 = hi - gr * (hi - lo)
            d1, c1 = fit_c_nb(columns_nb(tau, x1), y, s, Linv, fixed, fixv, c1, 60)
        else:
            lo, x1, d1, c1 = x1, x2, d2, c2
            x2 = lo + gr * (hi - lo)
            d2, c2 = fit_c_nb(columns_nb(tau, x2), y, s, Linv, fixed, fixv, c2, 60)
    if d1 < best_d:
        best_d, best_u, best_c = d1, x1, c1
    if d2 < best_d:
        best_d, best_u, best_c = d2, x2, c2
    return best_d, best_u, best_c
