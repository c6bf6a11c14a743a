"""Tests of ``aidnav.nav.earth`` (WGS-84 model and frame conversions).

Reference: ``pymap3d`` (test dependency) at thousands of random points with a fixed seed, including
the poles (±89.9999°), the equator, and heights from -1000 m to 40,000 km (GEO altitude included);
closed-form radii, the WGS-84 defined normal gravity values and known answers for the rates.

Note on the reference: ``pymap3d.ecef2geodetic`` (You 2000, one correction step, v3.x) is itself
only accurate below a few hundred km height (its latitude error reaches 2e-6 rad = 90 m near GEO
altitude), so ``ecef_to_lla`` / ``enu_to_lla`` are checked against pymap3d where pymap3d is exact,
and everywhere against the exactly known geodetic point that generated the ECEF coordinates
(``lla_to_ecef`` is closed-form and is itself checked against pymap3d to sub-millimetre).
"""

from __future__ import annotations

import numpy as np
import pymap3d as pm
import pytest

from aidnav.nav import earth

DEG = np.pi / 180.0
MM = 1e-3  # sub-millimetre tolerance [m]
RAD_TOL = 1e-9  # angular tolerance [rad]
GEO_H = 35786e3  # GEO height above the equator [m]
PYMAP3D_EXACT_H = 1e5  # pymap3d.ecef2geodetic is exact to < 1e-12 rad below this height [m]

WGS84 = pm.Ellipsoid.from_name("wgs84")


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


