"""GEO pointing geometry (seeds 000 and 003): LOS, az/el, exact Jacobians, servo angles (§1.1, §4.3)."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.nav import earth
from aidnav.nav.geo_pointing import (
    H_GEO_SEED000,
    R_GEO,
    R_GEO_SEED000,
    az_el_from_body,
    az_el_jacobian_rb,
    az_el_jacobians,
    beam_body,
    geo_radius_from_height,
    geo_sat_ecef,
    los_body,
    los_ecef,
    los_enu,
    pointing_az_el,
    servo_angles,
    servo_angles_rad,
)
from aidnav.nav.rotations import dcm_from_euler, dcm_from_rotvec

D = np.pi / 180.0


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def _textbook(lat_deg, lon_deg, sat_lon_deg):
    """Spherical-Earth textbook azimuth (cw from North, northern hemisphere), elevation and skew [deg]."""
    L = lat_deg * D
    dl = (sat_lon_deg - lon_deg) * D
    az = 180.0 - np.degrees(np.arctan(np.tan(dl) / np.sin(L)))
    el = np.degrees(np.arctan((np.cos(L) * np.cos(dl) - earth.A / R_GEO)
                              / np.sqrt(1.0 - np.cos(L) ** 2 * np.cos(dl) ** 2)))
    pol = -np.degrees(np.arctan(np.sin(dl) / np.tan(L)))
    return az % 360.0, el, pol


def test_satellite_position_and_radius_options():
    assert R_GEO == pytest.approx(42164.17e3)
    assert R_GEO_SEED000 == pytest.approx(42163.137e3)
    assert geo_radius_from_height(H_GEO_SEED000) == pytest.approx(R_GEO_SEED000)
    s = geo_sat_ecef(138.0 * D)
    assert np.linalg.norm(s) == pytest.approx(R_GEO)
    assert s[2] == 0.0
    assert np.degrees(np.arctan2(s[1], s[0])) == pytest.approx(138.0)
    # the seed-000 height changes the pointing only at the 1e-3 deg level (§0)
    C = dcm_from_euler(0.0, 0.0, 100 * D)
    a1 = np.array(pointing_az_el(39 * D, 116 * D, 0.0, C, geo_sat_ecef(138 * D)))
    a2 = np.array(pointing_az_el(39 * D, 116 * D, 0.0, C, geo_sat_ecef(138 * D, R_GEO_SEED000)))
    assert 0 < np.abs(np.degrees(a1 - a2)).max() < 1e-3


def test_los_frames_against_independent_enu():
    lat, lon, h = 39.9 * D, 116.4 * D, 50.0
    sat = geo_sat_ecef(110.5 * D)
    r_e = los_ecef(lat, lon, h, sat)
    slat, slon, sh = earth.ecef_to_lla(*sat)
    e, n, u = earth.lla_to_enu(slat, slon, sh, lat, lon, h)
    np.testing.assert_allclose(los_enu(lat, lon, h, sat), [e, n, u], rtol=0, atol=1e-4)
    assert np.linalg.norm(r_e) == pytest.approx(np.linalg.norm([e, n, u]), rel=1e-12)
    C = dcm_from_euler(3 * D, -2 * D, 77 * D)
    np.testing.assert_allclose(los_body(lat, lon, h, C, sat), C.T @ np.array([e, n, u]), atol=1e-4)


@pytest.mark.parametrize("lat, lon, sat_lon", [(39.9, 116.4, 110.5), (30.0, 100.0, 120.0),
                                               (45.0, 10.0, -20.0), (60.0, -5.0, 28.2), (-33.0, 151.0, 160.0),
                                               (5.0, 0.0, 50.0)])
def test_level_az_el_against_independent_lla_to_enu(lat, lon, sat_lon):
    """Level vehicle heading North: servo az = azimuth of the LOS from North, el = its elevation (ENU)."""
    h = 120.0
    sat = geo_sat_ecef(sat_lon * D)
    slat, slon, sh = earth.ecef_to_lla(*sat)
    e, n, u = earth.lla_to_enu(slat, slon, sh, lat * D, lon * D, h)
    az_ref = np.degrees(np.arctan2(e, n)) % 360.0
    el_ref = np.degrees(np.arctan2(u, np.hypot(e, n)))
    r = servo_angles(lat, lon, h, 0.0, 0.0, 0.0, sat_lon)
    assert r["azimuth_deg"] == pytest.approx(az_ref, abs=1e-9)
    assert r["elevation_deg"] == pytest.approx(el_ref, abs=1e-9)
    # heading ψ: the servo azimuth is measured from the body forward axis
    for hd in (37.0, 181.0, 300.0):
        rh = servo_angles(lat, lon, h, 0.0, 0.0, hd, sat_lon)
        assert np.degrees(_wrap((rh["azimuth_deg"] - (az_ref - hd)) * D)) == pytest.approx(0.0, abs=1e-9)
        assert rh["elevation_deg"] == pytest.approx(el_ref, abs=1e-9)
        # for a level antenna the polarization does not depend on the heading
        assert rh["polarization_deg"] == pytest.approx(r["polarization_deg"], abs=1e-9)


def test_sub_satellite_longitude_points_south_with_textbook_elevation():
    for lat in (10.0, 30.0, 39.9, 60.0):
        r = servo_angles(lat, 110.5, 0.0, 0.0, 0.0, 0.0, 110.5)
        assert r["azimuth_deg"] == pytest.approx(180.0, abs=1e-9)
        az_t, el_t, pol_t = _textbook(lat, 110.5, 110.5)
        assert r["elevation_deg"] == pytest.approx(el_t, abs=0.25)  # ellipsoid vs sphere
        assert r["polarization_deg"] == pytest.approx(0.0, abs=1e-9)  # no skew on the meridian
    # southern hemisphere: the satellite is due North
    r = servo_angles(-30.0, 20.0, 0.0, 0.0, 0.0, 0.0, 20.0)
    assert r["azimuth_deg"] == pytest.approx(0.0, abs=1e-9) or r["azimuth_deg"] == pytest.approx(360.0)
    # vehicle heading East at the sub-satellite longitude (north): satellite on the right, az = 90
    r = servo_angles(30.0, 20.0, 0.0, 0.0, 0.0, 90.0, 20.0)
    assert r["azimuth_deg"] == pytest.approx(90.0, abs=1e-9)
    # on the equator at the sub-satellite point: zenith
    r = servo_angles(0.0, 20.0, 0.0, 0.0, 0.0, 0.0, 20.0)
    assert r["elevation_deg"] == pytest.approx(90.0, abs=1e-9)


@pytest.mark.parametrize("lat, lon, sat_lon", [(39.9, 116.4, 110.5), (30.0, 100.0, 120.0),
                                               (45.0, 10.0, -20.0), (20.0, -80.0, -101.0), (50.0, 8.0, 19.2)])
def test_level_against_textbook_formulas(lat, lon, sat_lon):
    r = servo_angles(lat, lon, 0.0, 0.0, 0.0, 0.0, sat_lon)
    az_t, el_t, pol_t = _textbook(lat, lon, sat_lon)
    # spherical textbook formulas vs WGS-84: agree to the geodetic/geocentric difference (< 0.2 deg)
    assert np.degrees(_wrap((r["azimuth_deg"] - az_t) * D)) == pytest.approx(0.0, abs=0.2)
    assert r["elevation_deg"] == pytest.approx(el_t, abs=0.2)
    assert r["polarization_deg"] == pytest.approx(pol_t, abs=0.3)
    # magnitude of the skew = the textbook atan(sin Δλ / tan L)
    assert abs(r["polarization_deg"]) == pytest.approx(
        abs(np.degrees(np.arctan(np.sin((sat_lon - lon) * D) / np.tan(lat * D)))), abs=0.3)


def test_polarization_against_enu_construction_and_horizontal():
    """Polarization from an ENU construction for a tilted antenna, and horizontal = vertical + 90."""
    rng = np.random.default_rng(3)
    for _ in range(30):
        lat, lon = rng.uniform(-70, 70), rng.uniform(-180, 180)
        sat_lon = lon + rng.uniform(-60, 60)
        rph = rng.uniform([-20, -20, 0], [20, 20, 360])
        r = servo_angles(lat, lon, 10.0, *rph, sat_lon)
        C = dcm_from_euler(*(rph * D))
        sat = geo_sat_ecef(sat_lon * D)
        r_e = los_ecef(lat * D, lon * D, 10.0, sat)
        l_e = r_e / np.linalg.norm(r_e)
        p_e = np.array([0, 0, 1.0]) - l_e[2] * l_e
        Ce = earth.dcm_ecef_to_enu(lat * D, lon * D)
        l_n, p_n = Ce @ l_e, Ce @ p_e
        # antenna z_v: the body z axis made perpendicular to the beam (it lies in the plane of the
        # azimuth axis and the beam, on the azimuth-axis side)
        zb_n = C[:, 2]
        z_v = zb_n - (zb_n @ l_n) * l_n
        z_v /= np.linalg.norm(z_v)
        pol = np.degrees(np.arctan2(np.cross(z_v, p_n) @ l_n, z_v @ p_n))
        pol = (pol + 90.0) % 180.0 - 90.0
        if pol == -90.0:
            pol = 90.0
        assert np.degrees(_wrap(2 * (r["polarization_deg"] - pol) * D)) / 2 == pytest.approx(0.0, abs=1e-8)
        rh = servo_angles(lat, lon, 10.0, *rph, sat_lon, polarization="horizontal")
        dp = (rh["polarization_deg"] - r["polarization_deg"]) % 180.0
        assert dp == pytest.approx(90.0, abs=1e-9)
        assert -90.0 < r["polarization_deg"] <= 90.0 and -90.0 < rh["polarization_deg"] <= 90.0
        assert rh["azimuth_deg"] == r["azimuth_deg"] and rh["elevation_deg"] == r["elevation_deg"]
    with pytest.raises(ValueError):
        servo_angles(0, 0, 0, 0, 0, 0, 10, polarization="circular")


def test_beam_points_at_satellite_and_roll_pitch():
    lat, lon, h, sat_lon = 39.9, 116.4, 0.0, 110.5
    for rph in [(10.0, 0.0, 0.0), (0.0, 10.0, 45.0), (-7.0, 4.0, 200.0)]:
        r = servo_angles(lat, lon, h, *rph, sat_lon)
        C = dcm_from_euler(*(np.array(rph) * D))
        b_n = C @ beam_body(r["azimuth_deg"] * D, r["elevation_deg"] * D)
        l_n = los_enu(lat * D, lon * D, h, geo_sat_ecef(sat_lon * D))
        assert np.degrees(np.arccos(min(1.0, b_n @ l_n / np.linalg.norm(l_n)))) < 1e-6
    # pitch nose up by 10 deg heading South toward the satellite (on the meridian): el drops by 10 deg
    r0 = servo_angles(lat, 110.5, h, 0, 0, 180.0, sat_lon)
    r1 = servo_angles(lat, 110.5, h, 0, 10.0, 180.0, sat_lon)
    assert r0["azimuth_deg"] == pytest.approx(0.0, abs=1e-9) or r0["azimuth_deg"] == pytest.approx(360.0)
    assert r1["elevation_deg"] == pytest.approx(r0["elevation_deg"] - 10.0, abs=1e-9)


# ----------------------------------------------------------------------------------------- Jacobians
def _frame_to(u):
    """A rotation whose second column is the unit vector u (any completion)."""
    u = u / np.linalg.norm(u)
    a = np.array([1.0, 0, 0]) if abs(u[0]) < 0.9 else np.array([0, 0, 1.0])
    x = np.cross(u, a)
    x /= np.linalg.norm(x)
    z = np.cross(x, u)
    return np.column_stack([x, u, z])


def _geometry(rng, el_body_deg):
    """Random site, satellite and an attitude that puts the satellite at the given body elevation."""
    lat, lon = rng.uniform(-75, 75) * D, rng.uniform(-180, 180) * D
    h = rng.uniform(-100, 5000)
    sat = geo_sat_ecef(lon + rng.uniform(-70, 70) * D)
    r_n = los_enu(lat, lon, h, sat)
    az_b = rng.uniform(0, 2 * np.pi)
    r_b_dir = beam_body(az_b, el_body_deg * D)
    # C_b^n r_b_dir ∥ r_n: map the body direction onto the nav direction, then spin about it randomly
    Rb = _frame_to(r_b_dir)
    Rn = _frame_to(r_n)
    spin = dcm_from_rotvec(r_n / np.linalg.norm(r_n) * rng.uniform(0, 2 * np.pi))
    Cbn = spin @ Rn @ Rb.T
    return lat, lon, h, Cbn, sat


def _f(lat, lon, h, Cbn, sat, phi=np.zeros(3), dP=np.zeros(3)):
    """Nonlinear (az, el) with the computed attitude (I − [φ×])C (an exact rotation), position P + δP."""
    C = dcm_from_rotvec(-np.asarray(phi)) @ Cbn
    return np.array(pointing_az_el(lat + dP[0], lon + dP[1], h + dP[2], C, sat))


@pytest.mark.parametrize("el_body", [-5.0, 0.3, 12.0, 45.0, 80.0, 89.5, 89.95])
def test_jacobians_against_finite_differences(el_body):
    rng = np.random.default_rng(int(el_body * 100) % 9973)
    for _ in range(8):
        lat, lon, h, Cbn, sat = _geometry(rng, el_body)
        az, el, Hphi, Hpos = az_el_jacobians(lat, lon, h, Cbn, sat)
        assert np.degrees(el) == pytest.approx(el_body, abs=1e-8)
        assert np.allclose([az, el], _f(lat, lon, h, Cbn, sat))
        # step scaled with the distance of the LOS from the body z axis (az is singular at the zenith)
        s = np.cos(el)
        ea = 1e-6 * s
        for j in range(3):
            e = np.zeros(3)
            e[j] = ea
            d = _f(lat, lon, h, Cbn, sat, phi=e) - _f(lat, lon, h, Cbn, sat, phi=-e)
            d[0] = _wrap(d[0])
            fd = d / (2 * ea)
            np.testing.assert_allclose(Hphi[:, j], fd, rtol=1e-5, atol=1e-7 * np.abs(Hphi).max())
        steps = [100.0 * s / earth.A, 100.0 * s / earth.A, 100.0 * s]  # δL, δλ [rad] (~100 m·s), δh [m]
        for j in range(3):
            e = np.zeros(3)
            e[j] = steps[j]
            d = _f(lat, lon, h, Cbn, sat, dP=e) - _f(lat, lon, h, Cbn, sat, dP=-e)
            d[0] = _wrap(d[0])
            fd = d / (2 * steps[j])
            tol = 1e-6 * np.abs(Hpos[:, j]).max() + 1e-18
            np.testing.assert_allclose(Hpos[:, j], fd, rtol=1e-4, atol=tol)


def test_jacobian_A_and_seed000_form():
    """A is the exact Jacobian of (az, el) in r_b; H_phi = −A C_n^b [r_n×] (§1.1 eq. 26)."""
    rng = np.random.default_rng(11)
    for _ in range(20):
        r = rng.normal(size=3) * 1e7
        Aj = az_el_jacobian_rb(r)
        for j in range(3):
            e = np.zeros(3)
            e[j] = 1.0
            d = np.array(az_el_from_body(r + e)) - np.array(az_el_from_body(r - e))
            d[0] = _wrap(d[0])
            np.testing.assert_allclose(Aj[:, j], d / 2, rtol=1e-6, atol=1e-16)
    # seed 000 case: static at 116E 39N, heading 100, GEO at 138E (seed's radius)
    lat, lon, C = 39 * D, 116 * D, dcm_from_euler(0.0, 0.0, 100 * D)
    sat = geo_sat_ecef(138 * D, R_GEO_SEED000)
    az, el, Hphi, Hpos = az_el_jacobians(lat, lon, 0.0, C, sat)
    r_n = los_enu(lat, lon, 0.0, sat)
    rx = np.array([[0, -r_n[2], r_n[1]], [r_n[2], 0, -r_n[0]], [-r_n[1], r_n[0], 0]])
    np.testing.assert_allclose(Hphi, -az_el_jacobian_rb(C.T @ r_n) @ C.T @ rx, atol=1e-15)
    # 100 m of position error moves the angles by far less than 0.05 deg (the seed's conclusion)
    rm, rn = earth.radii(lat)
    dP = np.array([100 / rm, 100 / (rn * np.cos(lat)), 100.0])
    assert np.degrees(np.abs(Hpos @ dP)).max() < 0.005


def test_servo_kernel_matches_python_wrapper():
    C = dcm_from_euler(2 * D, -3 * D, 250 * D)
    sat = geo_sat_ecef(87.5 * D)
    az, el, pol = servo_angles_rad(25 * D, 100 * D, 300.0, C, sat, False)
    r = servo_angles(25, 100, 300.0, 2, -3, 250, 87.5)
    assert np.degrees([az, el, pol]) == pytest.approx([r["azimuth_deg"], r["elevation_deg"],
                                                       r["polarization_deg"]], abs=1e-10)
