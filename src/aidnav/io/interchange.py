"""Readers and writers of aidnav's interchange files (``CONVENTIONS.md``, "Interchange files").

CSV (comma-separated, one header line, ``#`` comment lines allowed before it) or Parquet with the same
columns, chosen by the file extension (``.csv``; ``.parquet`` / ``.pq``). Column order does not matter
when reading; names do, and they carry the units:

* IMU: ``time`` [s] and either rates ``gyro_{x,y,z}_rad_s`` [rad/s], ``accel_{x,y,z}_m_s2`` [m/s^2]
  or increments ``dtheta_{x,y,z}_rad`` [rad], ``dv_{x,y,z}_m_s`` [m/s]; body frame RFU.
* GNSS: ``time`` [s], ``lat_deg``, ``lon_deg`` [deg], ``height_m`` [m]; optional ``ve, vn, vu``
  [m/s ENU], ``std_e_m, std_n_m, std_u_m`` [m], ``std_ve, std_vn, std_vu`` [m/s], ``quality`` [-].
* Trajectory: ``time, lat_deg, lon_deg, height_m, ve, vn, vu, roll_deg, pitch_deg, heading_deg``,
  optional standard deviations ``<column>_std`` in the unit of their column (``lat_deg_std`` [deg of
  latitude] ...), any further columns (units in their names) kept in ``Trajectory.extra``.

Inside aidnav angles are radians and positions/velocities SI (``aidnav.data``); the conversion
happens here. CSV numbers are written at full float64 precision (shortest round-trip ``repr``) and
read back exactly.

Bad input raises :class:`aidnav.io.errors.DataError` naming the file, the line (for Parquet: the
1-based row) and the problem: empty file, missing columns, wrong number of fields on a line,
non-numeric value, NaN/inf, time not strictly increasing.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aidnav.data import GnssData, ImuData, Trajectory
from aidnav.io._std import (
    DEFAULT_POS_STD_M,
    DEFAULT_VEL_STD_M_S,
    ZERO_POS_STD_FLOOR_M,
    ZERO_VEL_STD_FLOOR_M_S,
    check_std,
    check_velocity,
)
from aidnav.io._table import (  # noqa: F401  (TEXT_COLUMNS, read_table: part of this module's API)
    META_KEY,
    TEXT_COLUMNS,
    WEEK_RE,
    InterchangeTable,
    open_table,
    read_table,
    write_table_file,
)
from aidnav.io.errors import DataError
from aidnav.io.gpstime import SECONDS_PER_WEEK, week_sow_to_utc_iso
from aidnav.io.kfgins import write_nav
from aidnav.nav.earth import radii
from aidnav.nav.rotations import wrap_2pi, wrap_360

__all__ = ["read_imu", "write_imu", "read_gnss", "write_gnss", "read_trajectory", "write_trajectory",
           "read_table", "IMU_RATE_COLUMNS", "IMU_INCREMENT_COLUMNS", "GNSS_COLUMNS", "TRAJECTORY_COLUMNS"]

IMU_RATE_COLUMNS = ["gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s", "accel_x_m_s2", "accel_y_m_s2",
                    "accel_z_m_s2"]
IMU_INCREMENT_COLUMNS = ["dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad", "dv_x_m_s", "dv_y_m_s", "dv_z_m_s"]
GNSS_COLUMNS = ["time", "lat_deg", "lon_deg", "height_m"]
GNSS_VEL_COLUMNS = ["ve", "vn", "vu"]
GNSS_STD_POS_COLUMNS = ["std_e_m", "std_n_m", "std_u_m"]
GNSS_STD_VEL_COLUMNS = ["std_ve", "std_vn", "std_vu"]
TRAJECTORY_COLUMNS = ["time", "lat_deg", "lon_deg", "height_m", "ve", "vn", "vu", "roll_deg", "pitch_deg",
                      "heading_deg"]
TRAJ_STD_POS = ["lat_deg_std", "lon_deg_std", "height_m_std"]
TRAJ_STD_VEL = ["ve_std", "vn_std", "vu_std"]
TRAJ_STD_ATT = ["roll_deg_std", "pitch_deg_std", "heading_deg_std"]


def read_imu(path) -> ImuData:
    """Read IMU samples (body frame RFU) from an interchange CSV/Parquet file.

    Increment columns ``dtheta_*_rad`` [rad], ``dv_*_m_s`` [m/s] are taken as they are; rate columns
    ``gyro_*_rad_s`` [rad/s], ``accel_*_m_s2`` [m/s^2] are converted to increments over
    (t_{k-1}, t_k]: Δθ_k = ω_k·(t_k − t_{k-1}) (the first interval takes the length of the second).
    ``t0`` (start of the first interval) comes from a ``# t0_s = ...`` comment / Parquet metadata when
    present, otherwise t_0 − (t_1 − t_0). Returns :class:`aidnav.data.ImuData` (time [s]).
    """
    t = open_table(path, copy=False)  # the columns may be read-only views: copied below, once
    t.require(["time"], "time")
    has_inc = t.has_all(IMU_INCREMENT_COLUMNS, "IMU increment")
    has_rate = t.has_all(IMU_RATE_COLUMNS, "IMU rate")
    if not has_inc and not has_rate:
        raise DataError(t.path, t.first_line - 1 if t.kind == "csv" else None,
                        "missing IMU columns: need either rates " + ", ".join(IMU_RATE_COLUMNS)
                        + " or increments " + ", ".join(IMU_INCREMENT_COLUMNS)
                        + f" (have: {', '.join(t.cols)})")
    used = IMU_INCREMENT_COLUMNS if has_inc else IMU_RATE_COLUMNS
    t.finite(["time", *used])
    t.increasing_time()
    time = t.cols["time"]
    if not time.flags.writeable:  # a view of the file's buffer
        time = time.copy()
    events = []
    # the gyro and accelerometer triads as two contiguous (N, 3) arrays (no (N, 6) copy)
    if has_inc:
        dth, dv = t.get(IMU_INCREMENT_COLUMNS[:3]), t.get(IMU_INCREMENT_COLUMNS[3:])
        if has_rate:
            events.append("file has both rate and increment columns; the increments were used")
    else:
        if len(time) < 2:
            t.fail(0, "rates need at least two samples to form increments")
        dt = np.diff(time, prepend=time[0] - (time[1] - time[0]))[:, None]
        dth, dv = t.get(IMU_RATE_COLUMNS[:3]), t.get(IMU_RATE_COLUMNS[3:])
        dth *= dt
        dv *= dt
        events.append("rates converted to increments (rate × Δt over (t_{k-1}, t_k])")
    t0 = t.meta.get("t0_s")
    if t0 is not None and not t0 < time[0]:
        t0 = None
    if t0 is None and has_rate:
        t0 = float(time[0] - (time[1] - time[0]))
    return ImuData(time=time, dtheta=dth, dv=dv, t0=t0, events=events, week=_week(t.meta))


def _week(meta: dict) -> int | None:
    w = meta.get("gps_week")
    return None if w is None else int(w)


def _provenance(comments: list[str], meta: dict, week: int | None, notes: list[str] | None):
    """GPS week and free-text notes (source format, time scale, conversions) into comments/metadata."""
    if week is not None:
        comments.append(f"gps_week = {int(week)}")
        meta["gps_week"] = int(week)
    if notes:
        comments.extend(str(n).replace("\n", " ") for n in notes)
        meta["notes"] = [str(n) for n in notes]


def write_imu(imu: ImuData, path, notes: list[str] | None = None) -> Path:
    """Write IMU increments (time [s], Δθ [rad], Δv [m/s], body RFU) to ``path`` (.csv or .parquet).

    The start of the first interval ``imu.t0`` [s] is kept in a ``# t0_s = ...`` comment (CSV) or the
    file metadata (Parquet), as are ``imu.week`` (``# gps_week = ...``) and ``notes`` (provenance: one
    comment line each / ``"notes"`` in the metadata).
    """
    df = {"time": imu.time}
    for j, c in enumerate(IMU_INCREMENT_COLUMNS[:3]):
        df[c] = imu.dtheta[:, j]
    for j, c in enumerate(IMU_INCREMENT_COLUMNS[3:]):
        df[c] = imu.dv[:, j]
    comments = ["aidnav IMU increments over (t_{k-1}, t_k], body frame RFU; time [s], dtheta [rad], dv [m/s]"]
    meta = {}
    if imu.t0 is not None:
        comments.append(f"t0_s = {float(imu.t0)!r}")
        meta["t0_s"] = float(imu.t0)
    _provenance(comments, meta, imu.week, notes)
    return write_table_file(df, path, comments, meta)


# ============================================================================================== GNSS
def _optional_triad(t: InterchangeTable, names: list[str]) -> np.ndarray | None:
    """(M, 3) array of the columns ``names`` that are present (absent ones all-NaN); None if none is."""
    if not any(c in t.cols for c in names):
        return None
    m = len(t)
    return np.column_stack([t.cols[c] if c in t.cols else np.full(m, np.nan) for c in names])


def read_gnss(path, min_pos_std_m: float = ZERO_POS_STD_FLOOR_M,
              min_vel_std_m_s: float = ZERO_VEL_STD_FLOOR_M_S) -> GnssData:
    """Read GNSS fixes: time [s], lat/lon [deg → rad], height [m]; optional ENU velocity [m/s],
    1σ ENU position [m] / velocity [m/s] and ``quality``. Returns :class:`aidnav.data.GnssData`.

    Partial content (:mod:`aidnav.io._std`): each velocity component is optional and NaN (or an empty
    field) means "not measured" — a file with ``ve, vn`` and no ``vu`` has vu all-NaN; σ columns are
    optional (absent: ``std_*`` None and an event names the σ the filter uses; a NaN σ of a measured
    value gets the default σ); σ = 0 is floored to ``min_pos_std_m`` / ``min_vel_std_m_s`` with a
    warning event; a negative σ is refused (DataError with file, line and column). Heights are as in
    the file: a datum offset is applied by :func:`aidnav.io.formats.read_gnss`.
    """
    t = open_table(path)
    t.require(GNSS_COLUMNS, "GNSS")
    t.finite(GNSS_COLUMNS)
    t.increasing_time()
    events: list[str] = []
    name = t.path.name
    vel = _optional_triad(t, GNSS_VEL_COLUMNS)
    if vel is not None:
        check_velocity(t.path, vel, GNSS_VEL_COLUMNS, t.line)
        absent = [c for c in GNSS_VEL_COLUMNS if c not in t.cols]
        if absent:
            events.append(f"{name}: no {', '.join(absent)} column: that velocity component is not measured "
                          "(NaN); only the measured components are used")
        nan_rows = int(np.isnan(vel[:, [GNSS_VEL_COLUMNS.index(c) for c in GNSS_VEL_COLUMNS
                                        if c in t.cols]]).any(axis=1).sum())
        if nan_rows:
            events.append(f"{name}: {nan_rows} fix(es) with some velocity component not measured (NaN)")
        if np.isnan(vel).all():
            vel = None
    measured_v = None if vel is None else ~np.isnan(vel)
    sp = _optional_triad(t, GNSS_STD_POS_COLUMNS)
    std_pos = check_std(t.path, sp, GNSS_STD_POS_COLUMNS, t.line, "position", DEFAULT_POS_STD_M,
                        min_pos_std_m, "m", events)
    std_vel = None
    if vel is not None:
        sv = _optional_triad(t, GNSS_STD_VEL_COLUMNS)
        std_vel = check_std(t.path, sv, GNSS_STD_VEL_COLUMNS, t.line, "velocity", DEFAULT_VEL_STD_M_S,
                            min_vel_std_m_s, "m/s", events, measured=measured_v)
    elif any(c in t.cols for c in GNSS_STD_VEL_COLUMNS):
        events.append(f"{name}: velocity σ columns without measured velocity: not used")
    quality = None
    if "quality" in t.cols:
        q = t.cols["quality"]
        quality = np.where(np.isfinite(q), q, 0).astype(np.int64)
    return GnssData(time=t.cols["time"], lat=np.radians(t.cols["lat_deg"]), lon=np.radians(t.cols["lon_deg"]),
                    height=t.cols["height_m"], vel=vel, std_pos=std_pos, std_vel=std_vel, quality=quality,
                    events=events, week=_week(t.meta))


def write_gnss(gnss: GnssData, path, notes: list[str] | None = None) -> Path:
    """Write GNSS fixes (time [s], lat/lon [deg], height [m], optional ENU velocity [m/s] (NaN = not
    measured, an empty CSV field), 1σ ENU position [m] / velocity [m/s], quality) to ``path`` (.csv or
    .parquet); ``gnss.week`` and ``notes`` are kept as for :func:`write_imu`."""
    df = {"time": gnss.time, "lat_deg": np.degrees(gnss.lat), "lon_deg": np.degrees(gnss.lon),
          "height_m": gnss.height}
    for arr, names in ((gnss.vel, GNSS_VEL_COLUMNS), (gnss.std_pos, GNSS_STD_POS_COLUMNS),
                       (gnss.std_vel, GNSS_STD_VEL_COLUMNS)):
        if arr is not None:
            for j, c in enumerate(names):
                df[c] = arr[:, j]
    if gnss.quality is not None:
        df["quality"] = np.asarray(gnss.quality, dtype=np.int64)
    comments = ["aidnav GNSS fixes; time [s], lat/lon [deg], height [m] ellipsoidal, velocity ENU [m/s], "
                "std ENU [m], [m/s]"]
    meta: dict = {}
    _provenance(comments, meta, gnss.week, notes)
    return write_table_file(df, path, comments, meta)


# ======================================================================================== trajectory
def _pos_std_scale(lat, h):
    """Metres per radian of latitude (north) and of longitude (east) at (lat [rad], h [m])."""
    rm, rn = radii(np.asarray(lat, dtype=float))
    return rm + h, (rn + h) * np.cos(lat)


def read_trajectory(path) -> Trajectory:
    """Read a trajectory (truth or estimate).

    Columns ``time`` [s], ``lat_deg, lon_deg`` [deg → rad], ``height_m`` [m], ``ve, vn, vu`` [m/s ENU],
    ``roll_deg, pitch_deg, heading_deg`` [deg → rad; heading wrapped to [0, 2π)]. Optional standard
    deviations: ``lat_deg_std, lon_deg_std`` [deg] → ``std_pos`` E/N [m] (via R_N, R_M),
    ``height_m_std`` → U [m] (``std_e_m, std_n_m, std_u_m`` [m] are preferred when present); ``ve_std ...`` →
    ``std_vel`` [m/s]; ``roll_deg_std ...`` → ``std_att`` [rad]. Other columns → ``extra`` as read.
    """
    return trajectory_from_table(open_table(path))


def trajectory_from_table(t: InterchangeTable) -> Trajectory:
    """The :class:`Trajectory` of :func:`read_trajectory` from a table of interchange columns (a whole file,
    or a piece of one read in batches by :mod:`aidnav.io.stream`), with the same checks."""
    t.require(TRAJECTORY_COLUMNS, "trajectory")
    has_sp = t.has_all(TRAJ_STD_POS, "position std")
    has_sv = t.has_all(TRAJ_STD_VEL, "velocity std")
    has_sa = t.has_all(TRAJ_STD_ATT, "attitude std")
    has_sp_m = t.has_all(GNSS_STD_POS_COLUMNS, "position std")
    std_cols = (TRAJ_STD_POS if has_sp else []) + (GNSS_STD_POS_COLUMNS if has_sp_m else []) \
        + (TRAJ_STD_VEL if has_sv else []) + (TRAJ_STD_ATT if has_sa else [])
    t.finite(TRAJECTORY_COLUMNS + std_cols)
    t.increasing_time()
    c = t.cols
    lat, lon, h = np.radians(c["lat_deg"]), np.radians(c["lon_deg"]), c["height_m"]
    heading = wrap_2pi(np.radians(c["heading_deg"]))
    heading[heading >= 2 * np.pi] = 0.0
    rph = np.column_stack([np.radians(c["roll_deg"]), np.radians(c["pitch_deg"]), heading])
    std_pos = std_vel = std_att = None
    if has_sp_m:  # metres as written (exact); the degree columns are kept for older files
        std_pos = t.get(GNSS_STD_POS_COLUMNS)
    elif has_sp:
        sn, se = _pos_std_scale(lat, h)
        std_pos = np.column_stack([np.radians(c["lon_deg_std"]) * se, np.radians(c["lat_deg_std"]) * sn,
                                   c["height_m_std"]])
    if has_sv:
        std_vel = t.get(TRAJ_STD_VEL)
    if has_sa:
        std_att = np.radians(t.get(TRAJ_STD_ATT))
    known = set(TRAJECTORY_COLUMNS) | set(std_cols) | {"gps_week"}
    extra = {k: v for k, v in c.items() if k not in known}
    week = t.meta.get("gps_week")
    if week is None and "gps_week" in c and np.isfinite(c["gps_week"][0]):
        week = int(c["gps_week"][0] - np.floor(c["time"][0] / SECONDS_PER_WEEK))
    return Trajectory(time=c["time"], lat=lat, lon=lon, height=h, vel=t.get(["ve", "vn", "vu"]), rph=rph,
                      std_pos=std_pos, std_vel=std_vel, std_att=std_att, extra=extra,
                      week=None if week is None else int(week))


def trajectory_columns(traj: Trajectory, week: int | None = None) -> dict[str, np.ndarray]:
    """The interchange columns of ``traj`` (degrees, m, m/s at the boundary) as a dict of arrays.

    ``std_pos`` E/N/U [m] becomes ``lon_deg_std, lat_deg_std`` [deg] and ``height_m_std`` [m] (kept
    for compatibility) **and** ``std_e_m, std_n_m, std_u_m`` [m]; ``std_vel`` → ``ve_std, vn_std,
    vu_std`` [m/s]; ``std_att`` → ``roll_deg_std ...`` [deg]; ``extra`` columns as they are. With
    ``week`` (the GPS week of ``traj.time``, which is then GPS seconds of week; default ``traj.week``,
    None when the trajectory does not know it) two columns follow
    ``time``: ``gps_week`` (the week of each epoch: a time past 604800 s belongs to the next week) and
    ``utc`` (ISO 8601 UTC, microseconds, leap seconds applied by :mod:`aidnav.io.gpstime`).
    """
    week = traj.week if week is None else week
    heading = wrap_360(np.degrees(traj.rph[:, 2]))
    heading[heading >= 360.0] = 0.0
    df = {"time": traj.time}
    if week is not None:
        wk = int(week) + np.floor(np.asarray(traj.time) / SECONDS_PER_WEEK).astype(np.int64)
        df["gps_week"] = wk
        df["utc"] = week_sow_to_utc_iso(int(week), traj.time)
    df.update({
        "lat_deg": np.degrees(traj.lat), "lon_deg": np.degrees(traj.lon),
        "height_m": traj.height, "ve": traj.vel[:, 0], "vn": traj.vel[:, 1], "vu": traj.vel[:, 2],
        "roll_deg": np.degrees(traj.rph[:, 0]), "pitch_deg": np.degrees(traj.rph[:, 1]),
        "heading_deg": heading,
    })
    if traj.std_pos is not None:
        sn, se = _pos_std_scale(traj.lat, traj.height)
        df["lat_deg_std"] = np.degrees(traj.std_pos[:, 1] / sn)
        df["lon_deg_std"] = np.degrees(traj.std_pos[:, 0] / se)
        df["height_m_std"] = traj.std_pos[:, 2]
        for j, c in enumerate(GNSS_STD_POS_COLUMNS):
            df[c] = traj.std_pos[:, j]
    if traj.std_vel is not None:
        for j, c in enumerate(TRAJ_STD_VEL):
            df[c] = traj.std_vel[:, j]
    if traj.std_att is not None:
        for j, c in enumerate(TRAJ_STD_ATT):
            df[c] = np.degrees(traj.std_att[:, j])
    for k, v in traj.extra.items():
        if k in df:
            continue
        df[k] = np.asarray(v)
    return df


def write_trajectory(traj: Trajectory, path, week: int | None = None) -> Path:
    """Write a trajectory (``CONVENTIONS.md`` trajectory columns, degrees at the boundary) to ``path``
    (.csv or .parquet); columns as :func:`trajectory_columns` (``week``: add ``gps_week`` and ``utc``).
    A ``.nav`` path writes KF-GINS navigation text instead (:func:`aidnav.io.kfgins.write_nav`)."""
    if str(path).lower().endswith(".nav"):
        return write_nav(traj, path, week=week)
    week = traj.week if week is None else week
    df = trajectory_columns(traj, week=week)
    comments = ["aidnav trajectory; time [s], lat/lon [deg], height [m] ellipsoidal, velocity ENU [m/s], "
                "roll/pitch/heading [deg] (heading clockwise from North); std_e_m/std_n_m/std_u_m [m]"
                + ("" if week is None else f"; time = GPS seconds of week {int(week)}, utc = UTC (ISO 8601)")]
    return write_table_file(df, path, comments, {} if week is None else {"gps_week": int(week)})
