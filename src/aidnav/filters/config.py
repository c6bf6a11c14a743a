"""Configuration of the loosely coupled filter (pydantic; units in every key name).

Every section forbids unknown keys, so a typo gives an error that names the key. Defaults suit a
consumer-grade MEMS IMU with a 1-10 Hz GNSS receiver (what ``aidnav process`` assumes without
``--config``; it prints what it assumed).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from aidnav.units import DEG, DEG_H, UG  # noqa: F401  (re-exported: the filters import them from here)


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class ImuNoise(_Strict):
    """IMU noise and sensor-error model of the filter (boundary units)."""

    arw_deg_sqrt_h: float = Field(0.3, gt=0, description="angle random walk [deg/sqrt(h)]")
    vrw_m_s_sqrt_h: float = Field(0.1, gt=0, description="velocity random walk [m/s/sqrt(h)]")
    gyro_bias_sigma_deg_h: float = Field(100.0, ge=0, description="initial/steady gyro bias 1σ [deg/h]")
    accel_bias_sigma_ug: float = Field(5000.0, ge=0, description="initial/steady accel bias 1σ [µg]")
    gyro_bias_tau_s: float = Field(3600.0, description="gyro bias correlation time [s]; <=0: random walk")
    accel_bias_tau_s: float = Field(3600.0, description="accel bias correlation time [s]; <=0: random walk")
    gyro_bias_instability_deg_h: float | None = Field(
        None, ge=0, description="steady-state σ of the Gauss-Markov bias driving noise [deg/h] "
        "(q = 2σ²/τ); None: gyro_bias_sigma_deg_h")
    accel_bias_instability_ug: float | None = Field(
        None, ge=0,
        description="steady-state σ of the Gauss-Markov accel bias [µg]; None: accel_bias_sigma_ug")
    gyro_bias_rw_deg_h_sqrt_h: float = Field(
        0.0, ge=0, description="gyro bias random-walk [deg/h/sqrt(h)], used when gyro_bias_tau_s <= 0")
    accel_bias_rw_ug_sqrt_h: float = Field(
        0.0, ge=0, description="accel bias random-walk [µg/sqrt(h)], used when accel_bias_tau_s <= 0")
    scale_factors: bool = Field(False, description="estimate gyro and accel scale factors (21 states)")
    gyro_sf_sigma_ppm: float = Field(1000.0, ge=0)
    accel_sf_sigma_ppm: float = Field(1000.0, ge=0)
    sf_tau_s: float = Field(0.0, description="scale-factor correlation time [s]; <=0: random constant")
    gyro_misalignment: bool = Field(
        False, description="estimate the gyro triad's misalignment (6 random constants m_ij: the rate about "
        "axis j read on axis i; 27 states, with the scale factors): a consumer IMU's tenths of a degree "
        "tilt the solution in every turn")
    gyro_misalignment_sigma_deg: float = Field(0.5, ge=0, description="1σ of each misalignment entry [deg]")
    accel_misalignment: bool = Field(
        False, description="estimate the accelerometer triad's misalignment (6 random constants m_ij: the "
        "specific force along axis j read on axis i; 33 states, after the gyro's): a consumer IMU's "
        "tenths of a degree turn every acceleration into a tilt-like vertical/lateral error; off, the "
        "accel bias σ has to cover m·g")
    accel_misalignment_sigma_deg: float = Field(0.5, ge=0, description="1σ of each accelerometer "
                                                "misalignment entry [deg]")
    noise_from_static: bool = Field(
        False, description="raise the ARW / VRW not stated here to the white-noise equivalent of the rates' "
        "spread at the log's static samples (engine vibration; filters.preprocess.noise_from_static); on "
        "in the loose filter without an imu section in the configuration (issue 35: a vibrating IMU's noise "
        "is unknown until the log shows it) and in the engine-driven vehicle presets")
    grade_from_static: bool = Field(
        False, description="class the IMU by the bias components its longest static run measures (gyro "
        "vertical and horizontal against the Earth rate, accelerometer vertical against gravity) and take "
        "the bias, instability, scale-factor and misalignment model of the posterior mixture of the grades "
        "the data leave possible (filters.grade); on without an imu section in the loose filter (issue 35)")
    time_offset_s: float = Field(0.0, description="added to IMU time stamps (IMU clock → GNSS time)")
    mounting_rph_deg: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="IMU body → vehicle frame rotation as roll, pitch, heading [deg] "
        "(C_b^v = C(r,p,h)^T); used by the non-holonomic constraint")

    @property
    def nins(self) -> int:
        """Size of the INS error block this section asks for: 15, 21 (scale factors), 27 (and the gyro
        misalignment) or 33 (and the accelerometer misalignment)."""
        if self.accel_misalignment:
            return 33
        return 27 if self.gyro_misalignment else (21 if self.scale_factors else 15)


class GnssAiding(_Strict):
    """How GNSS fixes are used."""

    lever_arm_m: tuple[float, float, float] = Field((0.0, 0.0, 0.0), description="IMU→antenna, body RFU [m]")
    use: Literal["both", "position", "velocity"] = "both"
    pos_std_scale: float = Field(1.0, gt=0, description="multiplies the receiver's σ")
    pos_std_scale_up: float = Field(1.0, gt=0, description="multiplies the vertical σ too (after "
                                    "pos_std_scale); both unstated: measured (aidnav.filters.gnss_errors)")
    vel_std_scale: float = Field(1.0, gt=0)
    min_pos_std_m: float = Field(0.05, gt=0, description="floor on position σ [m]")
    min_vel_std_m_s: float = Field(0.02, gt=0, description="floor on velocity σ [m/s]")
    default_pos_std_m: tuple[float, float, float] = (1.0, 1.0, 2.0)
    default_vel_std_m_s: tuple[float, float, float] = (0.1, 0.1, 0.2)
    float_std_factor: float = Field(2.0, gt=0, description="σ multiplier for RTK-float epochs (Q = 2); "
                                    "the quality rules: aidnav.io._std")
    single_std_factor: float = Field(5.0, gt=0, description="σ multiplier for single epochs (Q = 5 only; "
                                     "fixed, SBAS, DGPS, PPP: 1)")

    @property
    def pos_std_scales(self) -> tuple[float, float, float]:
        """The factors on the fixes' E, N, U position σ (``pos_std_scale``, ``pos_std_scale_up``)."""
        s = float(self.pos_std_scale)
        return s, s, s * float(self.pos_std_scale_up)
    height_offset_m: float = Field(0.0, description="added to GNSS heights (e.g. MSL → ellipsoidal) where "
                                   "the file does not declare ellipsoidal heights (aidnav.io.formats)")
    gate_probability: float = Field(0.9999, gt=0, le=1, description="chi-square gate; 1 disables")
    max_consecutive_rejections: int = Field(10, ge=1, description="then the filter re-initialises: its "
                                            "position/velocity/attitude covariance is inflated to the "
                                            "innovation and the fix accepted")
    nis_window: int = Field(0, ge=0, le=64, description="re-initialise as well when the sum of the NIS of "
                            "the last N accepted fixes of a type is above the 99.9 % quantile of chi-square "
                            "(N x dof), P's navigation block, IMU sensor errors and calibration then "
                            "scaled by the window's mean NIS per dof; 0: off (the vehicle presets, and no "
                            "option on a wheeled vehicle: 10)")
    error_tau_s: float = Field(0.0, ge=0, description="correlation time of the fixes' position errors [s]: "
                               "> 0 adds 3 first-order Gauss-Markov error states (high-rate receivers whose "
                               "errors are not white); 0: white errors")
    error_sigma_m: tuple[float, float, float] = Field(
        (0.5, 0.5, 1.0), description="steady-state σ of the correlated error E, N, U [m] (with error_tau_s); "
        "the receiver's σ (row) is then the white part")


