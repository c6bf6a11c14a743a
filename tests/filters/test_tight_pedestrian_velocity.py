"""Issue 40: the tight filter's velocity σ while walking, against a simulated pedestrian's truth
(:mod:`aidnav.sim.pedestrian`: speed 1.3 ± 0.2 m/s at 1.9 steps/s, a bounce, turns; the consumer IMU
grade; GPS + Galileo at 4 Hz with a carrier phase of σ 5 mm), scored as the walk is: the estimate's mean
velocity over each GNSS interval against the truth's (``benchmarks/pedestrian_velocity.py`` prints the
figures)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from aidnav.analysis.velocity_reference import interval_velocity_errors
from aidnav.data import ImuData

#: walking seconds scored (the walk's 100 s less a second at each end): at most one independent velocity
#: error per second is assumed for the χ² bounds (the filter's error is correlated over its records)
N_INDEPENDENT = 98


def _walking_errors(res, run):
    """(interval errors (K, 3), the filter's velocity σ at their middles (K, 3)) while walking."""
    from aidnav.filters.tight import to_trajectory  # lazy: as the module's other imports

    tr = to_trajectory(res)
    t = run.obs.time
    lat, lon, h = (np.interp(t, run.truth.time, a) for a in (run.truth.lat, run.truth.lon, run.truth.height))
    iv = interval_velocity_errors(res.time, res.state[:, 3:6], t, lat, lon, h)
    mid = 0.5 * (iv.t_start + iv.t_end)
    walk = (iv.t_start >= run.walk[0] + 1.0) & (iv.t_end <= run.walk[1] - 1.0)
    sv = np.column_stack([np.interp(mid, tr.time, tr.std_vel[:, i]) for i in range(3)])
    return iv.err[walk], sv[walk]


@pytest.fixture(scope="module")
def pedestrian():
    from aidnav.sim.pedestrian import simulate_pedestrian

    return simulate_pedestrian(0)


def test_the_pedestrian_walks_at_the_step_frequency(pedestrian):
    """Known answers of the motion: mean speed 1.3 m/s, swinging ±0.2 m/s (less the smoothing of the
    acceleration's edges) with its strongest line at 1.9 Hz, at rest at both ends."""
    tr, (w0, w1) = pedestrian.truth, pedestrian.walk
    m = (tr.time > w0 + 1.0) & (tr.time < w1 - 1.0)
    sp = np.hypot(tr.vel[m, 0], tr.vel[m, 1])
    assert sp.mean() == pytest.approx(1.3, abs=0.01)
    assert 0.15 < 0.5 * (sp.max() - sp.min()) <= 0.2
    f = np.fft.rfftfreq(sp.size, np.median(np.diff(tr.time)))
    spec = np.abs(np.fft.rfft(sp - sp.mean()))
    assert f[np.argmax(spec)] == pytest.approx(1.9, abs=0.05)
    assert np.abs(tr.vel[0]).max() < 1e-9 and np.abs(tr.vel[-1]).max() < 1e-6


def test_simulated_tdcp_velocities_are_consistent_with_their_sigma(pedestrian):
    """The TDCP least squares of the simulated phase against the truth's mean velocity over each interval:
    NEES per axis inside its two-sided 99.8 % χ² band (the phase is white of the σ the least squares
    assumes; an increment's error correlates −½ with the next one's, which leaves the mean NEES 1)."""
    from aidnav.estimators.tdcp import tdcp_series
    from aidnav.nav.earth import lla_to_ecef, lla_to_enu

    run = pedestrian
    t = run.obs.time
    lat, lon, h = (np.interp(t, run.truth.time, a) for a in (run.truth.lat, run.truth.lon, run.truth.height))
    r = tdcp_series(run.obs, run.eph, np.column_stack(lla_to_ecef(lat, lon, h)), variance_factor=False)
    p = np.column_stack(lla_to_enu(lat, lon, h, lat[0], lon[0], h[0]))
    err = r["vel_enu"] - np.diff(p, axis=0) / np.diff(t)[:, None]
    sd = np.sqrt(np.einsum("kii->ki", r["vel_cov_enu"]))
    ok = np.isfinite(err[:, 0])
    n = int(ok.sum())
    nees = np.mean((err[ok] / sd[ok]) ** 2, axis=0)
    # consecutive increments share a phase: about n/2 independent ones (a wider band than n's)
    lo, hi = chi2.ppf([0.001, 0.999], n // 2) / (n // 2)
    assert n > 500
    assert np.all((nees > lo) & (nees < hi)), (nees, lo, hi)


def _run(run, smooth, **gnss):
    from aidnav.estimators.tight_solution import process_tight
    from aidnav.filters.tight import TightConfig

    cfg = TightConfig(gnss=gnss) if gnss else TightConfig()
    return process_tight(run.imu, run.obs, run.eph, cfg, smooth=smooth)[0]


def _late(run, late_s):
    """The run with the IMU's stamps ``late_s`` late (an IMU-GNSS time offset of −``late_s``)."""
    return type(run)(run.truth, ImuData(run.imu.time + late_s, run.imu.dtheta, run.imu.dv,
                                        t0=run.imu.t0 + late_s), run.obs, run.eph, run.walk)


def _honest(e, s) -> bool:
    """Coverage ≥ 95 % per axis and mean (e/σ)² below the 99.9 % χ² quantile of N_INDEPENDENT errors."""
    cover = np.mean(np.abs(e) <= 3 * s, axis=0)
    nees = np.mean((e / s) ** 2, axis=0)
    return bool(np.all(cover >= 0.95) and np.all(nees < chi2.ppf(0.999, N_INDEPENDENT) / N_INDEPENDENT))


@pytest.mark.parametrize("smooth", [False, True])
@pytest.mark.parametrize("late_s", [0.0, 0.025])
def test_tight_velocity_sigma_is_honest_while_walking(pedestrian, smooth, late_s):
    """``aidnav tight``'s solution, no configuration, with the IMU's stamps on time and 25 ms late: while
    walking the interval velocity errors are inside 3σ at ≥ 95 % per axis and their mean (e/σ)² is below
    the 99.9 % χ² quantile of :data:`N_INDEPENDENT` independent errors (forward and smoothed)."""
    run = _late(pedestrian, late_s)
    e, s = _walking_errors(_run(run, smooth), run)
    assert len(e) > 350
    assert _honest(e, s), (np.mean(np.abs(e) <= 3 * s, axis=0), np.mean((e / s) ** 2, axis=0))


def test_an_unmodelled_imu_gnss_time_offset_makes_the_walking_velocity_sigma_optimistic(pedestrian):
    """The same check fails for the cause the walk shows: without the time offset from the phase
    (``gnss.time_offset_from_phase`` off) the IMU's stamps 25 ms late leave the smoothed velocity error ≈
    a·δt at every step while its σ averages the records down: mean (e/σ)² far above the χ² bound,
    coverage below 95 %."""
    run = _late(pedestrian, 0.025)
    e, s = _walking_errors(_run(run, True, time_offset_from_phase=False), run)
    nees = np.mean((e / s) ** 2, axis=0)
    assert np.all(nees > 2.0 * chi2.ppf(0.999, N_INDEPENDENT) / N_INDEPENDENT), nees
    assert np.all(np.mean(np.abs(e) <= 3 * s, axis=0) < 0.95)


@pytest.mark.parametrize("late_s", [0.0, 0.025, -0.05])
def test_the_time_offset_from_the_specific_force_norm_recovers_a_known_shift(pedestrian, late_s):
    """:func:`aidnav.estimators.tdcp.imu_time_offset` on the pedestrian: −late within 3σ, σ < 10 ms."""
    from aidnav.estimators.dgps import spp_series
    from aidnav.estimators.tdcp import imu_time_offset, tdcp_series
    from aidnav.nav.earth import gravity

    run = _late(pedestrian, late_s)
    r = tdcp_series(run.obs, run.eph, spp_series(run.obs, run.eph)["ecef"])
    d, sd, n = imu_time_offset(run.imu, run.obs.time, r["vel_enu"], gravity(np.radians(40.0), 50.0))
    assert n > 400 and sd < 0.010
    assert abs(d + late_s) < 3 * sd, (d, sd)
