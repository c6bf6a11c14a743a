"""GPS satellite math: broadcast-ephemeris orbit/clock, Klobuchar, Saastamoinen, nominal constellation, and
SPP on the walk data set against the RTK solution (an independent check of the ephemeris code)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from aidnav.nav.earth import lla_to_ecef
from aidnav.nav.gnss_sat import (
    C_LIGHT,
    dop,
    eccentric_anomaly,
    eph_state,
    klobuchar,
    saastamoinen_zenith,
    std_atmosphere,
    trop_mapping,
    tropo_delay,
)
from aidnav.sim.gnss_constellation import nominal_constellation, visible_satellites


@pytest.mark.parametrize("ecc", [0.0, 0.0104, 0.1, 0.3, 0.7])
def test_eccentric_anomaly_solves_keplers_equation(ecc):
    """The one Kepler solver of the Keplerian orbits against scipy's bracketed root of E − e sin E − M
    (E lies in [M − e, M + e]) for mean anomalies over (−π, π], and the closed forms: E = M for a circular
    orbit, E = 0 at M = 0 and E = π at M = π for any eccentricity."""
    for m in (-3.0, -1.2, -1e-3, 0.4, 1.0, 2.5, 3.1):
        ref = brentq(lambda e_, m=m: e_ - ecc * np.sin(e_) - m, m - ecc - 1e-9, m + ecc + 1e-9, xtol=1e-15,
                     rtol=4 * np.finfo(float).eps)
        ek = eccentric_anomaly(m, ecc)
        assert abs(ek - ref) < 1e-12, (m, ecc, ek, ref)
        assert abs(ek - ecc * np.sin(ek) - m) < 1e-14
    assert eccentric_anomaly(0.7, 0.0) == 0.7
    assert eccentric_anomaly(0.0, ecc) == 0.0
    assert abs(eccentric_anomaly(np.pi, ecc) - np.pi) < 1e-15


# a GPS LNAV record (G10 of the walk data set, 2025-08-28 18:00 GPST) in the column layout of gnss_sat
_G10 = np.array(
    [
        10,
        2381,
        410400.0,
        410400.0,
        -0.516209285706e-03,
        -0.818545231596e-11,
        0.0,
        0.515364910889e04,
        0.104180137860e-01,
        0.990331316097e00,
        0.121533091086e01,
        -0.231957460341e01,
        -0.226070087556e01,
        0.378730061342e-08,
        0.493591988659e-09,
        -0.750959851921e-08,
        -0.929459929466e-06,
        0.881403684616e-05,
        0.223000000000e03,
        -0.139687500000e02,
        0.160187482834e-06,
        -0.521540641785e-07,
        0.232830643654e-08,
        0.0,
        97.0,
        2.0,
        4.0,
    ]
)


def test_ephemeris_orbit_radius_velocity_and_clock_rates():
    t = 410400.0 - 1800.0
    p, v, dts, ddts = eph_state(_G10, t)
    a, e = _G10[7] ** 2, _G10[8]
    r = np.linalg.norm(p)
    assert a * (1 - e) - 200 < r < a * (1 + e) + 200  # harmonic corrections are < 1 km
    # analytic velocity and clock rate vs central differences
    h = 0.5
    p1, _, c1, _ = eph_state(_G10, t + h)
    p0, _, c0, _ = eph_state(_G10, t - h)
    np.testing.assert_allclose(v, (p1 - p0) / (2 * h), atol=2e-4)
    assert abs(ddts - (c1 - c0) / (2 * h)) < 1e-14
    # ECEF speed of a GPS satellite: ~3.9 km/s inertial minus Earth rotation
    assert 1500 < np.linalg.norm(v) < 4000
    # clock: af0 + af1 dt + relativistic term (|Δt_r| < 50 ns for e = 0.01)
    assert abs(dts - (_G10[4] + _G10[5] * (t - _G10[3]))) < 50e-9


def test_klobuchar_known_values():
    alpha = np.array([1e-8, 0.0, 0.0, 0.0])
    beta = np.array([9e4, 0.0, 0.0, 0.0])
    el = np.pi / 2
    f = 1.0 + 16.0 * (0.53 - 0.5) ** 3  # obliquity at the zenith
    # at the zenith the pierce point is the user; local time = t + 43200·λ/π; night: the 5 ns floor
    t_night = 2 * 3600.0  # 02:00 at λ = 0
    assert klobuchar(0.0, 0.0, 0.0, el, t_night, alpha, beta) == pytest.approx(C_LIGHT * 5e-9 * f, rel=1e-12)
    # 14:00 local time: the cosine peak, delay = F (5 ns + amplitude)
    assert klobuchar(0.0, 0.0, 0.0, el, 14 * 3600.0, alpha, beta) == pytest.approx(
        C_LIGHT * f * (5e-9 + 1e-8), rel=1e-12
    )
    # slant delays grow towards the horizon (F up to ~3)
    assert klobuchar(0.0, 0.0, 0.0, np.radians(5), 14 * 3600.0, alpha, beta) > 2.5 * C_LIGHT * 5e-9


def test_saastamoinen_known_values():
    # standard sea-level pressure at 45°: ZHD = 0.0022768 × 1013.25 = 2.3070 m
    zhd, zwd = saastamoinen_zenith(np.radians(45.0), 0.0, 1013.25, 288.15, 0.0)
    assert zhd == pytest.approx(2.30697, abs=1e-4)
    assert zwd == 0.0
    assert trop_mapping(np.pi / 2) == pytest.approx(1.0, abs=1e-6)
    assert trop_mapping(np.radians(5.0)) == pytest.approx(10.2, abs=0.1)
    p, t, e = std_atmosphere(0.0, 0.0)
    assert (p, t, e) == (pytest.approx(1013.25), pytest.approx(288.15), 0.0)
    assert tropo_delay(np.radians(45.0), 0.0, np.pi / 2, 0.0) == pytest.approx(2.30697, abs=1e-4)
    # with 70 % humidity at 15 °C the wet zenith delay is ~0.1 m; at 1 km the hydrostatic delay drops ~11 %
    assert 0.05 < tropo_delay(0.0, 0.0, np.pi / 2, 0.7) - tropo_delay(0.0, 0.0, np.pi / 2, 0.0) < 0.2
    assert tropo_delay(0.0, 1000.0, np.pi / 2, 0.0) / tropo_delay(0.0, 0.0, np.pi / 2, 0.0) == pytest.approx(
        0.887, abs=0.01
    )


def test_nominal_constellation_visibility_and_dop():
    eph = nominal_constellation(2381, 400000.0, 24)
    assert len(eph.table) == 24
    assert len(nominal_constellation(2381, 400000.0, 31).table) == 31
    for lat in (-60.0, 0.0, 34.0, 70.0):
        rx = np.array(lla_to_ecef(np.radians(lat), np.radians(10.0), 0.0))
        for dt in (0.0, 6 * 3600.0, 13 * 3600.0):
            prn, az, el = visible_satellites(eph, 400000.0 + dt, rx, 5.0)
            assert len(prn) >= 4
            assert np.all(np.diff(el) <= 0)
            u = np.column_stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])
            assert dop(u)["pdop"] < 10.0


def test_walk_spp_against_rtk(load_walk_gnss):
    """SPP of the walk data (4 GPS satellites with ephemeris, zero redundancy) within tens of metres of the
    RTK solution (Q = 1): an independent check of the broadcast orbits, clocks and the Sagnac term."""
    from aidnav.estimators.dgps import spp_series
    from aidnav.nav.earth import lla_difference_enu

    obs, nav, ref = load_walk_gnss()
    assert sorted(p for p in nav.prns if p < 100) == [10, 23, 27, 32]
    assert sorted(p for p in nav.prns if p >= 100) == [211, 221, 222, 234, 242, 243, 244, 250]  # C11 … C50
    assert abs(obs.time[0] - 408639.748) < 1e-9  # exact epoch (georinex alone truncates to µs)
    r = spp_series(obs, nav, iono="dual")
    assert "no redundancy: unchecked" in r["status"]
    j = np.clip(np.searchsorted(ref.time, obs.time), 0, len(ref) - 1)
    m = (np.abs(ref.time[j] - obs.time) < 0.01) & (ref.quality[j] == 1) & np.isfinite(r["lat"])
    assert m.sum() > 300
    e, n, u = lla_difference_enu(
        r["lat"][m], r["lon"][m], r["h"][m], ref.lat[j][m], ref.lon[j][m], ref.height[j][m]
    )
    hz = np.hypot(e, n)
    assert np.median(hz) < 20.0 and np.max(hz) < 40.0
    assert np.max(np.abs(u)) < 40.0
    # Doppler velocity against the RTK velocity
    dv = r["vel_enu"][m] - ref.vel[j][m]
    assert np.sqrt(np.nanmean(dv[:, :2] ** 2)) < 0.5
