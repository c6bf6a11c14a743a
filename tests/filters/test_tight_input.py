"""The tight filter's per-call inputs (:mod:`aidnav.filters.tight_input`, issue 40 session 17) against the
path they replace: the epoch rows written by one kernel into the records' data block must hold what
:func:`aidnav.nav.gnss_sat.satellite_states_epochs` and the numpy row building of main 715bc5d give
(ionosphere, URA, slots, scales, intervals bit for bit; positions, velocities, corrected code and rate and
the TDCP values to round-off since session 18's one Kepler solve a satellite), with and without velocity
records among the epochs; the IMU input's gap test without the median agrees with :func:`imu_gaps`, and a
log with a gap is bridged as :func:`bridge_gaps` does; the in-place compaction of the per-epoch outputs
equals the fancy-indexed copy; the arena hands out independent, aligned arrays and falls back to numpy
when full."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.data import ImuData
from aidnav.filters import measurements as ms
from aidnav.filters.measurements import epoch as ep
from aidnav.filters.preprocess import bridge_gaps, imu_gaps, surely_no_gap
from aidnav.filters.tight import TightConfig
from aidnav.filters.tight_input import (
    Arena,
    epoch_outputs,
    epoch_records,
    epoch_rows,
    imu_input,
    rejected_per_satellite,
)
from aidnav.nav.gnss_sat import E_PRN, E_URA, FREQ_L1, satellite_states_epochs
from aidnav.nav.gnss_types import GnssObservations, GpsEphemerides
from aidnav.sim.gnss_constellation import nominal_constellation

SOW = 345_600.0


def _case(seed=3, M=40, n_gps=8):
    """GPS satellites and their Galileo twins (ids + 100), pseudoranges near the true ranges with gaps, a
    satellite without an ephemeris, Dopplers, L2 codes and phase increments."""
    rng = np.random.default_rng(seed)
    g = nominal_constellation(2381, SOW, n_gps).table.copy()
    g[:, E_URA] = rng.uniform(1.0, 4.0, len(g))
    e = g.copy()
    e[:, E_PRN] += 100
    eph = GpsEphemerides(np.vstack([g, e]), 2381, None, None, [])
    prn = np.r_[np.arange(1, n_gps + 1), np.arange(101, 101 + n_gps), 30]  # PRN 30: no ephemeris
    S = len(prn)
    t = SOW + np.arange(M) * 1.0 + rng.uniform(-1e-4, 1e-4, M)
    code = rng.uniform(2.0e7, 2.5e7, (M, S))
    code[rng.random((M, S)) < 0.2] = np.nan
    dop = rng.normal(0.0, 2000.0, (M, S))
    dop[rng.random((M, S)) < 0.1] = np.nan
    code2 = code + rng.normal(3.0, 0.5, (M, S))
    obs = GnssObservations(t, 2381, prn, code, dop, np.full((M, S), 40.0), code2, "C2W")
    dphi = rng.normal(0.0, 500.0, (M, S))
    dphi[0] = np.nan
    return obs.with_frequencies(eph), eph, dphi


def _reference_rows(obs, eph, g, phase_increments=None):
    """The epoch rows as main 715bc5d built them (tight._epoch_rows: satellite_states_epochs, numpy)."""
    from aidnav.nav.gnss_sat import dual_frequency_iono

    ion = (dual_frequency_iono(obs.time, obs.code1, obs.code2, g.iono_window_s) if g.iono == "dual" else
           np.full(obs.code1.shape, np.nan))
    sp, sv, sc, scr, ura = satellite_states_epochs(np.ascontiguousarray(eph.table, float),
                                                   np.asarray(obs.prn, np.int64), np.asarray(obs.time, float),
                                                   np.ascontiguousarray(obs.code1, float), g.iono != "dual",
                                                   float(g.max_eph_age_s))
    M, S = obs.code1.shape
    rows = np.full((M, S, ep.E_W), np.nan)
    rows[:, :, 0:3], rows[:, :, 3:6] = sp, sv
    rows[:, :, 6] = np.where(np.isfinite(sp[:, :, 0]), obs.code1 + sc, np.nan)
    rows[:, :, 7], rows[:, :, 8], rows[:, :, 9] = obs.range_rate() + scr, ion, ura
    usable = np.isfinite(sp[:, :, 0]).any(axis=0)
    with_eph = np.flatnonzero(usable) if g.range_errors else np.zeros(0, int)
    rows[:, with_eph, 10] = np.arange(len(with_eph))
    letters = np.array([nm[0] for nm in obs.names])
    isb_sys = [c for c in "ECR" if (usable & (letters == c)).any()]
    for k, c in enumerate(isb_sys):
        rows[:, letters == c, 11] = k
    f = obs.frequencies()
    rows[:, :, 12] = np.where(np.isfinite(f), (FREQ_L1 / f) ** 2, 1.0)
    rows[:, :, 13] = np.array([g.system_sigma_factor.get(c, 1.0) for c in letters])
    if phase_increments is not None and M > 1:
        o = ep.E_PHASE
        rows[1:, :, o] = np.where(np.isfinite(sp[1:, :, 0]) & np.isfinite(sp[:-1, :, 0]),
                                  phase_increments[1:] + sc[1:] - sc[:-1], np.nan)
        rows[1:, :, o + 1:o + 4] = sp[:-1]
        rows[1:, :, o + 4] = np.diff(np.asarray(obs.time, float))[:, None]
    no_eph = (np.isfinite(obs.code1) & ~np.isfinite(sp[:, :, 0])).sum(axis=0)
    return rows, with_eph, isb_sys, no_eph


@pytest.mark.parametrize("iono, tdcp, velocity", [("klobuchar", False, False), ("klobuchar", True, True),
                                                  ("dual", True, False), ("none", False, True)])
def test_epoch_rows_are_the_old_paths_bits(iono, tdcp, velocity):
    obs, eph, dphi = _case()
    g = TightConfig(gnss={"iono": iono}).gnss
    M, S = obs.code1.shape
    vf = None
    if velocity:  # velocity records between (and one before, one at) the epochs
        tv = np.r_[obs.time[0] - 0.5, obs.time[:-1] + 0.5, obs.time[5]]
        vf = (tv, np.ones((len(tv), 3)), np.full((len(tv), 3), 0.1))
    arena = Arena(1 << 20)
    rec, sel, at = epoch_records(obs.time, vf, S, arena)
    events = []
    with_eph, isb_sys = epoch_rows(obs, eph, g, events, rec.data, at, dphi if tdcp else None)
    ref, ref_eph, ref_isb, no_eph = _reference_rows(obs, eph, g, dphi if tdcp else None)
    got = rec.data[at].reshape(M, S, ep.E_W)
    assert np.array_equal(np.isnan(got), np.isnan(ref))
    # the satellite states (one Kepler solve a satellite, session 18) differ by round-off: position, the
    # corrected code and the TDCP values within 1e-6 m (an ulp of the transmit time, 6e-11 s at 4e5 s, is
    # 2.3e-7 m of orbit; an ulp of E_k 2.4e-8 m), velocity and rate within 1e-9 m/s; the rest bit for bit
    sat = [0, 1, 2, 6, ep.E_PHASE, ep.E_PHASE + 1, ep.E_PHASE + 2, ep.E_PHASE + 3]
    assert np.nanmax(np.abs(got[:, :, sat] - ref[:, :, sat])) < 1e-6
    assert np.nanmax(np.abs(got[:, :, [3, 4, 5, 7]] - ref[:, :, [3, 4, 5, 7]])) < 1e-9
    rest = np.setdiff1d(np.arange(ep.E_W), sat + [3, 4, 5, 7])
    assert np.array_equal(got[:, :, rest], ref[:, :, rest], equal_nan=True)
    assert np.array_equal(with_eph, ref_eph) and isb_sys == ref_isb == ["E"]
    assert np.array_equal(sel, at) and np.all(rec.model[sel] == ms.M_PR) and np.all(np.diff(rec.t) >= 0)
    assert len(events) == 1 and events[0].startswith(f"G30: {no_eph[-1]} epoch(s)") and no_eph[-1] > 0
    assert np.isfinite(ref[:, :, 0]).sum() > M * (S - 1) // 2  # the case exercises the orbits
    if velocity:
        vel = np.setdiff1d(np.arange(len(rec.t)), sel)
        assert np.all(rec.model[vel] == ms.M_GNSS_VEL) and np.all(rec.data[vel, 0:3] == 1.0)
        assert np.all(np.isnan(rec.data[vel, 6:]))


def test_epoch_outputs_compacted_in_place_equal_the_selection():
    rng = np.random.default_rng(1)
    arena = Arena(1 << 20)
    grp = ep.epoch_out(30, 4, arena.full)
    for k in grp._fields:
        a = getattr(grp, k)
        a[...] = rng.normal(0, 1, a.shape) if a.dtype == float else rng.integers(0, 9, a.shape)
    want = ep.epoch_fields(ep.EpochOut(*[getattr(grp, k).copy() for k in grp._fields]))  # by name, copies
    sel = np.sort(rng.choice(30, 17, replace=False))
    out = epoch_outputs(grp, sel)
    assert isinstance(out, ep.EpochFields)
    for k in out._fields:
        w = getattr(want, k) if k == "flags" else getattr(want, k)[sel]
        assert np.array_equal(getattr(out, k), w), k
    grp2 = ep.epoch_out(30, 4, arena.full)
    grp2.t[:] = np.arange(30.0)
    assert np.array_equal(epoch_outputs(grp2, np.arange(30)).t, np.arange(30.0))  # all: nothing moved


def test_rejected_per_satellite_counts_outside_the_gate():
    nu = np.array([[3.0, np.nan, 1.0], [0.5, 2.0, -4.0]])
    s = np.array([[1.0, 1.0, 1.0], [1.0, np.nan, 1.0]])
    with np.errstate(invalid="ignore"):
        want = (nu**2 > 4.0 * s).sum(axis=0)
    assert np.array_equal(rejected_per_satellite(nu, s, 4.0), want) and want.tolist() == [1, 0, 1]


def test_arena_arrays_are_aligned_disjoint_and_fall_back_to_numpy():
    a = Arena(5 << 20)
    assert a.buf.ctypes.data % (2 << 20) == 0 and a.buf.size == 5 << 20
    x, y = a.full((3, 5), 1.5), a.full(7, 2, np.int64)
    assert x.flags.c_contiguous and x.ctypes.data % 64 == 0 and y.ctypes.data % 64 == 0
    assert np.all(x == 1.5) and np.all(y == 2) and y.dtype == np.int64
    assert not np.shares_memory(x, y) and np.shares_memory(x, a.buf)
    big = a.empty(1 << 20)  # 8 MB: more than is left
    assert big.shape == (1 << 20,) and not np.shares_memory(big, a.buf)


def _imu_log(n, seed, gaps=(), jitter=0.0, dt=0.01):
    """An IMU log of ``n`` samples at ``dt`` (uniform jitter of ± ``jitter`` × dt), with the intervals after
    the samples ``gaps`` (index, length in intervals) lengthened; increments of a phone at rest."""
    rng = np.random.default_rng(seed)
    d = dt * (1.0 + rng.uniform(-jitter, jitter, n))
    for k, m in gaps:
        d[k] = m * dt
    t = 1000.0 + np.cumsum(d)
    dv = np.tile([0.0, 0.0, 9.8 * dt], (n, 1)) + rng.normal(0.0, 1e-4, (n, 3))
    return ImuData(t, rng.normal(0.0, 1e-5, (n, 3)), dv, t0=1000.0)


@pytest.mark.parametrize("seed", range(6))
def test_gap_test_without_the_median_never_misses_a_gap(seed):
    """:func:`surely_no_gap` says "no gap" only where :func:`imu_gaps` (the median rule) finds none: logs
    regular, jittered, with gaps of 4.9-40 intervals, gaps in half the intervals (the median itself moved),
    even and odd lengths; and it says so for the regular and jittered logs without a gap (the fast path)."""
    rng = np.random.default_rng(100 + seed)
    for n in (2, 3, 4, 5, 50, 51, 2000, 2001):
        for jitter in (0.0, 0.2, 0.6):
            cases = [(), ((int(rng.integers(0, n)), 40.0),), ((n // 2, 4.9),), ((n - 1, 5.2),),
                     tuple((k, 3.0) for k in range(0, n, 2)), tuple((k, 12.0) for k in range(0, n, 3))]
            for gaps in cases:
                imu = _imu_log(n, seed, gaps, jitter)
                found = len(imu_gaps(imu)[2]) > 0
                fast = surely_no_gap(imu.time, float(imu.t0), 5.0)
                assert not (fast and found), (n, jitter, gaps)
                if not gaps and jitter < 0.6 and n > 2:  # max/min < 5: the fast path answers
                    assert fast, (n, jitter)


def test_imu_input_with_a_gap_is_bridge_gaps_result():
    """A log with a gap (sensor samples dropped): the tight IMU input (the median computed once, passed to
    :func:`bridge_gaps`) holds bridge_gaps' own increments, bit for bit, and the same events; without a gap
    the log's arrays themselves."""
    cfg = TightConfig()
    for gaps in (((700, 30.0),), ()):
        imu = _imu_log(2000, 7, gaps, 0.05)
        ev_ref, ev = [], []
        dth, dv, _ = bridge_gaps(imu, ev_ref)
        got = imu_input(imu, cfg, imu.time, 0, None, ev, None, Arena(1 << 20))
        assert np.array_equal(got.dth, dth) and np.array_equal(got.dv, dv) and ev == ev_ref
        assert np.array_equal(got.t, imu.time) and np.all(got.gap_var == 0.0)
        if gaps:
            assert len(ev) == 1 and "IMU gap" in ev[0] and not np.array_equal(got.dth, imu.dtheta)
        else:
            assert got.dth is imu.dtheta or np.shares_memory(got.dth, imu.dtheta)


