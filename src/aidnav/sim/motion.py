"""Truth trajectory and exact IMU increments from a piecewise motion command profile (numba kernel).

The motion is described by three commanded channels, piecewise constant over *primitive segments*:

* ``accel``: along-track acceleration dV/dt [m/s^2],
* ``turn_rate``: rate of the track (= heading) angle χ, clockwise positive [rad/s],
* ``fpa_rate``: rate of the flight-path angle γ, up positive [rad/s].

Between two segments each channel changes smoothly along a raised cosine of width
``min(transition, previous duration, next duration)`` centred on the boundary; the raised cosine is
antisymmetric about the boundary, so the integral of every channel (speed change, turn angle, climb
angle) is exactly that of the unsmoothed profile.

The vehicle flies coordinated: body forward axis along the velocity (heading = χ, pitch = γ), and
bank (roll) = roll0 + atan(V·χ̇/g0). The body rate ω_ib^b and specific force f^b follow analytically
(Earth rate, transport rate, Coriolis and WGS-84 normal gravity included); the kinematic state
(lat, lon, h, V, χ, γ) is integrated by RK4 with one step per IMU interval and the IMU increments
Δθ = ∫ω dt, Δv = ∫f dt are Simpson integrals with a 4th-order (Hermite) mid-point state.

Frames and units: n = ENU, b = RFU, radians, metres, seconds.
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.nav.earth import E2, OMEGA_IE, A, gravity
from aidnav.units import G0


@njit(cache=True)
def _commands(t, tb, half, vals, out):
    """Commanded values and their time derivatives at ``t``.

    ``tb``: (S,) segment start times; ``half``: (S,) half transition widths at each start (0 for the
    first); ``vals``: (S, 3). Writes out[0:3] = values, out[3:6] = derivatives.
    """
    s = np.searchsorted(tb, t, side="right") - 1
    if s < 0:
        s = 0
    # the nearest boundary is either tb[s] (we are just after it) or tb[s+1] (just before)
    j = -1
    if s >= 1 and t - tb[s] < half[s]:
        j = s
    elif s + 1 < tb.shape[0] and tb[s + 1] - t < half[s + 1]:
        j = s + 1
    if j < 0:
        for c in range(3):
            out[c] = vals[s, c]
            out[3 + c] = 0.0
    else:
        w = 2.0 * half[j]
        u = (t - tb[j] + half[j]) / w
        sm = 0.5 * (1.0 - np.cos(np.pi * u))
        dsm = 0.5 * np.pi * np.sin(np.pi * u) / w
        for c in range(3):
            d = vals[j, c] - vals[j - 1, c]
            out[c] = vals[j - 1, c] + d * sm
            out[3 + c] = d * dsm


@njit(cache=True)
def _deriv(y, cmd, dy):
    """Kinematic derivative of y = [lat, lon, h, V, chi, gamma]."""
    lat, h, v, chi, gam = y[0], y[2], y[3], y[4], y[5]
    sl = np.sin(lat)
    w2 = 1.0 - E2 * sl * sl
    rn = A / np.sqrt(w2)
    rm = A * (1.0 - E2) / (w2 * np.sqrt(w2))
    cg = np.cos(gam)
    dy[0] = v * np.cos(chi) * cg / (rm + h)
    dy[1] = v * np.sin(chi) * cg / ((rn + h) * np.cos(lat))
    dy[2] = v * np.sin(gam)
    dy[3] = cmd[0]
    dy[4] = cmd[1]
    dy[5] = cmd[2]


@njit(cache=True)
def _rates(y, cmd, roll0, w_out, f_out, nav_out):
    """Body rate ω_ib^b [rad/s], specific force f^b [m/s^2] and the nav outputs at state y.

    nav_out = [vE, vN, vU, roll, pitch, heading].
    """
    lat, h, v, chi, gam = y[0], y[2], y[3], y[4], y[5]
    a, r, qg, dr = cmd[0], cmd[1], cmd[2], cmd[4]
    sl, cl = np.sin(lat), np.cos(lat)
    w2 = 1.0 - E2 * sl * sl
    rn = A / np.sqrt(w2)
    rm = A * (1.0 - E2) / (w2 * np.sqrt(w2))
    sc, cc = np.sin(chi), np.cos(chi)
    sg, cg = np.sin(gam), np.cos(gam)
    ve, vn, vu = v * sc * cg, v * cc * cg, v * sg
    # acceleration in n
    ae = a * sc * cg + v * (r * cc * cg - qg * sc * sg)
    an = a * cc * cg + v * (-r * sc * cg - qg * cc * sg)
    au = a * sg + v * qg * cg
    # attitude
    x = v * r / G0
    roll = roll0 + np.arctan(x)
    droll = (a * r + v * dr) / G0 / (1.0 + x * x)
    pitch = gam
    dpitch = qg
    dpsi = -r
    sr, cr = np.sin(roll), np.cos(roll)
    sp, cp = np.sin(pitch), np.cos(pitch)
    sy, cy = -sc, cc  # psi = -heading
    # C_b^n
    c00 = cy * cr - sy * sp * sr
    c01 = -sy * cp
    c02 = cy * sr + sy * sp * cr
    c10 = sy * cr + cy * sp * sr
    c11 = cy * cp
    c12 = sy * sr - cy * sp * cr
    c20 = -cp * sr
    c21 = sp
    c22 = cp * cr
    # omega_nb^b from Euler rates
    wx = cr * dpitch - sr * cp * dpsi
    wy = sp * dpsi + droll
    wz = sr * dpitch + cr * cp * dpsi
    # omega_in^n
    wie_n, wie_u = OMEGA_IE * cl, OMEGA_IE * sl
    wen_e, wen_n, wen_u = -vn / (rm + h), ve / (rn + h), ve * sl / cl / (rn + h)
    ie, in_, iu = wen_e, wie_n + wen_n, wie_u + wen_u
    w_out[0] = wx + c00 * ie + c10 * in_ + c20 * iu
    w_out[1] = wy + c01 * ie + c11 * in_ + c21 * iu
    w_out[2] = wz + c02 * ie + c12 * in_ + c22 * iu
    # f^n = a + (2 wie + wen) x v - g^n
    cx, cy2, cz = wen_e, 2 * wie_n + wen_n, 2 * wie_u + wen_u
    g = gravity(lat, h)
    fe = ae + (cy2 * vu - cz * vn)
    fn = an + (cz * ve - cx * vu)
    fu = au + (cx * vn - cy2 * ve) + g
    f_out[0] = c00 * fe + c10 * fn + c20 * fu
    f_out[1] = c01 * fe + c11 * fn + c21 * fu
    f_out[2] = c02 * fe + c12 * fn + c22 * fu
    nav_out[0], nav_out[1], nav_out[2] = ve, vn, vu
    nav_out[3], nav_out[4], nav_out[5] = roll, pitch, chi


@njit(cache=True)
def generate(tb, half, vals, y0, roll0, dt, n):
    """Integrate the motion and return truth and exact IMU increments.

    Parameters
    ----------
    tb, half, vals : primitive segments (see :func:`_commands`), times relative to the start [s].
    y0 : (6,) initial [lat, lon (rad), h (m), V (m/s), χ (rad), γ (rad)].
    roll0 : constant roll offset [rad] added to the coordinated bank.
    dt : IMU interval [s]; n : number of IMU samples.

    Returns
    -------
    truth : (n+1, 10) [t, lat, lon, h, vE, vN, vU, roll, pitch, heading(χ, unwrapped)] at t = k·dt.
    dtheta, dv : (n, 3) increments over ((k-1)dt, k dt] [rad], [m/s], body RFU.
    """
    truth = np.empty((n + 1, 10))
    dth = np.empty((n, 3))
    dvv = np.empty((n, 3))
    y = y0.copy()
    cmd0 = np.empty(6)
    cmdm = np.empty(6)
    cmd1 = np.empty(6)
    f0 = np.empty(6)
    k2 = np.empty(6)
    k3 = np.empty(6)
    k4 = np.empty(6)
    ytmp = np.empty(6)
    ym = np.empty(6)
    w0 = np.empty(3)
    a0 = np.empty(3)
    wm = np.empty(3)
    am = np.empty(3)
    w1 = np.empty(3)
    a1 = np.empty(3)
    nav = np.empty(6)
    _commands(0.0, tb, half, vals, cmd0)
    _deriv(y, cmd0, f0)
    _rates(y, cmd0, roll0, w0, a0, nav)
    truth[0, 0] = 0.0
    truth[0, 1:4] = y[0:3]
    truth[0, 4:10] = nav
    for k in range(n):
        t = k * dt
        _commands(t + 0.5 * dt, tb, half, vals, cmdm)
        _commands(t + dt, tb, half, vals, cmd1)
        for i in range(6):
            ytmp[i] = y[i] + 0.5 * dt * f0[i]
        _deriv(ytmp, cmdm, k2)
        for i in range(6):
            ytmp[i] = y[i] + 0.5 * dt * k2[i]
        _deriv(ytmp, cmdm, k3)
        for i in range(6):
            ytmp[i] = y[i] + dt * k3[i]
        _deriv(ytmp, cmd1, k4)
        for i in range(6):
            ym[i] = y[i]  # keep y0 of the step
            y[i] = y[i] + dt / 6.0 * (f0[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        # derivative at the end (reused as k1 of the next step) and Hermite mid state
        _deriv(y, cmd1, k4)
        for i in range(6):
            ym[i] = 0.5 * (ym[i] + y[i]) + dt / 8.0 * (f0[i] - k4[i])
            f0[i] = k4[i]
        _rates(ym, cmdm, roll0, wm, am, nav)
        _rates(y, cmd1, roll0, w1, a1, nav)
        for i in range(3):
            dth[k, i] = dt / 6.0 * (w0[i] + 4.0 * wm[i] + w1[i])
            dvv[k, i] = dt / 6.0 * (a0[i] + 4.0 * am[i] + a1[i])
            w0[i] = w1[i]
            a0[i] = a1[i]
        truth[k + 1, 0] = t + dt
        truth[k + 1, 1:4] = y[0:3]
        truth[k + 1, 4:10] = nav
    return truth, dth, dvv


def half_widths(tb: np.ndarray, transition: float) -> np.ndarray:
    """Half transition widths at each segment start: ½·min(transition, previous and next duration)."""
    tb = np.asarray(tb, dtype=float)
    dur = np.diff(np.append(tb, np.inf))
    half = np.zeros_like(tb)
    for j in range(1, len(tb)):
        half[j] = 0.5 * min(transition, dur[j - 1], dur[j])
    return half
