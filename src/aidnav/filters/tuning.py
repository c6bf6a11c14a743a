"""Filter configuration matched to a simulated sensor set (the "truth model = filter model" case).

Used by Monte Carlo studies and tests: the loosely coupled filter is given the noise model of the
simulated IMU (:class:`aidnav.sim.imu.ImuSpec`, SI units) and GNSS receiver
(:class:`aidnav.sim.gnss.GnssSpec`), and an initial state drawn around the truth.
"""

from __future__ import annotations

import numpy as np

from aidnav.nav.earth import radii
from aidnav.nav.rotations import dcm_from_euler, dcm_from_rotvec, euler_from_dcm
from aidnav.units import DEG, DEG_H, G0, UG

from .config import LooseConfig


def loose_config_from_specs(imu_spec, gnss_spec=None, *, init_rph_deg=None, init_lla_deg_m=None,
                            init_vel=None, position_sigma_m=(1.0, 1.0, 1.0),
                            velocity_sigma_m_s=(0.1, 0.1, 0.1),
                            attitude_sigma_deg=(0.1, 0.1, 1.0), states: int = 15, prop_dt_s: float = 1.0,
                            floor_bias: bool = True, sensor_model: bool = True, **overrides) -> LooseConfig:
    """LooseConfig whose noise model matches ``imu_spec`` (SI) and ``gnss_spec``.

    ``sensor_model`` (default): the sensor errors as :func:`sensor_error_model` says (turn-on bias plus
    instability, scale factors and misalignment, issue 35; ``states`` then only asks for at least that
    many); False: the model before it (:func:`_one_markov_bias`: one Gauss-Markov bias state of initial
    σ² = σ_const² + σ_GM², driving noise q = 2σ_GM²/τ; scale factors only with ``states = 21``).
    ``init_*`` give the filter's initial state (``mode = given``); the σ's its initial covariance
    (position ENU [m], velocity [m/s], roll/pitch/heading [deg]). ``floor_bias`` keeps a
    tiny positive bias σ so that P stays positive definite for an error-free IMU.
    ``overrides``: section dicts merged into the configuration (e.g. ``constraints={"zupt": False}``).
    The self-calibration states are off (the simulated lever arm, zero time offset and mounting are
    given exactly); switch them on with ``calibration={...}``.
    """
    if sensor_model:
        imu = sensor_error_model(imu_spec, states, floor_bias)
        states = 33 if imu["accel_misalignment"] else (27 if imu["gyro_misalignment"] else
                                                        (21 if imu["scale_factors"] else 15))
    else:
        imu = _one_markov_bias(imu_spec, states, floor_bias)
    gnss = {}
    if gnss_spec is not None:
        gnss = dict(lever_arm_m=tuple(float(x) for x in gnss_spec.lever_arm_b),
                    use="both" if gnss_spec.velocity else "position",
                    min_pos_std_m=1e-3, min_vel_std_m_s=1e-4, gate_probability=1.0)
    init = dict(position_sigma_m=tuple(position_sigma_m), velocity_sigma_m_s=tuple(velocity_sigma_m_s),
                attitude_sigma_deg=tuple(attitude_sigma_deg))
    if init_rph_deg is not None:
        lat, lon, h = init_lla_deg_m
        init.update(mode="given", lat_deg=lat, lon_deg=lon, height_m=h,
                    velocity_m_s=tuple(float(v) for v in init_vel), roll_deg=init_rph_deg[0],
                    pitch_deg=init_rph_deg[1], heading_deg=init_rph_deg[2])
    cfg = dict(imu=imu, gnss=gnss, init=init, constraints=dict(zupt=False, nhc=False),
               filter=dict(states=states, prop_dt_s=prop_dt_s),
               calibration=dict(time_offset=False, lever_arm=False, mounting=False, velocity_delay=False))
    for k, v in overrides.items():
        cfg.setdefault(k, {}).update(v)
    return LooseConfig.model_validate(cfg)


