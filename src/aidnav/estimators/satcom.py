"""Satcom on the move (seed 003, patent CN104064869): MEMS-INS/GPS navigation, dual-quaternion antenna
control, servo model and pointing error (models.md §4).

Frames and units (``docs/conventions.md``): n = ENU, b = body RFU, antenna frame v (y_v beam, z_v on the
azimuth-axis side); position (lat, lon [rad], h [m]), velocity ENU [m/s], attitude q_b^n (Hamilton,
scalar first); angles in radians inside, degrees only where a name says ``_deg``. Times in seconds on the
input's scale.

What is here, in the order of the patent's system (its Fig. 3):

* **Navigation** (§4.1). :func:`run_nav8`: strapdown (:func:`aidnav.nav.strapdown.strapdown_step`)
  at the IMU ("interrupt") rate and the patent's **8-state Kalman filter** (Qin, Zhang & Wang, 2nd ed.)
  x = [δv_E, δv_N, φ_E, φ_N, ε_x, ε_y, ∇_x, ∇_y] with the GPS velocity difference z = v_INS − v_GPS (E, N)
  as measurement. The dynamics are the rows and columns of the common 15-state ENU model
  (:func:`aidnav.filters.ins_errors.fill_model`, §6) restricted to these states (φ_U dropped); the
  filter is the one Kalman core (:mod:`aidnav.filters.kalman`: ``discretize``, ``predict``, ``update``).
  Only the level attitude (and the E/N velocity, the x/y sensor biases) is corrected; heading comes from
  the initial alignment and gyro integration. The correction convention is that of docs/conventions.md:
  C_b^n(computed) = (I − [φ×]) C_b^n(true), corrected by q ← q(φ̂) ⊗ q. Outside the filter, position,
  height and vertical velocity are taken from each GPS fix (the 8 states have no position; a free
  vertical channel diverges); ``use_filter=False`` gives the same mechanisation without the Kalman
  correction ("free INS" for the attitude). :func:`run_loose_nav` runs the 15-state loosely coupled
  filter (:func:`aidnav.filters.loose.run_loose`) instead and recovers the same per-interrupt quantities.
  Both return a :class:`NavRun`: the navigation quaternion after each interrupt, the rotation vector
  ΔΘ of that interrupt (body relative to the ideal platform: q_pre = q_prev ⊗ q(ΔΘ), i.e.
  ΔΘ ≈ ∫(ω_ib^b − C_n^b ω_in^n)dt) and whether a filter correction was applied.
* **Dual-quaternion control** (§4.2, claims 1–2; total rate bound of issue 27).
  :func:`dual_quaternion_track`: the antenna-control quaternion starts equal to the navigation quaternion
  and receives the **same** ΔΘ every interrupt. The patent then "updates the antenna quaternion again with
  the three-axis command rotation vector" ([0025], [0071]). Here that vector is the geodesic toward the
  navigation quaternion: with e = rotvec(q_ant* ⊗ q_nav) (body frame; elements x ↔ pitch, y ↔ roll,
  z ↔ heading), q_ant ← q_ant ⊗ q(σ·e), σ = min(1, w·dt/|e|).
  - Signs: each element has the sign of the patent's rules a–f. This holds exactly for one axis alone and
    to first order otherwise, in the platform sense of §4.4 erratum 2: the command rotates the
    antenna's virtual platform, so every Euler difference d_k = angle_k(q_ant) − angle_k(q_nav) decreases.
    The patent's (Qin/PSINS) heading is the counter-clockwise yaw; aidnav's heading is clockwise, so the
    reported third difference is on yaw ψ = −heading.
  - Magnitude (claim 2 on the total rotation; §4.4 erratum 3): |e|/T_f ≤ w ≤ w_max. The rate is
    latched at each filter correction (w = min(w_max, margin·|e|/T_f)). Between corrections it is
    min(w_max, max(latched, |e|/T_f)). When |e|/T_f ≤ w_max every element is at least |e_k|/T_f, so the
    per-axis claim 2 holds; otherwise the bound w_max wins.
  - Bounds: the total change of the antenna attitude per interrupt beyond the gyro-propagated motion is
    exactly min(w·dt, |e|) ≤ w_max·dt. A guard keeps every Euler angle's change within w_max·dt too;
    off level the roll and heading axes are not orthogonal. A single-axis difference is chased exactly
    as by the per-axis rule (|d| falls by min(w·dt, |d|) per interrupt).
  - Closing: the common ΔΘ does not change the angle |e|, only how it is split between the Euler angles.
    So the angle falls linearly at w and every axis closes when the whole rotation does, at
    |e_0|/w (± one interrupt; ``docs/seed_003_closing_times.md``). The command never passes q_nav.
  - Servo commands are computed from q_ant only (:func:`servo_commands`).
* **Servo angles** (§4.3): :func:`aidnav.nav.geo_pointing.servo_angles_rad` /
  :func:`aidnav.nav.geo_pointing.servo_angles` (re-exported here).
* **Servo and pointing model**: :func:`servo_track` (each axis a second-order loop, natural frequency
  ω_n = 2π·bandwidth and damping ζ, with command-rate feed-forward, acceleration and rate limits),
  :func:`beam_errors` (angle between the servo's beam and the true line of sight, with the true attitude
  and position; polarization mismatch) and :func:`signal_loss_db` (Gaussian-beam pointing loss
  12·(θ/θ_3dB)² dB plus polarization mismatch loss −20·log10|cos Δp|).
* :func:`reference_chase`: the reference chase run of §4.5.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from aidnav.filters.ins_errors import (
    correct_increments,
    increment_buffers,
)
from aidnav.filters.prior import ins_p0_diag, ins_psd, markov_psd
from aidnav.jit import njit
from aidnav.nav.geo_pointing import servo_angles
from aidnav.nav.rotations import (
    euler_from_quat,
    quat_conj,
    quat_from_euler,
    quat_from_rotvec,
    quat_mult,
    quat_normalize,
    rotvec_from_quat,
    wrap_pi,
)
from aidnav.nav.strapdown import strapdown_step

from .satcom_servo import (  # noqa: F401  (re-exported: the servo half of the seed-003 system)
    ServoAxis,
    ServoResult,
    beam_errors,
    default_servo_axes,
    servo_commands,
    servo_track,
    signal_loss_db,
)

__all__ = [
    "Nav8Config", "NavRun", "run_nav8", "run_loose_nav", "dual_quaternion_track", "DualResult",
    "servo_commands", "ServoAxis", "default_servo_axes", "servo_track", "ServoResult", "beam_errors",
    "signal_loss_db", "reference_chase", "servo_angles", "NAV8_STATES", "quat_angle_between",
    "quat_angles_between",
]

from aidnav.filters import engine as eng
from aidnav.filters import measurements as ms
from aidnav.filters.layout import make_layout
from aidnav.filters.loose import run_loose
from aidnav.units import DEG, DEG_H, UG  # noqa: E402, F401  (DEG_H, UG: units of Nav8Config's keys)

#: the 8 states of the patent's filter and their indices in the 15-state model of ins_errors
NAV8_STATES = ("dvE", "dvN", "phiE", "phiN", "eps_x", "eps_y", "nabla_x", "nabla_y")
_IDX15 = np.array([3, 4, 0, 1, 9, 10, 12, 13], dtype=np.int64)


# ============================================================================================ navigation
@dataclass
class Nav8Config:
    """Settings of the patent's 8-state filter (boundary units in the names).

    The IMU noise model drives the 15-state process model (white gyro/accelerometer noise, first-order
    Gauss-Markov bias driving noise q = 2σ²/τ); only its 8-state part is used.
    """

    arw_deg_sqrt_h: float = 0.3
    vrw_m_s_sqrt_h: float = 0.1
    gyro_bias_sigma_deg_h: float = 10.0  #: initial σ of ε_x, ε_y
    accel_bias_sigma_ug: float = 1000.0  #: initial σ of ∇_x, ∇_y
    gyro_bias_instability_deg_h: float = 5.0
    accel_bias_instability_ug: float = 100.0
    bias_tau_s: float = 300.0
    vel_sigma_m_s: float = 0.1  #: GPS velocity 1σ (E, N) [m/s]
    init_vel_sigma_m_s: float = 0.2
    init_level_sigma_deg: float = 1.0  #: initial σ of φ_E, φ_N
    reset_position: bool = True  #: take lat, lon, h, v_U from each GPS fix (outside the filter)

    def q_psd(self) -> np.ndarray:
        """Continuous PSD of the 12 noise inputs of the 15-state model (SI units)."""
        return ins_psd(self.arw_deg_sqrt_h * DEG / 60.0, self.vrw_m_s_sqrt_h / 60.0,
                       markov_psd(self.gyro_bias_instability_deg_h * DEG_H, self.bias_tau_s),
                       markov_psd(self.accel_bias_instability_ug * UG, self.bias_tau_s))

    def p0(self) -> np.ndarray:
        """Initial covariance (8×8) of the filter's states (``NAV8_STATES``)."""
        d = ins_p0_diag(15, 0.0, 0.0, self.init_level_sigma_deg * DEG, self.init_vel_sigma_m_s, 0.0,
                        self.gyro_bias_sigma_deg_h * DEG_H, self.accel_bias_sigma_ug * UG)
        return np.diag(d[_IDX15])


