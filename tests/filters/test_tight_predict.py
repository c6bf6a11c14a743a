"""The tight filter's throughput path (issue 40): the block-diagonal predict of the independent scalar
states after the clock (range errors), the scalar Joseph update, and the rotation-dependent attitude
noise of gyro scale-factor and misalignment errors. Closed forms and equality with the full-matrix
algebra; no timings here (``benchmarks/tight.py`` prints those)."""

from __future__ import annotations

import numpy as np

from aidnav.filters.kalman import discretize, discretize_tail, predict, predict_tail
from aidnav.filters.predict import tail_start
from aidnav.filters.tight import rotation_variance


def _system(rng, nd=17, nt=5):
    """F, G, q of a head block (dense) and nt independent first-order Markov states after it."""
    n, mh = nd + nt, 14
    F = np.zeros((n, n))
    F[:nd, :nd] = 0.05 * rng.normal(size=(nd, nd))
    G = np.zeros((n, mh + nt))
    G[:nd, :mh] = rng.normal(size=(nd, mh))
    q = rng.uniform(0.5, 2.0, mh + nt)
    for i in range(nt):
        F[nd + i, nd + i] = -1.0 / rng.uniform(10.0, 2000.0)
        G[nd + i, mh + i] = rng.uniform(0.5, 2.0)
    return F, G, q


def test_block_predict_equals_the_full_matrix_predict():
    rng = np.random.default_rng(40)
    nd, nt = 17, 5
    F, G, q = _system(rng, nd, nt)
    n, T = nd + nt, 0.25
    Phi, Qd = np.zeros((n, n)), np.zeros((n, n))
    discretize(F, G, q, T, Phi, Qd)
    assert tail_start(F, G, nd) == nd
    # the tail's scalar discretisation is the full series' diagonal; the full Φ, Qd are block diagonal
    Pt, Qt = np.zeros((n, n)), np.zeros((n, n))
    qt = (G ** 2 @ q) * (np.arange(n) >= nd)
    discretize_tail(F, qt, T, Pt, Qt, nd)
    tail = np.arange(nd, n)
    np.testing.assert_allclose(Pt[tail, tail], Phi[tail, tail], rtol=1e-14)
    np.testing.assert_allclose(Qt[tail, tail], Qd[tail, tail], rtol=1e-12)
    assert np.all(Phi[:nd, nd:] == 0) and np.all(Qd[:nd, nd:] == 0)
    a = rng.normal(size=(n, n))
    P0 = a @ a.T / n + 0.1 * np.eye(n)
    x0 = rng.normal(size=n)
    P1, x1, P2, x2 = P0.copy(), x0.copy(), P0.copy(), x0.copy()
    predict(x1, P1, Phi, Qd)
    predict_tail(x2, P2, Phi, Qd, nd)
    np.testing.assert_allclose(P2, P1, rtol=1e-12, atol=1e-12 * np.abs(P1).max())
    np.testing.assert_allclose(x2, x1, rtol=1e-12, atol=1e-14)
    assert np.array_equal(P2, P2.T)


def test_tail_detection_refuses_coupled_states():
    rng = np.random.default_rng(41)
    nd, nt = 17, 3
    F, G, q = _system(rng, nd, nt)
    n = nd + nt
    assert tail_start(F, G, n) == n  # nothing asked: no tail
    F2 = F.copy()
    F2[nd + 1, 3] = 0.1  # a tail state driven by a head state
    assert tail_start(F2, G, nd) == n
    G2 = G.copy()
    G2[nd, 0] = 1.0  # a tail state sharing a head state's noise input
    assert tail_start(F, G2, nd) == n


