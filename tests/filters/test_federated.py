"""Federated SINS/GPS/SAPV filter (seed 000): SAPV measurement, fusion, equivalence, losses, consistency."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.experiments.reproduce import seed_000 as s0
from aidnav.filters.federated import FederatedConfig, fuse_information, run_federated, spd_inverse
from aidnav.filters.measurements import sapv_angles
from aidnav.nav.earth import radii
from aidnav.nav.geo_pointing import R_GEO_SEED000, geo_sat_ecef, pointing_az_el
from aidnav.nav.rotations import dcm_from_euler, dcm_from_rotvec, quat_from_dcm

D = np.pi / 180.0
ARCMIN = D / 60.0
LAT, LON, H = 39.0 * D, 116.0 * D, 0.0
SAT = geo_sat_ecef(138.0 * D, R_GEO_SEED000)


def _state(lat, lon, h, C):
    return np.array([lat, lon, h, 0.0, 0.0, 0.0, *quat_from_dcm(C)])


def _z(phi, dP, C_true, use_position=False):
    """SAPV z and H for a computed state (C_c = (I − [φ×]) C_true exactly, position + δP) against the true
    angles (noise-free antenna)."""
    az_t, el_t = pointing_az_el(LAT, LON, H, C_true, SAT)
    C_c = dcm_from_rotvec(-np.asarray(phi, float)) @ C_true
    st = _state(LAT + dP[0], LON + dP[1], H + dP[2], C_c)
    Hm, z = np.zeros((2, 15)), np.zeros(2)
    sapv_angles(st, C_c, SAT, az_t, el_t, use_position, Hm, z)
    return z, Hm


# ----------------------------------------------------------------------------- measurement model
@pytest.mark.parametrize("rph", [(0.0, 0.0, 100.0), (3.0, -2.0, 250.0), (-10.0, 5.0, 10.0)])
def test_sapv_H_against_the_full_nonlinear_chain(rph):
    """z = computed − measured ≈ H δx for attitude and position errors (residual second order)."""
    C = dcm_from_euler(*(np.array(rph) * D))
    rm, rn = radii(LAT)
    rng = np.random.default_rng(0)
    for scale in (1e-4, 1e-3):
        phi = rng.normal(0, scale, 3)
        dP = rng.normal(0, 1.0, 3) * np.array([1 / rm, 1 / (rn * np.cos(LAT)), 1.0]) * scale * 1e4  # 1-10 m
        z, Hm = _z(phi, dP, C, use_position=True)
        dx = np.zeros(15)
        dx[0:3], dx[6:9] = phi, dP
        lin = Hm @ dx
        # second-order residual: |z − H δx| ≲ |δx|² (rad); relative error ~ |φ|
        assert np.max(np.abs(z - lin)) < 5 * scale**2 + 1e-12
        assert np.max(np.abs(z - lin)) < 0.02 * np.max(np.abs(z))
    # the sign: a heading error ψ (φ_U = −ψ for a level body... here via φ) moves az by −(rotation about Up)
    z, Hm = _z([0.0, 0.0, 1e-3], np.zeros(3), dcm_from_euler(0, 0, 100 * D))
    # C_c = (I − [φ×]) C: rotating the body by −φ_U about Up turns its forward axis clockwise (heading + φ_U),
    # so the satellite's azimuth from the forward axis decreases: z_az = −φ_U (level body), z_el = 0
    assert z[0] == pytest.approx(-1e-3, rel=1e-3) and abs(z[1]) < 1e-9
    assert Hm[0, 2] == pytest.approx(-1.0, rel=1e-12) and Hm[1, 2] == pytest.approx(0.0, abs=1e-12)
    assert not np.any(Hm[:, 3:])  # position columns off by default (seed eq. 26)


def test_sapv_azimuth_wrap():
    """Satellite straight ahead (az ≈ 0 ≡ 2π): z stays small across the wrap, in (−π, π]."""
    az_true = pointing_az_el(LAT, LON, H, dcm_from_euler(0, 0, 0), SAT)[0]  # = LOS azimuth from North
    C = dcm_from_euler(0.0, 0.0, az_true + 0.01 * D)  # forward axis 0.01° clockwise past the LOS
    az, el = pointing_az_el(LAT, LON, H, C, SAT)
    assert np.degrees(az) == pytest.approx(360.0 - 0.01, abs=1e-6)
    Hm, z = np.zeros((2, 15)), np.zeros(2)
    for az_meas, expect in ((0.01 * D, -0.02 * D), (2 * np.pi - 0.03 * D, 0.02 * D)):
        sapv_angles(_state(LAT, LON, H, C), C, SAT, az_meas, el, False, Hm, z)
        assert z[0] == pytest.approx(expect, abs=1e-12) and abs(z[1]) < 1e-12


def test_position_columns_negligible_for_100_m():
    """§1.2 items 8-9 and §1.1 eq. 26: 100 m of position error moves the pointing by ≈ 0.002°, 1/25 of the
    0.05° noise."""
    C = dcm_from_euler(0, 0, 100 * D)
    rm, rn = radii(LAT)
    worst = 0.0
    for s in np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).T.reshape(-1, 3):
        dP = s * np.array([100 / rm, 100 / (rn * np.cos(LAT)), 100.0])
        z, Hm = _z(np.zeros(3), dP, C, use_position=True)
        np.testing.assert_allclose(Hm[:, 6:9] @ dP, z, rtol=1e-3, atol=1e-10)
        worst = max(worst, np.max(np.abs(z)))
    assert np.degrees(worst) < 0.0025


# ----------------------------------------------------------------------------- fusion algebra
def test_spd_inverse_and_information_fusion():
    rng = np.random.default_rng(1)
    scales = np.array([1e-3] * 3 + [0.1] * 3 + [1e-6, 1e-6, 10.0] + [5e-7] * 3 + [5e-3] * 3)
    A = rng.normal(size=(15, 15))
    P = (A @ A.T + 15 * np.eye(15)) * np.outer(scales, scales)
    Pi = spd_inverse(P)
    np.testing.assert_allclose((Pi @ P), np.eye(15), atol=1e-9)
    B = rng.normal(size=(15, 15))
    P2 = (B @ B.T + 15 * np.eye(15)) * np.outer(scales, scales)
    x1, x2 = rng.normal(size=15) * scales, rng.normal(size=15) * scales
    Pg, xg = fuse_information(np.stack([P, P2, P]), np.stack([x1, x2, x1]), np.array([True, True, False]))
    # reference: the fused estimate as a Kalman update of (x1, P) with "measurement" x2, covariance P2
    K = P @ np.linalg.inv(P + P2)
    S = np.outer(scales, scales)
    np.testing.assert_allclose(Pg / S, ((np.eye(15) - K) @ P) / S, atol=1e-9)
    np.testing.assert_allclose(xg / scales, (x1 + K @ (x2 - x1)) / scales, atol=1e-9)


def test_config_validation():
    with pytest.raises(ValueError, match="sum to 1"):
        FederatedConfig(beta_gps=0.5, beta_sapv=0.6)
    with pytest.raises(ValueError, match="mode"):
        FederatedConfig(mode="fusion")
    with pytest.raises(ValueError, match="> 0"):
        FederatedConfig(beta_gps=1.0, beta_sapv=0.0)
    assert FederatedConfig(mode="centralized", beta_gps=2.0).label == "centralized GPS+SAPV"
    assert FederatedConfig(beta_gps=0.3, beta_sapv=0.3, beta_master=0.4).label == "reset b=0.3/0.3/m0.4"


# ----------------------------------------------------------------------------- filter behaviour
@pytest.fixture(scope="module")
def case():
    """The seed's static scenario (Table 1), 300 s, one realisation."""
    sim, sv, cfg = s0.simulate_case(np.random.SeedSequence(11), duration_s=300.0)
    return sim, sv, cfg


