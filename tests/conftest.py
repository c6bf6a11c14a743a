"""Shared fixtures. Real data sets live outside the repository (never copied into it)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """Directory of the real data sets: $AIDNAV_DATA, else ``../shared/data`` beside the repository.

    Skips the test when the directory is absent. Tests needing one set should check it exists, e.g.
    ``d = data_dir / "rtklibexplorer_drive_0708"; if not d.is_dir(): pytest.skip(...)``.
    """
    d = Path(os.environ.get("AIDNAV_DATA", REPO_ROOT.parent / "shared" / "data"))
    if not d.is_dir():
        pytest.skip(f"real data not found at {d} (set AIDNAV_DATA to the data directory)")
    return d


# ------------------------------------------------------------------ loosely coupled filter tests
def _loose_error_state(res, truth, imu_errors, idx):
    """15-state error of a :class:`aidnav.filters.loose.LooseResult` against the simulation truth.

    res : LooseResult; truth : the IMU truth Trajectory (same time scale); imu_errors : the
    ``realised`` dict of :func:`aidnav.sim.imu.corrupt_imu` (constant biases only: no Gauss-Markov or
    random-walk drift in these tests); idx : indices into the result's outputs.
    Returns (len(idx), 15) in the filter's error state (``aidnav.filters.ins_errors``):
    φ [rad] with C_est = (I − [φ×]) C_true; δv = v_est − v_true [m/s]; δL, δλ [rad], δh [m] est − true;
    gyro/accel bias residual = true bias − estimated bias [rad/s, m/s²] (the filter's bias states are
    what remains in the compensated measurement, fed back as b̂ += ε̂; the opposite sign does not
    match the filter's cross-covariances).
    """
    import numpy as np

    from aidnav.nav.rotations import attitude_error_batch, euler_to_quat_batch

    idx = np.asarray(idx)
    t = res.time[idx]
    ti = np.searchsorted(truth.time, t)
    assert np.allclose(truth.time[ti], t, rtol=0, atol=1e-9), "outputs not on truth samples"
    st = res.state[idx]
    e = np.zeros((len(idx), 15))
    q_true = euler_to_quat_batch(np.ascontiguousarray(truth.rph[ti]))
    e[:, 0:3] = attitude_error_batch(np.ascontiguousarray(st[:, 6:10]), q_true)
    e[:, 3:6] = st[:, 3:6] - truth.vel[ti]
    e[:, 6] = st[:, 0] - truth.lat[ti]
    e[:, 7] = (st[:, 1] - truth.lon[ti] + np.pi) % (2 * np.pi) - np.pi
    e[:, 8] = st[:, 2] - truth.height[ti]
    e[:, 9:12] = imu_errors["gyro_bias"] - res.bias[idx, 0:3]
    e[:, 12:15] = imu_errors["accel_bias"] - res.bias[idx, 3:6]
    return e


@pytest.fixture(scope="session")
def loose_error_state():
    """The function :func:`_loose_error_state` (res, truth, imu_errors, idx) → (K, 15) errors."""
    return _loose_error_state


def _position_error_m(res, truth, idx):
    """(K, 3) ENU position error [m] (estimate − truth) and its (K, 3) 1σ from ``res.pdiag``."""
    import numpy as np

    from aidnav.nav.earth import lla_difference_enu, radii

    idx = np.asarray(idx)
    ti = np.searchsorted(truth.time, res.time[idx])
    st = res.state[idx]
    de, dn, du = lla_difference_enu(st[:, 0], st[:, 1], st[:, 2], truth.lat[ti], truth.lon[ti],
                                    truth.height[ti])
    rm, rn = radii(st[:, 0])
    pd = res.pdiag[idx]
    sig = np.sqrt(np.column_stack([pd[:, 7] * ((rn + st[:, 2]) * np.cos(st[:, 0])) ** 2,
                                   pd[:, 6] * (rm + st[:, 2]) ** 2, pd[:, 8]]))
    return np.column_stack([de, dn, du]), sig


@pytest.fixture(scope="session")
def position_error_m():
    """The function :func:`_position_error_m` (res, truth, idx) → (ENU error [m], ENU 1σ [m])."""
    return _position_error_m
