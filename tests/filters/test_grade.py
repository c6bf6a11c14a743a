"""The IMU's grade from the log's static samples (issue 35, session 12: :mod:`aidnav.filters.grade`).

Known answers of the choice rule (closed form), the grade rows against the project's grade table, and the
simulator against the classifier: static logs of every grade (20 s at rest, the grade's turn-on biases,
scale factors and misalignments drawn per seed) are classed no better than their grade — a consumer IMU
never gets a better grade's model (the unsafe direction), a better IMU leaves the unknown-grade model.
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.filters import grade as gr
from aidnav.filters.config import DEFAULT_IMU, ImuNoise, LooseConfig
from aidnav.filters.layout import ST_Q
from aidnav.nav.earth import OMEGA_IE
from aidnav.nav.rotations import euler_from_quat
from aidnav.sim.imu import ImuSpec
from aidnav.sim.run import simulate
from aidnav.sim.scenario import parse_scenario
from aidnav.units import DEG, DEG_H, UG

ORDER = ["navigation", "tactical", "mems", "unknown"]


@pytest.mark.parametrize("i", range(3))
def test_grade_rows_are_the_grade_table(i):
    name, (gb, gi, ab, ai, tau, gsf, asf, mis) = gr.GRADE_ROWS[i]
    s = ImuSpec.grade(name)
    np.testing.assert_allclose([np.max(s.gyro_bias) / DEG_H, np.max(s.gyro_bias_instability) / DEG_H,
                                np.max(s.accel_bias) / UG, np.max(s.accel_bias_instability) / UG,
                                np.min(s.gyro_bias_tau), np.max(s.gyro_scale) * 1e6,
                                np.max(s.accel_scale) * 1e6, np.max(s.gyro_misalignment) / DEG * 3600.0],
                               [gb, gi, ab, ai, tau, gsf, asf, mis], rtol=1e-9)


def test_choice_known_answers():
    """The posterior in closed form from the Gaussian likelihoods; zero residuals measured to 1e-4 deg/h
    and 0.1 µg: the navigation grade (the others below ALPHA); a tactical IMU's 20-s start (gyro
    residuals within its 1.4-deg/h standard error, the accelerometer's 190 µg): navigation the most
    probable, but tactical is possible, and the cautious choice takes it."""
    se = np.array([1e-4 * DEG_H, 1e-4 * DEG_H, 0.1 * UG])
    r = np.zeros(3)
    name, _, p = gr.choose_grade(r, se)
    models = gr.grade_models()
    s = []
    for _, m in models:
        sg = m["gyro_bias_sigma_deg_h"] * DEG_H
        sa = np.hypot(m["accel_bias_sigma_ug"], m["accel_sf_sigma_ppm"] * 9.80665e-6 / UG)
        sv = np.sqrt((sa * UG) ** 2 + (gr.GRAVITY_MODEL_UG * UG) ** 2 + se[2] ** 2)
        s.append([np.hypot(sg, se[0]), np.hypot(sg, se[1]), sv])
    like = 1.0 / np.prod(np.array(s), axis=1)
    np.testing.assert_allclose(p, like / like.sum(), rtol=1e-9)
    assert name == ORDER[max(i for i in range(4) if p[i] >= gr.ALPHA)]
    assert name == "navigation"
    name, _, p = gr.choose_grade(np.array([0.5 * DEG_H, -1.8 * DEG_H, 190 * UG]),
                                 np.array([1.4 * DEG_H, 1.4 * DEG_H, 177 * UG]))
    assert np.argmax(p) == 0 and p[1] >= gr.ALPHA > p[2] and name == "tactical"  # not the most probable
    # consumer-sized residuals: the unknown grade
    assert gr.choose_grade(np.array([200 * DEG_H, -300 * DEG_H, 8000 * UG]), se)[0] == "unknown"
    # a gyro at the Earth rate but an accelerometer 8 mg off: no better grade explains both
    assert gr.choose_grade(np.array([0.0, 0.0, 8000 * UG]), se)[0] == "unknown"


def _static_log(grade: str, seed: int, lat_deg: float = 40.0):
    scn = parse_scenario({"name": "static", "seed": seed, "imu_rate_hz": 100,
                          "initial": {"lat_deg": lat_deg, "lon_deg": 116.0, "height_m": 50.0,
                                      "heading_deg": (20.0 + 37.0 * seed) % 360.0},
                          "segments": [{"type": "static", "duration_s": 20}],
                          "sensors": {"imu": {"grade": grade}, "gnss": {"rate_hz": 1.0}}})
    return simulate(scn, seed)


@pytest.mark.parametrize("grade", ["navigation", "tactical", "mems", "consumer"])
def test_static_logs_are_never_classed_better_than_their_grade(grade):
    """12 seeds per grade; the classer sees only the IMU log. Measured (n35g): navigation → navigation
    12/12; tactical → tactical 6, mems 6 (its 20-s start cannot tell a 1-deg/h gyro bias from 10 deg/h:
    the cautious choice); mems → mems 12/12; consumer → unknown 12/12."""
    truth = ORDER.index("unknown" if grade == "consumer" else grade)
    got = []
    for seed in range(12):
        sim = _static_log(grade, seed)
        lat = float(sim.gnss.lat[0])
        r, se = gr.static_residuals(sim.imu, lat, 50.0, sim.imu.time[0], sim.imu.time[-1] + 1e-9)
        got.append(ORDER.index(gr.choose_grade(r, se)[0]))
    print(grade, [ORDER[g] for g in got])
    assert min(got) >= truth  # never a better grade's model than the IMU's
    if grade == "consumer":
        assert set(got) == {3}
    else:
        assert np.mean(np.array(got) < 3) >= 0.9  # a better IMU leaves the unknown-grade model


def test_earth_rate_residuals_of_a_perfect_imu_are_zero():
    sim = _static_log("perfect", 0, lat_deg=-33.0)
    t = sim.imu.time
    r, se = gr.static_residuals(sim.imu, float(sim.gnss.lat[0]), 50.0, t[0], t[-1] + 1e-9)
    assert abs(r[0]) < 1e-3 * OMEGA_IE and abs(r[1]) < 1e-3 * OMEGA_IE and abs(r[2]) < 1 * UG


def test_the_filter_takes_the_grade_only_without_an_imu_section():
    sim = _static_log("navigation", 1)
    ev: list[str] = []
    static = np.ones(len(sim.imu), bool)
    lat = float(sim.gnss.lat[0])
    cfg = gr.grade_from_static(sim.imu, static, lat, 50.0, LooseConfig(), ev)
    assert cfg.imu.gyro_bias_sigma_deg_h < 1.0 and cfg.imu.accel_bias_sigma_ug < 1000.0, ev
    assert "IMU grade from" in ev[0]
    # an imu section (grade_from_static off): untouched
    own = LooseConfig(imu=ImuNoise(gyro_bias_sigma_deg_h=50.0))
    assert gr.grade_from_static(sim.imu, static, lat, 50.0, own, []) is own
    # a key stated with a value of its own is kept
    mine = LooseConfig(imu=ImuNoise(**{**DEFAULT_IMU, "gyro_misalignment_sigma_deg": 0.3}))
    assert gr.grade_from_static(sim.imu, static, lat, 50.0, mine, []).imu.gyro_misalignment_sigma_deg == 0.3
    # too short at rest: the unknown grade
    ev = []
    assert gr.grade_from_static(sim.imu, np.arange(len(sim.imu)) < 500, lat, 50.0, LooseConfig(), ev) \
        .imu.gyro_bias_sigma_deg_h == DEFAULT_IMU["gyro_bias_sigma_deg_h"]
    assert "IMU grade unknown" in ev[0]


def test_a_mems_imu_is_modelled_by_the_posterior_mixture():
    """Classed MEMS (the cautious choice) with a tactical posterior above ALPHA: modelled by the mixture of
    the possible grades (each σ² = Σ p σ², the MEMS one by the unknown-grade model, grade.ADOPTED) — not
    the tactical model, and no looser than the unknown grade (issue 35, session 13)."""
    sim = _static_log("mems", 2)
    ev: list[str] = []
    lat = float(sim.gnss.lat[0])
    cfg = gr.grade_from_static(sim.imu, np.ones(len(sim.imu), bool), lat, 50.0, LooseConfig(), ev)
    r, se = gr.static_residuals(sim.imu, lat, 50.0, sim.imu.time[0], sim.imu.time[-1] + 1e-9)
    p = gr.grade_posterior(r, se)
    assert p[1] >= gr.ALPHA and p[2] >= gr.ALPHA and p[0] < gr.ALPHA, p  # tactical and MEMS possible
    w = np.where(p >= gr.ALPHA, p, 0.0)
    w = w / w.sum()
    tac, unk = gr.grade_models()[1][1], gr.grade_models()[3][1]
    for k in ("gyro_bias_sigma_deg_h", "accel_bias_sigma_ug", "gyro_sf_sigma_ppm"):
        want = np.sqrt(w[1] * tac[k] ** 2 + (w[2] + w[3]) * unk[k] ** 2)
        assert getattr(cfg.imu, k) == pytest.approx(want, rel=1e-9), k
        assert tac[k] < getattr(cfg.imu, k) <= unk[k]
    assert "-> mems: the posterior mixture of the models of tactical, mems" in ev[0], ev


def test_a_consumer_imu_keeps_the_unknown_grade_model():
    """No better grade possible (posterior < ALPHA): the configuration is left as it is."""
    sim = _static_log("consumer", 1)
    ev: list[str] = []
    cfg = gr.grade_from_static(sim.imu, np.ones(len(sim.imu), bool), float(sim.gnss.lat[0]), 50.0,
                               LooseConfig(), ev)
    assert "-> unknown: the unknown-grade model" in ev[0], ev
    assert cfg.imu == LooseConfig().imu


def test_mixture_model_known_answer():
    """Σ p σ² per σ (and per random-walk density), renormalised; a state any part has is on, a part
    without it adds nothing; the correlation time of the part with most of that bias's variance."""
    a = {"gyro_bias_sigma_deg_h": 1.0, "accel_bias_sigma_ug": 100.0, "accel_bias_tau_s": 0.0,
         "gyro_bias_rw_deg_h_sqrt_h": 2.0, "scale_factors": True, "accel_misalignment": True,
         "accel_misalignment_sigma_deg": 0.02}
    b = {"gyro_bias_sigma_deg_h": 10.0, "accel_bias_sigma_ug": 1000.0, "accel_bias_tau_s": 3600.0,
         "gyro_bias_rw_deg_h_sqrt_h": 4.0, "scale_factors": False}
    m = gr.mixture_model([(0.3, a), (0.1, b)])  # renormalised to 0.75 / 0.25
    assert m["gyro_bias_sigma_deg_h"] == pytest.approx(np.sqrt(0.75 * 1.0 + 0.25 * 100.0))
    assert m["accel_bias_sigma_ug"] == pytest.approx(np.sqrt(0.75 * 1e4 + 0.25 * 1e6))
    assert m["gyro_bias_rw_deg_h_sqrt_h"] == pytest.approx(np.sqrt(0.75 * 4.0 + 0.25 * 16.0))
    assert m["accel_misalignment_sigma_deg"] == pytest.approx(np.sqrt(0.75) * 0.02)
    assert m["scale_factors"] is True and m["accel_misalignment"] is True
    assert m["accel_bias_tau_s"] == 3600.0  # b: 0.25e6 of the variance against a's 0.75e4
    assert gr.mixture_model([(1.0, a)]) == pytest.approx({k: float(v) for k, v in a.items()})


