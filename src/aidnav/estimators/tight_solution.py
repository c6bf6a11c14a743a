"""The tight solution from raw observations, as ``aidnav tight`` computes it (IMU + RINEX observations +
navigation records → :class:`aidnav.filters.tight.TightResult`), without files: the command's step below its
file handling (:mod:`aidnav.apps.tight`), and what the consistency matrix's tight cells run.

Steps of :func:`process_tight`: SPP with Doppler velocity on every epoch (:func:`aidnav.estimators.dgps.
spp_series`) gives the start position and the GNSS course; roll and pitch from the mean specific force
over ``init.static_window_s`` (static start); heading (unless configured) by matching the IMU's
velocity changes to the SPP velocity changes (:func:`aidnav.filters.heading_match.velocity_match_heading`:
no mounting or vehicle assumed; used when its σ ≤ 30°), else from the first SPP course above
``init.course_min_speed_m_s`` (plus the IMU mounting heading); ZUPTs where the IMU is still and the
SPP speed is low (:func:`aidnav.filters.loose.static_flags`); the carrier phase as ``gnss.tdcp_model``
says; each satellite's pseudoranges from the first epoch at which the SPP used it (a newly acquired
satellite enters past the snapshot solution's residual check: :func:`_admitted`); then
:func:`aidnav.filters.tight.run_tight`. Times stay GPS seconds of the observations' reference
week.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from aidnav.data import GnssData
from aidnav.estimators.dgps import spp_series
from aidnav.filters.config import (
    UNKNOWN_GRADE_IMU,
    UNKNOWN_GRADE_IMU_ACCEL_MISALIGNMENT,
    ImuNoise,
    LooseConfig,
)
from aidnav.filters.heading_match import velocity_match_heading
from aidnav.filters.loose import static_flags
from aidnav.filters.tight import (
    TightConfig,
    clock_allan,
    clock_drift_psd,
    clock_hm2_from_psd,
    run_tight,
    to_trajectory,
)
from aidnav.filters.wheeled import MEDIAN_DEG, NHC_LEVER_ARM_SIGMA_M, NHC_SIGMA_M_S, wheeled_vehicle
from aidnav.nav.gnss_sat import sat_name
from aidnav.nav.rotations import wrap_2pi
from aidnav.units import DEG

#: what the no-configuration IMU model is (aidnav.filters.config.UNKNOWN_GRADE_IMU), for the events
UNKNOWN_GRADE_NOTE = ("Groves' consumer range: gyro bias 360 deg/h turn-on + 20 deg/h instability, "
                      "accelerometer bias 10 mg + 0.5 mg, scale factors 5000 ppm and gyro misalignment "
                      "0.5 deg as states")
SPP_START_SIGMA_M = 100.0  # start-position σ with range-error states [m] (far above any SPP error)
# a velocity-matched heading is used when its σ is below this (beyond it the linearised filter copes no
# better than with an unknown heading); its σ is floored (gyro drift over the matching span, 2 deg)
MAX_MATCH_SIGMA = np.radians(30.0)
MIN_MATCH_SIGMA_DEG = 2.0

__all__ = ["process_tight"]


def process_tight(imu, obs, eph, cfg: TightConfig | None = None, events: list | None = None,
                  smooth: bool = False, cov_times=None):
    """Run the tightly coupled filter on real data; returns (TightResult, spp dict). ``cov_times``: as
    :func:`aidnav.filters.tight.run_tight`'s."""
    from aidnav.filters.preprocess import noise_from_static  # lazy: as the other filter imports here

    cfg = cfg or TightConfig()
    # no constraints section and no vehicle: the NHC is decided from the log (_no_option_nhc)
    no_option = "constraints" not in cfg.model_fields_set and not cfg.constraints.nhc
    events = events if events is not None else []
    keys = set(UNKNOWN_GRADE_IMU_ACCEL_MISALIGNMENT) - {"noise_from_static"}
    if cfg.imu.model_dump(include=keys) == ImuNoise(**UNKNOWN_GRADE_IMU).model_dump(include=keys):
        events.append(f"no imu section: the error model of an IMU of unknown grade ({UNKNOWN_GRADE_NOTE}; "
                      f"{cfg.nins} INS states)")
    elif cfg.imu.model_dump(include=keys) == ImuNoise(**UNKNOWN_GRADE_IMU_ACCEL_MISALIGNMENT).model_dump(
            include=keys):
        events.append(f"no imu section and no NHC: the error model of an IMU of unknown grade "
                      f"({UNKNOWN_GRADE_NOTE}; the accelerometer misalignment 0.5 deg as states, the bias "
                      f"10 mg + 0.5 mg; {cfg.nins} INS states)")
    sp, g, t_imu, i0 = _spp_start(imu, obs, eph, cfg)
    cfg = _clock_from_log(sp, cfg, events)
    tdcp = _tdcp(obs, eph, sp, cfg)
    cfg = _time_offset_from_phase(imu, obs, tdcp, sp, cfg, events)
    if cfg.imu.time_offset_s != 0.0:
        sp, g, t_imu, i0 = _spp_start(imu, obs, eph, cfg, sp)
    ini = cfg.init
    win = (t_imu >= sp["time"][i0]) & (t_imu < sp["time"][i0] + ini.static_window_s)
    dtw = np.diff(np.concatenate([[imu.t0], imu.time]))[win]
    f = imu.dv[win].sum(axis=0) / dtw.sum()
    level = (f, _levelling_sigma(imu, win, dtw, f))
    roll = np.arctan2(-f[0], f[2])
    pitch = np.arctan2(f[1], np.hypot(f[0], f[2]))
    wb = _rest_gyro_bias(imu, win)
    heading, heading_reset, cfg = _start_heading(imu, sp, i0, g, (roll, pitch, wb), cfg, events)
    ini = cfg.init
    if cfg.gnss.range_errors:
        # the SPP start fix is a linearisation point, not information: its error is the range errors the
        # filter estimates (correlated with them), so the first epoch's pseudoranges must place it
        ini = ini.model_copy(update={"position_sigma_m": (SPP_START_SIGMA_M,) * 3})
        cfg = cfg.model_copy(update={"init": ini})
    lc = LooseConfig(imu=cfg.imu, constraints=cfg.constraints, init=cfg.init)
    static = static_flags(imu, g, lc) if cfg.constraints.zupt or cfg.imu.noise_from_static else None
    if cfg.imu.noise_from_static:  # engine vibration (vehicle presets): IMU noise from the static samples
        cfg = cfg.model_copy(update={"imu": noise_from_static(imu, static, lc, events).imu})
    if not cfg.constraints.zupt:
        static = None
    init_state = (
        float(t_imu[np.searchsorted(t_imu, sp["time"][i0]) - 1]),
        sp["lat"][i0],
        sp["lon"][i0],
        sp["h"][i0],
        np.zeros(3),
        np.array([roll, pitch, heading]),
    )
    if static is None or not static[np.searchsorted(t_imu, sp["time"][i0])]:
        v0 = sp["vel_enu"][i0]
        init_state = init_state[:4] + (np.nan_to_num(v0),) + init_state[5:]
    events.append(
        f"start at t={init_state[0]:.3f} from SPP; roll {np.degrees(roll):.2f}, pitch "
        f"{np.degrees(pitch):.2f} deg from the mean specific force over {ini.static_window_s:g} s"
    )
    rows = cfg.gnss.tdcp_model == "rows"
    dphi = _tdcp_increments(obs, eph, cfg, events) if rows else None
    vfix = None if rows else _tdcp_velocities(imu, obs, tdcp, cfg, events)

    obs_f = _admitted(obs, sp, events)

    def run(c, smooth_it, ev):
        return run_tight(imu, obs_f, eph, c, init_state=init_state, static=static,
                         heading_reset=heading_reset, events=ev, smooth=smooth_it, velocity_fixes=vfix,
                         phase_increments=dphi, cov_times=cov_times, level=level)

    if not no_option:
        return run(cfg, smooth, events), sp
    # the decision on the whole log: the smoothed first pass (its attitude σ is what the log supports; the
    # forward pass's heading σ stays above the test's 1° through a partial sky)
    first_events: list = []
    first = run(cfg, True, first_events)
    nhc_cfg = _no_option_nhc(first, cfg, sp, events)
    if nhc_cfg is None and smooth:
        events.extend(first_events)
        return first, sp
    return run(cfg if nhc_cfg is None else nhc_cfg, smooth, events), sp


