"""GPS CNAV ephemerides (L2C / L5 message types 10, 11 and 30) from u-blox UBX-RXM-SFRBX → ephemeris rows.

**Why.** A receiver that tracks L2C or L5 decodes a satellite's CNAV messages (12 s each) independently of
its L1 C/A LNAV subframes (6 s each, a full set every 30 s). In a short log a satellite may have a complete
CNAV data set and no complete LNAV one (the walk of issue 40: G08, G18, G24); these records fill such
satellites. For L1 C/A users LNAV is the primary source: :func:`aidnav.io.rinex.read_rinex_pair` adds a
CNAV record only for a satellite with no LNAV record (its merge rule).

**The message** (IS-GPS-200 §30.3.3; bit numbers 1–300 of a message): preamble 10001011 (1–8), PRN (9–14),
message type (15–20), TOW count of the next message [6 s] (21–37), alert (38); the message's CRC-24Q
(the same code as Galileo's, :func:`aidnav.io.galileo_inav.crc24q`) over bits 1–276 in bits 277–300.
Type 10 (Table 30-I): week number (13 bits), L1/L2/L5 health, t_op, URA_ED index, toe, ΔA (from A_ref
= 26 559 710 m), Ȧ, Δn0, Δn0-dot, M0, e, ω. Type 11 (Table 30-II): toe, Ω0, i0, ΔΩ̇ (from Ω̇_ref =
−2.6e-9 semicircles/s), i0-dot, C_is, C_ic, C_rs, C_rc, C_us, C_uc. Types 30–37 (Table 30-III) start with
the clock: t_op, URA_NED0–2, toc, a_f0, a_f1, a_f2; type 30 adds T_GD and the inter-signal corrections
ISC (L1 C/A, L2C, L5I5, L5Q5) and the Klobuchar coefficients α0–α3, β0–β3 (the LNAV parameters, same
scales; §30.3.3.3.1.2; the reader returns those of the last type 30 in the log). u-blox delivers a
message as 10 words of 32 bits (sigId 3/4: L2 CL/CM, 6/7: L5 I/Q): the 300 bits are the first 300 of the
320 (checked on the walk: all 40 L2 CM and 108 L5 I messages pass their CRC in that reading).

**A data set** is messages 10 and 11 of one satellite with the same toe and a message 30 whose toc is that
toe (the latest of each kept); once per (satellite, toe). Its clock for an L1 C/A pseudorange is
a_f0 + a_f1 Δt + a_f2 Δt² + Δt_r − (T_GD − ISC_L1C/A) (§30.3.3.3.1.1.1), so the row's group delay
(``E_TGD``, which the L1 user subtracts) is T_GD − ISC_L1C/A. URA [m] is √(URA_ED² + URA_NED0²) of the
indices' nominal values (2^(1 + N/2) for N ≤ 6, 2^(N − 2) above; the NED terms' rates are not used); health
is the L1 bit.

**The orbit** (Table 30-II) differs from LNAV's in two terms: the semi-major axis changes in time, A_k =
A0 + Ȧ t_k, and the mean-motion correction too, Δn_A = Δn0 + ½ Δn0-dot t_k (with n0 from A0). The rows of
:mod:`aidnav.nav.gnss_sat` have neither, so a record is *re-epoched* to a time t_ref (the middle of the
log's observation epochs): toe := t_ref, a := A_k(t_ref), M0 := M_k(t_ref), Δn := Ṁ_k(t_ref) − √(μ/a³),
i0 := i_k(t_ref), Ω0 so that Ω_k(t_ref) is unchanged, and the radius rate Ȧ (1 − e cos E) at t_ref
carried by a sinusoid added to C_rs, C_rc that is zero at t_ref: K sin(2φ − 2φ(t_ref)), K = Ȧ (1 − e cos
E)/(2 v̇) (off by K x³/6, x = 2 v̇ (t − t_ref): 20 µm at 67 s, 1.5 cm at 10 min). The position is then
exact at t_ref and so are the rates; what is left is the mean anomaly's ½ Δn0-dot (t − t_ref)² along the
track: measured against :func:`cnav_state` (the ICD's full equations) on the walk ≤ 4 mm over its 134 s
(0.1 mm/s). The rows are meant for the log's span: ~0.3 m at 10 min from t_ref, metres at an hour
(:func:`aidnav.io.rinex.read_rinex_pair` warns past :data:`aidnav.io.rinex.CNAV_SPAN_S`). A CNAV row has
IODE −1.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from aidnav.io.errors import DataError
from aidnav.io.galileo_inav import crc24q
from aidnav.io.gpstime import SECONDS_PER_WEEK
from aidnav.io.sfrbx import near_week, read_sfrbx
from aidnav.nav.gnss_sat import (
    E_AF0,
    E_AF1,
    E_AF2,
    E_CIC,
    E_CIS,
    E_CRC,
    E_CRS,
    E_CUC,
    E_CUS,
    E_DN,
    E_ECC,
    E_FIT,
    E_HEALTH,
    E_I0,
    E_IDOT,
    E_IODE,
    E_M0,
    E_OMEGA,
    E_OMEGA0,
    E_OMEGADOT,
    E_PRN,
    E_SQRTA,
    E_TGD,
    E_TOC,
    E_TOE,
    E_TOES,
    E_URA,
    E_WEEK,
    GM_GPS,
    N_EPH,
    OMEGA_E_GPS,
    PI_GPS,
    eccentric_anomaly,
)
from aidnav.nav.gnss_types import GpsEphemerides

__all__ = ["MESSAGE_FIELDS", "A_REF", "OMEGADOT_REF", "cnav_message", "decode_message", "assemble",
           "cnav_state", "cnav_row", "read_ubx_gps_cnav", "ura_nominal_m"]

A_REF = 26559710.0  #: CNAV reference semi-major axis [m] (IS-GPS-200 Table 30-II)
OMEGADOT_REF = -2.6e-9 * PI_GPS  #: CNAV reference rate of right ascension [rad/s]
_SC = PI_GPS
_HEAD = [("preamble", 1, 8, False, 1), ("prn", 9, 6, False, 1), ("type", 15, 6, False, 1),
         ("tow", 21, 17, False, 6.0), ("alert", 38, 1, False, 1)]
_CLOCK = [("top", 39, 11, False, 300.0), ("ura_ned0", 50, 5, True, 1), ("ura_ned1", 55, 3, False, 1),
          ("ura_ned2", 58, 3, False, 1), ("toc", 61, 11, False, 300.0), ("af0", 72, 26, True, 2.0**-35),
          ("af1", 98, 20, True, 2.0**-48), ("af2", 118, 10, True, 2.0**-60)]
#: Fields per message type: (name, first bit 1–300, bits, signed, scale) — IS-GPS-200 Tables 30-I to 30-III
MESSAGE_FIELDS = {
    10: _HEAD + [("wn", 39, 13, False, 1), ("health", 52, 3, False, 1), ("top", 55, 11, False, 300.0),
                 ("ura_ed", 66, 5, True, 1), ("toe", 71, 11, False, 300.0), ("da", 82, 26, True, 2.0**-9),
                 ("adot", 108, 25, True, 2.0**-21), ("dn0", 133, 17, True, 2.0**-44 * _SC),
                 ("dn0dot", 150, 23, True, 2.0**-57 * _SC), ("m0", 173, 33, True, 2.0**-32 * _SC),
                 ("ecc", 206, 33, False, 2.0**-34), ("omega", 239, 33, True, 2.0**-32 * _SC),
                 ("isf", 272, 1, False, 1), ("l2c_phasing", 273, 1, False, 1)],
    11: _HEAD + [("toe", 39, 11, False, 300.0), ("omega0", 50, 33, True, 2.0**-32 * _SC),
                 ("i0", 83, 33, True, 2.0**-32 * _SC), ("domegadot", 116, 17, True, 2.0**-44 * _SC),
                 ("idot", 133, 15, True, 2.0**-44 * _SC), ("cis", 148, 16, True, 2.0**-30),
                 ("cic", 164, 16, True, 2.0**-30), ("crs", 180, 24, True, 2.0**-8),
                 ("crc", 204, 24, True, 2.0**-8), ("cus", 228, 21, True, 2.0**-30),
                 ("cuc", 249, 21, True, 2.0**-30)],
    30: _HEAD + _CLOCK + [("tgd", 128, 13, True, 2.0**-35), ("isc_l1ca", 141, 13, True, 2.0**-35),
                          ("isc_l2c", 154, 13, True, 2.0**-35), ("isc_l5i5", 167, 13, True, 2.0**-35),
                          ("isc_l5q5", 180, 13, True, 2.0**-35), ("alpha0", 193, 8, True, 2.0**-30),
                          ("alpha1", 201, 8, True, 2.0**-27), ("alpha2", 209, 8, True, 2.0**-24),
                          ("alpha3", 217, 8, True, 2.0**-24), ("beta0", 225, 8, True, 2.0**11),
                          ("beta1", 233, 8, True, 2.0**14), ("beta2", 241, 8, True, 2.0**16),
                          ("beta3", 249, 8, True, 2.0**16)],
}
_NOT_AVAILABLE = -(2**12) * 2.0**-35  # T_GD / ISC "1000000000000": not available (§30.3.3.3.1.1.2)
_L2C_L5_SIGNALS = (3, 4, 6, 7)  # u-blox sigId of GPS L2 CL, L2 CM, L5 I, L5 Q


def cnav_message(dwrds) -> tuple[int | None, str]:
    """The 300-bit CNAV message of one u-blox SFRBX frame (10 words: the first 300 of 320 bits), or (None,
    why not): "length", "preamble", "crc"."""
    if len(dwrds) != 10:
        return None, "length"
    v = 0
    for w in dwrds:
        v = (v << 32) | (int(w) & 0xFFFFFFFF)
    msg = v >> 20
    if msg >> 292 != 0b10001011:
        return None, "preamble"
    if crc24q((msg >> 24).to_bytes(35, "big")) != msg & 0xFFFFFF:  # 276 bits, 4 zero pad bits
        return None, "crc"
    return msg, "ok"


def decode_message(msg: int) -> dict:
    """Header fields (every type) and, for types 10, 11 and 30, the scaled fields of :data:`MESSAGE_FIELDS`
    of a 300-bit message; types 31–37 give the header and the clock block."""
    mtype = (msg >> (300 - 20)) & 63
    fields = MESSAGE_FIELDS.get(mtype, _HEAD + _CLOCK if 31 <= mtype <= 37 else _HEAD)
    out = {}
    for name, first, n, signed, scale in fields:
        v = (msg >> (300 - first + 1 - n)) & ((1 << n) - 1)
        if signed and v >> (n - 1):
            v -= 1 << n
        out[name] = v * scale
    return out


def ura_nominal_m(index: int) -> float:
    """Nominal value [m] of a URA_ED / URA_NED0 index N (IS-GPS-200 §30.3.3.1.1.4: 2^(1 + N/2) for N ≤ 6,
    2^(N − 2) for 6 < N < 15; 15: NaN, no accuracy prediction)."""
    n = int(index)
    if n <= 6:
        return 2.0 ** (1.0 + n / 2.0)
    return 2.0 ** (n - 2) if n < 15 else float("nan")


def _elements(m10: dict, m11: dict, tk: float):
    """A_k, n_A (mean motion), M_k, Ṁ_k of the ICD's CNAV equations at t_k."""
    a0 = A_REF + m10["da"]
    n0 = np.sqrt(GM_GPS / a0**3)
    ak = a0 + m10["adot"] * tk
    mk = m10["m0"] + (n0 + m10["dn0"] + 0.5 * m10["dn0dot"] * tk) * tk
    mk_dot = n0 + m10["dn0"] + m10["dn0dot"] * tk
    return ak, mk, mk_dot


