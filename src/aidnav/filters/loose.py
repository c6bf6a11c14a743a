"""Loosely coupled GNSS/INS on the filter engine (:mod:`aidnav.filters.engine`): closed-loop error-state
Kalman filter and RTS smoother.

Frames and units: n = ENU, b = RFU (IMU), position (lat, lon [rad], h [m]), velocity ENU [m/s],
attitude q_b^n; times keep the input's scale (GPS seconds of week for GNSS-timed logs).

This module is the loose filter's *layout and models*: the 15/21-state INS layout plus the optional
calibration states (odometer scale factor, barometer bias; :mod:`aidnav.filters.layout`), the records
it feeds (GNSS position and velocity with lever arm, odometer speed, barometric height) and the node
constraints (ZUPT, ZARU at static samples, NHC otherwise) of :mod:`aidnav.filters.measurements`, and
the gate settings. The engine does the node schedule, prediction, the gate policy, the innovation log,
the feedback and the smoother. Input preparation (static detection, IMU gaps, alignment) is in
:mod:`aidnav.filters.preprocess`.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from aidnav.nav.rotations import dcm_from_euler, quat_from_euler
from aidnav.units import DEG

from . import aids as aid_kinds
from . import measurements as ms
from .chi2 import chi2_isf
from .engine import (
    C_AMAX,
    C_MOUNT_H,
    NEVER,
    Imu,
    Init,
    Models,
    Output,
    Process,
    Records,
    feedback,
    run_filter,
)
from .engine_batch import batchable, run_batch, run_outputs, stack_inputs
from .grade import grade_from_static
from .layout import (
    DV,
    L_LEVER,
    L_MOUNT,
    L_N,
    L_NINS,
    L_TOFF,
    L_VDEL,
    NAV,
    RN_LEVER,
    layout_names,
    make_layout,
)
from .preprocess import (
    bridge_gaps,
    coarse_mounting,
    correlated_gnss_errors,
    course_alignment,
    gnss_arrays,
    gnss_velocity_for_init,
    imu_gaps,
    initial_state,
    noise_from_static,
    static_flags,
    visible_fixes,
)
from .prior import calibration_prior, initial_covariance, levelled_tilt_covariance, process_noise
from .result import FilterResult, LooseResult, to_trajectory
from .run_log import calibration_base, gnss_records, log_dict, loose_counts, reinit_events
from .smoother import rts, smooth_outputs

# names kept from before the engine (used by the other filters and the tests)
_apply_correction = feedback
_rts_kernel = rts
_smooth_outputs = smooth_outputs
__all__ = ["run_loose", "LooseResult", "FilterResult", "to_trajectory", "process_noise", "initial_covariance",
           "static_flags", "bridge_gaps", "gnss_arrays", "course_alignment", "loose_layout",
           "run_loose_batch", "loose_inputs", "loose_result"]


def loose_layout(cfg, aids=(), gnss=True, gnss_velocity=True) -> np.ndarray:
    """Layout of the loose filter: 15, 21, 27 or 33 INS states (``cfg.nstate``), then the calibration
    states of the ``aids`` (:class:`aidnav.filters.aids.Aid`; e.g. the odometer scale factor, the
    barometer bias, where their section enables them), then the self-calibration states of
    ``cfg.calibration`` where they are observable: GNSS lever arm and IMU–GNSS time offset (with GNSS
    fixes), the mounting angles (with the NHC or an aid in the vehicle frame, the odometer)."""
    aux = aid_kinds.layout_states(cfg, aids)
    est = calibration_switches(cfg, aid_kinds.vehicle_frame(aids), gnss_velocity)
    for name in ("lever_arm", "time_offset", "mounting", "velocity_delay"):
        if est[name] and (gnss or name == "mounting"):
            aux.append(name)
    if gnss and cfg.gnss.error_tau_s > 0 and cfg.gnss.use in ("both", "position"):
        aux.append("gnss_pos_error")
    return make_layout(cfg.nstate >= 21, tuple(aux), misalignment=cfg.nstate >= 27,
                       accel_misalignment=cfg.nstate == 33)


def calibration_switches(cfg, odometer: bool = False, gnss_velocity: bool = True) -> dict:
    """Which calibration states the loose filter estimates (``cfg.calibration``; unset = automatic,
    see :class:`aidnav.filters.config.Calibration`). The mounting needs the NHC or an aid in the vehicle
    frame (``odometer``).
    gnss_velocity : whether the fixes carry a velocity (the automatic time offset needs it)."""
    c = cfg.calibration
    vel = gnss_velocity and cfg.gnss.use in ("both", "velocity")
    auto = {"time_offset": vel and "time_offset_s" not in cfg.imu.model_fields_set,
            "lever_arm": "lever_arm_m" not in cfg.gnss.model_fields_set,
            "mounting": True}
    out = {k: (auto[k] if getattr(c, k) is None else bool(getattr(c, k))) for k in auto}
    vd = out["time_offset"] if c.velocity_delay is None else bool(c.velocity_delay)
    out["velocity_delay"] = vd and vel
    out["mounting"] &= bool(cfg.constraints.nhc or odometer)
    return out


def _models(cfg) -> Models:
    """Parameters, χ² gates (by number of rows) and the rejection rule of every model the loose filter
    feeds: GNSS position/velocity gated at ``gnss.gate_probability`` with the consecutive-rejection rule;
    NHC gated at 25 (the χ²(2) quantile of 1 − e^(−12.5)) when GNSS gating is on; ZUPT and ZARU
    ungated; every aid of :data:`aidnav.filters.aids.AIDS` (odometer, barometer, magnetometer, ...) gated
    like GNSS, never re-initialising the navigation block, with its own parameters."""
    gp, c = cfg.gnss.gate_probability, cfg.constraints
    par = np.zeros((ms.N_MODELS, 16))
    gate = np.zeros((ms.N_MODELS, ms.MAX_ROWS + 1))
    max_rej = np.full(ms.N_MODELS, NEVER, np.int64)
    win_n = np.zeros(ms.N_MODELS, np.int64)
    chi2 = np.array([0.0] + [chi2_isf(m, 1.0 - gp) if gp < 1 else 0.0 for m in range(1, ms.MAX_ROWS + 1)])
    mr = np.array(cfg.imu.mounting_rph_deg) * DEG
    cbv = dcm_from_euler(mr[0], mr[1], mr[2]).ravel()
    # the aids see one component of the motion: an inconsistency there is as much their calibration
    # state's as the navigation's, so they never re-initialise the navigation block
    for md, win in [(ms.M_GNSS_POS, cfg.gnss.nis_window), (ms.M_GNSS_VEL, cfg.gnss.nis_window)] + \
            [(k.model, -1) for k in aid_kinds.AIDS.values()]:
        gate[md] = chi2
        max_rej[md] = cfg.gnss.max_consecutive_rejections
        win_n[md] = win
    par[ms.M_GNSS_POS, 0:3] = par[ms.M_GNSS_VEL, 0:3] = cfg.gnss.lever_arm_m
    for k in aid_kinds.AIDS.values():
        if k.params is not None:
            p = k.params(cfg, cbv)
            par[k.model, :len(p)] = p
    V = ms.vehicle
    par[ms.M_NHC, V.V_SIG], par[ms.M_NHC, V.V_MIN_SPEED] = c.nhc_sigma_m_s, c.nhc_min_speed_m_s
    par[ms.M_NHC, V.V_LEVER:V.V_LEVER + 3], par[ms.M_NHC, V.V_CBV:V.V_CBV + 9] = c.nhc_lever_arm_m, cbv
    par[ms.M_NHC, V.V_LEVER_SIG] = c.nhc_lever_arm_sigma_m
    # the heading hold after an IMU gap, its re-alignment from the GNSS course, the acceleration bound of the
    # motion a gap leaves unmodelled in the records used at its closing node (engine.C_*)
    par[ms.M_GNSS_VEL, C_MOUNT_H:C_AMAX + 1] = (mr[2], cfg.init.course_min_speed_m_s,
                                                cfg.init.course_heading_sigma_deg * DEG,
                                                cfg.motion.heading_hold_deg * DEG, cfg.motion.max_accel_m_s2)
    gate[ms.M_NHC, 1:] = 25.0 if gp < 1 else 0.0
    par[ms.M_ZUPT, 0], par[ms.M_ZARU, 0] = c.zupt_sigma_m_s, c.zaru_sigma_deg_s * DEG
    node = []
    if c.zupt:
        node.append((ms.M_ZUPT, 1))
        if c.zaru_sigma_deg_s > 0:
            node.append((ms.M_ZARU, 1))
    if c.nhc:
        node.append((ms.M_NHC, 0))
    return Models(par, gate, max_rej, np.array(node, np.int64).reshape(-1, 2), win_n)


def _records(cfg, g, use, aids):
    """Time-sorted records (GNSS position, velocity per fix; the aids') and, per GNSS fix, the index of
    its position and velocity record (−1: none)."""
    g_t, g_lat, g_lon, g_h, g_vel, g_spos, g_svel = g
    m = len(g_t)
    sc = cfg.gnss
    pos = np.column_stack([g_lat, g_lon, g_h, g_spos * np.asarray(sc.pos_std_scales)])
    vel = np.column_stack([g_vel, g_svel * sc.vel_std_scale])
    has_vel = np.any(~np.isnan(g_vel), axis=1)
    t, mdl, rows, u, src = [], [], [], [], []
    if sc.use in ("both", "position"):
        t.append(g_t), mdl.append(np.full(m, ms.M_GNSS_POS)), rows.append(pos), u.append(use)
        src.append(np.arange(m))
    if sc.use in ("both", "velocity"):
        t.append(g_t), mdl.append(np.full(m, ms.M_GNSS_VEL)), rows.append(vel), u.append(use & has_vel)
        src.append(np.arange(m))
    for ta, ma, ra, ua in aid_kinds.records(cfg, aids):
        t.append(ta), mdl.append(ma), rows.append(ra), u.append(ua), src.append(np.full(len(ta), -1))
    if not t:
        return Records(np.zeros(0), np.zeros(0, np.int64), np.zeros((0, 6)), np.zeros(0, np.bool_)), None
    t, mdl, rows, u, src = (np.concatenate(a) for a in (t, mdl, rows, u, src))
    # stable order: by time; at one time GNSS position, velocity (per fix), then the aids by model id
    o = np.lexsort((mdl, np.where(src >= 0, src, m), t))
    rec = Records(np.ascontiguousarray(t[o]), mdl[o].astype(np.int64), np.ascontiguousarray(rows[o]),
                  np.ascontiguousarray(u[o]))
    return rec, (mdl[o], src[o])


Setup = namedtuple("Setup", ["cfg", "lay", "n", "k0", "t_imu", "proc", "ini", "models", "rec", "rmap",
                             "out_every", "reset_time"])


def loose_setup(imu, gnss, cfg, withheld, events, aids=(), rate_hz: float | None = None) -> Setup:
    """Everything :func:`run_loose` gives the engine except the per-sample IMU arrays: the configuration
    (with a coarse mounting where it is unknown), layout, process model, initial state (``ini``;
    ``reset_idx`` relative to ``k0``, the first IMU sample used; ``reset_time`` the time of the course
    alignment or None), models, records (``rmap``: their GNSS fix of origin) and the output decimation.
    ``imu`` may be the head of the log (:mod:`aidnav.filters.stream`) when no coarse mounting is needed.
    ``rate_hz``: ``imu.rate_hz`` when the caller already has it (:func:`run_loose_batch`)."""
    has_vel = gnss.vel is not None and bool(np.any(np.isfinite(gnss.vel)))
    cfg = correlated_gnss_errors(cfg, gnss, events)  # fixes above 1 Hz: Gauss-Markov error states
    static = None
    if cfg.imu.grade_from_static or cfg.imu.noise_from_static:
        static = static_flags(imu, visible_fixes(gnss, withheld), cfg)
    if cfg.imu.grade_from_static:  # a log at rest measures three bias components: the IMU's grade
        cfg = grade_from_static(imu, static, *_where(gnss), cfg, events)
    lay = loose_layout(cfg, aids, gnss=len(gnss) > 0, gnss_velocity=has_vel)
    n_ins, n = cfg.nstate, int(lay[L_N])
    t_imu = imu.time + cfg.imu.time_offset_s
    g = gnss_arrays(gnss, cfg)
    g_t, g_lat, g_lon, g_h, g_vel, g_spos, g_svel = g
    use = np.ones(len(gnss), dtype=np.bool_) if withheld is None else ~np.asarray(withheld, bool)
    finite = np.isfinite(g_lat) & np.isfinite(g_lon) & np.isfinite(g_h) & np.all(np.isfinite(g_spos), axis=1)
    if not finite.all():
        bad_t = g_t[~finite]
        events.append(f"{int((~finite).sum())} GNSS fixes with NaN/inf position or sigma not used "
                      f"(first at t={bad_t[0]:.3f})")
        use &= finite
    cfg = _coarse_mounting_if_unknown(cfg, imu, gnss, t_imu, g, use, aids, events)
    if cfg.imu.noise_from_static:  # engine vibration: IMU noise from the log's static samples
        cfg = noise_from_static(imu, static, cfg, events)
    ev0: list[str] = []
    i0, ev0 = _aid_heading(initial_state(imu, gnss, cfg, t_imu, g, use, ev0), cfg, aids, ev0)
    events += ev0
    rph = i0["rph"]
    q0 = quat_from_euler(rph[0], rph[1], rph[2])
    v0 = i0["v0"]
    st0 = np.array([i0["lat0"], i0["lon0"], i0["h0"], v0[0], v0[1], v0[2], *q0], float)
    aux = calibration_prior(cfg, lay)
    P0 = np.zeros((n, n))
    P0[:n_ins, :n_ins] = initial_covariance(cfg, n_ins, i0["lat0"], i0["h0"], i0["att_sig"])
    if i0.get("vel_sig") is not None:  # in-motion start: velocity from GNSS with its σ
        for i in range(3):
            P0[DV + i, DV + i] = max(P0[DV + i, DV + i], float(i0["vel_sig"][i]) ** 2)
    P0[n_ins:, n_ins:] = np.diag(aux[:, 0])
    if i0.get("level") is not None:  # a static levelling: the tilt is what the accelerometer errors make it
        P0 = levelled_tilt_covariance(P0, n_ins, i0["level"][0], dcm_from_euler(*rph), i0["level"][1])
    q_psd = np.concatenate([process_noise(cfg, n_ins), aux[:, 1]])
    taus = np.array([cfg.imu.gyro_bias_tau_s, cfg.imu.accel_bias_tau_s, cfg.imu.sf_tau_s, cfg.imu.sf_tau_s])
    # a Gauss–Markov calibration state (τ > 0: the GNSS position errors, a Markov odometer scale factor or
    # baro bias) has the conditional mean x̂ ← e^{−T/τ} x̂ between updates: an open-loop state of the
    # engine; held instead (a random constant's mean), its estimate drifts without bound under the σ
    # of a bounded process (38 m against σ 1 m after 10 min parked with 10-Hz fixes)
    markov = (n_ins + np.flatnonzero(aux[:, 2] > 0)).astype(np.int64)
    proc = Process(lay, q_psd, taus, np.ascontiguousarray(aux[:, 2]), float(cfg.filter.prop_dt_s),
                   open=markov)
    out_every = 1
    if cfg.filter.output_rate_hz:
        rate = imu.rate_hz if rate_hz is None else rate_hz
        out_every = max(1, int(round(rate / cfg.filter.output_rate_hz)))
    rec, rmap = _records(cfg, g, use, aids)
    reset_nav = np.concatenate([i0["reset_nav"], cfg.gnss.lever_arm_m])
    ini = Init(float(i0["t0"]), st0, np.zeros(n - 9), P0, int(i0["reset_idx"]), float(i0["reset_heading"]),
               cfg.init.course_heading_sigma_deg * DEG, reset_nav)
    models = _models(cfg)._replace(cal=_reinit_cal(lay, P0))
    return Setup(cfg, lay, n, int(i0["k0"]), t_imu, proc, ini, models, rec, rmap, out_every,
                 i0.get("reset_time"))


def _where(gnss) -> tuple[float, float]:
    """Latitude [rad] and height [m] of the first fix with a finite position (0, 0: none)."""
    ok = np.flatnonzero(np.isfinite(gnss.lat) & np.isfinite(gnss.height))
    return (float(gnss.lat[ok[0]]), float(gnss.height[ok[0]])) if len(ok) else (0.0, 0.0)


def _reinit_cal(lay, P0) -> np.ndarray:
    """The states a re-initialisation repairs with the navigation block: rows (index, prior variance, 1:
    every re-initialisation / 0: an NIS window's only) (engine ``Models.cal``). An NIS window that fires
    says that the filter's covariance was λ too small over N fixes; every state learnt jointly with the
    navigation under that covariance is then as suspect as the navigation: the IMU's sensor errors
    (biases, scale factors, misalignments: a tilt re-learnt against a bias that kept its converged σ
    collapses onto the same wrong bias) and the calibration (GNSS lever arm, time offset, velocity delay,
    mounting). Each is scaled with the navigation block, at most back to its prior (issue 35, item 5: a
    calibration is repaired, never thrown away). The re-initialisation after consecutive rejections (a
    jump of the navigation: the factor makes one innovation consistent, up to 1e12) repairs the time
    offset, velocity delay and mounting, not the sensor errors nor the lever arm (:func:`.reinit.inflate`:
    with fixes whose σ is far too small, issue 35's zero-σ regression, repairing the biases at each of its
    re-initialisations let the next fixes drag them: 2.0 m against 0.76 m)."""
    rows = [(i, P0[i, i], 0.0) for i in range(NAV, int(lay[L_NINS]))]
    for key, k, every in ((L_LEVER, 3, 0.0), (L_TOFF, 1, 1.0), (L_VDEL, 1, 1.0), (L_MOUNT, 3, 1.0)):
        for i in range(k if lay[key] >= 0 else 0):
            rows.append((lay[key] + i, P0[lay[key] + i, lay[key] + i], every))
    return np.array(rows, float).reshape(-1, 3)


def run_loose(imu, gnss, cfg=None, withheld=None, smooth: bool = False, events: list | None = None,
              cov_times=None, aids=()):
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
        P (n×n, error state of :mod:`aidnav.filters.layout`): for each, the first IMU sample at or
        after it; P is the one the filter holds there after that sample's updates (covariance is
        propagated at nodes only, so ask for node times, e.g. GNSS epochs). Returned in
        ``FilterResult.cov_time`` / ``FilterResult.cov``; times outside the processed span are dropped.
    aids : sequence of :class:`aidnav.filters.aids.Aid` (odometer, barometer, magnetometer heading, ...:
        :data:`aidnav.filters.aids.AIDS`), e.g. ``[aid("odometer", OdometerData(...))]``; the settings of
        each are its section of ``cfg``.
    """
    from .config import LooseConfig  # lazy: pydantic (the filter's kernels do not need it)

    cfg = cfg or LooseConfig()
    events = events if events is not None else []
    su, imu_in, static_used, cov_idx = loose_inputs(imu, gnss, cfg, withheld, events, cov_times, aids)
    r = run_filter(imu_in, su.rec, su.models, su.proc, su.ini, Output(su.out_every, bool(smooth), cov_idx))
    res = loose_result(su, r, imu, gnss, static_used, events)
    if cov_times is not None:
        res.cov_time, res.cov = imu_in.t[cov_idx], r.cov
    n = su.n
    if smooth and len(r.node_idx) > 1:
        ds, Ps = rts(r.S_post, r.S_prior, r.S_phi, r.S_dx, r.reset_node)
        sm_st, sm_b = smooth_outputs(r.out_idx, r.out_st, r.out_bias, r.out_node, r.node_idx, ds, r.S_dx, n)
        res.forward_state, res.forward_pdiag = r.out_st, r.out_pdiag
        res.state, res.bias = sm_st, sm_b
        pd = np.einsum("kii->ki", Ps)
        res.pdiag = pd[np.clip(r.out_node, 0, len(r.node_idx) - 1)]
        res.smoothed = True
        mem = r.S_post.nbytes + r.S_prior.nbytes + r.S_phi.nbytes + Ps.nbytes
        res.counts["smoother_memory_mb"] = mem / 1e6
    return res


#: what a batch's runs share through their common sample times (:func:`run_loose_batch`): ``rate_hz``
#: (:attr:`aidnav.data.ImuData.rate_hz`) and, where the times have no gap (:func:`.preprocess.imu_gaps`),
#: the all-zero gap variances ``no_gaps`` (N, 4) that :func:`.preprocess.bridge_gaps` would return, else None
SharedTimes = namedtuple("SharedTimes", ["rate_hz", "no_gaps"])


def shared_times(imus) -> SharedTimes | None:
    """The :class:`SharedTimes` of runs whose IMU logs have the same sample times and ``t0`` (None where
    they differ): the medians and the (N, 4) zeros computed once for a batch instead of once a run."""
    i0 = imus[0]
    if any(im.t0 != i0.t0 or not (im.time is i0.time or np.array_equal(im.time, i0.time)) for im in imus):
        return None
    gaps = imu_gaps(i0)[2]
    return SharedTimes(i0.rate_hz, np.zeros((len(i0), 4)) if len(gaps) == 0 else None)


def loose_inputs(imu, gnss, cfg, withheld=None, events=None, cov_times=None, aids=(), shared=None):
    """What :func:`run_loose` gives the engine: (:class:`Setup`, the engine's :class:`.engine.Imu` from the
    first sample used, the number of static samples among them, the sample indices of ``cov_times``).
    ``shared``: the :class:`SharedTimes` of ``imu``'s sample times (the same values, computed once for a
    batch of runs); its ``no_gaps`` is then this run's gap variances (read only)."""
    events = events if events is not None else []
    su = loose_setup(imu, gnss, cfg, withheld, events, aids, None if shared is None else shared.rate_hz)
    cfg, k0, t_imu = su.cfg, su.k0, su.t_imu
    if shared is not None and shared.no_gaps is not None:  # what bridge_gaps returns without a gap
        dth_in, dv_in, gap_var = imu.dtheta, imu.dv, shared.no_gaps
    else:
        dth_in, dv_in, gap_var = bridge_gaps(imu, events, bounds=cfg.motion)
    # static flags for every run: the ZUPT/ZARU where the configuration asks for them (counted), and the
    # engine's tilt turn and heading hold at rest (engine._turn_tilt_at_rest) always
    static = static_flags(imu, visible_fixes(gnss, withheld), cfg)
    cov_idx = np.zeros(0, np.int64)
    if cov_times is not None:
        ct = np.sort(np.atleast_1d(np.asarray(cov_times, float)))
        # first sample at or after each time (1 µs tolerance for times computed as k·dt)
        cov_idx = np.searchsorted(t_imu[k0:], ct - 1e-6, side="left").astype(np.int64)
        cov_idx = cov_idx[cov_idx < len(t_imu) - k0]
    sl = slice(k0, None)
    imu_in = Imu(t_imu[sl], dth_in[sl], dv_in[sl], static[sl], gap_var[sl], np.zeros((0, 2)))
    return su, imu_in, int(static[sl].sum()) if cfg.constraints.zupt else 0, cov_idx


def loose_result(su, r, imu, gnss, static_used, events) -> FilterResult:
    """The :class:`FilterResult` of a forward pass ``r`` (:class:`.engine.EngineOut`) of the loose filter
    set up by ``su`` (:func:`loose_setup`) on ``imu``, ``gnss`` (no smoother, no kept covariances)."""
    cfg, lay, k0, t_imu = su.cfg, su.lay, su.k0, su.t_imu
    log = log_dict(r.log, r.n_log)
    cnt = loose_counts(log, len(r.node_idx), static_used, len(imu), k0)
    events += reinit_events(log)
    # the outputs are stamped on the GNSS scale with the final time-offset estimate (docs/conventions.md: the
    # offset is added to the IMU stamps); a forward output at t holds the INS of IMU time t − d̂
    d_hat = float(r.bias[lay[L_TOFF] - NAV]) if lay[L_TOFF] >= 0 else 0.0
    if d_hat:
        sd = float(np.sqrt(r.P[lay[L_TOFF], lay[L_TOFF]]))
        events.append(f"IMU time offset estimated {d_hat:+.4f} s (sigma {sd:.4f} s): output times shifted "
                      "by it")
    ts = t_imu[k0:]
    res = FilterResult(time=ts[r.out_idx] + d_hat, state=r.out_st, bias=r.out_bias, pdiag=r.out_pdiag,
                       node_time=ts[r.node_idx], records=gnss_records(log, su.rmap, len(gnss)),
                       counts=cnt, final_P=r.P, innovations=log, events=events, layout=lay,
                       state_names=layout_names(lay))
    res.calibration_base = calibration_base(cfg)
    res.gnss_time = np.asarray(gnss.time, float)
    return res


def run_loose_batch(imus, gnss_list, cfgs):
    """:func:`run_loose` (forward pass, no smoother) of runs that share a trajectory (the same IMU sample
    times and GNSS fix times; their own increments, fixes and configurations, e.g. initial states),
    advanced together by :func:`aidnav.filters.engine_batch.run_batch`: each result is bit-identical to
    ``run_loose(imu, gnss, cfg)``. Returns the list of :class:`FilterResult`, or None when the runs
    cannot be batched (:func:`aidnav.filters.engine_batch.batchable`: then run them one by one)."""
    ins = []
    shared = shared_times(imus)
    for imu, gnss, cfg in zip(imus, gnss_list, cfgs, strict=True):
        events = []
        su, imu_in, static_used, _ = loose_inputs(imu, gnss, cfg, events=events, shared=shared)
        ins.append((su, imu_in, static_used, events))
    sus, imu_ins = [i[0] for i in ins], [i[1] for i in ins]
    every = sus[0].out_every
    recs, inis = [su.rec for su in sus], [su.ini for su in sus]
    why = batchable(imu_ins, recs, [su.models for su in sus], [su.proc for su in sus], inis, every)
    if why is not None or any(su.out_every != every for su in sus):
        return None
    inp, ini = stack_inputs(imu_ins, recs, inis, every)
    b = run_batch(inp, sus[0].models, sus[0].proc, ini)
    return [loose_result(su, run_outputs(b, r), imu, gnss, used, events)
            for r, ((su, _, used, events), imu, gnss) in enumerate(zip(ins, imus, gnss_list, strict=True))]


def _aid_heading(i0, cfg, aids, events):
    """The initial state ``i0`` (:func:`aidnav.filters.preprocess.initial_state`) with the heading of an
    aid that gives one at t0 (the magnetometer) where none is configured and the aid's σ is below the
    one found (e.g. π: unknown until a GNSS course): then no course alignment follows. Returns (i0, the
    initialisation's events without those of the heading it replaced)."""
    if cfg.init.heading_deg is not None or cfg.init.mode == "given":
        return i0, events
    h = aid_kinds.initial_heading(cfg, aids, float(i0["t0"]))
    if h is None or not h[1] < i0["att_sig"][2]:
        return i0, events
    psi, sig, name = h
    i0 = dict(i0, rph=np.array([i0["rph"][0], i0["rph"][1], psi]), att_sig=i0["att_sig"].copy(),
              reset_idx=-1, reset_heading=0.0, reset_nav=np.full(RN_LEVER, np.nan), reset_time=None)
    i0["att_sig"][2] = sig
    events = [e for e in events if not ("heading" in e and ("course" in e or "gyrocompass" in e))]
    events.append(f"initial heading from {name}: {np.degrees(psi):.2f} deg (sigma {np.degrees(sig):.2f} deg)")
    return i0, events


def _coarse_mounting_if_unknown(cfg, imu, gnss, t_imu, g, use, aids, events):
    """With the NHC or an aid in the vehicle frame (odometer) and no ``imu.mounting_rph_deg`` in the
    configuration, the mounting is unknown and may be anything (an IMU mounted backwards): a coarse
    mounting from the log (:func:`aidnav.filters.preprocess.coarse_mounting`, a whole-log fit:
    post-processing) replaces the identity, and the mounting state refines it. Returns the
    configuration to use."""
    if not (cfg.constraints.nhc or aid_kinds.vehicle_frame(aids)) or \
            "mounting_rph_deg" in cfg.imu.model_fields_set:
        return cfg
    iu = np.flatnonzero(use)
    gs = tuple(a[iu] for a in g)
    vel, _ = gnss_velocity_for_init(gnss.subset(use), gs)
    cm = coarse_mounting(imu, t_imu, gnss.subset(use), vel)
    if cm is None:
        events.append("mounting not given and not resolvable from the log (too little motion): identity "
                      "used for the NHC/odometer")
        return cfg
    rph = tuple(float(np.degrees(x)) for x in cm[1:4])
    events.append(f"mounting not given: coarse IMU->vehicle mounting from the log's accelerations "
                  f"(roll {rph[0]:.1f}, pitch {rph[1]:.1f}, heading {rph[2]:.1f} deg, {cm[4]} epochs)")
    return cfg.model_copy(update={"imu": cfg.imu.model_copy(update={"mounting_rph_deg": rph})})
