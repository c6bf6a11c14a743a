"""Attitude algebra: DCM, quaternion, Euler angles, rotation vector.

Conventions (stated once, used everywhere; ``docs/conventions.md``):

* ``C`` is ``C_b^n``: maps body (RFU) vectors to nav (ENU) vectors, v^n = C v^b.
* Quaternions are Hamilton, scalar first ``[q0, q1, q2, q3]``, ``q = q_b^n`` with
  v^n = q ⊗ v^b ⊗ q*.
* Euler angles are ``(roll, pitch, heading)`` in **radians**: heading clockwise from true North in
  [0, 2π), pitch nose up in [-π/2, π/2], roll right wing down in (-π, π].
  ``C_b^n = R3(-heading) · R1(pitch) · R2(roll)`` with active elementary rotations.
* Rotation vectors are in radians; ``quat_from_rotvec(r)`` is the rotation by |r| about r/|r|.
* Attitude error φ (small rotation vector in n): ``C(computed) = (I - [φ×]) C(true)``.

All functions are numba-compiled; the ``*_batch`` functions take ``(N, 3)`` / ``(N, 4)`` arrays.
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit

TWO_PI = 2.0 * np.pi


@njit(cache=True)
def skew(v):
    """Skew-symmetric matrix [v×] such that [v×] w = v × w."""
    m = np.zeros((3, 3))
    m[0, 1], m[0, 2] = -v[2], v[1]
    m[1, 0], m[1, 2] = v[2], -v[0]
    m[2, 0], m[2, 1] = -v[1], v[0]
    return m


@njit(cache=True, inline="always")
def cross(a, b):
    """Cross product of two length-3 arrays (inlined: the measurement models call it often)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(cache=True)
def dcm_from_euler(roll, pitch, heading):
    """C_b^n from roll, pitch, heading [rad] (see module conventions)."""
    sr, cr = np.sin(roll), np.cos(roll)
    sp, cp = np.sin(pitch), np.cos(pitch)
    # yaw psi = -heading
    sy, cy = -np.sin(heading), np.cos(heading)
    c = np.empty((3, 3))
    # R3(psi) R1(pitch) R2(roll)
    c[0, 0] = cy * cr - sy * sp * sr
    c[0, 1] = -sy * cp
    c[0, 2] = cy * sr + sy * sp * cr
    c[1, 0] = sy * cr + cy * sp * sr
    c[1, 1] = cy * cp
    c[1, 2] = sy * sr - cy * sp * cr
    c[2, 0] = -cp * sr
    c[2, 1] = sp
    c[2, 2] = cp * cr
    return c


@njit(cache=True)
def euler_from_dcm(c):
    """(roll, pitch, heading) [rad] from C_b^n; heading in [0, 2π), roll in (-π, π].

    At pitch = ±90° (gimbal lock) roll and heading are not separable; roll is then set to 0 and the
    whole rotation about the vertical is given to heading.
    """
    s = min(1.0, max(-1.0, c[2, 1]))
    pitch = np.arcsin(s)
    if abs(c[2, 0]) < 1e-12 and abs(c[2, 2]) < 1e-12:
        roll = 0.0
        heading = np.arctan2(c[1, 0], c[0, 0])  # psi = atan2(C10, C00) with roll = 0 → heading = -psi
        heading = -heading
    else:
        roll = np.arctan2(-c[2, 0], c[2, 2])
        heading = np.arctan2(c[0, 1], c[1, 1])
    heading = wrap_2pi(heading)
    if roll <= -np.pi:
        roll += TWO_PI
    return roll, pitch, heading


@njit(cache=True)
def quat_mult(p, q):
    """Hamilton product p ⊗ q (scalar first)."""
    r = np.empty(4)
    r[0] = p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3]
    r[1] = p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2]
    r[2] = p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1]
    r[3] = p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0]
    return r


@njit(cache=True)
def quat_conj(q):
    """Conjugate (inverse of a unit quaternion)."""
    return np.array([q[0], -q[1], -q[2], -q[3]])


@njit(cache=True)
def quat_normalize(q):
    """Unit quaternion with non-negative scalar part."""
    n = np.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
    if q[0] < 0:
        n = -n
    return q / n


