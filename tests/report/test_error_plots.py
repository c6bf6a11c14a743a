"""Tests of aidnav.report.error_plots: the figures are written as PNG files."""

from __future__ import annotations

import numpy as np

from aidnav.analysis.errors import trajectory_errors
from aidnav.data import Trajectory
from aidnav.report.error_plots import (
    plot_attitude_errors,
    plot_errors,
    plot_nees,
    plot_velocity_errors,
    time_axis,
)

PNG = b"\x89PNG\r\n\x1a\n"


def _pair(with_attitude=True, t0=345600.0):
    rng = np.random.default_rng(0)
    t = t0 + np.arange(0.0, 50.0, 0.5)
    n = len(t)
    lat = np.radians(30.0) + 1e-7 * (t - t0)
    lon = np.radians(114.0) + np.zeros(n)
    h = np.full(n, 50.0)
    vel = np.tile([1.0, 0.0, 0.0], (n, 1))
    rph = np.tile(np.radians([1.0, 2.0, 359.0]), (n, 1))
    ref = Trajectory(t, lat, lon, h, vel, rph if with_attitude else np.full((n, 3), np.nan))
    est = Trajectory(t, lat + 1e-7 * rng.normal(size=n), lon + 1e-7 * rng.normal(size=n),
                     h + rng.normal(size=n), vel + 0.05 * rng.normal(size=(n, 3)),
                     rph + np.radians(0.05) * rng.normal(size=(n, 3)),
                     std_pos=np.tile([0.5, 0.5, 1.0], (n, 1)), std_vel=np.full((n, 3), 0.05),
                     std_att=np.full((n, 3), np.radians(0.05)))
    return est, ref


def _is_png(p):
    return p.exists() and p.stat().st_size > 1000 and p.read_bytes()[:8] == PNG


def test_all_figures_written(tmp_path):
    e = trajectory_errors(*_pair())
    paths = plot_errors(e, tmp_path / "figs")
    names = sorted(p.name for p in paths)
    assert names == ["attitude_errors.png", "horizontal_error.png", "position_errors.png",
                     "velocity_errors.png"]
    assert all(_is_png(p) for p in paths)


def test_no_attitude_figure_without_reference_attitude(tmp_path):
    e = trajectory_errors(*_pair(with_attitude=False))
    assert plot_attitude_errors(e, tmp_path / "att.png") is None
    assert not (tmp_path / "att.png").exists()
    paths = plot_errors(e, tmp_path, prefix="rtk_")
    assert sorted(p.name for p in paths) == ["rtk_horizontal_error.png", "rtk_position_errors.png",
                                             "rtk_velocity_errors.png"]
    e.vel = None
    assert plot_velocity_errors(e, tmp_path / "vel.png") is None


def test_nees_figure(tmp_path):
    rng = np.random.default_rng(1)
    t = 1000.0 + np.arange(200.0)
    p1 = plot_nees(t, rng.chisquare(3, size=200), 3, tmp_path / "nees1.png")
    p2 = plot_nees(t, rng.chisquare(3, size=(20, 200)), 3, tmp_path / "nees20.png", label="NIS")
    p3 = plot_nees(t, 1000 * rng.chisquare(3, size=200), 3, tmp_path / "nees_bad.png")  # log axis
    assert all(_is_png(p) for p in (p1, p2, p3))


def test_time_axis_label_states_start():
    t, label = time_axis(np.array([345600.5, 345601.5]))
    np.testing.assert_allclose(t, [0.0, 1.0])
    assert "345600.500" in label and "GPS SOW" in label
