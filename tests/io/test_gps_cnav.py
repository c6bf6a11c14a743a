"""GPS CNAV data sets from u-blox RXM-SFRBX (aidnav.io.gps_cnav): messages 10, 11, 30 built from chosen field
values at IS-GPS-200's bit positions and decoded back, a corrupted message refused by its CRC, the
re-epoched row against the ICD's own CNAV orbit equations, and on the walk: every message's CRC, the CNAV
orbits of the satellites that also have LNAV against the LNAV ones, and ``read_rinex_pair(ubx_nav=)``
adding G08, G18, G24 with pseudorange residuals at the metres level of the nav file's satellites (issue 40).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from aidnav.io import gps_cnav as gc
from aidnav.io.galileo_inav import crc24q
from aidnav.nav import gnss_sat as gs

SC = 3.1415926535898
#: (field, first bit, last bit, signed, scale) of IS-GPS-200 Tables 30-I, 30-II, 30-III (message bits 1-300),
#: written from the ICD independently of the module's table
ICD = {
    10: [("wn", 39, 51, 0, 1), ("health", 52, 54, 0, 1), ("top", 55, 65, 0, 300), ("ura_ed", 66, 70, 1, 1),
         ("toe", 71, 81, 0, 300), ("da", 82, 107, 1, 2.0**-9), ("adot", 108, 132, 1, 2.0**-21),
         ("dn0", 133, 149, 1, 2.0**-44 * SC), ("dn0dot", 150, 172, 1, 2.0**-57 * SC),
         ("m0", 173, 205, 1, 2.0**-32 * SC), ("ecc", 206, 238, 0, 2.0**-34),
         ("omega", 239, 271, 1, 2.0**-32 * SC)],
    11: [("toe", 39, 49, 0, 300), ("omega0", 50, 82, 1, 2.0**-32 * SC), ("i0", 83, 115, 1, 2.0**-32 * SC),
         ("domegadot", 116, 132, 1, 2.0**-44 * SC), ("idot", 133, 147, 1, 2.0**-44 * SC),
         ("cis", 148, 163, 1, 2.0**-30), ("cic", 164, 179, 1, 2.0**-30), ("crs", 180, 203, 1, 2.0**-8),
         ("crc", 204, 227, 1, 2.0**-8), ("cus", 228, 248, 1, 2.0**-30), ("cuc", 249, 269, 1, 2.0**-30)],
    30: [("top", 39, 49, 0, 300), ("ura_ned0", 50, 54, 1, 1), ("toc", 61, 71, 0, 300),
         ("af0", 72, 97, 1, 2.0**-35), ("af1", 98, 117, 1, 2.0**-48), ("af2", 118, 127, 1, 2.0**-60),
         ("tgd", 128, 140, 1, 2.0**-35), ("isc_l1ca", 141, 153, 1, 2.0**-35),
         ("alpha0", 193, 200, 1, 2.0**-30), ("alpha1", 201, 208, 1, 2.0**-27),
         ("alpha2", 209, 216, 1, 2.0**-24), ("alpha3", 217, 224, 1, 2.0**-24),
         ("beta0", 225, 232, 1, 2.0**11), ("beta1", 233, 240, 1, 2.0**14),
         ("beta2", 241, 248, 1, 2.0**16), ("beta3", 249, 256, 1, 2.0**16)],
}
#: chosen raw values (a GPS-like orbit: A ≈ A_ref + 3.2 km, e ≈ 0.012, i ≈ 55°)
RAW = {
    10: {"wn": 2381, "health": 1, "top": 1300, "ura_ed": -3, "toe": 1362, "da": 1654321, "adot": 13000,
         "dn0": 11000, "dn0dot": -3000, "m0": -1234567890, "ecc": 206000000, "omega": 987654321},
    11: {"toe": 1362, "omega0": -2123456789, "i0": 1309000000, "domegadot": -2500, "idot": -400, "cis": 50,
         "cic": -70, "crs": 2500000, "crc": 5000000, "cus": 300000, "cuc": -250000},
    30: {"top": 1300, "ura_ned0": -6, "toc": 1362, "af0": -12345678, "af1": -4000, "af2": 3, "tgd": 150,
         "isc_l1ca": -40, "alpha0": 26, "alpha1": 2, "alpha2": -2, "alpha3": -1, "beta0": 65, "beta1": 3,
         "beta2": -4, "beta3": 7},
}


def _message(mtype: int, raw: dict, prn: int = 7, tow: int = 68115, corrupt: int | None = None) -> list[int]:
    """The 10 u-blox words of a CNAV message (300 bits, CRC-24Q over bits 1-276, 20 zero bits after)."""
    bits = [0] * 300

    def put(first, last, v):
        n = last - first + 1
        for k in range(n):
            bits[first - 1 + k] = (v >> (n - 1 - k)) & 1

    put(1, 8, 0b10001011)
    put(9, 14, prn)
    put(15, 20, mtype)
    put(21, 37, tow)
    for name, first, last, _, _ in ICD[mtype]:
        put(first, last, raw[name] & ((1 << (last - first + 1)) - 1))
    body = int("".join(map(str, bits[:276])), 2)
    msg = (body << 24) | crc24q(body.to_bytes(35, "big"))
    if corrupt is not None:
        msg ^= 1 << (299 - corrupt)
    v = msg << 20
    return [(v >> (32 * (9 - i))) & 0xFFFFFFFF for i in range(10)]


@pytest.mark.parametrize("mtype", [10, 11, 30])
def test_message_fields_decode_back(mtype):
    msg, why = gc.cnav_message(_message(mtype, RAW[mtype]))
    assert why == "ok"
    f = gc.decode_message(msg)
    assert f["type"] == mtype and f["prn"] == 7 and f["tow"] == 68115 * 6
    for name, _, _, _, scale in ICD[mtype]:
        assert f[name] == pytest.approx(RAW[mtype][name] * scale, rel=1e-15, abs=0), name


@pytest.mark.parametrize("bit", [0, 9, 38, 150, 275, 276, 299])
def test_corrupted_message_refused(bit):
    _, why = gc.cnav_message(_message(11, RAW[11], corrupt=bit))
    assert why == ("preamble" if bit < 8 else "crc")


def _sets(toc=1362):
    raw30 = dict(RAW[30], toc=toc)
    msgs = [(7, gc.decode_message(gc.cnav_message(_message(k, r))[0])) for k, r in
            ((10, RAW[10]), (11, RAW[11]), (30, raw30))]
    return msgs


def test_assembly_and_reepoched_row():
    """Types 10/11 of one toe and a type 30 of that toc make one row (once); the row re-epoched to t_ref
    reproduces the ICD's CNAV orbit (``cnav_state``, with Ȧ and Δn0-dot) to < 1 µm at t_ref and < 5 mm
    within ±70 s; the row at its toe (600 s away) or without the Ȧ term is off by decimetres."""
    rows, count, _ = gc.assemble(_sets(toc=1361), ref_week=2381)
    assert len(rows) == 0 and count["toe/toc differ (waiting)"] == 1
    msgs = _sets()
    rows, _, sets = gc.assemble(msgs + msgs[2:], ref_week=2381)
    assert len(rows) == 1
    toe = 1362 * 300.0
    t_ref = toe + 600.0
    r = gc.cnav_row(7, sets[0][1], 2381, t_ref)
    assert r[gs.E_TOE] == t_ref and r[gs.E_TOC] == toe and r[gs.E_HEALTH] == 0  # the L1 bit (L5 set)
    assert r[gs.E_TGD] == pytest.approx((150 + 40) * 2.0**-35)
    assert r[gs.E_URA] == pytest.approx(np.hypot(2.0 ** (1 - 1.5), 2.0 ** (1 - 3.0)))
    m10, m11 = sets[0][1][10], sets[0][1][11]
    err = [np.linalg.norm(gs.eph_state(r, t)[0] - gc.cnav_state(m10, m11, toe, t))
           for t in t_ref + np.r_[0, -70, 70]]
    print(f"re-epoched row vs ICD CNAV orbit: {err[0]:.2e} m at t_ref, {max(err):.2e} m within ±70 s")
    assert err[0] < 1e-6 and max(err) < 5e-3
    # both parts matter: not re-epoched (the row at its toe, 600 s away), and the Ȧ term dropped
    at_toe = gc.cnav_row(7, sets[0][1], 2381, None)
    assert np.linalg.norm(gs.eph_state(at_toe, t_ref)[0] - gc.cnav_state(m10, m11, toe, t_ref)) > 0.1
    no_adot = gc.cnav_row(7, {**sets[0][1], 10: dict(m10, adot=0.0)}, 2381, t_ref)
    t = t_ref + 70
    assert np.linalg.norm(gs.eph_state(no_adot, t)[0] - gc.cnav_state(m10, m11, toe, t)) > 0.3  # Ȧ·70 s
    # the velocity is right too (the radius rate Ȧ): central difference of the ICD orbit
    v_icd = (gc.cnav_state(m10, m11, toe, t_ref + 0.5) - gc.cnav_state(m10, m11, toe, t_ref - 0.5))
    assert np.linalg.norm(gs.eph_state(r, t_ref)[1] - v_icd) < 1e-4


def _bench():
    path = Path(__file__).resolve().parents[2] / "benchmarks" / "ubx_nav_residuals.py"
    spec = importlib.util.spec_from_file_location("ubx_nav_residuals", path)
    bench = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(path.parent))  # it imports its sibling galileo_inav_residuals, as when run
    try:
        spec.loader.exec_module(bench)
    finally:
        sys.path.remove(str(path.parent))
    return bench


def test_walk_cnav(walk_dir):
    """The walk's log: all 148 L2C/L5 messages pass their CRC; 7 data sets; for the 4 satellites that also
    have LNAV records the CNAV orbit agrees with the LNAV one (< 1 m, velocity < 1 mm/s); merged by
    ``read_rinex_pair``, LNAV adds nothing (same as the file), CNAV adds G08, G18, G24 only, and their
    pseudorange residuals against the RTK positions are at the metres level of the file's satellites."""
    from aidnav.io.rinex import read_rinex_nav  # lazy: georinex is heavy to import

    cnav = gc.read_ubx_gps_cnav(walk_dir / "gnss_1730.ubx")
    ev = cnav.events[0]
    assert "messages ok 148" in ev and "crc" not in ev and "preamble" not in ev
    assert sorted(cnav.table[:, gs.E_PRN].astype(int)) == [8, 10, 18, 23, 24, 27, 32]
    nav = read_rinex_nav(walk_dir / "rinex_converted" / "gnss_1730.nav", systems="G").to_week(cnav.ref_week)
    for r in cnav.table:
        x = nav.table[nav.table[:, gs.E_PRN] == r[gs.E_PRN]]
        if len(x):
            p1, v1, _, _ = gs.eph_state(r, r[gs.E_TOE])
            p2, v2, _, _ = gs.eph_state(x[0], r[gs.E_TOE])
            assert np.linalg.norm(p1 - p2) < 1.0 and np.linalg.norm(v1 - v2) < 1e-3
    out, _, file_gps, eph = _bench().residuals(walk_dir, step_s=30.0)
    gps = eph.table[eph.table[:, gs.E_PRN] < 100]
    assert sorted(gps[:, gs.E_PRN].astype(int)) == [8, 10, 18, 23, 24, 27, 32]
    assert np.array_equal(gps[np.isin(gps[:, gs.E_PRN], list(file_gps))], nav.to_week(eph.ref_week).table)
    assert any("0 GPS LNAV record(s) added" in e for e in eph.events)
    new = np.concatenate([out[s] for s in (8, 18, 24)])
    old = np.concatenate([out[s] for s in file_gps])
    rms_new, rms_old = np.sqrt(np.mean(new**2)), np.sqrt(np.mean(old**2))
    print(f"walk GPS residual RMS: CNAV-added {rms_new:.2f} m ({len(new)}), the nav file's {rms_old:.2f} m "
          f"({len(old)})")
    assert rms_new < 2.0 * rms_old and np.max(np.abs(new)) < 25.0  # a wrong field or week gives km
    # the log's Klobuchar coefficients (the nav file has none): those of a type 30; a zenith delay of metres
    assert cnav.iono_alpha is not None and np.array_equal(eph.iono_alpha, cnav.iono_alpha)
    assert any("Klobuchar coefficients from the log" in e for e in eph.events)
    scales = [2.0**-30, 2.0**-27, 2.0**-24, 2.0**-24, 2.0**11, 2.0**14, 2.0**16, 2.0**16]
    steps = np.r_[eph.iono_alpha, eph.iono_beta] / scales
    assert np.array_equal(steps, np.round(steps)) and np.all(np.abs(steps) < 128)
    zenith = gs.klobuchar(0.6998, -1.8352, 0.0, np.pi / 2, eph.table[0, gs.E_TOE] % 604800.0, eph.iono_alpha,
                          eph.iono_beta)
    print(f"broadcast Klobuchar zenith delay at the walk: {zenith:.2f} m")
    assert 0.5 < zenith < 30.0


