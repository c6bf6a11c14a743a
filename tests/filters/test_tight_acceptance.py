"""Acceptance tests of issue 15 (seed 001): two-satellite tight coupling against free inertial and dead
reckoning (Monte Carlo), broadcast-ephemeris orbits against an independent implementation, and bad GNSS
input (missing ephemeris, NaN pseudorange, 1 km blunder) in SPP and the tight filter."""

from __future__ import annotations

import copy

import numpy as np
from scipy.stats import binomtest

from aidnav.data import ImuData
from aidnav.estimators.dgps import dead_reckon, satellites_from_pseudoranges, spp, spp_series
from aidnav.filters.tight import TightConfig, run_tight
from aidnav.filters.tuning import loose_config_from_specs
from aidnav.nav.earth import lla_difference_enu, radii
from aidnav.nav.gnss_sat import E_PRN, eph_state
from aidnav.nav.gnss_types import GnssObservations
from aidnav.sim.gnss_constellation import nominal_constellation
from aidnav.sim.gnss_raw import RawGnssSpec, limit_satellites, simulate_raw_gnss
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth

SOW = 400000.0
T_OUT = 60.0  # all satellites before, 2 satellites (or none) from here to the end (~62 s)
SCN = parse_scenario(
    {
        "initial": {"lat_deg": 34.2, "lon_deg": 108.9, "height_m": 1000, "speed_m_s": 60, "heading_deg": 30},
        "imu_rate_hz": 50,
        "transition_s": 2.0,
        "segments": [
            {"type": "straight", "duration_s": 60},
            {"type": "turn", "angle_deg": 60, "rate_deg_s": 3},
            {"type": "straight", "duration_s": 42},
        ],
    }
)
TRUTH, IMU_TRUE, _ = generate_truth(SCN)
GSPEC = RawGnssSpec(rate_hz=1.0)
SPEC = ImuSpec.grade("tactical")


def _eph():
    eph = nominal_constellation(2381, SOW, 24)
    eph.iono_alpha, eph.iono_beta = GSPEC.iono_alpha, GSPEC.iono_beta
    return eph


def _cfg():
    return TightConfig(
        states=17,
        imu=loose_config_from_specs(SPEC, sensor_model=False).imu,  # 15 INS states: the model before issue 35
        constraints={"zupt": False},
        init={
            "attitude_sigma_deg": (0.05, 0.05, 0.3),
            "position_sigma_m": (3, 3, 3),
            "velocity_sigma_m_s": (0.1, 0.1, 0.1),
        },
        gnss={"code_sigma_m": 1.0, "rate_sigma_m_s": 0.06, "mask_deg": 5.0, "range_errors": False},
    )


def _run_inputs(seed, eph):
    rng = np.random.default_rng(seed)
    imu_c, _ = corrupt_imu(IMU_TRUE, SPEC, rng)
    imu = ImuData(imu_c.time + SOW, imu_c.dtheta, imu_c.dv, t0=imu_c.t0 + SOW)
    sim = simulate_raw_gnss(TRUTH, eph, GSPEC, rng, SOW)
    dp = rng.normal(0, 2.0, 3)
    rm, rn = radii(TRUTH.lat[0])
    h = TRUTH.height[0]
    init = (
        SOW + TRUTH.time[0],
        TRUTH.lat[0] + dp[1] / (rm + h),
        TRUTH.lon[0] + dp[0] / ((rn + h) * np.cos(TRUTH.lat[0])),
        h + dp[2],
        TRUTH.vel[0] + rng.normal(0, 0.1, 3),
        TRUTH.rph[0] + np.radians([0.05, 0.05, 0.3]) * rng.standard_normal(3),
    )
    return imu, sim, init


def _enu_error(res):
    """(N, 3) ENU position error [m] of a TightResult, the times relative to the truth, truth indices."""
    tt = res.time - SOW
    j = np.clip(np.searchsorted(TRUTH.time, tt - 1e-9), 0, len(TRUTH.time) - 1)
    s = res.state
    de, dn, du = lla_difference_enu(s[:, 0], s[:, 1], s[:, 2], TRUTH.lat[j], TRUTH.lon[j], TRUTH.height[j])
    return np.column_stack([de, dn, du]), tt, j