def _run(case, fed, sapv=None, keep_cov=False):
    sim, sv, cfg = case
    return run_federated(sim.imu, sim.gnss, sv if sapv is None else sapv, cfg, fed, keep_cov=keep_cov)


def _head(res, truth):
    return s0.euler_errors(res, truth)[:, 2] / ARCMIN


def test_sapv_makes_heading_observable(case):
    """The seed's main claim: on a static vehicle SINS/GPS hardly sees heading; with SAPV it is < 10′ at
    once."""
    truth = case[0].truth
    gps = _run(case, FederatedConfig(mode="centralized", use_sapv=False))
    fed = _run(case, FederatedConfig())
    t = gps.time
    late = t > 100.0
    h_gps, h_fed = _head(gps, truth), _head(fed, truth)
    rms_gps, rms_fed = np.sqrt(np.mean(h_gps[late] ** 2)), np.sqrt(np.mean(h_fed[late] ** 2))
    assert rms_gps > 10 * rms_fed
    assert np.max(np.abs(h_fed[t >= 30.0])) < 10.0
    # the filter knows it: heading σ with SAPV a few arc-minutes, without it tens of arc-minutes
    s_fed = np.sqrt(fed.pdiag[-1, 2]) / ARCMIN
    s_gps = np.sqrt(gps.pdiag[-1, 2]) / ARCMIN
    assert s_fed < 3.0 and s_gps > 5 * s_fed
    # every valid SAPV epoch was used, no GPS fix missed
    assert (fed.sapv_status[case[1].valid] == 1).all() and (fed.gps_pos_status == 1).all()
    assert (gps.sapv_status == -1).all()


