"""Corrections that are not tied to one file format: the IMU time offset (IMU clock → GNSS time).
The jobs call it once; nothing downstream of :mod:`aidnav.io` applies it again. (The height datum is
applied by :func:`aidnav.io.formats.read_gnss`.)"""

from __future__ import annotations

import numpy as np

from aidnav.data import ImuData


def shift_imu_time(imu: ImuData, offset_s: float) -> ImuData:
    """IMU samples with ``offset_s`` added to every stamp (IMU clock → GNSS time scale)."""
    if not offset_s:
        return imu
    if not np.isfinite(offset_s):
        raise ValueError(f"IMU time offset {offset_s}: not a finite number of seconds")
    ev = list(imu.events) + [f"IMU time offset {offset_s:+.4f} s added to the IMU stamps"]
    return ImuData(imu.time + offset_s, imu.dtheta, imu.dv, t0=imu.t0 + offset_s, events=ev)
