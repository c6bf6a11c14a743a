"""Issue 39, session 8: what the seed-000 pitch row and seed-004 Table 8's velocity/position rows rest on.

* Seed 004: with the white master of the seed's text, the GNSS baseline reaches the sub's velocity and
  position only through the sub's first epoch (initialised at the master's position, P0 = the master's
  position σ): a 60-km run restarted from the 20-km run's first-epoch position with the 20-km filter gives
  the 20-km errors bit for bit (the structural null of Table 8's "non-decreasing with L0" rows), and the
  verdict follows that control, not a tolerance.
* Seed 000: the initial level errors are fitted to Table 2 state 1 (least relative squared misfit of the
  SINS/GPS pitch and roll std), and with Table 1's GPS velocity the filter's own pitch σ at 30 s is above
  2′ at any level prior (the tilt the antenna cannot see is observed only through the GPS velocity).
"""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from aidnav.experiments.reproduce import seed_000
from aidnav.experiments.reproduce import seed_004_tables as t4
from aidnav.filters import transfer as tf
from aidnav.models.distributed_pos import MasterPosSpec
from aidnav.sim import distributed_pos as dp
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth

INI = {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 7000.0, "speed_m_s": 100.0, "heading_deg": 40.0}


def test_baseline_reaches_the_sub_only_through_its_first_epoch():
    bundle = generate_truth(parse_scenario({"initial": INI, "segments": [
        {"type": "straight", "duration_s": 30.0}, {"type": "o_circle", "duration_s": 120.0, "name": "O"},
        {"type": "straight", "duration_s": 60.0, "name": "AB"}]}, "<test>"))
    cfgs = {b: dp.DistributedPosConfig(master=MasterPosSpec.for_gnss_baseline(b, pos_drift_fraction=0.0))
            for b in (20.0, 60.0)}
    geo = dp.sub_geometry(bundle[0], bundle[1], cfgs[20.0].lever_arm)
    runs = {b: dp.simulate_distributed_pos(bundle, c, 7, geo) for b, c in cfgs.items()}
    f20 = tf.TransferConfig.from_sim(cfgs[20.0])

    def errors(run, fcfg):
        e = tf.transfer_errors(tf.run_transfer(run, fcfg), run)
        return np.column_stack([e.vel, e.pos])

    ref = errors(runs[20.0], f20)
    far = runs[60.0]
    # the same draws: the master's velocity and attitude noise do not depend on the baseline
    np.testing.assert_array_equal(far.master.vel, runs[20.0].master.vel)
    assert np.max(np.abs(errors(far, tf.TransferConfig.from_sim(cfgs[60.0])) - ref)) > 1e-4  # it does act
    first = {a: np.concatenate([getattr(runs[20.0].master, a)[:1], getattr(far.master, a)[1:]])
             for a in ("lat", "lon", "height")}
    ctl = replace(far, master=replace(far.master, **first))
    np.testing.assert_array_equal(errors(ctl, f20), ref)  # ... through the first epoch and P0 only


def _group(lat_ratio: float, vel_ratio: float = 1.0, runs: int = 4) -> t4.Group:
    rng = np.random.default_rng(3)
    base = rng.uniform(0.5, 1.5, (runs, len(t4.QUANTS)))
    cases = {}
    for b, k in zip(t4.BASELINES, (0, 1, 2), strict=True):
        a = base.copy()
        a[:, t4.QUANTS.index("lat")] *= lat_ratio**k
        for q in ("vE", "vN", "vU"):
            a[:, t4.QUANTS.index(q)] *= vel_ratio**k
        a[:, t4.QUANTS.index("baseline")] *= (1.0, 5.0, 10.0)[k]
        cases[b] = SimpleNamespace(std=a)
    return t4.Group(cases)


def _row(rows, q):
    return next(r for r in rows if r["quantity"].startswith(f"{q}: smallest ratio"))


def test_table8_null_verdict_follows_the_first_epoch_control():
    g = _group(lat_ratio=0.998)  # a 0.2 % decrease per step: beyond the 0.1 % tolerance
    control = {"vE": 0.0, "vN": 0.0, "vU": 0.0, "lat": 0.0, "lon": 0.0, "runs": 2, "near": 20, "far": 60}
    rows = t4.t8_rows(g, control=control)
    for q in ("vE", "vN", "vU", "lat", "lon"):
        r = _row(rows, q)
        assert r["verdict"] == "structural-null" and r["holds"] is False, q
        assert "first epoch" in r["reason"] and "bit for bit" in r["reason"]
    assert "drifting master" in _row(t4.t8_rows(g, spec=False, control=control), "lat")["reason"]
    # a control that does not reproduce the near-baseline STD leaves the trend to the Monte Carlo
    rows = t4.t8_rows(g, control={**control, "lat": 1e-3})
    assert _row(rows, "lat")["verdict"] == "fails" and _row(rows, "vE")["verdict"] == "structural-null"
    # without a control: the tolerance rule (lat changes by 0.2 % per step, velocity not at all)
    rows = t4.t8_rows(g)
    assert _row(rows, "lat")["verdict"] == "fails" and _row(rows, "vN")["verdict"] == "structural-null"


def test_level_fit_takes_the_least_misfit_to_table_2_state_1():
    ps, rs = seed_000.PAPER_STATE1_LEVEL_STD["pitch"], seed_000.PAPER_STATE1_LEVEL_STD["roll"]

    def cell(p, r):
        return {"p_std": p, "r_std": r, "fit": ((p - ps) / ps) ** 2 + ((r - rs) / rs) ** 2}

    sweep = {0.1: cell(1.36, 1.22), 0.4: cell(3.41, 2.82), 0.5: cell(3.91, 3.23)}
    assert seed_000.level0_fit(sweep) == 0.5  # misfit 0.061 against 0.067 at 0.4°
    sweep[0.4] = cell(3.3, 3.7)
    assert seed_000.level0_fit(sweep) == 0.4


def test_level_prior_and_the_30_s_pitch_limit():
    sw = seed_000.level0_sweep(2, 5, 120.0, levels=(0.1, 0.5), phi_u=-3.5)
    assert sw[0.5]["p_std"] > 1.5 * sw[0.1]["p_std"] and sw[0.5]["r_std"] > 1.5 * sw[0.1]["r_std"]
    # Table 1's GPS velocity (0.5 m/s) cannot settle the unseen tilt below 2′ (1σ) by 30 s, whatever the prior
    assert 2.0 < sw[0.1]["sigma30"] <= sw[0.5]["sigma30"] < 2.0 * sw[0.1]["sigma30"]
    for c in sw.values():
        assert c["rms30"] > 0 and c["t_below"] >= 0
        assert c["fit"] == pytest.approx(((c["p_std"] - 3.2584) / 3.2584) ** 2
                                         + ((c["r_std"] - 3.7765) / 3.7765) ** 2)