def test_fusion_reset_equals_centralized(case):
    """Fusion-reset with any β (sum 1, master or not) is algebraically the centralized filter: the β-scaled
    prior informations sum to P⁻¹ and the measurement informations add. Only rounding differs (Jacobi-scaled
    inversions at every epoch, ~1e-12 relative): tolerance 1e-8 of the estimate's own σ."""
    c = _run(case, FederatedConfig(mode="centralized"), keep_cov=True)
    sig = np.sqrt(c.pdiag)
    for fed in (FederatedConfig(), FederatedConfig(beta_gps=0.8, beta_sapv=0.2),
                FederatedConfig(beta_gps=0.25, beta_sapv=0.25, beta_master=0.5)):
        r = _run(case, fed, keep_cov=True)
        np.testing.assert_array_equal(r.time, c.time)
        att = np.abs(s0.euler_errors(r, case[0].truth) - s0.euler_errors(c, case[0].truth))
        assert np.max(att / sig[:, [1, 0, 2]]) < 1e-8, fed.label
        np.testing.assert_allclose(r.state[:, 3:6], c.state[:, 3:6], rtol=0, atol=1e-8 * sig[:, 3:6].min())
        np.testing.assert_allclose(r.bias / np.sqrt(c.pdiag[:, 9:15]), c.bias / np.sqrt(c.pdiag[:, 9:15]),
                                   rtol=0, atol=1e-8)
        norm = np.sqrt(c.pdiag[:, :, None] * c.pdiag[:, None, :])
        np.testing.assert_allclose(r.cov / norm, c.cov / norm, rtol=0, atol=1e-8)


def test_no_reset_is_conservative(case):
    """No-reset: the fused P bounds the centralized one (Carlson), the estimate stays close to it."""
    c = _run(case, FederatedConfig(mode="centralized"))
    for fed in (FederatedConfig(mode="no_reset"),
                FederatedConfig(mode="no_reset", beta_gps=0.8, beta_sapv=0.2)):
        r = _run(case, fed)
        assert np.min(r.pdiag / c.pdiag) > 1 - 1e-9
        assert np.max(np.abs(_head(r, case[0].truth) - _head(c, case[0].truth))) < 0.1 * np.sqrt(
            c.pdiag[-1, 2]) / ARCMIN


def test_sapv_loss_keeps_the_solution_continuous_and_bounded(case):
    sim, sv, cfg = case
    lost = sv.with_loss(100.0, 200.0)
    ref = _run(case, FederatedConfig())
    for fed in (FederatedConfig(), FederatedConfig(mode="no_reset")):
        r = _run(case, fed, sapv=lost)
        h = _head(r, sim.truth)
        sig = np.sqrt(r.pdiag[:, 2]) / ARCMIN
        t = r.time
        win = (t > 95.0) & (t < 205.0)
        assert (r.sapv_status[(sv.time >= 100) & (sv.time < 200)] == -1).all()
        # bounded: inside ±3σ and well below the 10′ bound throughout; σ stays of the same size during the
        # loss (the gyro bias is known; the SINS/GPS gyrocompassing still informs heading)
        assert np.all(np.abs(h[t > 30.0]) < 3 * sig[t > 30.0] + 0.5) and np.max(np.abs(h[t > 30])) < 10.0
        i0, i1 = np.searchsorted(t, 100.0), np.searchsorted(t, 200.0)
        assert 0.5 * sig[i0 - 1] < sig[i1 - 1] < 3 * sig[i0 - 1]
        # continuous: no epoch-to-epoch step larger than 3σ at the loss or the return of the SAPV
        assert np.max(np.abs(np.diff(h[win]))) < 3 * sig[i1 - 1]
        # much better than SINS/GPS alone over the loss (the heading information is kept)
        assert np.max(np.abs(h[win])) < 0.2 * np.max(np.abs(_head(_run(case, FederatedConfig(
            mode="centralized", use_sapv=False)), sim.truth)[win]))
        # after the return the solution rejoins the no-loss one
        assert abs(h[-1] - _head(ref, sim.truth)[-1]) < sig[-1]


