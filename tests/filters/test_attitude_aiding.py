"""INS aided by sparse attitude fixes (aidnav.filters.attitude_aiding)."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.data import ImuData
from aidnav.filters.attitude_aiding import fuse_attitude_fixes, imu_noise_psd, initial_covariance_15
from aidnav.nav.rotations import dcm_from_euler, dcm_from_quat, quat_from_dcm, rotvec_from_dcm, skew
from aidnav.nav.strapdown import make_state, mechanize
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.motion import generate, half_widths

D = np.pi / 180.0


@pytest.fixture(scope="module")
def flight():
    """120 s of level coordinated flight at 100 m/s with alternating turns (bank ±15°), 100 Hz."""
    tb = np.arange(0.0, 120.0, 20.0)
    vals = np.zeros((len(tb), 3))
    vals[:, 1] = np.where(np.arange(len(tb)) % 2 == 0, 1.5 * D, -1.0 * D)
    tr, dth, dv = generate(tb, half_widths(tb, 4.0), vals, np.array([0.56, 2.07, 1000.0, 100.0, 0.3, 0.0]),
                           0.0, 0.01, 12000)
    imu = ImuData(time=tr[1:, 0].copy(), dtheta=dth, dv=dv, t0=0.0)
    C = np.array([dcm_from_euler(*r) for r in tr[:, 7:10]])
    return tr, imu, C


def _errors(states, C_true):
    return np.array([rotvec_from_dcm(np.ascontiguousarray(C_true[k] @ dcm_from_quat(states[k, 6:10]).T))
                     for k in range(len(states))])


def _fixes(tr, C, rng, sigma, period=5.0):
    idx = np.arange(int(round(period / 0.01)), len(tr), int(round(period / 0.01)))
    Cf = []
    for k in idx:
        e = rng.standard_normal(3) * sigma
        Cf.append(dcm_from_quat(quat_from_dcm((np.eye(3) - skew(e)) @ C[k])))
    return tr[idx, 0], np.array(Cf), np.tile(np.eye(3) * sigma**2, (len(idx), 1, 1))


def test_free_ins_equals_strapdown(flight):
    tr, imu, C = flight
    st0 = make_state(tr[0, 1], tr[0, 2], tr[0, 3], tr[0, 4:7], quat_from_dcm(C[0]))
    q = imu_noise_psd(0.3, 0.1, 1.0, 10.0, 3600.0)
    P0 = initial_covariance_15(1 * D, 0.1, 1.0, 50.0, 1000.0, tr[0, 1], tr[0, 3])
    res = fuse_attitude_fixes(imu, st0, [], np.zeros((0, 3, 3)), np.zeros((0, 3, 3)), q, P0)
    ref = mechanize(imu.time, imu.dtheta, imu.dv, st0, 0.0, np.zeros(0), np.zeros(0))
    np.testing.assert_allclose(res.states, ref, rtol=0, atol=1e-12)
    # the free INS covariance grows
    assert np.all(res.std_att[-1] > res.std_att[0])


def test_exact_fixes_keep_the_truth(flight):
    tr, imu, C = flight
    st0 = make_state(tr[0, 1], tr[0, 2], tr[0, 3], tr[0, 4:7], quat_from_dcm(C[0]))
    q = imu_noise_psd(0.3, 0.1, 1.0, 10.0, 3600.0)
    P0 = initial_covariance_15(1 * D, 0.1, 1.0, 50.0, 1000.0, tr[0, 1], tr[0, 3])
    ft, Cf, Rf = _fixes(tr, C, np.random.default_rng(0), 0.0)
    res = fuse_attitude_fixes(imu, st0, ft, Cf, Rf + np.eye(3) * 1e-12, q, P0)
    err = _errors(res.states, C[1:])
    assert np.max(np.abs(err)) < 1e-8


def test_fixes_bound_the_attitude_error(flight):
    """Low-grade INS (50 deg/h, 1 mg): with fixes every 5 s (σ 0.5°) the attitude error stays bounded and
    consistent with the filter's σ, while the free INS drifts."""
    tr, imu_true, C = flight
    rng = np.random.default_rng(7)
    spec = ImuSpec.from_units(gyro_bias_deg_h=50.0, arw_deg_sqrt_h=0.3, accel_bias_ug=1000.0,
                              vrw_m_s_sqrt_h=0.1)
    q = imu_noise_psd(0.3, 0.1, 1.0, 10.0, 3600.0)
    P0 = initial_covariance_15(1 * D, 0.1, 1.0, 50.0, 1000.0, tr[0, 1], tr[0, 3])
    sig = 0.5 * D
    end_ins, end_fused, z2 = [], [], []
    for _ in range(3):
        imu, _ = corrupt_imu(imu_true, spec, rng)
        e0 = rng.standard_normal(3) * D
        st0 = make_state(tr[0, 1], tr[0, 2], tr[0, 3], tr[0, 4:7],
                         quat_from_dcm((np.eye(3) - skew(e0)) @ C[0]))
        ft, Cf, Rf = _fixes(tr, C, rng, sig)
        hold = (tr[1:, 3].copy(), tr[1:, 6].copy())
        fused = fuse_attitude_fixes(imu, st0, ft, Cf, Rf, q, P0, hold_h=hold[0], hold_vu=hold[1])
        ins = fuse_attitude_fixes(imu, st0, ft, Cf, Rf, q, P0, hold_h=hold[0], hold_vu=hold[1],
                                  use_fixes=False)
        ef = _errors(fused.states, C[1:])
        ei = _errors(ins.states, C[1:])
        late = imu.time > 10.0
        assert np.max(np.abs(ef[late])) < 4 * sig  # bounded between fixes
        assert np.all(fused.fix_accepted)
        end_ins.append(np.linalg.norm(ei[-1]))
        end_fused.append(np.linalg.norm(ef[-1]))
        z2.append(np.mean((ef[late] / fused.std_att[late]) ** 2))
    assert min(end_ins) > 2 * max(end_fused)
    assert np.mean(end_ins) > 1.0 * D  # the free INS drifts by degrees in 2 minutes
    assert 0.3 < np.mean(z2) < 2.5  # filter σ consistent with the errors


