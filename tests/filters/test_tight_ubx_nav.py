"""The walk with `aidnav tight`'s default navigation data (issue 40): the RINEX navigation file and the UBX
log its observation file names (`gnss.ubx_nav: auto`, :mod:`aidnav.io.nav_sources`), whose Galileo I/NAV
ephemerides add 6 healthy satellites to the file's 4 GPS ones. Figures: docs/results.md, issue 40 session
14 (q40e); `benchmarks/galileo_walk_tight.py`, `benchmarks/walk_reference_offset.py`."""

from __future__ import annotations

import copy
import warnings

import numpy as np
import pytest

from aidnav.filters.tight import TightConfig
from aidnav.nav.gnss_sat import sat_name

#: why the horizontal figures against the walk's reference fail with the Galileo satellites
REFERENCE_OFFSET = ("the walk's reference (the receiver's own RTK NAV-PVT, its base station's coordinates "
                    "unknown) is offset from every broadcast-ephemeris solution by ~8 m horizontally: "
                    "GPS-only SPP mean E/N 7.37/4.12 m, Galileo-only 5.59/5.53 m, each satellite left out "
                    "7.6-8.5 m (benchmarks/walk_reference_offset.py); the tight solution's SD about its mean "
                    "is 0.23/0.25 m")


def test_the_option_wins_and_a_configured_path_is_the_configuration_files(tmp_path):
    from aidnav.apps.tight import ubx_nav_setting

    cfg = TightConfig(gnss={"ubx_nav": "logs/rover.ubx"})
    assert TightConfig().gnss.ubx_nav == "auto"
    assert ubx_nav_setting(cfg, None, tmp_path / "c.yaml") == ("logs/rover.ubx", str(tmp_path))
    assert ubx_nav_setting(cfg, "none", tmp_path / "c.yaml") == ("none", None)
    assert ubx_nav_setting(TightConfig(), None, None) == ("auto", None)
    assert TightConfig(gnss={"ubx_nav": None}).gnss.ubx_nav is None


@pytest.fixture(scope="module")
def walk_ubx(walk_dir, load_walk):
    """`aidnav tight`'s processing with no configuration and the default navigation data: ENU errors
    against the RTK reference at every reference epoch, their σ, the result, the observations and the
    ephemerides used."""
    from aidnav.apps.tight import process_tight
    from aidnav.filters.tight import to_trajectory
    from aidnav.io.nav_sources import read_observations_and_navigation
    from aidnav.nav.earth import lla_difference_enu

    imu, _, _, ref = load_walk()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        obs, eph, ev, src = read_observations_and_navigation(
            walk_dir / "rinex_converted" / "gnss_1730.obs", walk_dir / "rinex_converted" / "gnss_1730.nav",
            TightConfig().gnss.systems, TightConfig().gnss.ubx_nav)
    res, _ = process_tight(imu, obs, eph, None, events=ev)
    tr = to_trajectory(res)
    sel = (ref.time >= tr.time[0]) & (ref.time <= tr.time[-1])
    j = np.clip(np.searchsorted(tr.time, ref.time[sel]), 0, len(tr.time) - 1)
    d = np.column_stack(lla_difference_enu(tr.lat[j], tr.lon[j], tr.height[j], ref.lat[sel], ref.lon[sel],
                                           ref.height[sel]))
    return d, tr.std_pos[j], res, (obs, eph, src, ref, imu, ev)


def test_walk_default_uses_the_galileo_satellites_of_the_ubx_log(walk_ubx):
    """The log's Galileo satellites get range-error states and a Galileo inter-system bias, and the velocity
    against the RTK positions' differences is better than the navigation file alone gives (measured 0.0677
    m/s with the Galileo satellites, 0.0693 m/s with the log's GPS CNAV satellites and Klobuchar
    coefficients too (session 14 merge), 0.0675 m/s with the receiver's phase σ as the TDCP weights (the
    log's RXM-RAWX cpStdev, session 15; bound: below session 14's 0.0693); 0.0772 m/s alone:
    test_tight_partial_sky.py's walk_default)."""
    from aidnav.analysis.velocity_reference import interval_velocity_errors

    d, _, res, (_, _, src, ref, *_) = walk_ubx
    gal = {sat_name(p) for p in res.range_error_prn if sat_name(p)[0] == "E"}
    assert gal == set(src["satellites"]["Galileo"]) and len(gal) == 6
    assert res.isb_systems == "E" and res.isb_std[-1, 0] < 5.0
    iv = interval_velocity_errors(res.time, res.state[:, 3:6], ref.time, ref.lat, ref.lon, ref.height,
                                  use=ref.quality == 1)
    assert len(iv) > 300 and iv.rms_horizontal() < 0.069