def _clock_from_log(sp, cfg: TightConfig, events: list) -> TightConfig:
    """``gnss.clock_from_log``: the receiver clock's drift wander measured on the SPP's own clock-drift
    series (:func:`aidnav.filters.tight.clock_drift_psd`), and where it exceeds the grade's prior (TCXO by
    default) the drift's random-walk coefficient h-2 raised to it — as the IMU's white noise is raised to
    the log's static samples: the grade is a floor, the log says when its oscillator wanders more (a
    receiver warming up: the walk's drift ramps by −0.2 m/s² for its first 115 s, 8 m/s in 40 s against
    the TCXO's 1.2 m/s σ). A given ``clock_hm2`` is kept. Returns the configuration to use."""
    g = cfg.gnss
    if not g.clock_from_log or g.clock_hm2 is not None:
        return cfg
    fit = clock_drift_psd(sp["time"], sp["clock_drift"])
    if fit is None:
        events.append("receiver clock: too few SPP clock drifts to measure its wander; the "
                      f"{g.clock_grade} prior kept")
        return cfg
    s_d, _, n_lags = fit
    hm2_grade = clock_allan(g)[1]
    hm2 = clock_hm2_from_psd(s_d)
    how = (f"h-2 {hm2:.3g} used ({hm2 / hm2_grade:.3g}x the {g.clock_grade} prior's {hm2_grade:.3g})"
           if hm2 > hm2_grade else f"within the {g.clock_grade} prior's h-2 {hm2_grade:.3g}: kept")
    events.append(f"receiver clock: drift wander of the SPP clock drifts over {n_lags} lags, random-walk PSD "
                  f"{s_d:.3g} m^2/s^3: {how}")
    if hm2 <= hm2_grade:
        return cfg
    return cfg.model_copy(update={"gnss": g.model_copy(update={"clock_hm2": hm2})})


