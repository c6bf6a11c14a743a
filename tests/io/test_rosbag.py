"""ROS 1 / ROS 2 bags written in the test by rosbags' own writers: same data as the interchange files."""

from __future__ import annotations

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from aidnav.io import formats, interchange
from aidnav.io.convert import convert
from aidnav.io.errors import DataError

GPS_EPOCH_UNIX = 315964800
WEEK = 2381
LEAP_2025 = 18  # GPST − UTC in 2025 (IERS)


def _header(ts, sow, frame="base"):
    """Header with the UTC stamp of GPS (WEEK, sow), whole seconds and nanoseconds kept exact."""
    h, t = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    whole = int(np.floor(sow))
    nsec = int(round((sow - whole) * 1e9))
    sec = GPS_EPOCH_UNIX + WEEK * 604800 + whole - LEAP_2025
    stamp = t(sec=sec, nanosec=nsec)
    if "seq" in h.__dataclass_fields__:  # ROS 1
        return h(seq=0, stamp=stamp, frame_id=frame)
    return h(stamp=stamp, frame_id=frame)


def _data(n=60, rate=100.0):
    rng = np.random.default_rng(7)
    t = 408600.0 + np.arange(n) / rate
    w = 0.05 * rng.standard_normal((n, 3))  # body RFU [rad/s]
    f = np.array([0.0, 0.0, 9.8]) + 0.1 * rng.standard_normal((n, 3))  # [m/s²]
    tg = 408600.0 + np.arange(4) * 0.2
    k = np.arange(4)
    lla = np.column_stack([40.0966 + 1e-6 * k, -105.147 + 2e-6 * k, 1580.0 + 0.01 * k])
    sig = np.array([[0.01, 0.02, 0.03]] * 4)
    v = rng.standard_normal((4, 3))
    return t, w, f, tg, lla, sig, v


def _write_bag(path, ros: int, with_twist=True, nofix_at=None, imu_topics=("/imu/data",)):
    t, w, f, tg, lla, sig, v = _data()
    ts = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
    T = ts.types
    v3, q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    if ros == 1:
        from rosbags.rosbag1 import Writer

        writer, ser = Writer(path), ts.serialize_ros1
    else:
        from rosbags.rosbag2 import Writer

        writer, ser = Writer(path, version=9), ts.serialize_cdr
    with writer as wr:
        imu_c = [wr.add_connection(tp, "sensor_msgs/msg/Imu", typestore=ts) for tp in imu_topics]
        fix_c = wr.add_connection("/fix", "sensor_msgs/msg/NavSatFix", typestore=ts)
        vel_c = (wr.add_connection("/vel", "geometry_msgs/msg/TwistStamped", typestore=ts) if with_twist
                 else None)
        # interleave by time, as a recorder would
        events = [(tk, "imu", k) for k, tk in enumerate(t)] + [(tk, "fix", k) for k, tk in enumerate(tg)]
        for tk, kind, k in sorted(events):
            ns = int(round(tk * 1e9))
            if kind == "imu":
                # body RFU → ROS FLU: x_FLU = y_RFU, y_FLU = −x_RFU, z_FLU = z_RFU
                m = T["sensor_msgs/msg/Imu"](_header(ts, tk, "imu"), q(0.0, 0.0, 0.0, 1.0), np.zeros(9),
                                             v3(w[k, 1], -w[k, 0], w[k, 2]), np.zeros(9),
                                             v3(f[k, 1], -f[k, 0], f[k, 2]), np.zeros(9))
                for c in imu_c:
                    wr.write(c, ns, ser(m, m.__msgtype__))
                continue
            status = T["sensor_msgs/msg/NavSatStatus"](status=-1 if k == nofix_at else 0, service=1)
            m = T["sensor_msgs/msg/NavSatFix"](_header(ts, tk, "gps"), status, *lla[k],
                                               np.diag(sig[k] ** 2).ravel(), 2)
            wr.write(fix_c, ns, ser(m, m.__msgtype__))
            if vel_c is not None:
                tw = T["geometry_msgs/msg/Twist"](v3(*v[k]), v3(0.0, 0.0, 0.0))
                m = T["geometry_msgs/msg/TwistStamped"](_header(ts, tk, "gps"), tw)
                wr.write(vel_c, ns, ser(m, m.__msgtype__))
    return path


