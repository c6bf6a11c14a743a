"""Aircraft attitude from a dipole triad and one polarized base-station signal (seed 002, §3).

Estimators of the wave parameters, their Cramér–Rao bounds and the attitude steps 1–4.

Frames (see :mod:`aidnav.nav.wave_frame`): the wave parameters (φ, θ, γ) are angles in the seed's
antenna frame I (FLU); η is the (known) ellipticity. Everything returned to the user is in our
conventions: C_b^n (RFU → ENU), (roll, pitch, heading) as in ``CONVENTIONS.md``, misalignment ε in n
with C_b^n(est) = (I − [ε×]) C_b^n(true). Angles in radians.

* :func:`closed_form` — seed eqs. (2)–(4) as corrected in §3.3 (eq. (3) gets its minus sign and
  |a_z|²; eq. (4), valid only for a real s(t), is replaced by the Stokes/Jones form), applied to one
  snapshot or, better, to the principal eigenvector of R̂ (:func:`closed_form_covariance`).
* :func:`ml_estimate` — the concentrated maximum likelihood of eqs. (5)–(6): with ‖A‖ = 1 and one
  source it maximises AᴴR̂A over (φ, θ, γ) (BFGS with the analytic gradient, started from the closed
  form). :func:`concentrated_loglik` is eq. (6) with the circular-complex normalisation
  (§3.6 erratum 5; the argmax is unchanged).
* :func:`crb_eq7` (seed eq. (7), correct as printed) and :func:`crb_numerical` (Slepian–Bangs Fisher
  information of the circular Gaussian model over (φ, θ, γ, P, σ²), with complex-step derivatives):
  the two agree to rounding. :func:`crb_rotation_vector` is the CVAE bound of the small rotation δ
  of the wave frame (components about u, ṽ1, ṽ2) = (1+ρ)/(2Nρ²)·diag(1/cos²2η, 1/sin²η, 1/cos²η)
  (the printed CVAE has a spurious leading "N·", §3.6 erratum 7); :func:`crb_attitude` maps it to
  the misalignment in n and to (roll, pitch, heading), which **does** depend on the geometry (§3.5:
  the seed's "independent of DOA and attitude" holds for the rotation vector only).
* :func:`attitude_from_wave` — steps 1–4: C_I^B = C_W^B C_I^W with the corrected eq. (9)
  (C_W^B = [Rx(γ′) Ry(−θ′) Rz(φ′+π)]ᵀ, §3.4), then C_b^n = P C_I^B Pᵀ, optionally rotated from
  the base's geographic frame into the aircraft's (the seed assumes them parallel — flat Earth; physics
  says they differ by the great-circle angle, so :func:`estimate_attitude` takes ``base_to_local``).
* Ambiguities (§3.3): η known removes (φ, θ, γ, η) ↔ (φ±π, −θ, −γ, −η); γ and γ + π give the same
  subspace, i.e. a 180° ambiguity of the attitude about the line of sight, resolved by
  :func:`resolve_line_of_sight` with a prior attitude (e.g. the previous epoch) or "upright".
* Bad input (all public estimators): every unobservable case raises :class:`ValueError` naming the
  parameter that cannot be estimated; no number is returned for it. From A = cosη ṽ1 + i sinη ṽ2 and the
  CVAE bound diag(1/cos²2η, 1/sin²η, 1/cos²η):

  - η = 0 (linear polarization): A = ṽ1 is real, only the major axis ṽ1 (2 degrees of freedom) is seen;
    the rotation about ṽ1 is unobservable (1/sin²η = ∞), so the DOA (φ, θ) and the tilt γ are not
    identifiable (u can be any direction ⊥ ṽ1); in the seed's nose-on geometry this is the pitch.
  - |η| = π/4 (circular polarization): a rotation α about u only multiplies A by e^{∓iα}, absorbed in
    s(t); the tilt γ (rotation about the line of sight u, 1/cos²2η = ∞) is unobservable; (φ, θ) are not.
  - |η| > π/4, non-finite η: outside the model's range.
  - estimated source at θ = ±90° (a_z = 0): the DOA parametrisation is singular (gimbal lock of
    Rx(γ)Ry(θ)Rz(φ)); the azimuth φ is undefined and only φ ∓ γ is, so φ and γ are unobservable.
  - wrong array shapes, non-finite or all-zero data, n < 1 snapshots, SNR ρ ≤ 0 (linear) in the bounds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from aidnav.jit import njit
from aidnav.nav.rotations import dcm_from_euler, euler_from_dcm, rotvec_from_dcm
from aidnav.nav.wave_frame import (
    P_SEED,
    base_wave_dcm,
    steering_vector,
    wave_dcm,
    wave_params_from_dcm,
    wave_rotation_jacobian,
    wave_vectors,
    wrap_tilt,
)

__all__ = [
    "closed_form", "principal_eigenvector", "closed_form_covariance", "power_noise", "concentrated_loglik",
    "MLResult", "ml_estimate", "objective_gradient", "crb_eq7", "crb_numerical", "crb_rotation_vector",
    "cvae_bound",
    "euler_error_jacobian", "attitude_from_wave", "crb_attitude", "resolve_line_of_sight", "AttitudeFix",
    "estimate_attitude",
]

#: |η| (or π/4 − |η|) below this [rad] counts as η = 0 (or ±45°): unobservable, see the module docstring.
ETA_TOL = 1e-9
#: |a_z| / ‖a‖ below this counts as a source at θ = ±90° (φ undefined).
ZENITH_TOL = 1e-9


def check_eta(eta) -> float:
    """η as a float; ValueError for η = 0 / ±45° (naming what becomes unobservable) or outside [−π/4, π/4]."""
    if np.ndim(eta) != 0 or not np.isrealobj(eta):
        raise ValueError(f"eta must be a real scalar [rad], got {eta!r}")
    e = float(eta)
    if not np.isfinite(e) or abs(e) > np.pi / 4 + ETA_TOL:
        raise ValueError(f"eta must be finite and in [-pi/4, pi/4] rad, got {eta!r}")
    if abs(e) < ETA_TOL:
        raise ValueError("eta = 0 (linear polarization): the rotation about the major axis is unobservable, "
                         "so the DOA (phi, theta) and the tilt gamma cannot be estimated")
    if np.pi / 4 - abs(e) < ETA_TOL:
        raise ValueError("|eta| = 45 deg (circular polarization): the tilt gamma (rotation about the line of "
                         "sight) is unobservable")
    return e


def _check_finite(x, name):
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} contains NaN or inf")


def _check_cov(R, batch: bool) -> np.ndarray:
    """R̂ as a complex array of shape (3, 3) (or (..., 3, 3) when ``batch``), finite, non-zero trace."""
    R = np.asarray(R, dtype=complex)
    if R.ndim < 2 or R.shape[-2:] != (3, 3) or (not batch and R.ndim != 2):
        want = "(..., 3, 3)" if batch else "(3, 3)"
        raise ValueError(f"R must have shape {want} (sample covariance of the triad), got {R.shape}")
    _check_finite(R, "R")
    if np.any(np.real(np.trace(R, axis1=-2, axis2=-1)) <= 0.0):
        raise ValueError("R has a non-positive trace (no data / zero snapshots)")
    return R


def check_snapshots(n) -> int:
    if np.ndim(n) != 0 or not np.isfinite(n) or n < 1 or n != int(n):
        raise ValueError(f"n (number of snapshots) must be an integer >= 1, got {n!r}")
    return int(n)


def zenith_error():
    return ValueError("source at theta = +-90 deg (a_z = 0): the DOA is singular, the azimuth phi (and the "
                      "tilt gamma, only phi -+ gamma is defined) is unobservable")


# ============================================================================ closed form (eqs. 2–4)
def closed_form(a, eta):
    """Closed-form (φ, θ, γ) [rad] from a snapshot or a steering-vector estimate ``a`` (..., 3) complex.

    §3.3 (corrected seed eqs. 2–4), with η [rad] known (η ≠ 0 for φ; |η| < π/4 for γ):

    * φ = atan2(sgn η · Im{a_x a_z*}, −sgn η · Im{a_y a_z*})  (the seed's arccot with its −π branch)
    * θ = arctan(−(Re{a_x a_z*} cos φ + Re{a_y a_z*} sin φ) / |a_z|²)  (seed: no minus sign, /s_z)
    * γ = ½ atan2(−S2·sgn cos2η, S1·sgn cos2η), with the Jones vector j = [v1ᵀa, v2ᵀa] and Stokes
      S1 = |j1|² − |j2|², S2 = 2 Re{j1 j2*} (replaces seed eq. 4, which holds for a real s(t) only).

    Exact on noise-free data for θ ∈ (−π/2, π/2) and a_z ≠ 0. Returns arrays of shape (...) each,
    γ ∈ (−π/2, π/2].

    Raises ValueError (module docstring, "Bad input"): η = 0 (φ, θ, γ unobservable), |η| = 45° (γ
    unobservable), |η| > 45° or non-finite; a source at θ = ±90° in any element (|a_z| ≤ 1e-9‖a‖: φ, γ
    unobservable); ``a`` not of shape (..., 3), non-finite or zero.
    """
    eta = check_eta(eta)
    a = np.asarray(a, dtype=complex)
    if a.ndim < 1 or a.shape[-1] != 3:
        raise ValueError(f"a must have shape (..., 3) (dipole outputs x, y, z), got {a.shape}")
    _check_finite(a, "a")
    nrm2 = np.sum(a.real**2 + a.imag**2, axis=-1)
    if np.any(nrm2 == 0.0):
        raise ValueError("a is zero (no signal)")
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    if np.any(np.abs(az) ** 2 <= ZENITH_TOL**2 * nrm2):
        raise zenith_error()
    xz = ax * np.conj(az)
    yz = ay * np.conj(az)
    sg = np.sign(eta)
    phi = np.arctan2(sg * xz.imag, -sg * yz.imag)
    cp, sp = np.cos(phi), np.sin(phi)
    theta = np.arctan(-(xz.real * cp + yz.real * sp) / (np.abs(az) ** 2))
    ct, st = np.cos(theta), np.sin(theta)
    j1 = -sp * ax + cp * ay
    j2 = -cp * st * ax - sp * st * ay + ct * az
    s1 = np.abs(j1) ** 2 - np.abs(j2) ** 2
    s2 = 2.0 * (j1 * np.conj(j2)).real
    c2 = np.sign(np.cos(2.0 * eta)) or 1.0
    gamma = wrap_tilt(0.5 * np.arctan2(-s2 * c2, s1 * c2))
    return phi, theta, gamma


def principal_eigenvector(R):
    """Unit eigenvector of the largest eigenvalue of Hermitian R (..., 3, 3) → (..., 3) complex."""
    _, v = np.linalg.eigh(R)
    return v[..., :, -1]


def closed_form_covariance(R, eta):
    """:func:`closed_form` applied to the principal eigenvector of the sample covariance R̂ (..., 3, 3).

    Raises ValueError as :func:`closed_form` (η = 0: φ, θ, γ unobservable; |η| = 45°: γ unobservable;
    estimated θ = ±90°: φ, γ unobservable), and for R̂ not of shape (..., 3, 3), non-finite, or with a
    non-positive trace.
    """
    eta = check_eta(eta)
    return closed_form(principal_eigenvector(_check_cov(R, batch=True)), eta)


# ============================================================================ concentrated ML (eqs. 5–6)
def power_noise(A, R):
    """(P̂, σ̂²) for a unit steering vector A and sample covariance R̂ (seed / Nehorai & Paldi):
    σ̂² = ½ tr[(I − AAᴴ) R̂], P̂ = AᴴR̂A − σ̂²."""
    x = float(np.real(np.conj(A) @ R @ A))
    s2 = 0.5 * (float(np.real(np.trace(R))) - x)
    return x - s2, s2


def concentrated_loglik(params, R, eta, n):
    """Concentrated log-likelihood L(φ, θ, γ) of n circular complex Gaussian snapshots (eq. 6 corrected).

    L = −n [3 ln π + ln det R(P̂, σ̂²) + tr(R⁻¹R̂)] = −n [3 ln π + 3 + ln(AᴴR̂A) + 2 ln σ̂²] with the
    estimates of :func:`power_noise` (valid where P̂ ≥ 0, where L increases with AᴴR̂A). The seed's eq. (5)
    uses a real-Gaussian normalisation ((2π)^{3/2}, ½ in the exponent); the argmax is the same.
    """
    A = steering_vector(*params, eta)
    x = float(np.real(np.conj(A) @ R @ A))
    _, s2 = power_noise(A, R)
    return -n * (3.0 * np.log(np.pi) + 3.0 + np.log(x) + 2.0 * np.log(s2))


@dataclass
class MLResult:
    """Concentrated-ML estimate: wave parameters [rad] (γ ∈ (−π/2, π/2]), P̂, σ̂², ρ̂ = P̂/σ̂², the
    maximised AᴴR̂A, optimizer success flag and iteration count."""

    phi: float
    theta: float
    gamma: float
    power: float
    noise_var: float
    snr: float
    objective: float
    success: bool
    nit: int

    @property
    def params(self) -> tuple[float, float, float]:
        return self.phi, self.theta, self.gamma


@njit(cache=True)
def objective_gradient(p, R, ce, se, g):
    """f = AᴴR̂A at p = (φ, θ, γ) [rad] and its gradient 2 Re{DᴴR̂A} written into g (3,), for
    A = cosη ṽ1 + i sinη ṽ2 (ce = cos η, se = sin η) and R (3, 3) complex128; A and D = ∂A/∂(φ, θ, γ)
    written out (numba; the per-fix BFGS and the batch Newton of ``polarization_batch`` share it)."""
    cp, sp = np.cos(p[0]), np.sin(p[0])
    ct, st = np.cos(p[1]), np.sin(p[1])
    cg, sg = np.cos(p[2]), np.sin(p[2])
    u = np.array([cp * ct, sp * ct, st])
    v1 = np.array([-sp, cp, 0.0])
    v2 = np.array([-cp * st, -sp * st, ct])
    d1 = np.array([-cp, -sp, 0.0])  # ∂v1/∂φ
    d2 = np.array([sp * st, -cp * st, 0.0])  # ∂v2/∂φ
    A = np.empty(3, np.complex128)
    D = np.empty((3, 3), np.complex128)
    for i in range(3):
        t1 = cg * v1[i] - sg * v2[i]
        t2 = sg * v1[i] + cg * v2[i]
        A[i] = ce * t1 + 1j * se * t2
        D[i, 0] = ce * (cg * d1[i] - sg * d2[i]) + 1j * se * (sg * d1[i] + cg * d2[i])
        D[i, 1] = (ce * sg - 1j * se * cg) * u[i]
        D[i, 2] = -ce * t2 + 1j * se * t1
    RA = R @ A
    f = 0.0
    for i in range(3):
        f += (np.conj(A[i]) * RA[i]).real
    for j in range(3):
        s = 0.0
        for i in range(3):
            s += (np.conj(D[i, j]) * RA[i]).real
        g[j] = 2.0 * s
    return f


def _neg_obj(p, R, eta, scale):
    """−AᴴR̂A·scale and its gradient (scipy's BFGS minimises)."""
    g = np.empty(3)
    f = objective_gradient(np.asarray(p, dtype=float), R, np.cos(eta), np.sin(eta), g)
    return -f * scale, -g * scale


def ml_estimate(R, eta, start=None, gtol=1e-9, maxiter=200) -> MLResult:
    """Concentrated ML (φ, θ, γ) from a sample covariance R̂ (3×3) with η [rad] known.

    Maximises AᴴR̂A (§3.3) with scipy BFGS and the analytic gradient 2 Re{Dᴴ R̂ A}, started from
    ``start`` (φ, θ, γ) or from :func:`closed_form_covariance`. The result is put back into the
    canonical ranges through the wave-frame DCM (θ ∈ [−π/2, π/2], γ folded into (−π/2, π/2]).
    ``success`` is also set when BFGS stops on "precision loss" with a gradient norm (of AᴴR̂A / tr R̂)
    below 1e-7, i.e. at the optimum to ~1e-7 rad. The principal-eigenvector closed form is already within
    ~1e-4 rad of the ML at SNR 10 dB (both are first-order equivalent), so the search is short.

    Raises ValueError (module docstring, "Bad input"): η = 0 (φ, θ, γ unobservable), |η| = 45° (γ
    unobservable), |η| > 45° or non-finite; an estimate (closed-form start or ML optimum) at θ = ±90°
    (φ, γ unobservable); R̂ not of shape (3, 3), non-finite or with a non-positive trace; ``start`` not
    3 finite numbers.
    """
    eta = check_eta(eta)
    R = _check_cov(R, batch=False)
    if start is None:
        p0 = np.array(closed_form_covariance(R, eta), dtype=float)
    else:
        p0 = np.asarray(start, dtype=float)
        if p0.shape != (3,):
            raise ValueError(f"start must have shape (3,) (phi, theta, gamma), got {p0.shape}")
        _check_finite(p0, "start")
    scale = 1.0 / float(np.real(np.trace(R)))
    R = np.ascontiguousarray(R, dtype=np.complex128)
    res = minimize(_neg_obj, p0, args=(R, eta, scale), jac=True, method="BFGS",
                   options={"gtol": gtol, "maxiter": maxiter})
    phi, theta, gamma = wave_params_from_dcm(wave_dcm(*res.x))
    if abs(np.cos(theta)) <= ZENITH_TOL:
        raise zenith_error()
    A = steering_vector(phi, theta, gamma, eta)
    pw, s2 = power_noise(A, R)
    return MLResult(phi, theta, gamma, pw, s2, pw / s2 if s2 > 0 else np.inf, -res.fun / scale,
                    bool(res.success or np.linalg.norm(res.jac) < 1e-7), int(res.nit))


# ============================================================================ Cramér–Rao bounds
def _factor(snr, n):
    """(1+ρ)/(2Nρ²) written as (1/ρ + 1/ρ²)/(2N), so that ρ = ∞ (noise-free) gives 0.

    ValueError for ρ ≤ 0 or NaN (linear SNR) and for N < 1."""
    if not float(snr) > 0.0:
        raise ValueError(f"snr (linear P/sigma^2) must be > 0, got {snr!r}")
    n = check_snapshots(n)
    r = 1.0 / float(snr)
    return (r + r * r) / (2.0 * n)


def crb_eq7(phi, theta, gamma, eta, snr, n):
    """Seed eq. (7): CRB(φ, θ, γ) = (1+ρ)/(2Nρ²)·C [rad²], ρ = P/σ² (linear), N snapshots. 3×3."""
    se2, ce2 = np.sin(eta) ** 2, np.cos(eta) ** 2
    sg, cg = np.sin(gamma), np.cos(gamma)
    st, ct = np.sin(theta), np.cos(theta)
    t2 = np.tan(theta) ** 2
    c11 = (sg**2 * ce2 + cg**2 * se2) / (se2 * ce2 * ct**2)
    c12 = (1 - 2 * se2) * sg * cg / (se2 * ce2 * ct)
    c13 = st * sg**2 / (ct**2 * se2) + st * cg**2 / (ct**2 * ce2)
    c22 = (sg**2 * se2 + cg**2 * ce2) / (se2 * ce2)
    c23 = (1 - 2 * se2) * sg * cg * st / (se2 * ce2 * ct)
    c33 = 1 / np.cos(2 * eta) ** 2 + sg**2 * t2 / se2 + cg**2 * t2 / ce2
    C = np.array([[c11, c12, c13], [c12, c22, c23], [c13, c23, c33]])
    return _factor(snr, n) * C


def _dA_complex_step(phi, theta, gamma, eta, h=1e-30):
    """∂A/∂(φ, θ, γ) by complex-step differentiation of the real wave vectors ṽ1, ṽ2 (exact to rounding)."""
    cols = []
    p = np.array([phi, theta, gamma], dtype=complex)
    for k in range(3):
        q = p.copy()
        q[k] += 1j * h
        _, t1, t2 = wave_vectors(*q)
        cols.append(np.cos(eta) * t1.imag / h + 1j * np.sin(eta) * t2.imag / h)
    return np.column_stack(cols)


def crb_numerical(phi, theta, gamma, eta, snr, n, power=1.0):
    """CRB of (φ, θ, γ) [rad²] from the full Fisher information of the circular Gaussian model.

    Parameters (φ, θ, γ, P, σ²) with R = P A Aᴴ + σ² I; Slepian–Bangs: FIM_kl = N tr(R⁻¹ R_k R⁻¹ R_l);
    ∂A by complex step (independent of eq. 7 and of the analytic derivatives). Returns the 3×3 block of
    FIM⁻¹ (P and σ² are nuisance parameters).
    """
    _factor(snr, n)  # validates snr > 0, n >= 1
    s2 = power / float(snr)
    A = steering_vector(phi, theta, gamma, eta)
    D = _dA_complex_step(phi, theta, gamma, eta)
    R = power * np.outer(A, A.conj()) + s2 * np.eye(3)
    Ri = np.linalg.inv(R)
    dR = [power * (np.outer(D[:, k], A.conj()) + np.outer(A, D[:, k].conj())) for k in range(3)]
    dR += [np.outer(A, A.conj()), np.eye(3, dtype=complex)]
    F = np.empty((5, 5))
    for k in range(5):
        for m in range(5):
            F[k, m] = n * np.real(np.trace(Ri @ dR[k] @ Ri @ dR[m]))
    return np.linalg.inv(F)[:3, :3]


def crb_rotation_vector(phi, theta, gamma, eta, snr, n):
    """CVAE bound [rad²]: CRB of the wave-frame rotation δ (about u, ṽ1, ṽ2), J CRB(φ,θ,γ) Jᵀ.

    δ: C_I^W(est) = (I − [δ×]) C_I^W(true). Analytically (1+ρ)/(2Nρ²)·diag(1/cos²2η, 1/sin²η, 1/cos²η)
    (:func:`cvae_bound`) for every DOA and tilt.
    """
    J = wave_rotation_jacobian(phi, theta, gamma)
    return J @ crb_eq7(phi, theta, gamma, eta, snr, n) @ J.T


def cvae_bound(eta, snr, n):
    """(1+ρ)/(2Nρ²)·diag(1/cos²2η, 1/sin²η, 1/cos²η) [rad²] (§3.5; no leading N·)."""
    return _factor(snr, n) * np.diag([1 / np.cos(2 * eta) ** 2, 1 / np.sin(eta) ** 2,
                                                    1 / np.cos(eta) ** 2])


def euler_error_jacobian(roll, pitch, heading):
    """J_E: d(roll, pitch, heading) = J_E ε for a misalignment ε in n, C(est) = (I − [ε×]) C(true).

    From C = R3(ψ) R1(pitch) R2(roll), ψ = −heading: dC = [(e3 dψ + R3 e1 dpitch + R3 R1 e2 droll)×] C
    = −[ε×] C. Singular at pitch = ±90°.
    """
    psi = -heading
    cy, sy = np.cos(psi), np.sin(psi)
    cp, sp = np.cos(pitch), np.sin(pitch)
    M = np.array([[-sy * cp, cy, 0.0], [cy * cp, sy, 0.0], [sp, 0.0, 1.0]])  # columns: roll, pitch, psi
    J = -np.linalg.inv(M)
    J[2, :] *= -1.0  # heading = −ψ
    return J


# ============================================================================ attitude (steps 1–4)
def _base_to_local(base_to_local):
    return np.eye(3) if base_to_local is None else np.asarray(base_to_local, dtype=float)


def attitude_from_wave(phi, theta, gamma, bearing, elevation, tx_tilt, base_to_local=None):
    """C_b^n (RFU → ENU) from the wave frame seen by the triad and the base's geometry (steps 1–4).

    phi, theta, gamma : wave parameters in the seed's antenna frame I (FLU) [rad];
    bearing : azimuth of the aircraft seen from the base, clockwise from North [rad] (seed φ′ = −bearing,
        counter-clockwise from North toward West); elevation : θ′ [rad]; tx_tilt : γ′ [rad] (tilt of the
        arriving wave in the (v1, v2) basis of the arrival direction in the base frame);
    base_to_local : C_{n_base}^{n} from the base's ENU to the aircraft's ENU (identity = the seed's flat
        Earth; use :func:`aidnav.nav.wave_frame.enu_rotation_between`).

    C_I^B = C_W^B C_I^W (corrected eq. 9), C_b^n = base_to_local · P C_I^B Pᵀ.
    """
    C_IB = base_wave_dcm(-bearing, elevation, tx_tilt) @ wave_dcm(phi, theta, gamma)
    return _base_to_local(base_to_local) @ P_SEED @ C_IB @ P_SEED.T


def crb_attitude(phi, theta, gamma, eta, snr, n, bearing, elevation, tx_tilt, base_to_local=None):
    """Attitude CRB for a geometry: (cov of the misalignment ε in n [rad²], cov of (roll, pitch, heading)
    [rad²], C_b^n). ε = base_to_local · P · C_W^B · δ with δ of :func:`crb_rotation_vector`
    (base-station angles taken as exact, as in the seed §5)."""
    G = _base_to_local(base_to_local) @ P_SEED @ base_wave_dcm(-bearing, elevation, tx_tilt)
    cov_eps = G @ crb_rotation_vector(phi, theta, gamma, eta, snr, n) @ G.T
    C = attitude_from_wave(phi, theta, gamma, bearing, elevation, tx_tilt, base_to_local)
    JE = euler_error_jacobian(*euler_from_dcm(C))
    return cov_eps, JE @ cov_eps @ JE.T, C


def _angle_between(C1, C2):
    return float(np.linalg.norm(rotvec_from_dcm(np.ascontiguousarray(C1 @ C2.T))))


def resolve_line_of_sight(phi, theta, gamma, bearing, elevation, tx_tilt, prior=None, base_to_local=None):
    """Choose γ or γ + π (the 180° ambiguity of the attitude about the line of sight, §3.3).

    prior : C_b^n of a prior attitude (e.g. the previous epoch, or the INS) — the candidate closest to it
    wins; without a prior the aircraft is assumed upright (the candidate whose body up axis points most
    upward, largest C_b^n[2, 2]). Returns (γ chosen [rad, in (−π, π]], C_b^n, flipped: bool).
    """
    cands = [gamma, gamma + np.pi if gamma <= 0 else gamma - np.pi]
    Cs = [attitude_from_wave(phi, theta, g, bearing, elevation, tx_tilt, base_to_local) for g in cands]
    if prior is not None:
        score = [-_angle_between(C, np.asarray(prior, dtype=float)) for C in Cs]
    else:
        score = [C[2, 2] for C in Cs]
    i = int(np.argmax(score))
    return cands[i], Cs[i], i == 1


@dataclass
class AttitudeFix:
    """One polarization attitude fix in our conventions.

    rph : (roll, pitch, heading) [rad]; C_bn : C_b^n (RFU → ENU); cov_eps : 3×3 covariance [rad²] of the
    misalignment ε in n (C(est) = (I − [ε×]) C(true)), the CRB at the estimated SNR (the measurement
    noise for :func:`aidnav.filters.measurements.attitude`); cov_rph : 3×3 [rad²] of (roll, pitch,
    heading); wave : (φ, θ, γ) [rad] in the seed frame I; snr : ρ̂ (linear); n : snapshots;
    method : "ml" or "closed_form"; flipped : the line-of-sight ambiguity took γ + π.
    """

    rph: np.ndarray
    C_bn: np.ndarray
    cov_eps: np.ndarray
    cov_rph: np.ndarray
    wave: tuple
    snr: float
    n: int
    method: str
    flipped: bool


def estimate_attitude(R, n, eta, bearing, elevation, tx_tilt, method="ml", prior=None,
                      base_to_local=None) -> AttitudeFix:
    """Attitude fix from the sample covariance R̂ (3×3, n snapshots, seed frame I) of the triad.

    eta : the known transmitted ellipticity [rad] (0 < |η| < π/4); bearing, elevation : of the aircraft
    seen from the base [rad] (bearing clockwise from North); tx_tilt : γ′ [rad]; method : "ml" (default)
    or "closed_form" (principal eigenvector); prior : C_b^n used to resolve the line-of-sight ambiguity
    (None: upright); base_to_local : C_{n_base}^{n} (None: flat Earth, the seed's assumption).

    Raises ValueError, never a fix that pretends (module docstring, "Bad input"): η = 0 (DOA and tilt,
    hence the attitude about the major axis, unobservable), |η| = 45° (tilt γ, the attitude about the
    line of sight, unobservable), |η| > 45° or non-finite η; an estimated source at θ = ±90° (φ, γ
    unobservable); R̂ not of shape (3, 3), non-finite or with a non-positive trace; n not an integer ≥ 1;
    non-finite bearing, elevation or tx_tilt; an unknown ``method``.
    """
    eta = check_eta(eta)
    R = _check_cov(R, batch=False)
    n = check_snapshots(n)
    _check_finite([bearing, elevation, tx_tilt], "bearing/elevation/tx_tilt")
    if method == "ml":
        ml = ml_estimate(R, eta)
        phi, theta, gamma, snr = ml.phi, ml.theta, ml.gamma, ml.snr
    elif method == "closed_form":
        phi, theta, gamma = (float(x) for x in closed_form_covariance(R, eta))
        pw, s2 = power_noise(steering_vector(phi, theta, gamma, eta), R)
        snr = pw / s2 if s2 > 0 else np.inf
    else:
        raise ValueError(f"method must be 'ml' or 'closed_form', got {method!r}")
    gamma, C, flipped = resolve_line_of_sight(phi, theta, gamma, bearing, elevation, tx_tilt, prior,
                                              base_to_local)
    cov_eps, cov_rph, _ = crb_attitude(phi, theta, gamma, eta, max(snr, 1e-6), n, bearing, elevation,
                                       tx_tilt, base_to_local)
    return AttitudeFix(np.array(euler_from_dcm(C)), C, cov_eps, cov_rph, (phi, theta, gamma), float(snr),
                       int(n), method, flipped)


def dcm_from_rph(rph):
    """C_b^n from (roll, pitch, heading) [rad] (convenience re-export of the project convention)."""
    return dcm_from_euler(float(rph[0]), float(rph[1]), float(rph[2]))
