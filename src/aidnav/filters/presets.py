"""Vehicle presets of the loose filter (``aidnav process --vehicle NAME``): constraints and default
noise for a kind of vehicle, applied over a configuration by :func:`apply_preset`.

No preset means the conservative defaults of :class:`aidnav.filters.config.LooseConfig` (no vehicle
constraint, consumer-MEMS noise). Every number below is physics of the vehicle kind, not a fit:

* ``car``: the non-holonomic constraint (a wheeled vehicle does not slide sideways or jump: lateral
  and vertical velocity σ 0.05 m/s at the axle, above 1 m/s); the IMU → rear-axle lever arm is not
  known, so its ω × l enters the NHC variance with σ 1 m per axis (an IMU anywhere in a car body is
  within about a metre of the rear axle centre, in height and along the car); the mounting angles
  are estimated (3° σ); ZUPT at standstill; heading from the course above 2 m/s (a car's course equals
  its heading without slip); the IMU noise is raised to what the log's static samples show
  (:func:`aidnav.filters.preprocess.noise_from_static`: a running engine vibrates the IMU far above its
  datasheet noise, and the filter must cover it).
* ``aircraft`` (a fixed-wing aircraft): no NHC (aircraft sideslip and climb); ZUPT kept (a parked
  aircraft is still, and the static test needs both IMU and GNSS); heading from the course above 2 m/s
  with σ 10°: below its take-off speed a fixed-wing aircraft rolls on its wheels and its course is its
  heading (nose-wheel steering, no crab on the ground), and 10° covers a log that starts airborne (crab
  asin(w/V): 11° in a 20-kn crosswind at 100 kn). Before (issue 35, session 9) the course aligned only
  above 15 m/s: a log that never went faster (the consistency matrix's 10 m/s car) navigated with an
  unknown heading throughout, E/N 3σ coverage 17–60 %.
* ``pedestrian``: no NHC (people side-step), ZUPT on (standing still), heading from the course above
  1 m/s with σ 30° (a walker's body need not face the walking direction; a phone even less).
* ``ship``: no NHC (leeway and currents), no ZUPT (a ship at anchor still heaves), heading from the
  course above 2 m/s with σ 15° (drift angle).

The IMU noise is raised to what the log's static samples show in every preset (engine vibration; a hand
holding a phone adds its tremor, which stays while walking: the filter must cover it; also the loose
filter's default without a preset when the configuration has no imu section, issue 35); no preset states
an IMU error model (a vehicle kind says nothing of the IMU's grade: the default model applies). Every
preset re-initialises when the NIS of the last 10 accepted fixes of a type is far out of its χ² band
(``gnss.nis_window``; off without a preset, where the filter keeps the configured model, unless the log
shows a wheeled vehicle: :mod:`aidnav.filters.wheeled`); such a re-initialisation scales the navigation
block, the IMU's sensor-error states and the calibration states by the window's mean NIS per dof (each
sensor-error and calibration state at most back to its prior: a calibration is repaired with the
navigation, never thrown away, issue 35 item 5; :func:`aidnav.filters.loose._reinit_cal`). Each preset
states what the vehicle can do (``motion``: speed, acceleration, turn-rate and tilt bounds), which sizes
the covariance an IMU gap adds (:func:`aidnav.filters.preprocess.bridge_gaps`); without a preset the
bounds of an unknown vehicle (:class:`aidnav.filters.config.MotionBounds`).
"""

from __future__ import annotations

from .config import DEFAULT_IMU, LooseConfig