@dataclass
class NavRun:
    """Navigation output at every IMU interrupt (input to :func:`dual_quaternion_track`).

    time (N,) [s]; state (N, 10) [lat, lon, h, vE, vN, vU, q_b^n] after the interrupt (and after any filter
    correction); dtheta (N, 3) ΔΘ of the interrupt [rad] (body, relative to the ideal platform); dt (N,)
    interrupt periods [s]; corrected (N,) bool: a filter correction was applied at that interrupt;
    q0 (4,) the navigation quaternion before the first interrupt; t0 [s] its time. filter_time (M,),
    filter_x (M, n): the estimated error at each filter epoch (before feedback); bias (N, k) the sensor
    bias estimates [gyro rad/s, accel m/s²]; label: which filter.
    """

    time: np.ndarray
    state: np.ndarray
    dtheta: np.ndarray
    dt: np.ndarray
    corrected: np.ndarray
    q0: np.ndarray
    t0: float
    filter_time: np.ndarray = field(default_factory=lambda: np.zeros(0))
    filter_x: np.ndarray = field(default_factory=lambda: np.zeros((0, 8)))
    bias: np.ndarray | None = None
    label: str = ""


def _nav8_engine(imu, gnss, st0, cfg: Nav8Config, use_filter: bool):
    """The 8-state filter on the filter engine (:func:`aidnav.filters.engine.run_filter`): the state
    subset ``_IDX15`` of the 15-state layout, nodes at the GPS fixes only (a fix at t is used at the first
    IMU sample at or after t − 1 ns), the GNSS velocity model with the vertical component left out
    (z = v_INS − v_GPS, E and N) and no lever arm, ungated; position, height and v_U from each fix after
    the node (``reset_pos``, outside the filter). Returns the engine output and the record times."""

    m, n = len(gnss), len(imu)
    row = np.full((m, 10), np.nan)
    row[:, 0:2] = gnss.vel[:, 0:2]
    row[:, 3:6] = cfg.vel_sigma_m_s
    row[:, 6:9] = np.column_stack([gnss.lat, gnss.lon, gnss.height])
    row[:, 9] = gnss.vel[:, 2]
    rec = eng.Records(np.asarray(gnss.time, float) - 1e-9, np.full(m, ms.M_GNSS_VEL, np.int64), row,
                      np.full(m, bool(use_filter)))
    mod = eng.Models(np.zeros((ms.N_MODELS, 4)), np.zeros((ms.N_MODELS, ms.MAX_ROWS + 1)),
                     np.full(ms.N_MODELS, eng.NEVER, np.int64), np.zeros((0, 2), np.int64))
    tau = float(cfg.bias_tau_s)
    proc = eng.Process(make_layout(), cfg.q_psd(), np.array([tau, tau, 0.0, 0.0]), np.zeros(0), 1e9,
                       _IDX15, bool(cfg.reset_position))
    ini = eng.Init(float(imu.t0), st0, np.zeros(6), cfg.p0(), -1, 0.0, 0.0, np.full(15, np.nan))
    imu_in = eng.Imu(np.asarray(imu.time, float), imu.dtheta, imu.dv, np.zeros(n, np.bool_), np.zeros((n, 2)),
                     np.zeros((0, 2)))
    return eng.run_filter(imu_in, rec, mod, proc, ini, eng.Output(1, True, np.zeros(0, np.int64))), rec.t


