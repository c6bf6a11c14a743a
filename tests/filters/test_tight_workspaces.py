"""The tight run's work arrays passed in (issue 40, session 16) against the allocating originals and dense
references: the head's series with a workspace reused across calls of other sizes and sparsity, the scalar
update over h's nonzero entries, the per-sample strapdown on one buffer array, and the epoch's satellite
geometry computed once."""

from __future__ import annotations

import numpy as np

from aidnav.filters.ins_errors import (
    increment_buffers,
    new_accumulator,
    propagate_sample,
    propagate_sample_rows,
)
from aidnav.filters.kalman import (
    discretize,
    discretize_sparse,
    discretize_sparse_ws,
    discretize_split,
    sparse_work,
    update,
    update_scalar,
    update_scalar_ws,
)
from aidnav.filters.measurements.epoch import E_W, _geometry
from aidnav.nav.gnss_sat import az_el, geo_range
from aidnav.nav.strapdown import strapdown_step, strapdown_step_rows


def _sparse_system(rng, n, m, density):
    F = rng.normal(size=(n, n)) * 0.05 * (rng.random((n, n)) < density)
    G = rng.normal(size=(n, m)) * (rng.random((n, m)) < 0.3)
    return F, G, rng.random(m) * 1e-3


def test_series_with_a_reused_workspace_is_the_allocating_series():
    """:func:`discretize_sparse_ws` with one workspace (sized for 20 states) reused over systems of other
    sizes and sparsity gives :func:`discretize_sparse`'s Φ, Qd bit for bit, and :func:`discretize`'s to
    rounding; a workspace whose products are not reset would carry the previous call into the next."""
    rng = np.random.default_rng(5)
    ws = sparse_work(20)
    for n, m, density in ((17, 13, 0.2), (9, 6, 0.9), (20, 20, 0.05), (17, 13, 0.3), (3, 2, 1.0)):
        F, G, q = _sparse_system(rng, n, m, density)
        T = rng.uniform(0.05, 1.0)
        Phi_ref, Qd_ref = np.zeros((n, n)), np.zeros((n, n))
        discretize_sparse(F, G, q, T, Phi_ref, Qd_ref)
        Phi, Qd = np.full((n, n), np.nan), np.full((n, n), np.nan)
        discretize_sparse_ws(F, G, q, T, Phi, Qd, ws)
        np.testing.assert_array_equal(Phi, Phi_ref)
        np.testing.assert_array_equal(Qd, Qd_ref)
        Phi_d, Qd_d = np.zeros((n, n)), np.zeros((n, n))
        discretize(F, G, q, T, Phi_d, Qd_d)
        np.testing.assert_allclose(Phi, Phi_d, rtol=0, atol=1e-14)
        np.testing.assert_allclose(Qd, Qd_d, rtol=0, atol=1e-12 * np.abs(Qd_d).max())
    # the split head's coupling Φ_DC = F_DC T + F_DD F_DC T²/2 with and without the workspace: the same bits
    d, c = 17, 12
    Fd, Gd, q = _sparse_system(rng, d, 13, 0.2)
    Fdc = rng.normal(size=(d, c)) * (rng.random((d, c)) < 0.3)
    outs = []
    for w in (None, ws):
        Phd, Phdc, Qdd = np.zeros((d, d)), np.full((d, c), np.nan), np.zeros((d, d))
        discretize_split(Fd, Fdc, Gd, q, 0.7, Phd, Phdc, Qdd, w)
        outs.append((Phd, Phdc, Qdd))
    for a, b in zip(*outs, strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(outs[0][1], Fdc * 0.7 + Fd @ Fdc * 0.7 ** 2 / 2, rtol=0, atol=1e-15)


def test_scalar_update_over_the_nonzero_entries_equals_the_batch_update():
    """:func:`update_scalar_ws` (p = P h over h's nonzero entries, work rows reused) equals the batch Joseph
    update :func:`update` of the same row to rounding, and the allocating :func:`update_scalar` bit for
    bit; the gate rejects what the batch update rejects, leaving x and P as they were."""
    rng = np.random.default_rng(9)
    n = 33
    A = rng.normal(size=(n, n))
    P0 = A @ A.T / n + np.eye(n)
    x0 = rng.normal(size=n) * 0.1
    ws = np.full((2, n), np.nan)
    for _ in range(6):
        h = np.zeros(n)
        nz = rng.choice(n, size=10, replace=False)
        h[nz] = rng.normal(size=10)
        r, z = rng.uniform(0.5, 4.0), rng.normal()
        x1, P1 = x0.copy(), P0.copy()
        ok1, nu1, s1 = update_scalar_ws(x1, P1, h, r, z, 0.0, ws)
        x2, P2 = x0.copy(), P0.copy()
        ok2, nu2, s2 = update_scalar(x2, P2, h, r, z, 0.0)
        assert ok1 and ok2 and nu1 == nu2 and s1 == s2
        np.testing.assert_array_equal(x1, x2)
        np.testing.assert_array_equal(P1, P2)
        np.testing.assert_array_equal(P1, P1.T)
        x3, P3 = x0.copy(), P0.copy()
        nu3, s3 = np.zeros(1), np.zeros(1)
        ok3, _ = update(x3, P3, h[None, :].copy(), np.array([[r]]), np.array([z]), 0.0, nu3, s3)
        assert ok3
        np.testing.assert_allclose(x1, x3, rtol=0, atol=1e-13)
        np.testing.assert_allclose(P1, P3, rtol=0, atol=1e-12)
        assert abs(s1 - s3[0]) < 1e-12 * s1 and abs(nu1 - nu3[0]) < 1e-12
    h = np.zeros(n)
    h[[0, 9, 30]] = 1.0
    x1, P1 = x0.copy(), P0.copy()
    ok, nu, s = update_scalar_ws(x1, P1, h, 1.0, 1e3, 9.0, ws)  # far outside the gate
    assert not ok and nu * nu / s > 9.0
    np.testing.assert_array_equal(x1, x0)
    np.testing.assert_array_equal(P1, P0)


def test_per_sample_propagation_on_one_buffer_is_the_original_bit_for_bit():
    """:func:`propagate_sample_rows` (the increments read by index, the buffers as rows of one array)
    gives :func:`propagate_sample`'s state, accumulator and buffers bit for bit over 400 samples, for each
    sensor-error model (0, 6, 12, 18, 24 estimates); and :func:`strapdown_step_rows` is
    :func:`strapdown_step` bit for bit."""
    rng = np.random.default_rng(3)
    N = 400
    dth = rng.normal(size=(N, 3)) * 2e-3 + np.array([0.0, 0.0, 1e-3])
    dth[::97] *= 80.0  # a few rotations above the series' range (the exact branch of the quaternion)
    dv = rng.normal(size=(N, 3)) * 2e-2 + np.array([0.0, 0.0, 0.098])
    t = np.cumsum(np.full(N, 0.01) + rng.random(N) * 1e-4)
    st0 = np.array([0.6, 0.2, 120.0, 3.0, -2.0, 0.1, 0.9, 0.1, -0.2, np.sqrt(1 - 0.81 - 0.01 - 0.04)])
    for nb in (0, 6, 12, 18, 24):
        bias = rng.normal(size=nb) * 1e-3
        st1, st2 = st0.copy(), st0.copy()
        acc1, acc2 = new_accumulator(), new_accumulator()
        b1 = increment_buffers()
        buf = np.zeros((4, 3))
        tp = 0.0
        for k in range(N):
            dt, tp = t[k] - tp, t[k]
            T1 = propagate_sample(st1, acc1, dth[k], dv[k], bias, dt, *b1)
            T2 = propagate_sample_rows(st2, acc2, dth, dv, k, bias, dt, buf)
            assert T1 == T2
        np.testing.assert_array_equal(st1, st2)
        np.testing.assert_array_equal(acc1, acc2)
        np.testing.assert_array_equal(np.array(b1), buf)
        assert not np.array_equal(st1, st0)
    a = np.zeros((4, 3))
    a[:] = rng.normal(size=(4, 3)) * 1e-2
    s1, s2 = st0.copy(), st0.copy()
    strapdown_step(s1, a[0].copy(), a[1].copy(), a[2].copy(), a[3].copy(), 0.01)
    strapdown_step_rows(s2, a, 0.01)
    np.testing.assert_array_equal(s1, s2)


def test_epoch_geometry_is_the_per_satellite_computation():
    """:func:`.measurements.epoch._geometry` holds, for each satellite with a code and a position, the
    range and unit vector of :func:`geo_range` and the azimuth and elevation of :func:`az_el` bit for bit;
    the rows of the others are left as they were."""
    rng = np.random.default_rng(2)
    S = 7
    row = np.full(S * E_W, np.nan)
    ra = np.array([4.0e6, 0.9e6, 4.8e6])
    for j in range(S):
        o = j * E_W
        row[o:o + 3] = ra + rng.normal(size=3) * 1.5e7
        row[o + 6] = 2.2e7
    row[2 * E_W + 6] = np.nan  # no code
    row[5 * E_W] = np.nan  # no position
    geo = np.full((S, 6), -1.0)
    lat, lon = 0.85, 0.22
    _geometry(row, ra, lat, lon, geo)
    for j in range(S):
        if j in (2, 5):
            assert (geo[j] == -1.0).all()
            continue
        rho, e = geo_range(row[j * E_W:j * E_W + 3], ra)
        az, el, _ = az_el(e, lat, lon)
        np.testing.assert_array_equal(geo[j], [rho, e[0], e[1], e[2], az, el])
