"""Statistical tests of the IMU error model (fixed seeds; bounds from the sampling distributions)."""

import numpy as np
import pytest
from scipy import stats

from aidnav.data import ImuData
from aidnav.sim.imu import GRADES, ImuSpec, corrupt_imu

P = 1e-6  # two-sided probability of a false alarm per check
ZMAX = stats.norm.isf(P / 2)  # ≈ 4.9


def chi2_band(dof):
    return stats.chi2.ppf(P / 2, dof), stats.chi2.isf(P / 2, dof)


def static_imu(n, dt=0.01, t_start=0.0):
    t = t_start + dt * np.arange(1, n + 1)
    dth = np.zeros((n, 3))
    dv = np.tile([0.0, 0.0, 9.8 * dt], (n, 1))
    return ImuData(t, dth, dv, t0=t_start)


# ------------------------------------------------------------------------------------------- units
def test_unit_conversions():
    s = ImuSpec.from_units(gyro_bias_deg_h=1.0, accel_bias_ug=1.0, arw_deg_sqrt_h=1.0, vrw_m_s_sqrt_h=1.0,
                           gyro_bias_instability_deg_h=2.0, accel_bias_instability_ug=3.0,
                           gyro_scale_ppm=1.0, accel_scale_ppm=2.0, misalignment_arcsec=1.0,
                           gyro_rrw_deg_h_sqrt_h=1.0, accel_rrw_ug_sqrt_h=1.0, bias_corr_time_s=100.0)
    np.testing.assert_allclose(s.gyro_bias, np.pi / 180 / 3600, rtol=1e-15)
    np.testing.assert_allclose(s.accel_bias, 9.80665e-6, rtol=1e-15)
    np.testing.assert_allclose(s.gyro_arw, np.pi / 180 / 60, rtol=1e-15)  # √h = 60 √s
    np.testing.assert_allclose(s.accel_vrw, 1 / 60, rtol=1e-15)
    np.testing.assert_allclose(s.gyro_bias_instability, 2 * np.pi / 180 / 3600, rtol=1e-15)
    np.testing.assert_allclose(s.accel_bias_instability, 3 * 9.80665e-6, rtol=1e-15)
    np.testing.assert_allclose(s.gyro_scale, 1e-6)
    np.testing.assert_allclose(s.accel_scale, 2e-6)
    np.testing.assert_allclose(s.gyro_misalignment, np.pi / 180 / 3600)
    np.testing.assert_allclose(s.gyro_rrw, np.pi / 180 / 3600 / 60)
    np.testing.assert_allclose(s.accel_rrw, 9.80665e-6 / 60)
    np.testing.assert_allclose(s.gyro_bias_tau, 100.0)
    back = s.to_units()
    np.testing.assert_allclose(back["gyro_bias_deg_h"], 1.0)
    np.testing.assert_allclose(back["accel_bias_ug"], 1.0)
    np.testing.assert_allclose(back["arw_deg_sqrt_h"], 1.0)


def test_per_axis_values():
    s = ImuSpec.from_units(gyro_bias_deg_h=[1, 2, 3], bias_mode="fixed")
    np.testing.assert_allclose(s.gyro_bias / (np.pi / 180 / 3600), [1, 2, 3])
    with pytest.raises(ValueError):
        ImuSpec.from_units(gyro_bias_deg_h=[1, 2])
    with pytest.raises(ValueError):
        ImuSpec.from_units(gyro_bias_deg_h=-1.0)  # random σ must be >= 0


