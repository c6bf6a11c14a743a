"""``aidnav process --odometer --baro``: the CSV files reach the filter (updates counted, scale factor
and barometer bias estimated near their simulated values) and bad files exit 2 naming the line."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from aidnav.apps.simulate import simulate_to_dir
from aidnav.io.interchange import read_trajectory

pytestmark = pytest.mark.slow

SCN = """name: aux
seed: 8
initial: {lat_deg: 30, lon_deg: 114, height_m: 20, speed_m_s: 0, heading_deg: 60}
segments:
  - {type: static, duration_s: 30}
  - {type: accelerate, duration_s: 10, to_speed_m_s: 15}
  - {type: turn, angle_deg: 90, duration_s: 20}
  - {type: straight, duration_s: 60}
  - {type: turn, angle_deg: -90, duration_s: 20}
  - {type: straight, duration_s: 60}
sensors:
  imu: {grade: tactical}
"""
ODO_K = 0.02  # odometer reads 2 % high
BARO_B = 7.0  # barometric height 7 m above the ellipsoidal one


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    from rich.console import Console

    from aidnav.io.interchange import read_trajectory as rt
    from aidnav.sim.baro import simulate_baro
    from aidnav.sim.odometer import simulate_odometer

    d = tmp_path_factory.mktemp("aux")
    (d / "s.yaml").write_text(SCN)
    simulate_to_dir(d / "s.yaml", d / "sim", fmt="parquet", console=Console(quiet=True))
    truth = rt(d / "sim/truth.parquet")
    odo = simulate_odometer(truth, 10.0, ODO_K, 0.05, np.random.default_rng(1))
    baro = simulate_baro(truth, 5.0, BARO_B, 0.3, np.random.default_rng(2))
    np.savetxt(d / "odo.csv", np.column_stack([odo.time, odo.speed]), delimiter=",",
               header="time_s,speed_m_s", comments="", fmt="%.17g")
    np.savetxt(d / "baro.csv", np.column_stack([baro.time, baro.height]), delimiter=",",
               header="time_s,height_m", comments="", fmt="%.17g")
    return d


def _process(d, out, *extra):
    return subprocess.run([sys.executable, "-m", "aidnav", "process", "--imu", str(d / "sim/imu.parquet"),
                           "--gnss", str(d / "sim/gnss.parquet"), "-o", str(d / out), "--no-figures", *extra],
                          capture_output=True, text=True, timeout=600)


def test_odometer_and_baro_reach_the_filter(files):
    r = _process(files, "o", "--odometer", str(files / "odo.csv"), "--baro", str(files / "baro.csv"),
                 "--kfgins-nav")
    assert r.returncode == 0, r.stderr
    from aidnav.io.kfgins import read_nav

    nav = read_nav(files / "o" / "trajectory.nav")  # the KF-GINS result file, read back
    t = read_trajectory(files / "o" / "trajectory.parquet")
    np.testing.assert_allclose(nav.time, t.time, rtol=0, atol=1e-6)
    np.testing.assert_allclose(nav.lat, t.lat, rtol=0, atol=1e-10)
    np.testing.assert_allclose(nav.vel, t.vel, rtol=0, atol=1e-6)
    s = json.loads((files / "o" / "summary.json").read_text())
    assert s["counts"]["odometer_updates"] > 500 and s["counts"]["baro_updates"] > 500
    b = t.extra["baro_bias_m"][-1]
    assert abs(b - BARO_B) < 1.0, b
    # the odometer scale factor with its σ from the summary: within 4σ of the simulated value
    k = s["calibration"]["odometer_scale"]
    assert k["estimated"] and k["std"] < 0.01, k
    assert abs(k["value"] - ODO_K) < 4 * k["std"], k


def test_bad_odometer_file_exits_2(files):
    (files / "bad.csv").write_text("time_s,speed_m_s\n1.0,3.0\n2.0,fast\n")
    r = _process(files, "b", "--odometer", str(files / "bad.csv"))
    assert r.returncode == 2, r.stderr
    assert "bad.csv" in r.stderr and "3" in r.stderr


def test_an_unknown_aid_is_a_clear_error(tmp_path):
    from typer.testing import CliRunner

    from aidnav.cli import app

    r = CliRunner().invoke(app, ["process", "--imu", "i.csv", "--gnss", "g.csv", "--aid", "sonar=x.csv",
                                 "-o", str(tmp_path / "o")])
    assert r.exit_code == 2 and "--aid sonar=x.csv" in r.output and "odometer, baro, mag" in r.output
