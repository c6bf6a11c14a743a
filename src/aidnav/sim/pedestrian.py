"""A simulated pedestrian with raw GNSS and carrier phase: the truth for the tight filter's velocity and its σ
while walking (issue 40, the walk's velocity σ).

**Motion** (:func:`walking_truth`): standing, a start, then walking with the speed oscillating at the step
frequency — the body brakes as the foot lands and speeds up as it pushes off: the along-track acceleration is
a square wave of ±A smoothed by the motion generator's raised cosines (:mod:`aidnav.sim.motion`), alternating
every half step, so the speed swings about its mean by ±A/(4·f_step) (a triangle wave; ±0.2 m/s at 1.9 Hz
for A = 1.52 m/s²) — and a vertical bounce of the same rhythm (flight-path angle ±``bounce_deg``), with
turns of the walk's kind (90° in 2–3 s) between straight stretches; then a stop and standing again.
Frames and units as :mod:`aidnav.sim.trajectory` (n = ENU, b = RFU, rad, m, s).

**Carrier phase** (:func:`with_carrier_phase`): λL = ρ + c·dt_r − c·dt_s + T − I + λN + ε_φ. The geometric
part, clocks and troposphere are those of the same simulation without its code errors (the same draws:
:meth:`aidnav.sim.gnss_raw.RawGnssSpec.perfect` keeps the receiver clocks and the Klobuchar and
Saastamoinen models), N an integer per satellite, ε_φ white of σ ``phase_sigma_m``. The ionosphere enters
the phase with the code's sign here (its change over an interval of 0.25 s is below 0.1 mm: it cancels in
every time difference); code-minus-phase is not used by anything that reads this. No cycle slips.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from aidnav.data import ImuData, Trajectory
from aidnav.nav.gnss_sat import C_LIGHT
from aidnav.nav.rotations import wrap_2pi
from aidnav.sim.motion import generate, half_widths

__all__ = ["STEP_HZ", "PedestrianRun", "simulate_pedestrian", "walking_truth", "with_carrier_phase"]

STEP_HZ = 1.9  #: steps per second (a walker's cadence, 100–120 steps/min)
SOW = 345600.0  #: GPS seconds of week at the start (the consistency matrix's tight sky)
WEEK = 2381


def _primitives(speed, step_hz, accel_amp, bounce_deg, turns, walk_s, stand_s, start_s):
    """(duration, accel, turn rate, fpa rate) primitives: stand, start to ``speed``, walk with steps and
    ``turns`` ((time into the walk [s], angle [deg], duration [s])), stop, stand. The walk is made of
    quarter steps: the acceleration and the flight-path angle's rate are + over the first quarter, then
    alternate every two quarters (triangle waves about the mean speed and 0, one period per step), and
    the walk ends after an even number of quarters (both back at their means)."""
    prims = [(stand_s, 0.0, 0.0, 0.0), (start_s, speed / start_s, 0.0, 0.0)]
    q = 0.25 / step_hz
    g_rate = math.radians(bounce_deg) / q
    n = int(walk_s / q)
    n -= n % 2
    for k in range(n):
        t = (k + 0.5) * q
        turn = sum(math.radians(ang) / dur for t0, ang, dur in turns if t0 <= t < t0 + dur)
        sign = 1.0 if ((k + 1) // 2) % 2 == 0 else -1.0
        prims.append((q, sign * accel_amp, turn, sign * g_rate))
    return prims, n * q


def walking_truth(speed=1.3, step_hz=STEP_HZ, speed_amp=0.2, bounce_deg=5.0, walk_s=100.0, stand_s=12.0,
                  end_s=15.0, imu_rate_hz=100.0, transition_s=0.08, lat_deg=40.0, lon_deg=116.0,
                  height_m=50.0, heading_deg=20.0):
    """(truth :class:`Trajectory`, perfect :class:`ImuData`, the walking span (start, end) [s]) of the
    module's pedestrian: the speed oscillates by ±``speed_amp`` about ``speed`` at ``step_hz``. Times from
    0 (the truth's samples at 0, dt, …)."""
    accel = 4.0 * step_hz * speed_amp  # the triangle wave's slope
    turns = [(15.0, 90.0, 2.5), (30.0, -90.0, 2.5), (45.0, 180.0, 4.0), (62.0, 90.0, 2.0),
             (75.0, -135.0, 3.0), (88.0, 90.0, 2.5)]
    start_s = 3.0
    prims, walked = _primitives(speed, step_hz, accel, bounce_deg, [t for t in turns if t[0] < walk_s],
                                walk_s, stand_s, start_s)
    prims += [(start_s, -speed / start_s, 0.0, 0.0), (end_s, 0.0, 0.0, 0.0)]
    durs = np.array([p[0] for p in prims])
    tb = np.concatenate([[0.0], np.cumsum(durs)[:-1]])
    vals = np.array([p[1:] for p in prims], float)
    half = half_widths(tb, transition_s)
    dt = 1.0 / imu_rate_hz
    n = int(math.floor(durs.sum() / dt + 1e-6))
    y0 = np.array([math.radians(lat_deg), math.radians(lon_deg), height_m, 0.0, math.radians(heading_deg),
                   0.0])
    tr, dth, dv = generate(tb, half, vals, y0, 0.0, dt, n)
    t = np.arange(n + 1) * dt
    truth = Trajectory(time=t, lat=tr[:, 1].copy(), lon=tr[:, 2].copy(), height=tr[:, 3].copy(),
                       vel=np.ascontiguousarray(tr[:, 4:7]), rph=np.column_stack([tr[:, 7], tr[:, 8],
                                                                                  wrap_2pi(tr[:, 9])]))
    imu = ImuData(time=t[1:].copy(), dtheta=dth, dv=dv, t0=0.0)
    return truth, imu, (stand_s + start_s, stand_s + start_s + walked)


def with_carrier_phase(obs, truth, eph, spec, seed, t0_gps, phase_sigma_m=0.005):
    """A copy of ``obs`` (the rover of :func:`aidnav.sim.gnss_raw.simulate_raw_gnss` run with ``spec`` and a
    generator seeded ``seed``) with an L1 carrier phase [cycles] (module doc) where it has a code; its
    loss-of-lock indicator 0."""
    from aidnav.sim.gnss_raw import simulate_raw_gnss  # lazy: the raw simulator only for a phase

    clean = simulate_raw_gnss(truth, eph, spec.perfect(), np.random.default_rng(seed), t0_gps).rover
    rng = np.random.default_rng([int(np.atleast_1d(seed)[0]), 77])
    S = clean.code1.shape[1]
    lam = C_LIGHT / obs.frequencies()
    amb = rng.integers(-1_000_000, 1_000_000, S).astype(float)
    noise = rng.standard_normal(clean.code1.shape) * phase_sigma_m
    phase = (clean.code1 + noise) / lam + amb
    phase = np.where(np.isfinite(obs.code1), phase, np.nan)
    return dataclasses.replace(obs, phase1=phase, lli1=np.zeros(phase.shape, np.int64),
                               events=list(obs.events) + [f"carrier phase simulated (σ {phase_sigma_m} m)"])


class PedestrianRun:
    """truth (GPS time scale), imu (corrupted, GPS scale), obs (raw GNSS with phase), eph, walk (start, end)
    [GPS s]."""

    def __init__(self, truth, imu, obs, eph, walk):
        self.truth, self.imu, self.obs, self.eph, self.walk = truth, imu, obs, eph, walk


def simulate_pedestrian(seed: int, grade: str = "consumer", rate_hz: float = 4.0, systems: str = "GE",
                        phase_sigma_m: float = 0.005, **motion) -> PedestrianRun:
    """The module's pedestrian with an IMU of ``grade`` (:meth:`aidnav.sim.imu.ImuSpec.grade`) and raw GNSS
    of ``systems`` at ``rate_hz`` with carrier phase; every draw from ``seed``."""
    from aidnav.sim.gnss_constellation import nominal_multi_constellation  # lazy: the sensors only here
    from aidnav.sim.gnss_raw import RawGnssSpec, simulate_raw_gnss  # lazy: the sensors only here
    from aidnav.sim.imu import ImuSpec, corrupt_imu  # lazy: the sensors only here

    truth, imu_true, (w0, w1) = walking_truth(**motion)
    imu, _ = corrupt_imu(imu_true, ImuSpec.grade(grade), np.random.default_rng([seed, 35]))
    eph = nominal_multi_constellation(WEEK, SOW, systems)
    spec = RawGnssSpec(rate_hz=rate_hz)
    eph.iono_alpha, eph.iono_beta = spec.iono_alpha, spec.iono_beta
    gseed = [seed, 40]
    raw = simulate_raw_gnss(truth, eph, spec, np.random.default_rng(gseed), SOW)
    obs = with_carrier_phase(raw.rover, truth, eph, spec, gseed, SOW, phase_sigma_m)
    tg = Trajectory(time=truth.time + SOW, lat=truth.lat, lon=truth.lon, height=truth.height, vel=truth.vel,
                    rph=truth.rph)
    imu_g = ImuData(imu.time + SOW, imu.dtheta, imu.dv, t0=imu.t0 + SOW)
    return PedestrianRun(tg, imu_g, obs, eph, (w0 + SOW, w1 + SOW))