class Initialisation(_Strict):
    """Initial state: given, or automatic (static coarse alignment + heading from GNSS course)."""

    mode: Literal["auto", "given"] = "auto"
    lat_deg: float | None = None
    lon_deg: float | None = None
    height_m: float | None = None
    velocity_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    roll_deg: float | None = None
    pitch_deg: float | None = None
    heading_deg: float | None = None
    position_sigma_m: tuple[float, float, float] = (1.0, 1.0, 2.0)
    velocity_sigma_m_s: tuple[float, float, float] = (0.1, 0.1, 0.1)
    attitude_sigma_deg: tuple[float, float, float] = (2.0, 2.0, 10.0)
    static_window_s: float = Field(20.0, gt=0, description="window of the static coarse alignment [s]")
    course_min_speed_m_s: float = Field(3.0, gt=0, description="speed for heading from GNSS course")
    course_heading_sigma_deg: float = Field(5.0, gt=0)


class Constraints(_Strict):
    """Vehicle aids: zero-velocity updates and the non-holonomic constraint (cars)."""

    zupt: bool = True
    zupt_sigma_m_s: float = Field(0.02, gt=0)
    zaru_sigma_deg_s: float = Field(0.0, ge=0, description="zero angular rate update σ; 0 = off")
    static_gnss_speed_m_s: float = Field(0.1, gt=0, description="GNSS speed below which it may be static")
    static_gyro_std_deg_s: float = Field(5.0, gt=0, description="gyro std over 1 s below which static")
    static_accel_std_m_s2: float = Field(0.5, gt=0, description="accel std over 1 s below which static")
    nhc: bool = False
    nhc_sigma_m_s: float = Field(0.1, gt=0)
    nhc_min_speed_m_s: float = Field(1.0, ge=0)
    nhc_lever_arm_m: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="IMU → constrained point (rear axle), body RFU [m]")
    nhc_lever_arm_sigma_m: float = Field(
        0.0, ge=0, description="1σ per axis of the unknown part of nhc_lever_arm_m [m]: the constrained "
        "velocity ω × l it causes is added to the NHC variance")


