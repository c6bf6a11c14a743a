"""``evaluate`` figures through the file path: an unaligned start (heading σ ±540°) does not flatten the
attitude-error axis."""

from __future__ import annotations

import numpy as np

from aidnav.data import Trajectory
from aidnav.io.interchange import write_trajectory


def test_evaluate_attitude_axis_robust(tmp_path, monkeypatch):
    from aidnav.apps.evaluate import evaluate_files
    from aidnav.report import error_plots

    n = 1500
    t = 345600.0 + 0.2 * np.arange(n)
    lat = np.radians(30.0) + 1e-8 * np.arange(n)
    lon = np.full(n, np.radians(114.0))
    h = np.full(n, 10.0)
    vel = np.tile([0.0, 1.0, 0.0], (n, 1))
    rph = np.tile(np.radians([1.0, 2.0, 90.0]), (n, 1))
    ref = Trajectory(t, lat, lon, h, vel, rph)
    err = np.radians(0.1) * np.sin(np.arange(n) / 7.0)
    s_h = np.radians(0.05 + 540.0 * np.exp(-(t - t[0]) / 30.0))
    est = Trajectory(t, lat, lon, h, vel, rph + np.column_stack([0 * err, 0 * err, err]),
                     std_pos=np.ones((n, 3)), std_vel=np.full((n, 3), 0.1),
                     std_att=np.column_stack([np.full(n, 1e-3), np.full(n, 1e-3), s_h]))
    write_trajectory(est, tmp_path / "est.csv")
    write_trajectory(ref, tmp_path / "ref.csv")
    limits = {}
    save = error_plots._save

    def spy(fig, path):
        limits[path.name] = [ax.get_ylim() for ax in fig.axes]
        return save(fig, path)

    monkeypatch.setattr(error_plots, "_save", spy)
    _, written = evaluate_files(tmp_path / "est.csv", tmp_path / "ref.csv", tmp_path / "ev")
    assert "attitude_errors.png" in {p.name for p in written}
    lo, hi = limits["attitude_errors.png"][2]
    assert hi - lo < 5.0  # deg
    assert hi > 0.1  # the 0.1 deg errors are inside the view
