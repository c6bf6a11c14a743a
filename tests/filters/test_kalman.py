"""Tests of the Kalman core ``aidnav.filters.kalman`` (and the closed-loop RTS pass of ``loose``).

(a) ``discretize`` (third-order Taylor Φ, Qd) against the exact ``van_loan`` on random stable
    systems: error bounds from the first neglected series term and the convergence order
    (Φ error ∝ T³, Qd error ∝ T⁴); ``van_loan`` itself against a quadrature of ∫ Φ Q Φᵀ.
(b) ``update`` = the textbook gain form (I − KH)P and the information form; = the Joseph product form it
    replaced (issue 40) on ill-scaled SPD P with diagonal and full R; gating.
(c) ``update_scalar`` sequentially = ``update`` in one batch for a diagonal R.
(d) RTS: the forward filter + ``rts_gain`` backward pass, and the closed-loop ``_rts_kernel`` used by
    the loosely coupled smoother, equal the dense Gaussian conditioning of the stacked linear system.

Units are arbitrary (consistent) in these algebraic checks.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad_vec
from scipy.linalg import expm
from scipy.stats import chi2

from aidnav.filters.ins_errors import fill_model, noise_count
from aidnav.filters.kalman import discretize, predict, rts_gain, update, update_scalar, van_loan
from aidnav.filters.loose import _rts_kernel


def random_system(rng, n=6, m=4, f_scale=1.0):
    """Random stable F (eigenvalues with negative real parts, plus rotation), G (n×m), q > 0."""
    a = rng.normal(size=(n, n))
    skew = 0.5 * (a - a.T)
    b = rng.normal(size=(n, n))
    F = f_scale * (skew - 0.3 * (b @ b.T) / n - 0.1 * np.eye(n))
    G = rng.normal(size=(n, m))
    q = rng.uniform(0.5, 2.0, m)
    return F, G, q


def random_spd(rng, n, scale=1.0):
    a = rng.normal(size=(n, n))
    return scale * (a @ a.T / n + 0.1 * np.eye(n))


# ------------------------------------------------------------------------ (a) discretisation
@pytest.mark.parametrize("seed", range(5))
def test_discretize_matches_van_loan_with_taylor_error_bounds(seed):
    rng = np.random.default_rng(seed)
    n, m = 6, 4
    F, G, q = random_system(rng, n, m)
    nf = np.linalg.norm(F, 2)
    Q = (G * q) @ G.T
    nq = np.linalg.norm(Q, 2)
    errs_phi, errs_qd = [], []
    for T in (0.02 / nf, 0.01 / nf, 0.005 / nf):  # ‖F‖T = 0.02 ... 0.005
        Phi, Qd = np.zeros((n, n)), np.zeros((n, n))
        discretize(F, G, q, T, Phi, Qd)
        Phi_x, Qd_x = van_loan(F, G, q, T)
        e_phi = np.linalg.norm(Phi - Phi_x, 2)
        e_qd = np.linalg.norm(Qd - Qd_x, 2)
        x = nf * T
        # first neglected terms: (FT)³/3! for Φ; T⁴/4! (F³Q + 3F²QFᵀ + 3FQF²ᵀ + QF³ᵀ) for Qd
        # (norm ≤ 8‖F‖³‖Q‖T⁴/24); the factor 1.1 covers the (geometric) tail at ‖F‖T ≤ 0.02
        assert e_phi <= 1.1 * x**3 / 6.0
        assert e_qd <= 1.1 * 8.0 * x**3 * nq * T / 24.0
        # "Φ to 1e-6 relative at small T" (‖F‖T = 0.01 gives ≤ 1.7e-7)
        if x <= 0.0101:
            assert e_phi / np.linalg.norm(Phi_x, 2) < 1e-6
            assert e_qd / np.linalg.norm(Qd_x, 2) < 1e-6
        errs_phi.append(e_phi)
        errs_qd.append(e_qd)
        # symmetric Qd
        assert np.allclose(Qd, Qd.T, rtol=0, atol=1e-15 * np.abs(Qd).max())
    # convergence orders: halving T divides the Φ error by 2³ and the Qd error by 2⁴ (third-order Qd)
    for a, b in zip(errs_phi[:-1], errs_phi[1:], strict=True):
        assert np.log2(a / b) == pytest.approx(3.0, abs=0.15)
    for a, b in zip(errs_qd[:-1], errs_qd[1:], strict=True):
        assert np.log2(a / b) == pytest.approx(4.0, abs=0.15)


def test_van_loan_is_the_exact_integral():
    rng = np.random.default_rng(11)
    F, G, q = random_system(rng, 5, 3)
    T = 0.7
    Q = (G * q) @ G.T
    Phi_x, Qd_x = van_loan(F, G, q, T)
    assert np.allclose(Phi_x, expm(F * T), rtol=0, atol=1e-13)
    integral, _ = quad_vec(lambda s: expm(F * s) @ Q @ expm(F * s).T, 0.0, T, epsabs=1e-13, epsrel=1e-12)
    assert np.allclose(Qd_x, integral, rtol=0, atol=1e-10 * np.abs(integral).max())


def test_discretize_ins_model_at_one_second():
    """Module doc: at T = 1 s the INS model's truncation is small for the navigation states.

    Measured: Φ nav block 1.5e-5, Qd attitude block 1e-10, velocity block 6e-6 relative. The position
    block misses 3e-3 relative: the ARW reaches position through [f×] and two integrations, a T⁵
    term (q_g f² T⁵/20) beyond the third-order series (harmless: it is ~1e-10 m² per second against
    position variances of 1e-2 m² and more)."""
    n = 15
    m = noise_count(n)
    F, G = np.zeros((n, n)), np.zeros((n, m))
    lat, h = np.radians(45.0), 3000.0
    v = np.array([120.0, 80.0, 2.0])
    fn = np.array([1.5, -2.0, 9.9])
    C = np.eye(3)
    fill_model(F, G, lat, h, v, fn, C, np.zeros(3), C.T @ fn, (3600.0, 3600.0, 0.0, 0.0))
    q = np.array([(0.1 * np.pi / 180 / 60) ** 2] * 3 + [(0.03 / 60) ** 2] * 3
                 + [2 * (0.3 * np.pi / 180 / 3600) ** 2 / 3600] * 3 + [2 * (50e-6 * 9.8) ** 2 / 3600] * 3)
    Phi, Qd = np.zeros((n, n)), np.zeros((n, n))
    discretize(F, G, q, 1.0, Phi, Qd)
    Phi_x, Qd_x = van_loan(F, G, q, 1.0)
    nav = slice(0, 9)
    assert np.linalg.norm(Phi[nav, nav] - Phi_x[nav, nav]) < 1e-3 * np.linalg.norm(Phi_x[nav, nav])
    # Qd per navigation block (attitude, velocity, position): relative to that block's size
    for b, tol in ((slice(0, 3), 1e-6), (slice(3, 6), 1e-4), (slice(6, 9), 1e-2)):
        assert np.linalg.norm(Qd[b, b] - Qd_x[b, b]) < tol * np.linalg.norm(Qd_x[b, b])


def test_predict():
    rng = np.random.default_rng(3)
    n = 5
    x = rng.normal(size=n)
    P = random_spd(rng, n)
    Phi = rng.normal(size=(n, n))
    Qd = random_spd(rng, n, 0.1)
    x0, P0 = x.copy(), P.copy()
    predict(x, P, Phi, Qd)
    assert np.allclose(x, Phi @ x0, rtol=1e-13, atol=1e-13)
    assert np.allclose(P, Phi @ P0 @ Phi.T + Qd, rtol=1e-12, atol=1e-12)
    assert np.array_equal(P, P.T)


# ----------------------------------------------------------------------------- (b) update
@pytest.mark.parametrize("seed", range(4))
def test_update_equals_gain_form_and_information_form(seed):
    rng = np.random.default_rng(100 + seed)
    n, m = 9, 3
    P = random_spd(rng, n)
    x = rng.normal(size=n)
    H = rng.normal(size=(m, n))
    R = random_spd(rng, m, 0.5)
    z = H @ x + rng.normal(size=m)
    xk, Pk = x.copy(), P.copy()
    innov, sd = np.zeros(m), np.zeros(m)
    ok, nis = update(xk, Pk, H, R, z, 0.0, innov, sd)
    assert ok
    # textbook gain form
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    x_t = x + K @ (z - H @ x)
    P_t = (np.eye(n) - K @ H) @ P
    # information form
    Ri = np.linalg.inv(R)
    P_i = np.linalg.inv(np.linalg.inv(P) + H.T @ Ri @ H)
    x_i = P_i @ (np.linalg.solve(P, x) + H.T @ Ri @ z)
    sc = np.abs(P).max()
    for xr, Pr in ((x_t, P_t), (x_i, P_i)):
        assert np.allclose(xk, xr, rtol=0, atol=1e-10 * np.abs(xr).max())
        assert np.allclose(Pk, Pr, rtol=0, atol=1e-10 * sc)
    assert np.array_equal(Pk, Pk.T)
    nu = z - H @ x
    assert np.allclose(innov, nu, rtol=1e-13, atol=1e-13)
    assert np.allclose(sd, np.diag(S), rtol=1e-13)
    assert nis == pytest.approx(nu @ np.linalg.solve(S, nu), rel=1e-10)


def _joseph_product(x, P, H, R, z):
    """The Joseph update in its product form, (I − K H) P (I − K H)ᵀ + K R Kᵀ then symmetrised: ``update``'s
    form before issue 40 (2n³ per update; ``update`` now expands it, O(n²m))."""
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    IKH = np.eye(x.shape[0]) - K @ H
    Pn = IKH @ P @ IKH.T + K @ R @ K.T
    return x + K @ (z - H @ x), 0.5 * (Pn + Pn.T)


@pytest.mark.parametrize("m", [1, 3, 6])
@pytest.mark.parametrize("full_r", [False, True])
def test_update_equals_the_joseph_product_form(m, full_r):
    """A 33-state P scaled like the tight filter's (variances 1e-10 … 1e6: attitude, biases, clock) with
    correlations; R diagonal or full: the expanded update = the product form to 1e-9 of each entry's scale
    (√(Pᵢᵢ Pⱼⱼ)), over 5 chained updates."""
    rng = np.random.default_rng(300 + m + 10 * full_r)
    n = 33
    d = 10.0 ** rng.uniform(-5, 3, n)  # standard deviations
    C = random_spd(rng, n)
    C /= np.sqrt(np.outer(np.diag(C), np.diag(C)))
    P = C * np.outer(d, d)
    x = rng.normal(size=n) * d
    xk, Pk, xr, Pr = x.copy(), P.copy(), x.copy(), P.copy()
    for _ in range(5):
        H = rng.normal(size=(m, n)) * (rng.uniform(size=(m, n)) < 0.3) / d.mean()
        R = random_spd(rng, m, 0.5) if full_r else np.diag(rng.uniform(0.1, 2.0, m))
        z = H @ x + rng.normal(size=m)
        ok, _ = update(xk, Pk, H, R, z, 0.0, np.zeros(m), np.zeros(m))
        assert ok
        xr, Pr = _joseph_product(xr, Pr, H, R, z)
        sc = np.sqrt(np.outer(np.diag(Pr), np.diag(Pr)))
        assert np.abs(Pk - Pr).max() > 0 or m == 1  # a different computation, not a copy of the reference
        assert np.all(np.abs(Pk - Pr) <= 1e-9 * sc)
        assert np.all(np.abs(xk - xr) <= 1e-9 * np.sqrt(np.diag(Pr)))
        assert np.array_equal(Pk, Pk.T)
        assert np.linalg.eigvalsh(Pk / sc).min() > 0


def test_update_joseph_form_keeps_p_positive_definite_with_suboptimal_round_off():
    """A very precise measurement of an uncertain state (κ(S) large): P stays symmetric PD."""
    rng = np.random.default_rng(7)
    n = 6
    P = np.diag([1e6, 1e6, 1e6, 1e-2, 1e-2, 1e-2])
    H = np.hstack([np.eye(3), np.zeros((3, 3))])
    R = np.eye(3) * 1e-8
    x = np.zeros(n)
    for _ in range(20):
        z = rng.normal(size=3) * 1e-4
        update(x, P, H, R, z, 0.0, np.zeros(3), np.zeros(3))
    assert np.array_equal(P, P.T)
    assert np.linalg.eigvalsh(P).min() > 0


def test_update_with_a_singular_innovation_covariance_raises():
    """S = H P Hᵀ + R singular (a row repeated, R = 0): the update raises as LAPACK's inverse did before
    issue 40's loops, instead of returning NaNs; x and P are left untouched."""
    P, x = np.eye(3), np.zeros(3)
    for H in (np.array([[0.0, 0.0, 0.0]]), np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])):
        m = H.shape[0]
        with pytest.raises(np.linalg.LinAlgError):
            update(x, P, H, np.zeros((m, m)), np.ones(m), 0.0, np.zeros(m), np.zeros(m))
        assert np.array_equal(P, np.eye(3)) and not x.any()