def _init_state(lat, lon, h, vel, rph):
    q0 = quat_from_euler(float(rph[0]), float(rph[1]), float(rph[2]))
    return np.array([lat, lon, h, vel[0], vel[1], vel[2], *q0], float)


def run_nav8(imu, gnss, lat: float, lon: float, h: float, vel, rph, cfg: Nav8Config | None = None,
             use_filter: bool = True) -> NavRun:
    """MEMS INS + GPS with the patent's 8-state velocity-matching filter (§4.1).

    imu : :class:`aidnav.data.ImuData` (increments, body RFU); gnss : :class:`aidnav.data.GnssData` with
    velocity (the filter period T_f is the GPS interval). Initial state at ``imu.t0``: lat, lon [rad],
    h [m], vel ENU [m/s] (3,), rph = (roll, pitch, heading) [rad] (from the initial alignment).
    ``use_filter=False``: no Kalman correction (position, height and v_U still follow GPS when
    ``cfg.reset_position``), i.e. free-INS attitude. Returns a :class:`NavRun`.
    """
    cfg = cfg or Nav8Config()
    if gnss.vel is None:
        raise ValueError("run_nav8: the 8-state filter needs GPS velocity")
    st0 = _init_state(lat, lon, h, np.asarray(vel, float), rph)
    r, rec_t = _nav8_engine(imu, gnss, st0, cfg, use_filter)
    t = np.asarray(imu.time, float)
    dth, dts = _replay_increments(t, imu.dtheta, imu.dv, float(imu.t0), st0, r.out_st, r.out_bias, 6)
    used = r.log.status[:len(rec_t)] == 1  # the fixes the filter used, at their node sample
    k_used = np.searchsorted(t, rec_t[used], side="left")
    corr = np.zeros(len(t), np.bool_)
    corr[k_used] = True
    x = r.S_dx[np.searchsorted(r.node_idx, k_used)]
    return NavRun(time=t.copy(), state=r.out_st, dtheta=dth, dt=dts, corrected=corr, q0=st0[6:10].copy(),
                  t0=float(imu.t0), filter_time=t[k_used], filter_x=x, bias=r.out_bias,
                  label="8-state" if use_filter else "free INS")


