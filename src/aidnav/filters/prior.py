"""The prior of every INS error-state filter: process-noise PSD vectors and initial covariances (one
builder, used by the loose, tight, federated, attitude-aiding and satcom 8-state filters), and the
initial state of ``init.mode = "given"``.

PSD vector q (continuous, SI), in the order of the noise inputs of :mod:`aidnav.filters.ins_errors`:
gyro white ×3 [rad²/s], accelerometer white ×3 [m²/s³], gyro-bias driving ×3, accelerometer-bias
driving ×3, (gyro and accelerometer scale-factor driving ×3 each), (gyro misalignment driving ×6),
(accelerometer misalignment driving ×6), then
one per calibration state of
the layout. A first-order Gauss-Markov state of steady-state σ and correlation time τ > 0 is driven by
q = 2σ²/τ; τ ≤ 0 is a random walk of PSD rw² (rw = 0: a random constant) (:func:`markov_psd`).

Initial covariance: diagonal, in the layout's order (:mod:`aidnav.filters.layout`): φ, δv, δL δλ δh
(position σ given in metres E, N, U), biases, scale factors, calibration states.
"""

from __future__ import annotations

import numpy as np

from aidnav.nav.earth import radii
from aidnav.units import DEG, DEG_H, UG

from .ins_errors import MIS_IN, MIS_OUT
from .layout import (
    BA,
    BG,
    DP,
    DV,
    L_BARO,
    L_GPE,
    L_LEVER,
    L_MOUNT,
    L_ODO,
    L_TOFF,
    L_VDEL,
    MA,
    MG,
    PHI,
    SA,
    SG,
)

__all__ = ["markov_psd", "ins_psd", "ins_p0_diag", "process_noise", "initial_covariance",
           "calibration_prior", "given_initial_state", "levelled_tilt_covariance"]


def markov_psd(sigma: float, tau: float, rw: float = 0.0) -> float:
    """Driving-noise PSD of a Gauss-Markov state: 2σ²/τ for τ > 0, else rw² (random walk / constant)."""
    return 2.0 * sigma**2 / tau if tau > 0 else rw**2


def ins_psd(arw: float, vrw: float, q_gyro_bias: float, q_accel_bias: float, q_sf=None,
            q_mis: float | None = None, q_amis: float | None = None) -> np.ndarray:
    """PSD vector of the INS block: arw [rad/√s], vrw [m/s/√s], bias driving PSDs; ``q_sf`` (gyro,
    accelerometer) scale-factor driving PSDs for the 21-state model (18 inputs), None: 15 states (12);
    ``q_mis`` the gyro misalignment's driving PSD for the 27-state model (24 inputs); ``q_amis`` the
    accelerometer misalignment's for the 33-state model (30 inputs)."""
    q = [arw**2] * 3 + [vrw**2] * 3 + [q_gyro_bias] * 3 + [q_accel_bias] * 3
    if q_sf is not None:
        q += [q_sf[0]] * 3 + [q_sf[1]] * 3
    if q_mis is not None:
        q += [q_mis] * 6
    if q_amis is not None:
        q += [q_amis] * 6
    return np.array(q, dtype=float)


def _three(x):
    return np.broadcast_to(np.asarray(x, float), (3,))


def ins_p0_diag(n: int, lat: float, h: float, att, vel, pos_m, gyro_bias, accel_bias, sf=(0.0, 0.0),
                mis: float = 0.0, amis: float = 0.0):
    """Initial variances (n,) of the INS block (n = 9, 15, 21, 27 or 33; more: zeros for the caller to fill)
    from 1σ values (scalars or 3-vectors): attitude [rad], velocity [m/s], position E, N, U [m] (→ δL, δλ,
    δh at lat [rad], h [m]), gyro bias [rad/s], accelerometer bias [m/s²], ``sf`` scale factors [-],
    ``mis`` gyro misalignment [rad] (n ≥ 27), ``amis`` accelerometer misalignment [rad] (n ≥ 33)."""
    rm, rn = radii(lat)
    ps = _three(pos_m)
    d = np.zeros(n)
    d[PHI:PHI + 3] = _three(att) ** 2
    d[DV:DV + 3] = _three(vel) ** 2
    d[DP] = (ps[1] / (rm + h)) ** 2
    d[DP + 1] = (ps[0] / ((rn + h) * np.cos(lat))) ** 2
    d[DP + 2] = ps[2] ** 2
    if n >= 15:
        d[BG:BG + 3] = _three(gyro_bias) ** 2
        d[BA:BA + 3] = _three(accel_bias) ** 2
    if n >= 21:
        d[SG:SG + 3] = sf[0] ** 2
        d[SA:SA + 3] = sf[1] ** 2
    if n >= 27:
        d[MG:MG + 6] = mis ** 2
    if n >= 33:
        d[MA:MA + 6] = amis ** 2
    return d


