"""check_solution (the last check before a solution is written): known answers, and the kernel's jump
test against the whole-array formula it replaced (issue 29: one pass over the rows)."""

import numpy as np
import pytest

from aidnav.apps.common import MAX_PLAUSIBLE_SPEED_M_S, MIN_JUMP_M, check_solution
from aidnav.data import Trajectory
from aidnav.errors import DivergenceError
from aidnav.nav.earth import lla_difference_enu


def _traj(n=500, seed=0):
    rng = np.random.default_rng(seed)
    t = 100.0 + 0.01 * np.arange(n)
    lat = np.radians(30.0) + 1e-7 * np.cumsum(rng.normal(size=n))
    lon = np.radians(114.0) + 1e-7 * np.cumsum(rng.normal(size=n))
    return Trajectory(t, lat, lon, 50.0 + rng.normal(size=n), rng.normal(size=(n, 3)),
                      rng.uniform(0, 1, (n, 3)), std_pos=np.full((n, 3), 0.5))


def test_good_solution_passes():
    check_solution(_traj())


def test_nan_names_first_epoch_and_count():
    tr = _traj()
    tr.vel[120, 1] = np.nan
    tr.rph[300, 2] = np.inf
    with pytest.raises(DivergenceError, match=r"NaN/inf in the solution from t=101\.200 s \(2 samples\)"):
        check_solution(tr, "x")


def test_jump_names_the_step():
    tr = _traj()
    tr.lat[250:] += 20_000.0 / 6.37e6  # 20 km × R_M(30°) / 6370 km ≈ 19.94 km north in one 10-ms step
    with pytest.raises(DivergenceError, match=r"jumps 1994\d\.\d m in 0\.010 s at t=102\.500 s"):
        check_solution(tr, "x")


def test_sigma_beyond_limit():
    tr = _traj()
    tr.std_pos[400, 0] = 2e5
    with pytest.raises(DivergenceError, match=r"position σ 2e\+05 m at t=104\.000 s"):
        check_solution(tr, "x")


def test_jump_index_as_the_whole_array_formula():
    """The first jump over random steps near both thresholds, longitude wrapping at ±π included."""
    from aidnav.apps.check_kernels import first_jump

    rng = np.random.default_rng(2)
    n = 20000
    t = np.cumsum(rng.uniform(0.0, 5.0, n))
    t[rng.integers(0, n, 50)] = np.nan
    lat = rng.uniform(-1.5, 1.5, n)
    lon = np.where(rng.uniform(size=n) < 0.5, np.pi - 1e-4, -np.pi + 1e-4) + rng.normal(0, 1e-3, n)
    h = rng.normal(0, 1e4, n)
    for _ in range(200):
        a = rng.integers(0, n - 1)
        de, dn, du = lla_difference_enu(lat[1:], lon[1:], h[1:], lat[:-1], lon[:-1], h[:-1])
        step = np.sqrt(de**2 + dn**2 + du**2)
        sp = step / np.maximum(np.diff(t), 1e-9)
        jump = np.flatnonzero((sp > MAX_PLAUSIBLE_SPEED_M_S) & (step > MIN_JUMP_M))
        i, st, dt = first_jump(t, lat, lon, h, MAX_PLAUSIBLE_SPEED_M_S, MIN_JUMP_M)
        assert i == (jump[0] if len(jump) else -1)
        if i >= 0:
            assert st == step[i] and dt == t[i + 1] - t[i]
        t, lat, lon, h = t[a:], lat[a:], lon[a:], h[a:]
        if len(t) < 3:
            break