def cnav_state(m10: dict, m11: dict, toe_sow: float, t_sow: float) -> np.ndarray:
    """ECEF position [m] of a CNAV data set at GPS time of week ``t_sow`` by IS-GPS-200 Table 30-II (the
    reference for :func:`cnav_row`'s re-epoching)."""
    tk = t_sow - toe_sow
    ak, mk, _ = _elements(m10, m11, tk)
    ecc = m10["ecc"]
    ek = eccentric_anomaly(mk, ecc)
    vk = np.arctan2(np.sqrt(1.0 - ecc * ecc) * np.sin(ek), np.cos(ek) - ecc)
    phi = vk + m10["omega"]
    s2, c2 = np.sin(2 * phi), np.cos(2 * phi)
    u = phi + m11["cus"] * s2 + m11["cuc"] * c2
    r = ak * (1.0 - ecc * np.cos(ek)) + m11["crs"] * s2 + m11["crc"] * c2
    inc = m11["i0"] + m11["idot"] * tk + m11["cis"] * s2 + m11["cic"] * c2
    om = m11["omega0"] + (OMEGADOT_REF + m11["domegadot"] - OMEGA_E_GPS) * tk - OMEGA_E_GPS * toe_sow
    xp, yp = r * np.cos(u), r * np.sin(u)
    return np.array([xp * np.cos(om) - yp * np.cos(inc) * np.sin(om),
                     xp * np.sin(om) + yp * np.cos(inc) * np.cos(om), yp * np.sin(inc)])