@njit(cache=True)
def _replay_increments(imu_t, dth, dvel, t0, st0, states, bias, nb):
    """ΔΘ of every interrupt of a closed-loop run: replay one strapdown step from the previous output
    with the same bias-compensated increments, q_pre = q_prev ⊗ q(ΔΘ) (scalar code: no temporaries)."""
    n = imu_t.shape[0]
    out = np.empty((n, 3))
    dts = np.empty(n)
    st = st0.copy()
    b = np.zeros(nb)
    dthc, dvc, dth_prev, dv_prev = increment_buffers()  # corrected increments: this / previous sample
    tp = t0
    for k in range(n):
        dt = imu_t[k] - tp
        tp = imu_t[k]
        correct_increments(dth[k], dvel[k], b, dt, dthc, dvc)
        p0, p1, p2, p3 = st[6], -st[7], -st[8], -st[9]  # q_prev*
        strapdown_step(st, dthc, dvc, dth_prev, dv_prev, dt)
        q0, q1, q2, q3 = st[6], st[7], st[8], st[9]
        r0 = p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3  # q_prev* ⊗ q (rotations.quat_mult)
        r1 = p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2
        r2 = p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1
        r3 = p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0
        if r0 < 0:  # its rotation vector (rotations.rotvec_from_quat)
            r0, r1, r2, r3 = -r0, -r1, -r2, -r3
        s = np.sqrt(r1 ** 2 + r2 ** 2 + r3 ** 2)
        f = 2.0 / r0 * (1.0 - s * s / (3.0 * r0 * r0)) if s < 1e-8 else 2.0 * np.arctan2(s, r0) / s
        out[k, 0], out[k, 1], out[k, 2] = f * r1, f * r2, f * r3
        dts[k] = dt
        for i in range(3):
            dth_prev[i] = dthc[i]
            dv_prev[i] = dvc[i]
        for i in range(10):
            st[i] = states[k, i]
        for i in range(nb):
            b[i] = bias[k, i]
    return out, dts


