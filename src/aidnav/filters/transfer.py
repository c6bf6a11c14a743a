"""Transfer alignment of a sub-IMU to a master POS by velocity + attitude matching (seed 004, §5.1), on
the filter engine (:mod:`aidnav.filters.engine`): the driver, the RTS smoother and the covariance
analysis. The state layout, the process model and the settings are in :mod:`.transfer_model` (names
re-exported here), the errors against a simulation's truth in :mod:`.transfer_errors`.

Frames and units: n = ENU, b = RFU; radians, metres, seconds (:mod:`.transfer_model`).

The engine runs the strapdown (:func:`aidnav.nav.strapdown.strapdown_step`) at the IMU rate
(0.01 s) and a node at each master output (1 s): prediction (the flexure block exact, ρ, θ, θ̇
open-loop), one 6-row velocity + attitude matching update (Joseph form, optional χ² gate) and the
closed-loop feedback of φ, δv, δp, ε, ∇ into the strapdown state and the bias estimates.

Initialisation (transfer of the master's output at t₀): position = master position + C̃_bm^n r,
velocity = lever-arm-compensated master velocity, attitude = master attitude (nominal mounting I),
biases 0. P₀ is diagonal with a diffuse φ and δv (``att_prior_deg``, ``vel_prior_m_s``), the master's
position accuracy, the sensor grade's bias σ, ``mounting_sigma_deg`` for ρ and the stationary flexure
covariance; the first update at t₀ (:func:`aidnav.filters.engine.initial_update`) then ties
φ + C(ρ + θ) and δv to the master's output, which is the joint prior of an initialisation from that
output (φ₀ = −C(ρ+θ₀) − master error).

Consistency: with these choices the filter's NEES is within its χ² band over the whole run (tests).
Two details matter for that: the attitude residual uses the exact composition about the current
ρ̂ + θ̂ with the left Jacobian of SO(3) in H, and ρ, θ, θ̇ are never reset. ``smooth=True`` adds
the engine's RTS pass over the epochs (t₀ included).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from types import SimpleNamespace
from typing import TYPE_CHECKING

import numpy as np

from aidnav.jit import njit
from aidnav.models.distributed_pos import MasterPosSpec
from aidnav.nav.earth import OMEGA_IE, radii
from aidnav.nav.rotations import dcm_from_euler, euler_error_map, quat_from_dcm, quat_to_euler_batch
from aidnav.nav.strapdown import make_state

from . import measurements as ms
from .engine import Imu, Init, Output, Records, initial_update, run_filter
from .smoother import rts, smooth_outputs
from .transfer_errors import TransferErrors, segment_statistic, transfer_errors
from .transfer_model import (  # noqa: F401  (re-exported: the model is part of this module's API)
    BA,
    BG,
    DEG,
    DP,
    DV,
    N_INS,
    PHI,
    RHO,
    THETA,
    THETA_DOT,
    TransferConfig,
    discretize_transfer,
    fill_transfer_model,
    left_jacobian,
    state_labels,
    transfer_models,
    transfer_process,
)

if TYPE_CHECKING:  # the simulator's containers, for annotations only (filters do not import sim)
    from aidnav.sim.distributed_pos import DistributedPosRun

__all__ = ["PHI", "DV", "DP", "BG", "BA", "RHO", "THETA", "THETA_DOT", "TransferConfig", "TransferResult",
           "TransferErrors", "fill_transfer_model", "discretize_transfer", "run_transfer", "transfer_errors",
           "segment_statistic", "covariance_analysis", "CovarianceAnalysis", "state_labels", "left_jacobian"]


@dataclass
class TransferResult:
    """Output of :func:`run_transfer` at the filter epochs (after each update).

    time (M,) [s]; state (M, 10) sub lat, lon [rad], h [m], v^n [m/s], q_bs^n; rph (M, 3) sub roll,
    pitch, heading [rad]; bias (M, 6) gyro [rad/s] and accelerometer [m/s²] bias estimates; rho (M, 3)
    ρ̂ [rad]; theta (M, 3) θ̂ [rad]; theta_dot (M, 3) θ̂̇ [rad/s] (NaN for 21 states); pdiag (M, n)
    covariance diagonal; cov (M, n, n) full covariance (only with ``keep_cov``); nis (M,) 6-row NIS;
    accepted (M,) gate verdicts; innov, s_diag (M, 6) innovations and diag of their covariance
    (attitude, then velocity). Smoothed (``smooth=True``): state, rph, bias, ρ̂, θ̂, θ̂̇, pdiag and cov
    are the RTS solution and ``forward`` holds the filter's.
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
    forward: TransferResult | None = None


