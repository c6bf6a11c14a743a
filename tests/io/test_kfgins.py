"""KF-GINS text files, built by hand from the format's README (i2Nav-WHU/KF-GINS, "Data format")."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.data import Trajectory
from aidnav.io import formats, kfgins
from aidnav.io.errors import DataError
from aidnav.io.interchange import read_trajectory, write_trajectory

G = 9.80665


def test_imu_frd_to_rfu_units_and_time(tmp_path):
    """A level, static, north-facing FRD IMU: specific force points up, i.e. −z_FRD; in body RFU it is
    +z. Angle increments are permuted x↔y and z negated."""
    dt = 0.005
    lines = [f"{456300.0 + k * dt:.3f} 1e-5 2e-5 3e-5 0.0001 -0.0002 {-G * dt!r}" for k in range(4)]
    p = tmp_path / "imu.txt"
    p.write_text("\n".join(lines) + "\n")
    assert formats.detect_imu_format(p) == "kfgins"
    imu = formats.read_imu(p)
    np.testing.assert_allclose(imu.time, 456300.0 + dt * np.arange(4), rtol=0, atol=1e-9)
    np.testing.assert_allclose(imu.dtheta[0], [2e-5, 1e-5, -3e-5], rtol=0, atol=0)
    np.testing.assert_allclose(imu.dv[0], [-0.0002, 0.0001, G * dt], rtol=0, atol=1e-15)
    assert imu.t0 == pytest.approx(456300.0 - dt)
    assert any("kfgins" in e for e in imu.events)


def test_imu_comma_and_tab_separated_and_odometer_column(tmp_path):
    p = tmp_path / "imu.txt"
    p.write_text("1.0,\t1e-5, 0, 0, 0, 0, -0.049, 3.5\n1.005\t1e-5 0 0 0 0 -0.049 3.5\n")
    imu = kfgins.read_imu(p)
    assert imu.dtheta[1, 1] == 1e-5 and imu.dv[1, 2] == 0.049
    assert any("odometer" in e and "not used" in e for e in imu.events)


def test_imu_errors_name_the_line(tmp_path):
    p = tmp_path / "imu.txt"
    p.write_text("1.0 0 0 0 0 0 0\n1.005 0 0 0 0 0\n")
    with pytest.raises(DataError) as ei:
        kfgins.read_imu(p)
    assert ei.value.line == 2 and "6 fields" in ei.value.problem
    p.write_text("1.0 0 0 0 0 0 0\n1.0 0 0 0 0 0 0\n")
    with pytest.raises(DataError) as ei:
        kfgins.read_imu(p)
    assert ei.value.line == 2 and "duplicate" in ei.value.problem
    p.write_text("1.0 0 0 0 0 0 0\n1.005 0 x 0 0 0 0\n")
    with pytest.raises(DataError) as ei:
        kfgins.read_imu(p)
    assert ei.value.line == 2 and "'x'" in ei.value.problem


def test_gnss_columns_and_sigma_order(tmp_path):
    p = tmp_path / "gnss.txt"
    p.write_text("456300.0 30.4447873 114.4718024 20.910 0.005 0.004 0.008\n"
                 "456301.0 30.4447874 114.4718025 20.911 0.006 0.003 0.009\n")
    g = formats.read_gnss(p)
    np.testing.assert_allclose(g.time, [456300.0, 456301.0])
    np.testing.assert_allclose(np.degrees(g.lat), [30.4447873, 30.4447874], rtol=0, atol=1e-12)
    np.testing.assert_allclose(g.height, [20.910, 20.911])
    np.testing.assert_array_equal(g.std_pos, [[0.004, 0.005, 0.008], [0.003, 0.006, 0.009]])  # σE σN σU
    assert g.vel is None


def test_gnss_zero_sigma_floored_and_bad_latitude(tmp_path):
    p = tmp_path / "gnss.txt"
    p.write_text("1.0 30 114 20 0 0.004 0.008\n")
    g = kfgins.read_gnss(p)
    assert g.std_pos[0, 1] == 0.05 and any(e.startswith("warning") for e in g.events)
    p.write_text("1.0 114 30 20 0.005 0.004 0.008\n")
    with pytest.raises(DataError, match="latitude 114"):
        kfgins.read_gnss(p)


def test_nav_read_by_hand(tmp_path):
    p = tmp_path / "traj.nav"
    # week sow lat lon h vN vE vD roll pitch yaw ; yaw −90 = heading 270
    p.write_text("2238 386743.4 30.5 114.25 20.0 1.0 2.0 3.0 1.5 -2.5 -90.0\n"
                 "2238 386743.6 30.5 114.25 20.0 1.0 2.0 3.0 1.5 -2.5 45.0\n")
    assert formats.detect_trajectory_format(p) == "kfgins-nav"
    t = formats.read_trajectory_any(p)
    np.testing.assert_allclose(t.vel[0], [2.0, 1.0, -3.0])
    np.testing.assert_allclose(np.degrees(t.rph[:, 2]), [270.0, 45.0])
    np.testing.assert_allclose(np.degrees(t.rph[0, :2]), [1.5, -2.5])
    assert t.week == 2238 and t.time[0] == 386743.4


def _traj(n=5):
    rng = np.random.default_rng(1)
    return Trajectory(time=100.0 + 0.1 * np.arange(n), lat=np.radians(30.5 + 1e-6 * rng.standard_normal(n)),
                      lon=np.radians(114.25 + 1e-6 * rng.standard_normal(n)),
                      height=20 + rng.standard_normal(n),
                      vel=rng.standard_normal((n, 3)), rph=np.column_stack([0.01 * rng.standard_normal(n),
                                                                            0.02 * rng.standard_normal(n),
                                                                            rng.uniform(0, 2 * np.pi, n)]),
                      std_pos=np.abs(rng.standard_normal((n, 3))))


def test_nav_writer_columns_parsed_independently(tmp_path):
    t = _traj()
    p = kfgins.write_nav(t, tmp_path / "out.nav", week=2238)
    a = np.loadtxt(p)
    assert a.shape == (5, 11)
    np.testing.assert_array_equal(a[:, 0], 2238)
    np.testing.assert_array_equal(a[:, 1], t.time)
    np.testing.assert_array_equal(a[:, 2], np.degrees(t.lat))
    np.testing.assert_array_equal(a[:, 5:8], np.column_stack([t.vel[:, 1], t.vel[:, 0], -t.vel[:, 2]]))
    np.testing.assert_allclose(a[:, 10], np.mod(np.degrees(t.rph[:, 2]), 360.0), rtol=0, atol=1e-12)
    # write_trajectory with a .nav path writes the same file; reading back gives the same trajectory
    p2 = write_trajectory(t, tmp_path / "out2.nav", week=2238)
    assert p2.read_text() == p.read_text()
    back = kfgins.read_nav(p)
    for k in ("time", "height", "vel"):
        np.testing.assert_array_equal(getattr(back, k), getattr(t, k))
    for k in ("lat", "lon"):  # degrees ↔ radians: 1 ulp
        np.testing.assert_allclose(getattr(back, k), getattr(t, k), rtol=1e-15, atol=0)
    np.testing.assert_allclose(back.rph, t.rph, rtol=0, atol=1e-14)


def test_imu_and_gnss_writers_round_trip(tmp_path):
    p = tmp_path / "imu.txt"
    p.write_text("1.0 1e-5 2e-5 3e-5 4e-4 5e-4 -0.049\n1.005 -1e-5 2e-5 3e-5 4e-4 5e-4 -0.049\n")
    imu = kfgins.read_imu(p)
    q = kfgins.write_imu(imu, tmp_path / "imu2.txt")
    np.testing.assert_array_equal(np.loadtxt(q), np.loadtxt(p))
    g = tmp_path / "g.txt"
    g.write_text("1.0 30.1 114.2 20.5 0.01 0.02 0.03\n")
    q = kfgins.write_gnss(kfgins.read_gnss(g), tmp_path / "g2.txt")
    np.testing.assert_allclose(np.loadtxt(q), np.loadtxt(g), rtol=1e-15, atol=0)


def test_trajectory_metres_week_and_utc_columns(tmp_path):
    """Issue 28 item 4: σ in metres beside the old degree columns, GPS week + UTC ISO time."""
    import pandas as pd

    t = _traj()
    t.time = 386743.4 + 0.1 * np.arange(5)
    p = write_trajectory(t, tmp_path / "t.csv", week=2238)
    df = pd.read_csv(p, comment="#")
    np.testing.assert_array_equal(df[["std_e_m", "std_n_m", "std_u_m"]].to_numpy(), t.std_pos)
    # one σ naming scheme (issue 38): the degree σ columns are no longer written
    assert not {"lat_deg_std", "lon_deg_std", "height_m_std"} & set(df.columns)
    assert (df["gps_week"] == 2238).all()
    assert df["utc"][0] == "2022-12-01T11:25:25.400000Z"  # 18 leap seconds: 11:25:43.4 GPST
    for ext in ("csv", "parquet"):
        q = write_trajectory(t, tmp_path / f"w.{ext}", week=2238)
        back = read_trajectory(q)
        assert back.week == 2238 and "utc" not in back.extra and "gps_week" not in back.extra
        np.testing.assert_array_equal(back.std_pos, t.std_pos)  # exact: the metre columns are read
    df2 = t.to_dataframe(week=2238)
    assert df2["utc"][0] == df["utc"][0] and list(df2.columns) == list(df.columns)


def test_nav_across_the_week_end(tmp_path):
    t = _traj(3)
    t.time = np.array([604799.5, 604800.0, 604800.5])
    p = kfgins.write_nav(t, tmp_path / "w.nav", week=2238)
    a = np.loadtxt(p)
    np.testing.assert_array_equal(a[:, 0], [2238, 2239, 2239])
    np.testing.assert_array_equal(a[:, 1], [604799.5, 0.0, 0.5])
    np.testing.assert_array_equal(kfgins.read_nav(p).time, t.time)
