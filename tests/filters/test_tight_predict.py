"""The tight filter's throughput path (issue 40): the block-diagonal predict of the independent scalar
states after the clock (range errors), the scalar Joseph update, and the rotation-dependent attitude
noise of gyro scale-factor and misalignment errors. Closed forms and equality with the full-matrix
algebra; no timings here (``benchmarks/tight.py`` prints those)."""

from __future__ import annotations

import numpy as np

from aidnav.filters.config import UNKNOWN_GRADE_IMU
from aidnav.filters.engine import Process
from aidnav.filters.ins_errors import ACC_FB, ACC_FN, ACC_TN, ACC_WB, new_accumulator, noise_count
from aidnav.filters.kalman import (
    discretize,
    discretize_sparse,
    discretize_tail,
    predict,
    predict_split,
    predict_tail,
)
from aidnav.filters.layout import L_CLK, L_N
from aidnav.filters.predict import error_model, predict_node, tail_start
from aidnav.filters.prior import process_noise
from aidnav.filters.tight import TightConfig, rotation_variance, tight_layout
from aidnav.nav.rotations import dcm_from_quat, quat_from_euler


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


def test_sparse_series_equals_the_dense_series():
    """:func:`discretize_sparse` (products over F's and G's nonzero entries) gives :func:`discretize`'s Φ
    and Qd, for an INS-like sparse F and a dense one."""
    rng = np.random.default_rng(7)
    for dense in (False, True):
        F, G, q = _system(rng, 17, 0)
        if not dense:
            F[rng.random(F.shape) < 0.75] = 0.0
            G[rng.random(G.shape) < 0.7] = 0.0
        Phi, Qd, Phi2, Qd2 = (np.full((17, 17), np.nan) for _ in range(4))
        discretize(F, G, q, 0.8, Phi, Qd)
        discretize_sparse(F, G, q, 0.8, Phi2, Qd2)
        np.testing.assert_allclose(Phi2, Phi, rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(Qd2, Qd, rtol=1e-13, atol=1e-15 * np.abs(Qd).max())


def _tight_model(nins, n_range=4, n_isb=1):
    """The tight filter's process model of an IMU grade with ``nins`` INS states (27: the no-configuration
    unknown-grade model, its scale factors and misalignments random constants), its clock, ``n_isb``
    inter-system biases and ``n_range`` range errors; the engine's error-model arrays of it."""

    cfg = TightConfig(imu=UNKNOWN_GRADE_IMU if nins == 27 else {})
    assert cfg.nins == nins
    lay = tight_layout(cfg.states, n_range, n_isb, nins)
    n, nfull = int(lay[L_N]), max(nins, 15)
    mins = noise_count(nfull)
    q = np.r_[process_noise(cfg, nfull), 1e-2, 1e-4, np.full(n_isb, 1e-3), np.full(n_range, 2.0 / 600.0)]
    taus = np.array([cfg.imu.gyro_bias_tau_s, cfg.imu.accel_bias_tau_s, cfg.imu.sf_tau_s, cfg.imu.sf_tau_s])
    aux_tau = np.r_[0.0, 3600.0, np.zeros(n_isb), np.full(n_range, 600.0)]
    proc = Process(lay, q, taus, aux_tau, 1.0, open=np.arange(n - n_range, n, dtype=np.int64))
    return proc, error_model(lay, proc, nfull, mins, n - nins, n, nins, 0), (nins, mins, n)


def test_node_predict_equals_the_full_matrix_algebra():
    """The tight filter's predict at a node (:func:`aidnav.filters.predict.predict_node`: the head's series
    over F's nonzero entries, its constant and diagonal rows and the range-error tail out of the products)
    equals the slow path — the full F, G of the same interval, :func:`discretize`, Φ P Φᵀ + Qd — over a
    chain of nodes, for the no-configuration model (27 INS states: 12 constant, 6 diagonal bias rows) and
    the 15-state one (issue 40)."""

    rng = np.random.default_rng(40)
    for nins in (27, 15):
        proc, em, dims = _tight_model(nins)
        n, nd, sp = dims[2], em[6], em[11]
        hd, d, f = sp[0], sp[1], sp[8]
        ic = int(proc.lay[L_CLK])
        assert nd == ic + 2  # the tail: the inter-system bias and the range errors
        if nins == 27:  # full rows: navigation and clock bias; diagonal: the six biases and the clock drift
            assert (d, f) == (17, 10) and sorted(hd[f:d]) == [9, 10, 11, 12, 13, 14, ic + 1]
        a = rng.normal(size=(n, n))
        P = a @ a.T / n + np.diag(rng.uniform(0.1, 2.0, n))
        P_ref = P.copy()
        for k in range(4):
            st = np.r_[0.7 + 0.01 * k, 2.1, 100.0 * k, rng.normal(0.0, 3.0, 3), quat_from_euler(
                *rng.uniform(-1.0, 1.0, 3))]
            C = dcm_from_quat(st[6:10])
            T, ns = rng.uniform(0.2, 1.0), 100
            acc = new_accumulator()
            acc[0:3] = C * ns
            acc[ACC_FN] = C @ (np.array([0.1, 0.2, 9.8]) + rng.normal(0.0, 1.0, 3)) * T
            acc[ACC_WB], acc[ACC_FB] = rng.normal(0.0, 0.05, 3) * T, np.array([0.3, -0.2, 9.8]) * T
            acc[ACC_TN, :2] = T, ns
            x = rng.normal(size=n)
            predict_node(st, acc, x, P, T, proc, em, dims)
            Fi, Gi, F, G = (m.copy() for m in em[:4])  # Fi, Gi: the interval's INS model
            F[:nins, :nins], G[:nins, :dims[1]] = Fi[:nins, :nins], Gi[:nins, :dims[1]]
            Phi, Qd = np.zeros((n, n)), np.zeros((n, n))
            discretize(F, G, proc.q, T, Phi, Qd)
            x_ref = np.zeros(n)
            predict(x_ref, P_ref, Phi, Qd)
            np.testing.assert_allclose(em[4], Phi, rtol=1e-13, atol=1e-15)
            scale = np.sqrt(np.outer(np.diag(P_ref), np.diag(P_ref)))
            assert np.abs(P - P_ref).max() / scale.max() < 1e-13
            assert np.all(np.abs(P - P_ref) <= 1e-11 * scale)
            assert np.array_equal(P, P.T) and not x.any()
        if nins == 27:  # it can fail: a full row (the clock bias) taken as diagonal
            P1, P2, x = P.copy(), P.copy(), np.zeros(n)
            wk, nh = em[12], len(hd)
            predict_split(x, P1, em[4], em[5], hd, d, wk, f)
            wk2 = (np.zeros((f - 1, nh)), np.zeros((nh, f - 1)), wk[2], np.zeros((f - 1, n)),
                   np.zeros((f - 1, nh)), np.zeros((f - 1, f - 1)), wk[6])
            predict_split(x, P2, em[4], em[5], hd, d, wk2, f - 1)
            assert (np.abs(P1 - P2) / np.sqrt(np.outer(np.diag(P1), np.diag(P1)))).max() > 1e-3
