"""Datum, quality and σ by format (issue 38): what each file says about its heights decides whether the
configured offset applies; ROS NavSatFix status/covariance and Twist velocity frames as the messages define
them; the quality → σ factor rule written once (aidnav.io._std) and used by the filter's preprocessing."""

from __future__ import annotations

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from aidnav.data import GnssData
from aidnav.filters.config import LooseConfig
from aidnav.filters.preprocess import gnss_arrays
from aidnav.io import formats
from aidnav.io._std import quality_std_factor
from aidnav.io.errors import DataError

GPS_EPOCH_UNIX = 315964800
WEEK = 2381


def _bag(path, status=2, cov_type=2, twist="cov", frame="gps", n=4):
    """A ROS 2 bag of n NavSatFix (σ E, N, U = 0.01, 0.02, 0.03 m) + one velocity topic, stamps UTC."""
    from rosbags.rosbag2 import Writer

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    v3 = T["geometry_msgs/msg/Vector3"]
    with Writer(path, version=9) as wr:
        cf = wr.add_connection("/fix", "sensor_msgs/msg/NavSatFix", typestore=ts)
        vt = ("geometry_msgs/msg/TwistWithCovarianceStamped" if twist == "cov" else
              "geometry_msgs/msg/TwistStamped")
        cv = wr.add_connection("/vel", vt, typestore=ts)
        for k in range(n):
            sec = GPS_EPOCH_UNIX + WEEK * 604800 + 408600 + k - 18
            stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=0)
            h = T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)
            st = T["sensor_msgs/msg/NavSatStatus"](status=status, service=1)
            cov = np.array([[1e-4, 5e-5, 0], [5e-5, 4e-4, 0], [0, 0, 9e-4]]).ravel()  # E, N, U (m²)
            m = T["sensor_msgs/msg/NavSatFix"](h, st, 40.0, -105.0, 1580.0 + k, cov, cov_type)
            wr.write(cf, k * 10**9, ts.serialize_cdr(m, m.__msgtype__))
            tw = T["geometry_msgs/msg/Twist"](v3(1.0, 2.0, 3.0), v3(0.0, 0.0, 0.0))  # x, y, z in `frame`
            if twist == "cov":
                c6 = np.diag([0.04, 0.09, 0.16, 1, 1, 1]).ravel()
                m = T["geometry_msgs/msg/TwistWithCovarianceStamped"](
                    h, T["geometry_msgs/msg/TwistWithCovariance"](tw, c6))
            else:
                m = T["geometry_msgs/msg/TwistStamped"](h, tw)
            wr.write(cv, k * 10**9, ts.serialize_cdr(m, m.__msgtype__))
    return path


def test_navsatfix_is_ellipsoidal_and_its_covariance_is_the_sigma(tmp_path):
    bag = _bag(tmp_path / "b")
    g = formats.read_gnss(bag, height_offset_m=-21.4)
    assert g.height_datum == "ellipsoid" and g.height_offset_m == 0.0
    np.testing.assert_array_equal(g.height, 1580.0 + np.arange(4))  # offset not added
    w = [e for e in g.events if e.startswith("warning:")]
    assert len(w) == 1 and "-21.400" in w[0] and "NavSatFix" in w[0] and "NOT applied" in w[0]
    np.testing.assert_allclose(g.std_pos, [[0.01, 0.02, 0.03]] * 4)  # √diag, E N U as the message says
    assert (g.quality == 4).all()  # GBAS_FIX
    np.testing.assert_allclose(g.vel, [[1.0, 2.0, 3.0]] * 4)  # frame 'gps': ENU
    np.testing.assert_allclose(g.std_vel, [[0.2, 0.3, 0.4]] * 4)  # TwistWithCovariance linear block
    assert any("position_covariance_type 4 × 2 (diagonal known)" in e for e in g.events)


def test_covariance_type_unknown_and_ned_and_body_frames(tmp_path):
    g = formats.read_gnss(_bag(tmp_path / "u", cov_type=0, status=0, twist="plain", frame="gps_ned"))
    assert g.std_pos is None and (g.quality == 5).all()
    np.testing.assert_allclose(g.vel, [[2.0, 1.0, -3.0]] * 4)  # NED (1, 2, 3) → ENU (2, 1, −3)
    assert any("NED → ENU" in e for e in g.events)
    with pytest.raises(DataError, match="body frame 'base_link'"):
        formats.read_gnss(_bag(tmp_path / "bl", frame="base_link"))
    with pytest.raises(DataError, match="not a ROS bag"):
        formats.read_gnss(tmp_path / "bl" / "metadata.yaml", fmt="kfgins", topic="/fix")


def test_rtklib_header_states_the_datum(tmp_path):
    body = "2025/07/08 19:34:18.499 40.0966268 -105.1474483 1601.4740 1 21 0.01 0.01 0.02 0 0 0 0.0 0.0\n"
    for head, datum, h in (("% (lat/lon/height=WGS84/ellipsoidal,Q=1:fix)", "ellipsoid", 1601.474),
                           ("% (lat/lon/height=WGS84/geodetic,Q=1:fix)", "msl", 1601.474 - 21.4),
                           ("%  GPST latitude(deg) longitude(deg) height(m)", "unknown", 1601.474 - 21.4)):
        p = tmp_path / f"{datum}.pos"
        p.write_text(head + "\n" + body)
        g = formats.read_gnss(p, height_offset_m=-21.4)
        assert g.height_datum == datum
        np.testing.assert_allclose(g.height, h)


def test_quality_factor_rule_is_the_documented_one():
    # float ×2, single ×5, all others (fixed, SBAS, DGPS, PPP, unknown 0) ×1
    f = quality_std_factor(np.array([0, 1, 2, 3, 4, 5, 6]), 2.0, 5.0)
    np.testing.assert_array_equal(f, [1, 1, 2, 1, 1, 5, 1])
    cfg = LooseConfig()
    m = 6
    g = GnssData(np.arange(m, dtype=float), np.zeros(m), np.zeros(m), np.zeros(m),
                 std_pos=np.full((m, 3), 0.1), quality=np.array([1, 2, 3, 4, 5, 6]))
    spos = gnss_arrays(g, cfg)[5]
    g_ = cfg.gnss
    np.testing.assert_allclose(spos[:, 0], np.maximum([0.1, 0.1 * g_.float_std_factor, 0.1, 0.1,
                                                       0.1 * g_.single_std_factor, 0.1], g_.min_pos_std_m))