def test_presets():
    deg_h, ug = np.pi / 180 / 3600, 9.80665e-6
    for g in GRADES:
        s = ImuSpec.grade(g)
        assert s.name == g
    for g in ("navigation", "tactical", "mems", "consumer", "seed004_high", "seed004_medium", "seed004_low"):
        assert g in GRADES
    t = ImuSpec.grade("Tactical")
    np.testing.assert_allclose(t.gyro_bias, deg_h)
    np.testing.assert_allclose(t.gyro_arw, 0.1 * np.pi / 180 / 60)
    np.testing.assert_allclose(t.accel_bias, 100 * ug)
    n = ImuSpec.grade("navigation")
    np.testing.assert_allclose(n.gyro_bias, 0.005 * deg_h)
    np.testing.assert_allclose(n.gyro_arw, 0.002 * np.pi / 180 / 60)
    np.testing.assert_allclose(n.accel_bias, 10 * ug)
    m = ImuSpec.grade("mems")
    np.testing.assert_allclose(m.gyro_bias, 10 * deg_h)
    np.testing.assert_allclose(m.gyro_arw, 0.3 * np.pi / 180 / 60)
    np.testing.assert_allclose(m.accel_bias, 1000 * ug)
    # seed 004 Table 1: constant X deg/h and random X deg/h/√Hz (= X deg/h·√s); accel Y µg and Y µg/√Hz
    for g, x, y in (("seed004_high", 0.01, 10), ("seed004_medium", 0.05, 50), ("seed004_low", 0.1, 100),
                    ("seed004_sub", 0.1, 50)):
        s = ImuSpec.grade(g)
        np.testing.assert_allclose(s.gyro_bias, x * deg_h, rtol=1e-14)
        np.testing.assert_allclose(s.gyro_arw, x * deg_h, rtol=1e-14)  # rad/s/√Hz = rad/√s
        np.testing.assert_allclose(s.accel_bias, y * ug, rtol=1e-14)
        np.testing.assert_allclose(s.accel_vrw, y * ug, rtol=1e-14)
        assert not np.any(s.gyro_bias_instability) and not np.any(s.gyro_scale)
    s0 = ImuSpec.grade("seed000")
    np.testing.assert_allclose(s0.gyro_bias, 0.1 * deg_h)
    np.testing.assert_allclose(s0.gyro_arw, 0.01 * deg_h)
    np.testing.assert_allclose(s0.accel_bias, 500 * ug)
    np.testing.assert_allclose(s0.accel_vrw, 100 * ug)
    assert ImuSpec.grade("perfect").is_perfect
    with pytest.raises(ValueError, match="unknown grade"):
        ImuSpec.grade("military")


def test_from_config():
    s = ImuSpec.from_config({"grade": "tactical", "arw_deg_sqrt_h": 0.2, "misalignment_arcsec": 10,
                             "gyro_quant_rad": 1e-7, "accel_bias_ug": None})
    np.testing.assert_allclose(s.gyro_arw, 0.2 * np.pi / 180 / 60)
    np.testing.assert_allclose(s.accel_bias, 100 * 9.80665e-6)  # None → preset value kept
    np.testing.assert_allclose(s.accel_misalignment, 10 * np.pi / 180 / 3600)
    assert s.gyro_quant == 1e-7 and s.name == "tactical"
    with pytest.raises(ValueError, match="gyro_bias_dph"):
        ImuSpec.from_config({"grade": "mems", "gyro_bias_dph": 1.0})
    with pytest.raises(ValueError, match="unknown grade"):
        ImuSpec.from_config({"grade": "nope"})
    assert ImuSpec.from_config({"grade": "mems", "perfect": True}).is_perfect
    assert not ImuSpec.from_config({"grade": "mems", "perfect": False}).is_perfect
    fixed = ImuSpec.from_config({"gyro_bias_deg_h": [1, -2, 3], "bias_mode": "fixed"})
    np.testing.assert_allclose(fixed.gyro_bias / (np.pi / 180 / 3600), [1, -2, 3])

    class Model:  # pydantic-like
        def model_dump(self):
            return {"grade": "navigation", "vrw_m_s_sqrt_h": 0.01, "perfect": None}

    s = ImuSpec.from_config(Model())
    np.testing.assert_allclose(s.accel_vrw, 0.01 / 60)


# ----------------------------------------------------------------------------------- behaviour
def test_perfect_is_identity():
    rng = np.random.default_rng(5)
    n = 1000
    imu = ImuData(0.01 * np.arange(1, n + 1), rng.normal(size=(n, 3)) * 1e-3, rng.normal(size=(n, 3)) * 0.1,
                  t0=0.0)
    out, real = corrupt_imu(imu, ImuSpec.perfect(), np.random.default_rng(1))
    assert np.array_equal(out.dtheta, imu.dtheta) and np.array_equal(out.dv, imu.dv)
    assert np.array_equal(out.time, imu.time) and out.t0 == imu.t0
    assert not np.any(real["gyro_bias"]) and np.array_equal(real["gyro_matrix"], np.eye(3))


def test_reproducible_and_seed_dependent():
    imu = static_imu(2000)
    spec = ImuSpec.grade("mems")
    a, ra = corrupt_imu(imu, spec, np.random.default_rng(42))
    b, rb = corrupt_imu(imu, spec, np.random.default_rng(42))
    c, _ = corrupt_imu(imu, spec, np.random.default_rng(43))
    assert np.array_equal(a.dtheta, b.dtheta) and np.array_equal(a.dv, b.dv)
    assert np.array_equal(ra["gyro_bias"], rb["gyro_bias"])
    assert not np.allclose(a.dtheta, c.dtheta)