class Calibration(_Strict):
    """Self-calibration states of the loose filter. Each switch is ``true`` (estimate), ``false`` (the
    configured value is exact) or unset (automatic, where observable):

    * ``time_offset`` (IMU–GNSS, added to the IMU stamps, starting at ``imu.time_offset_s``): automatic =
      estimated when GNSS velocity is used (the offset is seen through the acceleration, a·δt; with
      positions alone only through v·δt against the position σ) and ``imu.time_offset_s`` is not given;
    * ``lever_arm`` (IMU → antenna): automatic = estimated unless ``gnss.lever_arm_m`` is given;
    * ``mounting`` (IMU → vehicle, about the vehicle axes): automatic = estimated with the NHC or an
      odometer (without them it is not observable; a mounting off by a degree biases every NHC update).
    * ``velocity_delay`` (the receiver's velocity describes its stamp − τ, e.g. a Doppler or
      position-difference average, while the position is at the stamp): automatic = with the time offset.
    Each state starts at the configured value (0 for the velocity delay) with the given 1σ."""

    time_offset: bool | None = Field(None, description="estimate the IMU-GNSS time offset (None: auto)")
    time_offset_sigma_s: float = Field(0.2, gt=0, description="initial 1σ of the time offset [s]")
    time_offset_rw_s_sqrt_s: float = Field(0.0, ge=0, description="random walk of the offset [s/sqrt(s)]")
    lever_arm: bool | None = Field(None, description="estimate the IMU → antenna lever arm (None: auto)")
    lever_arm_sigma_m: float = Field(0.3, gt=0, description="initial 1σ per axis of the lever arm [m]")
    mounting: bool | None = Field(None, description="estimate the IMU → vehicle mounting (None: auto)")
    mounting_sigma_deg: float = Field(3.0, gt=0, description="initial 1σ per axis of the mounting [deg]")
    velocity_delay: bool | None = Field(None, description="estimate a delay of the GNSS velocity relative "
                                        "to its position (None: auto = with the time offset)")
    velocity_delay_sigma_s: float = Field(0.1, gt=0, description="initial 1σ of the velocity delay [s]")


