"""The tight run's speed path (issue 40, session 15) against dense references: the open-loop states'
propagation over Φ's open columns against the matrix product, the head predict with full, diagonal
(Gauss–Markov bias) and constant rows against Φ P Φᵀ + Qd, and the choice of the engine's output arrays
(a caller's block or the kernel's own)."""

from __future__ import annotations

import numpy as np

from aidnav.filters.kalman import discretize, predict, predict_split
from aidnav.filters.output_rows import NO_ROWS, output_rows, whole_run_rows
from aidnav.filters.predict import diagonal_last, head_split, open_loop_change


def test_open_loop_change_equals_the_matrix_product():
    """Φ x̂ − x̂ over the open columns equals the dense product with x̂ zero elsewhere: to rounding with
    several open columns per row, exactly for a diagonal tail (tight coupling's range errors)."""
    rng = np.random.default_rng(11)
    n = 33
    bias = rng.normal(size=n - 9)
    cases = ((np.array([12, 17, 20, 31], np.int64), False), (np.arange(29, 33, dtype=np.int64), True))
    for opn, tail in cases:
        Phi = rng.normal(size=(n, n))
        if tail:  # the tail: only the diagonal in the open rows and columns
            Phi[29:, :], Phi[:, 29:] = 0.0, 0.0
            Phi[np.arange(29, 33), np.arange(29, 33)] = 1.0 - rng.random(4) * 1e-3
        xo = np.zeros(n)
        xo[opn] = bias[opn - 9]
        ref = Phi @ xo - xo
        got = open_loop_change(Phi, bias, opn, n)
        if tail:
            np.testing.assert_array_equal(got, ref)
        else:
            np.testing.assert_allclose(got, ref, rtol=1e-14, atol=1e-14 * np.abs(ref).max())
        # it can fail: an open state left out changes the result by its column
        assert np.abs(open_loop_change(Phi, bias, opn[1:], n) - ref).max() > 0.05 * np.abs(ref).max()
    assert not open_loop_change(np.eye(n), bias, np.zeros(0, np.int64), n).any()


def _head_system(rng, nf=10, ng=7, nc=12, nt=4):
    """A head of nf full rows, ng diagonal rows (bias-like: F's only nonzero entry on the diagonal) and nc
    constant rows, interleaved, then nt scalar tail states; F, G, q (n × m)."""
    nh = nf + ng + nc
    n, m = nh + nt, nh + nt
    perm = rng.permutation(np.arange(3, nh))
    diag, const = perm[:ng], perm[ng:ng + nc]
    F = rng.normal(size=(n, n)) * 0.05
    F[:, nh:], F[nh:, :] = 0.0, 0.0
    F[const, :] = 0.0
    F[diag, :] = 0.0
    F[diag, diag] = -rng.random(ng) * 1e-2
    F[np.arange(nh, n), np.arange(nh, n)] = -1.0 / 600.0
    G = np.zeros((n, m))
    G[np.arange(n), np.arange(n)] = 1.0
    G[const, const] = 0.0
    q = rng.random(m) * 1e-3
    return F, G, q, nh, n


def test_head_predict_products_equal_the_dense_predict():
    """:func:`predict_split` with f full rows, the diagonal (Gauss–Markov) rows scaled and the constant rows
    left out gives the dense Φ P Φᵀ + Qd, for random systems and covariances (σ from 1e-3 to 30); with an
    entry of a full row of Φ changed it does not (the test can fail)."""
    from aidnav.filters.predict import tail_start

    rng = np.random.default_rng(2026)
    for trial in range(4):
        F, G, q, nh, n = _head_system(rng)
        T = 0.25 + 0.25 * trial
        Phi, Qd = np.zeros((n, n)), np.zeros((n, n))
        discretize(F, G, q, T, Phi, Qd)
        assert tail_start(F, G, nh) == nh
        hd, d = head_split(F[:nh, :nh], G[:nh, :], q, nh)
        hd, f = diagonal_last(F[:nh, :nh], hd, d)
        assert (d, f) == (17, 10)
        a = rng.normal(size=(n, n))
        P0 = a @ a.T / n + np.diag(10.0 ** rng.uniform(-6, 3, n))
        x0 = rng.normal(size=n)
        P1, x1, P2, x2 = P0.copy(), x0.copy(), P0.copy(), x0.copy()
        predict(x1, P1, Phi, Qd)
        wk = (np.zeros((f, nh)), np.zeros((nh, f)), np.zeros((nh, n)), np.zeros((f, n)), np.zeros((f, nh)),
              np.zeros((f, f)), np.zeros(nh))
        predict_split(x2, P2, Phi.copy(), Qd, hd, d, wk, f)
        scale = np.sqrt(np.outer(np.diag(P1), np.diag(P1)))
        assert np.all(np.abs(P2 - P1) <= 1e-12 * scale)
        np.testing.assert_allclose(x2, x1, rtol=1e-12, atol=1e-14)
        assert np.array_equal(P2, P2.T)
        bad = Phi.copy()
        bad[hd[0], hd[f - 1]] += 0.1  # a full row's entry off: the products must see it
        P3 = P0.copy()
        predict_split(x0.copy(), P3, bad, Qd, hd, d, wk, f)
        assert np.abs(P3 - P1).max() > 1e-4 * np.abs(P1).max()


