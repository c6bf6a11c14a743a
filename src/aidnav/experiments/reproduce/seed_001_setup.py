"""Seed 001: the setting of the reproduction (base, glide path, approach, sensors, clock), the relative
least-squares study of §2.3 targets 1-2 and the approach scenario and tight-filter configuration.
:mod:`.seed_001` re-exports these names."""

from __future__ import annotations

import numpy as np

from aidnav.estimators.dgps import relative_position, satellites_from_pseudoranges
from aidnav.filters.tight import TightConfig
from aidnav.filters.tuning import loose_config_from_specs
from aidnav.nav.earth import dcm_ecef_to_enu, lla_to_ecef, radii
from aidnav.sim.gnss_constellation import nominal_constellation
from aidnav.sim.gnss_raw import static_pseudoranges
from aidnav.sim.imu import ImuSpec
from aidnav.sim.scenario import parse_scenario
from aidnav.units import DEG

SEED = "001"
TITLE = "Key technologies of approach and landing based on tightly integrated DGPS/SINS (Pang et al., 2013)"
WEEK, SOW0 = 2381, 400000.0
BASE_LAT, BASE_LON, BASE_H = 34.2 * DEG, 108.9 * DEG, 400.0
GLIDE = 3.0 * DEG
SPEED = 70.0
PRE_S, APP_S, OUT_S = 120.0, 92.0, 20.0
START_KM = 25.0
IMU_HZ = 50.0
PAIR = "spread"  # which two satellites remain after the outage
CLOCK = {"clock_h0": 2e-19, "clock_hm2": 2e-20}  # receiver oscillator (TCXO of Brown & Hwang)
#: a poor receiver oscillator for the sensitivity table: 100× the TCXO's white-frequency and random-walk
#: frequency noise (h0, h−2)
POOR_CLOCK = {"clock_h0": 2e-17, "clock_hm2": 2e-18}
#: an ideal receiver clock for the sensitivity table (white-frequency and random-walk-frequency noise
#: ~1e-7 of the TCXO's: the clock drift is then known and two satellites observe two velocity directions)
IDEAL_CLOCK = {"clock_h0": 2e-26, "clock_hm2": 2e-27}
#: approach accuracy figures the seed's "approximately CAT-II" is judged against (95 % horizontal, vertical
#: [m]; alert limits horizontal, vertical [m]): ICAO Annex 10 Vol. I Table 3.7.2.4-1 (GNSS signal-in-space
#: performance: CAT I accuracy 16 m H, 6.0-4.0 m V; alert limits 40 m, 35-10 m), and the CAT II/IIIA figures
#: of the ICAO GNSS requirements (accuracy 6.9 m H, 2.0 m V; alert limits 17.3 m, 5.3 m) as tabulated in
#: Yang et al., "Advances in BDS and satellite navigation augmentation technologies", Satellite Navigation
#: 1, 2020, Table 1 (after ICAO Annex 10)
CAT_LIMITS = {"CAT I": (16.0, 4.0, 40.0, 10.0), "CAT II": (6.9, 2.0, 17.3, 5.3)}
IMU_GRADE = "tactical"  #: fibre-optic class (1°/h bias, 0.1°/√h ARW), as the SPAN-CPT's gyros
DEFAULT_RUNS = 20
SENS_RUNS = 10  #: runs per case of the sensitivity tables (at most ``runs``)
SLOPE_S = 5.0  #: window before / after the satellites return for the slope comparison (b) [s]
#: the DR targets (a), (b) run over this many times the runs (one approach run costs ≈ 0.6 s CPU): (b)'s
#: effect is within a few per cent of zero, and 100 runs bound it to ≈ 10 % of the slope (2 standard errors)
DR_RUNS_FACTOR = 5
P_SIGN = 0.01  #: sign-test level of the DR targets
DOPPLER_SIGMA_M_S = 0.06  #: σ of a pseudorange rate (Doppler) in the tight filter [m/s]
GNSS_HZ = 2.0


# ------------------------------------------------------------------------------ relative LS targets
def rover_on_glide_path(baseline_m: float):
    """Rover ECEF [m] at horizontal distance ``baseline_m`` south of the base on the 3° glide path."""
    e, n, u = 0.0, -baseline_m, baseline_m * np.tan(GLIDE)
    C = dcm_ecef_to_enu(BASE_LAT, BASE_LON)
    return np.array(lla_to_ecef(BASE_LAT, BASE_LON, BASE_H)) + C.T @ np.array([e, n, u]), np.array([e, n, u])