class OdometerAiding(_Strict):
    """Odometer (wheel speed) updates, used when odometer data are given to the filter."""

    sigma_m_s: float = Field(0.05, gt=0, description="speed σ when the data carry none [m/s]")
    scale_factor: bool = Field(True, description="estimate the odometer scale factor (one state)")
    scale_factor_sigma_ppm: float = Field(10000.0, ge=0, description="initial scale-factor σ [ppm]")
    scale_factor_tau_s: float = Field(0.0, description="correlation time [s]; <=0: random constant")
    scale_factor_instability_ppm: float = Field(0.0, ge=0, description="Gauss-Markov σ (with tau > 0)")
    lever_arm_m: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="IMU → wheel contact point (rear axle centre), body RFU [m]")


class BaroAiding(_Strict):
    """Barometric height updates, used when barometer data are given to the filter."""

    sigma_m: float = Field(0.5, gt=0, description="height σ when the data carry none [m]")
    bias: bool = Field(True, description="estimate the barometer bias (one state)")
    bias_sigma_m: float = Field(10.0, ge=0, description="initial bias σ [m]")
    bias_tau_s: float = Field(0.0, description="correlation time [s]; <=0: random walk")
    bias_instability_m: float = Field(0.0, ge=0, description="Gauss-Markov σ [m] (with tau > 0)")
    bias_rw_m_sqrt_s: float = Field(0.001, ge=0, description="random walk [m/sqrt(s)] (tau <= 0)")


class MotionBounds(_Strict):
    """What the vehicle can do (§ IMU gaps): the bounds that size the covariance an IMU gap adds, since
    the motion inside it is not measured. Defaults: an unknown vehicle (a drone, a car or a person may
    carry the IMU), so generous; the vehicle presets state their own."""

    max_speed_m_s: float = Field(100.0, gt=0, description="largest speed [m/s]")
    max_accel_m_s2: float = Field(20.0, gt=0, description="largest horizontal/vertical acceleration [m/s^2]")
    max_turn_rate_deg_s: float = Field(180.0, gt=0, description="largest turn rate [deg/s]")
    max_tilt_deg: float = Field(45.0, gt=0, description="largest change of roll/pitch within a gap [deg]")
    heading_hold_deg: float = Field(
        30.0, gt=0, description="after an IMU gap that leaves the heading σ above this, the heading is held "
        "unknown (no correlation, nothing learnt from it) until a GNSS course re-aligns it")


class MagAiding(_Strict):
    """Magnetometer heading updates, used when heading data are given to the filter (``--aid mag=FILE``)."""

    sigma_deg: float = Field(3.0, gt=0, description="heading σ when the data carry none [deg]")
    declination_deg: float = Field(0.0, description="magnetic declination, east positive [deg]: the reader "
                                   "adds it to the magnetic headings (true = magnetic + declination)")


class FilterSettings(_Strict):
    states: Literal[15, 21, 27, 33] | None = None  # from imu.scale_factors, gyro/accel_misalignment when None
    prop_dt_s: float = Field(1.0, gt=0, description="max covariance propagation interval [s]")
    output_rate_hz: float | None = Field(None, description="output rate; None = every IMU sample")


