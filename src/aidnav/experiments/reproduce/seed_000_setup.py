"""Seed 000: the setting of the reproduction (the seed's Table 1, its printed Table 2 and eq. 24, the
filter variants), the scenario, sensor and filter configuration of one Monte Carlo realisation, the error
series in the seed's units and the eq. (23)-(26) geometry check. :mod:`.seed_000` re-exports these names.
"""

from __future__ import annotations

import numpy as np

from aidnav.analysis import errors
from aidnav.filters.federated import FederatedConfig
from aidnav.nav.earth import radii
from aidnav.nav.geo_pointing import R_GEO_SEED000, az_el_jacobians, geo_sat_ecef, pointing_az_el
from aidnav.nav.rotations import dcm_from_euler, dcm_from_rotvec, euler_from_dcm, wrap_pi
from aidnav.sim.gnss import GnssSpec
from aidnav.sim.imu import ImuSpec
from aidnav.sim.sapv import SapvSpec, simulate_sapv
from aidnav.units import ARCMIN
from aidnav.units import DEG as D

SEED = "000"
TITLE = "Satellite antenna pointing vector (SAPV) aiding of SINS/GPS with a federated Kalman filter"
DEFAULT_RUNS = 30  #: resolves the §1.3 ratio rows within 2 standard errors (20 did not, for vE)

SITE = dict(lat_deg=39.0, lon_deg=116.0, height_m=0.0)
HEADING_DEG = 100.0
SAT_LON_DEG = 138.0
DURATION_S = 500.0
IMU_RATE_HZ = 100.0
GPS_SIGMA_POS_M = 10.0
GPS_SIGMA_VEL_M_S = 0.5
#: GPS velocity σ [m/s] of the covariance study of the pitch claim (how fast the level tilt converges)
GPS_VEL_SWEEP_M_S = (0.5, 0.25, 0.1)
GPS_RATE_HZ = 1.0
SAPV_SIGMA_DEG = 0.05
ACCEL_BIAS_UG = 500.0  #: accelerometer constant bias σ of Table 1 [µg] (the seed000 IMU preset)
SAPV_RATE_HZ = 1.0
#: the seed's one simulated run read literally: Table 1's constant drift 0.1°/h and accelerometer bias 500 µg
#: are values, the same on every axis (not σ of a draw); used for the "pitch below ~2′ after 30 s" claim
SEED_RUN_IMU = dict(bias_mode="fixed", gyro_bias_deg_h=0.1, accel_bias_ug=500.0)
#: the same with the horizontal accelerometer biases of opposite sign (x +500, y −500 µg): the sign pattern
#: that puts the most bias into the tilt the antenna cannot see (a sensitivity case)
ADVERSE_RUN_IMU = dict(bias_mode="fixed", gyro_bias_deg_h=0.1, accel_bias_ug=(500.0, -500.0, 500.0))
#: initial misalignment φ_E, φ_N, φ_U [deg] of the 2026-12-01 decision: φ_U0 = 1° (the largest value at
#: which our own targets held) is now the sensitivity case (§1.3, superseded 2026-12-06); the default φ_U0
#: is fitted to the seed's Table 2 state-1 heading statistics by :func:`.seed_000_runs.phi_u0_fit` over
#: PHI_U0_GRID_DEG
PHI0_DEG = (0.1, 0.1, 1.0)
#: the φ_U0 values [deg] of the fit to Table 2 state 1 (SINS/GPS heading mean −76.9′, std 98.5′); the fitted
#: default is the grid value whose run-averaged heading mean and std match those best (relative squared error)
PHI_U0_GRID_DEG = (1.0, 2.0, 3.0, 3.5, 4.0, 5.0)
#: the seed's Table 2 state 1 (SINS/GPS) heading error over its 500-s run: (mean, std) [arcmin]
PAPER_STATE1_HEADING = (-76.9119, 98.5442)
#: the initial level errors φ_E0 = φ_N0 [deg] of the fit to Table 2 state 1's pitch and roll std (the seed
#: does not give them; 0.1° was our choice of 2026-12-01): the same rule as φ_U0 (§1.3, 2026-12-06), applied
#: to the level axes by :func:`.seed_000_runs.level0_fit` (issue 39, session 8)
LEVEL0_GRID_DEG = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8)
#: the seed's Table 2 state 1 (SINS/GPS) pitch and roll error std over its 500-s run [arcmin]; their means
#: (1.21′, 1.14′) are one draw of the bias-tied tilt (σ∇/g = 1.72′) and do not enter the fit
PAPER_STATE1_LEVEL_STD = {"pitch": 3.2584, "roll": 3.7765}
POS0_SIGMA_M = 10.0  #: initial position error σ [m]: the INS starts from a GPS fix (σ 10 m)
VEL0_SIGMA_M_S = 0.5  #: initial velocity error σ [m/s]: from a GPS velocity (σ 0.5 m/s)
#: initial heading errors [deg] of the sensitivity sweep of the velocity target (§1.3, erratum 12)
HEADING0_SWEEP_DEG = PHI_U0_GRID_DEG
SWEEP_RUNS = 10
#: the §1.3 velocity ratios run over this many times the runs (SINS/GPS and the federated filter only). With
#: φ_U0 fitted to Table 2 the spec row (SAPV does not degrade velocity, ratio ≤ 1.1) is far from its
#: boundary and the ±15 % comparison is a paper row: the main runs resolve both (was 20 under the 1° decision)
RATIO_RUNS_FACTOR = 1
SETTLE_S = 30.0  #: "with SAPV the heading error is below 10′ after ≤ 30 s"
LAST_S = 400.0  #: heading RMS ratio over the last 400 s
SAPV_LOSS = (200.0, 300.0)  #: SAPV lost (blockage) in this window [s]
GPS_OUTAGE = (200.0, 260.0)  #: GPS outage in this window [s]

