"""numpy twins of a few :mod:`aidnav.nav` functions, for processes that must not start numba.

The figures' child of ``aidnav process`` (:mod:`aidnav.apps.run_outputs`) is forked before the command
imports numba and draws the overview and the maps with these: importing :mod:`aidnav.nav.earth` or
:mod:`aidnav.nav.rotations` imports numba (≈ 0.3 s and ≈ 60 MiB), and their first call from Python loads
numba's target and the kernel from its cache (≈ 0.2 s more). The formulas are those of
:func:`aidnav.nav.earth.lla_to_ecef`, :func:`~aidnav.nav.earth.dcm_ecef_to_enu`,
:func:`~aidnav.nav.earth.lla_to_enu`, :func:`aidnav.nav.rotations.wrap_pi` and
:func:`~aidnav.nav.rotations.wrap_360` (a test checks they give the same numbers); the WGS-84 constants
are :mod:`aidnav.nav.earth`'s (the test compares them too). Arrays in, arrays out; nothing here is
compiled.
"""

from __future__ import annotations

import numpy as np

__all__ = ["A", "E2", "lla_to_ecef", "dcm_ecef_to_enu", "lla_to_enu", "wrap_pi", "wrap_360"]

A = 6378137.0  #: WGS-84 semi-major axis [m] (:data:`aidnav.nav.earth.A`)
F = 1.0 / 298.257223563  #: WGS-84 flattening (:data:`aidnav.nav.earth.F`)
E2 = F * (2.0 - F)  #: first eccentricity squared (:data:`aidnav.nav.earth.E2`)


def lla_to_ecef(lat, lon, h):
    """Geodetic (lat, lon [rad], h [m]) to ECEF (x, y, z) [m]."""
    lat, lon, h = np.asarray(lat, float), np.asarray(lon, float), np.asarray(h, float)
    s = np.sin(lat)
    rn = A / np.sqrt(1.0 - E2 * s * s)
    x = (rn + h) * np.cos(lat) * np.cos(lon)
    y = (rn + h) * np.cos(lat) * np.sin(lon)
    z = (rn * (1.0 - E2) + h) * s
    return x, y, z


def dcm_ecef_to_enu(lat, lon) -> np.ndarray:
    """C_e^n: rotation from ECEF to the local ENU frame at (lat, lon) [rad]; 3x3 array."""
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    return np.array([[-so, co, 0.0], [-sl * co, -sl * so, cl], [cl * co, cl * so, sl]])


def lla_to_enu(lat, lon, h, lat0, lon0, h0):
    """Geodetic point(s) (rad, rad, m) to ENU [m] about the origin (lat0, lon0 [rad], h0 [m])."""
    x, y, z = lla_to_ecef(lat, lon, h)
    x0, y0, z0 = lla_to_ecef(lat0, lon0, h0)
    d = np.stack([x - x0, y - y0, z - z0])
    e, n, u = np.tensordot(dcm_ecef_to_enu(float(lat0), float(lon0)), d, axes=1)
    return e, n, u


def wrap_pi(a):
    """Wrap angle(s) [rad] to [-π, π)."""
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def wrap_360(a):
    """Wrap angle(s) [deg] to [0, 360) (headings, azimuths)."""
    r = a % 360.0
    return r - 360.0 * (r >= 360.0)
