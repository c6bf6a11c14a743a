"""Range-error states of the tight filter (issue 26): the single-frequency error budget and a simulation in
which every pseudorange carries a Gauss-Markov range error of exactly that budget — the filter's NEES
must stay in its χ² band (the filter model = the simulated model)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.stats import chi2

from aidnav.data import ImuData
from aidnav.filters.tight import TightConfig, run_tight, tight_nav_covariance_m
from aidnav.filters.tuning import loose_config_from_specs
from aidnav.nav.earth import dcm_ecef_to_enu, lla_to_ecef, radii
from aidnav.nav.gnss_sat import E_URA, range_error_sigma
from aidnav.nav.rotations import attitude_error_batch, euler_to_quat_batch
from aidnav.sim.gnss_constellation import nominal_constellation
from aidnav.sim.gnss_raw import RawGnssSpec, simulate_raw_gnss
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth

SOW = 400000.0
TAU = 1800.0
SCN = parse_scenario({
    "initial": {"lat_deg": 34.2, "lon_deg": 108.9, "height_m": 1000, "speed_m_s": 20, "heading_deg": 30},
    "imu_rate_hz": 50, "transition_s": 2.0,
    "segments": [{"type": "straight", "duration_s": 40}, {"type": "turn", "angle_deg": 90, "rate_deg_s": 3},
                 {"type": "straight", "duration_s": 110}]})
TRUTH, IMU_TRUE, _ = generate_truth(SCN)


def test_range_error_budget_known_values():
    """RTKLIB pntpos.c budget: σ² = URA² + σ_ion² + (ERR_SAAS/(sin E + 0.1))² + ERR_CBIAS²."""
    el = np.radians(30.0)
    trop = 0.3 / (0.5 + 0.1)
    assert range_error_sigma(el, 2.0, 1, 6.0, True) == pytest.approx(np.sqrt(4 + 9 + trop**2 + 0.09))
    assert range_error_sigma(el, 2.0, 0, 6.0, True) == pytest.approx(np.sqrt(4 + 25 + trop**2 + 0.09))
    assert range_error_sigma(el, 2.0, 2, 6.0, False) == pytest.approx(np.sqrt(4 + (3.0 / 0.6) ** 2 + 0.09))
    assert range_error_sigma(el, np.nan, 2, 0.0, True) > 6000.0  # unknown accuracy (RTKLIB: 6144 m)


def _range_errors(sim, eph, rng):
    """σ_j(E)·u_j per epoch and satellite, u_j unit-variance first-order Gauss-Markov (exact at the epoch
    spacing), σ_j the filter's budget at the true elevation and the simulated Klobuchar delay."""
    el, ion = sim.truth["elevation"], sim.truth["iono"]
    M, S = el.shape
    a = np.exp(-np.diff(sim.rover.time, prepend=sim.rover.time[0]) / TAU)
    u = np.zeros((M, S))
    u[0] = rng.standard_normal(S)
    for k in range(1, M):
        u[k] = a[k] * u[k - 1] + np.sqrt(1 - a[k] ** 2) * rng.standard_normal(S)
    sig = np.full((M, S), np.nan)
    for k in range(M):
        for j in range(S):
            if np.isfinite(el[k, j]) and np.isfinite(ion[k, j]):
                sig[k, j] = range_error_sigma(el[k, j], eph.table[j, E_URA], 1, ion[k, j], True)
    return sig * u


