"""The tight filter's throughput path (issue 40): the block-diagonal predict of the independent scalar
states after the clock (range errors), the scalar Joseph update, and the rotation-dependent attitude
noise of gyro scale-factor and misalignment errors. Closed forms and equality with the full-matrix
algebra; no timings here (``benchmarks/tight.py`` prints those)."""

from __future__ import annotations

import numpy as np

from aidnav.filters.engine import tail_start
from aidnav.filters.kalman import discretize, discretize_tail, predict, predict_tail
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
