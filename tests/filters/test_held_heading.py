"""The states a fix cannot inform while the heading is held unknown (issue 35, p35h): the time offset,
velocity delay and GNSS lever arm are considered, not estimated (``filters.held_heading``)."""

import numpy as np

from aidnav.filters.held_heading import consider_states, considered_states
from aidnav.filters.layout import L_LEVER, L_N, L_TOFF, L_VDEL


def test_considered_states_name_the_time_states_and_the_lever_arm():
    lay = np.full(16, -1, np.int64)
    lay[L_N], lay[L_TOFF], lay[L_VDEL], lay[L_LEVER] = 32, 30, 31, 27
    assert considered_states(lay, 0) == (30, 31, 27, 28, 29)
    assert considered_states(lay, 12) == (-1, -1, -1, -1, -1)  # a state subset: none
    lay[L_LEVER] = -1
    assert considered_states(lay, 0) == (30, 31, -1, -1, -1)


def test_a_considered_state_keeps_its_block_and_goes_into_r():
    """Known answer: states 0, 1 estimated, 2, 3 considered. Their correlations with 0, 1 are zeroed, their
    own 2×2 block (with its correlation) kept, R grows by H_c P_cc H_cᵀ and their H columns are zeroed — so
    a Kalman update with the result leaves them (estimate and covariance) as they are."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(4, 4))
    P = A @ A.T + np.eye(4)
    Pcc = P[2:, 2:].copy()
    H = rng.normal(size=(2, 4))
    R = np.diag([0.5, 0.7])
    Hc = H[:, 2:].copy()
    consider_states(H, R, 2, P, (2, 3, -1, -1, -1))
    np.testing.assert_array_equal(P[2:, :2], 0.0)
    np.testing.assert_array_equal(P[:2, 2:], 0.0)
    np.testing.assert_array_equal(P[2:, 2:], Pcc)
    np.testing.assert_allclose(R, np.diag([0.5, 0.7]) + Hc @ Pcc @ Hc.T, rtol=1e-12)
    np.testing.assert_array_equal(H[:, 2:], 0.0)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    np.testing.assert_array_equal(K[2:], 0.0)  # the considered states take no gain


def test_the_held_start_does_not_learn_the_lever_arm_nor_collapse_the_tilt():
    """The consistency matrix's 1 Hz white car run, seed 9, the pedestrian preset (no NHC): the heading is
    held unknown over the 30-s start at rest (σ 180°). Before this change the held heading's wander turned
    C_b^n l while the antenna stood still, the lever σ fell 0.30 → 0.10 m with correlations to the tilt
    and accelerometer bias, and the first fix after the course alignment (31 s) took the tilt σ from
    0.56/0.61° to 0.21/0.20° against a 1.1° pitch error. Now the lever arm keeps its prior until the
    alignment and the tilt σ stays what the start's rest gave it (≈ 0.7°) through the next fix."""
    from aidnav.experiments import consistency_matrix as cm  # lazy: the matrix's run (experiments layer)
    from aidnav.filters.loose import run_loose  # lazy: with the matrix's run

    cond = cm.condition("gnss 1 Hz white")
    run = cm.simulate_condition(cond, 9)
    cfg = cm.choose_gnss_errors(run.imu, run.gnss, cm.config_for("pedestrian", cond, run, True), None, [])
    res = run_loose(run.imu, run.gnss, cfg, cov_times=np.array([29.9, 32.01]))
    il = list(res.state_names).index("lever_arm_x")
    sig = np.sqrt(np.diagonal(res.cov, axis1=1, axis2=2))
    np.testing.assert_allclose(sig[0, il:il + 3], cfg.calibration.lever_arm_sigma_m, rtol=1e-9)
    assert np.all(np.degrees(sig[1, :2]) > 0.5), np.degrees(sig[1, :2])