# ------------------------------------------------------------------ from the filters' configuration
def process_noise(cfg, nstate: int) -> np.ndarray:
    """PSD vector q of the INS block (15, 21, 27 or 33 states) from ``cfg.imu`` (:class:`.config.ImuNoise`).
    """
    im = cfg.imu
    sg = im.gyro_bias_instability_deg_h
    sg = im.gyro_bias_sigma_deg_h if sg is None else sg
    sa = im.accel_bias_sigma_ug if im.accel_bias_instability_ug is None else im.accel_bias_instability_ug
    qg = markov_psd(sg * DEG_H, im.gyro_bias_tau_s, im.gyro_bias_rw_deg_h_sqrt_h * DEG_H / 60)
    qa = markov_psd(sa * UG, im.accel_bias_tau_s, im.accel_bias_rw_ug_sqrt_h * UG / 60)
    q_sf = q_mis = q_amis = None
    if nstate >= 21:
        qs = 2.0 * (1e-6) ** 2 / im.sf_tau_s if im.sf_tau_s > 0 else 0.0
        q_sf = (qs * im.gyro_sf_sigma_ppm**2, qs * im.accel_sf_sigma_ppm**2)
    if nstate >= 27:
        q_mis = 0.0  # a random constant
    if nstate >= 33:
        q_amis = 0.0  # a random constant
    return ins_psd(im.arw_deg_sqrt_h * DEG / 60.0, im.vrw_m_s_sqrt_h / 60.0, qg, qa, q_sf, q_mis, q_amis)


def initial_covariance(cfg, nstate: int, lat: float, h: float, att_sigma_rad) -> np.ndarray:
    """Diagonal P0 of the INS block from ``cfg.init`` and ``cfg.imu`` (attitude σ given in radians).
    The accelerometer misalignment without the gyro's (``imu.accel_misalignment`` alone: the 33-state
    block) holds the gyro misalignment states at zero (σ 1e-6 deg: a positive definite P for the
    smoother's solve)."""
    im = cfg.imu
    gmis = 1e-6 if (im.accel_misalignment and not im.gyro_misalignment) else im.gyro_misalignment_sigma_deg
    return np.diag(ins_p0_diag(nstate, lat, h, att_sigma_rad, cfg.init.velocity_sigma_m_s,
                               cfg.init.position_sigma_m, im.gyro_bias_sigma_deg_h * DEG_H,
                               im.accel_bias_sigma_ug * UG, (im.gyro_sf_sigma_ppm * 1e-6,
                                                             im.accel_sf_sigma_ppm * 1e-6),
                               gmis * np.pi / 180.0, im.accel_misalignment_sigma_deg * np.pi / 180.0))


def calibration_prior(cfg, lay) -> np.ndarray:
    """(initial variance, noise PSD, τ) (k, 3) of each calibration state of layout ``lay``, in layout
    order, from ``cfg.odometer``, ``cfg.baro``, ``cfg.calibration`` and ``cfg.gnss``."""
    rows = []
    if lay[L_ODO] >= 0:
        o = cfg.odometer
        tau = o.scale_factor_tau_s
        rows.append((lay[L_ODO], (o.scale_factor_sigma_ppm * 1e-6) ** 2,
                     markov_psd(o.scale_factor_instability_ppm * 1e-6, tau), tau))
    if lay[L_BARO] >= 0:
        b = cfg.baro
        rows.append((lay[L_BARO], b.bias_sigma_m ** 2, markov_psd(b.bias_instability_m, b.bias_tau_s,
                                                                    b.bias_rw_m_sqrt_s), b.bias_tau_s))
    c = cfg.calibration
    for j in range(3):
        if lay[L_LEVER] >= 0:
            rows.append((lay[L_LEVER] + j, c.lever_arm_sigma_m ** 2, 0.0, 0.0))
        if lay[L_MOUNT] >= 0:
            rows.append((lay[L_MOUNT] + j, (c.mounting_sigma_deg * np.pi / 180) ** 2, 0.0, 0.0))
    if lay[L_TOFF] >= 0:
        rows.append((lay[L_TOFF], c.time_offset_sigma_s ** 2, c.time_offset_rw_s_sqrt_s ** 2, 0.0))
    if lay[L_VDEL] >= 0:
        rows.append((lay[L_VDEL], c.velocity_delay_sigma_s ** 2, 0.0, 0.0))
    if lay[L_GPE] >= 0:
        tau = cfg.gnss.error_tau_s
        for j, sg in enumerate(cfg.gnss.error_sigma_m):
            rows.append((lay[L_GPE] + j, sg ** 2, markov_psd(sg, tau), tau))
    return np.array([r[1:] for r in sorted(rows)], float).reshape(-1, 3)


