"""The tight filter's pseudorange row (``measurements.epoch.epoch_update``) against central finite
differences of its own innovation, the per-satellite range-error column included.

``epoch_update`` applies its rows as sequential scalar updates and does not hand H out; with one
satellite, code only, x = 0 and a diagonal P, the update x⁺ = P h ν / s gives h_i = x⁺_i s / (P_ii ν)
exactly (ν, s: the innovation and its variance, logged in the epoch outputs). The innovation ν = ρ_meas
− (ρ̂ + I + T + b̂ + σ_j(E)·û_j) as a function of the error state δx fed back into the computed state
(``engine.feedback``: x = true − estimated, p ← p − δp, b̂ ← b̂ + δb) has ∂ν/∂δx = −h (feeding back δx
removes h δx from the innovation). Checked at û_j = 0 and at û_j = 2 (two σ: the elevation dependence of
σ_j(E) through the position, neglected in h, is u_j dσ/dE dE/dp ≈ 1e-7 m per metre — inside the
tolerance, and the check says so by passing there too). The one neglect the tolerance names is the
troposphere delay's height derivative (≈ 3e-4 m per metre of height).
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.filters.engine import feedback, node_rates
from aidnav.filters.layout import L_CLK, L_N, L_RERR
from aidnav.filters.measurements import Nav
from aidnav.filters.measurements import epoch as ep
from aidnav.filters.measurements.check import step_response
from aidnav.filters.tight import tight_layout
from aidnav.nav.earth import lla_to_ecef
from aidnav.nav.gnss_sat import az_el, geo_range, range_error_sigma, tropo_delay
from aidnav.nav.rotations import dcm_from_quat, quat_from_euler

LAY = tight_layout(17, n_range=3)  # 15 INS + clock (2) + 3 range-error states
N = int(LAY[L_N])
LEVER = np.array([0.3, 0.8, -1.1])
T_GPS = 345_600.0
# finite-difference steps: attitude [rad], velocity [m/s], lat/lon [rad], height [m], biases, clock, û
STEPS = np.array([1e-5] * 3 + [1e-3] * 3 + [1e-8, 1e-8, 0.05] + [1e-5] * 3 + [1e-3] * 3 + [0.05, 0.01]
                 + [1e-3] * 3)


def _state(u):
    q = quat_from_euler(0.05, -0.02, 0.7)
    st = np.array([0.53, 1.99, 35.0, 3.0, -1.0, 0.1, *q])
    bias = np.zeros(N - 9)
    bias[LAY[L_CLK] - 9:LAY[L_CLK] - 7] = [1200.0, 0.4]
    bias[LAY[L_RERR] - 9 + 1] = u  # the satellite's slot is 1
    return st, bias


def _nav(st, bias):
    C = dcm_from_quat(st[6:10])
    w = np.zeros((4, 3))
    wb = np.array([0.01, -0.02, 0.05])
    node_rates(st, wb, wb * 0.01, 0.01, w)
    return Nav(st, C, w, 0.0, bias)


def _row_par():
    sat = np.array(lla_to_ecef(0.9, 2.4, 20_200e3))
    row = np.full(ep.E_W, np.nan)
    row[0:3] = sat
    row[3:6] = [1500.0, -2100.0, 900.0]
    row[6] = 2.31e7  # pseudorange [m] (any value: only ∂ν/∂δx matters)
    row[9] = 2.0  # URA [m]
    row[10] = 1.0  # range-error slot
    par = np.zeros(ep.E_NPAR)
    par[ep.E_LEVER:ep.E_LEVER + 3] = LEVER
    par[ep.E_MASK] = 0.1
    par[ep.E_SIG_CODE], par[ep.E_SIG_RATE] = 3.0, 0.1
    par[ep.E_IONO], par[ep.E_TROPO], par[ep.E_HUMID], par[ep.E_RATE] = 1.0, 1.0, 0.5, 0.0
    par[ep.E_JUMP], par[ep.E_SIG_B], par[ep.E_SIG_D], par[ep.E_CODE_MIN] = 1e12, 100.0, 1.0, 1.0
    par[ep.E_ALPHA:ep.E_ALPHA + 4] = [1.1e-8, 1.5e-8, -6.0e-8, -1.2e-7]
    par[ep.E_BETA:ep.E_BETA + 4] = [9.0e4, 8.2e4, -6.6e4, -5.2e5]
    return row, par


def _innovation(st, bias, p_diag):
    """(ν, s, x⁺) of one epoch_update from x = 0, P = diag(p_diag), the clock already started."""
    row, par = _row_par()
    grp = ep.epoch_out(1, row.shape[0] // ep.E_W)
    grp.flags[0] = 1  # clock initialised: no reset from the median residual
    x, P = np.zeros(N), np.diag(p_diag)
    ep.epoch_update(x, P, _nav(st, bias), row, par, LAY, 0.0, grp, 0, T_GPS)
    return grp.sat[ep.S_PR_NU, 0, 0], grp.sat[ep.S_PR_S, 0, 0], x


@pytest.mark.parametrize("u", [0.0, 2.0])
def test_pseudorange_row_with_range_error_state_matches_finite_differences(u):
    st0, b0 = _state(u)
    p_diag = np.linspace(0.5, 2.0, N)
    nu, s, xp = _innovation(st0.copy(), b0.copy(), p_diag)
    assert np.isfinite(nu) and s > 0
    h = xp * s / (p_diag * nu)
    # meas = pred(true) ≈ pred(computed) + h δx, and feeding δx back makes the computed state the
    # true one: ν after the feedback = ν − h δx, so column j of h is −∂ν/∂δx_j
    D = step_response(lambda st, b: _innovation(st, b, p_diag)[0], st0, b0, STEPS, feedback)
    resp = h * STEPS
    tol = 1e-4 * np.abs(D).max() + 1e-9
    # the row neglects the height derivative of the troposphere delay (Saastamoinen at the INS height)
    row, par = _row_par()
    _, e = geo_range(row[0:3], np.array(lla_to_ecef(st0[0], st0[1], st0[2])))
    el = az_el(e, st0[0], st0[1])[1]
    dh = STEPS[8]
    tol = np.full(N, tol)
    tol[8] += 1.5 * abs(tropo_delay(st0[0], st0[2] + dh, el, par[ep.E_HUMID])
                        - tropo_delay(st0[0], st0[2] - dh, el, par[ep.E_HUMID])) / 2.0
    bad = np.abs(resp - D) > tol
    assert not bad.any(), f"h differs at {np.flatnonzero(bad).tolist()}: h·ε {resp[bad]}, FD {D[bad]}"
    # the columns that must be there: clock 1, range error σ_j(E) of this satellite's slot only
    ic, ir = int(LAY[L_CLK]), int(LAY[L_RERR])
    assert h[ic] == pytest.approx(1.0, abs=1e-9)
    assert h[ir] == 0.0 and h[ir + 2] == 0.0
    assert 0.5 < h[ir + 1] < 30.0  # metres: a single-frequency budget at this elevation


def test_range_error_column_is_the_budget_sigma_at_the_satellite():
    st0, b0 = _state(0.0)
    p_diag = np.ones(N)
    nu, s, xp = _innovation(st0.copy(), b0.copy(), p_diag)
    h = xp * s / (p_diag * nu)
    row, par = _row_par()
    # the elevation at the antenna the filter uses (no lever arm effect beyond metres on 20,000 km)
    ra = np.array(lla_to_ecef(st0[0], st0[1], st0[2]))
    _, e = geo_range(row[0:3], ra)
    _, el, _ = az_el(e, st0[0], st0[1])
    # applied ionosphere is Klobuchar (mode 1): the budget's iono term is 0.5 × the applied delay, so
    # compare with bounds from the budget at zero and at a generous delay
    lo = range_error_sigma(el, row[9], 1, 0.0, True)
    hi = range_error_sigma(el, row[9], 1, 30.0, True)
    assert lo <= h[int(LAY[L_RERR]) + 1] <= hi
