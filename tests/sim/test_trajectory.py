"""Segment compilation: the five motion modes of seed 004 Table 3 and IMU increment consistency."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from aidnav.nav.earth import gravity
from aidnav.sim.scenario import ScenarioError, load_scenario, parse_scenario
from aidnav.sim.trajectory import compile_segments, generate_truth, segment_interval

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

# Table 3 (seed 004): (name, start, end) of every leg
TABLE3 = {
    "none": [("AB", 0, 400), ("U", 400, 600), ("CD", 600, 1000)],
    "s_turns": [("lead_in", 0, 100), ("S", 100, 800), ("AB", 800, 1200), ("U", 1200, 1400),
                ("CD", 1400, 1800)],
    "o_circle": [("lead_in", 0, 100), ("O", 100, 500), ("AB", 500, 900), ("U", 900, 1100),
                 ("CD", 1100, 1500)],
    "figure8": [("lead_in", 0, 100), ("8", 100, 1000), ("AB", 1000, 1400), ("U", 1400, 1600),
                ("CD", 1600, 2000)],
    "climb": [("climb", 0, 500), ("AB", 500, 900), ("U", 900, 1100), ("CD", 1100, 1500)],
}
# headings [deg] on the AB and CD legs
LEG_HEADING = {"none": (40, 220), "s_turns": (40, 220), "o_circle": (40, 220), "figure8": (40, 220),
               "climb": (130, 310)}
EDGE = 3.0  # s kept away from segment boundaries (transition half-width 2 s)


@pytest.fixture(scope="module")
def runs():
    out = {}
    for mode in TABLE3:
        scn = load_scenario(EXAMPLES / f"{mode}.yaml")
        truth, imu, table = generate_truth(scn)
        out[mode] = (scn, truth, imu, table)
    return out


def _hdg(truth):
    """Unwrapped heading [deg]."""
    return np.degrees(np.unwrap(truth.rph[:, 2]))


def _at(truth, t):
    return int(round(t / (truth.time[1] - truth.time[0])))


def _window(truth, t0, t1):
    return slice(_at(truth, t0), _at(truth, t1) + 1)


@pytest.mark.parametrize("mode", list(TABLE3))
def test_segment_timings_and_time_grid(runs, mode):
    scn, truth, imu, table = runs[mode]
    assert [(r["name"], r["start_s"], r["end_s"]) for r in table] == [(n, float(a), float(b))
                                                                       for n, a, b in TABLE3[mode]]
    T = TABLE3[mode][-1][2]
    n = int(T * 100)
    assert len(truth) == n + 1 and len(imu) == n
    np.testing.assert_allclose(truth.time, np.arange(n + 1) * 0.01, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(imu.time, truth.time[1:])
    assert imu.t0 == 0.0
    assert np.all((truth.rph[:, 2] >= 0) & (truth.rph[:, 2] < 2 * np.pi))
    assert segment_interval(table, "CD") == (float(TABLE3[mode][-1][1]), float(T))
    with pytest.raises(KeyError, match="no segment named"):
        segment_interval(table, "XY")


@pytest.mark.parametrize("mode", list(TABLE3))
def test_u_turn_is_180_and_legs_straight_and_level(runs, mode):
    scn, truth, imu, table = runs[mode]
    h = _hdg(truth)
    u0, u1 = segment_interval(table, "U")
    dpsi = h[_at(truth, u1 + EDGE)] - h[_at(truth, u0 - EDGE)]
    assert abs(dpsi - 180.0) < 0.01
    for leg, want in zip(("AB", "CD"), LEG_HEADING[mode], strict=True):
        a, b = segment_interval(table, leg)
        w = _window(truth, a + EDGE, b - EDGE)
        hw = np.mod(h[w], 360.0)
        assert np.ptp(hw) < 1e-6, leg
        assert abs(hw.mean() - want) < 1e-6, (leg, hw.mean())
        # level: no climb, zero pitch and roll
        assert np.max(np.abs(truth.vel[w, 2])) < 1e-9
        assert np.ptp(truth.height[w]) < 1e-6
        assert np.max(np.abs(truth.rph[w, :2])) < 1e-9
        np.testing.assert_allclose(np.hypot(truth.vel[w, 0], truth.vel[w, 1]), 100.0, atol=1e-9)
    # the U-turn itself: constant 0.9 deg/s with the coordinated bank
    w = _window(truth, u0 + EDGE, u1 - EDGE)
    rate = np.diff(h[w]) / 0.01
    np.testing.assert_allclose(rate, 0.9, atol=1e-6)
    bank = np.degrees(np.arctan(100.0 * np.radians(0.9) / 9.80665))
    np.testing.assert_allclose(np.degrees(truth.rph[w, 0]), bank, atol=1e-9)


def test_none_mode_single_turn(runs):
    scn, truth, imu, table = runs["none"]
    h = _hdg(truth)
    assert abs(h[-1] - h[0] - 180.0) < 0.01
    assert np.all(np.diff(h) >= -1e-12)  # clockwise only
    assert np.ptp(truth.height) < 1e-6


def test_s_turns_swing_and_net_zero(runs):
    scn, truth, imu, table = runs["s_turns"]
    h = _hdg(truth)
    a, b = segment_interval(table, "S")
    w = _window(truth, a, b)
    dev = h[w] - 40.0
    assert 29.5 < dev.max() <= 30.0 + 1e-9
    assert -30.0 - 1e-9 <= dev.min() < -29.5
    assert abs(h[_at(truth, b + EDGE)] - h[_at(truth, a - EDGE)]) < 0.01
    # two cycles: the heading crosses the entry heading going right at the start of each cycle
    up = np.flatnonzero((dev[:-1] < 0) & (dev[1:] >= 0))
    assert len(up) == 1  # the 2nd cycle starts at 450 s (the 1st at the segment start)
    assert abs(truth.time[w][up[0]] - 450.0) < 1.0
    assert np.ptp(truth.height) < 1e-6


def test_o_circle_360(runs):
    scn, truth, imu, table = runs["o_circle"]
    h = _hdg(truth)
    a, b = segment_interval(table, "O")
    assert abs(h[_at(truth, b + EDGE)] - h[_at(truth, a - EDGE)] - 360.0) < 0.01


def test_figure8_two_opposite_circles(runs):
    scn, truth, imu, table = runs["figure8"]
    h = _hdg(truth)
    a, b = segment_interval(table, "8")
    w = _window(truth, a - EDGE, b + EDGE)
    total = np.sum(np.abs(np.diff(h[w])))
    assert total >= 720.0 - 0.01
    assert abs(total - 720.0) < 0.01
    assert abs(h[w][-1] - h[w][0]) < 0.01
    # first circle right (+360), second left
    mid = _at(truth, 0.5 * (a + b))
    assert abs(h[mid] - h[_at(truth, a - EDGE)] - 360.0) < 0.01
    assert np.ptp(truth.height) < 1e-6


def test_climb(runs):
    scn, truth, imu, table = runs["climb"]
    seg = scn.segments[0]
    a, b = segment_interval(table, "climb")
    gain = truth.height[_at(truth, b + EDGE)] - truth.height[0]
    # 5 m/s vertical while climbing; the pull-up and push-over (pull_s each) cost pull_s x 5 m
    assert abs(gain - 5.0 * (500.0 - seg.pull_time_s)) < 0.005 * 2500
    assert abs(gain - 5.0 * 500.0) < 0.025 * 2500
    w = _window(truth, a + seg.pull_time_s + EDGE, b - seg.pull_time_s - EDGE)
    np.testing.assert_allclose(truth.vel[w, 2], 5.0, atol=1e-9)
    np.testing.assert_allclose(np.degrees(truth.rph[w, 1]), np.degrees(np.arcsin(0.05)), atol=1e-9)
    h = _hdg(truth)
    assert abs(h[_at(truth, b + EDGE)] - h[0] - 90.0) < 0.01  # the gentle turn
    assert np.max(np.abs(np.degrees(truth.rph[w, 0]))) < 3.0


def test_imu_increments_straight_level(runs):
    scn, truth, imu, table = runs["figure8"]
    a, b = segment_interval(table, "AB")
    k = slice(_at(truth, a + EDGE), _at(truth, b - EDGE))  # imu index k covers (t_k, t_k+1]
    dt = 0.01
    g = gravity(truth.lat[k], truth.height[k])
    # accelerometer z ≈ g·dt (plus Coriolis/centripetal terms of order 1e-2 m/s²)
    np.testing.assert_allclose(imu.dv[k, 2] / dt, g, atol=2e-2)
    assert np.max(np.abs(imu.dv[k, :2] / dt)) < 2e-2
    # gyros: Earth rate + transport rate only (< 1e-4 rad/s)
    assert np.max(np.abs(imu.dtheta[k] / dt)) < 1e-4


def test_imu_increments_mechanize_back_to_truth():
    """Integrating the exact increments with the strapdown reproduces the truth (short turn + climb)."""
    from aidnav.nav.rotations import quat_from_euler
    from aidnav.nav.strapdown import make_state, mechanize

    scn = parse_scenario({
        "initial": {"lat_deg": 40, "lon_deg": 116, "height_m": 1000, "speed_m_s": 80, "heading_deg": 40},
        "segments": [{"type": "straight", "duration_s": 10},
                     {"type": "turn", "angle_deg": 90, "duration_s": 30},
                     {"type": "climb", "duration_s": 40, "flight_path_deg": 5, "angle_deg": -30},
                     {"type": "accelerate", "duration_s": 10, "accel_m_s2": 2}],
    })
    truth, imu, _ = generate_truth(scn)
    q0 = quat_from_euler(*truth.rph[0])
    st0 = make_state(truth.lat[0], truth.lon[0], truth.height[0], truth.vel[0], q0)
    out = mechanize(imu.time, imu.dtheta, imu.dv, st0, imu.t0, np.empty(0), np.empty(0))
    from aidnav.nav.rotations import attitude_error_batch, euler_to_quat_batch

    phi = attitude_error_batch(out[:, 6:10], euler_to_quat_batch(truth.rph[1:]))
    assert np.max(np.abs(phi)) < 1e-6
    assert np.max(np.abs(out[:, 3:6] - truth.vel[1:])) < 1e-3
    assert np.max(np.abs(out[:, 2] - truth.height[1:])) < 0.05


def test_accelerate_and_radius_turn():
    scn = parse_scenario({
        "initial": {"lat_deg": 10, "lon_deg": 20, "speed_m_s": 0, "heading_deg": 0},
        "transition_s": 2,
        "segments": [{"type": "static", "duration_s": 5},
                     {"type": "accelerate", "duration_s": 10, "to_speed_m_s": 20},
                     {"type": "turn", "angle_deg": -90, "radius_m": 200, "name": "t"},
                     {"type": "accelerate", "duration_s": 10, "accel_m_s2": -2}],
    })
    truth, imu, table = generate_truth(scn)
    spd = np.linalg.norm(truth.vel, axis=1)
    assert spd[0] == 0.0 and abs(spd[_at(truth, 14)] - 18.0) < 1e-6
    a, b = segment_interval(table, "t")
    assert abs((b - a) - np.pi / 2 * 200 / 20) < 1e-9  # duration = |angle| R / V
    h = _hdg(truth)
    assert abs(h[_at(truth, b + 1.5)] - h[_at(truth, a - 1.5)] + 90.0) < 0.01
    # the run ends at the last whole IMU interval (40.70 s of 40.708 s): speed 2 m/s² x 8 ms
    assert abs(spd[-1] - 2.0 * (25.0 + np.pi / 2 * 10 - truth.time[-1])) < 1e-6
    # standing still: specific force = gravity up, gyros = Earth rate
    k = slice(0, _at(truth, 4))
    np.testing.assert_allclose(np.linalg.norm(imu.dtheta[k], axis=1) / 0.01, 7.2921151467e-5, rtol=1e-9)


def test_motion_errors():
    base = {"initial": {"lat_deg": 0, "lon_deg": 0, "speed_m_s": 0}}
    with pytest.raises(ScenarioError, match=r"segments\.0: turn: needs a speed > 0"):
        generate_truth(parse_scenario({**base, "segments": [
            {"type": "turn", "angle_deg": 90, "duration_s": 9}]}))
    with pytest.raises(ScenarioError, match="segments.1.*negative"):
        generate_truth(parse_scenario({**base, "segments": [
            {"type": "static", "duration_s": 1}, {"type": "accelerate", "duration_s": 5, "accel_m_s2": -1}]}))
    moving = {"initial": {"lat_deg": 0, "lon_deg": 0, "speed_m_s": 10}}
    with pytest.raises(ScenarioError, match="static.*moving"):
        generate_truth(parse_scenario({**moving, "segments": [{"type": "static", "duration_s": 1}]}))
    with pytest.raises(ScenarioError, match="vertical_speed_m_s"):
        compile_segments(parse_scenario({**moving, "segments": [
            {"type": "climb", "duration_s": 50, "vertical_speed_m_s": 12}]}))