@njit(cache=True, inline="always")
def _half_angle(a2):
    """cos(a/2) and sin(a/2)/a of the angle a = √a2 [rad]; 4th-order series for a² < 1e-8 (exact to
    float64 there, and no loss of relative precision as a → 0)."""
    if a2 < 1e-8:
        return 1.0 - a2 / 8.0 + a2 * a2 / 384.0, 0.5 - a2 / 48.0 + a2 * a2 / 3840.0
    a = np.sqrt(a2)
    return np.cos(0.5 * a), np.sin(0.5 * a) / a


@njit(cache=True)
def quat_from_rotvec(r):
    """Quaternion of the rotation vector ``r`` [rad]; series for |r| small (exact to float64)."""
    c, s = _half_angle(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
    return np.array([c, s * r[0], s * r[1], s * r[2]])


@njit(cache=True)
def rotvec_from_quat(q):
    """Rotation vector [rad] of quaternion ``q``, angle in [0, π]."""
    if q[0] < 0:
        q = -q
    s = np.sqrt(q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
    if s < 1e-8:
        k = 2.0 / q[0] * (1.0 - s * s / (3.0 * q[0] * q[0]))
    else:
        k = 2.0 * np.arctan2(s, q[0]) / s
    return np.array([k * q[1], k * q[2], k * q[3]])


@njit(cache=True, inline="always")
def dcm_entries(q0, q1, q2, q3):
    """The entries of C_b^n of q_b^n = (q0, q1, q2, q3), row by row, as nine scalars (no array: for
    the per-sample paths of the kernels)."""
    return (q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2),
            2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 - q0 * q1),
            2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3)


@njit(cache=True)
def dcm_from_quat(q):
    """DCM of quaternion ``q`` (q_b^n → C_b^n)."""
    c = np.empty((3, 3))
    c[0, 0], c[0, 1], c[0, 2], c[1, 0], c[1, 1], c[1, 2], c[2, 0], c[2, 1], c[2, 2] = dcm_entries(
        q[0], q[1], q[2], q[3])
    return c


@njit(cache=True)
def quat_from_dcm(c):
    """Quaternion (scalar first, q0 ≥ 0) of a DCM, by Shepperd's numerically stable method."""
    tr = c[0, 0] + c[1, 1] + c[2, 2]
    q = np.empty(4)
    if tr >= c[0, 0] and tr >= c[1, 1] and tr >= c[2, 2]:
        s = 2.0 * np.sqrt(1.0 + tr)
        q[0] = 0.25 * s
        q[1] = (c[2, 1] - c[1, 2]) / s
        q[2] = (c[0, 2] - c[2, 0]) / s
        q[3] = (c[1, 0] - c[0, 1]) / s
    elif c[0, 0] >= c[1, 1] and c[0, 0] >= c[2, 2]:
        s = 2.0 * np.sqrt(1.0 + c[0, 0] - c[1, 1] - c[2, 2])
        q[0] = (c[2, 1] - c[1, 2]) / s
        q[1] = 0.25 * s
        q[2] = (c[0, 1] + c[1, 0]) / s
        q[3] = (c[0, 2] + c[2, 0]) / s
    elif c[1, 1] >= c[2, 2]:
        s = 2.0 * np.sqrt(1.0 + c[1, 1] - c[0, 0] - c[2, 2])
        q[0] = (c[0, 2] - c[2, 0]) / s
        q[1] = (c[0, 1] + c[1, 0]) / s
        q[2] = 0.25 * s
        q[3] = (c[1, 2] + c[2, 1]) / s
    else:
        s = 2.0 * np.sqrt(1.0 + c[2, 2] - c[0, 0] - c[1, 1])
        q[0] = (c[1, 0] - c[0, 1]) / s
        q[1] = (c[0, 2] + c[2, 0]) / s
        q[2] = (c[1, 2] + c[2, 1]) / s
        q[3] = 0.25 * s
    return quat_normalize(q)


