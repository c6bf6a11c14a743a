"""NMEA reader on logs written with pynmea2's own sentence classes (checksums computed by pynmea2)."""

from __future__ import annotations

import math

import numpy as np
import pynmea2
import pytest

from aidnav.io import formats
from aidnav.io.errors import DataError
from aidnav.io.nmea import read_nmea
from aidnav.units import KNOT as KNOT_M_S


def gga(t, lat="4020.17357194", ns="N", lon="11637.64500807", ew="E", q="4", alt="57.4034", sep="-8.4438"):
    return str(pynmea2.GGA("GP", "GGA", (t, lat, ns, lon, ew, q, "17", "0.9", alt, "M", sep, "M", "", "")))


def rmc(t, date="011222", spd="16.216", crs="171.3", status="A"):
    return str(pynmea2.RMC("GP", "RMC", (t, status, "4020.17401738", "N", "11637.64492453", "E", spd, crs,
                                         date, "7.2", "W", "D")))


def vtg(crs="90.0", kmh="36.0"):
    return str(pynmea2.VTG("GP", "VTG", (crs, "T", "", "M", "", "N", kmh, "K", "D")))


def gst(t, slat="0.3", slon="0.2", salt="0.6"):
    return str(pynmea2.GST("GP", "GST", (t, "1.0", "0.5", "0.4", "10", slat, slon, salt)))


def _log(tmp_path, lines, name="log.nmea"):
    p = tmp_path / name
    p.write_text("\r\n".join(lines) + "\r\n")
    return p


def test_gga_rmc_known_answers(tmp_path):
    """The sentences of a NovAtel log whose binary header gives GPS week 2238, 386743.4 s for the RMC
    epoch 11:25:25.40 UTC on 2022-12-01 (18 leap seconds)."""
    p = _log(tmp_path, [rmc("112525.40"), gga("112525.40"), gst("112525.40"),
                        rmc("112525.50"), gga("112525.50")])
    assert formats.detect_gnss_format(p) == "nmea"
    g = formats.read_gnss(p)
    assert g.week == 2238
    np.testing.assert_allclose(g.time, [386743.4, 386743.5], rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.degrees(g.lat[0]), 40 + 20.17357194 / 60, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.degrees(g.lon[0]), 116 + 37.64500807 / 60, rtol=0, atol=1e-12)
    np.testing.assert_allclose(g.height, 57.4034 - 8.4438, rtol=0, atol=1e-9)  # MSL + geoid separation
    s = 16.216 * 1852 / 3600
    c = math.radians(171.3)
    np.testing.assert_allclose(g.vel[0, :2], [s * math.sin(c), s * math.cos(c)], rtol=1e-12)
    assert np.isnan(g.vel[:, 2]).all()  # speed/course: vertical velocity not measured
    assert g.quality.tolist() == [1, 1]  # GGA 4 = RTK fixed → Q 1
    np.testing.assert_allclose(g.std_pos[0], [0.2, 0.3, 0.6])  # GST σlon, σlat, σalt → E, N, U
    # no GST for that epoch: σ from the GGA HDOP 0.9 with the stated UERE (aidnav.io._std.NMEA_UERE_M)
    np.testing.assert_allclose(g.std_pos[1], [0.9, 0.9, 1.8])
    assert g.height_datum == "ellipsoid"
    assert any("UTC → GPST (+18 s" in e for e in g.events)


def test_vtg_velocity_and_date_parameter_and_midnight(tmp_path):
    p = _log(tmp_path, [gga("235959.00"), vtg("90.0", "36.0"), gga("000000.00"), vtg("0.0", "0.0")])
    with pytest.raises(DataError, match="date"):
        read_nmea(p)
    g = read_nmea(p, date="2022-12-03")  # a Saturday: 23:59:59 UTC + 18 s is in the next GPS week
    np.testing.assert_allclose(np.diff(g.time), [1.0])
    # 2022-12-03 23:59:59 UTC = 2022-12-04 00:00:17 GPST, week 2239 starts on Sunday 2022-12-04
    assert g.week == 2239 and g.time[0] == pytest.approx(17.0)
    np.testing.assert_allclose(g.vel[0, :2], [10.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(g.vel[1, :2], [0.0, 0.0])


def test_invalid_fixes_bad_checksum_and_missing_geoid_separation(tmp_path):
    bad = gga("112525.60")[:-2] + "00"  # wrong checksum
    lines = [rmc("112525.40"), gga("112525.40", q="0"), rmc("112525.50"), gga("112525.50", sep=""),
             bad, "\x00\x01binary", rmc("112525.70"), gga("112525.70", q="1")]
    g = read_nmea(_log(tmp_path, lines))
    assert len(g) == 2 and g.quality.tolist() == [1, 5]  # GGA 4 (RTK fixed), 1 (single)
    ev = " | ".join(g.events)
    assert "fix quality 0" in ev and "bad checksum" in ev and "not NMEA" in ev
    assert "without geoid separation" in ev and "nearest given separation" in ev
    # the GGA without separation takes its neighbour's: both ellipsoidal
    np.testing.assert_allclose(g.height, [57.4034 - 8.4438, 57.4034 - 8.4438])
    assert g.height_datum == "ellipsoid"


def test_no_gga_is_an_error(tmp_path):
    with pytest.raises(DataError, match="no GGA"):
        read_nmea(_log(tmp_path, [rmc("112525.40"), rmc("112525.50")]))


def test_rmc_speed_units(tmp_path):
    p = _log(tmp_path, [rmc("000001.00", spd="1.0", crs="0.0"), gga("000001.00")])
    g = read_nmea(p)
    assert g.vel[0, 1] == pytest.approx(KNOT_M_S) and g.vel[0, 1] == pytest.approx(0.514444, abs=1e-6)
