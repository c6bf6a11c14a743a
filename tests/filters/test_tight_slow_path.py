"""The tight filter's fast predict changes no result (issue 40): a whole simulated run of the
no-configuration model (27 INS states: 12 constant, 6 diagonal bias rows; clock; range errors) with velocity
records between the epochs, once as ``run_tight`` runs it (the head's series over F's nonzero entries, its
constant and diagonal rows and the range-error tail kept out of the products) and once through the
engine's slow path (the full-matrix series and Φ P Φᵀ + Qd at every node: the path a filter without a
scalar tail takes). The slow path is forced by giving one range-error state its exact Gauss–Markov
transition (``Process.gm``), which differs from the series' by (T/τ)³/6 ≈ 3e-11 relative (τ = 1800 s,
T ≤ 1 s): the two runs agree to that, not to a golden number."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.data import ImuData
from aidnav.filters import tight as tight_module
from aidnav.filters.config import UNKNOWN_GRADE_IMU
from aidnav.filters.engine import run_filter
from aidnav.filters.layout import L_N, L_RERR
from aidnav.filters.output_rows import NO_ROWS, whole_run_rows
from aidnav.filters.tight import TightConfig, run_tight
from aidnav.nav.earth import radii
from aidnav.sim.gnss_constellation import nominal_constellation
from aidnav.sim.gnss_raw import RawGnssSpec, simulate_raw_gnss
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth

SOW = 400000.0


@pytest.fixture(scope="module")
def engine_inputs():
    """The engine's arguments of a tight run (no-configuration IMU model, TDCP-like velocity records)."""
    scn = parse_scenario({
        "initial": {"lat_deg": 34.2, "lon_deg": 108.9, "height_m": 500, "speed_m_s": 10, "heading_deg": 30},
        "imu_rate_hz": 50, "transition_s": 2.0,
        "segments": [{"type": "straight", "duration_s": 30},
                     {"type": "turn", "angle_deg": 90, "rate_deg_s": 6},
                     {"type": "straight", "duration_s": 45}]})
    truth, imu_true, _ = generate_truth(scn)
    imu, _ = corrupt_imu(imu_true, ImuSpec.grade("mems"), np.random.default_rng(3))
    imu = ImuData(imu.time + SOW, imu.dtheta, imu.dv, t0=imu.t0 + SOW)
    eph = nominal_constellation(2381, SOW, 24)
    gnss = simulate_raw_gnss(truth, eph, RawGnssSpec(rate_hz=2.0), np.random.default_rng(4), SOW).rover
    # velocity records half-way between the epochs (as the TDCP mean velocities): nodes of their own
    tv = 0.5 * (gnss.time[1:] + gnss.time[:-1])
    j = np.searchsorted(truth.time, tv - SOW)
    rng = np.random.default_rng(5)
    vel = (tv, truth.vel[j] + rng.normal(0.0, 0.02, (len(j), 3)), np.full((len(j), 3), 0.02))
    rm, rn = radii(truth.lat[0])
    init = (SOW + truth.time[0], truth.lat[0] + 1.0 / rm, truth.lon[0], truth.height[0] - 1.0,
            truth.vel[0] + 0.05, truth.rph[0] + np.radians([0.1, -0.1, 0.5]))
    captured = {}

    def capture(*a):
        captured["a"] = a
        return run_filter(*a)

    cfg = TightConfig(imu=UNKNOWN_GRADE_IMU)
    mp = pytest.MonkeyPatch()
    mp.setattr(tight_module, "run_filter", capture)  # (this project's own module)
    try:
        res = run_tight(imu, gnss, eph, cfg, init_state=init, velocity_fixes=vel)
    finally:
        mp.undo()
    assert res.nstate == 27 + 2 + int(res.range_error.shape[1]) and res.range_error.shape[1] >= 6
    assert res.counts["velocity_records"] == len(tv) and res.counts["pr_used"] > 0
    return captured["a"]


def test_the_fast_predict_gives_the_slow_paths_solution(engine_inputs):
    imu, rec, mod, proc, ini, out = engine_inputs
    fast = run_filter(imu, rec, mod, proc, ini, out)
    n, ir = int(proc.lay[L_N]), int(proc.lay[L_RERR])
    tau = TightConfig().gnss.range_error_tau_s
    slow_proc = proc._replace(gm=np.array([[n - 1.0, -1.0, 1.0 / tau, 1.0]]))  # unit-variance Markov state
    assert ir >= 0 and n - 1 >= ir
    slow = run_filter(imu, rec, mod, slow_proc, ini, out._replace(rows=NO_ROWS))  # (not fast's rows)
    assert fast.n_log == slow.n_log and np.array_equal(fast.log.status, slow.log.status)
    np.testing.assert_array_equal(fast.out_idx, slow.out_idx)
    pos = np.abs(fast.out_st[:, :3] - slow.out_st[:, :3]) * np.array([6.4e6, 6.4e6, 1.0])  # [m]
    assert pos.max() < 1e-6
    assert np.abs(fast.out_st[:, 3:] - slow.out_st[:, 3:]).max() < 1e-8  # velocity [m/s], quaternion
    scale = np.sqrt(np.outer(np.diag(slow.P), np.diag(slow.P)))
    assert np.all(np.abs(fast.P - slow.P) <= 1e-7 * scale)
    np.testing.assert_allclose(fast.out_pdiag, slow.out_pdiag, rtol=1e-7, atol=1e-30)
    np.testing.assert_allclose(fast.bias, slow.bias, rtol=1e-7, atol=1e-12)


def test_the_callers_output_block_gives_the_kernels_own_arrays(engine_inputs):
    """``run_tight``'s outputs in one block it allocates (:mod:`aidnav.filters.output_rows`: huge pages) are
    the numbers the kernel writes into its own arrays, bit for bit; the block is the one filled."""
    imu, rec, mod, proc, ini, out = engine_inputs
    own = run_filter(imu, rec, mod, proc, ini, out._replace(rows=NO_ROWS))
    rows = whole_run_rows(out.rows[0].shape[0], out.rows[1].shape[1], out.rows[2].shape[1])
    blk = run_filter(imu, rec, mod, proc, ini, out._replace(rows=rows))
    assert len(own.out_idx) == rows[0].shape[0]
    for a, b, r in zip((own.out_st, own.out_bias, own.out_pdiag), (blk.out_st, blk.out_bias, blk.out_pdiag),
                       rows, strict=True):
        assert np.shares_memory(b, r) and not np.shares_memory(a, r)
        np.testing.assert_array_equal(b, a)
    np.testing.assert_array_equal(blk.P, own.P)
    np.testing.assert_array_equal(blk.out_node, own.out_node)
