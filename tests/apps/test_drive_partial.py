"""Real drive: a receiver without vertical velocity (no ``vu`` column, or ``vu`` NaN in some rows)
gives the same horizontal accuracy as the full file (within 10 %), and ``aidnav convert`` then
``aidnav process`` gives the same trajectory as ``process`` on the original files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from aidnav.apps.process import load_config, process, process_logs
from aidnav.data import GnssData
from aidnav.io.formats import read_gnss, read_imu
from aidnav.io.interchange import read_trajectory

REPO = Path(__file__).resolve().parents[2]
CFG = REPO / "examples" / "rtklibexplorer_drive_0708.yaml"
OUTAGES = ["40:15:45"]  # the benchmark outages of the data README


@pytest.fixture(scope="module")
def drive(data_dir):
    d = data_dir / "rtklibexplorer_drive_0708"
    if not d.is_dir():
        pytest.skip(f"{d} not found")
    cfg = load_config(CFG)
    imu = read_imu(d / "imu_1934.csv")
    gnss = read_gnss(d / "gnss_1934_sf.pos", height_offset_m=cfg.gnss.height_offset_m)
    cfg = cfg.model_copy(update={"gnss": cfg.gnss.model_copy(update={"height_offset_m": 0.0})})
    full = process(imu, gnss, cfg, outages=OUTAGES)
    return d, cfg, imu, gnss, full


def _rms(run) -> float:
    return run.summary["outage_score"]["rms_m"]


def test_no_vertical_velocity_same_horizontal_accuracy(drive):
    _, cfg, imu, gnss, full = drive
    g = GnssData(gnss.time, gnss.lat, gnss.lon, gnss.height, gnss.vel.copy(),
                 gnss.std_pos, gnss.std_vel, gnss.quality)
    g.vel[:, 2] = np.nan
    novu = process(imu, g, cfg, outages=OUTAGES)
    assert novu.summary["gnss_velocity_accepted"] > 0.9 * full.summary["gnss_velocity_accepted"]
    assert abs(_rms(novu) - _rms(full)) <= 0.10 * _rms(full), (_rms(novu), _rms(full))
    # and only in some rows
    g.vel[:, 2] = gnss.vel[:, 2]
    g.vel[::3, 2] = np.nan
    some = process(imu, g, cfg, outages=OUTAGES)
    assert abs(_rms(some) - _rms(full)) <= 0.10 * _rms(full), (_rms(some), _rms(full))


def test_convert_then_process_is_the_same(drive, tmp_path):
    from aidnav.io.convert import convert

    d, _, _, _, _ = drive
    convert(d / "imu_1934.csv", tmp_path / "c" / "imu.parquet", kind="imu")
    convert(d / "gnss_1934_sf.pos", tmp_path / "c" / "gnss.parquet", kind="gnss")
    a = process_logs(d / "imu_1934.csv", d / "gnss_1934_sf.pos", CFG, tmp_path / "a")
    # the converted GNSS file holds the file's heights; the config's datum offset is applied on reading
    b = process_logs(tmp_path / "c" / "imu.parquet", tmp_path / "c" / "gnss.parquet", CFG, tmp_path / "b")
    ta = read_trajectory(tmp_path / "a" / "trajectory.parquet")
    tb = read_trajectory(tmp_path / "b" / "trajectory.parquet")
    assert a["gnss_fixes"] == b["gnss_fixes"] and a["imu_samples"] == b["imu_samples"]
    np.testing.assert_allclose(tb.time, ta.time, rtol=0, atol=1e-9)
    np.testing.assert_allclose(tb.lat, ta.lat, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tb.height, ta.height, rtol=0, atol=1e-6)