def relative_ls_study(
    rng,
    baselines_km=(5, 10, 20, 30, 40),
    n_times: int = 10,
    nees_draws: int = 400,
    common_sigma_m: float = 10.0,
):
    """Targets 1–2 of §2.3 (noise-free common mode; σ = 1 m NEES). Returns a dict of results."""
    eph = nominal_constellation(WEEK, SOW0, 24)
    pb = np.array(lla_to_ecef(BASE_LAT, BASE_LON, BASE_H))
    times = SOW0 + np.linspace(0, 3600, n_times)
    err_iter = {}
    single = []
    nees = []
    cdt_err = []
    for b in baselines_km:
        pk, enu_true = rover_on_glide_path(b * 1e3)
        worst = 0.0
        for t in times:
            cb, ck = rng.normal(0, 3e4), rng.normal(0, 3e4)
            pr_b, _ = static_pseudoranges(eph, t, pb, cb)
            pr_k, _ = static_pseudoranges(eph, t, pk, ck)
            common = rng.normal(0, common_sigma_m, len(pr_b))
            pr_b, pr_k = pr_b + common, pr_k + common
            sb, _, _, _ = satellites_from_pseudoranges(eph.table, eph.table[:, 0], t, pr_b, max_age_s=1e7)
            sk, _, _, _ = satellites_from_pseudoranges(eph.table, eph.table[:, 0], t, pr_k, max_age_s=1e7)
            r = relative_position(pb, sb, pr_b, sk, pr_k, sigma0=1.0, weighting="equal")
            worst = max(worst, float(np.linalg.norm(r.enu - enu_true)), abs(r.clock_m - (ck - cb)))
            if b == 20:
                r1 = relative_position(pb, sb, pr_b, sk, pr_k, sigma0=1.0, weighting="equal", iterate=False)
                single.append(np.r_[r1.enu - enu_true, r1.clock_m - (ck - cb)])
                # σ = 1 m white noise on the single differences (here: on the rover's pseudoranges)
                for _ in range(nees_draws // n_times):
                    prn_k = pr_k + rng.normal(0, 1.0, len(pr_k))
                    sk2, _, _, _ = satellites_from_pseudoranges(
                        eph.table, eph.table[:, 0], t, prn_k, max_age_s=1e7
                    )
                    r2 = relative_position(pb, sb, pr_b, sk2, prn_k, sigma0=1.0, weighting="equal")
                    d = np.r_[r2.enu - enu_true, r2.clock_m - (ck - cb)]
                    nees.append(float(d @ np.linalg.solve(r2.cov, d)))
                    cdt_err.append(d)
        err_iter[b] = worst
    single = np.array(single)
    return {
        "err_iter": err_iter,
        "single_mean": single.mean(0),
        "single_max3d": float(np.max(np.linalg.norm(single[:, :3], axis=1))),
        "single": single,
        "nees": np.array(nees),
        "noise_err": np.array(cdt_err),
    }


# --------------------------------------------------------------------------------- the approach run
def approach_scenario():
    """The seed's approach: level pre-approach towards the base, then 92 s on a 3° descent."""
    rm, _ = radii(BASE_LAT)
    dist0 = START_KM * 1e3 + PRE_S * SPEED
    lat0 = BASE_LAT - dist0 / (rm + BASE_H)
    h0 = BASE_H + START_KM * 1e3 * np.tan(GLIDE)
    return parse_scenario(
        {
            "name": "seed001_approach",
            "imu_rate_hz": IMU_HZ,
            "transition_s": 1.0,
            "initial": {
                "lat_deg": np.degrees(lat0),
                "lon_deg": np.degrees(BASE_LON),
                "height_m": float(h0),
                "speed_m_s": SPEED,
                "heading_deg": 0.0,
            },
            "segments": [
                {"type": "straight", "duration_s": PRE_S, "name": "pre-approach"},
                {
                    "type": "climb",
                    "duration_s": APP_S,
                    "flight_path_deg": -3.0,
                    "pull_s": 2.0,
                    "name": "approach",
                },
            ],
        }
    )


def imu_spec(grade: str = IMU_GRADE):
    return ImuSpec.grade(grade)


def tight_cfg(spec, clock=None):
    # the SPEC §2.1 model (17 states: 15 + clock): one Gauss-Markov bias per axis, no scale-factor or
    # misalignment states (issue 35's sensor model is the tuning default for the loose filter, not this one)
    lc = loose_config_from_specs(spec, sensor_model=False)
    return TightConfig(
        states=17,
        imu=lc.imu,
        constraints={"zupt": False},
        filter={"prop_dt_s": 0.5},
        init={
            "position_sigma_m": (3, 3, 5),
            "velocity_sigma_m_s": (0.3, 0.3, 0.3),
            "attitude_sigma_deg": (0.5, 0.5, 2.0),
        },
        gnss={"code_sigma_m": 1.0, "rate_sigma_m_s": DOPPLER_SIGMA_M_S, "mask_deg": 5.0,
              "range_errors": False, **(clock or CLOCK)},
    )
