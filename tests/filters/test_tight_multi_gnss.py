"""Tight coupling with two constellations (issue 40 item 4): 2 GPS + 2 Galileo satellites against 4 GPS.

The Galileo satellites are the GPS orbits under Galileo ids (ids 101…124, the Galileo constants: the orbits
agree to < 0.1 m over the run), so both cases have the same geometry; the Galileo pseudoranges carry an
inter-system bias of 8 m that the filter estimates as a state. A 60-s start with the full sky of both
systems (the bias is learned there), then 4 satellites for the remaining ~220 s: GPS {a, b, c, d} (the best
PDOP at the window's start) or GPS {a, b} + Galileo {c', d'}. Errors: receiver noise and multipath (the
simulator's defaults), no satellite-level errors (orbit, satellite clock, ionosphere-model and troposphere
residuals), so that the comparison is of the bias state's cost and not of which satellites' orbit errors
were drawn; 16 fixed seeds, one realisation each shared by both cases up to the window."""

from __future__ import annotations

import itertools

import numpy as np

from aidnav.filters.tight import TightConfig, run_tight
from aidnav.filters.tuning import loose_config_from_specs
from aidnav.nav.gnss_sat import E_PRN, E_URA, dop
from aidnav.nav.gnss_types import GpsEphemerides
from aidnav.sim.gnss_constellation import nominal_constellation
from aidnav.sim.gnss_raw import RawGnssSpec, simulate_raw_gnss
from aidnav.sim.imu import ImuSpec

from .test_tight import SOW, TRUTH, _imu, _init, _pos_err

ISB = 8.0
WARM = 60.0


def _twins():
    g = nominal_constellation(2381, SOW, 24).table.copy()
    g[:, E_URA] = 2.0
    e = g.copy()
    e[:, E_PRN] += 100  # the same orbits as Galileo satellites
    return GpsEphemerides(np.vstack([g, e]), 2381, None, None, [])


def _best_four(obs, el, az, k):
    vis = [j for j in range(24) if np.isfinite(obs.code1[k, j]) and el[k, j] > np.radians(10)]

    def pdop(c):
        c = list(c)
        return dop(np.column_stack([np.cos(el[k, c]) * np.sin(az[k, c]), np.cos(el[k, c]) * np.cos(az[k, c]),
                                    np.sin(el[k, c])]))["pdop"]

    return min(itertools.combinations(vis, 4), key=pdop)


def _only(obs, cols, t_from):
    o = obs.subset_sats(obs.prn)
    late = o.time >= t_from
    drop = np.setdiff1d(np.arange(len(o.prn)), cols)
    for a in (o.code1, o.doppler1, o.cn0):
        a[np.ix_(late, drop)] = np.nan
    return o