def test_rotation_variance_closed_form():
    """A constant rate ω about z for 2.5 s in 1-s blocks: (σ_sf² + σ_m²)(ω·1 s)² at the end of each full
    block and (ω·0.5 s)² at the last sample; back-and-forth rotation within a block leaves nothing."""
    dt, w, sf, mis = 1.0 / 128.0, 0.3, 1e-3, np.radians(0.5)
    t = 100.0 + np.arange(320) * dt
    dth = np.zeros((320, 3))
    dth[:, 2] = w * dt
    v = rotation_variance(t, dth, sf, mis, 1.0)
    s2 = sf ** 2 + mis ** 2
    assert list(np.flatnonzero(v)) == [127, 255, 319]
    np.testing.assert_allclose(v[[127, 255, 319]], s2 * (w * np.array([1.0, 1.0, 0.5])) ** 2, rtol=1e-12)
    dth[:, 2] = np.where((np.arange(320) // 64) % 2 == 0, w * dt, -w * dt)  # ±0.5 s: net 0 per full block
    v = rotation_variance(t, dth, sf, mis, 1.0)
    assert v[:256].max() < 1e-20
    np.testing.assert_allclose(v[319], s2 * (w * 0.5) ** 2, rtol=1e-12)
    assert not rotation_variance(t, dth, 0.0, 0.0, 1.0).any()


def _const_system(rng, nd=17, nc=12, nt=4):
    """A head of nd states with dynamics coupled to nc constant states (zero F row, no noise: scale
    factors, misalignments) interleaved with them, then nt independent Markov states."""
    F, G, q = _system(rng, nd + nc, nt)
    n = nd + nc + nt
    const = np.sort(rng.choice(np.arange(3, nd + nc), nc, replace=False))
    F[const, :] = 0.0
    G[const, :] = 0.0
    G[const[0], 0] = 1.0  # an input of zero PSD shared with a dynamic state: still no noise
    q[0] = 0.0
    return F, G, q, const, n


def test_split_predict_equals_the_full_matrix_predict():
    """Constant states kept out of the series and the products give the full Φ P Φᵀ + Qd (issue 40)."""
    from aidnav.filters.kalman import discretize_split, predict_split
    from aidnav.filters.predict import head_split

    rng = np.random.default_rng(42)
    nh, nc, nt = 29, 12, 4
    F, G, q, const, n = _const_system(rng, nh - nc, nc, nt)
    T = 0.9
    Phi, Qd = np.zeros((n, n)), np.zeros((n, n))
    discretize(F, G, q, T, Phi, Qd)
    hd, d = head_split(F[:nh, :nh], G[:nh, :], q, nh)
    assert d == nh - nc and sorted(hd[d:]) == list(const) and sorted(hd) == list(range(nh))
    D, C = hd[:d], hd[d:]
    # the full series gives what the split assumes: Φ rows eᵢ and Qd rows 0 at the constant states
    np.testing.assert_array_equal(Phi[C][:, C], np.eye(nc))
    assert np.all(Phi[C][:, D] == 0) and np.all(Qd[C] == 0)
    Phd, Phdc, Qdd = np.zeros((d, d)), np.zeros((d, nc)), np.zeros((d, d))
    discretize_split(F[np.ix_(D, D)], F[np.ix_(D, C)].copy(), G[D].copy(), q, T, Phd, Phdc, Qdd)
    np.testing.assert_allclose(Phd, Phi[np.ix_(D, D)], rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(Phdc, Phi[np.ix_(D, C)], rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(Qdd, Qd[np.ix_(D, D)], rtol=1e-12, atol=1e-15)
    a = rng.normal(size=(n, n))
    P0 = a @ a.T / n + 0.1 * np.eye(n)
    x0 = rng.normal(size=n)
    P1, x1, P2, x2 = P0.copy(), x0.copy(), P0.copy(), x0.copy()
    predict(x1, P1, Phi, Qd)
    Phi2, Qd2 = Phi.copy(), Qd.copy()
    Phi2[C] = 99.0  # rows the split does not read
    wk = (np.zeros((d, nh)), np.zeros((nh, d)), np.zeros((nh, n)), np.zeros((d, n)), np.zeros((d, nh)),
          np.zeros((d, d)), np.zeros(nh))
    predict_split(x2, P2, Phi2, Qd2, hd, d, wk)
    np.testing.assert_allclose(P2, P1, rtol=1e-12, atol=1e-12 * np.abs(P1).max())
    np.testing.assert_allclose(x2, x1, rtol=1e-12, atol=1e-14)
    assert np.array_equal(P2, P2.T)
    # it can fail: a constant state that is not (a noise of its own) makes the split wrong
    q3 = q.copy()
    G3 = G.copy()
    G3[C[0], -1] = 1.0
    Phi3, Qd3 = np.zeros((n, n)), np.zeros((n, n))
    discretize(F, G3, q3, T, Phi3, Qd3)
    assert head_split(F[:nh, :nh], G3[:nh, :], q3, nh)[1] == d + 1
    P3 = P0.copy()
    predict_split(x0.copy(), P3, Phi3, Qd3, hd, d, wk)
    P4 = P0.copy()
    predict(x0.copy(), P4, Phi3, Qd3)
    assert np.abs(P3 - P4).max() > 1e-3 * np.abs(P4).max()