def test_gps_outage_continues_on_sapv():
    sim, sv, cfg = s0.simulate_case(np.random.SeedSequence(11), duration_s=300.0,
                                    gps_outages=((150.0, 210.0),))
    r = run_federated(sim.imu, sim.gnss, sv, cfg, FederatedConfig())
    g = run_federated(sim.imu, sim.gnss, sv, cfg, FederatedConfig(mode="centralized", use_sapv=False))
    t = r.time
    out = (t > 150.0) & (t <= 210.0)
    assert not np.any((sim.gnss.time > 150.5) & (sim.gnss.time < 209.5))
    h = _head(r, sim.truth)
    assert np.max(np.abs(h[t > 30])) < 10.0
    vh = np.hypot(*s0.velocity_errors(r, sim.truth)[:, :2].T)
    vg = np.hypot(*s0.velocity_errors(g, sim.truth)[:, :2].T)
    # free-inertial velocity over 60 s stays bounded (tilt known from SAPV + GPS before the outage)
    assert np.max(vh[out]) < 1.0 and np.max(vh[out]) <= np.max(vg[out]) + 0.05
    # GPS back: the velocity error returns to the GPS-aided level
    assert np.max(vh[t > 240]) < 0.5


@pytest.mark.slow
def test_centralized_nees_and_nis_in_chi2_band():
    """Monte Carlo (12 runs × 200 s, fixed seeds): initial errors drawn from P_0, IMU biases from their σ; the
    run-averaged NEES (15 states) must lie in its χ²(15·R)/R 95 % band at ≥ 85 % of the epochs (95 % expected;
    the epochs are correlated, so the count is not binomial and the margin is wide), and its mean over
    epochs inside the same band (an average of correlated values has at most the variance of one). The pooled
    SAPV NIS mean must be inside the χ²(2) 99 % band for the pooled count (innovations are white)."""
    from aidnav.analysis.consistency import chi2_band, nees

    R = 12
    ne, nis = [], []
    for ss in np.random.SeedSequence(2024).spawn(R):
        sim, sv, cfg = s0.simulate_case(ss, duration_s=200.0, draw_attitude=True)
        c = run_federated(sim.imu, sim.gnss, sv, cfg, FederatedConfig(mode="centralized"), keep_cov=True)
        ne.append(nees(s0.error_state(c, sim.truth, sim.imu_errors), c.cov))
        nis.append(c.sapv_nis[c.sapv_status == 1])
    m = np.mean(ne, axis=0)
    lo, hi = chi2_band(15, R, 0.95)
    assert np.mean((m >= lo) & (m <= hi)) >= 0.85
    assert lo <= np.mean(m) <= hi
    nis = np.concatenate(nis)
    nlo, nhi = chi2_band(2, len(nis), 0.99)
    assert nlo <= np.mean(nis) <= nhi


def test_driving_with_turns_and_off_grid_sapv_epochs():
    """A slow drive with a 90° turn (3°/s) and SAPV epochs 5 ms after the IMU samples (carried to the
    sample by the body rotation): consistent SAPV innovations and heading at the arc-minute level."""
    from aidnav.sim.run import simulate
    from aidnav.sim.sapv import simulate_sapv
    from aidnav.sim.scenario import Scenario

    scn = Scenario.model_validate(dict(
        name="drive", seed=5, initial=dict(lat_deg=39.0, lon_deg=116.0, height_m=0.0, speed_m_s=10.0,
                                           heading_deg=100.0),
        imu_rate_hz=100.0, transition_s=2.0,
        segments=[dict(type="straight", duration_s=60.0), dict(type="turn", angle_deg=90.0, rate_deg_s=3.0),
                  dict(type="s_turns", duration_s=60.0, amplitude_deg=10.0, n_cycles=2),
                  dict(type="straight", duration_s=30.0)],
        sensors=dict(imu=dict(grade="seed000"), gnss=dict(rate_hz=1.0, sigma_pos_m=[10.0] * 3,
                                                          sigma_vel_m_s=[0.5] * 3))))
    sim = simulate(scn, seed=5)
    times = np.arange(1.0, sim.truth.time[-1] - 1.0) + 0.005
    sv = simulate_sapv(sim.truth, s0.sapv_spec(), np.random.default_rng(6), times=times)
    cfg = s0.filter_config(sim.truth, np.random.default_rng(7))
    r = run_federated(sim.imu, sim.gnss, sv, cfg, FederatedConfig())
    c = run_federated(sim.imu, sim.gnss, sv, cfg, FederatedConfig(mode="centralized"))
    nis = c.sapv_nis[c.sapv_status == 1]
    assert len(nis) == len(times)
    from aidnav.analysis.consistency import chi2_band

    lo, hi = chi2_band(2, len(nis), 0.999)
    assert lo <= np.mean(nis) <= hi
    h = _head(r, sim.truth)
    assert np.max(np.abs(h[r.time > 30.0])) < 5.0
