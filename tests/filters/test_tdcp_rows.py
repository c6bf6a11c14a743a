"""The tight filter's time-differenced carrier-phase rows (issue 40): ``measurements.epoch.tdcp_row``
against central finite differences of its own innovation (the INS, clock and clone columns), the clone
(``clone_epoch``) as the exact linear map of the error state, and the whole epoch: a phase increment that
is the true range change gives a zero innovation, a cycle of slip an innovation of one wavelength.

Innovation z = y − (ρ̂_k − ρ̂_{k−1} + b̂(t_k) − b̂_c) as a function of the error state δx fed back into the
computed state (``engine.feedback``: navigation computed − true, p ← p − δp; clock and clone true −
estimated, b̂ ← b̂ + δb) has ∂z/∂δx = −h (the convention of ``test_epoch_jacobian``).
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.filters.engine import feedback, node_rates
from aidnav.filters.layout import DV, L_CLK, L_N, L_TDCP
from aidnav.filters.measurements import Nav
from aidnav.filters.measurements import epoch as ep
from aidnav.filters.measurements.check import step_response
from aidnav.filters.tight import tight_layout
from aidnav.nav.earth import lla_to_ecef
from aidnav.nav.gnss_sat import LAMBDA_L1, geo_range
from aidnav.nav.rotations import dcm_from_quat, quat_from_euler

LAY = tight_layout(17, n_range=2, n_isb=1, phase=True)  # 15 INS + clock 2 + ISB 1 + clone 4 + 2 range errors
N = int(LAY[L_N])
IC, ICL = int(LAY[L_CLK]), int(LAY[L_TDCP])
LEVER = np.array([0.3, 0.8, -1.1])
DT_BACK = 0.004  # node time − receive time [s]
# finite-difference steps: attitude [rad], velocity [m/s], lat/lon [rad], height [m], biases, clock, ISB,
# clone (ECEF m, clock m), range errors
STEPS = np.array([1e-5] * 3 + [1e-3] * 3 + [1e-8, 1e-8, 0.05] + [1e-5] * 3 + [1e-3] * 3 + [0.05, 0.01]
                 + [0.05] + [0.05] * 4 + [1e-3] * 2)


def _state():
    q = quat_from_euler(0.05, -0.02, 0.7)
    st = np.array([0.53, 1.99, 35.0, 3.0, -1.0, 0.1, *q])
    bias = np.zeros(N - 9)
    bias[IC - 9:IC - 7] = [1200.0, -65.0]
    # the clone: the antenna ~0.8 m away a quarter second ago, and the clock then
    bias[ICL - 9:ICL - 6] = np.array(lla_to_ecef(st[0], st[1], st[2])) + [0.4, -0.6, 0.3]
    bias[ICL - 6] = 1200.0 + 65.0 * 0.25
    return st, bias


def _nav(st, bias):
    C = dcm_from_quat(st[6:10])
    w = np.zeros((4, 3))
    wb = np.array([0.01, -0.02, 0.05])
    node_rates(st, wb, wb * 0.01, 0.01, w)
    return Nav(st, C, w, DT_BACK, bias)


def _row(y=-17.0):
    sat1 = np.array(lla_to_ecef(0.9, 2.4, 20_200e3))
    row = np.full(ep.E_W, np.nan)
    row[0:3] = sat1
    row[3:6] = [1500.0, -2100.0, 900.0]
    row[6] = 2.31e7
    row[ep.E_PHASE] = y
    row[ep.E_PHASE + 1:ep.E_PHASE + 4] = sat1 - 0.25 * row[3:6]
    row[ep.E_PHASE + 4] = 0.25
    return row


def _z(st, bias, row):
    nav = _nav(st, bias)
    Hp, Hv = np.zeros((3, 15)), np.zeros((3, 15))
    ra, _, Cen = ep._antenna(nav, LEVER, Hp, Hv)
    h = np.zeros(N)
    return ep.tdcp_row(nav, row, 0, LAY, ra, Cen, Hp, h), h


def test_tdcp_row_matches_finite_differences():
    st0, b0 = _state()
    row = _row()
    _, h = _z(st0.copy(), b0.copy(), row)
    D = step_response(lambda st, b: _z(st, b, row)[0], st0, b0, STEPS, feedback)
    resp = h * STEPS
    tol = 1e-4 * np.abs(D).max() + 1e-9
    bad = np.abs(resp - D) > tol
    assert not bad.any(), f"h differs at {np.flatnonzero(bad).tolist()}: h·ε {resp[bad]}, FD {D[bad]}"
    # the columns that must be there: clock 1 and −dt_back at the drift, −1 at the clone's clock, the
    # clone position's column a unit vector (the line of sight a quarter second ago); none at ISB/range errors
    assert h[IC] == 1.0 and h[IC + 1] == pytest.approx(-DT_BACK) and h[ICL + 3] == -1.0
    assert np.linalg.norm(h[ICL:ICL + 3]) == pytest.approx(1.0, abs=1e-12)
    assert np.all(h[IC + 2] == 0.0) and np.all(h[ICL + 4:] == 0.0)
    assert np.linalg.norm(h[DV:DV + 3]) == pytest.approx(DT_BACK, rel=1e-9)


def test_true_range_change_gives_zero_innovation_and_a_slip_one_wavelength():
    """y built from the geometry (true clone position, true clocks): z = 0 to float precision; y + λ
    (a one-cycle slip the indicator missed): z = λ, and its σ (2σ_φ² at 90° elevation) says 8σ."""
    st, b = _state()
    row = _row(0.0)
    nav = _nav(st, b)
    Hp, Hv = np.zeros((3, 15)), np.zeros((3, 15))
    ra, _, _ = ep._antenna(nav, LEVER, Hp, Hv)
    rho1, _ = geo_range(row[0:3], ra)
    rho0, _ = geo_range(row[ep.E_PHASE + 1:ep.E_PHASE + 4], b[ICL - 9:ICL - 6])
    b_k = b[IC - 9] - b[IC - 8] * DT_BACK
    row[ep.E_PHASE] = rho1 - rho0 + b_k - b[ICL - 6]
    assert abs(_z(st, b, row)[0]) < 1e-6
    row[ep.E_PHASE] += LAMBDA_L1
    assert _z(st, b, row)[0] == pytest.approx(LAMBDA_L1, abs=1e-6)


def test_clone_is_the_linear_map_of_the_error_state():
    """After ``clone_epoch`` the clone's estimate, covariance rows and block are A x, A P, A P Aᵀ with A
    the antenna position (ECEF, true − computed) and receive-time clock rows; its nominal is the antenna
    and b̂ − d̂·dt_back."""
    rng = np.random.default_rng(3)
    st, b = _state()
    nav = _nav(st, b)
    Hp, Hv = np.zeros((3, 15)), np.zeros((3, 15))
    ra, _, Cen = ep._antenna(nav, LEVER, Hp, Hv)
    L = rng.normal(size=(N, N))
    P = L @ L.T + N * np.eye(N)
    x = rng.normal(size=N)
    P0, x0 = P.copy(), x.copy()
    ep.clone_epoch(x, P, nav, LAY, ra, Cen, Hp)
    A = np.zeros((4, N))
    A[:3, :15] = -Cen.T @ Hp
    A[:3, DV:DV + 3] += Cen.T * DT_BACK
    A[3, IC], A[3, IC + 1] = 1.0, -DT_BACK
    keep = np.r_[0:ICL, ICL + 4:N]
    assert np.allclose(x[ICL:ICL + 4], A @ x0) and np.array_equal(x[keep], x0[keep])
    assert np.allclose(P[ICL:ICL + 4, keep], (A @ P0)[:, keep])
    assert np.allclose(P[ICL:ICL + 4, ICL:ICL + 4], A @ P0 @ A.T)
    assert np.array_equal(P[np.ix_(keep, keep)], P0[np.ix_(keep, keep)])
    assert np.allclose(P, P.T)
    assert np.array_equal(b[ICL - 9:ICL - 6], ra)
    assert b[ICL - 6] == pytest.approx(1200.0 + 65.0 * DT_BACK)