def run_loose_nav(imu, gnss, lat: float, lon: float, h: float, vel, rph, cfg=None) -> NavRun:
    """The 15-state loosely coupled filter (:func:`aidnav.filters.loose.run_loose`) as the navigation of
    the antenna controller: same initial state as :func:`run_nav8` (given mode), corrections at the
    filter nodes (every GPS fix and ``cfg.filter.prop_dt_s``); full attitude (heading too) is corrected.

    ``cfg`` : :class:`aidnav.filters.config.LooseConfig` or None (consumer MEMS defaults); its
    ``init`` section is overwritten with the given state. Returns a :class:`NavRun` whose ΔΘ are
    recovered by replaying each interrupt's strapdown step (exact: the same kernel and inputs).
    """
    from aidnav.filters.config import LooseConfig  # lazy: pulls in pydantic

    cfg = (cfg or LooseConfig()).model_copy(deep=True)
    ini = cfg.init
    ini.mode = "given"
    ini.lat_deg, ini.lon_deg, ini.height_m = float(np.degrees(lat)), float(np.degrees(lon)), float(h)
    ini.velocity_m_s = tuple(float(v) for v in vel)
    ini.roll_deg, ini.pitch_deg, ini.heading_deg = (float(np.degrees(a)) for a in rph)
    cfg.filter.output_rate_hz = None
    # the 15-state navigation: no self-calibration states (simulated data, exact lever arm and clocks)
    cfg.calibration.time_offset = cfg.calibration.lever_arm = cfg.calibration.mounting = False
    cfg.calibration.velocity_delay = False
    if cfg.imu.time_offset_s != 0.0:
        raise ValueError("run_loose_nav: use IMU data already on the GNSS time scale (time_offset_s = 0)")
    res = run_loose(imu, gnss, cfg)
    if len(res.time) != len(imu):
        raise RuntimeError("run_loose_nav: expected an output at every IMU sample")
    # the initial state exactly as run_loose builds it (degrees round trip included)
    st0 = _init_state(ini.lat_deg * DEG, ini.lon_deg * DEG, ini.height_m, np.array(ini.velocity_m_s),
                      np.array([ini.roll_deg, ini.pitch_deg, ini.heading_deg]) * DEG)
    nb = res.bias.shape[1]
    dth, dts = _replay_increments(imu.time, imu.dtheta, imu.dv, float(imu.t0), st0,
                                  np.ascontiguousarray(res.state), np.ascontiguousarray(res.bias), nb)
    corrected = np.isin(res.time, res.node_time)
    return NavRun(time=res.time, state=res.state, dtheta=dth, dt=dts, corrected=corrected,
                  q0=st0[6:10].copy(), t0=float(imu.t0), bias=res.bias, label=f"{cfg.nstate}-state loose")


# ============================================================================= dual-quaternion control
@njit(cache=True)
def quat_angle_between(p, q):
    """Rotation angle [rad] between two unit quaternions (sign-insensitive)."""
    r = quat_mult(quat_conj(p), q)
    s = np.sqrt(r[1] * r[1] + r[2] * r[2] + r[3] * r[3])
    return 2.0 * np.arctan2(s, abs(r[0]))


