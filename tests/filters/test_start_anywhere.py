"""Start from any state (issue 26, item 1), simulated with fixed seeds.

* a car already moving at the first fix, position-only 1 Hz fixes: horizontal error <= 1 m RMS after
  30 s (velocity from position differences with their σ, heading from the course only when the speed
  is 5σ above its noise, roll/pitch from the specific force corrected by the GNSS acceleration);
* 10 min parked with 10 Hz position-only fixes (1 m noise: the position differences are noise), then
  driving: no heading from the noise while parked, no ZUPT claimed from the GNSS, and the heading σ
  covers the heading error at every parked epoch (|error| <= 3σ, as a χ²(1) 99.7 % bound);
* a 30 s IMU gap in a turn: the bridged gap's variance covers what the gap did to the heading.
The filter's noise model is the simulated sensors' (:func:`aidnav.filters.tuning.loose_config_from_specs`).
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.data import ImuData
from aidnav.filters.loose import run_loose, to_trajectory
from aidnav.filters.tuning import loose_config_from_specs
from aidnav.nav.earth import lla_difference_enu
from aidnav.sim.gnss import GnssSpec
from aidnav.sim.imu import ImuSpec
from aidnav.sim.run import simulate
from aidnav.sim.scenario import parse_scenario


def _scn(segments, speed, gnss, seed=5, grade="mems"):
    return parse_scenario({
        "name": "start", "seed": seed, "imu_rate_hz": 100,
        "initial": {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 50.0, "speed_m_s": speed,
                    "heading_deg": 37.0},
        "segments": segments, "sensors": {"imu": {"grade": grade}, "gnss": gnss}})


def _cfg(sim, **over):
    spec = ImuSpec.grade(sim.scenario.sensors.imu.grade)
    g = GnssSpec.from_config(sim.scenario.sensors.gnss)
    init = {"mode": "auto", "attitude_sigma_deg": [2.0, 2.0, 10.0], "static_window_s": 10.0}
    init.update(over.pop("init", {}))
    return loose_config_from_specs(spec, g, init=init, **over)


def _herr(traj, truth):
    j = np.clip(np.searchsorted(truth.time, traj.time), 0, len(truth) - 1)
    e, n, _ = lla_difference_enu(traj.lat, traj.lon, 0.0, truth.lat[j], truth.lon[j], 0.0)
    return np.hypot(e, n), j


def _heading_err(traj, truth, j):
    return (traj.rph[:, 2] - truth.rph[j, 2] + np.pi) % (2 * np.pi) - np.pi


@pytest.mark.parametrize("seed", [5, 6])
def test_moving_start_position_only_1hz(seed):
    sim = simulate(_scn([{"type": "straight", "duration_s": 20}, {"type": "turn", "angle_deg": 90,
                                                                   "duration_s": 15},
                         {"type": "straight", "duration_s": 30}, {"type": "turn", "angle_deg": -60,
                                                                   "duration_s": 10},
                         {"type": "straight", "duration_s": 30}], 15.0,
                        {"rate_hz": 1, "sigma_pos_m": [0.5, 0.5, 1.0], "velocity": False}, seed=seed))
    events: list[str] = []
    r = run_loose(sim.imu, sim.gnss, _cfg(sim), events=events)
    assert any("in-motion start" in e for e in events), events
    traj = to_trajectory(r)
    h, _ = _herr(traj, sim.truth)
    after = traj.time >= traj.time[0] + 30.0
    assert np.sqrt(np.mean(h[after] ** 2)) <= 1.0


def test_parked_then_driving_10hz_position_only():
    sim = simulate(_scn([{"type": "static", "duration_s": 600},
                         {"type": "accelerate", "duration_s": 10, "to_speed_m_s": 12},
                         {"type": "turn", "angle_deg": 90, "duration_s": 15},
                         {"type": "straight", "duration_s": 40}], 0.0,
                        {"rate_hz": 10, "sigma_pos_m": [1.0, 1.0, 2.0], "velocity": False}, seed=9))
    cfg = _cfg(sim, constraints={"zupt": True}, init={"course_min_speed_m_s": 2.0})
    events: list[str] = []
    r = run_loose(sim.imu, sim.gnss, cfg, events=events)
    align = [e for e in events if "heading from GNSS course at t=" in e]
    assert align, events
    t_align = float(align[0].split("t=")[1].split(":")[0])
    assert t_align > sim.truth.time[0] + 600.0  # never while parked
    assert r.counts["zupt_updates"] == 0  # the GNSS cannot say "static" with 1 m noise at 10 Hz
    traj = to_trajectory(r)
    _, j = _herr(traj, sim.truth)
    parked = traj.time < sim.truth.time[0] + 600.0
    err = np.abs(_heading_err(traj, sim.truth, j))
    sig = traj.std_att[:, 2]
    assert np.all(err[parked] <= 3.0 * sig[parked])
    assert np.min(sig[parked]) > np.radians(30.0)  # no heading information while parked: σ stays large


def test_imu_gap_in_a_turn_heading_sigma_covers_the_error():
    sim = simulate(_scn([{"type": "straight", "duration_s": 60}, {"type": "turn", "angle_deg": 270,
                                                                   "duration_s": 60},
                         {"type": "straight", "duration_s": 60}], 10.0,
                        {"rate_hz": 1, "sigma_pos_m": [0.5, 0.5, 1.0], "sigma_vel_m_s": [0.05, 0.05, 0.1]},
                        seed=3, grade="tactical"))
    imu = sim.imu
    t = imu.time
    keep = ~((t > t[0] + 80.0) & (t <= t[0] + 110.0))  # 30 s without IMU samples, in the turn
    gap = ImuData(t[keep], imu.dtheta[keep], imu.dv[keep], t0=imu.t0)
    events: list[str] = []
    r = run_loose(gap, sim.gnss, _cfg(sim, init={"mode": "auto"}), events=events)
    assert any("IMU gap" in e for e in events)
    traj = to_trajectory(r)
    _, j = _herr(traj, sim.truth)
    after = np.searchsorted(traj.time, t[0] + 110.0)
    err = abs(_heading_err(traj, sim.truth, j)[after])
    assert err <= 3.0 * traj.std_att[after, 2], (np.degrees(err), np.degrees(traj.std_att[after, 2]))


def test_coarse_mounting_of_an_imu_mounted_backwards_and_tilted():
    """IMU axes = vehicle axes turned by a known C_b^v (heading 95°, roll −6°, pitch 1°): the coarse
    mounting from the accelerations is within 4° of it (the linear range of the mounting state, σ 3°;
    "up" from the mean specific force is off by the mean acceleration / g ≈ 1° on this run)."""
    from aidnav.filters.preprocess import coarse_mounting, velocity_from_positions
    from aidnav.nav.rotations import dcm_from_euler

    sim = simulate(_scn([{"type": "accelerate", "duration_s": 10, "to_speed_m_s": 12},
                         {"type": "turn", "angle_deg": 90, "duration_s": 10},
                         {"type": "straight", "duration_s": 10}, {"type": "turn", "angle_deg": -120,
                                                                   "duration_s": 12},
                         {"type": "accelerate", "duration_s": 8, "to_speed_m_s": 4},
                         {"type": "turn", "angle_deg": 180, "duration_s": 15},
                         {"type": "accelerate", "duration_s": 10, "to_speed_m_s": 14}], 2.0,
                        {"rate_hz": 4, "sigma_pos_m": [0.02, 0.02, 0.04],
                         "sigma_vel_m_s": [0.03, 0.03, 0.05]},
                        seed=4, grade="mems"))
    cbv = dcm_from_euler(np.radians(-6.0), np.radians(1.0), np.radians(95.0))
    imu = sim.imu
    rot = ImuData(imu.time, imu.dtheta @ cbv, imu.dv @ cbv, t0=imu.t0)  # body' = C_v^b' · vehicle
    vel, _ = velocity_from_positions(sim.gnss, 1.0) if sim.gnss.vel is None else (sim.gnss.vel, None)
    cm = coarse_mounting(rot, rot.time, sim.gnss, vel)
    assert cm is not None
    C = cm[0]
    ang = np.degrees(np.arccos(np.clip((np.trace(C @ cbv.T) - 1) / 2, -1, 1)))
    assert ang < 4.0, (ang, np.degrees(cm[1:4]))


def test_spp_course_only_when_meaningful():
    """SPP Doppler noise at a standstill (σ 1 m/s, spikes above 3 m/s) never gives a course; a walk at
    1.3 m/s with 0.15 m/s noise does, from its 2 s mean."""
    from aidnav.estimators.tight_solution import _meaningful_course

    rng = np.random.default_rng(2)
    t = np.arange(0.0, 60.0, 0.25)
    still = rng.normal(0.0, 1.0, (len(t), 3))
    assert np.hypot(still[:, 0], still[:, 1]).max() > 3.0
    assert _meaningful_course(t, still, 0.8) is None
    walk = rng.normal(0.0, 0.15, (len(t), 3))
    walk[:, 0] += 1.3 * np.sin(np.radians(40.0))
    walk[:, 1] += 1.3 * np.cos(np.radians(40.0))
    tc, course, spd, se = _meaningful_course(t, walk, 0.8)
    assert abs(np.degrees(course) - 40.0) < 3.0 * np.degrees(se / spd) + 1.0


def _walk_run(load_walk, cfg):
    """``process_tight`` on the walk with ``cfg``: (TightResult, tight comparison, SPP comparison) over
    every reference epoch."""
    from aidnav.apps.tight import compare_with_reference, process_tight

    imu, obs, nav, ref = load_walk()
    res, sp = process_tight(imu, obs, nav, cfg)
    c = compare_with_reference(res.time, res.state[:, 0], res.state[:, 1], res.state[:, 2], ref, quality=None)
    ok = np.isfinite(sp["lat"])
    cs = compare_with_reference(sp["time"][ok], sp["lat"][ok], sp["lon"][ok], sp["h"][ok], ref, quality=None)
    return res, c, cs, ref


@pytest.fixture(scope="module")
def walk_default(load_walk):
    """``aidnav tight`` on the walk with no configuration: (tight, SPP) horizontal RMS over every
    reference epoch (issue 26: before, the heading came from an SPP speed spike and it diverged to 21 m)."""
    from aidnav.filters.tight import TightConfig

    res, c, cs, ref = _walk_run(load_walk, TightConfig())
    WALK["tight"], WALK["spp"], WALK["res"], WALK["ref"] = c, cs, res, ref
    return c["horizontal_rms"], cs["horizontal_rms"]


@pytest.fixture(scope="module")
def walk_white(load_walk):
    """The walk with white-noise pseudoranges only (``range_errors`` off: the filter before the
    range-error states; code and Doppler only, no carrier phase): (tight comparison, SPP comparison)."""
    from aidnav.filters.tight import TightConfig

    _, c, cs, _ = _walk_run(load_walk, TightConfig(gnss={"range_errors": False, "use_phase": False}))
    return c, cs


WALK: dict = {}  # the full comparisons of walk_default (diagnosis test below)


def test_walk_tight_does_not_diverge(walk_default):
    tight, spp = walk_default
    assert tight <= 1.1 * spp  # measured 8.37 m vs SPP 8.51 m (issue 40; 8.83 m vs 8.36 m before)


def test_walk_tight_no_worse_than_spp(walk_default):
    """Reached in issue 40: tight 8.37 m against SPP 8.51 m (both with RTKLIB's default ionosphere) with
    the carrier phase's TDCP velocities; code + Doppler only it was 8.84 m (issue 26's 8.83 m)."""
    tight, spp = walk_default
    assert tight <= spp


def test_walk_error_is_a_common_offset(walk_default, walk_white):
    """Diagnosis of the walk's 8.4-8.6 m (issue 26): SPP and tight share one horizontal offset from the RTK
    reference (their mean errors within 1 m of each other, each over 7 m), and about that offset the
    tight filter scatters less than SPP (measured 0.75 m vs 1.00 m). With 4 GPS satellites (zero
    redundancy) a common range error cannot be told from a reference offset; the horizontal RMS compares
    the offsets, not the filters. The scatter comparison is of the filter with white-noise
    pseudoranges only (``walk_white``, 0.75 m): with the range-error states on, the filter lets the
    position wander within the range errors' σ (scatter 1.13 m vs SPP 0.98 m, measured)."""
    s = WALK["spp"]
    c = walk_white[0]
    assert np.hypot(*(c["mean"][:2] - s["mean"][:2])) < 1.0
    assert np.hypot(*c["mean"][:2]) > 7.0 and np.hypot(*s["mean"][:2]) > 7.0
    # with the carrier phase (issue 40) the tight offset is smaller than the SPP's (measured 8.37 vs 8.45 m)
    assert np.hypot(*WALK["tight"]["mean"][:2]) < np.hypot(*s["mean"][:2])
    c = walk_white[0]
    assert np.hypot(*c["std"][:2]) < np.hypot(*s["std"][:2])


