"""Time-differenced carrier phase (issue 40): cycle slips from the loss-of-lock indicator and the
phase-Doppler test, the displacement least squares against a closed-form geometry, its χ² consistency, and
the walk (an injected slip is caught; TDCP velocity against the RTK solution)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from aidnav.estimators.tdcp import phase_increments, tdcp_displacement
from aidnav.nav.gnss_sat import LAMBDA_L1, geo_range

R0 = np.array([-1276965.0, -4717231.0, 4087230.0])  # the walk's approximate position


def _geometry(rng, n=7):
    """Satellites ~20 200 km above R0 in random directions above 15° elevation, moving ~3.9 km/s."""
    up = R0 / np.linalg.norm(R0)
    sats, vel = [], []
    while len(sats) < n:
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        if d @ up < np.sin(np.radians(15)):
            continue
        sats.append(R0 + 2.2e7 * d)
        vel.append(np.cross(d, rng.normal(size=3)) * 3900.0 / np.linalg.norm(np.cross(d, rng.normal(size=3))))
    return np.array(sats), np.array(vel)


def test_displacement_closed_form_and_chi_square_consistency():
    rng = np.random.default_rng(4)
    sats0, vel = _geometry(rng)
    sats1 = sats0 + 0.25 * vel
    dr_true, db_true = np.array([0.31, -0.12, 0.05]), -18.0
    r1 = R0 + dr_true
    y = np.array([geo_range(sats1[j], r1)[0] - geo_range(sats0[j], R0)[0] for j in range(len(sats0))])
    y += db_true
    # exact data: exact answer up to the linearisation about the prior (|Δr| · angle ≈ sub-mm)
    x, cov, used = tdcp_displacement(sats0, sats1, R0 + rng.normal(0, 5.0, 3), y)
    assert used.all()
    assert np.allclose(x[:3], dr_true, atol=1e-3) and abs(x[3] - db_true) < 1e-3
    # phase noise σ 5 mm per epoch: NEES of (Δr, Δb) over 300 draws within the χ²(4·300) 99.9 % band
    s = 0.005
    nees = 0.0
    for _ in range(300):
        yn = y + rng.normal(0, s, len(y)) - rng.normal(0, s, len(y))
        x, cov, _ = tdcp_displacement(sats0, sats1, R0, yn, s)
        e = x - np.r_[dr_true, db_true]
        nees += e @ np.linalg.solve(cov, e)
    assert chi2.ppf(5e-4, 1200) < nees < chi2.ppf(1 - 5e-4, 1200)
    # fewer than four satellites: no solution
    assert tdcp_displacement(sats0[:3], sats1[:3], R0, y[:3]) is None


def test_displacement_per_satellite_sigma_is_weighted_least_squares_and_consistent():
    """σ per satellite (7 satellites, σ 3–30 mm): NEES of (Δr, Δb) over 300 draws within the χ²(4·300)
    99.9 % band, and one satellite of σ 10⁶× the others' gives the solution without it."""
    rng = np.random.default_rng(5)
    sats0, vel = _geometry(rng)
    sats1 = sats0 + 0.25 * vel
    dr_true, db_true = np.array([-0.2, 0.4, 0.01]), 3.0
    y = np.array([geo_range(sats1[j], R0 + dr_true)[0] - geo_range(sats0[j], R0)[0]
                  for j in range(len(sats0))]) + db_true
    s = np.linspace(0.003, 0.03, len(y))
    nees = 0.0
    for _ in range(300):
        yn = y + rng.normal(0, s) - rng.normal(0, s)
        x, cov, _ = tdcp_displacement(sats0, sats1, R0, yn, s)
        e = x - np.r_[dr_true, db_true]
        nees += e @ np.linalg.solve(cov, e)
    assert chi2.ppf(5e-4, 1200) < nees < chi2.ppf(1 - 5e-4, 1200)
    yn = y + rng.normal(0, 0.005, len(y))
    yn[2] += 0.5
    s = np.full(len(y), 0.005)
    s[2] = 5e3
    x_w = tdcp_displacement(sats0, sats1, R0, yn, s)[0]
    keep = np.arange(len(y)) != 2
    x_drop = tdcp_displacement(sats0[keep], sats1[keep], R0, yn[keep], 0.005)[0]
    np.testing.assert_allclose(x_w, x_drop, atol=1e-6)


def test_cycle_slips_from_the_indicator_and_the_doppler():
    t = np.arange(0, 5.0, 0.25)
    rate = np.column_stack([np.full(len(t), 120.0), 300.0 * np.sin(t)])  # m/s
    rng_m = np.column_stack([np.cumsum(np.r_[0, 0.5 * (rate[1:, 0] + rate[:-1, 0]) * 0.25]),
                             np.cumsum(np.r_[0, 0.5 * (rate[1:, 1] + rate[:-1, 1]) * 0.25])])
    L = rng_m / LAMBDA_L1 + 1234.0
    lli = np.zeros(L.shape, np.int64)
    L[10:, 0] += 1.0  # a one-cycle slip at epoch 10 of satellite 0
    lli[5, 1] = 1  # lock lost at epoch 5 of satellite 1 (no jump: still flagged)
    lli[7, 1] = 2  # half-cycle ambiguity only: not a slip
    L[12, 1] = np.nan
    dphi, slip = phase_increments(t, L, lli, rate)
    assert slip[10, 0] == 2 and slip[5, 1] == 1
    assert np.count_nonzero(slip) == 2
    assert np.isnan(dphi[10, 0]) and np.isnan(dphi[5, 1]) and np.isnan(dphi[12, 1]) and np.isnan(dphi[13, 1])
    ok = np.isfinite(dphi)
    assert ok.sum() == 2 * (len(t) - 1) - 4
    # the kept increments are the range increments
    assert np.allclose(dphi[ok], np.diff(rng_m, axis=0, prepend=np.nan)[ok], atol=1e-6)


