"""u-blox RXM-RAWX (issue 40, session 15): the frame layout and the receiver's σ decoded from frames written
here at the interface description's byte offsets, the loss-of-lock indicator, and the walk's log against
the RINEX file RTKLIB's convbin wrote from it (code, phase, Doppler and C/N0 equal to RINEX's rounding; a
phase present exactly where convbin's cpStdev rule keeps it)."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from aidnav.io.rawx import merge_rawx, rawx_observations, read_rawx
from aidnav.nav.gnss_sat import C_LIGHT, FREQ_L1, sat_id


def _frame(cls: int, mid: int, payload: bytes) -> bytes:
    body = bytes([cls, mid]) + struct.pack("<H", len(payload)) + payload
    a = b = 0
    for x in body:
        a = (a + x) & 0xFF
        b = (b + a) & 0xFF
    return b"\xb5\x62" + body + bytes([a, b])


def _rawx(tow: float, week: int, meas: list) -> bytes:
    """An RXM-RAWX frame: meas = [(pr, cp, do, gnssId, svId, sigId, lock_ms, cno, prs, cps, dos, trk)]."""
    p = struct.pack("<dHbBBB2x", tow, week, 18, len(meas), 0, 1)
    for pr, cp, do, g, sv, sig, lock, cno, prs, cps, dos, trk in meas:
        p += struct.pack("<ddfBBBBHBBBBBx", pr, cp, do, g, sv, sig, 0, lock, cno, prs, cps, dos, trk)
    return _frame(0x02, 0x15, p)


def test_rawx_fields_and_sigma_conversions(tmp_path):
    """Two epochs, GPS L1 C/A, BeiDou B1C pilot (sigId 5) and a BeiDou B1I (sigId 0: not the signal read);
    a frame with a broken checksum between them is skipped."""
    e1 = [(2.1e7, 1.1e8, -512.25, 0, 10, 0, 5000, 45, 3, 2, 4, 0b0111),
          (2.3e7, 1.2e8, 100.5, 3, 21, 5, 800, 38, 5, 7, 6, 0b1111),
          (2.3e7, 1.2e8, 100.5, 3, 21, 0, 800, 38, 5, 7, 6, 0b0111)]
    e2 = [(2.1e7 + 10, 1.1e8 + 50, -512.0, 0, 10, 0, 200, 44, 3, 3, 4, 0b0011),  # lock fell: a slip; half
          (2.3e7 + 10, 1.2e8 + 60, 101.0, 3, 21, 5, 1050, 37, 5, 15, 6, 0b1101)]  # no cpValid: no phase
    bad = bytearray(_rawx(5.0, 2381, e1))
    bad[-1] ^= 0xFF
    f = tmp_path / "x.ubx"
    f.write_bytes(b"junk" + _rawx(408000.0, 2381, e1) + bytes(bad) + _rawx(408000.25, 2381, e2))
    m = read_rawx(f)
    assert m.week == 2381 and len(m.time) == 5
    np.testing.assert_array_equal(m.time, [408000.0] * 3 + [408000.25] * 2)
    assert list(m.letter) == ["G", "C", "C", "G", "C"] and list(m.sv) == [10, 21, 21, 10, 21]
    np.testing.assert_allclose(m.pr_std[:2], [0.01 * 2**3, 0.01 * 2**5])  # 0.01·2^n m
    np.testing.assert_allclose(m.cp_std[:2], [0.004 * 2, 0.004 * 7])  # 0.004·n cycles
    np.testing.assert_allclose(m.do_std[:2], [0.002 * 2**4, 0.002 * 2**6])  # 0.002·2^n Hz
    rx = rawx_observations(m)
    o = rx.obs
    assert o.names == ["G10", "C21"] and list(o.prn) == [sat_id("G10"), sat_id("C21")]
    np.testing.assert_allclose(o.frequencies(), FREQ_L1)  # B1C at 1575.42 MHz, not B1I's
    lam = C_LIGHT / FREQ_L1
    np.testing.assert_allclose(o.code1, [[2.1e7, 2.3e7], [2.1e7 + 10, 2.3e7 + 10]])
    assert np.isnan(o.phase1[1, 1]) and o.phase1[1, 0] == 1.1e8 + 50
    np.testing.assert_allclose(rx.phase_sigma[0], [0.008 * lam, 0.028 * lam])
    np.testing.assert_allclose(rx.rate_sigma[0], [0.032 * lam, 0.128 * lam])
    # indicator: bit 0 at the first phase and where the lock time fell; bit 1: the half cycle unresolved
    assert o.lli1[0, 0] == 1 and o.lli1[0, 1] == 1 and o.lli1[1, 0] == 1 | 2
    merged = merge_rawx(rawx_observations(m, "G").obs, rx)
    assert merged.names == ["G10", "C21"] and np.isfinite(merged.phase_sigma1[0]).all()


def test_walk_rawx_equals_the_rinex_file_written_from_it(walk_dir):
    """The walk's log against its RINEX file (convbin 2.4.3): every code, Doppler and C/N0 equal to the
    file's rounding; the phase equal where both have it, and the file has it exactly where the receiver's
    cpStdev index is ≤ 5 (RTKLIB's CPSTD_VALID); BeiDou (B1C, not in the file) added for 10 satellites."""
    from aidnav.io.rinex import read_rinex_obs  # lazy: georinex-backed module

    obs = read_rinex_obs(walk_dir / "rinex_converted" / "gnss_1730.obs", systems="GES")
    m = read_rawx(walk_dir / "gnss_1730.ubx")
    rx = rawx_observations(m, "GESC", obs.ref_week, obs.time)
    o = rx.obs.subset_sats(obs.prn)
    for a, b, tol in ((obs.code1, o.code1, 5e-4), (obs.doppler1, o.doppler1, 5e-4), (obs.cn0, o.cn0, 0.0)):
        assert np.array_equal(np.isfinite(a), np.isfinite(b))
        assert np.nanmax(np.abs(a - b)) <= tol + 1e-9
    both = np.isfinite(obs.phase1)
    assert np.all(np.isfinite(o.phase1[both])) and np.nanmax(np.abs(obs.phase1 - o.phase1)) <= 5e-4 + 1e-9
    lam = C_LIGHT / FREQ_L1
    idx = np.rint(rx.phase_sigma / lam / 0.004)
    extra = np.isfinite(o.phase1) & ~both
    assert both.sum() > 6000 and extra.sum() > 1000
    idx = _in_order(idx, rx.obs.prn, obs.prn)
    assert np.all(idx[both] <= 5) and np.all(idx[extra] > 5)
    merged = merge_rawx(obs, rx, "C")
    new = [n for n in merged.names if n[0] == "C"]
    assert len(new) == 10 and np.isfinite(merged.phase1[:, [merged.names.index(n) for n in new]]).sum() > 3000


def _in_order(a, ids, prns):
    """The columns of ``a`` (T, len(ids)) in the order ``prns``."""
    pos = {int(p): j for j, p in enumerate(ids)}
    return np.column_stack([a[:, pos[int(p)]] for p in prns])


def test_missing_log_or_no_rawx(tmp_path):
    from aidnav.io.errors import DataError

    with pytest.raises(DataError):
        read_rawx(tmp_path / "none.ubx")
    f = tmp_path / "empty.ubx"
    f.write_bytes(_frame(0x01, 0x07, bytes(92)))
    with pytest.raises(DataError):
        read_rawx(f)
