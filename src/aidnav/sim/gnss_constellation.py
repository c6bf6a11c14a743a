"""Nominal GPS constellation for simulations at any place and time: Keplerian almanac-like orbits as
ephemeris records (the format of :mod:`aidnav.nav.gnss_sat`, zero harmonic terms).

Slots: the baseline 24-slot constellation of the GPS SPS Performance Standard (2001, Table 3-1):
six planes A–F, RAAN 272.847° + 60°·k at the defined epoch 1993-07-01 00:00 (Greenwich hour angle
18 h 36 min 14.4 s), four slots per plane with the tabulated arguments of latitude; inclination 55°,
semi-major axis 26 559.7 km, circular orbits, nodal regression −4.4874e-7 deg/s. Satellites 25–31
(``n_sats`` > 24) go into planes A, B, C, D, E, F, A at the middle of the plane's widest gap in
argument of latitude (like the expandable slots of later standards; not their exact positions).

Propagation to any time t (GPS seconds since the defined epoch; the 9 s GPS−UTC of 1993 neglected):
u(t) = u_slot + n t with n = √(μ/a³); RAAN(t) = RAAN_slot + Ω̇ t; the geographic longitude of the
ascending node λ(t) = RAAN(t) − (GHA₀ + ω_e t). Each satellite becomes one ephemeris record with toe at
the chosen reference time (M0 = u(toe), ω = 0, Ω0 = λ(toe) + ω_e·toe as in IS-GPS-200), valid at all
times (it is exactly Keplerian). The geometry is "nominal", not the real sky of that date.
"""

from __future__ import annotations

import numpy as np

from aidnav.io.gpstime import SECONDS_PER_WEEK, calendar_to_week_sow
from aidnav.nav.gnss_sat import (
    E_FIT,
    E_HEALTH,
    E_I0,
    E_M0,
    E_OMEGA0,
    E_OMEGADOT,
    E_PRN,
    E_SQRTA,
    E_TOC,
    E_TOE,
    E_TOES,
    E_URA,
    E_WEEK,
    G_FCN,
    G_POS,
    G_VEL,
    GM_BDS,
    GM_GAL,
    GM_GPS,
    MU_GLO,
    N_EPH,
    OMEGA_E_BDS,
    OMEGA_E_GLO,
    OMEGA_E_GPS,
    SYSTEMS,
    sat_states,
    visible,
)
from aidnav.nav.gnss_types import GpsEphemerides
from aidnav.nav.rotations import wrap_360, wrap_pi

__all__ = ["SLOTS_24", "nominal_constellation", "visible_satellites", "walker_constellation",
           "nominal_multi_constellation", "WALKER"]

#: (plane, slot, RAAN [deg], argument of latitude [deg]) at 1993-07-01 00:00 (SPS PS 2001, Table 3-1)
SLOTS_24 = (
    ("A", 1, 272.847, 268.126),
    ("A", 2, 272.847, 161.786),
    ("A", 3, 272.847, 11.676),
    ("A", 4, 272.847, 41.806),
    ("B", 1, 332.847, 80.956),
    ("B", 2, 332.847, 173.336),
    ("B", 3, 332.847, 309.976),
    ("B", 4, 332.847, 204.376),
    ("C", 1, 32.847, 111.876),
    ("C", 2, 32.847, 11.796),
    ("C", 3, 32.847, 339.666),
    ("C", 4, 32.847, 241.556),
    ("D", 1, 92.847, 135.226),
    ("D", 2, 92.847, 265.446),
    ("D", 3, 92.847, 35.156),
    ("D", 4, 92.847, 167.356),
    ("E", 1, 152.847, 197.046),
    ("E", 2, 152.847, 302.596),
    ("E", 3, 152.847, 66.066),
    ("E", 4, 152.847, 333.686),
    ("F", 1, 212.847, 238.886),
    ("F", 2, 212.847, 345.226),
    ("F", 3, 212.847, 105.206),
    ("F", 4, 212.847, 135.346),
)
_EPOCH_1993 = "1993-07-01T00:00:00"
_GHA0_DEG = (18 + 36 / 60 + 14.4 / 3600) * 15.0
_A_NOM = 26559.7e3
_OMEGA_DOT = np.radians(-4.4874e-7)  # rad/s
_EXTRA_PLANES = "ABCDEFA"


