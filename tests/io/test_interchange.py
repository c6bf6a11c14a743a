"""Interchange files: full-precision round trips (CSV, Parquet) and DataError on bad input."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from aidnav.data import GnssData, ImuData, Trajectory
from aidnav.io.errors import DataError
from aidnav.io.interchange import (
    IMU_INCREMENT_COLUMNS,
    IMU_RATE_COLUMNS,
    read_gnss,
    read_imu,
    read_table,
    read_trajectory,
    write_gnss,
    write_imu,
    write_trajectory,
)

EXTS = ["csv", "parquet"]


def _imu(n=500, seed=0):
    rng = np.random.default_rng(seed)
    t = 1000.0 + np.arange(1, n + 1) * 0.01 + rng.uniform(-1e-4, 1e-4, n)
    return ImuData(t, rng.normal(size=(n, 3)) * 1e-4 * np.pi, rng.normal(size=(n, 3)) / 3.0, t0=1000.0)


def _traj(n=300, seed=1, std=True):
    rng = np.random.default_rng(seed)
    lat = np.radians(40.0) + np.cumsum(rng.normal(size=n)) * 1e-7
    lon = np.radians(116.0) + np.cumsum(rng.normal(size=n)) * 1e-7
    rph = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.3, 0.3, n),
                           rng.uniform(0, 2 * np.pi, n)])
    kw = {}
    if std:
        kw = dict(std_pos=rng.uniform(0.1, 5, (n, 3)), std_vel=rng.uniform(0.01, 1, (n, 3)),
                  std_att=rng.uniform(1e-5, 1e-2, (n, 3)), extra={"gyro_bias_x_deg_h": rng.normal(size=n)})
    return Trajectory(np.arange(n) * 0.1 + 1 / 3, lat, lon, 7000 + rng.normal(size=n) / 7,
                      rng.normal(size=(n, 3)) * 100, rph, **kw)


@pytest.mark.parametrize("ext", EXTS)
def test_imu_round_trip_exact(tmp_path, ext):
    imu = _imu()
    p = write_imu(imu, tmp_path / f"imu.{ext}")
    back = read_imu(p)
    np.testing.assert_array_equal(back.time, imu.time)
    np.testing.assert_array_equal(back.dtheta, imu.dtheta)
    np.testing.assert_array_equal(back.dv, imu.dv)
    assert back.t0 == 1000.0


def test_imu_csv_has_comment_header(tmp_path):
    p = write_imu(_imu(5), tmp_path / "imu.csv")
    lines = p.read_text().splitlines()
    assert lines[0].startswith("#")
    header = [ln for ln in lines if not ln.startswith("#")][0]
    assert header.split(",") == ["time", *IMU_INCREMENT_COLUMNS]


@pytest.mark.parametrize("ext", EXTS)
def test_imu_rates_to_increments(tmp_path, ext):
    t = np.array([0.01, 0.02, 0.04, 0.05])
    rates = np.arange(24, dtype=float).reshape(4, 6) - 10.0
    df = pd.DataFrame(rates, columns=IMU_RATE_COLUMNS)
    df.insert(0, "time", t)
    p = tmp_path / f"rates.{ext}"
    df = df[list(reversed(df.columns))]  # column order does not matter
    if ext == "csv":
        p.write_text("# a comment\n# another\n" + df.to_csv(index=False))
    else:
        df.to_parquet(p)
    imu = read_imu(p)
    dt = np.array([0.01, 0.01, 0.02, 0.01])
    np.testing.assert_allclose(imu.dtheta, rates[:, :3] * dt[:, None], rtol=1e-15)
    np.testing.assert_allclose(imu.dv, rates[:, 3:] * dt[:, None], rtol=1e-15)
    assert imu.t0 == pytest.approx(0.0, abs=1e-15)
    assert any("rates" in e for e in imu.events)


@pytest.mark.parametrize("ext", EXTS)
def test_gnss_round_trip(tmp_path, ext):
    rng = np.random.default_rng(3)
    m = 50
    g = GnssData(np.arange(m) + 0.5, np.radians(40 + rng.normal(size=m) * 1e-4),
                 np.radians(116 + rng.normal(size=m) * 1e-4), 7000 + rng.normal(size=m),
                 vel=rng.normal(size=(m, 3)), std_pos=rng.uniform(0.1, 1, (m, 3)),
                 std_vel=rng.uniform(0.01, 0.1, (m, 3)), quality=np.full(m, 5))
    p = write_gnss(g, tmp_path / f"gnss.{ext}")
    b = read_gnss(p)
    np.testing.assert_array_equal(b.time, g.time)
    np.testing.assert_allclose(b.lat, g.lat, rtol=2e-16, atol=0)
    np.testing.assert_allclose(b.lon, g.lon, rtol=2e-16, atol=0)
    np.testing.assert_array_equal(b.height, g.height)
    np.testing.assert_array_equal(b.vel, g.vel)
    np.testing.assert_array_equal(b.std_pos, g.std_pos)
    np.testing.assert_array_equal(b.std_vel, g.std_vel)
    np.testing.assert_array_equal(b.quality, g.quality)
    # the degrees in the file are exactly the degrees written
    cols, _ = read_table(p)
    np.testing.assert_array_equal(cols["lat_deg"], np.degrees(g.lat))


def test_gnss_minimal_columns(tmp_path):
    p = tmp_path / "g.csv"
    p.write_text("lon_deg,time,height_m,lat_deg\n116,1,10,40\n116.5,2,11,40.5\n")
    g = read_gnss(p)
    assert g.vel is None and g.std_pos is None and g.std_vel is None and g.quality is None
    np.testing.assert_allclose(np.degrees(g.lat), [40, 40.5])


@pytest.mark.parametrize("ext", EXTS)
def test_trajectory_round_trip(tmp_path, ext):
    tr = _traj()
    p = write_trajectory(tr, tmp_path / f"traj.{ext}")
    b = read_trajectory(p)
    np.testing.assert_array_equal(b.time, tr.time)
    np.testing.assert_allclose(b.lat, tr.lat, rtol=2e-16, atol=0)
    np.testing.assert_allclose(b.lon, tr.lon, rtol=2e-16, atol=0)
    np.testing.assert_array_equal(b.height, tr.height)
    np.testing.assert_array_equal(b.vel, tr.vel)
    np.testing.assert_allclose(b.rph, tr.rph, rtol=4e-16, atol=1e-300)
    np.testing.assert_allclose(b.std_pos, tr.std_pos, rtol=1e-14)
    np.testing.assert_array_equal(b.std_vel, tr.std_vel)
    np.testing.assert_allclose(b.std_att, tr.std_att, rtol=4e-16)
    np.testing.assert_array_equal(b.extra["gyro_bias_x_deg_h"], tr.extra["gyro_bias_x_deg_h"])
    # writing what was read gives the same file content
    p2 = write_trajectory(b, tmp_path / f"traj2.{ext}")
    c1, _ = read_table(p)
    c2, _ = read_table(p2)
    for k in ("time", "height_m", "ve", "gyro_bias_x_deg_h"):
        np.testing.assert_array_equal(c1[k], c2[k])


def test_trajectory_columns_and_heading_range(tmp_path):
    tr = _traj(20, std=False)
    tr.rph[0, 2] = 2 * np.pi - 1e-18  # rounds to 360 deg → written as 0
    p = write_trajectory(tr, tmp_path / "t.csv")
    header = [ln for ln in p.read_text().splitlines() if not ln.startswith("#")][0]
    assert header == "time,lat_deg,lon_deg,height_m,ve,vn,vu,roll_deg,pitch_deg,heading_deg"
    cols, _ = read_table(p)
    assert np.all((cols["heading_deg"] >= 0) & (cols["heading_deg"] < 360))
    b = read_trajectory(p)
    assert b.std_pos is None and b.extra == {}
    assert np.all((b.rph[:, 2] >= 0) & (b.rph[:, 2] < 2 * np.pi))


def test_trajectory_std_in_metres_accepted(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("time,lat_deg,lon_deg,height_m,ve,vn,vu,roll_deg,pitch_deg,heading_deg,std_e_m,std_n_m,std_u_m\n"
                 "0,40,116,10,1,2,3,1,2,350,0.5,0.6,0.7\n")
    b = read_trajectory(p)
    np.testing.assert_array_equal(b.std_pos, [[0.5, 0.6, 0.7]])
    np.testing.assert_allclose(np.degrees(b.rph[0]), [1, 2, 350])


def test_large_csv_round_trip(tmp_path):
    n = 100_000
    rng = np.random.default_rng(5)
    imu = ImuData(np.arange(1, n + 1) * 0.01, rng.normal(size=(n, 3)) * 1e-5, rng.normal(size=(n, 3)) * 0.1,
                  t0=0.0)
    p = write_imu(imu, tmp_path / "big.csv")
    back = read_imu(p)  # (a value-for-value round trip of every column; the reader's speed: benchmarks/)
    np.testing.assert_array_equal(back.time, imu.time)
    np.testing.assert_array_equal(back.dtheta, imu.dtheta)
    np.testing.assert_array_equal(back.dv, imu.dv)
    assert back.t0 == imu.t0


# ----------------------------------------------------------------------------------------- bad input
IMU_HEADER = "time," + ",".join(IMU_INCREMENT_COLUMNS)
ROW = "{t},1e-5,2e-5,3e-5,0.01,0.02,0.098"


def _imu_csv(tmp_path, rows, pre="# c1\n"):
    p = tmp_path / "bad.csv"
    p.write_text(pre + IMU_HEADER + "\n" + "\n".join(rows) + "\n")
    return p


def _err(fn, p) -> DataError:
    with pytest.raises(DataError) as ei:
        fn(p)
    e = ei.value
    assert e.path == str(p)
    assert str(e).startswith(str(p))
    return e


def test_empty_file(tmp_path):
    p = tmp_path / "e.csv"
    p.write_text("")
    e = _err(read_imu, p)
    assert "empty" in e.problem
    p.write_text("# only a comment\n\n")
    assert "empty" in _err(read_gnss, p).problem


def test_header_only(tmp_path):
    p = _imu_csv(tmp_path, [])
    p.write_text("# c\n" + IMU_HEADER + "\n")
    e = _err(read_imu, p)
    assert e.line == 2 and "no data" in e.problem


def test_missing_columns_named(tmp_path):
    p = tmp_path / "g.csv"
    p.write_text("time,lat_deg,height_m\n1,40,10\n")
    e = _err(read_gnss, p)
    assert "lon_deg" in e.problem and e.line == 1
    # issue 25: a missing vu column is "vertical velocity not measured" (all-NaN), not an error
    p.write_text("time,lat_deg,lon_deg,height_m,ve,vn\n1,40,116,10,1,2\n")
    g = read_gnss(p)
    np.testing.assert_array_equal(g.vel[0, :2], [1.0, 2.0])
    assert np.isnan(g.vel[0, 2]) and any("vu" in e for e in g.events)
    p = tmp_path / "i.csv"
    p.write_text("time,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_m_s,dv_y_m_s\n1,0,0,0,0,0\n")
    e = _err(read_imu, p)
    assert "dv_z_m_s" in e.problem
    p.write_text("time,foo\n1,2\n")
    e = _err(read_imu, p)
    assert "gyro_x_rad_s" in e.problem and "dtheta_x_rad" in e.problem
    p.write_text("time,lat_deg,lon_deg,height_m,ve,vn,vu,roll_deg,pitch_deg\n0,1,2,3,4,5,6,7,8\n")
    assert "heading_deg" in _err(read_trajectory, p).problem


def test_wrong_column_count(tmp_path):
    p = _imu_csv(tmp_path, [ROW.format(t=1), ROW.format(t=2) + ",5", ROW.format(t=3)])
    e = _err(read_imu, p)
    assert e.line == 4 and "8" in e.problem and "7" in e.problem
    p = _imu_csv(tmp_path, [ROW.format(t=1), ROW.format(t=2), "3,1,2"])
    e = _err(read_imu, p)
    assert e.line == 5 and "3" in e.problem


def test_non_numeric(tmp_path):
    rows = [ROW.format(t=k) for k in range(1, 6)]
    rows[3] = rows[3].replace("0.02", "abc")
    p = _imu_csv(tmp_path, rows)
    e = _err(read_imu, p)
    assert e.line == 6 and "abc" in e.problem and "dv_y_m_s" in e.problem


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf", ""])
def test_nan_inf_empty(tmp_path, bad):
    rows = [ROW.format(t=k) for k in range(1, 6)]
    rows[2] = rows[2].replace("0.098", bad)
    p = _imu_csv(tmp_path, rows)
    e = _err(read_imu, p)
    assert e.line == 5 and "dv_z_m_s" in e.problem and "finite" in e.problem


@pytest.mark.parametrize("times, line, word",
                         [([1, 2, 2, 3], 5, "duplicate"), ([1, 2, 3, 2.5], 6, "backwards")])
def test_time_not_increasing(tmp_path, times, line, word):
    p = _imu_csv(tmp_path, [ROW.format(t=t) for t in times])
    e = _err(read_imu, p)
    assert e.line == line and word in e.problem and f"line {line - 1}" in e.problem


def test_blank_line_inside_and_trailing(tmp_path):
    p = _imu_csv(tmp_path, [ROW.format(t=1), "", ROW.format(t=2)])
    e = _err(read_imu, p)
    assert e.line == 4 and "blank" in e.problem
    p = _imu_csv(tmp_path, [ROW.format(t=1), ROW.format(t=2), "", ""])
    assert len(read_imu(p)) == 2


def test_crlf_line_endings(tmp_path):
    p = tmp_path / "crlf.csv"
    text = "# c\r\n" + IMU_HEADER + "\r\n" + ROW.format(t=1) + "\r\n" + ROW.format(t=2) + "\r\n"
    p.write_bytes(text.encode())
    imu = read_imu(p)
    np.testing.assert_array_equal(imu.time, [1.0, 2.0])
    assert imu.dv[0, 2] == 0.098


def test_parquet_bad_rows(tmp_path):
    df = pd.DataFrame({"time": [1.0, 2.0, 2.0], "lat_deg": [40.0] * 3, "lon_deg": [116.0] * 3,
                       "height_m": [1.0, np.nan, 3.0]})
    p = tmp_path / "g.parquet"
    df.to_parquet(p)
    e = _err(read_gnss, p)
    assert e.line == 2 and "height_m" in e.problem
    df["height_m"] = 1.0
    df.to_parquet(p)
    e = _err(read_gnss, p)
    assert e.line == 3 and "duplicate" in e.problem
    df["lat_deg"] = ["40", "x", "41"]
    df.to_parquet(p)
    e = _err(read_gnss, p)
    assert e.line == 2 and "'x'" in e.problem
    pd.DataFrame({"time": []}, dtype=float).to_parquet(p)
    assert "empty" in _err(read_gnss, p).problem


def test_unknown_extension_and_missing_file(tmp_path):
    assert "unknown file type" in _err(read_imu, tmp_path / "x.txt").problem
    assert "cannot read" in _err(read_imu, tmp_path / "missing.csv").problem
