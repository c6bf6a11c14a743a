"""Raw rtklibexplorer IMU log reader: units, axes, increments, time mapping, reported problems."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from aidnav.io.gpstime import gpst_unix_to_week_sow
from aidnav.io.logs import read_rtklibexplorer_imu
from aidnav.io.rtklib import read_pos

G0 = 9.80665
START = 1752003261.854  # log start, GPST counted like Unix time
OFFSET = 0.0731  # GPST of the first stamp minus log start [s]
DRIFT = 200e-6  # large, to be measurable over a 30-s synthetic log


def _make_log(tmp_path, lines_spec, name="imu.csv", latency=0.003):
    """Write a CSV from (text, stamp_ms or None) items and its tag file (LF as logged).

    Lines are ready at true time + latency and written on a 15.625 ms logger tick.
    Returns the CSV path and the true GPST (counted like Unix time) of stamp ``s`` [ms] as a function.
    """
    s0 = next(s for _, s in lines_spec if s is not None)

    def true_t(s):
        return START + OFFSET + (1 + DRIFT) * (np.asarray(s, float) - s0) * 1e-3

    data = b""
    records = []
    last_ready = 0.0
    for text, s in lines_spec:
        data += text.encode()
        if s is not None:
            last_ready = max(last_ready, true_t(s) + latency - START)
        tick = int(np.ceil(last_ready / 0.015625) * 15.625)  # written at the next logger tick [ms]
        if records and records[-1][0] == tick:
            records[-1][1] = len(data)
        else:
            records.append([tick, len(data)])
    p = tmp_path / name
    p.write_bytes(data)
    sec = int(START)
    with open(str(p) + ".tag", "wb") as f:
        f.write(b"TIMETAG RTKLIB demo5".ljust(60, b"\0"))
        f.write(struct.pack("<IId", 1000, sec, START - sec))
        f.write(np.array(records, dtype="<u4").tobytes())
    return p, true_t


def _good(s, acc=(0.1, 0.2, 1.0), gyr=(1.0, -2.0, 3.0)):
    return (f"{acc[0]:.3f},{acc[1]:.3f},{acc[2]:.3f},{gyr[0]:.3f},{gyr[1]:.3f},{gyr[2]:.3f},{s}\n", s)


def test_units_axes_increments_and_time(tmp_path):
    stamps = 261906 + np.cumsum(np.r_[0, np.random.default_rng(0).choice([9, 10, 11], 2999)])
    p, true_t = _make_log(tmp_path, [_good(int(s)) for s in stamps])
    imu, fit = read_rtklibexplorer_imu(p, return_fit=True)
    assert len(imu) == 2999  # first line skipped
    assert imu.events[0] == "imu.csv:1: first line skipped (the logger can start in the middle of a line)"
    week, sow_true = gpst_unix_to_week_sow(true_t(stamps[1:]))
    assert week.tolist()[0] == 2374
    # lower envelope = true time + 3 ms transport latency, within the 1 ms tick resolution
    np.testing.assert_allclose(imu.time - sow_true, 0.003, atol=1.5e-3)
    assert fit.drift_ppm == pytest.approx(200.0, abs=10.0)
    dt = np.diff(imu.time)
    np.testing.assert_allclose(imu.dv[1:], np.outer(dt, [0.1 * G0, 0.2 * G0, 1.0 * G0]), rtol=1e-12)
    np.testing.assert_allclose(imu.dtheta[1:], np.outer(dt, np.radians([1.0, -2.0, 3.0])), rtol=1e-12)
    assert imu.t0 == pytest.approx(imu.time[0] - dt[0])
    np.testing.assert_allclose(imu.dv.sum(0) / (imu.time[-1] - imu.t0), [0.1 * G0, 0.2 * G0, G0], rtol=1e-12)


def test_trapezoid_rule(tmp_path):
    spec = [_good(1000 + 10 * k, gyr=(float(k), 0.0, 0.0)) for k in range(50)]
    imu = read_rtklibexplorer_imu(_make_log(tmp_path, spec)[0])
    dt = np.diff(imu.time)
    # rate k at t_k: increment over (t_{k-1}, t_k] is (k - 1/2)·dt
    np.testing.assert_allclose(imu.dtheta[1:, 0], np.radians(np.arange(2, 50) - 0.5) * dt, rtol=1e-12)


def test_axes_and_mounting(tmp_path):
    p, _ = _make_log(tmp_path, [_good(1000 + 10 * k) for k in range(20)])
    frd = read_rtklibexplorer_imu(p, axes="FRD")
    np.testing.assert_allclose(frd.dv[1:] / np.diff(frd.time)[:, None], [[0.2 * G0, 0.1 * G0, -G0]] * 18)
    c = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90° about z
    m = read_rtklibexplorer_imu(p, mounting=c)
    np.testing.assert_allclose(m.dv[1:] / np.diff(m.time)[:, None], [[-0.2 * G0, 0.1 * G0, G0]] * 18)
    with pytest.raises(ValueError, match="axes"):
        read_rtklibexplorer_imu(p, axes="XYZ")


def test_problems_are_reported_with_line_numbers(tmp_path):
    spec = [_good(1000 + 10 * k) for k in range(40)]
    spec[5] = ("0.1,0.2,1.0,1.0,-2.0,1050\n", 1050)  # line 6: 6 fields
    spec[8] = ("0.1,abc,1.0,1.0,-2.0,3.0,1080\n", 1080)  # line 9: not a number
    spec[10] = ("0.1,0.2,nan,1.0,-2.0,3.0,1100\n", 1100)  # line 11: NaN
    spec[13] = _good(1120)  # line 14: duplicate of line 13's stamp
    spec[16] = _good(1140)  # line 17: backwards
    spec += [_good(1600 + 10 * k) for k in range(10)]  # line 41: gap of 210 ms
    spec.append(("0.012,-0.042,1.009,0.015,-0.084,", None))  # line 51: cut short
    imu = read_rtklibexplorer_imu(_make_log(tmp_path, spec)[0])
    ev = "\n".join(imu.events)
    assert "imu.csv:1: first line skipped" in ev
    assert "imu.csv:6: 6 fields, expected 7; line skipped" in ev
    assert "imu.csv:51: 6 fields, expected 7; line skipped" in ev
    assert "imu.csv:9: field is not a number; line skipped" in ev
    assert "imu.csv:11: NaN or inf value; line skipped" in ev
    assert "imu.csv:14: duplicate time stamp; line skipped" in ev
    assert "imu.csv:17: time stamp goes backwards; line skipped" in ev
    assert "imu.csv:41: gap of" in ev
    assert len(imu) == 51 - 7  # 51 lines: first, 6-field, not-a-number, NaN, dup, back, cut
    assert np.all(np.diff(imu.time) > 0)


# ------------------------------------------------------------------------------------- real data
def _set(data_dir, name):
    d = data_dir / name
    if not d.is_dir():
        pytest.skip(f"data set {name} not found in {data_dir}")
    return d


def test_real_drive_log_time_span_and_mapping(data_dir):
    d = _set(data_dir, "rtklibexplorer_drive_0708")
    imu, fit = read_rtklibexplorer_imu(d / "imu_1934.csv", return_fit=True)  # (its speed: benchmarks/)
    assert len(imu) == 54859  # 54,860 lines, the first skipped
    assert np.all(np.diff(imu.time) > 0) and 95 < imu.rate_hz < 105
    gnss = read_pos(d / "gnss_1934_sf.pos")
    # tag log start 19:34:21.854 GPST, the first lines arrived 131 ms later;
    # GNSS epochs 19:34:18.499-19:43:27.499
    assert imu.time[0] - 243261.854 == pytest.approx(0.14, abs=0.03)
    assert 3.0 < imu.time[0] - gnss.time[0] < 4.0  # IMU starts 3.5 s after the first fix
    assert 2.5 < imu.time[-1] - gnss.time[-1] < 3.5  # and ends 3.1 s after the last one
    assert imu.time[-1] - imu.time[0] == pytest.approx(548.59, abs=0.05)
    # arrival − fitted time: 16 ms band (logger tick) above a lower envelope at 0
    r = fit.residual_ms
    assert -0.5 < r["p1"] < 0.5 and r["min"] > -3.0
    assert 6.0 < r["median"] < 10.0 and 14.0 < r["p99"] < 18.0 and r["max"] < 50.0
    assert fit.drift_ppm == pytest.approx(13.2, abs=0.5)
    assert any("CRLF" in e for e in imu.events)


def test_real_walk_log_truncated_last_line(data_dir):
    d = _set(data_dir, "rtklibexplorer_walk_0827")
    imu, fit = read_rtklibexplorer_imu(d / "imu_1730.csv", return_fit=True)
    assert "imu_1730.csv:20457: 6 fields, expected 7; line skipped" in imu.events
    assert imu.events[0].startswith("imu_1730.csv:1: first line skipped (6 fields, expected 7")
    assert len(imu) == 20455
    assert 150 < imu.rate_hz < 170  # median interval 6 ms
    gnss = read_pos(d / "gnss_1730_sf.pos")
    assert 0.5 < imu.time[0] - gnss.time[0] < 2.0 and 1.0 < imu.time[-1] - gnss.time[-1] < 2.5
    r = fit.residual_ms
    assert -0.5 < r["p1"] < 0.5 and 6.0 < r["median"] < 10.0 and r["p99"] < 18.0 and r["max"] < 120.0
    assert abs(fit.drift_ppm) < 2.0
