"""The tight kernel's layout changes of issue 40, session 17 against references written here: the batch
update's Joseph pass with three measurement rows fused into one pass over P's row (the same additions in
the same order as one pass per row: bit for bit), the per-epoch outputs packed in five arrays and named
again by :func:`epoch_fields`, and the node-constraint counts that let a node without constraints skip
their update context."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.filters.engine import _constraint_counts
from aidnav.filters.kalman import update
from aidnav.filters.layout import L_CLK
from aidnav.filters.measurements import epoch as ep


def _update_one_pass_per_row(x, P, H, R, z):
    """:func:`update` as it was before the fused pass (plain numpy / Python, the same operations in the same
    order): Bᵀ = H P, S = H B + R, Kᵀ = S⁻¹ Bᵀ (S⁻¹ by numpy), P += (K S)_i Kᵀ − (K_i Bᵀ + B_i Kᵀ) one
    measurement row at a time over the upper triangle, then mirrored."""
    m, n = z.shape[0], x.shape[0]
    Bt, nu = np.zeros((m, n)), z.copy()
    for a in range(m):
        for k in range(n):
            if H[a, k] != 0.0:
                nu[a] -= H[a, k] * x[k]
                Bt[a] += H[a, k] * P[k]
    S = R.copy()
    for a in range(m):
        for b in range(m):
            v = 0.0
            for j in range(n):
                v += H[a, j] * Bt[b, j]
            S[a, b] += v
    return Bt, S, nu


@pytest.mark.parametrize("m", [1, 2, 3, 4, 6])
def test_update_is_the_joseph_form(m):
    """:func:`update`'s P is exactly symmetric and equals the textbook Joseph form (I − K H) P (I − K H)ᵀ +
    K R Kᵀ to rounding, and x⁺ = x + K ν."""
    rng = np.random.default_rng(40 + m)
    for n in (9, 17, 33):
        A = rng.normal(size=(n, n))
        P0 = A @ A.T + np.eye(n)
        H = rng.normal(size=(m, n)) * (rng.random((m, n)) < 0.4)
        H[:, 0] = 1.0  # no all-zero row
        R = np.diag(rng.uniform(0.1, 1.0, m))
        z, x0 = rng.normal(size=m), rng.normal(size=n)
        x, P = x0.copy(), P0.copy()
        ok, _ = update(x, P, H, R, z, 0.0, np.zeros(m), np.zeros(m))
        assert ok
        np.testing.assert_array_equal(P, P.T)
        Bt, S, nu = _update_one_pass_per_row(x0, P0, H, R, z)
        K = np.linalg.solve(S, Bt).T
        IKH = np.eye(n) - K @ H
        Pj = IKH @ P0 @ IKH.T + K @ R @ K.T
        np.testing.assert_allclose(P, Pj, rtol=0, atol=1e-10 * np.abs(Pj).max())
        np.testing.assert_allclose(x, x0 + K @ nu, rtol=0, atol=1e-10 * max(1.0, np.abs(x).max()))


@pytest.mark.parametrize("m, n", [(3, 33), (1, 17), (2, 9), (4, 33), (6, 21)])
def test_fused_joseph_pass_is_one_pass_per_row(m, n):
    """The kernel's update (three measurement rows per pass over P's row, then one at a time) equals, bit
    for bit, a Python transcription of the arithmetic before the fused pass: the same Gauss-Jordan inverse,
    the same loops, one pass over P's row per measurement row (a pass that reordered the rows' terms would
    differ in the last bits)."""
    rng = np.random.default_rng(7 + m + n)
    A = rng.normal(size=(n, n))
    P0 = A @ A.T + np.eye(n)
    H = rng.normal(size=(m, n)) * (rng.random((m, n)) < 0.4)
    H[:, min(3, n - 1)] = 1.0
    R, z, x0 = np.diag(rng.uniform(0.01, 0.1, m)), rng.normal(size=m) * 0.1, rng.normal(size=n)
    x, P = x0.copy(), P0.copy()
    update(x, P, H, R, z, 0.0, np.zeros(m), np.zeros(m))
    Bt, S, nu = _update_one_pass_per_row(x0, P0, H, R, z)
    Y = _gauss_jordan(S)
    Kt = np.zeros((m, n))
    for a in range(m):
        for b in range(m):
            Kt[a] += Y[b, a] * Bt[b]
    KSt = np.zeros((m, n))
    for a in range(m):
        for b in range(m):
            KSt[a] += S[b, a] * Kt[b]
    Pr = P0.copy()
    for i in range(n):
        for a in range(m):
            for j in range(i, n):
                Pr[i, j] += KSt[a, i] * Kt[a, j] - (Kt[a, i] * Bt[a, j] + Bt[a, i] * Kt[a, j])
    iu = np.triu_indices(n)
    Pr.T[iu] = Pr[iu]
    np.testing.assert_array_equal(P, Pr)


def _gauss_jordan(S):
    """:func:`aidnav.filters.kalman._inverse`'s arithmetic in Python (partial pivoting)."""
    m = S.shape[0]
    A, Y = S.copy(), np.eye(m)
    for c in range(m):
        p = c
        for r in range(c + 1, m):
            if abs(A[r, c]) > abs(A[p, c]):
                p = r
        if p != c:
            A[[c, p]], Y[[c, p]] = A[[p, c]], Y[[p, c]]
        d = 1.0 / A[c, c]
        A[c] *= d
        Y[c] *= d
        for r in range(m):
            if r != c and A[r, c] != 0.0:
                f = A[r, c]
                A[r] -= f * A[c]
                Y[r] -= f * Y[c]
    return Y


