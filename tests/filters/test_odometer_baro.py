"""Odometer (with scale-factor state) and barometer (with bias state) on the filter engine.

Simulated car (15 m/s, turns and S-turns, 280 s), MEMS IMU with constant biases (10 deg/h, 1 mg; ARW
0.3 deg/√h, VRW 0.1 m/s/√h), 1 Hz GNSS position + velocity withheld for 60 s (t ∈ [200, 260) s).
Per run (fixed seeds, ``SeedSequence(BASE).spawn(N_RUNS)``): IMU errors, GNSS noise, initial errors,
odometer noise (10 Hz, scale factor +1 %, σ 0.05 m/s) and barometer noise (5 Hz, bias +5 m, σ 0.3 m).

* Odometer (with the non-holonomic constraint, which gives the lateral and vertical velocity the
  odometer does not see): RMS over the runs of the horizontal error at the end of the outage ≤ 1/5 of
  the unaided (GNSS-only) one (one run's unaided error can be near zero by chance: the drift is
  random, so the comparison is of the spreads).
* Barometer: height error at the end of the outage ≤ 2 m in every run, and its RMS below half the
  unaided one.
* NEES of the full error state (15 INS states + the calibration state) at 4 epochs in the outage:
  the N-run average at each epoch within its two-sided χ²(N·n)/N band at 1 − 0.01/8 (Bonferroni over
  4 epochs × 2 filters: a consistent filter fails with probability ≤ 1 %).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from aidnav.filters import measurements as ms
from aidnav.filters.aids import aid
from aidnav.filters.layout import L_BARO, L_N, L_ODO
from aidnav.filters.loose import run_loose
from aidnav.filters.tuning import loose_config_from_specs, perturbed_initial_state
from aidnav.nav.earth import lla_difference_enu
from aidnav.sim.baro import simulate_baro
from aidnav.sim.gnss import GnssSpec, simulate_gnss
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.odometer import simulate_odometer
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth

BASE_SEED = 20261201
N_RUNS = 12
OUTAGE = (200.0, 260.0)
NEES_T = np.array([215.0, 230.0, 245.0, 259.99])
ODO_K, BARO_B = 0.01, 5.0
MEMS = dict(gyro_bias_deg_h=10.0, arw_deg_sqrt_h=0.3, accel_bias_ug=1000.0, vrw_m_s_sqrt_h=0.1,
            bias_corr_time_s=np.inf)


def car():
    return parse_scenario(dict(
        name="car-odo", seed=1, imu_rate_hz=100.0,
        initial=dict(lat_deg=30.0, lon_deg=114.0, height_m=50.0, speed_m_s=15.0, heading_deg=30.0),
        segments=[dict(type="straight", duration_s=60), dict(type="turn", angle_deg=90, rate_deg_s=5),
                  dict(type="straight", duration_s=40),
                  dict(type="s_turns", duration_s=60, amplitude_deg=20),
                  dict(type="turn", angle_deg=-90, rate_deg_s=5), dict(type="straight", duration_s=85)]))


@pytest.fixture(scope="module")
def runs(loose_error_state):
    truth, imu_true, _ = generate_truth(car())
    spec = ImuSpec.from_units(**MEMS)
    gs = GnssSpec(rate_hz=1.0, sigma_pos_enu=[0.5, 0.5, 1.0], sigma_vel_enu=[0.05, 0.05, 0.1])
    out = {k: [] for k in ("h_free", "h_odo", "v_free", "v_baro", "nees_odo", "nees_baro", "n_odo", "n_baro")}
    for ss in np.random.SeedSequence(BASE_SEED).spawn(N_RUNS):
        s_imu, s_gnss, s_init, s_odo, s_baro = ss.spawn(5)
        imu, realised = corrupt_imu(imu_true, spec, np.random.default_rng(s_imu))
        gnss = simulate_gnss(truth, gs, np.random.default_rng(s_gnss))
        withheld = (gnss.time >= OUTAGE[0]) & (gnss.time < OUTAGE[1])
        lla, vel, rph = perturbed_initial_state(truth, np.random.default_rng(s_init))
        odo = simulate_odometer(truth, 10.0, ODO_K, 0.05, np.random.default_rng(s_odo))
        baro = simulate_baro(truth, 5.0, BARO_B, 0.3, np.random.default_rng(s_baro))

        def cfg(lla=lla, vel=vel, rph=rph, **kw):
            return loose_config_from_specs(spec, gs, init_rph_deg=rph, init_lla_deg_m=lla, init_vel=vel,
                                           constraints={"zupt": False, **kw})

        k_end = int(np.searchsorted(truth.time, OUTAGE[1])) - 1  # last sample before the fix at 260 s
        free = run_loose(imu, gnss, cfg(), withheld=withheld)
        c_odo = cfg(nhc=True, nhc_sigma_m_s=0.05, nhc_min_speed_m_s=1.0)
        r_odo = run_loose(imu, gnss, c_odo, withheld=withheld, aids=[aid("odometer", odo)],
                          cov_times=NEES_T)
        r_baro = run_loose(imu, gnss, cfg(), withheld=withheld, aids=[aid("baro", baro)],
                           cov_times=NEES_T)
        for res, key in ((free, "free"), (r_odo, "odo"), (r_baro, "baro")):
            k = int(np.searchsorted(res.time, truth.time[k_end]))
            de, dn, du = lla_difference_enu(res.state[k, 0], res.state[k, 1], res.state[k, 2],
                                            truth.lat[k_end], truth.lon[k_end], truth.height[k_end])
            if key in ("free", "odo"):
                out[f"h_{key}"].append(float(np.hypot(de, dn)))
            if key in ("free", "baro"):
                out[f"v_{key}"].append(float(abs(du)))
        for res, key, slot, true_val in ((r_odo, "odo", L_ODO, ODO_K), (r_baro, "baro", L_BARO, BARO_B)):
            lay = res.layout
            idx = np.searchsorted(res.time, res.cov_time - 1e-9)
            e15 = loose_error_state(res, truth, realised, idx)
            e = np.column_stack([e15, true_val - res.bias[idx, lay[slot] - 9]])
            assert e.shape[1] == lay[L_N]
            nees = [float(ei @ np.linalg.solve(P, ei)) for ei, P in zip(e, res.cov, strict=True)]
            out[f"nees_{key}"].append(nees)
            out[f"n_{key}"].append(res.counts[f"{key if key == 'baro' else 'odometer'}_updates"])
    return {k: np.array(v) for k, v in out.items()}


def test_odometer_limits_horizontal_drift(runs):
    rms_free, rms_odo = np.sqrt(np.mean(runs["h_free"] ** 2)), np.sqrt(np.mean(runs["h_odo"] ** 2))
    print(f"\nend-of-outage horizontal error RMS: unaided {rms_free:.2f} m, odometer+NHC {rms_odo:.2f} m "
          f"(ratio {rms_odo / rms_free:.3f})")
    assert np.all(runs["n_odo"] > 2500)  # 10 Hz over 280 s, all accepted but a few
    assert rms_odo <= rms_free / 5.0


def test_barometer_bounds_height(runs):
    print(f"\nend-of-outage height error: unaided mean {runs['v_free'].mean():.2f} m, barometer max "
          f"{runs['v_baro'].max():.2f} m")
    assert np.all(runs["n_baro"] > 1300)
    assert np.all(runs["v_baro"] <= 2.0)
    assert np.sqrt(np.mean(runs["v_baro"] ** 2)) < 0.5 * np.sqrt(np.mean(runs["v_free"] ** 2))


@pytest.mark.parametrize("key", ["odo", "baro"])
def test_nees_in_band(runs, key):
    nees = runs[f"nees_{key}"]  # (N_RUNS, 4)
    n = 16
    lo, hi = chi2.ppf([0.01 / 16, 1 - 0.01 / 16], N_RUNS * n) / N_RUNS
    avg = nees.mean(axis=0)
    print(f"\n{key}: NEES averages {np.round(avg, 2)} band [{lo:.2f}, {hi:.2f}]")
    assert np.all((avg > lo) & (avg < hi))


@pytest.fixture(scope="module")
def combined():
    """One run with odometer, NHC and barometer (17 states), forward and smoothed."""
    truth, imu_true, _ = generate_truth(car())
    spec = ImuSpec.from_units(**MEMS)
    gs = GnssSpec(rate_hz=1.0, sigma_pos_enu=[0.5, 0.5, 1.0], sigma_vel_enu=[0.05, 0.05, 0.1])
    s_imu, s_gnss, s_init, s_odo, s_baro = np.random.SeedSequence(BASE_SEED + 1).spawn(5)
    imu, _ = corrupt_imu(imu_true, spec, np.random.default_rng(s_imu))
    gnss = simulate_gnss(truth, gs, np.random.default_rng(s_gnss))
    withheld = (gnss.time >= OUTAGE[0]) & (gnss.time < OUTAGE[1])
    lla, vel, rph = perturbed_initial_state(truth, np.random.default_rng(s_init))
    odo = simulate_odometer(truth, 10.0, ODO_K, 0.05, np.random.default_rng(s_odo))
    baro = simulate_baro(truth, 5.0, BARO_B, 0.3, np.random.default_rng(s_baro))
    cfg = loose_config_from_specs(spec, gs, init_rph_deg=rph, init_lla_deg_m=lla, init_vel=vel,
                                  constraints={"zupt": False, "nhc": True, "nhc_sigma_m_s": 0.05})
    res = run_loose(imu, gnss, cfg, withheld=withheld, aids=[aid("odometer", odo), aid("baro", baro)],
                    smooth=True)
    return truth, res


def test_smoother_and_result_with_calibration_states(combined, position_error_m):
    truth, res = combined
    assert res.smoothed and res.layout[L_N] == 17
    fwd = type(res)(res.time, res.forward_state, res.bias, res.forward_pdiag, res.node_time)
    out = (res.time >= OUTAGE[0]) & (res.time < OUTAGE[1])
    e_s, _ = position_error_m(res, truth, np.flatnonzero(out))
    e_f, _ = position_error_m(fwd, truth, np.flatnonzero(out))
    print(f"\noutage position RMS: forward {np.sqrt(np.mean(e_f ** 2)):.3f} m, smoothed "
          f"{np.sqrt(np.mean(e_s ** 2)):.3f} m")
    assert np.sqrt(np.mean(e_s ** 2)) < np.sqrt(np.mean(e_f ** 2))
    assert np.all(res.pdiag <= res.forward_pdiag * (1 + 1e-9) + 1e-30)
    # the smoothed calibration estimates are near the simulated values (3σ)
    lay = res.layout
    for slot, true_val in ((L_ODO, ODO_K), (L_BARO, BARO_B)):
        j = lay[slot]
        assert abs(res.bias[-1, j - 9] - true_val) < 3 * np.sqrt(res.pdiag[-1, j])
    # the innovation log: one-row models have NIS = ν²/S; statuses cover every record
    log = res.innovations
    b = log["model"] == ms.M_BARO
    assert b.sum() > 1300 and np.allclose(log["nis"][b], log["nu"][b, 0] ** 2 / log["s"][b, 0])
    assert set(np.unique(log["status"])) <= {-1, 0, 1} and set(log["model_name"][b]) == {"baro"}
    df = res.to_dataframe()
    assert np.allclose(df["sigma_baro_bias"], np.sqrt(res.pdiag[:, 16]))
    assert np.allclose(df["odometer_scale"], res.bias[:, 15 - 9])
    traj = res.to_trajectory()
    assert np.allclose(traj.extra["baro_bias_m"], res.bias[:, 16 - 9])
    assert np.allclose(traj.extra["odometer_scale_ppm"], res.bias[:, 15 - 9] * 1e6)