def test_walk_reference_offset_is_common_to_gps_and_galileo(walk_ubx):
    """Why the horizontal figures against the walk's reference are a constant ~8 m: single point positions
    of the GPS satellites alone and of the Galileo satellites alone (independent orbits, clocks and group
    delays) are both ≥ 6 m from the reference on average and within 3 m of each other, and the tight
    solution's scatter about its mean is < 1 m (measured 0.23/0.25 m) while its mean is ~8 m away: the
    offset is common to the constellations (the reference's absolute position, not a satellite's error)."""
    from aidnav.estimators.spp import spp_series
    from aidnav.nav.earth import lla_difference_enu

    d, _, _, (obs, eph, src, ref, *_) = walk_ubx
    means = {}
    for system in ("GPS", "Galileo"):
        o = copy.deepcopy(obs)
        keep = set(src["satellites"][system])
        for j, p in enumerate(o.prn):
            if sat_name(p) not in keep:
                o.code1[:, j] = np.nan
        sp = spp_series(o, eph, sigma0=3.0, iono="klobuchar", mask_deg=10.0)
        ok = np.isfinite(sp["lat"])
        i = np.clip(np.searchsorted(ref.time, sp["time"][ok]), 0, len(ref) - 1)
        e, n, _ = lla_difference_enu(sp["lat"][ok], sp["lon"][ok], sp["h"][ok], ref.lat[i], ref.lon[i],
                                     ref.height[i])
        assert ok.sum() > 500
        means[system] = np.array([e.mean(), n.mean()])
    print({k: np.round(v, 2) for k, v in means.items()})  # measured GPS 7.37/4.12, Galileo 5.59/5.53 m
    assert np.hypot(*means["GPS"]) >= 6.0 and np.hypot(*means["Galileo"]) >= 6.0
    assert np.hypot(*(means["GPS"] - means["Galileo"])) < 3.0
    assert np.hypot(*d[:, :2].mean(0)) > 8.0 and np.all(d[:, :2].std(0) < 1.0)


def test_walk_default_horizontal_rms_at_most_rtklib_spp(walk_ubx):
    """Issue 40's horizontal target with every source of the log (Galileo I/NAV, GPS CNAV, the broadcast
    Klobuchar coefficients): measured 8.332 m in the session-14 merge (8.884 m with Galileo alone, a
    strict xfail then: the reference offset below)."""
    d = walk_ubx[0]
    assert np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2)) <= 8.50


@pytest.mark.xfail(strict=True, reason=(
    "3.72 m measured in session 16 (3.80 m before the IMU time offset from the phase) with the log's "
    "broadcast Klobuchar coefficients (CNAV type 30; 2.01 m with RTKLIB's "
    "default coefficients, which the log does not use): the mean height is -3.55 m from the reference and "
    "a dual-frequency (ionosphere-free) GPS solution, which needs no model, puts it at -3.25 m: the "
    "reference (its height conversion) sits ~3 m above every broadcast solution; issue 40's V <= 3.5 m "
    "target against this reference is a decision asked of the issue's owner"))
def test_walk_default_vertical_rms_within_3_5_m(walk_ubx):
    d = walk_ubx[0]
    assert np.sqrt(np.mean(d[:, 2] ** 2)) <= 3.5


def test_walk_default_3_sigma_coverage(walk_ubx):
    """Measured 98.3 / 100 / 100 % in the session-14 merge (east 52.7 % with Galileo alone: ten satellites
    bring the east σ to ~2 m against the reference's east offset)."""
    d, s, *_ = walk_ubx
    assert np.all(np.mean(np.abs(d) <= 3 * s, axis=0) >= 0.95)