def cnav_row(prn: int, m: dict, ref_week: int, t_ref: float | None) -> np.ndarray:
    """The ephemeris row of a CNAV data set ``m`` (types 10, 11, 30) re-epoched to ``t_ref`` [s on the
    ``ref_week`` scale] (module doc; None: at its toe, i.e. Ȧ and Δn0-dot dropped)."""
    m10, m11, m30 = m[10], m[11], m[30]
    wn = int(m10["wn"])
    tow = m10["tow"]  # the next message's start (within 12 s of this one's: enough for ± half a week)
    wk_toe, wk_toc = near_week(m10["toe"], wn, tow), near_week(m30["toc"], wn, tow)
    toe = (wk_toe - ref_week) * SECONDS_PER_WEEK + m10["toe"]
    t_ref = toe if t_ref is None else float(t_ref)
    tk = t_ref - toe
    ak, mk, mk_dot = _elements(m10, m11, tk)
    toes = (ref_week * SECONDS_PER_WEEK + t_ref) % SECONDS_PER_WEEK  # t_ref's own second of week
    omega_dot = OMEGADOT_REF + m11["domegadot"]
    r = np.zeros(N_EPH)
    r[E_PRN] = prn
    r[E_WEEK] = wk_toe
    r[E_TOE], r[E_TOES] = t_ref, toes
    r[E_TOC] = (wk_toc - ref_week) * SECONDS_PER_WEEK + m30["toc"]
    r[E_AF0], r[E_AF1], r[E_AF2] = m30["af0"], m30["af1"], m30["af2"]
    r[E_SQRTA], r[E_ECC], r[E_OMEGA] = np.sqrt(ak), m10["ecc"], m10["omega"]
    r[E_M0], r[E_DN] = mk, mk_dot - np.sqrt(GM_GPS / ak**3)
    r[E_I0], r[E_IDOT] = m11["i0"] + m11["idot"] * tk, m11["idot"]
    r[E_OMEGADOT] = omega_dot
    # Ω_k = Ω0 + (Ω̇ − ω_e) t_k − ω_e toe_sow kept at t_ref with the row's own toe
    r[E_OMEGA0] = (m11["omega0"] + (omega_dot - OMEGA_E_GPS) * tk - OMEGA_E_GPS * m10["toe"]
                   + OMEGA_E_GPS * toes)
    # Ȧ: a radius rate Ȧ (1 − e cos E) at t_ref as a sinusoid of 2φ through zero at φ(t_ref) (module doc)
    ecc = m10["ecc"]
    ek = eccentric_anomaly(mk, ecc)
    den = 1.0 - ecc * np.cos(ek)
    phi0 = np.arctan2(np.sqrt(1.0 - ecc * ecc) * np.sin(ek), np.cos(ek) - ecc) + m10["omega"]
    k = m10["adot"] * den / (2.0 * mk_dot * np.sqrt(1.0 - ecc * ecc) / den**2)  # Ȧ (1 − e cos E) / (2 v̇)
    r[E_CUC], r[E_CUS] = m11["cuc"], m11["cus"]
    r[E_CRS], r[E_CRC] = m11["crs"] + k * np.cos(2 * phi0), m11["crc"] - k * np.sin(2 * phi0)
    r[E_CIC], r[E_CIS] = m11["cic"], m11["cis"]
    tgd = 0.0 if m30["tgd"] == _NOT_AVAILABLE else m30["tgd"]
    isc = 0.0 if m30["isc_l1ca"] == _NOT_AVAILABLE else m30["isc_l1ca"]
    r[E_TGD] = tgd - isc
    r[E_HEALTH] = (int(m10["health"]) >> 2) & 1  # the L1 bit (L1, L2, L5: most significant first)
    r[E_IODE] = -1.0  # CNAV has no IODE (a data set is its toe): −1 also marks a CNAV row
    r[E_URA] = float(np.hypot(ura_nominal_m(m10["ura_ed"]), ura_nominal_m(m30["ura_ned0"])))
    r[E_FIT] = 3.0  # a CNAV data set's curve fit is 3 h (§30.3.3.1.1)
    return r


