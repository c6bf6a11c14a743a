"""GPS L1 C/A LNAV subframes from u-blox RXM-SFRBX (aidnav.io.gps_lnav): the parity's known answer (the
published parity matrix), subframes 1-3 built from chosen field values at IS-GPS-200's bit positions and
decoded back, words with bad parity refused, IODC/IODE matching, and on the walk: every subframe's parity,
the decoded records against the RINEX navigation file's (issue 40)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from aidnav.io import gps_lnav as gl
from aidnav.nav import gnss_sat as gs

#: the parity matrix H of IS-GPS-200 Table 20-XIV as published (J. Tsui, Fundamentals of GPS receivers,
#: eq. 5.3; D. Baker, "How does parity checking used by GPS satellites work?", Table 1): row k = which of
#: d1..d24 enter D(24+k)
H = ["111011000111110011010010", "011101100011111001101001", "101110110001111100110100",
     "010111011000111110011010", "101011101100011111001101", "001011011110101000100111"]
SC = 3.1415926535898  # IS-GPS-200's π
#: (field, [(first bit, last bit) in the 300-bit subframe, IS-GPS-200 Figure 20-1], signed, scale),
#: written from the ICD independently of the module's (word, bit) table
ICD = {
    1: [("wn", [(61, 70)], 0, 1), ("ura", [(73, 76)], 0, 1), ("health", [(77, 82)], 0, 1),
        ("iodc", [(83, 84), (211, 218)], 0, 1), ("tgd", [(197, 204)], 1, 2.0**-31),
        ("toc", [(219, 234)], 0, 16), ("af2", [(241, 248)], 1, 2.0**-55), ("af1", [(249, 264)], 1, 2.0**-43),
        ("af0", [(271, 292)], 1, 2.0**-31)],
    2: [("iode", [(61, 68)], 0, 1), ("crs", [(69, 84)], 1, 2.0**-5), ("dn", [(91, 106)], 1, 2.0**-43 * SC),
        ("m0", [(107, 114), (121, 144)], 1, 2.0**-31 * SC), ("cuc", [(151, 166)], 1, 2.0**-29),
        ("ecc", [(167, 174), (181, 204)], 0, 2.0**-33), ("cus", [(211, 226)], 1, 2.0**-29),
        ("sqrta", [(227, 234), (241, 264)], 0, 2.0**-19), ("toe", [(271, 286)], 0, 16),
        ("fit_flag", [(287, 287)], 0, 1)],
    3: [("cic", [(61, 76)], 1, 2.0**-29), ("omega0", [(77, 84), (91, 114)], 1, 2.0**-31 * SC),
        ("cis", [(121, 136)], 1, 2.0**-29), ("i0", [(137, 144), (151, 174)], 1, 2.0**-31 * SC),
        ("crc", [(181, 196)], 1, 2.0**-5), ("omega", [(197, 204), (211, 234)], 1, 2.0**-31 * SC),
        ("omegadot", [(241, 264)], 1, 2.0**-43 * SC), ("iode", [(271, 278)], 0, 1),
        ("idot", [(279, 292)], 1, 2.0**-43 * SC)],
}
#: chosen raw (integer) values; negative ones test the two's complement
RAW = {
    1: {"wn": 333, "ura": 1, "health": 0, "iodc": 0x2A7, "tgd": -23, "toc": 25875, "af2": -3, "af1": -1234,
        "af0": -987654},
    2: {"iode": 0xA7, "crs": -1234, "dn": 17000, "m0": -1234567890, "cuc": -2500, "ecc": 54321987,
        "cus": 3000, "sqrta": 2702000000, "toe": 25875, "fit_flag": 0},
    3: {"cic": -50, "omega0": 987654321, "cis": 77, "i0": 659706976, "crc": 6000, "omega": -55555555,
        "omegadot": -8000, "iode": 0xA7, "idot": -321},
}
TOW = 100790  # HOW TOW count of subframe 1 (×6 s = 604740 s: near the end of week 2381 = 333 + 2·1024)


def _put(bits: list, first: int, last: int, value: int):
    n = last - first + 1
    for k in range(n):
        bits[first - 1 + k] = (value >> (n - 1 - k)) & 1


def _subframe_data(sfid: int, raw: dict, tow: int) -> list:
    """The 300 bit cells of a subframe with its data bits set (parity cells left 0)."""
    b = [0] * 300
    _put(b, 1, 8, gl.PREAMBLE)
    _put(b, 9, 22, 0x1234)
    _put(b, 31, 47, tow)
    _put(b, 50, 52, sfid)
    for name, parts, _, _ in ICD[sfid]:
        n = sum(last - first + 1 for first, last in parts)
        v = raw[name] & ((1 << n) - 1)
        for first, last in parts:
            n -= last - first + 1
            _put(b, first, last, v >> n)
    return b


def _transmit(cells: list) -> list[int]:
    """The ten transmitted 30-bit words: d_i ⊕ D30* and Table 20-XIV parity; words 2 and 10 get their
    bits 23-24 chosen so that D29 = D30 = 0 (IS-GPS-200 §20.3.5.2)."""
    words, d29s, d30s = [], 0, 0
    for k in range(10):
        data = int("".join(map(str, cells[30 * k:30 * k + 24])), 2)
        if k in (1, 9):
            data = next(data & ~3 | t for t in range(4) if gl.parity(data & ~3 | t, d29s, d30s) & 3 == 0)
        word = ((data ^ (0xFFFFFF if d30s else 0)) << 6) | gl.parity(data, d29s, d30s)
        words.append(word)
        d29s, d30s = (word >> 1) & 1, word & 1
    return words


def _ublox(words: list[int]) -> list[int]:
    """The receiver's storage (module doc): a word after D30 = 1 complemented, bits 31-30 = (D29 ⊕ D30, 0) of
    the previous transmitted word."""
    out, d29s, d30s = [], 0, 0
    for w in words:
        out.append(((d29s ^ d30s) << 31) | (w ^ (0x3FFFFFFF if d30s else 0)))
        d29s, d30s = (w >> 1) & 1, w & 1
    return out


def _sfrbx(sfid: int, raw: dict, tow: int = TOW) -> list[int]:
    return _ublox(_transmit(_subframe_data(sfid, raw, tow)))


def test_parity_known_answer():
    """Each data bit alone gives its column of the published matrix; D29* enters D25, D27, D30 and D30*
    enters D26, D28, D29; D30* = 1 complements the data bits."""
    for i in range(1, 25):
        col = int("".join(row[i - 1] for row in H), 2)
        assert gl.parity(1 << (24 - i), 0, 0) == col, i
    assert gl.parity(0, 1, 0) == 0b101001 and gl.parity(0, 0, 1) == 0b010110
    rng = np.random.default_rng(40)
    for _ in range(50):
        d, a, b = int(rng.integers(0, 1 << 24)), int(rng.integers(0, 2)), int(rng.integers(0, 2))
        p = 0
        for row in H:  # the matrix form: D(24+k) = (D29* or D30*) ⊕ (row · d mod 2)
            p = (p << 1) | (int(row, 2) & d).bit_count() & 1
        assert gl.parity(d, a, b) == p ^ (a * 0b101001) ^ (b * 0b010110)
        tx = ((d ^ (0xFFFFFF * b)) << 6) | gl.parity(d, a, b)
        assert gl.word_ok(tx, a, b) and not gl.word_ok(tx ^ (1 << int(rng.integers(0, 30))), a, b)


@pytest.mark.parametrize("sfid", [1, 2, 3])
def test_subframe_fields_decode_back(sfid):
    data, why = gl.ublox_subframe(_sfrbx(sfid, RAW[sfid]))
    assert why == "ok"
    f = gl.decode_subframe(data)
    assert f["sfid"] == sfid and f["preamble"] == gl.PREAMBLE and f["tow"] == TOW * 6 and f["tlm"] == 0x1234
    for name, _, _, scale in ICD[sfid]:
        assert f[name] == pytest.approx(RAW[sfid][name] * scale, rel=1e-15, abs=0), name


@pytest.mark.parametrize("bit", [0, 7, 29, 30, 61, 100, 143, 179, 211, 240, 269, 298, 299])
def test_bad_parity_refused(bit):
    """One flipped bit anywhere in the 300 (data or parity) fails its word's check; bits 31-30 of the
    u-blox words are not needed."""
    w = _sfrbx(2, RAW[2])
    k, j = divmod(bit, 30)
    w[k] ^= 1 << (29 - j)
    assert gl.ublox_subframe(w) == (None, "parity")
    ok = [x & 0x3FFFFFFF for x in _sfrbx(2, RAW[2])]
    assert gl.ublox_subframe(ok)[1] == "ok"


def test_assembled_record_and_iod_matching():
    sf = {k: gl.decode_subframe(gl.ublox_subframe(_sfrbx(k, RAW[k], TOW + k - 1))[0]) for k in (1, 2, 3)}
    rows, count = gl.assemble([(7, sf[1]), (7, sf[2])], ref_week=2381)
    assert len(rows) == 0  # subframe 3 missing
    other = gl.decode_subframe(gl.ublox_subframe(_sfrbx(3, dict(RAW[3], iode=0xA8)))[0])
    rows, count = gl.assemble([(7, sf[1]), (7, sf[2]), (7, other)], ref_week=2381)
    assert len(rows) == 0 and count["IODC/IODE differ (waiting)"] == 1
    rows, _ = gl.assemble([(7, sf[1]), (7, sf[2]), (7, other), (7, sf[3]), (7, sf[3])], ref_week=2381)
    assert len(rows) == 1  # once per (satellite, IODE, toe)
    r = rows[0]
    assert r[gs.E_PRN] == 7 and r[gs.E_WEEK] == 2381 and r[gs.E_IODE] == 0xA7
    assert r[gs.E_TOE] == r[gs.E_TOES] == 25875 * 16 == r[gs.E_TOC]
    assert r[gs.E_SQRTA] == 2702000000 * 2**-19 and r[gs.E_ECC] == 54321987 * 2**-33
    assert r[gs.E_M0] == -1234567890 * 2**-31 * SC and r[gs.E_AF0] == -987654 * 2**-31
    assert r[gs.E_TGD] == -23 * 2**-31 and r[gs.E_URA] == 2.8 and r[gs.E_FIT] == 4.0
    assert gl.ura_m(0) == 2.0 and gl.ura_m(6) == 16.0 and gl.ura_m(14) == 4096.0 and math.isnan(gl.ura_m(15))
    assert gl.fit_hours(1, 240) == 8.0 and gl.fit_hours(1, 0x2A7) == 6.0
    # the 10-bit week unrolled to the reference week; a toe early in the week after the transmit week
    rows, _ = gl.assemble([(7, sf[1]), (7, sf[2]), (7, sf[3])], ref_week=2381 + 1024)
    assert rows[0][gs.E_WEEK] == 2381 + 1024
    early = {2: gl.decode_subframe(gl.ublox_subframe(_sfrbx(2, dict(RAW[2], toe=225)))[0])}
    rows, _ = gl.assemble([(7, sf[1]), (7, early[2]), (7, sf[3])], ref_week=2381)
    assert rows[0][gs.E_WEEK] == 2382 and rows[0][gs.E_TOE] == 604800 + 3600


def test_walk_lnav_equals_the_nav_file(walk_dir):
    """The walk's log: every L1 C/A subframe passes its parity (80), the 4 satellites with subframes 1-3
    (G10, G23, G27, G32) get records equal to the RINEX file's (RTKLIB convbin, same broadcast): positions
    within 1 cm over ±2 h, clocks within 1 mm (merged by ``read_rinex_pair`` they add nothing:
    test_gps_cnav.py)."""
    from aidnav.io.rinex import read_rinex_nav  # lazy: georinex is heavy to import

    lnav = gl.read_ubx_gps_lnav(walk_dir / "gnss_1730.ubx")
    ev = lnav.events[0]
    print(ev)
    assert "subframes ok 80" in ev and "parity" not in ev
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        nav = read_rinex_nav(walk_dir / "rinex_converted" / "gnss_1730.nav", systems="G")
        nav = nav.to_week(lnav.ref_week)
    assert sorted(lnav.table[:, gs.E_PRN].astype(int)) == [10, 23, 27, 32]
    worst = 0.0
    for r in lnav.table:
        x = nav.table[(nav.table[:, gs.E_PRN] == r[gs.E_PRN]) & (nav.table[:, gs.E_IODE] == r[gs.E_IODE])]
        assert len(x) == 1 and x[0][gs.E_TOE] == r[gs.E_TOE] and x[0][gs.E_URA] == r[gs.E_URA]
        for t in r[gs.E_TOE] + np.linspace(-7200, 7200, 9):
            p1, _, c1, _ = gs.eph_state(r, t)
            p2, _, c2, _ = gs.eph_state(x[0], t)
            worst = max(worst, float(np.linalg.norm(p1 - p2)))
            assert abs(c1 - c2) * gs.C_LIGHT < 1e-3
    print(f"largest position difference LNAV vs RINEX: {worst * 1000:.2f} mm")
    assert worst < 0.01