def test_walk_the_ubx_satellites_move_the_solution_as_its_sigma_says(walk_ubx, walk_dir):
    """Without a truth free of the reference's offset, the filter's own σ is checked against itself: the
    solution with the navigation file alone (σ_N) and with the UBX log's records too (σ_U ≤ σ_N: a superset
    of the satellites) differ by an amount whose variance, for nested optimal estimators, is σ_N² − σ_U² per
    axis; ≥ 95 % of the reference epochs within 3 of those σ (measured with the Galileo records: mean
    differences without − with E/N/U +1.30/−2.93/+1.27 m, σ 2.5/4.2/8.7 m)."""
    from aidnav.apps.tight import process_tight
    from aidnav.filters.tight import to_trajectory
    from aidnav.io.rinex import read_rinex_nav
    from aidnav.nav.earth import lla_difference_enu

    _, _, res_u, (obs, eph, _, ref, imu, _) = walk_ubx
    nav = read_rinex_nav(walk_dir / "rinex_converted" / "gnss_1730.nav", systems=TightConfig().gnss.systems)
    res, _ = process_tight(imu, obs, nav.to_week(obs.ref_week), None)
    # the reference epochs inside both runs (with the UBX log's satellites the IMU-GNSS time offset is
    # estimated from the phase and moves the IMU's span by d̂: gnss.time_offset_from_phase)
    tr, tr_u = to_trajectory(res), to_trajectory(res_u)
    sel = (ref.time >= max(tr.time[0], tr_u.time[0])) & (ref.time <= min(tr.time[-1], tr_u.time[-1]))

    def at(t):
        j = np.clip(np.searchsorted(t.time, ref.time[sel]), 0, len(t.time) - 1)
        return np.column_stack(lla_difference_enu(t.lat[j], t.lon[j], t.height[j], ref.lat[sel], ref.lon[sel],
                                                  ref.height[sel])), t.std_pos[j]

    (d_n, s_n), (d, s) = at(tr), at(tr_u)
    assert len(d_n) > 500
    var = s_n**2 - s**2
    assert np.all(np.median(var, axis=0) > 0)  # the UBX log's satellites shrink every axis' σ
    z = (d_n - d) / np.sqrt(np.maximum(var, 1e-6))
    print("mean difference", np.round((d_n - d).mean(0), 2), "sigma", np.round(np.sqrt(np.median(var, 0)), 2))
    assert np.all(np.mean(np.abs(z) <= 3, axis=0) >= 0.95)


def test_walk_galileo_group_delay_as_the_icd_applies_it(walk_ubx):
    """The single-frequency E1 user's clock is the I/NAV clock − BGD(E1, E5b) (OS SIS ICD §5.1.5; RTKLIB
    pntpos: P − BGD): with it the SPP post-fit residuals of the Galileo satellites are smallest (measured
    RMS 1.15 m; 1.82 m without the BGD, 2.78 m with its sign flipped) and the Galileo inter-system bias
    (GST − GPST and the receiver's E1/L1 bias) is near 0 (measured median −0.04 m)."""
    from aidnav.estimators.spp import spp_series
    from aidnav.nav.gnss_sat import E_PRN, E_TGD, SYSTEMS
    from aidnav.nav.gnss_types import GpsEphemerides

    _, _, _, (obs, eph, *_) = walk_ubx
    gal = eph.table[:, E_PRN] // 100 == SYSTEMS.index("E")
    is_gal = np.array([sat_name(p)[0] == "E" for p in obs.prn])
    rms, isb = [], []
    for sign in (1.0, 0.0, -1.0):
        t = eph.table.copy()
        t[gal, E_TGD] *= sign
        sp = spp_series(obs, GpsEphemerides(t, eph.ref_week), sigma0=3.0, iono="klobuchar", mask_deg=10.0)
        rms.append(np.sqrt(np.nanmean(sp["residuals"][:, is_gal] ** 2)))
        isb.append(np.nanmedian(sp["isb_m"]["E"]))
    print("Galileo post-fit residual RMS", np.round(rms, 2), "ISB", np.round(isb, 2))
    assert rms[0] < rms[1] < rms[2] and abs(isb[0]) < 1.0
