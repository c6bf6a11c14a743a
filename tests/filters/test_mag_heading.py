"""Magnetometer heading aid (issue 36), simulated with fixed seeds: a car parked for 5 min, then driving
for 5 min (accelerate, turns, S-turns), MEMS IMU (constant biases 10 deg/h, 1 mg; ARW 0.3 deg/√h, VRW
0.1 m/s/√h), 1 Hz GNSS position + velocity, 10 Hz magnetometer heading (σ 1°), automatic initialisation.

Without the magnetometer the heading of a parked MEMS car is unknown until it drives (no gyrocompass at
10 deg/h, no GNSS course); with it:

* the initial heading comes from the magnetometer (no course alignment) and every heading record is used;
* heading error ≤ 2° at every output epoch after the first 10 s, in every run;
* NEES of the full error state (15) at 6 epochs (3 parked, 3 driving): the N-run average at each within
  its two-sided χ²(15 N)/N band at 1 − 0.01/12 (Bonferroni over the 6 epochs, both tails).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from aidnav.filters.aids import aid
from aidnav.filters.layout import L_N
from aidnav.filters.loose import run_loose, to_trajectory
from aidnav.filters.tuning import loose_config_from_specs
from aidnav.sim.gnss import GnssSpec, simulate_gnss
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.magnetometer import simulate_mag_heading
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth

BASE_SEED = 20261206
N_RUNS = 6
PARKED_S = 300.0
NEES_T = np.array([100.0, 200.0, 290.0, 400.0, 500.0, 590.0])
MEMS = dict(gyro_bias_deg_h=10.0, arw_deg_sqrt_h=0.3, accel_bias_ug=1000.0, vrw_m_s_sqrt_h=0.1,
            bias_corr_time_s=np.inf)


def parked_then_drive():
    return parse_scenario(dict(
        name="parked-then-drive", seed=1, imu_rate_hz=100.0,
        initial=dict(lat_deg=30.0, lon_deg=114.0, height_m=50.0, speed_m_s=0.0, heading_deg=137.0),
        segments=[dict(type="static", duration_s=PARKED_S),
                  dict(type="accelerate", duration_s=10, to_speed_m_s=12),
                  dict(type="straight", duration_s=50), dict(type="turn", angle_deg=90, rate_deg_s=6),
                  dict(type="s_turns", duration_s=80, amplitude_deg=20),
                  dict(type="turn", angle_deg=-120, rate_deg_s=6), dict(type="straight", duration_s=125)]))


@pytest.fixture(scope="module")
def runs(loose_error_state):
    truth, imu_true, _ = generate_truth(parked_then_drive())
    assert truth.time[-1] - truth.time[0] >= 600.0 - 1e-6
    spec = ImuSpec.from_units(**MEMS)
    gs = GnssSpec(rate_hz=1.0, sigma_pos_enu=[0.5, 0.5, 1.0], sigma_vel_enu=[0.05, 0.05, 0.1])
    cfg = loose_config_from_specs(spec, gs, init={"mode": "auto", "static_window_s": 10.0},
                                  attitude_sigma_deg=(0.5, 0.5, 10.0), constraints={"zupt": True})
    t0 = truth.time[0]
    out = {"herr": [], "nees": [], "events": [], "mag": [], "n_mag": []}
    for ss in np.random.SeedSequence(BASE_SEED).spawn(N_RUNS):
        s_imu, s_gnss, s_mag = ss.spawn(3)
        imu, realised = corrupt_imu(imu_true, spec, np.random.default_rng(s_imu))
        gnss = simulate_gnss(truth, gs, np.random.default_rng(s_gnss))
        mag = simulate_mag_heading(truth, 10.0, 1.0, np.random.default_rng(s_mag))
        events: list[str] = []
        res = run_loose(imu, gnss, cfg, events=events, aids=[aid("mag", mag)], cov_times=t0 + NEES_T)
        traj = to_trajectory(res)
        j = np.clip(np.searchsorted(truth.time, traj.time - 1e-9), 0, len(truth.time) - 1)
        herr = (traj.rph[:, 2] - truth.rph[j, 2] + np.pi) % (2 * np.pi) - np.pi
        out["herr"].append(np.abs(herr[traj.time >= traj.time[0] + 10.0]).max())
        idx = np.searchsorted(res.time, res.cov_time - 1e-9)
        e = loose_error_state(res, truth, realised, idx)
        assert e.shape[1] == res.layout[L_N] == 15
        out["nees"].append([float(ei @ np.linalg.solve(P, ei)) for ei, P in zip(e, res.cov, strict=True)])
        out["events"].append(events)
        out["n_mag"].append((res.counts["mag_updates"], res.counts.get("mag_rejected", 0), len(mag)))
    return out


def test_heading_from_the_magnetometer_within_2_deg(runs):
    print(f"\nmax heading error per run [deg]: {np.round(np.degrees(runs['herr']), 2)}; "
          f"mag updates (accepted, rejected, records): {runs['n_mag']}")
    for events in runs["events"]:
        assert any(e.startswith("initial heading from mag") for e in events), events
        assert not any("heading from GNSS course" in e for e in events), events
    for acc, rej, n in runs["n_mag"]:
        assert acc >= 0.99 * n and rej <= 0.01 * n
    assert np.degrees(max(runs["herr"])) <= 2.0


def test_nees_in_band(runs):
    nees = np.array(runs["nees"])  # (N_RUNS, epochs)
    k = len(NEES_T)
    lo, hi = chi2.ppf([0.01 / (2 * k), 1 - 0.01 / (2 * k)], N_RUNS * 15) / N_RUNS
    avg = nees.mean(axis=0)
    print(f"\nNEES averages {np.round(avg, 2)} band [{lo:.2f}, {hi:.2f}]")
    assert np.all((avg > lo) & (avg < hi))