# ------------------------------------------------------------------ 1. two satellites, Monte Carlo
def test_two_satellite_tight_coupling_drifts_less_than_free_inertial_and_dead_reckoning():
    """60 s of all-satellite tight coupling, then 60 s (a 60° turn then straight) with the 2 satellites of
    widest azimuth spread. Compared over the same 60 s with the same IMU, GNSS and initial errors:

    * loose coupling, which gets no fix from 2 satellites (SPP needs 4): the filter run with no GNSS at
      all in the window = free inertial from the same converged state;
    * dead reckoning of the seed (eqs. 6–7): the relative position integrated (Euler, 50 Hz) from the
      INS velocity of that free-inertial run, frame-rotated, starting from zero at the window start.

    Drift = |position error at the end − position error at the window start| (3-D; dead reckoning starts
    from the exact relative origin, so its error is its drift). Paired sign test over 50 fixed-seed
    runs: H0 "tight is as likely to drift more as less" (p = ½), one-sided exact binomial; the sign
    test needs no distributional assumption about the drifts (heavy-tailed, heading-dominated). At
    α = 1e-3 it needs ≥ 36 wins of 50. Measured: 42/50 (free), 41/50 (DR); medians 9.7, 16.3, 16.4 m.
    """
    eph = _eph()
    cfg = _cfg()
    runs = 50
    d_tight, d_free, d_dr = np.zeros(runs), np.zeros(runs), np.zeros(runs)
    for r in range(runs):
        imu, sim, init = _run_inputs(1000 + r, eph)
        t0 = SOW + TRUTH.time[0]
        el, az = sim.truth["elevation"], sim.truth["azimuth"]
        two = limit_satellites(sim.rover, el, [(T_OUT, 1e4, 2)], t0, how="spread", azimuth=az)
        none = limit_satellites(sim.rover, el, [(T_OUT, 1e4, 0)], t0)
        r2 = run_tight(imu, two, eph, cfg, init_state=init)
        r0 = run_tight(imu, none, eph, cfg, init_state=init)
        e2, tt, j = _enu_error(r2)
        e0, _, _ = _enu_error(r0)
        k = int(np.searchsorted(tt, T_OUT))
        assert np.allclose(e2[k - 1], e0[k - 1])  # identical up to the window
        assert r2.epochs["n_pr"][-5:].max() == 2 and r0.epochs["n_pr"][-5:].max() == 0
        d_tight[r] = np.linalg.norm(e2[-1] - e2[k])
        d_free[r] = np.linalg.norm(e0[-1] - e0[k])
        s = r0.state[k:]
        dr = dead_reckon(r0.time[k:], s[:, 3:6], s[:, 0], s[:, 1], s[0, 0], s[0, 1], np.zeros(3))
        jj = j[k:]
        n = len(jj)
        de, dn, du = lla_difference_enu(
            TRUTH.lat[jj],
            TRUTH.lon[jj],
            TRUTH.height[jj],
            np.full(n, s[0, 0]),
            np.full(n, s[0, 1]),
            np.full(n, s[0, 2]),
        )
        # the truth's relative position measured from the INS start point of the window
        truth_rel = np.array([de[-1] - de[0], dn[-1] - dn[0], du[-1] - du[0]])
        d_dr[r] = np.linalg.norm(dr[-1] - truth_rel)
    print("median drift tight / free / DR [m]:", np.median(d_tight), np.median(d_free), np.median(d_dr))
    w_free = int(np.sum(d_tight < d_free))
    w_dr = int(np.sum(d_tight < d_dr))
    print("wins vs free, vs DR:", w_free, w_dr)
    assert binomtest(w_free, runs, 0.5, alternative="greater").pvalue < 1e-3, w_free
    assert binomtest(w_dr, runs, 0.5, alternative="greater").pvalue < 1e-3, w_dr
    assert np.median(d_tight) < 0.8 * min(np.median(d_free), np.median(d_dr))


# ------------------------------------------------------------------ 2. independent ephemeris check
_MU = 3.986005e14
_OMEGA_E = 7.2921151467e-5


def _parse_rinex3_gps_nav(text):
    """GPS records of a RINEX 3 navigation file, parsed field by field (independent of georinex)."""
    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    recs = []
    while i < len(lines):
        ln = lines[i]
        if not ln.startswith("G"):
            i += 1
            continue
        block = lines[i : i + 8]
        vals = [float(block[0][23 + 19 * m : 42 + 19 * m].replace("D", "E")) for m in range(3)]
        for b in block[1:]:
            for m in range(4):
                f = b[4 + 19 * m : 23 + 19 * m].replace("D", "E").strip()
                vals.append(float(f) if f else 0.0)
        y, mo, d, hh, mi, ss = (int(x) for x in block[0][4:23].split())
        recs.append((int(block[0][1:3]), (y, mo, d, hh, mi, ss), vals))
        i += 8
    return recs


