"""Federated Kalman filter SINS/GPS + SINS/SAPV (seed 000), and the centralized filter it is compared with.

Frames and units (``CONVENTIONS.md``): n = ENU, b = RFU; strapdown state [lat, lon (rad), h (m), v^n (m/s),
q_b^n]; the 15-state error model of :mod:`aidnav.filters.ins_errors` (φ with C_b^n(computed) =
(I − [φ×]) C_b^n(true), δv, δL δλ δh, gyro bias residual ε [rad/s], accelerometer bias residual ∇
[m/s²], all computed − true). GNSS fixes: antenna position/velocity (:class:`aidnav.data.GnssData`);
SAPV: antenna azimuth/elevation axis angles [rad] (:class:`aidnav.sim.sapv.SapvData`). A measurement is
used at the first IMU sample t_k at or after its time t_j (GPS: the INS is moved back along its velocity;
SAPV: the line of sight is carried by the body rotation over t_k − t_j).

Architecture (Carlson's federated filter, SPEC §1.1): one strapdown INS (numba, every IMU sample), two
*local* filters sharing its 15-state error model, local 1 = SINS/GPS (position + velocity,
:func:`~aidnav.filters.measurements.gnss_position`, :func:`~aidnav.filters.measurements.gnss_velocity`),
local 2 = SINS/SAPV (:func:`~aidnav.filters.measurements.sapv_angles`), and a *master* filter that does a
time update only. Information-sharing factors β_1 + β_2 + β_m = 1 (β_m = 0: no master). At every filter
epoch (covariance node: each GPS or SAPV epoch and at most every ``prop_dt`` seconds):

1. time update of every filter with the same Φ and Qd (:func:`~aidnav.filters.kalman.discretize`,
   :func:`~aidnav.filters.kalman.predict`): local i uses Q_i = Qd/β_i (master Qd/β_m);
2. measurement updates in the local filters (:func:`~aidnav.filters.kalman.update`, Joseph form);
3. fusion (:func:`fuse_information`): P_g = (Σ P_i⁻¹ + P_m⁻¹)⁻¹, x_g = P_g (Σ P_i⁻¹ x_i + P_m⁻¹ x_m);
4. closed-loop feedback of x_g to the INS (:func:`aidnav.filters.loose._apply_correction`:
   C_b^n ← (I + [φ̂×]) C_b^n, v ← v − δv̂, p ← p − δp̂, bias estimates ← + ε̂, ∇̂);
5. mode ``"reset"`` (fusion-reset): P_i ← P_g/β_i, x_i ← 0 (and the master likewise). With the same
   linearisation point for all local filters this is algebraically the centralized filter (the
   information of the priors sums to P_g⁻¹, the measurement information adds), so it equals
   ``"centralized"`` up to rounding. Mode ``"no_reset"``: the local filters keep their covariances and
   only follow the INS correction (x_i ← x_i − x_g: their estimate of the true state is unchanged); with
   P_i(0) = P_0/β_i and Q_i = Q/β_i the fused covariance is a conservative bound (not optimal), and a
   fault in one local filter does not propagate into the others.

``"centralized"``: one filter with all measurements (GPS and SAPV) in sequence, before the feedback.
The INS-only solution with GPS (``use_sapv=False``) is the seed's SINS/GPS.

When one local filter's measurements stop (SAPV lost: NaN epochs of :class:`~aidnav.sim.sapv.SapvData`;
GPS outage: missing fixes) its filter keeps predicting and the fused solution continues on the other.

The per-IMU-sample work (strapdown, bias compensation, interval sums for F) and the epoch work (the
covariance algebra) are one numba kernel (:func:`_federated_kernel`), as the loosely coupled filter.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from aidnav.nav.earth import OMEGA_IE, radii
from aidnav.nav.geo_pointing import az_el_from_body, beam_body, los_enu
from aidnav.nav.rotations import dcm_from_quat

from .ins_errors import (
    increment_buffers,
    interval_model,
    measurement_arrays,
    model_arrays,
    new_accumulator,
    noise_count,
    propagate_sample,
    reset_accumulator,
)
from .kalman import discretize, predict, update
from .loose import _apply_correction
from .measurements import gnss_position, gnss_velocity, sapv_angles

__all__ = ["FederatedConfig", "FederatedResult", "run_federated", "run_centralized", "fuse_information",
           "spd_inverse", "MODES", "SAPV_SKIP_REASONS"]

MODES = {"centralized": 0, "reset": 1, "no_reset": 2}

# FederatedResult.sapv_status codes of SAPV epochs that were not used
SAPV_UNUSED = -1  #: antenna not tracking (reason flag), or SAPV not used in this run
SAPV_BAD_INPUT = -2  #: NaN on an epoch flagged as tracking, or an angle outside its range
SAPV_BELOW_HORIZON = -3  #: the satellite is below the local horizon at the INS position
#: FederatedResult.counts["sapv_skipped"] keys: why SAPV epochs were skipped
SAPV_SKIP_REASONS = {
    "not_tracking": "antenna reports no lock (SapvData.reason != OK)",
    "nan": "non-finite az/el on an epoch flagged as tracking",
    "angle_out_of_range": "azimuth outside [0, 2*pi) or elevation outside [-pi/2, pi/2] rad",
    "below_horizon": "the satellite is below the local horizon at the INS position",
}

# float parameters of the kernel
P_PROP_DT = 0
P_TAU_G = 1
P_TAU_A = 2
P_GATE_POS = 3
P_GATE_VEL = 4
P_GATE_SAPV = 5
P_USE_POS = 6
P_USE_VEL = 7
P_USE_SAPV = 8
P_SAPV_POS = 9
P_LEVER = 10  # 3
N_PAR = 13


@njit(cache=True)
def spd_inverse(P):
    """Inverse of a symmetric positive-definite matrix with Jacobi (diagonal) scaling.

    P⁻¹ = D⁻¹ (D⁻¹ P D⁻¹)⁻¹ D⁻¹ with D = √diag(P): the INS error covariance mixes rad², m² and (rad/s)²
    (diagonal spanning ~25 orders of magnitude); the scaled matrix is a correlation matrix whose
    condition number reflects only the correlations. Returns the symmetrised inverse.
    """
    n = P.shape[0]
    d = np.empty(n)
    for i in range(n):
        d[i] = 1.0 / np.sqrt(P[i, i])
    S = np.outer(d, d)
    Ci = np.linalg.inv(P * S) * S
    return 0.5 * (Ci + Ci.T)


@njit(cache=True)
def fuse_information(Ps, xs, use):
    """Information fusion of the federated filter: P_g = (Σ P_i⁻¹)⁻¹, x_g = P_g Σ P_i⁻¹ x_i.

    Ps (k, n, n), xs (k, n); use (k,) bool: which filters take part (a filter with no information, e.g. a
    master with β_m = 0, is left out). Returns (P_g, x_g).
    """
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


@njit(cache=True)
def _federated_kernel(imu_t, dth, dvel, t0, st0, P0, q_psd, par, mode, beta,
                      g_t, g_lat, g_lon, g_h, g_vel, g_spos, g_svel, g_use,
                      s_t, s_az, s_el, s_sig, s_use, sat, keep_cov):
    n_imu = imu_t.shape[0]
    n = P0.shape[0]
    m = noise_count(n)
    M = g_t.shape[0]
    S = s_t.shape[0]
    nloc = 1 if mode == 0 else 2
    r_sapv = 0 if mode == 0 else 1
    has_master = mode != 0 and beta[2] > 0.0
    # filters: locals 0..nloc-1, the master at index nloc (used only when has_master)
    nf = nloc + 1
    Pf = np.zeros((nf, n, n))
    xf = np.zeros((nf, n))
    qs = np.ones(nf)
    use_f = np.zeros(nf, np.bool_)
    for i in range(nloc):
        qs[i] = 1.0 if mode == 0 else 1.0 / beta[i]
        Pf[i] = P0 * qs[i]
        use_f[i] = True
    if has_master:
        qs[nloc] = 1.0 / beta[2]
        Pf[nloc] = P0 * qs[nloc]
        use_f[nloc] = True
    st = st0.copy()
    bias = np.zeros(n - 9)
    F, G, Phi, Qd = model_arrays(n, m)
    H3, z3, R3, innov3, sd3 = measurement_arrays(3, n)  # GPS position / velocity
    H2, z2, R2, innov2, sd2 = measurement_arrays(2, n)  # SAPV azimuth / elevation
    lever = par[P_LEVER:P_LEVER + 3].copy()
    prop_dt = par[P_PROP_DT]
    max_nodes = M + S + int((imu_t[-1] - t0) / prop_dt) + 3
    if max_nodes > n_imu:
        max_nodes = n_imu
    node_k = np.empty(max_nodes, np.int64)
    out_st = np.empty((max_nodes, 10))
    out_bias = np.empty((max_nodes, n - 9))
    out_pd = np.empty((max_nodes, n))
    out_loc = np.empty((max_nodes, nloc, 3))
    out_cov = np.zeros((max_nodes if keep_cov else 1, n, n))
    rec_pos = np.full(M, -1, np.int8)
    rec_vel = np.full(M, -1, np.int8)
    rec_pos_nis = np.full(M, np.nan)
    rec_vel_nis = np.full(M, np.nan)
    rec_s = np.full(S, -1, np.int8)
    rec_s_innov = np.full((S, 2), np.nan)
    rec_s_s = np.full((S, 2), np.nan)
    rec_s_nis = np.full(S, np.nan)
    gi = 0
    while gi < M and g_t[gi] <= t0:
        gi += 1
    si = 0
    while si < S and s_t[si] <= t0:
        si += 1
    acc = new_accumulator()  # sums over the samples since the last node (ins_errors.ACC_*)
    dthc, dvc, dth_prev, dv_prev = increment_buffers()  # corrected increments: this / previous sample
    tp = t0
    kn = 0
    for k in range(n_imu):
        dt = imu_t[k] - tp
        tp = imu_t[k]
        T = propagate_sample(st, acc, dth[k], dvel[k], bias, dt, dthc, dvc, dth_prev, dv_prev)
        tk = imu_t[k] + 1e-9
        is_node = (T >= prop_dt - 1e-9 or (gi < M and g_t[gi] <= tk) or (si < S and s_t[si] <= tk)
                   or k == n_imu - 1)
        if not (is_node and T > 0.0):
            continue
        C = dcm_from_quat(st[6:10])
        interval_model(F, G, st, acc, par[P_TAU_G], par[P_TAU_A], 0.0, 0.0)
        discretize(F, G, q_psd, T, Phi, Qd)
        # 1. time update of every filter (local i with Q/β_i; the master with Q/β_m)
        for i in range(nf):
            if use_f[i]:
                predict(xf[i], Pf[i], Phi, Qd * qs[i])
        # 2. local measurement updates
        while gi < M and g_t[gi] <= tk:
            if g_use[gi]:
                if par[P_USE_POS] > 0:
                    gnss_position(st, C, lever, g_lat[gi], g_lon[gi], g_h[gi], imu_t[k] - g_t[gi], H3, z3)
                    R3[:, :] = 0.0
                    for i in range(3):
                        R3[i, i] = g_spos[gi, i] ** 2
                    ok, nis = update(xf[0], Pf[0], H3, R3, z3, par[P_GATE_POS], innov3, sd3)
                    rec_pos[gi] = 1 if ok else 0
                    rec_pos_nis[gi] = nis
                if par[P_USE_VEL] > 0 and not np.isnan(g_vel[gi, 0]):
                    cl = np.cos(st[0])
                    sl = np.sin(st[0])
                    rm, rn = radii(st[0])
                    w_in = np.array([-st[4] / (rm + st[2]), OMEGA_IE * cl + st[3] / (rn + st[2]),
                                     OMEGA_IE * sl + st[3] * sl / cl / (rn + st[2])])
                    gnss_velocity(st, C, lever, dthc / dt, w_in, g_vel[gi], H3, z3)
                    R3[:, :] = 0.0
                    for i in range(3):
                        R3[i, i] = g_svel[gi, i] ** 2
                    ok, nis = update(xf[0], Pf[0], H3, R3, z3, par[P_GATE_VEL], innov3, sd3)
                    rec_vel[gi] = 1 if ok else 0
                    rec_vel_nis[gi] = nis
            gi += 1
        while si < S and s_t[si] <= tk:
            if s_use[si] and par[P_USE_SAPV] > 0:
                az_m, el_m = s_az[si], s_el[si]
                dtb = imu_t[k] - s_t[si]
                if dtb > 1e-9:
                    # the angles describe the body at t_j < t_k: carry the (nav-fixed) line of sight into the
                    # body frame at t_k, r_b(k) = (I − [θ×]) r_b(j) with θ = ω_ib^b (t_k − t_j)
                    u = beam_body(az_m, el_m)
                    th = dthc * (dtb / dt)
                    az_m, el_m = az_el_from_body(u - np.cross(th, u))
                if los_enu(st[0], st[1], st[2], sat)[2] < 0.0:
                    # the satellite is below the local horizon at the INS position: the antenna cannot be
                    # tracking it (wrong satellite longitude / data): skipped, flagged
                    rec_s[si] = SAPV_BELOW_HORIZON
                else:
                    sapv_angles(st, C, sat, az_m, el_m, par[P_SAPV_POS] > 0, H2, z2)
                    R2[0, 0] = s_sig[0] ** 2
                    R2[1, 1] = s_sig[1] ** 2
                    ok, nis = update(xf[r_sapv], Pf[r_sapv], H2, R2, z2, par[P_GATE_SAPV], innov2, sd2)
                    rec_s[si] = 1 if ok else 0
                    rec_s_nis[si] = nis
                    rec_s_innov[si] = innov2
                    rec_s_s[si] = sd2
            si += 1
        # 3. fusion
        if mode == 0:
            Pg = Pf[0].copy()
            xg = xf[0].copy()
        else:
            Pg, xg = fuse_information(Pf, xf, use_f)
        # 4. closed-loop feedback to the INS
        _apply_correction(st, bias, xg, n)
        # 5. reset / follow the correction
        for i in range(nf):
            if not use_f[i]:
                continue
            if mode == 2:
                xf[i] -= xg
            else:
                xf[i][:] = 0.0
                if mode == 1:
                    Pf[i][:, :] = Pg * qs[i]
        node_k[kn] = k
        out_st[kn] = st
        out_bias[kn] = bias
        for i in range(n):
            out_pd[kn, i] = Pg[i, i]
        for i in range(nloc):
            for j in range(3):
                out_loc[kn, i, j] = np.sqrt(Pf[i][j, j])
        if keep_cov:
            out_cov[kn] = Pg
        kn += 1
        reset_accumulator(acc)
    return (node_k[:kn], out_st[:kn], out_bias[:kn], out_pd[:kn], out_loc[:kn],
            out_cov[:kn] if keep_cov else out_cov[:0], rec_pos, rec_vel, rec_pos_nis, rec_vel_nis,
            rec_s, rec_s_innov, rec_s_s, rec_s_nis)


# ------------------------------------------------------------------------------------------ driver
@dataclass(frozen=True)
class FederatedConfig:
    """Options of :func:`run_federated`.

    mode : ``"reset"`` (fusion-reset, default), ``"no_reset"`` or ``"centralized"``.
    beta_gps, beta_sapv, beta_master : information-sharing factors of local 1 (SINS/GPS), local 2
        (SINS/SAPV) and the master (time update only; 0 = no master); they must sum to 1 (ignored for
        ``"centralized"``).
    use_gps, use_sapv : which measurements are used at all (SINS/GPS = ``use_sapv=False``).
    sapv_position_columns : include the position columns of the SAPV H (SPEC eq. 23); the seed drops
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
    """Output of :func:`run_federated` at the filter epochs (after the feedback).

    time : (K,) [s]; state : (K, 10) [lat, lon, h, vE, vN, vU, q_b^n]; rph : (K, 3) roll, pitch, heading
    [rad]; bias : (K, 6) estimated gyro [rad/s] and accelerometer [m/s²] biases; pdiag : (K, 15) diagonal
    of the fused covariance P_g; cov : (K, 15, 15) P_g (only with ``keep_cov``); local_att_std :
    (K, nloc, 3) 1σ of φ in each local filter [rad] (inflated by 1/β_i in the federated modes);
    gps_pos_status, gps_vel_status : (M,) int8 per fix, −1 not used, 0 gated out, 1 used; gps_pos_nis,
    gps_vel_nis : (M,); sapv_status : (S,) int8 likewise; sapv_innov : (S, 2) ν = z − H x [rad];
    sapv_s : (S, 2) diag of its S [rad²]; sapv_nis : (S,) (of the filter that used it); config : the
    :class:`FederatedConfig`. sapv_status codes below −1: −2 bad input (NaN angles on an epoch flagged
    as tracking, azimuth outside [0, 2π) or elevation outside [−π/2, π/2]), −3 satellite below the local
    horizon at the INS position; those epochs are skipped. counts : ``{"sapv_used", "sapv_gated": int,
    "sapv_skipped": {reason: int}}`` with the reasons of :data:`SAPV_SKIP_REASONS` (epochs of a run with
    ``use_sapv=False`` are not counted as skipped).
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


def _empty_gnss():
    z = np.zeros(0)
    return z, z, z, z, np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3))


def run_federated(imu, gnss, sapv, cfg, fed: FederatedConfig | None = None, *,
                  keep_cov: bool = False) -> FederatedResult:
    """SINS/GPS/SAPV: federated (fusion-reset or no-reset) or centralized error-state Kalman filter.

    Parameters
    ----------
    imu : :class:`aidnav.data.ImuData` (increments, body RFU); the filter starts at ``imu.t0``.
    gnss : :class:`aidnav.data.GnssData` antenna fixes (σ columns or ``cfg.gnss.default_*``), or None.
    sapv : :class:`aidnav.sim.sapv.SapvData` antenna angles (NaN = not tracking; R = its ``sigma``²), or None.
    cfg : :class:`aidnav.filters.config.LooseConfig` with ``init.mode = "given"`` (initial position,
        velocity, attitude and their σ), the IMU noise model (:func:`aidnav.filters.loose.process_noise`,
        :func:`aidnav.filters.loose.initial_covariance`), the GNSS σ handling
        (:func:`aidnav.filters.loose.gnss_arrays`: floors, scale factors) and ``filter.prop_dt_s``.
        Only 15 states (no scale factors).
    fed : :class:`FederatedConfig` (default: fusion-reset, β = 1/2, 1/2).
    keep_cov : keep the full fused covariance at every epoch (``FederatedResult.cov``).

    Returns
    -------
    :class:`FederatedResult` (algorithm in the module docstring).
    """
    from scipy.special import chdtri

    from aidnav.nav.rotations import quat_from_euler, quat_to_euler_batch

    from .config import DEG
    from .loose import gnss_arrays, initial_covariance, process_noise

    fed = fed or FederatedConfig()
    if cfg.nstate != 15:
        raise ValueError("run_federated: the SAPV federated filter has the 15-state model (no scale factors)")
    ini = cfg.init
    if ini.mode != "given":
        raise ValueError("run_federated needs cfg.init.mode = 'given' (initial position, velocity, attitude)")
    missing = [k for k in ("lat_deg", "lon_deg", "height_m", "roll_deg", "pitch_deg", "heading_deg")
               if getattr(ini, k) is None]
    if missing:
        raise ValueError(f"init.mode = given needs init.{', init.'.join(missing)}")
    lat0, lon0, h0 = ini.lat_deg * DEG, ini.lon_deg * DEG, ini.height_m
    q0 = quat_from_euler(ini.roll_deg * DEG, ini.pitch_deg * DEG, ini.heading_deg * DEG)
    st0 = np.array([lat0, lon0, h0, *ini.velocity_m_s, *q0], float)
    P0 = initial_covariance(cfg, 15, lat0, h0, np.array(ini.attitude_sigma_deg) * DEG)
    q_psd = process_noise(cfg, 15)
    if gnss is None or len(gnss) == 0:
        g_t, g_lat, g_lon, g_h, g_vel, g_spos, g_svel = _empty_gnss()
    else:
        g_t, g_lat, g_lon, g_h, g_vel, g_spos, g_svel = gnss_arrays(gnss, cfg)
    g_use = np.ones(len(g_t), np.bool_)
    if sapv is None or len(sapv) == 0:
        s_t, s_az, s_el = np.zeros(0), np.zeros(0), np.zeros(0)
        s_skip = np.zeros(0, "<U20")
        s_use = np.zeros(0, np.bool_)
        s_sig = np.ones(2)
        sat = np.array([1.0, 0.0, 0.0])
    else:
        s_t, s_az, s_el = sapv.time, sapv.az, sapv.el
        s_skip = _sapv_input_check(sapv)
        s_use = np.ascontiguousarray(s_skip == "")
        s_sig = np.ascontiguousarray(sapv.sigma, dtype=float)
        sat = np.ascontiguousarray(sapv.sat_ecef, dtype=float)
    par = np.zeros(N_PAR)
    par[P_PROP_DT] = cfg.filter.prop_dt_s
    par[P_TAU_G] = cfg.imu.gyro_bias_tau_s
    par[P_TAU_A] = cfg.imu.accel_bias_tau_s
    gp = fed.gate_probability
    par[P_GATE_POS] = chdtri(3, 1.0 - gp) if gp < 1 else 0.0
    par[P_GATE_VEL] = par[P_GATE_POS]
    par[P_GATE_SAPV] = chdtri(2, 1.0 - gp) if gp < 1 else 0.0
    use_g = fed.use_gps and len(g_t) > 0
    par[P_USE_POS] = use_g and cfg.gnss.use in ("both", "position")
    par[P_USE_VEL] = use_g and cfg.gnss.use in ("both", "velocity")
    par[P_USE_SAPV] = fed.use_sapv and len(s_t) > 0
    par[P_SAPV_POS] = fed.sapv_position_columns
    par[P_LEVER:P_LEVER + 3] = cfg.gnss.lever_arm_m
    beta = np.array([fed.beta_gps, fed.beta_sapv, fed.beta_master], float)
    def arr(a):
        return np.ascontiguousarray(a, dtype=float)

    r = _federated_kernel(arr(imu.time), imu.dtheta, imu.dv, float(imu.t0), st0, P0, q_psd, par,
                          MODES[fed.mode], beta, g_t, g_lat, g_lon, g_h, g_vel, g_spos, g_svel, g_use,
                          arr(s_t), arr(s_az), arr(s_el), s_sig, s_use, sat, keep_cov)
    (node_k, out_st, out_bias, out_pd, out_loc, out_cov, rpos, rvel, rpn, rvn, rs, rsi, rss, rsn) = r
    rph = quat_to_euler_batch(np.ascontiguousarray(out_st[:, 6:10]))
    skipped = dict.fromkeys(SAPV_SKIP_REASONS, 0)
    if par[P_USE_SAPV] > 0:
        rs[(s_skip == "nan") | (s_skip == "angle_out_of_range")] = SAPV_BAD_INPUT
        for k in ("not_tracking", "nan", "angle_out_of_range"):
            skipped[k] = int(np.count_nonzero(s_skip == k))
        skipped["below_horizon"] = int(np.count_nonzero(rs == SAPV_BELOW_HORIZON))
    counts = {"sapv_used": int(np.count_nonzero(rs == 1)), "sapv_gated": int(np.count_nonzero(rs == 0)),
              "sapv_skipped": skipped}
    return FederatedResult(time=imu.time[node_k], state=out_st, rph=rph, bias=out_bias, pdiag=out_pd,
                           cov=out_cov if keep_cov else None, local_att_std=out_loc, gps_pos_status=rpos,
                           gps_vel_status=rvel, gps_pos_nis=rpn, gps_vel_nis=rvn, sapv_status=rs,
                           sapv_innov=rsi, sapv_s=rss, sapv_nis=rsn, config=fed, counts=counts)


def _sapv_input_check(sapv) -> np.ndarray:
    """(S,) str: why each SAPV epoch cannot be used (a key of :data:`SAPV_SKIP_REASONS`), "" if it can.

    The angles follow :func:`aidnav.nav.geo_pointing.az_el_from_body`: az ∈ [0, 2π), el ∈ [−π/2, π/2]
    [rad]; anything else is a unit or convention error in the data (e.g. degrees), not a measurement.
    """
    from aidnav.models.sapv import OK

    az, el = np.asarray(sapv.az, float), np.asarray(sapv.el, float)
    out = np.full(len(az), "", "<U20")
    finite = np.isfinite(az) & np.isfinite(el)
    with np.errstate(invalid="ignore"):
        bad_range = finite & ((az < 0.0) | (az >= 2.0 * np.pi) | (np.abs(el) > 0.5 * np.pi))
    tracking = np.asarray(sapv.reason) == OK
    out[tracking & bad_range] = "angle_out_of_range"
    out[tracking & ~finite] = "nan"
    out[~tracking] = "not_tracking"
    return out


def run_centralized(imu, gnss, sapv, cfg, *, use_gps: bool = True, use_sapv: bool = True,
                    sapv_position_columns: bool = False, gate_probability: float = 1.0,
                    keep_cov: bool = False) -> FederatedResult:
    """One 15-state filter with GPS and SAPV measurements (the reference of the federated filter).

    Same arguments and result as :func:`run_federated`; ``use_sapv=False`` is the seed's SINS/GPS.
    """
    fed = FederatedConfig(mode="centralized", use_gps=use_gps, use_sapv=use_sapv,
                          sapv_position_columns=sapv_position_columns, gate_probability=gate_probability)
    return run_federated(imu, gnss, sapv, cfg, fed, keep_cov=keep_cov)
