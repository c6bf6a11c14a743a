"""Heights on real data: the datum (height) offset is applied exactly once.

The drive and walk `.pos` files hold heights above mean sea level; the configs state the geoid
undulation (−21.4 m) as ``gnss.height_offset_m``. The output is ellipsoidal, so at aided epochs
estimate − (file height + offset) must be small (the RTK solution is cm-level vertically; the INS
interpolates between 4 Hz fixes). Before the fix the offset was added twice (42.8 m, exit 0).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from aidnav.apps.process import load_config, process_logs
from aidnav.io.interchange import read_trajectory
from aidnav.io.rtklib import read_pos

REPO = Path(__file__).resolve().parents[2]

CASES = [
    ("rtklibexplorer_drive_0708", "imu_1934.csv", "gnss_1934_sf.pos", "rtklibexplorer_drive_0708.yaml"),
    ("rtklibexplorer_walk_0827", "imu_1730.csv", "gnss_1730_sf.pos", "rtklibexplorer_walk_0827.yaml"),
]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_heights_at_aided_epochs(data_dir, tmp_path, case):
    name, imu, pos, cfg_name = case
    d = data_dir / name
    if not d.is_dir():
        pytest.skip(f"{d} not found")
    cfg_path = REPO / "examples" / cfg_name
    offset = load_config(cfg_path).gnss.height_offset_m
    assert offset != 0.0, "the example must state the datum offset for this test to mean anything"
    s = process_logs(d / imu, d / pos, cfg_path, tmp_path)
    traj = read_trajectory(tmp_path / "trajectory.parquet")
    raw = read_pos(d / pos)  # heights as in the file (no offset)
    acc = np.asarray(s["accepted_fix_times"]) if "accepted_fix_times" in s else raw.time
    t = acc[(acc >= traj.time[0]) & (acc <= traj.time[-1])]
    idx = np.searchsorted(raw.time, t)
    h_ref = raw.height[idx] + offset
    h_est = np.interp(t, traj.time, traj.height)
    rms = float(np.sqrt(np.mean((h_est - h_ref) ** 2)))
    assert len(t) > 100
    assert rms < 0.3, f"{name}: height RMS at aided epochs {rms:.3f} m (offset {offset} m)"
