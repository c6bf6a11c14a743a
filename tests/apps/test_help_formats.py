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
