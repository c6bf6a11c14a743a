"""The tilt's turn with the heading (issue 35, session 13; :mod:`aidnav.filters.tilt_turn`): the turn is the
feedback rotation's twist about Up, and the node matrices the engine keeps make the RTS pass exact across
the turns — checked against the smoothed mean and covariance of the whole linear-Gaussian model solved at
once (a closed form, no filter code in the reference)."""

from __future__ import annotations

import numpy as np

from aidnav.filters.ins_errors import turn_tilt_by
from aidnav.filters.smoother import rts
from aidnav.filters.tilt_turn import keep_post, keep_prior, turn_with_feedback
from aidnav.nav.rotations import dcm_from_quat, quat_from_euler, quat_from_rotvec, quat_mult

N, K = 5, 7  # states (φ_E, φ_N, φ_U, two others), nodes
IX = np.arange(15)


def _T(dh):
    """The turn's matrix: I with the tilt block turned by the heading change dh."""
    T = np.eye(N)
    c, s = np.cos(-dh), np.sin(-dh)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def test_turn_matrix_is_turn_tilt_by():
    P = np.random.default_rng(1).normal(size=(N, N))
    P = P @ P.T
    Q = P.copy()
    turn_tilt_by(Q, 0, 1, 0.7)
    T = _T(0.7)
    np.testing.assert_allclose(Q, T @ P @ T.T, atol=1e-14)


def test_the_turn_is_the_feedback_twist_not_the_euler_heading_change():
    """A pure tilt correction on a pitched body moves the Euler heading (here by ~0.7°) but turns nothing; a
    rotation about Up by ψ turns the tilt by a heading change of −ψ whatever the attitude."""
    q0 = quat_from_euler(0.3, 1.2, 0.5)

    def heading(q):
        C = dcm_from_quat(q)
        return np.arctan2(C[0, 1], C[1, 1])

    tilt = np.zeros(15)
    tilt[0] = 0.01
    assert abs(heading(quat_mult(quat_from_rotvec(tilt[:3]), q0)) - heading(q0)) > 0.01
    P = np.eye(N)
    assert turn_with_feedback(tilt, P, True, IX) == 0.0
    np.testing.assert_array_equal(P, np.eye(N))
    yaw = np.zeros(15)
    yaw[2] = 0.2
    P = np.diag([1.0, 4.0, 1.0, 1.0, 1.0])
    assert np.isclose(turn_with_feedback(yaw, P, True, IX), -0.2)
    T = _T(-0.2)
    np.testing.assert_allclose(P, T @ np.diag([1.0, 4.0, 1.0, 1.0, 1.0]) @ T.T, atol=1e-14)
    assert turn_with_feedback(yaw, P, False, IX) == 0.0  # a static node: turned at rest, at the next node


def _forward(seed, told=True):
    """A closed-loop filter of a random linear model with a tilt turn at rest (after the prediction) and
    one after the feedback at some nodes, keeping the node matrices as the engine does (``told``: the
    turns passed to keep_prior/keep_post; False: the matrices as kept before session 13); and the same
    model written as one linear map of the base variables (e⁺₀, w₁…w_K, v₀…v_K) for the reference."""
    rng = np.random.default_rng(seed)
    P0 = np.diag(rng.uniform(0.5, 2.0, N))
    Phis = [np.eye(N)] + [np.eye(N) + 0.2 * rng.normal(size=(N, N)) for _ in range(K - 1)]
    Qs = [np.zeros((N, N))] + [np.diag(rng.uniform(0.01, 0.1, N)) for _ in range(K - 1)]
    H = rng.normal(size=(2, N))
    R = np.diag([0.3, 0.5])
    rest = [0.0, 0.3, 0.0, 0.0, -0.2, 0.0, 0.0]
    post = [0.0, 0.0, 0.8, -1.1, 0.0, 0.4, 0.0]
    z = rng.normal(size=(K, 2))
    S = (np.zeros((K, N, N)), np.zeros((K, N, N)), np.zeros((K, N, N)), np.zeros((K, N)))
    # reference: e⁺ = A_e b + c_e over the base variables b (n_b of them), z_k = H e⁻_k + v_k
    nb = N * K + 2 * K
    Ae, ce = np.zeros((N, nb)), np.zeros(N)
    Ae[:, :N] = np.eye(N)  # e⁺ before node 0 = the prior draw (Φ₀ = I, Q₀ = 0)
    cov_b = np.zeros((nb, nb))
    cov_b[:N, :N] = P0
    rows, refs = [], []
    P = P0.copy()
    for k in range(K):
        P = Phis[k] @ P @ Phis[k].T + Qs[k]
        Tr = _T(rest[k])
        P = Tr @ P @ Tr.T
        keep_prior(True, S, k, Phis[k], P, rest[k] if told else 0.0, IX)
        wi = slice(N * k, N * (k + 1)) if k else slice(0, 0)
        Am, cm = Tr @ Phis[k] @ Ae, Tr @ Phis[k] @ ce  # e⁻_k
        if k:
            Am[:, wi] += Tr
            cov_b[wi, wi] = Qs[k]
        vi = slice(N * K + 2 * k, N * K + 2 * k + 2)
        Az = H @ Am
        Az[:, vi] += np.eye(2)
        cov_b[vi, vi] = R
        rows.append((Az, H @ cm))
        Kg = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        dx = Kg @ z[k]
        P = (np.eye(N) - Kg @ H) @ P
        Tf = _T(post[k])
        P = Tf @ P @ Tf.T
        keep_post(True, S, k, P, dx, post[k] if told else 0.0, IX)
        Ae, ce = Tf @ Am, Tf @ (cm - dx)
        refs.append((Ae.copy(), ce.copy()))
    return S, z, rows, refs, cov_b


def test_rts_across_turns_is_the_exact_smoother():
    """ds_k and Ps_k of the RTS pass over the kept matrices equal E[e⁺_k | z₀…z_K] and its covariance from
    the joint Gaussian, and Ps ≤ P⁺ at every node; without the turns in the kept matrices (the node's
    matrices as the engine kept them before) the pass is not the smoother."""
    for seed in range(3):
        S, z, rows, refs, cov_b = _forward(seed)
        ds, Ps = rts(S[0], S[1], S[2], S[3], -1)
        Az = np.vstack([a for a, _ in rows])
        cz = np.concatenate([c for _, c in rows])
        Szz = Az @ cov_b @ Az.T
        gain = cov_b @ Az.T @ np.linalg.inv(Szz)
        mb = gain @ (z.ravel() - cz)
        Cb = cov_b - gain @ Az @ cov_b
        for k, (Ae, ce) in enumerate(refs):
            np.testing.assert_allclose(ds[k], Ae @ mb + ce, atol=1e-9)
            np.testing.assert_allclose(Ps[k], Ae @ Cb @ Ae.T, atol=1e-9)
            assert np.all(np.linalg.eigvalsh(S[0][k] - Ps[k]) >= -1e-12)
        S, z, rows, refs, cov_b = _forward(seed, told=False)
        ds_old, Ps_old = rts(S[0], S[1], S[2], S[3], -1)
        assert not np.allclose(ds_old[1], refs[1][0] @ mb + refs[1][1], atol=1e-3)
        assert not np.allclose(Ps_old[1], refs[1][0] @ Cb @ refs[1][0].T, atol=1e-3)
