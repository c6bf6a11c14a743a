"""KF-GINS text files (i2Nav-WHU/KF-GINS, README "Data format"; also OB_GINS and awesome-gins-datasets).

All are headerless numeric text, fields separated by spaces, tabs or commas (KF-GINS splits on any of
", \\t"):

* IMU: ``t dθx dθy dθz dvx dvy dvz`` — GPS seconds of week [s], angle increments [rad], velocity
  increments [m/s], IMU frame **FRD** (x forward, y right, z down); an optional 8th column (odometer
  speed [m/s]) is not used here (stated in the events).
* GNSS: ``t lat lon h σN σE σD`` — GPS seconds of week [s], latitude/longitude [deg], ellipsoidal
  height [m], position standard deviations north-east-down [m]. KF-GINS's loader also accepts 13
  columns and then takes σ from columns 8–10; the other six are not documented and are not used
  (stated in the events).
* Navigation result / ground truth ``.nav``: ``week sow lat lon h vN vE vD roll pitch yaw`` — GPS week
  (0 in some data sets), seconds of week [s], [deg], [deg], [m], NED velocity [m/s], attitude [deg]
  (yaw clockwise from North, ZYX order).

Conversions to aidnav (``docs/conventions.md``): b_RFU = [y_FRD, x_FRD, −z_FRD]; v_ENU = [vE, vN, −vD];
σ_ENU = [σE, σN, σD]; radians inside. KF-GINS's roll/pitch/yaw of the FRD body in NED are the same
physical angles as aidnav's roll (right wing down), pitch (nose up) and heading (clockwise from North)
of the RFU body in ENU, so they are taken as they are (heading wrapped to [0, 360) deg).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from aidnav.data import GnssData, ImuData, Trajectory
from aidnav.io._std import DEFAULT_POS_STD_M, ZERO_POS_STD_FLOOR_M, check_std
from aidnav.io._text import check_increasing, read_numeric_text
from aidnav.io.atomic import part_path, replacing
from aidnav.io.errors import DataError
from aidnav.nav.rotations import wrap_2pi, wrap_360

__all__ = ["read_imu", "read_gnss", "read_nav", "write_nav", "write_imu", "write_gnss", "FRD_TO_RFU"]

#: v_RFU = FRD_TO_RFU @ v_FRD
FRD_TO_RFU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def _check_lat(path, lat_deg, line_no):
    bad = np.abs(lat_deg) > 90
    if bad.any():
        i = int(np.argmax(bad))
        raise DataError(path, int(line_no[i]), f"latitude {lat_deg[i]} deg out of [-90, 90] "
                                               "(columns: t lat lon h ...)")


def read_imu(path) -> ImuData:
    """KF-GINS IMU text (``t dθ dv``, FRD, rad and m/s increments) → :class:`ImuData` (body RFU).

    Time: the file's GPS seconds of week [s]; each increment covers (t_{k-1}, t_k]; ``t0`` =
    t_0 − (t_1 − t_0)."""
    path = Path(path)
    v, ln = read_numeric_text(path, (7, 8), "KF-GINS IMU (t dθx dθy dθz dvx dvy dvz)")
    if len(v) < 2:
        raise DataError(path, None, "fewer than 2 IMU samples")
    check_increasing(path, v[:, 0], ln)
    events = [f"{path.name}: KF-GINS IMU text; time = GPS seconds of week as in the file; increments "
              "FRD → body RFU (x_RFU = y_FRD, y_RFU = x_FRD, z_RFU = −z_FRD)"]
    if v.shape[1] == 8:
        events.append(f"{path.name}: 8th column (odometer speed) not used")
    return ImuData(v[:, 0], v[:, 1:4] @ FRD_TO_RFU.T, v[:, 4:7] @ FRD_TO_RFU.T, events=events)


def read_gnss(path, min_pos_std_m: float = ZERO_POS_STD_FLOOR_M) -> GnssData:
    """KF-GINS GNSS text (``t lat lon h σN σE σD``) → :class:`GnssData` (time [s], lat/lon [rad],
    ellipsoidal height [m], std_pos ENU [m]; no velocity). σ = 0 floored, negative σ refused."""
    path = Path(path)
    v, ln = read_numeric_text(path, (7, 13), "KF-GINS GNSS (t lat lon h σN σE σD)")
    check_increasing(path, v[:, 0], ln)
    _check_lat(path, v[:, 1], ln)
    events = [f"{path.name}: KF-GINS GNSS text; time = GPS seconds of week as in the file; heights "
              "ellipsoidal; σ north-east-down → ENU"]
    s0 = 4 if v.shape[1] == 7 else 7
    if v.shape[1] == 13:
        events.append(f"{path.name}: 13 columns: position σ from columns 8-10 (as KF-GINS reads them); "
                      "columns 5-7 and 11-13 not used")

    def line_of(i):
        return int(ln[i])

    names = [f"σE (column {s0 + 2})", f"σN (column {s0 + 1})", f"σD (column {s0 + 3})"]
    std = check_std(path, v[:, [s0 + 1, s0, s0 + 2]], names, line_of, "position", DEFAULT_POS_STD_M,
                    min_pos_std_m, "m", events)
    return GnssData(v[:, 0], np.radians(v[:, 1]), np.radians(v[:, 2]), v[:, 3], std_pos=std, events=events)


def read_nav(path) -> Trajectory:
    """KF-GINS navigation result / truth (``week sow lat lon h vN vE vD roll pitch yaw``) →
    :class:`Trajectory` (time = seconds of week [s], ENU velocity, radians; the week in ``extra``)."""
    path = Path(path)
    v, ln = read_numeric_text(path, (11,), "KF-GINS navigation (week sow lat lon h vN vE vD roll pitch yaw)")
    # a log across the week end: seconds counted on from the first epoch's week
    time = v[:, 1] + np.where(v[:, 0] > 0, v[:, 0] - v[0, 0], 0.0) * 604800.0
    check_increasing(path, time, ln)
    _check_lat(path, v[:, 2], ln)
    heading = wrap_2pi(np.radians(v[:, 10]))
    heading[heading >= 2 * np.pi] = 0.0
    return Trajectory(time=time, lat=np.radians(v[:, 2]), lon=np.radians(v[:, 3]), height=v[:, 4],
                      vel=np.column_stack([v[:, 6], v[:, 5], -v[:, 7]]),
                      rph=np.column_stack([np.radians(v[:, 8]), np.radians(v[:, 9]), heading]),
                      extra={"gps_week": v[:, 0]}, week=int(v[0, 0]) if v[0, 0] > 0 else None)


def _write_rows(path, cols: list[np.ndarray], int_cols=()) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fmt = " ".join("%d" if j in int_cols else "%.17g" for j in range(len(cols)))
    with replacing(path) as tmp:
        np.savetxt(tmp, np.column_stack(cols), fmt=fmt)
    return path


def nav_rows(traj: Trajectory, week: int | None = None) -> np.ndarray:
    """The rows of a KF-GINS ``.nav`` file (:func:`write_nav`) for ``traj``: (N, 11)."""
    heading = wrap_360(np.degrees(traj.rph[:, 2]))
    heading[heading >= 360.0] = 0.0
    week = traj.week if week is None else week
    roll = np.floor(np.asarray(traj.time) / 604800.0) if week is not None else 0.0  # past the week end
    wk = (0 if week is None else int(week)) + roll * np.ones(len(traj.time))
    sow = np.asarray(traj.time) - roll * 604800.0
    return np.column_stack([wk, sow, np.degrees(traj.lat), np.degrees(traj.lon), traj.height, traj.vel[:, 1],
                            traj.vel[:, 0], -traj.vel[:, 2], np.degrees(traj.rph[:, 0]),
                            np.degrees(traj.rph[:, 1]), heading])


#: the number format of a ``.nav`` row: week as an integer, the rest at full float64 precision
NAV_FORMAT = " ".join(["%d"] + ["%.17g"] * 10)


def write_nav(traj: Trajectory, path, week: int | None = None) -> Path:
    """Write ``traj`` as a KF-GINS ``.nav`` text file: ``week sow lat lon h vN vE vD roll pitch yaw``
    (week, seconds of week [s], [deg], [deg], [m], NED [m/s], [deg]; yaw = heading in [0, 360)).

    week : the GPS week of ``traj.time`` (default ``traj.week``; written as 0 when unknown, as KF-GINS
    data sets do).
    Full float64 precision (``%.17g``): reading it back gives the same numbers."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with replacing(path) as tmp:
        np.savetxt(tmp, nav_rows(traj, week), fmt=NAV_FORMAT)
    return path