def _slots(n_sats: int):
    if not 1 <= n_sats <= 31:
        raise ValueError("n_sats must be in 1..31")
    slots = [(p, s, r, u) for p, s, r, u in SLOTS_24]
    for k in range(max(0, n_sats - 24)):
        plane = _EXTRA_PLANES[k]
        us = np.sort([u for p, _, _, u in slots if p == plane])
        gaps = np.diff(np.r_[us, us[0] + 360.0])
        i = int(np.argmax(gaps))
        raan = next(r for p, _, r, _ in slots if p == plane)
        slots.append(
            (
                plane,
                5 + sum(1 for p, *_ in slots[24:] if p == plane),
                raan,
                float(wrap_360(us[i] + gaps[i] / 2)),
            )
        )
    return slots[:n_sats]


def nominal_constellation(
    week: int, sow: float, n_sats: int = 24, inclination_deg: float = 55.0, ref_week: int | None = None
) -> GpsEphemerides:
    """Ephemeris records of the nominal constellation with toe = toc = (week, sow) (GPS time).

    n_sats : 1–31 (PRN 1…n in slot order A1…F4, then the extra slots). ref_week : week of the table's
    time scale (default ``week``). Clock terms are zero (the simulator adds satellite clock errors).
    Returns :class:`aidnav.nav.gnss_types.GpsEphemerides` (no Klobuchar coefficients).
    """
    ref_week = int(week if ref_week is None else ref_week)
    w0, s0 = calendar_to_week_sow(_EPOCH_1993)
    t_since = (week - w0) * SECONDS_PER_WEEK + (sow - s0)
    n = np.sqrt(GM_GPS / _A_NOM**3)
    toe = (week - ref_week) * SECONDS_PER_WEEK + sow
    rows = []
    for k, (_, _, raan, u) in enumerate(_slots(n_sats)):
        r = np.zeros(N_EPH)
        r[E_PRN] = k + 1
        r[E_WEEK] = week
        r[E_TOE] = toe
        r[E_TOC] = toe
        r[E_TOES] = toe  # Ω0 below is referred to this scale
        r[E_SQRTA] = np.sqrt(_A_NOM)
        r[E_I0] = np.radians(inclination_deg)
        u_t = np.radians(u) + n * t_since
        lam = np.radians(raan) + _OMEGA_DOT * t_since - (np.radians(_GHA0_DEG) + OMEGA_E_GPS * t_since)
        r[E_M0] = wrap_pi(u_t)
        # IS-GPS-200: Ω_k = Ω0 + (Ω̇ − ω_e) t_k − ω_e toe; at t_k = 0 this must be λ(toe)
        r[E_OMEGA0] = wrap_pi(lam + OMEGA_E_GPS * toe)
        r[E_OMEGADOT] = _OMEGA_DOT
        r[E_HEALTH] = 0.0
        r[E_FIT] = 1e6
        rows.append(r)
    return GpsEphemerides(
        np.array(rows),
        ref_week,
        None,
        None,
        [f"nominal {n_sats}-satellite GPS constellation (SPS PS 2001 slots), toe {week}/{sow:.0f}"],
    )


def visible_satellites(eph: GpsEphemerides, t: float, rx_ecef, mask_deg: float = 5.0):
    """PRNs (array), azimuths and elevations [rad] of the satellites above ``mask_deg`` at GPS time ``t``
    (reference-week scale of ``eph``) seen from ``rx_ecef`` (3,) [m], sorted by decreasing elevation."""
    idx = np.arange(len(eph.table), dtype=np.int64)
    pos, _, _, _ = sat_states(eph.table, idx, float(t))
    vis, az, el = visible(pos, rx_ecef, mask_deg)
    order = np.argsort(-np.where(vis, el, -np.inf))
    order = order[vis[order]]
    return eph.table[order, E_PRN].astype(int), az[order], el[order]


#: nominal MEO constellations as Walker i:T/P/F patterns: (semi-major axis [m], inclination [deg], satellites
#: T, planes P, phasing F): Galileo 24/3/1 at 29 600 km, 56° (Galileo OS SDD); BeiDou-3 MEO 24/3/1 at
#: 27 906 km, 55° (BeiDou OS SIS ICD; no GEO/IGSO here); GLONASS 24/3/1 at 25 510 km, 64.8° (GLONASS ICD)
WALKER = {"E": (29600.0e3, 56.0, 24, 3, 1), "C": (27906.1e3, 55.0, 24, 3, 1),
          "R": (25510.0e3, 64.8, 24, 3, 1)}


