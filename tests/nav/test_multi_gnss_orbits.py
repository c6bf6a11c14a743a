"""Orbits of every constellation (issue 40 item 4): GLONASS by the ICD's Runge-Kutta against the ICD's
worked example and an independent inertial-frame integration, BeiDou GEO's rotation against a
geostationary record, Galileo/BeiDou MEO records against Kepler's third law."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from aidnav.nav.gnss_sat import (
    E_AF0,
    E_AF1,
    E_AF2,
    E_ECC,
    E_I0,
    E_M0,
    E_OMEGA0,
    E_PRN,
    E_SQRTA,
    E_TGD,
    E_TOC,
    E_TOE,
    E_TOES,
    G_POS,
    G_VEL,
    GM_BDS,
    J2_GLO,
    MU_GLO,
    N_EPH,
    OMEGA_E_BDS,
    OMEGA_E_GLO,
    RE_GLO,
    eccentric_anomaly,
    eccentric_anomaly_from,
    eph_clock,
    eph_state,
    glonass_orbit,
    sat_from_pseudorange,
    sat_from_pseudorange_once,
    sat_from_pseudorange_scalars,
    sat_id,
    sat_name,
)


def test_glonass_rk4_reproduces_the_icd_worked_example():
    """GLONASS ICD (CDMA general description 2016, Appendix J.1): state at t_b = 11700 s, propagated to
    t_i = 12300 s; the ICD's precise result 7523.174819, −10506.961965, 21999.239413 km and 0.950126007,
    2.855687825, 1.040679862 km/s (its simplified algorithm, which aidnav's is, differs by ~0.5 m)."""
    x0 = np.array([7003.008789e3, -12206.626953e3, 21280.765625e3, 0.7835417e3, 2.8042530e3, 1.3525150e3])
    acc = np.array([0.0, 1.7e-6, -5.41e-6])  # 1.7e-9, -5.41e-9 km/s²
    x = glonass_orbit(x0, acc, 600.0, 60.0)
    ref_p = np.array([7523.174819e3, -10506.961965e3, 21999.239413e3])
    ref_v = np.array([0.950126007e3, 2.855687825e3, 1.040679862e3])
    dp, dv = np.linalg.norm(x[:3] - ref_p), np.linalg.norm(x[3:] - ref_v)
    print(f"ICD example: position {dp:.3f} m, velocity {1e3 * dv:.2f} mm/s")
    assert dp < 1.5 and dv < 5e-3


def test_glonass_rk4_agrees_with_an_inertial_frame_integration():
    """The same J2 field integrated in the inertial frame by scipy's DOP853 (tolerance 1e-12) and turned
    back into the rotating frame: the 60-s RK4 of the ICD agrees to < 1 cm over ±15 min."""
    x0 = np.array([7003.008789e3, -12206.626953e3, 21280.765625e3, 0.7835417e3, 2.8042530e3, 1.3525150e3])
    w = OMEGA_E_GLO

    def f(_, y):
        r = y[:3]
        r2 = r @ r
        rn = np.sqrt(r2)
        k = 1.5 * J2_GLO * MU_GLO * RE_GLO**2 / rn**5
        z2 = 5 * r[2] ** 2 / r2
        a = -MU_GLO / rn**3 * r - k * np.array([r[0] * (1 - z2), r[1] * (1 - z2), r[2] * (3 - z2)])
        return np.r_[y[3:], a]

    yi = np.r_[x0[:3], x0[3:] + np.cross([0, 0, w], x0[:3])]  # inertial = rotating at t_b
    for tk in (900.0, -900.0, 437.0):
        sol = solve_ivp(f, (0, tk), yi, method="DOP853", rtol=1e-12, atol=1e-6)
        ri, vi = sol.y[:3, -1], sol.y[3:, -1]
        c, s = np.cos(w * tk), np.sin(w * tk)
        R = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])  # inertial → rotating after tk
        r_ref = R @ ri
        v_ref = R @ (vi - np.cross([0, 0, w], ri))
        x = glonass_orbit(x0, np.zeros(3), tk, 60.0)
        assert np.linalg.norm(x[:3] - r_ref) < 0.01
        assert np.linalg.norm(x[3:] - v_ref) < 1e-5


def _kepler_record(sid, a, inc, om0, m0, toe):
    r = np.zeros(N_EPH)
    r[E_PRN], r[E_SQRTA], r[E_I0], r[E_OMEGA0], r[E_M0] = sid, np.sqrt(a), inc, om0, m0
    r[E_TOE] = r[E_TOC] = r[E_TOES] = toe
    return r


