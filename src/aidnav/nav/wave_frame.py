"""Wave-structure frame of a polarized plane wave and the frames of seed 002 (dipole-triad attitude).

Pure geometry shared by the dipole-triad signal simulator (:mod:`aidnav.sim.dipole_triad`) and the
estimators (:mod:`aidnav.estimators.polarization`); §3.1–3.2 and §3.4.

Seed-002 frames (converted at this boundary, never inside an algorithm):

* I: antenna/body frame of the seed, **FLU** (x nose, y left wing, z up). The seed's "y right wing"
  is left-handed (§3.6 erratum 1).
* B: geographic frame at the base station, **NWU** (x North, y West, z Up).
* W: wave-structure frame with axes (u, ṽ1, ṽ2): u the unit vector from the antenna **toward** the
  source (the wave travels along −u), ṽ1 the major and ṽ2 the minor axis of the E-field ellipse.

Ours (``docs/conventions.md``): body b = RFU, nav n = ENU. ``P_SEED = [[0,−1,0],[1,0,0],[0,0,1]]`` maps
both: v_ENU = P v_NWU, v_RFU = P v_FLU, C_b^n = P C_I^B Pᵀ. P is a proper rotation (+90° about z).

Wave parameters (§3.2): direction of arrival φ (azimuth, from the I/B x axis toward y, in
(−π, π]) and θ (elevation in [−π/2, π/2]; the seed's "[0, π]" is an OCR slip), tilt γ ∈ (−π/2, π/2]
and ellipticity η ∈ [−π/4, π/4]:

    u  = [cosφ cosθ, sinφ cosθ, sinθ]
    v1 = [−sinφ, cosφ, 0]            (= up × u / |up × u|, horizontal, left of u)
    v2 = [−cosφ sinθ, −sinφ sinθ, cosθ]   (= u × v1)
    ṽ1 = cosγ v1 − sinγ v2,  ṽ2 = sinγ v1 + cosγ v2,  (u, ṽ1, ṽ2) right-handed
    A  = V Q w = cosη ṽ1 + i sinη ṽ2,  ‖A‖ = 1

``C_I^W = Rx(γ) Ry(θ) Rz(φ)`` (seed eq. 8 as printed) has rows [uᵀ; ṽ1ᵀ; ṽ2ᵀ] in I coordinates.
All angles in radians. Plain numpy (3×3 algebra; not in any per-sample loop).
"""

from __future__ import annotations

import numpy as np

from .earth import dcm_ecef_to_enu

#: Seed-002 frames → ours: v_ENU = P v_NWU, v_RFU = P v_FLU, C_b^n = P C_I^B Pᵀ.
P_SEED = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]], dtype=np.result_type(a, float))


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]], dtype=np.result_type(a, float))


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]], dtype=np.result_type(a, float))


def wave_vectors(phi, theta, gamma):
    """(u, ṽ1, ṽ2) of the wave frame, each (3,), in the frame where (φ, θ) are measured [rad].

    Works with complex arguments too (used for complex-step derivatives).
    """
    cp, sp = np.cos(phi), np.sin(phi)
    ct, st = np.cos(theta), np.sin(theta)
    cg, sg = np.cos(gamma), np.sin(gamma)
    u = np.array([cp * ct, sp * ct, st])
    v1 = np.array([-sp, cp, 0.0 * sp])
    v2 = np.array([-cp * st, -sp * st, ct])
    return u, cg * v1 - sg * v2, sg * v1 + cg * v2


def wave_dcm(phi, theta, gamma):
    """C_I^W = Rx(γ) Ry(θ) Rz(φ) (seed eq. 8): rows u, ṽ1, ṽ2; maps I (or B) coordinates to W."""
    return _rx(gamma) @ _ry(theta) @ _rz(phi)


def wave_dcm_derivatives(phi, theta, gamma):
    """(∂C/∂φ, ∂C/∂θ, ∂C/∂γ) of :func:`wave_dcm`, each 3×3 (analytic)."""
    X, Y, Z = _rx(gamma), _ry(theta), _rz(phi)
    cp, sp = np.cos(phi), np.sin(phi)
    ct, st = np.cos(theta), np.sin(theta)
    cg, sg = np.cos(gamma), np.sin(gamma)
    dZ = np.array([[-sp, cp, 0.0], [-cp, -sp, 0.0], [0.0, 0.0, 0.0]])
    dY = np.array([[-st, 0.0, ct], [0.0, 0.0, 0.0], [-ct, 0.0, -st]])
    dX = np.array([[0.0, 0.0, 0.0], [0.0, -sg, -cg], [0.0, cg, -sg]])
    return X @ Y @ dZ, X @ dY @ Z, dX @ Y @ Z


def wave_params_from_dcm(C):
    """(φ, θ, γ) [rad] of a wave-frame DCM with rows u, ṽ1, ṽ2 (inverse of :func:`wave_dcm`).

    φ ∈ (−π, π], θ ∈ [−π/2, π/2]; γ is returned in (−π/2, π/2]: γ and γ + π describe the same
    polarization subspace (A → −A), so the steering vector cannot tell them apart. The frame of the
    returned angles may therefore differ from ``C`` by a rotation of π about u (the line-of-sight
    ambiguity, §3.3); use :func:`wave_params_from_dcm_full` to keep it.
    """
    phi, theta, gamma = wave_params_from_dcm_full(C)
    return phi, theta, wrap_tilt(gamma)


