"""Galileo I/NAV pages from u-blox RXM-SFRBX (aidnav.io.galileo_inav): CRC-24Q known answer, pages built
from chosen field values at the OS SIS ICD's bit positions decoded back, and the walk's decoded satellites'
pseudorange residuals against the RTK reference (issue 40)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from aidnav.io import galileo_inav as gi
from aidnav.nav import gnss_sat as gs

PI = math.pi
#: (field, first bit, bits, signed, scale) per word type, written from the ICD's tables (Tables 40-44) as
#: absolute bit positions in the 128-bit word, independently of the module's cumulative table.
ICD = {
    1: [("iodnav", 6, 10, 0, 1), ("toe", 16, 14, 0, 60), ("m0", 30, 32, 1, 2**-31 * PI),
        ("ecc", 62, 32, 0, 2**-33), ("sqrta", 94, 32, 0, 2**-19)],
    2: [("iodnav", 6, 10, 0, 1), ("omega0", 16, 32, 1, 2**-31 * PI), ("i0", 48, 32, 1, 2**-31 * PI),
        ("omega", 80, 32, 1, 2**-31 * PI), ("idot", 112, 14, 1, 2**-43 * PI)],
    3: [("iodnav", 6, 10, 0, 1), ("omegadot", 16, 24, 1, 2**-43 * PI), ("dn", 40, 16, 1, 2**-43 * PI),
        ("cuc", 56, 16, 1, 2**-29), ("cus", 72, 16, 1, 2**-29), ("crc", 88, 16, 1, 2**-5),
        ("crs", 104, 16, 1, 2**-5), ("sisa", 120, 8, 0, 1)],
    4: [("iodnav", 6, 10, 0, 1), ("svid", 16, 6, 0, 1), ("cic", 22, 16, 1, 2**-29),
        ("cis", 38, 16, 1, 2**-29), ("toc", 54, 14, 0, 60), ("af0", 68, 31, 1, 2**-34),
        ("af1", 99, 21, 1, 2**-46), ("af2", 120, 6, 1, 2**-59)],
    5: [("ai0", 6, 11, 0, 2**-2), ("ai1", 17, 11, 1, 2**-8), ("ai2", 28, 14, 1, 2**-15),
        ("bgd_e1e5a", 47, 10, 1, 2**-32), ("bgd_e1e5b", 57, 10, 1, 2**-32), ("e5b_hs", 67, 2, 0, 1),
        ("e1b_hs", 69, 2, 0, 1), ("e5b_dvs", 71, 1, 0, 1), ("e1b_dvs", 72, 1, 0, 1), ("wn", 73, 12, 0, 1),
        ("tow", 85, 20, 0, 1)],
}
#: chosen raw (integer) field values; negative ones test the two's complement
RAW = {
    1: {"iodnav": 345, "toe": 6790, "m0": -1234567890, "ecc": 2345678, "sqrta": 2852436543},
    2: {"iodnav": 345, "omega0": 987654321, "i0": 659706976, "omega": -55555555, "idot": -4321},
    3: {"iodnav": 345, "omegadot": -5432100, "dn": 12345, "cuc": -1111, "cus": 2222, "crc": 7000,
        "crs": -3000, "sisa": 107},
    4: {"iodnav": 345, "svid": 26, "cic": -77, "cis": 88, "toc": 6790, "af0": -987654321, "af1": -123456,
        "af2": 3},
    5: {"ai0": 500, "ai1": -300, "ai2": 4000, "bgd_e1e5a": -17, "bgd_e1e5b": 21, "e5b_hs": 0, "e1b_hs": 0,
        "e5b_dvs": 0, "e1b_dvs": 0, "wn": 1357, "tow": 408601},
}


def _word(wtype: int, raw: dict) -> int:
    w = wtype << 122
    for name, start, n, _, _ in ICD[wtype]:
        w |= (raw[name] & ((1 << n) - 1)) << (128 - start - n)
    return w


def _sfrbx(word: int, corrupt: int | None = None) -> list[int]:
    """The 8 SFRBX words of the nominal page carrying the 128-bit data word (module doc's layout)."""
    even = (0 << 119) | (0 << 118) | ((word >> 16) << 6)  # even/odd 0, page type 0, 112 data bits, tail
    odd_head = (1 << 81) | (0 << 80) | ((word & 0xFFFF) << 64) | (0x5A5A5A5A5A << 24) | (0x2ABCDE << 2)
    crc = gi.crc24q(((even >> 6) << 82 | odd_head).to_bytes(25, "big"))  # 114 + 82 bits, 4 zero pad bits
    odd = (odd_head << 38) | (crc << 14) | (0x77 << 6)
    page = (even << 8) << 128 | (odd << 8)  # each 120-bit part left-aligned in 128 bits
    if corrupt is not None:
        page ^= 1 << (255 - corrupt)
    return [(page >> (32 * (7 - i))) & 0xFFFFFFFF for i in range(8)]


def test_crc24q_known_answers():
    assert gi.crc24q(b"123456789") == 0xCDE703  # CRC-24/LTE-A (= CRC-24Q) check value of the CRC catalogue
    assert gi.crc24q(b"") == 0
    msg = b"galileo i/nav"
    c = gi.crc24q(msg)
    assert gi.crc24q(msg + c.to_bytes(3, "big")) == 0  # a message followed by its CRC leaves no remainder


@pytest.mark.parametrize("wtype", [1, 2, 3, 4, 5])
def test_page_fields_decode_back(wtype):
    word, why = gi.inav_page(_sfrbx(_word(wtype, RAW[wtype])))
    assert why == "ok"
    f = gi.decode_word(word)
    assert f["type"] == wtype
    for name, _, _, _, scale in ICD[wtype]:
        assert f[name] == pytest.approx(RAW[wtype][name] * scale, rel=1e-15, abs=0), name


@pytest.mark.parametrize("bit", [0, 5, 60, 113, 128, 130, 150, 209, 230])
def test_corrupted_page_refused(bit):
    """A flipped bit inside the CRC's span or the CRC itself is caught; bits 0 / 128 (even/odd) first."""
    _, why = gi.inav_page(_sfrbx(_word(3, RAW[3]), corrupt=bit))
    assert why in ("crc", "even/odd")
    _, why = gi.inav_page(_sfrbx(_word(3, RAW[3]), corrupt=1))
    assert why == "alert"


def test_assembled_record():
    words = [(26, _word(k, RAW[k])) for k in (5, 1, 2, 3)]
    rows, count = gi.assemble(words)
    assert len(rows) == 0  # word 4 missing
    rows, count = gi.assemble(words + [(26, _word(4, dict(RAW[4], iodnav=346)))])
    assert len(rows) == 0  # IODnav differs
    rows, _ = gi.assemble(words + [(26, _word(4, RAW[4]))] * 2)
    assert len(rows) == 1  # once per (satellite, IODnav, toe)
    r = rows[0]
    assert r[gs.E_PRN] == gs.sat_id("E26") and r[gs.E_WEEK] == 1357 + 1024
    assert r[gs.E_TOE] == r[gs.E_TOES] == 6790 * 60 and r[gs.E_TOC] == 6790 * 60
    assert r[gs.E_SQRTA] == 2852436543 * 2**-19 and r[gs.E_ECC] == 2345678 * 2**-33
    assert r[gs.E_AF0] == -987654321 * 2**-34 and r[gs.E_TGD] == 21 * 2**-32
    assert r[gs.E_URA] == pytest.approx(2.0 + 0.16 * 7) and r[gs.E_HEALTH] == 0 and r[gs.E_IODE] == 345
    assert gi.sisa_m(255) != gi.sisa_m(255)  # NaN: no accuracy prediction
    # toe at the end of a week read at the start of the next: the record's week is the previous one
    late = {1: dict(RAW[1], toe=10070)}  # 604200 s
    rows, _ = gi.assemble([(26, _word(k, late.get(k, RAW[k]))) for k in (1, 2, 3, 4)]
                          + [(26, _word(5, dict(RAW[5], tow=100)))])
    assert rows[0][gs.E_WEEK] == 1357 + 1024 - 1


def test_walk_galileo_residuals(data_dir):
    """The walk's UBX log: every E1-B page passes its CRC, 7 satellites get a complete ephemeris, and the
    decoded healthy satellites' pseudorange residuals against the RTK positions (after the receiver clock
    from the GPS satellites and one GPS-Galileo offset) are at the metres level, like the GPS satellites'."""
    import importlib.util  # lazy: the benchmark's computation is loaded only with the data

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "galileo_inav_residuals.py"
    spec = importlib.util.spec_from_file_location("galileo_inav_residuals", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    out, offset, gal = bench.residuals(data_dir / "rtklibexplorer_walk_0827", step_s=30.0)
    ev = gal.events[0]
    assert "pages ok 396" in ev and "pages crc" not in ev
    assert len(np.unique(gal.table[:, gs.E_PRN])) == 7
    e = np.concatenate([np.asarray(v) - offset for s, v in out.items() if s >= 100])
    g = np.concatenate([np.asarray(v) for s, v in out.items() if s < 100])
    rms_e, rms_g = np.sqrt(np.mean(e**2)), np.sqrt(np.mean(g**2))
    print(f"walk Galileo residual RMS {rms_e:.2f} m ({len(e)}), GPS {rms_g:.2f} m, offset {offset:.2f} m")
    assert rms_e < 8.0 and np.max(np.abs(e)) < 25.0  # a wrong field or week gives km


def test_walk_pair_with_ubx_nav(data_dir):
    """``read_rinex_pair(..., ubx_nav=)``: the walk's nav file has no Galileo record, the UBX log adds its 7
    (E14 flagged unhealthy, as broadcast), the Galileo observations are kept, and the file's GPS records
    are unchanged (test_gps_cnav.py: the GPS satellites the log adds)."""
    import warnings  # lazy: only this test reads RINEX (georinex's FutureWarnings)

    from aidnav.io.rinex import read_rinex_pair  # lazy: georinex is heavy to import

    d = data_dir / "rtklibexplorer_walk_0827"
    if not d.is_dir():
        pytest.skip("walk data set not found")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        args = (d / "rinex_converted" / "gnss_1730.obs", d / "rinex_converted" / "gnss_1730.nav", "GE")
        obs0, eph0, ev0 = read_rinex_pair(*args)
        obs1, eph1, ev1 = read_rinex_pair(*args, ubx_nav=d / "gnss_1730.ubx")
    gal = eph1.table[eph1.table[:, gs.E_PRN] // 100 == 1]
    assert not np.any(obs0.prn // 100 == 1) and any("no Galileo ephemeris" in e for e in ev0)
    assert sorted(gal[:, gs.E_PRN].astype(int) % 100) == [7, 8, 13, 14, 26, 29, 33]
    assert [int(r[gs.E_PRN]) % 100 for r in gal if r[gs.E_HEALTH] != 0] == [14]
    assert np.all(np.abs(gal[:, gs.E_TOE] - obs1.time[0]) < 7200)  # on the observations' week
    assert set(obs1.prn[obs1.prn // 100 == 1] % 100) >= {7, 26, 29, 33}
    gps = [e.table[e.table[:, gs.E_PRN] < 100] for e in (eph0, eph1)]
    kept = np.isin(gps[1][:, gs.E_PRN], gps[0][:, gs.E_PRN])  # the log's GPS CNAV adds G08, G18, G24
    assert np.array_equal(gps[0], gps[1][kept]) and sorted(gps[1][~kept, gs.E_PRN]) == [8, 18, 24]


def test_log_without_galileo_pages_refused(tmp_path):
    from aidnav.io.errors import DataError  # lazy: only this test

    p = tmp_path / "x.ubx"
    p.write_bytes(b"\xb5\x62\x01\x07\x00\x00" + b"not a log" * 10)
    with pytest.raises(DataError, match="no complete Galileo I/NAV ephemeris"):
        gi.read_ubx_galileo_inav(p)
    with pytest.raises(DataError, match="file not found"):
        gi.read_ubx_galileo_inav(tmp_path / "none.ubx")