def _drive_log(grade: str, seed: int):
    scn = parse_scenario({"name": "start", "seed": seed, "imu_rate_hz": 100,
                          "initial": {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 50.0,
                                      "heading_deg": 20.0},
                          "segments": [{"type": "static", "duration_s": 30},
                                       {"type": "accelerate", "duration_s": 10, "to_speed_m_s": 10}],
                          "sensors": {"imu": {"grade": grade}, "gnss": {"rate_hz": 1.0}}})
    return simulate(scn, seed)


@pytest.mark.parametrize("grade", ["navigation", "consumer"])
def test_static_start_prior_is_the_levelling_where_the_bias_is_small(grade):
    """No option: a navigation-grade IMU, classed, starts with its levelling's tilt σ (the standard error
    of the mean specific force ⊕ the grade's bias / g: hundredths of a degree, covering its error) and its
    gyrocompass heading σ; an IMU of unknown grade keeps the configured 2° (its levelling's 0.76° is the
    13-mg bias, correlated with the bias states) and an unknown heading until the GNSS course."""
    from aidnav.filters.loose import loose_setup  # lazy: the filter's setup, only this test

    sim = _drive_log(grade, 3)
    ev: list[str] = []
    su = loose_setup(sim.imu, sim.gnss, LooseConfig(), None, ev)
    sig = np.sqrt(np.diag(su.ini.P)[:3])
    if grade == "navigation":
        rph = np.array(euler_from_quat(su.ini.st[ST_Q:ST_Q + 4]))
        err = rph - sim.truth.rph[0]
        err[2] = (err[2] + np.pi) % (2 * np.pi) - np.pi
        assert np.all(sig[:2] < 0.05 * DEG) and sig[2] < 1.0 * DEG, (np.degrees(sig), ev)
        assert np.all(np.abs(err) <= 3.0 * sig), (np.degrees(err), np.degrees(sig))
    else:
        np.testing.assert_allclose(sig[:2], 2.0 * DEG, rtol=1e-9)
        assert sig[2] > 80 * DEG
