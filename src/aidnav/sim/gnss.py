"""GNSS position/velocity receiver simulation from a truth trajectory (loosely coupled PV fixes).

Frames and units (``docs/conventions.md``): truth and output positions geodetic (lat, lon [rad], h [m],
WGS-84); velocities ENU [m/s]; lever arm in the body frame RFU [m] from the IMU to the antenna phase
centre; times [s] in the truth's time scale.

How a fix is made (:func:`simulate_gnss`):

1. **Fix times** are the tags t_j = t_start + j / rate_hz, j = 1, 2, ... (t_start itself excluded; computed
   as j/rate, not accumulated) up to the truth's last time.
2. **Latency**: the fix tagged t_j describes the antenna at t_j - latency_s (the receiver reports it late
   but stamps it with the reception time). Tags whose described time is before the truth's start are
   dropped (noted in ``events``).
3. **Outages** (start_s, duration_s), relative to t_start, remove every fix whose *tag* satisfies
   start_s <= t_j - t_start < start_s + duration_s; each outage is listed in ``events``.
4. **Truth interpolation** to the described time: position and velocity by cubic Hermite interpolation in
   ECEF (positions and their derivatives, the truth velocities, at the two neighbouring samples;
   4th-order in the sample spacing, exact at a sample), attitude by quaternion slerp between the
   neighbouring samples (exact at a sample). Non-uniform truth time steps are fine.
5. **Lever arm**, exact rigid-body kinematics in ECEF:
   r_ant^e = r^e + C_n^e C_b^n l^b and v_ant^e = v^e + C_n^e C_b^n (ω_eb^b × l^b), then converted to
   geodetic and to ENU at the antenna. ω_eb^b = ω_nb^b + C_n^b ω_en^n. ω_nb^b is, by default, the finite
   difference of the truth attitude (rotation vector of q_k* ⊗ q_{k+1} over Δt, a second-order estimate
   at the interval midpoint, then linearly interpolated / extrapolated to the fix time); or, when the
   true gyro rate ``omega_ib_b`` is passed, ω_eb^b = ω_ib^b - C_n^b ω_ie^n (linearly interpolated).
6. **Noise**: white Gaussian, independent per axis, σ = ``sigma_pos_enu`` [m] applied in ENU
   (converted to lat/lon with the radii R_M, R_N at the antenna) and ``sigma_vel_enu`` [m/s]; the
   ``std_pos``/``std_vel`` columns hold these σ. Noise is drawn for every tag before outages are removed
   (and always for velocity), so the same seed gives the same noise on the surviving fixes whatever
   the outages or the velocity option.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from aidnav.data import GnssData, Trajectory
from aidnav.jit import njit
from aidnav.nav.earth import OMEGA_IE, ecef_to_lla, lla_to_ecef, radii
from aidnav.nav.rotations import (
    dcm_from_quat,
    euler_to_quat_batch,
    quat_conj,
    quat_from_rotvec,
    quat_mult,
    rotvec_from_quat,
    wrap_pi,
)


def _vec3(x, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim == 0:
        a = np.full(3, float(a))
    elif a.shape == (2,):  # [horizontal, vertical]
        a = np.array([a[0], a[0], a[1]])
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"GnssSpec.{name}: expected a scalar, [horizontal, vertical] or 3 finite values")
    return a.copy()


def time_windows(items, name: str) -> list[tuple[float, float]]:
    """Time windows (outages, blockages) as a list of (start [s], duration [s]) from pairs or mappings
    {start_s, duration_s}; ValueError (naming ``name``) for unknown keys or a negative duration."""
    out = []
    for w in items:
        if isinstance(w, dict):
            bad = set(w) - {"start_s", "duration_s"}
            if bad:
                raise ValueError(f"{name}: unknown key(s) {', '.join(map(repr, sorted(bad)))}")
            w = (w["start_s"], w["duration_s"])
        start, dur = float(w[0]), float(w[1])
        if dur < 0:
            raise ValueError(f"{name}: duration_s must be >= 0")
        out.append((start, dur))
    return out


@dataclass
class GnssSpec:
    """GNSS position/velocity receiver model.

    rate_hz : fix rate [Hz].
    sigma_pos_enu : (3,) 1σ white position noise, East, North, Up [m] (scalar → all axes;
        [h, v] → [h, h, v]).
    sigma_vel_enu : (3,) 1σ white velocity noise, ENU [m/s] (same shorthands).
    lever_arm_b : (3,) IMU → antenna phase centre, body RFU [m].
    outages : list of (start_s, duration_s) [s], start relative to the truth's first time.
    latency_s : the fix tagged t describes the antenna at t - latency_s [s] (>= 0).
    velocity : also output ENU velocity (and its σ).
    """

    rate_hz: float = 1.0
    sigma_pos_enu: np.ndarray = field(default_factory=lambda: np.array([1.0, 1.0, 2.0]))
    sigma_vel_enu: np.ndarray = field(default_factory=lambda: np.array([0.05, 0.05, 0.1]))
    lever_arm_b: np.ndarray = field(default_factory=lambda: np.zeros(3))
    outages: list[tuple[float, float]] = field(default_factory=list)
    latency_s: float = 0.0
    velocity: bool = True

    def __post_init__(self):
        self.rate_hz = float(self.rate_hz)
        if not self.rate_hz > 0:
            raise ValueError("GnssSpec.rate_hz must be > 0")
        self.sigma_pos_enu = _vec3(self.sigma_pos_enu, "sigma_pos_enu")
        self.sigma_vel_enu = _vec3(self.sigma_vel_enu, "sigma_vel_enu")
        if np.any(self.sigma_pos_enu < 0) or np.any(self.sigma_vel_enu < 0):
            raise ValueError("GnssSpec: σ must be >= 0")
        lev = np.asarray(self.lever_arm_b, dtype=float)
        if lev.shape != (3,):
            raise ValueError("GnssSpec.lever_arm_b: expected 3 values [m], body RFU")
        self.lever_arm_b = lev.copy()
        self.outages = time_windows(self.outages, "GnssSpec.outages")
        self.latency_s = float(self.latency_s)
        if self.latency_s < 0:
            raise ValueError("GnssSpec.latency_s must be >= 0")
        self.velocity = bool(self.velocity)

    def __eq__(self, other):
        if not isinstance(other, GnssSpec):
            return NotImplemented
        return all(np.array_equal(getattr(self, f.name), getattr(other, f.name)) for f in fields(self))

    @classmethod
    def from_config(cls, cfg: Any) -> GnssSpec:
        """Spec from a dict (or a pydantic model, via ``model_dump()``).

        Keys (all optional; None = default): rate_hz [Hz], sigma_pos_m [m] and sigma_vel_m_s [m/s] (scalar,
        [horizontal, vertical] or [E, N, U]), lever_arm_m [m] (body RFU), outages (list of
        {start_s, duration_s} [s] or pairs), latency_s [s], velocity (bool). Unknown keys → ValueError.
        """
        if cfg is None:
            d = {}
        else:
            d = cfg.model_dump() if hasattr(cfg, "model_dump") else dict(cfg)
        names = {"rate_hz": "rate_hz", "sigma_pos_m": "sigma_pos_enu", "sigma_vel_m_s": "sigma_vel_enu",
                 "lever_arm_m": "lever_arm_b", "outages": "outages", "latency_s": "latency_s",
                 "velocity": "velocity"}
        unknown = [k for k in d if k not in names]
        if unknown:
            raise ValueError(f"GnssSpec.from_config: unknown key(s) {', '.join(map(repr, unknown))}; "
                             f"allowed: {', '.join(names)}")
        kw = {}
        for k, v in d.items():
            if v is None:
                continue
            if k == "outages":
                v = [o.model_dump() if hasattr(o, "model_dump") else o for o in v]
            kw[names[k]] = v
        return cls(**kw)


# --------------------------------------------------------------------------------------- helpers
def _c_en(lat, lon) -> np.ndarray:
    """(M, 3, 3) C_e^n (ECEF → ENU) for arrays of lat, lon [rad]."""
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    z = np.zeros_like(lat)
    return np.stack([np.stack([-so, co, z], -1),
                     np.stack([-sl * co, -sl * so, cl], -1),
                     np.stack([cl * co, cl * so, sl], -1)], -2)


@njit(cache=True)
def _slerp_dcm(q, idx, s):
    """C_b^n (M, 3, 3) at fractions s (M,) of the intervals idx (M,) of the quaternions q (N, 4)."""
    m = idx.shape[0]
    out = np.empty((m, 3, 3))
    for j in range(m):
        i = idx[j]
        d = quat_mult(quat_conj(q[i]), q[i + 1])
        r = rotvec_from_quat(d)  # shortest rotation (handles q and -q)
        qj = quat_mult(q[i], quat_from_rotvec(s[j] * r))
        out[j] = dcm_from_quat(qj)
    return out


@njit(cache=True)
def _midpoint_rates(q, t):
    """ω_nb^b [rad/s] (N-1, 3) at the interval midpoints: rotation vector of q_k* ⊗ q_{k+1} over Δt."""
    n = q.shape[0]
    out = np.empty((n - 1, 3))
    for k in range(n - 1):
        r = rotvec_from_quat(quat_mult(quat_conj(q[k]), q[k + 1]))
        out[k] = r / (t[k + 1] - t[k])
    return out


def _interp_linear_extrap(x, xp, fp):
    """Linear interpolation of fp (K, 3) at x, linear extrapolation beyond xp[0] and xp[-1]."""
    if len(xp) == 1:
        return np.repeat(fp, len(x), axis=0)
    j = np.clip(np.searchsorted(xp, x, side="right") - 1, 0, len(xp) - 2)
    w = ((x - xp[j]) / (xp[j + 1] - xp[j]))[:, None]
    return fp[j] * (1.0 - w) + fp[j + 1] * w


def interpolate_truth(truth: Trajectory, times: np.ndarray, omega_ib_b: np.ndarray | None = None):
    """Truth IMU state at ``times`` [s] (inside the truth's time span).

    Returns (r_e (M, 3) ECEF [m], v_e (M, 3) ECEF [m/s], lat, lon, h (M,) [rad, rad, m], v_n (M, 3) ENU
    [m/s], c_bn (M, 3, 3) C_b^n, w_eb_b (M, 3) ω_eb^b body RFU [rad/s]); method in the module docstring.
    """
    t = np.asarray(truth.time, dtype=float)
    times = np.asarray(times, dtype=float)
    if len(t) < 2 or np.any(np.diff(t) <= 0):
        raise ValueError("truth: need >= 2 samples with strictly increasing time")
    if len(times) and (times.min() < t[0] - 1e-9 or times.max() > t[-1] + 1e-9):
        raise ValueError("interpolate_truth: times outside the truth's span")
    lat, lon, h = (np.asarray(a, dtype=float) for a in (truth.lat, truth.lon, truth.height))
    vel = np.asarray(truth.vel, dtype=float).reshape(-1, 3)
    x, y, z = lla_to_ecef(lat, lon, h)
    r_e = np.stack([x, y, z], -1)
    c_en = _c_en(lat, lon)
    v_e = np.einsum("kji,kj->ki", c_en, vel)  # C_n^e v^n

    i = np.clip(np.searchsorted(t, times, side="right") - 1, 0, len(t) - 2)
    dt = t[i + 1] - t[i]
    s = np.clip((times - t[i]) / dt, 0.0, 1.0)
    s2, s3 = s * s, s * s * s
    h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
    d00, d10, d01, d11 = 6 * s2 - 6 * s, 3 * s2 - 4 * s + 1, -6 * s2 + 6 * s, 3 * s2 - 2 * s
    dtc = dt[:, None]
    p0, p1, w0, w1 = r_e[i], r_e[i + 1], v_e[i], v_e[i + 1]
    rf = h00[:, None] * p0 + h10[:, None] * dtc * w0 + h01[:, None] * p1 + h11[:, None] * dtc * w1
    vf = (d00[:, None] * p0 + d10[:, None] * dtc * w0 + d01[:, None] * p1 + d11[:, None] * dtc * w1) / dtc
    # exact sample values where s is 0 or 1 (avoid rounding of the polynomial)
    at0, at1 = s == 0.0, s == 1.0
    rf[at0], vf[at0] = p0[at0], w0[at0]
    rf[at1], vf[at1] = p1[at1], w1[at1]
    latf, lonf, hf = ecef_to_lla(rf[:, 0], rf[:, 1], rf[:, 2])
    latf, lonf, hf = np.atleast_1d(latf), np.atleast_1d(lonf), np.atleast_1d(hf)
    c_en_f = _c_en(latf, lonf)
    vnf = np.einsum("kij,kj->ki", c_en_f, vf)

    q = euler_to_quat_batch(np.ascontiguousarray(np.asarray(truth.rph, dtype=float).reshape(-1, 3)))
    c_bn = _slerp_dcm(q, i.astype(np.int64), s)

    if omega_ib_b is not None:
        w_ib = np.asarray(omega_ib_b, dtype=float).reshape(len(t), 3)
        w_ib_f = w_ib[i] * (1 - s[:, None]) + w_ib[i + 1] * s[:, None]
        w_ie_n = np.stack([np.zeros_like(latf), OMEGA_IE * np.cos(latf), OMEGA_IE * np.sin(latf)], -1)
        w_eb = w_ib_f - np.einsum("kji,kj->ki", c_bn, w_ie_n)
    else:
        tm = 0.5 * (t[:-1] + t[1:])
        w_nb = _interp_linear_extrap(times, tm, _midpoint_rates(q, t))
        rm, rn = radii(latf)
        w_en_n = np.stack([-vnf[:, 1] / (rm + hf), vnf[:, 0] / (rn + hf),
                           vnf[:, 0] * np.tan(latf) / (rn + hf)], -1)
        w_eb = w_nb + np.einsum("kji,kj->ki", c_bn, w_en_n)
    return rf, vf, latf, lonf, hf, vnf, c_bn, w_eb


def simulate_gnss(truth: Trajectory, spec: GnssSpec, rng: np.random.Generator,
                  omega_ib_b: np.ndarray | None = None) -> GnssData:
    """Simulate GNSS antenna position (and velocity) fixes from an IMU truth trajectory.

    Parameters
    ----------
    truth : IMU truth: time [s] (strictly increasing, may be non-uniform), lat, lon [rad], height [m],
        vel ENU [m/s], rph (roll, pitch, heading) [rad].
    spec : receiver model (rate, σ ENU, lever arm body RFU [m], outages, latency); see :class:`GnssSpec`.
    rng : random generator for the noise (its state advances).
    omega_ib_b : optional (N, 3) true body rate ω_ib^b [rad/s], body RFU, at the truth times (what an ideal
        gyro measures); without it the body rate is taken from finite differences of the truth attitude.

    Returns
    -------
    GnssData : antenna fixes, time-tagged per the latency rule; lat, lon [rad], height [m], vel ENU [m/s]
    (None unless ``spec.velocity``), std_pos [m] / std_vel [m/s] = the σ of the spec, quality None,
    events listing removed fixes (outages, latency). The method is in the module docstring.
    """
    t = np.asarray(truth.time, dtype=float)
    if len(t) < 2:
        raise ValueError("simulate_gnss: the truth needs at least 2 samples")
    t_start, t_end = t[0], t[-1]
    span = t_end - t_start
    n_tags = int(np.floor(span * spec.rate_hz + 1e-9))
    tags = t_start + np.arange(1, n_tags + 1) / spec.rate_hz
    tags = tags[tags <= t_end + 1e-9]
    m_all = len(tags)
    zp = rng.standard_normal((m_all, 3))
    zv = rng.standard_normal((m_all, 3))

    events: list[str] = []
    keep = np.ones(m_all, dtype=bool)
    described = np.minimum(tags - spec.latency_s, t_end)
    early = described < t_start - 1e-9
    if spec.latency_s > 0:
        events.append(f"GNSS latency {spec.latency_s:g} s: fix tagged t describes the antenna at t - latency")
    if np.any(early):
        events.append(f"GNSS: {int(early.sum())} fix(es) before t_start + latency dropped")
    keep &= ~early
    rel = tags - t_start
    for start, dur in spec.outages:
        hit = (rel >= start - 1e-9) & (rel < start + dur - 1e-9)
        events.append(f"GNSS outage {start:g}-{start + dur:g} s after start (t = {t_start + start:.3f} to "
                      f"{t_start + start + dur:.3f} s): {int((hit & keep).sum())} fix(es) removed")
        keep &= ~hit
    tags, described, zp, zv = tags[keep], np.maximum(described[keep], t_start), zp[keep], zv[keep]
    m = len(tags)
    if m == 0:
        empty = np.zeros(0)
        return GnssData(empty, empty, empty, empty, np.zeros((0, 3)) if spec.velocity else None,
                        np.zeros((0, 3)), np.zeros((0, 3)) if spec.velocity else None, None, events)

    r_e, v_e, lat, lon, _, _, c_bn, w_eb = interpolate_truth(truth, described, omega_ib_b)
    lev = spec.lever_arm_b
    c_ne = np.transpose(_c_en(lat, lon), (0, 2, 1))
    l_n = c_bn @ lev
    r_ant = r_e + np.einsum("kij,kj->ki", c_ne, l_n)
    v_ant = v_e + np.einsum("kij,kj->ki", c_ne, np.einsum("kij,kj->ki", c_bn, np.cross(w_eb, lev)))
    lat_a, lon_a, h_a = ecef_to_lla(r_ant[:, 0], r_ant[:, 1], r_ant[:, 2])
    lat_a, lon_a, h_a = np.atleast_1d(lat_a), np.atleast_1d(lon_a), np.atleast_1d(h_a)
    vn_a = np.einsum("kij,kj->ki", _c_en(lat_a, lon_a), v_ant)

    sp = spec.sigma_pos_enu
    ne = zp * sp  # ENU position noise [m]
    rm, rn = radii(lat_a)
    lat_o = lat_a + ne[:, 1] / (rm + h_a)
    lon_o = lon_a + ne[:, 0] / ((rn + h_a) * np.cos(lat_a))
    lon_o = wrap_pi(lon_o)
    h_o = h_a + ne[:, 2]
    std_pos = np.tile(sp, (m, 1))
    vel = std_vel = None
    if spec.velocity:
        vel = vn_a + zv * spec.sigma_vel_enu
        std_vel = np.tile(spec.sigma_vel_enu, (m, 1))
    return GnssData(tags, lat_o, lon_o, h_o, vel, std_pos, std_vel, None, events)


__all__ = ["GnssSpec", "simulate_gnss", "interpolate_truth", "time_windows"]
