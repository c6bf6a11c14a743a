"""GNSS receiver simulation: fix times, lever arm (position and ω×l velocity), noise, outages, latency."""

import numpy as np
import pytest
from scipy import stats

from aidnav.data import Trajectory
from aidnav.nav.earth import E2, OMEGA_IE, A, lla_difference_enu, lla_to_enu
from aidnav.sim.gnss import GnssSpec, simulate_gnss

P = 1e-6
LAT0, LON0, H0 = np.radians(34.2), np.radians(108.9), 400.0


def static_truth(t, heading=0.0, pitch=0.0, roll=0.0):
    n = len(t)
    rph = np.tile([roll, pitch, heading], (n, 1)).astype(float)
    return Trajectory(np.asarray(t, float), np.full(n, LAT0), np.full(n, LON0), np.full(n, H0),
                      np.zeros((n, 3)), rph)


def north_truth(t, w=2e-6, acc=3e-8, c=0.05):
    """Accelerating northward/climbing motion with exactly consistent velocity (analytic)."""
    t = np.asarray(t, float)
    lat = LAT0 + w * t + acc * t**2
    h = H0 + c * t**2
    rm = A * (1 - E2) / (1 - E2 * np.sin(lat) ** 2) ** 1.5
    vel = np.stack([np.zeros_like(t), (rm + h) * (w + 2 * acc * t), 2 * c * t], -1)
    rph = np.tile([0.0, 0.0, 0.0], (len(t), 1))
    return Trajectory(t, lat, np.full(len(t), LON0), h, vel, rph)


def quiet(**kw):
    return GnssSpec(sigma_pos_enu=0.0, sigma_vel_enu=0.0, **kw)


def test_fix_times_from_truth_start():
    t = 100.0 + np.arange(0, 1001) * 0.01
    g = simulate_gnss(static_truth(t), quiet(rate_hz=5.0), np.random.default_rng(0))
    np.testing.assert_allclose(g.time, 100.0 + np.arange(1, 51) / 5.0, rtol=0, atol=1e-12)
    assert g.std_pos.shape == (50, 3) and g.vel.shape == (50, 3)


def test_lever_arm_forward_at_heading_90_is_east():
    t = np.arange(0, 11) * 0.1
    tr = static_truth(t, heading=np.pi / 2)
    g = simulate_gnss(tr, quiet(lever_arm_b=[0.0, 1.0, 0.0]), np.random.default_rng(0))
    e, n, u = lla_to_enu(g.lat, g.lon, g.height, LAT0, LON0, H0)
    np.testing.assert_allclose(e, 1.0, atol=1e-8)
    np.testing.assert_allclose(n, 0.0, atol=1e-8)
    np.testing.assert_allclose(u, 0.0, atol=1e-8)
    np.testing.assert_allclose(g.vel, 0.0, atol=1e-9)


def test_lever_arm_with_pitch_and_roll():
    t = np.arange(0, 11) * 0.1
    # pitch 30° nose up, heading 0: forward axis → (0, cos30, sin30)
    g = simulate_gnss(static_truth(t, pitch=np.radians(30)), quiet(lever_arm_b=[0, 2.0, 0]),
                      np.random.default_rng(0))
    e, n, u = lla_to_enu(g.lat, g.lon, g.height, LAT0, LON0, H0)
    np.testing.assert_allclose(np.c_[e, n, u], np.tile([0, 2 * np.cos(np.radians(30)), 1.0], (len(e), 1)),
                               atol=1e-8)
    # roll 90° right wing down, heading 0: body up axis → East (C_b^n · [0,0,1] = [sin r, 0, cos r])
    g = simulate_gnss(static_truth(t, roll=np.pi / 2), quiet(lever_arm_b=[0, 0, 1.5]),
                      np.random.default_rng(0))
    e, n, u = lla_to_enu(g.lat, g.lon, g.height, LAT0, LON0, H0)
    np.testing.assert_allclose(np.c_[e, n, u], np.tile([1.5, 0, 0], (len(e), 1)), atol=1e-8)


