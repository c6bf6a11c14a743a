"""One format detection for IMU, GNSS and trajectory files; unknown formats; delimiters; datum offset once."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.io import formats, gpstime
from aidnav.io.errors import DataError
from aidnav.io.interchange import read_gnss as read_gnss_interchange
from aidnav.io.interchange import read_imu as read_imu_interchange

IMU_HEAD = "time,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_m_s,dv_y_m_s,dv_z_m_s"


def _w(tmp_path, name, text):
    p = tmp_path / name
    (p.write_bytes if isinstance(text, bytes) else p.write_text)(text)
    return p


# ---------------------------------------------------------------------------------- GPS time / leap s
@pytest.mark.parametrize("utc, leap", [("1980-01-06T00:00:00", 0), ("1981-06-30T23:59:59", 0),
                                       ("1981-07-01T00:00:00", 1), ("1999-01-01T00:00:00", 13),
                                       ("2016-12-31T23:59:59", 17), ("2017-01-01T00:00:00", 18),
                                       ("2025-08-28T17:30:21", 18)])
def test_leap_seconds_table(utc, leap):
    t = float(np.datetime64(utc, "s").astype(np.int64))
    assert gpstime.leap_seconds(t) == leap
    assert gpstime.gpst_unix_to_utc_unix(gpstime.utc_unix_to_gpst_unix(t)) == t


def test_week_sow_to_utc_iso_known_epoch():
    # NovAtel log in the KF-GINS issue: GPS week 2238, 386743.4 s = 2022-12-01 11:25:25.4 UTC (RMC)
    assert gpstime.week_sow_to_utc_iso(2238, 386743.4)[0] == "2022-12-01T11:25:25.400000Z"
    with pytest.raises(ValueError):
        gpstime.leap_seconds(0.0)


# ---------------------------------------------------------------------------------------- detection
def test_detect_interchange_and_headerless_formats(tmp_path):
    imu = _w(tmp_path, "imu.csv", IMU_HEAD + "\n1,0,0,0,0,0,0.098\n2,0,0,0,0,0,0.098\n")
    gnss = _w(tmp_path, "g.csv", "time,lat_deg,lon_deg,height_m\n1,40,116,10\n")
    kf_imu = _w(tmp_path, "kf_imu.txt", "100.0 1e-4 2e-4 3e-4 0.01 0.02 -0.098\n100.005 1e-4 2e-4 3e-4 "
                                        "0.01 0.02 -0.098\n")
    kf_gnss = _w(tmp_path, "kf_gnss.txt", "100.0 30.5 114.3 20.1 0.01 0.02 0.03\n101.0 30.5 114.3 20.1 "
                                          "0.01 0.02 0.03\n")
    assert formats.detect_imu_format(imu) == "interchange"
    assert formats.detect_gnss_format(gnss) == "interchange"
    assert formats.detect_imu_format(kf_imu) == "kfgins"
    assert formats.detect_gnss_format(kf_gnss) == "kfgins"
    assert formats.detect_gnss_format(_w(tmp_path, "x.txt", "$GPGGA,112525.50,4020.1,N,11637.6,E,4,17,0.9,"
                                         "57.4,M,-8.4,M,,*47\n")) == "nmea"
    pos = "% RTKLIB\n2025/07/08 19:34:18.499 40 -105 1601 1 21 0.01 0.01 0.01 0 0 0 0 0\n"
    assert formats.detect_gnss_format(_w(tmp_path, "s.txt", pos)) == "rtklib-pos"
    assert formats.detect_gnss_format(_w(tmp_path, "u.bin", b"\xb5\x62\x01\x07\x5c\x00" + bytes(98))) == "ubx"


@pytest.mark.parametrize("content, seen", [
    ("", "empty"),
    ("1 2 3\n4 5 6\n", "3 numeric columns"),
    ("hello world\nfoo\n", "without a 'time' column: hello, world"),
    (b"\x00\x01\x02\x03garbage" * 10, "binary"),
    ("a;b;c\n1;2;3\n", "without a 'time' column"),
])
def test_unknown_imu_format_names_the_expected_ones(tmp_path, content, seen):
    """Today's bug: a headerless or garbage file fell through to the raw-logger reader and died looking
    for a .tag file."""
    p = _w(tmp_path, "x.dat", content)
    with pytest.raises(DataError) as ei:
        formats.read_imu(p)
    msg = ei.value.problem
    assert seen in msg
    if content:
        assert msg.startswith("unknown format: expected one of") and "kfgins" in msg and "rosbag" in msg
        assert ".tag" in msg  # the raw format is listed with what it needs, not crashed into


def test_unknown_gnss_format(tmp_path):
    p = _w(tmp_path, "g.dat", "1 2 3 4\n5 6 7 8\n")
    with pytest.raises(DataError) as ei:
        formats.read_gnss(p)
    assert ei.value.problem.startswith("unknown format") and "nmea" in ei.value.problem
    with pytest.raises(DataError, match="file not found"):
        formats.read_gnss(tmp_path / "none.csv")
    with pytest.raises(ValueError, match="unknown GNSS format"):
        formats.read_gnss(p, fmt="gpx")


def test_raw_log_without_tag_is_named(tmp_path):
    rows = "".join(f"0.01,-0.02,1.01,0.1,0.2,0.3,{3326339 + 6 * k}\n" for k in range(10))
    p = _w(tmp_path, "imu.csv", rows)
    with pytest.raises(DataError) as ei:
        formats.read_imu(p)
    assert "imu.csv.tag" in ei.value.problem and "missing" in ei.value.problem


# --------------------------------------------------------------------------------------- delimiters
@pytest.mark.parametrize("sep", [";", "\t"])
def test_semicolon_and_tab_delimiters(tmp_path, sep):
    ref = _w(tmp_path, "ref.csv", IMU_HEAD + "\n1,0.1,0.2,0.3,0.4,0.5,0.6\n2,1e-3,2e-3,3e-3,4,5,6\n")
    text = ref.read_text().replace(",", sep)
    p = _w(tmp_path, "sep.csv", text)
    a, b = read_imu_interchange(ref), formats.read_imu(p)
    np.testing.assert_array_equal(a.time, b.time)
    np.testing.assert_array_equal(a.dtheta, b.dtheta)
    np.testing.assert_array_equal(a.dv, b.dv)


def test_decimal_comma_and_space_separated_header_named(tmp_path):
    p = _w(tmp_path, "g.csv", "time;lat_deg;lon_deg;height_m\n1;40,5;116;10\n")
    with pytest.raises(DataError) as ei:
        read_gnss_interchange(p)
    assert ei.value.line == 2 and "decimal comma" in ei.value.problem
    p = _w(tmp_path, "g2.csv", "time lat_deg lon_deg height_m\n1 40 116 10\n")
    with pytest.raises(DataError) as ei:
        read_gnss_interchange(p)
    assert "spaces" in ei.value.problem and "','" in ei.value.problem


# ------------------------------------------------------------------------------------- datum offset
def test_height_offset_applied_once_for_every_format(tmp_path):
    inter = _w(tmp_path, "g.csv", "time,lat_deg,lon_deg,height_m\n1,40,116,100\n2,40,116,101\n")
    kf = _w(tmp_path, "g.txt", "1 40 116 100 0.1 0.1 0.2\n2 40 116 101 0.1 0.1 0.2\n")
    pos = _w(tmp_path, "g.pos", "% h\n2025/07/08 19:34:18.000 40 116 100 1 21 0.01 0.01 0.01 0 0 0 0 0\n"
                                "2025/07/08 19:34:19.000 40 116 101 1 21 0.01 0.01 0.01 0 0 0 0 0\n")
    for p in (inter, kf, pos):
        g = formats.read_gnss(p, height_offset_m=-21.4)
        np.testing.assert_allclose(g.height, [100 - 21.4, 101 - 21.4], rtol=0, atol=1e-12)
        assert sum("datum offset -21.400 m" in e for e in g.events) == 1
        assert formats.read_gnss(p).height.tolist() == [100.0, 101.0]
        t = formats.read_trajectory_any(p, height_offset_m=-21.4)
        np.testing.assert_allclose(t.height, [100 - 21.4, 101 - 21.4], rtol=0, atol=1e-12)
        assert np.isnan(t.rph).all()


def test_spreadsheet_export_bom_and_quoted_header(tmp_path):
    text = b'\xef\xbb\xbf"time";"lat_deg";"lon_deg";"height_m"\r\n1;40;116;10\r\n2;40;116;11\r\n'
    p = _w(tmp_path, "g.csv", text)
    g = formats.read_gnss(p)
    assert g.height.tolist() == [10.0, 11.0] and np.degrees(g.lat[0]) == 40.0


def test_kfgins_imu_and_gnss_files_swapped(tmp_path):
    imu = _w(tmp_path, "imu.txt", "100.0 1e-4 2e-4 3e-4 0.01 0.02 0.098\n"
                                  "100.005 1e-4 2e-4 3e-4 0.01 0.02 0.098\n")
    gnss = _w(tmp_path, "gnss.txt", "100.0 30.5 114.3 20.1 0.01 0.02 0.03\n"
                                    "101.0 30.5 114.3 20.1 0.01 0.02 0.03\n")
    with pytest.raises(DataError, match="KF-GINS IMU file"):
        formats.read_gnss(imu)
    with pytest.raises(DataError, match="KF-GINS GNSS file"):
        formats.read_imu(gnss)
