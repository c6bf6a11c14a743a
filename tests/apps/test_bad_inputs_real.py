"""Bad inputs on the real walk set (issue 37): `tight` given an observation file as --nav, and an IMU log
that does not overlap the observations, exit 2 naming the problem (they were exit 1: KeyError 'sqrtA',
IndexError)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest


def cli(*args):
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    env.pop("AIDNAV_DEBUG", None)
    r = subprocess.run([sys.executable, "-m", "aidnav", *map(str, args)], capture_output=True, text=True,
                       env=env, timeout=600)
    return r.returncode, r.stdout + r.stderr


@pytest.mark.slow
def test_tight_bad_inputs(data_dir, tmp_path):
    w = data_dir / "rtklibexplorer_walk_0827"
    drive = data_dir / "rtklibexplorer_drive_0708/imu_1934.csv"
    if not (w / "rinex_converted/gnss_1730.obs").exists() or not drive.exists():
        pytest.skip("walk/drive data not present")
    obs, nav = w / "rinex_converted/gnss_1730.obs", w / "rinex_converted/gnss_1730.nav"
    rc, out = cli("tight", "--imu", w / "imu_1730.csv", "--obs", obs, "--nav", obs, "--no-figures",
                  "-o", tmp_path / "a")
    assert rc == 2 and "gnss_1730.obs" in out and "not a RINEX navigation file" in out, out
    rc, out = cli("tight", "--imu", drive, "--obs", obs, "--nav", nav, "--no-figures", "-o", tmp_path / "b")
    assert rc == 2 and "do not overlap" in out, out
    assert "Traceback" not in out