def _admitted(obs, sp, events: list):
    """The observations with each satellite's pseudoranges before the first epoch at which the SPP used it
    removed (only the code: its Doppler and phase rows are left as the filter's epoch rows make them):
    a newly acquired satellite enters the filter once an epoch's snapshot solution has taken it — with
    redundancy, past the residual check (:func:`aidnav.estimators.spp.spp`). A receiver's code of the first
    seconds after acquisition can be tens of metres off while its tracking loops settle (the walk's G08: its
    first 30 code epochs, all excluded by the check, +20…+34 m; issue 40, session 14): in the filter one such
    range accepted at the gate's edge goes into the satellite's range-error state and the position for the
    rest of the run. A satellite the SPP never uses is not used. Returns the observations (the same object
    when nothing is removed)."""
    used = np.isfinite(sp["residuals"])
    has = np.isfinite(obs.code1)
    first = np.where(used.any(axis=0), np.argmax(used, axis=0), len(obs.time))
    before = has & (np.arange(len(obs.time))[:, None] < first[None, :])
    if not before.any():
        return obs
    late = [f"{sat_name(p)} {int(before[:, j].sum())}" for j, p in enumerate(obs.prn)
            if before[:, j].any() and first[j] < len(obs.time)]
    never = [sat_name(p) for j, p in enumerate(obs.prn) if before[:, j].any() and first[j] == len(obs.time)]
    if late:
        events.append(f"pseudoranges before the SPP first used their satellite not used ({', '.join(late)} "
                      "epochs): a satellite enters once a snapshot solution has taken it")
    if never:
        events.append(f"satellites the SPP never used (no usable ephemeris, below the mask or excluded by "
                      f"its residual check) not given to the filter: {' '.join(never)}")
    return dataclasses.replace(obs, code1=np.where(before, np.nan, obs.code1))