def test_output_rows_take_the_callers_block_only_where_it_fits():
    n_out, nb, n = 50, 24, 33
    rows = whole_run_rows(n_out, nb, n)
    assert [r.shape for r in rows] == [(n_out, 10), (n_out, nb), (n_out, n)]
    assert all(r.flags.c_contiguous for r in rows) and rows[0].base is rows[2].base
    got = output_rows(rows, True, n_out, nb, n)
    assert all(np.shares_memory(g, r) for g, r in zip(got, rows, strict=True))
    for whole, shape in ((False, (n_out, nb, n)), (True, (n_out + 1, nb, n)), (True, (n_out, nb + 1, n)),
                         (True, (n_out, nb, n - 1))):
        got = output_rows(rows, whole, *shape)
        assert not any(np.shares_memory(g, r) for g, r in zip(got, rows, strict=True))
        assert [g.shape for g in got] == [(shape[0], 10), (shape[0], shape[1]), (shape[0], shape[2])]
    got = output_rows(NO_ROWS, True, n_out, nb, n)
    assert [g.shape for g in got] == [(n_out, 10), (n_out, nb), (n_out, n)]


def test_head_predict_fast_math_keeps_ieee_nan_handling():
    """:func:`predict_split` is compiled with :data:`SAFE_FASTMATH` (issue 40, session 18): no ``nnan`` or
    ``ninf``, so it equals the strict-IEEE compilation of the same function to rounding, and a NaN in P, x
    or Qd reaches exactly the entries of P and x that it reaches there (none lost, none added)."""
    import numba  # lazy: the strict-IEEE compilation of the same function, for this test only

    from aidnav.filters.kalman import SAFE_FASTMATH

    assert not SAFE_FASTMATH & {"fast", "nnan", "ninf", "afn"}
    strict = numba.njit(predict_split.py_func)
    rng = np.random.default_rng(18)
    F, G, q, nh, n = _head_system(rng)
    Phi, Qd = np.zeros((n, n)), np.zeros((n, n))
    discretize(F, G, q, 0.5, Phi, Qd)
    hd, d = head_split(F[:nh, :nh], G[:nh, :], q, nh)
    hd, f = diagonal_last(F[:nh, :nh], hd, d)
    a = rng.normal(size=(n, n))
    P0 = a @ a.T / n + np.diag(10.0 ** rng.uniform(-6, 3, n))
    x0 = rng.normal(size=n)

    def both(P, x, Qd_):
        out = []
        for fn in (predict_split, strict):
            Pw, xw = P.copy(), x.copy()
            wk = (np.zeros((f, nh)), np.zeros((nh, f)), np.zeros((nh, n)), np.zeros((f, n)),
                  np.zeros((f, nh)), np.zeros((f, f)), np.zeros(nh))
            fn(xw, Pw, Phi, Qd_, hd, d, wk, f)
            out.append((Pw, xw))
        return out

    (Pf, xf), (Ps, xs) = both(P0, x0, Qd)
    scale = np.sqrt(np.outer(np.diag(Ps), np.diag(Ps)))
    assert np.all(np.abs(Pf - Ps) <= 1e-13 * scale) and np.array_equal(Pf, Pf.T)
    np.testing.assert_allclose(xf, xs, rtol=1e-13, atol=1e-15)
    for where in ("P full", "P diagonal", "P constant", "x", "Qd tail"):
        P, x, Qn = P0.copy(), x0.copy(), Qd.copy()
        if where == "x":
            x[hd[1]] = np.nan
        elif where == "Qd tail":
            Qn[n - 1, n - 1] = np.nan
        else:
            i = hd[{"P full": 0, "P diagonal": f, "P constant": d}[where]]
            P[i, n - 2] = P[n - 2, i] = np.nan
        (Pf, xf), (Ps, xs) = both(P, x, Qn)
        assert np.isnan(Ps).any() or np.isnan(xs).any()  # the NaN went somewhere (the test can fail)
        np.testing.assert_array_equal(np.isnan(Pf), np.isnan(Ps))
        np.testing.assert_array_equal(np.isnan(xf), np.isnan(xs))
        ok = ~np.isnan(Ps)
        assert np.all(np.abs(Pf - Ps)[ok] <= 1e-13 * np.nan_to_num(scale, nan=np.inf)[ok] + 1e-300)
