"""The engine adds a node's IMU gap variance whatever part of it is nonzero (issue 40, session 17): a
velocity-only variance (the tight filter's two-column ``gap_var``: the IMU-GNSS timing noise at the velocity
records, :func:`aidnav.filters.tight.timing_variance`) grows P's velocity diagonal by exactly the sum that
reached the node, and the heading hold after a gap fires only where the attitude's variance grew. Known
answers: the same engine inputs run twice with the records unused (P only propagated), the difference of P
at the node is the gap's diagonal."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.data import ImuData
from aidnav.filters import tight as tight_module
from aidnav.filters.config import UNKNOWN_GRADE_IMU
from aidnav.filters.engine import C_HOLD, run_filter
from aidnav.filters.layout import DV, PHI
from aidnav.filters.measurements import M_GNSS_VEL
from aidnav.filters.output_rows import NO_ROWS
from aidnav.filters.tight import TightConfig, run_tight
from aidnav.sim.gnss_constellation import nominal_constellation
from aidnav.sim.gnss_raw import RawGnssSpec, simulate_raw_gnss
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth

SOW = 400000.0


@pytest.fixture(scope="module")
def engine_inputs():
    """The engine's arguments of a short tight run with velocity records (captured at ``run_filter``)."""
    scn = parse_scenario({
        "initial": {"lat_deg": 34.2, "lon_deg": 108.9, "height_m": 500, "speed_m_s": 10, "heading_deg": 30},
        "imu_rate_hz": 50, "transition_s": 2.0, "segments": [{"type": "straight", "duration_s": 12}]})
    truth, imu_true, _ = generate_truth(scn)
    imu, _ = corrupt_imu(imu_true, ImuSpec.grade("mems"), np.random.default_rng(3))
    imu = ImuData(imu.time + SOW, imu.dtheta, imu.dv, t0=imu.t0 + SOW)
    eph = nominal_constellation(2381, SOW, 24)
    gnss = simulate_raw_gnss(truth, eph, RawGnssSpec(rate_hz=2.0), np.random.default_rng(4), SOW).rover
    tv = 0.5 * (gnss.time[1:] + gnss.time[:-1])
    j = np.searchsorted(truth.time, tv - SOW)
    vel = (tv, truth.vel[j], np.full((len(j), 3), 0.02))
    init = (SOW + truth.time[0], truth.lat[0], truth.lon[0], truth.height[0], truth.vel[0], truth.rph[0])
    captured = {}

    def capture(*a):
        captured["a"] = a
        return run_filter(*a)

    mp = pytest.MonkeyPatch()
    mp.setattr(tight_module, "run_filter", capture)  # (this project's own module)
    try:
        run_tight(imu, gnss, eph, TightConfig(imu=UNKNOWN_GRADE_IMU), init_state=init, velocity_fixes=vel)
    finally:
        mp.undo()
    return captured["a"]


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
