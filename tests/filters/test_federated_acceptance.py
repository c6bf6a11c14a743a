"""Issue 14 acceptance (seed 000, SAPV federated filter): bad SAPV input is skipped and counted, and the
fusion-reset federated filter agrees with the centralized one within its 1σ on the reproduction scenario."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.experiments.reproduce import seed_000 as s0
from aidnav.filters.federated import SAPV_SKIP_REASONS, FederatedConfig, run_federated
from aidnav.nav.geo_pointing import R_GEO_SEED000
from aidnav.nav.rotations import attitude_error_batch
from aidnav.sim import sapv as sp

D = np.pi / 180.0
FAR_SIDE_LON_DEG = s0.SITE["lon_deg"] - 180.0  # antipodal GEO longitude of the vehicle: always below horizon


@pytest.fixture(scope="module")
def case():
    """The seed's static scenario (Table 1), 120 s, one realisation."""
    return s0.simulate_case(np.random.SeedSequence(14), duration_s=120.0)


def _copy(sv, **changes):
    kw = dict(time=sv.time, az=sv.az.copy(), el=sv.el.copy(), reason=sv.reason.copy(), sigma=sv.sigma,
              sat_lon=sv.sat_lon, sat_radius=sv.sat_radius)
    kw.update(changes)
    return sp.SapvData(**kw)


def _run(case, sapv, fed=None):
    sim, _, cfg = case
    return run_federated(sim.imu, sim.gnss, sapv, cfg, fed or FederatedConfig())


def test_counts_of_a_clean_run(case):
    sv = case[1]
    r = _run(case, sv)
    assert set(r.counts["sapv_skipped"]) == set(SAPV_SKIP_REASONS)
    assert r.counts["sapv_used"] == int(sv.valid.sum()) == len(sv)
    assert r.counts["sapv_gated"] == 0 and not any(r.counts["sapv_skipped"].values())
    # SINS/GPS (SAPV not used at all): nothing is reported as skipped
    g = _run(case, sv, FederatedConfig(mode="centralized", use_sapv=False))
    assert g.counts["sapv_used"] == 0 and not any(g.counts["sapv_skipped"].values())


def test_satellite_below_the_horizon_is_skipped_and_counted(case):
    """Angles that claim to track a GEO on the far side of the Earth: every epoch skipped (status −3),
    counted as ``below_horizon``, and the solution is exactly SINS/GPS."""
    sv = case[1]
    far = _copy(sv, sat_lon=FAR_SIDE_LON_DEG * D)
    r = _run(case, far)
    assert r.counts["sapv_skipped"]["below_horizon"] == len(sv)
    assert r.counts["sapv_used"] == 0 and (r.sapv_status == -3).all()
    assert np.isnan(r.sapv_nis).all()
    g = _run(case, sv, FederatedConfig(use_sapv=False))
    np.testing.assert_array_equal(r.state, g.state)
    np.testing.assert_array_equal(r.pdiag, g.pdiag)


def test_simulator_flags_a_satellite_below_the_horizon(case):
    """The antenna model never reports angles to a satellite the Earth hides (NaN, LOW_ELEVATION, event)."""
    truth = case[0].truth
    spec = s0.sapv_spec(sat_lon_deg=FAR_SIDE_LON_DEG, elevation_mask_deg=-90.0)  # the mask alone passes all
    d = sp.simulate_sapv(truth, spec, np.random.default_rng(0))
    assert (d.reason == sp.LOW_ELEVATION).all() and not d.valid.any()
    assert np.isnan(d.az).all() and np.isnan(d.el).all()
    assert any("below the horizon" in e for e in d.events)
    # the filter then skips them as "not tracking"
    r = _run(case, d)
    assert r.counts["sapv_skipped"]["not_tracking"] == len(d) and r.counts["sapv_used"] == 0


def test_out_of_range_and_nan_angles_are_skipped_and_counted(case):
    """el > 90°, az < 0, az >= 360° (degrees passed as radians) and NaN on a 'tracking' epoch: skipped
    (status −2) and counted by reason; the other epochs are used, and the solution equals the one with those
    epochs marked lost. A flagged loss is counted as ``not_tracking`` (status −1)."""
    sv = case[1]
    az, el = sv.az.copy(), sv.el.copy()
    el[10] = 95.0 * D
    el[11] = -91.0 * D
    az[20] = -0.01
    az[21] = np.degrees(az[21])  # degrees by mistake: > 2π
    az[22] = 2.0 * np.pi
    az[30] = np.nan
    el[31] = np.nan
    bad = _copy(sv, az=az, el=el).with_loss(60.0, 70.0)
    r = _run(case, bad)
    sk = r.counts["sapv_skipped"]
    lost = (sv.time >= 60.0) & (sv.time < 70.0)
    assert sk == {"not_tracking": int(lost.sum()), "nan": 2, "angle_out_of_range": 5, "below_horizon": 0}
    idx = [10, 11, 20, 21, 22, 30, 31]
    assert (r.sapv_status[idx] == -2).all() and (r.sapv_status[lost] == -1).all()
    assert r.counts["sapv_used"] == len(sv) - 7 - int(lost.sum()) == int((r.sapv_status == 1).sum())
    rs = bad.reason.copy()
    rs[idx] = sp.BLOCKED
    ref = _run(case, _copy(bad, reason=rs))
    np.testing.assert_array_equal(r.state, ref.state)
    assert np.all(np.isfinite(r.state)) and np.all(np.isfinite(r.pdiag))


def test_federated_reset_agrees_with_centralized_within_1_sigma():
    """Reproduction scenario (seed_000.simulate_case, full 500 s): fusion-reset β = ½, ½ against the
    centralized filter, every state at every epoch: |x_fed − x_cen| < σ_cen (the fused and central states
    are compared directly: attitude as the rotation between the two estimates)."""
    sim, sv, cfg = s0.simulate_case(np.random.SeedSequence(2012))
    reset = FederatedConfig(mode="reset", beta_gps=0.5, beta_sapv=0.5)
    fed = run_federated(sim.imu, sim.gnss, sv, cfg, reset)
    cen = run_federated(sim.imu, sim.gnss, sv, cfg, FederatedConfig(mode="centralized"))
    np.testing.assert_array_equal(fed.time, cen.time)
    assert fed.counts["sapv_used"] == cen.counts["sapv_used"] == len(sv)
    sig = np.sqrt(cen.pdiag)
    d = np.empty_like(sig)
    d[:, 0:3] = attitude_error_batch(np.ascontiguousarray(fed.state[:, 6:10]),
                                     np.ascontiguousarray(cen.state[:, 6:10]))
    d[:, 3:6] = fed.state[:, 3:6] - cen.state[:, 3:6]
    d[:, 6:9] = fed.state[:, 0:3] - cen.state[:, 0:3]
    d[:, 9:15] = fed.bias - cen.bias
    ratio = np.abs(d) / sig
    assert np.all(ratio < 1.0), f"largest |x_fed − x_cen| / σ_cen = {ratio.max():.3g}"
    # in fact they agree to rounding (the fusion-reset filter is algebraically the centralized one)
    assert ratio.max() < 1e-6
    assert sv.sat_radius == R_GEO_SEED000
