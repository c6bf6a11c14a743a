"""Dipole-triad (three co-located orthogonal electric dipoles) signal simulator, seed 002 / §3.2.

Signal model (verified in §3.2): complex snapshots of the three dipole outputs, in the seed's
antenna frame I (FLU: x nose, y left wing, z up),

    S(t) = A s(t) + e(t),   A = cosη ṽ1 + i sinη ṽ2  (‖A‖ = 1, :func:`aidnav.nav.wave_frame.steering_vector`)

with s(t) ~ CN(0, P) and e(t) ~ CN(0, σ² I) circular complex Gaussian, white in time, so that
S ~ CN(0, R), R = P A Aᴴ + σ² I. SNR ρ = P/σ² (per dipole; signal power over the noise power of one
channel), SNR_dB = 10 log10 ρ.

The geometry helpers compute the wave parameters (φ, θ, γ) that an aircraft with attitude C_b^n
(ENU/RFU, ``docs/conventions.md``) sees from a base station at a given bearing/elevation, transmitting a
wave with tilt γ′ (the inverse of the attitude steps of §3.4, exact for any distance: the
base's and the aircraft's geographic frames are related by ``base_to_local``).

Angles in radians, distances in metres.
"""

from __future__ import annotations

import numpy as np

from aidnav.nav.earth import lla_to_enu
from aidnav.nav.rotations import wrap_2pi
from aidnav.nav.wave_frame import (
    P_SEED,
    base_wave_dcm_enu,
    enu_rotation_between,
    steering_vector,
    wave_params_from_dcm_full,
)

__all__ = ["simulate_snapshots", "sample_covariance", "wave_params_for_attitude", "base_geometry"]


def simulate_snapshots(phi, theta, gamma, eta, snr_db, n, rng: np.random.Generator, power=1.0,
                       runs: int | None = None) -> np.ndarray:
    """Complex dipole-triad snapshots S(t) = A s(t) + e(t) in the seed's antenna frame I (FLU).

    phi, theta, gamma, eta : wave parameters [rad] (§3.2); snr_db : 10 log10(P/σ²);
    n : snapshots; rng : numpy Generator; power : P (σ² = P/ρ); runs : independent realisations.

    Returns (n, 3) complex, or (runs, n, 3) when ``runs`` is given. Rows are snapshots [s_x, s_y, s_z].
    ``snr_db`` may be any real number (negative: below the noise; +inf: noise-free); ValueError for NaN
    or −inf (ρ = 0, no signal), n or runs not an integer ≥ 1, and power not finite and > 0.
    """
    if np.isnan(snr_db) or snr_db == -np.inf:
        raise ValueError(f"snr_db must be a number > -inf (linear SNR > 0), got {snr_db!r}")
    for name, k in (("n", n), ("runs", 1 if runs is None else runs)):
        if np.ndim(k) != 0 or not np.isfinite(k) or k < 1 or k != int(k):
            raise ValueError(f"{name} must be an integer >= 1, got {k!r}")
    if not (np.isfinite(power) and power > 0):
        raise ValueError(f"power must be finite and > 0, got {power!r}")
    n = int(n)
    runs = None if runs is None else int(runs)
    a = steering_vector(phi, theta, gamma, eta)
    rho = 10.0 ** (snr_db / 10.0)
    sig2 = power / rho
    shape = (n,) if runs is None else (runs, n)
    s = np.sqrt(power / 2.0) * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape))
    e = np.sqrt(sig2 / 2.0) * (rng.standard_normal(shape + (3,)) + 1j * rng.standard_normal(shape + (3,)))
    return s[..., None] * a + e


def sample_covariance(S: np.ndarray) -> np.ndarray:
    """R̂ = (1/N) Σ S(t) S(t)ᴴ of snapshots (..., N, 3) → (..., 3, 3) Hermitian.

    ValueError for S not of shape (..., N, 3) with N ≥ 1 (zero snapshots) or with NaN/inf entries."""
    S = np.asarray(S)
    if S.ndim < 2 or S.shape[-1] != 3 or S.shape[-2] < 1:
        raise ValueError(f"S must have shape (..., N, 3) with N >= 1 snapshots, got {S.shape}")
    if not np.all(np.isfinite(S)):
        raise ValueError("S (snapshots) contains NaN or inf")
    return np.einsum("...ti,...tj->...ij", S, S.conj()) / S.shape[-2]


def wave_params_for_attitude(C_bn, bearing, elevation, tx_tilt, base_to_local=None):
    """Wave parameters (φ, θ, γ) [rad] seen by the triad of an aircraft with attitude ``C_bn``.

    C_bn : C_b^n (RFU → ENU of the aircraft's local level); bearing : azimuth of the aircraft seen from
    the base, clockwise from North [rad]; elevation : elevation of the aircraft seen from the base [rad];
    tx_tilt : γ′, tilt of the arriving wave's major axis in the (v1, v2) basis of the arrival direction
    in the base frame [rad]; base_to_local : C_{n_base}^{n} (base ENU → aircraft ENU), identity when None
    (the seed's flat-Earth assumption).

    Returns (φ, θ, γ) in the seed's antenna frame I (FLU), γ ∈ (−π, π] (the frame itself, not folded).
    """
    C_wnb = base_wave_dcm_enu(bearing, elevation, tx_tilt)  # W -> base ENU
    M = np.eye(3) if base_to_local is None else np.asarray(base_to_local)
    C_bw = C_wnb.T @ M.T @ np.asarray(C_bn)  # body RFU -> W
    C_IW = C_bw @ P_SEED  # I (FLU) -> W, since v_RFU = P v_FLU
    return wave_params_from_dcm_full(C_IW)


def base_geometry(lat_base, lon_base, h_base, lat, lon, h):
    """Bearing and elevation of the aircraft seen from the base (exact, in the base's ENU) [rad], range
    [m], and C_{n_base}^{n} (base ENU → aircraft ENU). Positions geodetic [rad, rad, m]."""
    e, n_, u = lla_to_enu(lat, lon, h, lat_base, lon_base, h_base)
    rng_ = float(np.sqrt(e * e + n_ * n_ + u * u))
    bearing = float(wrap_2pi(np.arctan2(e, n_)))
    elev = float(np.arcsin(u / rng_))
    return bearing, elev, rng_, enu_rotation_between(lat_base, lon_base, lat, lon)
