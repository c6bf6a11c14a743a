"""Automatic initialisation of the loosely coupled filter: gyrocompassing, course alignment, in-motion."""

from __future__ import annotations

import numpy as np

from aidnav.filters.config import LooseConfig
from aidnav.filters.loose import run_loose, to_trajectory
from aidnav.sim.run import simulate
from aidnav.sim.scenario import parse_scenario


def _scn(grade, segments, speed=0.0):
    return parse_scenario({
        "name": "align", "seed": 11, "imu_rate_hz": 100,
        "initial": {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 50.0, "speed_m_s": speed,
                    "heading_deg": 123.0},
        "segments": segments,
        "sensors": {"imu": {"grade": grade}, "gnss": {"rate_hz": 1, "sigma_pos_m": [0.3, 0.3, 0.6],
                                                      "sigma_vel_m_s": [0.03, 0.03, 0.05]}},
    })


def _heading_error_deg(traj, truth, t):
    i = np.searchsorted(traj.time, t)
    j = np.searchsorted(truth.time, t)
    return float((np.degrees(traj.rph[i, 2] - truth.rph[j, 2]) + 180) % 360 - 180)


def test_navigation_grade_gyrocompasses_before_moving():
    sim = simulate(_scn("navigation", [{"type": "static", "duration_s": 120},
                                       {"type": "accelerate", "duration_s": 10, "to_speed_m_s": 10},
                                       {"type": "straight", "duration_s": 20}]))
    cfg = LooseConfig.model_validate({
        "imu": {"arw_deg_sqrt_h": 0.002, "vrw_m_s_sqrt_h": 0.002, "gyro_bias_sigma_deg_h": 0.01,
                "accel_bias_sigma_ug": 20, "gyro_bias_tau_s": 0, "accel_bias_tau_s": 0},
        "init": {"static_window_s": 100}})
    events: list[str] = []
    r = run_loose(sim.imu, sim.gnss, cfg, events=events)
    assert any("gyrocompassing" in e for e in events), events
    assert not any("GNSS course" in e for e in events)
    # heading known to a fraction of a degree before the vehicle moves (ARW-limited gyrocompass)
    assert abs(_heading_error_deg(to_trajectory(r), sim.truth, 110.0)) < 0.5


def test_mems_grade_falls_back_to_course():
    sim = simulate(_scn("mems", [{"type": "static", "duration_s": 30},
                                 {"type": "accelerate", "duration_s": 10, "to_speed_m_s": 12},
                                 {"type": "turn", "angle_deg": 90, "duration_s": 15},
                                 {"type": "straight", "duration_s": 40}]))
    cfg = LooseConfig.model_validate({"init": {"static_window_s": 20, "course_min_speed_m_s": 2.0}})
    events: list[str] = []
    r = run_loose(sim.imu, sim.gnss, cfg, events=events)
    assert any("no gyrocompass heading" in e for e in events), events
    assert any("heading from GNSS course" in e for e in events), events
    assert abs(_heading_error_deg(to_trajectory(r), sim.truth, 90.0)) < 3.0


def test_in_motion_start_is_detected_and_converges():
    sim = simulate(_scn("tactical", [{"type": "accelerate", "duration_s": 20, "to_speed_m_s": 25},
                                     {"type": "turn", "angle_deg": 120, "duration_s": 20},
                                     {"type": "straight", "duration_s": 30},
                                     {"type": "turn", "angle_deg": -120, "duration_s": 20},
                                     {"type": "straight", "duration_s": 30}], speed=5.0))
    cfg = LooseConfig.model_validate({"init": {"static_window_s": 10, "course_min_speed_m_s": 3.0},
                                      "imu": {"arw_deg_sqrt_h": 0.1, "vrw_m_s_sqrt_h": 0.05,
                                              "gyro_bias_sigma_deg_h": 3, "accel_bias_sigma_ug": 300}})
    events: list[str] = []
    r = run_loose(sim.imu, sim.gnss, cfg, events=events)
    assert any("in-motion start" in e for e in events), events
    traj = to_trajectory(r)
    assert abs(_heading_error_deg(traj, sim.truth, 115.0)) < 1.0
