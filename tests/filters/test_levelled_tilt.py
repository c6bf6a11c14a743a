"""The start tilt of a levelled (static coarse) alignment is what the accelerometer errors do to the
measured specific force (issue 35/40, :func:`aidnav.filters.prior.levelled_tilt_covariance`). Known
answer against the simulator: a static IMU corrupted by :func:`aidnav.sim.imu.corrupt_imu` with a
consumer grade's realised bias, scale factors and misalignments (no noise), levelled as ``aidnav tight``
levels it; the tilt error predicted from the realised constants through the prior's covariance (the
regression of the tilt on the accelerometer states, A = P_tx P_xx⁻¹) must equal the levelling's actual
tilt error to second order."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.data import ImuData
from aidnav.filters.ins_errors import BA, MA, MIS_IN, MIS_OUT, SA
from aidnav.filters.prior import levelled_tilt_covariance
from aidnav.nav.rotations import dcm_from_euler
from aidnav.sim.imu import ImuSpec, corrupt_imu

G = 9.80665
ACC = np.r_[BA:BA + 3, SA:SA + 3, MA:MA + 6]  # the accelerometer states of the 33-state block


def _phi(c_est, c_true):
    """φ of C_est = (I − [φ×]) C_true (the filter's convention, computed − true)."""
    s = np.eye(3) - c_est @ c_true.T
    return 0.5 * np.array([s[2, 1] - s[1, 2], s[0, 2] - s[2, 0], s[1, 0] - s[0, 1]])


@pytest.mark.parametrize("seed,rph_deg", [(1, (3.0, -2.0, 20.0)), (2, (-1.0, 4.0, 250.0)),
                                          (3, (0.0, 0.0, 90.0))])
def test_levelling_tilt_is_the_accelerometer_errors_through_the_prior(seed, rph_deg):
    rph = np.radians(rph_deg)
    c_true = dcm_from_euler(*rph)
    n, dt = 200, 0.01
    dv = np.tile(c_true.T @ np.array([0.0, 0.0, G]) * dt, (n, 1))
    imu = ImuData(np.arange(1, n + 1) * dt, np.zeros((n, 3)), dv, t0=0.0)
    spec = ImuSpec.from_config({"grade": "consumer", "arw_deg_sqrt_h": 0.0, "vrw_m_s_sqrt_h": 0.0,
                                "accel_bias_instability_ug": 0.0, "gyro_bias_instability_deg_h": 0.0})
    meas, real = corrupt_imu(imu, spec, np.random.default_rng(seed))
    f = meas.dv.sum(axis=0) / (n * dt)
    roll, pitch = np.arctan2(-f[0], f[2]), np.arctan2(f[1], np.hypot(f[0], f[2]))  # as aidnav tight levels
    c_est = dcm_from_euler(roll, pitch, rph[2])
    phi = _phi(c_est, c_true)
    assert np.degrees(np.abs(phi[:2])).max() > 0.2  # a tilt error worth predicting

    x = np.zeros(33)
    x[BA:BA + 3] = real["accel_bias"]
    x[SA:SA + 3] = real["accel_scale"]
    x[MA:MA + 6] = [real["accel_misalignment"][o, i] for o, i in zip(MIS_OUT, MIS_IN, strict=True)]
    sig = np.r_[np.full(3, 0.03), np.full(3, 0.1), np.full(3, 1.0), np.full(3, 1e-3), np.full(3, 0.1),
                np.full(3, 1e-3), np.full(3, 5e-3), np.full(6, 1e-2), np.full(6, 1e-2)]
    P0 = np.diag(sig ** 2)
    sw = 1e-4
    P = levelled_tilt_covariance(P0, 33, f, c_est, sw)
    t = [0, 1]
    A = P[np.ix_(t, ACC)] @ np.linalg.inv(P[np.ix_(ACC, ACC)])
    pred = A @ x[ACC]
    # to second order: the products of the ~1e-2 errors (tilt, misalignments) are ~1 % of the tilt; a
    # wrong sign leaves 200 %, a transposed misalignment tens of %
    assert np.linalg.norm(pred - phi[:2]) <= 0.03 * np.linalg.norm(phi[:2]), (pred, phi[:2])
    # the tilt's variance: the accelerometer states' image plus the levelling's own σ_w²; P stays a
    # covariance; the heading row and every other state untouched
    image = A @ P[np.ix_(ACC, ACC)] @ A.T
    np.testing.assert_allclose(P[np.ix_(t, t)] - image, sw ** 2 * np.eye(2), atol=1e-14)
    np.testing.assert_allclose(P, P.T)
    assert np.linalg.eigvalsh(P).min() > 0
    rest = np.r_[2:33]
    np.testing.assert_array_equal(P[np.ix_(rest, rest)], P0[np.ix_(rest, rest)])
    # the independent σ it replaces would say the tilt has nothing to do with the accelerometers
    assert np.all(np.abs(P[np.ix_(t, ACC)]).max(axis=1) > 0)


def test_a_bias_only_block_holds_the_bias_part():
    """15 states: the tilt is correlated with the bias alone, g·φ_N = (C ∇)_E, g·φ_E = −(C ∇)_N."""
    c = dcm_from_euler(0.0, 0.0, 0.0)
    f = np.array([0.0, 0.0, G])
    P = levelled_tilt_covariance(np.diag(np.full(15, 1e-4)), 15, f, c, 0.0)
    np.testing.assert_allclose(P[0, BA:BA + 3], [0.0, -1e-4 / G, 0.0])
    np.testing.assert_allclose(P[1, BA:BA + 3], [1e-4 / G, 0.0, 0.0])
    np.testing.assert_allclose(np.diag(P)[:2], 1e-4 / G ** 2)


def test_the_loose_filter_keeps_the_levelled_tilt_at_rest():
    """The loose filter's static start (issue 35, session 14): the tilt σ at the end of a 30-s standstill
    is the levelling's, √(σ_∇² + (σ_m g)²)/g with the model's accelerometer bias and misalignment σ (the
    MEMS grade's row: 0.115°), and covers the error the realised constants leave. Before, the levelling's
    tilt was given an independent σ of that size and the ZUPTs at rest, observing g·φ + ∇ + M·g again,
    shrank it by up to √2 (0.08–0.09° on the consistency matrix's MEMS seeds, errors to 0.37°)."""
    from aidnav.filters.config import DEFAULT_IMU, LooseConfig  # lazy: the loose filter, only this test
    from aidnav.filters.grade import grade_models  # lazy: only this test
    from aidnav.filters.loose import run_loose  # lazy: only this test
    from aidnav.filters.result import to_trajectory  # lazy: only this test
    from aidnav.sim.run import simulate  # lazy: only this test
    from aidnav.sim.scenario import parse_scenario  # lazy: only this test

    mems = dict(grade_models()[2][1])
    imu = {**DEFAULT_IMU, **mems, "grade_from_static": False}
    want = np.hypot(mems["accel_bias_sigma_ug"] * 1e-6 * G, np.radians(mems["accel_misalignment_sigma_deg"])
                    * G) / G
    for seed in (1, 6):
        scn = parse_scenario({"name": "rest", "seed": seed, "imu_rate_hz": 100,
                              "initial": {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 50.0,
                                          "heading_deg": 20.0},
                              "segments": [{"type": "static", "duration_s": 30},
                                           {"type": "accelerate", "duration_s": 10, "to_speed_m_s": 10}],
                              "sensors": {"imu": {"grade": "mems"}, "gnss": {"rate_hz": 1.0}}})
        sim = simulate(scn, seed)
        tr = to_trajectory(run_loose(sim.imu, sim.gnss, LooseConfig(imu=imu)))
        k = np.searchsorted(tr.time, 28.0)
        sig = tr.std_att[k, :2]
        assert np.all(sig >= 0.95 * want) and np.all(sig <= 1.1 * want), (np.degrees(sig), np.degrees(want))
        j = np.searchsorted(sim.truth.time, tr.time[k])
        err = tr.rph[k, :2] - sim.truth.rph[j, :2]
        assert np.all(np.abs(err) <= 3.0 * sig), (seed, np.degrees(err), np.degrees(sig))
