"""The engine adds a node's IMU gap variance whatever part of it is nonzero (issue 40, session 17): a
velocity-only variance (the tight filter's two-column ``gap_var``: the IMU-GNSS timing noise at the velocity
records, :func:`aidnav.filters.tight.timing_variance`) grows P's velocity diagonal by exactly the sum that
reached the node, and the heading hold after a gap fires only where the attitude's variance grew. Known
answers: the same engine inputs run twice with the records unused (P only propagated), the difference of P
at the node is the gap's diagonal."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.filters.engine import C_HOLD, run_filter
from aidnav.filters.layout import DV, PHI
from aidnav.filters.measurements import M_GNSS_VEL
from aidnav.filters.output_rows import NO_ROWS

SOW = 400000.0


@pytest.fixture(scope="module")
def engine_inputs(tight_engine_args):
    """The engine's arguments of a short tight run with velocity records (captured at ``run_filter``)."""
    return tight_engine_args([{"type": "straight", "duration_s": 12}], sow=SOW)[0]


def _run(args, gap_var, k, hold_rad):
    """The run with ``gap_var`` and every record unused (no update), the heading hold's threshold
    ``hold_rad``, P kept after the node at sample ``k`` (none: −1)."""
    imu, rec, mod, proc, ini, out = args
    par = mod.par.copy()
    par[M_GNSS_VEL, C_HOLD] = hold_rad
    return run_filter(imu._replace(gap_var=gap_var), rec._replace(use=np.zeros_like(rec.use)),
                      mod._replace(par=par), proc, ini,
                      out._replace(cov_idx=np.array([k] if k >= 0 else [], np.int64), rows=NO_ROWS))


def _P_at(args, gap_var, k, hold_rad):
    return _run(args, gap_var, k, hold_rad).cov[0]


def _node_half_way(args):
    """(a node's sample half-way through the run, the previous node's sample)."""
    n_imu = args[0].t.shape[0]
    nodes = _run(args, np.zeros((n_imu, 2)), -1, 0.0).node_idx
    i = int(np.searchsorted(nodes, n_imu // 2))
    return int(nodes[i]), int(nodes[i - 1])


@pytest.mark.parametrize("hold_deg", [0.0, 1e-6])
def test_a_velocity_only_gap_variance_grows_the_velocity_diagonal_by_its_sum(engine_inputs, hold_deg):
    """Two samples' velocity variances before a node (the attitude column zero): P at the node grows by
    their sum on the three velocity axes and nowhere else — with the heading hold's threshold below any
    heading σ too (the hold must not fire: the attitude's variance did not grow). Main's engine (the gap
    added only with an attitude part) leaves P unchanged here."""
    n_imu = engine_inputs[0].t.shape[0]
    k, kp = _node_half_way(engine_inputs)  # two samples of the interval before that node
    assert k - kp >= 3
    base = np.zeros((n_imu, 2))
    gv = base.copy()
    gv[kp + 1, 1], gv[k, 1] = 2.5e-4, 1.5e-4
    hold = np.radians(hold_deg)
    d = _P_at(engine_inputs, gv, k, hold) - _P_at(engine_inputs, base, k, hold)
    expect = np.zeros_like(d)
    for i in range(3):
        expect[DV + i, DV + i] = 4.0e-4
    np.testing.assert_allclose(d, expect, rtol=0, atol=1e-15)


def test_the_heading_hold_fires_where_the_attitude_variance_grew(engine_inputs):
    """The contrast: an attitude gap variance with the hold's threshold below the heading σ holds the
    heading unknown at the node (its row and column cleared but the diagonal), as the loose filter's bridged
    gaps do."""
    n_imu = engine_inputs[0].t.shape[0]
    k = _node_half_way(engine_inputs)[0]
    gv = np.zeros((n_imu, 2))
    gv[k, 0] = 1e-6
    P = _P_at(engine_inputs, gv, k, np.radians(1e-6))
    iu = PHI + 2
    off = np.delete(P[iu], iu)
    assert P[iu, iu] > 0 and np.all(off == 0.0)
    P0 = _P_at(engine_inputs, np.zeros((n_imu, 2)), k, np.radians(1e-6))
    assert np.count_nonzero(np.delete(P0[iu], iu)) > 0  # without the gap the heading keeps its correlations