def test_update_gating_rejects_beyond_chi2_threshold_and_records():
    rng = np.random.default_rng(5)
    n, m = 6, 3
    P = random_spd(rng, n)
    H = rng.normal(size=(m, n))
    R = np.diag([0.5, 0.7, 0.9])
    S = H @ P @ H.T + R
    gate = chi2.ppf(0.9999, m)
    L = np.linalg.cholesky(S)
    direction = rng.normal(size=m)
    direction /= np.linalg.norm(direction)
    x0 = np.zeros(n)
    for d2, accept in ((1.01 * gate, False), (0.99 * gate, True)):
        nu = L @ direction * np.sqrt(d2)  # νᵀ S⁻¹ ν = d2
        x, Pk = x0.copy(), P.copy()
        innov, sd = np.full(m, np.nan), np.full(m, np.nan)
        ok, nis = update(x, Pk, H, R, nu, gate, innov, sd)
        assert ok == accept
        assert nis == pytest.approx(d2, rel=1e-10)
        assert np.allclose(innov, nu, rtol=1e-14, atol=0)
        assert np.allclose(sd, np.diag(S), rtol=1e-13)
        if accept:
            assert np.abs(x).max() > 0 and np.trace(Pk) < np.trace(P)
        else:
            assert np.array_equal(x, x0) and np.array_equal(Pk, P)
    # gate <= 0 disables gating
    x, Pk = x0.copy(), P.copy()
    ok, nis = update(x, Pk, H, R, L @ direction * 1e3, 0.0, np.zeros(m), np.zeros(m))
    assert ok and nis > gate