def test_the_clock_alone_is_eph_states_clock_bit_for_bit():
    """``eph_clock`` (the transmit-time passes' clock without the orbit, issue 40) returns exactly the
    dts of ``eph_state`` for a Keplerian record of every system (GPS, Galileo, BeiDou MEO and GEO) with an
    eccentric orbit, a clock polynomial and its relativistic term, over ±2 h."""
    for name in ("G05", "E11", "C25", "C03"):
        rec = _kepler_record(sat_id(name), 26560e3, np.radians(55.0), 0.3, 0.2, 345600.0)
        rec[E_ECC], rec[E_AF0], rec[E_AF1], rec[E_AF2] = 0.013, 1.7e-4, -3.2e-12, 1e-19
        for dt in (-7200.0, -0.07, 0.0, 13.7, 7199.0):
            dts = eph_state(rec, 345600.0 + dt)[2]
            assert eph_clock(rec, 345600.0 + dt) == dts and abs(dts - 1.7e-4) < 1e-7


def test_beidou_geo_record_of_a_geostationary_satellite_stays_put():
    """BeiDou GEO elements are given in a frame tilted by 5° (ICD 5.2.4.12): a circular record with
    i0 = 5°, the node at 180° and n = ω_e (CGCS2000) is a geostationary satellite: on the equator, fixed in
    the Earth frame over ±6 h, at the radius a."""
    a = (GM_BDS / OMEGA_E_BDS**2) ** (1 / 3)
    toe = 345600.0
    rec = _kepler_record(sat_id("C03"), a, np.radians(5.0), np.pi + OMEGA_E_BDS * toe, 0.7, toe)
    p0, _, _, _ = eph_state(rec, toe)
    for dt in (-21600.0, -3600.0, 10.0, 7200.0, 21600.0):
        p, v, _, _ = eph_state(rec, toe + dt)
        assert abs(p[2]) < 1.0 and np.linalg.norm(p - p0) < 1.0 and np.linalg.norm(v) < 1e-3
        assert abs(np.linalg.norm(p) - a) < 1.0
    # the same record as a MEO satellite (C19) moves: the GEO branch is taken by the PRN
    p, _, _, _ = eph_state(_kepler_record(sat_id("C19"), a, np.radians(5.0), np.pi, 0.7, toe), toe + 3600)
    assert np.linalg.norm(p - p0) > 1e5


def test_galileo_and_beidou_meo_records_follow_keplers_third_law():
    """A circular record of each system returns to the same inertial place after one period 2π√(a³/μ)
    with the system's μ (Galileo 3.986004418e14; the Earth-fixed position then differs by the Earth's
    rotation over the period, ω_e of the system)."""
    for name, a, om_e in (("E11", 29600e3, 7.2921151467e-5), ("C25", 27906.1e3, OMEGA_E_BDS)):
        rec = _kepler_record(sat_id(name), a, np.radians(56.0), 0.3, 0.2, 0.0)
        per = 2 * np.pi * np.sqrt(a**3 / 3.986004418e14)
        p0, _, _, _ = eph_state(rec, 0.0)
        p1, _, _, _ = eph_state(rec, per)
        c, s = np.cos(om_e * per), np.sin(om_e * per)
        assert np.linalg.norm(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ p1 - p0) < 1e-3
    assert sat_name(sat_id("R07")) == "R07" and sat_id("G05") == 5


def _parse_rinex3_beidou(text):
    """BeiDou records of a RINEX 3 navigation file, field by field (independent of georinex): (name,
    the 31 numbers after the epoch)."""
    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    recs = []
    while i < len(lines):
        ln = lines[i]
        if not ln.startswith("C"):
            i += 1
            continue
        block = lines[i:i + 8]
        vals = [float(block[0][23 + 19 * m:42 + 19 * m].replace("D", "E")) for m in range(3)]
        for b in block[1:]:
            for m in range(4):
                f = b[4 + 19 * m:23 + 19 * m].replace("D", "E").strip()
                vals.append(float(f) if f else 0.0)
        recs.append((ln[:3], vals))
        i += 8
    return recs


def _bds_textbook(v, t_bdt):
    """BeiDou ICD (B1I 2.1, 5.2.4.12) MEO/IGSO position at BDT seconds of week t_bdt, CGCS2000 constants."""
    mu, we = 3.986004418e14, 7.2921150e-5
    (_aode, crs, dn, m0, cuc, e, cus, sqrta, toe, cic, om0, cis, i0, crc, w, omdot, idot) = v[3:20]
    a = sqrta**2
    tk = t_bdt - toe
    mk = m0 + (np.sqrt(mu / a**3) + dn) * tk
    ek = mk
    for _ in range(50):
        ek = mk + e * np.sin(ek)
    phi = np.arctan2(np.sqrt(1 - e**2) * np.sin(ek), np.cos(ek) - e) + w
    u = phi + cus * np.sin(2 * phi) + cuc * np.cos(2 * phi)
    r = a * (1 - e * np.cos(ek)) + crs * np.sin(2 * phi) + crc * np.cos(2 * phi)
    inc = i0 + idot * tk + cis * np.sin(2 * phi) + cic * np.cos(2 * phi)
    om = om0 + (omdot - we) * tk - we * toe
    x, y = r * np.cos(u), r * np.sin(u)
    ci, so, co = np.cos(inc), np.sin(om), np.cos(om)
    return np.array([x * co - y * ci * so, x * so + y * ci * co, y * np.sin(inc)])