def test_epoch_fields_name_the_packed_outputs():
    """Values written where the kernel writes each output (``cnt``, ``sat``, ``node`` by their ``C_*``,
    ``S_*``, ``N_*`` offsets) come back under their names, for a selection of epochs; P_nav row-major."""
    M, S = 4, 3
    grp = ep.epoch_out(M, S)
    assert np.isnan(ep.epoch_fields(grp).clk).all() and (ep.epoch_fields(grp).state == 0).all()
    names = ("navail", "npr", "nrate", "nrej", "ntd", "ntdrej")
    cols = (ep.C_AVAIL, ep.C_PR, ep.C_RATE, ep.C_REJ, ep.C_TD, ep.C_TDREJ)
    for v, c in enumerate(cols):
        grp.cnt[:, c] = np.arange(M) + 10 * v
    sats = ("pr_nu", "pr_s", "rate_nu", "rate_s", "el")
    planes = (ep.S_PR_NU, ep.S_PR_S, ep.S_RATE_NU, ep.S_RATE_S, ep.S_EL)
    for v, s in enumerate(planes):
        grp.sat[s] = np.arange(M * S).reshape(M, S) + 100.0 * v
    grp.t[:] = np.arange(M) + 0.5
    P = np.arange(81.0).reshape(9, 9)
    lay = np.full(14, -1, np.int64)
    lay[0], lay[1], lay[L_CLK] = 29, 27, 27  # the clock at bias[18], bias[19]
    for g in range(M):
        ep.epoch_record(grp, g, np.arange(10.0) + g, np.r_[np.zeros(18), [7.0 + g, 8.0 + g]], P + g, lay)
    sel = np.array([3, 1])
    f = ep.epoch_fields(grp, sel)
    for v, name in enumerate(names):
        np.testing.assert_array_equal(getattr(f, name), sel + 10 * v)
    for v, name in enumerate(sats):
        np.testing.assert_array_equal(getattr(f, name), (np.arange(M * S).reshape(M, S) + 100.0 * v)[sel])
    np.testing.assert_array_equal(f.t, sel + 0.5)
    np.testing.assert_array_equal(f.P_nav, np.stack([P + g for g in sel]))
    np.testing.assert_array_equal(f.clk, np.stack([[7.0 + g, 8.0 + g] for g in sel]))
    np.testing.assert_array_equal(f.state, np.stack([np.arange(10.0) + g for g in sel]))
    assert f.flags is grp.flags


def test_constraint_counts():
    """Node constraints counted at moving (0) and static (1) samples; none: both zero."""
    np.testing.assert_array_equal(_constraint_counts(np.array([[2, 1], [4, 0], [3, 1]])), [1, 2])
    np.testing.assert_array_equal(_constraint_counts(np.zeros((0, 2), np.int64)), [0, 0])
