"""convert(): any readable IMU / GNSS log → interchange; reading the output gives the same arrays."""

from __future__ import annotations

import json

import numpy as np
import pyarrow.parquet as pq
import pynmea2
import pytest

from aidnav.io import formats
from aidnav.io.convert import convert
from aidnav.io.errors import DataError


def _same_imu(a, b):
    np.testing.assert_array_equal(a.time, b.time)
    np.testing.assert_array_equal(a.dtheta, b.dtheta)
    np.testing.assert_array_equal(a.dv, b.dv)
    assert a.t0 == b.t0 and a.week == b.week


def _same_gnss(a, b):
    for k in ("time", "lat", "lon", "height", "vel", "std_pos", "std_vel", "quality"):
        x, y = getattr(a, k), getattr(b, k)
        assert (x is None) == (y is None), k
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=k)  # NaN == NaN here
    assert a.week == b.week


@pytest.mark.parametrize("ext", ["csv", "parquet"])
def test_kfgins_imu_and_gnss(tmp_path, ext):
    imu = tmp_path / "imu.txt"
    imu.write_text("\n".join(f"{100 + 0.005 * k!r} 1e-5 {2e-5 * k!r} 3e-5 4e-4 5e-4 -0.049"
                             for k in range(5)))
    gnss = tmp_path / "gnss.txt"
    gnss.write_text("100.0 30.1 114.2 20.5 0.01 0.02 0.03\n101.0 30.1 114.2 20.6 0.01 0.02 0.03\n")
    s = convert(imu, tmp_path / f"imu.{ext}")
    assert s["kind"] == "imu" and s["format"] == "kfgins" and s["samples"] == 5
    _same_imu(formats.read_imu(imu), formats.read_imu(s["output"]))
    s = convert(gnss, tmp_path / f"gnss.{ext}")
    assert s["kind"] == "gnss" and s["format"] == "kfgins"
    _same_gnss(formats.read_gnss(gnss), formats.read_gnss(s["output"]))


def test_nmea_to_csv_keeps_unmeasured_vu_and_records_provenance(tmp_path):
    def rmc(t):
        return str(pynmea2.RMC("GP", "RMC", (t, "A", "4020.1", "N", "11637.6", "E", "10.0", "45.0", "011222",
                                             "", "", "A")))

    def gga(t):
        return str(pynmea2.GGA("GP", "GGA", (t, "4020.1", "N", "11637.6", "E", "4", "17", "0.9", "57.4", "M",
                                             "-8.4", "M", "", "")))

    p = tmp_path / "log.nmea"
    p.write_text("\n".join([rmc("112525.00"), gga("112525.00"), rmc("112526.00"), gga("112526.00")]) + "\n")
    s = convert(p, tmp_path / "g.csv")
    text = (tmp_path / "g.csv").read_text()
    assert "converted by aidnav from log.nmea (gnss, format nmea)" in text
    assert "GPS seconds of week 2238" in text and "UTC → GPST (+18 s" in text
    a, b = formats.read_gnss(p), formats.read_gnss(s["output"])
    _same_gnss(a, b)
    assert np.isnan(b.vel[:, 2]).all()


def test_pos_with_datum_offset_applied_once(tmp_path):
    p = tmp_path / "s.pos"
    p.write_text("% h\n2025/07/08 19:34:18.000 40 -105 1601.4 1 21 0.01 0.01 0.01 0 0 0 0 0\n"
                 "2025/07/08 19:34:19.000 40 -105 1601.5 1 21 0.01 0.01 0.01 0 0 0 0 0\n")
    s = convert(p, tmp_path / "g.parquet", height_offset_m=-21.4)
    g = formats.read_gnss(s["output"])  # no offset: the output is already ellipsoidal
    np.testing.assert_allclose(g.height, [1601.4 - 21.4, 1601.5 - 21.4], rtol=0, atol=1e-9)
    meta = json.loads(pq.ParquetFile(s["output"]).schema_arrow.metadata[b"aidnav"])
    assert meta["gps_week"] == 2374 and any("datum offset -21.400 m" in n for n in meta["notes"])


def test_raw_rtklibexplorer_log(walk_dir, tmp_path):
    d = walk_dir
    s = convert(d / "imu_1730.csv", tmp_path / "imu.parquet")
    assert s["format"] == "rtklibexplorer" and s["week"] == 2381
    _same_imu(formats.read_imu(d / "imu_1730.csv"), formats.read_imu(s["output"]))


def test_bad_output_and_input(tmp_path):
    p = tmp_path / "g.txt"
    p.write_text("1 40 116 10 0.1 0.1 0.2\n")
    with pytest.raises(DataError, match="output must be .csv or .parquet"):
        convert(p, tmp_path / "out.xlsx")
    q = tmp_path / "junk.bin"
    q.write_bytes(b"\x00\x01junk" * 20)
    with pytest.raises(DataError) as ei:
        convert(q, tmp_path / "out.csv")
    assert ei.value.problem.startswith("unknown format") and "IMU logs" in ei.value.problem
    assert "GNSS logs" in ei.value.problem and "binary" in ei.value.problem


def test_options_of_the_other_kind_refused(tmp_path):
    p = tmp_path / "imu.txt"
    p.write_text("1.0 0 0 0 0 0 -0.049\n1.005 0 0 0 0 0 -0.049\n")
    with pytest.raises(ValueError, match="date do not apply to IMU"):
        convert(p, tmp_path / "o.csv", date="2022-12-01")
    assert convert(p, tmp_path / "o.csv", date=None, topic=None)["samples"] == 2