def test_two_gps_and_two_galileo_are_as_good_as_four_gps():
    eph = _twins()
    spec = ImuSpec.grade("mems")
    gspec = RawGnssSpec(rate_hz=1.0, isb_m={"E": ISB}, eph_sigma_rac_m=(0, 0, 0), sat_clock_sigma_m=0.0,
                        sat_clock_drift_sigma_m_s=0.0, iono_scale_sigma=0.0, iono_gradient_mm_km=0.0,
                        tropo_zenith_sigma_m=0.0)
    cfg = TightConfig(states=17, imu=loose_config_from_specs(spec, sensor_model=False).imu,
                      constraints={"zupt": False},
                      init={"attitude_sigma_deg": (0.2, 0.2, 1.0), "position_sigma_m": (3, 3, 3),
                            "velocity_sigma_m_s": (0.2, 0.2, 0.2)},
                      gnss={"code_sigma_m": 1.0, "rate_sigma_m_s": 0.06, "mask_deg": 5.0,
                            "range_errors": False})
    t0 = SOW + TRUTH.time[0]
    sq = {"4G": [], "2G2E": []}
    isb_z = []
    for seed in range(16):
        sim = simulate_raw_gnss(TRUTH, eph, gspec, np.random.default_rng(10 + seed), SOW)
        k = int(np.searchsorted(sim.rover.time, t0 + WARM))
        a, b, c, d = _best_four(sim.rover, sim.truth["elevation"], sim.truth["azimuth"], k)
        init, imu = _init(np.random.default_rng(5 + seed)), _imu(spec, 2 + seed)
        for name, cols in (("4G", [a, b, c, d]), ("2G2E", [a, b, 24 + c, 24 + d])):
            r = run_tight(imu, _only(sim.rover, cols, t0 + WARM), eph, cfg, init_state=init)
            err, tt = _pos_err(r)
            sq[name].append(np.mean(err[tt >= TRUTH.time[0] + WARM] ** 2))
            if name == "2G2E":
                assert r.isb_systems == "E"
                isb_z.append((r.isb[-1, 0] - ISB) / r.isb_std[-1, 0])
    rms4, rms22 = np.sqrt(np.mean(sq["4G"])), np.sqrt(np.mean(sq["2G2E"]))
    print(f"3-D RMS after the start: 4 GPS {rms4:.3f} m, 2 GPS + 2 Galileo {rms22:.3f} m "
          f"(ratio {rms22 / rms4:.3f}); ISB errors / σ: {np.round(isb_z, 2)}")
    assert rms22 <= 1.10 * rms4
    assert np.sum(np.abs(isb_z) < 3.0) >= 15  # the bias is estimated within its 3σ


def test_four_constellations_with_fdma_glonass_estimate_the_inter_system_biases():
    """GPS + Galileo + BeiDou + GLONASS (nominal Walker skies, GLONASS on its FDMA channels: Doppler at
    1602 + 0.5625·k MHz), ISBs 8, −15, 30 m, the simulator's full error model, range-error states on: the
    biases are found within 3σ, rates are not rejected (a wrong GLONASS wavelength would be metres per
    second), and the position error stays within metres."""
    from aidnav.sim.gnss_constellation import nominal_multi_constellation

    isb = {"E": 8.0, "C": -15.0, "R": 30.0}
    eph = nominal_multi_constellation(2381, SOW + 150, "GECR", node0_deg={"E": 20.0, "C": 50.0, "R": 80.0})
    spec = ImuSpec.grade("mems")
    cfg = TightConfig(states=17, imu=loose_config_from_specs(spec, sensor_model=False).imu,
                      constraints={"zupt": False},
                      init={"attitude_sigma_deg": (0.2, 0.2, 1.0), "position_sigma_m": (3, 3, 3),
                            "velocity_sigma_m_s": (0.2, 0.2, 0.2)},
                      gnss={"code_sigma_m": 1.0, "rate_sigma_m_s": 0.06, "mask_deg": 5.0})
    sim = simulate_raw_gnss(TRUTH, eph, RawGnssSpec(rate_hz=1.0, isb_m=isb), np.random.default_rng(40), SOW)
    glo = np.array([n[0] == "R" for n in sim.rover.names])
    assert np.isfinite(sim.rover.code1[:, glo]).sum(axis=1).min() >= 4
    r = run_tight(_imu(spec, 2), sim.rover, eph, cfg, init_state=_init(np.random.default_rng(5)))
    err, _ = _pos_err(r)
    z = (r.isb[-1] - [isb[c] for c in r.isb_systems]) / r.isb_std[-1]
    print(f"3-D RMS {np.sqrt(np.mean(err**2)):.2f} m, ISB {r.isb_systems} {np.round(r.isb[-1], 2)} ± "
          f"{np.round(r.isb_std[-1], 2)}, rejected {r.counts['rejected']} of {r.counts['rate_used']} rates")
    assert r.isb_systems == "ECR" and np.all(np.abs(z) < 3.0)
    assert r.counts["rejected"] < 0.01 * r.counts["rate_used"]
    assert np.sqrt(np.mean(err**2)) < 3.0