@njit(cache=True)
def quat_angles_between(p, q):
    """Rotation angles [rad] (N,) between the rows of two (N, 4) quaternion arrays."""
    n = p.shape[0]
    out = np.empty(n)
    for k in range(n):
        out[k] = quat_angle_between(p[k], q[k])
    return out


@njit(cache=True)
def _wrap_pi(a):
    """:func:`wrap_pi` onto (-π, π]."""
    r = wrap_pi(a)
    if r == -np.pi:
        r = np.pi
    return r


@njit(cache=True)
def _patent_angles(q):
    """(pitch, roll, yaw) [rad] of q_b^n in the patent's element order; yaw = −heading (CCW positive)."""
    r, p, h = euler_from_quat(q)
    return p, r, -h


@njit(cache=True)
def _align_sign(q, ref):
    """q or −q, whichever is on the side of ``ref`` (keeps the quaternion sign continuous)."""
    if q[0] * ref[0] + q[1] * ref[1] + q[2] * ref[2] + q[3] * ref[3] < 0:
        return -q
    return q


@njit(cache=True)
def _euler_change(a0, q):
    """Euler change a0 − angles(q), patent order [pitch, roll, yaw], wrapped (platform sense +)."""
    p, r, y = _patent_angles(q)
    return np.array([_wrap_pi(a0[0] - p), _wrap_pi(a0[1] - r), _wrap_pi(a0[2] - y)])


@njit(cache=True)
def _dual_kernel(q0, dtheta, dts, q_nav, corrected, t_f, w_max, margin):
    """Antenna-control quaternion chasing q_nav along the geodesic at a bounded total rate (§4.2).

    Per interrupt: q_ant ← q_ant ⊗ q(ΔΘ) (the same increment as q_nav); then with the body-frame
    difference e = rotvec(q_ant* ⊗ q_nav) (angle |e|, unchanged by the common increment) the command is
    the rotation σ·e, σ = min(1, w·dt/|e|), w = min(w_max, max(w_lat, |e|/T_f)), w_lat latched at each
    correction at min(w_max, margin·|e|/T_f). Its rotation is exactly σ|e| ≤ w·dt ≤ w_max·dt (no
    iteration). Guard: off level the roll and heading Euler axes are not orthogonal, so an Euler angle can
    move by up to σ|e|/cos(pitch); σ is then shrunk until none moves by more than w_max·dt (the Euler
    change is linear in σ up to a relative O(σ|e|) term, so one or two rescaling passes suffice; bisection
    is the fallback).
    """
    n = dtheta.shape[0]
    q_ant = q0.copy()
    w_lat = 0.0
    out_q = np.empty((n, 4))
    out_d = np.empty((n, 3))  # Euler differences after the command [pitch, roll, yaw]
    out_step = np.zeros((n, 3))  # Euler change applied by the command [pitch, roll, yaw] (platform sense +)
    out_rot = np.zeros((n, 3))  # rotation vector of the command, body frame: q_ant ← q_ant ⊗ q(rot)
    out_w = np.empty(n)  # total command rate w [rad/s]
    a_nav = np.empty(3)
    for k in range(n):
        # 1. the same ΔΘ as the navigation quaternion (gyro-propagated motion)
        q_ant = quat_normalize(quat_mult(q_ant, quat_from_rotvec(dtheta[k])))
        qn = q_nav[k]
        pn, rn, yn = _patent_angles(qn)
        a_nav[0], a_nav[1], a_nav[2] = pn, rn, yn
        pa, ra, ya = _patent_angles(q_ant)
        a_ant = np.array([pa, ra, ya])
        # 2. the difference as one rotation (shortest way) and its angle
        e = rotvec_from_quat(quat_mult(quat_conj(q_ant), qn))
        ang = np.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
        # 3. the rate, claim 2 on the total rotation: |e|/T_f ≤ w ≤ w_max (w_max wins), latched
        if corrected[k]:
            w_lat = min(w_max, margin * ang / t_f)
        w = min(w_max, max(w_lat, ang / t_f))
        out_w[k] = w
        dt = dts[k]
        if ang > 0.0:
            w_ax = w_max * dt
            frac = min(1.0, w * dt / ang)
            if frac >= 1.0:
                q_new = _align_sign(qn.copy(), q_ant)  # closes: the antenna attitude is the navigation's
            else:
                q_new = quat_normalize(quat_mult(q_ant, quat_from_rotvec(frac * e)))
            step = _euler_change(a_ant, q_new)
            m = np.abs(step).max()
            if m > w_ax:  # guard: no Euler angle beyond w_max·dt (off level only)
                for _ in range(8):
                    frac *= w_ax / m
                    q_new = quat_normalize(quat_mult(q_ant, quat_from_rotvec(frac * e)))
                    step = _euler_change(a_ant, q_new)
                    m = np.abs(step).max()
                    if m <= w_ax:
                        break
                if m > w_ax:  # fallback (not met away from pitch ±90°): bisection on [0, frac]
                    lo, hi = 0.0, frac
                    for _ in range(60):
                        mid = 0.5 * (lo + hi)
                        qm = quat_normalize(quat_mult(q_ant, quat_from_rotvec(mid * e)))
                        if np.abs(_euler_change(a_ant, qm)).max() <= w_ax:
                            lo = mid
                        else:
                            hi = mid
                    q_new = quat_normalize(quat_mult(q_ant, quat_from_rotvec(lo * e)))
                    step = _euler_change(a_ant, q_new)
            out_rot[k] = rotvec_from_quat(quat_mult(quat_conj(q_ant), q_new))
            out_step[k] = step
            q_ant = q_new
        out_q[k] = q_ant
        pa, ra, ya = _patent_angles(q_ant)
        out_d[k, 0] = _wrap_pi(pa - a_nav[0])
        out_d[k, 1] = _wrap_pi(ra - a_nav[1])
        out_d[k, 2] = _wrap_pi(ya - a_nav[2])
    return out_q, out_d, out_step, out_rot, out_w


