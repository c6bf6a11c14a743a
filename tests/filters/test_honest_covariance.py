"""Honest covariance with 10 Hz GNSS whose errors are time-correlated (issue 26, item 3).

Simulated car (tactical IMU, fixed seed), position fixes at 10 Hz with a first-order Gauss-Markov
error (σ 0.5 m horizontal, 1 m up, τ 30 s) plus 5 cm white noise. Three filters:
  A: the same fixes at 1 Hz, treated as white with the total σ (the reference);
  B: all 10 Hz fixes treated as white with the total σ: 10× the information the fixes hold, so σ is
     too small (the issue: attitude worse and σ 10–40× too small);
  C: all 10 Hz fixes with three Gauss-Markov error states (``gnss.error_tau_s``, ``gnss.error_sigma_m``;
     the file σ is the white part): the σ must cover the error;
  D (issue 35): all 10 Hz fixes with the total σ and nothing stated about their errors: the default then
     chooses the Gauss-Markov states from the rate (``preprocess.correlated_gnss_errors``), so it covers.
Checks: C's horizontal position error within 3σ (per axis) at >= 95 % of the epochs after 60 s (the
χ²(1) 99.7 % point, with margin for the correlated samples), and its heading error no worse than 2× A's;
B fails the coverage (what the Gauss-Markov states fix).
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.filters.loose import run_loose, to_trajectory
from aidnav.filters.tuning import loose_config_from_specs
from aidnav.nav.earth import lla_difference_enu, radii
from aidnav.sim.gnss import GnssSpec
from aidnav.sim.imu import ImuSpec
from aidnav.sim.run import simulate
from aidnav.sim.scenario import parse_scenario

SIG_GM = np.array([0.5, 0.5, 1.0])
TAU = 30.0
WHITE = 0.05


@pytest.fixture(scope="module")
def runs():
    scn = parse_scenario({
        "name": "gm", "seed": 21, "imu_rate_hz": 100,
        "initial": {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 50.0, "speed_m_s": 10.0,
                    "heading_deg": 20.0},
        "segments": [{"type": "straight", "duration_s": 60}, {"type": "turn", "angle_deg": 180,
                                                               "duration_s": 30},
                     {"type": "straight", "duration_s": 60}, {"type": "turn", "angle_deg": -90,
                                                               "duration_s": 20},
                     {"type": "straight", "duration_s": 90}, {"type": "turn", "angle_deg": 270,
                                                               "duration_s": 40},
                     {"type": "straight", "duration_s": 60}],
        "sensors": {"imu": {"grade": "tactical"},
                    "gnss": {"rate_hz": 10, "sigma_pos_m": [WHITE, WHITE, WHITE], "velocity": False}}})
    sim = simulate(scn)
    g = sim.gnss
    rng = np.random.default_rng(8)
    dt = 0.1
    a = np.exp(-dt / TAU)
    b = np.zeros((len(g), 3))
    b[0] = rng.normal(0.0, SIG_GM)
    for k in range(1, len(g)):
        b[k] = a * b[k - 1] + np.sqrt(1 - a * a) * rng.normal(0.0, SIG_GM)
    rm, rn = radii(g.lat)
    g.lat = g.lat + b[:, 1] / (rm + g.height)
    g.lon = g.lon + b[:, 0] / ((rn + g.height) * np.cos(g.lat))
    g.height = g.height + b[:, 2]
    spec = ImuSpec.grade("tactical")
    gs = GnssSpec.from_config(scn.sensors.gnss)
    t0 = sim.truth
    lla0 = (np.degrees(t0.lat[0]), np.degrees(t0.lon[0]), t0.height[0])
    init = dict(init_rph_deg=np.degrees(t0.rph[0]), init_lla_deg_m=lla0, init_vel=t0.vel[0],
                position_sigma_m=(1.0, 1.0, 1.0), attitude_sigma_deg=(0.5, 0.5, 3.0))
    total = np.sqrt(WHITE ** 2 + SIG_GM ** 2)
    white = g.subset(np.ones(len(g), bool))
    white.std_pos = np.tile(total, (len(g), 1))
    one_hz = white.subset(np.arange(len(g)) % 10 == 0)
    cfg_w = loose_config_from_specs(spec, gs, **init, gnss={"error_tau_s": 0.0})  # white, stated
    cfg_d = loose_config_from_specs(spec, gs, **init)
    cfg_gm = loose_config_from_specs(spec, gs, **init, gnss={"error_tau_s": TAU,
                                                            "error_sigma_m": tuple(SIG_GM)})
    out = {}
    cases = (("A", cfg_w, one_hz), ("B", cfg_w, white), ("C", cfg_gm, g), ("D", cfg_d, white))
    for name, cfg, fixes in cases:
        out[name] = to_trajectory(run_loose(sim.imu, fixes, cfg))
    return sim.truth, out


def _stats(traj, truth, t_min=60.0):
    j = np.clip(np.searchsorted(truth.time, traj.time), 0, len(truth) - 1)
    e, n, _ = lla_difference_enu(traj.lat, traj.lon, 0.0, truth.lat[j], truth.lon[j], 0.0)
    m = traj.time >= traj.time[0] + t_min
    cover = np.mean((np.abs(e[m]) <= 3 * traj.std_pos[m, 0]) & (np.abs(n[m]) <= 3 * traj.std_pos[m, 1]))
    dh = (traj.rph[:, 2] - truth.rph[j, 2] + np.pi) % (2 * np.pi) - np.pi
    return cover, float(np.sqrt(np.mean(dh[m] ** 2)))


def test_gauss_markov_states_keep_sigma_honest(runs):
    truth, out = runs
    cover_c, head_c = _stats(out["C"], truth)
    _, head_a = _stats(out["A"], truth)
    print(f"\nGM states at 10 Hz: 3σ coverage {cover_c:.3f}, heading RMS {np.degrees(head_c):.3f} deg; "
          f"1 Hz white: heading RMS {np.degrees(head_a):.3f} deg")
    assert cover_c >= 0.95, cover_c
    assert head_c <= 2.0 * head_a, (np.degrees(head_c), np.degrees(head_a))


def test_white_model_at_10_hz_claims_too_much(runs):
    truth, out = runs
    cover_b, _ = _stats(out["B"], truth)
    head_b = np.degrees(_stats(out["B"], truth)[1])
    print(f"\nwhite model at 10 Hz: 3σ coverage {cover_b:.3f}, heading RMS {head_b:.3f} deg")
    assert cover_b < 0.95, cover_b


def test_default_at_10_hz_chooses_correlated_errors(runs):
    truth, out = runs
    cover_d, _ = _stats(out["D"], truth)
    print(f"\ndefault at 10 Hz: 3σ coverage {cover_d:.3f}")
    assert cover_d >= 0.95, cover_d


def test_nis_health_flags_only_the_window_where_sigma_is_wrong():
    """χ²(3) NIS at 4 Hz for 120 s, ×10 in [60, 90) s (σ √10 too small there): that window and only it."""
    from aidnav.filters.result import FilterResult, nis_health

    rng = np.random.default_rng(4)
    t = np.arange(0.0, 120.0, 0.25)
    nis = rng.chisquare(3, len(t))
    bad = (t >= 60) & (t < 90)
    nis[bad] *= 10.0
    rec = {"pos_status": np.ones(len(t), np.int8), "pos_nis": nis, "pos_innov": np.zeros((len(t), 3))}
    r = FilterResult(t, np.zeros((len(t), 10)), np.zeros((len(t), 6)), np.zeros((len(t), 15)), t,
                     records=rec, gnss_time=t)
    h = nis_health(r)
    assert [(w["model"], w["start"]) for w in h["windows"]] == [("gnss_position", 60.0)]
    assert "too small" in h["warnings"][0]
