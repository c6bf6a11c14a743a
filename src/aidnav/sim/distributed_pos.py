"""Airborne distributed POS (seed 004, §5): master POS output and a wing-mounted sub-IMU.

Frames and units (``docs/conventions.md``): n = ENU, b = RFU; radians, metres, seconds inside; the
boundary specs carry their units in their names (``*_deg``, ``*_m``, ``*_s``). ``b_m`` is the master
body frame, ``b_s`` the sub-IMU body frame.

**Master POS output** (:func:`simulate_master_pos`): the truth at the filter rate plus white errors of
the POS/AV610 real-time accuracies (§5.1: roll and pitch 0.005°, heading 0.02°, velocity
0.03 m/s, horizontal position 0.1 m, height 0.2 m, 1σ), or the GNSS-baseline variants of seed
Table 7 (:meth:`MasterPosSpec.for_gnss_baseline`). Euler-angle errors are added to the true roll,
pitch and heading; the same unit-variance draws are used whatever the σ (common random numbers).
The master's angular rate ω_ib^bm (for the lever-arm compensation of its velocity) is its own IMU's,
taken error-free: its errors (≲ 0.01°/h) are far below anything the transfer alignment can see.

**Sub-IMU** (:func:`simulate_sub_imu`), at the lever arm r^bm (default [5, 0.1, 0.1] m) with a fixed
mounting misalignment ρ (default 0.5° per axis) and a wing flexure angle θ(t):

* attitude: C_bs^bm = exp(−[(ρ + θ)×]) (§5.1 item 10, exact rotation), so that
  C_bs^n = C_bm^n C_bs^bm ≈ (I − [C_bm^n(ρ+θ)×]) C_bm^n;
* gyro increments: Δθ_s = rotvec(C_bm^bs(t_{k−1}) · exp([Δθ_m×]) · C_bs^bm(t_k)), the exact body
  attitude change over the interval, i.e. the master rate rotated into b_s plus the flexure rate;
* accelerometer increments: Δv_s = C_bm^bs(t_mid)·(Δv_m + (ω̇×r + ω×(ω×r))·Δt − ΔG·Δt), with
  ω = ω_ib^bm (see :func:`lever_arm_increment`) and ΔG the difference of the gravitational
  acceleration between the two points (WGS-84 normal gravity at each point plus the centrifugal
  difference; ≈ 0.8 µg here);
* position r_s = r_m + C_bm^n r (exact, through ECEF), velocity v_s = v_m + C_bm^n (ω_eb^bm × r),
  both in the sub's own ENU frame n_s (the two ENU frames differ by |r|/R ≈ 8e-7 rad; the truth
  accounts for it, the filter takes them equal as §5.1 does);
* sensor errors: :func:`aidnav.sim.imu.corrupt_imu` with an :class:`~aidnav.sim.imu.ImuSpec` (seed
  Table 1 grades ``seed004_high/medium/low``, and the §3.1 sub-IMU ``seed004_sub``, the default).

**Flexure** (:func:`simulate_flexure`): per body axis J a second-order Gauss-Markov process
θ̈ + 2βθ̇ + β²θ = η with β = 2.146/τ and PSD Q_η = 4β³σ² (§5.1 items 6–7), so that
var θ = σ², var θ̇ = β²σ², R(t) = σ²(1 + β|t|)e^{−β|t|} and R(τ) = σ²/e. Discretised exactly:
the transition matrix of the critically damped 2×2 system is
Φ(t) = e^{−βt}[[1 + βt, t], [−β²t, 1 − βt]] (the matrix exponential of [[0, 1], [−β², −2β]]·t)
and, the process being stationary, Qd = P∞ − Φ P∞ Φᵀ with P∞ = diag(σ², β²σ²), which equals the
exact integral ∫Φ(s) [0, 1]ᵀ Q_η [0, 1] Φ(s)ᵀ ds (checked against Van Loan's method in the tests).
The process starts from its stationary distribution. Defaults τ_x = τ_z = 2 s, τ_y = 5 s,
σ_x = σ_z = 0.01°, σ_y = 0.15°.

Random streams: a run seed (int or ``numpy.random.SeedSequence``) gives three children, in this order:
flexure, sub-IMU errors, master POS errors; the children are derived without mutating the parent, so
the same seed gives the same draws whatever else changes (common random numbers across cases).
:func:`simulate_distributed_pos` draws the white and driving noises per flight segment instead
(:mod:`aidnav.sim.segment_noise`): common random numbers across trajectory variants too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from aidnav.data import ImuData, Trajectory
from aidnav.jit import njit
from aidnav.models.distributed_pos import (  # noqa: F401  (re-exported: the shared error model)
    BETA_FACTOR,
    GNSS_BASELINE_ACCURACY_M,
    FlexureSpec,
    MasterPosSpec,
    flexure_autocorrelation,
    flexure_transition,
)
from aidnav.nav.earth import OMEGA_IE, dcm_ecef_to_enu, ecef_to_lla, gravity, lla_to_ecef, radii
from aidnav.nav.rotations import (
    dcm_from_euler,
    euler_error_map,  # noqa: F401  (re-exported)
    euler_from_dcm,
    rotvec_from_dcm,
    wrap_2pi,
)
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.segment_noise import segment_normals
from aidnav.units import DEG

__all__ = [
    "BETA_FACTOR", "GNSS_BASELINE_ACCURACY_M", "MasterPosSpec", "FlexureSpec", "DistributedPosConfig",
    "MasterPosOutput", "SubImuOutput", "DistributedPosRun", "flexure_transition", "simulate_flexure",
    "second_order_markov",
    "flexure_autocorrelation", "lever_arm_acceleration", "lever_arm_increment", "simulate_master_pos",
    "simulate_sub_imu", "simulate_distributed_pos", "run_streams", "euler_error_map", "SubGeometry",
    "sub_geometry",
]

@dataclass(frozen=True)
class DistributedPosConfig:
    """A distributed POS: lever arm r^bm [m] (master body RFU), mounting misalignment ρ [deg] per axis
    (fixed, the truth), flexure, sub-IMU error spec and master POS accuracy."""

    lever_arm_m: tuple[float, float, float] = (5.0, 0.1, 0.1)
    mounting_deg: tuple[float, float, float] = (0.5, 0.5, 0.5)
    flexure: FlexureSpec = field(default_factory=FlexureSpec)
    sub_imu: ImuSpec = field(default_factory=lambda: ImuSpec.grade("seed004_sub"))
    master: MasterPosSpec = field(default_factory=MasterPosSpec)

    @property
    def lever_arm(self) -> np.ndarray:
        return np.asarray(self.lever_arm_m, float)

    @property
    def mounting(self) -> np.ndarray:
        """ρ [rad]."""
        return np.asarray(self.mounting_deg, float) * DEG


# --------------------------------------------------------------------------------------- flexure
@njit(cache=True)
def _flexure_kernel(phi, lch, z, x0, theta, theta_dot):
    """x_{k+1} = Φ x_k + L z_k per axis; theta/theta_dot (n+1, 3) filled from x0 (3, 2)."""
    n = z.shape[0]
    for a in range(3):
        t0 = x0[a, 0]
        t1 = x0[a, 1]
        theta[0, a] = t0
        theta_dot[0, a] = t1
        for k in range(n):
            w0 = lch[a, 0, 0] * z[k, a, 0]
            w1 = lch[a, 1, 0] * z[k, a, 0] + lch[a, 1, 1] * z[k, a, 1]
            n0 = phi[a, 0, 0] * t0 + phi[a, 0, 1] * t1 + w0
            n1 = phi[a, 1, 0] * t0 + phi[a, 1, 1] * t1 + w1
            t0 = n0
            t1 = n1
            theta[k + 1, a] = t0
            theta_dot[k + 1, a] = t1


def second_order_markov(sigma, tau, dt: float, n: int, rng: np.random.Generator | None,
                        normals=None) -> tuple[np.ndarray, np.ndarray]:
    """Second-order Gauss-Markov processes x (and ẋ), one per entry of ``sigma``/``tau`` (3 each, any unit
    of x per σ; τ [s] the 1/e correlation time, β = 2.146/τ), sampled at t = 0, dt, …, n·dt [s]: arrays
    (n+1, 3) each. Exact discretisation (:func:`flexure_transition`), stationary start. Draws: 6 normals
    for the start, then (n, 3, 2) normals; or ``normals`` = (z0 (3, 2), z (n, 3, 2)) given (``rng`` unused).
    """
    sigma = np.asarray(sigma, float)
    beta = BETA_FACTOR / np.asarray(tau, float)
    phi = np.empty((3, 2, 2))
    lch = np.zeros((3, 2, 2))
    x0 = np.empty((3, 2))
    z0 = rng.standard_normal((3, 2)) if normals is None else np.asarray(normals[0], float)
    for a in range(3):
        phi[a], qd = flexure_transition(beta[a], sigma[a], dt)
        if sigma[a] > 0:
            lch[a] = np.linalg.cholesky(qd)
        x0[a] = [sigma[a] * z0[a, 0], beta[a] * sigma[a] * z0[a, 1]]
    z = rng.standard_normal((int(n), 3, 2)) if normals is None else np.ascontiguousarray(normals[1], float)
    x = np.empty((int(n) + 1, 3))
    x_dot = np.empty((int(n) + 1, 3))
    _flexure_kernel(phi, lch, z, x0, x, x_dot)
    return x, x_dot


def simulate_flexure(spec: FlexureSpec, dt: float, n: int, rng: np.random.Generator | None,
                     normals=None) -> tuple[np.ndarray, np.ndarray]:
    """Flexure angle θ [rad] and rate θ̇ [rad/s], (n+1, 3) each at t = 0, dt, …, n·dt [s]
    (:func:`second_order_markov` with the spec's σ and τ; ``normals`` as there)."""
    return second_order_markov(spec.sigma, spec.tau, dt, n, rng, normals)


# -------------------------------------------------------------------------------------- lever arm
@njit(cache=True)
def lever_arm_acceleration(w, wdot, r):
    """ω̇ × r + ω × (ω × r) [m/s²] for rates ω [rad/s], ω̇ [rad/s²] and lever arm r [m] (length-3)."""
    wr = np.array([w[1] * r[2] - w[2] * r[1], w[2] * r[0] - w[0] * r[2], w[0] * r[1] - w[1] * r[0]])
    out = np.empty(3)
    out[0] = wdot[1] * r[2] - wdot[2] * r[1] + w[1] * wr[2] - w[2] * wr[1]
    out[1] = wdot[2] * r[0] - wdot[0] * r[2] + w[2] * wr[0] - w[0] * wr[2]
    out[2] = wdot[0] * r[1] - wdot[1] * r[0] + w[0] * wr[1] - w[1] * wr[0]
    return out


@njit(cache=True)
def _rates_at_points(dth, dt):
    """ω_ib [rad/s] at the sample points t_0..t_N from increments over (t_{k−1}, t_k] (N, 3).

    The increments are interval means ω̄ = Δθ/Δt; point values are reconstructed from them as from
    cell averages: fourth order inside, ω(t_k) = (−ω̄_{k−1} + 7ω̄_k + 7ω̄_{k+1} − ω̄_{k+2})/12 (ω̄_k the
    mean over the interval ending at t_k), third order at and next to the two ends (one-sided
    (11, −7, 2)/6 and (2, 5, −1)/6). Fewer than three intervals: means and their average.
    """
    n = dth.shape[0]
    w = np.empty((n + 1, 3))
    for i in range(3):
        if n < 3:
            w[0, i] = dth[0, i] / dt
            w[n, i] = dth[n - 1, i] / dt
            if n == 2:
                w[1, i] = 0.5 * (dth[0, i] + dth[1, i]) / dt
            continue
        for k in range(2, n - 1):
            w[k, i] = (-dth[k - 2, i] + 7.0 * dth[k - 1, i] + 7.0 * dth[k, i] - dth[k + 1, i]) / (12.0 * dt)
        w[0, i] = (11.0 * dth[0, i] - 7.0 * dth[1, i] + 2.0 * dth[2, i]) / (6.0 * dt)
        w[1, i] = (2.0 * dth[0, i] + 5.0 * dth[1, i] - dth[2, i]) / (6.0 * dt)
        w[n - 1, i] = (-dth[n - 3, i] + 5.0 * dth[n - 2, i] + 2.0 * dth[n - 1, i]) / (6.0 * dt)
        w[n, i] = (2.0 * dth[n - 3, i] - 7.0 * dth[n - 2, i] + 11.0 * dth[n - 1, i]) / (6.0 * dt)
    return w


@njit(cache=True)
def lever_arm_increment(dth, dt, r):
    """Velocity increments [m/s] (N, 3) of the lever-arm acceleration ω̇×r + ω×(ω×r) over each interval.

    dth (N, 3): body angle increments Δθ = ∫ω_ib dt [rad] over (t_{k−1}, t_k] of a uniform grid ``dt``
    [s]; r (3,) [m] in the same body frame. ∫ω̇ dt = ω(t_k) − ω(t_{k−1}) with ω at the points from
    :func:`_rates_at_points` (fourth order inside), and ∫ω×(ω×r) dt ≈ Δt·ω̄×(ω̄×r) with ω̄ = Δθ/Δt
    (error O(Δt³) per interval).
    """
    n = dth.shape[0]
    wp = _rates_at_points(dth, dt)
    out = np.empty((n, 3))
    zero = np.zeros(3)
    for k in range(n):
        wm = dth[k] / dt
        dw = wp[k + 1] - wp[k]
        a_c = lever_arm_acceleration(wm, zero, r)
        a_t = lever_arm_acceleration(zero, dw, r)
        for i in range(3):
            out[k, i] = a_c[i] * dt + a_t[i]
    return out


# ------------------------------------------------------------------------------------- sub-IMU
@njit(cache=True)
def _gravity_ecef(lat, lon, h):
    """Normal gravity vector [m/s²] in ECEF at (lat, lon, h) (down the ellipsoid normal)."""
    c = dcm_ecef_to_enu(lat, lon)
    g = gravity(lat, h)
    return np.array([-g * c[2, 0], -g * c[2, 1], -g * c[2, 2]])


@njit(cache=True)
def _geometry_kernel(lat, lon, hgt, vel, rph, dth_m, dv_m, dt, r):
    """Flexure-independent part of the sub-IMU: its position, velocity, C_bm^n, C_nm^ns at the N+1 points
    and the master increments plus lever-arm and gravitational-difference terms over the N intervals."""
    n = dth_m.shape[0]
    npt = n + 1
    s_lat = np.empty(npt)
    s_lon = np.empty(npt)
    s_h = np.empty(npt)
    s_vel = np.empty((npt, 3))
    c_m = np.empty((npt, 3, 3))
    c_ms = np.empty((npt, 3, 3))
    dg_b = np.empty((npt, 3))  # gravitational difference in b_m [m/s²]
    wp = _rates_at_points(dth_m, dt)
    for k in range(npt):
        cm = dcm_from_euler(rph[k, 0], rph[k, 1], rph[k, 2])
        c_m[k] = cm
        cen_m = dcm_ecef_to_enu(lat[k], lon[k])  # C_e^nm
        x, y, z = lla_to_ecef(lat[k], lon[k], hgt[k])
        dn = cm @ r
        de = cen_m.T @ dn
        la, lo, hh = ecef_to_lla(x + de[0], y + de[1], z + de[2])
        s_lat[k], s_lon[k], s_h[k] = la, lo, hh
        cen_s = dcm_ecef_to_enu(la, lo)
        cms = cen_s @ cen_m.T  # C_nm^ns
        c_ms[k] = cms
        # velocity: v_m + C_bm^n (ω_eb^bm × r), in n_s
        w_ie_n = np.array([0.0, OMEGA_IE * np.cos(lat[k]), OMEGA_IE * np.sin(lat[k])])
        w_eb = wp[k] - cm.T @ w_ie_n
        wxr = np.array([w_eb[1] * r[2] - w_eb[2] * r[1], w_eb[2] * r[0] - w_eb[0] * r[2],
                        w_eb[0] * r[1] - w_eb[1] * r[0]])
        s_vel[k] = cms @ (vel[k] + cm @ wxr)
        # gravitational acceleration difference G_s − G_m = g_s − g_m + Ω×(Ω×(R_s − R_m)), into b_m
        gs = _gravity_ecef(la, lo, hh)
        gm = _gravity_ecef(lat[k], lon[k], hgt[k])
        cent = np.array([-OMEGA_IE * OMEGA_IE * de[0], -OMEGA_IE * OMEGA_IE * de[1], 0.0])
        dg_b[k] = cm.T @ (cen_m @ (gs - gm + cent))
    lev = lever_arm_increment(dth_m, dt, r)
    dvb = np.empty((n, 3))
    for k in range(n):
        for i in range(3):
            dvb[k, i] = dv_m[k, i] + lev[k, i] - 0.5 * (dg_b[k, i] + dg_b[k + 1, i]) * dt
    return s_lat, s_lon, s_h, s_vel, c_m, c_ms, dvb


@njit(cache=True, inline="always")
def _rv2dcm(x, y, z, c):
    """c ← exp([r×]) for r = (x, y, z) (Rodrigues; series below 1e-4 rad), no allocation."""
    a2 = x * x + y * y + z * z
    if a2 < 1e-8:
        s = 1.0 - a2 / 6.0
        k = 0.5 - a2 / 24.0
    else:
        a = np.sqrt(a2)
        s = np.sin(a) / a
        k = (1.0 - np.cos(a)) / a2
    c[0, 0] = 1.0 - k * (y * y + z * z)
    c[1, 1] = 1.0 - k * (x * x + z * z)
    c[2, 2] = 1.0 - k * (x * x + y * y)
    c[0, 1] = -s * z + k * x * y
    c[1, 0] = s * z + k * x * y
    c[0, 2] = s * y + k * x * z
    c[2, 0] = -s * y + k * x * z
    c[1, 2] = -s * x + k * y * z
    c[2, 1] = s * x + k * y * z


@njit(cache=True, inline="always")
def _mm(a, b, out):
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


@njit(cache=True, inline="always")
def _mtm(a, b, out):
    """out = aᵀ b."""
    for i in range(3):
        for j in range(3):
            out[i, j] = a[0, i] * b[0, j] + a[1, i] * b[1, j] + a[2, i] * b[2, j]


@njit(cache=True)
def _sub_run_kernel(c_m, c_ms, dth_m, dvb, rho, theta):
    """Flexure-dependent part: sub increments (N, 3) ×2 and the sub truth roll, pitch, heading (N+1, 3)."""
    n = dth_m.shape[0]
    dth_s = np.empty((n, 3))
    dv_s = np.empty((n, 3))
    rph = np.empty((n + 1, 3))
    c0 = np.empty((3, 3))  # C_bs^bm at t_{k}
    c1 = np.empty((3, 3))
    cd = np.empty((3, 3))
    t1 = np.empty((3, 3))
    t2 = np.empty((3, 3))
    for k in range(n + 1):
        _rv2dcm(-(rho[0] + theta[k, 0]), -(rho[1] + theta[k, 1]), -(rho[2] + theta[k, 2]), c1)
        # attitude C_bs^ns = C_nm^ns C_bm^nm C_bs^bm
        _mm(c_m[k], c1, t1)
        _mm(c_ms[k], t1, t2)
        ro, pi, he = euler_from_dcm(t2)
        rph[k, 0], rph[k, 1], rph[k, 2] = ro, pi, he
        if k > 0:
            j = k - 1
            # C_bs(k)^bs(k−1) = C_bm^bs(k−1) exp([Δθ_m×]) C_bs^bm(k)
            _rv2dcm(dth_m[j, 0], dth_m[j, 1], dth_m[j, 2], cd)
            _mtm(c0, cd, t1)
            _mm(t1, c1, t2)
            rv = rotvec_from_dcm(t2)
            dth_s[j, 0], dth_s[j, 1], dth_s[j, 2] = rv[0], rv[1], rv[2]
            _rv2dcm(-(rho[0] + 0.5 * (theta[j, 0] + theta[k, 0])),
                    -(rho[1] + 0.5 * (theta[j, 1] + theta[k, 1])),
                    -(rho[2] + 0.5 * (theta[j, 2] + theta[k, 2])), cd)
            for i in range(3):
                dv_s[j, i] = cd[0, i] * dvb[j, 0] + cd[1, i] * dvb[j, 1] + cd[2, i] * dvb[j, 2]
        for a in range(3):
            for b in range(3):
                c0[a, b] = c1[a, b]
    return dth_s, dv_s, rph


@dataclass
class SubGeometry:
    """Flexure-independent part of a sub-IMU simulation for one master truth (reuse it across runs).

    lat, lon [rad], height [m], vel (N+1, 3) [m/s]: sub truth position and velocity (in n_s);
    c_m (N+1, 3, 3) C_bm^n; c_ms (N+1, 3, 3) C_nm^ns; dvb (N, 3) master Δv plus lever-arm and
    gravitational-difference increments in b_m [m/s]; lever_arm (3,) [m]; dt [s].
    """

    lat: np.ndarray
    lon: np.ndarray
    height: np.ndarray
    vel: np.ndarray
    c_m: np.ndarray
    c_ms: np.ndarray
    dvb: np.ndarray
    lever_arm: np.ndarray
    dt: float


def sub_geometry(truth: Trajectory, imu: ImuData, lever_arm) -> SubGeometry:
    """Compute the :class:`SubGeometry` of a master ``truth`` (N+1 points) and its increments (N)."""
    dt = _uniform_dt(imu)
    n = len(imu)
    if len(truth.time) != n + 1:
        raise ValueError("sub_geometry: truth must have one more point than the IMU has samples")
    r = np.asarray(lever_arm, float)
    s_lat, s_lon, s_h, s_vel, c_m, c_ms, dvb = _geometry_kernel(
        truth.lat, truth.lon, truth.height, np.ascontiguousarray(truth.vel), np.ascontiguousarray(truth.rph),
        imu.dtheta, imu.dv, dt, r)
    return SubGeometry(s_lat, s_lon, s_h, s_vel, c_m, c_ms, dvb, r, dt)


# ---------------------------------------------------------------------------------------- outputs
@dataclass
class MasterPosOutput:
    """Master POS output at the filter epochs.

    time (M,) [s]; index (M,) truth sample index of each epoch; lat, lon [rad], height [m] (M,);
    vel (M, 3) ENU [m/s]; rph (M, 3) roll, pitch, heading [rad]; w_ib (M, 3) master body rate ω_ib^bm
    [rad/s] (error-free IMU); spec: the :class:`MasterPosSpec` used.
    """

    time: np.ndarray
    index: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    height: np.ndarray
    vel: np.ndarray
    rph: np.ndarray
    w_ib: np.ndarray
    spec: MasterPosSpec


@dataclass
class SubImuOutput:
    """Sub-IMU simulation: truth (:class:`~aidnav.data.Trajectory` at the IMU points), error-free and
    corrupted increments (:class:`~aidnav.data.ImuData`), flexure θ, θ̇ (N+1, 3) [rad, rad/s] at the
    points, mounting ρ (3,) [rad], lever arm r (3,) [m] and the realised IMU error constants
    (:func:`~aidnav.sim.imu.corrupt_imu`)."""

    truth: Trajectory
    imu_true: ImuData
    imu: ImuData
    theta: np.ndarray
    theta_dot: np.ndarray
    rho: np.ndarray
    lever_arm: np.ndarray
    imu_errors: dict


@dataclass
class DistributedPosRun:
    """One simulated run: master truth/IMU and segment table (from
    :func:`aidnav.sim.trajectory.generate_truth`), the sub-IMU and the master POS output."""

    master_truth: Trajectory
    master_imu: ImuData
    segments: list[dict]
    sub: SubImuOutput
    master: MasterPosOutput
    config: DistributedPosConfig


def _uniform_dt(imu: ImuData) -> float:
    dt = np.diff(np.concatenate(([imu.t0], imu.time)))
    d = float(np.median(dt))
    if np.max(np.abs(dt - d)) > 1e-9 * max(1.0, d):
        raise ValueError("distributed_pos: the IMU grid must be uniform")
    return d


def run_streams(seed) -> list[np.random.SeedSequence]:
    """The three child seed sequences (flexure, sub-IMU errors, master errors) of a run ``seed``
    (int or SeedSequence), derived without mutating ``seed``."""
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(int(seed))
    return [np.random.SeedSequence(ss.entropy, spawn_key=tuple(ss.spawn_key) + (i,)) for i in range(3)]


def simulate_master_pos(truth: Trajectory, imu: ImuData, spec: MasterPosSpec,
                        rng: np.random.Generator | None, normals=None) -> MasterPosOutput:
    """Master POS output at ``spec.rate_hz`` (epochs at multiples of the period from the truth start).

    truth, imu: master truth and error-free increments on a uniform grid (from ``generate_truth``).
    Draws, fixed order: (M, 3) attitude, (M, 3) velocity, (M, 3) position unit normals (made
    Gauss-Markov, stationary from the first epoch, when ``spec.corr_time_s`` > 0), then the position
    drift's draws (:func:`second_order_markov`; see :class:`MasterPosSpec`). Or ``normals`` given
    (``rng`` unused): (z (M, 9) attitude|velocity|position, drift start (3, 2), drift (M-1, 3, 2)).
    """
    dt = float(truth.time[1] - truth.time[0])
    ratio = int(round(1.0 / (spec.rate_hz * dt)))
    if ratio < 1 or abs(ratio * dt * spec.rate_hz - 1.0) > 1e-9:
        raise ValueError("simulate_master_pos: the output period must be a multiple of the IMU interval")
    idx = np.arange(0, len(truth.time), ratio)
    m = len(idx)
    if normals is None:
        za, zv, zp = (rng.standard_normal((m, 3)) for _ in range(3))
    else:
        z = np.array(normals[0], float)
        za, zv, zp = z[:, 0:3], z[:, 3:6], z[:, 6:9]
    if spec.corr_time_s > 0:
        a = math.exp(-ratio * dt / spec.corr_time_s)
        b = math.sqrt(1.0 - a * a)
        for z in (za, zv, zp):
            for k in range(1, m):
                z[k] = a * z[k - 1] + b * z[k]
    rph = truth.rph[idx] + za * spec.att_sigma_rad
    rph[:, 2] = wrap_2pi(rph[:, 2])
    drift, drift_rate = second_order_markov(spec.pos_drift_sigma_m, np.full(3, spec.pos_drift_tau_s),
                                            ratio * dt, m - 1, rng, None if normals is None else normals[1:])
    vel = truth.vel[idx] + zv * spec.sigma_vel_m_s + drift_rate
    lat, h = truth.lat[idx], truth.height[idx]
    rm, rn = radii(lat)
    dp = zp * (spec.pos_sigma_m * math.sqrt(1.0 - spec.pos_drift_fraction)) + drift
    w = _rates_at_points(imu.dtheta, dt)[idx]
    return MasterPosOutput(time=truth.time[idx].copy(), index=idx, lat=lat + dp[:, 1] / (rm + h),
                           lon=truth.lon[idx] + dp[:, 0] / ((rn + h) * np.cos(lat)), height=h + dp[:, 2],
                           vel=vel, rph=rph, w_ib=w, spec=spec)


def simulate_sub_imu(truth: Trajectory, imu: ImuData, cfg: DistributedPosConfig,
                     rng_flex: np.random.Generator | None, rng_imu: np.random.Generator,
                     geometry: SubGeometry | None = None, normals=None) -> SubImuOutput:
    """Sub-IMU truth and increments for a master truth trajectory and its error-free increments.

    ``truth`` must hold the points t_0..t_N of the N intervals of ``imu`` (as ``generate_truth`` gives).
    ``geometry``: :func:`sub_geometry` of this truth and ``cfg.lever_arm`` (computed when None).
    ``normals``: None (the flexure draws from ``rng_flex``, every IMU error from ``rng_imu``) or
    (flexure start (3, 2), flexure (N, 3, 2), IMU white noise (N, 6) gyro|accel): the white noise is then
    added from these (exactly as :func:`~aidnav.sim.imu.corrupt_imu` adds it, which needs no
    quantisation), the turn-on errors still from ``rng_imu``.
    """
    geo = geometry if geometry is not None else sub_geometry(truth, imu, cfg.lever_arm)
    if not np.array_equal(geo.lever_arm, cfg.lever_arm) or len(geo.lat) != len(truth.time):
        raise ValueError("simulate_sub_imu: geometry was computed for another truth or lever arm")
    n = len(imu)
    theta, theta_dot = simulate_flexure(cfg.flexure, geo.dt, n, rng_flex, None if normals is None
                                        else normals[:2])
    rho = cfg.mounting
    dth_s, dv_s, s_rph = _sub_run_kernel(geo.c_m, geo.c_ms, imu.dtheta, geo.dvb, rho, theta)
    sub_truth = Trajectory(time=truth.time.copy(), lat=geo.lat, lon=geo.lon, height=geo.height, vel=geo.vel,
                           rph=s_rph)
    imu_true = ImuData(imu.time.copy(), dth_s, dv_s, t0=imu.t0)
    spec = cfg.sub_imu
    if normals is None:
        imu_c, realised = corrupt_imu(imu_true, spec, rng_imu)
    else:
        if spec.gyro_quant > 0 or spec.accel_quant > 0:
            raise ValueError("simulate_sub_imu: keyed white noise needs an IMU spec without quantisation")
        imu_c, realised = corrupt_imu(imu_true, replace(spec, gyro_arw=np.zeros(3), accel_vrw=np.zeros(3)),
                                      rng_imu)
        sh = np.sqrt(geo.dt)
        imu_c.dtheta[:] += spec.gyro_arw * sh * normals[2][:, :3]
        imu_c.dv[:] += spec.accel_vrw * sh * normals[2][:, 3:]
    return SubImuOutput(truth=sub_truth, imu_true=imu_true, imu=imu_c, theta=theta, theta_dot=theta_dot,
                        rho=rho, lever_arm=geo.lever_arm, imu_errors=realised)


def simulate_distributed_pos(scn_or_truth, cfg: DistributedPosConfig | None = None, seed=1,
                             geometry: SubGeometry | None = None) -> DistributedPosRun:
    """Simulate one run of a distributed POS.

    scn_or_truth: a :class:`~aidnav.sim.scenario.Scenario`, or the tuple ``(truth, imu, segments)``
    that :func:`aidnav.sim.trajectory.generate_truth` returns (pass it to reuse one truth for many
    runs). cfg: :class:`DistributedPosConfig` (default: seed §3.1). seed: int or SeedSequence
    (see :func:`run_streams`). geometry: :func:`sub_geometry` of this truth (reused across runs).

    Common random numbers across trajectory variants: the flexure, the sub-IMU white noise and every
    master error are drawn per flight segment (:func:`aidnav.sim.segment_noise.segment_normals`), so two
    variants flying a segment of the same name get the same noise on it over the time they share (a
    leg inserted or lengthened shifts nothing after it); the sub-IMU's turn-on errors come from the
    run's sub-IMU stream (:func:`run_streams`).
    """
    cfg = cfg or DistributedPosConfig()
    if isinstance(scn_or_truth, tuple):
        truth, imu, segments = scn_or_truth
    else:
        from aidnav.sim.trajectory import generate_truth  # lazy: pulls in pydantic, yaml

        truth, imu, segments = generate_truth(scn_or_truth)
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(int(seed))
    _, s_imu, _ = run_streams(ss)
    dt = _uniform_dt(imu)
    ratio = int(round(1.0 / (cfg.master.rate_hz * dt)))
    t_m = truth.time[::ratio]
    flex = (segment_normals(ss, 10, [0.0], None, (3, 2))[0],
            segment_normals(ss, 11, imu.time, segments, (3, 2)),
            segment_normals(ss, 12, imu.time, segments, (6,)))
    sub = simulate_sub_imu(truth, imu, cfg, None, np.random.default_rng(s_imu), geometry, normals=flex)
    mst = (segment_normals(ss, 13, t_m, segments, (9,)), segment_normals(ss, 14, [0.0], None, (3, 2))[0],
           segment_normals(ss, 15, t_m[1:], segments, (3, 2)))
    master = simulate_master_pos(truth, imu, cfg.master, None, normals=mst)
    return DistributedPosRun(master_truth=truth, master_imu=imu, segments=segments, sub=sub, master=master,
                             config=cfg)