@dataclass
class DualResult:
    """Output of :func:`dual_quaternion_track` (per interrupt).

    q_ant (N, 4) antenna-control quaternion; diff (N, 3) Euler differences q_ant − q_nav after the command,
    patent order [pitch, roll, yaw=−heading] [rad]; step (N, 3) Euler change applied by the command (platform
    sense, + = the antenna angle decreased) [rad]; cmd_rotvec (N, 3) the command as a body-frame rotation
    vector (q_ant ← q_ant ⊗ q(cmd_rotvec)) [rad], its norm the total change of the antenna attitude beyond
    the vehicle motion; w (N,) the total command rate [rad/s] (its share on element k is w·|e_k|/|e|).
    """

    q_ant: np.ndarray
    diff: np.ndarray
    step: np.ndarray
    cmd_rotvec: np.ndarray
    w: np.ndarray


def dual_quaternion_track(nav: NavRun, t_f: float = 1.0, w_max: float = 0.5 * DEG,
                          margin: float = 1.0) -> DualResult:
    """Antenna-control quaternion chasing the navigation quaternion (§4.2, claims 1–2, issue 27).

    nav : :class:`NavRun`; t_f : filter period T_f [s]; w_max : largest pointing-error rate the antenna
    tolerates [rad/s], a bound on the **total** change of the antenna attitude per interrupt beyond the
    vehicle motion (and on each Euler angle's); margin (≥ 1) : the latched rate is margin·|e|/T_f (the
    patent asks for "at least" |d|/T_f; 1 closes a difference exactly in T_f). The command follows the
    geodesic from q_ant to q_nav, so the rate is shared between the axes in proportion to their remaining
    differences and all of them close together (``docs/seed_003_closing_times.md``); a single-axis
    difference is chased exactly as by the per-axis rule. See the module docstring.
    """
    if margin < 1.0:
        raise ValueError("margin must be >= 1 (the rate is at least |d|/T_f)")
    if not (t_f > 0 and w_max > 0):
        raise ValueError("t_f and w_max must be > 0")
    q_nav = np.ascontiguousarray(nav.state[:, 6:10])
    r = _dual_kernel(np.asarray(nav.q0, float), np.ascontiguousarray(nav.dtheta),
                     np.ascontiguousarray(nav.dt), q_nav, np.ascontiguousarray(nav.corrected, dtype=np.bool_),
                     float(t_f), float(w_max), float(margin))
    return DualResult(*r)

