"""Pointing geometry of a GEO satellite: line of sight, antenna az/el, Jacobians, servo angles.

One module serves seed 000 (SAPV aiding: antenna az/el as a measurement of the attitude) and seed 003
(satcom on the move: servo azimuth, elevation and polarization). models.md §1.1 and §4.3.

Frames and units (``docs/conventions.md``): e = ECEF WGS-84, n = ENU, b = body RFU (x right, y forward, z up),
antenna frame v (y_v along the beam, z_v on the azimuth-axis side, x_v = y_v × z_v). Latitude, longitude
and angles in **radians** inside this module (degrees only in :func:`servo_angles`); heights, positions
and lines of sight in metres.

* GEO satellite: latitude 0, longitude λ_s, radius ``radius`` (default :data:`aidnav.nav.earth.R_GEO`
  = 42164.17 km). Seed 000 puts it at height 3.5785e7 m above the ellipsoid instead:
  :func:`geo_radius_from_height` (radius = a + h at the equator) or :data:`R_GEO_SEED000`.
* Line of sight r_e = p_sat − p(L, λ, h); r_n = C_e^n r_e; r_b = C_n^b r_n = (C_b^n)ᵀ r_n.
* Antenna azimuth az = atan2(r_b,x, r_b,y) ∈ [0, 2π): clockwise (seen from above) from the body forward
  axis, in the body x-y plane; elevation el = atan2(r_b,z, √(r_b,x² + r_b,y²)) above that plane.
  The antenna frame is C_v^b = R3(−az)·R1(el), so az = el = 0 points the beam along body forward.
* Jacobians (exact derivatives of the nonlinear chain at the evaluation point):
  with s = √(Δx²+Δy²), ρ = |r_b|,
  A = ∂(az, el)/∂r_b = [[Δy/s², −Δx/s², 0], [−ΔxΔz/(ρ²s), −ΔyΔz/(ρ²s), s/ρ²]];
  attitude error φ with C_b^n(computed) = (I − [φ×]) C_b^n(true): ∂r_b/∂φ = −C_n^b [r_n×];
  position error δP = [δL, δλ, δh] (computed − true): ∂r_b/∂δP = C_n^b (C_e^n B + [r_n×] D), with
  B = ∂r_e/∂P = −C_n^e M with M = [[0, (R_N+h)cosL, 0], [R_M+h, 0, 0], [0, 0, 1]] (exact: the North
  component of ∂p/∂L *is* R_M + h) and D = [[−1, 0, 0], [0, cosL, 0], [0, sinL, 0]] (the rotation of the
  ENU frame, C_e^n(P + δP) = (I − [DδP ×]) C_e^n(P) to first order).
  Hence δ[az, el] = −A C_n^b [r_n×] φ + A C_n^b (C_e^n B + [r_n×] D) δP (§1.1 eq. 23).
* Servo polarization (§4.3): the satellite's "vertical" E-field at the antenna is
  p = k − (k·l) l (k = Earth spin axis, l = r_e/|r_e|); pol = atan2((z_v × p)·y_v, z_v·p), the angle from
  z_v to p as a right-handed rotation about the beam (clockwise seen from behind the antenna looking at
  the satellite), reduced to (−π/2, π/2]; horizontal polarization adds π/2 before the reduction.

All kernels are numba-compiled and take scalars / small arrays; :func:`servo_angles` is the plain-Python
entry point in degrees used by the CLI.
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.units import DEG

from .earth import R_GEO, dcm_ecef_to_enu, lla_to_ecef, radii
from .earth import A as WGS84_A
from .rotations import dcm_from_euler, skew, wrap_360

__all__ = [
    "R_GEO", "H_GEO_SEED000", "R_GEO_SEED000", "geo_radius_from_height", "geo_sat_ecef", "los_ecef",
    "los_enu", "los_body", "az_el_from_body", "az_el_jacobian_rb", "pointing_az_el", "az_el_jacobians",
    "beam_body", "polarization_from_body", "servo_angles_rad", "servo_angles", "wrap_pol",
]

H_GEO_SEED000 = 3.5785e7  #: seed 000's GEO height above the ellipsoid [m]


@njit(cache=True)
def geo_radius_from_height(height):
    """Geocentric radius [m] of a GEO satellite given its height [m] above the WGS-84 ellipsoid (equator)."""
    return WGS84_A + height


R_GEO_SEED000 = WGS84_A + H_GEO_SEED000  #: seed 000's GEO radius, 42163.137 km [m]


@njit(cache=True)
def geo_sat_ecef(sat_lon, radius=R_GEO):
    """ECEF position [m] (3,) of a GEO satellite at longitude ``sat_lon`` [rad, east +] and ``radius`` [m]."""
    return np.array([radius * np.cos(sat_lon), radius * np.sin(sat_lon), 0.0])


@njit(cache=True)
def los_ecef(lat, lon, h, sat_ecef):
    """Line of sight r_e = p_sat − p [m] (3,) in ECEF from the geodetic point (lat, lon [rad], h [m])."""
    x, y, z = lla_to_ecef(lat, lon, h)
    return np.array([sat_ecef[0] - x, sat_ecef[1] - y, sat_ecef[2] - z])


@njit(cache=True)
def los_enu(lat, lon, h, sat_ecef):
    """Line of sight r_n = C_e^n r_e [m] (3,) in the local ENU frame at (lat, lon [rad], h [m])."""
    return dcm_ecef_to_enu(lat, lon) @ los_ecef(lat, lon, h, sat_ecef)


@njit(cache=True)
def los_body(lat, lon, h, Cbn, sat_ecef):
    """Line of sight r_b = C_n^b C_e^n r_e [m] (3,) in the body frame RFU; ``Cbn`` = C_b^n (3×3)."""
    return Cbn.T @ los_enu(lat, lon, h, sat_ecef)


@njit(cache=True)
def az_el_from_body(r_b):
    """(az, el) [rad] of a body-frame direction: az = atan2(x, y) ∈ [0, 2π) clockwise from forward,
    el = atan2(z, √(x²+y²)) above the body x-y plane."""
    az = np.arctan2(r_b[0], r_b[1])
    if az < 0.0:
        az += 2.0 * np.pi
    el = np.arctan2(r_b[2], np.sqrt(r_b[0] * r_b[0] + r_b[1] * r_b[1]))
    return az, el


@njit(cache=True)
def az_el_jacobian_rb(r_b):
    """A = ∂(az, el)/∂r_b (2×3) [rad/m] of :func:`az_el_from_body` (singular at el = ±90°)."""
    x, y, z = r_b[0], r_b[1], r_b[2]
    s2 = x * x + y * y
    s = np.sqrt(s2)
    rho2 = s2 + z * z
    J = np.zeros((2, 3))
    J[0, 0] = y / s2
    J[0, 1] = -x / s2
    J[1, 0] = -x * z / (rho2 * s)
    J[1, 1] = -y * z / (rho2 * s)
    J[1, 2] = s / rho2
    return J


@njit(cache=True)
def pointing_az_el(lat, lon, h, Cbn, sat_ecef):
    """Antenna (az, el) [rad] of the satellite seen from (lat, lon [rad], h [m]) with attitude C_b^n."""
    return az_el_from_body(los_body(lat, lon, h, Cbn, sat_ecef))


@njit(cache=True)
def az_el_jacobians(lat, lon, h, Cbn, sat_ecef):
    """(az, el, H_phi, H_pos): antenna angles [rad] and their exact Jacobians.

    H_phi (2×3) = ∂(az, el)/∂φ [rad/rad] for the attitude error φ (n frame) with
    C_b^n(computed) = (I − [φ×]) C_b^n(true); H_pos (2×3) = ∂(az, el)/∂[δL, δλ, δh] [rad/rad, rad/rad,
    rad/m] for a position error (computed − true) with the satellite fixed. Both are evaluated at the
    given (computed) state; see the module docstring for the formulas (§1.1 eq. 23).
    """
    Ce = dcm_ecef_to_enu(lat, lon)
    r_e = los_ecef(lat, lon, h, sat_ecef)
    r_n = Ce @ r_e
    Cnb = Cbn.T
    r_b = Cnb @ r_n
    az, el = az_el_from_body(r_b)
    Aj = az_el_jacobian_rb(r_b)
    rx = skew(r_n)
    H_phi = -(Aj @ (Cnb @ rx))
    rm, rn = radii(lat)
    cl, sl = np.cos(lat), np.sin(lat)
    # B = ∂r_e/∂P = −C_n^e M, M columns: ∂p^n/∂L = (R_M+h) North, ∂p^n/∂λ = (R_N+h)cosL East, ∂p^n/∂h = Up
    M = np.zeros((3, 3))
    M[1, 0] = rm + h
    M[0, 1] = (rn + h) * cl
    M[2, 2] = 1.0
    B = -(Ce.T @ M)
    D = np.zeros((3, 3))
    D[0, 0] = -1.0
    D[1, 1] = cl
    D[2, 1] = sl
    H_pos = Aj @ (Cnb @ (Ce @ B + rx @ D))
    return az, el, H_phi, H_pos


@njit(cache=True)
def beam_body(az, el):
    """Unit beam direction in the body frame for antenna angles (az, el) [rad]: C_v^b [0, 1, 0]."""
    ce = np.cos(el)
    return np.array([np.sin(az) * ce, np.cos(az) * ce, np.sin(el)])


@njit(cache=True)
def wrap_pol(p):
    """Reduce a polarization angle [rad] modulo π to (−π/2, π/2]."""
    r = p - np.pi * np.floor(p / np.pi)  # [0, π)
    if r > 0.5 * np.pi:
        r -= np.pi
    return r


@njit(cache=True)
def polarization_from_body(az, el, p_b):
    """Polarization angle [rad] from the antenna reference z_v to the field direction ``p_b`` (body frame)
    for antenna angles (az, el): atan2((z_v × p)·y_v, z_v·p), not reduced (§4.3)."""
    sa, ca = np.sin(az), np.cos(az)
    se, ce = np.sin(el), np.cos(el)
    # C_v^b = R3(-az) R1(el); columns x_v, y_v = [sa·ce, ca·ce, se] (the beam), z_v
    z_v = np.array([-sa * se, -ca * se, ce])
    x_v = np.array([ca, -sa, 0.0])  # = y_v × z_v
    return np.arctan2(x_v[0] * p_b[0] + x_v[1] * p_b[1] + x_v[2] * p_b[2],
                      z_v[0] * p_b[0] + z_v[1] * p_b[1] + z_v[2] * p_b[2])


@njit(cache=True)
def servo_angles_rad(lat, lon, h, Cbn, sat_ecef, horizontal):
    """Servo (azimuth, elevation, polarization) [rad] (§4.3) at (lat, lon [rad], h [m]) with attitude
    C_b^n; az ∈ [0, 2π), el ∈ [−π/2, π/2], pol ∈ (−π/2, π/2]; ``horizontal``: horizontal polarization."""
    Ce = dcm_ecef_to_enu(lat, lon)
    r_e = los_ecef(lat, lon, h, sat_ecef)
    r_b = Cbn.T @ (Ce @ r_e)
    az, el = az_el_from_body(r_b)
    nrm = np.sqrt(r_e[0] ** 2 + r_e[1] ** 2 + r_e[2] ** 2)
    l0, l1, l2 = r_e[0] / nrm, r_e[1] / nrm, r_e[2] / nrm
    # p = k - (k·l) l with k = [0, 0, 1]
    p_e = np.array([-l2 * l0, -l2 * l1, 1.0 - l2 * l2])
    p_b = Cbn.T @ (Ce @ p_e)
    pol = polarization_from_body(az, el, p_b)
    if horizontal:
        pol += 0.5 * np.pi
    return az, el, wrap_pol(pol)


def servo_angles(lat_deg: float, lon_deg: float, height_m: float, roll_deg: float, pitch_deg: float,
                 heading_deg: float, sat_lon_deg: float, polarization: str = "vertical",
                 radius_m: float = R_GEO) -> dict:
    """Servo azimuth, elevation and polarization [deg] of a satcom antenna (§4.3).

    Vehicle at geodetic (lat_deg, lon_deg [deg], height_m [m] WGS-84) with attitude (roll, pitch, heading
    [deg], docs/conventions.md); GEO satellite at longitude ``sat_lon_deg`` [deg E] and radius ``radius_m``
    [m] (default R_GEO = 42164.17 km). ``polarization``: "vertical" or "horizontal".

    Returns ``{"azimuth_deg": [0, 360), "elevation_deg": [-90, 90], "polarization_deg": (-90, 90]}``:
    azimuth clockwise from the body forward axis in the body x-y plane, elevation above that plane,
    polarization the right-handed rotation about the beam from the antenna reference axis z_v to the
    satellite's field direction.
    """
    pol = str(polarization).strip().lower()
    if pol not in ("vertical", "horizontal"):
        raise ValueError(f"polarization must be 'vertical' or 'horizontal' (got {polarization!r})")
    d = DEG
    Cbn = dcm_from_euler(float(roll_deg) * d, float(pitch_deg) * d, float(heading_deg) * d)
    sat = geo_sat_ecef(float(sat_lon_deg) * d, float(radius_m))
    az, el, p = servo_angles_rad(float(lat_deg) * d, float(lon_deg) * d, float(height_m), Cbn, sat,
                                 pol == "horizontal")
    return {"azimuth_deg": float(wrap_360(np.degrees(az))), "elevation_deg": float(np.degrees(el)),
            "polarization_deg": float(np.degrees(p))}
