"""Unit constants: multiply a value in the named unit to get SI / radians (the units inside aidnav).

``x_rad_s = x_deg_h * DEG_H``; divide to go back (``x_deg_h = x_rad_s / DEG_H``). Conversions of
files happen in :mod:`aidnav.io`; these constants are for configuration keys and sensor specs, whose
units are in their names.
"""

from __future__ import annotations

import math

__all__ = ["DEG", "ARCMIN", "ARCSEC", "DEG_H", "DEG_S", "DEG_SQRT_H", "DEG_H_SQRT_H", "G0", "MG", "UG",
           "UG_SQRT_H", "PPM", "HOUR", "SQRT_H", "UG_SQRT_HZ", "M_S_SQRT_H", "KNOT"]

DEG = math.pi / 180.0  #: 1 degree [rad]
ARCMIN = DEG / 60.0  #: 1 arcminute [rad]
ARCSEC = DEG / 3600.0  #: 1 arcsecond [rad]
HOUR = 3600.0  #: 1 hour [s]
SQRT_H = math.sqrt(HOUR)  #: √(1 h) [√s]
DEG_S = DEG  #: 1 deg/s [rad/s]
DEG_H = DEG / HOUR  #: 1 deg/h [rad/s]
DEG_SQRT_H = DEG / SQRT_H  #: 1 deg/√h (angle random walk) [rad/√s]
M_S_SQRT_H = 1.0 / SQRT_H  #: 1 m/s/√h (velocity random walk) [m/s/√s]
G0 = 9.80665  #: standard gravity, only for unit conversion (g, mg, µg) [m/s²]
MG = G0 * 1e-3  #: 1 mg [m/s²]
UG = G0 * 1e-6  #: 1 µg [m/s²]
UG_SQRT_HZ = UG  #: 1 µg/√Hz [m/s²/√Hz] = [m/s/√s]
UG_SQRT_H = UG / SQRT_H  #: 1 µg/√h (accelerometer bias random walk) [m/s²/√s]
DEG_H_SQRT_H = DEG_H / SQRT_H  #: 1 deg/h/√h (gyro bias random walk) [rad/s/√s]
PPM = 1e-6  #: 1 ppm [-]
KNOT = 1852.0 / HOUR  #: 1 knot (NMEA speed over ground) [m/s]