@njit(cache=True)
def dcm_from_rotvec(r):
    """DCM of a rotation vector (Rodrigues: I + sin a/a [r×] + (1 − cos a)/a² [r×]², by half angles)."""
    ch, sh = _half_angle(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
    k = skew(r)
    return np.eye(3) + (2.0 * ch * sh) * k + (2.0 * sh * sh) * (k @ k)


@njit(cache=True)
def rotvec_from_dcm(c):
    """Rotation vector [rad] of a DCM."""
    return rotvec_from_quat(quat_from_dcm(c))


@njit(cache=True)
def quat_from_euler(roll, pitch, heading):
    """q_b^n from roll, pitch, heading [rad]."""
    return quat_from_dcm(dcm_from_euler(roll, pitch, heading))


@njit(cache=True)
def euler_from_quat(q):
    """(roll, pitch, heading) [rad] of q_b^n."""
    return euler_from_dcm(dcm_from_quat(q))


@njit(cache=True)
def quat_rotate(q, v):
    """Rotate vector ``v`` by ``q``: returns q ⊗ v ⊗ q* (= C(q) v)."""
    return dcm_from_quat(q) @ v


@njit(cache=True)
def quat_update(q, rotvec):
    """Right-multiply ``q`` by the rotation ``rotvec`` (body-frame increment): q ⊗ q(rotvec), normalised."""
    return quat_normalize(quat_mult(q, quat_from_rotvec(rotvec)))


@njit(cache=True)
def small_angle_dcm(phi):
    """First-order DCM I + [φ×] for a small rotation vector φ [rad]."""
    return np.eye(3) + skew(phi)


# ----------------------------------------------------------------------------------- batches
@njit(cache=True)
def euler_to_quat_batch(rph):
    """(N, 3) array of (roll, pitch, heading) [rad] → (N, 4) quaternions q_b^n."""
    n = rph.shape[0]
    out = np.empty((n, 4))
    for i in range(n):
        out[i] = quat_from_euler(rph[i, 0], rph[i, 1], rph[i, 2])
    return out


@njit(cache=True)
def quat_to_euler_batch(q):
    """(N, 4) quaternions q_b^n → (N, 3) (roll, pitch, heading) [rad]."""
    n = q.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        r, p, h = euler_from_quat(q[i])
        out[i, 0], out[i, 1], out[i, 2] = r, p, h
    return out


@njit(cache=True)
def attitude_error_batch(q_est, q_true):
    """Misalignment φ [rad] in n with C_est = (I - [φ×]) C_true, for (N, 4) arrays.

    φ is the rotation vector of C_true C_est^T (exact, not only small-angle).
    """
    n = q_est.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        d = quat_mult(q_true[i], quat_conj(q_est[i]))
        out[i] = rotvec_from_quat(d)
    return out


# ------------------------------------------------------------------------------- angle wrapping
# numba functions for scalars and arrays alike (numpy arrays of any shape, floats), callable from kernels
@njit(cache=True)
def wrap_pi(a):
    """Wrap angle(s) [rad] to [-π, π)."""
    return (a + np.pi) % TWO_PI - np.pi


@njit(cache=True)
def wrap_180(a):
    """Wrap angle(s) [deg] to [-180, 180)."""
    return (a + 180.0) % 360.0 - 180.0


@njit(cache=True)
def wrap_2pi(a):
    """Wrap angle(s) [rad] to [0, 2π) (headings, azimuths)."""
    r = a % TWO_PI
    return r - TWO_PI * (r >= TWO_PI)  # a tiny negative angle rounds to 2π


@njit(cache=True)
def wrap_360(a):
    """Wrap angle(s) [deg] to [0, 360) (headings, azimuths)."""
    r = a % 360.0
    return r - 360.0 * (r >= 360.0)


def euler_error_map(rph: np.ndarray) -> np.ndarray:
    """M (…, 3, 3) with φ = M·[δroll, δpitch, δheading] for small Euler-angle errors (rad).

    φ is the misalignment of docs/conventions.md (C_computed = (I − [φ×]) C_true). With C = R3(ψ)R1(p)R2(r),
    ψ = −heading: columns −R3R1·e_y (roll), −R3·e_x (pitch), +e_z (heading).
    """
    rph = np.asarray(rph, float)
    p, h = rph[..., 1], rph[..., 2]
    sy, cy = -np.sin(h), np.cos(h)
    sp, cp = np.sin(p), np.cos(p)
    m = np.zeros(rph.shape[:-1] + (3, 3))
    # R3(ψ) e_x = [cψ, sψ, 0]; R3 R1 e_y = R3 [0, cp, sp] = [−sψ cp, cψ cp, sp]
    m[..., 0, 0], m[..., 1, 0], m[..., 2, 0] = sy * cp, -cy * cp, -sp
    m[..., 0, 1], m[..., 1, 1] = -cy, -sy
    m[..., 2, 2] = 1.0
    return m
