"""The numpy twins of :mod:`aidnav.nav.plain` give the numbers of the numba functions they copy."""

from __future__ import annotations

import numpy as np

from aidnav.nav import earth, plain, rotations


def test_constants_are_earths():
    assert (plain.A, plain.F, plain.E2) == (earth.A, earth.F, earth.E2)


def test_lla_to_enu_and_wraps_match_the_kernels():
    rng = np.random.default_rng(5)
    lat = rng.uniform(-1.5, 1.5, 200)
    lon = rng.uniform(-np.pi, np.pi, 200)
    h = rng.uniform(-100.0, 2e4, 200)
    for i in (0, 17, 150):
        got = plain.lla_to_enu(lat, lon, h, lat[i], lon[i], h[i])
        want = earth.lla_to_enu(lat, lon, h, lat[i], lon[i], h[i])
        np.testing.assert_allclose(np.array(got), np.array(want), rtol=0, atol=1e-6)
        np.testing.assert_allclose(np.array(got)[:, i], 0.0, atol=1e-6)
    np.testing.assert_array_equal(plain.dcm_ecef_to_enu(0.3, -1.2), earth.dcm_ecef_to_enu(0.3, -1.2))
    a = np.concatenate([rng.uniform(-50.0, 50.0, 300), [-np.pi, np.pi, 0.0, 2 * np.pi]])
    np.testing.assert_array_equal(plain.wrap_pi(a), rotations.wrap_pi(a))
    d = np.concatenate([rng.uniform(-2000.0, 2000.0, 300), [-360.0, 0.0, 360.0, -1e-14, 720.0]])
    np.testing.assert_array_equal(plain.wrap_360(d), rotations.wrap_360(d))
