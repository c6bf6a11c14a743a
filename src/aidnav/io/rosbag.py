"""ROS 1 (``.bag``) and ROS 2 (bag directory with ``metadata.yaml``) bags → ImuData / GnssData, via
``rosbags`` (pure Python; no ROS installation needed).

Messages read:

* ``sensor_msgs/Imu``: ``angular_velocity`` [rad/s] and ``linear_acceleration`` [m/s²] (rates), in the
  frame of the message. ROS body frames follow REP-103, **FLU** (x forward, y left, z up): converted to
  body RFU, x_RFU = −y_FLU, y_RFU = x_FLU, z_RFU = z_FLU (``axes="FLU"``; "RFU" and "FRD" are also
  accepted). Rates become increments over (t_{k-1}, t_k] exactly as the interchange reader forms them
  from rate columns: Δθ_k = ω_k·(t_k − t_{k-1}), the first interval taking the length of the second.
* ``sensor_msgs/NavSatFix``: ``latitude, longitude`` [deg], ``altitude`` [m] above the WGS-84
  **ellipsoid** (the message definition: ``height_datum = "ellipsoid"``, a configured height offset is
  not applied, :mod:`aidnav.io.formats`). σ = √diag(``position_covariance``) (ENU [m²], row-major, as
  the message defines it) when ``position_covariance_type`` is 1 (approximated), 2 (diagonal known) or
  3 (known; the off-diagonal terms are not used); type 0 (unknown): σ absent, the filter default is
  used. The types seen are stated in the events. Fixes with status −1 (NO_FIX) are skipped (counted).
  quality (RTKLIB Q, the rules of :mod:`aidnav.io._std`): status 0 FIX → 5 (single), 1 SBAS_FIX → 3,
  2 GBAS_FIX → 4 (ground-based augmentation: DGPS or RTK; σ from the covariance, factor 1).
* optional velocity, ``geometry_msgs/TwistStamped`` or ``TwistWithCovarianceStamped`` (σ from the
  diagonal of the linear block of its covariance when positive), matched to the fixes by header stamp
  (within ``match_s``); fixes without a velocity message get NaN (not measured). Its frame is the
  header's ``frame_id``: one naming NED (``…ned…``) is converted NED → ENU; a body frame
  (:data:`BODY_FRAMES`) is refused (a body velocity is not a GNSS velocity); any other (``enu``, ``map``,
  ``gps``, ``gnss``, empty, …) is taken as ENU (x East, y North, z Up), as GNSS drivers publish it
  (``nmea_navsat_driver``, ``ublox_gps``); the frame used is stated in the events.

Time: the header stamps (``sec + nanosec·1e-9``). ``stamps="utc"`` (default; ROS time is POSIX/UTC):
converted to GPST with the leap seconds and returned as GPS seconds of week of the first sample's week;
``"gps"``: the stamps are GPST counted like Unix time (some GNSS drivers); ``"raw"``: kept as they are
(simulation time). The choice is stated in the events.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np

from aidnav.data import GnssData, ImuData
from aidnav.io._std import DEFAULT_POS_STD_M, DEFAULT_VEL_STD_M_S, ZERO_POS_STD_FLOOR_M, check_std
from aidnav.io.errors import DataError
from aidnav.io.gpstime import GPS_EPOCH_UNIX, SECONDS_PER_WEEK, leap_seconds

IMU_TYPE = "sensor_msgs/msg/Imu"
FIX_TYPE = "sensor_msgs/msg/NavSatFix"
TWIST_TYPE = "geometry_msgs/msg/TwistStamped"
TWIST_COV_TYPE = "geometry_msgs/msg/TwistWithCovarianceStamped"
#: frame ids of a vehicle/sensor body frame: a velocity there is refused for GNSS
BODY_FRAMES = ("base_link", "base_footprint", "body", "imu", "imu_link", "vehicle")
_COV_TYPES = {0: "unknown", 1: "approximated", 2: "diagonal known", 3: "known"}

#: v_RFU = AXES[name] @ v_sensor
AXES = {
    "FLU": np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
    "RFU": np.eye(3),
    "FRD": np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]),
}
_FIX_Q = {0: 5, 1: 3, 2: 4}


def _bag_path(path) -> Path:
    """A ROS 2 storage file (.db3 / .mcap) given instead of its bag directory → the directory."""
    path = Path(path)
    storage = path.suffix.lower() in (".db3", ".mcap") and path.is_file()
    if storage and (path.parent / "metadata.yaml").exists():
        return path.parent
    return path


def is_rosbag(path) -> bool:
    """True for a ROS 1 bag file or a ROS 2 bag directory (``metadata.yaml``) or a storage file in one."""
    path = _bag_path(path)
    if path.is_dir():
        return (path / "metadata.yaml").exists()
    try:
        with open(path, "rb") as f:
            return f.read(13) == b"#ROSBAG V2.0\n"
    except OSError:
        return False


def bag_reader(path):
    from rosbags.highlevel import AnyReader  # lazy: rosbags is heavy to import
    from rosbags.typesys import Stores, get_typestore  # lazy: rosbags is heavy to import

    path = _bag_path(path)
    if not is_rosbag(path):
        raise DataError(path, None, "not a ROS bag (a ROS 1 .bag file or a ROS 2 bag directory with "
                                    "metadata.yaml)")
    try:
        return _opened(AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)), path)
    except Exception as e:  # noqa: BLE001  (rosbags raises its own error classes for a broken bag)
        raise DataError(path, None, f"cannot open ROS bag: {e}") from None


@contextlib.contextmanager
def _opened(rd, path):
    """The reader opened (a damaged or truncated bag fails here: its index is read on opening)."""
    try:
        rd.open()
    except Exception as e:  # noqa: BLE001  (rosbags raises its own error classes for a broken bag)
        raise DataError(path, None, f"cannot read the ROS bag: {e} — the file is damaged or truncated (a "
                        "recording that was cut off?): reindex it (`rosbag reindex` for ROS 1) or record "
                        "it again") from None
    try:
        yield rd
    finally:
        rd.close()


def _pick(path, reader, msgtype: str | tuple[str, ...], topic: str | None, required: bool = True,
          option: str = "topic="):
    types = (msgtype,) if isinstance(msgtype, str) else tuple(msgtype)
    what = " or ".join(types)
    conns = [c for c in reader.connections if c.msgtype in types]
    topics = sorted({c.topic for c in conns})
    if topic is not None:
        conns = [c for c in conns if c.topic == topic]
        if not conns:
            have = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
            raise DataError(path, None, f"no {what} messages on topic {topic!r} (topics of that type: "
                                        f"{', '.join(topics) or 'none'}; all topics: {', '.join(have)})")
        return conns
    if not conns:
        if required:
            have = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
            raise DataError(path, None, f"no {what} topic in the bag (have: {', '.join(have) or 'none'})")
        return []
    if len(topics) > 1:
        raise DataError(path, None, f"several {what} topics: {', '.join(topics)}; choose one ({option} on "
                        "the command line, topic= in Python), or keep one in the bag (e.g. `rosbag filter`)")
    return conns


def _stamp(msg) -> tuple[int, int]:
    st = msg.header.stamp
    return int(st.sec), int(st.nanosec)


def _time_scale(sec: np.ndarray, nsec: np.ndarray, stamps: str, name: str,
                events: list[str]) -> tuple[np.ndarray, int | None]:
    """Header stamps (whole seconds, nanoseconds) → seconds [s] on the chosen scale. The whole seconds
    and the fraction are kept apart until the end: a POSIX count in float64 resolves only ~0.2 μs."""
    sec = np.asarray(sec, dtype=np.int64)
    frac = np.asarray(nsec, dtype=float) * 1e-9
    if stamps == "raw":
        events.append(f"{name}: header stamps kept as they are (stamps='raw')")
        return sec.astype(float) + frac, None
    if stamps == "utc":
        leap = np.asarray(leap_seconds(sec.astype(float) + frac), dtype=np.int64)
        how = f"UTC → GPST (+{int(leap[0])} s leap seconds)"
    elif stamps == "gps":
        leap = np.zeros_like(sec)
        how = "stamps are GPST (stamps='gps')"
    else:
        raise ValueError(f"stamps must be 'utc', 'gps' or 'raw', got {stamps!r}")
    g = sec + leap - GPS_EPOCH_UNIX
    week = int(g[0] // SECONDS_PER_WEEK)
    sow = (g - week * SECONDS_PER_WEEK).astype(float) + frac
    events.append(f"{name}: header stamps {how}; time = GPS seconds of week {week}")
    return sow, week


def _check_increasing(path, t, what):
    d = np.diff(t)
    bad = ~(d > 0)
    if bad.any():
        i = int(np.argmax(bad)) + 1
        raise DataError(path, f"{what} message {i + 1}", f"header stamp {float(t[i])!r} s does not increase "
                                                         f"(previous {float(t[i - 1])!r} s)")


def read_imu(path, topic: str | None = None, axes: str = "FLU", stamps: str = "utc") -> ImuData:
    """sensor_msgs/Imu messages of a bag → ImuData (GPS seconds of week with ``stamps="utc"``/"gps",
    increments [rad], [m/s] in body RFU). See the module docstring."""
    if axes not in AXES:
        raise ValueError(f"axes must be one of {sorted(AXES)}, got {axes!r}")
    path = Path(path)
    with bag_reader(path) as rd:
        conns = _pick(path, rd, IMU_TYPE, topic, option="--imu-topic")
        t, w, f = [], [], []
        for conn, _ts, raw in rd.messages(connections=conns):
            m = rd.deserialize(raw, conn.msgtype)
            t.append(_stamp(m))
            av, la = m.angular_velocity, m.linear_acceleration
            w.append((av.x, av.y, av.z))
            f.append((la.x, la.y, la.z))
        topic_name = conns[0].topic
    if len(t) < 2:
        raise DataError(path, None, f"{len(t)} IMU message(s) on {topic_name}: need at least 2")
    st = np.asarray(t, dtype=np.int64)
    events: list[str] = []
    time, week = _time_scale(st[:, 0], st[:, 1], stamps, path.name, events)
    _check_increasing(path, time, topic_name)
    c = AXES[axes]
    w = np.asarray(w, dtype=float) @ c.T
    f = np.asarray(f, dtype=float) @ c.T
    bad = ~np.isfinite(np.hstack([w, f])).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        raise DataError(path, f"{topic_name} message {i + 1}", "NaN or inf rate")
    dt = np.diff(time, prepend=time[0] - (time[1] - time[0]))[:, None]
    events.append(f"{path.name}: {len(time)} sensor_msgs/Imu on {topic_name}; axes {axes} → body RFU; "
                  "rates converted to increments (rate × Δt over (t_{k-1}, t_k])")
    return ImuData(time, w * dt, f * dt, t0=float(time[0] - (time[1] - time[0])), events=events, week=week)


def read_gnss(path, topic: str | None = None, vel_topic: str | None = None, stamps: str = "utc",
              match_s: float = 1e-3, min_pos_std_m: float = ZERO_POS_STD_FLOOR_M) -> GnssData:
    """sensor_msgs/NavSatFix (+ optional geometry_msgs/TwistStamped velocity) of a bag → GnssData
    (GPS seconds of week, lat/lon [rad], ellipsoidal height [m], ENU velocity [m/s], σ ENU [m]).
    See the module docstring."""
    path = Path(path)
    events: list[str] = []
    name = path.name
    with bag_reader(path) as rd:
        conns = _pick(path, rd, FIX_TYPE, topic, option="--gnss-topic")
        vconns = _pick(path, rd, (TWIST_TYPE, TWIST_COV_TYPE), vel_topic, required=vel_topic is not None,
                       option="--gnss-vel-topic")
        rows, n_nofix = [], 0
        cov_types: dict[int, int] = {}
        for conn, _ts, raw in rd.messages(connections=conns):
            m = rd.deserialize(raw, conn.msgtype)
            if m.status.status < 0:
                n_nofix += 1
                continue
            ct = int(m.position_covariance_type)
            cov_types[ct] = cov_types.get(ct, 0) + 1
            cov = np.asarray(m.position_covariance, dtype=float).reshape(3, 3)
            sd = np.sqrt(np.abs(np.diag(cov))) * np.sign(np.diag(cov)) if ct > 0 else np.full(3, np.nan)
            rows.append((*_stamp(m), m.latitude, m.longitude, m.altitude, *sd,
                         _FIX_Q.get(int(m.status.status), 5)))
        vt, vv, vs, frames = [], [], [], set()
        for conn, _ts, raw in (rd.messages(connections=vconns) if vconns else ()):  # [] would mean all
            m = rd.deserialize(raw, conn.msgtype)
            vt.append(_stamp(m))
            frames.add(str(m.header.frame_id))
            tw = m.twist.twist if conn.msgtype == TWIST_COV_TYPE else m.twist
            lin = tw.linear
            vv.append((lin.x, lin.y, lin.z))
            if conn.msgtype == TWIST_COV_TYPE:
                d = np.diag(np.asarray(m.twist.covariance, dtype=float).reshape(6, 6))[:3]
                vs.append(tuple(np.sqrt(d) if np.all(d > 0) else (np.nan,) * 3))
            else:
                vs.append((np.nan,) * 3)
        fix_topic = conns[0].topic
    if n_nofix:
        events.append(f"{name}: {n_nofix} NavSatFix message(s) with status NO_FIX skipped")
    if not rows:
        raise DataError(path, None, f"no NavSatFix with a fix on {fix_topic}")
    st = np.asarray([r[:2] for r in rows], dtype=np.int64)
    a = np.asarray([r[2:] for r in rows], dtype=float)  # lat lon alt σE σN σU Q
    time, week = _time_scale(st[:, 0], st[:, 1], stamps, name, events)
    _check_increasing(path, time, fix_topic)
    bad = np.abs(a[:, 0]) > 90
    if bad.any():
        raise DataError(path, f"{fix_topic} fix {int(np.argmax(bad)) + 1}", f"latitude {a[bad][0, 0]} deg")
    vel = std_vel = None
    if vconns:
        vst = np.asarray(vt, dtype=np.int64).reshape(-1, 2)
        vt = _time_scale(vst[:, 0], vst[:, 1], stamps, name, [])[0]
        vv = np.asarray(vv, dtype=float)
        order = np.argsort(vt)
        vt, vv = vt[order], vv[order]
        j = np.clip(np.searchsorted(vt, time), 1, len(vt) - 1) if len(vt) > 1 else np.zeros(len(a), int)
        if len(vt) > 1:
            j = np.where(np.abs(vt[j - 1] - time) < np.abs(vt[j] - time), j - 1, j)
        vs = np.asarray(vs, dtype=float).reshape(-1, 3)[order]
        ok = np.abs(vt[j] - time) <= match_s
        frame = _velocity_frame(path, vconns[0].topic, frames)
        if frame == "NED":
            vv = vv[:, [1, 0, 2]] * np.array([1.0, 1.0, -1.0])
            vs = vs[:, [1, 0, 2]]
        vel = np.full((len(a), 3), np.nan)
        vel[ok] = vv[j[ok]]
        kind = vconns[0].msgtype.rsplit("/", 1)[-1]
        events.append(f"{name}: velocity from {kind} on {vconns[0].topic} (frame_id "
                      f"{', '.join(sorted(frames)) or 'empty'} → twist.linear as {frame}"
                      f"{' → ENU' if frame == 'NED' else ''}); {int(ok.sum())} of {len(a)} fixes matched "
                      f"within {match_s:g} s, others not measured")
        sv = np.full((len(a), 3), np.nan)
        sv[ok] = vs[j[ok]]
        std_vel = check_std(path, None if np.isnan(sv).all() else sv, ["σve", "σvn", "σvu"],
                            lambda i: f"{vconns[0].topic} velocity {i + 1}", "velocity", DEFAULT_VEL_STD_M_S,
                            0.0, "m/s", events, measured=~np.isnan(vel))
    sp = a[:, 3:6]
    std_pos = check_std(path, None if np.isnan(sp).all() else sp, ["σE", "σN", "σU"],
                        lambda i: f"{fix_topic} fix {i + 1}", "position", DEFAULT_POS_STD_M, min_pos_std_m,
                        "m", events)
    cts = ", ".join(f"{n} × {k} ({_COV_TYPES.get(k, '?')})" for k, n in sorted(cov_types.items()))
    qs = {int(q): int((a[:, 6] == q).sum()) for q in np.unique(a[:, 6])}
    events.append(f"{name}: {len(a)} NavSatFix on {fix_topic}; ellipsoidal altitude; position_covariance_"
                  f"type {cts}: σ from the covariance diagonal where the type is > 0; quality "
                  + ", ".join(f"Q{q} ({n})" for q, n in qs.items()) + " (status FIX → 5, SBAS → 3, GBAS → 4)")
    return GnssData(time, np.radians(a[:, 0]), np.radians(a[:, 1]), a[:, 2], vel=vel, std_pos=std_pos,
                    std_vel=std_vel, quality=a[:, 6].astype(np.int64), events=events, week=week,
                    height_datum="ellipsoid")


def _velocity_frame(path, topic: str, frames: set[str]) -> str:
    """"ENU" or "NED" from the velocity messages' frame ids (module docstring); a body frame is refused."""
    low = {f.lower().lstrip("/") for f in frames}
    body = sorted(f for f in low if f in BODY_FRAMES)
    if body:
        raise DataError(path, None, f"{topic}: velocity in the body frame {body[0]!r}: a GNSS velocity must "
                                    "be in an Earth frame (ENU or NED); choose the receiver's velocity topic "
                                    "(--gnss-vel-topic)")
    ned = {f for f in low if "ned" in f}
    if ned and len(ned) < len(low):
        raise DataError(path, None, f"{topic}: velocity frame ids mix NED and others: {sorted(frames)}")
    return "NED" if ned else "ENU"