@pytest.mark.slow
def test_nees_with_simulated_budget_range_errors_within_chi_square_bounds():
    """12 seeded runs; the simulated pseudoranges carry white noise (0.5 m) plus a Gauss-Markov range error
    per satellite of the filter's budget σ (URA 2 m, 50 % of the Klobuchar delay, Saastamoinen residual,
    code bias) and τ = 1800 s; the filter runs with its range-error states (defaults). Mean NEES (9 dof)
    at a few instants within the two-sided 99 % χ²(9·runs)/runs band."""
    inf3 = np.full(3, np.inf)
    spec = ImuSpec(gyro_bias=np.radians(3.0 / 3600), accel_bias=2.94e-3, gyro_arw=np.radians(0.1 / 60),
                   accel_vrw=0.05 / 60, gyro_bias_tau=inf3, accel_bias_tau=inf3)
    gspec = dataclasses.replace(RawGnssSpec(rate_hz=1.0).perfect(), code_sigma_m=0.5, rate_sigma_m_s=0.05)
    eph = nominal_constellation(2381, SOW, 24)
    eph.iono_alpha, eph.iono_beta = gspec.iono_alpha, gspec.iono_beta
    eph.table[:, E_URA] = 2.0  # IS-GPS-200 URA index 0 (the walk's broadcast value)
    cfg = TightConfig(states=17, imu=loose_config_from_specs(spec).imu, constraints={"zupt": False},
                      init={"attitude_sigma_deg": (0.05, 0.05, 0.3), "position_sigma_m": (2, 2, 2),
                            "velocity_sigma_m_s": (0.1, 0.1, 0.1)},
                      gnss={"code_sigma_m": 0.5, "rate_sigma_m_s": 0.05, "mask_deg": 5.0,
                            "gate_probability": 1.0, "clock_bias_sigma_m": 5.0, "clock_drift_sigma_m_s": 0.2,
                            "range_error_tau_s": TAU})
    runs, instants = 12, (20.0, 60.0, 110.0, 170.0)
    nees = np.zeros((runs, len(instants)))
    rm, rn = radii(TRUTH.lat[0])
    for r in range(runs):
        rng = np.random.default_rng(700 + r)
        imu_c, _ = corrupt_imu(IMU_TRUE, spec, np.random.default_rng(800 + r))
        imu = ImuData(imu_c.time + SOW, imu_c.dtheta, imu_c.dv, t0=imu_c.t0 + SOW)
        sim = simulate_raw_gnss(TRUTH, eph, gspec, np.random.default_rng(900 + r), SOW)
        sim.rover.code1 = sim.rover.code1 + _range_errors(sim, eph, rng)
        dp, h = rng.normal(0, 2.0, 3), TRUTH.height[0]
        init = (SOW + TRUTH.time[0], TRUTH.lat[0] + dp[1] / (rm + h),
                TRUTH.lon[0] + dp[0] / ((rn + h) * np.cos(TRUTH.lat[0])), h + dp[2],
                TRUTH.vel[0] + rng.normal(0, 0.1, 3),
                TRUTH.rph[0] + np.radians([0.05, 0.05, 0.3]) * rng.standard_normal(3))
        res = run_tight(imu, sim.rover, eph, cfg, init_state=init)
        ep = res.epochs
        for i, k in enumerate(np.argmin(np.abs(ep["time"][:, None] - SOW - np.array(instants)), axis=0)):
            st = ep["state"][k]
            # truth at the IMU sample closing the epoch (where the record holds the state)
            t_imu = res.time[np.searchsorted(res.time, ep["time"][k] - 1e-9)] - SOW
            j = min(int(np.searchsorted(TRUTH.time, t_imu - 1e-9)), len(TRUTH) - 1)
            p_true = np.array(lla_to_ecef(TRUTH.lat[j], TRUTH.lon[j], TRUTH.height[j]))
            d_p = dcm_ecef_to_enu(st[0], st[1]) @ (np.array(lla_to_ecef(*st[:3])) - p_true)
            q_true = euler_to_quat_batch(TRUTH.rph[j][None].copy())
            err = np.r_[attitude_error_batch(st[None, 6:10].copy(), q_true)[0], st[3:6] - TRUTH.vel[j], d_p]
            cov = tight_nav_covariance_m(ep["P_nav"][k], st[0], st[2])
            nees[r, i] = err @ np.linalg.solve(cov, err)
    mean, band = nees.mean(0), chi2.ppf([0.005, 0.995], 9 * runs) / runs
    print("NEES", mean, band)
    assert np.all((mean > band[0]) & (mean < band[1])), (mean, band)