def test_white_noise_chi_square_nonuniform_dt():
    """ARW/VRW: increment noise has σ·√Δt_k, per sample, also for non-uniform intervals."""
    rng = np.random.default_rng(11)
    n = 100_000
    dt = rng.uniform(0.005, 0.02, n)
    t = np.cumsum(dt)
    imu = ImuData(t, np.zeros((n, 3)), np.zeros((n, 3)), t0=0.0)
    spec = ImuSpec.from_units(arw_deg_sqrt_h=[0.1, 0.2, 0.3], vrw_m_s_sqrt_h=[0.05, 0.05, 0.1])
    out, _ = corrupt_imu(imu, spec, np.random.default_rng(12))
    lo, hi = chi2_band(n)
    for x, sig in ((out.dtheta, spec.gyro_arw), (out.dv, spec.accel_vrw)):
        z = x / (sig * np.sqrt(dt)[:, None])
        ss = np.sum(z**2, axis=0)  # known zero mean → χ²(n)
        assert np.all((ss > lo) & (ss < hi)), (ss / n)
        # and uncorrelated between samples (lag-1 correlation ~ N(0, 1/n))
        r1 = np.sum(z[1:] * z[:-1], axis=0) / ss
        assert np.all(np.abs(r1) < ZMAX / np.sqrt(n))


def test_gauss_markov_variance_and_correlation():
    n, dt, tau = 200_000, 0.01, 1.0
    spec = ImuSpec.from_units(gyro_bias_instability_deg_h=[10, 20, 30],
                              accel_bias_instability_ug=[100, 200, 300], bias_corr_time_s=tau)
    imu = static_imu(n, dt)
    out, real = corrupt_imu(imu, spec, np.random.default_rng(3), return_drift=True)
    # the increments carry exactly the drift (held over each interval)
    h = np.diff(np.concatenate(([imu.t0], imu.time)))[:, None]
    np.testing.assert_allclose(out.dtheta, real["gyro_drift"] * h, rtol=1e-13, atol=1e-22)
    np.testing.assert_allclose(out.dv - imu.dv, real["accel_drift"] * h, rtol=1e-9, atol=1e-17)
    sig = np.concatenate((spec.gyro_bias_instability, spec.accel_bias_instability))
    x = np.concatenate((real["gyro_drift"], real["accel_drift"]), axis=1) / sig  # unit stationary variance
    phi = np.exp(-dt / tau)
    k = x.shape[1]
    # stationary variance: var(mean(x²)) = (2/n)(1+φ²)/(1-φ²) for an AR(1) with known zero mean
    v = np.mean(x**2, axis=0)
    sd_v = np.sqrt(2.0 / n * (1 + phi**2) / (1 - phi**2))
    assert abs(v.mean() - 1.0) < ZMAX * sd_v / np.sqrt(k), v
    assert np.all(np.abs(v - 1.0) < ZMAX * sd_v), v
    # lag-τ autocorrelation e^{-1}; Bartlett's variance for an AR(1)
    lag = int(round(tau / dt))
    r = np.sum(x[lag:] * x[:-lag], axis=0) / np.sum(x**2, axis=0)
    p2l = phi ** (2 * lag)
    sd_r = np.sqrt(((1 + phi**2) * (1 - p2l) / (1 - phi**2) - 2 * lag * p2l) / n)
    assert np.all(np.abs(r - np.exp(-1.0)) < ZMAX * sd_r), (r, sd_r)
    assert abs(r.mean() - np.exp(-1.0)) < ZMAX * sd_r / np.sqrt(k)


def test_turn_on_draws_distribution():
    """Constant bias σ, GM initial state (stationary), scale σ, misalignment σ over many runs."""
    spec = ImuSpec.from_units(gyro_bias_deg_h=[1, 2, 3], accel_bias_ug=[10, 20, 30],
                              gyro_bias_instability_deg_h=0.5, accel_bias_instability_ug=5.0,
                              gyro_scale_ppm=100, accel_scale_ppm=[100, 200, 300], misalignment_arcsec=20)
    imu = static_imu(2)
    rng = np.random.default_rng(99)
    runs = [corrupt_imu(imu, spec, rng)[1] for _ in range(3000)]
    checks = [("gyro_bias", spec.gyro_bias), ("accel_bias", spec.accel_bias),
              ("gyro_bias_gm0", spec.gyro_bias_instability), ("accel_bias_gm0", spec.accel_bias_instability),
              ("gyro_scale", spec.gyro_scale), ("accel_scale", spec.accel_scale)]
    for key, sig in checks:
        z = np.array([r[key] for r in runs]) / sig
        lo, hi = chi2_band(z.size)
        assert lo < np.sum(z**2) < hi, key
    off = ~np.eye(3, dtype=bool)
    for key, sig in (("gyro_misalignment", spec.gyro_misalignment), ("accel_misalignment",
                                                                     spec.accel_misalignment)):
        m = np.array([r[key] for r in runs])
        assert not np.any(m[:, ~off])
        z = m[:, off] / sig[0]
        lo, hi = chi2_band(z.size)
        assert lo < np.sum(z**2) < hi, key


