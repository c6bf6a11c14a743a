"""Every measurement model's H against central finite differences of its own nonlinear function.

For a model z(nav) = h(INS state) − measured, the error state δx maps the computed state to the true
one through the engine's closed-loop feedback (:func:`aidnav.filters.engine.feedback`: C ← (I+[φ×])C,
v ← v − δv, p ← p − δp, b̂ ← b̂ + r). With the same measurement, z(computed) − z(true(δx)) ≈ H δx,
so column j of H is −(z(true(+ε e_j)) − z(true(−ε e_j))) / 2ε. Where a model takes the body rate
from the gyro-bias estimate (GNSS velocity lever arm, ZARU, pseudorange rate), the true state's rate
is the raw rate minus the true bias; the NHC and the odometer use the body rate as an input (their
lever-arm term has no gyro-bias column), so there the rate is held.

Tolerance: each entry within 1e-4 of the largest response of its column plus 1e-6 of the largest
response of its row (terms below that are second order: Earth-rate and transport-rate variations);
a wrong sign or a missing lever-arm, scale-factor or clock column is O(1) of its column.
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.filters import measurements as ms
from aidnav.filters.engine import feedback, node_rates
from aidnav.filters.layout import L_BARO, L_CLK, L_N, L_ODO, make_layout
from aidnav.filters.measurements.check import check_jacobian
from aidnav.nav.earth import lla_to_ecef
from aidnav.nav.rotations import dcm_from_euler, dcm_from_quat, quat_from_euler

LAY = make_layout(True, ("odometer_scale", "baro_bias", "clock"))  # 21 + 1 + 1 + 2 = 25 states
N = int(LAY[L_N])
W_RAW = np.array([0.05, -0.02, 0.3])  # raw body rate [rad/s]
STEPS = np.array([1e-4] * 3 + [1e-3] * 3 + [1e-7, 1e-7, 0.5] + [1e-4] * 3 + [1e-3] * 3 + [1e-4] * 6
                 + [1e-3, 0.1, 1.0, 0.1])


def _nominal():
    q = quat_from_euler(0.1, -0.05, 1.0)
    st = np.array([0.6, 2.0, 120.0, 12.0, -5.0, 0.8, *q])
    bias = np.zeros(N - 9)
    bias[0:3] = [1e-3, -2e-3, 5e-4]
    bias[LAY[L_ODO] - 9] = 0.02
    bias[LAY[L_BARO] - 9] = 3.0
    bias[LAY[L_CLK] - 9:LAY[L_CLK] - 7] = [150.0, 2.0]
    return st, bias


def _nav(st, bias, dt_back, rate_from_bias, bias_nominal):
    C = dcm_from_quat(st[6:10])
    b = bias if rate_from_bias else bias_nominal
    wb = W_RAW - b[0:3]
    w = np.zeros((4, 3))
    node_rates(st, wb, wb * 0.01, 0.01, w)
    return ms.Nav(st, C, w, dt_back, bias)


def _check(model, row, par, rate_from_bias=True, dt_back=0.0, allow=None):
    st0, b0 = _nominal()
    def nav_of(st, b):
        return _nav(st, b, dt_back, rate_from_bias, b0)

    return check_jacobian(model, row, par, LAY, st0, b0, nav_of,
                          STEPS, feedback, allow)


LEVER = np.array([0.4, 1.3, -0.9])


def _vehicle_par():
    p = np.zeros(16)
    V = ms.vehicle
    p[V.V_SIG], p[V.V_MIN_SPEED], p[V.V_LEVER:V.V_LEVER + 3] = 0.1, 1.0, LEVER
    p[V.V_CBV:V.V_CBV + 9] = dcm_from_euler(0.01, -0.02, 0.03).ravel()
    return p


def test_gnss_position_with_lever_arm_and_time_shift():
    H, R, _ = _check(ms.gnss_position_model, np.array([0.6, 2.0, 100.0, 1.0, 2.0, 3.0]), LEVER,
                     dt_back=0.2)
    assert np.allclose(np.diag(R), [1.0, 4.0, 9.0])


def test_gnss_velocity_with_lever_arm():
    _check(ms.gnss_velocity_model, np.array([11.0, -4.0, 1.0, 0.1, 0.2, 0.3]), LEVER)


def test_gnss_velocity_only_measured_components():
    """NaN = not measured: the rows are those of the measured components, in order, with their σ."""
    row = np.array([11.0, np.nan, 1.0, 0.1, 0.2, 0.3])
    H, R, z = _check(ms.gnss_velocity_model, row, LEVER)
    Hf, Rf, zf = _check(ms.gnss_velocity_model, np.array([11.0, 0.0, 1.0, 0.1, 0.2, 0.3]), LEVER)
    assert H.shape[0] == 2 and np.allclose(H, Hf[[0, 2]]) and np.allclose(z, zf[[0, 2]])
    assert np.allclose(R, np.diag([0.01, 0.09]))


def test_zupt_and_zaru():
    _check(ms.zupt_model, np.zeros(6), np.array([0.02]))
    _check(ms.zaru_model, np.zeros(6), np.array([1e-3]))


def test_nhc_with_lever_arm_and_mounting():
    _check(ms.nhc_model, np.zeros(6), _vehicle_par(), rate_from_bias=False)


def test_odometer_with_scale_factor_state():
    row = np.array([12.5, 0.05, 0, 0, 0, 0])
    H, _, _ = _check(ms.odometer_model, row, _vehicle_par(), rate_from_bias=False)
    assert H[0, LAY[L_ODO]] != 0.0


def test_barometer_with_bias_state():
    H, R, _ = _check(ms.baro_model, np.array([118.0, 0.5, 0, 0, 0, 0]), np.zeros(1))
    assert H[0, LAY[L_BARO]] == -1.0 and R[0, 0] == 0.25


def test_attitude_fix():
    """H = [I, 0] is the Jacobian at a zero residual (the linearisation point): measured ≈ computed."""
    Cm = dcm_from_euler(0.1 + 1e-6, -0.05 - 2e-6, 1.0 + 3e-6)
    H, R, _ = _check(ms.attitude_model, np.concatenate([Cm.ravel(), np.diag([1e-4, 2e-4, 4e-4]).ravel()]),
                     np.zeros(1))
    assert np.allclose(R, np.diag([1e-4, 2e-4, 4e-4]))


def test_velocity_attitude_matching():
    Cm = dcm_from_euler(0.1 - 1e-6, -0.05 + 1e-6, 1.0 + 2e-6)
    row = np.concatenate([[11.0, -5.5, 0.7], Cm.ravel(), [0.1] * 3, [0.01] * 3])
    H, R, _ = _check(ms.velocity_attitude_matching, row, np.zeros(1))
    assert H.shape == (6, N)


def test_sapv_angles():
    sat = np.array(lla_to_ecef(0.0, 2.2, 35786e3))
    row = np.concatenate([sat, [0.0, 0.0, 0.01, 0.01]])
    st, b = _nominal()
    H = np.zeros((ms.MAX_ROWS, N))
    z = np.zeros(ms.MAX_ROWS)
    ms.sapv_model(_nav(st, b, 0.0, True, b), row, np.array([1.0]), LAY, H, z, np.zeros((6, 6)))
    row[3:5] = z[:2] - 0.01  # measured angles near the computed ones (no wrap inside the differences)
    _check(ms.sapv_model, row, np.array([1.0]))


@pytest.mark.parametrize("with_rate", [False, True])
def test_pseudorange_and_rate(with_rate):
    sat = np.array(lla_to_ecef(0.5, 2.3, 20200e3))
    vsat = np.array([1200.0, -2500.0, 1800.0])
    row = np.array([*sat, *vsat, 2.2e7, -300.0 if with_rate else np.nan, 3.0, 0.1])
    # the rate row neglects the position dependence of the line of sight, |v_rel|/ρ per metre
    allow = None
    if with_rate:
        allow = np.zeros((2, N))
        allow[1, 6:9] = 4e3 / 2e7 * np.array([1e-7 * 6.4e6, 1e-7 * 6.4e6, 0.5]) * 2
    H, R, _ = _check(ms.pseudorange_model, row, LEVER, dt_back=0.07, allow=allow)
    assert H.shape[0] == (2 if with_rate else 1)
    assert H[0, LAY[L_CLK]] == -1.0 and (not with_rate or H[1, LAY[L_CLK] + 1] == -1.0)


def test_magnetometer_heading():
    st, b = _nominal()
    H = np.zeros((ms.MAX_ROWS, N))
    z = np.zeros(ms.MAX_ROWS)
    ms.mag_heading_model(_nav(st, b, 0.0, True, b), np.array([0.0, 0.01]), np.zeros(1), LAY, H, z,
                         np.zeros((6, 6)))
    psi = z[0]  # the INS heading (measured 0)
    row = np.array([psi - 0.02, np.radians(2.0)])  # measured near the computed heading (no wrap)
    H, R, z = _check(ms.mag_heading_model, row, np.zeros(1), dt_back=0.05)
    assert np.isclose(R[0, 0], np.radians(2.0) ** 2) and H[0, 2] == 1.0
    # the heading wraps: a measurement 2π away gives the same innovation
    H2, _, z2 = _check(ms.mag_heading_model, row + np.array([2 * np.pi, 0.0]), np.zeros(1), dt_back=0.05)
    assert np.isclose(z2[0], z[0]) and np.allclose(H2, H)
