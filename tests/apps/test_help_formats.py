"""``process --help`` and ``evaluate --help`` name every format the readers know (issue 38): a format
added to aidnav.io.formats without its name in the help fails here."""

from __future__ import annotations

from typer.testing import CliRunner

from aidnav.cli import app
from aidnav.io.formats import GNSS_FORMATS, IMU_FORMATS, TRAJECTORY_FORMATS

#: how each format is named in the help texts
NAMES = {"interchange": "interchange", "rtklibexplorer": "rtklibexplorer", "kfgins": "KF-GINS",
         "rosbag": "ROS", "rtklib-pos": ".pos", "nmea": "NMEA", "ubx": "UBX", "kfgins-nav": ".nav"}


def _help(cmd: str) -> str:
    r = CliRunner().invoke(app, [cmd, "--help"], terminal_width=400)
    assert r.exit_code == 0, r.output
    return " ".join(r.output.split())


def test_process_help_names_every_imu_and_gnss_format():
    text = _help("process")
    for k in [*IMU_FORMATS, *GNSS_FORMATS]:
        assert NAMES[k] in text, (k, text[:3000])
    assert "--imu-topic" in text and "--gnss-topic" in text


def test_evaluate_help_names_every_trajectory_format():
    text = _help("evaluate")
    for k in TRAJECTORY_FORMATS:
        assert NAMES[k.removeprefix("gnss:")] in text, (k, text[:3000])


def test_topic_options_refuse_a_file_that_is_not_a_bag(tmp_path):
    imu = tmp_path / "imu.csv"
    imu.write_text("time,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,accel_x_m_s2,accel_y_m_s2,accel_z_m_s2\n"
                   + "".join(f"{100 + 0.01 * k:.2f},0,0,0,0,0,9.8\n" for k in range(10)))
    gnss = tmp_path / "gnss.csv"
    gnss.write_text("time,lat_deg,lon_deg,height_m\n100.0,40.0,-105.0,1600.0\n")
    for opt, msg in (("--imu-topic", "is not a ROS bag"), ("--gnss-topic", "not a ROS bag")):
        r = CliRunner().invoke(app, ["process", "--imu", str(imu), "--gnss", str(gnss), opt, "/x", "-o",
                                     str(tmp_path / "o"), "--no-figures"], terminal_width=400)
        assert r.exit_code == 2, r.output
        assert msg in " ".join(r.output.split()), r.output
