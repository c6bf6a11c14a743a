"""Issue 35's four regressions on plain inputs, run with no option at all (``process`` with the default
configuration, as a new user would): a simulated 300-s car (MEMS IMU, 100 Hz; GNSS position σ 0.5 m
horizontal, velocity 0.05 m/s; 30 s parked, then driving with four turns). The figures of the issue's
older code are the bounds: GNSS at 0.2 Hz horizontal RMS ≤ 1 m; a 30-s IMU gap inside a turn ≤ 30 m with
a σ that covers the error; fixes whose σ is 0 in the file (floored by the reader) ≤ 1.2 m; the clean
1-Hz run's heading RMS ≤ 0.5°. Errors after the first 60 s (the course alignment is at the start of the
drive)."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.apps.process import process
from aidnav.data import ImuData
from aidnav.io._std import ZERO_POS_STD_FLOOR_M
from aidnav.nav.earth import lla_difference_enu
from aidnav.sim.run import simulate
from aidnav.sim.scenario import parse_scenario

T_MIN = 60.0
GAP = (140.0, 170.0)  # inside the 180° turn of 135…175 s


def _scenario(rate_hz):
    return parse_scenario({
        "name": "car300", "seed": 3, "imu_rate_hz": 100,
        "initial": {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 50.0, "speed_m_s": 0.0,
                    "heading_deg": 30.0},
        "segments": [{"type": "static", "duration_s": 30},
                     {"type": "accelerate", "duration_s": 10, "to_speed_m_s": 12},
                     {"type": "straight", "duration_s": 40},
                     {"type": "turn", "angle_deg": 90, "duration_s": 15},
                     {"type": "straight", "duration_s": 40},
                     {"type": "turn", "angle_deg": -180, "duration_s": 40},
                     {"type": "straight", "duration_s": 40},
                     {"type": "turn", "angle_deg": 90, "duration_s": 20},
                     {"type": "straight", "duration_s": 65}],
        "sensors": {"imu": {"grade": "mems"},
                    "gnss": {"rate_hz": rate_hz, "sigma_pos_m": [0.5, 0.5, 1.0],
                             "sigma_vel_m_s": [0.05, 0.05, 0.1], "velocity": True}}})


@pytest.fixture(scope="module")
def sim1():
    return simulate(_scenario(1.0))


def _errors(run, truth):
    tr = run.trajectory
    it = np.clip(np.searchsorted(truth.time, tr.time - 1e-6), 0, len(truth.time) - 1)
    e, n, _ = lla_difference_enu(tr.lat, tr.lon, tr.height, truth.lat[it], truth.lon[it], truth.height[it])
    dh = (np.degrees(tr.rph[:, 2] - truth.rph[it, 2]) + 180.0) % 360.0 - 180.0
    m = tr.time >= truth.time[0] + T_MIN
    return tr, e, n, dh, m


def test_clean_baseline_heading(sim1):
    run = process(sim1.imu, sim1.gnss)
    # no option decides the NHC from the log (issue 35, item 6): the simulated car has no sideslip
    assert any(e.startswith("vehicle from the log: wheeled") and "NHC on" in e for e in run.summary["events"])
    tr, e, n, dh, m = _errors(run, sim1.truth)
    assert np.sqrt(np.mean(dh[m] ** 2)) <= 0.5
    assert np.sqrt(np.mean(e[m] ** 2 + n[m] ** 2)) <= 1.0


def test_gnss_at_0_2_hz():
    sim = simulate(_scenario(0.2))
    tr, e, n, dh, m = _errors(process(sim.imu, sim.gnss), sim.truth)
    assert np.sqrt(np.mean(e[m] ** 2 + n[m] ** 2)) <= 1.0


def test_zero_sigma_in_the_file(sim1):
    """Fixes claiming 5 cm against 0.5 m of noise: the first pass measures their σ understated and scales
    it (filters.gnss_errors; over seeds: test_gnss_sigma_factor.py); the run must stay within the older
    code's figure."""
    g = sim1.gnss.subset(np.ones(len(sim1.gnss), bool))
    g.std_pos = np.full((len(g), 3), ZERO_POS_STD_FLOOR_M)  # what the readers make of σ = 0
    tr, e, n, dh, m = _errors(process(sim1.imu, g), sim1.truth)
    assert np.sqrt(np.mean(e[m] ** 2 + n[m] ** 2)) <= 1.2


def test_imu_gap_in_a_turn(sim1):
    """30 s of IMU samples missing inside the 180° turn: position ≤ 30 m off everywhere after it, the
    3σ per horizontal axis covers the error at the first sample after it and at ≥ 90 % of the samples
    after it (one run: its errors are correlated over tens of seconds, so the fraction of a consistent
    filter scatters well below the 99.5 % of independent samples), and the heading, held unknown until
    the GNSS course re-aligns it, is covered by its 3σ from the gap's end on (at ≥ 95 % of the samples)
    and ends within 2° of the truth."""
    imu = sim1.imu
    t0 = imu.time[0]
    keep = ~((imu.time > t0 + GAP[0]) & (imu.time < t0 + GAP[1]))
    run = process(ImuData(imu.time[keep], imu.dtheta[keep], imu.dv[keep], t0=imu.t0), sim1.gnss)
    assert any("IMU gap of 30" in ev for ev in run.summary["events"])
    tr, e, n, dh, _ = _errors(run, sim1.truth)
    a = tr.time >= t0 + GAP[1]
    assert np.hypot(e[a], n[a]).max() <= 30.0
    se, sn = tr.std_pos[a, 0], tr.std_pos[a, 1]
    cov = (np.abs(e[a]) <= 3 * se) & (np.abs(n[a]) <= 3 * sn)
    assert cov[0] and cov.mean() >= 0.90
    sh = np.degrees(tr.std_att[a, 2])
    assert np.mean(np.abs(dh[a]) <= 3 * sh) >= 0.95
    assert abs(dh[-1]) <= 2.0