@pytest.fixture(scope="module")
def points():
    """Random geodetic points (deg, deg, m): uniform on the sphere, heights -1 km ... 40,000 km.

    Edge cases appended: poles ±89.9999°, the equator, longitudes ±180°, GEO altitude, -1000 m.
    """
    rng = np.random.default_rng(20240601)
    n = 4000
    lat = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n)))
    lon = rng.uniform(-180.0, 180.0, n)
    h = np.concatenate(
        [
            rng.uniform(-1000.0, 10e3, n // 4),  # near the surface
            10.0 ** rng.uniform(1.0, np.log10(4e7), n // 4),  # log-spread up to 40,000 km
            rng.uniform(-1000.0, 4e7, n - n // 2),
        ]
    )
    edge_lat, edge_lon, edge_h = [], [], []
    for la in (89.9999, -89.9999, 0.0, 45.0, -45.0):
        for lo in (-180.0, -90.0, 0.0, 37.5, 179.999999):
            for hh in (-1000.0, 0.0, 1.0, 8848.0, 400e3, GEO_H, 4e7):
                edge_lat.append(la)
                edge_lon.append(lo)
                edge_h.append(hh)
    lat = np.concatenate([lat, edge_lat])
    lon = np.concatenate([lon, edge_lon])
    h = np.concatenate([h, edge_h])
    return lat, lon, h


def test_constants():
    assert earth.A == 6378137.0
    assert earth.F == 1.0 / 298.257223563
    assert earth.OMEGA_IE == 7.2921151467e-5
    assert earth.GM == 3.986004418e14
    assert earth.B == pytest.approx(WGS84.semiminor_axis, abs=1e-9)
    assert np.sqrt(earth.E2) == pytest.approx(WGS84.eccentricity, rel=1e-15)
    # geostationary radius: GM / ω² = r³ (to 1 km, the convention's rounded value)
    assert earth.R_GEO == pytest.approx((earth.GM / earth.OMEGA_IE**2) ** (1 / 3), abs=1e3)


# ---------------------------------------------------------------------------- ECEF <-> geodetic
def test_lla_to_ecef_matches_pymap3d(points):
    lat, lon, h = points
    x, y, z = earth.lla_to_ecef(lat * DEG, lon * DEG, h)
    xr, yr, zr = pm.geodetic2ecef(lat, lon, h, WGS84, deg=True)
    assert np.max(np.abs(x - xr)) < MM
    assert np.max(np.abs(y - yr)) < MM
    assert np.max(np.abs(z - zr)) < MM


def test_lla_to_ecef_scalar():
    x, y, z = earth.lla_to_ecef(0.0, 0.0, 0.0)
    assert (x, y, z) == (earth.A, 0.0, 0.0)
    x, y, z = earth.lla_to_ecef(np.pi / 2, 0.3, 0.0)
    assert abs(x) < 1e-9 and abs(y) < 1e-9 and z == pytest.approx(earth.B, abs=1e-9)
    # GEO point above 0°E
    x, y, z = earth.lla_to_ecef(0.0, 0.0, GEO_H)
    assert x == pytest.approx(earth.A + GEO_H, abs=1e-9)


def test_ecef_to_lla_roundtrip_exact(points):
    """ecef_to_lla(lla_to_ecef(p)) == p at all heights up to 40,000 km (< 1e-9 rad, < 1 mm)."""
    lat, lon, h = points
    x, y, z = earth.lla_to_ecef(lat * DEG, lon * DEG, h)
    la, lo, hh = earth.ecef_to_lla(x, y, z)
    assert np.max(np.abs(la - lat * DEG)) < RAD_TOL
    assert np.max(np.abs(_wrap(lo - lon * DEG))) < RAD_TOL
    assert np.max(np.abs(hh - h)) < MM
    # latitude error as a distance on the (raised) ellipsoid: sub-millimetre
    assert np.max(np.abs(la - lat * DEG) * (earth.A + h)) < MM


def test_ecef_to_lla_matches_pymap3d(points):
    """Against pymap3d where pymap3d itself is exact (h < 100 km), and no worse than it beyond."""
    lat, lon, h = points
    x, y, z = earth.lla_to_ecef(lat * DEG, lon * DEG, h)
    la, lo, hh = earth.ecef_to_lla(x, y, z)
    lar, lor, hr = pm.ecef2geodetic(x, y, z, WGS84, deg=False)
    low = h < PYMAP3D_EXACT_H
    assert low.sum() > 1000
    assert np.max(np.abs(la - lar)[low]) < RAD_TOL
    assert np.max(np.abs(_wrap(lo - lor))) < RAD_TOL
    assert np.max(np.abs(hh - hr)[low]) < MM
    # beyond, ours is at least as close to the generating point as pymap3d (up to rounding)
    assert np.all(np.abs(la - lat * DEG) <= np.abs(lar - lat * DEG) + 1e-12)
    assert np.all(np.abs(hh - h) <= np.abs(hr - h) + 1e-6)


def test_ecef_to_lla_special_points():
    # on the axis (pole), at the centre-adjacent region and far out
    la, lo, hh = earth.ecef_to_lla(0.0, 0.0, earth.B + 100.0)
    assert la == pytest.approx(np.pi / 2, abs=1e-12) and hh == pytest.approx(100.0, abs=1e-6)
    la, lo, hh = earth.ecef_to_lla(0.0, 0.0, -(earth.B + 4e7))
    assert la == pytest.approx(-np.pi / 2, abs=1e-12) and hh == pytest.approx(4e7, abs=1e-6)
    la, lo, hh = earth.ecef_to_lla(earth.R_GEO, 0.0, 0.0)
    assert la == 0.0 and lo == 0.0 and hh == pytest.approx(earth.R_GEO - earth.A, abs=1e-6)
    la, lo, hh = earth.ecef_to_lla(-earth.A, 0.0, 0.0)
    assert abs(lo) == pytest.approx(np.pi) and hh == pytest.approx(0.0, abs=1e-9)


# ---------------------------------------------------------------------------- ENU
@pytest.fixture(scope="module")
def enu_cases(points):
    """Pairs (origin, target): targets are the random points, origins random incl. poles/equator."""
    lat, lon, h = points
    rng = np.random.default_rng(7)
    m = 60
    olat = np.concatenate([[89.9999, -89.9999, 0.0, 0.0], np.degrees(np.arcsin(rng.uniform(-1, 1, m)))])
    olon = np.concatenate([[0.0, 123.0, 0.0, -179.9], rng.uniform(-180, 180, m)])
    oh = np.concatenate(
        [[-1000.0, 0.0, GEO_H, 100.0], rng.uniform(-1000, 4e7, m // 2), rng.uniform(-1000, 1e4, m - m // 2)]
    )
    # each origin gets a slice of the targets (all targets are used)
    idx = np.array_split(np.arange(lat.size), olat.size)
    return [(olat[i], olon[i], oh[i], lat[j], lon[j], h[j]) for i, j in enumerate(idx)]


def test_ecef_enu_against_pymap3d(enu_cases):
    for lat0, lon0, h0, lat, lon, h in enu_cases:
        x, y, z = pm.geodetic2ecef(lat, lon, h, WGS84, deg=True)
        e, n, u = earth.ecef_to_enu(x, y, z, lat0 * DEG, lon0 * DEG, h0)
        er, nr, ur = pm.ecef2enu(x, y, z, lat0, lon0, h0, WGS84, deg=True)
        assert np.max(np.abs(np.stack([e - er, n - nr, u - ur]))) < MM
        xb, yb, zb = earth.enu_to_ecef(er, nr, ur, lat0 * DEG, lon0 * DEG, h0)
        xr, yr, zr = pm.enu2ecef(er, nr, ur, lat0, lon0, h0, WGS84, deg=True)
        assert np.max(np.abs(np.stack([xb - xr, yb - yr, zb - zr]))) < MM
        assert np.max(np.abs(np.stack([xb - x, yb - y, zb - z]))) < MM


def test_lla_enu_against_pymap3d(enu_cases):
    for lat0, lon0, h0, lat, lon, h in enu_cases:
        e, n, u = earth.lla_to_enu(lat * DEG, lon * DEG, h, lat0 * DEG, lon0 * DEG, h0)
        er, nr, ur = pm.geodetic2enu(lat, lon, h, lat0, lon0, h0, WGS84, deg=True)
        assert np.max(np.abs(np.stack([e - er, n - nr, u - ur]))) < MM
        # back: exact against the generating point; against pymap3d where it is exact
        la, lo, hh = earth.enu_to_lla(er, nr, ur, lat0 * DEG, lon0 * DEG, h0)
        assert np.max(np.abs(la - lat * DEG)) < RAD_TOL
        assert np.max(np.abs(_wrap(lo - lon * DEG))) < RAD_TOL
        assert np.max(np.abs(hh - h)) < MM
        lar, lor, hr = pm.enu2geodetic(er, nr, ur, lat0 * DEG, lon0 * DEG, h0, WGS84, deg=False)
        low = h < PYMAP3D_EXACT_H
        assert np.max(np.abs(la - lar)[low], initial=0.0) < RAD_TOL
        assert np.max(np.abs(_wrap(lo - lor))) < RAD_TOL
        assert np.max(np.abs(hh - hr)[low], initial=0.0) < MM


def test_enu_scalar_and_origin():
    lat0, lon0, h0 = 40 * DEG, 116 * DEG, 50.0
    e, n, u = earth.lla_to_enu(lat0, lon0, h0, lat0, lon0, h0)
    assert max(abs(float(e)), abs(float(n)), abs(float(u))) < 1e-9
    # 1 km up along the normal is (0, 0, 1000) in ENU
    e, n, u = earth.lla_to_enu(lat0, lon0, h0 + 1000.0, lat0, lon0, h0)
    assert np.allclose([e, n, u], [0.0, 0.0, 1000.0], atol=1e-8)


def test_lla_difference_enu_small():
    """Curvilinear differences agree with ENU to the curvature term ~ d² (1 + |tan L|) / R."""
    rng = np.random.default_rng(3)
    for lat0, lon0, h0 in ((40 * DEG, 179.99999999 * DEG, 100.0), (-89.9 * DEG, 0.0, 0.0), (0.0, 1.0, 1e4)):
        rm, rn = earth.radii(lat0)
        d = 10.0  # [m]
        lat = lat0 + rng.uniform(-d, d, 200) / (rm + h0)
        lon = _wrap(lon0 + rng.uniform(-d, d, 200) / ((rn + h0) * np.cos(lat0)))  # across ±180°
        h = h0 + rng.uniform(-10, 10, 200)
        de, dn, du = earth.lla_difference_enu(lat, lon, h, lat0, lon0, h0)
        e, n, u = earth.lla_to_enu(lat, lon, h, lat0, lon0, h0)
        tol = 2 * d**2 * (1 + abs(np.tan(lat0))) / earth.A
        assert np.max(np.abs(de - e)) < tol and np.max(np.abs(dn - n)) < tol
        assert np.allclose(du, h - h0, rtol=0, atol=1e-9)


# ---------------------------------------------------------------------------- radii, gravity
def test_radii_closed_form():
    a, e2, b = earth.A, earth.E2, earth.B
    lat = np.linspace(-np.pi / 2, np.pi / 2, 721)
    rm, rn = earth.radii(lat)
    w = 1.0 - e2 * np.sin(lat) ** 2
    assert np.allclose(rn, a / np.sqrt(w), rtol=1e-15, atol=0)
    assert np.allclose(rm, a * (1 - e2) / w**1.5, rtol=1e-14, atol=0)
    # known values: equator R_N = a, R_M = b²/a; pole R_M = R_N = a²/b
    rm0, rn0 = earth.radii(0.0)
    assert rn0 == pytest.approx(a, abs=1e-9)
    assert rm0 == pytest.approx(b * b / a, abs=1e-6)
    assert rm0 == pytest.approx(6335439.327, abs=1e-3)
    rmp, rnp = earth.radii(np.pi / 2)
    assert rmp == pytest.approx(a * a / b, abs=1e-6) and rnp == pytest.approx(a * a / b, abs=1e-6)
    assert rnp == pytest.approx(6399593.626, abs=1e-3)
    # R_M is the radius of curvature of the meridian: d(arc length)/d(lat) from lla_to_ecef
    la, d = 0.7, 1e-6
    p1 = np.array(earth.lla_to_ecef(la - d, 0.0, 0.0))
    p2 = np.array(earth.lla_to_ecef(la + d, 0.0, 0.0))
    assert np.linalg.norm(p2 - p1) / (2 * d) == pytest.approx(earth.radii(la)[0], rel=1e-9)


def test_normal_gravity_defined_values():
    # WGS-84 (NIMA TR8350.2) defined normal gravity on the ellipsoid
    assert earth.gravity(0.0, 0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert earth.gravity(np.pi / 2, 0.0) == pytest.approx(9.8321849378, abs=1e-9)
    assert earth.gravity(-np.pi / 2, 0.0) == pytest.approx(9.8321849378, abs=1e-9)
    # Somigliana formula with the closed-form constant k = b γ_p / (a γ_e) - 1
    ge, gp = 9.7803253359, 9.8321849378
    k = earth.B * gp / (earth.A * ge) - 1.0
    lat = np.linspace(-np.pi / 2, np.pi / 2, 181)
    s2 = np.sin(lat) ** 2
    ref = ge * (1 + k * s2) / np.sqrt(1 - earth.E2 * s2)
    assert np.max(np.abs(earth.gravity(lat, np.zeros_like(lat)) - ref)) < 1e-9


def test_normal_gravity_height_gradient():
    lat = np.linspace(-np.pi / 2, np.pi / 2, 37)
    dgdh = earth.gravity_dh(lat, np.zeros_like(lat))
    # free-air gradient ≈ -3.086e-6 s^-2 everywhere (equator -3.0877e-6, pole -3.0834e-6)
    assert np.all(np.abs(dgdh / -3.086e-6 - 1.0) < 1.5e-3)
    m = earth.OMEGA_IE**2 * earth.A**2 * earth.B / earth.GM
    assert dgdh[18] == pytest.approx(-2 * 9.7803253359 / earth.A * (1 + earth.F + m), rel=1e-12)
    # finite-difference consistency, and the second-order term 3 g h² / a²
    for la in (0.0, 0.6, -1.2):
        for h in (0.0, 1e4, 1e5):
            fd = (earth.gravity(la, h + 1.0) - earth.gravity(la, h - 1.0)) / 2.0
            assert earth.gravity_dh(la, h) == pytest.approx(fd, rel=1e-8)
    g1, g0 = earth.gravity(0.3, 1000.0), earth.gravity(0.3, 0.0)
    assert g1 - g0 == pytest.approx(-3.086e-3, rel=2e-3)


# ---------------------------------------------------------------------------- rates, DCM
def test_earth_rate_n():
    w = earth.OMEGA_IE
    assert np.allclose(earth.earth_rate_n(0.0), [0.0, w, 0.0], atol=1e-20)
    assert np.allclose(earth.earth_rate_n(np.pi / 2), [0.0, 0.0, w], atol=1e-20)
    assert np.allclose(earth.earth_rate_n(-np.pi / 2), [0.0, 0.0, -w], atol=1e-20)
    rng = np.random.default_rng(5)
    for lat, lon in zip(rng.uniform(-1.5, 1.5, 20), rng.uniform(-3, 3, 20), strict=True):
        # ω_ie^n = C_e^n [0, 0, Ω]
        ref = earth.dcm_ecef_to_enu(lat, lon) @ np.array([0.0, 0.0, w])
        assert np.allclose(earth.earth_rate_n(lat), ref, rtol=0, atol=1e-19)


def test_transport_rate_known_answers():
    rm0, rn0 = earth.radii(0.0)
    # eastward at the equator: rotation about North at vE / (R_N + h)
    assert np.allclose(
        earth.transport_rate_n(0.0, 1000.0, np.array([100.0, 0.0, 0.0])),
        [0.0, 100.0 / (rn0 + 1000.0), 0.0],
        rtol=1e-15,
        atol=1e-22,
    )
    # northward: rotation about West at vN / (R_M + h)
    assert np.allclose(
        earth.transport_rate_n(0.0, 0.0, np.array([0.0, 50.0, 3.0])),
        [-50.0 / rm0, 0.0, 0.0],
        rtol=1e-15,
        atol=1e-22,
    )
    # 45°: vertical component vE tan L / (R_N + h) equals the north one
    w = earth.transport_rate_n(np.pi / 4, 0.0, np.array([200.0, 0.0, 0.0]))
    assert w[2] == pytest.approx(w[1], rel=1e-14)


def test_transport_rate_is_rotation_rate_of_enu():
    """[ω_en^n ×] = C_e^n d(C_n^e)/dt along a trajectory with velocity v (finite differences)."""
    rng = np.random.default_rng(11)
    for _ in range(10):
        lat, lon, h = rng.uniform(-1.4, 1.4), rng.uniform(-3, 3), rng.uniform(-100, 1e4)
        v = rng.uniform(-300, 300, 3)
        rm, rn = earth.radii(lat)
        dlat, dlon = v[1] / (rm + h), v[0] / ((rn + h) * np.cos(lat))
        d = 1e-2
        c_plus = earth.dcm_ecef_to_enu(lat + dlat * d, lon + dlon * d).T
        c_minus = earth.dcm_ecef_to_enu(lat - dlat * d, lon - dlon * d).T
        omega = earth.dcm_ecef_to_enu(lat, lon) @ (c_plus - c_minus) / (2 * d)
        w = earth.transport_rate_n(lat, h, v)
        assert np.allclose(omega, -omega.T, atol=1e-12)
        assert np.allclose([omega[2, 1], omega[0, 2], omega[1, 0]], w, rtol=1e-6, atol=1e-13)


def test_dcm_ecef_to_enu():
    rng = np.random.default_rng(13)
    lats = np.concatenate([[89.9999 * DEG, -89.9999 * DEG, 0.0], rng.uniform(-np.pi / 2, np.pi / 2, 50)])
    lons = np.concatenate([[0.0, 2.0, -np.pi], rng.uniform(-np.pi, np.pi, 50)])
    for lat, lon in zip(lats, lons, strict=True):
        c = earth.dcm_ecef_to_enu(lat, lon)
        assert np.allclose(c @ c.T, np.eye(3), atol=1e-15)
        assert np.linalg.det(c) == pytest.approx(1.0, abs=1e-15)
        # up = ellipsoid normal: gradient of x²/a² + y²/a² + z²/b² at the surface point
        x, y, z = earth.lla_to_ecef(lat, lon, 0.0)
        nrm = np.array([x / earth.A**2, y / earth.A**2, z / earth.B**2])
        assert np.allclose(c[2], nrm / np.linalg.norm(nrm), atol=1e-15)
        # and the direction in which height increases
        p0 = np.array(earth.lla_to_ecef(lat, lon, 0.0))
        p1 = np.array(earth.lla_to_ecef(lat, lon, 1000.0))
        assert np.allclose(c[2], (p1 - p0) / 1000.0, atol=1e-12)
        # north along increasing latitude, east along increasing longitude
        d = 1e-7
        pn = np.array(earth.lla_to_ecef(lat + d, lon, 0.0)) - np.array(earth.lla_to_ecef(lat - d, lon, 0.0))
        assert np.allclose(c[1], pn / np.linalg.norm(pn), atol=1e-7)
        if abs(lat) < 1.5:
            pe = np.array(earth.lla_to_ecef(lat, lon + d, 0.0))
            pe -= np.array(earth.lla_to_ecef(lat, lon - d, 0.0))
            assert np.allclose(c[0], pe / np.linalg.norm(pe), atol=1e-7)
    # against pymap3d's ENU axes
    for lat, lon in zip(lats[:10], lons[:10], strict=True):
        c = earth.dcm_ecef_to_enu(lat, lon)
        for k in range(3):
            ref = pm.uvw2enu(*np.eye(3)[k], lat, lon, deg=False)
            assert np.allclose(c[:, k], ref, atol=1e-15)
