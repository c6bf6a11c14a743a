"""Issue 40, session 18: the IMU-GNSS time offset (:func:`aidnav.estimators.tdcp.imu_time_offset`) with the
epochs the TDCP velocities' covariance states noisier than the median down-weighted (``vel_cov``) — a few
intervals solved from a few satellites must not spoil the estimate nor its σ."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from aidnav.estimators.tdcp import imu_time_offset, slope_variance_ma

from .test_tdcp import _bounce_imu  # the closed-form bounce (A = 3 cm, f = 1.9 Hz)

D_TRUE = 0.025  # the IMU's stamps are 25 ms late: the offset to add is −25 ms
DT = 0.25


def _draw(seed, t_e, z, bad_sigma_m):
    """One draw of TDCP mean velocities of the bounce: white noise of 7 mm on each epoch's height (each
    interval's displacement σ ≈ 1 cm) and, on a random 2 % of the intervals, an extra displacement error
    that makes that interval's σ ``bad_sigma_m`` (an interval solved from a few satellites); the covariance
    states both (1 cm, or ``bad_sigma_m``, over Δ)."""
    rng = np.random.default_rng([seed, 18])
    n = t_e.size - 1
    bad = rng.random(n) < 0.02
    sig = np.where(bad, bad_sigma_m, 0.0099)
    extra = rng.normal(0.0, 1.0, n) * np.sqrt(sig ** 2 - 0.0099 ** 2)
    h = z(t_e) + rng.normal(0.0, 0.007, t_e.size)
    vel = np.zeros((n, 3))
    vel[:, 2] = (np.diff(h) + extra) / DT
    cov = np.zeros((n, 3, 3))
    cov[:, 0, 0] = cov[:, 1, 1] = 1e-4
    cov[:, 2, 2] = (sig / DT) ** 2
    return vel, cov


def test_imu_time_offset_weighted_by_the_tdcp_covariance_is_honest_and_not_spoilt():
    """48 draws of the bounce with 2 % of the intervals 30× noisier (σ 30 cm, as the simulated pedestrian's
    intervals left with 5 of 17 satellites, whose vertical acceleration σ is ~5× the others'), stated in
    ``vel_cov``. Weighted: the normalised errors' mean square inside the two-sided 99 % χ²(48) band
    (0.55–1.60), ≥ 95 % within 3σ, and the σ no more than 1.2× the σ of the same draws without the bad
    intervals (they remove ~4 % of the information, each spoiling two accelerations: 1/√0.96 ≈ 1.02).
    Unweighted (``vel_cov`` None) the bad intervals dominate: σ ≈ 3× (measured 6.8 against 2.3 ms) — the
    contrast asserted too, so that the weights cannot silently fall off."""
    imu, z = _bounce_imu(D_TRUE, 40.0)
    t_e = np.arange(1.0, 39.0, DT)
    zs, sig_w, sig_ref, sig_u = [], [], [], []
    for seed in range(48):
        vel, cov = _draw(seed, t_e, z, 0.30)
        d, sd, _ = imu_time_offset(imu, t_e, vel, 9.80, max_lag_s=0.1, vel_cov=cov)
        zs.append((d + D_TRUE) / sd)
        sig_w.append(sd)
        sig_u.append(imu_time_offset(imu, t_e, vel, 9.80, max_lag_s=0.1)[1])
        vel0, cov0 = _draw(seed, t_e, z, 0.0099)  # the same draws, every interval good
        sig_ref.append(imu_time_offset(imu, t_e, vel0, 9.80, max_lag_s=0.1, vel_cov=cov0)[1])
    zs = np.array(zs)
    lo, hi = chi2.ppf([0.005, 0.995], zs.size) / zs.size
    assert lo < np.mean(zs ** 2) < hi, np.mean(zs ** 2)
    assert np.mean(np.abs(zs) <= 3.0) >= 0.95
    rms = lambda v: np.sqrt(np.mean(np.square(v)))  # noqa: E731
    assert rms(sig_w) <= 1.2 * rms(sig_ref), (rms(sig_w), rms(sig_ref))
    assert rms(sig_u) >= 2.0 * rms(sig_ref), (rms(sig_u), rms(sig_ref))


def test_imu_time_offset_equal_weights_change_nothing():
    """A covariance that is the same at every epoch (at any scale) weighs every epoch alike: the estimate and
    σ of the unweighted fit (every weight min(1, median/itself) = 1)."""
    imu, z = _bounce_imu(D_TRUE, 40.0)
    t_e = np.arange(1.0, 39.0, DT)
    vel, _ = _draw(3, t_e, z, 0.0099)
    cov = np.broadcast_to(np.diag([1e-4, 1e-4, 4e-3]), (t_e.size - 1, 3, 3))
    d_u, s_u, n_u = imu_time_offset(imu, t_e, vel, 9.80, max_lag_s=0.1)
    d_w, s_w, n_w = imu_time_offset(imu, t_e, vel, 9.80, max_lag_s=0.1, vel_cov=17.0 * cov)
    assert n_w == n_u
    assert d_w == pytest.approx(d_u, abs=1e-12)
    assert s_w == pytest.approx(s_u, rel=1e-9)


def test_slope_variance_ma_with_weights_by_hand():
    """Closed form, by hand: x = (1, −1, 2), e = (1, 2, −1) at epochs (0, 1, 2), w = (2, 1, 1): wxe =
    (2, −2, −2), Σwx² = 2 + 1 + 4 = 7. Order 0: (4 + 4 + 4)/49 = 12/49; order 1: + 2·(2·(−2) + (−2)(−2)) = 0
    → 12/49; order 2: + 2·(2·(−2)) = −8 → 4/49, floored at the white 12/49. w = 1 gives the unweighted
    value."""
    x, e, idx = np.array([1.0, -1.0, 2.0]), np.array([1.0, 2.0, -1.0]), np.array([0, 1, 2])
    w = np.array([2.0, 1.0, 1.0])
    assert slope_variance_ma(x, e, idx, 0, w) == pytest.approx(12 / 49)
    assert slope_variance_ma(x, e, idx, 1, w) == pytest.approx(12 / 49)
    assert slope_variance_ma(x, e, idx, 2, w) == pytest.approx(12 / 49)
    x2, w2 = np.array([1.0, 1.0]), np.array([3.0, 1.0])  # wxe = (3, 1) at (0, 1), Σwx² = 4: (9 + 1 + 6)/16
    assert slope_variance_ma(x2, np.array([1.0, 1.0]), np.array([0, 1]), 1, w2) == pytest.approx(1.0)
    assert slope_variance_ma(x, e, idx, 1, np.ones(3)) == pytest.approx(slope_variance_ma(x, e, idx, 1))
