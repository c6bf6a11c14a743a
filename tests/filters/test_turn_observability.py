"""Issue 35 (session 15): what a yaw turn tells the tight filter about the tilt — a known answer.

After a levelled start the tilt is the accelerometer bias's image (g·φ = C ∇, horizontal). In a turn about
the vertical the image C(ψ)∇ turns with the body and the tilt does not, so the two separate — but a gyro
misalignment (δω_x = m_xz ω_z, δω_y = m_yz ω_z) turns the tilt during the turn by −∫C(ψ)(m_xz e_x + m_yz e_y)
dψ, whose image in the velocity error, g·R₉₀∫C e dψ, is −g·m·C(ψ)e plus a constant: the same function of
ψ as the bias's image. So a yaw turn observes only the sums ∇_x − g·m_xz and ∇_y − g·m_yz, and the tilt
after it keeps the part of g·m the sums leave: per axis

    σ_φ = σ_∇ σ_gm / √(σ_∇² + σ_gm²) / g,   σ_gm = g·σ_m,

0.42° for the unknown-grade model (σ_∇ 13.28 mg, σ_m 0.5°), not the 0.8° the misalignment alone would add
over 90° were nothing observed, nor the ~0 a bias without misalignment would leave. The consistency
matrix's tight seed 4 (pitch −1.18° at σ 0.43° after the first turn, ∇̂_y +20.8 mg against +0.85 mg) is this
posterior with a 3.4σ draw of m_yz (−1.683°): the closed form's posterior mean gives ∇̂_y = k(∇_y − g m_yz)
= +20.9 mg and a pitch error of 1.17° (k = σ_∇²/(σ_∇² + σ_gm²) = 0.706).

The test runs the filter's own error model (:func:`aidnav.filters.ins_errors.fill_model`, the 27-state
block) through a 90° turn at 10 m/s, covariance only, with the horizontal velocity measured at every node
(σ 0.05 m/s at 10 Hz: the tilt's and the bias's only witness at constant speed), the other sensor errors
held near zero, and compares the tilt σ with the closed form (0.409° against 0.418°; velocities good to
1 cm/s give 0.36°, to 1 mm/s 0.20°: the model's weak couplings — Coriolis, Earth rate — then add a
little); a straight drive leaves it at σ_∇/g, and without misalignment states the turn leaves nearly
nothing (so the misalignment × turn-rate columns are what hold it up; their central-difference check:
``test_ins_errors.test_scale_factor_and_misalignment_columns_match_numerical_jacobian``).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from aidnav.filters.ins_errors import DV, PHI, fill_model
from aidnav.filters.prior import levelled_tilt_covariance
from aidnav.nav.earth import OMEGA_IE, gravity
from aidnav.nav.rotations import dcm_from_euler

LAT, H, SPEED, DT = np.radians(40.0), 50.0, 10.0, 0.1
SIG_BA = 13.28e-3 * 9.80665  # the unknown-grade model's accelerometer bias σ [m/s²]
SIG_M = np.radians(0.5)  # its gyro misalignment σ [rad]


def _tilt_sigma_after(turn_deg: float, sig_m: float) -> float:
    """Per-axis tilt σ [rad] after 5 s straight, a turn of ``turn_deg`` in 15 s and 5 s straight."""
    g = gravity(LAT, H)
    n = 27
    P = np.diag(np.r_[np.zeros(3), np.full(3, 0.01 ** 2), np.full(3, 1e-9), np.full(3, 1e-9),
                      np.full(3, SIG_BA ** 2), np.full(6, 1e-12), np.full(6, sig_m ** 2 + 1e-16)])
    P[PHI + 2, PHI + 2] = np.radians(0.01) ** 2  # the heading known: only the tilt/bias/misalignment split
    psi = np.radians(20.0)
    P = levelled_tilt_covariance(P, n, np.array([0.0, 0.0, g]), dcm_from_euler(0.0, 0.0, psi), 0.0, g)
    R = np.diag([0.05 ** 2] * 2)  # horizontal velocity [m/s] at 10 Hz (GNSS Doppler-like)
    Hm = np.zeros((2, n))
    Hm[0, DV], Hm[1, DV + 1] = 1.0, 1.0
    F, G = np.zeros((n, n)), np.zeros((n, 24))
    rate = np.radians(turn_deg) / 15.0
    for k in range(int(25.0 / DT)):
        t = k * DT
        w = rate if 5.0 <= t < 20.0 else 0.0
        C = dcm_from_euler(0.0, 0.0, psi)
        fwd = C @ np.array([0.0, 1.0, 0.0])
        v = SPEED * fwd
        # the centripetal acceleration: the heading increases clockwise, the body turns about −Up
        a = -w * SPEED * np.array([fwd[1], -fwd[0], 0.0])
        fn = a + np.array([0.0, 0.0, g])
        wb = np.array([0.0, 0.0, -w]) + C.T @ np.array([0.0, OMEGA_IE * np.cos(LAT), OMEGA_IE * np.sin(LAT)])
        fill_model(F, G, LAT, H, v, fn, C, wb, C.T @ fn, (0.0, 0.0, 0.0, 0.0))
        Phi = expm(F * DT)
        P = Phi @ P @ Phi.T
        S = Hm @ P @ Hm.T + R
        K = P @ Hm.T @ np.linalg.inv(S)
        P = (np.eye(n) - K @ Hm) @ P
        P = 0.5 * (P + P.T)
        psi += w * DT
    return float(np.sqrt(0.5 * (P[PHI, PHI] + P[PHI + 1, PHI + 1])))


def test_turn_observes_the_bias_minus_the_misalignment_only():
    g = gravity(LAT, H)
    sgm = g * SIG_M
    closed = SIG_BA * sgm / np.hypot(SIG_BA, sgm) / g
    assert np.degrees(closed) == pytest.approx(0.42, abs=0.01)
    got = _tilt_sigma_after(90.0, SIG_M)
    assert got == pytest.approx(closed, rel=0.05), (np.degrees(got), np.degrees(closed))


def test_a_straight_drive_leaves_the_levelled_tilt_and_a_turn_without_misalignment_separates_it():
    g = gravity(LAT, H)
    straight = _tilt_sigma_after(0.0, SIG_M)
    assert straight == pytest.approx(SIG_BA / g, rel=0.02), np.degrees(straight)
    no_mis = _tilt_sigma_after(90.0, 1e-9)
    assert no_mis < 0.25 * SIG_BA / g, np.degrees(no_mis)


def test_seed_4_is_the_posterior_of_its_draw():
    """The closed form's posterior mean with seed 4's draws (∇_y +0.85 mg, m_yz −1.683°): ∇̂_y and the
    tilt error the filter showed after the first turn (+20.8 mg, −1.18°; results.md, q35t)."""
    g = 9.80665
    sgm = g * SIG_M
    k = SIG_BA ** 2 / (SIG_BA ** 2 + sgm ** 2)
    b_y, gm = 0.85e-3 * g, g * np.radians(-1.683)
    b_hat = k * (b_y - gm)
    gm_hat = b_hat - (b_y - gm)
    assert b_hat / (1e-3 * g) == pytest.approx(20.8, abs=0.5)
    assert np.degrees(abs(gm - gm_hat) / g) == pytest.approx(1.18, abs=0.05)
    # 2.8σ of the posterior: an honest σ covers it at 3σ only just — the draw, not the σ
    assert 2.5 < abs(gm - gm_hat) / (SIG_BA * sgm / np.hypot(SIG_BA, sgm)) < 3.0