def walker_constellation(system: str, week: int, sow: float, ref_week: int | None = None,
                         node0_deg: float = 0.0, ura_m: float = 2.0) -> np.ndarray:
    """Ephemeris records (K, N_EPH) of the nominal ``system`` ("E", "C" or "R") constellation of
    :data:`WALKER` with toe = toc = (week, sow) GPS time: circular orbits, Earth-fixed node longitudes
    ``node0_deg`` + 360°·p/P at toe, arguments of latitude 360°·(s/S + F·p/T) (the geometry is nominal, not
    the real sky). PRNs 1…24 (BeiDou 19…42: PRN 1–5 and 59–63 are GEO satellites). Galileo/BeiDou:
    Keplerian records on the GPS scale (``E_TOES`` = toe on that scale, the
    node referred to it, like :func:`nominal_constellation`); GLONASS: the PZ-90 state at t_b (Earth-fixed
    position and velocity of the circular orbit; the RK4 propagation then adds J2), channels k = −7…6 in
    turn, no luni-solar acceleration. Clock terms zero."""
    a, inc_deg, T, P, F = WALKER[system]
    ref_week = int(week if ref_week is None else ref_week)
    toe = (week - ref_week) * SECONDS_PER_WEEK + sow
    sys = SYSTEMS.index(system)
    gm = {"E": GM_GAL, "C": GM_BDS, "R": MU_GLO}[system]
    om_e = {"E": OMEGA_E_GPS, "C": OMEGA_E_BDS, "R": OMEGA_E_GLO}[system]
    n = np.sqrt(gm / a**3)
    inc = np.radians(inc_deg)
    per = T // P
    rows = []
    for k in range(T):
        p, q = divmod(k, per)
        lam = np.radians(node0_deg + 360.0 * p / P)
        u = np.radians(360.0 * (q / per + F * p / T))
        r = np.zeros(N_EPH)
        r[E_PRN] = 100 * sys + k + 1 + (18 if system == "C" else 0)  # BeiDou: C19…C42 (C01–C05 are GEO)
        r[E_WEEK], r[E_TOE], r[E_TOC], r[E_TOES] = week, toe, toe, toe
        r[E_FIT], r[E_URA] = 1e6, ura_m
        if system != "R":
            r[E_SQRTA], r[E_I0], r[E_M0] = np.sqrt(a), inc, wrap_pi(u)
            r[E_OMEGA0] = wrap_pi(lam + om_e * toe)
        else:
            cu, su, cl, sl, ci, si = np.cos(u), np.sin(u), np.cos(lam), np.sin(lam), np.cos(inc), np.sin(inc)
            pos = a * np.array([cl * cu - sl * su * ci, sl * cu + cl * su * ci, su * si])
            vi = a * n * np.array([-cl * su - sl * cu * ci, -sl * su + cl * cu * ci, cu * si])
            r[G_POS:G_POS + 3] = pos
            r[G_VEL:G_VEL + 3] = vi - np.cross([0.0, 0.0, om_e], pos)  # Earth-fixed velocity
            r[G_FCN] = (k % 14) - 7
        rows.append(r)
    return np.array(rows)


def nominal_multi_constellation(week: int, sow: float, systems: str = "GE", n_gps: int = 24,
                                ref_week: int | None = None, node0_deg: dict | None = None) -> GpsEphemerides:
    """GPS (:func:`nominal_constellation`) and the nominal Galileo / BeiDou / GLONASS constellations of
    :data:`WALKER` (``systems``: letters of "GECR") in one table (satellite ids of
    :mod:`aidnav.nav.gnss_sat`); ``node0_deg`` per letter (default 0°)."""
    tabs = []
    if "G" in systems:
        g = nominal_constellation(week, sow, n_gps, ref_week=ref_week).table.copy()
        g[:, E_URA] = 2.0
        tabs.append(g)
    for s in "ECR":
        if s in systems:
            tabs.append(walker_constellation(s, week, sow, ref_week, (node0_deg or {}).get(s, 0.0)))
    return GpsEphemerides(np.vstack(tabs), int(week if ref_week is None else ref_week), None, None,
                          [f"nominal {systems} constellations (GPS SPS PS slots, Walker patterns), toe "
                           f"{week}/{sow:.0f}"])