def _no_option_nhc(res, cfg: TightConfig, sp, events: list):
    """What ``aidnav process`` does with no option (issue 35 item 6,
    :func:`aidnav.filters.wheeled.no_option_constraint`), on the tight solution ``res`` computed without the
    NHC (smoothed): a wheeled vehicle (:func:`aidnav.filters.wheeled.wheeled_vehicle`, over the SPP epochs)
    gets the NHC with the cautious σ of :data:`~aidnav.filters.wheeled.NHC_SIGMA_M_S` and the unknown lever
    arm's σ. The tight filter has no mounting states (its NHC takes the configured mounting as exact), so the
    NHC is used only where the log's own axis of motion is the IMU's forward axis (y, RFU) within the test's
    median bound :data:`~aidnav.filters.wheeled.MEDIAN_DEG`; otherwise it says so. Without the NHC a wheeled
    vehicle's IMU-to-body rotation (the common part of the sensors' misalignments) is unobservable and its
    tilt error follows it; with it, the pitch and heading of the IMU against the vehicle are observed. Returns
    the configuration with the NHC, or None.
    """
    tr = to_trajectory(res)
    d = wheeled_vehicle(tr.time, tr.vel, tr.rph, tr.std_att, sp["time"][np.isfinite(sp["lat"])])
    if not d["wheeled"]:
        events.append(f"vehicle from the log: NHC off, {d['reason']}")
        return None
    off = float(np.degrees(np.arccos(min(1.0, abs(d["axis"][1])))))
    if off > MEDIAN_DEG or any(cfg.imu.mounting_rph_deg):
        events.append(f"vehicle from the log: {d['reason']}, but its axis of motion is {off:.1f} deg off the "
                      "IMU's forward axis (or a mounting is configured) and the tightly coupled filter has "
                      "no mounting states: NHC off; give constraints.nhc and imu.mounting_rph_deg to use it")
        return None
    con = cfg.constraints.model_copy(update={"nhc": True, "nhc_sigma_m_s": NHC_SIGMA_M_S,
                                             "nhc_lever_arm_sigma_m": NHC_LEVER_ARM_SIGMA_M})
    events.append(f"vehicle from the log: {d['reason']}: NHC on with sigma {NHC_SIGMA_M_S:g} m/s (lever arm "
                  f"sigma {NHC_LEVER_ARM_SIGMA_M:g} m); a constraints section in the configuration decides "
                  "instead")
    return cfg.model_copy(update={"constraints": con})


def _levelling_sigma(imu, win, dtw, f, block_s: float = 1.0) -> float:
    """The levelling's own tilt error [rad] (beyond what the accelerometer errors do, which the prior
    carries: :func:`aidnav.filters.prior.levelled_tilt_covariance`): the standard error of the window's mean
    specific force, from the scatter of its ``block_s`` means (a still IMU: its noise; a walker or a
    vibrating car: the motion, correlated within a block, counts), largest horizontal body axis, / g."""
    t = imu.time[win]
    blk = np.floor((t - t[0]) / block_s).astype(np.int64)
    nb = int(blk[-1]) + 1 if t.size else 0
    if nb < 2:
        return float(np.radians(2.0))  # no scatter to measure: the field default's attitude σ
    dv, dt = imu.dv[win], dtw
    means = np.array([dv[blk == k].sum(axis=0) / dt[blk == k].sum() for k in range(nb) if np.any(blk == k)])
    se = means.std(axis=0, ddof=1) / np.sqrt(len(means))
    return float(np.max(se[:2]) / np.linalg.norm(f))


def _rest_gyro_bias(imu, win, block_s: float = 1.0, quiet: float = 3.0):
    """The mean gyro rate [rad/s] (3,) over the first unbroken run of quiet ``block_s`` blocks of the
    levelling window ``win`` (bool per IMU sample) — the gyro bias (and the Earth rate) when the IMU is at
    rest — or None when the window's first block is not quiet. A block is quiet when the spread of its
    rates (the largest per-axis σ) is at most ``quiet`` times the quietest block's: at rest the spread is
    the sensor's white noise (a 1-s σ of 100+ samples is good to ~7 %), so 3× is motion, not chance: a
    walker lifting the phone, whose rate would otherwise be taken for bias (no threshold in deg/s needed)."""
    idx = np.flatnonzero(win)
    if idx.size < 2:
        return None
    t = imu.time[idx]
    blk = np.floor((t - t[0]) / block_s).astype(np.int64)
    dt = np.diff(np.concatenate([[imu.t0], imu.time]))[idx]
    w = imu.dtheta[idx] / dt[:, None]
    nb = int(blk[-1]) + 1
    spread = np.array([w[blk == k].std(axis=0).max() if (blk == k).sum() > 2 else np.inf for k in range(nb)])
    if not np.isfinite(spread).any():
        return None
    noisy = np.flatnonzero(spread > quiet * spread.min())
    n_quiet = int(noisy[0]) if noisy.size else nb
    if n_quiet == 0:
        return None
    sel = blk < n_quiet
    return imu.dtheta[idx][sel].sum(axis=0) / dt[sel].sum()


