"""§5.3 trends of the seed-004 reproduction on a small Monte Carlo (fixed seeds, common random
numbers), with the reproduction's own cases (ARW reading of the sub-IMU, Gauss-Markov master position
drift):

* the S, O, figure-8 and climb maneuvers give pitch and roll STDs within ±30 % of their mean, and no
  maneuver gives ≥ 2× worse pitch and roll;
* attitude nearly independent of the GNSS baseline (±10 %), velocity and horizontal position STDs
  non-decreasing with it (the master's velocity carries the rate of its baseline-dependent position
  drift, and the sub's position, the integral of its matched velocity, follows the drift).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from aidnav.experiments.reproduce import seed_004 as s4

pytestmark = pytest.mark.slow
RUNS = 4


@pytest.fixture(scope="module")
def runner():
    return s4._Runner(np.random.SeedSequence(11).spawn(RUNS), lambda m: None)


def _spread(v) -> float:
    v = np.asarray(v, float)
    return float(np.max(np.abs(v / v.mean() - 1.0)))


@pytest.mark.slow
def test_maneuvers_give_similar_pitch_and_roll(runner):
    t4 = {m: runner.run(s4.Case(mode=m, t1=0.0, t2=400.0)).mean() for m in s4.MODES}
    four = ("s_turns", "o_circle", "figure8", "climb")
    for q in ("pitch", "roll"):
        v = [t4[m][q] for m in four]
        assert _spread(v) <= 0.3, (q, v)
        assert t4["none"][q] >= 2.0 * np.mean(v), (q, t4["none"][q], v)
    assert t4["none"]["heading"] >= 5.0 * t4["figure8"]["heading"]


@pytest.mark.slow
def test_baseline_moves_velocity_and_position_not_attitude(runner, monkeypatch):
    t8 = {b: runner.run(replace(s4.BASE, baseline_km=float(b))).mean() for b in s4.BASELINES}
    for q in ("heading", "pitch", "roll"):
        assert _spread([t8[b][q] for b in s4.BASELINES]) <= 0.1, q
    for q in ("vE", "vN", "lat", "lon"):
        v = [t8[b][q] for b in s4.BASELINES]
        assert v[0] <= v[1] <= v[2], (q, v)
    assert t8[60]["lat"] > 1.1 * t8[20]["lat"] and t8[60]["vE"] > 1.02 * t8[20]["vE"]
    # and it is the master's drift that does it: with white master position errors only, flat
    white = s4.sim_config

    def sim_white(case):
        cfg = white(case)
        return replace(cfg, master=replace(cfg.master, pos_drift_fraction=0.0))

    monkeypatch.setattr(s4, "sim_config", sim_white)
    r = s4._Runner(np.random.SeedSequence(11).spawn(RUNS), lambda m: None)
    w = {b: r.run(replace(s4.BASE, baseline_km=float(b))).mean() for b in (20, 60)}
    assert w[60]["vE"] == pytest.approx(w[20]["vE"], rel=0.01)
    assert w[60]["lat"] == pytest.approx(w[20]["lat"], rel=0.02)


@pytest.mark.slow
def test_heading_does_not_decrease_as_t2_grows():
    """Heading STD vs the imaging-leg length T2 (figure-8, T1 = 200 s), paired over 20 runs with common
    random numbers: it grows from 100 to 200 s, and no decrease from 200 to 400 s is detectable (the
    paired change is above −2 standard errors; with 10 runs the reproduction's means differ by 1 %)."""
    r = s4._Runner(np.random.SeedSequence(21).spawn(20), lambda m: None)
    h = {t2: r.run(s4.Case(mode="figure8", t1=200.0, t2=float(t2))).std[:, 0] for t2 in s4.T2_VALUES}
    for a, b in ((100, 200), (200, 400)):
        d = h[b] - h[a]
        z = d.mean() / (d.std(ddof=1) / np.sqrt(len(d)))
        assert z > -2.0, (a, b, z)
    assert h[200].mean() > h[100].mean()