PRESETS: dict[str, dict] = {
    "car": {
        "constraints": {"nhc": True, "nhc_sigma_m_s": 0.05, "nhc_min_speed_m_s": 1.0,
                        "nhc_lever_arm_sigma_m": 1.0, "zupt": True},
        "calibration": {"mounting": True, "mounting_sigma_deg": 3.0},
        "init": {"course_min_speed_m_s": 2.0, "course_heading_sigma_deg": 5.0},
        "imu": {"noise_from_static": True},
        "gnss": {"nis_window": 10},
        # a road car: 250 km/h, 1 g braking or cornering, 60 deg/s yaw (parking), body roll/pitch 10 deg
        "motion": {"max_speed_m_s": 70.0, "max_accel_m_s2": 10.0, "max_turn_rate_deg_s": 60.0,
                   "max_tilt_deg": 10.0},
    },
    "aircraft": {
        "constraints": {"nhc": False, "zupt": True},
        # below its take-off speed a fixed-wing aircraft rolls on its wheels: its course is its heading
        # (nose-wheel steering, no crab on the ground), so the course aligns it from taxi speed as a car's
        # does; σ 10° covers a log that starts airborne (crab asin(w/V): 11° in a 20-kn crosswind at 100 kn)
        "init": {"course_min_speed_m_s": 2.0, "course_heading_sigma_deg": 10.0},
        "imu": {"noise_from_static": True},
        "gnss": {"nis_window": 10},
        # 300 m/s, 3 g, 45 deg/s roll or turn, any attitude
        "motion": {"max_speed_m_s": 300.0, "max_accel_m_s2": 30.0, "max_turn_rate_deg_s": 45.0,
                   "max_tilt_deg": 90.0},
    },
    "pedestrian": {
        "constraints": {"nhc": False, "zupt": True},
        "init": {"course_min_speed_m_s": 1.0, "course_heading_sigma_deg": 30.0},
        # the IMU's white noise is what its static samples show, whatever carries it (a hand holding a
        # phone adds its tremor: larger, and the filter must cover it while walking too)
        "imu": {"noise_from_static": True},
        "gnss": {"nis_window": 10},
        # a runner at 10 m/s, 1 g, a body (or a phone) turned by 360 deg/s, held at any angle
        "motion": {"max_speed_m_s": 10.0, "max_accel_m_s2": 10.0, "max_turn_rate_deg_s": 360.0,
                   "max_tilt_deg": 90.0},
    },
    "ship": {
        "constraints": {"nhc": False, "zupt": False},
        "init": {"course_min_speed_m_s": 2.0, "course_heading_sigma_deg": 15.0},
        "imu": {"noise_from_static": True},
        "gnss": {"nis_window": 10},
        # 25 m/s, 0.2 g, 10 deg/s rate of turn, rolling by 30 deg
        "motion": {"max_speed_m_s": 25.0, "max_accel_m_s2": 2.0, "max_turn_rate_deg_s": 10.0,
                   "max_tilt_deg": 30.0},
    },
}

__all__ = ["PRESETS", "apply_preset", "preset_names"]


def preset_names() -> list[str]:
    """Names accepted by :func:`apply_preset`."""
    return sorted(PRESETS)


def apply_preset(cfg: LooseConfig | None, name: str | None) -> LooseConfig:
    """``cfg`` (default: :class:`LooseConfig`) with the preset ``name`` applied under it: a key the
    configuration states explicitly (in its YAML) wins over the preset; ``None`` returns ``cfg``
    unchanged. Unknown names raise ValueError naming the known ones."""
    cfg = cfg if cfg is not None else LooseConfig()
    if name is None:
        return cfg
    if name not in PRESETS:
        raise ValueError(f"--vehicle {name!r}: unknown vehicle; known: {', '.join(preset_names())}")
    data = cfg.model_dump(exclude_unset=True)
    merged: dict = {}
    for section, vals in PRESETS[name].items():
        merged[section] = dict(vals)
    if "imu" not in data:  # no imu section: the default model under the preset's keys (config.DEFAULT_IMU)
        merged["imu"] = {**DEFAULT_IMU, **merged.get("imu", {})}
    for section, vals in data.items():
        if isinstance(vals, dict):
            merged.setdefault(section, {}).update(vals)
        else:
            merged[section] = vals
    return LooseConfig.model_validate(merged)