def _bouncing_walker(seed, slips=(), n_sat=12, n_epochs=401, bounce_m=0.08, rate_sigma=0.05,
                     phase_sigma=0.003):
    """A receiver at 4 Hz bouncing 1.9 Hz vertically (amplitude ``bounce_m``) and swaying 0.95 Hz sideways
    (half that), ``n_sat`` fixed lines of sight above 10° elevation, a clock drifting 1 m/s; Dopplers (the
    exact range rate plus white noise of σ ``rate_sigma``·√(½ + ½/sin²E)) and phases (plus white noise of σ
    ``phase_sigma``); ``slips``: (epoch, satellite) one-cycle slips added from that epoch on. Returns the
    arguments of phase_increments' statistical test: (t, L, lli, range rate, geometry, sigma)."""
    rng = np.random.default_rng(seed)
    el = np.radians(rng.uniform(10.0, 85.0, n_sat))
    az = rng.uniform(0.0, 2.0 * np.pi, n_sat)
    e = np.column_stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])  # ENU, rx -> sat
    t = np.arange(n_epochs) * 0.25
    w = 2.0 * np.pi * 1.9
    pos = np.column_stack([0.5 * bounce_m * np.sin(0.5 * w * t), 1.3 * t, bounce_m * np.sin(w * t)])
    vel = np.column_stack([0.25 * bounce_m * w * np.cos(0.5 * w * t), np.full_like(t, 1.3),
                           bounce_m * w * np.cos(w * t)])
    rho = -pos @ e.T + 1.0 * t[:, None]  # moving towards a satellite shortens its range
    rate = -vel @ e.T + 1.0
    fac = np.sqrt(0.5 + 0.5 / np.sin(el) ** 2)
    rate = rate + rng.standard_normal(rate.shape) * rate_sigma * fac
    L = (rho + rng.standard_normal(rho.shape) * phase_sigma) / LAMBDA_L1 + rng.integers(-1000, 1000, n_sat)
    for k, j in slips:
        L[k:, j] += 1.0
    geo = (np.broadcast_to(e, (n_epochs, n_sat, 3)), np.broadcast_to(el, (n_epochs, n_sat)))
    return t, L, np.zeros(L.shape, np.int64), rate, geo, (rate_sigma, phase_sigma)


def test_slip_test_false_alarms_follow_their_probability():
    """No slip, a walker whose 1.9-Hz bounce the Doppler trapezoid cannot follow at 4 Hz (its error on a
    line of sight, (Δt − 2 sin(ωΔt/2)/ω)·v-ish, up to 14 cm: common to the satellites through the
    geometry): the statistical test flags no more increments than the binomial 99.9 % quantile of
    ``false_alarm`` = 1e-3 over 10 seeds × 4 800 increments (measured 39 of 48 000, bound 71); the
    constant half-cycle threshold flags 11 381 (the false alarms issue 40 session 17 removed)."""
    from scipy.stats import binom

    from aidnav.estimators.tdcp import SLIP_FALSE_ALARM

    n_new, n_old, n_inc = 0, 0, 0
    for seed in range(10):
        t, L, lli, rate, geo, sig = _bouncing_walker(seed)
        _, slip = phase_increments(t, L, lli, rate, None, LAMBDA_L1, geo, sig)
        _, old = phase_increments(t, L, lli, rate, 0.5)
        n_new += int((slip == 2).sum())
        n_old += int((old == 2).sum())
        n_inc += (len(t) - 1) * L.shape[1]
    bound = binom.ppf(0.999, n_inc, SLIP_FALSE_ALARM)
    assert n_new <= bound, (n_new, bound)
    assert n_old > 10 * bound, (n_old, bound)


def test_slip_test_finds_one_cycle_above_30_degrees():
    """One-cycle slips on the same bouncing walker, one every 10 epochs on satellites above 30° elevation:
    each is flagged, on its satellite (the smallest slip found with 99 % probability is (z + 2.33)·σ_s/√(1 −
    h), σ_s the statistic's stated σ and h its leverage: 8 cm at 30° for these noises, under a cycle's
    19 cm), and nothing else in those intervals; the kept increments are the range's."""
    t, L, lli, rate, geo, sig = _bouncing_walker(3)
    high = np.flatnonzero(geo[1][0] > np.radians(30.0))
    slips = [(k, int(high[i % len(high)])) for i, k in enumerate(range(10, len(t), 10))]
    t, L, lli, rate, geo, sig = _bouncing_walker(3, slips)
    _, slip = phase_increments(t, L, lli, rate, None, LAMBDA_L1, geo, sig)
    for k, j in slips:
        assert slip[k, j] == 2, (k, j)
        assert np.count_nonzero(slip[k]) == 1, (k, np.flatnonzero(slip[k]))