# ---------------------------------------------------------------------- (c) scalar updates
def test_update_scalar_sequential_equals_batch_for_diagonal_r():
    rng = np.random.default_rng(21)
    n, m = 15, 6
    P = random_spd(rng, n)
    x = rng.normal(size=n)
    H = rng.normal(size=(m, n))
    r = rng.uniform(0.1, 2.0, m)
    z = rng.normal(size=m) * 3
    xb, Pb = x.copy(), P.copy()
    update(xb, Pb, H, np.diag(r), z, 0.0, np.zeros(m), np.zeros(m))
    xs, Ps = x.copy(), P.copy()
    for i in range(m):
        ok, nu, s = update_scalar(xs, Ps, H[i].copy(), r[i], z[i], 0.0)
        assert ok
    assert np.allclose(xs, xb, rtol=0, atol=1e-10 * np.abs(xb).max())
    assert np.allclose(Ps, Pb, rtol=0, atol=1e-10 * np.abs(Pb).max())
    assert np.array_equal(Ps, Ps.T)  # exactly symmetric, scalar by scalar
    # scalar gating: ν²/s against the threshold; rejected updates change nothing
    h = H[0].copy()
    s_exp = h @ P @ h + r[0]
    z_far = h @ x + 5.0 * np.sqrt(s_exp)  # ν²/s = 25 > χ²₁(0.9999) = 15.1
    xg, Pg = x.copy(), P.copy()
    ok, nu, s = update_scalar(xg, Pg, h, r[0], z_far, chi2.ppf(0.9999, 1))
    assert not ok and s == pytest.approx(s_exp, rel=1e-12) and nu == pytest.approx(5.0 * np.sqrt(s_exp))
    assert np.array_equal(xg, x) and np.array_equal(Pg, P)


