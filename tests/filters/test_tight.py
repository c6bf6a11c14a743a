"""Tightly coupled EKF: fewer than four satellites, consistency (NEES), and the walk data set."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from aidnav.data import ImuData
from aidnav.estimators.dgps import satellites_from_pseudoranges, spp
from aidnav.filters.tight import TightConfig, run_tight, tight_nav_covariance_m
from aidnav.filters.tuning import loose_config_from_specs
from aidnav.nav.earth import dcm_ecef_to_enu, lla_to_ecef, radii
from aidnav.nav.rotations import attitude_error_batch, euler_to_quat_batch
from aidnav.sim.gnss_constellation import nominal_constellation
from aidnav.sim.gnss_raw import RawGnssSpec, limit_satellites, simulate_raw_gnss
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth

SOW = 400000.0
EPH = nominal_constellation(2381, SOW, 24)
SCN = parse_scenario(
    {
        "initial": {"lat_deg": 34.2, "lon_deg": 108.9, "height_m": 1000, "speed_m_s": 60, "heading_deg": 30},
        "imu_rate_hz": 50,
        "transition_s": 2.0,
        "segments": [
            {"type": "straight", "duration_s": 60},
            {"type": "turn", "angle_deg": 90, "rate_deg_s": 3},
            {"type": "straight", "duration_s": 150},
        ],
    }
)
TRUTH, IMU_TRUE, _ = generate_truth(SCN)


def _imu(spec, seed):
    imu, _ = corrupt_imu(IMU_TRUE, spec, np.random.default_rng(seed))
    return ImuData(imu.time + SOW, imu.dtheta, imu.dv, t0=imu.t0 + SOW)


def _init(rng, sig_p=2.0, sig_v=0.1, sig_a=(0.05, 0.05, 0.3)):
    dp = rng.normal(0, sig_p, 3)
    rm, rn = radii(TRUTH.lat[0])
    h = TRUTH.height[0]
    return (
        SOW + TRUTH.time[0],
        TRUTH.lat[0] + dp[1] / (rm + h),
        TRUTH.lon[0] + dp[0] / ((rn + h) * np.cos(TRUTH.lat[0])),
        h + dp[2],
        TRUTH.vel[0] + rng.normal(0, sig_v, 3),
        TRUTH.rph[0] + np.radians(np.array(sig_a)) * rng.standard_normal(3),
    )


def _pos_err(res):
    tt = res.time - SOW
    j = np.clip(np.searchsorted(TRUTH.time, tt - 1e-9), 0, len(TRUTH.time) - 1)
    pe = np.array(lla_to_ecef(res.state[:, 0], res.state[:, 1], res.state[:, 2])).T
    pt = np.array(lla_to_ecef(TRUTH.lat[j], TRUTH.lon[j], TRUTH.height[j])).T
    return np.linalg.norm(pe - pt, axis=1), tt


def test_three_satellites_keep_the_error_bounded_where_loose_coupling_has_no_fix():
    spec = ImuSpec.grade("mems")
    imu = _imu(spec, 2)
    sim = simulate_raw_gnss(TRUTH, EPH, RawGnssSpec(rate_hz=1.0), np.random.default_rng(1), SOW)
    cfg = TightConfig(
        states=17,
        imu=loose_config_from_specs(spec, sensor_model=False).imu,  # 15 INS states: the model before issue 35
        constraints={"zupt": False},
        init={
            "attitude_sigma_deg": (0.2, 0.2, 1.0),
            "position_sigma_m": (3, 3, 3),
            "velocity_sigma_m_s": (0.2, 0.2, 0.2),
        },
        gnss={"code_sigma_m": 1.0, "rate_sigma_m_s": 0.06, "mask_deg": 5.0, "range_errors": False},
    )
    init = _init(np.random.default_rng(5))
    t0 = SOW + TRUTH.time[0]
    three = limit_satellites(sim.rover, sim.truth["elevation"], [(60.0, 1e4, 3)], t0)
    none = limit_satellites(sim.rover, sim.truth["elevation"], [(60.0, 1e4, 0)], t0)
    # SPP (and so a loosely coupled filter) has no fix with three satellites
    k = int(np.searchsorted(three.time, t0 + 100.0))
    pos, _, clk, _ = satellites_from_pseudoranges(
        EPH.table, three.prn, three.time[k], three.code1[k], max_age_s=1e7
    )
    assert np.isfinite(three.code1[k]).sum() == 3
    assert spp(pos, clk, three.code1[k], t_sow=three.time[k]).status == "too few satellites"
    r3 = run_tight(imu, three, EPH, cfg, init_state=init)
    r0 = run_tight(imu, none, EPH, cfg, init_state=init)  # what a filter without fixes does: free inertial
    e3, tt = _pos_err(r3)
    e0, _ = _pos_err(r0)
    late = tt > 200.0
    assert r3.counts["pr_used"] > 0 and r3.epochs["n_pr"][-5:].max() <= 3
    assert np.max(e3[late]) < 0.25 * np.max(e0[late])
    assert np.max(e3) < 60.0


def test_nees_of_the_tight_filter_within_chi_square_bounds():
    """Filter model = truth model (bias + white noise IMU, white GNSS noise, same clock): the mean NEES of
    position-velocity-attitude (9 dof) at a few instants over Monte Carlo runs is within χ² bounds."""
    spec = ImuSpec(
        gyro_bias=np.radians(3.0) / 3600,
        accel_bias=300e-6 * 9.80665,
        gyro_arw=np.radians(0.1) / 60,
        accel_vrw=0.05 / 60,
        gyro_bias_tau=np.full(3, np.inf),
        accel_bias_tau=np.full(3, np.inf),
    )
    gspec = RawGnssSpec(
        rate_hz=1.0,
        multipath_sigma_m=0.0,
        eph_sigma_rac_m=(0, 0, 0),
        sat_clock_sigma_m=0.0,
        sat_clock_drift_sigma_m_s=0.0,
        iono_scale_sigma=0.0,
        iono_gradient_mm_km=0.0,
        tropo_zenith_sigma_m=0.0,
        code_sigma_m=0.5,
        rate_sigma_m_s=0.05,
    )
    EPH.iono_alpha = gspec.iono_alpha
    EPH.iono_beta = gspec.iono_beta
    lc = loose_config_from_specs(spec)
    cfg = TightConfig(
        states=17,
        imu=lc.imu,
        constraints={"zupt": False},
        init={
            "attitude_sigma_deg": (0.05, 0.05, 0.3),
            "position_sigma_m": (2, 2, 2),
            "velocity_sigma_m_s": (0.1, 0.1, 0.1),
        },
        gnss={
            "code_sigma_m": 0.5,
            "rate_sigma_m_s": 0.05,
            "mask_deg": 5.0,
            "gate_probability": 1.0,
            "clock_bias_sigma_m": 5.0,
            "clock_drift_sigma_m_s": 0.2,
            "range_errors": False,
        },
    )
    runs = 12
    instants = (30.0, 90.0, 150.0, 200.0, 260.0)
    nees = np.zeros((runs, len(instants)))
    for r in range(runs):
        rng = np.random.default_rng(100 + r)
        imu = _imu(spec, 200 + r)
        sim = simulate_raw_gnss(TRUTH, EPH, gspec, np.random.default_rng(300 + r), SOW)
        init = _init(rng, 2.0, 0.1, (0.05, 0.05, 0.3))
        res = run_tight(imu, sim.rover, EPH, cfg, init_state=init)
        ep = res.epochs
        for i, t in enumerate(instants):
            k = int(np.argmin(np.abs(ep["time"] - SOW - t)))
            st = ep["state"][k]
            # the record holds the state after the update at the IMU sample closing the epoch
            k_imu = int(np.searchsorted(res.time, ep["time"][k] - 1e-9))
            j = int(
                np.clip(np.searchsorted(TRUTH.time, res.time[k_imu] - SOW - 1e-9), 0, len(TRUTH.time) - 1)
            )
            pt = np.array(lla_to_ecef(TRUTH.lat[j], TRUTH.lon[j], TRUTH.height[j]))
            pe = np.array(lla_to_ecef(st[0], st[1], st[2]))
            dp = dcm_ecef_to_enu(st[0], st[1]) @ (pe - pt)
            dv = st[3:6] - TRUTH.vel[j]
            # misalignment φ with C_est = (I − [φ×]) C_true, the filter's attitude error
            phi = attitude_error_batch(st[None, 6:10].copy(), euler_to_quat_batch(TRUTH.rph[j][None].copy()))[
                0
            ]
            d = np.r_[phi, dv, dp]
            P = tight_nav_covariance_m(ep["P_nav"][k], st[0], st[2])
            nees[r, i] = d @ np.linalg.solve(P, d)
    m = nees.mean(0)
    lo, hi = chi2.ppf(0.005, 9 * runs) / runs, chi2.ppf(0.995, 9 * runs) / runs
    print("NEES", m, lo, hi)
    assert np.all(m > lo) and np.all(m < hi), (m, lo, hi)


def test_walk_data_tight_coupling(load_walk):
    """Walk data: 4 GPS satellites, code + Doppler only. The honest accuracy of such a solution is the SPP's
    (a few metres of bias from the ranging errors of four satellites; no redundancy to detect them)."""
    import yaml

    from aidnav.apps.tight import compare_with_reference, process_tight

    imu, obs, nav, ref = load_walk()
    root = __import__("pathlib").Path(__file__).resolve().parents[2]
    y = yaml.safe_load((root / "examples" / "rtklibexplorer_walk_0827.yaml").read_text())
    cfg = TightConfig(
        states=17,
        imu=y["imu"],
        init=y["init"],
        constraints=y["constraints"],
        filter=y["filter"],
        gnss={
            "code_sigma_m": 1.5,
            "rate_sigma_m_s": 0.15,
            "iono": "dual",
            "mask_deg": 5.0,
            "clock_hm2": 2e-18,
            "clock_drift_sigma_m_s": 5.0,
        },
    )
    res, sp = process_tight(imu, obs, nav, cfg)
    assert res.counts["clock_jumps"] == 0 and res.counts["pr_used"] > 1500
    c = compare_with_reference(res.time, res.state[:, 0], res.state[:, 1], res.state[:, 2], ref)
    assert c["n"] > 300
    assert c["horizontal_rms"] < 15.0 and c["vertical_rms"] < 15.0
    # the tight solution is smoother than the SPP: its scatter about its own mean is smaller
    ok = np.isfinite(sp["lat"])
    cs = compare_with_reference(sp["time"][ok], sp["lat"][ok], sp["lon"][ok], sp["h"][ok], ref)
    assert np.linalg.norm(c["std"][:2]) < 1.5 * np.linalg.norm(cs["std"][:2])
    j = np.clip(np.searchsorted(res.time, ref.time), 0, len(res.time) - 1)
    q = ref.quality == 1
    assert np.sqrt(np.mean((res.state[j[q], 3:5] - ref.vel[q, :2]) ** 2)) < 0.3
