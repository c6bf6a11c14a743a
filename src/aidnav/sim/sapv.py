"""Satellite-antenna pointing vector (SAPV) sensor: the axis angles of an antenna that tracks a GEO satellite.

Seed 000 (§1.1): a satcom antenna on the vehicle that has acquired a GEO satellite keeps its beam on
it by self-search (step tracking); its azimuth- and elevation-axis angle sensors then report the
satellite's direction in the body (platform) frame to within a fraction of the beamwidth. Those two
angles are a measurement of the vehicle attitude.

Frames and units (``docs/conventions.md``, :mod:`aidnav.nav.geo_pointing`): body b = RFU; antenna azimuth
az ∈ [0, 2π) clockwise (seen from above) from the body forward axis in the body x-y plane, elevation
el ∈ [−π/2, π/2] above that plane (:func:`aidnav.nav.geo_pointing.az_el_from_body`); angles in radians
inside (degrees in :class:`SapvSpec`, the boundary); times in seconds on the truth's time scale.

Model of one epoch t_j (:func:`simulate_sapv`):

* true angles (az, el) = :func:`aidnav.nav.geo_pointing.pointing_az_el` of the truth position and
  attitude interpolated to t_j (:func:`aidnav.sim.gnss.interpolate_truth`), satellite at longitude
  ``sat_lon_deg`` and radius ``sat_radius_m`` (seed 000: height 3.5785e7 m, :data:`R_GEO_SEED000`);
* reported angles = true + tracking error: white Gaussian, σ = ``sigma_deg`` (az, el), plus an optional
  slowly varying bias per axis, first-order Gauss-Markov with stationary σ ``bias_sigma_deg`` and
  correlation time ``bias_tau_s`` (exact discretisation b_j = e^{−Δt/τ} b_{j−1} + σ√(1 − e^{−2Δt/τ}) w_j,
  started from the stationary distribution); the azimuth is reduced to [0, 2π);
* tracking lost → NaN angles and a reason flag (the first that applies, in this order):
  ``BLOCKED`` inside a blockage window (start_s, duration_s) relative to the first truth time;
  ``LOW_ELEVATION`` antenna elevation (body frame: the elevation axis, which is what the antenna can
  reach; for a level vehicle it is the topocentric elevation) below ``elevation_mask_deg``, or the
  satellite below the local horizon (topocentric elevation < 0, e.g. a GEO longitude on the far side of
  the Earth: a tilted body could otherwise point "through" the Earth);
  ``BODY_RATE`` body angular rate |ω_nb^b| above ``max_body_rate_deg_s`` (the tracking loop cannot
  follow); ``REACQUIRING`` within ``reacquire_s`` after any loss ends (search and re-lock time).
  Noise is drawn for every epoch before the losses are applied, so the same seed gives the same errors
  on the surviving epochs whatever the losses.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aidnav.data import Trajectory
from aidnav.nav.geo_pointing import R_GEO, R_GEO_SEED000, az_el_from_body, geo_sat_ecef
from aidnav.nav.rotations import wrap_2pi
from aidnav.sim.gnss import time_windows
from aidnav.units import DEG

__all__ = ["SapvSpec", "SapvData", "simulate_sapv", "OK", "BLOCKED", "LOW_ELEVATION", "BODY_RATE",
           "REACQUIRING", "REASONS", "R_GEO", "R_GEO_SEED000"]


from aidnav.models.sapv import BLOCKED, BODY_RATE, LOW_ELEVATION, OK, REACQUIRING, REASONS  # noqa: E402, F401
from aidnav.nav.geo_pointing import los_enu
from aidnav.nav.rotations import euler_to_quat_batch
from aidnav.sim.gnss import interpolate_truth


def _pair(x, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim == 0:
        a = np.full(2, float(a))
    if a.shape != (2,) or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ValueError(f"SapvSpec.{name}: expected a scalar or (az, el), finite and >= 0")
    return a.copy()


@dataclass
class SapvSpec:
    """Antenna tracking model (boundary units: degrees, seconds).

    rate_hz : angle output rate [Hz]; sigma_deg : white tracking error 1σ (az, el) [deg] (scalar → both);
    bias_sigma_deg : stationary 1σ of the Gauss-Markov tracking bias (az, el) [deg] (0 = none);
    bias_tau_s : its correlation time [s]; sat_lon_deg : GEO longitude [deg, east +];
    sat_radius_m : geocentric radius [m] (default R_GEO; seed 000: :data:`R_GEO_SEED000`);
    elevation_mask_deg : lowest antenna elevation that can be tracked [deg];
    max_body_rate_deg_s : largest body rate the tracking loop follows [deg/s];
    blockages : list of (start_s, duration_s) [s] relative to the truth's first time (or dicts);
    reacquire_s : time after a loss ends before the angles are valid again [s].
    """

    rate_hz: float = 1.0
    sigma_deg: Any = 0.05
    bias_sigma_deg: Any = 0.0
    bias_tau_s: float = 300.0
    sat_lon_deg: float = 138.0
    sat_radius_m: float = R_GEO
    elevation_mask_deg: float = 5.0
    max_body_rate_deg_s: float = 60.0
    blockages: list = field(default_factory=list)
    reacquire_s: float = 0.0

    def __post_init__(self):
        self.rate_hz = float(self.rate_hz)
        if not self.rate_hz > 0:
            raise ValueError("SapvSpec.rate_hz must be > 0")
        self.sigma_deg = _pair(self.sigma_deg, "sigma_deg")
        self.bias_sigma_deg = _pair(self.bias_sigma_deg, "bias_sigma_deg")
        self.bias_tau_s = float(self.bias_tau_s)
        if np.any(self.bias_sigma_deg > 0) and not self.bias_tau_s > 0:
            raise ValueError("SapvSpec.bias_tau_s must be > 0 when bias_sigma_deg > 0")
        if not self.sat_radius_m > 7.0e6:
            raise ValueError("SapvSpec.sat_radius_m: a geocentric radius [m] well above the Earth's")
        if not self.max_body_rate_deg_s > 0:
            raise ValueError("SapvSpec.max_body_rate_deg_s must be > 0")
        if self.reacquire_s < 0:
            raise ValueError("SapvSpec.reacquire_s must be >= 0")
        self.blockages = time_windows(self.blockages, "SapvSpec.blockages")

    @property
    def sat_ecef(self) -> np.ndarray:
        """ECEF position of the satellite [m] (3,)."""
        return geo_sat_ecef(self.sat_lon_deg * DEG, float(self.sat_radius_m))


@dataclass
class SapvData:
    """Antenna angle outputs.

    time : (M,) [s]; az, el : (M,) reported angles [rad] (az ∈ [0, 2π)), NaN where not tracking;
    reason : (M,) int8 flag (``OK`` = 0 tracking, else the cause, see :data:`REASONS`);
    sigma : (2,) white tracking error 1σ (az, el) [rad] (what a filter should use as R);
    sat_lon : satellite longitude [rad]; sat_radius : its geocentric radius [m];
    az_true, el_true : (M,) error-free angles [rad] (NaN never); bias : (M, 2) realised tracking bias [rad];
    events : human-readable notes (losses and their causes).
    """

    time: np.ndarray
    az: np.ndarray
    el: np.ndarray
    reason: np.ndarray
    sigma: np.ndarray
    sat_lon: float
    sat_radius: float
    az_true: np.ndarray | None = None
    el_true: np.ndarray | None = None
    bias: np.ndarray | None = None
    events: list[str] = field(default_factory=list)

    def __post_init__(self):
        self.time = np.ascontiguousarray(self.time, dtype=float)
        self.az = np.ascontiguousarray(self.az, dtype=float)
        self.el = np.ascontiguousarray(self.el, dtype=float)
        self.reason = np.ascontiguousarray(self.reason, dtype=np.int8)
        self.sigma = np.broadcast_to(np.asarray(self.sigma, dtype=float), (2,)).copy()
        if not (len(self.time) == len(self.az) == len(self.el) == len(self.reason)):
            raise ValueError("SapvData: time, az, el and reason must have the same length")

    def __len__(self) -> int:
        return len(self.time)

    @property
    def valid(self) -> np.ndarray:
        """(M,) bool: the antenna reports angles at this epoch."""
        return (self.reason == OK) & np.isfinite(self.az) & np.isfinite(self.el)

    @property
    def sat_ecef(self) -> np.ndarray:
        """ECEF position of the tracked satellite [m] (3,)."""
        return geo_sat_ecef(float(self.sat_lon), float(self.sat_radius))

    def with_loss(self, start: float, stop: float, reason: int = BLOCKED) -> SapvData:
        """A copy with the epochs start <= time < stop [s] (absolute times) marked lost with ``reason``."""
        hit = (self.time >= start) & (self.time < stop)
        rs = self.reason.copy()
        rs[hit & (rs == OK)] = reason
        az, el = self.az.copy(), self.el.copy()
        az[hit], el[hit] = np.nan, np.nan
        return SapvData(self.time, az, el, rs, self.sigma, self.sat_lon, self.sat_radius, self.az_true,
                        self.el_true, self.bias, [*self.events, f"SAPV lost {start:g}-{stop:g} s "
                                                               f"({REASONS[reason]})"])


def _body_rate(truth: Trajectory, times: np.ndarray) -> np.ndarray:
    """|ω_nb^b| [rad/s] at ``times`` from finite differences of the truth attitude: the rotation angle of
    q_k* ⊗ q_{k+1} over each interval; the larger of the two intervals around each time (a loss is not
    hidden by interpolation)."""
    t = np.asarray(truth.time, float)
    q = euler_to_quat_batch(np.ascontiguousarray(np.asarray(truth.rph, float)))
    p, r = q[:-1], q[1:]
    # conj(p) ⊗ r = (p0 r0 + pv·rv, p0 rv − r0 pv − pv × rv)
    s = np.abs(np.sum(p * r, axis=1))
    v = p[:, :1] * r[:, 1:] - r[:, :1] * p[:, 1:] - np.cross(p[:, 1:], r[:, 1:])
    w = 2.0 * np.arctan2(np.linalg.norm(v, axis=1), s) / np.diff(t)
    tm = 0.5 * (t[:-1] + t[1:])
    j = np.clip(np.searchsorted(tm, times), 0, len(tm) - 1)
    jp = np.clip(j - 1, 0, len(tm) - 1)
    return np.maximum(w[j], w[jp])


def simulate_sapv(truth: Trajectory, spec: SapvSpec, rng: np.random.Generator,
                  times: np.ndarray | None = None) -> SapvData:
    """Simulate the antenna's azimuth/elevation axis angles along a truth trajectory.

    Parameters
    ----------
    truth : IMU truth (time [s], lat, lon [rad], height [m], vel ENU [m/s], rph [rad]); the antenna's
        rotation centre is taken at the IMU (a lever arm does not change the direction to a GEO
        satellite by more than ~1e-7 rad per metre).
    spec : :class:`SapvSpec`. rng : random generator (its state advances).
    times : optional output times [s] inside the truth span; default t_start + j/rate_hz, j = 1, 2, ...

    Returns
    -------
    :class:`SapvData` (model in the module docstring).
    """
    t = np.asarray(truth.time, dtype=float)
    t_start, t_end = t[0], t[-1]
    if times is None:
        n = int(np.floor((t_end - t_start) * spec.rate_hz + 1e-9))
        times = t_start + np.arange(1, n + 1) / spec.rate_hz
        times = times[times <= t_end + 1e-9]
    times = np.asarray(times, dtype=float)
    m = len(times)
    white = rng.standard_normal((m, 2))
    gm = rng.standard_normal((m, 2))
    sat = spec.sat_ecef
    _, _, lat, lon, h, _, c_bn, _ = interpolate_truth(truth, np.minimum(times, t_end))

    az_t = np.empty(m)
    el_t = np.empty(m)
    below = np.zeros(m, bool)  # satellite below the local (topocentric) horizon: the Earth is in the way
    for j in range(m):
        r_n = los_enu(lat[j], lon[j], h[j], sat)
        below[j] = r_n[2] < 0.0
        az_t[j], el_t[j] = az_el_from_body(c_bn[j].T @ r_n)
    # tracking bias: first-order Gauss-Markov, stationary start
    sb = spec.bias_sigma_deg * DEG
    bias = np.zeros((m, 2))
    if np.any(sb > 0):
        b = sb * gm[0]
        bias[0] = b
        for j in range(1, m):
            a = np.exp(-(times[j] - times[j - 1]) / spec.bias_tau_s)
            b = a * b + sb * np.sqrt(1.0 - a * a) * gm[j]
            bias[j] = b
    sig = spec.sigma_deg * DEG
    az = wrap_2pi(az_t + bias[:, 0] + sig[0] * white[:, 0])
    az[az >= 2.0 * np.pi] = 0.0  # np.mod of a tiny negative angle rounds to 2π: keep az in [0, 2π)
    el = el_t + bias[:, 1] + sig[1] * white[:, 1]
    # losses
    reason = np.zeros(m, np.int8)
    events: list[str] = []
    rel = times - t_start
    for s, d in spec.blockages:
        hit = (rel >= s - 1e-9) & (rel < s + d - 1e-9) & (reason == OK)
        reason[hit] = BLOCKED
        events.append(f"SAPV blockage {s:g}-{s + d:g} s after start: {int(hit.sum())} epoch(s) lost")
    low = ((el_t < spec.elevation_mask_deg * DEG) | below) & (reason == OK)
    reason[low] = LOW_ELEVATION
    if low.any():
        events.append(f"SAPV: {int(low.sum())} epoch(s) with the antenna elevation below "
                      f"{spec.elevation_mask_deg:g} deg or the satellite below the horizon "
                      f"({int((below & low).sum())})")
    fast = (_body_rate(truth, times) > spec.max_body_rate_deg_s * DEG) & (reason == OK)
    reason[fast] = BODY_RATE
    if fast.any():
        events.append(f"SAPV: {int(fast.sum())} epoch(s) with the body rate above "
                      f"{spec.max_body_rate_deg_s:g} deg/s")
    if spec.reacquire_s > 0:
        lost_t = times[reason != OK]
        for j in np.flatnonzero(reason == OK):
            before = lost_t[lost_t < times[j]]
            if len(before) and times[j] - before[-1] <= spec.reacquire_s + 1e-9:
                reason[j] = REACQUIRING
    bad = reason != OK
    az[bad] = np.nan
    el[bad] = np.nan
    return SapvData(times, az, el, reason, sig, spec.sat_lon_deg * DEG, float(spec.sat_radius_m), az_t, el_t,
                    bias, events)