def assemble(messages, ref_week: int, t_ref: float | None = None) -> tuple[np.ndarray, Counter, list]:
    """Complete CNAV data sets → rows (:func:`cnav_row`).

    messages : iterable of (PRN, fields of :func:`decode_message`) in reception order. Per satellite the
    latest message 10, 11 and 30 are kept; a row is made when types 10 and 11 share a toe and type 30's toc
    is that toe, once per (satellite, toe). Returns (rows (K, N_EPH), counts, the data sets (PRN, dict))."""
    held: dict[int, dict] = {}
    done: set = set()
    rows, sets, count = [], [], Counter()
    for prn, f in messages:
        mtype = int(f["type"])
        count[f"type {mtype}"] += 1
        if mtype not in (10, 11, 30):
            continue
        m = held.setdefault(int(prn), {})
        m[mtype] = f
        if len(m) < 3:
            continue
        if not m[10]["toe"] == m[11]["toe"] == m[30]["toc"]:
            count["toe/toc differ (waiting)"] += 1
            continue
        key = (int(prn), m[10]["toe"])
        if key in done:
            continue
        done.add(key)
        rows.append(cnav_row(int(prn), m, ref_week, t_ref))
        sets.append((int(prn), dict(m)))
    return (np.array(rows) if rows else np.zeros((0, N_EPH))), count, sets