#: Table 2 of the seed (attitude rows in arc-minutes per §1.2 item 11; velocity m/s), state 1 = SINS/GPS,
#: state 2 = SINS/GPS/SAPV
PAPER_T2 = {
    "heading": {"mean": (-76.9119, -0.3550), "std": (98.5442, 2.8714)},
    "roll": {"mean": (1.1392, 0.4296), "std": (3.7765, 3.7504)},
    "pitch": {"mean": (1.2096, -1.1423), "std": (3.2584, 0.7877)},
    "vN": {"mean": (0.0312, 0.0290), "std": (0.0951, 0.0952)},
    "vU": {"mean": (-0.0106, -0.0531), "std": (0.0851, 0.0670)},
    "vE": {"mean": (-0.0055, -0.0052), "std": (0.0869, 0.0870)},
}
#: seed eq. (24), printed; §1.2 item 8: not reproduced by any consistent model
PAPER_EQ24 = np.array([[0.4547, 0.8011, 0.0], [-0.8376, 0.2001, 0.0]])

GPS_ONLY = "SINS/GPS"
FED = "federated reset b=1/2,1/2"
VARIANTS = {
    GPS_ONLY: FederatedConfig(mode="centralized", use_sapv=False),
    FED: FederatedConfig(mode="reset", beta_gps=0.5, beta_sapv=0.5),
    "federated reset b=1/3,1/3, master 1/3": FederatedConfig(mode="reset", beta_gps=1 / 3, beta_sapv=1 / 3,
                                                              beta_master=1 / 3),
    "federated reset b=0.8,0.2": FederatedConfig(mode="reset", beta_gps=0.8, beta_sapv=0.2),
    "federated no-reset b=1/2,1/2": FederatedConfig(mode="no_reset", beta_gps=0.5, beta_sapv=0.5),
    "federated no-reset b=0.8,0.2": FederatedConfig(mode="no_reset", beta_gps=0.8, beta_sapv=0.2),
    "centralized GPS+SAPV": FederatedConfig(mode="centralized"),
}
CENTRAL = "centralized GPS+SAPV"
QUANTS = ("heading", "roll", "pitch", "vN", "vU", "vE")  # the seed's row order (erratum 11)
UNITS = {"heading": "arcmin", "roll": "arcmin", "pitch": "arcmin", "vN": "m/s", "vU": "m/s", "vE": "m/s"}


