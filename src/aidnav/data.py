"""In-memory containers shared by every package: IMU samples, GNSS fixes, trajectories.

Plain numpy arrays in aidnav's conventions (``docs/conventions.md``): SI units, radians, body RFU,
nav ENU. Files in other units and frames are converted by :mod:`aidnav.io` before they get here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class ImuData:
    """IMU increments.

    time : (N,) sample times t_k [s] (strictly increasing); sample k covers (t_{k-1}, t_k].
    dtheta : (N, 3) angle increments [rad], body RFU.
    dv : (N, 3) velocity increments (integrated specific force) [m/s], body RFU.
    t0 : start time of the first interval [s] (t_0 - Δt by default).
    events : human-readable notes about the data (gaps, dropped lines, ...), never silently dropped.
    week : GPS week of ``time`` when it is GPS seconds of week (None: unknown or not GNSS-timed).
    """

    time: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    t0: float | None = None
    events: list[str] = field(default_factory=list)
    week: int | None = None

    def __post_init__(self):
        self.time = np.ascontiguousarray(self.time, dtype=float)
        self.dtheta = np.ascontiguousarray(self.dtheta, dtype=float).reshape(-1, 3)
        self.dv = np.ascontiguousarray(self.dv, dtype=float).reshape(-1, 3)
        if not (len(self.time) == len(self.dtheta) == len(self.dv)):
            raise ValueError("ImuData: time, dtheta and dv must have the same length")
        if self.t0 is None and len(self.time) > 1:
            self.t0 = float(self.time[0] - (self.time[1] - self.time[0]))

    def __len__(self) -> int:
        return len(self.time)

    @property
    def rate_hz(self) -> float:
        """Median sample rate [Hz]."""
        return float(1.0 / np.median(np.diff(self.time)))

    def slice(self, start: float, stop: float) -> ImuData:
        """Samples with start <= time < stop."""
        m = (self.time >= start) & (self.time < stop)
        idx = np.flatnonzero(m)
        t0 = self.time[idx[0] - 1] if len(idx) and idx[0] > 0 else None
        return ImuData(self.time[m], self.dtheta[m], self.dv[m], t0=t0, week=self.week)

    def to_dataframe(self):
        """A pandas DataFrame in the interchange columns: ``time`` [s], ``dtheta_{x,y,z}_rad`` [rad],
        ``dv_{x,y,z}_m_s`` [m/s] (body RFU)."""
        import pandas as pd  # lazy: pandas is heavy to import

        cols = {"time": self.time}
        for j, a in enumerate("xyz"):
            cols[f"dtheta_{a}_rad"] = self.dtheta[:, j]
        for j, a in enumerate("xyz"):
            cols[f"dv_{a}_m_s"] = self.dv[:, j]
        return pd.DataFrame(cols)


@dataclass
class GnssData:
    """GNSS position (and optional velocity) fixes of the antenna.

    time : (M,) [s]; lat, lon : (M,) [rad]; height : (M,) ellipsoidal [m].
    vel : (M, 3) ENU velocity [m/s] or None.
    std_pos : (M, 3) 1σ ENU position [m]; std_vel : (M, 3) 1σ ENU velocity [m/s] or None.
    quality : (M,) integer quality flag (RTKLIB Q: 1 fix, 2 float, 5 single; 0 unknown) or None.
    A velocity component that is NaN was not measured (e.g. vu of a speed/course fix).
    week : GPS week of ``time`` when it is GPS seconds of week (None: unknown).
    height_datum : what the file says its heights are: ``"ellipsoid"`` (WGS-84 ellipsoidal: ROS NavSatFix,
        UBX NAV-PVT ``height``, NMEA GGA MSL + its geoid separation), ``"msl"`` (above mean sea level, the
        separation unknown) or ``"unknown"`` (the file does not say). Set by the reader.
    height_offset_m : the datum offset :func:`aidnav.io.formats.read_gnss` added to ``height`` [m].
    """

    time: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    height: np.ndarray
    vel: np.ndarray | None = None
    std_pos: np.ndarray | None = None
    std_vel: np.ndarray | None = None
    quality: np.ndarray | None = None
    events: list[str] = field(default_factory=list)
    week: int | None = None
    height_datum: str = "unknown"
    height_offset_m: float = 0.0

    def __post_init__(self):
        self.time = np.ascontiguousarray(self.time, dtype=float)
        self.lat = np.ascontiguousarray(self.lat, dtype=float)
        self.lon = np.ascontiguousarray(self.lon, dtype=float)
        self.height = np.ascontiguousarray(self.height, dtype=float)
        m = len(self.time)
        if self.vel is not None:
            self.vel = np.ascontiguousarray(self.vel, dtype=float).reshape(m, 3)
        if self.std_pos is not None:
            self.std_pos = np.ascontiguousarray(self.std_pos, dtype=float).reshape(m, 3)
        if self.std_vel is not None:
            self.std_vel = np.ascontiguousarray(self.std_vel, dtype=float).reshape(m, 3)

    def __len__(self) -> int:
        return len(self.time)

    def subset(self, mask: np.ndarray) -> GnssData:
        """Fixes where ``mask`` is True."""
        def pick(a):
            return None if a is None else a[mask]

        return GnssData(self.time[mask], self.lat[mask], self.lon[mask], self.height[mask],
                        pick(self.vel), pick(self.std_pos), pick(self.std_vel), pick(self.quality),
                        week=self.week, height_datum=self.height_datum, height_offset_m=self.height_offset_m)

    def to_dataframe(self):
        """A pandas DataFrame in the interchange columns: ``time`` [s], ``lat_deg, lon_deg`` [deg],
        ``height_m`` [m], then where present ``ve, vn, vu`` [m/s], ``std_e_m, std_n_m, std_u_m`` [m],
        ``std_ve, std_vn, std_vu`` [m/s], ``quality``."""
        import pandas as pd  # lazy: pandas is heavy to import

        cols = {"time": self.time, "lat_deg": np.degrees(self.lat), "lon_deg": np.degrees(self.lon),
                "height_m": self.height}
        for arr, names in ((self.vel, ("ve", "vn", "vu")), (self.std_pos, ("std_e_m", "std_n_m", "std_u_m")),
                           (self.std_vel, ("std_ve", "std_vn", "std_vu"))):
            if arr is not None:
                for j, c in enumerate(names):
                    cols[c] = arr[:, j]
        if self.quality is not None:
            cols["quality"] = np.asarray(self.quality)
        return pd.DataFrame(cols)


@dataclass
class Trajectory:
    """Navigation solution or truth (of the IMU, not the antenna).

    time : (N,) [s]; lat, lon : (N,) [rad]; height : (N,) ellipsoidal [m]; vel : (N, 3) ENU [m/s];
    rph : (N, 3) roll, pitch, heading [rad] (heading in [0, 2π)).
    std_pos : (N, 3) 1σ ENU position [m]; std_vel : (N, 3) 1σ ENU velocity [m/s];
    std_att : (N, 3) 1σ roll, pitch, heading [rad] (all optional).
    extra : further per-epoch columns keyed by their interchange name with units
    (e.g. ``"gyro_bias_x_deg_h"``).
    week : GPS week of ``time`` when it is GPS seconds of week (None: unknown).
    The interchange writer turns std_* into the σ columns of docs/conventions.md
    (``std_e_m`` … ``std_u_m``, ``std_ve`` … ``std_vu``, ``std_roll_deg`` … ``std_heading_deg``).
    """

    time: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    height: np.ndarray
    vel: np.ndarray
    rph: np.ndarray
    std_pos: np.ndarray | None = None
    std_vel: np.ndarray | None = None
    std_att: np.ndarray | None = None
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    week: int | None = None

    def __len__(self) -> int:
        return len(self.time)

    def to_dataframe(self, week: int | None = None):
        """A pandas DataFrame with the interchange trajectory columns (degrees, m, m/s; heading in
        [0, 360)), the σ columns as :func:`aidnav.io.interchange.write_trajectory` writes them (including
        ``std_e_m, std_n_m, std_u_m`` [m]) and ``extra``; with ``week`` also ``gps_week`` and ``utc``."""
        import pandas as pd  # lazy: pandas is heavy to import

        # the unit conversions to file columns have one owner, aidnav.io (imported here, not at the top:
        # aidnav.io imports this module)
        from aidnav.io.interchange import trajectory_columns  # lazy: pulls in numba, pyarrow

        return pd.DataFrame(trajectory_columns(self, week=week))