class NavWriter:
    """A KF-GINS ``.nav`` file written piece by piece (``write(traj)`` in time order, then ``close()``;
    ``abort()`` on an error): the rows of :func:`write_nav`, as ``NAME.part`` renamed when complete."""

    def __init__(self, path, week: int | None = None):
        self.path, self.week = Path(path), week
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.part = part_path(self.path)
        self.f = open(self.part, "wb")

    def write(self, traj) -> None:
        np.savetxt(self.f, nav_rows(traj, self.week), fmt=NAV_FORMAT)

    def close(self) -> Path:
        self.f.close()
        os.replace(self.part, self.path)
        return self.path

    def abort(self) -> None:
        self.f.close()
        self.part.unlink(missing_ok=True)


def write_imu(imu: ImuData, path) -> Path:
    """Write increments as KF-GINS IMU text (``t dθ dv`` FRD; b_FRD = [y_RFU, x_RFU, −z_RFU])."""
    m = FRD_TO_RFU.T  # its own inverse
    dth, dv = imu.dtheta @ m.T, imu.dv @ m.T
    return _write_rows(path, [imu.time, *dth.T, *dv.T])


def write_gnss(gnss: GnssData, path) -> Path:
    """Write fixes as KF-GINS GNSS text (``t lat lon h σN σE σD``); KF-GINS needs σ: fixes without
    ``std_pos`` are refused (ValueError)."""
    if gnss.std_pos is None:
        raise ValueError("KF-GINS GNSS files need position σ: the fixes have none")
    s = gnss.std_pos
    return _write_rows(path, [gnss.time, np.degrees(gnss.lat), np.degrees(gnss.lon), gnss.height,
                              s[:, 1], s[:, 0], s[:, 2]])