# ============================================================================ scenario
def seed_scenario(duration_s: float = DURATION_S, imu_rate_hz: float = IMU_RATE_HZ, gps_outages=(),
                  imu=None):
    """The seed's Table 1 scenario (:class:`aidnav.sim.scenario.Scenario`): static vehicle, heading 100°.
    ``imu``: overrides of the ``seed000`` IMU preset (e.g. :data:`SEED_RUN_IMU`; default: biases drawn per
    run with Table 1's values as σ)."""
    from aidnav.sim.scenario import Scenario  # lazy: pulls in pydantic

    return Scenario.model_validate(dict(
        name="seed000", description="seed 000 Table 1: static vehicle, SINS/GPS/SAPV", seed=1,
        initial=dict(**SITE, speed_m_s=0.0, heading_deg=HEADING_DEG), imu_rate_hz=imu_rate_hz,
        transition_s=0.0,
        segments=[dict(type="static", duration_s=duration_s)],
        sensors=dict(imu=dict(grade="seed000", **(imu or {})),
                     gnss=dict(rate_hz=GPS_RATE_HZ, sigma_pos_m=[GPS_SIGMA_POS_M] * 3,
                               sigma_vel_m_s=[GPS_SIGMA_VEL_M_S] * 3,
                               outages=[dict(start_s=s, duration_s=e - s) for s, e in gps_outages]))))


def sapv_spec(**changes):
    """The seed's antenna: σ 0.05° (az, el) at 1 Hz, GEO 138°E at height 3.5785e7 m."""

    kw = dict(rate_hz=SAPV_RATE_HZ, sigma_deg=SAPV_SIGMA_DEG, sat_lon_deg=SAT_LON_DEG,
              sat_radius_m=R_GEO_SEED000)
    kw.update(changes)
    return SapvSpec(**kw)


def filter_config(truth, rng, phi0_deg=PHI0_DEG, draw_attitude: bool = False,
                  pos_sigma_m: float = POS0_SIGMA_M, vel_sigma_m_s: float = VEL0_SIGMA_M_S):
    """Filter configuration matched to the seed's sensors, with the initial state set around the truth.

    φ_0 = ``phi0_deg`` (E, N, U) [deg] applied as C_est = (I − [φ×]) C_true (drawn from N(0, diag(φ0²))
    when ``draw_attitude``); position and velocity errors drawn with σ ``pos_sigma_m``, ``vel_sigma_m_s``;
    P_0 = diag of those σ and the IMU's bias σ.
    """
    from aidnav.filters.tuning import loose_config_from_specs  # lazy: pulls in pydantic

    lat, lon, h = truth.lat[0], truth.lon[0], truth.height[0]
    rm, rn = radii(lat)
    dp = rng.normal(0.0, pos_sigma_m, 3)
    dv = rng.normal(0.0, vel_sigma_m_s, 3)
    phi = np.asarray(phi0_deg, float) * D
    if draw_attitude:
        phi = rng.normal(0.0, phi)
    lla = (np.degrees(lat + dp[1] / (rm + h)), np.degrees(lon + dp[0] / ((rn + h) * np.cos(lat))), h + dp[2])
    C = dcm_from_rotvec(-phi) @ dcm_from_euler(*truth.rph[0])
    rph = np.degrees(euler_from_dcm(C))
    gspec = GnssSpec(sigma_pos_enu=GPS_SIGMA_POS_M, sigma_vel_enu=GPS_SIGMA_VEL_M_S)
    return loose_config_from_specs(ImuSpec.grade("seed000"), gspec, init_rph_deg=rph, init_lla_deg_m=lla,
                                   init_vel=truth.vel[0] + dv, position_sigma_m=(pos_sigma_m,) * 3,
                                   velocity_sigma_m_s=(vel_sigma_m_s,) * 3,
                                   attitude_sigma_deg=tuple(float(x) for x in np.abs(phi0_deg)),
                                   sensor_model=False)  # SPEC §1.1: the 15-state model


def simulate_case(seed_seq: np.random.SeedSequence, duration_s: float = DURATION_S, gps_outages=(),
                  sapv_changes=None, draw_attitude: bool = False, imu=None, phi0_deg=PHI0_DEG):
    """One Monte Carlo realisation: (sim result, SAPV data, filter config). Independent streams for the
    IMU/GPS simulation, the antenna and the initial errors are spawned from ``seed_seq``; ``imu``: IMU
    overrides (:func:`seed_scenario`; the filter's P_0 keeps Table 1's σ); ``phi0_deg``: the initial
    misalignment (E, N, U) [deg]."""
    from aidnav.sim.run import simulate  # lazy: pulls in pydantic

    # children built from the spawn key (not .spawn(), which advances a counter): the same seed_seq gives
    # the same streams on every call (e.g. the GPS-outage rerun of a realisation)
    s_sim, s_sapv, s_init = (np.random.SeedSequence(seed_seq.entropy, spawn_key=(*seed_seq.spawn_key, i))
                             for i in range(3))
    sim = simulate(seed_scenario(duration_s, gps_outages=gps_outages, imu=imu),
                   seed=int(s_sim.generate_state(1)[0]))
    sv = simulate_sapv(sim.truth, sapv_spec(**(sapv_changes or {})), np.random.default_rng(s_sapv))
    cfg = filter_config(sim.truth, np.random.default_rng(s_init), phi0_deg=phi0_deg,
                        draw_attitude=draw_attitude)
    return sim, sv, cfg