def test_walk_beidou_records_against_the_icd_in_bdt(walk_nav_file, walk_nav):
    """The walk's navigation file holds 8 BeiDou-3 MEO records (the data set has no BeiDou observations):
    read through georinex onto the GPS scale (BDT + 14 s, week + 1356), they give the positions of the ICD's
    algorithm evaluated in BDT from a plain-text parse, to < 1 mm over ±2 h (a 14-s error would be ~50 km)."""
    nav = walk_nav
    recs = _parse_rinex3_beidou(walk_nav_file.read_text())
    assert len(recs) == 8
    worst = 0.0
    for name, v in recs:
        row = nav.table[nav.table[:, E_PRN] == sat_id(name)][0]
        toe, week = v[3 + 8], v[3 + 18]
        shift = (week + 1356 - nav.ref_week) * 604800 + 14.0
        for dt in np.arange(-7200.0, 7200.1, 1200.0):
            pos, _, _, _ = eph_state(row, shift + toe + dt)
            ref = _bds_textbook(v, toe + dt)
            worst = max(worst, float(np.linalg.norm(pos - ref)))
            assert 2.6e7 < np.linalg.norm(ref) < 2.95e7  # MEO
    print("worst BeiDou orbit difference [m]:", worst)
    assert worst < 1e-3


def test_pseudorange_state_as_scalars_is_the_array_path_bit_for_bit():
    """``sat_from_pseudorange_scalars`` (the tight filter's epoch rows, issue 40 session 17: no arrays per
    satellite) returns exactly ``sat_from_pseudorange``'s position, velocity, clock and rate for a record of
    every system (GPS, Galileo, BeiDou MEO and GEO, GLONASS), with and without T_GD."""
    recs = []
    for name in ("G05", "E11", "C25", "C03"):
        rec = _kepler_record(sat_id(name), 26560e3, np.radians(55.0), 0.3, 0.2, 345600.0)
        rec[E_ECC], rec[E_AF0], rec[E_AF1], rec[E_AF2], rec[E_TGD] = 0.013, 1.7e-4, -3.2e-12, 1e-19, 4e-9
        recs.append(rec)
    glo = np.zeros(N_EPH)
    glo[E_PRN], glo[E_TOE], glo[E_AF0], glo[E_AF1] = sat_id("R05"), 345600.0, 2e-5, 1e-12
    glo[G_POS:G_POS + 3] = 7003.008789e3, -12206.626953e3, 21280.765625e3
    glo[G_VEL:G_VEL + 3] = 0.7835417e3, 2.8042530e3, 1.3525150e3
    recs.append(glo)
    for rec in recs:
        for dt, pr in ((-1500.0, 2.1e7), (0.0, 2.25e7), (913.7, 2.4e7)):
            for tgd in (True, False):
                p, v, dts, ddts = sat_from_pseudorange(rec, 345600.0 + dt, pr, tgd)
                got = sat_from_pseudorange_scalars(rec, 345600.0 + dt, pr, tgd)
                assert got == (*p, *v, dts, ddts) and np.all(np.isfinite(got))


def _glonass_and_sbas_records():
    glo = np.zeros(N_EPH)
    glo[E_PRN], glo[E_TOE], glo[E_AF0], glo[E_AF1] = sat_id("R05"), 345600.0, 2e-5, 1e-12
    glo[G_POS:G_POS + 3] = 7003.008789e3, -12206.626953e3, 21280.765625e3
    glo[G_VEL:G_VEL + 3] = 0.7835417e3, 2.8042530e3, 1.3525150e3
    sbs = np.zeros(N_EPH)
    sbs[E_PRN], sbs[E_TOE], sbs[E_AF0], sbs[E_AF1] = sat_id("S31"), 345600.0, -3e-8, 2e-12
    sbs[G_POS:G_POS + 3] = 24000e3, 33000e3, 100e3
    sbs[G_VEL:G_VEL + 3] = 1.0, -0.5, 0.2
    return glo, sbs


