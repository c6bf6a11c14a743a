"""Galileo I/NAV broadcast ephemerides decoded from u-blox UBX-RXM-SFRBX frames → :class:`GpsEphemerides`.

A u-blox receiver delivers each Galileo E1-B I/NAV nominal page (even + odd part, 2 s) as one RXM-SFRBX
message with ``gnssId`` 2, ``sigId`` 1 (E1-B) and 8 words of 32 bits: words 1–4 hold the even part's 120
bits (even/odd 1, page type 1, data 112, tail 6) left-aligned, words 5–8 the odd part's 120 bits (even/odd
1, page type 1, data 16, reserved 40, SAR 22, spare 2, CRC 24, reserved 8, tail 6) (u-blox interface
description, "Galileo E1-B"; RTKLIB ``ublox.c`` ``decode_gal_inav``). The page's CRC-24Q covers the even
part's first 114 bits and the odd part's first 82 (196 bits, padded with 4 leading zeros to 25 bytes;
Galileo OS SIS ICD §4.3.2.3). The 128-bit data word is the even part's 112 data bits followed by the odd
part's 16; its first 6 bits are the word type.

Word types 1–4 carry the ephemeris and clock (each with the 10-bit IODnav), word 5 the BGDs, the signal
health and the GST week and time of week (OS SIS ICD Table 40–44; scale factors there). A record is
complete when words 1–4 of one satellite share an IODnav and a word 5 has been received; it is put on the
GPS reference-week scale of :mod:`aidnav.nav.gnss_sat` (the GST week + 1024 is the GPS week; the
GST–GPST offset, a few ns, is not applied, as for RINEX records), its group delay is BGD(E1, E5b) (the
I/NAV user's, as :func:`aidnav.io.rinex.read_rinex_nav` takes), its URA the SISA [m] and its health the
RINEX health word (bit 0 E1-B DVS, bits 1–2 E1-B HS, bit 6 E5b DVS, bits 7–8 E5b HS).

Alert pages, pages with a bad CRC and F/NAV or E6 frames (other ``sigId``) are counted and not used. The
log's frames are read by :func:`aidnav.io.sfrbx.read_sfrbx` (shared with :mod:`aidnav.io.gps_lnav`).
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
    sat_id,
)
from aidnav.nav.gnss_types import GpsEphemerides

__all__ = ["WORD_FIELDS", "crc24q", "decode_word", "inav_page", "assemble", "read_ubx_galileo_inav",
           "sisa_m", "GST_GPS_WEEK"]

GST_GPS_WEEK = 1024  # GPS week of GST week 0 (1999-08-22)
_SC = np.pi  # semicircles → rad (the ICD's π)

#: Fields per word type: (name, bits, signed, scale); each word starts with its 6-bit type (OS SIS ICD
#: Tables 40–44). Angles in semicircles are scaled to radians here.
WORD_FIELDS = {
    1: [("type", 6, False, 1), ("iodnav", 10, False, 1), ("toe", 14, False, 60.0),
        ("m0", 32, True, 2.0**-31 * _SC), ("ecc", 32, False, 2.0**-33), ("sqrta", 32, False, 2.0**-19)],
    2: [("type", 6, False, 1), ("iodnav", 10, False, 1), ("omega0", 32, True, 2.0**-31 * _SC),
        ("i0", 32, True, 2.0**-31 * _SC), ("omega", 32, True, 2.0**-31 * _SC),
        ("idot", 14, True, 2.0**-43 * _SC)],
    3: [("type", 6, False, 1), ("iodnav", 10, False, 1), ("omegadot", 24, True, 2.0**-43 * _SC),
        ("dn", 16, True, 2.0**-43 * _SC), ("cuc", 16, True, 2.0**-29), ("cus", 16, True, 2.0**-29),
        ("crc", 16, True, 2.0**-5), ("crs", 16, True, 2.0**-5), ("sisa", 8, False, 1)],
    4: [("type", 6, False, 1), ("iodnav", 10, False, 1), ("svid", 6, False, 1), ("cic", 16, True, 2.0**-29),
        ("cis", 16, True, 2.0**-29), ("toc", 14, False, 60.0), ("af0", 31, True, 2.0**-34),
        ("af1", 21, True, 2.0**-46), ("af2", 6, True, 2.0**-59)],
    5: [("type", 6, False, 1), ("ai0", 11, False, 2.0**-2), ("ai1", 11, True, 2.0**-8),
        ("ai2", 14, True, 2.0**-15), ("iono_flags", 5, False, 1), ("bgd_e1e5a", 10, True, 2.0**-32),
        ("bgd_e1e5b", 10, True, 2.0**-32), ("e5b_hs", 2, False, 1), ("e1b_hs", 2, False, 1),
        ("e5b_dvs", 1, False, 1), ("e1b_dvs", 1, False, 1), ("wn", 12, False, 1), ("tow", 20, False, 1)],
}


def crc24q(data: bytes) -> int:
    """CRC-24Q (polynomial 0x1864CFB, initial value 0, no reflection, no final xor) of ``data``."""
    crc = 0
    for b in data:
        crc ^= b << 16
        for _ in range(8):
            crc <<= 1
            if crc & 0x1000000:
                crc ^= 0x1864CFB
    return crc & 0xFFFFFF


def _bits(value: int, width: int, start: int, n: int) -> int:
    """Bits ``start`` .. ``start + n`` (MSB first) of the ``width``-bit integer ``value``."""
    return (value >> (width - start - n)) & ((1 << n) - 1)


def inav_page(words) -> tuple[int | None, str]:
    """The 128-bit data word of one SFRBX E1-B page (8 words of 32 bits), or (None, why not): "alert",
    "even/odd" (the parts out of order) or "crc". Returns (word, "ok") when the page is good."""
    if len(words) != 8:
        return None, "length"
    page = 0
    for w in words:
        page = (page << 32) | (int(w) & 0xFFFFFFFF)
    even, odd = page >> 128, page & ((1 << 128) - 1)
    if _bits(even, 128, 1, 1) or _bits(odd, 128, 1, 1):
        return None, "alert"
    if _bits(even, 128, 0, 1) != 0 or _bits(odd, 128, 0, 1) != 1:
        return None, "even/odd"
    covered = (_bits(even, 128, 0, 114) << 82) | _bits(odd, 128, 0, 82)  # 196 bits (+4 zeros: 25 bytes)
    if crc24q(covered.to_bytes(25, "big")) != _bits(odd, 128, 82, 24):
        return None, "crc"
    return (_bits(even, 128, 2, 112) << 16) | _bits(odd, 128, 2, 16), "ok"


def decode_word(word: int) -> dict | None:
    """The fields (scaled, :data:`WORD_FIELDS`) of a 128-bit I/NAV data word of type 1–5; None for
    other types."""
    wtype = _bits(word, 128, 0, 6)
    if wtype not in WORD_FIELDS:
        return None
    out, pos = {}, 0
    for name, n, signed, scale in WORD_FIELDS[wtype]:
        v = _bits(word, 128, pos, n)
        if signed and v >> (n - 1):
            v -= 1 << n
        out[name] = v * scale
        pos += n
    return out


def sisa_m(index: int) -> float:
    """SISA [m] of the broadcast 8-bit index (OS SIS ICD Table 89); NaN for "no accuracy prediction"
    (255) and the spare indices."""
    i = int(index)
    if i < 50:
        return 0.01 * i
    if i < 75:
        return 0.5 + 0.02 * (i - 50)
    if i < 100:
        return 1.0 + 0.04 * (i - 75)
    if i < 126:
        return 2.0 + 0.16 * (i - 100)
    return float("nan")


def _record(prn: int, w: dict, ref_week: int | None) -> np.ndarray:
    """One ephemeris row (columns of :mod:`aidnav.nav.gnss_sat`) from words 1–5 (``w[k]`` fields)."""
    w1, w2, w3, w4, w5 = (w[k] for k in range(1, 6))
    wn = int(w5["wn"]) + GST_GPS_WEEK
    wk_toe = near_week(w1["toe"], wn, w5["tow"])
    wk_toc = near_week(w4["toc"], wn, w5["tow"])
    ref = wk_toe if ref_week is None else ref_week
    r = np.zeros(N_EPH)
    r[E_PRN] = sat_id(f"E{prn:02d}")
    r[E_WEEK] = wk_toe
    r[E_TOE] = (wk_toe - ref) * SECONDS_PER_WEEK + w1["toe"]
    r[E_TOES] = w1["toe"]
    r[E_TOC] = (wk_toc - ref) * SECONDS_PER_WEEK + w4["toc"]
    r[E_AF0], r[E_AF1], r[E_AF2] = w4["af0"], w4["af1"], w4["af2"]
    r[E_SQRTA], r[E_ECC], r[E_M0] = w1["sqrta"], w1["ecc"], w1["m0"]
    r[E_I0], r[E_OMEGA0], r[E_OMEGA], r[E_IDOT] = w2["i0"], w2["omega0"], w2["omega"], w2["idot"]
    r[E_OMEGADOT], r[E_DN] = w3["omegadot"], w3["dn"]
    r[E_CUC], r[E_CUS], r[E_CRC], r[E_CRS] = w3["cuc"], w3["cus"], w3["crc"], w3["crs"]
    r[E_CIC], r[E_CIS] = w4["cic"], w4["cis"]
    r[E_TGD] = w5["bgd_e1e5b"]
    r[E_HEALTH] = (int(w5["e1b_dvs"]) | int(w5["e1b_hs"]) << 1 | int(w5["e5b_dvs"]) << 6
                   | int(w5["e5b_hs"]) << 7)
    r[E_IODE] = w1["iodnav"]
    r[E_URA] = sisa_m(w3["sisa"])
    r[E_FIT] = 4.0
    return r


def assemble(pages, ref_week: int | None = None) -> tuple[np.ndarray, Counter]:
    """Complete ephemeris rows from decoded pages.

    pages : iterable of (Galileo PRN, 128-bit data word) in reception order. Per satellite the latest word
    of each type 1–5 is kept; a row is made whenever words 1–4 share one IODnav and a word 5 is held, once
    per (satellite, IODnav, toe). Rows are on ``ref_week`` (default: each record's own toe week). Returns
    (rows (K, N_EPH), counts of what happened).
    """
    held: dict[int, dict] = {}
    done: set = set()
    rows, count = [], Counter()
    for prn, word in pages:
        f = decode_word(word)
        if f is None:
            count["other word types"] += 1
            continue
        w = held.setdefault(int(prn), {})
        w[int(f["type"])] = f
        count[f"word {int(f['type'])}"] += 1
        if len(w) < 5 or len({w[k]["iodnav"] for k in range(1, 5)}) != 1:
            continue
        key = (int(prn), int(w[1]["iodnav"]), w[1]["toe"])
        if key in done:
            continue
        done.add(key)
        rows.append(_record(int(prn), w, ref_week))
    return (np.array(rows) if rows else np.zeros((0, N_EPH))), count


def read_ubx_galileo_inav(path, ref_week: int | None = None, log=None) -> GpsEphemerides:
    """The Galileo I/NAV ephemerides broadcast in the RXM-SFRBX frames of the UBX log ``path`` (module doc),
    toe/toc on the GPS week ``ref_week`` (default: the earliest record's week). ``log``: the log already
    read by :func:`aidnav.io.sfrbx.read_sfrbx` (else it is read here). Raises DataError when the file is
    missing or holds no complete Galileo ephemeris."""
    path = Path(path)
    log = read_sfrbx(path) if log is None else log
    pages, count = [], Counter()
    for sv, sig, words in log.of(2):
        if sig != 1:  # sigId: E1-B only (F/NAV on E5a, E6 frames are not I/NAV)
            count["not E1-B frames"] += 1
            continue
        word, why = inav_page(words)
        count[f"pages {why}"] += 1
        if word is not None:
            pages.append((int(sv), word))
    rows, c2 = assemble(pages, None)
    count.update(c2)
    if len(rows) == 0:
        raise DataError(path, None, "no complete Galileo I/NAV ephemeris (words 1-5 with one IODnav) in the "
                        "RXM-SFRBX frames of this log: give a RINEX navigation file instead")
    week = int(np.min(rows[:, E_WEEK])) if ref_week is None else int(ref_week)
    shift = (rows[:, E_WEEK] - week) * SECONDS_PER_WEEK  # each row is on its own toe week: move to ``week``
    rows[:, E_TOE] += shift
    rows[:, E_TOC] += shift
    rows = rows[np.lexsort((rows[:, E_TOE], rows[:, E_PRN]))]
    events = [f"{path.name}: Galileo I/NAV: {len(rows)} record(s) of "
              f"{len(np.unique(rows[:, E_PRN]))} satellite(s); " + ", ".join(f"{k} {v}" for k, v in
                                                                         sorted(count.items()))]
    bad = int(np.sum(rows[:, E_HEALTH] != 0))
    if bad:
        events.append(f"{path.name}: {bad} Galileo record(s) flagged unhealthy (not used)")
    return GpsEphemerides(rows, week, None, None, events)
