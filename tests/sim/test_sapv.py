"""SAPV antenna model (seed 000): true angles, tracking error statistics, losses and their flags."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.nav.geo_pointing import R_GEO_SEED000, geo_sat_ecef, pointing_az_el
from aidnav.nav.rotations import dcm_from_euler
from aidnav.sim import sapv as sp
from aidnav.sim.scenario import Scenario
from aidnav.sim.trajectory import generate_truth

D = np.pi / 180.0


def _truth(segments, heading=100.0, rate=50.0, speed=0.0):
    scn = Scenario.model_validate(dict(
        name="t", initial=dict(lat_deg=39.0, lon_deg=116.0, height_m=0.0, heading_deg=heading,
                               speed_m_s=speed), imu_rate_hz=rate, transition_s=1.0, segments=segments))
    return generate_truth(scn)[0]


@pytest.fixture(scope="module")
def static_truth():
    return _truth([dict(type="static", duration_s=400.0)])


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def test_true_angles_and_noise_free_output(static_truth):
    spec = sp.SapvSpec(sigma_deg=0.0, sat_lon_deg=138.0, sat_radius_m=R_GEO_SEED000)
    d = sp.simulate_sapv(static_truth, spec, np.random.default_rng(0))
    assert len(d) == 400 and np.allclose(d.time, np.arange(1, 401))
    C = dcm_from_euler(*static_truth.rph[0])
    az, el = pointing_az_el(39 * D, 116 * D, 0.0, C, geo_sat_ecef(138 * D, R_GEO_SEED000))
    np.testing.assert_allclose(d.az, az, atol=1e-12)
    np.testing.assert_allclose(d.el, el, atol=1e-12)
    assert np.degrees(az) == pytest.approx(47.277, abs=1e-3)
    assert np.degrees(el) == pytest.approx(39.413, abs=1e-3)
    assert d.valid.all() and (d.reason == sp.OK).all()
    np.testing.assert_allclose(d.sat_ecef, geo_sat_ecef(138 * D, R_GEO_SEED000))
    np.testing.assert_allclose(d.sigma, 0.0)


def test_white_tracking_error_statistics(static_truth):
    """σ = 0.05° per axis: sample std inside its χ² 99.9 % interval, mean within 4 standard errors."""
    from scipy.stats import chi2

    spec = sp.SapvSpec(rate_hz=10.0, sigma_deg=(0.05, 0.08), sat_lon_deg=138.0)
    d = sp.simulate_sapv(static_truth, spec, np.random.default_rng(1))
    n = len(d)
    for i, (meas, true, s) in enumerate(((d.az, d.az_true, 0.05), (d.el, d.el_true, 0.08))):
        e = (_wrap(meas - true) if i == 0 else meas - true) / D
        lo, hi = chi2.ppf([0.0005, 0.9995], n - 1) / (n - 1)
        assert lo <= np.var(e, ddof=1) / s**2 <= hi
        assert abs(np.mean(e)) < 4 * s / np.sqrt(n)
    assert np.all((d.az >= 0) & (d.az < 2 * np.pi))
    np.testing.assert_allclose(d.sigma, np.array([0.05, 0.08]) * D)


def test_gauss_markov_bias(static_truth):
    """Stationary σ and lag-τ autocorrelation e⁻¹ of the slowly varying tracking bias."""
    spec = sp.SapvSpec(rate_hz=10.0, sigma_deg=0.0, bias_sigma_deg=(0.02, 0.03), bias_tau_s=5.0)
    b = sp.simulate_sapv(static_truth, spec, np.random.default_rng(2)).bias / D
    n = len(b)
    lag = 50  # τ at 10 Hz
    for i, s in enumerate((0.02, 0.03)):
        x = b[:, i]
        # ~n/(2τ·rate) = 400 effective samples: σ within ±15 %, ρ(τ) within ±0.12
        assert np.std(x) == pytest.approx(s, rel=0.15)
        rho = np.corrcoef(x[:-lag], x[lag:])[0, 1]
        assert rho == pytest.approx(np.exp(-1.0), abs=0.12)
    assert n == 4000


def test_blockage_mask_and_reacquisition(static_truth):
    spec = sp.SapvSpec(blockages=[(100.0, 50.0), {"start_s": 300.0, "duration_s": 10.0}], reacquire_s=5.0)
    d = sp.simulate_sapv(static_truth, spec, np.random.default_rng(3))
    blk = (d.time >= 100) & (d.time < 150) | (d.time >= 300) & (d.time < 310)
    assert (d.reason[blk] == sp.BLOCKED).all() and np.isnan(d.az[blk]).all() and np.isnan(d.el[blk]).all()
    reacq = (d.time >= 150) & (d.time < 155) | (d.time >= 310) & (d.time < 315)
    assert (d.reason[reacq] == sp.REACQUIRING).all()
    assert d.valid[~(blk | reacq)].all() and not d.valid[blk | reacq].any()
    assert any("blockage" in e for e in d.events)
    # the surviving epochs carry the same errors whatever the losses (noise drawn before the losses)
    ref = sp.simulate_sapv(static_truth, sp.SapvSpec(), np.random.default_rng(3))
    ok = d.valid
    np.testing.assert_array_equal(d.az[ok], ref.az[ok])
    # elevation mask above the satellite's elevation: nothing tracked
    low = sp.simulate_sapv(static_truth, sp.SapvSpec(elevation_mask_deg=45.0), np.random.default_rng(3))
    assert (low.reason == sp.LOW_ELEVATION).all() and not low.valid.any()
    # with_loss marks a window lost after the fact
    lost = ref.with_loss(200.0, 260.0)
    w = (ref.time >= 200) & (ref.time < 260)
    assert (lost.reason[w] == sp.BLOCKED).all() and lost.valid[~w].all() and np.isnan(lost.az[w]).all()


def test_body_rate_limit_on_a_turn():
    truth = _truth([dict(type="straight", duration_s=20.0),
                    dict(type="turn", angle_deg=180.0, rate_deg_s=15.0),
                    dict(type="straight", duration_s=20.0)], heading=0.0, speed=5.0)
    # a slow vehicle turning at 15 deg/s (12 s): the tracking loop (10 deg/s limit) loses the satellite
    spec = sp.SapvSpec(rate_hz=5.0, max_body_rate_deg_s=10.0)
    d = sp.simulate_sapv(truth, spec, np.random.default_rng(4))
    fast = d.reason == sp.BODY_RATE
    assert fast.any() and (d.time[fast] > 19.0).all() and (d.time[fast] < 34.0).all()  # 1-s transitions
    assert d.valid[d.time < 19.0].all() and d.valid[d.time > 34.0].all()
    # the azimuth follows the heading change (180° turn: az changes by 180° mod 360)
    a0, a1 = d.az_true[d.time < 19.0][0], d.az_true[d.time > 35.0][-1]
    assert abs(abs(_wrap(a1 - a0)) - np.pi) < 2 * D


def test_spec_validation():
    with pytest.raises(ValueError, match="rate_hz"):
        sp.SapvSpec(rate_hz=0.0)
    with pytest.raises(ValueError, match="bias_tau_s"):
        sp.SapvSpec(bias_sigma_deg=0.01, bias_tau_s=0.0)
    with pytest.raises(ValueError, match="sigma_deg"):
        sp.SapvSpec(sigma_deg=(0.1, 0.1, 0.1))
    with pytest.raises(ValueError, match="unknown key"):
        sp.SapvSpec(blockages=[{"start": 1.0, "duration_s": 2.0}])
    with pytest.raises(ValueError, match="radius"):
        sp.SapvSpec(sat_radius_m=3.5785e7 - 4e7)
