"""Plausibility checks of what a log says about itself, before any filtering.

Each check looks for the signature of a common mistake (accelerometer in g, gyro in deg/s, rates
written where increments belong, time in milliseconds, IMU and GNSS on different time scales,
latitude/longitude that cannot be degrees) and raises a :class:`DataError` that names the likely
cause and the option or column to fix it. A user who knows better skips a check by name
(``--skip-check NAME``, see :data:`CHECKS`).
"""

from __future__ import annotations

import numpy as np

from aidnav.io.errors import DataError
from aidnav.io.motion_checks import MOTION_CHECKS, check_motion, check_up
from aidnav.units import G0

__all__ = ["CHECKS", "validate_skip", "check_imu", "check_gnss", "check_overlap", "check_motion"]

OMEGA_IE = 7.2921151467e-5

#: name → what it checks (the names accepted by ``--skip-check``)
CHECKS = {
    "imu-rate": "IMU sample interval between 0.1 ms and 1 s (time in seconds, not ms or µs)",
    "imu-accel": "median specific force between 0.3 g and 3 g (accelerometer in m/s², not g; "
                 "increments not written as rates)",
    "imu-gyro": "95th percentile of |ω| below 20 rad/s (gyro in rad/s, not deg/s)",
    "gnss-latlon": "latitude within ±90° and longitude within ±360° (degrees, not radians)",
    "overlap": "the GNSS fixes and the IMU samples share a time span",
    **MOTION_CHECKS,  # from physics: the IMU against the GNSS track (aidnav.io.motion_checks)
}


def _skip(name: str, skip) -> bool:
    if name not in CHECKS:  # pragma: no cover - programming error
        raise KeyError(name)
    return name in (skip or ())


def validate_skip(skip) -> list[str]:
    """Check ``--skip-check`` names; unknown names are an error that lists the known ones."""
    skip = list(skip or [])
    bad = [s for s in skip if s not in CHECKS]
    if bad:
        raise DataError("--skip-check", None, f"unknown check {', '.join(bad)}: expected one of "
                        + ", ".join(CHECKS))
    return skip


def check_imu(imu, path, skip=()) -> list[str]:
    """Checks of an :class:`aidnav.data.ImuData`; returns warnings, raises on implausible data."""
    warnings: list[str] = []
    n = len(imu)
    if n < 2:
        raise DataError(path, None, f"{n} IMU sample(s): at least 2 are needed")
    dt_all = np.diff(np.concatenate([[imu.t0], imu.time]))
    dt = float(np.median(dt_all))
    if not _skip("imu-rate", skip):
        if dt > 1.0:
            raise DataError(path, None, f"median IMU sample interval {dt:g} s ({1 / dt:.3g} Hz): is the "
                            "time column in milliseconds? Convert it to seconds (or --skip-check imu-rate)")
        if dt < 1e-4:
            raise DataError(path, None, f"median IMU sample interval {dt:g} s ({1 / dt:.3g} Hz): is the "
                            "time column in microseconds or nanoseconds? Convert it to seconds "
                            "(or --skip-check imu-rate)")
    good = dt_all > 0
    f = np.linalg.norm(imu.dv[good], axis=1) / dt_all[good]
    w = np.linalg.norm(imu.dtheta[good], axis=1) / dt_all[good]
    fm = float(np.median(f))
    if not _skip("imu-accel", skip):
        if fm < 0.3 * G0 or fm > 3.0 * G0:
            if abs(fm - 1.0) < 0.3:
                cause = "the accelerometer looks like it is in g: multiply by 9.80665 (columns accel_*_m_s2)"
            elif abs(fm - G0 * dt) < 0.3 * G0 * dt:
                cause = ("the values look like increments Δv [m/s] written in rate columns: name them "
                         "dv_x_m_s … instead of accel_x_m_s2 …")
            elif abs(fm * dt - G0) < 0.3 * G0:
                cause = ("the values look like rates [m/s²] written in increment columns: name them "
                         "accel_x_m_s2 … instead of dv_x_m_s …")
            else:
                cause = "check the accelerometer unit and the time column"
            raise DataError(path, None, f"median specific force {fm:.4g} m/s² (gravity is {G0} m/s²): "
                            f"{cause} "
                            "(or --skip-check imu-accel)")
    if not _skip("imu-gyro", skip):
        w95 = float(np.percentile(w, 95))
        if w95 > 20.0:
            raise DataError(path, None, f"95 % of the angular rates are below {w95:.3g} rad/s "
                            f"({np.degrees(w95):.0f} deg/s): the gyro looks like it is in deg/s: multiply "
                            "by π/180 (columns gyro_*_rad_s) (or --skip-check imu-gyro)")
    check_up(imu, path, skip)
    return warnings


def check_gnss(gnss, path, skip=()) -> list[str]:
    """Checks of an :class:`aidnav.data.GnssData` (lat/lon already in radians)."""
    warnings: list[str] = []
    if len(gnss) == 0:
        raise DataError(path, None, "no GNSS fixes")
    if not _skip("gnss-latlon", skip):
        lat = np.degrees(np.asarray(gnss.lat))
        lon = np.degrees(np.asarray(gnss.lon))
        ok = np.isfinite(lat) & np.isfinite(lon)
        if (np.abs(lat[ok]) > 90.0 + 1e-9).any() or (np.abs(lon[ok]) > 360.0 + 1e-9).any():
            i = int(np.flatnonzero(ok & ((np.abs(lat) > 90) | (np.abs(lon) > 360)))[0])
            raise DataError(path, None, f"fix {i}: latitude {lat[i]:g}°, longitude {lon[i]:g}° cannot be "
                            "degrees (are they in another unit, or swapped?)")
        if ok.any() and (np.abs(lat[ok]) < np.degrees(np.pi / 2) / 57.0).all() and \
                (np.abs(lon[ok]) < 180.0 / 57.0).all() and np.ptp(lat[ok]) < 1e-3:
            warnings.append(f"{path}: every latitude is below 1.6° and every longitude below 3.2°: "
                            "if these are radians, convert them to degrees (lat_deg, lon_deg)")
    return warnings


def check_overlap(imu, gnss, imu_path, gnss_path, skip=()) -> list[str]:
    """IMU and GNSS must share a time span; a partial overlap is a warning."""
    if _skip("overlap", skip):
        return []
    ti0, ti1 = float(imu.time[0]), float(imu.time[-1])
    tg0, tg1 = float(np.min(gnss.time)), float(np.max(gnss.time))
    if tg1 < ti0 or tg0 > ti1:
        hint = ""
        gap = tg0 - ti0
        if abs(gap) > 86400 * 6:
            hint = " (one looks like GPS seconds of week and the other not: give --time-offset, or convert)"
        elif abs(gap) > 1800 and abs(gap / 3600.0 - round(gap / 3600.0)) < 0.05:
            hint = (f" (they start {gap / 3600.0:+.0f} h apart: a time zone or local-time clock? give "
                    f"--time-offset {round(gap / 3600.0) * 3600:+.0f}, or convert)")
        raise DataError(gnss_path, None, f"GNSS fixes span {tg0:.3f}…{tg1:.3f} s but the IMU ({imu_path}) "
                        f"spans {ti0:.3f}…{ti1:.3f} s: no common time{hint}")
    inside = ((gnss.time >= ti0) & (gnss.time <= ti1)).mean()
    if inside < 0.999:
        return [f"{100 * (1 - inside):.1f} % of the GNSS fixes lie outside the IMU's time span "
                f"{ti0:.3f}…{ti1:.3f} s and are not used"]
    return []
