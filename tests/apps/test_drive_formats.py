"""The real drive written by the formats' own tools and processed with the shipped drive configuration
(issue 38 acceptance).

From ``rtklibexplorer_drive_0708`` (RTK ``.pos`` heights above MSL, the configuration's datum offset
−21.4 m): an NMEA log written with pynmea2's sentence classes (GGA with the geoid separation −21.4 m, RMC,
GST) and a ROS 2 bag written with rosbags (``sensor_msgs/Imu`` from the raw IMU log, ``NavSatFix`` with
status GBAS_FIX and the RTK covariance, ``TwistWithCovarianceStamped`` velocity). Both files declare
ellipsoidal heights, so the configuration's offset must not be added again (a warning names both); the
heights must match the ``.pos`` plus its datum at aided epochs, and the outage score (15-s outages every
45 s from 40 s, the data README's benchmark) must be present and within 1.3× of the ``.pos`` run.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from aidnav.apps.process import load_config, process_logs
from aidnav.io import formats
from aidnav.io.gpstime import GPS_EPOCH_UNIX, leap_seconds
from aidnav.io.interchange import read_trajectory
from aidnav.io.rtklib import read_pos

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]
CFG = REPO / "examples" / "rtklibexplorer_drive_0708.yaml"
SEP = -21.4  # the data README's geoid undulation: .pos heights + SEP = ellipsoidal
OUTAGE = ["40:15:45"]


def _utc(week: int, sow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """GPS week + seconds of week → UTC POSIX (whole seconds, nanoseconds)."""
    whole = np.floor(sow)
    nsec = np.round((sow - whole) * 1e9).astype(np.int64)
    g = (GPS_EPOCH_UNIX + week * 604800 + whole).astype(np.int64)
    leap = np.asarray(leap_seconds(g.astype(float) - 18), dtype=np.int64)
    return g - leap, nsec


def _dm(x: float, deg_digits: int) -> str:
    """|degrees| → NMEA 'ddmm.mmmmmmmmm' (deg_digits degree digits)."""
    a = abs(x)
    d = int(a)
    return f"{d:0{deg_digits}d}{(a - d) * 60:012.9f}"


def write_nmea(pos, path: Path) -> None:
    """GGA (RTK fixed 4 / float 5, MSL altitude + geoid separation), RMC, GST with the .pos σ."""
    import pynmea2

    sec, nsec = _utc(pos.week, pos.time)
    lines = []
    q_gga = {1: "4", 2: "5"}
    for k in range(len(pos.time)):
        t = np.datetime64(int(sec[k]), "s") + np.timedelta64(int(nsec[k]), "ns")
        ts = str(t)  # YYYY-MM-DDTHH:MM:SS.fffffffff
        hh, mm, ss = ts[11:13], ts[14:16], float(ts[17:])
        tod = f"{hh}{mm}{ss:05.2f}"
        date = f"{ts[8:10]}{ts[5:7]}{ts[2:4]}"
        lat, lon = np.degrees(pos.lat[k]), np.degrees(pos.lon[k])
        la, lo = _dm(lat, 2), _dm(lon, 3)
        ns, ew = ("N" if lat >= 0 else "S"), ("E" if lon >= 0 else "W")
        msl = pos.height[k]  # the .pos heights are above MSL (data README)
        q = q_gga.get(int(pos.quality[k]), "1")
        lines.append(str(pynmea2.GGA("GN", "GGA", (tod, la, ns, lo, ew, q, "21", "0.6", f"{msl:.4f}", "M",
                                                   f"{SEP:.1f}", "M", "", ""))))
        ve, vn = pos.vel[k, 0], pos.vel[k, 1]
        spd = np.hypot(ve, vn) / (1852 / 3600)
        crs = np.degrees(np.arctan2(ve, vn)) % 360
        lines.append(str(pynmea2.RMC("GN", "RMC", (tod, "A", la, ns, lo, ew, f"{spd:.4f}", f"{crs:.3f}", date,
                                                   "", "", "D"))))
        se, sn, su = pos.std_pos[k]
        lines.append(str(pynmea2.GST("GN", "GST", (tod, "0.01", f"{se:.4f}", f"{sn:.4f}", "0", f"{sn:.4f}",
                                                   f"{se:.4f}", f"{su:.4f}"))))
    path.write_text("\r\n".join(lines) + "\r\n")


def write_bag(imu, pos, path: Path) -> None:
    """ROS 2 bag: Imu (rates, FLU), NavSatFix (GBAS_FIX, ellipsoidal altitude, ENU covariance type 2),
    TwistWithCovarianceStamped (ENU, frame 'gps') — stamps UTC."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    v3, quat = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    hdr, tm = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    dt = np.diff(imu.time, prepend=imu.t0)
    w, f = imu.dtheta / dt[:, None], imu.dv / dt[:, None]  # body RFU rates
    isec, insec = _utc(imu.week, imu.time)
    gsec, gnsec = _utc(pos.week, pos.time)
    z9 = np.zeros(9)
    with Writer(path, version=9) as wr:
        ci = wr.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=ts)
        cf = wr.add_connection("/fix", "sensor_msgs/msg/NavSatFix", typestore=ts)
        cv = wr.add_connection("/fix_velocity", "geometry_msgs/msg/TwistWithCovarianceStamped", typestore=ts)
        ins = isec * 10**9 + insec
        gns = gsec * 10**9 + gnsec
        order = sorted([(int(x), 0, k) for k, x in enumerate(ins)]
                       + [(int(x), 1, k) for k, x in enumerate(gns)])
        for ns, kind, k in order:
            if kind == 0:
                h = hdr(stamp=tm(sec=int(isec[k]), nanosec=int(insec[k])), frame_id="imu")
                m = T["sensor_msgs/msg/Imu"](h, quat(0.0, 0.0, 0.0, 1.0), z9,
                                             v3(w[k, 1], -w[k, 0], w[k, 2]), z9,  # RFU → FLU
                                             v3(f[k, 1], -f[k, 0], f[k, 2]), z9)
                wr.write(ci, ns, ts.serialize_cdr(m, m.__msgtype__))
                continue
            h = hdr(stamp=tm(sec=int(gsec[k]), nanosec=int(gnsec[k])), frame_id="gps")
            st = T["sensor_msgs/msg/NavSatStatus"](status=2, service=1)  # GBAS_FIX: RTK
            cov = np.diag(pos.std_pos[k] ** 2).ravel()  # E, N, U (the message's ENU)
            lat, lon = float(np.degrees(pos.lat[k])), float(np.degrees(pos.lon[k]))
            m = T["sensor_msgs/msg/NavSatFix"](h, st, lat, lon, float(pos.height[k] + SEP), cov, 2)
            wr.write(cf, ns, ts.serialize_cdr(m, m.__msgtype__))
            c6 = np.zeros((6, 6))
            c6[:3, :3] = np.diag(pos.std_vel[k] ** 2)
            c6[3:, 3:] = np.eye(3)
            tw = T["geometry_msgs/msg/TwistWithCovariance"](T["geometry_msgs/msg/Twist"](v3(*pos.vel[k]),
                                                                                        v3(0.0, 0.0, 0.0)),
                                                            c6.ravel())
            m = T["geometry_msgs/msg/TwistWithCovarianceStamped"](h, tw)
            wr.write(cv, ns, ts.serialize_cdr(m, m.__msgtype__))