@pytest.mark.parametrize("use_omega", [False, True])
def test_rotating_vehicle_velocity_is_omega_cross_lever(use_omega):
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.005, 0.015, 2000))  # non-uniform truth times
    t -= t[0]
    rate = np.radians(10.0)  # heading rate, clockwise
    hd = np.pi / 2 + rate * t
    tr = static_truth(t)
    tr.rph[:, 2] = hd
    omega = None
    if use_omega:
        # ω_ib^b = ω_nb^b + C_n^b ω_ie^n; heading clockwise → ω_nb^b = [0, 0, -rate]
        w_ie = np.array([0.0, OMEGA_IE * np.cos(LAT0), OMEGA_IE * np.sin(LAT0)])
        c, s = np.cos(hd), np.sin(hd)
        # C_n^b for level attitude: rows of C_b^n transposed; C_b^n = R3(-hd)
        w_ie_b = np.stack([c * w_ie[0] - s * w_ie[1], s * w_ie[0] + c * w_ie[1],
                           np.full_like(t, w_ie[2])], -1)
        omega = w_ie_b + np.array([0.0, 0.0, -rate])
    lev = np.array([0.3, 1.0, 0.2])
    g = simulate_gnss(tr, quiet(rate_hz=2.0, lever_arm_b=lev), np.random.default_rng(0), omega_ib_b=omega)
    hf = np.pi / 2 + rate * g.time
    c, s = np.cos(hf), np.sin(hf)
    wxl = np.cross([0.0, 0.0, -rate], lev)  # ω_nb^b × l, body RFU
    # C_b^n for level attitude, heading hf: x_b → (cos h, -sin h), y_b → (sin h, cos h)
    v_exp = np.stack([c * wxl[0] + s * wxl[1], -s * wxl[0] + c * wxl[1], np.full_like(hf, wxl[2])], -1)
    np.testing.assert_allclose(g.vel, v_exp, atol=1e-6)  # frame of antenna vs IMU: ~1e-7 relative
    assert np.max(np.abs(g.vel[:, :2])) > 0.1  # not trivially zero
    e, n, u = lla_to_enu(g.lat, g.lon, g.height, LAT0, LON0, H0)
    p_exp = np.stack([c * lev[0] + s * lev[1], -s * lev[0] + c * lev[1]], -1)
    np.testing.assert_allclose(np.c_[e, n], p_exp, atol=1e-7)


def test_interpolation_of_moving_truth_and_latency():
    t = np.arange(0, 601) * 0.1  # 10 Hz truth
    tr = north_truth(t)
    lat_s = 0.0537
    g = simulate_gnss(tr, quiet(rate_hz=1.0, latency_s=lat_s), np.random.default_rng(0))
    assert len(g) == 60 and np.isclose(g.time[0], 1.0)
    ref = north_truth(g.time - lat_s)  # the fix tagged t describes t - latency
    de, dn, du = lla_difference_enu(g.lat, g.lon, g.height, ref.lat, ref.lon, ref.height)
    assert np.max(np.abs(np.c_[de, dn, du])) < 1e-5
    np.testing.assert_allclose(g.vel, ref.vel, atol=1e-6)
    assert any("latency" in e for e in g.events)
    # a latency longer than one period drops the first fix and says so
    g2 = simulate_gnss(tr, quiet(rate_hz=1.0, latency_s=1.5), np.random.default_rng(0))
    assert np.isclose(g2.time[0], 2.0) and any("dropped" in e for e in g2.events)