def given_initial_state(ini, who: str):
    """(lat, lon [rad], h [m], v^n (3,) [m/s], (roll, pitch, heading) [rad]) of an
    :class:`.config.Initialisation` in "given" mode; ValueError naming ``who`` and what is missing."""
    missing = [k for k in ("lat_deg", "lon_deg", "height_m", "roll_deg", "pitch_deg", "heading_deg")
               if getattr(ini, k) is None]
    if missing:
        raise ValueError(f"{who} needs init.mode = given with init.{', init.'.join(missing)}")
    return (ini.lat_deg * DEG, ini.lon_deg * DEG, ini.height_m, np.array(ini.velocity_m_s, float),
            np.array([ini.roll_deg, ini.pitch_deg, ini.heading_deg]) * DEG)


def levelled_tilt_covariance(P: np.ndarray, nins: int, fb, cbn, sigma_w, f_true: float | None = None
                             ) -> np.ndarray:
    """``P`` (n×n, INS block first) with the tilt rows of a static coarse alignment (levelling: roll and
    pitch from the mean specific force ``fb`` (3,) [m/s²] in the body, attitude ``cbn`` = C_b^n at the
    start). The levelling puts the measured specific force on the vertical, so its tilt error is what the
    accelerometer errors do to that force (issue 35/40): with δf = ∇ + diag(f^b)·s_a + M_a·f^b (the residual
    states of :mod:`.ins_errors`, whichever the block has: bias ≥ 15, scale factors ≥ 21, misalignment 33)
    and φ as computed − true, C_b^n(computed) f̃^b vertical gives g·φ_N = (C δf)_E, g·φ_E = −(C δf)_N. So
    φ_EN = A·x + w: the tilt's variance A P Aᵀ + σ_w², its covariance with every state A·P (the sensor
    states' prior holds what they are), ``sigma_w`` (scalar or (2,)) [rad] the levelling's own error (the
    mean force's standard error / g). An independent tilt σ instead (``init.attitude_sigma_deg``) claims
    the tilt and the accelerometer errors unrelated, i.e. a start tilt that carries information of its own
    (on the consistency matrix's consumer IMU a small effect: results.md, n35t). Returns a new array; φ_U
    untouched.

    ``f_true`` [m/s²]: the magnitude of the *true* specific force during the levelling (at rest: normal
    gravity, :func:`aidnav.nav.earth.gravity`), the g of the relation above; None: |f^b|, the measured one
    (the loose filter's start). The two differ by the accelerometer's own error along the vertical (a
    consumer IMU's z bias: 1–3 %), and the difference matters over time: the dynamics hold the tilt against
    the bias-corrected specific force (:func:`.ins_errors.fill_model`'s [f^n×] with f^n = C(f̃ − b̂)), which
    goes to g as soon as the vertical channel has estimated the z bias; a tie made with |f^b| is then not
    the direction the data cannot see (perturbing the tilt by φ and the bias by the g·φ that keeps
    f̃ = C^T g e_U + ∇ leaves every measurement at rest unchanged), and the filter reads the mismatch, b_z/g of
    the bias's image, as information on the split: the tight filter's tilt σ fell below σ_b/g at rest
    (issue 35, session 15)."""
    P = np.array(P, float, copy=True)
    n = P.shape[0]
    fb = np.asarray(fb, float)
    J = np.zeros((3, n))
    if nins >= 15:
        J[:, BA:BA + 3] = np.eye(3)
    if nins >= 21:
        J[[0, 1, 2], [SA, SA + 1, SA + 2]] = fb
    if nins >= 33:
        for k in range(6):
            J[MIS_OUT[k], MA + k] = fb[MIS_IN[k]]
    cj = np.asarray(cbn, float) @ J / (np.linalg.norm(fb) if f_true is None else float(f_true))
    A = np.vstack([-cj[1], cj[0]])  # rows φ_E, φ_N
    t = [PHI, PHI + 1]
    P[t, :] = 0.0
    P[:, t] = 0.0
    X = A @ P
    P[t, :] = X
    P[:, t] = X.T
    sw = np.broadcast_to(np.asarray(sigma_w, float), (2,))
    P[np.ix_(t, t)] = A @ P @ A.T + np.diag(sw ** 2)
    return P
