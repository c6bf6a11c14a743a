"""Messages that name the file, the line or field, what is wrong and what to do (issue 37): corrupted
NMEA/UBX logs say "bad checksum", a binary scenario or experiment file is named, numbers print as
numbers (not ``np.float64(…)``), no option the command line lacks is offered as the fix."""

from __future__ import annotations

import pynmea2
import pytest
from pyubx2 import GET, UBXMessage

from aidnav.experiments.config import ExperimentError, load_experiment
from aidnav.io import formats
from aidnav.io.errors import DataError
from aidnav.sim.scenario import ScenarioError, load_scenario


def _gga(t):
    return str(pynmea2.GGA("GP", "GGA", (t, "4020.17357194", "N", "11637.64500807", "E", "4", "17", "0.9",
                                         "57.4034", "M", "-8.4438", "M", "", "")))


def test_nmea_every_checksum_bad(tmp_path):
    p = tmp_path / "bad.nmea"
    p.write_text("\r\n".join(_gga(f"1125{s:02d}.00")[:-2] + "00" for s in range(5)) + "\r\n")
    with pytest.raises(DataError, match=r"bad\.nmea:1: no GGA sentence with a good checksum.*bad checksum"):
        formats.read_gnss(p, "nmea")


def test_nmea_without_date_names_no_cli_option(tmp_path):
    p = tmp_path / "nodate.nmea"
    p.write_text("\r\n".join(_gga(f"1125{s:02d}.00") for s in range(5)) + "\r\n")
    with pytest.raises(DataError, match="RMC") as e:
        formats.read_gnss(p, "nmea")
    assert "(date=YYYY-MM-DD)" not in str(e.value)


def test_ubx_every_checksum_bad(tmp_path):
    f = dict(iTOW=408639750, year=2025, month=8, day=28, hour=17, min=30, second=21, validDate=1, validTime=1,
             fullyResolved=1, tAcc=21, nano=0, fixType=3, gnssFixOk=1, diffSoln=1, carrSoln=2, numSV=25,
             lon=-105.1, lat=40.1, height=1580048, hMSL=1601435, hAcc=14, vAcc=10, velN=0, velE=0, velD=0,
             sAcc=70)
    frame = bytearray(UBXMessage("NAV", "NAV-PVT", GET, **f).serialize())
    frame[-1] ^= 0xFF  # checksum byte
    p = tmp_path / "bad.ubx"
    p.write_bytes(bytes(frame) * 4)
    with pytest.raises(DataError, match=r"bad\.ubx.*bad checksum.*corrupted"):
        formats.read_gnss(p, "ubx")


def test_binary_scenario_and_experiment_are_named(tmp_path):
    p = tmp_path / "scn.yaml"
    p.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(ScenarioError, match=r"scn\.yaml: not a text file"):
        load_scenario(p)
    with pytest.raises(ExperimentError, match=r"scn\.yaml: not a text file"):
        load_experiment(p)


def test_numbers_print_as_numbers(tmp_path):
    p = tmp_path / "imu.csv"
    p.write_text("time,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,accel_x_m_s2,accel_y_m_s2,accel_z_m_s2\n"
                 "0.01,0,0,0,0,0,9.8\n0.02,0,0,0,0,0,9.8\n0.02,0,0,0,0,0,9.8\n0.03,0,0,0,0,0,9.8\n")
    with pytest.raises(DataError) as e:
        formats.read_imu(p)
    msg = str(e.value)
    assert "duplicate time" in msg and "0.02 s" in msg and "np.float64" not in msg
