"""Federated Kalman filter SINS/GPS + SINS/SAPV (seed 000), and the centralized filter it is compared with.

Frames and units (docs/conventions.md): n = ENU, b = RFU; strapdown state [lat, lon (rad), h (m), v^n (m/s),
q_b^n]; the 15-state INS error layout of :mod:`aidnav.filters.layout`. GNSS: antenna position/velocity
(:class:`aidnav.data.GnssData`); SAPV: antenna axis angles [rad] (:class:`aidnav.sim.sapv.SapvData`). A
measurement is used at the first IMU sample at or after its time (GPS: the INS moved back along its
velocity; SAPV: the line of sight carried by the body rotation, :func:`.measurements.sapv.carry_angles`).

Carlson's federated filter (§1.1): one strapdown INS, local 1 = SINS/GPS, local 2 = SINS/SAPV, and a
master with a time update only; sharing factors β_1 + β_2 + β_m = 1 (β_m = 0: no master). At each node
(each GPS or SAPV epoch, at most every ``prop_dt``): (1) time update of every filter with one Φ, Qd
(local i: Qd/β_i); (2) updates in the locals with the engine's records, models, gate policy and log
(:func:`aidnav.filters.gate.gated_update`); (3) fusion (:func:`fuse_information`) P_g = (Σ P_i⁻¹)⁻¹,
x_g = P_g Σ P_i⁻¹ x_i; (4) closed-loop feedback of x_g (:func:`aidnav.filters.engine.feedback`);
(5) ``"reset"``: P_i ← P_g/β_i, x_i ← 0 (algebraically the centralized filter), ``"no_reset"``: the
locals keep their covariances, x_i ← x_i − x_g (the fused covariance is a conservative bound).
``"centralized"``: one filter, GPS then SAPV updates. A local whose measurements stop keeps predicting.
``smooth``: the engine's RTS pass over the fused nodes with the fused prior Φ P_g Φᵀ + Qd (exact for
"reset" and "centralized"; for "no_reset" the smoother of the fused bound).
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass, field

import numpy as np

from aidnav.jit import njit
from aidnav.nav.geo_pointing import los_enu
from aidnav.nav.rotations import dcm_from_quat, quat_from_euler, quat_to_euler_batch
from aidnav.units import DEG

from . import ins_errors as ie
from .chi2 import chi2_isf
from .engine import (
    NEVER,
    Imu,
    Log,
    Models,
    Records,
    Work,
    feedback,
    node_rates,
)
from .gate import gated_update
from .kalman import discretize, predict
from .layout import ST_POS, ST_Q, make_layout
from .measurements import M_GNSS_POS, M_GNSS_VEL, M_SAPV, MAX_ROWS, MODELS_KEY, N_MODELS, Nav, fill
from .measurements import sapv as sp
from .measurements import streams as st_
from .measurements.common import W_FIX
from .measurements.gnss import W_FN
from .measurements.sapv import SAPV_BAD_INPUT, SAPV_BELOW_HORIZON, SAPV_SKIP_REASONS, SAPV_UNUSED
from .preprocess import gnss_arrays
from .prior import given_initial_state, initial_covariance, process_noise
from .run_log import log_dict
from .smoother import rts, smooth_outputs

__all__ = ["FederatedConfig", "FederatedResult", "run_federated", "run_centralized", "fuse_information",
           "spd_inverse", "MODES", "SAPV_SKIP_REASONS", "SAPV_UNUSED", "SAPV_BAD_INPUT", "SAPV_BELOW_HORIZON"]
MODES = {"centralized": 0, "reset": 1, "no_reset": 2}
# mode (MODES), beta (3,), t0 [s], st0 (10,), P0, q (PSDs), tau (g, a) [s], prop_dt [s], keep_cov, smooth
Fed = namedtuple("Fed", ["mode", "beta", "t0", "st", "P", "q", "tau", "prop_dt", "keep_cov", "smooth"])
FedOut = namedtuple("FedOut", ["node_k", "st", "bias", "pd", "loc", "cov", "log", "S_post", "S_prior",
                               "S_phi", "S_dx"])


@njit(cache=True)
def spd_inverse(P):
    """Symmetrised inverse of an SPD matrix with Jacobi scaling, P⁻¹ = D⁻¹ (D⁻¹ P D⁻¹)⁻¹ D⁻¹, D = √diag(P)
    (the INS covariance mixes rad², m², (rad/s)²: the scaled matrix is a correlation matrix)."""
    n = P.shape[0]
    d = np.empty(n)
    for i in range(n):
        d[i] = 1.0 / np.sqrt(P[i, i])
    S = np.outer(d, d)
    Ci = np.linalg.inv(P * S) * S
    return 0.5 * (Ci + Ci.T)


@njit(cache=True)
def fuse_information(Ps, xs, use):
    """P_g = (Σ P_i⁻¹)⁻¹, x_g = P_g Σ P_i⁻¹ x_i over Ps (k, n, n), xs (k, n) where ``use`` (k,) (a filter
    without information, e.g. a master with β_m = 0, is left out). Returns (P_g, x_g)."""
    n = Ps.shape[1]
    Y = np.zeros((n, n))
    y = np.zeros(n)
    for i in range(Ps.shape[0]):
        if use[i]:
            Yi = spd_inverse(Ps[i])
            Y += Yi
            y += Yi @ xs[i]
    Pg = spd_inverse(Y)
    return Pg, Pg @ y


@njit(cache=True, depends=MODELS_KEY)
def _federated_kernel(imu, gn, sv, mod, lay, fed):
    """Forward pass (module doc). gn, sv: engine :class:`Records` of GNSS (position, velocity) and SAPV
    (``sapv_model`` rows); mod: engine :class:`Models`; lay: layout 15; fed: :class:`Fed`."""
    n_imu, n, M, S, mode = imu.t.shape[0], fed.P.shape[0], gn.t.shape[0], sv.t.shape[0], fed.mode
    nloc, r_sapv = (1, 0) if mode == 0 else (2, 1)
    nf = nloc + 1  # locals 0..nloc-1, the master at nloc (used when β_m > 0)
    Pf, xf, qs, use_f = np.zeros((nf, n, n)), np.zeros((nf, n)), np.ones(nf), np.zeros(nf, np.bool_)
    for i in range(nf):
        if i < nloc or (mode != 0 and fed.beta[2] > 0.0):
            qs[i] = 1.0 if mode == 0 else 1.0 / fed.beta[min(i, 2)]
            Pf[i], use_f[i] = fed.P * qs[i], True
    st, bias, Pg = fed.st.copy(), np.zeros(n - 9), fed.P.copy()
    F, G, Phi, Qd = ie.model_arrays(n, ie.noise_count(n))
    wk = Work(np.zeros((MAX_ROWS, n)), np.zeros(MAX_ROWS), np.zeros((MAX_ROWS, MAX_ROWS)))
    w = np.zeros((5, 3))  # rows W_IB, W_FIX, W_IE, W_IN, W_FN (as the engine: models may read the mean f^n)
    mx = min(M + S + int((imu.t[-1] - fed.t0) / fed.prop_dt) + 3, n_imu)
    node_k, out_st, out_bias = np.empty(mx, np.int64), np.empty((mx, 10)), np.empty((mx, n - 9))
    out_pd, out_loc = np.empty((mx, n)), np.empty((mx, nloc, 3))
    out_cov = np.zeros((mx if fed.keep_cov else 1, n, n))
    ns = mx if fed.smooth else 1
    S_post, S_prior, S_phi = np.zeros((ns, n, n)), np.zeros((ns, n, n)), np.zeros((ns, n, n))
    S_dx = np.zeros((ns, n))
    cap = M + S
    log = Log(np.full(cap, np.nan), np.full(cap, -1, np.int8), np.full(cap, -1, np.int8),
              np.full(cap, np.nan), np.full((cap, MAX_ROWS), np.nan), np.full((cap, MAX_ROWS), np.nan),
              np.full(cap, -1, np.int64), np.zeros(cap, np.int8))
    for i in range(cap):
        log.t[i] = gn.t[i] if i < M else sv.t[i - M]
        log.model[i], log.ref[i] = (gn.model[i], i) if i < M else (M_SAPV, i - M)
    rej = np.zeros(N_MODELS, np.int64)
    gi, si = np.searchsorted(gn.t, fed.t0, side="right"), np.searchsorted(sv.t, fed.t0, side="right")
    acc = ie.new_accumulator()
    dthc, dvc, dth_prev, dv_prev = ie.increment_buffers()
    tp, kn = fed.t0, 0
    for k in range(n_imu):
        dt = imu.t[k] - tp
        tp = imu.t[k]
        T = ie.propagate_sample(st, acc, imu.dth[k], imu.dv[k], bias, dt, dthc, dvc, dth_prev, dv_prev)
        tk = imu.t[k] + 1e-9
        due = (gi < M and gn.t[gi] <= tk) or (si < S and sv.t[si] <= tk)
        if not ((T >= fed.prop_dt - 1e-9 or due or k == n_imu - 1) and T > 0.0):
            continue
        C = dcm_from_quat(st[ST_Q:ST_Q + 4])
        wb = ie.interval_model(F, G, st, acc, fed.tau[0], fed.tau[1], 0.0, 0.0)
        discretize(F, G, fed.q, T, Phi, Qd)
        for i in range(nf):  # 1. time update (local i with Q/β_i; the master with Q/β_m)
            if use_f[i]:
                predict(xf[i], Pf[i], Phi, Qd * qs[i])
        if fed.smooth:
            S_phi[kn], S_prior[kn] = Phi, Phi @ Pg @ Phi.T + Qd
        node_rates(st, wb, dthc, dt, w)
        w[W_FN] = acc[ie.ACC_FN] / T
        while gi < M and gn.t[gi] <= tk:  # 2. local updates: GNSS in local 1
            if gn.use[gi]:
                md = gn.model[gi]
                nav = Nav(st, C, w, imu.t[k] - gn.t[gi], bias)
                m = fill(md, nav, gn.data[gi], mod.par[md], lay, wk.H, wk.z, wk.R)
                if m > 0:
                    gated_update(xf[0], Pf[0], wk, m, md, mod, rej, log, gi)
            gi += 1
        while si < S and sv.t[si] <= tk:  # SAPV in local 2 (in the one filter when centralized)
            if sv.use[si]:
                row = sv.data[si].copy()
                sp.carry_angles(row, w[W_FIX], imu.t[k] - sv.t[si])
                if los_enu(st[ST_POS], st[ST_POS + 1], st[ST_POS + 2], row[0:3].copy())[2] < 0.0:
                    log.status[M + si] = SAPV_BELOW_HORIZON  # the antenna cannot be tracking it: skipped
                else:
                    nav = Nav(st, C, w, 0.0, bias)
                    m = fill(M_SAPV, nav, row, mod.par[M_SAPV], lay, wk.H, wk.z, wk.R)
                    gated_update(xf[r_sapv], Pf[r_sapv], wk, m, M_SAPV, mod, rej, log, M + si)
            si += 1
        if mode == 0:  # 3. fusion
            Pg, xg = Pf[0].copy(), xf[0].copy()
        else:
            Pg, xg = fuse_information(Pf, xf, use_f)
        feedback(st, bias, xg, n)  # 4. closed-loop feedback
        for i in range(nf):  # 5. reset / follow the correction
            if use_f[i]:
                if mode == 2:
                    xf[i] -= xg
                else:
                    xf[i][:] = 0.0
                    if mode == 1:
                        Pf[i][:, :] = Pg * qs[i]
        if fed.smooth:
            S_post[kn], S_dx[kn] = Pg, xg
        node_k[kn], out_st[kn], out_bias[kn] = k, st, bias
        out_pd[kn] = np.diag(Pg)
        for i in range(nloc):
            out_loc[kn, i] = np.sqrt(np.diag(Pf[i])[:3])
        if fed.keep_cov:
            out_cov[kn] = Pg
        kn += 1
        ie.reset_accumulator(acc)
    return FedOut(node_k[:kn], out_st[:kn], out_bias[:kn], out_pd[:kn], out_loc[:kn],
                  out_cov[:kn] if fed.keep_cov else out_cov[:0], log, S_post[:kn], S_prior[:kn], S_phi[:kn],
                  S_dx[:kn])


@dataclass(frozen=True)
class FederatedConfig:
    """Options of :func:`run_federated`.

    mode : ``"reset"`` (fusion-reset, default), ``"no_reset"`` or ``"centralized"``.
    beta_gps, beta_sapv, beta_master : information-sharing factors of local 1 (SINS/GPS), local 2
        (SINS/SAPV) and the master (time update only; 0 = no master); they must sum to 1 (ignored for
        ``"centralized"``).
    use_gps, use_sapv : which measurements are used at all (SINS/GPS = ``use_sapv=False``).
    sapv_position_columns : include the position columns of the SAPV H (§1.1 eq. 23); the seed drops
        them (eq. 26, the default).
    gate_probability : chi-square gate on each update (1 disables, the default).
    """

    mode: str = "reset"
    beta_gps: float = 0.5
    beta_sapv: float = 0.5
    beta_master: float = 0.0
    use_gps: bool = True
    use_sapv: bool = True
    sapv_position_columns: bool = False
    gate_probability: float = 1.0

    def __post_init__(self):
        if self.mode not in MODES:
            raise ValueError(f"FederatedConfig.mode must be one of {', '.join(MODES)} (got {self.mode!r})")
        if self.mode != "centralized":
            b = (self.beta_gps, self.beta_sapv, self.beta_master)
            if self.beta_gps <= 0 or self.beta_sapv <= 0 or self.beta_master < 0:
                raise ValueError("FederatedConfig: beta_gps, beta_sapv must be > 0 and beta_master >= 0")
            if abs(sum(b) - 1.0) > 1e-9:
                raise ValueError(f"FederatedConfig: the information-sharing factors must sum to 1 "
                                 f"(beta_gps + beta_sapv + beta_master = {sum(b):.12g})")
        if not 0 < self.gate_probability <= 1:
            raise ValueError("FederatedConfig.gate_probability must be in (0, 1]")

    @property
    def label(self) -> str:
        """Short name, e.g. ``reset b=0.5/0.5`` or ``centralized``."""
        if self.mode == "centralized":
            parts = [s for s, u in (("GPS", self.use_gps), ("SAPV", self.use_sapv)) if u]
            return "centralized " + "+".join(parts)
        m = f"/m{self.beta_master:g}" if self.beta_master > 0 else ""
        return f"{self.mode} b={self.beta_gps:g}/{self.beta_sapv:g}{m}"


@dataclass
class FederatedResult:
    """Output of :func:`run_federated` at the filter nodes (after the feedback).

    time : (K,) [s]; state : (K, 10) [lat, lon, h, vE, vN, vU, q_b^n]; rph : (K, 3) roll, pitch, heading
    [rad]; bias : (K, 6) gyro [rad/s] and accelerometer [m/s²] bias estimates; pdiag : (K, 15) diagonal of
    the fused covariance P_g (smoothed when ``smoothed``; forward in ``forward_state``/``forward_pdiag``);
    cov : (K, 15, 15) forward P_g (only with ``keep_cov``); local_att_std : (K, nloc, 3) 1σ of φ in each
    local filter [rad] (inflated by 1/β_i); gps_pos_status, gps_vel_status : (M,) int8 per fix, −1 not
    used, 0 gated out, 1 used; gps_pos_nis, gps_vel_nis : (M,); sapv_status : (S,) int8 likewise, below −1
    skipped (−2 bad input: NaN on a tracking epoch, az ∉ [0, 2π) or el ∉ [−π/2, π/2]; −3 satellite below
    the local horizon); sapv_innov : (S, 2) ν [rad]; sapv_s : (S, 2) diag S [rad²]; sapv_nis : (S,);
    counts : ``{"sapv_used", "sapv_gated", "sapv_skipped": {reason: int}}`` (:data:`SAPV_SKIP_REASONS`;
    a run with ``use_sapv=False`` counts none as skipped); innovations : the engine log (GNSS, then SAPV).
    """

    time: np.ndarray
    state: np.ndarray
    rph: np.ndarray
    bias: np.ndarray
    pdiag: np.ndarray
    cov: np.ndarray | None
    local_att_std: np.ndarray
    gps_pos_status: np.ndarray
    gps_vel_status: np.ndarray
    gps_pos_nis: np.ndarray
    gps_vel_nis: np.ndarray
    sapv_status: np.ndarray
    sapv_innov: np.ndarray
    sapv_s: np.ndarray
    sapv_nis: np.ndarray
    config: FederatedConfig
    counts: dict = field(default_factory=dict)
    smoothed: bool = False
    forward_state: np.ndarray | None = None
    forward_pdiag: np.ndarray | None = None
    innovations: dict = field(default_factory=dict)


def run_federated(imu, gnss, sapv, cfg, fed: FederatedConfig | None = None, *, keep_cov: bool = False,
                  smooth: bool = False) -> FederatedResult:
    """SINS/GPS/SAPV: federated (fusion-reset or no-reset) or centralized error-state Kalman filter.
    imu : :class:`aidnav.data.ImuData` (increments, body RFU); the filter starts at ``imu.t0``.
    gnss : :class:`aidnav.data.GnssData` antenna fixes (σ columns or ``cfg.gnss.default_*``), or None.
    sapv : :class:`aidnav.sim.sapv.SapvData` antenna angles (NaN = not tracking; R = its ``sigma``²), or None.
    cfg : :class:`aidnav.filters.config.LooseConfig` with ``init.mode = "given"`` (initial state and σ),
        the IMU noise model, the GNSS σ handling (:func:`aidnav.filters.loose.gnss_arrays`) and
        ``filter.prop_dt_s``; 15 states only. fed : :class:`FederatedConfig` (default: fusion-reset,
        β = 1/2, 1/2). keep_cov : keep the full forward fused covariance at every node.
    smooth : RTS smoother over the fused nodes (module doc); the forward solution stays in ``forward_*``.
    """
    fed = fed or FederatedConfig()
    if cfg.nstate != 15:
        raise ValueError("run_federated: the SAPV federated filter has the 15-state model (no scale factors)")
    ini = cfg.init
    if ini.mode != "given":
        raise ValueError("run_federated needs cfg.init.mode = 'given' (initial position, velocity, attitude)")
    lat0, lon0, h0, v0, rph0 = given_initial_state(ini, "run_federated")
    q0 = quat_from_euler(rph0[0], rph0[1], rph0[2])
    st0 = np.array([lat0, lon0, h0, *v0, *q0], float)
    P0 = initial_covariance(cfg, 15, lat0, h0, np.array(ini.attitude_sigma_deg) * DEG)
    m = 0 if gnss is None else len(gnss)
    use_g = fed.use_gps and m > 0
    g = gnss_arrays(gnss, cfg) if m else (np.zeros(0),) * 4 + (np.zeros((0, 3)),) * 3
    gr, order = st_.gnss_records(g, use_g and cfg.gnss.use in ("both", "position"),
                                 use_g and cfg.gnss.use in ("both", "velocity"))
    sr, s_skip = st_.sapv_records(sapv, fed.use_sapv)
    gn, sv = Records(*gr), Records(*sr)
    gp = fed.gate_probability
    par = np.zeros((N_MODELS, 4))
    par[M_GNSS_POS, :3] = par[M_GNSS_VEL, :3] = cfg.gnss.lever_arm_m
    par[M_SAPV, 0] = fed.sapv_position_columns
    gate = np.zeros((N_MODELS, MAX_ROWS + 1))
    if gp < 1:
        gate[M_GNSS_POS, 1:4] = gate[M_GNSS_VEL, 1:4] = chi2_isf(3, 1.0 - gp)  # one χ²(3) gate (as before)
        gate[M_SAPV, 2] = chi2_isf(2, 1.0 - gp)
    mod = Models(par, gate, np.full(N_MODELS, NEVER, np.int64), np.zeros((0, 2), np.int64))
    t_imu = np.ascontiguousarray(imu.time, dtype=float)
    no = np.zeros((0, 2))
    imu_in = Imu(t_imu, imu.dtheta, imu.dv, np.zeros(len(t_imu), np.bool_), no, no)
    f = Fed(MODES[fed.mode], np.array([fed.beta_gps, fed.beta_sapv, fed.beta_master], float), float(imu.t0),
            st0, P0, process_noise(cfg, 15), np.array([cfg.imu.gyro_bias_tau_s, cfg.imu.accel_bias_tau_s]),
            float(cfg.filter.prop_dt_s), bool(keep_cov), bool(smooth))
    r = _federated_kernel(imu_in, gn, sv, mod, make_layout(), f)
    log = log_dict(r.log, len(r.log.t))
    M = len(gn.t)
    gl = st_.per_fix(log, order, m)
    rs, ls = log["status"][M:].copy(), slice(M, None)
    counts = sp.sapv_counts(rs, s_skip, fed.use_sapv and len(sv.t) > 0)
    rph = quat_to_euler_batch(np.ascontiguousarray(r.st[:, 6:10]))
    res = FederatedResult(time=t_imu[r.node_k], state=r.st, rph=rph, bias=r.bias, pdiag=r.pd,
                          cov=r.cov if keep_cov else None, local_att_std=r.loc,
                          gps_pos_status=gl["status"][0], gps_vel_status=gl["status"][1],
                          gps_pos_nis=gl["nis"][0], gps_vel_nis=gl["nis"][1], sapv_status=rs,
                          sapv_innov=log["nu"][ls, :2], sapv_s=log["s"][ls, :2], sapv_nis=log["nis"][ls],
                          config=fed, counts=counts, innovations=log)
    if smooth and len(r.node_k) > 1:
        ds, Ps = rts(r.S_post, r.S_prior, r.S_phi, r.S_dx, -1)
        kk = r.node_k
        sm_st, sm_b = smooth_outputs(kk, r.st, r.bias, np.arange(len(kk)), kk, ds, r.S_dx, 15)
        res.forward_state, res.forward_pdiag = res.state, res.pdiag
        res.state, res.bias, res.pdiag = sm_st, sm_b, np.einsum("kii->ki", Ps)
        res.rph, res.smoothed = quat_to_euler_batch(np.ascontiguousarray(sm_st[:, 6:10])), True
    return res


def run_centralized(imu, gnss, sapv, cfg, *, use_gps: bool = True, use_sapv: bool = True,
                    sapv_position_columns: bool = False, gate_probability: float = 1.0,
                    keep_cov: bool = False) -> FederatedResult:
    """One 15-state filter with GPS and SAPV (the federated filter's reference; as :func:`run_federated`;
    ``use_sapv=False`` is the seed's SINS/GPS)."""
    fed = FederatedConfig(mode="centralized", use_gps=use_gps, use_sapv=use_sapv,
                          sapv_position_columns=sapv_position_columns, gate_probability=gate_probability)
    return run_federated(imu, gnss, sapv, cfg, fed, keep_cov=keep_cov)
