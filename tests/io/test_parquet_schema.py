"""Parquet files that pandas/pyarrow/duckdb users read as meant (issue 38): every field carries its unit
and frame in the schema, ``utc`` is a UTC timestamp column, σ columns follow one scheme (``std_*``) and
files with the old names (``ve_std``, ``roll_deg_std``) are still read."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pyarrow.parquet as pq

from aidnav.data import Trajectory
from aidnav.io.interchange import read_trajectory, write_trajectory
from aidnav.io.stream import TrajectoryWriter

WEEK = 2238


def _traj(n=5):
    t = 386743.4 + 0.1 * np.arange(n)
    return Trajectory(t, np.radians(np.full(n, 40.0)), np.radians(np.full(n, 116.0)), np.full(n, 50.0),
                      np.tile([1.0, 2.0, 0.1], (n, 1)), np.tile([0.01, 0.02, 1.0], (n, 1)),
                      std_pos=np.tile([0.1, 0.2, 0.3], (n, 1)), std_vel=np.tile([0.01, 0.02, 0.03], (n, 1)),
                      std_att=np.tile([1e-3, 2e-3, 3e-3], (n, 1)), extra={"gyro_bias_x_deg_h": np.ones(n)})


def _check_schema(path):
    sch = pq.read_schema(path)
    units = {f.name: (f.metadata or {}).get(b"unit", b"").decode() for f in sch}
    frames = {f.name: (f.metadata or {}).get(b"frame", b"").decode() for f in sch}
    assert units["time"] == "s" and units["lat_deg"] == "deg" and units["height_m"] == "m"
    assert units["ve"] == "m/s" and frames["ve"] == "ENU east" and "ellipsoidal" in frames["height_m"]
    assert units["std_e_m"] == "m" and units["std_ve"] == "m/s" and units["std_heading_deg"] == "deg"
    assert units["gyro_bias_x_deg_h"] == "deg/h" and frames["gyro_bias_x_deg_h"] == "body RFU"
    assert all(units[n] for n in sch.names), [n for n in sch.names if not units[n]]
    f = sch.field("utc")
    assert str(f.type) == "timestamp[us, tz=UTC]"
    assert not {"ve_std", "roll_deg_std", "lat_deg_std"} & set(sch.names)
    tbl = pq.read_table(path)
    first = tbl.column("utc")[0].as_py()
    # 2022-12-01 11:25:43.4 GPST − 18 s
    assert first == dt.datetime(2022, 12, 1, 11, 25, 25, 400000, tzinfo=dt.UTC)


def test_parquet_fields_carry_units_and_utc_is_a_timestamp(tmp_path):
    tr = _traj()
    p = write_trajectory(tr, tmp_path / "t.parquet", week=WEEK)
    _check_schema(p)
    back = read_trajectory(p)
    assert back.week == WEEK and "utc" not in back.extra
    np.testing.assert_allclose(back.std_vel, tr.std_vel)
    np.testing.assert_allclose(back.std_att, tr.std_att, rtol=1e-12)
    # the streamed writer writes the same schema
    w = TrajectoryWriter(tmp_path / "s.parquet", week=WEEK)
    w.write(tr)
    _check_schema(w.close())


def test_old_sigma_names_are_still_read(tmp_path):
    tr = _traj()
    p = write_trajectory(tr, tmp_path / "t.csv", week=WEEK)
    text = p.read_text()
    for new, old in (("std_ve", "ve_std"), ("std_vn", "vn_std"), ("std_vu", "vu_std"),
                     ("std_roll_deg", "roll_deg_std"), ("std_pitch_deg", "pitch_deg_std"),
                     ("std_heading_deg", "heading_deg_std")):
        text = text.replace(new, old)
    (tmp_path / "old.csv").write_text(text)
    back = read_trajectory(tmp_path / "old.csv")
    np.testing.assert_allclose(back.std_vel, tr.std_vel)
    np.testing.assert_allclose(back.std_att, tr.std_att, rtol=1e-12)
