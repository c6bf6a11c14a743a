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

from aidnav.filters.engine import run_filter
from aidnav.filters.layout import L_N, L_RERR
from aidnav.filters.output_rows import NO_ROWS, whole_run_rows
from aidnav.filters.tight import TightConfig

SOW = 400000.0


@pytest.fixture(scope="module")
def engine_inputs(tight_engine_args):
    """The engine's arguments of a tight run (no-configuration IMU model, TDCP-like velocity records)."""
    segments = [{"type": "straight", "duration_s": 30}, {"type": "turn", "angle_deg": 90, "rate_deg_s": 6},
                {"type": "straight", "duration_s": 45}]
    args, res, n_vel = tight_engine_args(segments, vel_noise_m_s=0.02, start_error=True, sow=SOW)
    assert res.nstate == 27 + 2 + int(res.range_error.shape[1]) and res.range_error.shape[1] >= 6
    assert res.counts["velocity_records"] == n_vel and res.counts["pr_used"] > 0
    return args


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
