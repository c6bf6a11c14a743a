"""Compile a scenario's motion segments into command primitives and generate truth + perfect IMU data.

Each segment of :class:`aidnav.sim.scenario.Scenario` becomes one or more *primitives* with
piecewise-constant commands ``[accel (m/s^2), turn_rate (rad/s, + clockwise), fpa_rate (rad/s, + up)]``
for the numba kernel :func:`aidnav.sim.motion.generate`, which smooths every command change with a
raised cosine of width ``transition_s`` (never wider than the neighbouring primitives). The smoothing
is antisymmetric about each boundary, so the integral of every channel is unchanged: the heading
change across a turn segment (measured from before to after its smoothed edges) equals its angle,
and the flight-path angle returns exactly to 0 after a climb.

How the segments are compiled (angles signed, + = clockwise/right):

* ``static``: all commands 0 (speed must be 0). ``straight``: all 0.
* ``accelerate``: accel = a or (to_speed − V)/duration.
* ``turn``: turn_rate = angle/duration, with duration = |angle|/rate or |angle|·R/V when given so.
* ``u_turn`` / ``o_circle``: a turn of ±180° / ±360° over the duration.
* ``figure8``: a 360° circle, a short straight of ``transition_s`` (at most duration/10) so that the
  rate reversal does not cut the corner, and a 360° circle the other way; each circle turns through
  exactly 360°.
* ``s_turns``: per cycle of period T = duration/n_cycles, eight constant-rate turns of T/8 each, the
  j-th turning through A·(sin(2π(j+1)/8) − sin(2πj/8)): the heading at the piece boundaries lies on
  A·sin(2πt/T) (a piecewise-linear sine through 0, ±0.71A, ±A), so it swings ±A and the net change is 0.
  The raised-cosine smoothing rounds the peaks slightly (by ≈ 0.18·rate·transition_s).
* ``climb``: flight-path angle ramped linearly (constant fpa_rate) from its entry value to γ over the
  first ``pull_s`` seconds, held, and ramped back to 0 over the last ``pull_s`` seconds; an optional
  simultaneous turn through ``angle_deg`` at a constant rate over the whole segment. Altitude change
  ≈ V·sin γ·(duration − pull_s).

Outputs follow ``docs/conventions.md``: n = ENU, b = RFU, radians, metres, seconds since the start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from aidnav.data import ImuData, Trajectory
from aidnav.nav.rotations import wrap_2pi
from aidnav.sim import scenario as sc
from aidnav.sim.motion import generate, half_widths
from aidnav.sim.scenario import Scenario, ScenarioError

__all__ = ["CompiledMotion", "compile_segments", "generate_truth", "segment_interval"]

_TWO_PI = 2.0 * math.pi


@dataclass
class CompiledMotion:
    """Primitive command profile for :func:`aidnav.sim.motion.generate`.

    tb : (S,) primitive start times [s]; half : (S,) half transition widths [s];
    vals : (S, 3) [accel m/s^2, turn_rate rad/s (+ clockwise), fpa_rate rad/s (+ up)];
    y0 : (6,) [lat rad, lon rad, h m, V m/s, χ rad, γ rad]; roll0 : roll offset [rad];
    dt : IMU interval [s]; n : number of IMU samples; duration_s : end time [s];
    table : one dict per scenario segment {index, name, type, start_s, end_s}.
    """

    tb: np.ndarray
    half: np.ndarray
    vals: np.ndarray
    y0: np.ndarray
    roll0: float
    dt: float
    n: int
    duration_s: float
    table: list[dict] = field(default_factory=list)


class _Builder:
    def __init__(self, where: str):
        self.where = where
        self.t = 0.0
        self.prims: list[tuple[float, float, float, float]] = []  # (duration, accel, turn, fpa)

    def add(self, dur: float, accel: float = 0.0, turn: float = 0.0, fpa: float = 0.0):
        if dur <= 0.0:
            return
        self.prims.append((float(dur), float(accel), float(turn), float(fpa)))
        self.t += dur


def _sign(direction: str) -> float:
    return 1.0 if direction == "right" else -1.0


def compile_segments(scn: Scenario) -> CompiledMotion:
    """Turn the segments of ``scn`` into primitive commands (see the module docstring).

    Raises :class:`ScenarioError` for motions that cannot be flown (turn or climb at zero speed,
    negative speed, static segment while moving, climb steeper than the speed allows).
    """
    where = scn.source or "<scenario>"
    ini = scn.initial
    v = float(ini.speed_m_s)
    gam = math.radians(ini.pitch_deg)
    b = _Builder(where)
    table = []

    def fail(i, seg, msg):
        label = f" ({seg.name})" if seg.name else ""
        raise ScenarioError(f"{where}: segments.{i}{label}: {seg.type}: {msg}")

    def need_speed(i, seg):
        if v <= 0.0:
            fail(i, seg, f"needs a speed > 0 (the speed here is {v:g} m/s; add an accelerate segment)")

    for i, seg in enumerate(scn.segments):
        t_start = b.t
        if isinstance(seg, sc.StaticSegment):
            if abs(v) > 1e-9:
                fail(i, seg, f"the vehicle is moving at {v:g} m/s; decelerate to 0 first "
                             "(accelerate with to_speed_m_s: 0)")
            b.add(seg.duration_s)
        elif isinstance(seg, sc.StraightSegment):
            b.add(seg.duration_s)
        elif isinstance(seg, sc.AccelerateSegment):
            a = seg.accel_m_s2 if seg.accel_m_s2 is not None else (seg.to_speed_m_s - v) / seg.duration_s
            v_end = v + a * seg.duration_s
            if v_end < -1e-9:
                fail(i, seg, f"the speed would become negative ({v_end:g} m/s)")
            b.add(seg.duration_s, accel=a)
            v = float(seg.to_speed_m_s) if seg.to_speed_m_s is not None else max(v_end, 0.0)
        elif isinstance(seg, sc.TurnSegment):
            need_speed(i, seg)
            ang = math.radians(seg.angle_deg)
            if seg.duration_s is not None:
                dur = float(seg.duration_s)
            elif seg.rate_deg_s is not None:
                dur = abs(seg.angle_deg) / seg.rate_deg_s
            else:
                dur = abs(ang) * seg.radius_m / v
            b.add(dur, turn=ang / dur)
        elif isinstance(seg, (sc.UTurnSegment, sc.OCircleSegment)):
            need_speed(i, seg)
            ang = (math.pi if isinstance(seg, sc.UTurnSegment) else _TWO_PI) * _sign(seg.direction)
            b.add(seg.duration_s, turn=ang / seg.duration_s)
        elif isinstance(seg, sc.Figure8Segment):
            need_speed(i, seg)
            gap = min(scn.transition_s, seg.duration_s / 10.0)
            half_d = 0.5 * (seg.duration_s - gap)
            r = _TWO_PI / half_d * _sign(seg.direction)
            b.add(half_d, turn=r)
            b.add(gap)
            b.add(seg.duration_s - half_d - gap, turn=-r)
        elif isinstance(seg, sc.STurnsSegment):
            need_speed(i, seg)
            amp = math.radians(seg.amplitude_deg) * _sign(seg.direction)
            piece = seg.duration_s / (8 * seg.n_cycles)
            phases = np.sin(np.arange(9) * _TWO_PI / 8.0)
            phases[[0, 4, 8]] = 0.0
            dpsi = amp * np.diff(phases)
            for _ in range(seg.n_cycles):
                for d in dpsi:
                    b.add(piece, turn=d / piece)
        elif isinstance(seg, sc.ClimbSegment):
            need_speed(i, seg)
            if seg.vertical_speed_m_s is not None:
                if abs(seg.vertical_speed_m_s) >= v:
                    fail(i, seg, f"vertical_speed_m_s = {seg.vertical_speed_m_s:g} m/s is not less than "
                                 f"the speed {v:g} m/s")
                g_target = math.asin(seg.vertical_speed_m_s / v)
            else:
                g_target = math.radians(seg.flight_path_deg)
            tp = seg.pull_time_s
            turn = math.radians(seg.angle_deg) / seg.duration_s
            b.add(tp, turn=turn, fpa=(g_target - gam) / tp)
            b.add(seg.duration_s - 2 * tp, turn=turn)
            b.add(tp, turn=turn, fpa=-g_target / tp)
            gam = 0.0
        else:  # pragma: no cover - the union is closed
            fail(i, seg, "unknown segment type")
        table.append({"index": i, "name": seg.name or f"{seg.type}_{i}", "type": seg.type,
                      "start_s": t_start, "end_s": b.t})

    return _compiled(b.prims, b.t, scn, where, table)


def _compiled(primitives, total, scn: Scenario, where: str, table) -> CompiledMotion:
    """The :class:`CompiledMotion` of the primitives of :func:`compile_segments` (``total`` s long):
    consecutive primitives with equal commands merged, their transitions, the sample grid."""
    ini = scn.initial
    # merge consecutive primitives with equal commands (keeps transitions as wide as possible)
    prims: list[list[float]] = []
    for p in primitives:
        if prims and prims[-1][1:] == list(p[1:]):
            prims[-1][0] += p[0]
        else:
            prims.append(list(p))
    durs = np.array([p[0] for p in prims])
    tb = np.concatenate([[0.0], np.cumsum(durs)[:-1]])
    vals = np.array([p[1:] for p in prims], dtype=float).reshape(-1, 3)
    half = half_widths(tb, scn.transition_s)
    total = float(total)
    dt = 1.0 / float(scn.imu_rate_hz)
    n = int(math.floor(total / dt + 1e-6))
    if n < 2:
        raise ScenarioError(f"{where}: the scenario lasts {total:g} s, less than two IMU samples")
    y0 = np.array([math.radians(ini.lat_deg), math.radians(ini.lon_deg), float(ini.height_m),
                   float(ini.speed_m_s), math.radians(ini.heading_deg), math.radians(ini.pitch_deg)])
    return CompiledMotion(tb=tb, half=half, vals=vals, y0=y0, roll0=math.radians(ini.roll_deg), dt=dt,
                          n=n, duration_s=total, table=table)


def generate_truth(scn: Scenario) -> tuple[Trajectory, ImuData, list[dict]]:
    """Truth trajectory and perfect IMU increments for a scenario.

    Returns
    -------
    truth : :class:`~aidnav.data.Trajectory` at t = 0, dt, ..., n·dt [s since the start], with
        dt = 1/imu_rate_hz and n = floor(total duration / dt) (the run ends at the last whole IMU
        interval when the duration is not a multiple of dt): lat, lon
        [rad], height [m], vel ENU [m/s], rph = roll, pitch, heading [rad] (heading in [0, 2π)).
    imu : :class:`~aidnav.data.ImuData`, error-free Δθ [rad] and Δv [m/s] in body RFU over
        ((k−1)dt, k·dt], time-tagged at k·dt (k = 1..n), t0 = 0.
    segments : list of {index, name, type, start_s, end_s} per scenario segment (unnamed segments get
        ``"<type>_<index>"``).
    """
    cm = compile_segments(scn)
    tr, dth, dv = generate(cm.tb, cm.half, cm.vals, cm.y0, cm.roll0, cm.dt, cm.n)
    # exact sample times k·dt (the kernel accumulates the same values; recompute for tidiness)
    t = np.arange(cm.n + 1) * cm.dt
    heading = wrap_2pi(tr[:, 9])
    rph = np.column_stack([tr[:, 7], tr[:, 8], heading])
    truth = Trajectory(time=t, lat=tr[:, 1].copy(), lon=tr[:, 2].copy(), height=tr[:, 3].copy(),
                       vel=np.ascontiguousarray(tr[:, 4:7]), rph=rph)
    imu = ImuData(time=t[1:].copy(), dtheta=dth, dv=dv, t0=0.0)
    return truth, imu, cm.table


def segment_interval(segments: list[dict], name: str) -> tuple[float, float]:
    """(start_s, end_s) [s] of the segment called ``name`` in a table from :func:`generate_truth`."""
    for row in segments:
        if row["name"] == name:
            return float(row["start_s"]), float(row["end_s"])
    raise KeyError(f"no segment named {name!r} (have: {', '.join(r['name'] for r in segments)})")
