"""SPP, residual check, base/rover single differences and dead reckoning (seed 001)."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.data import Trajectory
from aidnav.estimators.dgps import (
    dead_reckon,
    relative_position,
    satellites_from_pseudoranges,
    spp,
)
from aidnav.nav.earth import dcm_ecef_to_enu, lla_to_ecef, radii
from aidnav.sim.gnss_constellation import nominal_constellation
from aidnav.sim.gnss_raw import RawGnssSpec, simulate_raw_gnss, static_pseudoranges

LAT, LON, H = np.radians(34.2), np.radians(108.9), 400.0
SOW = 400000.0
EPH = nominal_constellation(2381, SOW, 24)


def _sats(pr, t):
    return satellites_from_pseudoranges(EPH.table, EPH.table[:, 0], t, pr, max_age_s=1e7)


def _static_truth(lat, lon, h, duration=60.0, dt=0.5):
    t = np.arange(0, duration + 1e-9, dt)
    n = len(t)
    return Trajectory(t, np.full(n, lat), np.full(n, lon), np.full(n, h), np.zeros((n, 3)), np.zeros((n, 3)))


def test_spp_recovers_truth_within_dop_bounds():
    rng = np.random.default_rng(3)
    rx = np.array(lla_to_ecef(LAT, LON, H))
    z = []
    for k in range(200):
        t = SOW + 60.0 * k
        pr, el = static_pseudoranges(EPH, t, rx, 1234.5)
        sig = 1.0 * np.sqrt(0.5 + 0.5 / np.sin(np.maximum(el, 0.035)) ** 2)
        prn = pr + rng.standard_normal(len(pr)) * sig
        pos, _, clk, _ = _sats(prn, t)
        r = spp(pos, clk, prn, t_sow=t, sigma0=1.0, tropo=False, mask_deg=5.0)
        assert r.status in ("ok", "excluded")
        d = np.r_[r.ecef - rx, r.clock_m - 1234.5]
        z.append(d @ np.linalg.solve(r.cov, d))
        assert np.linalg.norm(r.ecef - rx) < 6 * r.dop["pdop"]
    # NEES of (x, y, z, clock): mean 4 within its 99 % bounds for 200 samples
    assert 3.4 < np.mean(z) < 4.7


def test_spp_residual_check_excludes_faulty_satellite_and_reports_zero_redundancy():
    rx = np.array(lla_to_ecef(LAT, LON, H))
    pr, el = static_pseudoranges(EPH, SOW, rx, 0.0)
    vis = np.flatnonzero(np.isfinite(pr))
    assert len(vis) >= 6
    bad = vis[2]
    pr_f = pr + np.random.default_rng(1).normal(0, 0.3, len(pr))
    pr_f[bad] += 60.0
    pos, _, clk, _ = _sats(pr_f, SOW)
    r = spp(
        pos, clk, pr_f, prns=EPH.table[:, 0].astype(int), t_sow=SOW, sigma0=0.3, tropo=False, mask_deg=0.0
    )
    assert r.excluded == [int(EPH.table[bad, 0])]
    assert r.status == "excluded"
    assert np.linalg.norm(r.ecef - rx) < 3.0
    # exactly four satellites: zero redundancy, solved but unchecked
    keep = np.full(len(pr), np.nan)
    keep[vis[:4]] = pr[vis[:4]]
    pos, _, clk, _ = _sats(keep, SOW)
    r4 = spp(pos, clk, keep, t_sow=SOW, tropo=False, mask_deg=0.0)
    assert r4.status == "no redundancy: unchecked" and r4.n_used == 4
    assert np.linalg.norm(r4.ecef - rx) < 1e-3
    three = keep.copy()
    three[vis[0]] = np.nan
    pos, _, clk, _ = _sats(three, SOW)
    assert spp(pos, clk, three, t_sow=SOW, tropo=False, mask_deg=0.0).status == "too few satellites"


def _glide(b_m):
    enu = np.array([0.0, -b_m, b_m * np.tan(np.radians(3.0))])
    pb = np.array(lla_to_ecef(LAT, LON, H))
    return pb, pb + dcm_ecef_to_enu(LAT, LON).T @ enu, enu


@pytest.mark.parametrize("b_km", [1.0, 20.0, 40.0])
def test_relative_ls_common_mode_iterated_exact_single_linearisation_not(b_km):
    rng = np.random.default_rng(int(b_km))
    pb, pk, enu = _glide(b_km * 1e3)
    pr_b, _ = static_pseudoranges(EPH, SOW, pb, 2e4)
    pr_k, _ = static_pseudoranges(EPH, SOW, pk, -5e3)
    common = rng.normal(0, 10.0, len(pr_b))
    pr_b, pr_k = pr_b + common, pr_k + common
    sb, _, _, _ = _sats(pr_b, SOW)
    sk, _, _, _ = _sats(pr_k, SOW)
    # base position only roughly known (10 m) still gives mm-level relative positions at these baselines
    r = relative_position(pb, sb, pr_b, sk, pr_k, weighting="equal")
    assert np.linalg.norm(r.enu - enu) < 1e-3
    assert r.clock_m == pytest.approx(-5e3 - 2e4, abs=1e-3)
    rr = relative_position(pb + np.array([6.0, -5.0, 5.0]), sb, pr_b, sk, pr_k, weighting="equal")
    assert np.linalg.norm(rr.enu - enu) < 0.02 * b_km
    r1 = relative_position(pb, sb, pr_b, sk, pr_k, weighting="equal", iterate=False)
    err1 = np.linalg.norm(r1.enu - enu)
    # second-order error of the single linearisation ~ b²/(2ρ): metres at 20 km
    if b_km >= 20:
        assert err1 > 0.3
    rng_m, az, el = r.range_m, r.azimuth, r.elevation
    assert rng_m == pytest.approx(np.linalg.norm(enu), abs=1e-3)
    assert np.degrees(az) == pytest.approx(180.0, abs=1e-6)
    assert np.degrees(el) == pytest.approx(np.degrees(np.arctan2(enu[2], b_km * 1e3)), abs=1e-6)


def test_relative_ls_noise_covariance_nees():
    rng = np.random.default_rng(7)
    pb, pk, enu = _glide(20e3)
    z = []
    for k in range(10):
        t = SOW + 300.0 * k
        pr_b, _ = static_pseudoranges(EPH, t, pb, 0.0)
        pr_k, _ = static_pseudoranges(EPH, t, pk, 100.0)
        sb, _, _, _ = _sats(pr_b, t)
        for _ in range(30):
            p = pr_k + rng.standard_normal(len(pr_k))
            sk, _, _, _ = _sats(p, t)
            r = relative_position(pb, sb, pr_b, sk, p, sigma0=1.0, weighting="equal")
            d = np.r_[r.enu - enu, r.clock_m - 100.0]
            z.append(d @ np.linalg.solve(r.cov, d))
    assert 3.5 < np.mean(z) < 4.55  # 300 draws of χ²(4): mean 4 ± 0.3 (2.6 σ)


def test_single_differences_cancel_common_errors_and_decorrelate_with_baseline():
    spec = RawGnssSpec(
        code_sigma_m=0.0,
        rate_sigma_m_s=0.0,
        multipath_sigma_m=0.0,
        rate_hz=1.0,
        iono_gradient_mm_km=5.0,
        tropo_zenith_sigma_m=0.05,
    )
    alpha = np.array([1.1176e-8, 7.4506e-9, -5.9605e-8, -5.9605e-8])
    rm, _ = radii(LAT)
    errs, spp_errs = {}, []
    for b_km in (1.0, 40.0):
        lat_k = LAT - b_km * 1e3 / (rm + H)
        truth = _static_truth(lat_k, LON, H, duration=20.0)
        sim = simulate_raw_gnss(truth, EPH, spec, np.random.default_rng(11), SOW, base_lla=(LAT, LON, H))
        rv, bs = sim.rover, sim.base
        e = []
        for k in range(len(rv.time)):
            sk, _, ck, _ = _sats(rv.code1[k], rv.time[k])
            sb, _, _, _ = _sats(bs.code1[k], bs.time[k])
            r = relative_position(sim.base_ecef, sb, bs.code1[k], sk, rv.code1[k], tropo_difference=True)
            true_rel = dcm_ecef_to_enu(LAT, LON) @ (sim.truth["antenna_ecef"][k] - sim.base_ecef)
            e.append(np.linalg.norm(r.enu - true_rel))
            if b_km == 1.0:
                s = spp(
                    sk,
                    ck,
                    rv.code1[k],
                    t_sow=rv.time[k],
                    iono_alpha=alpha,
                    iono_beta=np.array([9.0112e4, 4.9152e4, -1.9661e5, -6.5536e4]),
                )
                spp_errs.append(np.linalg.norm(s.ecef - sim.truth["antenna_ecef"][k]))
        errs[b_km] = np.mean(e)
    assert errs[1.0] < 0.1 * np.mean(spp_errs)
    assert errs[1.0] < 0.05
    assert errs[40.0] > 2 * errs[1.0]


def test_dead_reckoning_exact_and_frame_rotation():
    # constant ENU velocity of a rover 25 km south of the base: trapezoid and Euler exact for constant v
    rm, rn = radii(LAT)
    t = np.arange(0, 20.0 + 1e-9, 0.02)
    v = np.array([0.0, 70.0, 0.0])
    lat_k = LAT - 25e3 / (rm + H) + v[1] * t / (rm + H)
    lon_k = np.full_like(t, LON + 5e3 / (rn * np.cos(LAT)))
    vel = np.tile(v, (len(t), 1))
    dx0 = np.array([5e3, -25e3, 1300.0])
    tr = dead_reckon(t, vel, lat_k, lon_k, LAT, LON, dx0, method="trapezoid")
    eu = dead_reckon(t, vel, lat_k, lon_k, LAT, LON, dx0)
    np.testing.assert_allclose(tr, eu, atol=1e-3)  # the rotated velocity turns slowly (curvature)
    nr = dead_reckon(t, vel, lat_k, lon_k, LAT, LON, dx0, rotate=False)
    # rover 5 km east: the North axes differ by ~Δλ sinL; vertical axes by ~25 km/R ≈ 0.22°
    gap = np.linalg.norm(nr[-1] - tr[-1])
    assert 3.0 < gap < 6.0
    # velocity of the rover in the base frame (exact rotation) has a vertical component from the curvature
    assert tr[-1, 2] - dx0[2] == pytest.approx(1400 * 25e3 / 6.37e6, rel=0.05)