def test_lone_satellite_test_keeps_its_probability_under_heavy_tails():
    """No slip, no geometry (every satellite tested alone, as the walk with its nav file alone): each
    interval's statistic carries a Student-t error of 5 degrees of freedom (excess kurtosis 6; the real
    walk's statistic has ν ≈ 4–6 by the same estimate: the trapezoid's error of the walker's motion, one per
    interval) of SD 2 cm on top of normal Doppler (0.05 m/s) and phase (3 mm) noise. The test, its tails
    from the run's own kurtosis (tdcp.slip_threshold), flags no more increments than the binomial 99.9 %
    quantile of false_alarm = 1e-3 over 20 seeds × 3 192; the normal quantile on the same statistics' own
    SD flags more than that bound (the test can fail)."""
    from statistics import NormalDist

    from scipy.stats import binom

    from aidnav.estimators.tdcp import SLIP_FALSE_ALARM

    n_sat, n_ep, sr, sp, nu = 8, 400, 0.05, 0.003, 5.0
    t = np.arange(n_ep) * 0.25
    z_norm = NormalDist().inv_cdf(1.0 - 0.5 * SLIP_FALSE_ALARM)
    n_new, n_norm, n_inc = 0, 0, 0
    for seed in range(20):
        rng = np.random.default_rng(100 + seed)
        rho = 20e6 + rng.uniform(-800.0, 800.0, n_sat) * t[:, None] + 1.0 * t[:, None]
        rate = np.gradient(rho, t, axis=0) + sr * rng.standard_normal(rho.shape)
        motion = np.cumsum(0.02 * np.sqrt((nu - 2.0) / nu) * rng.standard_t(nu, rho.shape), axis=0)
        L = (rho + motion + sp * rng.standard_normal(rho.shape)) / LAMBDA_L1
        _, slip = phase_increments(t, L, np.zeros(L.shape, np.int64), rate, None, LAMBDA_L1, None, (sr, sp))
        n_new += int((slip == 2).sum())
        s = LAMBDA_L1 * np.diff(L, axis=0) - 0.5 * (rate[1:] + rate[:-1]) * 0.25
        n_norm += int((np.abs(s - s.mean()) > z_norm * s.std()).sum())
        n_inc += (n_ep - 1) * n_sat
    bound = binom.ppf(0.999, n_inc, SLIP_FALSE_ALARM)
    assert n_new <= bound, (n_new, bound)
    assert n_norm > bound, (n_norm, bound)


def test_slip_test_learns_an_overstated_doppler_sigma_and_finds_low_slips(monkeypatch):
    """The bouncing walker with a true Doppler σ of 0.05 m/s (zenith) stated as 0.1 m/s (the tight filter's
    default against the simulator's): the geometric test's variance factor from the run's own residuals
    (≈ ¼, above its floor 0.1) puts the smallest slip found with 99 % probability, (z + 2.33)·σ_s/√(1 − h),
    under a cycle down to ≈ 12°: of the one-cycle slips on the satellites at 12–30° elevation (13.4–27.6°),
    one every 10 epochs, 95 % or more are found on their satellite (at 99 % each near 12°). With the factor
    floored at 1 (the stated σ as a lower bound, the test of issue 40 session 17) fewer than half are."""
    from aidnav.estimators import tdcp

    t, L, lli, rate, geo, _ = _bouncing_walker(5, n_sat=14)
    el = np.degrees(geo[1][0])
    low = np.flatnonzero((el > 12.0) & (el < 30.0))
    assert len(low) >= 3, el
    slips = [(k, int(low[i % len(low)])) for i, k in enumerate(range(10, len(t), 10))]
    t, L, lli, rate, geo, _ = _bouncing_walker(5, slips, n_sat=14)
    stated = (0.1, 0.003)
    _, slip = phase_increments(t, L, lli, rate, None, LAMBDA_L1, geo, stated)
    found = [slip[k, j] == 2 for k, j in slips]
    assert sum(found) >= 0.95 * len(slips), [s for s, f in zip(slips, found, strict=True) if not f]
    monkeypatch.setattr(tdcp, "SLIP_VARIANCE_FLOOR", 1.0)
    _, slip1 = phase_increments(t, L, lli, rate, None, LAMBDA_L1, geo, stated)
    assert sum(slip1[k, j] == 2 for k, j in slips) < 0.5 * len(slips)


@pytest.fixture(scope="module")
def walk(load_walk_gnss):
    from aidnav.estimators.dgps import spp_series

    obs, nav, ref = load_walk_gnss()
    return obs, nav, spp_series(obs, nav), ref