@njit(cache=True)
def _dcm_batch(rph):
    """(N, 3) roll, pitch, heading [rad] → (N, 3, 3) C_b^n."""
    out = np.empty((rph.shape[0], 3, 3))
    for i in range(rph.shape[0]):
        out[i] = dcm_from_euler(rph[i, 0], rph[i, 1], rph[i, 2])
    return out


def _records(master, M: int) -> tuple[Records, np.ndarray]:
    """Velocity + attitude matching records of the first M master outputs (30-entry rows of
    :func:`aidnav.filters.measurements.attitude.velocity_attitude_matching`) and C̃_bm^n (M, 3, 3)."""
    rph = np.ascontiguousarray(master.rph[:M])
    Cm = _dcm_batch(rph)
    Mmap = euler_error_map(rph)
    Ra = Mmap @ np.diag(master.spec.att_sigma_rad**2) @ np.swapaxes(Mmap, -1, -2)
    data = np.zeros((M, 30))
    data[:, 0:3], data[:, 3:12] = master.vel[:M], Cm.reshape(M, 9)
    data[:, 12:15] = float(master.spec.sigma_vel_m_s)
    data[:, 18:27], data[:, 27:30] = Ra.reshape(M, 9), master.w_ib[:M]
    rec = Records(np.ascontiguousarray(master.time[:M], float), np.full(M, ms.M_VATT, np.int64), data,
                  np.ones(M, np.bool_))
    return rec, Cm


def _align(imu, master, cfg: TransferConfig, ratio: int, M: int, keep_cov: bool, smooth: bool,
           lever=None) -> TransferResult:
    """The engine run over M master epochs (epoch j at IMU sample boundary j·ratio)."""
    n = cfg.nstate
    r = np.asarray(cfg.lever_arm_m if lever is None else lever, float)
    rec, Cm = _records(master, M)
    # initial sub state from the master output at t0
    rm, rn = radii(master.lat[0])
    h0 = master.height[0]
    dn = Cm[0] @ r
    lat0 = master.lat[0] + dn[1] / (rm + h0)
    lon0 = master.lon[0] + dn[0] / ((rn + h0) * math.cos(master.lat[0]))
    wie = np.array([0.0, OMEGA_IE * math.cos(master.lat[0]), OMEGA_IE * math.sin(master.lat[0])])
    v0 = master.vel[0] + Cm[0] @ np.cross(master.w_ib[0] - Cm[0].T @ wie, r)
    st0 = make_state(lat0, lon0, h0 + dn[2], v0, quat_from_dcm(Cm[0]))
    dt = float(imu.time[1] - imu.time[0])
    proc = transfer_process(cfg, ratio * dt)
    mod = transfer_models(cfg, r)
    ini = Init(float(master.time[0]), st0, np.zeros(n - 9), cfg.initial_covariance(lat0, h0), -1, 0.0, 0.0,
               np.full(15, np.nan))
    st0, b0, P0, log0, dx0 = initial_update(rec, mod, proc, ini)
    ns = (M - 1) * ratio
    c = np.ascontiguousarray
    imu_in = Imu(c(imu.time[:ns], float), c(imu.dtheta[:ns]), c(imu.dv[:ns]), np.zeros(ns, np.bool_),
                 np.zeros((ns, 2)), np.zeros((0, 2)))
    cov_idx = np.arange(1, M, dtype=np.int64) * ratio - 1 if keep_cov else np.zeros(0, np.int64)
    o = run_filter(imu_in, rec, mod, proc, ini._replace(st=st0, bias=b0, P=P0), Output(0, smooth, cov_idx))
    if len(o.node_idx) != M - 1:
        raise RuntimeError(f"transfer: {len(o.node_idx)} engine nodes for {M - 1} master epochs")
    st, bias = np.vstack([st0, o.out_st]), np.vstack([b0, o.out_bias])
    pd = np.vstack([np.diag(P0), o.out_pdiag])
    cov = np.concatenate([P0[None], o.cov]) if keep_cov else None
    lg = o.log
    for k in ("nis", "nu", "s", "status"):
        getattr(lg, k)[0] = getattr(log0, k)[0]
    att_vel = [3, 4, 5, 0, 1, 2]  # the model's rows are velocity, then attitude
    res = _result(master.time[:M], st, bias, pd, cov, cfg)
    res.nis, res.accepted = lg.nis[:M].copy(), lg.status[:M] == 1
    res.innov, res.s_diag = lg.nu[:M][:, att_vel], lg.s[:M][:, att_vel]
    if not smooth:
        return res
    # the RTS pass over t0 and the engine's nodes (t0: no prediction before it, Φ = I unused)
    S_post, S_prior = np.concatenate([P0[None], o.S_post]), np.concatenate([P0[None], o.S_prior])
    S_phi = np.concatenate([np.eye(n)[None], o.S_phi])
    S_dx = np.concatenate([dx0[None], o.S_dx])
    ds, Ps = rts(S_post, S_prior, S_phi, S_dx, -1)
    k = np.arange(M, dtype=np.int64)
    sm_st, sm_b = smooth_outputs(k, st, bias, k, k, ds, S_dx, n)
    sm = _result(master.time[:M], sm_st, sm_b, np.einsum("kii->ki", Ps), Ps if keep_cov else None, cfg)
    return replace(sm, nis=res.nis, accepted=res.accepted, innov=res.innov, s_diag=res.s_diag, forward=res)


