"""Same input, same answer (issue 37): the real drive from its raw rtklibexplorer CSV (in memory), from
the converted interchange Parquet (the streamed path) and from the converted interchange CSV gives the
same summary — calibration (time offset and velocity delay estimated automatically), NIS, counts — and
the same trajectory. The streamed path used to mark ``imu.time_offset_s`` as given and so stopped
estimating the time offset and the velocity delay."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from aidnav.io.interchange import read_trajectory

pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]


def cli(*args):
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    env.pop("AIDNAV_DEBUG", None)
    r = subprocess.run([sys.executable, "-m", "aidnav", *map(str, args)], capture_output=True, text=True,
                       env=env, timeout=900)
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout


def test_drive_csv_parquet_interchange_agree(data_dir, tmp_path):
    d = data_dir / "rtklibexplorer_drive_0708"
    if not (d / "imu_1934.csv").exists():
        pytest.skip("rtklibexplorer_drive_0708 not present")
    # the example configuration with the time offset and velocity delay left automatic
    cfg = "\n".join(ln for ln in (REPO / "examples/rtklibexplorer_drive_0708.yaml").read_text().splitlines()
                    if not ln.strip().startswith(("time_offset:", "velocity_delay:")))
    (tmp_path / "cfg.yaml").write_text(cfg)
    cli("convert", "--imu", d / "imu_1934.csv", "-o", tmp_path / "pq")
    cli("convert", "--imu", d / "imu_1934.csv", "-o", tmp_path / "csv", "--format", "csv")
    runs = {}
    for name, imu in (("raw", d / "imu_1934.csv"), ("parquet", tmp_path / "pq/imu.parquet"),
                      ("csv", tmp_path / "csv/imu.csv")):
        cli("process", "--imu", imu, "--gnss", d / "gnss_1934_sf.pos", "--config", tmp_path / "cfg.yaml",
            "--no-figures", "-o", tmp_path / name)
        runs[name] = json.loads((tmp_path / name / "summary.json").read_text())
    ref = runs["raw"]
    assert ref["calibration"]["time_offset_s"]["estimated"]  # automatic: estimated with GNSS velocities
    same = [k for k in ref if k not in ("imu", "output", "events", "timing_s")]
    for name in ("parquet", "csv"):
        for k in same:
            assert runs[name][k] == ref[k], (name, k)
        a, b = (read_trajectory(tmp_path / n / "trajectory.parquet") for n in ("raw", name))
        np.testing.assert_array_equal(a.time, b.time)
        np.testing.assert_array_equal(a.lat, b.lat)
        np.testing.assert_array_equal(a.rph, b.rph)