def test_walk_tight_three_sigma_covers_the_horizontal_error(walk_default):
    """Honest covariance on the walk (issue 26): at every reference epoch (all qualities) inside the
    solution, the horizontal error is inside the 3σ envelope 3·√(σ_E² + σ_N²) of ``aidnav tight`` at
    ≥ 95 % of the epochs. The σ comes from the per-satellite range-error states with RTKLIB's published
    single-frequency budget (URA 2 m from the broadcast ephemeris, 5 m ionosphere as this navigation
    file has no Klobuchar coefficients, Saastamoinen residual, code bias: docs/models.md), nothing fitted
    here. Before: 0 % (σ 0.24/0.35 m vs an 8.5 m error). Measured: 100 % (median σ_h 12.8 m)."""
    from aidnav.filters.tight import to_trajectory
    from aidnav.nav.earth import lla_difference_enu

    res, ref = WALK["res"], WALK["ref"]
    tr = to_trajectory(res)
    m = (ref.time >= tr.time[0]) & (ref.time <= tr.time[-1])
    t = ref.time[m]
    la, lo = np.interp(t, tr.time, tr.lat), np.interp(t, tr.time, tr.lon)
    e, n, _ = lla_difference_enu(la, lo, 0.0 * la, ref.lat[m], ref.lon[m], 0.0 * la)
    sig = np.hypot(np.interp(t, tr.time, tr.std_pos[:, 0]), np.interp(t, tr.time, tr.std_pos[:, 1]))
    assert m.sum() > 500
    assert np.mean(np.hypot(e, n) <= 3.0 * sig) >= 0.95
