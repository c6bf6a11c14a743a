"""Loosely coupled GNSS/INS: closed-loop error-state Kalman filter and RTS smoother.

Frames and units: n = ENU, b = RFU (IMU), position (lat, lon [rad], h [m]), velocity ENU [m/s],
attitude q_b^n; times keep the input's scale (GPS seconds of week for GNSS-timed logs).

Structure: one numba kernel runs the whole forward pass (strapdown at the IMU rate; covariance
propagated at *nodes*: every ``prop_dt`` seconds and at every GNSS epoch; updates at nodes), using the
core of :mod:`aidnav.filters.kalman`, the model of :mod:`aidnav.filters.ins_errors` and the
measurement functions of :mod:`aidnav.filters.measurements`. The smoother is a backward RTS pass
over the nodes (memory O(nodes·n²), not O(IMU samples·n²)), whose corrections are interpolated
between nodes and applied to the forward trajectory.

Closed-loop feedback after each update (φ̂, δv̂, δp̂, bias residuals ε̂, ∇̂, scale-factor residuals):
C_b^n ← (I + [φ̂×]) C_b^n (as q ← q(φ̂) ⊗ q), v ← v − δv̂, p ← p − δp̂, b̂ ← b̂ + ε̂; the error
state is then zero.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from aidnav.nav.earth import OMEGA_IE, radii
from aidnav.nav.rotations import dcm_from_quat, quat_from_rotvec, quat_mult, quat_normalize

from .ins_errors import (
    increment_buffers,
    interval_model,
    measurement_arrays,
    model_arrays,
    new_accumulator,
    noise_count,
    propagate_sample,
    reset_accumulator,
    set_heading,
)
from .kalman import discretize, rts_gain, update
from .layout import BA, BG, DP, DV, NAV, PHI, SA, SG, ST_POS, ST_Q, ST_VEL
from .measurements import gnss_position, gnss_velocity, nonholonomic, zero_velocity

# indices into the float parameter vector of the kernel
P_LEVER = 0  # 3: IMU -> antenna lever arm, body [m]
P_TAU = 3  # 4: tau gyro bias, accel bias, gyro SF, accel SF [s]
P_GATE_POS = 7
P_GATE_VEL = 8
P_USE_POS = 9
P_USE_VEL = 10
P_PROP_DT = 11
P_NHC_SIG = 12  # <= 0: off
P_NHC_MIN_SPEED = 13
P_NHC_LEVER = 14  # 3
P_CBV = 17  # 9: IMU body -> vehicle rotation, row-major
P_ZUPT_SIG = 26  # <= 0: off
P_MAX_REJECT = 27
P_POS_STD_SCALE = 28
P_VEL_STD_SCALE = 29
P_ZARU_SIG = 30  # zero angular rate update sigma [rad/s], <= 0 off
P_GATE_VEL1 = 31  # chi-square gate of a velocity fix with 1 measured component
P_GATE_VEL2 = 32  # ... with 2 measured components (e.g. no vertical velocity)
N_PARAMS = 33


@njit(cache=True)
def _apply_correction(st, bias, dx, nstate):
    """Closed-loop feedback of an error estimate dx into the strapdown state and the sensor errors."""
    q = quat_mult(quat_from_rotvec(dx[PHI:PHI + 3]), st[ST_Q:ST_Q + 4])
    st[ST_Q:ST_Q + 4] = quat_normalize(q)
    for i in range(3):
        st[ST_VEL + i] -= dx[DV + i]
        st[ST_POS + i] -= dx[DP + i]
    for i in range(nstate - NAV):
        bias[i] += dx[NAV + i]


@njit(cache=True)
def _loose_kernel(imu_t, dth, dvel, t0, st0, bias0, P0, q_psd, par,
                  g_t, g_lat, g_lon, g_h, g_vel, g_spos, g_svel, g_use,
                  static, gap_var, reset_idx, reset_heading, reset_sigma, reset_nav, out_every, smooth,
                  cov_idx):
    n_imu = imu_t.shape[0]
    n = P0.shape[0]
    m = noise_count(n)
    nb = n - 9
    M = g_t.shape[0]
    st = st0.copy()
    bias = bias0.copy()  # [bg(3), ba(3), sg(3), sa(3)] as far as the state has them
    P = P0.copy()
    x = np.zeros(n)
    F, G, Phi, Qd = model_arrays(n, m)
    H3, z3, R3, innov, sdiag = measurement_arrays(3, n)  # GNSS position / velocity, ZUPT, ZARU
    H2, z2, R2, innov2, sdiag2 = measurement_arrays(2, n)  # non-holonomic constraint
    lever = par[P_LEVER:P_LEVER + 3].copy()
    nhc_lever = par[P_NHC_LEVER:P_NHC_LEVER + 3].copy()
    Cbv = par[P_CBV:P_CBV + 9].copy().reshape(3, 3)
    prop_dt = par[P_PROP_DT]
    # outputs
    n_out = (n_imu + out_every - 1) // out_every
    out_idx = np.empty(n_out, np.int64)
    out_st = np.empty((n_out, 10))
    out_bias = np.empty((n_out, max(nb, 1)))
    out_pdiag = np.empty((n_out, n))
    out_node = np.empty(n_out, np.int64)  # index of the last node at or before the sample
    # nodes
    max_nodes = M + int((imu_t[-1] - t0) / prop_dt) + 3 + n_imu // max(1, int(prop_dt * 1000.0))
    if max_nodes > n_imu + 1:
        max_nodes = n_imu + 1
    node_idx = np.empty(max_nodes, np.int64)
    ns = max_nodes if smooth else 1
    S_post = np.zeros((ns, n, n))
    S_prior = np.zeros((ns, n, n))
    S_phi = np.zeros((ns, n, n))
    S_dx = np.zeros((ns, n))
    # records
    rec_pos = np.full(M, -1, np.int8)
    rec_vel = np.full(M, -1, np.int8)
    rec_pos_innov = np.full((M, 3), np.nan)
    rec_pos_s = np.full((M, 3), np.nan)
    rec_vel_innov = np.full((M, 3), np.nan)
    rec_vel_s = np.full((M, 3), np.nan)
    rec_pos_nis = np.full(M, np.nan)
    rec_vel_nis = np.full(M, np.nan)
    # full covariance at the requested samples (cov_idx: sorted sample indices)
    cov_out = np.zeros((cov_idx.shape[0], n, n))
    ci = 0
    n_nhc = 0
    n_zupt = 0
    n_nhc_rej = 0
    reset_node = -1
    # state of the loop
    gi = 0
    while gi < M and g_t[gi] <= t0:
        gi += 1
    acc = new_accumulator()  # sums over the samples since the last node (ins_errors.ACC_*)
    gap_phi = 0.0
    gap_v = 0.0
    dthc, dvc, dth_prev, dv_prev = increment_buffers()  # corrected increments: this / previous sample
    tp = t0
    kn = 0
    oi = 0
    n_rej_pos = 0
    n_rej_vel = 0
    last_w = np.zeros(3)
    for k in range(n_imu):
        dt = imu_t[k] - tp
        tp = imu_t[k]
        T = propagate_sample(st, acc, dth[k], dvel[k], bias, dt, dthc, dvc, dth_prev, dv_prev)
        # bridged IMU gaps: attitude / velocity variance of the unknown motion, added at the next node
        gap_phi += gap_var[k, 0]
        gap_v += gap_var[k, 1]
        if k == reset_idx:
            reset_node = kn  # the next node is the first one after the re-initialisation
            # heading (re)initialisation: keep roll and pitch, set heading, reset its covariance
            set_heading(st, P, reset_heading, reset_sigma)
            dvr = np.sqrt((st[3] - reset_nav[0]) ** 2 + (st[4] - reset_nav[1]) ** 2)
            sv = np.sqrt(P[DV, DV] + P[DV + 1, DV + 1] + reset_nav[6] ** 2)
            if not np.isnan(reset_nav[0]) and dvr > 3.0 * sv:
                # the velocity and position integrated with the unknown heading are re-initialised
                # from the GNSS fix that gave the course (antenna → IMU with the new attitude)
                l_n = dcm_from_quat(st[ST_Q:ST_Q + 4]) @ lever
                rm, rn = radii(reset_nav[3])
                st[0] = reset_nav[3] - l_n[1] / (rm + reset_nav[5])
                st[1] = reset_nav[4] - l_n[0] / ((rn + reset_nav[5]) * np.cos(reset_nav[3]))
                st[2] = reset_nav[5] - l_n[2]
                st[3], st[4], st[5] = reset_nav[0], reset_nav[1], reset_nav[2]
                for i in range(DV, DP + 3):
                    for j in range(n):
                        P[i, j] = 0.0
                        P[j, i] = 0.0
                for i in range(3):
                    P[DV + i, DV + i] = reset_nav[6 + i] ** 2
                P[DP, DP] = (reset_nav[10] / (rm + reset_nav[5])) ** 2
                P[DP + 1, DP + 1] = (reset_nav[9] / ((rn + reset_nav[5]) * np.cos(reset_nav[3]))) ** 2
                P[DP + 2, DP + 2] = reset_nav[11] ** 2
        is_node = T >= prop_dt - 1e-9 or (gi < M and g_t[gi] <= imu_t[k]) or k == n_imu - 1
        if is_node and T > 0.0:
            C = dcm_from_quat(st[ST_Q:ST_Q + 4])
            wb = interval_model(F, G, st, acc, par[P_TAU], par[P_TAU + 1], par[P_TAU + 2], par[P_TAU + 3])
            last_w[:] = wb
            discretize(F, G, q_psd, T, Phi, Qd)
            P[:, :] = Phi @ P @ Phi.T + Qd
            if gap_phi > 0.0:
                for i in range(3):
                    P[PHI + i, PHI + i] += gap_phi
                    P[DV + i, DV + i] += gap_v
                gap_phi = 0.0
                gap_v = 0.0
            P[:, :] = 0.5 * (P + P.T)
            if smooth:
                S_phi[kn] = Phi
                S_prior[kn] = P
            x[:] = 0.0
            # ---- GNSS updates for fixes in (t_{k-1}, t_k]
            while gi < M and g_t[gi] <= imu_t[k]:
                if g_use[gi]:
                    dt_back = imu_t[k] - g_t[gi]
                    if par[P_USE_POS] > 0:
                        gnss_position(st, C, lever, g_lat[gi], g_lon[gi], g_h[gi], dt_back, H3, z3)
                        R3[:, :] = 0.0
                        for i in range(3):
                            R3[i, i] = (g_spos[gi, i] * par[P_POS_STD_SCALE]) ** 2
                        gate = par[P_GATE_POS]
                        if n_rej_pos >= par[P_MAX_REJECT]:
                            gate = 0.0
                        ok, nis = update(x, P, H3, R3, z3, gate, innov, sdiag)
                        rec_pos[gi] = 1 if ok else 0
                        rec_pos_nis[gi] = nis
                        rec_pos_innov[gi] = innov
                        rec_pos_s[gi] = sdiag
                        n_rej_pos = 0 if ok else n_rej_pos + 1
                    nvm = 0  # measured velocity components (NaN: not measured)
                    for i in range(3):
                        if not np.isnan(g_vel[gi, i]):
                            nvm += 1
                    if par[P_USE_VEL] > 0 and nvm > 0:
                        sl = np.sin(st[0])
                        cl = np.cos(st[0])
                        rm, rn = radii(st[0])
                        w_in = np.array([-st[4] / (rm + st[2]), OMEGA_IE * cl + st[3] / (rn + st[2]),
                                         OMEGA_IE * sl + st[3] * sl / cl / (rn + st[2])])
                        # lever-arm rate: the body rate at the fix (last increment), not the mean
                        # rate since the previous node (up to prop_dt ago: lags in turn transitions)
                        w_fix = dthc / dt
                        gnss_velocity(st, C, lever, w_fix, w_in, g_vel[gi], H3, z3)
                        # only the measured components enter the update
                        Hm = np.zeros((nvm, n))
                        zm = np.zeros(nvm)
                        Rm = np.zeros((nvm, nvm))
                        innov_m = np.zeros(nvm)
                        sdiag_m = np.zeros(nvm)
                        r = 0
                        for i in range(3):
                            if not np.isnan(g_vel[gi, i]):
                                Hm[r, :] = H3[i, :]
                                zm[r] = z3[i]
                                Rm[r, r] = (g_svel[gi, i] * par[P_VEL_STD_SCALE]) ** 2
                                r += 1
                        gate = par[P_GATE_VEL] if nvm == 3 else (par[P_GATE_VEL2] if nvm == 2
                                                                  else par[P_GATE_VEL1])
                        if n_rej_vel >= par[P_MAX_REJECT]:
                            gate = 0.0
                        ok, nis = update(x, P, Hm, Rm, zm, gate, innov_m, sdiag_m)
                        n_rej_vel = 0 if ok else n_rej_vel + 1
                        rec_vel[gi] = 1 if ok else 0
                        rec_vel_nis[gi] = nis
                        r = 0
                        for i in range(3):
                            if not np.isnan(g_vel[gi, i]):
                                rec_vel_innov[gi, i] = innov_m[r]
                                rec_vel_s[gi, i] = sdiag_m[r]
                                r += 1
                gi += 1
            # ---- vehicle constraints
            if static[k] and par[P_ZUPT_SIG] > 0:
                zero_velocity(st, H3, z3)
                R3[:, :] = 0.0
                for i in range(3):
                    R3[i, i] = par[P_ZUPT_SIG] ** 2
                update(x, P, H3, R3, z3, 0.0, innov, sdiag)
                n_zupt += 1
                if par[P_ZARU_SIG] > 0:
                    # zero angular rate: measured rate minus Earth rate in body = gyro bias residual
                    wie_b = C.T @ np.array([0.0, OMEGA_IE * np.cos(st[0]), OMEGA_IE * np.sin(st[0])])
                    for i in range(3):
                        H3[i, :] = 0.0
                        H3[i, BG + i] = 1.0
                        z3[i] = wb[i] - wie_b[i]
                        R3[i, i] = par[P_ZARU_SIG] ** 2
                    update(x, P, H3, R3, z3, 0.0, innov, sdiag)
            elif par[P_NHC_SIG] > 0:
                sp = np.sqrt(st[3] ** 2 + st[4] ** 2)
                if sp > par[P_NHC_MIN_SPEED]:
                    w_nb = wb - C.T @ np.array([0.0, OMEGA_IE * np.cos(st[0]), OMEGA_IE * np.sin(st[0])])
                    nonholonomic(st, C, Cbv, w_nb, nhc_lever, H2, z2)
                    R2[0, 0] = par[P_NHC_SIG] ** 2
                    R2[1, 1] = par[P_NHC_SIG] ** 2
                    ok, nis = update(x, P, H2, R2, z2, 0.0 if par[P_GATE_VEL] <= 0 else 25.0, innov2, sdiag2)
                    if ok:
                        n_nhc += 1
                    else:
                        n_nhc_rej += 1
            _apply_correction(st, bias, x, n)
            node_idx[kn] = k
            if smooth:
                S_post[kn] = P
                S_dx[kn] = x
            kn += 1
            reset_accumulator(acc)
        if k % out_every == 0:
            out_idx[oi] = k
            out_st[oi] = st
            for i in range(nb):
                out_bias[oi, i] = bias[i]
            for i in range(n):
                out_pdiag[oi, i] = P[i, i]
            out_node[oi] = kn - 1
            oi += 1
        while ci < cov_idx.shape[0] and cov_idx[ci] == k:
            cov_out[ci] = P
            ci += 1
    counts = np.array([n_zupt, n_nhc, n_nhc_rej, kn, reset_node])
    return (out_idx[:oi], out_st[:oi], out_bias[:oi], out_pdiag[:oi], out_node[:oi],
            node_idx[:kn], S_post[:kn], S_prior[:kn], S_phi[:kn], S_dx[:kn],
            rec_pos, rec_vel, rec_pos_innov, rec_pos_s, rec_vel_innov, rec_vel_s,
            rec_pos_nis, rec_vel_nis, counts, st, bias, P, cov_out)


@njit(cache=True)
def _rts_kernel(S_post, S_prior, S_phi, S_dx, brk):
    """Backward RTS pass over nodes of a closed-loop filter.

    Returns ds (K, n): smoothed error of the post-update nominal at each node, and Ps (K, n, n).
    Recursion: ds_k = A_k (ds_{k+1} + dx_{k+1}),  Ps_k = P⁺_k + A_k (Ps_{k+1} − P⁻_{k+1}) A_kᵀ.
    ``brk``: index of the first node after a state re-initialisation (heading alignment), or −1;
    no information is passed backwards across it (the states before it are not linearly related).
    """
    K = S_post.shape[0]
    n = S_post.shape[1]
    ds = np.zeros((K, n))
    Ps = np.empty((K, n, n))
    Ps[K - 1] = S_post[K - 1]
    for k in range(K - 2, -1, -1):
        if k + 1 == brk:
            ds[k] = 0.0
            Ps[k] = S_post[k]
            continue
        A = rts_gain(S_post[k], S_phi[k + 1], S_prior[k + 1])
        ds[k] = A @ (ds[k + 1] + S_dx[k + 1])
        Pk = S_post[k] + A @ (Ps[k + 1] - S_prior[k + 1]) @ A.T
        Ps[k] = 0.5 * (Pk + Pk.T)
    return ds, Ps


@njit(cache=True)
def _smooth_outputs(out_idx, out_st, out_bias, out_node, node_idx, ds, S_dx, nstate):
    """Apply the smoothed corrections to the forward outputs (linear in time between nodes)."""
    n_out = out_idx.shape[0]
    K = node_idx.shape[0]
    st = np.empty(10)
    dx = np.empty(nstate)
    b = np.empty(max(nstate - 9, 1))
    res_st = out_st.copy()
    res_b = out_bias.copy()
    for o in range(n_out):
        j = out_node[o]
        k = out_idx[o]
        if j < 0:
            dx[:] = ds[0] + S_dx[0]
        elif j >= K - 1:
            dx[:] = ds[K - 1]
        else:
            k0 = node_idx[j]
            k1 = node_idx[j + 1]
            a = (k - k0) / (k1 - k0) if k1 > k0 else 0.0
            dx[:] = (1.0 - a) * ds[j] + a * (ds[j + 1] + S_dx[j + 1])
            if k == k0:
                dx[:] = ds[j]
        st[:] = out_st[o]
        for i in range(nstate - 9):
            b[i] = out_bias[o, i]
        _apply_correction(st, b, dx, nstate)
        res_st[o] = st
        for i in range(nstate - 9):
            res_b[o, i] = b[i]
    return res_st, res_b


@dataclass
class LooseResult:
    """Output of :func:`run_loose` (arrays in aidnav conventions; see module doc)."""

    time: np.ndarray  # (N,) output times [s]
    state: np.ndarray  # (N, 10) lat, lon, h, vE, vN, vU, q
    bias: np.ndarray  # (N, nb) gyro bias [rad/s], accel bias [m/s²], (gyro SF, accel SF [-])
    pdiag: np.ndarray  # (N, n) covariance diagonal (forward, or smoothed when smoothed)
    node_time: np.ndarray
    records: dict = field(default_factory=dict)
    counts: dict = field(default_factory=dict)
    smoothed: bool = False
    final_P: np.ndarray | None = None
    forward_state: np.ndarray | None = None
    forward_pdiag: np.ndarray | None = None
    cov_time: np.ndarray | None = None  # (K,) sample times of ``cov`` (only with ``cov_times``)
    cov: np.ndarray | None = None  # (K, n, n) forward covariance at ``cov_time``


# ----------------------------------------------------------------------------------- driver
def static_flags(imu, gnss, cfg, window_s: float = 1.0) -> np.ndarray:
    """Per-IMU-sample static detection: low gyro and accel spread over ``window_s`` and, where GNSS
    velocity exists, GNSS speed below ``cfg.constraints.static_gnss_speed_m_s``."""
    c = cfg.constraints
    dt = np.diff(np.concatenate([[imu.t0], imu.time]))
    dt[dt <= 0] = np.nan
    w = imu.dtheta / dt[:, None]
    f = imu.dv / dt[:, None]
    n = max(2, int(round(window_s * imu.rate_hz)))

    def rolling_std(a):
        a = np.nan_to_num(a)
        cs = np.cumsum(np.vstack([np.zeros((1, a.shape[1])), a]), axis=0)
        cs2 = np.cumsum(np.vstack([np.zeros((1, a.shape[1])), a * a]), axis=0)
        idx = np.arange(1, len(a) + 1)
        lo = np.maximum(idx - n, 0)
        cnt = (idx - lo)[:, None]
        mean = (cs[idx] - cs[lo]) / cnt
        var = (cs2[idx] - cs2[lo]) / cnt - mean**2
        return np.sqrt(np.maximum(var, 0.0)).max(axis=1)

    ok = (rolling_std(w) < c.static_gyro_std_deg_s * np.pi / 180) & (rolling_std(f) < c.static_accel_std_m_s2)
    if gnss is not None and gnss.vel is not None and len(gnss) > 0:
        sp = np.hypot(gnss.vel[:, 0], gnss.vel[:, 1])
        j = np.clip(np.searchsorted(gnss.time, imu.time), 0, len(gnss) - 1)
        jp = np.clip(j - 1, 0, len(gnss) - 1)
        near = (np.abs(gnss.time[j] - imu.time) < 1.0) | (np.abs(gnss.time[jp] - imu.time) < 1.0)
        ok &= near & (np.maximum(sp[j], sp[jp]) < c.static_gnss_speed_m_s)
    else:
        ok &= False
    return ok


def process_noise(cfg, nstate: int) -> np.ndarray:
    """Continuous process-noise PSD vector q (SI units) from the configuration."""
    from .config import DEG, DEG_H, UG

    im = cfg.imu
    arw = im.arw_deg_sqrt_h * DEG / 60.0
    vrw = im.vrw_m_s_sqrt_h / 60.0

    def bias_q(sigma, tau, rw):
        return 2.0 * sigma**2 / tau if tau > 0 else rw**2

    sg = im.gyro_bias_instability_deg_h
    sg = im.gyro_bias_sigma_deg_h if sg is None else sg
    sa = im.accel_bias_sigma_ug if im.accel_bias_instability_ug is None else im.accel_bias_instability_ug
    qg = bias_q(sg * DEG_H, im.gyro_bias_tau_s, im.gyro_bias_rw_deg_h_sqrt_h * DEG_H / 60)
    qa = bias_q(sa * UG, im.accel_bias_tau_s, im.accel_bias_rw_ug_sqrt_h * UG / 60)
    q = [arw**2] * 3 + [vrw**2] * 3 + [qg] * 3 + [qa] * 3
    if nstate == 21:
        qs = 2.0 * (1e-6) ** 2 / im.sf_tau_s if im.sf_tau_s > 0 else 0.0
        q += [qs * im.gyro_sf_sigma_ppm**2] * 3 + [qs * im.accel_sf_sigma_ppm**2] * 3
    return np.array(q, dtype=float)


def initial_covariance(cfg, nstate: int, lat: float, h: float, att_sigma_rad) -> np.ndarray:
    """Diagonal P0 from the configuration (position σ converted from metres to δL, δλ, δh)."""
    from .config import DEG_H, UG

    rm, rn = radii(lat)
    ps = cfg.init.position_sigma_m
    d = np.zeros(nstate)
    d[PHI:PHI + 3] = np.asarray(att_sigma_rad) ** 2
    d[DV:DV + 3] = np.asarray(cfg.init.velocity_sigma_m_s) ** 2
    d[DP] = (ps[1] / (rm + h)) ** 2
    d[DP + 1] = (ps[0] / ((rn + h) * np.cos(lat))) ** 2
    d[DP + 2] = ps[2] ** 2
    d[BG:BG + 3] = (cfg.imu.gyro_bias_sigma_deg_h * DEG_H) ** 2
    d[BA:BA + 3] = (cfg.imu.accel_bias_sigma_ug * UG) ** 2
    if nstate >= 21:
        d[SG:SG + 3] = (cfg.imu.gyro_sf_sigma_ppm * 1e-6) ** 2
        d[SA:SA + 3] = (cfg.imu.accel_sf_sigma_ppm * 1e-6) ** 2
    return np.diag(d)


def bridge_gaps(imu, events: list, factor: float = 5.0, window_s: float = 1.0):
    """Increments ready for the kernel, with IMU time gaps (interval > ``factor`` × median) bridged.

    A sample after a gap either already spans the gap (e.g. rates × Δt from a reader: |Δv|/Δt ≈ g)
    or only covers one nominal interval (a sensor that dropped samples: |Δv|/Δt_nominal ≈ g). In the
    second case the gap is bridged by holding the mean rates of the ``window_s`` before it (holding one
    sample's rates would scale its white noise by the gap length instead of its square root).
    Either way the motion during the gap is unknown: the returned ``gap_var`` (N, 2) holds, for the
    sample after each gap, the variance added to each attitude axis [rad²] and each velocity axis
    [(m/s)²] by holding the rates: (σ_ω T)² and (σ_f T)² with σ the spread of the rates in the window
    before the gap (floors 0.1 deg/s and 0.05 m/s²). Each gap and the decision go into ``events``.
    Returns (dtheta, dv, gap_var); the arrays are copies only when something was changed.
    """
    dt = np.diff(np.concatenate([[imu.t0], imu.time]))
    med = float(np.median(dt))
    gaps = np.flatnonzero(dt > factor * med)
    gap_var = np.zeros((len(imu), 2))
    if len(gaps) == 0:
        return imu.dtheta, imu.dv, gap_var
    dth, dv = imu.dtheta.copy(), imu.dv.copy()
    nwin = max(2, int(round(window_s / med)))
    for k in gaps:
        T = dt[k]
        lo = max(0, k - nwin)
        if k - lo >= 2:
            w = imu.dtheta[lo:k] / dt[lo:k, None]
            f = imu.dv[lo:k] / dt[lo:k, None]
            w_mean, f_mean = w.mean(axis=0), f.mean(axis=0)
            s_w = max(float(np.sqrt(np.mean(np.var(w, axis=0)))), np.radians(0.1))
            s_f = max(float(np.sqrt(np.mean(np.var(f, axis=0)))), 0.05)
        else:
            w_mean, f_mean = imu.dtheta[k] / med, imu.dv[k] / med
            s_w, s_f = np.radians(1.0), 0.5
        f_span = np.linalg.norm(dv[k]) / T
        f_nom = np.linalg.norm(dv[k]) / med
        if abs(f_span - 9.8) < abs(f_nom - 9.8):
            how = "its increments already span the gap"
        else:
            dth[k] = w_mean * T
            dv[k] = f_mean * T
            how = f"bridged with the mean rates of the {nwin * med:.2f} s before it"
        gap_var[k] = [(s_w * T) ** 2, (s_f * T) ** 2]
        events.append(f"IMU gap of {T:.3f} s before t={imu.time[k]:.3f} ({T / med:.0f} nominal intervals); "
                      f"{how}; attitude/velocity variance inflated by ({np.degrees(s_w * T):.2f} deg)^2, "
                      f"({s_f * T:.2f} m/s)^2 for the unknown motion")
    return dth, dv, gap_var


def gnss_arrays(gnss, cfg):
    """GNSS fixes as kernel arrays with σ floors and quality factors applied (heights as read)."""
    g = cfg.gnss
    m = len(gnss)
    spos = (np.tile(g.default_pos_std_m, (m, 1)) if gnss.std_pos is None else gnss.std_pos.copy())
    svel = (np.tile(g.default_vel_std_m_s, (m, 1)) if gnss.std_vel is None else gnss.std_vel.copy())
    if gnss.quality is not None:
        fac = np.where(gnss.quality == 2, g.float_std_factor,
                       np.where(gnss.quality >= 4, g.single_std_factor, 1.0))
        spos *= fac[:, None]
        svel *= fac[:, None]
    spos = np.maximum(spos, g.min_pos_std_m)
    svel = np.maximum(svel, g.min_vel_std_m_s)
    vel = gnss.vel if gnss.vel is not None else np.full((m, 3), np.nan)
    # heights arrive ellipsoidal: the datum offset is applied once, by the reader (aidnav.io)
    return (gnss.time, gnss.lat, gnss.lon, gnss.height,
            np.ascontiguousarray(vel), np.ascontiguousarray(spos), np.ascontiguousarray(svel))


def course_alignment(gnss, cfg, t_start: float):
    """First GNSS epoch after ``t_start`` with horizontal speed above the threshold.

    Returns (time, course [rad], index of the fix) or None.
    """
    if gnss.vel is None:
        ve = np.gradient(gnss.lon, gnss.time) * 6378137.0 * np.cos(gnss.lat)
        vn = np.gradient(gnss.lat, gnss.time) * 6378137.0
    else:
        ve, vn = gnss.vel[:, 0], gnss.vel[:, 1]
    sp = np.hypot(ve, vn)
    idx = np.flatnonzero((sp > cfg.init.course_min_speed_m_s) & (gnss.time > t_start))
    if len(idx) == 0:
        return None
    i = idx[0]
    return float(gnss.time[i]), float(np.arctan2(ve[i], vn[i]) % (2 * np.pi)), int(i)


def run_loose(imu, gnss, cfg=None, withheld=None, smooth: bool = False, events: list | None = None,
              cov_times=None):
    """Loosely coupled GNSS/INS over whole logs.

    Parameters
    ----------
    imu : :class:`aidnav.data.ImuData` (increments, body RFU, time on the GNSS scale after any
        configured offset). gnss : :class:`aidnav.data.GnssData` (antenna fixes).
    cfg : :class:`aidnav.filters.config.LooseConfig` (defaults: consumer MEMS).
    withheld : optional bool mask over the GNSS fixes that must not be used (simulated outages).
    smooth : run the RTS smoother as well (the result then holds the smoothed solution; the forward
        solution stays in ``forward_state``/``forward_pdiag``).
    events : list to which notable events are appended (initialisation, heading alignment, ...).
    cov_times : optional times [s] (input time scale) at which to keep the full forward covariance
        P (n×n, error state of :mod:`aidnav.filters.ins_errors`): for each, the first IMU sample at or
        after it; P is the one the filter holds there after that sample's updates (covariance is
        propagated at nodes only, so ask for node times, e.g. GNSS epochs). Returned in
        ``LooseResult.cov_time`` / ``LooseResult.cov``; times outside the processed span are dropped.
    """
    from aidnav.data import ImuData
    from aidnav.nav.rotations import quat_from_euler

    from .config import DEG, LooseConfig

    cfg = cfg or LooseConfig()
    events = events if events is not None else []
    nstate = cfg.nstate
    nb = nstate - 9
    t_imu = imu.time + cfg.imu.time_offset_s
    g_t, g_lat, g_lon, g_h, g_vel, g_spos, g_svel = gnss_arrays(gnss, cfg)
    use = np.ones(len(gnss), dtype=np.bool_) if withheld is None else ~np.asarray(withheld, bool)
    finite = np.isfinite(g_lat) & np.isfinite(g_lon) & np.isfinite(g_h) & np.all(np.isfinite(g_spos), axis=1)
    if not finite.all():
        bad_t = g_t[~finite]
        events.append(f"{int((~finite).sum())} GNSS fixes with NaN/inf position or sigma not used "
                      f"(first at t={bad_t[0]:.3f})")
        use &= finite
    ini = cfg.init
    # ---- initial state
    if ini.mode == "given":
        missing = [k for k in ("lat_deg", "lon_deg", "height_m", "roll_deg", "pitch_deg", "heading_deg")
                   if getattr(ini, k) is None]
        if missing:
            raise ValueError(f"init.mode = given needs init.{', init.'.join(missing)}")
        t0 = float(imu.t0 + cfg.imu.time_offset_s)
        lat0, lon0, h0 = ini.lat_deg * DEG, ini.lon_deg * DEG, ini.height_m
        v0 = np.array(ini.velocity_m_s, float)
        rph = np.array([ini.roll_deg, ini.pitch_deg, ini.heading_deg]) * DEG
        att_sig = np.array(ini.attitude_sigma_deg) * DEG
        reset_idx, reset_heading = -1, 0.0
        reset_nav = np.full(12, np.nan)
        k0 = 0
    else:
        # start at the first GNSS fix inside the IMU span
        first = np.flatnonzero(use & (g_t >= t_imu[0]))
        if len(first) == 0:
            raise ValueError("no GNSS fix inside the IMU time span: cannot initialise")
        i0 = first[0]
        k0 = int(np.searchsorted(t_imu, g_t[i0], side="right"))
        if k0 > 0:
            events.append(f"initialisation at the first GNSS fix t={g_t[i0]:.3f}: {k0} IMU samples before it "
                          "are not used")
        t0 = float(g_t[i0]) if k0 == 0 else float(t_imu[k0 - 1])
        lat0, lon0, h0 = g_lat[i0], g_lon[i0], g_h[i0]
        v0 = np.nan_to_num(g_vel[i0]) if not np.isnan(g_vel[i0, 0]) else np.zeros(3)
        # static coarse alignment (aidnav.nav.alignment): roll/pitch from the mean specific force over
        # the static window; heading by gyrocompassing where the gyro grade resolves the Earth rate
        from aidnav.nav.alignment import coarse_align_static

        t_a = t_imu[k0]
        win_imu = ImuData(t_imu, imu.dtheta, imu.dv, t0=imu.t0 + cfg.imu.time_offset_s)
        gb = cfg.imu.gyro_bias_sigma_deg_h * DEG / 3600.0
        roll, pitch, gc_heading, ainfo = coarse_align_static(win_imu, lat0, t_a, t_a + ini.static_window_s,
                                                             height=h0, gyro_bias_std=gb)
        heading = 0.0
        att_sig = np.array(ini.attitude_sigma_deg) * DEG
        gw = use & (g_t >= t_a) & (g_t < t_a + ini.static_window_s)
        moving = bool(np.any(np.hypot(g_vel[gw, 0], g_vel[gw, 1]) > cfg.constraints.static_gnss_speed_m_s))
        if moving or abs(ainfo["f_norm"] - ainfo["gravity"]) > 0.02 * ainfo["gravity"]:
            # not static: in-motion start, level from zero with a wide sigma (the filter converges)
            events.append(f"in-motion start (GNSS speed above {cfg.constraints.static_gnss_speed_m_s} m/s or "
                          f"mean specific force {ainfo['f_norm']:.3f} m/s^2 not gravity "
                          f"{ainfo['gravity']:.3f}): roll and pitch start at 0 with sigma 10 deg")
            roll, pitch, gc_heading = 0.0, 0.0, None
            att_sig[0:2] = np.maximum(att_sig[0:2], 10.0 * DEG)
        if ini.heading_deg is not None:
            heading = ini.heading_deg * DEG
        elif gc_heading is not None:
            heading = gc_heading
        if ini.roll_deg is not None:
            roll = ini.roll_deg * DEG
        if ini.pitch_deg is not None:
            pitch = ini.pitch_deg * DEG
        rph = np.array([roll, pitch, heading])
        f = ainfo["mean_f"] / 9.80665
        events.append(f"coarse alignment over {ini.static_window_s:g} s: roll {np.degrees(roll):.2f} deg, "
                      f"pitch {np.degrees(pitch):.2f} deg (mean specific force {np.round(f, 4)} g)")
        if ini.heading_deg is None and gc_heading is not None:
            events.append(f"heading by gyrocompassing: {np.degrees(gc_heading):.2f} deg "
                          f"(sigma {np.degrees(ainfo['heading_std']):.2f} deg)")
            att_sig[2] = max(att_sig[2], ainfo["heading_std"])
        elif ini.heading_deg is None:
            events.append(f"no gyrocompass heading ({ainfo['heading_reason']}): heading from GNSS course")
        reset_idx, reset_heading = -1, 0.0
        reset_nav = np.full(12, np.nan)
        if ini.heading_deg is None and gc_heading is None:
            ca = course_alignment(gnss.subset(use), cfg, t0)
            if ca is None:
                events.append("heading never aligned: no GNSS speed above init.course_min_speed_m_s")
            else:
                tca, course, ica = ca
                ica = np.flatnonzero(use)[ica]
                # a component the receiver did not measure (NaN) resets to 0 with σ 1 m/s
                meas = ~np.isnan(g_vel[ica])
                vel_g = np.where(meas, np.nan_to_num(g_vel[ica]), 0.0)
                svel = np.where(meas, g_svel[ica], 1.0)
                reset_nav = np.array([*vel_g, g_lat[ica], g_lon[ica], g_h[ica], *svel, *g_spos[ica]])
                mount_h = cfg.imu.mounting_rph_deg[2] * DEG
                # vehicle heading = course; IMU heading = vehicle heading + mounting heading
                reset_heading = (course + mount_h) % (2 * np.pi)
                reset_idx = int(np.searchsorted(t_imu[k0:], tca, side="left"))
                events.append(f"heading from GNSS course at t={tca:.3f}: {np.degrees(reset_heading):.2f} deg")
            att_sig[2] = np.pi  # unknown until the course alignment
    dth_in, dv_in, gap_var = bridge_gaps(imu, events)
    q0 = quat_from_euler(rph[0], rph[1], rph[2])
    st0 = np.array([lat0, lon0, h0, v0[0], v0[1], v0[2], *q0], float)
    P0 = initial_covariance(cfg, nstate, lat0, h0, att_sig)
    q_psd = process_noise(cfg, nstate)
    par = np.zeros(N_PARAMS)
    par[P_LEVER:P_LEVER + 3] = cfg.gnss.lever_arm_m
    taus = [cfg.imu.gyro_bias_tau_s, cfg.imu.accel_bias_tau_s, cfg.imu.sf_tau_s, cfg.imu.sf_tau_s]
    par[P_TAU:P_TAU + 4] = taus
    from scipy.special import chdtri  # chi-square quantile (scipy.stats costs 1 s of start-up)

    gp = cfg.gnss.gate_probability
    par[P_GATE_POS] = chdtri(3, 1.0 - gp) if gp < 1 else 0.0
    par[P_GATE_VEL] = par[P_GATE_POS]
    par[P_GATE_VEL1] = chdtri(1, 1.0 - gp) if gp < 1 else 0.0
    par[P_GATE_VEL2] = chdtri(2, 1.0 - gp) if gp < 1 else 0.0
    par[P_USE_POS] = cfg.gnss.use in ("both", "position")
    par[P_USE_VEL] = cfg.gnss.use in ("both", "velocity")
    par[P_PROP_DT] = cfg.filter.prop_dt_s
    c = cfg.constraints
    par[P_NHC_SIG] = c.nhc_sigma_m_s if c.nhc else 0.0
    par[P_NHC_MIN_SPEED] = c.nhc_min_speed_m_s
    par[P_NHC_LEVER:P_NHC_LEVER + 3] = c.nhc_lever_arm_m
    from aidnav.nav.rotations import dcm_from_euler

    mr = np.array(cfg.imu.mounting_rph_deg) * DEG
    par[P_CBV:P_CBV + 9] = dcm_from_euler(mr[0], mr[1], mr[2]).ravel()
    par[P_ZUPT_SIG] = c.zupt_sigma_m_s if c.zupt else 0.0
    par[P_MAX_REJECT] = cfg.gnss.max_consecutive_rejections
    par[P_POS_STD_SCALE] = cfg.gnss.pos_std_scale
    par[P_VEL_STD_SCALE] = cfg.gnss.vel_std_scale
    par[P_ZARU_SIG] = c.zaru_sigma_deg_s * DEG
    static = static_flags(imu, gnss, cfg) if c.zupt else np.zeros(len(imu), np.bool_)
    out_every = 1
    if cfg.filter.output_rate_hz:
        out_every = max(1, int(round(imu.rate_hz / cfg.filter.output_rate_hz)))
    bias0 = np.zeros(nb)
    cov_idx = np.zeros(0, np.int64)
    if cov_times is not None:
        ct = np.sort(np.atleast_1d(np.asarray(cov_times, float)))
        # first sample at or after each time (1 µs tolerance for times computed as k·dt)
        cov_idx = np.searchsorted(t_imu[k0:], ct - 1e-6, side="left").astype(np.int64)
        cov_idx = cov_idx[cov_idx < len(t_imu) - k0]
    r = _loose_kernel(t_imu[k0:], dth_in[k0:], dv_in[k0:], t0, st0, bias0, P0, q_psd, par,
                      g_t, g_lat, g_lon, g_h, g_vel, g_spos, g_svel, use,
                      static[k0:], gap_var[k0:], reset_idx, reset_heading,
                      ini.course_heading_sigma_deg * DEG, reset_nav, out_every, smooth, cov_idx)
    (out_idx, out_st, out_bias, out_pdiag, out_node, node_idx, S_post, S_prior, S_phi, S_dx,
     rec_pos, rec_vel, rpi, rps, rvi, rvs, rpn, rvn, counts, st_end, bias_end, P_end, cov_out) = r
    records = dict(pos_status=rec_pos, vel_status=rec_vel, pos_innov=rpi, pos_s=rps, vel_innov=rvi,
                   vel_s=rvs, pos_nis=rpn, vel_nis=rvn)
    cnt = dict(zupt_updates=int(counts[0]), nhc_updates=int(counts[1]), nhc_rejected=int(counts[2]),
               nodes=int(counts[3]), static_samples=int(static[k0:].sum()), imu_samples_used=len(imu) - k0,
               imu_samples_skipped=k0)
    res = LooseResult(time=t_imu[k0:][out_idx], state=out_st, bias=out_bias, pdiag=out_pdiag,
                      node_time=t_imu[k0:][node_idx], records=records, counts=cnt, final_P=P_end)
    if cov_times is not None:
        res.cov_time, res.cov = t_imu[k0:][cov_idx], cov_out
    if smooth and len(node_idx) > 1:
        ds, Ps = _rts_kernel(S_post, S_prior, S_phi, S_dx, int(counts[4]))
        sm_st, sm_b = _smooth_outputs(out_idx, out_st, out_bias, out_node, node_idx, ds, S_dx, nstate)
        res.forward_state, res.forward_pdiag = out_st, out_pdiag
        res.state, res.bias = sm_st, sm_b
        pd = np.einsum("kii->ki", Ps)
        res.pdiag = pd[np.clip(out_node, 0, len(node_idx) - 1)]
        res.smoothed = True
        res.counts["smoother_memory_mb"] = (S_post.nbytes + S_prior.nbytes + S_phi.nbytes + Ps.nbytes) / 1e6
    return res


def to_trajectory(res: LooseResult):
    """LooseResult → :class:`aidnav.data.Trajectory` with σ columns and bias columns."""
    from aidnav.data import Trajectory
    from aidnav.nav.rotations import quat_to_euler_batch

    s = res.state
    lat, h = s[:, 0], s[:, 2]
    rm, rn = radii(lat)
    pd = np.sqrt(np.maximum(res.pdiag, 0.0))
    std_pos = np.column_stack([pd[:, 7] * (rn + h) * np.cos(lat), pd[:, 6] * (rm + h), pd[:, 8]])
    rph = quat_to_euler_batch(np.ascontiguousarray(s[:, 6:10]))
    hd = rph[:, 2]
    # φ (E, N, U) → roll/pitch/heading σ (diagonal approximation about the current heading)
    sr = np.sqrt((np.cos(hd) * pd[:, 1]) ** 2 + (np.sin(hd) * pd[:, 0]) ** 2)
    sp = np.sqrt((np.sin(hd) * pd[:, 1]) ** 2 + (np.cos(hd) * pd[:, 0]) ** 2)
    std_att = np.column_stack([sr, sp, pd[:, 2]])
    extra = {}
    names = ["gyro_bias_{}_deg_h", "accel_bias_{}_ug", "gyro_sf_{}_ppm", "accel_sf_{}_ppm"]
    scale = [180 / np.pi * 3600, 1 / 9.80665e-6, 1e6, 1e6]
    for j in range(res.bias.shape[1] // 3):
        for i, ax in enumerate("xyz"):
            extra[names[j].format(ax)] = res.bias[:, 3 * j + i] * scale[j]
    return Trajectory(time=res.time, lat=lat, lon=s[:, 1], height=h, vel=s[:, 3:6], rph=rph,
                      std_pos=std_pos, std_vel=pd[:, 3:6], std_att=std_att, extra=extra)