# --------------------------------------------------------------------------------- (d) RTS
def _cv_model(dt=1.0, q=0.05):
    """Constant-velocity model in 2-D (x, y, vx, vy): Φ, Qd (white-acceleration PSD q), H (position)."""
    Phi = np.eye(4)
    Phi[0, 2] = Phi[1, 3] = dt
    Q1 = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    Qd = np.zeros((4, 4))
    Qd[np.ix_([0, 2], [0, 2])] = Q1
    Qd[np.ix_([1, 3], [1, 3])] = Q1
    H = np.zeros((2, 4))
    H[0, 0] = H[1, 1] = 1.0
    return Phi, Qd, H


def _batch_smoother(m0, P0, Phi, Qd, H, R, ys):
    """Dense Gaussian conditioning of the stacked states X = [x_0 ... x_N] on all measurements."""
    n = m0.size
    N = len(ys)
    mean = np.zeros(N * n)
    cov = np.zeros((N * n, N * n))
    Phis = [np.eye(n)]
    for _ in range(1, N):
        Phis.append(Phi @ Phis[-1])
    for k in range(N):
        mean[k * n:(k + 1) * n] = Phis[k] @ m0
    # Cov(x_j, x_k) for j <= k: Φ^(k-j) Cov(x_j)
    Pk = P0.copy()
    marg = [P0]
    for _ in range(1, N):
        Pk = Phi @ Pk @ Phi.T + Qd
        marg.append(Pk)
    for j in range(N):
        for k in range(j, N):
            c = np.linalg.matrix_power(Phi, k - j) @ marg[j]
            cov[k * n:(k + 1) * n, j * n:(j + 1) * n] = c
            cov[j * n:(j + 1) * n, k * n:(k + 1) * n] = c.T
    Hb = np.kron(np.eye(N), H)
    Rb = np.kron(np.eye(N), R)
    S = Hb @ cov @ Hb.T + Rb
    K = np.linalg.solve(S, Hb @ cov).T
    y = np.concatenate(ys)
    mean_s = mean + K @ (y - Hb @ mean)
    cov_s = cov - K @ Hb @ cov
    return mean_s.reshape(N, n), np.array([cov_s[k * n:(k + 1) * n, k * n:(k + 1) * n] for k in range(N)])


