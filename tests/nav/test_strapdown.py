"""Tests of the strapdown mechanization ``aidnav.nav.strapdown``.

(a) closed loop: error-free IMU increments of a 1-hour 100 Hz figure-8 flight from
    ``aidnav.sim.motion.generate`` reproduce the truth (vertical channel held to the truth);
(b) Schuler: a stationary 3-hour run with constant gyro and accelerometer biases oscillates with
    the Schuler period 2π √(R/g), R = √(R_M R_N) (≈ 84.4 min);
(c) a static, level IMU at rest does not drift.

Frames and units as in ``docs/conventions.md``: n = ENU, b = RFU, radians, metres, seconds.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from aidnav.nav import earth, rotations, strapdown
from aidnav.sim import motion
from aidnav.units import UG

DEG = np.pi / 180.0
ARCSEC = DEG / 3600.0


# ---------------------------------------------------------------------------- helpers
def figure8_segments(duration=3600.0, speed_turn_deg_s=3.0, climb_deg=2.0):
    """Primitive segments (tb, half, vals) of a figure-8 flight at constant speed.

    60 s straight, then alternating +360° / -360° turns at 3°/s (120 s each), separated by 30 s
    straights that carry a gentle climb (then, on the next straight, a descent): flight-path angle
    ramped to ±2° in 10 s, held 10 s, ramped back in 10 s. Channel transitions are 4 s raised cosines.
    vals columns: along-track acceleration [m/s²], turn rate [rad/s] (clockwise +), FPA rate [rad/s].
    """
    r = speed_turn_deg_s * DEG
    g = climb_deg * DEG / 10.0
    tb, vals = [0.0], [[0.0, 0.0, 0.0]]
    t, sign, k = 60.0, 1.0, 0
    while t < duration:
        up = g if k % 2 == 0 else -g
        for dur, row in (
            (360.0 / speed_turn_deg_s, [0.0, sign * r, 0.0]),
            (10.0, [0.0, 0.0, up]),
            (10.0, [0.0, 0.0, 0.0]),
            (10.0, [0.0, 0.0, -up]),
        ):
            tb.append(t)
            vals.append(row)
            t += dur
        sign, k = -sign, k + 1
    tb = np.array(tb)
    return tb, motion.half_widths(tb, 4.0), np.array(vals)


def static_increments(lat, h, roll, pitch, heading, dt, n, gyro_bias=np.zeros(3), accel_bias=np.zeros(3)):
    """Exact increments of an IMU at rest on the rotating Earth, plus constant biases.

    Returns (dtheta, dv), each (n, 3): Δθ = (C_n^b ω_ie^n + b_g) dt [rad],
    Δv = (C_n^b [0, 0, g] + b_a) dt [m/s].
    """
    c_nb = rotations.dcm_from_euler(roll, pitch, heading).T
    w_b = c_nb @ earth.earth_rate_n(lat)
    f_b = c_nb @ np.array([0.0, 0.0, earth.gravity(lat, h)])
    dth = np.tile((w_b + gyro_bias) * dt, (n, 1))
    dv = np.tile((f_b + accel_bias) * dt, (n, 1))
    return dth, dv


def position_error_enu(out, lat, lon, h):
    """(dE, dN, dU) [m] of the mechanized states ``out`` relative to (lat, lon, h)."""
    return earth.lla_difference_enu(out[:, 0], out[:, 1], out[:, 2], lat, lon, h)


# ---------------------------------------------------------------------------- (a) closed loop
@pytest.fixture(scope="module")
def figure8_run():
    dt, n = 0.01, 360_000  # 1 hour at 100 Hz
    tb, half, vals = figure8_segments(n * dt)
    y0 = np.array([40.0 * DEG, 116.0 * DEG, 1000.0, 100.0, 30.0 * DEG, 0.0])
    truth, dth, dv = motion.generate(tb, half, vals, y0, 0.0, dt, n)
    q_true = rotations.euler_to_quat_batch(np.ascontiguousarray(truth[:, 7:10]))
    st0 = strapdown.make_state(truth[0, 1], truth[0, 2], truth[0, 3], truth[0, 4:7], q_true[0])
    out = strapdown.mechanize(
        np.ascontiguousarray(truth[1:, 0]),
        dth,
        dv,
        st0,
        0.0,
        np.ascontiguousarray(truth[1:, 3]),
        np.ascontiguousarray(truth[1:, 6]),
    )
    return truth, q_true, out


def test_closed_loop_figure8(figure8_run):
    """Error-free increments of a 1-h figure-8 flight at 100 Hz reproduce the truth.

    100 m/s, alternating ±360° turns at 3°/s (bank ≈ 28°) with climbing/descending straights,
    8,550° of accumulated heading change. The free-inertial vertical channel is unstable, so height
    and vertical velocity are held to the truth (``hold_h``, ``hold_vu``); everything else is free
    inertial. Acceptance: horizontal position error < 1 m and attitude error < 2 arc-seconds over the
    whole hour (attitude error = rotations.attitude_error_batch, C_est = (I - [φ×]) C_true).
    """
    truth, q_true, out = figure8_run
    # the trajectory is what it should be
    dchi = np.diff(truth[:, 9])  # unwrapped heading
    assert np.sum(np.abs(dchi)) >= 720.0 * DEG
    assert np.ptp(truth[:, 9]) >= 2 * np.pi - 1e-6  # full circles
    assert dchi.max() > 0.99 * 3 * DEG * 0.01 and dchi.min() < -0.99 * 3 * DEG * 0.01  # right and left
    assert np.ptp(truth[:, 3]) > 20.0  # climbs
    assert np.max(np.abs(truth[:, 7])) > 25 * DEG  # banked turns

    de, dn, du = position_error_enu(out, truth[1:, 1], truth[1:, 2], truth[1:, 3])
    hor = np.hypot(de, dn)
    phi = rotations.attitude_error_batch(np.ascontiguousarray(out[:, 6:10]), q_true[1:])
    att = np.linalg.norm(phi, axis=1) / ARCSEC
    dvel = np.abs(out[:, 3:5] - truth[1:, 4:6])
    print(
        f"\nclosed loop 1 h figure-8 @100 Hz: max horizontal error {hor.max():.4f} m, "
        f"max attitude error {att.max():.5f} arcsec, max horizontal velocity error {dvel.max():.2e} m/s"
    )
    assert hor.max() < 1.0
    assert att.max() < 2.0
    assert np.all(out[:, 2] == truth[1:, 3]) and np.all(out[:, 5] == truth[1:, 6])  # held
    # regression guard on the current (second-order) accuracy: ~7 mm, ~3e-4" and ~1e-5 m/s
    # (a start-of-interval nav-frame rate in the attitude update gave 0.8 m and 0.036")
    assert hor.max() < 0.05
    assert att.max() < 0.01
    assert dvel.max() < 1e-4


def test_closed_loop_short_free_vertical():
    """First 2 minutes of the figure-8 with the vertical channel free (empty hold arrays)."""
    dt, n = 0.01, 12_000
    tb, half, vals = figure8_segments(3600.0)
    y0 = np.array([-33.0 * DEG, -70.0 * DEG, 500.0, 100.0, 200.0 * DEG, 0.0])
    truth, dth, dv = motion.generate(tb, half, vals, y0, 0.0, dt, n)
    q_true = rotations.euler_to_quat_batch(np.ascontiguousarray(truth[:, 7:10]))
    st0 = strapdown.make_state(truth[0, 1], truth[0, 2], truth[0, 3], truth[0, 4:7], q_true[0])
    out = strapdown.mechanize(np.ascontiguousarray(truth[1:, 0]), dth, dv, st0, 0.0, np.empty(0), np.empty(0))
    de, dn, du = position_error_enu(out, truth[1:, 1], truth[1:, 2], truth[1:, 3])
    # the free vertical channel diverges slowly; over 2 minutes it stays at the algorithm's accuracy
    assert np.max(np.abs(np.stack([de, dn, du]))) < 1e-3
    assert np.max(np.abs(out[:, 3:6] - truth[1:, 4:7])) < 1e-4
    phi = rotations.attitude_error_batch(np.ascontiguousarray(out[:, 6:10]), q_true[1:])
    assert np.max(np.abs(phi)) < 0.01 * ARCSEC


# ---------------------------------------------------------------------------- (b) Schuler
def fit_schuler(t, de, dn, deg=3):
    """Fit the horizontal error z = dE + i dN [m] with the model of a Schuler loop under Foucault coupling.

    z(t) = Σ_k c_k (t/T)^k + A e^{iλ1 t} + B e^{iλ2 t}: the error equation
    z'' + 2i Ω sin L z' + ω_s² z = forcing has the modes λ = -Ω sin L ± √(ω_s² + Ω² sin² L),
    i.e. a Schuler oscillation whose plane turns at the Foucault rate. The polynomial absorbs the
    slow (24-h, gyro-driven) terms. Variable projection: the linear coefficients are solved for each
    (λ1, λ2) by least squares and (λ1, λ2) by scipy.optimize.least_squares.

    Returns (schuler angular frequency (λ1 - λ2)/2, Foucault rate -(λ1 + λ2)/2, amplitudes, residual).
    """
    z = de + 1j * dn
    tau = t / t[-1]
    poly = np.stack([tau**k for k in range(deg + 1)], axis=1)

    def design(lam):
        return np.hstack([poly, np.exp(1j * lam[0] * t)[:, None], np.exp(1j * lam[1] * t)[:, None]])

    def resid(lam):
        m = design(lam)
        c, *_ = np.linalg.lstsq(m, z, rcond=None)
        r = z - m @ c
        return np.concatenate([r.real, r.imag])

    w0 = 2 * np.pi / (84.0 * 60.0)  # start a little off the expected value
    sol = least_squares(resid, [w0, -w0], x_scale=[1e-4, 1e-4], xtol=1e-14, ftol=1e-14)
    lam1, lam2 = sorted(sol.x, reverse=True)
    c, *_ = np.linalg.lstsq(design([lam1, lam2]), z, rcond=None)
    rms = np.sqrt(np.mean(sol.fun**2))
    return 0.5 * (lam1 - lam2), -0.5 * (lam1 + lam2), np.abs(c[-2:]), rms


def test_schuler_period():
    """Stationary 3-h run at 40° N, 0.01°/h gyro and 10 µg accelerometer biases on every axis, height held.

    The horizontal position error oscillates with the Schuler period 2π √(R/g), R = √(R_M R_N)
    (84.45 min at 40° N), its plane turning at the Foucault rate Ω sin L; the fitted period must be
    84.4 min ± 1 % and within 1 % of the exact value. 10 Hz is enough: the increments are constant.
    """
    lat, lon, h = 40.0 * DEG, 10.0 * DEG, 100.0
    dt, n = 0.1, 108_000  # 3 h at 10 Hz
    bg = 0.01 * DEG / 3600.0 * np.ones(3)  # 0.01 deg/h [rad/s]
    ba = 10.0 * UG * np.ones(3)  # 10 ug [m/s^2]
    heading = 30.0 * DEG
    dth, dv = static_increments(lat, h, 0.0, 0.0, heading, dt, n, bg, ba)
    t = dt * np.arange(1, n + 1)
    st0 = strapdown.make_state(lat, lon, h, np.zeros(3), rotations.quat_from_euler(0.0, 0.0, heading))
    out = strapdown.mechanize(t, dth, dv, st0, 0.0, np.full(n, h), np.zeros(n))
    de, dn, _ = position_error_enu(out, lat, lon, h)

    rm, rn = earth.radii(lat)
    g = earth.gravity(lat, h)
    period_exact = 2 * np.pi * np.sqrt(np.sqrt((rm + h) * (rn + h)) / g)
    w_s, w_f, amp, rms = fit_schuler(t, de, dn)
    period_fit = 2 * np.pi / w_s
    print(
        f"\nSchuler: fitted period {period_fit / 60:.3f} min, exact {period_exact / 60:.3f} min "
        f"(ratio {period_fit / period_exact:.5f}); Foucault rate {w_f:.3e} rad/s "
        f"(Ω sin L = {earth.OMEGA_IE * np.sin(lat):.3e}); amplitudes {amp[0]:.1f}, {amp[1]:.1f} m, "
        f"fit rms {rms:.3f} m; max |error| {np.max(np.hypot(de, dn)):.0f} m"
    )
    assert period_exact / 60 == pytest.approx(84.45, abs=0.01)
    assert abs(period_fit / 60 - 84.4) < 0.01 * 84.4
    assert abs(period_fit / period_exact - 1) < 0.01
    assert w_f == pytest.approx(earth.OMEGA_IE * np.sin(lat), rel=0.1)
    # a real oscillation of tens to hundreds of metres, fitted to well below its amplitude
    assert np.all(amp > 20.0) and rms < 0.01 * amp.min()


# ---------------------------------------------------------------------------- (c) static
@pytest.mark.parametrize("hold", [False, True])
def test_static_level_no_drift(hold):
    """A level IMU at rest (exact increments incl. Earth rate and normal gravity) does not drift.

    10 min at 100 Hz, time-tagged in GPS seconds of week; vertical channel free or held.
    """
    lat, lon, h, heading = -35.0 * DEG, 149.0 * DEG, 600.0, 123.0 * DEG
    dt, n = 0.01, 60_000
    dth, dv = static_increments(lat, h, 0.0, 0.0, heading, dt, n)
    t0 = 388_800.0
    t = t0 + dt * np.arange(1, n + 1)
    q0 = rotations.quat_from_euler(0.0, 0.0, heading)
    st0 = strapdown.make_state(lat, lon, h, np.zeros(3), q0)
    hh, hv = (np.full(n, h), np.zeros(n)) if hold else (np.empty(0), np.empty(0))
    out = strapdown.mechanize(t, dth, dv, st0, t0, hh, hv)
    de, dn, du = position_error_enu(out, lat, lon, h)
    assert np.max(np.abs(np.stack([de, dn, du]))) < 1e-6
    assert np.max(np.abs(out[:, 3:6])) < 1e-8
    phi = rotations.attitude_error_batch(np.ascontiguousarray(out[:, 6:10]), np.tile(q0, (n, 1)))
    assert np.max(np.abs(phi)) < 1e-9
