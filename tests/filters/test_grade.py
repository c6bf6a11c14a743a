"""The IMU's grade from the log's static samples (issue 35, session 12: :mod:`aidnav.filters.grade`).

Known answers of the choice rule (closed form), the grade rows against the project's grade table, and the
simulator against the classifier: static logs of every grade (20 s at rest, the grade's turn-on biases,
scale factors and misalignments drawn per seed) are classed no better than their grade — a consumer IMU
never gets a better grade's model (the unsafe direction), a better IMU leaves the unknown-grade model.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from aidnav.filters import grade as gr
from aidnav.filters.config import DEFAULT_IMU, ImuNoise, LooseConfig
from aidnav.filters.layout import ST_Q
from aidnav.nav.earth import OMEGA_IE
from aidnav.nav.rotations import dcm_from_quat, euler_from_quat
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


def _tail(w, sig, s):
    """The two-sided probability of |x| > 3s under the scale mixture Σ w_i N(0, σ_i²) (scipy's normal
    tail: independent of the module's bisection)."""
    return sum(wi * 2.0 * norm.sf(3.0 * s / si) for wi, si in zip(w, sig, strict=True) if si > 0)


def test_a_mems_imu_is_modelled_by_the_posterior_mixture():
    """Classed MEMS (the cautious choice) with a tactical posterior above ALPHA: modelled by the mixture of
    the possible grades, the MEMS grade by its own row (grade.ADOPTED, issue 35 session 14; before, by the
    unknown-grade model: σ 4× the error, ratio 0.26), each σ the one whose 3σ tail is the mixture's
    (:func:`aidnav.filters.grade.mixture_model`) — above the tactical model's, at most the MEMS one's, and
    above the variance-matched σ (the mixture is heavier-tailed than one Gaussian of its variance)."""
    assert "mems" in gr.ADOPTED
    sim = _static_log("mems", 2)
    ev: list[str] = []
    lat = float(sim.gnss.lat[0])
    cfg = gr.grade_from_static(sim.imu, np.ones(len(sim.imu), bool), lat, 50.0, LooseConfig(), ev)
    r, se = gr.static_residuals(sim.imu, lat, 50.0, sim.imu.time[0], sim.imu.time[-1] + 1e-9)
    p = gr.grade_posterior(r, se)
    assert p[1] >= gr.ALPHA and p[2] >= gr.ALPHA and p[0] < gr.ALPHA and p[3] < gr.ALPHA, p
    w = np.array([p[1], p[2]]) / (p[1] + p[2])
    tac, mems = gr.grade_models()[1][1], gr.grade_models()[2][1]
    for k in ("gyro_bias_sigma_deg_h", "accel_bias_sigma_ug", "gyro_sf_sigma_ppm"):
        s = getattr(cfg.imu, k)
        assert _tail(w, [tac[k], mems[k]], s) == pytest.approx(2.0 * norm.sf(3.0), rel=1e-6), k
        assert tac[k] < s <= mems[k]
        assert s > np.sqrt(w[0] * tac[k] ** 2 + w[1] * mems[k] ** 2)
    assert cfg.imu.accel_misalignment and cfg.imu.gyro_misalignment and cfg.imu.scale_factors
    assert "-> mems: the posterior mixture of the models of tactical, mems" in ev[0], ev
    assert "unknown-grade model" not in ev[0], ev


def test_a_consumer_imu_keeps_the_unknown_grade_model():
    """No better grade possible (posterior < ALPHA): the configuration is left as it is."""
    sim = _static_log("consumer", 1)
    ev: list[str] = []
    cfg = gr.grade_from_static(sim.imu, np.ones(len(sim.imu), bool), float(sim.gnss.lat[0]), 50.0,
                               LooseConfig(), ev)
    assert "-> unknown: the unknown-grade model" in ev[0], ev
    assert cfg.imu == LooseConfig().imu


def test_mixture_model_known_answer():
    """Each σ (and random-walk density) is the one whose 3σ tail is the mixture's (weights renormalised; a
    part without the key adds nothing to the tail); one part: its own σ; a state any part has is on; the
    correlation time of the part with most of that bias's variance."""
    a = {"gyro_bias_sigma_deg_h": 1.0, "accel_bias_sigma_ug": 100.0, "accel_bias_tau_s": 0.0,
         "gyro_bias_rw_deg_h_sqrt_h": 2.0, "scale_factors": True, "accel_misalignment": True,
         "accel_misalignment_sigma_deg": 0.02}
    b = {"gyro_bias_sigma_deg_h": 10.0, "accel_bias_sigma_ug": 1000.0, "accel_bias_tau_s": 3600.0,
         "gyro_bias_rw_deg_h_sqrt_h": 4.0, "scale_factors": False}
    m = gr.mixture_model([(0.3, a), (0.1, b)])  # renormalised to 0.75 / 0.25
    p3 = 2.0 * norm.sf(3.0)
    for k, sig in (("gyro_bias_sigma_deg_h", (1.0, 10.0)), ("accel_bias_sigma_ug", (100.0, 1000.0)),
                   ("gyro_bias_rw_deg_h_sqrt_h", (2.0, 4.0)), ("accel_misalignment_sigma_deg", (0.02, 0.0))):
        assert _tail((0.75, 0.25), sig, m[k]) == pytest.approx(p3, rel=1e-6), k
        assert max(sig) >= m[k] > np.sqrt(0.75 * sig[0] ** 2 + 0.25 * sig[1] ** 2), k
    # a quarter of the IMUs with a 10× larger bias: the 3σ point is that part's 0.27 %/0.25 tail
    assert m["gyro_bias_sigma_deg_h"] == pytest.approx(10.0 * norm.isf(p3 / 0.25 / 2.0) / 3.0, rel=1e-3)
    assert m["scale_factors"] is True and m["accel_misalignment"] is True
    assert m["accel_bias_tau_s"] == 3600.0  # b: 0.25e6 of the variance against a's 0.75e4
    assert gr.mixture_model([(1.0, a)]) == pytest.approx({k: float(v) for k, v in a.items()})
    assert gr.mixture_model([(0.5, a), (0.5, a)]) == pytest.approx({k: float(v) for k, v in a.items()})


def _drive_log(grade: str, seed: int):
    scn = parse_scenario({"name": "start", "seed": seed, "imu_rate_hz": 100,
                          "initial": {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 50.0,
                                      "heading_deg": 20.0},
                          "segments": [{"type": "static", "duration_s": 30},
                                       {"type": "accelerate", "duration_s": 10, "to_speed_m_s": 10}],
                          "sensors": {"imu": {"grade": grade}, "gnss": {"rate_hz": 1.0}}})
    return simulate(scn, seed)


@pytest.mark.parametrize("grade", ["navigation", "consumer"])
def test_static_start_tilt_prior_is_joint_with_the_accelerometer_errors(grade):
    """No option: a static start's tilt prior is the levelling's — the accelerometer errors of the model
    the filter takes (a navigation-grade IMU: its grade's, classed; otherwise the unknown grade's) divided
    by g, plus an independent part (the mean force's standard error for a fine levelling, else the
    configured σ's part beyond b/g, q35t) — *correlated* with those error states (issue 35, session 14:
    the levelled tilt is g·φ_N = (C ∇)_E, g·φ_E = −(C ∇)_N; an independent σ let the ZUPTs at rest observe
    the same sum again and shrink the tilt σ below its error). Known answer from the model's σ's; the
    navigation IMU's levelling and gyrocompass errors are covered; an unknown grade's heading is unknown."""
    from aidnav.filters.ins_errors import MIS_IN, MIS_OUT  # lazy: only this test
    from aidnav.filters.layout import BA, MA, SA  # lazy: only this test
    from aidnav.filters.loose import loose_setup  # lazy: the filter's setup, only this test

    sim = _drive_log(grade, 3)
    ev: list[str] = []
    su = loose_setup(sim.imu, sim.gnss, LooseConfig(), None, ev)
    P = su.ini.P
    sig = np.sqrt(np.diag(P)[:3])
    im = su.cfg.imu
    b = im.accel_bias_sigma_ug * UG
    if im.accel_misalignment:
        b = np.hypot(b, np.radians(im.accel_misalignment_sigma_deg) * 9.80665)
    want = b / 9.80665
    # the marginal: a fine levelling's (≤ b/g + its standard error) for the navigation IMU; otherwise the
    # configured σ it would have had alone (q35t's σ_w: only the correlation is new)
    hi = want + 0.01 * DEG if grade == "navigation" else 1.01 * np.radians(2.0)
    assert np.all(sig[:2] >= 0.99 * want) and np.all(sig[:2] <= hi), (np.degrees(sig), np.degrees(want))
    C = dcm_from_quat(su.ini.st[ST_Q:ST_Q + 4])
    fb = C.T @ np.array([0.0, 0.0, 9.80665])  # the specific force at rest, body
    n = su.cfg.nstate
    for row, t in ((0, 1), (1, 0)):  # φ_N with (C δf)_E, φ_E with (C δf)_N; δf = ∇ + S f + M f
        v = np.zeros(P.shape[0])
        v[BA:BA + 3] = C[row]
        if n >= 21:
            v[SA:SA + 3] = C[row] * fb
        if n >= 33:
            for k in range(6):
                v[MA + k] = C[row, MIS_OUT[k]] * fb[MIS_IN[k]]
        k = (P[t] @ v) / (v @ P @ v)  # the tilt's regression on the accelerometer combination: ∓1/g
        assert abs(abs(k) * 9.80665 - 1.0) < 0.01, (row, k)
    if grade == "navigation":
        rph = np.array(euler_from_quat(su.ini.st[ST_Q:ST_Q + 4]))
        err = rph - sim.truth.rph[0]
        err[2] = (err[2] + np.pi) % (2 * np.pi) - np.pi
        assert np.all(sig[:2] < 0.05 * DEG) and sig[2] < 1.0 * DEG, (np.degrees(sig), ev)
        assert np.all(np.abs(err) <= 3.0 * sig), (np.degrees(err), np.degrees(sig))
    else:
        assert sig[2] > 80 * DEG