def test_smoother_on_attitude_fixes(flight):
    """The engine's RTS pass on the attitude-aided INS (fixes every 5 s, σ 0.5°, 50 deg/h gyro): the
    smoothed attitude RMS is below the forward one, its σ never above the forward σ, and the smoothed
    errors are consistent with the smoothed σ (mean of (e/σ)² within [0.3, 2.5], as the forward test)."""
    tr, imu_true, C = flight
    rng = np.random.default_rng(11)
    spec = ImuSpec.from_units(gyro_bias_deg_h=50.0, arw_deg_sqrt_h=0.3, accel_bias_ug=1000.0,
                              vrw_m_s_sqrt_h=0.1)
    q = imu_noise_psd(0.3, 0.1, 1.0, 10.0, 3600.0)
    P0 = initial_covariance_15(1 * D, 0.1, 1.0, 50.0, 1000.0, tr[0, 1], tr[0, 3])
    imu, _ = corrupt_imu(imu_true, spec, rng)
    e0 = rng.standard_normal(3) * D
    st0 = make_state(tr[0, 1], tr[0, 2], tr[0, 3], tr[0, 4:7], quat_from_dcm((np.eye(3) - skew(e0)) @ C[0]))
    ft, Cf, Rf = _fixes(tr, C, rng, 0.5 * D)
    res = fuse_attitude_fixes(imu, st0, ft, Cf, Rf, q, P0, hold_h=tr[1:, 3].copy(), hold_vu=tr[1:, 6].copy(),
                              smooth=True)
    assert res.smoothed and res.forward_states is not None
    late = imu.time > 10.0
    es = _errors(res.states, C[1:])[late]
    ef = _errors(res.forward_states, C[1:])[late]
    print(f"\nattitude RMS forward {np.degrees(np.sqrt(np.mean(ef ** 2))):.3f} deg, smoothed "
          f"{np.degrees(np.sqrt(np.mean(es ** 2))):.3f} deg")
    assert np.sqrt(np.mean(es ** 2)) < np.sqrt(np.mean(ef ** 2))
    assert np.all(res.std_att <= res.forward_std_att * (1 + 1e-9))
    assert 0.3 < np.mean((es / res.std_att[late]) ** 2) < 2.5