def test_constant_bias_is_mean_offset():
    n, dt = 100_000, 0.01
    for mode in ("fixed", "random"):
        sign = np.array([1.0, -1.0, 1.0]) if mode == "fixed" else 1.0  # a random σ is >= 0
        spec = ImuSpec.from_units(gyro_bias_deg_h=sign * np.array([1.0, 2.0, 3.0]),
                                  accel_bias_ug=sign * np.array([100, 200, 50]),
                                  arw_deg_sqrt_h=0.1, vrw_m_s_sqrt_h=0.05, bias_mode=mode)
        imu = static_imu(n, dt)
        out, real = corrupt_imu(imu, spec, np.random.default_rng(8))
        if mode == "fixed":
            np.testing.assert_array_equal(real["gyro_bias"], spec.gyro_bias)
            np.testing.assert_array_equal(real["accel_bias"], spec.accel_bias)
        mg = out.dtheta.mean(axis=0) / dt
        ma = (out.dv - imu.dv).mean(axis=0) / dt
        # the mean of white rate noise over T = n·dt has σ = density/√T
        assert np.all(np.abs(mg - real["gyro_bias"]) < ZMAX * spec.gyro_arw / np.sqrt(n * dt))
        assert np.all(np.abs(ma - real["accel_bias"]) < ZMAX * spec.accel_vrw / np.sqrt(n * dt))


def test_scale_and_misalignment_matrix():
    rng = np.random.default_rng(21)
    n = 500
    imu = ImuData(0.01 * np.arange(1, n + 1), rng.normal(size=(n, 3)) * 0.01, rng.normal(size=(n, 3)) * 0.1,
                  t0=0.0)
    spec = ImuSpec.from_units(gyro_scale_ppm=1000, accel_scale_ppm=[500, 1000, 2000], misalignment_arcsec=100)
    out, real = corrupt_imu(imu, spec, np.random.default_rng(22))
    for s, m, mat in (("gyro_scale", "gyro_misalignment", "gyro_matrix"),
                      ("accel_scale", "accel_misalignment", "accel_matrix")):
        np.testing.assert_allclose(real[mat], np.eye(3) + np.diag(real[s]) + real[m], rtol=0, atol=1e-16)
        assert np.all(np.diag(real[m]) == 0)
    np.testing.assert_allclose(out.dtheta, imu.dtheta @ real["gyro_matrix"].T, rtol=1e-14, atol=1e-18)
    np.testing.assert_allclose(out.dv, imu.dv @ real["accel_matrix"].T, rtol=1e-14, atol=1e-17)


def test_quantisation_unbiased_with_residual_carry():
    n = 100_000
    q_g, q_a = 1e-5, 1e-3
    true_g = np.array([1.2345e-6, -3.3e-6, 7.77e-5])  # not multiples of the quantum
    true_a = np.array([0.098, 1.23e-4, -4.56e-4])
    imu = ImuData(0.01 * np.arange(1, n + 1), np.tile(true_g, (n, 1)), np.tile(true_a, (n, 1)), t0=0.0)
    spec = ImuSpec.from_units(gyro_quant_rad=q_g, accel_quant_m_s=q_a)
    out, _ = corrupt_imu(imu, spec, np.random.default_rng(4))
    for x, x0, q in ((out.dtheta, imu.dtheta, q_g), (out.dv, imu.dv, q_a)):
        k = x / q
        np.testing.assert_allclose(k, np.round(k), atol=1e-6)  # multiples of q
        err = np.cumsum(x - x0, axis=0)
        # running sum = input sum + r_0 - r_k with |r| <= q/2 (r_0 random): within q
        assert np.max(np.abs(err)) <= q * (1 + 1e-9)
        np.testing.assert_allclose(x.mean(axis=0), x0[0], atol=q / n)  # unbiased over the run