def sensor_error_model(imu_spec, states: int = 15, floor_bias: bool = True) -> dict:
    """The ``imu`` section of :class:`LooseConfig` that models what the sensors of ``imu_spec`` do (issue
    35); nothing below is tuned, every number is the spec's:

    * bias = turn-on constant (σ_c, drawn once) + in-run instability (Gauss–Markov σ_i, τ): a random walk
      of PSD 2σ_i²/τ started at σ0² = σ_c² + σ_i². Its increments over any T (2σ_i²T/τ) bound those of
      the constant plus the Gauss–Markov (2σ_i²(1 − e^(−T/τ))) and equal them for T ≪ τ, so the turn-on
      constant is never forgotten (one Gauss–Markov state of σ0 forgets it within τ); a random constant
      when there is no instability; the spec's rate / acceleration random walk (``gyro_rrw``,
      ``accel_rrw``: a bias random walk of PSD rrw²) adds its PSD to that random walk's;
    * scale factors: the 21-state model (random constants of the spec's σ) when the IMU has scale-factor
      errors (or ``states = 21``); otherwise none;
    * accelerometer misalignment: each off-diagonal entry m (σ_m) turns the specific force along one
      axis into m·f on another: m·g, a constant bias, while the vehicle is level, but m·a in every
      acceleration (at 10 Hz fixes resolve the z accelerometer's m_zx·a as a pitch error: issue 35,
      session 10): six random-constant states of the spec's σ (33 states, after the gyro's) when the IMU
      has it (or ``states = 33``); the accelerometer bias σ0 then holds only the scale factor's s·g on
      the vertical when scale factors are not states;
    * gyro misalignment: m·ω, a rate error while the vehicle turns (a consumer IMU's 0.5° tilts the
      solution by 0.5° × the angle turned): six random-constant states of the spec's σ (27 states) when
      the IMU has it.
    """
    gb, ab = float(np.max(imu_spec.gyro_bias)), float(np.max(imu_spec.accel_bias))
    gi = float(np.max(imu_spec.gyro_bias_instability))
    ai = float(np.max(imu_spec.accel_bias_instability))
    tau_g, tau_a = float(np.min(imu_spec.gyro_bias_tau)), float(np.min(imu_spec.accel_bias_tau))
    gsf, asf = float(np.max(imu_spec.gyro_scale)), float(np.max(imu_spec.accel_scale))
    am = float(np.max(imu_spec.accel_misalignment))
    gm = float(np.max(imu_spec.gyro_misalignment))
    sf = states >= 21 or gsf > 0 or asf > 0 or gm > 0 or am > 0
    ams = am > 0 or states == 33  # accelerometer misalignment states (then not in the bias σ)
    tiny_g, tiny_a = (1e-4 * DEG_H, 1e-3 * UG) if floor_bias else (0.0, 0.0)
    ab0 = np.sqrt(ab ** 2 + ai ** 2 + (0.0 if ams else am * G0) ** 2 + (0.0 if sf else asf * G0) ** 2)

    def rw(sig, tau, rrw, unit):  # random walk [unit/√h]: the instability's PSD 2σ²/τ plus the spec's rrw²
        q = 2.0 * sig ** 2 / tau if (sig > 0 and np.isfinite(tau)) else 0.0
        return np.sqrt(q + rrw ** 2) * 60.0 / unit

    return dict(
        arw_deg_sqrt_h=max(float(np.max(imu_spec.gyro_arw)) / DEG * 60.0, 1e-6),
        vrw_m_s_sqrt_h=max(float(np.max(imu_spec.accel_vrw)) * 60.0, 1e-6),
        gyro_bias_sigma_deg_h=max(np.hypot(gb, gi), tiny_g) / DEG_H,
        accel_bias_sigma_ug=max(ab0, tiny_a) / UG,
        gyro_bias_tau_s=0.0, accel_bias_tau_s=0.0,
        gyro_bias_rw_deg_h_sqrt_h=rw(gi, tau_g, float(np.max(imu_spec.gyro_rrw)), DEG_H),
        accel_bias_rw_ug_sqrt_h=rw(ai, tau_a, float(np.max(imu_spec.accel_rrw)), UG),
        scale_factors=sf,
        gyro_sf_sigma_ppm=max(gsf * 1e6, 1e-3),
        accel_sf_sigma_ppm=max(asf * 1e6, 1e-3),
        gyro_misalignment=gm > 0 or states >= 27,
        gyro_misalignment_sigma_deg=gm / DEG,
        accel_misalignment=ams,
        accel_misalignment_sigma_deg=am / DEG,
    )