def _is_gps_200_position(v, t):
    """Textbook IS-GPS-200 Table 20-IV user algorithm (ECEF position at GPS time t, seconds of week)."""
    (_iode, crs, dn, m0, cuc, e, cus, sqrta, toe, cic, om0, cis, i0, crc, w, omdot, idot) = v[:17]
    a = sqrta**2
    n = np.sqrt(_MU / a**3) + dn
    tk = t - toe
    if tk > 302400:
        tk -= 604800
    elif tk < -302400:
        tk += 604800
    mk = m0 + n * tk
    ek = mk
    for _ in range(50):
        ek = mk + e * np.sin(ek)
    nu = np.arctan2(np.sqrt(1 - e**2) * np.sin(ek), np.cos(ek) - e)
    phi = nu + w
    u = phi + cus * np.sin(2 * phi) + cuc * np.cos(2 * phi)
    r = a * (1 - e * np.cos(ek)) + crs * np.sin(2 * phi) + crc * np.cos(2 * phi)
    inc = i0 + idot * tk + cis * np.sin(2 * phi) + cic * np.cos(2 * phi)
    x1, y1 = r * np.cos(u), r * np.sin(u)
    om = om0 + (omdot - _OMEGA_E) * tk - _OMEGA_E * toe
    return np.array(
        [
            x1 * np.cos(om) - y1 * np.cos(inc) * np.sin(om),
            x1 * np.sin(om) + y1 * np.cos(inc) * np.cos(om),
            y1 * np.sin(inc),
        ]
    )


def test_broadcast_orbits_agree_with_an_independent_is_gps_200_implementation(walk_nav_file, walk_nav):
    """Walk data set's RINEX nav (read by aidnav through georinex) vs a plain-text parse + textbook
    IS-GPS-200 algorithm, over ±2 h around toe every 10 min: agreement < 1 m (measured: 3e-8 m)."""
    nav = walk_nav
    recs = _parse_rinex3_gps_nav(walk_nav_file.read_text())
    assert len(recs) == int((nav.table[:, E_PRN] < 100).sum()) >= 4  # the GPS records (also 8 BeiDou)
    worst = 0.0
    for prn, _, vals in recs:
        toe = vals[3 + 8]  # sow of toe (reference week = this record's week here)
        week = vals[3 + 18]
        row = nav.table[nav.table[:, E_PRN] == prn][0]
        shift = (week - nav.ref_week) * 604800
        for dt in np.arange(-7200.0, 7200.1, 600.0):
            ref = _is_gps_200_position(vals[3:], toe + dt)
            pos, _, _, _ = eph_state(row, shift + toe + dt)
            worst = max(worst, float(np.linalg.norm(pos - ref)))
            assert 2.0e7 < np.linalg.norm(ref) < 2.7e7
    print("worst orbit difference [m]:", worst)
    assert worst < 1.0


# ------------------------------------------------------------------ 3. bad input: SPP and tight filter
def _bad_case():
    """Simulated all-satellite run with: one satellite in the observations but not in the navigation
    data, a NaN pseudorange on another at epochs 30–34, a +1 km blunder on a third at epoch 40."""
    eph = _eph()
    imu, sim, init = _run_inputs(7, eph)
    obs = sim.rover
    code = obs.code1.copy()
    vis = np.isfinite(code).all(axis=0)
    cand = np.flatnonzero(vis)
    j_noeph, j_nan, j_blunder = (int(c) for c in cand[:3])
    code[30:35, j_nan] = np.nan
    code[40, j_blunder] += 1000.0
    bad_obs = GnssObservations(
        obs.time, obs.ref_week, obs.prn, code, obs.doppler1, obs.cn0, None, None, None, list(obs.events)
    )
    bad_eph = copy.deepcopy(eph)
    bad_eph.table = eph.table[eph.table[:, E_PRN] != obs.prn[j_noeph]]
    return eph, bad_eph, imu, obs, bad_obs, init, (j_noeph, j_nan, j_blunder)