def test_rate_random_walk_variance():
    dt, n, runs = 0.1, 100, 2000
    spec = ImuSpec.from_units(gyro_rrw_deg_h_sqrt_h=[10, 20, 30], accel_rrw_ug_sqrt_h=100)
    imu = static_imu(n, dt)
    rng = np.random.default_rng(77)
    end = np.array([corrupt_imu(imu, spec, rng, return_drift=True)[1]["gyro_drift"][-1] for _ in range(runs)])
    z = end / (spec.gyro_rrw * np.sqrt(n * dt))  # var of the walk after T = σ²T
    lo, hi = chi2_band(z.size)
    assert lo < np.sum(z**2) < hi


def test_needs_t0_and_increasing_times():
    imu = ImuData(np.array([1.0]), np.zeros((1, 3)), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="t0"):
        corrupt_imu(imu, ImuSpec.grade("mems"), np.random.default_rng(0))


# ------------------------------------------------------------------------- kernel vs the original loop
def _reference_kernel(dth, dv, dt, mat_g, mat_a, b_g, b_a, gm_sig, gm_tau, white, rrw, quant, rng, state,
                      out_g, out_a, drift, keep_drift):
    """The corruption loop as first written (one triad after the other through array views), the reference
    of the element-by-element kernel."""
    n = dth.shape[0]
    h_last, sh = np.nan, 0.0
    g_fac, r_fac, w_fac, phis, z = np.empty(6), np.empty(6), np.empty(6), np.empty(6), np.empty(18)
    for k in range(n):
        for j in range(18):
            z[j] = rng.standard_normal()
        h = dt[k]
        if h != h_last:
            h_last, sh = h, np.sqrt(h)
            for c in range(6):
                phis[c] = np.exp(-h / gm_tau[c])
                g_fac[c] = gm_sig[c] * np.sqrt(max(0.0, 1.0 - phis[c] * phis[c]))
                r_fac[c] = rrw[c] * sh
                w_fac[c] = white[c] * sh
        for s in range(2):
            inc = dth[k] if s == 0 else dv[k]
            mat = mat_g if s == 0 else mat_a
            b = b_g if s == 0 else b_a
            q = quant[s]
            for i in range(3):
                c = 3 * s + i
                state[0, c] = phis[c] * state[0, c] + g_fac[c] * z[6 + c]
                state[1, c] += r_fac[c] * z[12 + c]
                dr = state[0, c] + state[1, c]
                if keep_drift:
                    drift[k, c] = dr
                x = mat[i, 0] * inc[0] + mat[i, 1] * inc[1] + mat[i, 2] * inc[2]
                x += (b[i] + dr) * h + w_fac[c] * z[c]
                if q > 0.0:
                    y = x + state[2, c]
                    xq = np.floor(y / q + 0.5) * q
                    state[2, c] = y - xq
                    x = xq
                if s == 0:
                    out_g[k, i] = x
                else:
                    out_a[k, i] = x


def test_kernel_bitwise_equal_to_reference():
    """The corruption kernel gives the reference loop's values bit for bit (every error term, quantisation
    with residual carry, Gauss-Markov and random walk drift, uneven intervals)."""
    from numba import njit

    from aidnav.sim.imu import _corrupt_kernel

    ref = njit(_reference_kernel)
    rng0 = np.random.default_rng(3)
    n = 3000
    dt = np.where(np.arange(n) % 7 == 3, 0.02, 0.01)
    dth, dv = rng0.normal(0, 1e-3, (n, 3)), rng0.normal(0, 0.1, (n, 3))
    mat_g, mat_a = np.eye(3) + rng0.normal(0, 1e-3, (3, 3)), np.eye(3) + rng0.normal(0, 1e-3, (3, 3))
    args = (dth, dv, dt, mat_g, mat_a, rng0.normal(0, 1e-5, 3), rng0.normal(0, 1e-3, 3),
            np.full(6, 1e-5), np.array([300.0, 600, np.inf, 100, 50, 3600]), np.full(6, 1e-3),
            np.full(6, 1e-6), np.array([1e-6, 1e-4]))
    outs = []
    for fn in (_corrupt_kernel, ref):
        state = np.array([[1e-6] * 6, [0.0] * 6, [3e-7, -2e-7, 1e-7, 2e-5, -1e-5, 4e-5]])
        o = (np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 6)))
        fn(*args, np.random.default_rng(11), state, o[0], o[1], o[2], True)
        outs.append(o + (state,))
    for a, b in zip(*outs, strict=True):
        assert np.array_equal(a, b)
    assert np.any(outs[0][0] != dth)