def test_glonass_and_sbas_clocks_alone_are_eph_states_bit_for_bit():
    """``eph_clock`` of a GLONASS and an SBAS record (no orbit propagated since session 18: the transmit-time
    passes propagated the GLONASS orbit twice for its linear clock) is exactly ``eph_state``'s dts."""
    for rec in _glonass_and_sbas_records():
        for dt in (-300.0, -0.07, 0.0, 13.7, 299.0):
            assert eph_clock(rec, 345600.0 + dt) == eph_state(rec, 345600.0 + dt)[2]


def test_pseudorange_state_with_one_kepler_solve_is_the_passes_to_round_off():
    """``sat_from_pseudorange_once`` (the tight filter's epoch rows, issue 40 session 18: one Kepler solve a
    satellite and epoch, warm-started from the satellite's previous one) against ``sat_from_pseudorange``
    (two transmit-time clock passes, then the state; three cold solves): a Keplerian record of every system
    (GPS, Galileo, BeiDou MEO; eccentric, with a clock polynomial and T_GD) over 1 h of 1-s epochs and
    after jumps the warm start must not take (> 0.1 rad of mean anomaly): position within 1e-6 m (an ulp
    of the transmit time near 4e5 s, 6e-11 s, is 2.3e-7 m of orbit; an ulp of E_k, 9e-16 rad, 2.4e-8 m),
    velocity within 1e-9 m/s, clock within 1e-18 s (a 1e-3 s offset's ulp is 2e-19 s), its rate within
    1e-20; BeiDou GEO and GLONASS/SBAS records go through the passes: the same bits, and no warm state."""
    for name in ("G05", "E11", "C25"):
        rec = _kepler_record(sat_id(name), 26560e3, np.radians(55.0), 0.3, 0.2, 345600.0)
        rec[E_ECC], rec[E_AF0], rec[E_AF1], rec[E_AF2], rec[E_TGD] = 0.02, 6.7e-4, -3.2e-12, 1e-19, 4e-9
        warm, worst, steps = np.full(3, np.nan), np.zeros(4), 0
        t_rx = 345600.0 - 1800.0 + np.r_[np.arange(3600.0) + 0.0731, 5000.0, 5001.0, 3000.0, 3001.0]
        pr = 2.2e7 + 6e5 * np.sin(t_rx / 900.0)
        for k, (t, p) in enumerate(zip(t_rx, pr, strict=True)):
            tgd = k % 2 == 0
            pos, vel, dts, ddts = sat_from_pseudorange(rec, t, p, tgd)
            m_prev = warm[1]
            got = sat_from_pseudorange_once(rec, t, p, tgd, warm)
            steps += abs(warm[1] - m_prev) < 0.1  # warm-started
            worst = np.maximum(worst, [np.max(np.abs(np.array(got[0:3]) - pos)),
                                       np.max(np.abs(np.array(got[3:6]) - vel)), abs(got[6] - dts),
                                       abs(got[7] - ddts)])
            assert np.isfinite(warm).all() and abs(warm[0] - eccentric_anomaly(warm[1], 0.02)) < 1e-13
        print(name, "largest differences (position m, velocity m/s, clock s, rate):", worst)
        assert worst[0] < 1e-6 and worst[1] < 1e-9 and worst[2] < 1e-18 and worst[3] < 1e-20
        assert steps == len(t_rx) - 3  # the first epoch and the two jumps start cold
    geo = _kepler_record(sat_id("C03"), 42164e3, np.radians(1.0), 0.3, 0.2, 345600.0)
    for rec in (geo, *_glonass_and_sbas_records()):
        warm = np.array([1.0, 2.0, 1.0])
        for t in (345600.0 - 200.0, 345600.0 + 13.7):
            assert sat_from_pseudorange_once(rec, t, 3.7e7, True, warm) == sat_from_pseudorange_scalars(
                rec, t, 3.7e7, True) and np.isnan(warm[0])


def test_eccentric_anomaly_from_any_start_solves_keplers_equation():
    """Newton's iteration from a warm start converges to the same root as from M (within 2 ulps of E) for
    starts off by up to 0.5 rad, eccentricities to 0.1; from M it is ``eccentric_anomaly`` itself."""
    rng = np.random.default_rng(4)
    for _ in range(500):
        mk, ecc = rng.uniform(-4.0, 10.0), rng.uniform(0.0, 0.1)
        ek = eccentric_anomaly(mk, ecc)
        assert abs(ek - ecc * np.sin(ek) - mk) < 1e-14
        assert eccentric_anomaly_from(mk, ecc, mk) == ek
        start = ek + rng.uniform(-0.5, 0.5)
        assert abs(eccentric_anomaly_from(mk, ecc, start) - ek) <= 2 * np.spacing(abs(ek))
