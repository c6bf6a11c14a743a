"""Re-initialisation when the innovations say the filter is wrong (issue 26, item 3).

The engine's policy (:func:`aidnav.filters.gate.policy_update`): after ``max_consecutive_rejections``
rejected fixes of a type, or when the sum of the NIS of the last ``nis_window`` accepted fixes is above
the 99.9 % quantile of χ²(N·m), the navigation block of P is scaled until the triggering innovation is
consistent (NIS = m) and the fix is accepted; the event is logged and reported.

Checks: closed forms (the Wilson–Hilferty quantile against scipy; the inflation gives NIS = m and keeps
P positive semi-definite), and two seeded simulations of a car with a MEMS IMU (grade ``mems``) and
1 Hz position and velocity fixes: (a) a 30 m step in every fix from t = 150 s (a datum change) and (b)
an initial heading 40° wrong with a claimed σ of 1°. Each must log a re-initialisation, recover
(horizontal error below 1 m and heading error below 2° in the last 60 s) and have its covariance
honest again afterwards: the per-epoch horizontal NEES within the χ²(2) 99.7 % point, and the heading
error within 3σ, at ≥ 95 % of the epochs of the last 60 s.
Without the re-initialisation (b) stays wrong, with σ claiming otherwise.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.special import chdtri

from aidnav.filters.loose import run_loose
from aidnav.filters.reinit import chi2_quantile, inflate_nav
from aidnav.filters.tuning import loose_config_from_specs
from aidnav.nav.earth import lla_difference_enu
from aidnav.sim.run import simulate
from aidnav.sim.scenario import parse_scenario

CHI2_2_997 = float(chdtri(2, 0.003))  # 11.6


@pytest.mark.parametrize("k", [10, 20, 30, 60, 300])
def test_wilson_hilferty_quantile(k):
    exact = chdtri(k, 1e-3)
    assert exact <= chi2_quantile(float(k), 3.090232) <= exact * (1.0 + 0.06 / np.sqrt(k))


def test_inflation_makes_the_innovation_consistent():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(15, 15))
    P = A @ A.T * 1e-4 + np.eye(15) * 1e-6
    H = np.zeros((3, 15))
    H[:, 6:9] = np.eye(3)
    R = np.eye(3) * 1e-4
    z = np.array([1.0, -2.0, 0.5])
    x = np.zeros(15)
    Pi = P.copy()
    a = inflate_nav(x, Pi, H, R, z)
    S = H @ Pi @ H.T + R
    assert a > 1.0
    assert z @ np.linalg.solve(S, z) == pytest.approx(3.0, rel=1e-6)
    assert np.linalg.eigvalsh(Pi).min() > -1e-12
    assert np.allclose(Pi[9:, 9:], P[9:, 9:])  # sensor errors untouched
    assert np.all(np.diag(Pi)[:9] >= np.diag(P)[:9])  # the navigation block inflated
    assert np.all(np.diag(Pi)[:3] <= np.maximum(np.diag(P)[:3], (0.5 * np.pi) ** 2) * (1 + 1e-12))
    Pc = P.copy()
    assert inflate_nav(x, Pc, H, R, np.zeros(3)) == 1.0 and np.array_equal(Pc, P)  # consistent: nothing


@pytest.fixture(scope="module")
def car():
    scn = parse_scenario({
        "name": "reinit", "seed": 31, "imu_rate_hz": 100,
        "initial": {"lat_deg": 40.0, "lon_deg": -105.0, "height_m": 1600.0, "speed_m_s": 10.0,
                    "heading_deg": 30.0},
        "segments": [{"type": "straight", "duration_s": 40},
                     {"type": "turn", "angle_deg": 90, "duration_s": 15},
                     {"type": "straight", "duration_s": 60}, {"type": "turn", "angle_deg": -120,
                                                              "duration_s": 20},
                     {"type": "straight", "duration_s": 60}, {"type": "turn", "angle_deg": 180,
                                                              "duration_s": 30},
                     {"type": "straight", "duration_s": 75}],
        "sensors": {"imu": {"grade": "mems"},
                    "gnss": {"rate_hz": 1, "sigma_pos_m": [0.5, 0.5, 1.0],
                             "sigma_vel_m_s": [0.05, 0.05, 0.1]}}})
    return simulate(scn)


def _cfg(sim, heading_off_deg=0.0, heading_sigma_deg=1.0, **gnss):
    from aidnav.sim.gnss import GnssSpec
    from aidnav.sim.imu import ImuSpec

    t0 = sim.truth
    rph = np.degrees(t0.rph[0]) + [0.0, 0.0, heading_off_deg]
    return loose_config_from_specs(
        ImuSpec.grade("mems"), GnssSpec.from_config(sim.scenario.sensors.gnss), init_rph_deg=rph,
        init_lla_deg_m=(np.degrees(t0.lat[0]), np.degrees(t0.lon[0]), t0.height[0]), init_vel=t0.vel[0],
        attitude_sigma_deg=(0.5, 0.5, heading_sigma_deg),
        gnss={"gate_probability": 0.9999, "nis_window": 10, **gnss})


def _errors(res, truth):
    j = np.clip(np.searchsorted(truth.time, res.time), 0, len(truth.time) - 1)
    e, n, _ = lla_difference_enu(res.state[:, 0], res.state[:, 1], 0.0, truth.lat[j], truth.lon[j], 0.0)
    from aidnav.filters.loose import to_trajectory

    tr = to_trajectory(res)
    dh = np.degrees((tr.rph[:, 2] - truth.rph[j, 2] + np.pi) % (2 * np.pi) - np.pi)
    # horizontal NEES with the E/N variances (their correlation is small after a fix; diagonal form)
    nees = e ** 2 / tr.std_pos[:, 0] ** 2 + n ** 2 / tr.std_pos[:, 1] ** 2
    return np.hypot(e, n), dh, nees, tr.std_att[:, 2]


def _check_recovered(res, truth, label):
    err, dh, nees, sd_h = _errors(res, truth)
    last = res.time >= res.time[-1] - 60.0
    cover = float(np.mean(nees[last] <= CHI2_2_997))
    cover_h = float(np.mean(np.abs(dh[last]) <= 3.0 * np.degrees(sd_h[last])))
    print(f"\n{label}: last 60 s horizontal error max {err[last].max():.2f} m, |heading error| max "
          f"{np.abs(dh[last]).max():.2f} deg, NEES coverage {cover:.3f}, heading 3 sigma coverage "
          f"{cover_h:.3f}")
    assert err[last].max() < 1.0
    assert np.abs(dh[last]).max() < 2.0
    assert cover >= 0.95 and cover_h >= 0.95


def test_position_step_reinitialises_and_recovers(car):
    sim = car
    g = sim.gnss.subset(np.ones(len(sim.gnss), bool))
    j = int(np.searchsorted(g.time, g.time[0] + 150.0))
    g.lat[j:] += 30.0 / 6.36e6  # 30 m north from t = 150 s: every later fix
    # the truth moves with the fixes: the filter must follow the new datum
    truth = sim.truth
    lat = np.where(truth.time >= g.time[j] - 1e-6, truth.lat + 30.0 / 6.36e6, truth.lat)
    truth_shift = dataclasses.replace(truth, lat=lat)
    events: list[str] = []
    res = run_loose(sim.imu, g, _cfg(sim), events=events)
    st, why = res.records["pos_status"], res.records["pos_reinit"]
    assert np.all(st[j:j + 10] == 0) and st[j + 10] == 1 and why[j + 10] == 1
    assert any("re-initialisation" in e and "consecutive rejections" in e for e in events), events
    _check_recovered(res, truth_shift, "30 m step")


def test_wrong_heading_reinitialises_and_recovers(car):
    sim = car
    events: list[str] = []
    res = run_loose(sim.imu, sim.gnss, _cfg(sim, heading_off_deg=40.0), events=events)
    assert any("re-initialisation" in e for e in events), events
    _check_recovered(res, sim.truth, "heading 40 deg off")


def test_without_reinitialisation_a_wrong_heading_claims_too_much(car):
    """The same start with the re-initialisation off (no NIS window, no consecutive-rejection limit in
    reach): the error is outside the claimed σ for much of the run — what the re-initialisation fixes."""
    sim = car
    res = run_loose(sim.imu, sim.gnss, _cfg(sim, heading_off_deg=40.0, nis_window=0,
                                             max_consecutive_rejections=100000))
    _, dh, nees, _ = _errors(res, sim.truth)
    assert float(np.mean(nees <= CHI2_2_997)) < 0.9
