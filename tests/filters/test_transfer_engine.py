"""Transfer alignment on the filter engine: the engine's exact Gauss-Markov blocks and open-loop states,
the velocity + attitude matching model's Jacobian (lever arm, mounting and flexure columns), and the RTS
smoother of the transfer filter on a simulated maneuvering flight.

Frames and units as in ``docs/conventions.md``: n = ENU, b = RFU, radians, metres, seconds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from aidnav.analysis.consistency import chi2_band, nees
from aidnav.filters import engine as eng
from aidnav.filters import measurements as ms
from aidnav.filters import transfer as tf
from aidnav.filters.kalman import van_loan
from aidnav.filters.layout import L_FLEX, L_MOUNT, L_N, NAV
from aidnav.filters.measurements.check import check_jacobian
from aidnav.filters.predict import exact_blocks
from aidnav.filters.transfer_model import transfer_layout
from aidnav.nav.earth import OMEGA_IE
from aidnav.nav.rotations import dcm_from_euler, dcm_from_quat, dcm_from_rotvec, quat_from_euler
from aidnav.sim import distributed_pos as dp
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth

DEG = math.pi / 180.0
RUNS = 8  # fixed seeds 300..307


# ------------------------------------------------------------------------------- engine pieces
@pytest.mark.parametrize("order", [1, 2])
def test_exact_blocks_against_van_loan(order):
    """A first- and a second-order Gauss-Markov block among other states: Φ, Qd of the block equal Van
    Loan's (exact), the rest of Φ, Qd untouched."""
    n, i, j, beta, sig, T = 6, 2, (4 if order == 2 else -1), 1.3, 0.02, 1.0
    F, G, q = np.zeros((n, n)), np.zeros((n, n)), np.zeros(n)
    if order == 2:
        F[i, j], F[j, i], F[j, j] = 1.0, -beta * beta, -2.0 * beta
        G[j, j], q[j] = 1.0, 4.0 * beta**3 * sig**2
    else:
        F[i, i], G[i, i], q[i] = -beta, 1.0, 2.0 * beta * sig**2
    F[0, 1], G[0, 0], q[0] = 0.3, 1.0, 1e-4  # another (Taylor-accurate) block
    Phi, Qd = np.full((n, n), 7.0), np.full((n, n), 7.0)
    Phi_e, Qd_e = van_loan(F, G, q, T)
    blk = [i] if j < 0 else [i, j]
    Phi[0:2, 0:2], Qd[0:2, 0:2] = Phi_e[0:2, 0:2], Qd_e[0:2, 0:2]
    exact_blocks(Phi, Qd, np.array([[i, j, beta, sig]], float), T)
    np.testing.assert_allclose(Phi[np.ix_(blk, blk)], Phi_e[np.ix_(blk, blk)], rtol=1e-12)
    np.testing.assert_allclose(Qd[np.ix_(blk, blk)], Qd_e[np.ix_(blk, blk)], rtol=1e-9)
    assert Phi[0, 0] == Phi_e[0, 0] and Phi[0, blk[0]] == 0.0 and Qd[blk[-1], 0] == 0.0
    assert Phi[3, 3] == 7.0  # states outside the blocks are left as they are


def test_carry_estimates_propagates_the_open_states():
    """x̂ ← Φ x̂ for the open states (kept in bias); what Φ carries from them into a closed calibration
    state is fed back into it; the INS states (no coupling here) are unchanged."""
    n = 14
    rng = np.random.default_rng(3)
    Phi = np.eye(n)
    Phi[11:14, 11:14] += 0.1 * rng.standard_normal((3, 3))
    Phi[10, 12] = 0.5  # open → closed calibration state
    st = np.array([0.7, 2.0, 100.0, 1.0, 2.0, 0.1, *quat_from_euler(0.1, 0.2, 0.3)])
    bias = rng.standard_normal(n - NAV)
    b0, st0 = bias.copy(), st.copy()
    eng.carry_estimates(st, bias, Phi, np.arange(11, 14), n)
    np.testing.assert_allclose(bias[11 - NAV:], Phi[11:14, 11:14] @ b0[11 - NAV:], rtol=1e-14)
    assert bias[10 - NAV] == pytest.approx(b0[10 - NAV] + 0.5 * b0[12 - NAV])
    np.testing.assert_array_equal(bias[:10 - NAV], b0[:10 - NAV])
    np.testing.assert_array_equal(st, st0)