def read_ubx_gps_cnav(path, ref_week: int | None = None, log=None) -> GpsEphemerides:
    """The GPS CNAV data sets broadcast on L2C and L5 in the RXM-SFRBX frames of the UBX log ``path``
    (module doc), re-epoched to the middle of the log's RXM-RAWX epochs, on the GPS week ``ref_week``
    (default: the log's first RXM-RAWX week), with the Klobuchar coefficients of the last type 30 (None
    without one). Raises DataError when the file is missing or holds no complete CNAV data set (or no
    RXM-RAWX to date it)."""
    path = Path(path)
    log = read_sfrbx(path) if log is None else log
    if log.rawx_week is None or log.rawx_span is None:
        raise DataError(path, None, "no UBX-RXM-RAWX in this log to date its CNAV data sets")
    ref = int(log.rawx_week) if ref_week is None else int(ref_week)
    t_ref = 0.5 * (log.rawx_span[0] + log.rawx_span[1]) + (int(log.rawx_week) - ref) * SECONDS_PER_WEEK
    messages, count = [], Counter()
    for sv, sig, words in log.of(0):
        if sig not in _L2C_L5_SIGNALS:
            continue
        msg, why = cnav_message(words)
        count[f"messages {why}"] += 1
        if msg is not None:
            f = decode_message(msg)
            if int(f["prn"]) != int(sv):
                count["PRN differs from svId"] += 1
                continue
            messages.append((sv, f))
    rows, c2, _ = assemble(messages, ref, t_ref)
    count.update(c2)
    alpha = beta = None
    t30 = [f for _, f in messages if int(f["type"]) == 30]
    if t30:  # the Klobuchar coefficients of the last type 30 received (the latest upload)
        alpha = np.array([t30[-1][f"alpha{i}"] for i in range(4)])
        beta = np.array([t30[-1][f"beta{i}"] for i in range(4)])
    if len(rows) == 0:
        raise DataError(path, None, "no complete GPS CNAV data set (messages 10, 11, 30 of one toe) in the "
                        "RXM-SFRBX frames of this log")
    rows = rows[np.lexsort((rows[:, E_TOE], rows[:, E_PRN]))]
    n_sat = len(np.unique(rows[:, E_PRN]))
    events = [f"{path.name}: GPS CNAV: {len(rows)} data set(s) of {n_sat} satellite(s), re-epoched to "
              f"t = {t_ref % SECONDS_PER_WEEK:.0f} s of week; " + ", ".join(f"{k} {v}" for k, v in
                                                                            sorted(count.items()))]
    bad = int(np.sum(rows[:, E_HEALTH] != 0))
    if bad:
        events.append(f"{path.name}: {bad} GPS CNAV record(s) flagged unhealthy on L1 (not used)")
    return GpsEphemerides(rows, ref, alpha, beta, events)