def wave_params_from_dcm_full(C):
    """(φ, θ, γ) [rad] of a wave-frame DCM, γ ∈ (−π, π] (no folding; ``wave_dcm`` round-trips)."""
    u, t1 = C[0], C[1]
    phi = float(np.arctan2(u[1], u[0]))
    theta = float(np.arcsin(np.clip(u[2], -1.0, 1.0)))
    _, v1, v2 = wave_vectors(phi, theta, 0.0)
    gamma = float(np.arctan2(-(t1 @ v2), t1 @ v1))
    return phi, theta, gamma


def wrap_tilt(gamma):
    """Fold a tilt angle [rad] into (−π/2, π/2] (tilt is defined modulo π)."""
    g = (np.asarray(gamma, dtype=float) + 0.5 * np.pi) % np.pi - 0.5 * np.pi
    g = np.where(g <= -0.5 * np.pi + 1e-15, g + np.pi, g)
    return float(g) if np.ndim(g) == 0 else g


def steering_vector(phi, theta, gamma, eta):
    """Polarization–space steering vector A = cosη ṽ1 + i sinη ṽ2 (complex (3,), ‖A‖ = 1) [rad].

    Equals the seed's V Q w and its component form (§3.2, verified).
    """
    _, t1, t2 = wave_vectors(phi, theta, gamma)
    return np.cos(eta) * t1 + 1j * np.sin(eta) * t2


def steering_derivatives(phi, theta, gamma, eta):
    """D = [∂A/∂φ, ∂A/∂θ, ∂A/∂γ] (complex 3×3, analytic) of :func:`steering_vector`."""
    w = np.array([0.0, np.cos(eta), 1j * np.sin(eta)])  # A = Cᵀ w (the rows of C are u, ṽ1, ṽ2)
    return np.column_stack([d.T @ w for d in wave_dcm_derivatives(phi, theta, gamma)])


def vee(M):
    """Vector of a skew-symmetric matrix M = [v×]."""
    return np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]]) * 0.5


def wave_rotation_jacobian(phi, theta, gamma):
    """J (3×3): small wave-frame rotation δ (components about u, ṽ1, ṽ2) per (dφ, dθ, dγ).

    δ is defined by C_I^W(p + dp) = (I − [δ×]) C_I^W(p), δ = J dp (first order). This is the seed's
    CVAE matrix up to the sign convention of the rotation vector (§3.5).
    """
    C = wave_dcm(phi, theta, gamma)
    return np.column_stack([vee(-(d @ C.T)) for d in wave_dcm_derivatives(phi, theta, gamma)])


# ------------------------------------------------------------------ base-station side (§3.4)
def base_wave_dcm(base_azimuth_ccw, base_elevation, tx_tilt):
    """C_W^B (corrected eq. 9): maps wave-frame coordinates to the base's NWU frame B.

    base_azimuth_ccw : φ′, azimuth of the aircraft seen from the base, counter-clockwise from North
        toward West [rad] (seed convention; = −bearing); base_elevation : θ′ [rad];
    tx_tilt : γ′, the tilt of the major axis of the wave arriving at the aircraft, defined with the
        (v1, v2) basis of the arrival direction expressed in B [rad].

    The arrival direction (aircraft → base) in B has azimuth φ′ + π and elevation −θ′, so
    C_W^B = [Rx(γ′) Ry(−θ′) Rz(φ′ + π)]ᵀ. The seed prints Ry(+θ′)ᵀ in the middle: a sign error for an
    aircraft above the base (§3.6 erratum 6).
    """
    return wave_dcm(base_azimuth_ccw + np.pi, -base_elevation, tx_tilt).T


def base_wave_dcm_enu(bearing, base_elevation, tx_tilt):
    """C_W^{n_base}: wave frame → the base's ENU frame, from the bearing of the aircraft seen from the
    base (clockwise from North, like heading) [rad], its elevation [rad] and the tilt γ′ [rad]."""
    return P_SEED @ base_wave_dcm(-bearing, base_elevation, tx_tilt)


def seed_to_ours_dcm(C_I_B):
    """C_b^n (RFU → ENU) from the seed's C_I^B (FLU → NWU): P C Pᵀ."""
    return P_SEED @ C_I_B @ P_SEED.T


def ours_to_seed_dcm(C_b_n):
    """The seed's C_I^B (FLU → NWU) from C_b^n (RFU → ENU): Pᵀ C P."""
    return P_SEED.T @ C_b_n @ P_SEED


def enu_rotation_between(lat_from, lon_from, lat_to, lon_to):
    """C_{n_from}^{n_to}: rotation from the ENU frame at (lat_from, lon_from) to the ENU frame at
    (lat_to, lon_to) [rad] (through ECEF). Identity for the same point. Used to take an attitude
    referred to the base station's geographic frame into the aircraft's local-level frame; the seed
    takes the two as parallel (flat Earth), which errs by the great-circle angle between them
    (≈ 0.09° per 10 km)."""

    return dcm_ecef_to_enu(float(lat_to), float(lon_to)) @ dcm_ecef_to_enu(float(lat_from), float(lon_from)).T


__all__ = ["P_SEED", "wave_vectors", "wave_dcm", "wave_dcm_derivatives", "wave_params_from_dcm",
           "wave_params_from_dcm_full", "wrap_tilt", "steering_vector", "steering_derivatives", "vee",
           "wave_rotation_jacobian", "base_wave_dcm", "base_wave_dcm_enu", "seed_to_ours_dcm",
           "ours_to_seed_dcm", "enu_rotation_between"]
