"""simulate_to_dir: a short scenario end to end (files, figure, reproducibility, errors)."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from rich.console import Console

from aidnav.apps.simulate import simulate_to_dir
from aidnav.io.interchange import read_gnss, read_imu, read_trajectory
from aidnav.sim.run import ScenarioError, simulate
from aidnav.sim.scenario import load_scenario

SHORT = """# 60 s test scenario
name: short
seed: 5
initial: {lat_deg: 30, lon_deg: 100, height_m: 500, speed_m_s: 50, heading_deg: 10}
segments:
  - {type: straight, duration_s: 20, name: AB}
  - {type: turn, angle_deg: 60, duration_s: 20}
  - {type: straight, duration_s: 20, name: CD}
sensors:
  imu: {grade: tactical}
  gnss: {rate_hz: 2, lever_arm_m: [0.1, 1.0, 0.5], outages: [{start_s: 30, duration_s: 10}]}
"""


def _console():
    return Console(file=io.StringIO(), width=100)


@pytest.fixture()
def short_yaml(tmp_path):
    p = tmp_path / "short.yaml"
    p.write_text(SHORT)
    return p


def test_simulate_to_dir_writes_everything(tmp_path, short_yaml):
    out = tmp_path / "out"
    written = simulate_to_dir(short_yaml, out, fmt="both", console=_console())
    names = sorted(p.name for p in written)
    assert names == sorted(["truth.csv", "imu.csv", "gnss.csv", "truth.parquet", "imu.parquet",
                            "gnss.parquet", "run.json", "trajectory.png"])
    for p in written:
        assert p.exists() and p.stat().st_size > 0
    assert (out / "trajectory.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    truth = read_trajectory(out / "truth.csv")
    assert len(truth) == 6001 and truth.time[-1] == pytest.approx(60.0)
    imu = read_imu(out / "imu.parquet")
    assert len(imu) == 6000 and imu.t0 == 0.0
    gnss = read_gnss(out / "gnss.csv")
    assert gnss.vel is not None and gnss.std_pos is not None
    # 2 Hz over 60 s minus a 10 s outage
    assert 95 <= len(gnss) <= 101
    assert not np.any((gnss.time >= 30) & (gnss.time < 40))
    info = json.loads((out / "run.json").read_text())
    assert info["seed"] == 5 and info["scenario"] == "short"
    assert [s["name"] for s in info["segments"]] == ["AB", "turn_1", "CD"]
    # csv and parquet hold the same numbers
    t2 = read_trajectory(out / "truth.parquet")
    np.testing.assert_array_equal(t2.lat, truth.lat)


def test_seed_override_and_reproducible(short_yaml):
    scn = load_scenario(short_yaml)
    a = simulate(scn)
    b = simulate(scn)
    c = simulate(scn, seed=6)
    assert a.seed == 5 and c.seed == 6
    np.testing.assert_array_equal(a.imu.dtheta, b.imu.dtheta)
    np.testing.assert_array_equal(a.gnss.lat, b.gnss.lat)
    assert not np.array_equal(a.imu.dtheta, c.imu.dtheta)
    assert not np.array_equal(a.gnss.lat, c.gnss.lat)
    # the corrupted IMU differs from the perfect one, the truth does not depend on the seed
    assert not np.array_equal(a.imu.dv, a.imu_true.dv)
    np.testing.assert_array_equal(a.truth.lat, c.truth.lat)


def test_only_csv(tmp_path, short_yaml):
    written = simulate_to_dir(short_yaml, tmp_path / "o", fmt="csv", console=_console())
    assert not any(p.suffix == ".parquet" for p in written)


def test_errors(tmp_path, short_yaml):
    with pytest.raises(ScenarioError, match="format"):
        simulate_to_dir(short_yaml, tmp_path / "o", fmt="xlsx", console=_console())
    bad = tmp_path / "bad.yaml"
    bad.write_text(SHORT.replace("grade: tactical", "grade: nonsense"))
    with pytest.raises(ScenarioError, match=r"sensors\.imu.*nonsense"):
        simulate_to_dir(bad, tmp_path / "o", console=_console())
    bad.write_text(SHORT.replace("duration_s: 20, name: AB", "duraton_s: 20, name: AB"))
    with pytest.raises(ScenarioError, match=r"segments\.0\.duraton_s"):
        simulate_to_dir(bad, tmp_path / "o", console=_console())