def _interchange(tmp_path):
    import pandas as pd

    t, w, f, tg, lla, sig, v = _data()
    imu = pd.DataFrame({"time": t, **{f"gyro_{a}_rad_s": w[:, j] for j, a in enumerate("xyz")},
                        **{f"accel_{a}_m_s2": f[:, j] for j, a in enumerate("xyz")}})
    imu.to_csv(tmp_path / "imu.csv", index=False, float_format="%.17g")
    g = pd.DataFrame({"time": tg, "lat_deg": lla[:, 0], "lon_deg": lla[:, 1], "height_m": lla[:, 2],
                      "ve": v[:, 0], "vn": v[:, 1], "vu": v[:, 2], "std_e_m": sig[:, 0], "std_n_m": sig[:, 1],
                      "std_u_m": sig[:, 2]})
    g.to_csv(tmp_path / "gnss.csv", index=False, float_format="%.17g")
    return interchange.read_imu(tmp_path / "imu.csv"), interchange.read_gnss(tmp_path / "gnss.csv")


@pytest.mark.parametrize("ros", [1, 2])
def test_bag_round_trip_same_as_interchange(tmp_path, ros):
    bag = _write_bag(tmp_path / ("log.bag" if ros == 1 else "log_ros2"), ros)
    ref_imu, ref_g = _interchange(tmp_path)
    assert formats.detect_imu_format(bag) == formats.detect_gnss_format(bag) == "rosbag"
    imu = formats.read_imu(bag)
    assert imu.week == WEEK
    np.testing.assert_allclose(imu.time, ref_imu.time, rtol=0, atol=1e-9)  # ns stamps
    np.testing.assert_allclose(imu.dtheta, ref_imu.dtheta, rtol=1e-6, atol=1e-15)
    np.testing.assert_allclose(imu.dv, ref_imu.dv, rtol=1e-6, atol=1e-15)
    assert imu.t0 == pytest.approx(ref_imu.t0, abs=1e-9)
    g = formats.read_gnss(bag)
    assert g.week == WEEK
    np.testing.assert_allclose(g.time, ref_g.time, rtol=0, atol=1e-9)
    np.testing.assert_allclose(g.lat, ref_g.lat, rtol=1e-15)
    np.testing.assert_allclose(g.lon, ref_g.lon, rtol=1e-15)
    np.testing.assert_array_equal(g.height, ref_g.height)
    np.testing.assert_allclose(g.std_pos, ref_g.std_pos, rtol=1e-15)
    np.testing.assert_array_equal(g.vel, ref_g.vel)
    assert (g.quality == 5).all()
    if ros == 2:  # the storage file inside the bag directory is accepted for the directory
        db3 = next(bag.glob("*.db3"))
        np.testing.assert_array_equal(formats.read_imu(db3).dtheta, imu.dtheta)
    # convert → interchange → the same arrays as the bag reader
    out = convert(bag, tmp_path / "imu_from_bag.parquet", kind="imu")
    back = formats.read_imu(out["output"])
    np.testing.assert_array_equal(back.dtheta, imu.dtheta)
    assert back.week == WEEK


def test_bag_choices_and_problems(tmp_path):
    bag = _write_bag(tmp_path / "two.bag", 1, with_twist=False, nofix_at=1, imu_topics=("/a", "/b"))
    with pytest.raises(DataError, match="several sensor_msgs/msg/Imu topics: /a, /b"):
        formats.read_imu(bag)
    assert len(formats.read_imu(bag, topic="/b")) == 60
    with pytest.raises(DataError, match="no sensor_msgs/msg/Imu messages on topic '/c'"):
        formats.read_imu(bag, topic="/c")
    g = formats.read_gnss(bag)
    assert len(g) == 3 and g.vel is None and any("NO_FIX" in e for e in g.events)
    with pytest.raises(DataError, match="IMU and GNSS"):
        convert(bag, tmp_path / "x.csv")
    raw = formats.read_imu(bag, topic="/a", stamps="raw")
    assert raw.week is None and raw.time[0] == pytest.approx(GPS_EPOCH_UNIX + WEEK * 604800 + 408600 - 18)


def test_truncated_bag_is_named(tmp_path):
    """A ROS 1 bag cut off while recording (issue 37): exit 2 naming the file and what to do, not exit 1."""
    bag = _write_bag(tmp_path / "full.bag", 1)
    cut = tmp_path / "cut.bag"
    cut.write_bytes(bag.read_bytes()[:bag.stat().st_size * 2 // 3])
    for read in (formats.read_imu, formats.read_gnss):
        with pytest.raises(DataError, match="cut.bag.*truncated"):
            read(cut)