def _result(time, st, bias, pd, cov, cfg) -> TransferResult:
    """A :class:`TransferResult` from the engine's state and sensor/calibration estimates at the epochs."""
    M = len(time)
    tdot = bias[:, 12:15] if cfg.nstate == 24 else np.full((M, 3), np.nan)
    empty = np.zeros(0)
    return TransferResult(time=np.array(time, float), state=st, rph=quat_to_euler_batch(np.ascontiguousarray(
        st[:, 6:10])), bias=bias[:, :6].copy(), rho=bias[:, 6:9].copy(), theta=bias[:, 9:12].copy(),
        theta_dot=tdot.copy(), pdiag=pd, cov=cov, nis=empty, accepted=empty, innov=empty, s_diag=empty,
        config=cfg)


def run_transfer(run: DistributedPosRun, cfg: TransferConfig | None = None, keep_cov: bool = False,
                 imu=None, smooth: bool = False) -> TransferResult:
    """Transfer-align the sub-IMU of ``run`` to its master POS output.

    cfg: filter settings (default :meth:`TransferConfig.from_sim` of the run's config, 24 states).
    keep_cov: keep the full covariance at every epoch. imu: sub-IMU increments to use instead of
    ``run.sub.imu`` (e.g. the error-free ones). smooth: return the RTS solution (the filter's in
    ``forward``).
    """
    cfg = cfg or TransferConfig.from_sim(run.config)
    imu = imu if imu is not None else run.sub.imu
    master = run.master
    ratio = int(master.index[1] - master.index[0]) if len(master.index) > 1 else 1
    if master.index[0] != 0:
        raise ValueError("run_transfer: the master output must start at the first truth point")
    M = int(min(len(master.time), len(imu) // ratio + 1))
    return _align(imu, master, cfg, ratio, M, keep_cov, smooth)


# --------------------------------------------------------------------------- covariance analysis
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
    truth; the sub's own motion differs only by the lever-arm terms, ignored here). The engine runs the
    filter on the error-free increments with the master's error-free output as measurements: its F and
    H are those of the truth (the covariance of a filter that linearises about a near-truth estimate),
    and Φ, Qd and the updates are those of :func:`run_transfer`.
    """
    truth, imu, segments = truth_bundle
    cfg = cfg or TransferConfig()
    master = master or cfg.master
    dt = float(truth.time[1] - truth.time[0])
    ratio = int(round(1.0 / (rate_hz * dt)))
    idx = np.arange(0, len(truth.time), ratio)
    cfg_m = cfg if cfg.master == master else replace(cfg, master=master)
    out = SimpleNamespace(time=truth.time[idx], lat=truth.lat[idx], lon=truth.lon[idx],
                          height=truth.height[idx], vel=truth.vel[idx], rph=truth.rph[idx],
                          w_ib=np.zeros((len(idx), 3)), spec=master)
    res = _align(imu, out, cfg_m, ratio, len(idx), True, False, lever=np.zeros(3))
    # Euler-angle σ: δe = M⁻¹ φ
    Minv = np.linalg.inv(euler_error_map(truth.rph[idx]))
    Pe = Minv @ res.cov[:, :3, :3] @ np.swapaxes(Minv, -1, -2)
    sig = np.sqrt(np.maximum(np.diagonal(Pe, axis1=1, axis2=2), 0.0))
    return CovarianceAnalysis(time=truth.time[idx].copy(), cov=res.cov, rph_sigma=sig, segments=segments)