def _one_markov_bias(imu_spec, states: int, floor_bias: bool) -> dict:
    """The ``imu`` section of the model before issue 35: one Gauss–Markov bias state per axis (turn-on
    constant and instability together, σ0² = σ_const² + σ_GM², q = 2σ_GM²/τ: the constant is forgotten
    within τ), scale factors only with ``states = 21``, misalignment not modelled."""
    gb = float(np.max(imu_spec.gyro_bias))
    ab = float(np.max(imu_spec.accel_bias))
    gi = float(np.max(imu_spec.gyro_bias_instability))
    ai = float(np.max(imu_spec.accel_bias_instability))
    tau_g = float(np.min(imu_spec.gyro_bias_tau))
    tau_a = float(np.min(imu_spec.accel_bias_tau))
    arw = float(np.max(imu_spec.gyro_arw))
    vrw = float(np.max(imu_spec.accel_vrw))
    tiny_g, tiny_a = (1e-4 * DEG_H, 1e-3 * UG) if floor_bias else (0.0, 0.0)
    return dict(
        arw_deg_sqrt_h=max(arw / DEG * 60.0, 1e-6),
        vrw_m_s_sqrt_h=max(vrw * 60.0, 1e-6),
        gyro_bias_sigma_deg_h=max(np.hypot(gb, gi), tiny_g) / DEG_H,
        accel_bias_sigma_ug=max(np.hypot(ab, ai), tiny_a) / UG,
        gyro_bias_instability_deg_h=gi / DEG_H,
        accel_bias_instability_ug=ai / UG,
        gyro_bias_tau_s=tau_g if (gi > 0 and np.isfinite(tau_g)) else 0.0,
        accel_bias_tau_s=tau_a if (ai > 0 and np.isfinite(tau_a)) else 0.0,
        scale_factors=states == 21,
        gyro_sf_sigma_ppm=max(float(np.max(imu_spec.gyro_scale)) * 1e6, 1e-3),
        accel_sf_sigma_ppm=max(float(np.max(imu_spec.accel_scale)) * 1e6, 1e-3),
    )


def perturbed_initial_state(truth, rng, position_sigma_m=(1.0, 1.0, 1.0), velocity_sigma_m_s=(0.1, 0.1, 0.1),
                            attitude_sigma_deg=(0.1, 0.1, 1.0), index: int = 0):
    """Initial (lla_deg_m, vel, rph_deg) drawn around the truth at ``index`` with the given 1σ's.

    The attitude error is applied as a misalignment φ in n (C_est = (I − [φ×]) C_true), so the filter's
    error state starts exactly as drawn.
    """
    lat, lon, h = truth.lat[index], truth.lon[index], truth.height[index]
    rm, rn = radii(lat)
    dp = rng.normal(0.0, position_sigma_m)
    dv = rng.normal(0.0, velocity_sigma_m_s)
    phi = rng.normal(0.0, np.radians(attitude_sigma_deg))
    lla = (np.degrees(lat + dp[1] / (rm + h)), np.degrees(lon + dp[0] / ((rn + h) * np.cos(lat))), h + dp[2])
    vel = truth.vel[index] + dv
    C = dcm_from_rotvec(-phi) @ dcm_from_euler(*truth.rph[index])
    rph = np.degrees(euler_from_dcm(C))
    return lla, vel, rph
