"""Tests of aidnav.analysis.errors: known offsets, interpolation, exclusions, heading wrap."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.analysis.errors import error_statistics, fraction_within_sigma, trajectory_errors
from aidnav.data import Trajectory
from aidnav.nav.earth import radii

LAT0, LON0, H0 = np.radians(30.0), np.radians(114.0), 100.0


def linear_traj(t, heading0_deg=10.0, heading_rate_deg=0.5, roll_deg=5.0, pitch_deg=-3.0, std=None):
    """Trajectory whose lat/lon/height, velocity and heading are linear in time (so linear
    interpolation and slerp reproduce them exactly at any time in between)."""
    t = np.asarray(t, dtype=float)
    n = len(t)
    lat = LAT0 + 1e-6 * t
    lon = LON0 + 2e-6 * t
    h = H0 + 0.3 * t
    vel = np.column_stack([1.0 + 0.1 * t, 2.0 - 0.05 * t, 0.3 * np.ones(n)])
    heading = np.radians(heading0_deg + heading_rate_deg * t) % (2 * np.pi)
    rph = np.column_stack([np.full(n, np.radians(roll_deg)), np.full(n, np.radians(pitch_deg)), heading])
    kw = {}
    if std is not None:
        kw = {"std_pos": np.tile(std[0], (n, 1)), "std_vel": np.tile(std[1], (n, 1)),
              "std_att": np.tile(std[2], (n, 1))}
    return Trajectory(time=t, lat=lat, lon=lon, height=h, vel=vel, rph=rph, **kw)


def shifted(tr: Trajectory, dn_m=0.0, dheading_rad=0.0, dh_m=0.0) -> Trajectory:
    rm, _ = radii(tr.lat)
    rph = tr.rph.copy()
    rph[:, 2] = (rph[:, 2] + dheading_rad) % (2 * np.pi)
    return Trajectory(tr.time.copy(), tr.lat + dn_m / (rm + tr.height), tr.lon.copy(), tr.height + dh_m,
                      tr.vel.copy(), rph, tr.std_pos, tr.std_vel, tr.std_att)


def test_known_offsets_exact():
    ref = linear_traj(np.arange(0.0, 60.0, 0.1))
    est = shifted(ref, dn_m=1.0, dheading_rad=np.radians(0.1))
    e = trajectory_errors(est, ref)
    assert e.n_used == len(ref) and e.n_excluded == 0
    np.testing.assert_allclose(e.pos[:, 1], 1.0, atol=1e-8)
    np.testing.assert_allclose(e.pos[:, [0, 2]], 0.0, atol=1e-8)
    np.testing.assert_allclose(e.horizontal, 1.0, atol=1e-8)
    np.testing.assert_allclose(e.vel, 0.0, atol=1e-12)
    np.testing.assert_allclose(e.att[:, 2], np.radians(0.1), atol=1e-12)
    np.testing.assert_allclose(e.att[:, :2], 0.0, atol=1e-12)

    s = error_statistics(e)
    assert s.loc["pos N", "RMS"] == pytest.approx(1.0, abs=1e-8)
    assert s.loc["pos N", "mean"] == pytest.approx(1.0, abs=1e-8)
    assert s.loc["pos N", "std"] == pytest.approx(0.0, abs=1e-8)
    assert s.loc["pos horizontal", "max"] == pytest.approx(1.0, abs=1e-8)
    assert s.loc["heading", "RMS"] == pytest.approx(0.1, abs=1e-9)
    assert s.loc["heading", "unit"] == "deg"
    assert s.loc["heading", "p95"] == pytest.approx(0.1, abs=1e-9)
    assert s.loc["pos E", "n"] == len(ref)
    assert list(s.columns) == ["RMS", "mean", "std", "p95", "max", "n", "unit"]
    assert list(s.index) == ["pos E", "pos N", "pos U", "pos horizontal", "pos 3D", "vel E", "vel N",
                             "vel U", "roll", "pitch", "heading"]


def test_up_offset_and_3d():
    ref = linear_traj(np.arange(0.0, 10.0, 1.0))
    est = shifted(ref, dn_m=3.0, dh_m=-4.0)
    e = trajectory_errors(est, ref)
    np.testing.assert_allclose(e.pos[:, 2], -4.0, atol=1e-9)
    np.testing.assert_allclose(e.pos3d, 5.0, atol=1e-8)
    s = error_statistics(e)
    assert s.loc["pos U", "mean"] == pytest.approx(-4.0)
    assert s.loc["pos U", "max"] == pytest.approx(4.0)  # max of |e|


def test_interpolation_off_grid_exact_for_linear_motion():
    # heading passes through north (358° → 13° over 30 s) to exercise slerp across the wrap
    est = linear_traj(np.arange(0.0, 30.0, 1.0), heading0_deg=358.0, heading_rate_deg=0.5)
    t_ref = np.array([0.25, 1.5, 3.7, 3.999, 4.0, 17.123, 28.9])
    ref = linear_traj(t_ref, heading0_deg=358.0, heading_rate_deg=0.5)
    e = trajectory_errors(est, ref)
    assert e.n_used == len(t_ref) and e.n_excluded == 0
    np.testing.assert_allclose(e.time, t_ref)
    np.testing.assert_allclose(e.pos, 0.0, atol=1e-6)
    np.testing.assert_allclose(e.vel, 0.0, atol=1e-12)
    np.testing.assert_allclose(e.att, 0.0, atol=1e-10)


def test_interpolated_offset_and_sigma():
    # estimate = reference + 1 m north at 10 Hz; reference at off-grid times
    grid = np.arange(0.0, 20.0, 0.1)
    est = shifted(linear_traj(grid, std=([1.0, 2.0, 3.0], [0.1, 0.2, 0.3], [0.01, 0.02, 0.03])), dn_m=1.0)
    est.std_pos = est.std_pos * (1.0 + grid[:, None])  # σ growing linearly with time
    ref = linear_traj(np.arange(0.05, 19.9, 0.37))
    e = trajectory_errors(est, ref)
    np.testing.assert_allclose(e.pos[:, 1], 1.0, atol=1e-6)
    np.testing.assert_allclose(e.std_pos[:, 0], 1.0 + e.time, rtol=1e-12)
    np.testing.assert_allclose(e.std_vel, np.tile([0.1, 0.2, 0.3], (len(e), 1)))
    f = fraction_within_sigma(e, k=1)
    assert f.loc["pos N", "fraction"] == 1.0  # |1 m| <= σN = 2(1+t)
    assert f.loc["pos N", "expected"] == pytest.approx(0.6827, abs=1e-4)
    assert f.loc["pos E", "fraction"] == 1.0  # error 0
    est.std_pos = np.full_like(est.std_pos, 0.5)
    f2 = fraction_within_sigma(trajectory_errors(est, ref), k=1)
    assert f2.loc["pos N", "fraction"] == 0.0
    assert f2.loc["pos N", "n"] == len(e)


def test_outside_span_excluded_and_counted():
    est = linear_traj(np.arange(0.0, 10.01, 0.5))
    t_ref = np.arange(-3.0, 14.0, 1.0)  # -3..13: 3 before, 3 after the span [0, 10]
    e = trajectory_errors(est, linear_traj(t_ref))
    assert e.n_reference == len(t_ref)
    assert e.n_outside == 6
    assert e.n_used == len(t_ref) - 6
    assert e.time[0] == 0.0 and e.time[-1] == 10.0  # span ends are inside
    assert e.used.sum() == e.n_used and len(e.used) == len(t_ref)
    assert any("outside" in n for n in e.notes)
    assert e.counts()["outside_span"] == 6


def test_gaps_excluded_and_counted():
    t_est = np.concatenate([np.arange(0.0, 10.0, 0.1), np.arange(20.0, 30.0, 0.1)])  # gap 9.9 .. 20
    est = linear_traj(t_est)
    t_ref = np.arange(0.0, 30.0, 1.0)
    e = trajectory_errors(est, linear_traj(t_ref))  # auto max_dt = 5 × 0.1 s
    assert e.max_dt == pytest.approx(0.5)
    assert e.n_gap == 10  # 10, 11, ..., 19 s
    assert e.n_outside == 0
    assert e.n_used == 20
    assert not np.any((e.time > 9.95) & (e.time < 19.95))
    e2 = trajectory_errors(est, linear_traj(t_ref), max_dt=np.inf)
    assert e2.n_gap == 0 and e2.n_used == 30


def test_invalid_reference_counted():
    ref = linear_traj(np.arange(0.0, 10.0, 1.0))
    ref.lat[3] = np.nan
    e = trajectory_errors(ref, ref)
    assert e.n_invalid == 1 and e.n_used == 9


@pytest.mark.parametrize("h_est, h_ref, expected",
                         [(0.1, 359.9, 0.2), (359.9, 0.1, -0.2), (180.0, 179.0, 1.0)])
def test_heading_wrap(h_est, h_ref, expected):
    ref = linear_traj(np.arange(0.0, 5.0, 1.0), heading0_deg=h_ref, heading_rate_deg=0.0)
    est = linear_traj(np.arange(0.0, 5.0, 1.0), heading0_deg=h_est, heading_rate_deg=0.0)
    e = trajectory_errors(est, ref)
    np.testing.assert_allclose(np.degrees(e.att[:, 2]), expected, atol=1e-9)
    assert error_statistics(e).loc["heading", "max"] == pytest.approx(abs(expected), abs=1e-9)


def test_heading_wrap_interpolated():
    est = linear_traj(np.arange(0.0, 5.0, 1.0), heading0_deg=0.1, heading_rate_deg=0.0)
    ref = linear_traj(np.array([0.5, 2.25]), heading0_deg=359.9, heading_rate_deg=0.0)
    e = trajectory_errors(est, ref)
    np.testing.assert_allclose(np.degrees(e.att[:, 2]), 0.2, atol=1e-9)


def test_reference_without_attitude_or_velocity():
    est = linear_traj(np.arange(0.0, 10.0, 1.0))
    ref = linear_traj(np.arange(0.0, 10.0, 1.0))
    ref.rph[:] = np.nan
    ref.vel[:] = np.nan
    e = trajectory_errors(est, ref)
    assert e.att is None and e.vel is None
    s = error_statistics(e)
    assert "heading" not in s.index and "vel E" not in s.index
    assert list(s.index) == ["pos E", "pos N", "pos U", "pos horizontal", "pos 3D"]
    df = e.to_dataframe()
    assert "dheading_deg" not in df.columns and "de_m" in df.columns


def test_statistics_window_and_values():
    ref = linear_traj(np.arange(0.0, 10.0, 1.0))
    est = shifted(ref)
    est.height = est.height + np.array([10.0] * 5 + [1.0, -1.0, 1.0, -1.0, 1.0])  # dU; t = 5..9 → ±1
    e = trajectory_errors(est, ref)
    s = error_statistics(e, window=(5.0, None))
    assert s.loc["pos U", "n"] == 5
    assert s.loc["pos U", "RMS"] == pytest.approx(1.0)
    assert s.loc["pos U", "mean"] == pytest.approx(0.2)
    assert s.loc["pos U", "std"] == pytest.approx(np.sqrt(1.0 - 0.04))
    assert s.loc["pos U", "max"] == pytest.approx(1.0)
    assert error_statistics(e).loc["pos U", "max"] == pytest.approx(10.0)


def test_not_increasing_time_rejected():
    est = linear_traj(np.array([0.0, 1.0, 1.0, 2.0]))
    with pytest.raises(ValueError, match="strictly increasing"):
        trajectory_errors(est, linear_traj(np.arange(3.0)))


def test_dataframe_columns_and_units():
    ref = linear_traj(np.arange(0.0, 3.0, 1.0))
    est = shifted(linear_traj(np.arange(0.0, 3.0, 1.0), std=([1, 1, 1], [1, 1, 1], [0.01, 0.01, 0.01])),
                  dheading_rad=np.radians(1.0))
    df = trajectory_errors(est, ref).to_dataframe()
    for c in ("time", "de_m", "dn_m", "du_m", "horizontal_m", "pos3d_m", "dve_m_s", "droll_deg",
              "dheading_deg", "std_de_m", "std_dheading_deg"):
        assert c in df.columns
    np.testing.assert_allclose(df["dheading_deg"], 1.0, atol=1e-9)
    np.testing.assert_allclose(df["std_dheading_deg"], np.degrees(0.01))
