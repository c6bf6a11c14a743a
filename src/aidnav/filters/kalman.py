"""The one Kalman filter core of aidnav (numba): discretisation, predict, Joseph update, gating, RTS.

Every filter in aidnav (loosely/tightly coupled, antenna aiding, transfer alignment, federated) is
this core plus a state layout, a process model F, G, q and measurement functions that fill H, z, R.
The functions are small and work on caller-owned arrays so that numba kernels can call them at high
rate without allocation-heavy Python objects.

Discretisation (``discretize``): Φ = I + F T + (F T)²/2 and, with Q = G diag(q) Gᵀ,
Qd = Q T + (F Q + Q Fᵀ) T²/2 + (F² Q + 2 F Q Fᵀ + Q F²ᵀ) T³/6, the Taylor series of the exact
integral ∫ Φ(s) Q Φ(s)ᵀ ds to third order (the common trapezoid ½(Φ Q Φᵀ + Q) T is second order).
The series is accurate when ‖F‖ T ≪ 1: for INS error models ‖F‖ is of the order of the Schuler
frequency and 1/τ of the Markov states (≤ 1e-2 s⁻¹ typical; up to 1 s⁻¹ for flexure states), so at
T ≤ 1 s the truncation is below 1e-3 relative for navigation states. :func:`van_loan` (scipy
``expm``, exact for a piecewise-constant F) is the reference used in the tests.

Update: Joseph form P = (I − K H) P (I − K H)ᵀ + K R Kᵀ (expanded: O(n²m), symmetric); the innovation
ν = z − H x is gated with its Mahalanobis distance νᵀ S⁻¹ ν against a chi-square quantile
(``gate`` ≤ 0 disables gating).
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit

# numba's fast-math flags that keep IEEE semantics for NaN and infinity (no ``nnan``/``ninf``: a NaN still
# propagates and every ``np.isnan`` test and comparison with NaN still holds) but let LLVM reassociate sums
# (vectorised reductions), fuse multiply-adds, ignore the sign of zero and use reciprocals: results differ
# from the strict IEEE order at rounding only. Used where P's products are the time (issue 40, session 18).
SAFE_FASTMATH = {"reassoc", "contract", "nsz", "arcp"}


@njit(cache=True)
def discretize(F, G, q, T, Phi, Qd):
    """Fill ``Phi`` and ``Qd`` from continuous F (n×n), G (n×m), noise PSD diag ``q`` (m,) over ``T`` [s]."""
    n = F.shape[0]
    FT = F * T
    Phi[:, :] = FT @ FT
    Phi *= 0.5
    Phi += FT
    for i in range(n):
        Phi[i, i] += 1.0
    Gq = G * q  # G diag(q)
    Q = Gq @ G.T
    FQ = F @ Q
    FFQ = F @ FQ
    FQF = FQ @ F.T
    # Qd = Q T + (FQ + QFᵀ) T²/2 + (F²Q + 2 F Q Fᵀ + Q F²ᵀ) T³/6 (element loop: no temporaries)
    c2, c3 = 0.5 * T * T, T * T * T / 6.0
    for i in range(n):
        for j in range(n):
            Qd[i, j] = (Q[i, j] * T + (FQ[i, j] + FQ[j, i]) * c2
                        + (FFQ[i, j] + FFQ[j, i] + 2.0 * FQF[i, j]) * c3)


@njit(cache=True)
def predict(x, P, Phi, Qd):
    """x ← Φ x, P ← Φ P Φᵀ + Qd (symmetrised). In place."""
    x[:] = Phi @ x
    A = Phi @ P @ Phi.T
    n = P.shape[0]
    for i in range(n):  # P = ½ (A + Qd + (A + Qd)ᵀ), no temporaries
        for j in range(n):
            P[i, j] = ((A[i, j] + Qd[i, j]) + (A[j, i] + Qd[j, i])) * 0.5


@njit(cache=True)
def discretize_tail(F, qt, T, Phi, Qd, nd):
    """Φ, Qd of the scalar states i ≥ ``nd`` (diagonal F, noise PSD ``qt[i]`` = Σ_c G²_ic q_c of inputs
    of their own): :func:`discretize`'s Taylor series for a scalar, Φ = 1 + f + f²/2, Qd = q T (1 + f
    + 2f²/3), f = F_ii T. Writes the diagonal only."""
    for i in range(nd, F.shape[0]):
        f = F[i, i] * T
        Phi[i, i] = 1.0 + f + 0.5 * f * f
        Qd[i, i] = qt[i] * T * (1.0 + f + 2.0 * f * f / 3.0)


@njit(cache=True)
def predict_tail(x, P, Phi, Qd, nd):
    """:func:`predict` for a Φ, Qd that are block diagonal: a full block of the first ``nd`` states and a
    diagonal after it (independent scalar Markov states such as per-satellite range errors: no other
    state drives them and they drive none). The head block is the matrix product, the rest scaling:
    P₁₁ ← Φ₁ P₁₁ Φ₁ᵀ + Qd₁, P₁₂ ← Φ₁ P₁₂ D, P₂₂ ← D P₂₂ D + Qd₂ (D = diag Φ₂). Same result as
    :func:`predict` (to rounding); off-block entries of Φ and Qd are not read."""
    n = P.shape[0]
    Ph = np.ascontiguousarray(Phi[:nd, :nd])
    x[:nd] = Ph @ x[:nd].copy()
    for i in range(nd, n):
        x[i] *= Phi[i, i]
    A = Ph @ np.ascontiguousarray(P[:nd, :nd]) @ Ph.T
    for i in range(nd):
        for j in range(i, nd):
            v = ((A[i, j] + Qd[i, j]) + (A[j, i] + Qd[j, i])) * 0.5
            P[i, j] = v
            P[j, i] = v
    if nd == n:
        return
    B = Ph @ np.ascontiguousarray(P[:nd, nd:])
    for j in range(nd, n):
        d = Phi[j, j]
        for i in range(nd):
            v = B[i, j - nd] * d
            P[i, j] = v
            P[j, i] = v
        for i in range(nd, j + 1):
            v = P[i, j] * (Phi[i, i] * d)
            P[i, j] = v
            P[j, i] = v
        P[j, j] += Qd[j, j]


@njit(cache=True)
def discretize_sparse(F, G, q, T, Phi, Qd):
    """:func:`discretize` (the same series: Φ and Qd equal to rounding) with its products taken over F's
    and G's nonzero entries only: an INS error model's F has ~60 nonzero entries of 17² (the bias rows
    are diagonal, the clock block 2 × 2) and G ~3 per row, so each product is a few row updates, in loops
    with no temporaries, instead of five small BLAS calls (issue 40: the tight filter's head at each of
    the walk's 887 nodes). Which entries are zero is read at each call: any F, G is handled (a dense one
    at the dense cost). Its work arrays allocated here: :func:`discretize_sparse_ws` takes them."""
    return discretize_sparse_ws(F, G, q, T, Phi, Qd, sparse_work(F.shape[0]))


@njit(cache=True)
def sparse_work(n):
    """The work arrays of :func:`discretize_sparse_ws` for up to n states: (4 n×n products, F's nonzero
    columns by row with their count in the last column)."""
    m = max(n, 1)
    return np.zeros((4, m, m)), np.zeros((m, m + 1), np.int64)


@njit(cache=True)
def discretize_sparse_ws(F, G, q, T, Phi, Qd, ws):
    """:func:`discretize_sparse` with its work arrays ``ws`` (:func:`sparse_work`, at least F's size) passed
    in: no allocation per call (issue 40, session 16: seven per node before). The series' third-order
    terms through one product less (issue 40, session 18): with M = F Q, F Q Fᵀ symmetric and
    F²Q = F M, the series' Qd is Q T + V + Vᵀ with V = F W, W = Q T²/2 + (M + Mᵀ) T³/6 — the same
    matrix (equal to :func:`discretize`'s to rounding), two row-update products
    instead of three and no transposed copy (3.0 → 2.5 µs at the tight filter's head, d = 17)."""
    n, m = F.shape[0], G.shape[1]
    W, col = ws
    FT, M, WW, V = W[0], W[1], W[2], W[3]  # (views: the first n rows and columns used)
    nc = W.shape[1]
    for i in range(n):  # F's nonzero columns by row (count in col[i, -1]); products reset
        c = 0
        for k in range(n):
            FT[i, k] = F[i, k] * T
            M[i, k], V[i, k] = 0.0, 0.0
            if F[i, k] != 0.0:
                col[i, c] = k
                c += 1
        col[i, nc] = c
    for i in range(n):
        for j in range(n):
            Phi[i, j] = 0.0
            Qd[i, j] = 0.0
        for e in range(col[i, nc]):  # Φ's row first holds (F T)² …
            k = col[i, e]
            f = FT[i, k]
            for j in range(n):
                Phi[i, j] += f * FT[k, j]
        for c in range(m):  # … and Qd's Q = G diag(q) Gᵀ
            g = G[i, c] * q[c]
            if g != 0.0:
                for j in range(n):
                    Qd[i, j] += g * G[j, c]
    for i in range(n):  # Φ = I + F T + (F T)²/2
        for j in range(n):
            Phi[i, j] = Phi[i, j] * 0.5 + FT[i, j]
        Phi[i, i] += 1.0
    for i in range(n):  # M = F Q
        for e in range(col[i, nc]):
            k = col[i, e]
            f = F[i, k]
            for j in range(n):
                M[i, j] += f * Qd[k, j]
    c2, c3 = 0.5 * T * T, T * T * T / 6.0
    for i in range(n):  # W = Q T²/2 + (M + Mᵀ) T³/6
        for j in range(n):
            WW[i, j] = Qd[i, j] * c2 + (M[i, j] + M[j, i]) * c3
    for i in range(n):  # V = F W
        for e in range(col[i, nc]):
            k = col[i, e]
            f = F[i, k]
            for j in range(n):
                V[i, j] += f * WW[k, j]
    for i in range(n):  # Qd = Q T + V + Vᵀ
        for j in range(n):
            Qd[i, j] = Qd[i, j] * T + (V[i, j] + V[j, i])


@njit(cache=True)
def discretize_split(Fd, Fdc, Gd, q, T, Phd, Phdc, Qdd, ws=None):
    """:func:`discretize` of a head whose constant states (a zero row of F and no noise: Φ row eᵢ, Qd row 0;
    sensor scale factors and misalignments without process noise) are left out of the series. ``Fd``
    (d×d), ``Gd`` (d×m): F and G of the d states with dynamics; ``Fdc`` (d×c): their coupling to the c
    constant states. Fills Φ_DD, Qd_DD (``Phd``, ``Qdd``: the full series' blocks, since F's constant rows
    are zero; :func:`discretize_sparse`) and Φ_DC = F_DC T + F_DD F_DC T²/2 (``Phdc``, over F_DD's nonzero
    entries). ``ws``: the series' work arrays (:func:`sparse_work`; None: allocated here)."""
    if ws is None:
        discretize_sparse(Fd, Gd, q, T, Phd, Qdd)
    else:
        discretize_sparse_ws(Fd, Gd, q, T, Phd, Qdd, ws)
    d, c = Fdc.shape
    if c == 0:
        return
    for a in range(d):  # (F_DC T taken where it is read: no temporary)
        for e in range(c):
            Phdc[a, e] = 0.0
        for k in range(d):
            f = Fd[a, k] * T
            if f != 0.0:
                for e in range(c):
                    Phdc[a, e] += f * (Fdc[k, e] * T)
        for e in range(c):
            Phdc[a, e] = Phdc[a, e] * 0.5 + Fdc[a, e] * T


@njit(cache=True, fastmath=SAFE_FASTMATH)  # its loops' sums vectorised and fused (issue 40, session 18)
def predict_split(x, P, Phi, Qd, hd, d, wk, f=-1):
    """:func:`predict_tail` for a head whose constant states are kept out of the matrix products. The head
    is the first ``nd`` = len(``hd``) states, ``hd`` its order: the d states with dynamics first — of them
    the first ``f`` (< 0: all d) with a full Φ row, then the diagonal ones (Φ's only nonzero entry in the
    head on the diagonal: Gauss–Markov or random-walk sensor biases, the clock drift) — then the constant
    ones (Φ row eᵢ, Qd row and column 0); the states from nd on are the diagonal tail. With
    R = Φ_F· P (the F rows of Φ P, every column) and φ the diagonal rows' Φ: P_FF ← R_F,head Φ_F,headᵀ +
    Qd_FF (symmetrised as :func:`predict`), P_FG ← R_FG φ_G + Qd_FG, P_GG ← φ P_GG φ + Qd_GG, P_FC ← R_FC,
    P_GC ← φ P_GC, P_Ft ← R_Ft D, P_Gt ← φ P_Gt D, P_CC unchanged, P_Ct ← P_Ct D, P_tt ← D P_tt D + Qd_tt.
    Same result as :func:`predict` with the full Φ (to rounding); the constant rows of Φ, the diagonal
    rows' off-diagonal entries and off-block entries are not read. ``wk``: work arrays (Φ_F,head (f×nd,
    columns in P's order), two unused arrays (nd×f, nd×n), R (f×n), an unused (f×nd) array, the FF
    product (f×f), Φ_F,head x (≥ f,)). The products in loops, not two dgemm calls (their overhead was most
    of their time at f = 10, nd = 29), compiled with :data:`SAFE_FASTMATH` (issue 40, session 18: 3.5 →
    2.9 µs at the walk's sizes; the result differs from the dgemm's at rounding)."""
    Phr, _, _, R, _, A, xh = wk
    n, nd = P.shape[0], hd.shape[0]
    f = d if f < 0 else f
    for a in range(f):  # Φ_F,head with the head's columns in P's order (P's first nd rows need no copy)
        for b in range(nd):
            Phr[a, b] = Phi[hd[a], b]
    for a in range(f):
        s = 0.0
        for b in range(nd):
            s += Phr[a, b] * x[b]
        xh[a] = s
    for a in range(f):
        x[hd[a]] = xh[a]
    for a in range(f, d):
        x[hd[a]] *= Phi[hd[a], hd[a]]
    for i in range(nd, n):
        x[i] *= Phi[i, i]
    for a in range(f):  # R = Φ_F,head P[:nd] (f, n): row updates over Φ's nonzero entries
        for j in range(n):
            R[a, j] = 0.0
        for b in range(nd):
            v = Phr[a, b]
            if v != 0.0:
                for j in range(n):
                    R[a, j] += v * P[b, j]
    for a in range(f):  # A = R_head Φ_F,headᵀ (f, f): its upper triangle, mirrored
        for b in range(a, f):
            s = 0.0
            for c in range(nd):
                s += R[a, c] * Phr[b, c]
            A[a, b] = s
            A[b, a] = s
    for a in range(f):
        ia = hd[a]
        for b in range(a, f):
            ib = hd[b]
            v = ((A[a, b] + Qd[ia, ib]) + (A[b, a] + Qd[ib, ia])) * 0.5
            P[ia, ib] = v
            P[ib, ia] = v
        for b in range(f, d):
            ib = hd[b]
            v = R[a, ib] * Phi[ib, ib] + (Qd[ia, ib] + Qd[ib, ia]) * 0.5
            P[ia, ib] = v
            P[ib, ia] = v
        for e in range(d, nd):
            ie = hd[e]
            v = R[a, ie]
            P[ia, ie] = v
            P[ie, ia] = v
        for j in range(nd, n):
            v = R[a, j] * Phi[j, j]
            P[ia, j] = v
            P[j, ia] = v
    for a in range(f, d):  # the diagonal rows: entries the loop above did not write, each read before written
        ia = hd[a]
        pa = Phi[ia, ia]
        for b in range(a, d):
            ib = hd[b]
            v = pa * P[ia, ib] * Phi[ib, ib] + (Qd[ia, ib] + Qd[ib, ia]) * 0.5
            P[ia, ib] = v
            P[ib, ia] = v
        for e in range(d, nd):
            ie = hd[e]
            v = pa * P[ia, ie]
            P[ia, ie] = v
            P[ie, ia] = v
        for j in range(nd, n):
            v = pa * P[ia, j] * Phi[j, j]
            P[ia, j] = v
            P[j, ia] = v
    for e in range(d, nd):
        ie = hd[e]
        for j in range(nd, n):
            v = P[ie, j] * Phi[j, j]
            P[ie, j] = v
            P[j, ie] = v
    for j in range(nd, n):
        dj = Phi[j, j]
        for i in range(nd, j + 1):
            v = P[i, j] * (Phi[i, i] * dj)
            P[i, j] = v
            P[j, i] = v
        P[j, j] += Qd[j, j]


@njit(cache=True)
def update(x, P, H, R, z, gate, innov_out, s_out):
    """Batch measurement update (Joseph form) with chi-square gating.

    x (n,), P (n,n) updated in place; H (m,n), R (m,m), z (m,).
    ``gate``: chi-square threshold for νᵀS⁻¹ν (≤ 0: no gating).
    Writes the innovation ν into ``innov_out`` (m,) and diag(S) into ``s_out`` (m,).
    Returns (accepted, nis).

    The Joseph form (I − K H) P (I − K H)ᵀ + K R Kᵀ expanded, P − K Bᵀ − B Kᵀ + (K S) Kᵀ with B = P Hᵀ,
    S = H B + R: the same matrix for any K (so the same first-order insensitivity to an error in K as the
    product form), in O(n²m) instead of the product's 2n³, symmetric by construction; the m-row form of
    :func:`update_scalar`'s (issue 40). Any R (no whitening needed: S, K and the gate are the batch's).
    P must be symmetric (Bᵀ is computed as H P). Loops, not BLAS calls: at the engine's sizes (n ≤ 40,
    m ≤ 6) the calls' overhead was most of the update's time."""
    m, n = z.shape[0], x.shape[0]
    # Bᵀ = H P (P symmetric) as row updates over H's nonzero entries (a velocity row has ~3 of 33)
    Bt = np.zeros((m, n))
    nu = z.copy()
    for a in range(m):
        for k in range(n):
            hak = H[a, k]
            if hak != 0.0:
                nu[a] -= hak * x[k]
                for j in range(n):
                    Bt[a, j] += hak * P[k, j]
    S = R.copy()
    for a in range(m):
        for b in range(m):
            v = 0.0
            for j in range(n):
                v += H[a, j] * Bt[b, j]
            S[a, b] += v
        innov_out[a] = nu[a]
        s_out[a] = S[a, a]
    Sinv = _inverse(S)
    nis = 0.0
    for a in range(m):
        for b in range(m):
            nis += nu[a] * Sinv[a, b] * nu[b]
    if gate > 0.0 and nis > gate:
        return False, nis
    Kt, KSt = np.zeros((m, n)), np.zeros((m, n))  # Kᵀ = S⁻¹ Bᵀ, (K S)ᵀ
    for a in range(m):
        for b in range(m):
            c = Sinv[b, a]
            for j in range(n):
                Kt[a, j] += c * Bt[b, j]
    for a in range(m):
        for b in range(m):
            c = S[b, a]
            for j in range(n):
                KSt[a, j] += c * Kt[b, j]
        for j in range(n):
            x[j] += Kt[a, j] * nu[a]
    for i in range(n):  # the upper triangle, row by row (vectorised over j), then mirrored
        a0 = 0
        while a0 + 3 <= m:  # three rows' terms in one pass over j, added in the same order (issue 40)
            _joseph_three(P, i, a0, KSt, Kt, Bt)
            a0 += 3
        for a in range(a0, m):
            ksa, ka, ba = KSt[a, i], Kt[a, i], Bt[a, i]
            for j in range(i, n):
                P[i, j] += ksa * Kt[a, j] - (ka * Bt[a, j] + ba * Kt[a, j])
    for i in range(n):
        for j in range(i + 1, n):
            P[j, i] = P[i, j]
    return True, nis


@njit(cache=True, inline="always")
def _joseph_three(P, i, a, KSt, Kt, Bt):
    """Row i (j ≥ i) of :func:`update`'s P += (K S)_i Kᵀ − (K_i Bᵀ + B_i Kᵀ) for the measurement rows a, a+1,
    a+2 in one pass over j: the terms added one after the other as three passes would add them (the same
    bits), with P's row read and written once (a 3-row update, 541 on the walk: its P loop 2.0 → 1.4 µs)."""
    k0, k1, k2 = KSt[a, i], KSt[a + 1, i], KSt[a + 2, i]
    c0, c1, c2 = Kt[a, i], Kt[a + 1, i], Kt[a + 2, i]
    b0, b1, b2 = Bt[a, i], Bt[a + 1, i], Bt[a + 2, i]
    for j in range(i, P.shape[0]):
        v = P[i, j] + (k0 * Kt[a, j] - (c0 * Bt[a, j] + b0 * Kt[a, j]))
        v = v + (k1 * Kt[a + 1, j] - (c1 * Bt[a + 1, j] + b1 * Kt[a + 1, j]))
        P[i, j] = v + (k2 * Kt[a + 2, j] - (c2 * Bt[a + 2, j] + b2 * Kt[a + 2, j]))


@njit(cache=True)
def _inverse(S):
    """The inverse of a small matrix (Gauss–Jordan, partial pivoting): no LAPACK call per update. A zero
    pivot (S singular) goes to ``np.linalg.inv``, which raises as the update did before (no silent NaN)."""
    m = S.shape[0]
    A, Y = S.copy(), np.eye(m)
    for c in range(m):
        p = c
        for r in range(c + 1, m):
            if abs(A[r, c]) > abs(A[p, c]):
                p = r
        if A[p, c] == 0.0:
            return np.linalg.inv(S)
        if p != c:
            for j in range(m):
                A[c, j], A[p, j] = A[p, j], A[c, j]
                Y[c, j], Y[p, j] = Y[p, j], Y[c, j]
        d = 1.0 / A[c, c]
        for j in range(m):
            A[c, j] *= d
            Y[c, j] *= d
        for r in range(m):
            if r != c:
                f = A[r, c]
                if f != 0.0:
                    for j in range(m):
                        A[r, j] -= f * A[c, j]
                        Y[r, j] -= f * Y[c, j]
    return Y


@njit(cache=True)
def update_scalar(x, P, h, r, z, gate):
    """Scalar update (one row ``h`` (n,), variance ``r``) in Joseph form; returns (accepted, ν, s).

    The Joseph form (I − k hᵀ) P (I − k hᵀ)ᵀ + r k kᵀ expanded, P − k pᵀ − p kᵀ + s k kᵀ with p = P h,
    s = hᵀ p + r: the same matrix (first-order insensitive to an error in k, as the product form) in
    O(n²) instead of two n×n products. Every entry is computed, row by row (vectorised), with a term
    symmetric in (i, j) bit for bit — P_ij − (k_i p_j + p_i k_j) + s (k_i k_j) — so P stays exactly
    symmetric without a triangle's strided writes (issue 40: 2× faster at n = 33). Its work rows
    allocated here: :func:`update_scalar_ws` takes them."""
    return update_scalar_ws(x, P, h, r, z, gate, np.empty((2, x.shape[0])))


@njit(cache=True)
def update_scalar_ws(x, P, h, r, z, gate, ws):
    """:func:`update_scalar` with its work rows ``ws`` (2, n) (p = P h, k) passed in, and hᵀx, p = P h
    (P symmetric: p = Σ_c h_c P_c·, contiguous rows), hᵀp taken over h's nonzero entries only (a
    pseudorange row has ~10 of 33): no allocation, no BLAS call (issue 40, session 16). Equal to the
    products to rounding (their order of summation differs)."""
    n = x.shape[0]
    ph, k = ws[0], ws[1]
    for j in range(n):
        ph[j] = 0.0
    hx = 0.0
    for c in range(n):
        hc = h[c]
        if hc != 0.0:
            hx += hc * x[c]
            for j in range(n):
                ph[j] += hc * P[c, j]
    nu = z - hx
    hp = 0.0
    for c in range(n):
        if h[c] != 0.0:
            hp += h[c] * ph[c]
    s = hp + r
    if gate > 0.0 and nu * nu / s > gate:
        return False, nu, s
    for i in range(n):
        k[i] = ph[i] / s
        x[i] += k[i] * nu
    for i in range(n):
        ki, pi = k[i], ph[i]
        for j in range(n):
            P[i, j] = P[i, j] - (ki * ph[j] + pi * k[j]) + s * (ki * k[j])
    return True, nu, s


@njit(cache=True)
def rts_gain(P_post, Phi, P_prior_next):
    """RTS smoother gain A = P⁺_k Φᵀ (P⁻_{k+1})⁻¹ (via a linear solve)."""
    # A = P Phi^T inv(Pn)  ->  Pn^T A^T = Phi P^T  (Pn symmetric)
    return np.linalg.solve(P_prior_next, Phi @ P_post.T).T


def van_loan(F: np.ndarray, G: np.ndarray, q: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact Φ and Qd for constant F, G, diag PSD q over T (Van Loan 1978, via scipy expm)."""
    from scipy.linalg import expm  # lazy: scipy is heavy to import

    n = F.shape[0]
    GQG = (G * q) @ G.T
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -F
    M[:n, n:] = GQG
    M[n:, n:] = F.T
    E = expm(M * T)
    Phi = E[n:, n:].T
    Qd = Phi @ E[:n, n:]
    return Phi, 0.5 * (Qd + Qd.T)