@pytest.mark.parametrize("seed", range(4))
def test_record_order_is_numpys_stable_merge(seed):
    """The records' time order of one kernel call (session 18) equals the numpy expressions it replaced:
    velocity records with a NaN time, velocity or σ dropped, a stable argsort of epochs then velocity
    records (ties with epochs and among velocity records kept in that order), the row of each record."""
    from aidnav.filters.tight_input import _record_order

    rng = np.random.default_rng(seed)
    M, K = 60, 70
    t_obs = np.sort(rng.choice(np.arange(100.0), M, replace=False))
    tv = np.r_[rng.choice(t_obs, 10), np.round(rng.uniform(-5.0, 105.0, K - 10), 1)]  # ties with epochs
    tv[rng.integers(0, K, 3)] = tv[0]  # ties among velocity records
    vv, sv = rng.normal(0.0, 1.0, (K, 3)), rng.uniform(0.1, 1.0, (K, 3))
    tv[5], vv[7, 1], sv[9, 2] = np.nan, np.nan, np.inf
    ok = np.isfinite(tv) & np.isfinite(vv).all(axis=1) & np.isfinite(sv).all(axis=1)
    t_all = np.concatenate([t_obs, tv[ok]])
    order = np.argsort(t_all, kind="stable")
    model = np.concatenate([np.full(M, 1, np.int64), np.full(ok.sum(), 2, np.int64)])[order]
    at = np.empty(len(t_all), np.int64)
    at[order] = np.arange(len(t_all))
    t, mod, at2, keep = _record_order(t_obs, tv, vv, sv, 1, 2)
    assert np.array_equal(keep, np.flatnonzero(ok)) and np.array_equal(t, t_all[order])
    assert np.array_equal(mod, model) and np.array_equal(at2, at)