#: An IMU error model for an IMU of unknown grade (issue 35; measured as the default without an ``imu``
#: section and under the presets, then not made the default: docs/results.md, issue 35 session 8): the
#: filter must not claim an accuracy a consumer IMU cannot give. Use: ``LooseConfig(imu=ImuNoise(
#: **UNKNOWN_GRADE_IMU))``. The numbers are the ``consumer`` row of the project's grade table
#: (:meth:`aidnav.sim.imu.ImuSpec.grade`: representative values of Groves §4.4's consumer range, not
#: fitted to any log) turned into the filter's model by the rules of
#: :func:`aidnav.filters.tuning.sensor_error_model`: gyro bias 360 deg/h turn-on ⊕ 20 deg/h instability;
#: accelerometer bias 10 mg turn-on ⊕ 0.5 mg instability ⊕ the 0.5° misalignment × 1 g; each instability
#: (τ 100 s) as the random walk of PSD 2σ²/τ; scale factors 5000 ppm and gyro misalignment 0.5° as states
#: (27 states). ARW and VRW are not stated here (a stated one is kept as given): the field defaults, raised
#: to what the log's static samples show (``noise_from_static``: a vibrating IMU's noise is the log's).
UNKNOWN_GRADE_IMU: dict = dict(
    gyro_bias_sigma_deg_h=float(np.hypot(360.0, 20.0)),
    accel_bias_sigma_ug=float(np.sqrt(10000.0 ** 2 + 500.0 ** 2 + (np.radians(0.5) * 1e6) ** 2)),
    gyro_bias_tau_s=0.0, accel_bias_tau_s=0.0,
    gyro_bias_rw_deg_h_sqrt_h=float(np.sqrt(2.0 * 20.0 ** 2 / 100.0) * 60.0),
    accel_bias_rw_ug_sqrt_h=float(np.sqrt(2.0 * 500.0 ** 2 / 100.0) * 60.0),
    scale_factors=True, gyro_sf_sigma_ppm=5000.0, accel_sf_sigma_ppm=5000.0,
    gyro_misalignment=True, gyro_misalignment_sigma_deg=0.5,
    noise_from_static=True,
)
#: :data:`UNKNOWN_GRADE_IMU` with the accelerometer misalignment (the same consumer row's 0.5°) as 6 states
#: instead of folded into the bias σ (which is then 10 mg ⊕ 0.5 mg): the tightly coupled filter's model
#: under a vehicle preset without the NHC (aircraft, pedestrian, ship; issue 35 session 16). The fold, m·g
#: in the bias, is exact while the specific force is gravity alone; in a turn the misalignment acts on the
#: centripetal force as a changing error that a constant bias cannot represent, and without the NHC only
#: the turns split the tilt from the bias, so the fold's error is read as information on that split (the
#: consistency matrix's tight rows, 40 seeds: the attitude NEES at the end of the run 1.70 per dof,
#: p = 3e-6, with the fold; 1.12, p = 0.17, with the states). With the NHC the pitch is observed against
#: the velocity and the fold is harmless (0.70 per dof): the car preset keeps :data:`UNKNOWN_GRADE_IMU`.
UNKNOWN_GRADE_IMU_ACCEL_MISALIGNMENT: dict = {
    **UNKNOWN_GRADE_IMU, "accel_bias_sigma_ug": float(np.hypot(10000.0, 500.0)),
    "accel_misalignment": True, "accel_misalignment_sigma_deg": 0.5}
#: The loose filter's IMU model without an ``imu`` section, with or without a preset (issue 35, m35u):
#: :data:`UNKNOWN_GRADE_IMU` with its accelerometer bias (the same 13.3 mg σ) as a Gauss–Markov process of
#: τ 3600 s, the structure of the field default's, instead of a random constant.
#: With ``grade_from_static`` (issue 35, session 12): a log that starts at rest may show a better IMU, whose
#: grade's model then replaces this one (:mod:`aidnav.filters.grade`).
DEFAULT_IMU: dict = {**UNKNOWN_GRADE_IMU, "accel_bias_tau_s": 3600.0, "grade_from_static": True}


class LooseConfig(_Strict):
    """Full configuration of ``aidnav process``."""

    # no imu section: the noise is also raised to what the log's static samples show (issue 35)
    imu: ImuNoise = ImuNoise(**DEFAULT_IMU)
    gnss: GnssAiding = GnssAiding()
    init: Initialisation = Initialisation()
    constraints: Constraints = Constraints()
    filter: FilterSettings = FilterSettings()
    odometer: OdometerAiding = OdometerAiding()
    baro: BaroAiding = BaroAiding()
    mag: MagAiding = MagAiding()
    calibration: Calibration = Calibration()
    motion: MotionBounds = MotionBounds()

    @property
    def nstate(self) -> int:
        if self.filter.states is not None:
            return self.filter.states
        return self.imu.nins