@pytest.fixture(scope="module")
def cv_problem():
    rng = np.random.default_rng(42)
    Phi, Qd, H = _cv_model()
    R = np.diag([4.0, 9.0])
    N = 40
    m0 = np.array([0.0, 0.0, 10.0, -5.0])
    P0 = np.diag([100.0, 100.0, 4.0, 4.0])
    x = m0 + np.linalg.cholesky(P0) @ rng.normal(size=4)
    ys = []
    for k in range(N):
        if k > 0:
            x = Phi @ x + np.linalg.cholesky(Qd) @ rng.normal(size=4)
        ys.append(H @ x + np.linalg.cholesky(R) @ rng.normal(size=2))
    ms, Pss = _batch_smoother(m0, P0, Phi, Qd, H, R, ys)
    return dict(Phi=Phi, Qd=Qd, H=H, R=R, m0=m0, P0=P0, ys=ys, ms=ms, Ps=Pss)


def test_rts_open_loop_equals_batch_smoother(cv_problem):
    c = cv_problem
    Phi, Qd, H, R = c["Phi"], c["Qd"], c["H"], c["R"]
    N = len(c["ys"])
    xs_post, Ps_post, xs_prior, Ps_prior = [], [], [], []
    x, P = c["m0"].copy(), c["P0"].copy()
    for k in range(N):
        if k > 0:
            predict(x, P, Phi, Qd)
        xs_prior.append(x.copy())
        Ps_prior.append(P.copy())
        update(x, P, H, R, c["ys"][k], 0.0, np.zeros(2), np.zeros(2))
        xs_post.append(x.copy())
        Ps_post.append(P.copy())
    xsm, Psm = [None] * N, [None] * N
    xsm[-1], Psm[-1] = xs_post[-1], Ps_post[-1]
    for k in range(N - 2, -1, -1):
        A = rts_gain(Ps_post[k], Phi, Ps_prior[k + 1])
        assert np.allclose(A, Ps_post[k] @ Phi.T @ np.linalg.inv(Ps_prior[k + 1]), rtol=1e-10, atol=1e-12)
        xsm[k] = xs_post[k] + A @ (xsm[k + 1] - xs_prior[k + 1])
        Psm[k] = Ps_post[k] + A @ (Psm[k + 1] - Ps_prior[k + 1]) @ A.T
    assert np.allclose(np.array(xsm), c["ms"], rtol=0, atol=1e-8 * np.abs(c["ms"]).max())
    assert np.allclose(np.array(Psm), c["Ps"], rtol=0, atol=1e-9 * np.abs(c["Ps"]).max())