def test_cnav_span_warning():
    """Observations reaching beyond CNAV_SPAN_S from a CNAV row's epoch are named; LNAV rows never."""
    from aidnav.io.rinex import CNAV_SPAN_S, cnav_span_warning  # lazy: georinex-backed module

    rows = np.zeros((2, gs.N_EPH))
    rows[:, gs.E_TOE] = 1000.0
    rows[1, gs.E_IODE] = -1.0  # a CNAV row
    assert cnav_span_warning(rows, np.array([900.0, 1100.0]), "x.ubx") == []
    w = cnav_span_warning(rows, np.array([900.0, 1000.0 + CNAV_SPAN_S + 1]), "x.ubx")
    assert len(w) == 1 and w[0].startswith("warning: x.ubx") and f"{CNAV_SPAN_S + 1:.0f} s" in w[0]
    assert cnav_span_warning(rows[:1], np.array([0.0, 1e5]), "x.ubx") == []


def test_ubx_sources_parsed():
    from aidnav.errors import InputError  # lazy: only this test
    from aidnav.io.rinex import UBX_SOURCES, parse_ubx_sources  # lazy: georinex-backed module

    assert parse_ubx_sources(UBX_SOURCES) == {"inav", "lnav", "cnav", "klobuchar", "cpstdev"}
    assert parse_ubx_sources(" inav, klobuchar ,") == {"inav", "klobuchar"} and parse_ubx_sources("") == set()
    with pytest.raises(InputError, match="almanac unknown"):
        parse_ubx_sources("inav,almanac")