# ====================================================================================== reference chase
def reference_chase(heading_deg: float = 100.0, yaw_rate_deg_s: float = 5.0, dt: float = 0.01,
                    t_f: float = 1.0, w_max_deg_s: float = 0.5, correction_rph_deg=(0.3, -0.5, 2.0),
                    t_correction: float = 1.0, duration: float = 8.0, margin: float = 1.0) -> dict:
    """The reference chase run of §4.5.

    A level vehicle at ``heading_deg`` yaws at ``yaw_rate_deg_s`` (heading increasing); every interrupt
    (``dt``) both quaternions get the same ΔΘ; at ``t_correction`` the navigation quaternion is corrected by
    (roll, pitch, heading) = ``correction_rph_deg`` (a filter correction). Returns arrays (time, nav and
    antenna Euler angles, differences [deg]) and the metrics: ``close_time_s`` (per axis: time after the
    correction at which the difference first reaches 0), ``max_step_deg`` (per axis: largest Euler change of
    the antenna per interrupt beyond the gyro-propagated motion), ``max_rot_deg`` (largest total command
    rotation per interrupt) and ``identity_before_rad`` (largest angle between q_ant and q_nav before the
    correction).
    """
    n = int(round(duration / dt))
    t = (np.arange(n) + 1) * dt
    dth = np.zeros((n, 3))
    dth[:, 2] = -yaw_rate_deg_s * DEG * dt  # heading (clockwise) increases: rotation about body z is negative
    q0 = quat_from_euler(0.0, 0.0, heading_deg * DEG)
    q = q0.copy()
    state = np.zeros((n, 10))
    corrected = np.zeros(n, bool)
    kc = int(round(t_correction / dt)) - 1
    for k in range(n):
        q = quat_normalize(quat_mult(q, quat_from_rotvec(dth[k])))
        if k == kc:
            r, p, hd = euler_from_quat(q)
            c = np.asarray(correction_rph_deg, float) * DEG
            q = quat_from_euler(r + c[0], p + c[1], hd + c[2])
            corrected[k] = True
        state[k, 6:10] = q
    nav = NavRun(time=t, state=state, dtheta=dth, dt=np.full(n, dt), corrected=corrected, q0=q0, t0=0.0,
                 label="chase")
    res = dual_quaternion_track(nav, t_f=t_f, w_max=w_max_deg_s * DEG, margin=margin)
    diff = np.degrees(res.diff)  # pitch, roll, yaw(=-heading)
    close = []
    for i in range(3):
        after = np.flatnonzero((np.abs(diff[:, i]) < 1e-9) & (np.arange(n) >= kc))
        close.append(float(t[after[0]] - t[kc]) if len(after) else float("nan"))
    ident = max((quat_angle_between(res.q_ant[k], state[k, 6:10]) for k in range(kc)), default=0.0)
    rot = np.degrees(np.linalg.norm(res.cmd_rotvec, axis=1))
    eul_nav = np.degrees(np.array([euler_from_quat(state[k, 6:10]) for k in range(n)]))
    eul_ant = np.degrees(np.array([euler_from_quat(res.q_ant[k]) for k in range(n)]))
    return {"time": t, "t_correction": float(t[kc]), "nav_rph_deg": eul_nav, "ant_rph_deg": eul_ant,
            "diff_deg": diff, "step_deg": np.degrees(res.step),
            "close_time_s": {"pitch": close[0], "roll": close[1], "heading": close[2]},
            "max_step_deg": {"pitch": float(np.abs(np.degrees(res.step[:, 0])).max()),
                             "roll": float(np.abs(np.degrees(res.step[:, 1])).max()),
                             "heading": float(np.abs(np.degrees(res.step[:, 2])).max())},
            "max_rot_deg": float(rot.max()), "identity_before_rad": float(ident)}