# ------------------------------------------------------------------------ measurement Jacobian
def test_velocity_attitude_matching_jacobian_with_mounting_and_lever_arm():
    """The 30-entry row (full R_a, master rate, lever arm) with mounting ρ̂ and flexure θ̂ of 0.5–1°:
    H against central differences (the ρ and θ columns carry the left Jacobian of SO(3))."""
    lay = transfer_layout(24)
    n = int(lay[L_N])
    st = np.array([0.7, 2.0, 7000.0, 64.0, 76.0, 1.0, *quat_from_euler(0.05, -0.02, 0.7)])
    b0 = np.zeros(n - NAV)
    b0[lay[L_MOUNT] - NAV:lay[L_MOUNT] - NAV + 3] = np.array([0.5, -0.7, 1.0]) * DEG
    b0[lay[L_FLEX] - NAV:lay[L_FLEX] - NAV + 3] = np.array([0.01, 0.15, -0.02]) * DEG
    ah = b0[6:9] + b0[9:12]
    Cm = dcm_from_quat(st[6:10]) @ dcm_from_rotvec(ah) @ dcm_from_rotvec(np.array([1e-5, -2e-5, 3e-5]))
    Ra = np.diag([1e-8, 2e-8, 4e-8])
    Ra[0, 2] = Ra[2, 0] = 5e-9
    row = np.concatenate([[64.1, 75.9, 1.05], Cm.ravel(), [0.05] * 3, [0.0] * 3, Ra.ravel(),
                          [0.02, -0.01, 0.05]])
    par = np.array([5.0, 0.1, 0.1])

    def nav_of(s, b):
        w = np.zeros((4, 3))
        w[2] = [0.0, OMEGA_IE * np.cos(s[0]), OMEGA_IE * np.sin(s[0])]
        return ms.Nav(s, dcm_from_quat(s[6:10]), w, 0.0, b)

    steps = np.array([1e-4] * 3 + [1e-3] * 3 + [1e-7, 1e-7, 0.5] + [1e-5] * 6 + [1e-4] * 9)
    H, R, z = check_jacobian(ms.velocity_attitude_matching, row, par, lay, st, b0, nav_of, steps,
                             eng.feedback)
    assert H.shape == (6, n) and np.allclose(R[3:, 3:], Ra) and np.allclose(np.diag(R)[:3], 0.05**2)
    assert not H[:, 21:24].any()  # θ̇ does not enter the measurement
    # the lever arm: v_slave = v_master + C_m (ω_eb × r)
    web = row[27:30] - Cm.T @ [0.0, OMEGA_IE * np.cos(st[0]), OMEGA_IE * np.sin(st[0])]
    np.testing.assert_allclose(z[:3], st[3:6] - row[:3] - Cm @ np.cross(web, par), atol=1e-12)


# -------------------------------------------------------------------------------------- smoother
@pytest.fixture(scope="module")
def smoothed_runs():
    """30 s straight, a 360° circle in 120 s, 150 s straight; forward filter and RTS (full covariance)."""
    ini = {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 7000.0, "speed_m_s": 100.0, "heading_deg": 40.0}
    seg = [{"type": "straight", "duration_s": 30.0}, {"type": "o_circle", "duration_s": 120.0},
           {"type": "straight", "duration_s": 150.0}]
    bundle = generate_truth(parse_scenario({"initial": ini, "segments": seg}, "<test>"))
    cfg = dp.DistributedPosConfig()
    geo = dp.sub_geometry(bundle[0], bundle[1], cfg.lever_arm)
    out = []
    for s in range(RUNS):
        run = dp.simulate_distributed_pos(bundle, cfg, 300 + s, geo)
        sm = tf.run_transfer(run, tf.TransferConfig.from_sim(cfg), keep_cov=True, smooth=True)
        out.append((sm, tf.transfer_errors(sm, run), tf.transfer_errors(sm.forward, run)))
    return out