@pytest.fixture(scope="module")
def runs(tmp_path_factory, data_dir):
    d = data_dir / "rtklibexplorer_drive_0708"
    if not d.is_dir():
        pytest.skip(f"{d} not found")
    tmp = tmp_path_factory.mktemp("drive_formats")
    pos = read_pos(d / "gnss_1934_sf.pos")
    imu = formats.read_imu(d / "imu_1934.csv")
    write_nmea(pos, tmp / "drive.nmea")
    write_bag(imu, pos, tmp / "drive_ros2")
    out = {}
    for name, imu_in, gnss_in in (("pos", d / "imu_1934.csv", d / "gnss_1934_sf.pos"),
                                  ("nmea", d / "imu_1934.csv", tmp / "drive.nmea"),
                                  ("bag", tmp / "drive_ros2", tmp / "drive_ros2")):
        s = process_logs(imu_in, gnss_in, CFG, tmp / name, outages=OUTAGE, figures=False)
        out[name] = (s, read_trajectory(tmp / name / "trajectory.parquet"))
    return pos, out


def _height_rms(pos, s, traj) -> float:
    acc = np.asarray(s["accepted_fix_times"]) if "accepted_fix_times" in s else pos.time
    t = acc[(acc >= traj.time[0]) & (acc <= traj.time[-1])]
    t = t[np.isin(np.round(t, 3), np.round(pos.time, 3))]
    idx = np.searchsorted(pos.time, t - 1e-6)
    h_ref = pos.height[idx] + SEP
    return float(np.sqrt(np.mean((np.interp(t, traj.time, traj.height) - h_ref) ** 2)))


@pytest.mark.parametrize("name", ["nmea", "bag"])
def test_heights_match_the_pos_plus_its_datum(runs, name):
    pos, out = runs
    s, traj = out[name]
    assert load_config(CFG).gnss.height_offset_m == SEP
    assert s["gnss_height_datum"] == "ellipsoid" and s["gnss_height_offset_m"] == 0.0
    assert any("NOT applied" in w and "-21.400" in w for w in s["events"] + s["warnings"]), \
        "the contradiction (offset configured, file ellipsoidal) must be a warning naming both"
    rms = _height_rms(pos, s, traj)
    print(f"{name}: height RMS at aided epochs {rms:.3f} m")
    assert rms < 0.3


@pytest.mark.parametrize("name", ["nmea", "bag"])
def test_outage_score_present_and_close_to_the_pos_run(runs, name):
    _, out = runs
    ref = out["pos"][0]["outage_score"]
    sc = out[name][0]["outage_score"]
    assert sc.get("rms_m") is not None and sc["n_scored"] > 100, sc
    print(f"{name}: outage RMS {sc['rms_m']:.3f} m vs .pos {ref['rms_m']:.3f} m (median end "
          f"{sc['end_error_median_m']:.2f} vs {ref['end_error_median_m']:.2f} m); {sc['reference']}")
    assert sc["rms_m"] <= 1.3 * ref["rms_m"]
    if name == "bag":  # GBAS_FIX → Q 4: no quality-1 fix, scored on all withheld fixes
        assert sc["reference"].startswith("all withheld") and set(sc["per_quality"]) == {"4"}
