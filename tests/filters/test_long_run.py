"""24-hour run of the loosely coupled filter: numerical health and consistency at the end of a day.

A surface vessel-like trajectory at 10-15 m/s (12 legs of ~2 h, turns of +90°/−60° at 1 deg/s and
speed changes between them), 10 Hz tactical IMU (constant biases 1 deg/h, 100 µg; ARW 0.1 deg/√h;
VRW 0.03 m/s/√h: the filter's own model, random-constant biases with no process noise, so their
covariance shrinks all day) and 1 Hz GNSS position + velocity; exactly 86 400 s.

* ``final_P`` symmetric to 1e-12 relative, positive definite (smallest eigenvalue > 0), and not
  ill-conditioned in the sense that matters for the filter: its correlation matrix
  D^-½ P D^-½ keeps its smallest eigenvalue well above round-off.
* NEES of the 15-state error over the last 4 hours, at 24 epochs 10 minutes apart: each a single
  run's χ²(15) value, held to its two-sided band at 1 − 0.05/24 (Bonferroni: a consistent filter
  fails any of them with probability ≤ 5 %).
* NIS of all 86 400 position and of all velocity fixes: white innovations, so each grand average is
  χ²(3N)/N; band at 1 − 0.01/2 (family 1 %). This checks consistency over the whole day, the last
  hours included.
* Position RMS over the last 4 hours within 20 % of the filter's RMS σ per ENU component (not a
  sharp statistical test: errors are correlated over minutes; it guards against gross divergence).

Measured runtime on the 2-core test machine: ~10 s (truth 2 s, sensors 3 s, filter 3.5 s).
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from aidnav.analysis.consistency import chi2_band, nees
from aidnav.filters.loose import run_loose
from aidnav.filters.tuning import loose_config_from_specs, perturbed_initial_state
from aidnav.sim.gnss import GnssSpec, simulate_gnss
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth

DAY = 86400.0
LAST_EPOCHS = np.arange(DAY - 4 * 3600.0, DAY - 1.0, 600.0)  # 24 epochs over the last 4 h


def _day_scenario():
    segs = []
    for i in range(12):
        segs += [dict(type="straight", duration_s=7065.0),
                 dict(type="turn", angle_deg=90.0 if i % 2 == 0 else -60.0, rate_deg_s=1.0),
                 dict(type="accelerate", duration_s=60.0, to_speed_m_s=15.0 if i % 2 == 0 else 10.0)]
    return parse_scenario(dict(name="day", seed=1, imu_rate_hz=10.0, transition_s=10.0,
                               initial=dict(lat_deg=35.0, lon_deg=120.0, height_m=5.0, speed_m_s=10.0,
                                            heading_deg=20.0),
                               segments=segs))


@pytest.fixture(scope="module")
def day_run(loose_error_state, position_error_m):
    t0 = time.perf_counter()
    truth, imu_true, _ = generate_truth(_day_scenario())
    assert truth.time[-1] == pytest.approx(DAY)
    t1 = time.perf_counter()
    spec = ImuSpec.from_units(gyro_bias_deg_h=1.0, arw_deg_sqrt_h=0.1, accel_bias_ug=100.0,
                              vrw_m_s_sqrt_h=0.03, bias_corr_time_s=np.inf)
    gs = GnssSpec(rate_hz=1.0, sigma_pos_enu=[0.5, 0.5, 1.0], sigma_vel_enu=[0.05, 0.05, 0.1])
    s_imu, s_gnss, s_init = np.random.SeedSequence(86400).spawn(3)
    imu, realised = corrupt_imu(imu_true, spec, np.random.default_rng(s_imu))
    gnss = simulate_gnss(truth, gs, np.random.default_rng(s_gnss))
    lla, vel, rph = perturbed_initial_state(truth, np.random.default_rng(s_init))
    cfg = loose_config_from_specs(spec, gs, init_rph_deg=rph, init_lla_deg_m=lla, init_vel=vel)
    t2 = time.perf_counter()
    res = run_loose(imu, gnss, cfg, cov_times=LAST_EPOCHS)
    t3 = time.perf_counter()
    idx = np.searchsorted(res.time, LAST_EPOCHS)
    assert np.allclose(res.time[idx], LAST_EPOCHS, rtol=0, atol=1e-6)
    err = loose_error_state(res, truth, realised, idx)
    last = res.time >= DAY - 4 * 3600.0
    pos_err, pos_sig = position_error_m(res, truth, np.flatnonzero(last)[::10])
    print(f"\n24-h run: truth {t1 - t0:.1f} s, sensors {t2 - t1:.1f} s, filter {t3 - t2:.1f} s "
          f"({len(imu)} IMU samples, {len(gnss)} fixes)")
    return dict(res=res, err=err, pos_err=pos_err, pos_sig=pos_sig)


def test_final_covariance_symmetric_positive_definite(day_run):
    P = day_run["res"].final_P
    assert P.shape == (15, 15) and np.all(np.isfinite(P))
    assert np.abs(P - P.T).max() <= 1e-12 * np.abs(P).max()
    ev = np.linalg.eigvalsh(0.5 * (P + P.T))
    d = 1.0 / np.sqrt(np.diag(P))
    ev_corr = np.linalg.eigvalsh(P * d[:, None] * d[None, :])
    print(f"\nfinal P: min eigenvalue {ev.min():.3e} (max {ev.max():.3e}); correlation matrix min eigenvalue "
          f"{ev_corr.min():.3f}; gyro bias σ {np.sqrt(np.diag(P)[9:12]) * 180 / np.pi * 3600} deg/h")
    assert ev.min() > 0.0
    assert np.all(np.diag(P) > 0)
    assert ev_corr.min() > 1e-6


def test_nees_in_band_over_the_last_hours(day_run):
    eps = nees(day_run["err"], day_run["res"].cov)
    lo, hi = chi2_band(15, 1, 1.0 - 0.05 / len(LAST_EPOCHS))
    print(f"\nNEES over the last 4 h: {np.round(eps, 1)} (mean {eps.mean():.2f}); "
          f"per-epoch band [{lo:.2f}, {hi:.2f}]")
    assert np.all((eps > lo) & (eps < hi))


def test_nis_over_the_day(day_run):
    rec = day_run["res"].records
    for name in ("pos_nis", "vel_nis"):
        v = rec[name][np.isfinite(rec[name])]
        assert v.size >= 86000
        lo, hi = chi2_band(3, v.size, 1.0 - 0.01 / 2)
        print(f"\n{name}: mean {v.mean():.4f} over {v.size} fixes (band [{lo:.4f}, {hi:.4f}]); "
              f"last 4 h {v[-14400:].mean():.4f}")
        assert lo < v.mean() < hi
    assert np.all(rec["pos_status"] == 1) and np.all(rec["vel_status"] == 1)


def test_position_error_matches_sigma_over_the_last_hours(day_run):
    e, s = day_run["pos_err"], day_run["pos_sig"]
    ratio = np.sqrt((e**2).mean(axis=0) / (s**2).mean(axis=0))
    print(f"\nlast 4 h: position RMS {np.sqrt((e**2).mean(axis=0)).round(3)} m, RMS σ "
          f"{np.sqrt((s**2).mean(axis=0)).round(3)} m, ratio {ratio.round(3)}")
    assert np.all((ratio > 0.8) & (ratio < 1.2))
