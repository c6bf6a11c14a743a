"""SPP with every constellation (issue 40 item 4): known answers from error-free pseudoranges of a static
receiver — simulated directly, and written to RINEX 3 navigation/observation files by a small writer here
(the RINEX 3.04 record layouts: BeiDou epochs and toe in BDT, GLONASS epochs in UTC, PZ-90 state in km) and
read back through georinex — with inter-system biases as unknowns."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.estimators.spp import spp
from aidnav.io.gpstime import week_sow_to_gpst_unix
from aidnav.io.rinex import read_rinex_nav, read_rinex_obs
from aidnav.nav.earth import lla_to_ecef
from aidnav.nav.gnss_sat import (
    E_AF0,
    E_AF1,
    E_CIC,
    E_CIS,
    E_CRC,
    E_CRS,
    E_CUC,
    E_CUS,
    E_DN,
    E_ECC,
    E_I0,
    E_IDOT,
    E_M0,
    E_OMEGA,
    E_OMEGA0,
    E_OMEGADOT,
    E_PRN,
    E_SQRTA,
    E_TOE,
    E_TOES,
    E_URA,
    G_ACC,
    G_FCN,
    G_POS,
    G_VEL,
    OMEGA_E_BDS,
    OMEGA_E_GPS,
    sat_name,
    satellites_from_pseudoranges,
)
from aidnav.sim.gnss_constellation import nominal_multi_constellation
from aidnav.sim.gnss_raw import static_pseudoranges

WEEK, SOW = 2381, 400000.0
RX = np.array(lla_to_ecef(np.radians(45.3), np.radians(10.7), 250.0))
ISB = {"E": 7.5, "C": -12.25, "R": 25.0}
CLOCK = 1234.5


def _pseudoranges(eph, t):
    pr, el = static_pseudoranges(eph, t, RX, clock_m=CLOCK, mask_deg=10.0)
    for j, sid in enumerate(eph.table[:, E_PRN].astype(int)):
        pr[j] += ISB.get(sat_name(sid)[0], 0.0)
    return pr, el


def _solve(table, ids, t, pr, freq=None):
    pos, _, clk, _ = satellites_from_pseudoranges(table, ids, t, pr, use_tgd=False, max_age_s=3600.0)
    return spp(pos, clk, pr, prns=ids, t_sow=t, tropo=False, mask_deg=10.0, freq=freq)


def test_spp_with_four_systems_recovers_position_clock_and_inter_system_biases():
    eph = nominal_multi_constellation(WEEK, SOW, "GECR", node0_deg={"E": 20.0, "C": 50.0, "R": 80.0})
    t = SOW + 30.0
    pr, el = _pseudoranges(eph, t)
    ids = eph.table[:, E_PRN].astype(int)
    vis = np.isfinite(pr)
    assert {sat_name(i)[0] for i in ids[vis]} == set("GECR")
    r = _solve(eph.table, ids, t, pr)
    assert r.status == "ok" and r.reference_system == "G"
    assert np.linalg.norm(r.ecef - RX) < 1e-3 and abs(r.clock_m - CLOCK) < 1e-3
    for c, b in ISB.items():
        assert abs(r.isb_m[c] - b) < 1e-3
    # 3 GPS + 2 Galileo: five unknowns, five satellites; 2 + 2 is one short
    keep = np.zeros(len(ids), bool)
    g, e = np.flatnonzero(vis & (ids < 100)), np.flatnonzero(vis & (ids // 100 == 1))
    keep[g[:3]] = keep[e[:2]] = True
    r5 = _solve(eph.table, ids, t, np.where(keep, pr, np.nan))
    assert r5.n_used == 5 and np.linalg.norm(r5.ecef - RX) < 1e-3 and abs(r5.isb_m["E"] - ISB["E"]) < 1e-3
    keep[g[2]] = False
    assert _solve(eph.table, ids, t, np.where(keep, pr, np.nan)).status == "too few satellites"
    # one system only (Galileo): its clock is the reference, no inter-system bias
    only_e = np.where(ids // 100 == 1, pr, np.nan)
    re = _solve(eph.table, ids, t, only_e)
    assert re.reference_system == "E" and not re.isb_m and abs(re.clock_m - CLOCK - ISB["E"]) < 1e-3


# ---------------------------------------------------------------- RINEX 3 writer (the format's layouts)
def _cal(unix):
    return np.datetime64(int(round(unix)), "s").astype(object)


def _num(v):
    return f"{v:19.12E}".replace("E", "D")


def _lines(first, vals):
    out = [first + "".join(_num(v) for v in vals[:3])]
    rest = vals[3:]
    for k in range(0, len(rest), 4):
        out.append("    " + "".join(_num(v) for v in rest[k:k + 4]))
    return out


def _nav_text(eph):
    out = ["     3.04           N: GNSS NAV DATA    M: Mixed            RINEX VERSION / TYPE",
           "                                                            END OF HEADER"]
    for r in eph.table:
        name = sat_name(r[E_PRN])
        sysl = name[0]
        t_gps = week_sow_to_gpst_unix(WEEK, r[E_TOE])
        if sysl == "R":  # epoch in UTC (GPST − 18 s in 2025), PZ-90 state in km
            d = _cal(t_gps - 18.0)
            vals = [r[E_AF0], r[E_AF1], 0.0]
            for k in range(3):
                vals += [r[G_POS + k] / 1e3, r[G_VEL + k] / 1e3, r[G_ACC + k] / 1e3,
                         [0.0, r[G_FCN], 0.0][k]]
        else:
            off = 14.0 if sysl == "C" else 0.0  # BDT = GPST − 14 s
            d = _cal(t_gps - off)
            toes = r[E_TOE] - off
            om_e = OMEGA_E_BDS if sysl == "C" else OMEGA_E_GPS
            om0 = r[E_OMEGA0] + om_e * (toes - r[E_TOES])  # Ω0 referred to the system's week
            week = {"G": WEEK, "E": WEEK, "C": WEEK - 1356}[sysl]
            vals = [r[E_AF0], r[E_AF1], 0.0, 0.0, r[E_CRS], r[E_DN], r[E_M0], r[E_CUC], r[E_ECC], r[E_CUS],
                    r[E_SQRTA], toes, r[E_CIC], om0, r[E_CIS], r[E_I0], r[E_CRC], r[E_OMEGA], r[E_OMEGADOT],
                    r[E_IDOT], 0.0, week, 0.0, r[E_URA], 0.0, 0.0, 0.0, toes]
            vals += {"G": [4.0], "E": [], "C": [0.0]}[sysl]
        out += _lines(f"{name} {d.year:04d} {d.month:02d} {d.day:02d} {d.hour:02d} {d.minute:02d} "
                      f"{d.second:02d}", vals)
    return "\n".join(out) + "\n"


def _obs_text(ids, times, prs):
    code = {"G": "C1C", "E": "C1C", "C": "C2I", "R": "C1C"}
    out = ["     3.04           OBSERVATION DATA    M: Mixed            RINEX VERSION / TYPE"]
    for s_ in "GECR":
        out.append(f"{s_}    2 {code[s_]} S{code[s_][1:]}".ljust(60) + "SYS / # / OBS TYPES")
    d = _cal(week_sow_to_gpst_unix(WEEK, times[0]))
    out.append(f"  {d.year:04d}    {d.month:02d}    {d.day:02d}    {d.hour:02d}    {d.minute:02d}   "
               f"{d.second:02d}.0000000     GPS".ljust(60) + "TIME OF FIRST OBS")
    out.append(" " * 60 + "END OF HEADER")
    for t, pr in zip(times, prs, strict=True):
        d = _cal(week_sow_to_gpst_unix(WEEK, t))
        ok = np.flatnonzero(np.isfinite(pr))
        out.append(f"> {d.year:04d} {d.month:02d} {d.day:02d} {d.hour:02d} {d.minute:02d} "
                   f"{d.second:2d}.0000000  0{len(ok):3d}")
        for j in ok:
            out.append(f"{sat_name(ids[j])}{pr[j]:14.3f}  {45.0:14.3f}  ")
    return "\n".join(out) + "\n"


def test_rinex3_files_of_four_systems_read_back_to_the_known_position(tmp_path):
    eph = nominal_multi_constellation(WEEK, SOW, "GECR", node0_deg={"E": 20.0, "C": 50.0, "R": 80.0})
    ids = eph.table[:, E_PRN].astype(int)
    times = SOW + np.array([30.0, 31.0, 32.0])
    prs = [np.round(_pseudoranges(eph, t)[0], 3) for t in times]
    (tmp_path / "m.nav").write_text(_nav_text(eph))
    (tmp_path / "m.obs").write_text(_obs_text(ids, times, prs))
    nav = read_rinex_nav(tmp_path / "m.nav")
    assert len(nav.table) == len(eph.table)
    assert any("records per system G 24, E 24, C 24, R 24" in e for e in nav.events)
    obs = read_rinex_obs(tmp_path / "m.obs", systems="GECR").with_frequencies(nav)
    assert set(n[0] for n in obs.names) == set("GECR")
    glo = np.array([n[0] == "R" for n in obs.names])
    ch = np.array([nav.table[nav.table[:, E_PRN] == i][0, G_FCN] for i in obs.prn[glo]])
    assert np.all(np.isfinite(obs.freq1)) and np.allclose(obs.freq1[glo], 1602e6 + 0.5625e6 * ch)
    for k, t in enumerate(obs.time):
        assert t == pytest.approx(times[k], abs=1e-6)
        r = _solve(nav.table, obs.prn, t, obs.code1[k], freq=obs.freq1)
        assert r.status == "ok"
        print(f"epoch {k}: {np.linalg.norm(r.ecef - RX):.4f} m, ISB", r.isb_m)
        assert np.linalg.norm(r.ecef - RX) < 0.02  # pseudoranges written to the mm
        for c, b in ISB.items():
            assert abs(r.isb_m[c] - b) < 0.02
    # GPS only (the default of the observation reader): the other systems are left out
    assert set(n[0] for n in read_rinex_obs(tmp_path / "m.obs").names) == {"G"}


def test_sbas_ranges_on_the_gps_clock():
    """An SBAS GEO record (state vector at t0, quadratic over ≤ 360 s as RTKLIB's seph2pos) is one more
    satellite on the GPS clock: 4 GPS + 1 SBAS solve with one redundancy and no inter-system bias."""
    from aidnav.nav.gnss_sat import E_HEALTH, SYS_SBS, eph_state
    from aidnav.nav.gnss_types import GpsEphemerides

    g = nominal_multi_constellation(WEEK, SOW, "G").table
    t = SOW + 30.0
    pr_g, el = static_pseudoranges(GpsEphemerides(g, WEEK), t, RX, clock_m=CLOCK, mask_deg=10.0)
    vis = np.flatnonzero(np.isfinite(pr_g))[:4]
    s = np.zeros_like(g[0])
    s[E_PRN], s[E_TOE], s[E_HEALTH] = 100 * SYS_SBS + 31, SOW, 0.0
    lon = np.radians(15.0)
    s[G_POS:G_POS + 3] = 42164e3 * np.array([np.cos(lon), np.sin(lon), 0.0])
    s[G_VEL:G_VEL + 3] = [0.3, -0.2, 1.0]
    s[G_ACC:G_ACC + 3] = [1e-5, 2e-5, -1e-5]
    p, v, _, _ = eph_state(s, SOW + 100.0)
    assert np.allclose(p, s[G_POS:G_POS + 3] + 100.0 * s[G_VEL:G_VEL + 3] + 5e3 * s[G_ACC:G_ACC + 3])
    table = np.vstack([g[vis], s])
    pr, _ = static_pseudoranges(GpsEphemerides(table, WEEK), t, RX, clock_m=CLOCK, mask_deg=10.0)
    ids = table[:, E_PRN].astype(int)
    assert np.isfinite(pr).all() and sat_name(ids[-1]) == "S31"
    r = _solve(table, ids, t, pr)
    assert r.status == "ok" and not r.isb_m and np.linalg.norm(r.ecef - RX) < 1e-3