def test_walk_injected_slip_is_caught_and_changes_nothing_else(walk):
    from aidnav.estimators.tdcp import tdcp_series

    obs, nav, sp, _ = walk
    assert obs.phase1 is not None and np.isfinite(obs.phase1).sum() > 2000
    base = tdcp_series(obs, nav, sp["ecef"])
    j = int(np.flatnonzero(obs.prn == 23)[0])
    ok = np.flatnonzero(np.isfinite(base["vel_enu"][:, 0]))
    k = int(ok[len(ok) // 2]) + 1  # an epoch whose interval had a solution
    o2 = obs.subset_sats(obs.prn)
    o2.phase1[k:, j] += 1.0
    r = tdcp_series(o2, nav, sp["ecef"])
    new = (r["slips"] != 0) & (base["slips"] == 0)
    assert new.sum() == 1 and new[k, j]
    # the slipped interval is not used (4 satellites left 3: no solution) and nothing else moved
    assert np.isnan(r["vel_enu"][k - 1, 0])
    other = np.arange(len(r["t_mid"])) != k - 1
    np.testing.assert_array_equal(r["vel_enu"][other], base["vel_enu"][other])


def test_walk_tdcp_velocity_against_rtk(walk):
    """TDCP mean velocities against the RTK solution's velocity (interpolated to the interval's mid time):
    measured 0.14 m/s horizontal RMS, against 0.46 m/s for the SPP Doppler velocity (the RTK velocity and the
    RTK position differences themselves differ by 0.15 m/s RMS at 4 Hz)."""
    from aidnav.estimators.tdcp import tdcp_series

    obs, nav, sp, ref = walk
    r = tdcp_series(obs, nav, sp["ecef"])

    def rms_h(t, v):
        ok = np.isfinite(v[:, 0])
        vr = np.column_stack([np.interp(t[ok], ref.time, ref.vel[:, i]) for i in range(2)])
        return np.sqrt(np.mean(np.sum((v[ok, :2] - vr) ** 2, axis=1))), ok.sum()

    tdcp, n = rms_h(r["t_mid"], r["vel_enu"])
    dop, _ = rms_h(sp["time"], sp["vel_enu"])
    assert n > 300
    assert tdcp < 0.5 * dop


def test_walk_tdcp_velocity_against_the_rtk_position_differences(walk):
    """The TDCP mean velocity of each interval against the RTK positions' difference over the same interval
    (both ends fixed; the mean velocity by definition, no time-tag convention: results.md, issue 40 session
    11): measured 0.090 m/s horizontal over 244 intervals — the 4 satellites' phase alone; aidnav tight's
    filter does 0.077 m/s forward."""
    from aidnav.analysis.velocity_reference import interval_velocity_errors
    from aidnav.estimators.tdcp import tdcp_series

    obs, nav, sp, ref = walk
    r = tdcp_series(obs, nav, sp["ecef"])
    iv = interval_velocity_errors(ref.time, ref.vel, ref.time, ref.lat, ref.lon, ref.height,
                                  use=ref.quality == 1)
    k = np.searchsorted(obs.time, iv.t_end - 0.005)  # the receiver's epoch of each reference interval's end
    k = np.clip(k, 1, len(obs.time) - 1)
    same = (np.abs(obs.time[k] - iv.t_end) < 0.005) & (np.abs(obs.time[k - 1] - iv.t_start) < 0.005)
    v = r["vel_enu"][k - 1]
    ok = same & np.isfinite(v[:, 0])
    d = v[ok, :2] - iv.ref[ok, :2]
    assert ok.sum() > 200
    rms = np.sqrt(np.mean(np.sum(d**2, axis=1)))
    assert rms < 0.12, (rms, ok.sum())


# ------------------------------------------------------------------ receiver phase wind-up
def _enu_axes(p):
    """Columns: east, north, up at the ECEF point p (a level antenna's x̂, ŷ, boresight)."""
    from aidnav.nav.earth import dcm_ecef_to_enu, ecef_to_lla

    lat, lon, _ = ecef_to_lla(*p)
    return dcm_ecef_to_enu(lat, lon).T


def _rot(axis, th):
    """Rotation matrix of angle th [rad] about the unit vector axis (right-handed)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


@pytest.mark.parametrize("tilt_deg", [0.0, 35.0])
def test_windup_of_a_boresight_rotation_is_the_same_for_every_satellite(tilt_deg):
    """Known answer (module doc): turning the antenna by θ about its own boresight changes every
    satellite's wind-up by −θ/2π cycles (λθ/2π less phase: 1.0 cm for 0.33 rad at L1), whatever the
    satellite's direction and the antenna's tilt; the clock change takes it."""
    from aidnav.estimators.tdcp import windup_increments

    sats, _ = _geometry(np.random.default_rng(11), 7)
    c0 = _rot(_enu_axes(R0)[:, 1], np.radians(tilt_deg)) @ _enu_axes(R0)  # tilted about north
    th = 0.33
    c1 = _rot(c0[:, 2], th) @ c0  # about the antenna's own boresight
    d = windup_increments(np.stack([sats, sats]), np.stack([R0, R0]), np.stack([c0, c1]))
    assert np.all(np.isnan(d[0]))
    np.testing.assert_allclose(d[1], -th / (2 * np.pi) * LAMBDA_L1, atol=1e-9)


def test_windup_of_a_tilt_differs_between_satellites_and_is_minus_theta_for_the_one_on_the_axis():
    """A rotation about the direction to satellite j turns that satellite's effective dipole by −θ about
    its line of sight (the same closed form): its increment is −λθ/2π; the others' differ (a rocking
    antenna's wind-up is not all clock)."""
    from aidnav.estimators.tdcp import windup_increments

    sats, _ = _geometry(np.random.default_rng(12), 6)
    c0 = _enu_axes(R0)
    th = 0.25
    for j in range(len(sats)):
        u = (sats[j] - R0) / np.linalg.norm(sats[j] - R0)
        d = windup_increments(np.stack([sats, sats]), np.stack([R0, R0]), np.stack([c0, _rot(u, th) @ c0]))[1]
        assert d[j] == pytest.approx(-th / (2 * np.pi) * LAMBDA_L1, abs=1e-9)
        assert np.ptp(d) > 1e-3  # the rest see other projected rotations (mm)


def test_windup_increment_wraps_and_a_fixed_antenna_has_none():
    """No rotation, no wind-up change (the satellite's half is held fixed); 1.9 turns in one interval read
    as −0.1 turn, +0.1 cycle (increments are taken modulo a cycle)."""
    from aidnav.estimators.tdcp import windup_increments

    sats, vel = _geometry(np.random.default_rng(13), 5)
    c0 = _enu_axes(R0)
    d = windup_increments(np.stack([sats, sats + 0.25 * vel]), np.stack([R0, R0 + 0.3]), np.stack([c0, c0]))
    assert np.nanmax(np.abs(d[1])) < 1e-6  # 0.3 m and 1 km of satellite motion: µm
    d = windup_increments(np.stack([sats, sats]), np.stack([R0, R0]),
                          np.stack([c0, _rot(c0[:, 2], 1.9 * 2 * np.pi) @ c0]))
    np.testing.assert_allclose(d[1], 0.1 * LAMBDA_L1, atol=1e-9)


def test_walk_sbas_phase_increments_are_unbiased_against_the_rtk_displacements(walk_dir):
    """The walk's three SBAS GEO satellites (S31, S33, S35: broadcast state vectors, quadratic propagation,
    on the GPS clock) give time-differenced phase: per interval with fixed RTK positions at both ends, the
    increment λΔL + Δ(c·dt_s) minus the geometric range change (Sagnac-corrected, satellite at each epoch's
    transmit time) minus the 4 GPS satellites' mean (the clock change) has no bias (measured means −0.02,
    +0.53, −1.47 mm over 180, 116, 154 intervals, SD 17.4, 13.3, 16.3 mm, against 7.6–13.2 mm for the GPS
    satellites: the GEOs' C/N0 is ~40 dB-Hz against 42–49), so the satellites' motion and clock rate are
    right to well under a millimetre per 0.25 s (a GEO moves metres per second in ECEF)."""
    import warnings

    from aidnav.io.rinex import read_rinex_pair
    from aidnav.io.rtklib import read_pos
    from aidnav.nav.earth import lla_to_ecef
    from aidnav.nav.gnss_sat import satellites_from_pseudoranges

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        obs, nav, _ = read_rinex_pair(walk_dir / "rinex_converted/gnss_1730.obs",
                                      walk_dir / "rinex_converted/gnss_1730.nav", "GS")
    ref = read_pos(walk_dir / "gnss_1730_sf.pos", height_offset_m=-21.4)
    names = obs.names
    dphi, _ = phase_increments(obs.time, obs.phase1, obs.lli1, obs.range_rate(), 0.5, obs.wavelengths())
    T, S = obs.code1.shape
    kr = np.clip(np.searchsorted(ref.time, obs.time - 0.005), 0, len(ref.time) - 1)
    fixed = (np.abs(ref.time[kr] - obs.time) < 0.005) & (ref.quality[kr] == 1)
    rx = np.column_stack(lla_to_ecef(ref.lat[kr], ref.lon[kr], ref.height[kr]))
    sp, sc = np.full((T, S, 3), np.nan), np.full((T, S), np.nan)
    for k in range(T):
        sp[k], _, sc[k], _ = satellites_from_pseudoranges(nav.table, obs.prn, obs.time[k], obs.code1[k])
    gps = np.array([n[0] == "G" for n in names])
    res = {n: [] for n in names}
    for k in np.flatnonzero(fixed[1:] & fixed[:-1]) + 1:
        v = np.array([dphi[k, j] + sc[k, j] - sc[k - 1, j] - (geo_range(sp[k, j], rx[k])[0]
                      - geo_range(sp[k - 1, j], rx[k - 1])[0]) for j in range(S)])
        g = gps & np.isfinite(v)
        if g.sum() < 4:
            continue
        for j in np.flatnonzero(np.isfinite(v)):
            res[names[j]].append(v[j] - v[g].mean())
    for n in ("S31", "S33", "S35"):
        a = np.array(res[n])
        assert len(a) > 100, (n, len(a))
        assert abs(a.mean()) < 3e-3 and a.std() < 0.025, (n, a.mean(), a.std())


def test_windup_equals_a_simulated_rhcp_wave_on_crossed_dipoles():
    """The sign and size from the signal itself, for any orientation: a right-hand circularly polarised
    plane wave (IS-GPS-200 §3.3.1.1; IEEE: the field turns right-handed about the propagation direction k,
    phasor Ẽ = ê1 − jê2 with ê1 × ê2 = k) received by crossed dipoles x̂, ŷ whose ŷ output is delayed by a
    quarter cycle (the RHCP antenna: Ṽ = Ẽ·x̂ − jẼ·ŷ, 2 for a zenith wave). The receiver's carrier phase
    in RINEX's sense (λL grows with the range: minus the received phase) changes by −Δarg Ṽ/2π cycles
    between two antenna attitudes; :func:`windup_increments` must give the same, for random attitudes
    (tilts and turns of up to 1 rad) and satellites in every direction above 15°."""
    from aidnav.estimators.tdcp import windup_increments

    rng = np.random.default_rng(21)
    sats, _ = _geometry(rng, 8)
    c0 = _enu_axes(R0)

    def wave_axes(s):
        k = (R0 - s) / np.linalg.norm(R0 - s)  # propagation: satellite → receiver
        e1 = np.cross(k, rng.normal(size=3))  # any ê1 ⊥ k (its choice is a constant phase)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(k, e1)  # ê1 × ê2 = k
        return e1, e2

    for _ in range(20):
        ca = _rot(rng.normal(size=3), rng.uniform(0, 1.0)) @ c0
        cb = _rot(rng.normal(size=3), rng.uniform(0, 1.0)) @ ca
        d = windup_increments(np.stack([sats, sats]), np.stack([R0, R0]), np.stack([ca, cb]))[1] / LAMBDA_L1
        for j, s in enumerate(sats):
            e1, e2 = wave_axes(s)
            E = e1 - 1j * e2
            va = E @ ca[:, 0] - 1j * (E @ ca[:, 1])
            vb = E @ cb[:, 0] - 1j * (E @ cb[:, 1])
            dl = -np.angle(vb / va) / (2 * np.pi)  # RINEX phase change [cycles], in (−½, ½]
            assert np.angle(np.exp(2j * np.pi * (dl - d[j]))) == pytest.approx(0.0, abs=1e-9)


# ------------------------------------------------------------------ the receiver's σ and the variance factor
def test_weighted_residuals_are_chi_square_and_the_variance_factor_recovers_a_wrong_scale():
    """8 satellites, phase σ 2–12 mm (as the receiver's cpStdev orders them) but stated 3× too small (the
    walk's cpStdev against its residuals): rᵀWr/(n − 4) ≈ 9 (the running factor after 400 intervals within
    the χ²(4·400) 99.9 % band of 9), and the covariance scaled by the running factor gives a NEES of (Δr, Δb)
    within the χ²(4·400) band, where the unscaled one is ~9× above it."""
    from aidnav.estimators.tdcp import running_variance_factor

    rng = np.random.default_rng(11)
    sats0, vel = _geometry(rng, 8)
    sats1 = sats0 + 0.25 * vel
    dr_true, db_true = np.array([0.4, -0.3, 0.02]), 1.5
    y = np.array([geo_range(sats1[j], R0 + dr_true)[0] - geo_range(sats0[j], R0)[0]
                  for j in range(len(sats0))]) + db_true
    s_true = np.linspace(0.002, 0.012, len(y))
    s_stated = s_true / 3.0
    K = 400
    chi2_k, errs, covs = np.zeros(K), [], []
    for k in range(K):
        yn = y + rng.normal(0, s_true) - rng.normal(0, s_true)
        x, cov, used, chi2_k[k] = tdcp_displacement(sats0, sats1, R0, yn, s_stated, with_chi2=True)
        errs.append(x - np.r_[dr_true, db_true])
        covs.append(cov)
    f = running_variance_factor(chi2_k, np.full(K, 4))
    n = 4 * K
    assert chi2.ppf(5e-4, n) < f[-1] * n / 9.0 < chi2.ppf(1 - 5e-4, n)
    assert np.all(f >= 1.0)
    nees_raw = sum(e @ np.linalg.solve(c, e) for e, c in zip(errs, covs, strict=True))
    nees = sum(e @ np.linalg.solve(c * f[k], e) for k, (e, c) in enumerate(zip(errs, covs, strict=True)))
    assert nees_raw > 5 * chi2.ppf(1 - 5e-4, n)
    # the first factors rest on few degrees of freedom: the band for the settled second half
    half = sum(errs[k] @ np.linalg.solve(covs[k] * f[k], errs[k]) for k in range(K // 2, K))
    assert chi2.ppf(5e-4, n // 2) < half < chi2.ppf(1 - 5e-4, n // 2), (nees, half)


def test_receiver_sigma_weights_beat_equal_weights():
    """Rows weighted by σ proportional to their simulated noise (the receiver's cpStdev × a common scale):
    the displacement's mean squared error over 400 draws is below equal weighting's (Gauss–Markov: the
    weighted least squares is the best linear unbiased one), by more than the draws' spread allows."""
    rng = np.random.default_rng(12)
    sats0, vel = _geometry(rng, 8)
    sats1 = sats0 + 0.25 * vel
    y = np.array([geo_range(sats1[j], R0)[0] - geo_range(sats0[j], R0)[0] for j in range(len(sats0))])
    s_true = np.r_[0.002, 0.002, 0.003, 0.004, 0.006, 0.010, 0.015, 0.025]
    se_w, se_eq = [], []
    for _ in range(400):
        yn = y + rng.normal(0, s_true) - rng.normal(0, s_true)
        se_w.append(np.sum(tdcp_displacement(sats0, sats1, R0, yn, s_true / 3.0)[0][:3] ** 2))
        se_eq.append(np.sum(tdcp_displacement(sats0, sats1, R0, yn, 0.005)[0][:3] ** 2))
    se_w, se_eq = np.array(se_w), np.array(se_eq)
    assert se_w.mean() < 0.5 * se_eq.mean()


@pytest.mark.parametrize("q", [0.3**2, 0.01**2])
def test_tdcp_records_taken_as_independent_are_conservative_for_the_velocity(q):
    """The phase of epoch k enters the delta-ranges k−1→k and k→k+1 (their errors correlated −½). One axis,
    the velocity a random walk of q [m²/s²] per 0.25 s (0.3²: a walker with nothing else; 0.01²: the
    prediction of an IMU-aided filter), phase σ 5 mm: a Kalman filter of the velocity that takes the TDCP
    mean velocities as independent (R = 2σ²/Δt²) against the proper model, the phase as a measurement of
    the position (state p, v; what an ambiguity state gives), 400 independent runs of 40 epochs, the
    velocity at the last epoch: the proper model's NEES is within the χ²(400) 99.9 % band; the independent
    one's is never above it, and below it where the filter averages many records (q = 0.01²: its σ too
    large; measured 361 and 213, the proper model 360 and 362): the correlation does not make the records' σ
    optimistic."""
    rng = np.random.default_rng(21)
    n_run, K, dt, s = 400, 40, 0.25, 0.005
    v = np.cumsum(rng.normal(0, np.sqrt(q), (n_run, K)), axis=1) + rng.normal(0, 1.0, (n_run, 1))
    p = np.cumsum(v * dt, axis=1)
    phi = p + rng.normal(0, s, (n_run, K))
    # (a) the velocity records as independent measurements
    va, Pa = np.zeros(n_run), 1.0
    for k in range(1, K):
        Pa += q
        y = (phi[:, k] - phi[:, k - 1]) / dt
        g = Pa / (Pa + 2 * s**2 / dt**2)
        va, Pa = va + g * (y - va), (1 - g) * Pa
    # (b) the phase as a position measurement (p_k = p_{k−1} + v_k Δt, v a random walk)
    x = np.zeros((n_run, 2))
    x[:, 0] = phi[:, 0]
    P = np.diag([s**2, 1.0])
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Q = q * np.array([[dt * dt, dt], [dt, 1.0]])  # v_k = v_{k−1} + w enters p_k through v_k Δt
    for k in range(1, K):
        x = x @ F.T
        P = F @ P @ F.T + Q
        g = P[:, 0] / (P[0, 0] + s**2)
        x = x + (phi[:, k] - x[:, 0])[:, None] * g[None, :]
        P = P - np.outer(g, P[0])
    nees_a = np.sum((va - v[:, -1]) ** 2) / Pa
    nees_b = np.sum((x[:, 1] - v[:, -1]) ** 2) / P[1, 1]
    lo, hi = chi2.ppf(5e-4, n_run), chi2.ppf(1 - 5e-4, n_run)
    assert lo < nees_b < hi, nees_b
    assert nees_a < (lo if q < 1e-3 else hi), nees_a


def test_walk_reference_noise_by_the_three_cornered_hat_is_near_the_target(walk_dir):
    """The walk's reference velocity (the RTK positions' differences) against two TDCP least-squares
    velocities of disjoint satellites (Galileo; GPS + the log's BeiDou B1C), three-cornered hat: the
    reference's own noise while walking (speed ≥ 0.2 m/s) is measured 0.040 / 0.033 m/s east / north
    (standing 0.011 / 0.015), so a perfect estimate would score ≈ 0.049 m/s horizontal over the walk's
    intervals — the issue's 0.05 m/s target is at this reference's floor (results.md, issue 40 session 15).
    Bounds: walking ≥ 0.025 m/s per horizontal axis, standing ≤ 0.025, and the floor over all intervals
    ≥ 0.04 m/s."""
    import warnings

    from aidnav.analysis.velocity_reference import interval_velocity_errors, three_cornered_hat
    from aidnav.estimators.dgps import spp_series
    from aidnav.estimators.tdcp import tdcp_series
    from aidnav.io.nav_sources import read_observations_and_navigation
    from aidnav.io.rinex import UBX_SOURCES_ALL
    from aidnav.io.rtklib import read_pos

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        obs, eph, _, _ = read_observations_and_navigation(
            walk_dir / "rinex_converted" / "gnss_1730.obs", walk_dir / "rinex_converted" / "gnss_1730.nav",
            "GECR", "auto", ubx_sources=UBX_SOURCES_ALL)
    assert sum(n[0] == "C" for n in obs.names) >= 7
    ref = read_pos(walk_dir / "gnss_1730_sf.pos", height_offset_m=-21.4)
    pos = spp_series(obs, eph)["ecef"]
    iv = interval_velocity_errors(ref.time, ref.vel, ref.time, ref.lat, ref.lon, ref.height,
                                  use=ref.quality == 1)
    k = np.clip(np.searchsorted(obs.time, iv.t_end - 0.005), 1, len(obs.time) - 1)
    same = (np.abs(obs.time[k] - iv.t_end) < 0.005) & (np.abs(obs.time[k - 1] - iv.t_start) < 0.005)
    v = []
    for letters in ("E", "GC"):
        o = obs.subset_sats(obs.prn[np.array([n[0] in letters for n in obs.names])])
        v.append(np.where(same[:, None], tdcp_series(o, eph, pos)["vel_enu"][k - 1], np.nan))
    walking = np.hypot(iv.ref[:, 0], iv.ref[:, 1]) >= 0.2
    var_r = []
    for m in (walking, ~walking):
        var_r.append(three_cornered_hat(v[0][m], v[1][m], iv.ref[m])[2])
    assert np.all(np.sqrt(var_r[0][:2]) >= 0.025) and np.all(np.sqrt(np.maximum(var_r[1][:2], 0)) <= 0.025)
    n_w = walking.sum()
    floor = np.sqrt((n_w * var_r[0][:2].sum() + (len(walking) - n_w) * var_r[1][:2].sum()) / len(walking))
    assert floor >= 0.04, floor


@pytest.mark.parametrize("d_true", [0.0, 0.031, -0.07])
def test_imu_time_offset_recovers_a_shift_of_a_noise_free_bounce(d_true):
    """Closed form: a body at a fixed attitude (body = ENU) bouncing vertically, z(t) = A sin(2πft) (A = 3 cm,
    f = 1.9 Hz), the IMU's Δv exact on its own stamps, which are ``d_true`` late against the GNSS epochs
    (4 Hz); the TDCP mean velocities exact. The offset to add is −d_true, to a fraction of a ms."""
    from types import SimpleNamespace

    from aidnav.estimators.tdcp import imu_time_offset

    g, amp, w = 9.80, 0.03, 2 * np.pi * 1.9
    t_imu = np.arange(0.0, 60.0, 0.005)
    z = lambda t: amp * np.sin(w * t)  # noqa: E731
    vz = lambda t: amp * w * np.cos(w * t)  # noqa: E731
    dv = np.zeros((t_imu.size - 1, 3))
    dv[:, 2] = vz(t_imu[1:]) - vz(t_imu[:-1]) + g * np.diff(t_imu)  # ∫(a + g) over each sample
    imu = SimpleNamespace(t0=t_imu[0] + d_true, time=t_imu[1:] + d_true, dv=dv)
    t_e = np.arange(1.0, 59.0, 0.25)
    vel = np.zeros((t_e.size - 1, 3))
    vel[:, 2] = (z(t_e[1:]) - z(t_e[:-1])) / 0.25
    d, sd, n = imu_time_offset(imu, t_e, vel, g)
    assert n == t_e.size - 2
    assert d == pytest.approx(-d_true, abs=5e-4)
    assert sd < 1e-3


def _bounce_imu(d_true, span_s):
    """The bounce of the closed-form test (body = ENU, z = A sin 2πft, A = 3 cm, f = 1.9 Hz): the IMU's exact
    Δv on stamps ``d_true`` late, the height function."""
    from types import SimpleNamespace

    g, amp, w = 9.80, 0.03, 2 * np.pi * 1.9
    t_imu = np.arange(0.0, span_s, 0.005)
    dv = np.zeros((t_imu.size - 1, 3))
    vz = amp * w * np.cos(w * t_imu)
    dv[:, 2] = np.diff(vz) + g * np.diff(t_imu)  # ∫(a + g) over each sample
    imu = SimpleNamespace(t0=t_imu[0] + d_true, time=t_imu[1:] + d_true, dv=dv)
    return imu, lambda t: amp * np.sin(w * t)


def test_imu_time_offset_sigma_is_honest_with_white_phase_noise():
    """The bounce with white noise of σ 1 cm on each epoch's height (a TDCP position; 4 Hz): the mean
    velocities' errors correlate −1/2, the second differences' −2/3 and 1/6 (a moving average of order 2),
    and the regressor alternates in sign (1.9 Hz seen at 4 Hz), so those autocovariances add to the offset's
    variance (≈ 8/3 of the white one). Over 48 draws the normalised errors (d̂ + d_true)/σ: mean square
    inside the two-sided 99 % χ²(48) band (0.55–1.60) and ≥ 95 % within 3σ. Measured 0.92; with the white
    sandwich alone (``MA_ORDER`` 0) 2.25 — outside."""
    from scipy.stats import chi2

    from aidnav.estimators.tdcp import imu_time_offset

    d_true = 0.025
    imu, z = _bounce_imu(d_true, 40.0)
    t_e = np.arange(1.0, 39.0, 0.25)
    zs = []
    for seed in range(48):
        h = z(t_e) + np.random.default_rng([seed, 17]).normal(0.0, 0.01, t_e.size)
        vel = np.zeros((t_e.size - 1, 3))
        vel[:, 2] = np.diff(h) / 0.25
        d, sd, _ = imu_time_offset(imu, t_e, vel, 9.80, max_lag_s=0.1)
        zs.append((d + d_true) / sd)
    zs = np.array(zs)
    lo, hi = chi2.ppf([0.005, 0.995], zs.size) / zs.size
    assert lo < np.mean(zs ** 2) < hi, np.mean(zs ** 2)
    assert np.mean(np.abs(zs) <= 3.0) >= 0.95


def test_slope_variance_ma_counts_the_pairs_within_the_order():
    """Closed form, by hand: x = (1, −1, 2, 1) at epochs (0, 1, 2, 5) (a gap after 2), e = (1, 2, −1, 3):
    xe = (1, −2, −2, 3), Σx² = 7. Order 0: Σ(xe)² = 18 → 18/49. Order 2: + 2·(1·(−2) + (−2)(−2) + 1·(−2)) = 0
    (lag 1: pairs (0,1), (1,2); lag 2: (0,2); epoch 5 has no partner) → 18/49; order 1 adds 2·(−2 + 4) = 4 →
    22/49. Negative sums are floored at the white 18/49: xe = (1, 1) at epochs (0, 1) with x = (1, 1) gives
    order 1: 2 + 2 = 4 → 4/4; xe = (1, −1): 2 − 2 = 0 → floored at 2/4."""
    from aidnav.estimators.tdcp import slope_variance_ma

    x, e, idx = np.array([1.0, -1.0, 2.0, 1.0]), np.array([1.0, 2.0, -1.0, 3.0]), np.array([0, 1, 2, 5])
    assert slope_variance_ma(x, e, idx, 0) == pytest.approx(18 / 49)
    assert slope_variance_ma(x, e, idx, 1) == pytest.approx(22 / 49)
    assert slope_variance_ma(x, e, idx, 2) == pytest.approx(18 / 49)
    assert slope_variance_ma([1.0, 1.0], [1.0, 1.0], [0, 1], 1) == pytest.approx(1.0)
    assert slope_variance_ma([1.0, 1.0], [1.0, -1.0], [0, 1], 1) == pytest.approx(0.5)


def test_timing_variance_is_the_specific_force_change_between_records():
    """Closed form: a specific force that steps from (0, 0, 9.8) to (1, 2, 9.8) m/s² between two records
    and back before the third: (σ·√5)² at the second record's sample and at the third's, 0 elsewhere."""
    from aidnav.filters.tight import timing_variance

    t = np.arange(1, 1001) * 0.01
    f = np.tile([0.0, 0.0, 9.8], (t.size, 1))
    f[(t > 3.0) & (t <= 6.0)] = [1.0, 2.0, 9.8]
    out = timing_variance(t, f * 0.01, np.array([2.0, 4.0, 8.0]), 0.02)
    k = np.searchsorted(t, [2.0, 4.0, 8.0])
    expect = np.zeros(t.size)
    expect[k[1:]] = (0.02 * np.sqrt(5.0)) ** 2
    np.testing.assert_allclose(out, expect, atol=1e-15)
