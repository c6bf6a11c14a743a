"""Distributed POS simulation (seed 004): flexure generator, lever-arm terms, sub-IMU, master output.

Frames and units as in ``docs/conventions.md``: n = ENU, b = RFU, radians, metres, seconds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from aidnav.filters.kalman import van_loan
from aidnav.nav.earth import lla_to_ecef
from aidnav.nav.rotations import attitude_error_batch, dcm_from_euler, euler_to_quat_batch, quat_from_euler
from aidnav.nav.strapdown import make_state, mechanize
from aidnav.sim import distributed_pos as dp
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth

DEG = math.pi / 180.0
INI = {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 7000.0, "speed_m_s": 100.0, "heading_deg": 40.0}


@pytest.fixture(scope="module")
def turning():
    """Straight 20 s, a 90° right turn in 60 s (0.9°/s at 100 m/s, bank ≈ 9°), straight 20 s."""
    scn = parse_scenario(
        {
            "initial": INI,
            "segments": [
                {"type": "straight", "duration_s": 20.0},
                {"type": "turn", "angle_deg": 54.0, "duration_s": 60.0, "name": "turn"},
                {"type": "straight", "duration_s": 20.0, "name": "AB"},
            ],
        },
        "<turning>",
    )
    return generate_truth(scn)


# ------------------------------------------------------------------------------------------- flexure
@pytest.mark.parametrize("dt", [0.01, 1.0])
def test_flexure_transition_is_exact(dt):
    spec = dp.FlexureSpec()
    for beta, sigma, q in zip(spec.beta, spec.sigma, spec.q_eta, strict=True):
        phi, qd = dp.flexure_transition(beta, sigma, dt)
        A = np.array([[0.0, 1.0], [-(beta**2), -2.0 * beta]])
        np.testing.assert_allclose(phi, expm(A * dt), rtol=1e-12, atol=1e-15)
        phi_vl, qd_vl = van_loan(A, np.array([[0.0], [1.0]]), np.array([q]), dt)
        np.testing.assert_allclose(phi, phi_vl, rtol=1e-10, atol=1e-15)
        np.testing.assert_allclose(qd, qd_vl, rtol=1e-6, atol=1e-12 * sigma**2)
        pinf = np.diag([sigma**2, (beta * sigma) ** 2])
        np.testing.assert_allclose(phi @ pinf @ phi.T + qd, pinf, rtol=1e-12, atol=1e-14 * sigma**2)
        # Q_η = 4β³σ² makes var θ = σ² (the Lyapunov solution of the continuous system)
        np.testing.assert_allclose(A @ pinf + pinf @ A.T + np.diag([0.0, q]), 0.0, atol=1e-14)


def _acf(x, nlag):
    x = x - x.mean(axis=0)
    nfft = 1 << int(math.ceil(math.log2(2 * len(x))))
    f = np.fft.rfft(x, nfft, axis=0)
    ac = np.fft.irfft(f * np.conj(f), nfft, axis=0)[:nlag] / len(x)
    return ac / ac[0]


def test_flexure_generator_std_and_lag():
    """σ̂ within 5 % and the 1/e lag within 5 % of the spec, with bounds from the sample size.

    For R(t) = σ²(1+β|t|)e^{−β|t|}: var(σ̂²)/σ⁴ ≈ (2/T)∫ρ² dt = 5/(βT), so sd(σ̂)/σ ≈ ½√(5/(βT)).
    The lag: Bartlett's variance of the sample autocorrelation at τ, divided by |ρ'(τ)|
    (ρ'(τ) = −β²τe^{−βτ}). The test asserts the error is within 4 sd and that 4 sd is within 5 %.
    """
    spec = dp.FlexureSpec()
    dt, T = 0.1, 1.0e5
    n = int(T / dt)
    th, thd = dp.simulate_flexure(spec, dt, n, np.random.default_rng(20240418))
    assert th.shape == (n + 1, 3) and thd.shape == (n + 1, 3)
    beta, sig, tau = spec.beta, spec.sigma, spec.tau
    # σ
    sd_sig = 0.5 * np.sqrt(5.0 / (beta * T))
    assert np.all(4 * sd_sig < 0.05)
    rel = th.std(axis=0) / sig - 1.0
    assert np.all(np.abs(rel) < 4 * sd_sig), (rel, sd_sig)
    # rate σ = βσ
    assert np.all(np.abs(thd.std(axis=0) / (beta * sig) - 1.0) < 0.05)
    # 1/e lag
    acf = _acf(th, int(3 * tau.max() / dt))
    u = np.arange(-int(60 / dt), int(60 / dt) + 1) * dt
    for a in range(3):
        k = int(np.argmax(acf[:, a] < math.exp(-1.0)))
        y0, y1 = acf[k - 1, a], acf[k, a]
        lag = dt * (k - 1 + (y0 - math.exp(-1.0)) / (y0 - y1))

        def rho(t, b=beta[a]):
            t = np.abs(t)
            return (1.0 + b * t) * np.exp(-b * t)

        r_tau = rho(tau[a])
        bart = (
            np.sum(
                rho(u) ** 2
                + rho(u + tau[a]) * rho(u - tau[a])
                - 4 * r_tau * rho(u) * rho(u + tau[a])
                + 2 * r_tau**2 * rho(u) ** 2
            )
            * dt
            / T
        )
        slope = beta[a] ** 2 * tau[a] * math.exp(-beta[a] * tau[a])
        sd_lag = math.sqrt(bart) / slope / tau[a]
        assert 4 * sd_lag < 0.05
        assert abs(lag / tau[a] - 1.0) < 4 * sd_lag, (a, lag, tau[a], sd_lag)
        assert abs(r_tau - math.exp(-1.0)) < 1e-3  # β = 2.146/τ puts 1/e at τ


def test_flexure_autocorrelation_theory():
    spec = dp.FlexureSpec()
    r = dp.flexure_autocorrelation(spec, [0.0, *spec.tau_s])
    np.testing.assert_allclose(r[0], spec.sigma**2)
    np.testing.assert_allclose(np.diag(r[1:]) / spec.sigma**2, math.exp(-1.0), rtol=2e-3)


# -------------------------------------------------------------------------------------- lever arm
def test_lever_arm_acceleration_formula():
    rng = np.random.default_rng(3)
    for _ in range(20):
        w, wd, r = rng.normal(size=(3, 3))
        exp = np.cross(wd, r) + np.cross(w, np.cross(w, r))
        np.testing.assert_allclose(dp.lever_arm_acceleration(w, wd, r), exp, rtol=1e-12, atol=1e-14)


def test_lever_arm_increment_known_rotation():
    """Mean of ω̇×r + ω×(ω×r) over each interval for ω(t) = [a sin wt, b + c t, d cos wt], from exact
    angle increments, against Gauss-Legendre quadrature of the analytic expression."""
    a, b, c, d, w = 0.3, 0.2, 0.01, 0.25, 1.3
    r = np.array([5.0, 0.1, 0.1])
    dt, n = 0.01, 2000
    t = np.arange(n + 1) * dt

    def omega(s):
        return np.stack([a * np.sin(w * s), b + c * s, d * np.cos(w * s)], axis=-1)

    def omega_dot(s):
        return np.stack([a * w * np.cos(w * s), np.full_like(s, c), -d * w * np.sin(w * s)], axis=-1)

    def angle(s):  # ∫ω dt from 0
        return np.stack(
            [a / w * (1 - np.cos(w * s)), b * s + 0.5 * c * s * s, d / w * np.sin(w * s)], axis=-1
        )

    dth = np.diff(angle(t), axis=0)
    got = dp.lever_arm_increment(dth, dt, r) / dt
    x, wts = np.polynomial.legendre.leggauss(6)
    s = 0.5 * (t[:-1, None] + t[1:, None]) + 0.5 * dt * x[None, :]
    wv, wdv = omega(s), omega_dot(s)
    acc = np.cross(wdv, r) + np.cross(wv, np.cross(wv, np.broadcast_to(r, wv.shape)))
    exp = 0.5 * np.sum(acc * wts[None, :, None], axis=1)
    scale = np.abs(exp).max()
    # fourth-order point rates for ω̇×r inside, third order at the ends; ω̄×(ω̄×r) is off by
    # ≈ Δt²/12·ω̇×(ω̇×r) (O(Δt²) in the mean: 6e-6 m/s² here, ~1e-10 m/s² for an aircraft)
    assert np.abs(got[2:-2] - exp[2:-2]).max() < 1e-5 * scale
    assert np.abs(got - exp).max() < 1e-4 * scale


# --------------------------------------------------------------------------------------- sub-IMU
def test_sub_imu_strapdown_reproduces_sub_truth(turning):
    """Error-free sub-IMU increments (flexure, mounting, lever arm, gravity difference included) drive the
    strapdown along the sub's own truth: the generation is consistent to the strapdown's accuracy."""
    cfg = dp.DistributedPosConfig()
    run = dp.simulate_distributed_pos(turning, cfg, seed=11)
    s, imu = run.sub.truth, run.sub.imu_true
    st0 = make_state(s.lat[0], s.lon[0], s.height[0], s.vel[0], quat_from_euler(*s.rph[0]))
    out = mechanize(imu.time, imu.dtheta, imu.dv, st0, imu.t0, s.height[1:], s.vel[1:, 2])
    att = attitude_error_batch(np.ascontiguousarray(out[:, 6:10]), euler_to_quat_batch(s.rph[1:]))
    assert np.abs(att).max() < 1e-7
    assert np.abs(out[:, 3:5] - s.vel[1:, :2]).max() < 1e-4
    ps = np.column_stack(lla_to_ecef(out[:, 0], out[:, 1], out[:, 2]))
    pt = np.column_stack(lla_to_ecef(s.lat[1:], s.lon[1:], s.height[1:]))
    assert np.linalg.norm(ps - pt, axis=1).max() < 0.01
    # the same increments without the lever-arm terms would not: the centripetal term in the turn
    assert np.abs(dp.lever_arm_increment(run.master_imu.dtheta, 0.01, cfg.lever_arm)).max() / 0.01 > 1e-3


def test_sub_truth_geometry(turning):
    cfg = dp.DistributedPosConfig()
    run = dp.simulate_distributed_pos(turning, cfg, seed=5)
    m, s = run.master_truth, run.sub.truth
    pm = np.column_stack(lla_to_ecef(m.lat, m.lon, m.height))
    ps = np.column_stack(lla_to_ecef(s.lat, s.lon, s.height))
    np.testing.assert_allclose(np.linalg.norm(ps - pm, axis=1), np.linalg.norm(cfg.lever_arm), rtol=1e-9)
    # attitude: C_bm^nᵀ C_bs^n = exp(−[(ρ+θ)×]) up to the ENU-frame difference (|r|/R ≈ 8e-7 rad)
    for k in (0, 3000, 8000):
        cm = dcm_from_euler(*m.rph[k])
        cs = dcm_from_euler(*s.rph[k])
        rel = cm.T @ cs
        alpha = run.sub.rho + run.sub.theta[k]
        expect = expm(
            -np.array([[0, -alpha[2], alpha[1]], [alpha[2], 0, -alpha[0]], [-alpha[1], alpha[0], 0]])
        )
        assert np.abs(rel - expect).max() < 2e-6
    # velocity: in the turn the sub (5 m right of the master) is closer to the turn centre
    k = 5000
    assert np.linalg.norm(s.vel[k]) < np.linalg.norm(m.vel[k])
    assert abs(np.linalg.norm(s.vel[k]) - np.linalg.norm(m.vel[k])) == pytest.approx(
        5.0 * 0.9 * DEG, rel=0.05
    )


def test_runs_are_reproducible_and_streams_independent(turning):
    a = dp.simulate_distributed_pos(turning, seed=7)
    b = dp.simulate_distributed_pos(turning, seed=np.random.SeedSequence(7))
    np.testing.assert_array_equal(a.sub.imu.dtheta, b.sub.imu.dtheta)
    np.testing.assert_array_equal(a.master.rph, b.master.rph)
    # changing the master accuracy changes no other draw (common random numbers)
    cfg = dp.DistributedPosConfig(master=dp.MasterPosSpec.for_gnss_baseline(60))
    c = dp.simulate_distributed_pos(turning, cfg, seed=7)
    np.testing.assert_array_equal(a.sub.imu.dv, c.sub.imu.dv)
    np.testing.assert_array_equal(a.sub.theta, c.sub.theta)
    np.testing.assert_array_equal(a.master.rph, c.master.rph)


# ---------------------------------------------------------------------------------------- master
def test_master_output_noise_statistics():
    scn = parse_scenario({"initial": INI, "segments": [{"type": "straight", "duration_s": 3000.0}]}, "<s>")
    truth, imu, _ = generate_truth(scn)
    spec = dp.MasterPosSpec.for_gnss_baseline(40, pos_drift_fraction=0.0)  # white errors only
    assert (spec.sigma_horizontal_m, spec.sigma_vertical_m) == (0.5, 1.0)
    out = dp.simulate_master_pos(truth, imu, spec, np.random.default_rng(1))
    idx = out.index
    assert len(idx) == 3001 and np.all(out.time == truth.time[idx])
    d_att = out.rph - truth.rph[idx]
    d_att[:, 2] = (d_att[:, 2] + np.pi) % (2 * np.pi) - np.pi
    tol = 4.0 / math.sqrt(2 * len(idx))  # 4 sd of a sample std
    np.testing.assert_allclose(d_att.std(axis=0) / spec.att_sigma_rad, 1.0, atol=tol)
    np.testing.assert_allclose((out.vel - truth.vel[idx]).std(axis=0) / spec.sigma_vel_m_s, 1.0, atol=tol)
    from aidnav.nav.earth import lla_difference_enu

    de, dn, du = lla_difference_enu(
        out.lat, out.lon, out.height, truth.lat[idx], truth.lon[idx], truth.height[idx]
    )
    np.testing.assert_allclose(np.std([de, dn, du], axis=1) / spec.pos_sigma_m, 1.0, atol=tol)
    # Gauss-Markov option: lag-1 correlation e^{−T/τ}, same stationary σ
    gm = dp.simulate_master_pos(truth, imu, dp.MasterPosSpec(corr_time_s=20.0), np.random.default_rng(1))
    e = gm.vel[:, 0] - truth.vel[idx, 0]
    r1 = np.corrcoef(e[:-1], e[1:])[0, 1]
    assert abs(r1 - math.exp(-1.0 / 20.0)) < 0.03
    assert abs(e.std() / 0.03 - 1.0) < 0.25


def test_master_position_drift_is_consistent_with_its_velocity():
    """The smooth position drift d(t) of the master (GNSS-baseline-dependent part) has its σ and the
    master velocity error carries exactly its rate ḋ: with no white errors, the finite difference of
    the position error equals the velocity error."""
    scn = parse_scenario({"initial": INI, "segments": [{"type": "straight", "duration_s": 6000.0}]}, "<s>")
    truth, imu, _ = generate_truth(scn)
    tau = 20.0
    spec = dp.MasterPosSpec.for_gnss_baseline(60, sigma_vel_m_s=0.0, pos_drift_fraction=1.0,
                                              pos_drift_tau_s=tau)
    out = dp.simulate_master_pos(truth, imu, spec, np.random.default_rng(3))
    idx = out.index
    from aidnav.nav.earth import lla_difference_enu

    ep = np.array(lla_difference_enu(out.lat, out.lon, out.height, truth.lat[idx], truth.lon[idx],
                                     truth.height[idx])).T
    ev = out.vel - truth.vel[idx]
    beta = dp.BETA_FACTOR / tau
    # 6000 s = 300 τ: the sample σ of this smooth process is within ~±15 % (4 sd) of the true σ
    np.testing.assert_allclose(ep.std(axis=0) / spec.pos_sigma_m, 1.0, atol=0.2)
    np.testing.assert_allclose(ev.std(axis=0) / (beta * spec.pos_sigma_m), 1.0, atol=0.2)
    np.testing.assert_allclose(spec.vel_drift_sigma_m_s, beta * spec.pos_sigma_m)
    # each 1-s position-error step is the integral of the velocity error (trapezoid rule)
    dp_step = np.diff(ep, axis=0)
    trap = 0.5 * (ev[1:] + ev[:-1]) * np.diff(out.time)[:, None]
    ratio = np.std(dp_step - trap, axis=0) / np.std(dp_step, axis=0)
    # the trapezoid residual of a velocity driven by white acceleration of PSD q = 4β³σ² has variance
    # q·dt³/12 against the step variance ≈ β²σ²·dt²: ratio² = β·dt/3 (0.19 here; 6000 steps: ±2 %)
    np.testing.assert_allclose(ratio, math.sqrt(beta * 1.0 / 3.0), rtol=0.1)
    with pytest.raises(ValueError, match="pos_drift_fraction"):
        dp.MasterPosSpec(pos_drift_fraction=1.5)


def test_euler_error_map():
    rph = np.array([0.3, -0.2, 2.0])
    d = np.array([1e-6, -2e-6, 3e-6])
    from aidnav.nav.rotations import quat_from_euler as qe

    phi = attitude_error_batch(qe(*(rph + d))[None], qe(*rph)[None])[0]
    np.testing.assert_allclose(dp.euler_error_map(rph) @ d, phi, rtol=1e-5, atol=1e-12)
    with pytest.raises(ValueError, match="Table 7"):
        dp.MasterPosSpec.for_gnss_baseline(30)
