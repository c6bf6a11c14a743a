"""The consistency matrix's seed-level statistics (:mod:`aidnav.experiments.consistency_seeds`, issue 35
session 16) on synthetic cells whose answer is known by construction: 40 seeds of honest errors constant
within each run, one seed wholly outside 3σ on pitch."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.analysis import seed_consistency as sc
from aidnav.experiments import consistency_matrix as cm
from aidnav.experiments import consistency_seeds as cs

K = 280


def _run(seed, z, sigma=0.01):
    """A seed whose errors are z·σ on every axis at every epoch (constant within the run), the 9-state
    NEES per dof and the attitude NEES those of independent unit z's."""
    t = np.arange(K, dtype=float)
    s = np.full((K, 6), sigma)
    e = np.tile(np.asarray(z, float) * sigma, (K, 1))
    z = np.asarray(z, float)
    return cm.SeedRun(seed, t, e, s, np.full(K, float(z @ z + 3 * z[3] ** 2) / 9.0), t - 1e-6,
                      np.full(K, float(z[3] ** 2 + z[4] ** 2 + z[5] ** 2)))


def _cell(bad_seed=4, bad_z=4.0):
    rng = np.random.default_rng(35)
    runs = []
    for seed in range(40):
        z = np.clip(rng.standard_normal(6), -2.5, 2.5)  # honest draws, all inside 3σ
        if seed == bad_seed:
            z[4] = -bad_z
        runs.append(_run(seed, z))
    return cm.aggregate("tight 3 satellites", "aircraft", runs)


def test_aggregate_blocks_and_pooled_coverage():
    """Pooled over 40 seeds: pitch 39/40 = 97.5 % (passes); the block holding the bad seed: 90 % (fails
    95 %), the other blocks 100 %; the per-seed worst-axis coverage 0 for the bad seed, 1 elsewhere."""
    cell = _cell()
    assert cell.coverage[4] == pytest.approx(0.975)
    assert cell.ok and cell.epochs == 40 * K and cell.seeds == 40
    first = cm.aggregate(cell.condition, cell.config, cell.runs[:10])
    assert first.coverage[4] == pytest.approx(0.9) and not first.ok
    assert cell.per_seed_min[4] == 0.0 and sum(cell.per_seed_min) == 39.0


def test_seed_statistics_known_answers():
    cond = cm.condition("tight 3 satellites")
    assert cs.fixed_times(cond) == {"first turn": 85.0, "end": 279.0}
    st = cs.seed_statistics(_cell(), cond, block=10, n_sim=4000)
    assert [b["ok"] for b in st["blocks"]] == [False, True, True, True]
    assert [b["first"] for b in st["blocks"]] == [0, 10, 20, 30]
    assert st["per_seed_hist"] == [1, 0, 0, 0, 39]
    pitch = st["fixed"]["first turn"]["tilt"]["pitch"]
    assert pitch["worst"] == pytest.approx(4.0) and pitch["worst_seed"] == 4
    # z² of a constant run at any fixed epoch: the χ² sum is that of the draws
    z = np.array([r.err[0, 4] / r.sigma[0, 4] for r in _cell().runs])
    assert pitch["chi2"]["p_upper"] == pytest.approx(sc.chi2_sum(z ** 2, 1)["p_upper"])
    t = st["tilt"]["pitch"]
    assert t["tau_s"] == pytest.approx(140.5, rel=1e-6)  # constant runs: the cap, half the run
    assert t["segment_s"] == np.inf  # constant runs: one stretch per run
    assert t["p_constant"] == pytest.approx(1 - (1 - sc.P3) ** 10)
    assert t["p_honest"] == pytest.approx(t["p_constant"], abs=4 * np.sqrt(t["p_constant"] / 4000))
    assert t["p_gauss_markov"] < t["p_honest"]
    assert t["p_resampled"] == pytest.approx(0.25, abs=4 * np.sqrt(0.25 * 0.75 / 4000))
    text = cs.format_seed_statistics([st])
    assert "FAIL ok ok ok" in text and "1/0/0/0/39" in text
    assert "Seed-level statistics" in "".join(cs.seed_statistics_html([st]))


def test_row_statistics_counts_shared_draws_once():
    """Two configurations of one row on the same seeds' draws (identical runs), roll and pitch drawn
    independently and constant within a run: 8 z-tests (2 cells × 2 axes × 2 fixed epochs) are 2
    independent ones (Galwey's M_eff, within the 40 seeds' sampling noise of a correlation: ±0.3); the block
    holding the bad seed fails in both: 1 of 4 blocks; P(an honest block fails ≥ 1 cell) at τ → ∞:
    1 − (1 − 0.0267)^M_eff."""
    cond = cm.condition("tight 3 satellites")
    a, b = _cell(), _cell()
    stats = [cs.seed_statistics(c, cond, n_sim=2000) for c in (a, b)]
    row = cs.row_statistics([a, b], stats)
    assert row["tests"] == 8
    assert row["m_eff"] == pytest.approx(2.0, abs=0.3)
    assert (row["blocks"], row["blocks_failed"]) == (4, 1)
    assert row["p_any_constant"] == pytest.approx(1 - (1 - sc.constant_block_failure(10)) ** row["m_eff"])
    assert "1 of 4 blocks" in cs.format_row_statistics(row)
