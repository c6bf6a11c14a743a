"""RTKLIB time-tag files, the IMU-clock → GPST fit, and the GPS time helpers."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from aidnav.io.errors import DataError
from aidnav.io.gpstime import (
    GPS_EPOCH_UNIX,
    calendar_to_gpst_unix,
    calendar_to_week_sow,
    gpst_unix_to_calendar,
    gpst_unix_to_week_sow,
    week_sow_to_gpst_unix,
)
from aidnav.io.timetag import fit_stamp_clock, line_end_offsets, read_timetag


# ------------------------------------------------------------------------------------------ gpstime
def test_gps_epoch_and_known_dates():
    assert calendar_to_week_sow("1980/01/06 00:00:00") == (0, 0.0)
    assert gpst_unix_to_week_sow(GPS_EPOCH_UNIX) == (0, 0.0)
    # 2025-07-08 is a Tuesday of GPS week 2374 (first epoch of the drive .pos file)
    wk, sow = calendar_to_week_sow("2025/07/08 19:34:18.499")
    assert wk == 2374
    assert sow == pytest.approx(2 * 86400 + 19 * 3600 + 34 * 60 + 18.499, abs=1e-9)
    # the drive IMU tag's start time (GPST counted like Unix time) is 2025-07-08 19:34:21.854
    wk2, sow2 = gpst_unix_to_week_sow(1752003261 + 0.854)
    assert (wk2, round(sow2, 6)) == (2374, round(sow + 3.355, 6))
    assert gpst_unix_to_calendar(1752003261.854) == "2025/07/08 19:34:21.854"
    assert calendar_to_gpst_unix("2025/07/08 19:34:21.854") == pytest.approx(1752003261.854, abs=1e-6)


def test_week_sow_vectorised_and_round_trip():
    t = 1752003261.0 + np.array([0.0, 0.25, 1e5, 5e5])  # crosses the end of week 2374
    wk, sow = gpst_unix_to_week_sow(t)
    assert wk.tolist() == [2374, 2374, 2374, 2375]
    assert np.all((sow >= 0) & (sow < 604800))
    np.testing.assert_allclose(week_sow_to_gpst_unix(wk, sow), t, rtol=0, atol=1e-6)
    wk0, sow0 = gpst_unix_to_week_sow(t, week=2374)  # one week for the whole log: stays increasing
    assert wk0 == 2374 and np.all(np.diff(sow0) > 0) and sow0[-1] > 604800
    w, s = calendar_to_week_sow(["2025/07/08 19:34:18.499", "2025-07-08T19:34:18.749", "2025/07/08 19:34:19"])
    np.testing.assert_allclose(s - s[0], [0.0, 0.25, 0.501], atol=1e-9)
    assert w.tolist() == [2374] * 3


def test_calendar_bad_string_names_element():
    with pytest.raises(ValueError, match="element 1"):
        calendar_to_week_sow(["2025/07/08 19:34:18.499", "2025/07/08 19:3x:18"])


# --------------------------------------------------------------------------------------- tag files
def _write_tag(path, start, records, header=b"TIMETAG RTKLIB demo5"):
    sec = int(np.floor(start))
    with open(path, "wb") as f:
        f.write(header.ljust(60, b"\0"))
        f.write(struct.pack("<IId", 123456, sec, start - sec))
        f.write(np.asarray(records, dtype="<u4").reshape(-1, 2).tobytes())


def test_read_timetag_fields(tmp_path):
    p = tmp_path / "x.tag"
    _write_tag(p, 1752003261.854, [[131, 37], [146, 99], [162, 180]])
    tag = read_timetag(p)
    assert tag.header == "TIMETAG RTKLIB demo5"
    assert tag.tick_start_ms == 123456
    assert tag.start_gpst == pytest.approx(1752003261.854, abs=1e-9)
    assert tag.tick_ms.tolist() == [131, 146, 162] and tag.offset.tolist() == [37, 99, 180]
    # bytes ending at 37 arrived with the first chunk, 38..99 with the second, beyond 180: unknown
    arr = tag.arrival_gpst([1, 37, 38, 99, 180, 181])
    np.testing.assert_allclose(arr[:5] - tag.start_gpst, [0.131, 0.131, 0.146, 0.146, 0.162], atol=1e-6)
    assert np.isnan(arr[5])


def test_read_timetag_errors(tmp_path):
    p = tmp_path / "bad.tag"
    _write_tag(p, 1.0e9, [[1, 10]], header=b"NOTATAG")
    with pytest.raises(DataError, match="TIMETAG"):
        read_timetag(p)
    _write_tag(p, 1.0e9, [[1, 10], [2, 30], [3, 20]])
    with pytest.raises(DataError, match=r"record 2 .*offset decreases"):
        read_timetag(p)
    p.write_bytes(b"TIMETAG short")
    with pytest.raises(DataError, match="bad.tag"):
        read_timetag(p)
    _write_tag(p, 1.0e9, [[1, 10], [2, 30]])
    with open(p, "ab") as f:
        f.write(b"\1\2\3")
    assert "partial record" in read_timetag(p).events[0]


def test_line_end_offsets_crlf_correction(tmp_path):
    stored = b"a,1\nbb,2\nccc"  # logged with CRLF: 'a,1\r\n' 'bb,2\r\n' 'ccc'
    p = tmp_path / "t.tag"
    _write_tag(p, 1e9, [[10, 5], [20, 14]])
    ends, notes = line_end_offsets(stored, read_timetag(p), "t.csv")
    assert ends.tolist() == [5, 11, 14] and "CRLF" in notes[0]
    _write_tag(p, 1e9, [[10, 4], [20, 12]])  # logged as stored
    ends, notes = line_end_offsets(stored, read_timetag(p), "t.csv")
    assert ends.tolist() == [4, 9, 12] and notes == []


# --------------------------------------------------------------------------------- clock fitting
def _simulate_logger(n=30000, drift_ppm=20.0, offset=0.1234, seed=1):
    """IMU stamps (1 ms resolution) and arrival times: written on a 15.625 ms logger tick after a
    4 ms transport latency, plus some stalls (late) and a few wrong (early) arrivals."""
    rng = np.random.default_rng(seed)
    stamp_ms = np.cumsum(rng.choice([8, 9, 10, 11], size=n, p=[0.03, 0.1, 0.74, 0.13])) + 261906
    stamp = stamp_ms * 1e-3
    true = 1.75e9 + offset + (1 + drift_ppm * 1e-6) * (stamp - stamp[0])
    ready = true + 0.004
    tick_phase = rng.uniform(0, 0.015625)
    arrival = np.ceil((ready - 1.75e9 - tick_phase) / 0.015625) * 0.015625 + 1.75e9 + tick_phase
    late = rng.choice(n, 50, replace=False)
    arrival[late] += rng.uniform(0.02, 0.1, 50)
    early = rng.choice(n, 10, replace=False)
    arrival[early] -= 0.03
    return stamp, arrival, true


def test_fit_recovers_lower_envelope_and_drift():
    stamp, arrival, true = _simulate_logger()
    fit = fit_stamp_clock(stamp, arrival, quantile=0.01)
    assert fit.drift_ppm == pytest.approx(20.0, abs=0.3)
    err = fit(stamp) - true
    # the lower envelope sits at the minimum latency (4 ms transport) + 1 % of the 15.6 ms band
    assert np.all(np.abs(err - 0.004) < 0.0015)
    r = fit.residual_ms
    assert -0.5 < r["p1"] < 0.5 and 5 < r["median"] < 11 and 14 < r["p99"] < 17
    assert 20 <= r["n_late"] <= 50 and r["n_early"] == 10
    # least squares would sit in the middle of the band and absorb the stalls
    assert 6.0 < r["mean_ls_offset"] < 10.0
    assert "drift +20" in fit.summary()


def test_fit_ignores_nan_arrivals():
    stamp, arrival, _ = _simulate_logger(n=5000)
    arrival[-100:] = np.nan
    fit = fit_stamp_clock(stamp, arrival)
    assert fit.residual_ms["n"] == 4900


# ------------------------------------------------------------------------------------- real data
def _set(data_dir, name):
    d = data_dir / name
    if not d.is_dir():
        pytest.skip(f"data set {name} not found in {data_dir}")
    return d


def test_real_drive_tag(data_dir):
    d = _set(data_dir, "rtklibexplorer_drive_0708")
    tag = read_timetag(d / "imu_1934.csv.tag")
    assert tag.header == "TIMETAG RTKLIB demo5"
    assert len(tag) == 37632
    assert tag.start_week_sow[0] == 2374
    assert tag.start_week_sow[1] == pytest.approx(243261.854, abs=1e-6)
    assert tag.tick_quantum_ms == 16.0  # Windows timer: writes every ~15.6 ms
    data = (d / "imu_1934.csv").read_bytes()
    ends, notes = line_end_offsets(data, tag, "imu_1934.csv")
    assert len(ends) == 54860 and ends[-1] == tag.offset[-1] and "CRLF" in notes[0]