def _spp_start(imu, obs, eph, cfg: TightConfig, sp=None):
    """The SPP solution of the observations (dict of :func:`spp_series`; ``sp`` when given), its fixes
    inside the IMU's time span as :class:`GnssData` (for the static detector and the course), the IMU times
    on the GNSS scale and the index of the first SPP fix inside the IMU span (an input error when there is
    none)."""
    iono = cfg.gnss.iono
    if sp is None:
        sp = spp_series(obs, eph, sigma0=cfg.gnss.code_sigma_m, iono=iono, mask_deg=cfg.gnss.mask_deg,
                        iono_window_s=cfg.gnss.iono_window_s)
    t_imu = imu.time + cfg.imu.time_offset_s
    ok = np.isfinite(sp["lat"]) & (sp["time"] >= t_imu[0]) & (sp["time"] < t_imu[-1])
    if not ok.any():
        fin = sp["time"][np.isfinite(sp["lat"])]
        span = f"{fin[0]:.3f}…{fin[-1]:.3f} s" if fin.size else "none"
        raise ValueError(f"no SPP fix inside the IMU time span {t_imu[0]:.3f}…{t_imu[-1]:.3f} s (SPP fixes "
                         f"from the observation file: {span}): the IMU log and the observation file do not "
                         "overlap — give files of the same session, or --time-offset if the IMU clock is "
                         "on another time scale")
    i0 = int(np.flatnonzero(ok)[0])
    # GNSS "fixes" from SPP for the static detector and the course
    g = GnssData(sp["time"][ok], sp["lat"][ok], sp["lon"][ok], sp["h"][ok], sp["vel_enu"][ok])
    return sp, g, t_imu, i0


def _start_heading(imu, sp, i0: int, g, level, cfg: TightConfig, events: list):
    """The heading to start from: the configuration's, or from matching IMU and SPP velocity changes
    (``level``: roll, pitch [rad] and the mean gyro rate (3,) [rad/s] of the static levelling window), or
    else unknown (σ 180°) until a meaningful SPP course resets it. Returns (heading [rad], the course
    reset (t, heading) or None, the configuration with the initial heading σ that goes with it)."""
    roll, pitch, wb = level
    ini = cfg.init
    heading = 0.0 if ini.heading_deg is None else ini.heading_deg * DEG
    heading_reset = None
    matched = None
    if ini.heading_deg is None:
        # the IMU's own heading from GNSS velocity changes: needs no mounting and no vehicle kind
        matched = velocity_match_heading(imu, sp["time"][i0], roll, pitch, g.time, g.vel, gyro_bias=wb)
        if matched is not None and matched[1] > MAX_MATCH_SIGMA:
            events.append(f"velocity-matched heading {np.degrees(matched[0]):.1f} deg not used: sigma "
                          f"{np.degrees(matched[1]):.1f} deg > {np.degrees(MAX_MATCH_SIGMA):.0f} deg")
            matched = None
    if matched is not None:
        heading = matched[0]
        sig = list(ini.attitude_sigma_deg)
        sig[2] = max(np.degrees(matched[1]), MIN_MATCH_SIGMA_DEG)
        cfg = cfg.model_copy(update={"init": ini.model_copy(update={"attitude_sigma_deg": tuple(sig)})})
        ini = cfg.init
        events.append(f"heading {np.degrees(heading):.1f} deg (sigma {sig[2]:.1f} deg) at the start by "
                      f"matching IMU and SPP velocity changes over {matched[2]} windows of 2 s")
    elif ini.heading_deg is None:
        # the course of the SPP Doppler velocities averaged over 2 s, and only where it is meaningful:
        # mean speed above init.course_min_speed_m_s and at least 5 times its standard error (the spread
        # of the velocities in the window / sqrt(n)); SPP speed noise at a standstill never qualifies
        found = _meaningful_course(g.time, g.vel, ini.course_min_speed_m_s)
        if found is not None:
            tc, course, spd, se = found
            heading_reset = (tc, float(wrap_2pi(course + cfg.imu.mounting_rph_deg[2] * DEG)))
            events.append(f"heading from the SPP course at t={tc:.2f}: {np.degrees(heading_reset[1]):.1f} "
                          "deg "
                          f"(2 s mean speed {spd:.2f} m/s, standard error {se:.2f} m/s)")
        else:
            events.append("heading never aligned: no SPP course above init.course_min_speed_m_s with a speed "
                          "5 standard errors above its noise; the heading stays unknown (sigma 180 deg)")
        # until it is aligned the heading is unknown: its initial σ says so
        sig = list(ini.attitude_sigma_deg)
        sig[2] = 180.0
        cfg = cfg.model_copy(update={"init": ini.model_copy(update={"attitude_sigma_deg": tuple(sig)})})
        ini = cfg.init
    return heading, heading_reset, cfg


