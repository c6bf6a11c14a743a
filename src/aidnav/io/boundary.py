"""The corrections that turn what a file says into aidnav's conventions and are not tied to one
format: the IMU time offset and the height datum. Readers and jobs call these once; nothing
downstream of :mod:`aidnav.io` applies them again."""

from __future__ import annotations

import numpy as np

from aidnav.data import GnssData, ImuData


def shift_imu_time(imu: ImuData, offset_s: float) -> ImuData:
    """IMU samples with ``offset_s`` added to every stamp (IMU clock → GNSS time scale)."""
    if not offset_s:
        return imu
    if not np.isfinite(offset_s):
        raise ValueError(f"IMU time offset {offset_s}: not a finite number of seconds")
    ev = list(imu.events) + [f"IMU time offset {offset_s:+.4f} s added to the IMU stamps"]
    return ImuData(imu.time + offset_s, imu.dtheta, imu.dv, t0=imu.t0 + offset_s, events=ev)


def shift_height(gnss: GnssData, offset_m: float, source: str = "") -> GnssData:
    """GNSS fixes with ``offset_m`` added to every height (e.g. geoid undulation: MSL → ellipsoid)."""
    if not offset_m:
        return gnss
    if not np.isfinite(offset_m):
        raise ValueError(f"height offset {offset_m}: not a finite number of metres")
    g = GnssData(gnss.time, gnss.lat, gnss.lon, gnss.height + offset_m, gnss.vel, gnss.std_pos,
                 gnss.std_vel, gnss.quality, events=list(gnss.events))
    g.events.append(f"{source + ': ' if source else ''}height offset {offset_m:+.3f} m added "
                    "(datum of the file → WGS-84 ellipsoid)")
    return g
