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


def test_all_figures_written(tmp_path, drawn_png):
    e = trajectory_errors(*_pair())
    paths = plot_errors(e, tmp_path / "figs")
    names = sorted(p.name for p in paths)
    assert names == ["attitude_errors.png", "horizontal_error.png", "position_errors.png",
                     "velocity_errors.png"]
    for p in paths:
        drawn_png(p)


def test_no_attitude_figure_without_reference_attitude(tmp_path):
    e = trajectory_errors(*_pair(with_attitude=False))
    assert plot_attitude_errors(e, tmp_path / "att.png") is None
    assert not (tmp_path / "att.png").exists()
    paths = plot_errors(e, tmp_path, prefix="rtk_")
    assert sorted(p.name for p in paths) == ["rtk_horizontal_error.png", "rtk_position_errors.png",
                                             "rtk_velocity_errors.png"]
    e.vel = None
    assert plot_velocity_errors(e, tmp_path / "vel.png") is None


def test_nees_figure(tmp_path, drawn_png):
    rng = np.random.default_rng(1)
    t = 1000.0 + np.arange(200.0)
    p1 = plot_nees(t, rng.chisquare(3, size=200), 3, tmp_path / "nees1.png")
    p2 = plot_nees(t, rng.chisquare(3, size=(20, 200)), 3, tmp_path / "nees20.png", label="NIS")
    p3 = plot_nees(t, 1000 * rng.chisquare(3, size=200), 3, tmp_path / "nees_bad.png")  # log axis
    for p in (p1, p2, p3):
        drawn_png(p)


def test_time_axis_label_states_start():
    t, label = time_axis(np.array([345600.5, 345601.5]))
    np.testing.assert_allclose(t, [0.0, 1.0])
    assert "345600.500" in label and "GPS SOW" in label


# ------------------------------------------------------------------------------ robust y-limits
def _unaligned_heading(n=2000, err_deg=0.1, sigma0_deg=540.0, sigma_end_deg=0.05):
    """Heading error of ``err_deg`` (sign alternating noise-free pattern) while the filter's heading σ
    starts at ``sigma0_deg`` and decays exponentially (time constant 20 s) to ``sigma_end_deg``."""
    t = 345600.0 + 0.1 * np.arange(n)
    lat = np.full(n, np.radians(30.0))
    lon = np.full(n, np.radians(114.0))
    h = np.full(n, 10.0)
    vel = np.zeros((n, 3))
    rph = np.tile(np.radians([1.0, 2.0, 90.0]), (n, 1))
    ref = Trajectory(t, lat, lon, h, vel, rph)
    e = np.radians(err_deg) * np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    est_rph = rph + np.column_stack([0.5 * e, 0.5 * e, e])
    s_h = np.radians(sigma_end_deg + (sigma0_deg - sigma_end_deg) * np.exp(-(t - t[0]) / 20.0))
    std_att = np.column_stack([np.full(n, np.radians(0.05)), np.full(n, np.radians(0.05)), s_h])
    est = Trajectory(t, lat, lon, h, vel, est_rph, std_pos=np.ones((n, 3)), std_vel=np.ones((n, 3)),
                     std_att=std_att)
    return trajectory_errors(est, ref)


def test_attitude_axis_follows_errors_not_initial_sigma():
    from aidnav.report.error_plots import attitude_error_figure

    fig = attitude_error_figure(_unaligned_heading())
    lo, hi = fig.axes[2].get_ylim()
    assert hi - lo < 5.0  # deg: before, ±3σ0 = ±1620 deg
    assert hi >= 0.1 * 1.25 * 0.999 and lo <= -0.1 * 1.25 * 0.999  # the errors stay inside the view
    # the ±3σ envelope is clipped to the view: no vertex of the shaded area far outside
    (env,) = [c for c in fig.axes[2].collections]
    y = np.concatenate([p.vertices[:, 1] for p in env.get_paths()])
    assert np.nanmax(np.abs(y)) <= 1.05 * hi + 1e-12


def test_robust_limit_rules():
    from aidnav.report.error_plots import robust_limit

    rng = np.random.default_rng(3)
    e = 0.1 * rng.standard_normal(1000)
    p99 = np.percentile(np.abs(e), 99)
    assert robust_limit(e) == 1.25 * p99
    # a typical envelope comparable to the errors is shown entirely
    assert robust_limit(e, np.full(1000, 0.4)) == 0.4
    # a huge envelope is capped at 5x the error scale
    assert robust_limit(e, np.full(1000, 1e4)) == 5 * 1.25 * p99
    # a few outliers do not set the scale
    e2 = e.copy()
    e2[:5] = 1e3
    assert robust_limit(e2) < 1.0
    # degenerate inputs
    assert robust_limit(np.zeros(10), np.full(10, 2.0)) == 2.0
    assert robust_limit(np.full(10, np.nan)) == 1.0


def test_horizontal_axis_robust():
    from aidnav.report.error_plots import horizontal_error_figure

    est, ref = _pair()
    n = len(est.time)
    est.std_pos = np.tile([0.5, 0.5, 1.0], (n, 1))
    est.std_pos[:10] = 1e4  # unaligned start
    e = trajectory_errors(est, ref)
    fig = horizontal_error_figure(e)
    lo, hi = fig.axes[0].get_ylim()
    assert lo == 0.0 and hi < 50.0
    assert hi >= 1.25 * np.percentile(np.concatenate([e.horizontal, e.pos3d]), 99) * 0.999
