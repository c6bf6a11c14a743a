"""Issue 35 ("a σ you can bet on"), items 3–5: the covariance an IMU gap adds (position included, bounded
by what the vehicle can do), the heading held unknown after a gap until a GNSS course re-aligns it,
correlated GNSS errors by default above 1 Hz, and the calibration states grown with the navigation block
by a re-initialisation. Unit checks with closed forms; the simulated-car regressions are in
``test_issue35_regressions.py``."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.data import GnssData, ImuData
from aidnav.filters.config import LooseConfig, MotionBounds
from aidnav.filters.preprocess import (
    GAP_HEADING,
    GAP_POS,
    GAP_TILT,
    GAP_VEL,
    GNSS_ERROR_TAU_S,
    bridge_gaps,
    correlated_gnss_errors,
)
from aidnav.filters.reinit import inflate, inflate_nav
from aidnav.units import DEG


def _imu_with_gap(rate_deg_s=5.0, gap_s=30.0):
    """100 Hz, level, turning at ``rate_deg_s`` about up, a dropped-sample gap of ``gap_s`` at 10 s."""
    dt = 0.01
    t = np.arange(1, 3001) * dt
    t = np.where(t > 10.0, t + gap_s - dt, t)
    n = len(t)
    dth = np.tile([0.0, 0.0, rate_deg_s * DEG * dt], (n, 1))
    dv = np.tile([0.0, 0.0, 9.8 * dt], (n, 1))
    return ImuData(t, dth, dv, t0=0.0)


CAR = MotionBounds(max_speed_m_s=70.0, max_accel_m_s2=10.0, max_turn_rate_deg_s=60.0, max_tilt_deg=10.0)


@pytest.mark.parametrize("bounds", [MotionBounds(), CAR])
def test_gap_variance_from_the_vehicle_bounds(bounds):
    """The closed forms of bridge_gaps: σ_a² = spread² + a_max²/3 (spread floored at 0.05 m/s²), velocity
    σ_a T capped at v_max, position σ_a T²/2 capped at v_max T; heading σ_ω T capped at π with
    σ_ω² = ω̄²/3 + spread² + ω_max²/3; roll/pitch capped at the tilt bound / √3."""
    imu = _imu_with_gap(5.0, 30.0)
    events = []
    _, _, gv = bridge_gaps(imu, events, bounds=bounds)
    k = np.flatnonzero(gv[:, GAP_POS])
    assert len(k) == 1 and len(events) == 1
    T = imu.time[k[0]] - imu.time[k[0] - 1]
    s_a = np.sqrt(0.05 ** 2 + bounds.max_accel_m_s2 ** 2 / 3.0)
    assert gv[k[0], GAP_VEL] == pytest.approx(min(s_a * T, bounds.max_speed_m_s) ** 2)
    assert gv[k[0], GAP_POS] == pytest.approx(min(0.5 * s_a * T * T, bounds.max_speed_m_s * T) ** 2)
    s_w = np.sqrt((5.0 * DEG) ** 2 / 3.0 + (bounds.max_turn_rate_deg_s * DEG) ** 2 / 3.0)
    assert gv[k[0], GAP_HEADING] == pytest.approx(min(s_w * T, np.pi) ** 2, rel=1e-3)
    assert gv[k[0], GAP_TILT] == pytest.approx((bounds.max_tilt_deg * DEG) ** 2 / 3.0, rel=1e-3)
    assert np.count_nonzero(gv) == 4  # only the sample after the gap


def test_short_gap_adds_little():
    """A 0.1-s gap of a car: position σ of centimetres, heading σ of a few degrees (no hold)."""
    car = CAR
    _, _, gv = bridge_gaps(_imu_with_gap(0.0, 0.1), [], bounds=car)
    k = np.flatnonzero(gv[:, GAP_POS])[0]
    assert np.sqrt(gv[k, GAP_POS]) < 0.06
    assert np.degrees(np.sqrt(gv[k, GAP_HEADING])) < car.max_turn_rate_deg_s * 0.11 / np.sqrt(3.0) + 0.1
    assert np.degrees(np.sqrt(gv[k, GAP_HEADING])) < LooseConfig().motion.heading_hold_deg


def _fixes(rate_hz, n=100, sigma=0.3):
    t = np.arange(n) / rate_hz
    z = np.zeros(n)
    return GnssData(t, z + 0.7, z + 2.0, z + 50.0, std_pos=np.full((n, 3), sigma))


def test_correlated_gnss_errors_by_default_above_1_hz():
    ev = []
    cfg = correlated_gnss_errors(LooseConfig(), _fixes(10.0), ev)
    assert cfg.gnss.error_tau_s == GNSS_ERROR_TAU_S
    assert cfg.gnss.error_sigma_m == pytest.approx((0.3, 0.3, 0.3))  # the fixes' median σ
    # carrier-phase fixes (σ of centimetres, floored at gnss.min_pos_std_m 0.05 m): white
    assert correlated_gnss_errors(LooseConfig(), _fixes(10.0, sigma=0.02), []).gnss.error_tau_s == 0.0
    assert "correlated" in ev[0]
    ev = []
    assert correlated_gnss_errors(LooseConfig(), _fixes(1.0), ev).gnss.error_tau_s == 0.0
    assert "white" in ev[0]
    stated = LooseConfig.model_validate({"gnss": {"error_tau_s": 0.0}})
    assert correlated_gnss_errors(stated, _fixes(10.0), []).gnss.error_tau_s == 0.0


def test_reinitialisation_grows_the_calibration_states_up_to_their_prior():
    """A time-offset state (index 15) that converged (σ 1 ms) with a wrong value: the re-initialisation
    scales it with the navigation block, by at most back to its prior (0.2 s)²; inflate_nav leaves it."""
    n = 16
    P = np.diag(np.r_[np.full(3, 1e-6), np.full(3, 1e-4), np.full(3, 1e-12), np.full(6, 1e-8), 1e-6])
    H = np.zeros((3, n))
    H[:, 3:6] = np.eye(3)
    H[:, 15] = [5.0, 0.0, 0.0]  # a velocity innovation that sees the offset through the acceleration
    R = np.eye(3) * 1e-4
    z = np.array([3.0, 0.0, 0.0])
    x = np.zeros(n)
    Pn, Pc = P.copy(), P.copy()
    a = inflate_nav(x, Pn, H, R, z)
    b = inflate(x, Pc, H, R, z, np.array([[15.0, 0.2 ** 2]]))
    assert a > 1.0 and b > 1.0
    assert Pn[15, 15] == P[15, 15]
    assert P[15, 15] < Pc[15, 15] <= 0.2 ** 2 * (1 + 1e-12)
    S = H @ Pc @ H.T + R
    assert z @ np.linalg.solve(S, z) == pytest.approx(3.0, rel=1e-6)  # consistent after the repair
    assert np.all(np.linalg.eigvalsh(Pc) > 0)
