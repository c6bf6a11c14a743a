"""Tightly coupled GNSS/INS: closed-loop error-state EKF with pseudorange and pseudorange-rate updates.

Frames and units: n = ENU, b = RFU (IMU), e = ECEF; strapdown state (lat, lon [rad], h [m], v^n [m/s],
q_b^n) as in :mod:`aidnav.filters.loose`; receiver clock bias b [m] and drift d [m/s]; GNSS times are
receiver tags on the GPS reference-week scale, IMU times on the same GPS scale.

**States** (SPEC 2.1, seed eq. 8): the navigation block of :mod:`aidnav.filters.ins_errors`
(φ, δv, δL δλ δh; errors = computed − true), then

* ``states=11`` (the seed's model): [φ(3), δv(3), δp(3), δt_u, δf],
* ``states=17``: [φ, δv, δp, ε (gyro bias, b), ∇ (accel bias, b), δt_u, δf],

where δt_u = b − b̂ [m] and δf = d − d̂ [m/s] (true − estimated, so that ρ_GPS = ρ_true + b: SPEC 2.1).
Clock dynamics: δṫ_u = δf + w_b, δḟ = −δf/τ_f + w_d (τ_f ≤ 0: random walk), with white-noise PSDs
S_b = c²h₀/2 and S_d = c²·2π²h₋₂ from the receiver oscillator's Allan coefficients.

**Measurements** (per satellite, sequential scalar updates with the one Kalman core,
:func:`aidnav.filters.kalman.update_scalar`, each gated by the χ²(1) quantile of ``gate_probability``):

* z_ρ = (P + c·dt_s − I − T) − (|r_s − r_a| + Sagnac + b̂), H = [e^T [l^n×], 0, a_j, (0), 1, 0] with
  a_j = [(R_M+h) e_N, (R_N+h) cos L e_E, e_U] (SPEC 2.1; the φ column is the lever-arm term);
* z_ρ̇ = (ρ̇_meas + c·ḋt_s) − (e·(v_s − v_a) + Sagnac rate + d̂), H = [e^T [(C(ω×l))×], e^T, 0, ...,
  −e^T C[l×] (gyro bias), 0, 1];

with e = [e_E, e_N, e_U] the ENU unit vector antenna → satellite, r_a / v_a the INS antenna position /
velocity (the H blocks of the antenna position and velocity are those of
:func:`aidnav.filters.measurements.gnss_position` / :func:`~aidnav.filters.measurements.gnss_velocity`).
The signals were received at GPS time t_tag − b̂/c; the INS antenna is moved back along its velocity
to that time. Satellite positions/clocks come from the broadcast ephemerides at the transmit time
implied by each pseudorange (:func:`aidnav.estimators.dgps.satellites_from_pseudoranges`), computed
before the kernel; ionosphere (Klobuchar or dual-frequency) and troposphere (Saastamoinen) are
evaluated at the INS position inside it. Any number of satellites is used (1, 2, 3 … : each is one
scalar row); with fewer than four the clock and position are only partly observable, and the filter
says so through its covariance.

**Clock start and jumps**: at the first epoch b̂, d̂ are the medians of the pseudorange and rate
residuals about the INS (any number of satellites); an epoch whose median pseudorange residual exceeds
``clock_jump_m`` (a receiver's millisecond clock jump) re-initialises b̂ and its variance (counted).

Closed-loop feedback after each node's updates: the navigation and bias part by
:func:`aidnav.filters.loose._apply_correction`, then b̂ ← b̂ + δt̂_u, d̂ ← d̂ + δf̂.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numba import njit
from pydantic import BaseModel, ConfigDict, Field

from aidnav.nav.earth import OMEGA_IE, dcm_ecef_to_enu, lla_to_ecef, radii
from aidnav.nav.gnss_sat import (
    C_LIGHT,
    az_el,
    dual_frequency_iono,
    geo_range,
    geo_range_rate,
    klobuchar,
    tropo_delay,
)
from aidnav.nav.rotations import dcm_from_quat

from .config import Constraints, FilterSettings, ImuNoise, Initialisation
from .ins_errors import (
    increment_buffers,
    interval_model,
    measurement_arrays,
    model_arrays,
    new_accumulator,
    propagate_sample,
    reset_accumulator,
    set_heading,
)
from .kalman import discretize, update, update_scalar
from .loose import _apply_correction
from .measurements import gnss_position, gnss_velocity, zero_velocity

__all__ = [
    "RawGnssAiding",
    "TightConfig",
    "TightResult",
    "run_tight",
    "tight_nav_covariance_m",
    "to_trajectory",
]

# float parameters of the kernel
T_LEVER = 0  # 3
T_TAU_G, T_TAU_A, T_TAU_F = 3, 4, 5
T_GATE_PR, T_GATE_RATE = 6, 7
T_USE_RATE, T_PROP_DT = 8, 9
T_SIG_CODE, T_SIG_RATE, T_MASK = 10, 11, 12
T_USE_IONO, T_USE_TROPO, T_HUMID = 13, 14, 15
T_ZUPT_SIG, T_CLOCK_JUMP, T_NNAV = 16, 17, 18
T_CLK_SIG_B, T_CLK_SIG_D = 19, 20
T_MAX_REJECT = 21
T_CODE_MIN = 22
N_TPAR = 23
N_NOISE = 14  # 12 INS noise inputs of ins_errors (15-state) + clock bias + clock drift


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class RawGnssAiding(_Strict):
    """How raw pseudoranges and rates are used (units in the names)."""

    lever_arm_m: tuple[float, float, float] = Field((0.0, 0.0, 0.0), description="IMU→antenna, body RFU [m]")
    code_sigma_m: float = Field(1.0, gt=0, description="zenith pseudorange σ; σ(E) = σ0 √(½+½/sin²E)")
    rate_sigma_m_s: float = Field(0.1, gt=0, description="zenith pseudorange-rate σ [m/s]")
    mask_deg: float = Field(10.0, description="elevation mask [deg]")
    use_rate: bool = True
    code_min_sats: int = Field(
        1,
        ge=1,
        description="use pseudoranges only at epochs with at least this many "
        "satellites (above the mask); 99 = rate (Doppler) updates only",
    )
    gate_probability: float = Field(0.9999, gt=0, le=1, description="per-satellite χ²(1) gate; 1 disables")
    max_consecutive_rejections: int = Field(20, ge=1, description="then the next epoch is not gated")
    iono: Literal["klobuchar", "none", "dual"] = "klobuchar"
    iono_window_s: float = Field(60.0, gt=0, description="smoothing window of the dual-frequency delay [s]")
    tropo: bool = True
    humidity: float = Field(0.7, ge=0, le=1)
    clock_h0: float = Field(2e-19, ge=0, description="white-frequency Allan coefficient h0 [s]")
    clock_hm2: float = Field(2e-20, ge=0, description="random-walk-frequency Allan coefficient h-2 [1/s]")
    clock_tau_s: float = Field(
        0.0, description="drift correlation time τ_f [s] (seed: Markov); <= 0 random walk"
    )
    clock_bias_sigma_m: float = Field(30.0, gt=0, description="σ of the initial clock bias [m]")
    clock_drift_sigma_m_s: float = Field(1.0, gt=0, description="σ of the initial clock drift [m/s]")
    clock_jump_m: float = Field(1.0e4, gt=0, description="median residual that re-initialises the clock [m]")
    max_eph_age_s: float = Field(7200.0, gt=0, description="|t − toe| limit of an ephemeris [s]")


class TightConfig(_Strict):
    """Configuration of :func:`run_tight` (the loosely coupled filter's sections plus ``gnss``)."""

    states: Literal[11, 17] = 17
    imu: ImuNoise = ImuNoise()
    gnss: RawGnssAiding = RawGnssAiding()
    init: Initialisation = Initialisation()
    constraints: Constraints = Constraints()
    filter: FilterSettings = FilterSettings()


@njit(cache=True)
def _build_model(F, G, F15, G15, nnav, tau_f):
    n = F.shape[0]
    F[:, :] = 0.0
    G[:, :] = 0.0
    F[:nnav, :nnav] = F15[:nnav, :nnav]
    G[:nnav, :12] = G15[:nnav, :12]
    ib = n - 2
    F[ib, ib + 1] = 1.0
    if tau_f > 0:
        F[ib + 1, ib + 1] = -1.0 / tau_f
    G[ib, 12] = 1.0
    G[ib + 1, 13] = 1.0


@njit(cache=True)
def _tight_kernel(
    imu_t,
    dth,
    dvel,
    t0,
    st0,
    bias0,
    clk0,
    P0,
    q_psd,
    par,
    g_t,
    sat_pos,
    sat_vel,
    sat_clk,
    sat_clk_rate,
    pr,
    rate,
    ion_ab,
    ion_dual,
    static,
    reset_idx,
    reset_heading,
    reset_sigma,
    out_every,
):
    n_imu = imu_t.shape[0]
    n = P0.shape[0]
    nnav = int(par[T_NNAV])
    nb = nnav - 9
    M = g_t.shape[0]
    S = pr.shape[1]
    st = st0.copy()
    bias = bias0.copy()
    clk = clk0.copy()
    P = P0.copy()
    x = np.zeros(n)
    F15, G15, _, _ = model_arrays(15, 12)  # INS block (ins_errors), then the clock states appended
    F, G, Phi, Qd = model_arrays(n, N_NOISE)
    H3, z3, R3, innov3, sdiag3 = measurement_arrays(3, n)  # ZUPT
    H3p = np.zeros((3, 15))  # antenna position / velocity blocks of the loosely coupled measurements
    H3v = np.zeros((3, 15))
    h = np.zeros(n)
    lever = par[T_LEVER : T_LEVER + 3].copy()
    alpha = ion_ab[:4].copy()
    beta = ion_ab[4:].copy()
    ib = n - 2
    n_out = (n_imu + out_every - 1) // out_every
    out_idx = np.empty(n_out, np.int64)
    out_st = np.empty((n_out, 10))
    out_bias = np.zeros((n_out, max(nb, 1)))
    out_clk = np.empty((n_out, 2))
    out_pdiag = np.empty((n_out, n))
    # per-epoch records
    rec_time = np.full(M, np.nan)
    rec_navail = np.zeros(M, np.int64)
    rec_npr = np.zeros(M, np.int64)
    rec_nrate = np.zeros(M, np.int64)
    rec_nrej = np.zeros(M, np.int64)
    rec_pr_innov = np.full((M, S), np.nan)
    rec_pr_s = np.full((M, S), np.nan)
    rec_rate_innov = np.full((M, S), np.nan)
    rec_rate_s = np.full((M, S), np.nan)
    rec_el = np.full((M, S), np.nan)
    rec_Pnav = np.zeros((M, 9, 9))
    rec_clk = np.full((M, 2), np.nan)
    rec_state = np.zeros((M, 10))
    n_jumps = 0
    n_zupt = 0
    clock_init = False
    n_rej_run = 0
    gi = 0
    while gi < M and g_t[gi] - clk[0] / C_LIGHT <= t0:
        gi += 1
    acc = new_accumulator()  # sums over the samples since the last node (ins_errors.ACC_*)
    dthc, dvc, dth_prev, dv_prev = increment_buffers()  # corrected increments: this / previous sample
    tp = t0
    oi = 0
    for k in range(n_imu):
        dt = imu_t[k] - tp
        tp = imu_t[k]
        T = propagate_sample(st, acc, dth[k], dvel[k], bias, dt, dthc, dvc, dth_prev, dv_prev)
        clk[0] += clk[1] * dt  # receiver clock bias [m] follows its drift [m/s]
        if k == reset_idx:
            set_heading(st, P, reset_heading, reset_sigma)  # heading from the GNSS course
        t_meas = g_t[gi] - clk[0] / C_LIGHT if gi < M else np.inf
        is_node = T >= par[T_PROP_DT] - 1e-9 or t_meas <= imu_t[k] or k == n_imu - 1
        if is_node and T > 0.0:
            C = dcm_from_quat(st[6:10])
            wb = interval_model(F15, G15, st, acc, par[T_TAU_G], par[T_TAU_A], 0.0, 0.0)
            _build_model(F, G, F15, G15, nnav, par[T_TAU_F])
            discretize(F, G, q_psd, T, Phi, Qd)
            P[:, :] = Phi @ P @ Phi.T + Qd
            P[:, :] = 0.5 * (P + P.T)
            x[:] = 0.0
            gi_first = gi
            while gi < M and g_t[gi] - clk[0] / C_LIGHT <= imu_t[k]:
                dt_back = imu_t[k] - (g_t[gi] - clk[0] / C_LIGHT)
                lat, lon, hh = st[0], st[1], st[2]
                Cen = dcm_ecef_to_enu(lat, lon)
                l_n = C @ lever
                rm, rn = radii(lat)
                sl, cl = np.sin(lat), np.cos(lat)
                w_in = np.array(
                    [
                        -st[4] / (rm + hh),
                        OMEGA_IE * cl + st[3] / (rn + hh),
                        OMEGA_IE * sl + st[3] * sl / cl / (rn + hh),
                    ]
                )
                # antenna position / velocity blocks (15 columns) from the loosely coupled measurements
                gnss_position(st, C, lever, lat, lon, hh, 0.0, H3p, z3)
                gnss_velocity(st, C, lever, wb, w_in, st[3:6], H3v, z3)
                v_ant_n = st[3:6] + z3  # z3 = v_ant − v_given with v_given = v
                pe = np.zeros(3)
                pe[0], pe[1], pe[2] = lla_to_ecef(lat, lon, hh)
                ra = pe + Cen.T @ (l_n - v_ant_n * dt_back)
                va = Cen.T @ v_ant_n
                t_gps = g_t[gi] - clk[0] / C_LIGHT
                rec_time[gi] = t_gps
                # clock initialisation / jump detection from the median residual
                res = np.full(S, np.nan)
                res_r = np.full(S, np.nan)
                for j in range(S):
                    if not (np.isfinite(pr[gi, j]) and np.isfinite(sat_pos[gi, j, 0])):
                        continue
                    rho, e = geo_range(sat_pos[gi, j], ra)
                    res[j] = pr[gi, j] + sat_clk[gi, j] - rho
                    if np.isfinite(rate[gi, j]):
                        res_r[j] = (
                            rate[gi, j]
                            + sat_clk_rate[gi, j]
                            - geo_range_rate(sat_pos[gi, j], sat_vel[gi, j], ra, va, e)
                        )
                okr = np.isfinite(res)
                if okr.sum() > 0:
                    med = np.median(res[okr])
                    if not clock_init or abs(med - clk[0]) > par[T_CLOCK_JUMP]:
                        if clock_init:
                            n_jumps += 1
                        clk[0] = med
                        for j in range(n):
                            P[ib, j] = 0.0
                            P[j, ib] = 0.0
                        P[ib, ib] = par[T_CLK_SIG_B] ** 2
                        okd = np.isfinite(res_r)
                        if not clock_init and okd.sum() > 0:
                            clk[1] = np.median(res_r[okd])
                            for j in range(n):
                                P[ib + 1, j] = 0.0
                                P[j, ib + 1] = 0.0
                            P[ib + 1, ib + 1] = par[T_CLK_SIG_D] ** 2
                        clock_init = True
                gate_pr = par[T_GATE_PR] if n_rej_run < par[T_MAX_REJECT] else 0.0
                gate_rate = par[T_GATE_RATE] if n_rej_run < par[T_MAX_REJECT] else 0.0
                n_rej_epoch = 0
                n_vis = 0
                for j in range(S):
                    if np.isfinite(pr[gi, j]) and np.isfinite(sat_pos[gi, j, 0]):
                        _, e = geo_range(sat_pos[gi, j], ra)
                        _, el, _ = az_el(e, lat, lon)
                        if el >= par[T_MASK]:
                            n_vis += 1
                use_code = n_vis >= par[T_CODE_MIN]
                for j in range(S):
                    if not (np.isfinite(pr[gi, j]) and np.isfinite(sat_pos[gi, j, 0])):
                        continue
                    rho, e = geo_range(sat_pos[gi, j], ra)
                    en = Cen @ e
                    az, el, _ = az_el(e, lat, lon)
                    rec_el[gi, j] = el
                    if el < par[T_MASK]:
                        continue
                    rec_navail[gi] += 1
                    corr = 0.0
                    if par[T_USE_IONO] > 0:
                        corr += klobuchar(lat, lon, az, el, t_gps, alpha, beta)
                    if par[T_USE_TROPO] > 0:
                        corr += tropo_delay(lat, hh, el, par[T_HUMID])
                    if np.isfinite(ion_dual[gi, j]):
                        corr += ion_dual[gi, j]
                    s_el = np.sin(max(el, 0.035))
                    mfac = 0.5 + 0.5 / (s_el * s_el)
                    z = pr[gi, j] + sat_clk[gi, j] - corr - (rho + clk[0])
                    h[:] = 0.0
                    for c in range(nnav):
                        h[c] = en[0] * H3p[0, c] + en[1] * H3p[1, c] + en[2] * H3p[2, c]
                    h[ib] = 1.0
                    if use_code:
                        ok, nu, s = update_scalar(x, P, h, par[T_SIG_CODE] ** 2 * mfac, z, gate_pr)
                        rec_pr_innov[gi, j] = nu
                        rec_pr_s[gi, j] = s
                        if ok:
                            rec_npr[gi] += 1
                        else:
                            n_rej_epoch += 1
                    if par[T_USE_RATE] > 0 and np.isfinite(rate[gi, j]):
                        rr = geo_range_rate(sat_pos[gi, j], sat_vel[gi, j], ra, va, e)
                        zr = rate[gi, j] + sat_clk_rate[gi, j] - (rr + clk[1])
                        h[:] = 0.0
                        for c in range(nnav):
                            h[c] = en[0] * H3v[0, c] + en[1] * H3v[1, c] + en[2] * H3v[2, c]
                        h[ib + 1] = 1.0
                        ok, nu, s = update_scalar(x, P, h, par[T_SIG_RATE] ** 2 * mfac, zr, gate_rate)
                        rec_rate_innov[gi, j] = nu
                        rec_rate_s[gi, j] = s
                        if ok:
                            rec_nrate[gi] += 1
                        else:
                            n_rej_epoch += 1
                rec_nrej[gi] = n_rej_epoch
                if n_rej_epoch > 0 and rec_npr[gi] == 0:
                    n_rej_run += 1
                else:
                    n_rej_run = 0
                gi += 1
            if static[k] and par[T_ZUPT_SIG] > 0:
                zero_velocity(st, H3p, z3)
                H3[:, :] = 0.0
                H3[:, :nnav] = H3p[:, :nnav]
                R3[:, :] = 0.0
                for i in range(3):
                    R3[i, i] = par[T_ZUPT_SIG] ** 2
                update(x, P, H3, R3, z3, 0.0, innov3, sdiag3)
                n_zupt += 1
            _apply_correction(st, bias, x, nnav)
            clk[0] += x[ib]
            clk[1] += x[ib + 1]
            # records of the epochs just processed
            for g in range(gi_first, gi):
                rec_clk[g, 0] = clk[0]
                rec_clk[g, 1] = clk[1]
                rec_Pnav[g] = P[:9, :9]
                rec_state[g] = st
            reset_accumulator(acc)
        if k % out_every == 0:
            out_idx[oi] = k
            out_st[oi] = st
            for i in range(nb):
                out_bias[oi, i] = bias[i]
            out_clk[oi] = clk
            for i in range(n):
                out_pdiag[oi, i] = P[i, i]
            oi += 1
    counts = np.array([n_zupt, n_jumps])
    return (
        out_idx[:oi],
        out_st[:oi],
        out_bias[:oi],
        out_clk[:oi],
        out_pdiag[:oi],
        rec_time,
        rec_navail,
        rec_npr,
        rec_nrate,
        rec_nrej,
        rec_pr_innov,
        rec_pr_s,
        rec_rate_innov,
        rec_rate_s,
        rec_el,
        rec_Pnav,
        rec_clk,
        rec_state,
        counts,
        P,
    )


@dataclass
class TightResult:
    """Output of :func:`run_tight`.

    time (N,) [s, GPS on the input scale]; state (N, 10) lat, lon, h, vE, vN, vU, q; bias (N, nb) gyro
    [rad/s] and accel [m/s²] bias estimates (17 states); clock (N, 2) b̂ [m], d̂ [m/s]; pdiag (N, n)
    covariance diagonal; epochs : dict of per-GNSS-epoch arrays (time = GPS receive time, n_avail, n_pr,
    n_rate, n_rejected, pr_innov/pr_s/rate_innov/rate_s (M, S), elevation (M, S), P_nav (M, 9, 9) and
    state (M, 10) after the epoch's update, clock (M, 2)); counts; events.
    """

    time: np.ndarray
    state: np.ndarray
    bias: np.ndarray
    clock: np.ndarray
    pdiag: np.ndarray
    epochs: dict = field(default_factory=dict)
    counts: dict = field(default_factory=dict)
    events: list = field(default_factory=list)
    nstate: int = 17
    final_P: np.ndarray | None = None


def _noise_vector(cfg: TightConfig) -> np.ndarray:
    from .config import LooseConfig
    from .loose import process_noise

    lc = LooseConfig(imu=cfg.imu)
    q = np.zeros(N_NOISE)
    q[:12] = process_noise(lc, 15)
    g = cfg.gnss
    q[12] = C_LIGHT**2 * g.clock_h0 / 2.0
    q[13] = C_LIGHT**2 * 2.0 * np.pi**2 * g.clock_hm2
    return q


def _initial_P(cfg: TightConfig, lat, h, att_sig) -> np.ndarray:
    from .config import LooseConfig
    from .loose import initial_covariance

    n = cfg.states
    P15 = initial_covariance(LooseConfig(imu=cfg.imu, init=cfg.init), 15, lat, h, att_sig)
    P = np.zeros((n, n))
    nn = 9 if n == 11 else 15
    P[:nn, :nn] = P15[:nn, :nn]
    P[n - 2, n - 2] = cfg.gnss.clock_bias_sigma_m**2
    P[n - 1, n - 1] = cfg.gnss.clock_drift_sigma_m_s**2
    return P


def _satellite_arrays(obs, eph, use_tgd, max_age):
    from aidnav.nav.gnss_sat import satellite_states as _satellites

    M, S = obs.code1.shape
    sp = np.full((M, S, 3), np.nan)
    sv = np.full((M, S, 3), np.nan)
    sc = np.full((M, S), np.nan)
    scr = np.full((M, S), np.nan)
    prn = np.asarray(obs.prn, np.int64)
    for k in range(M):
        sp[k], sv[k], sc[k], scr[k] = _satellites(
            eph.table, prn, float(obs.time[k]), obs.code1[k], use_tgd, float(max_age)
        )
    return sp, sv, sc, scr


def run_tight(
    imu,
    obs,
    eph,
    cfg: TightConfig | None = None,
    init_state=None,
    static=None,
    heading_reset=None,
    events: list | None = None,
    output_rate_hz: float | None = None,
) -> TightResult:
    """Tightly coupled GNSS/INS over whole logs.

    imu : :class:`aidnav.data.ImuData` (increments, body RFU; time on the GNSS scale: GPS seconds on the
    observations' reference-week scale). obs : :class:`aidnav.nav.gnss_types.GnssObservations` (receiver
    tags, L1 code, Doppler; L2 code for ``iono="dual"``). eph : broadcast ephemerides (put on the
    observations' week). cfg : :class:`TightConfig`.
    init_state : (t0 [s], lat, lon [rad], h [m], v^n (3,), (roll, pitch, heading) [rad]) to start from;
    default: ``cfg.init`` in "given" mode (degrees) at the IMU's first time.
    static : optional (N,) bool per IMU sample for ZUPTs (``cfg.constraints.zupt``).
    heading_reset : optional (t [s], heading [rad]) to set the heading at (e.g. a GNSS course).
    """
    from scipy.special import chdtri

    from aidnav.nav.rotations import quat_from_euler

    from .config import DEG

    cfg = cfg or TightConfig()
    events = events if events is not None else []
    if eph.ref_week != obs.ref_week:
        eph = eph.to_week(obs.ref_week)
    n = cfg.states
    nnav = 9 if n == 11 else 15
    g = cfg.gnss
    t_imu = imu.time + cfg.imu.time_offset_s
    if init_state is None:
        ini = cfg.init
        missing = [
            k
            for k in ("lat_deg", "lon_deg", "height_m", "roll_deg", "pitch_deg", "heading_deg")
            if getattr(ini, k) is None
        ]
        if missing:
            raise ValueError("run_tight needs init_state or init.mode = given with " + ", ".join(missing))
        init_state = (
            float(imu.t0 + cfg.imu.time_offset_s),
            ini.lat_deg * DEG,
            ini.lon_deg * DEG,
            ini.height_m,
            np.array(ini.velocity_m_s, float),
            np.array([ini.roll_deg, ini.pitch_deg, ini.heading_deg]) * DEG,
        )
    t0, lat0, lon0, h0, v0, rph0 = init_state
    k0 = int(np.searchsorted(t_imu, t0, side="right"))
    q0 = quat_from_euler(rph0[0], rph0[1], rph0[2])
    st0 = np.array([lat0, lon0, h0, *np.asarray(v0, float), *q0], float)
    att_sig = np.array(cfg.init.attitude_sigma_deg) * DEG
    P0 = _initial_P(cfg, lat0, h0, att_sig)
    q = _noise_vector(cfg)
    par = np.zeros(N_TPAR)
    par[T_LEVER : T_LEVER + 3] = g.lever_arm_m
    par[T_TAU_G] = cfg.imu.gyro_bias_tau_s
    par[T_TAU_A] = cfg.imu.accel_bias_tau_s
    par[T_TAU_F] = g.clock_tau_s
    gate = chdtri(1, 1.0 - g.gate_probability) if g.gate_probability < 1 else 0.0
    par[T_GATE_PR] = par[T_GATE_RATE] = gate
    par[T_USE_RATE] = g.use_rate
    par[T_PROP_DT] = cfg.filter.prop_dt_s
    par[T_SIG_CODE] = g.code_sigma_m
    par[T_SIG_RATE] = g.rate_sigma_m_s
    par[T_MASK] = np.radians(g.mask_deg)
    use_iono = g.iono == "klobuchar" and eph.iono_alpha is not None
    if g.iono == "klobuchar" and eph.iono_alpha is None:
        events.append("no Klobuchar coefficients: no ionospheric correction")
    par[T_USE_IONO] = use_iono
    par[T_USE_TROPO] = g.tropo
    par[T_HUMID] = g.humidity
    c = cfg.constraints
    par[T_ZUPT_SIG] = c.zupt_sigma_m_s if (c.zupt and static is not None) else 0.0
    par[T_CLOCK_JUMP] = g.clock_jump_m
    par[T_NNAV] = nnav
    par[T_CLK_SIG_B] = g.clock_bias_sigma_m
    par[T_CLK_SIG_D] = g.clock_drift_sigma_m_s
    par[T_MAX_REJECT] = g.max_consecutive_rejections
    par[T_CODE_MIN] = g.code_min_sats
    ion_ab = np.zeros(8)
    if use_iono:
        ion_ab[:4], ion_ab[4:] = eph.iono_alpha, eph.iono_beta
    use_tgd = g.iono != "dual"
    if g.iono == "dual":
        if obs.code2 is None:
            raise ValueError("iono = dual needs an L2 code")
        ion_dual = dual_frequency_iono(obs.time, obs.code1, obs.code2, g.iono_window_s)
    else:
        ion_dual = np.full(obs.code1.shape, np.nan)
    sp, sv, sc, scr = _satellite_arrays(obs, eph, use_tgd, g.max_eph_age_s)
    no_eph = (np.isfinite(obs.code1) & ~np.isfinite(sp[:, :, 0])).sum(axis=0)
    for j in np.flatnonzero(no_eph):
        events.append(
            f"G{int(obs.prn[j]):02d}: {int(no_eph[j])} epoch(s) with a pseudorange but no usable ephemeris; "
            "skipped"
        )
    rate = obs.range_rate()
    stat = np.zeros(len(t_imu), np.bool_) if static is None else np.asarray(static, np.bool_)
    reset_idx, reset_heading = -1, 0.0
    if heading_reset is not None:
        reset_idx = int(np.searchsorted(t_imu[k0:], heading_reset[0], side="left"))
        reset_heading = float(heading_reset[1])
    from .loose import bridge_gaps

    bridged = bridge_gaps(imu, events)  # (dtheta, dv[, gap variances: not used here])
    dth_in, dv_in = bridged[0], bridged[1]
    out_every = 1
    rate_hz = output_rate_hz or cfg.filter.output_rate_hz
    if rate_hz:
        out_every = max(1, int(round(imu.rate_hz / rate_hz)))
    r = _tight_kernel(
        t_imu[k0:],
        dth_in[k0:],
        dv_in[k0:],
        float(t0),
        st0,
        np.zeros(max(nnav - 9, 1)),
        np.zeros(2),
        P0,
        q,
        par,
        obs.time,
        sp,
        sv,
        sc,
        scr,
        obs.code1,
        rate,
        ion_ab,
        ion_dual,
        stat[k0:],
        reset_idx,
        reset_heading,
        cfg.init.course_heading_sigma_deg * DEG,
        out_every,
    )
    (
        out_idx,
        out_st,
        out_bias,
        out_clk,
        out_pd,
        rt,
        rna,
        rnp,
        rnr,
        rnj,
        rpi,
        rps,
        rri,
        rrs,
        rel,
        rP,
        rclk,
        rst,
        counts,
        P_end,
    ) = r
    epochs = dict(
        time=rt,
        n_avail=rna,
        n_pr=rnp,
        n_rate=rnr,
        n_rejected=rnj,
        pr_innov=rpi,
        pr_s=rps,
        rate_innov=rri,
        rate_s=rrs,
        elevation=rel,
        P_nav=rP,
        clock=rclk,
        state=rst,
        prn=obs.prn,
    )
    if gate > 0:
        with np.errstate(invalid="ignore"):
            rej_pr = (rpi**2 > gate * rps).sum(axis=0)
            rej_rate = (rri**2 > gate * rrs).sum(axis=0)
        for j in np.flatnonzero(rej_pr + rej_rate):
            events.append(
                f"G{int(obs.prn[j]):02d}: {int(rej_pr[j])} pseudorange(s) and {int(rej_rate[j])} rate(s) "
                "outside the innovation gate (rejected unless the gate was suspended)"
            )
    cnt = dict(
        zupt_updates=int(counts[0]),
        clock_jumps=int(counts[1]),
        epochs=int(np.isfinite(rt).sum()),
        pr_used=int(rnp.sum()),
        rate_used=int(rnr.sum()),
        rejected=int(rnj.sum()),
        imu_samples_skipped=k0,
    )
    return TightResult(
        time=t_imu[k0:][out_idx],
        state=out_st,
        bias=out_bias[:, : nnav - 9],
        clock=out_clk,
        pdiag=out_pd,
        epochs=epochs,
        counts=cnt,
        events=events,
        nstate=n,
        final_P=P_end,
    )


def tight_nav_covariance_m(P_nav: np.ndarray, lat: float, h: float) -> np.ndarray:
    """9×9 nav covariance (φ, δv, δL δλ δh) → (φ, δv, δE δN δU in metres)."""
    rm, rn = radii(lat)
    T = np.eye(9)
    T[6:9, 6:9] = [[0, (rn + h) * np.cos(lat), 0], [rm + h, 0, 0], [0, 0, 1]]
    return T @ P_nav @ T.T


def to_trajectory(res: TightResult):
    """TightResult → :class:`aidnav.data.Trajectory` (σ columns, bias and clock columns); the navigation
    part is the loosely coupled filter's conversion (same state layout for the first 9 + 6 states)."""
    from .loose import LooseResult
    from .loose import to_trajectory as nav_trajectory

    bias = res.bias[:, :6] if res.bias.shape[1] >= 6 else res.bias[:, :0]
    traj = nav_trajectory(LooseResult(res.time, res.state, bias, res.pdiag, res.time))
    traj.extra.update({"clock_bias_m": res.clock[:, 0], "clock_drift_m_s": res.clock[:, 1]})
    return traj