def _tdcp(obs, eph, sp, cfg):
    """The TDCP mean velocities (:func:`aidnav.estimators.tdcp.tdcp_series`) of ``gnss.tdcp_model``
    'velocity', or None (``gnss.use_phase`` off, the 'rows' model or no phase)."""
    from aidnav.estimators.tdcp import tdcp_series  # lazy: only where the observations have a phase

    g = cfg.gnss
    if not g.use_phase or obs.phase1 is None or g.tdcp_model == "rows":
        return None
    return tdcp_series(obs, eph, sp["ecef"], g.phase_sigma_m, g.slip_threshold_cycles)


def _time_offset_from_phase(imu, obs, r, sp, cfg, events):
    """``gnss.time_offset_from_phase``: with TDCP velocities ``r`` and no ``imu.time_offset_s`` in the
    configuration, the IMU-GNSS time offset from the specific force's norm
    (:func:`aidnav.estimators.tdcp.imu_time_offset`; TDCP velocities of 5+ satellites) as
    ``imu.time_offset_s`` and its σ as
    ``gnss.time_offset_sigma_s`` (unless configured). Returns the configuration to use."""
    from aidnav.estimators.tdcp import imu_time_offset  # lazy: as _tdcp
    from aidnav.nav.earth import gravity  # lazy: as _tdcp

    g = cfg.gnss
    if r is None or not g.time_offset_from_phase or "time_offset_s" in cfg.imu.model_fields_set:
        return cfg
    ok = np.isfinite(sp["lat"])
    if not ok.any():
        return cfg
    # only TDCP velocities with a redundant satellite (5+): with 4 the least squares has no check of its own
    # errors (no residual, no variance factor) and the vertical, which the norm reads, is the weakest
    vel = np.where((r["n_used"] >= 5)[:, None], r["vel_enu"], np.nan)
    est = imu_time_offset(imu, obs.time, vel, gravity(np.median(sp["lat"][ok]), np.median(sp["h"][ok])))
    if est is None:
        events.append("IMU-GNSS time offset: not estimated from the phase (too few TDCP accelerations of 5+ "
                      "satellites, or the fit at the edge of its ±0.2 s grid); the IMU stamps as they are")
        return cfg
    d, sd, n = est
    events.append(f"IMU-GNSS time offset from the specific force's norm (IMU against the TDCP accelerations, "
                  f"{n} epochs): {d:+.4f} s, sigma {sd:.4f} s, added to the IMU stamps; its sigma as the "
                  "velocity's timing noise at each record (gnss.time_offset_sigma_s)")
    gu = {} if "time_offset_sigma_s" in g.model_fields_set else {"time_offset_sigma_s": sd}
    return cfg.model_copy(update={"imu": cfg.imu.model_copy(update={"time_offset_s": d}),
                                  "gnss": g.model_copy(update=gu)})


