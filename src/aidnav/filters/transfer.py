"""Transfer alignment of a sub-IMU to a master POS by velocity + attitude matching (seed 004, §5.1).

Frames and units: n = ENU (master and sub navigation frames taken equal, §5.1), b_m / b_s the
master / sub body frames (RFU); radians, metres, seconds; sub state as in
:mod:`aidnav.nav.strapdown` (lat, lon, h, v^n, q_bs^n).

State (errors are computed − true, as in :mod:`aidnav.filters.ins_errors`):

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

Process model: the 15 INS error states from :func:`aidnav.filters.ins_errors.fill_model` (biases
random constants, white gyro/accelerometer noise of the sub-IMU grade), ρ̇ = 0, the flexure block
above. F is block diagonal between (INS, ρ) and the flexure, so the transition is discretised per
block: :func:`aidnav.filters.kalman.discretize` (third-order Taylor of Van Loan) for the INS+ρ block,
the exact matrix exponential for the flexure block (‖F_flex‖·T ≈ 2βT ≈ 2 at T = 1 s, far too large
for a Taylor series): :func:`aidnav.models.distributed_pos.flexure_transition`.

Measurements, every filter epoch (§5.1 item 10), one batch update of six rows with
:func:`aidnav.filters.kalman.update` (Joseph form, optional χ² gate):

* attitude: D = C̃_bs^n (C̃_bm^n)ᵀ ≈ I − [z_a×], z_a = φ + C̃_bm^n (ρ + θ) + v_a
  (:func:`aidnav.filters.measurements.attitude` gives z_a and the φ columns; the ρ and θ columns are
  C̃_bm^n J, J the left Jacobian of SO(3) at −(ρ̂ + θ̂)): the residual is formed about the current
  estimate of ρ + θ (EKF, see :func:`_measurement`). R_a = M diag(σ_roll², σ_pitch², σ_heading²) Mᵀ
  maps the master's Euler-angle errors into n (:func:`aidnav.nav.rotations.euler_error_map`).
* velocity: z_v = ṽ_s − (ṽ_m + C̃_bm^n (ω_eb^bm × r^bm)) = δv + v_v: the master velocity after lever-arm
  compensation, ω_eb^bm = ω_ib^bm − C_n^bm ω_ie^n (the master IMU's rate). R_v = σ_v² I.

Closed-loop feedback after each update of φ, δv, δp, ε, ∇ into the strapdown state and the bias
estimates (:func:`aidnav.filters.loose._apply_correction`); ρ, θ, θ̇ stay in the state vector and
are propagated by Φ. The strapdown (:func:`aidnav.nav.strapdown.strapdown_step`) runs at the IMU rate
(0.01 s) and the filter at the master output rate (1 s) inside one numba kernel per run.

Initialisation (transfer of the master's output at t₀): position = master position + C̃_bm^n r,
velocity = lever-arm-compensated master velocity, attitude = master attitude (nominal mounting I),
biases 0. P₀ is diagonal with a diffuse φ and δv (``att_prior_deg``, ``vel_prior_m_s``), the master's
position accuracy, the sensor grade's bias σ, ``mounting_sigma_deg`` for ρ and the stationary flexure
covariance; the first update at t₀ then ties φ + C(ρ + θ) and δv to the master's output, which is the
joint prior of an initialisation from that output (φ₀ = −C(ρ+θ₀) − master error).

Consistency: with these choices the filter's NEES is within its χ² band over the whole run (tests).
Two details matter for that: the attitude residual uses the exact composition about the current
ρ̂ + θ̂ with the left Jacobian of SO(3) in H (:func:`_measurement`), and ρ, θ, θ̇ are never reset.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from aidnav.models.distributed_pos import FlexureSpec, MasterPosSpec
from aidnav.nav.earth import OMEGA_IE, lla_difference_enu, radii
from aidnav.nav.rotations import (
    dcm_from_euler,
    euler_error_map,
    quat_from_dcm,
    quat_to_euler_batch,
)
from aidnav.nav.strapdown import make_state

if TYPE_CHECKING:  # the simulator's containers, for annotations only (filters do not import sim)
    from aidnav.sim.distributed_pos import DistributedPosConfig, DistributedPosRun

from .ins_errors import (
    measurement_arrays,
    model_arrays,
)
from .kalman import predict, update
from .transfer_model import (  # noqa: F401  (re-exported: the model is part of this module's API)
    BA,
    BG,
    DEG,
    DP,
    DV,
    N_INS,
    N_NOISE_INS,
    PHI,
    RHO,
    THETA,
    THETA_DOT,
    _measurement,
    _transfer_kernel,
    discretize_transfer,
    fill_transfer_model,
    left_jacobian,
    state_labels,
)

__all__ = ["PHI", "DV", "DP", "BG", "BA", "RHO", "THETA", "THETA_DOT", "TransferConfig", "TransferResult",
           "TransferErrors", "fill_transfer_model", "discretize_transfer", "run_transfer", "transfer_errors",
           "segment_statistic", "covariance_analysis", "CovarianceAnalysis", "state_labels", "left_jacobian"]

# -------------------------------------------------------------------------------------- driver
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
    gyro_bias_sigma: float = 0.1 * DEG / 3600.0
    accel_bias_sigma: float = 50.0 * 9.80665e-6
    gyro_arw: float = 0.1 * DEG / 3600.0
    accel_vrw: float = 50.0 * 9.80665e-6
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


@dataclass
class TransferResult:
    """Output of :func:`run_transfer` at the filter epochs (after each update).

    time (M,) [s]; state (M, 10) sub lat, lon [rad], h [m], v^n [m/s], q_bs^n; rph (M, 3) sub roll,
    pitch, heading [rad]; bias (M, 6) gyro [rad/s] and accelerometer [m/s²] bias estimates; rho (M, 3)
    ρ̂ [rad]; theta (M, 3) θ̂ [rad]; theta_dot (M, 3) θ̂̇ [rad/s] (NaN for 21 states); pdiag (M, n)
    covariance diagonal; cov (M, n, n) full covariance (only with ``keep_cov``); nis (M,) 6-row NIS;
    accepted (M,) gate verdicts; innov, s_diag (M, 6) innovations and diag of their covariance.
    """

    time: np.ndarray
    state: np.ndarray
    rph: np.ndarray
    bias: np.ndarray
    rho: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    pdiag: np.ndarray
    cov: np.ndarray | None
    nis: np.ndarray
    accepted: np.ndarray
    innov: np.ndarray
    s_diag: np.ndarray
    config: TransferConfig


@njit(cache=True)
def _dcm_batch(rph):
    """(N, 3) roll, pitch, heading [rad] → (N, 3, 3) C_b^n."""
    out = np.empty((rph.shape[0], 3, 3))
    for i in range(rph.shape[0]):
        out[i] = dcm_from_euler(rph[i, 0], rph[i, 1], rph[i, 2])
    return out


def _master_arrays(master):
    """C̃_bm^n (M, 3, 3) and R_a (M, 3, 3) from the master output."""
    Cm = _dcm_batch(np.ascontiguousarray(master.rph))
    Mmap = euler_error_map(master.rph)
    Ra = Mmap @ np.diag(master.spec.att_sigma_rad**2) @ np.swapaxes(Mmap, -1, -2)
    return Cm, Ra


def run_transfer(run: DistributedPosRun, cfg: TransferConfig | None = None, keep_cov: bool = False,
                 imu=None) -> TransferResult:
    """Transfer-align the sub-IMU of ``run`` to its master POS output.

    cfg: filter settings (default :meth:`TransferConfig.from_sim` of the run's config, 24 states).
    keep_cov: keep the full covariance at every epoch. imu: sub-IMU increments to use instead of
    ``run.sub.imu`` (e.g. the error-free ones).
    """
    cfg = cfg or TransferConfig.from_sim(run.config)
    imu = imu if imu is not None else run.sub.imu
    master = run.master
    dt = float(imu.time[1] - imu.time[0])
    ratio = int(master.index[1] - master.index[0]) if len(master.index) > 1 else 1
    if master.index[0] != 0:
        raise ValueError("run_transfer: the master output must start at the first truth point")
    M = int(min(len(master.time), len(imu) // ratio + 1))
    r = np.asarray(cfg.lever_arm_m, float)
    Cm, Ra = _master_arrays(master)
    # initial sub state from the master output at t0
    rm, rn = radii(master.lat[0])
    h0 = master.height[0]
    dn = Cm[0] @ r
    lat0 = master.lat[0] + dn[1] / (rm + h0)
    lon0 = master.lon[0] + dn[0] / ((rn + h0) * math.cos(master.lat[0]))
    wie = np.array([0.0, OMEGA_IE * math.cos(master.lat[0]), OMEGA_IE * math.sin(master.lat[0])])
    web = master.w_ib[0] - Cm[0].T @ wie
    v0 = master.vel[0] + Cm[0] @ np.cross(web, r)
    st0 = make_state(lat0, lon0, h0 + dn[2], v0, quat_from_dcm(Cm[0]))
    P0 = cfg.initial_covariance(lat0, h0)
    fl = cfg.flexure
    out = _transfer_kernel(imu.dtheta, imu.dv, dt, ratio, st0, P0, fl.beta, np.maximum(fl.sigma, 1e-12),
                           cfg.gyro_arw**2, cfg.accel_vrw**2, r, Cm[:M], np.ascontiguousarray(master.vel[:M]),
                           np.ascontiguousarray(master.w_ib[:M]), Ra[:M], float(master.spec.sigma_vel_m_s),
                           float(cfg.gate), bool(keep_cov))
    st, bias, xo, pd, P, nis, ok, innov, sd = out
    n = cfg.nstate
    rph = quat_to_euler_batch(np.ascontiguousarray(st[:, 6:10]))
    tdot = xo[:, 6:9] if n == 24 else np.full((M, 3), np.nan)
    return TransferResult(time=master.time[:M].copy(), state=st, rph=rph, bias=bias, rho=xo[:, 0:3],
                          theta=xo[:, 3:6], theta_dot=tdot, pdiag=pd, cov=P if keep_cov else None, nis=nis,
                          accepted=ok, innov=innov, s_diag=sd, config=cfg)


@dataclass
class TransferErrors:
    """Errors (estimate − truth) of a transfer alignment at its epochs.

    time (M,) [s]; rph (M, 3) roll, pitch, heading errors [rad] (wrapped); phi (M, 3) misalignment φ
    [rad] (rotation vector, CONVENTIONS sign); vel (M, 3) ENU [m/s]; pos (M, 3) E, N, U [m]
    (lat error as N, lon error as E); baseline (M,) error of the master–sub distance |p̃_s − p̃_m| [m]
    (master output position against the sub estimate); rho (M, 3), theta (M, 3), theta_dot (M, 3)
    errors of the estimates [rad, rad, rad/s]; state (M, n) errors of the full state vector in the
    filter's definition (for NEES).
    """

    time: np.ndarray
    rph: np.ndarray
    phi: np.ndarray
    vel: np.ndarray
    pos: np.ndarray
    baseline: np.ndarray
    rho: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    state: np.ndarray


def transfer_errors(res: TransferResult, run: DistributedPosRun) -> TransferErrors:
    """Errors of ``res`` against the truth of ``run`` at the filter epochs."""
    from aidnav.nav.earth import lla_to_ecef
    from aidnav.nav.rotations import attitude_error_batch, euler_to_quat_batch

    idx = run.master.index[:len(res.time)]
    s = run.sub.truth
    d_rph = res.rph - s.rph[idx]
    d_rph = (d_rph + np.pi) % (2 * np.pi) - np.pi
    phi = attitude_error_batch(np.ascontiguousarray(res.state[:, 6:10]), euler_to_quat_batch(s.rph[idx]))
    dvel = res.state[:, 3:6] - s.vel[idx]
    de, dn, du = lla_difference_enu(res.state[:, 0], res.state[:, 1], res.state[:, 2], s.lat[idx], s.lon[idx],
                                    s.height[idx])
    pos = np.column_stack([de, dn, du])
    m = run.master
    M = len(res.time)
    ps = np.column_stack(lla_to_ecef(res.state[:, 0], res.state[:, 1], res.state[:, 2]))
    pm = np.column_stack(lla_to_ecef(m.lat[:M], m.lon[:M], m.height[:M]))
    ts = np.column_stack(lla_to_ecef(s.lat[idx], s.lon[idx], s.height[idx]))
    tm = np.column_stack(lla_to_ecef(run.master_truth.lat[idx], run.master_truth.lon[idx],
                                     run.master_truth.height[idx]))
    base = np.linalg.norm(ps - pm, axis=1) - np.linalg.norm(ts - tm, axis=1)
    drho = res.rho - run.sub.rho[None, :]
    dth = res.theta - run.sub.theta[idx]
    dthd = res.theta_dot - run.sub.theta_dot[idx]
    n = res.config.nstate
    x = np.zeros((M, n))
    x[:, PHI:PHI + 3] = phi
    x[:, DV:DV + 3] = dvel
    x[:, DP] = res.state[:, 0] - s.lat[idx]
    x[:, DP + 1] = res.state[:, 1] - s.lon[idx]
    x[:, DP + 2] = res.state[:, 2] - s.height[idx]
    # bias residual states are true − estimated
    x[:, BG:BG + 3] = run.sub.imu_errors["gyro_bias"][None, :] - res.bias[:, :3]
    x[:, BA:BA + 3] = run.sub.imu_errors["accel_bias"][None, :] - res.bias[:, 3:]
    # the filter's residual states are zero after feedback, so the error of the estimate is −(state)
    x[:, :N_INS] = -x[:, :N_INS]
    x[:, RHO:RHO + 3] = drho
    x[:, THETA:THETA + 3] = dth
    if n == 24:
        x[:, THETA_DOT:THETA_DOT + 3] = dthd
    return TransferErrors(time=res.time, rph=d_rph, phi=phi, vel=dvel, pos=pos, baseline=base, rho=drho,
                          theta=dth, theta_dot=dthd, state=x)


def segment_statistic(time: np.ndarray, err: np.ndarray, segments: list[dict], names=("AB", "CD"),
                      stat: str = "std") -> np.ndarray:
    """Mean over the named segments of a per-segment statistic of ``err`` ((M,) or (M, k)) over time.

    stat: "std" (standard deviation over the segment, about its mean: the seed's "STD") or "rms"
    (root mean square about zero). Epochs with start ≤ t ≤ end of a segment belong to it.
    """
    e = np.asarray(err, float)
    vals = []
    for name in names:
        row = next((r for r in segments if r["name"] == name), None)
        if row is None:
            raise KeyError(f"segment_statistic: no segment named {name!r}")
        msk = (time >= row["start_s"] - 1e-9) & (time <= row["end_s"] + 1e-9)
        seg = e[msk]
        if stat == "std":
            vals.append(np.std(seg, axis=0))
        elif stat == "rms":
            vals.append(np.sqrt(np.mean(seg**2, axis=0)))
        else:
            raise ValueError(f"segment_statistic: stat must be 'std' or 'rms', got {stat!r}")
    return np.mean(vals, axis=0)


# --------------------------------------------------------------------------- covariance analysis
@njit(cache=True)
def _interval_means(c_m, dth, dv, ratio):
    """Per filter interval: mean C_b^n, mean f^n [m/s²], mean ω_ib^b and f^b (sample-level C at starts)."""
    n = dth.shape[0]
    M = n // ratio
    Cmean = np.zeros((M, 3, 3))
    fn = np.zeros((M, 3))
    wb = np.zeros((M, 3))
    fb = np.zeros((M, 3))
    for j in range(M):
        for kk in range(ratio):
            i = j * ratio + kk
            C = c_m[i]
            Cmean[j] += C
            fn[j] += C @ dv[i]
            wb[j] += dth[i]
            fb[j] += dv[i]
        Cmean[j] /= ratio
    return Cmean, fn, wb, fb


@njit(cache=True)
def _covariance_kernel(lat, h, vel, Cm, Cmean, fn, wb, fb, T, P0, beta, sigma, q_gyro, q_accel, Ra, sig_v):
    """Covariance-only recursion along a known trajectory (no strapdown, no noise): P⁺ at each epoch."""
    M = lat.shape[0]
    n = P0.shape[0]
    P = P0.copy()
    x = np.zeros(n)
    F, G, Phi, Qd = model_arrays(n, 15)
    q = np.zeros(15)
    H, z, R, innov, sd = measurement_arrays(6, n)
    out = np.empty((M, n, n))
    for j in range(M):
        if j > 0:
            fill_transfer_model(F, G, q, lat[j], h[j], vel[j], fn[j - 1] / T, Cmean[j - 1], wb[j - 1] / T,
                                fb[j - 1] / T, beta, sigma, q_gyro, q_accel)
            discretize_transfer(F, G, q, T, beta, sigma, Phi, Qd)
            predict(x, P, Phi, Qd)
        H[:, :] = 0.0
        R[:, :] = 0.0
        for i in range(3):
            H[i, PHI + i] = 1.0
            H[3 + i, DV + i] = 1.0
            for k in range(3):
                H[i, RHO + k] = Cm[j, i, k]
                H[i, THETA + k] = Cm[j, i, k]
                R[i, k] = Ra[j, i, k]
            R[3 + i, 3 + i] = sig_v * sig_v
        update(x, P, H, R, z, 0.0, innov, sd)
        out[j] = P
    return out


@dataclass
class CovarianceAnalysis:
    """Predicted accuracy of the transfer alignment along a trajectory (no Monte Carlo).

    time (M,) [s]; cov (M, n, n) a-posteriori covariance; rph_sigma (M, 3) predicted 1σ of the sub's
    roll, pitch, heading errors [rad]; segments: the trajectory's segment table.
    """

    time: np.ndarray
    cov: np.ndarray
    rph_sigma: np.ndarray
    segments: list[dict]

    def segment_rms(self, names=("AB", "CD")) -> np.ndarray:
        """Mean over the named segments of the RMS of the predicted σ (roll, pitch, heading) [rad]:
        the prediction of the Monte Carlo RMS error of :func:`segment_statistic` (``stat="rms"``)."""
        vals = []
        for name in names:
            row = next(r for r in self.segments if r["name"] == name)
            msk = (self.time >= row["start_s"] - 1e-9) & (self.time <= row["end_s"] + 1e-9)
            vals.append(np.sqrt(np.mean(self.rph_sigma[msk] ** 2, axis=0)))
        return np.mean(vals, axis=0)


def covariance_analysis(truth_bundle, cfg: TransferConfig | None = None,
                        master: MasterPosSpec | None = None, rate_hz: float = 1.0) -> CovarianceAnalysis:
    """Covariance analysis of the transfer alignment along a trajectory, without Monte Carlo.

    truth_bundle: ``(truth, imu, segments)`` of :func:`aidnav.sim.trajectory.generate_truth` (the master
    truth; the sub's own motion differs only by the lever-arm terms, ignored here). The filter's F and
    H are evaluated on the truth (the covariance of a filter that linearises about a near-truth
    estimate), Φ, Qd and the updates use the same functions as :func:`run_transfer`.
    """
    truth, imu, segments = truth_bundle
    cfg = cfg or TransferConfig()
    master = master or cfg.master
    dt = float(truth.time[1] - truth.time[0])
    ratio = int(round(1.0 / (rate_hz * dt)))
    idx = np.arange(0, len(truth.time), ratio)
    M = len(idx)
    n_s = (M - 1) * ratio
    c_all = _dcm_batch(np.ascontiguousarray(truth.rph[:n_s]))
    Cmean, fn, wb, fb = _interval_means(c_all, imu.dtheta[:n_s], imu.dv[:n_s], ratio)
    Cm = _dcm_batch(np.ascontiguousarray(truth.rph[idx]))
    Mmap = euler_error_map(truth.rph[idx])
    Ra = Mmap @ np.diag(master.att_sigma_rad**2) @ np.swapaxes(Mmap, -1, -2)
    cfg_m = cfg if cfg.master == master else replace(cfg, master=master)
    P0 = cfg_m.initial_covariance(truth.lat[0], truth.height[0])
    fl = cfg.flexure
    T = ratio * dt
    cov = _covariance_kernel(truth.lat[idx], truth.height[idx], np.ascontiguousarray(truth.vel[idx]), Cm,
                             Cmean, fn, wb, fb, T, P0, fl.beta, np.maximum(fl.sigma, 1e-12), cfg.gyro_arw**2,
                             cfg.accel_vrw**2, Ra, float(master.sigma_vel_m_s))
    # Euler-angle σ: δe = M⁻¹ φ
    Minv = np.linalg.inv(Mmap)
    Pphi = cov[:, :3, :3]
    Pe = Minv @ Pphi @ np.swapaxes(Minv, -1, -2)
    sig = np.sqrt(np.maximum(np.diagonal(Pe, axis1=1, axis2=2), 0.0))
    return CovarianceAnalysis(time=truth.time[idx].copy(), cov=cov, rph_sigma=sig, segments=segments)
