"""Transfer alignment of a sub-IMU to a master POS (seed 004, §5.1): the state layout, the process model
and the settings, for the filter engine (:mod:`aidnav.filters.engine`).

Frames and units: n = ENU (master and sub navigation frames taken equal, §5.1), b_m / b_s the
master / sub body frames (RFU); radians, metres, seconds; sub state as in
:mod:`aidnav.nav.strapdown` (lat, lon, h, v^n, q_bs^n).

State (layout ``make_layout(False, ("mounting", "flexure"))``; errors computed − true for the
navigation block, true − estimated for the others, as in :mod:`aidnav.filters.layout`):

=======  =============================================================  ============
0:3      φ, sub misalignment in n: C̃_bs^n = (I − [φ×]) C_bs^n             rad
3:6      δv^n                                                          m/s
6:9      δL, δλ, δh                                                    rad, rad, m
9:12     ε, gyro bias residual (true − estimated), b_s                 rad/s
12:15    ∇, accelerometer bias residual, b_s                            m/s²
15:18    ρ, fixed mounting misalignment, C_bs^bm = exp(−[(ρ+θ)×])      rad
18:21    θ, wing flexure angle                                         rad
21:24    θ̇, flexure rate (24-state model only)                         rad/s
=======  =============================================================  ============

* **24 states** (§5.1 item 9, recommended): θ is the second-order Markov process of the truth,
  θ̈ + 2βθ̇ + β²θ = η, Q_η = 4β³σ², β = 2.146/τ.
* **21 states** (the seed's count): x₂ = (ρ, θ) only, which cannot carry a second-order process, so θ
  is modelled as first-order Gauss-Markov θ̇ = −θ/τ + w with the same σ and τ (τ is then also its 1/e
  time), Q_w = 2σ²/τ. The truth stays second order: this variant is the seed's model mismatch.

Process model: the 15 INS error states of :func:`aidnav.filters.ins_errors.fill_model` (biases random
constants, white gyro/accelerometer noise of the sub-IMU grade), ρ̇ = 0, the flexure block above.
F is block diagonal between (INS, ρ) and the flexure, so the engine discretises the INS+ρ block with
:func:`aidnav.filters.kalman.discretize` (third-order Taylor of Van Loan) and the flexure block
exactly (``Process.gm``, :func:`aidnav.filters.predict.exact_blocks`: ‖F_flex‖·T ≈ 2βT ≈ 2 at T = 1 s,
far too large for a Taylor series). ρ, θ, θ̇ are open-loop states (``Process.open``): their estimate
is propagated as x̂ ← Φ x̂ and never reset (:func:`aidnav.filters.engine.carry_estimates`).

Measurement, every filter epoch (§5.1 item 10): velocity + attitude matching, one 6-row batch update
(:func:`aidnav.filters.measurements.attitude.velocity_attitude_matching`, with the master's lever-arm
velocity, the full attitude covariance R_a = M diag(σ_roll², σ_pitch², σ_heading²) Mᵀ of
:func:`aidnav.nav.rotations.euler_error_map`, and the exact composition about the current ρ̂ + θ̂ with
the left Jacobian of SO(3) in H). :func:`fill_transfer_model` and :func:`discretize_transfer` give the
continuous model with its 15 noise inputs and its discretisation for checks against Van Loan.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from aidnav.models.distributed_pos import FlexureSpec, MasterPosSpec
from aidnav.nav.earth import radii
from aidnav.units import DEG, DEG_H, UG

from . import measurements as ms
from .engine import NEVER, Models, Process
from .ins_errors import fill_model
from .kalman import discretize
from .layout import L_FLEX, make_layout
from .measurements.attitude import left_jacobian
from .predict import exact_blocks

if TYPE_CHECKING:  # the simulator's containers, for annotations only (filters do not import sim)
    from aidnav.sim.distributed_pos import DistributedPosConfig

__all__ = ["PHI", "DV", "DP", "BG", "BA", "RHO", "THETA", "THETA_DOT", "TransferConfig",
           "fill_transfer_model", "discretize_transfer", "state_labels", "left_jacobian", "transfer_layout",
           "transfer_process", "transfer_models"]

PHI, DV, DP, BG, BA, RHO, THETA, THETA_DOT = 0, 3, 6, 9, 12, 15, 18, 21
N_INS = 15
N_NOISE_INS = 12  # fill_model's noise inputs for 15 states


def state_labels(nstate: int = 24) -> list[str]:
    """Names of the states (with units) of the 24- or 21-state model."""
    names = ["phi_e_rad", "phi_n_rad", "phi_u_rad", "dve_m_s", "dvn_m_s", "dvu_m_s", "dlat_rad", "dlon_rad",
             "dh_m", "gyro_bias_x_rad_s", "gyro_bias_y_rad_s", "gyro_bias_z_rad_s", "accel_bias_x_m_s2",
             "accel_bias_y_m_s2", "accel_bias_z_m_s2", "rho_x_rad", "rho_y_rad", "rho_z_rad", "theta_x_rad",
             "theta_y_rad", "theta_z_rad", "theta_dot_x_rad_s", "theta_dot_y_rad_s", "theta_dot_z_rad_s"]
    return names[:nstate]


@dataclass(frozen=True)
class TransferConfig:
    """Settings of the transfer-alignment filter (SI units unless the name says otherwise).

    nstate: 24 (second-order flexure) or 21 (first-order, the seed's count). lever_arm_m: r^bm [m].
    flexure: flexure model (σ, τ). gyro_bias_sigma [rad/s], accel_bias_sigma [m/s²]: P₀ of the biases;
    gyro_arw [rad/√s], accel_vrw [m/s/√s]: white-noise densities (per axis, the largest of the three).
    mounting_sigma_deg: P₀ of ρ. att_prior_deg, vel_prior_m_s: diffuse P₀ of φ and δv before the
    first update. master: accuracy of the master output (R and the position part of P₀).
    gate: χ² gate of the 6-row update (≤ 0: none).
    """

    nstate: int = 24
    lever_arm_m: tuple[float, float, float] = (5.0, 0.1, 0.1)
    flexure: FlexureSpec = FlexureSpec()
    gyro_bias_sigma: float = 0.1 * DEG_H
    accel_bias_sigma: float = 50.0 * UG
    gyro_arw: float = 0.1 * DEG_H
    accel_vrw: float = 50.0 * UG
    mounting_sigma_deg: float = 1.0
    att_prior_deg: float = 3.0
    vel_prior_m_s: float = 1.0
    master: MasterPosSpec = MasterPosSpec()
    gate: float = 0.0

    def __post_init__(self):
        if self.nstate not in (21, 24):
            raise ValueError(f"TransferConfig.nstate must be 21 or 24, got {self.nstate}")

    @classmethod
    def from_sim(cls, cfg: DistributedPosConfig, nstate: int = 24, **kw) -> TransferConfig:
        """A filter matched to a simulation config (sensor grade, lever arm, flexure, master accuracy)."""
        imu = cfg.sub_imu
        return cls(nstate=nstate, lever_arm_m=tuple(float(v) for v in cfg.lever_arm_m), flexure=cfg.flexure,
                   gyro_bias_sigma=float(np.max(np.abs(imu.gyro_bias))),
                   accel_bias_sigma=float(np.max(np.abs(imu.accel_bias))),
                   gyro_arw=float(np.max(imu.gyro_arw)), accel_vrw=float(np.max(imu.accel_vrw)),
                   master=cfg.master, **kw)

    def initial_covariance(self, lat: float, h: float) -> np.ndarray:
        """Diagonal P₀ (n×n) at latitude ``lat`` [rad], height ``h`` [m]."""
        n = self.nstate
        rm, rn = radii(lat)
        sp = self.master.pos_sigma_m
        d = np.zeros(n)
        d[PHI:PHI + 3] = (self.att_prior_deg * DEG) ** 2
        d[DV:DV + 3] = self.vel_prior_m_s**2
        d[DP:DP + 3] = [(sp[1] / (rm + h)) ** 2, (sp[0] / ((rn + h) * math.cos(lat))) ** 2, sp[2] ** 2]
        d[BG:BG + 3] = max(self.gyro_bias_sigma, 1e-12) ** 2
        d[BA:BA + 3] = max(self.accel_bias_sigma, 1e-12) ** 2
        d[RHO:RHO + 3] = (self.mounting_sigma_deg * DEG) ** 2
        sig = self.flexure.sigma
        d[THETA:THETA + 3] = np.maximum(sig, 1e-12) ** 2
        if n == 24:
            d[THETA_DOT:THETA_DOT + 3] = np.maximum(self.flexure.beta * sig, 1e-12) ** 2
        return np.diag(d)


# ------------------------------------------------------------------------------ engine pieces
def transfer_layout(nstate: int = 24) -> np.ndarray:
    """The engine layout: 15 INS states, mounting ρ (3), flexure θ (3) and, for 24 states, θ̇ (3)."""
    return make_layout(False, ("mounting", "flexure" if nstate == 24 else "flexure_angle"))


def gm_blocks(nstate: int, beta, sigma) -> np.ndarray:
    """``Process.gm`` rows of the flexure: per axis (θ, θ̇, β, σ) (24 states) or (θ, −1, 1/τ, σ) (21)."""
    lay = transfer_layout(nstate)
    rows = []
    for j in range(3):
        i = int(lay[L_FLEX]) + j
        s = max(float(sigma[j]), 1e-12)
        if nstate == 24:
            rows.append((i, i + 3, float(beta[j]), s))
        else:
            rows.append((i, -1, float(beta[j]) / 2.146, s))  # 1/τ, τ = 2.146/β
    return np.array(rows, float)


def transfer_process(cfg: TransferConfig, T: float) -> Process:
    """Engine process model at the filter interval T [s]: INS white noise of the sub-IMU grade (biases
    random constants), ρ constant, the flexure exact (``gm``); ρ, θ, θ̇ open-loop (``open``)."""
    n = cfg.nstate
    q = np.zeros(N_NOISE_INS + n - N_INS)
    q[0:3], q[3:6] = cfg.gyro_arw**2, cfg.accel_vrw**2
    return Process(transfer_layout(n), q, np.zeros(4), np.zeros(n - N_INS), float(T), np.zeros(0, np.int64),
                   False, gm_blocks(n, cfg.flexure.beta, cfg.flexure.sigma), np.arange(RHO, n))


def transfer_models(cfg: TransferConfig, lever=None) -> Models:
    """Engine models: velocity + attitude matching with the lever arm (``lever`` or ``cfg.lever_arm_m``),
    gated at ``cfg.gate`` (6 rows; ≤ 0: ungated), no consecutive-rejection rule, no node constraints."""
    par = np.zeros((ms.N_MODELS, 3))
    par[ms.M_VATT] = cfg.lever_arm_m if lever is None else lever
    gate = np.zeros((ms.N_MODELS, ms.MAX_ROWS + 1))
    gate[ms.M_VATT, 6] = max(float(cfg.gate), 0.0)
    return Models(par, gate, np.full(ms.N_MODELS, NEVER, np.int64), np.zeros((0, 2), np.int64))


# ------------------------------------------------------------- continuous model (reference, checks)
def fill_transfer_model(F, G, q, lat, h, v, fn, Cbn, wb, fb, beta, sigma, q_gyro, q_accel):
    """Continuous model of the 24- or 21-state transfer alignment (n = F.shape[0]), filled in place.

    F (n×n), G (n×m) with m = 15 noise inputs [gyro white (3), accel white (3), gyro-bias and
    accel-bias driving (6, zero PSD: random constants), flexure driving (3)], q (m,) PSD.
    lat [rad], h [m], v^n [m/s], fn mean specific force in n [m/s²], Cbn C_bs^n, wb [rad/s], fb [m/s²],
    beta (3,) [1/s], sigma (3,) [rad] flexure parameters, q_gyro [rad²/s], q_accel [m²/s³] white PSDs.
    (The engine builds the same INS block with :func:`aidnav.filters.ins_errors.interval_model`.)
    """
    n = F.shape[0]
    F[:, :], G[:, :], q[:] = 0.0, 0.0, 0.0
    F15, G15 = np.zeros((N_INS, N_INS)), np.zeros((N_INS, N_NOISE_INS))
    fill_model(F15, G15, lat, h, np.asarray(v, float), np.asarray(fn, float), np.asarray(Cbn, float),
               np.asarray(wb, float), np.asarray(fb, float), (0.0, 0.0, 0.0, 0.0))
    F[:N_INS, :N_INS], G[:N_INS, :N_NOISE_INS] = F15, G15
    q[0:3], q[3:6] = q_gyro, q_accel
    for j in range(3):
        if n == 24:
            F[THETA + j, THETA_DOT + j] = 1.0
            F[THETA_DOT + j, THETA + j] = -beta[j] * beta[j]
            F[THETA_DOT + j, THETA_DOT + j] = -2.0 * beta[j]
            G[THETA_DOT + j, 12 + j] = 1.0
            q[12 + j] = 4.0 * beta[j] ** 3 * sigma[j] ** 2
        else:
            tau = 2.146 / beta[j]
            F[THETA + j, THETA + j] = -1.0 / tau
            G[THETA + j, 12 + j] = 1.0
            q[12 + j] = 2.0 * sigma[j] ** 2 / tau


def discretize_transfer(F, G, q, T, beta, sigma, Phi, Qd):
    """Φ, Qd (n×n) over ``T`` [s] of the model of :func:`fill_transfer_model`, as the engine forms
    them: :func:`aidnav.filters.kalman.discretize` for the whole model, then the flexure block exact
    (:func:`aidnav.filters.predict.exact_blocks`; F is block diagonal, so the INS + ρ block is that of
    the Taylor series alone)."""
    discretize(F, G, q, T, Phi, Qd)
    exact_blocks(Phi, Qd, gm_blocks(F.shape[0], beta, sigma), float(T))