def _tdcp_velocities(imu, obs, r, cfg, events):
    """TDCP mean velocities ``r`` (:func:`_tdcp`) as velocity records at the middle of each interval, or
    None. Their σ per axis: the TDCP σ and the
    difference between the interval's mean velocity and the velocity at its middle, Δt²/24 times the jerk,
    the jerk taken as the change of the IMU's specific force over the interval divided by Δt (the change of
    gravity's projection when the body turns counts too: conservative)."""
    g = cfg.gnss
    if r is None:
        return None
    t0, t1 = obs.time[:-1], obs.time[1:]
    t_imu = imu.time + cfg.imu.time_offset_s
    dt_imu = np.diff(np.concatenate([[imu.t0], imu.time]))
    f = imu.dv / dt_imu[:, None]
    fi = np.column_stack([np.interp(np.concatenate([t0, t1]), t_imu, f[:, i]) for i in range(3)])
    jerk_dt = np.linalg.norm(fi[len(t0):] - fi[:len(t0)], axis=1)  # |Δf| over the interval [m/s²]
    dyn = (t1 - t0) * jerk_dt / 24.0
    sig = np.sqrt(np.einsum("kii->ki", r["vel_cov_enu"]) + dyn[:, None] ** 2)
    n_ok = int(np.isfinite(r["vel_enu"][:, 0]).sum())
    n_slip = int((r["slips"] != 0).sum())
    src = "the receiver's (cpStdev)" if obs.phase_sigma1 is not None else f"{g.phase_sigma_m:g} m"
    events.append(f"carrier phase: {n_ok} TDCP velocities of {len(t0)} intervals (4+ satellites without a "
                  f"slip); {n_slip} cycle slip(s) flagged (loss-of-lock indicator or phase-Doppler test); "
                  f"phase sigma {src}, scaled by the least squares' variance factor (at the end "
                  f"{r['variance_factor'][-1]:.2f})")
    return r["t_mid"], r["vel_enu"], sig


def _tdcp_increments(obs, eph, cfg, events):
    """The carrier-phase increments λΔL [m] (M, S) between consecutive epochs with cycle slips removed
    (:func:`aidnav.estimators.tdcp.phase_increments`: loss-of-lock indicator and phase–Doppler test), for
    the tight filter's time-differenced carrier-phase rows; None when ``gnss.use_phase`` is off or the
    observations have no phase."""
    from aidnav.estimators.tdcp import phase_increments  # lazy: only where the observations have a phase

    g = cfg.gnss
    if not g.use_phase or obs.phase1 is None:
        return None
    if eph.ref_week != obs.ref_week:
        eph = eph.to_week(obs.ref_week)
    o = obs.with_frequencies(eph)  # wavelengths per satellite (GLONASS channels from the records)
    dphi, slips = phase_increments(o.time, o.phase1, o.lli1, o.range_rate(), g.slip_threshold_cycles,
                                   o.wavelengths())
    n_ok = int(np.isfinite(dphi).sum())
    n_slip = int((slips != 0).sum())
    events.append(f"carrier phase: {n_ok} phase increments for time-differenced delta-range rows; {n_slip} "
                  "cycle slip(s) flagged (loss-of-lock indicator or phase-Doppler test)")
    return dphi


def _meaningful_course(t, vel, min_speed, window_s: float = 2.0, k_sigma: float = 5.0):
    """First epoch whose ``window_s`` mean horizontal velocity has a speed above ``min_speed`` and above
    ``k_sigma`` standard errors (spread / √n of the velocities in the window). Returns (time, course [rad],
    mean speed, standard error) or None."""
    ve, vn = vel[:, 0], vel[:, 1]
    for i in np.flatnonzero(np.hypot(ve, vn) > min_speed):
        m = (np.abs(t - t[i]) <= 0.5 * window_s) & np.isfinite(ve) & np.isfinite(vn)
        n = int(m.sum())
        if n < 3:
            continue
        me, mn = ve[m].mean(), vn[m].mean()
        spd = float(np.hypot(me, mn))
        se = float(np.sqrt((ve[m].var(ddof=1) + vn[m].var(ddof=1)) / n))
        if spd > min_speed and spd > k_sigma * se:
            return float(t[i]), float(wrap_2pi(np.arctan2(me, mn))), spd, se
    return None
