"""Plausibility checks from physics (issue 37): the real drive made wrong the ways a stranger's file is
wrong — gyro in deg/s labelled rad/s, KF-GINS increments in degrees, an FRD IMU read as RFU, mirrored
axes, GNSS in UTC against an IMU in GPS time, a whole-hour offset — exits 2 naming the cause and the
fix (before any filtering), and each check is skippable by name. Known answers: 57.3 = 180/π, 18 s =
the leap seconds of 2017–, 3600 s."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from aidnav.data import ImuData
from aidnav.io import kfgins
from aidnav.io.errors import DataError
from aidnav.io.interchange import write_gnss, write_imu
from aidnav.io.motion_checks import check_motion, check_up, handedness
from aidnav.io.sanity import check_overlap


@pytest.fixture(scope="module")
def drive(data_dir):
    from aidnav.apps.process import read_gnss_any, read_imu_any

    d = data_dir / "rtklibexplorer_drive_0708"
    if not (d / "imu_1934.csv").exists():
        pytest.skip("rtklibexplorer_drive_0708 not present")
    return read_imu_any(d / "imu_1934.csv"), read_gnss_any(d / "gnss_1934_sf.pos")


def _imu(imu, dth=None, dv=None, dt=0.0):
    return ImuData(imu.time + dt, imu.dtheta if dth is None else dth, imu.dv if dv is None else dv,
                   t0=imu.t0 + dt, week=imu.week)


def _gnss(g, dt):
    import dataclasses

    return dataclasses.replace(g, time=g.time + dt)


def frd(a):  # RFU → FRD components (x forward = y, y right = x, z down = −z)
    return np.column_stack([a[:, 1], a[:, 0], -a[:, 2]])


def swap_xy(a):
    return np.column_stack([a[:, 1], a[:, 0], a[:, 2]])


def test_the_drive_passes(drive):
    imu, g = drive
    check_up(imu, "imu")
    assert check_motion(imu, g, "imu", "gnss") == []
    assert handedness(imu, g) > 0.9


@pytest.mark.parametrize("start", [100.0, 250.0, 400.0])
@pytest.mark.parametrize("lag", [0.0, 1.5])
def test_short_cuts_and_latency_are_not_a_time_scale(drive, start, lag):
    """60-s cuts of the drive (a fleet of one-minute logs) and a 1.5-s GNSS latency (the filter's own
    time-offset state) are not called different time scales: only shifts above TIME_SCALE_MIN_S are."""
    from aidnav.io.motion_checks import TIME_SCALE_MIN_S

    imu, g = drive
    t0 = imu.time[0] + start
    ki = (imu.time >= t0) & (imu.time < t0 + 60.0)
    kg = (g.time >= t0) & (g.time < t0 + 60.0)
    cut = ImuData(imu.time[ki], imu.dtheta[ki], imu.dv[ki], t0=float(imu.time[ki][0] - 0.01), week=imu.week)
    assert lag < TIME_SCALE_MIN_S
    assert check_motion(cut, _gnss(g.subset(kg), lag), "imu", "gnss") == []


@pytest.mark.parametrize("case, check, match", [
    ("deg", "imu-gyro-scale", "57"),
    ("frd", "imu-up", "FRD"),
    ("mirror", "imu-axes", "mirrored"),
    ("utc", "time-scale", "18 leap seconds"),
    ("hour", "overlap", "time zone"),
])
def test_wrong_files_are_named(drive, case, check, match):
    imu, g = drive
    if case == "deg":
        imu = _imu(imu, dth=np.degrees(imu.dtheta))
    elif case == "frd":
        imu = _imu(imu, dth=frd(imu.dtheta), dv=frd(imu.dv))
    elif case == "mirror":
        imu = _imu(imu, dth=swap_xy(imu.dtheta), dv=swap_xy(imu.dv))
    elif case == "utc":
        g = _gnss(g, -18.0)  # UTC = GPST − 18 s
    else:  # the IMU clock an hour ahead of a 9-min drive: no common time, the overlap check names it
        imu = _imu(imu, dt=3600.0)

    def checks(skip=()):
        check_up(imu, "imu", skip)
        check_overlap(imu, g, "imu", "gnss", skip)
        check_motion(imu, g, "imu", "gnss", skip)

    with pytest.raises(DataError, match=match):
        checks()
    checks(skip=[check])  # skippable by name


def cli(*args):
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    env.pop("AIDNAV_DEBUG", None)
    r = subprocess.run([sys.executable, "-m", "aidnav", *map(str, args)], capture_output=True, text=True,
                       env=env, timeout=600)
    return r.returncode, r.stdout + r.stderr


@pytest.mark.slow
def test_cli_exit_2_on_the_real_drive(drive, data_dir, tmp_path):
    """The four acceptance cases through `aidnav process` (files built here): exit 2, no traceback."""
    imu, g = drive
    pos = data_dir / "rtklibexplorer_drive_0708/gnss_1934_sf.pos"
    deg = write_imu(_imu(imu, dth=np.degrees(imu.dtheta)), tmp_path / "gyro_deg.csv")
    kf = kfgins.write_imu(_imu(imu, dth=np.degrees(imu.dtheta)), tmp_path / "kfgins_deg.imu")
    rfu = write_imu(_imu(imu, dth=frd(imu.dtheta), dv=frd(imu.dv)), tmp_path / "frd_as_rfu.csv")
    ok = write_imu(imu, tmp_path / "imu.csv")
    utc = write_gnss(_gnss(g, -18.0), tmp_path / "gnss_utc.csv")
    for imu_path, gnss_path, want in ((deg, pos, "deg/s"), (kf, pos, "deg/s"), (rfu, pos, "FRD"),
                                      (ok, utc, "leap seconds")):
        rc, out = cli("process", "--imu", imu_path, "--gnss", gnss_path, "--no-figures",
                      "-o", tmp_path / "out")
        assert rc == 2 and want in out, out
        assert "Traceback" not in out and str(imu_path if want != "leap seconds" else gnss_path) in out
