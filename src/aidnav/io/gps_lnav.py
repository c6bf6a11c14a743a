"""GPS L1 C/A LNAV broadcast ephemerides decoded from u-blox UBX-RXM-SFRBX frames → :class:`GpsEphemerides`.

**The message** (IS-GPS-200, §20.3.2–20.3.5). A subframe is 10 words of 30 bits, each 24 source data bits
d1–d24 (most significant first) and 6 parity bits D25–D30. The transmitted data bits are D_i = d_i ⊕ D30*
(D29*, D30*: the last two bits of the previous word; for word 1 they are 0, since word 10 ends with the
two non-information bits chosen to make its D29 = D30 = 0), and the parity bits are (Table 20-XIV)

    D25 = D29* ⊕ d1 ⊕ d2 ⊕ d3 ⊕ d5 ⊕ d6 ⊕ d10 ⊕ d11 ⊕ d12 ⊕ d13 ⊕ d14 ⊕ d17 ⊕ d18 ⊕ d20 ⊕ d23
    D26 = D30* ⊕ d2 ⊕ d3 ⊕ d4 ⊕ d6 ⊕ d7 ⊕ d11 ⊕ d12 ⊕ d13 ⊕ d14 ⊕ d15 ⊕ d18 ⊕ d19 ⊕ d21 ⊕ d24
    D27 = D29* ⊕ d1 ⊕ d3 ⊕ d4 ⊕ d5 ⊕ d7 ⊕ d8 ⊕ d12 ⊕ d13 ⊕ d14 ⊕ d15 ⊕ d16 ⊕ d19 ⊕ d20 ⊕ d22
    D28 = D30* ⊕ d2 ⊕ d4 ⊕ d5 ⊕ d6 ⊕ d8 ⊕ d9 ⊕ d13 ⊕ d14 ⊕ d15 ⊕ d16 ⊕ d17 ⊕ d20 ⊕ d21 ⊕ d23
    D29 = D30* ⊕ d1 ⊕ d3 ⊕ d5 ⊕ d6 ⊕ d7 ⊕ d9 ⊕ d10 ⊕ d14 ⊕ d15 ⊕ d16 ⊕ d17 ⊕ d18 ⊕ d21 ⊕ d22 ⊕ d24
    D30 = D29* ⊕ d3 ⊕ d5 ⊕ d6 ⊕ d8 ⊕ d9 ⊕ d10 ⊕ d11 ⊕ d13 ⊕ d15 ⊕ d19 ⊕ d22 ⊕ d23 ⊕ d24

Word 1 is the TLM (preamble 10001011, the TLM message, the integrity status flag), word 2 the HOW (the
17-bit TOW count of the next subframe's start [6 s], alert, anti-spoof, the subframe ID). Subframe 1 holds
the week number (10 bits, modulo 1024), URA index, health, IODC, T_GD, t_oc and a_f0–a_f2; subframes 2 and 3
the ephemeris with its IODE (Tables 20-I to 20-III; scale factors there; angles in semicircles, turned into
radians with the ICD's π, as RTKLIB's SC2RAD).

**The u-blox layout** (GPS, sigId 0: 10 words). Each 32-bit word holds the 30-bit word in bits 29–0; the
receiver has already complemented a word whose preceding D30 was 1 (so bits 29–6 are the source data
bits d1–d24), and its bits 31–30 are the previous word's (D29 ⊕ D30, 0), i.e. the word is stored in the
frame where D30* = 0 (checked on the walk's 800 words: every one passes parity in that reading). The
parity check here undoes the receiver's complement to recover the transmitted words (word 1 as stored;
a word is complemented back when the previous transmitted D30 is 1) and checks Table 20-XIV on those —
which needs neither the two top bits nor a u-blox convention beyond the complement. A subframe with a
word of bad parity, a wrong preamble or a subframe ID outside 1–5 is refused and counted.

**A record** is made when subframes 1, 2 and 3 of one satellite (the latest of each) agree on the issue
of data: the 8 least significant bits of IODC = IODE of subframe 2 = IODE of subframe 3 (IS-GPS-200
§20.3.3.4.1); once per (satellite, IODE, toe). Its week is subframe 1's week number unrolled to the one
nearest ``ref_week`` (the observations' week, or the log's first RXM-RAWX week); toe and toc are put in the
week nearest subframe 1's transmit time (± half a week); URA [m] is the URA index's nominal value
(2.0 … 4096 m, as RINEX writers put it), the fit interval from the fit flag and IODC (Table 20-XII; 4 h
when the flag is 0), the health the 6-bit health word.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from aidnav.io.errors import DataError
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
    N_EPH,
    PI_GPS,
)
from aidnav.nav.gnss_types import GpsEphemerides

__all__ = ["PARITY_EQUATIONS", "SUBFRAME_FIELDS", "PREAMBLE", "parity", "word_ok", "ublox_subframe",
           "decode_subframe", "assemble", "read_ubx_gps_lnav", "ura_m", "fit_hours"]

PREAMBLE = 0b10001011
_WORD = (1 << 30) - 1
#: IS-GPS-200 Table 20-XIV: parity bit → (which of D29*/D30* it starts from, the source data bits d_i)
PARITY_EQUATIONS = {
    25: (29, (1, 2, 3, 5, 6, 10, 11, 12, 13, 14, 17, 18, 20, 23)),
    26: (30, (2, 3, 4, 6, 7, 11, 12, 13, 14, 15, 18, 19, 21, 24)),
    27: (29, (1, 3, 4, 5, 7, 8, 12, 13, 14, 15, 16, 19, 20, 22)),
    28: (30, (2, 4, 5, 6, 8, 9, 13, 14, 15, 16, 17, 20, 21, 23)),
    29: (30, (1, 3, 5, 6, 7, 9, 10, 14, 15, 16, 17, 18, 21, 22, 24)),
    30: (29, (3, 5, 6, 8, 9, 10, 11, 13, 15, 19, 22, 23, 24)),
}
_MASKS = [(star, sum(1 << (24 - i) for i in idx)) for star, idx in PARITY_EQUATIONS.values()]

_SC = PI_GPS  # semicircles → rad (IS-GPS-200's π)
#: Fields per subframe: (name, [(word 1–10, first bit 1–24, bits), ...] most significant part first,
#: signed, scale) — IS-GPS-200 Tables 20-I (subframe 1), 20-III (subframes 2, 3); TLM and HOW in all.
_TLM_HOW = [("preamble", [(1, 1, 8)], False, 1), ("tlm", [(1, 9, 14)], False, 1),
            ("isf", [(1, 23, 1)], False, 1), ("tow", [(2, 1, 17)], False, 6.0),
            ("alert", [(2, 18, 1)], False, 1), ("anti_spoof", [(2, 19, 1)], False, 1),
            ("sfid", [(2, 20, 3)], False, 1)]
SUBFRAME_FIELDS = {
    1: _TLM_HOW + [
        ("wn", [(3, 1, 10)], False, 1), ("l2_codes", [(3, 11, 2)], False, 1), ("ura", [(3, 13, 4)], False, 1),
        ("health", [(3, 17, 6)], False, 1), ("iodc", [(3, 23, 2), (8, 1, 8)], False, 1),
        ("l2p_flag", [(4, 1, 1)], False, 1), ("tgd", [(7, 17, 8)], True, 2.0**-31),
        ("toc", [(8, 9, 16)], False, 16.0), ("af2", [(9, 1, 8)], True, 2.0**-55),
        ("af1", [(9, 9, 16)], True, 2.0**-43), ("af0", [(10, 1, 22)], True, 2.0**-31)],
    2: _TLM_HOW + [
        ("iode", [(3, 1, 8)], False, 1), ("crs", [(3, 9, 16)], True, 2.0**-5),
        ("dn", [(4, 1, 16)], True, 2.0**-43 * _SC), ("m0", [(4, 17, 8), (5, 1, 24)], True, 2.0**-31 * _SC),
        ("cuc", [(6, 1, 16)], True, 2.0**-29), ("ecc", [(6, 17, 8), (7, 1, 24)], False, 2.0**-33),
        ("cus", [(8, 1, 16)], True, 2.0**-29), ("sqrta", [(8, 17, 8), (9, 1, 24)], False, 2.0**-19),
        ("toe", [(10, 1, 16)], False, 16.0), ("fit_flag", [(10, 17, 1)], False, 1),
        ("aodo", [(10, 18, 5)], False, 900.0)],
    3: _TLM_HOW + [
        ("cic", [(3, 1, 16)], True, 2.0**-29), ("omega0", [(3, 17, 8), (4, 1, 24)], True, 2.0**-31 * _SC),
        ("cis", [(5, 1, 16)], True, 2.0**-29), ("i0", [(5, 17, 8), (6, 1, 24)], True, 2.0**-31 * _SC),
        ("crc", [(7, 1, 16)], True, 2.0**-5), ("omega", [(7, 17, 8), (8, 1, 24)], True, 2.0**-31 * _SC),
        ("omegadot", [(9, 1, 24)], True, 2.0**-43 * _SC), ("iode", [(10, 1, 8)], False, 1),
        ("idot", [(10, 9, 14)], True, 2.0**-43 * _SC)],
}
#: the URA index's nominal value X [m] (IS-GPS-200 §20.3.3.3.1.3: 2^(1 + N/2) for N ≤ 6, rounded to 2.8, 5.7,
#: 11.3 as the ICD gives them; 2^(N − 2) for 6 < N < 15), what RINEX writers (RTKLIB's convbin) put
_URA_M = (2.0, 2.8, 4.0, 5.7, 8.0, 11.3, 16.0, 32.0, 64.0, 128.0, 256.0, 512.0, 1024.0, 2048.0, 4096.0)


def parity(data24: int, d29s: int, d30s: int) -> int:
    """The 6 parity bits D25–D30 (D25 most significant) of the source data bits d1–d24 (``data24``, d1 most
    significant) after a word ending in D29*, D30* (Table 20-XIV)."""
    out = 0
    for star, mask in _MASKS:
        b = (d29s if star == 29 else d30s) ^ (bin(data24 & mask).count("1") & 1)
        out = (out << 1) | b
    return out


def word_ok(word30: int, d29s: int, d30s: int) -> bool:
    """Whether the transmitted 30-bit word (D1 most significant) passes its parity check after a word
    ending in D29*, D30*."""
    data = (word30 >> 6) ^ (0xFFFFFF if d30s else 0)  # d_i = D_i ⊕ D30*
    return parity(data, d29s, d30s) == (word30 & 0x3F)


def ublox_subframe(dwrds) -> tuple[int | None, str]:
    """The 240 source data bits (10 × 24, word 1 first) of one u-blox SFRBX GPS L1 C/A subframe, or (None,
    why not): "length", "parity" (a word fails Table 20-XIV), "preamble", "subframe id". Module doc."""
    if len(dwrds) != 10:
        return None, "length"
    data, d29s, d30s = 0, 0, 0
    for w in dwrds:
        word = int(w) & _WORD
        if d30s:  # the receiver complemented this word: undo it to check the transmitted word
            word ^= _WORD
        if not word_ok(word, d29s, d30s):
            return None, "parity"
        data = (data << 24) | ((word >> 6) ^ (0xFFFFFF if d30s else 0))
        d29s, d30s = (word >> 1) & 1, word & 1
    if data >> 232 != PREAMBLE:
        return None, "preamble"
    if not 1 <= (data >> (240 - 48 + 2)) & 7 <= 5:
        return None, "subframe id"
    return data, "ok"


def decode_subframe(data240: int) -> dict:
    """TLM/HOW fields (every subframe) and, for subframes 1–3, the scaled fields of
    :data:`SUBFRAME_FIELDS` of the 240 source data bits of one subframe."""
    sfid = (data240 >> (240 - 48 + 2)) & 7
    out = {}
    for name, parts, signed, scale in SUBFRAME_FIELDS.get(sfid, _TLM_HOW):
        v, n = 0, 0
        for word, first, bits in parts:
            v = (v << bits) | ((data240 >> (240 - 24 * (word - 1) - (first - 1) - bits)) & ((1 << bits) - 1))
            n += bits
        if signed and v >> (n - 1):
            v -= 1 << n
        out[name] = v * scale
    return out


def ura_m(index: int) -> float:
    """URA [m] of the 4-bit URA index: its nominal value (IS-GPS-200 §20.3.3.3.1.3; 15: NaN, no accuracy
    prediction)."""
    i = int(index)
    return _URA_M[i] if 0 <= i < 15 else float("nan")


def fit_hours(flag: int, iodc: int) -> float:
    """Curve-fit interval [h] of the fit interval flag and IODC (IS-GPS-200 Table 20-XII)."""
    if not flag:
        return 4.0
    if 240 <= iodc <= 247:
        return 8.0
    if 248 <= iodc <= 255 or iodc == 496:
        return 14.0
    if 497 <= iodc <= 503 or 1021 <= iodc <= 1023:
        return 26.0
    return 6.0


def _record(prn: int, s: dict, ref_week: int) -> np.ndarray:
    """One ephemeris row (columns of :mod:`aidnav.nav.gnss_sat`) from subframes 1–3 (``s[k]`` fields)."""
    s1, s2, s3 = s[1], s[2], s[3]
    wn = int(s1["wn"]) + 1024 * int(round((ref_week - int(s1["wn"])) / 1024.0))
    tow = s1["tow"] - 6.0  # the transmit time of subframe 1's start
    wk_toe, wk_toc = near_week(s2["toe"], wn, tow), near_week(s1["toc"], wn, tow)
    r = np.zeros(N_EPH)
    r[E_PRN] = prn
    r[E_WEEK] = wk_toe
    r[E_TOE] = (wk_toe - ref_week) * SECONDS_PER_WEEK + s2["toe"]
    r[E_TOES] = s2["toe"]
    r[E_TOC] = (wk_toc - ref_week) * SECONDS_PER_WEEK + s1["toc"]
    r[E_AF0], r[E_AF1], r[E_AF2] = s1["af0"], s1["af1"], s1["af2"]
    r[E_SQRTA], r[E_ECC], r[E_M0], r[E_DN] = s2["sqrta"], s2["ecc"], s2["m0"], s2["dn"]
    r[E_CUC], r[E_CUS], r[E_CRS] = s2["cuc"], s2["cus"], s2["crs"]
    r[E_I0], r[E_OMEGA0], r[E_OMEGA], r[E_IDOT] = s3["i0"], s3["omega0"], s3["omega"], s3["idot"]
    r[E_OMEGADOT], r[E_CIC], r[E_CIS], r[E_CRC] = s3["omegadot"], s3["cic"], s3["cis"], s3["crc"]
    r[E_TGD] = s1["tgd"]
    r[E_HEALTH] = s1["health"]
    r[E_IODE] = s2["iode"]
    r[E_URA] = ura_m(s1["ura"])
    r[E_FIT] = fit_hours(int(s2["fit_flag"]), int(s1["iodc"]))
    return r


def assemble(subframes, ref_week: int) -> tuple[np.ndarray, Counter]:
    """Complete ephemeris rows from decoded subframes.

    subframes : iterable of (PRN, fields of :func:`decode_subframe`) in reception order. Per satellite the
    latest subframe 1, 2 and 3 is kept; a row is made whenever IODC mod 256 = IODE(2) = IODE(3), once per
    (satellite, IODE, toe), with toe/toc on ``ref_week``'s scale. Returns (rows (K, N_EPH), counts).
    """
    held: dict[int, dict] = {}
    done: set = set()
    rows, count = [], Counter()
    for prn, f in subframes:
        sfid = int(f["sfid"])
        count[f"subframe {sfid}"] += 1
        if sfid > 3:
            continue
        s = held.setdefault(int(prn), {})
        s[sfid] = f
        if len(s) < 3:
            continue
        if not int(s[1]["iodc"]) & 0xFF == int(s[2]["iode"]) == int(s[3]["iode"]):
            count["IODC/IODE differ (waiting)"] += 1
            continue
        key = (int(prn), int(s[2]["iode"]), s[2]["toe"])
        if key in done:
            continue
        done.add(key)
        rows.append(_record(int(prn), s, ref_week))
    return (np.array(rows) if rows else np.zeros((0, N_EPH))), count


def read_ubx_gps_lnav(path, ref_week: int | None = None, log=None) -> GpsEphemerides:
    """The GPS LNAV ephemerides broadcast in the RXM-SFRBX frames (gnssId 0, sigId 0) of the UBX log
    ``path`` (module doc), on the GPS week ``ref_week`` (default: the log's first RXM-RAWX week). ``log``:
    the log already read by :func:`aidnav.io.sfrbx.read_sfrbx` (else it is read here). Raises DataError when
    the file is missing or holds no complete GPS ephemeris."""
    path = Path(path)
    log = read_sfrbx(path) if log is None else log
    if ref_week is None:
        if log.rawx_week is None:
            raise DataError(path, None, "no UBX-RXM-RAWX in this log to resolve the GPS week number (mod "
                            "1024): give the observations' week")
        ref_week = int(log.rawx_week)
    subframes, count = [], Counter()
    for sv, sig, words in log.of(0):
        if sig != 0:  # L2 CM / L5 carry CNAV, not LNAV
            count["not L1 C/A frames"] += 1
            continue
        data, why = ublox_subframe(words)
        count[f"subframes {why}"] += 1
        if data is not None:
            subframes.append((sv, decode_subframe(data)))
    rows, c2 = assemble(subframes, int(ref_week))
    count.update(c2)
    if len(rows) == 0:
        raise DataError(path, None, "no complete GPS LNAV ephemeris (subframes 1-3 with one IODE) in the "
                        "RXM-SFRBX frames of this log: give a RINEX navigation file instead")
    rows = rows[np.lexsort((rows[:, E_TOE], rows[:, E_PRN]))]
    n_sat = len(np.unique(rows[:, E_PRN]))
    events = [f"{path.name}: GPS LNAV: {len(rows)} record(s) of {n_sat} satellite(s); "
              + ", ".join(f"{k} {v}" for k, v in sorted(count.items()))]
    bad = int(np.sum(rows[:, E_HEALTH] != 0))
    if bad:
        events.append(f"{path.name}: {bad} GPS LNAV record(s) flagged unhealthy (not used)")
    return GpsEphemerides(rows, int(ref_week), None, None, events)
