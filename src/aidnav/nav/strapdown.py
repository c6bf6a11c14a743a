"""Strapdown INS mechanization in the local-level ENU frame, from IMU increments.

Frames and units (``docs/conventions.md``): body b = RFU, nav n = ENU, position (lat, lon [rad], h [m]),
velocity v^n [m/s], attitude q_b^n (Hamilton, scalar first). IMU input: increments Δθ [rad] and
Δv [m/s] over (t_{k-1}, t_k], body frame.

Algorithm per IMU interval T_k = t_k - t_{k-1} (one sample per update, plus the previous sample for
the coning and sculling corrections, i.e. the classic "one-sample + previous-cycle" form):

* attitude: body rotation vector φ_b = Δθ_k + (Δθ_{k-1} × Δθ_k)/12 (coning), nav-frame rotation
  ω_in^n T (Earth rate + transport rate, at the mid-interval position and velocity);
  q_k = q(-ω_in T) ⊗ q_{k-1} ⊗ q(φ_b).
* velocity: Δv_sf^b = Δv_k + ½ Δθ_k × Δv_k (rotation) + (Δθ_{k-1} × Δv_k + Δv_{k-1} × Δθ_k)/12
  (sculling); v_k = v_{k-1} + (I - ½[ω_in T ×]) C_b^n(k-1) Δv_sf^b + (g^n - (2ω_ie + ω_en) × v) T.
* position: trapezoidal velocity, radii and cos L at the mid-interval latitude and height.

The state vector used by the kernels is a float64 array of 10 numbers
``[lat, lon, h, vE, vN, vU, q0, q1, q2, q3]`` (``STATE_*`` indices below).
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit

from .earth import E2, OMEGA_IE, A, gravity
from .rotations import dcm_entries

LAT, LON, HGT, VE, VN, VU, Q0 = 0, 1, 2, 3, 4, 5, 6
NSTATE = 10


@njit(cache=True, inline="always")
def _rv2q(x, y, z):
    """Quaternion components of a rotation vector (series below 0.05 rad, exact above)."""
    a2 = x * x + y * y + z * z
    if a2 < 2.5e-3:
        c = 1.0 - a2 * (1.0 / 8.0 - a2 / 384.0)
        s = 0.5 - a2 * (1.0 / 48.0 - a2 / 3840.0)
    else:
        a = np.sqrt(a2)
        c = np.cos(0.5 * a)
        s = np.sin(0.5 * a) / a
    return c, s * x, s * y, s * z


@njit(cache=True, inline="always")  # per sample: inlined (a call passed 5 arrays, 10 refcount ops: issue 40)
def strapdown_step(st, dth, dvb, dth_prev, dv_prev, dt):
    """Advance the state ``st`` (length-10 array, updated in place) by one IMU interval.

    ``dth``, ``dvb``: increments of this interval [rad], [m/s] (body RFU); ``dth_prev``, ``dv_prev``:
    those of the previous interval (zeros at the first sample) for coning/sculling; ``dt`` [s].
    """
    ax, ay, az = dth[0], dth[1], dth[2]
    px, py, pz = dth_prev[0], dth_prev[1], dth_prev[2]
    vx, vy, vz = dvb[0], dvb[1], dvb[2]
    ux, uy, uz = dv_prev[0], dv_prev[1], dv_prev[2]
    phx, phy, phz, sx, sy, sz = _coning_sculling((ax, ay, az), (px, py, pz), (vx, vy, vz), (ux, uy, uz))
    _strapdown_core(st, phx, phy, phz, sx, sy, sz, dt)


@njit(cache=True, inline="always")  # per sample: inlined
def strapdown_step_rows(st, b, dt):
    """:func:`strapdown_step` with the increments as rows of one array ``b`` (≥ 4, 3): this interval's Δθ,
    Δv, then the previous interval's. One array where the kernel's per-sample loop passed four views of
    it: each inlined argument cost an atomic reference-count increment and decrement per sample (issue 40,
    session 16). The same arithmetic, so the same bits."""
    ax, ay, az = b[0, 0], b[0, 1], b[0, 2]
    px, py, pz = b[2, 0], b[2, 1], b[2, 2]
    vx, vy, vz = b[1, 0], b[1, 1], b[1, 2]
    ux, uy, uz = b[3, 0], b[3, 1], b[3, 2]
    phx, phy, phz, sx, sy, sz = _coning_sculling((ax, ay, az), (px, py, pz), (vx, vy, vz), (ux, uy, uz))
    _strapdown_core(st, phx, phy, phz, sx, sy, sz, dt)


@njit(cache=True, inline="always")
def _coning_sculling(a, p, v, u):
    """Coning and sculling of one interval from this interval's Δθ = a, Δv = v and the previous interval's
    Δθ = p, Δv = u (body; tuples of three floats, no array: nothing to reference-count per sample): the
    rotation vector φ and the velocity increment s, as six scalars."""
    ax, ay, az = a
    px, py, pz = p
    vx, vy, vz = v
    ux, uy, uz = u
    phx = ax + (py * az - pz * ay) / 12.0
    phy = ay + (pz * ax - px * az) / 12.0
    phz = az + (px * ay - py * ax) / 12.0
    sx = vx + 0.5 * (ay * vz - az * vy) + ((py * vz - pz * vy) + (uy * az - uz * ay)) / 12.0
    sy = vy + 0.5 * (az * vx - ax * vz) + ((pz * vx - px * vz) + (uz * ax - ux * az)) / 12.0
    sz = vz + 0.5 * (ax * vy - ay * vx) + ((px * vy - py * vx) + (ux * ay - uy * ax)) / 12.0
    return phx, phy, phz, sx, sy, sz


@njit(cache=True, inline="always")
def _strapdown_core(st, phx, phy, phz, sx, sy, sz, dt):
    """The strapdown step after coning and sculling: rotation vector φ and velocity increment s (body)."""
    lat, h = st[0], st[2]
    ve, vn, vu = st[3], st[4], st[5]
    q0, q1, q2, q3 = st[6], st[7], st[8], st[9]

    sl = np.sin(lat)
    cl = np.cos(lat)
    w2 = 1.0 - E2 * sl * sl
    w = np.sqrt(w2)
    rn = A / w
    rm = A * (1.0 - E2) / (w2 * w)
    rmh = rm + h
    rnh = rn + h
    # Earth and transport rates in ENU
    wie_n = OMEGA_IE * cl
    wie_u = OMEGA_IE * sl
    wen_e = -vn / rmh
    wen_n = ve / rnh
    wen_u = ve * sl / cl / rnh
    win_e = wen_e
    win_n = wie_n + wen_n
    win_u = wie_u + wen_u

    # C_b^n(k-1) * dv_sf^b
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = dcm_entries(q0, q1, q2, q3)
    fe = c00 * sx + c01 * sy + c02 * sz
    fn = c10 * sx + c11 * sy + c12 * sz
    fu = c20 * sx + c21 * sy + c22 * sz
    # (I - 0.5 [win*dt x]) f
    hx, hy, hz = 0.5 * win_e * dt, 0.5 * win_n * dt, 0.5 * win_u * dt
    de = fe - (hy * fu - hz * fn)
    dn = fn - (hz * fe - hx * fu)
    du = fu - (hx * fn - hy * fe)
    # gravity and Coriolis: g - (2 wie + wen) x v
    cx, cy, cz = wen_e, 2 * wie_n + wen_n, 2 * wie_u + wen_u
    g = gravity(lat, h)
    ge = -(cy * vu - cz * vn)
    gn = -(cz * ve - cx * vu)
    gu = -g - (cx * vn - cy * ve)
    # second pass: Coriolis with the mid-interval velocity (predictor-corrector)
    vme = ve + 0.5 * (de + ge * dt)
    vmn = vn + 0.5 * (dn + gn * dt)
    vmu = vu + 0.5 * (du + gu * dt)
    ge = -(cy * vmu - cz * vmn)
    gn = -(cz * vme - cx * vmu)
    gu = -g - (cx * vmn - cy * vme)
    ve1 = ve + de + ge * dt
    vn1 = vn + dn + gn * dt
    vu1 = vu + du + gu * dt

    # position (trapezoidal velocity)
    # radii and cos(lat) at the mid-interval latitude/height (second order in dt)
    dlat = 0.5 * (vn + vn1) / rmh * dt
    dh = 0.5 * (vu + vu1) * dt
    latm = lat + 0.5 * dlat
    hm = h + 0.5 * dh
    slm = np.sin(latm)
    w2m = 1.0 - E2 * slm * slm
    rmm = A * (1.0 - E2) / (w2m * np.sqrt(w2m))
    rnm = A / np.sqrt(w2m)
    st[0] = lat + 0.5 * (vn + vn1) / (rmm + hm) * dt
    st[1] = st[1] + 0.5 * (ve + ve1) / ((rnm + hm) * np.cos(latm)) * dt
    st[2] = h + dh
    st[3], st[4], st[5] = ve1, vn1, vu1

    # attitude: q = q(-win dt) (x) q (x) q(phi_b), with the nav-frame rotation win evaluated at the
    # mid-interval position and velocity (start-of-interval values leave a first-order error:
    # a lag of half an interval in the transport rate, ~0.03" and ~1 m over a 1-h turning flight)
    vem = 0.5 * (ve + ve1)
    vnm = 0.5 * (vn + vn1)
    clm = np.cos(latm)
    win_e = -vnm / (rmm + hm)
    win_n = OMEGA_IE * clm + vem / (rnm + hm)
    win_u = OMEGA_IE * slm + vem * slm / clm / (rnm + hm)
    b0, b1, b2, b3 = _rv2q(phx, phy, phz)
    r0 = q0 * b0 - q1 * b1 - q2 * b2 - q3 * b3
    r1 = q0 * b1 + q1 * b0 + q2 * b3 - q3 * b2
    r2 = q0 * b2 - q1 * b3 + q2 * b0 + q3 * b1
    r3 = q0 * b3 + q1 * b2 - q2 * b1 + q3 * b0
    n0, n1, n2, n3 = _rv2q(-win_e * dt, -win_n * dt, -win_u * dt)
    s0 = n0 * r0 - n1 * r1 - n2 * r2 - n3 * r3
    s1 = n0 * r1 + n1 * r0 + n2 * r3 - n3 * r2
    s2 = n0 * r2 - n1 * r3 + n2 * r0 + n3 * r1
    s3 = n0 * r3 + n1 * r2 - n2 * r1 + n3 * r0
    nrm = np.sqrt(s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3)
    if s0 < 0:
        nrm = -nrm
    st[6], st[7], st[8], st[9] = s0 / nrm, s1 / nrm, s2 / nrm, s3 / nrm


@njit(cache=True)
def mechanize(time, dtheta, dv, state0, t0, hold_h, hold_vu):
    """Run the strapdown over a whole log.

    Parameters
    ----------
    time : (N,) sample times t_k [s], strictly increasing; sample k covers (t_{k-1}, t_k].
    dtheta, dv : (N, 3) increments [rad], [m/s], body RFU.
    state0 : (10,) initial state at time ``t0`` (< time[0]); see module doc.
    hold_h, hold_vu : (N,) arrays to hold height [m] and up velocity [m/s] to (e.g. the truth), or
        empty arrays for a free vertical channel (unstable over long runs).

    Returns
    -------
    (N, 10) array of states at ``time``.
    """
    n = time.shape[0]
    out = np.empty((n, NSTATE))
    st = state0.copy()
    zero = np.zeros(3)
    hold = hold_h.shape[0] == n
    tp = t0
    for k in range(n):
        dt = time[k] - tp
        tp = time[k]
        if k == 0:
            strapdown_step(st, dtheta[k], dv[k], zero, zero, dt)
        else:
            strapdown_step(st, dtheta[k], dv[k], dtheta[k - 1], dv[k - 1], dt)
        if hold:
            st[2] = hold_h[k]
            st[5] = hold_vu[k]
        out[k] = st
    return out


def make_state(lat, lon, h, v, q):
    """Pack (lat, lon [rad], h [m], v^n [m/s], q_b^n) into the 10-element kernel state."""
    st = np.empty(NSTATE)
    st[0], st[1], st[2] = lat, lon, h
    st[3:6] = v
    st[6:10] = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return st
