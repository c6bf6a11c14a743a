"""Issue 25 acceptance: a GNSS file without vu (or with vu NaN in some rows) processes and gives the
same horizontal outage accuracy on the real drive as the full file, within 10 %."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from aidnav.apps.process import load_config, outage_windows, parse_outage, score_outages
from aidnav.filters.loose import run_loose, to_trajectory
from aidnav.io import formats
from aidnav.io.convert import convert

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_drive_without_vertical_velocity(data_dir, tmp_path):
    d = data_dir / "rtklibexplorer_drive_0708"
    if not d.is_dir():
        pytest.skip("drive data set not found")
    cfg = load_config(EXAMPLES / "rtklibexplorer_drive_0708.yaml")
    imu = formats.read_imu(d / "imu_1934.csv")
    full = convert(d / "gnss_1934_sf.pos", tmp_path / "full.csv", height_offset_m=cfg.gnss.height_offset_m)
    df = pd.read_csv(full["output"], comment="#")
    df.drop(columns=["vu", "std_vu"]).to_csv(tmp_path / "no_vu.csv", index=False, float_format="%.17g")
    df.loc[::2, "vu"] = np.nan
    df.to_csv(tmp_path / "some_vu.csv", index=False, float_format="%.17g")
    scores = {}
    for name in ("full", "no_vu", "some_vu"):
        g = formats.read_gnss(tmp_path / f"{name}.csv")
        if name == "no_vu":
            assert np.isnan(g.vel[:, 2]).all() and np.isfinite(g.vel[:, :2]).all()
        wins = outage_windows([parse_outage("40:15:45")], g.time[0], g.time[-1])
        withheld = np.zeros(len(g), bool)
        for a, b in wins:
            withheld |= (g.time >= a) & (g.time < b)
        r = run_loose(imu, g, cfg, withheld=withheld)
        scores[name] = score_outages(to_trajectory(r), g, wins, withheld)["rms_m"]
    for name in ("no_vu", "some_vu"):
        assert scores[name] <= 1.10 * scores["full"], scores