def test_noise_sigma_chi_square():
    t = np.arange(0, 4001) * 1.0
    sp = np.array([1.0, 2.0, 3.0])
    sv = np.array([0.1, 0.2, 0.3])
    g = simulate_gnss(static_truth(t), GnssSpec(rate_hz=1.0, sigma_pos_enu=sp, sigma_vel_enu=sv),
                      np.random.default_rng(123))
    n = len(g)
    de, dn, du = lla_difference_enu(g.lat, g.lon, g.height, LAT0, LON0, H0)
    lo, hi = stats.chi2.ppf(P / 2, n), stats.chi2.isf(P / 2, n)
    ss_p = np.sum((np.c_[de, dn, du] / sp) ** 2, axis=0)
    ss_v = np.sum((g.vel / sv) ** 2, axis=0)
    assert np.all((ss_p > lo) & (ss_p < hi)), ss_p / n
    assert np.all((ss_v > lo) & (ss_v < hi)), ss_v / n
    np.testing.assert_array_equal(g.std_pos, np.tile(sp, (n, 1)))
    np.testing.assert_array_equal(g.std_vel, np.tile(sv, (n, 1)))
    # independent axes: correlation E/N ~ N(0, 1/n)
    r = np.corrcoef(de, dn)[0, 1]
    assert abs(r) < stats.norm.isf(P / 2) / np.sqrt(n)


def test_outages_remove_fixes_and_are_listed():
    t = 50.0 + np.arange(0, 1001) * 0.1  # 100 s
    spec = GnssSpec(rate_hz=1.0, outages=[(10.0, 5.0), (50.0, 20.0)])
    g = simulate_gnss(static_truth(t), spec, np.random.default_rng(7))
    rel = g.time - 50.0
    assert len(g) == 100 - 5 - 20
    assert not np.any((rel >= 10) & (rel < 15)) and not np.any((rel >= 50) & (rel < 70))
    assert np.any(np.isclose(rel, 15.0)) and np.any(np.isclose(rel, 9.0))
    out_ev = [e for e in g.events if "outage" in e]
    assert len(out_ev) == 2 and "5 fix" in out_ev[0] and "20 fix" in out_ev[1]
    # common random numbers: surviving fixes have the same noise as without outages
    g0 = simulate_gnss(static_truth(t), GnssSpec(rate_hz=1.0), np.random.default_rng(7))
    keep = np.isin(np.round(g0.time, 6), np.round(g.time, 6))
    np.testing.assert_array_equal(g0.lat[keep], g.lat)
    np.testing.assert_array_equal(g0.vel[keep], g.vel)


def test_velocity_off_and_reproducible():
    t = np.arange(0, 101) * 0.1
    a = simulate_gnss(static_truth(t), GnssSpec(velocity=False), np.random.default_rng(3))
    b = simulate_gnss(static_truth(t), GnssSpec(velocity=False), np.random.default_rng(3))
    c = simulate_gnss(static_truth(t), GnssSpec(velocity=False), np.random.default_rng(4))
    assert a.vel is None and a.std_vel is None
    np.testing.assert_array_equal(a.lat, b.lat)
    assert not np.array_equal(a.lat, c.lat)


def test_from_config():
    s = GnssSpec.from_config({"rate_hz": 10, "sigma_pos_m": [0.5, 1.0], "sigma_vel_m_s": 0.05,
                              "lever_arm_m": [0.1, 0.2, 1.0], "outages": [{"start_s": 100, "duration_s": 60}],
                              "latency_s": 0.02, "velocity": False})
    assert s.rate_hz == 10 and s.latency_s == 0.02 and s.velocity is False
    np.testing.assert_array_equal(s.sigma_pos_enu, [0.5, 0.5, 1.0])
    np.testing.assert_array_equal(s.sigma_vel_enu, [0.05] * 3)
    np.testing.assert_array_equal(s.lever_arm_b, [0.1, 0.2, 1.0])
    assert s.outages == [(100.0, 60.0)]
    with pytest.raises(ValueError, match="sigma_pos"):
        GnssSpec.from_config({"sigma_pos": 1.0})
    with pytest.raises(ValueError, match="end_s"):
        GnssSpec.from_config({"outages": [{"start_s": 1, "end_s": 2}]})
    d = GnssSpec.from_config({"rate_hz": None})
    assert d.rate_hz == 1.0

    class Model:
        def model_dump(self):
            return {"rate_hz": 5.0, "outages": [], "lever_arm_m": None}

    assert GnssSpec.from_config(Model()).rate_hz == 5.0
