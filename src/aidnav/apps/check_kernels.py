"""The per-row tests of :func:`aidnav.apps.common.check_solution` as numba kernels (one pass over the
rows, no temporaries; imported when a solution is checked, so that the light commands do not load numba)."""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.nav.earth import E2, A
from aidnav.nav.rotations import TWO_PI


@njit(cache=True, nogil=True)
def nonfinite_rows(lat, lon, h, vel, rph):
    """(number of rows with a NaN/inf in lat, lon, height, velocity or attitude, the first of them)."""
    n, first = 0, -1
    for k in range(lat.shape[0]):
        ok = np.isfinite(lat[k]) and np.isfinite(lon[k]) and np.isfinite(h[k])
        for j in range(vel.shape[1]):
            ok = ok and np.isfinite(vel[k, j])
        for j in range(rph.shape[1]):
            ok = ok and np.isfinite(rph[k, j])
        if not ok:
            n += 1
            if first < 0:
                first = k
    return n, first


@njit(cache=True, nogil=True)
def first_jump(time, lat, lon, h, max_speed, min_jump):
    """(i, step [m], Δt [s]) of the first step from epoch i to i + 1 faster than ``max_speed`` and longer
    than ``min_jump`` (i = −1: none); the step as :func:`aidnav.nav.earth.lla_difference_enu` gives it
    (radii at epoch i), the speed over max(Δt, 1e-9 s)."""
    for k in range(lat.shape[0] - 1):
        lr, hr = lat[k], h[k]
        sl = np.sin(lr)
        w2 = 1.0 - E2 * sl * sl
        w = np.sqrt(w2)
        rn = A / w
        rm = A * (1.0 - E2) / (w2 * w)
        dlon = (lon[k + 1] - lon[k] + np.pi) % TWO_PI - np.pi
        de = dlon * (rn + hr) * np.cos(lr)
        dn = (lat[k + 1] - lr) * (rm + hr)
        du = h[k + 1] - hr
        step = np.sqrt(de * de + dn * dn + du * du)
        dt = time[k + 1] - time[k]
        sp = step / (dt if (dt > 1e-9 or np.isnan(dt)) else 1e-9)
        if sp > max_speed and step > min_jump:
            return k, step, dt
    return -1, 0.0, 0.0