# ============================================================================ errors
def truth_index(truth, times):
    """Indices of the truth samples at ``times`` (filter epochs are IMU samples)."""
    return errors.truth_index(truth.time, times)


def euler_errors(res, truth):
    """(K, 3) roll, pitch, heading errors estimate − truth [rad] (wrapped to (−π, π])."""
    return wrap_pi(res.rph - truth.rph[truth_index(truth, res.time)])


def velocity_errors(res, truth):
    """(K, 3) ENU velocity errors estimate − truth [m/s]."""
    return res.state[:, 3:6] - truth.vel[truth_index(truth, res.time)]


def error_state(res, truth, realised):
    """(K, 15) error in the filter's state definition (:func:`aidnav.analysis.errors.ins_error_state`)."""
    return errors.ins_error_state(res, truth, realised)


def seed_series(res, truth) -> dict:
    """Error time series in the seed's units: attitude [arcmin], velocity [m/s]."""
    e = euler_errors(res, truth) / ARCMIN
    v = velocity_errors(res, truth)
    sig = np.sqrt(res.pdiag[:, 2]) / ARCMIN
    return {"t": res.time - truth.time[0],
            "heading": e[:, 2], "roll": e[:, 0], "pitch": e[:, 1],
            "vE": v[:, 0], "vN": v[:, 1], "vU": v[:, 2], "heading_sigma": sig}


# ============================================================================ geometry (eqs. 23-26)
def geometry_check() -> dict:
    """Eq. (23)-(26) at the seed's case: our H_phi, H_pos (exact Jacobians), finite-difference check of both
    through the nonlinear chain, and the pointing change for the seed's 100 m position error (eq. 25)."""

    lat, lon, h = SITE["lat_deg"] * D, SITE["lon_deg"] * D, SITE["height_m"]
    C = dcm_from_euler(0.0, 0.0, HEADING_DEG * D)
    sat = geo_sat_ecef(SAT_LON_DEG * D, R_GEO_SEED000)
    az, el, Hphi, Hpos = az_el_jacobians(lat, lon, h, C, sat)

    def angles(phi, dP):
        # the computed state: C_c = (I − [φ×]) C (exact rotation), position + δP; satellite fixed
        a = pointing_az_el(lat + dP[0], lon + dP[1], h + dP[2], dcm_from_rotvec(-phi) @ C, sat)
        return np.array([a[0], a[1]])

    fd_phi = np.zeros((2, 3))
    fd_pos = np.zeros((2, 3))
    rm, rn = radii(lat)
    steps_pos = np.array([1.0 / rm, 1.0 / (rn * np.cos(lat)), 1.0])  # 1 m
    for j in range(3):
        e = np.zeros(3)
        e[j] = 1e-6
        fd_phi[:, j] = (angles(e, np.zeros(3)) - angles(-e, np.zeros(3))) / 2e-6
        p = np.zeros(3)
        p[j] = steps_pos[j]
        fd_pos[:, j] = (angles(np.zeros(3), p) - angles(np.zeros(3), -p)) / (2 * steps_pos[j])
    dP25 = np.array([100.0 / rm, 100.0 / (rn * np.cos(lat)), 100.0])  # eq. (25) with erratum 9's order
    return {"az_deg": float(np.degrees(az)), "el_deg": float(np.degrees(el)), "H_phi": Hphi, "H_pos": Hpos,
            "fd_rel_phi": float(np.max(np.abs(fd_phi - Hphi)) / np.max(np.abs(Hphi))),
            "fd_rel_pos": float(np.max(np.abs(fd_pos - Hpos)) / np.max(np.abs(Hpos))),
            "pos100_deg": float(np.degrees(np.max(np.abs(Hpos @ dP25))))}