def test_smoother_beats_the_filter(smoothed_runs):
    """Smoothed σ ≤ forward σ at every epoch and state; smoothed RMS error ≤ forward RMS for the
    attitude φ, the mounting ρ and the flexure θ (over runs and epochs), clearly so for the heading."""
    for sm, _, _ in smoothed_runs:
        assert np.all(sm.pdiag <= sm.forward.pdiag * (1 + 1e-9) + 1e-30)
        np.testing.assert_array_equal(sm.nis, sm.forward.nis)
    es = np.array([e.state for _, e, _ in smoothed_runs])
    ef = np.array([e.state for _, _, e in smoothed_runs])
    rms_s, rms_f = np.sqrt(np.mean(es**2, axis=(0, 1))), np.sqrt(np.mean(ef**2, axis=(0, 1)))
    for sl in (slice(0, 3), slice(tf.RHO, tf.RHO + 3), slice(tf.THETA, tf.THETA + 3)):
        assert np.all(rms_s[sl] <= rms_f[sl]), (sl, rms_s[sl], rms_f[sl])
    assert rms_s[2] < 0.5 * rms_f[2]  # the heading before the circle is resolved backwards


def test_smoother_nees_in_band(smoothed_runs):
    """Average over the runs of the smoother's 24-state NEES at every 10th epoch against the two-sided
    99 % χ² band of RUNS runs (≥ 90 % inside), and its mean over the epochs within the 99.9 % band of
    RUNS runs (smoothed errors are correlated over the whole run: ρ is a constant, so the epochs are
    not independent samples; the band of the fully correlated case is the one that holds)."""
    err = np.array([e.state for _, e, _ in smoothed_runs])
    cov = np.array([sm.cov for sm, _, _ in smoothed_runs])
    ep = slice(5, None, 10)
    v = nees(err[:, ep], cov[:, ep]).mean(axis=0)
    lo, hi = chi2_band(24, RUNS, 0.99)
    assert np.mean((v >= lo) & (v <= hi)) >= 0.9, v
    m_lo, m_hi = chi2_band(24, RUNS, 0.999)
    assert m_lo < v.mean() < m_hi, v.mean()


def test_attitude_columns_match_the_old_first_order_form_at_zero_mounting():
    """At α̂ = 0 the ρ and θ columns are C_m (J = I), the attitude rows those of a plain attitude fix."""
    lay = transfer_layout(21)
    n = int(lay[L_N])
    Cm = dcm_from_euler(0.1, -0.05, 1.0)
    H, z, R = np.zeros((6, n)), np.zeros(6), np.zeros((6, 6))
    row = np.concatenate([[1.0, 2.0, 0.0], Cm.ravel(), [0.1] * 3, [0.01] * 3])
    st = np.array([0.6, 2.0, 120.0, 1.0, 2.0, 0.0, *quat_from_euler(0.1, -0.05, 1.0)])
    nav = ms.Nav(st, dcm_from_quat(st[6:10]), np.zeros((4, 3)), 0.0, np.zeros(n - NAV))
    assert ms.velocity_attitude_matching(nav, row, np.zeros(1), lay, H, z, R) == 6
    np.testing.assert_allclose(H[3:6, 15:18], Cm, atol=1e-15)
    np.testing.assert_allclose(H[3:6, 18:21], Cm, atol=1e-15)
    np.testing.assert_allclose(np.diag(R), [0.01] * 3 + [1e-4] * 3)