def test_closed_loop_rts_kernel_equals_batch_smoother(cv_problem):
    """The error-state (closed-loop) form used by ``run_loose``: the nominal carries the estimate, the
    error state δx = nominal − truth is estimated at each node (dx) and fed back (nominal −= dx);
    ``_rts_kernel`` returns the smoothed error of the post-update nominal (smoothed = nominal − ds)."""
    c = cv_problem
    Phi, Qd, H, R = c["Phi"], c["Qd"], c["H"], c["R"]
    N = len(c["ys"])
    n = 4
    S_post, S_prior, S_phi, S_dx = (np.zeros((N, n, n)), np.zeros((N, n, n)), np.zeros((N, n, n)),
                                    np.zeros((N, n)))
    nominal = np.zeros((N, n))
    xn, P = c["m0"].copy(), c["P0"].copy()
    for k in range(N):
        if k > 0:
            xn = Phi @ xn
            P = Phi @ P @ Phi.T + Qd
        S_phi[k] = Phi if k > 0 else np.eye(n)
        S_prior[k] = P
        dx = np.zeros(n)
        # measurement of the error: z = H·nominal − y ≈ H δx
        update(dx, P, H, R, H @ xn - c["ys"][k], 0.0, np.zeros(2), np.zeros(2))
        xn = xn - dx
        S_post[k] = P
        S_dx[k] = dx
        nominal[k] = xn
    ds, Ps = _rts_kernel(S_post, S_prior, S_phi, S_dx, -1)  # -1: no re-initialisation break
    smoothed = nominal - ds
    assert np.allclose(smoothed, c["ms"], rtol=0, atol=1e-8 * np.abs(c["ms"]).max())
    assert np.allclose(Ps, c["Ps"], rtol=0, atol=1e-9 * np.abs(c["Ps"]).max())