def test_bad_input_in_spp_is_skipped_rejected_and_reported():
    eph, bad_eph, _, obs, bad_obs, _, (j_noeph, j_nan, j_blunder) = _bad_case()
    prn = bad_obs.prn
    # one epoch by hand: the blunder is excluded by the residual check, the others are not used
    k = 40
    pos, _, clk, _ = satellites_from_pseudoranges(bad_eph.table, prn, bad_obs.time[k], bad_obs.code1[k])
    assert not np.isfinite(pos[j_noeph]).any()
    r = spp(pos, clk, bad_obs.code1[k], prns=prn, t_sow=bad_obs.time[k], mask_deg=5.0)
    assert r.status == "excluded" and r.excluded == [prn[j_blunder]]
    assert not r.used[j_noeph] and not r.used[j_blunder]
    sp = spp_series(bad_obs, bad_eph, mask_deg=5.0, velocity=False)
    good = spp_series(obs, eph, mask_deg=5.0, velocity=False)
    assert np.isfinite(sp["lat"]).all()
    assert not np.isfinite(sp["residuals"][:, j_noeph]).any()
    assert not np.isfinite(sp["residuals"][30:35, j_nan]).any() and np.isfinite(sp["residuals"][36, j_nan])
    assert sp["excluded"][40] == [prn[j_blunder]]
    assert all(not e for i, e in enumerate(sp["excluded"]) if i != 40)
    ev = " | ".join(sp["events"])
    assert f"G{prn[j_noeph]:02d}: {len(obs)} epoch(s) with a pseudorange but no usable ephemeris" in ev
    assert f"G{prn[j_blunder]:02d}: excluded by the residual check at 1 epoch(s)" in ev
    assert good["events"] == []
    # nothing of the blunder stays in the fix: it equals the clean epoch's fix without those two satellites
    pos, _, clk, _ = satellites_from_pseudoranges(eph.table, prn, obs.time[k], obs.code1[k])
    drop = np.zeros(len(prn), bool)
    drop[[j_noeph, j_blunder]] = True
    r_ref = spp(
        pos,
        clk,
        obs.code1[k],
        prns=prn,
        t_sow=obs.time[k],
        mask_deg=5.0,
        exclude=drop,
        iono_alpha=eph.iono_alpha,
        iono_beta=eph.iono_beta,
    )
    assert np.linalg.norm(sp["ecef"][k] - r_ref.ecef) < 0.01
    assert np.linalg.norm(good["ecef"][k] - r_ref.ecef) < 10.0


def test_bad_input_in_the_tight_filter_is_skipped_rejected_and_reported():
    eph, bad_eph, imu, obs, bad_obs, init, (j_noeph, j_nan, j_blunder) = _bad_case()
    cfg = _cfg()
    prn = bad_obs.prn
    events: list = []
    res = run_tight(imu, bad_obs, bad_eph, cfg, init_state=init, events=events)
    ref = run_tight(imu, obs, eph, cfg, init_state=init)
    ep = res.epochs
    assert np.all(np.isfinite(res.state))
    # the satellite without ephemeris is never used; the NaN pseudoranges are skipped
    assert not np.isfinite(ep["pr_innov"][:, j_noeph]).any()
    assert not np.isfinite(ep["pr_innov"][30:35, j_nan]).any() and np.isfinite(ep["pr_innov"][36, j_nan])
    # the blunder is rejected by the gate at its epoch (only there)
    nu, s = ep["pr_innov"][40, j_blunder], ep["pr_s"][40, j_blunder]
    assert nu > 900.0 and nu**2 / s > 15.1  # χ²(1) quantile of 0.9999
    assert ep["n_rejected"][40] >= 1 and ep["n_pr"][40] == ep["n_avail"][40] - 1
    assert res.counts["clock_jumps"] == 0
    ev = " | ".join(res.events)
    assert res.events is events
    assert f"G{prn[j_noeph]:02d}: {len(obs)} epoch(s) with a pseudorange but no usable ephemeris" in ev
    assert f"G{prn[j_blunder]:02d}: 1 pseudorange(s)" in ev
    # and the solution stays close to the clean one (one satellite fewer; nothing of the blunder)
    e_bad, _, _ = _enu_error(res)
    e_ref, _, _ = _enu_error(ref)
    assert np.max(np.linalg.norm(e_bad - e_ref, axis=1)) < 5.0  # measured 2.2 m: one satellite fewer
    assert np.max(np.linalg.norm(e_bad, axis=1)) < 10.0
