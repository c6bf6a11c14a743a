"""Seed-level statistics of the consistency matrix's cells (issue 35, session 16): can a cell's 10-seed
coverage decide whether the filter's σ is honest?

In the tight rows (:mod:`aidnav.experiments.consistency_matrix`) the attitude error is made of a handful
of constants drawn once per seed (accelerometer biases, gyro misalignments), so a seed is nearly wholly
inside or wholly outside 3σ and one 3σ draw among ~12 constants × 10 seeds fails a cell. For a cell run
over more seeds (``benchmarks/consistency_matrix.py --tight-seeds 40``) :func:`seed_statistics` gives:

* the pooled coverage over all its seeds, and each consecutive block of ``block`` seeds' (the default
  10-seed figure is the first block's, :func:`aggregate` of those seeds);
* at fixed epochs (:func:`fixed_times`: the end of the first turn, where the turn has split the
  accelerometer bias from the tilt as far as it can, and the end of the run), per seed: the NEES of the 9
  navigation states (χ²₉) and of the attitude error φ (χ²₃), and the z = error/σ of roll and pitch; their
  sums over the seeds against χ²(R·n) (:func:`aidnav.analysis.seed_consistency.chi2_sum`: independent across
  seeds, so exact, unlike a test over each run's correlated epochs) and the z's KS test against N(0, 1);
* the per-seed worst-axis coverage distribution;
* for roll and pitch: the length L of the stretches over which z stays constant within a run and its
  correlation time τ (pooled; :func:`~aidnav.analysis.seed_consistency.segment_length`,
  :func:`~aidnav.analysis.seed_consistency.correlation_time`), the probability that an honest filter with
  those fails a block (:func:`~aidnav.analysis.seed_consistency.honest_block_failure`: z constant over
  stretches of L, or Gauss–Markov of τ) and in the limit L → ∞
  (:func:`~aidnav.analysis.seed_consistency.constant_block_failure`: 2.7 % per axis for 10 seeds), against
  the failure rate of blocks resampled from the cell's own seeds.
"""

from __future__ import annotations

import html

import numpy as np

from aidnav.analysis import seed_consistency as sc
from aidnav.report import html as H

from .consistency_matrix import AXES, COVERAGE_TARGET, EVAL_DT_S, CellResult, Condition, aggregate

__all__ = ["fixed_times", "seed_statistics", "row_statistics", "format_row_statistics",
           "format_seed_statistics", "seed_statistics_html"]

TILT = (3, 4)  #: roll, pitch in AXES


def fixed_times(cond: Condition) -> dict[str, float]:
    """The fixed epochs [s from the start] of the seed-level tests: the end of the condition's first turn
    segment (absent without one) and the end of the run (the last evaluation epoch before its end)."""
    t, out = 0.0, {}
    for seg in cond.segments:
        t += float(seg.get("duration_s", 0.0))
        if seg.get("type") == "turn" and "first turn" not in out:
            out["first turn"] = t
    out["end"] = float(np.floor((t - 1e-6) / EVAL_DT_S) * EVAL_DT_S)
    return out


def _z(run):
    with np.errstate(divide="ignore", invalid="ignore"):
        return run.err / run.sigma


def seed_statistics(cell: CellResult, cond: Condition, block: int = 10, n_sim: int = 20000,
                    rng=35) -> dict:
    """The statistics of the module doc for ``cell`` (its ``runs``: the seeds that ran) of ``cond``."""
    runs = cell.runs
    out: dict = {"condition": cell.condition, "config": cell.config, "seeds": len(runs), "block": block,
                 "pooled": [float(x) for x in cell.coverage]}
    blocks = [aggregate(cell.condition, cell.config, runs[i:i + block])
              for i in range(0, len(runs) - block + 1, block)]
    out["blocks"] = [dict(first=int(runs[i * block].seed), coverage=[float(x) for x in b.coverage],
                          ok=bool(b.ok)) for i, b in enumerate(blocks)]
    out["per_seed_min"] = [float(x) for x in cell.per_seed_min]
    out["per_seed_hist"] = sc.histogram(cell.per_seed_min)
    fixed = {}
    for name, t in fixed_times(cond).items():
        n9 = sc.values_at([r.nees_time for r in runs], [r.nees * 9.0 for r in runs], t)
        na = sc.values_at([r.nees_time for r in runs], [r.nees_att for r in runs], t)
        z = sc.values_at([r.time for r in runs], [_z(r) for r in runs], t)
        fixed[name] = dict(t=t, nees9=sc.chi2_sum(n9, 9), nees_att=sc.chi2_sum(na, 3),
                           tilt={AXES[a]: dict(chi2=sc.chi2_sum(z[:, a] ** 2, 1), ks=sc.ks_normal(z[:, a]),
                                              worst=float(np.nanmax(np.abs(z[:, a]))) if len(z) else np.nan,
                                              worst_seed=int(runs[int(np.nanargmax(np.abs(z[:, a])))].seed))
                                 for a in TILT})
    out["fixed"] = fixed
    n_ep = int(np.median([len(r.time) for r in runs])) if runs else 0
    tilt = {}
    for a in TILT:
        zs = [_z(r)[:, a] for r in runs]
        tau, seg = sc.correlation_time(zs, EVAL_DT_S), sc.segment_length(zs, EVAL_DT_S)
        covered = [np.sum(np.abs(r.err[:, a]) <= 3.0 * r.sigma[:, a]) for r in runs]
        tilt[AXES[a]] = dict(
            tau_s=tau, segment_s=seg,
            p_honest=sc.honest_block_failure(block, n_ep, seg, EVAL_DT_S, COVERAGE_TARGET, n_sim=n_sim,
                                             rng=rng),
            p_gauss_markov=sc.honest_block_failure(block, n_ep, tau, EVAL_DT_S, COVERAGE_TARGET, n_sim=n_sim,
                                                   rng=rng, model="gauss-markov"),
            p_constant=sc.constant_block_failure(block, COVERAGE_TARGET),
            p_resampled=(sc.resampled_block_failure(covered, [len(r.time) for r in runs], block,
                                                    COVERAGE_TARGET, n_sim, rng) if len(runs) >= block
                         else np.nan))
    out["tilt"] = tilt
    return out


def row_statistics(cells: list[CellResult], stats: list[dict]) -> dict:
    """Over several cells run on the same seeds (e.g. the tight rows): how many of their roll/pitch
    tests are independent — the effective number (:func:`~aidnav.analysis.seed_consistency.effective_tests`)
    of the per-seed z of roll and pitch at the fixed epochs over every cell (the configurations of a row
    share the seed's draws) — and so the probability that an honest filter fails at least one cell of a
    block (each test failing with the τ → ∞ bound, or with the median simulated P of :func:`seed_statistics`),
    against the blocks observed to fail some cell."""
    cols = []
    for c, st in zip(cells, stats, strict=True):
        for t in (v["t"] for v in st["fixed"].values()):
            z = sc.values_at([r.time for r in c.runs], [_z(r) for r in c.runs], t)
            cols += [z[:, a] for a in TILT]
    n = min((len(x) for x in cols), default=0)
    m_eff = sc.effective_tests(np.column_stack([x[:n] for x in cols])) if cols else np.nan
    p_const = stats[0]["tilt"]["roll"]["p_constant"] if stats else np.nan
    p_sim = float(np.median([st["tilt"][a]["p_honest"] for st in stats for a in ("roll", "pitch")])) \
        if stats else np.nan
    n_blocks = min((len(st["blocks"]) for st in stats), default=0)
    failed = sum(any(not st["blocks"][i]["ok"] for st in stats) for i in range(n_blocks))
    return dict(tests=len(cols), m_eff=m_eff, p_constant=p_const, p_honest=p_sim,
                p_any_constant=sc.any_failure(p_const, m_eff), p_any_honest=sc.any_failure(p_sim, m_eff),
                blocks=n_blocks, blocks_failed=failed)


def format_row_statistics(row: dict) -> str:
    """One line of :func:`row_statistics`."""
    return (f"{row['tests']} roll/pitch tests (cells x axes x fixed epochs) ~ {row['m_eff']:.1f} "
            f"independent: an honest filter fails >= 1 cell of a block with P = "
            f"{100 * row['p_any_honest']:.0f} % (each {100 * row['p_honest']:.1f} %, the segments' median) "
            f"to {100 * row['p_any_constant']:.0f} % "
            f"(tau -> inf, each {100 * row['p_constant']:.1f} %); observed: {row['blocks_failed']} of "
            f"{row['blocks']} blocks fail some cell")


def _p(x: float) -> str:
    return "nan" if not np.isfinite(x) else (f"{x:.2g}" if x < 0.01 else f"{x:.2f}")


def _rows(st: dict) -> list[list[str]]:
    """The fields of one cell's statistics, in the order of :data:`HEADER`."""
    f = st["fixed"]
    first = f.get("first turn", f["end"])
    blocks = " ".join(("ok" if b["ok"] else "FAIL") for b in st["blocks"])
    tilt = st["tilt"]
    return [[st["condition"], st["config"], str(st["seeds"]),
             " ".join(f"{100 * st['pooled'][a]:.1f}" for a in TILT), blocks,
             f"{_p(first['nees_att']['p_upper'])} / {_p(f['end']['nees_att']['p_upper'])}",
             f"{_p(first['nees9']['p_upper'])} / {_p(f['end']['nees9']['p_upper'])}",
             " ".join(f"{_p(first['tilt'][a]['ks'][1])}" for a in ("roll", "pitch")),
             " ".join(f"{first['tilt'][a]['worst']:.1f}({first['tilt'][a]['worst_seed']})"
                      for a in ("roll", "pitch")),
             "/".join(str(c) for c in st["per_seed_hist"]),
             " ".join(f"{tilt[a]['segment_s']:.0f}/{tilt[a]['tau_s']:.0f}" for a in ("roll", "pitch")),
             " ".join(f"{100 * tilt[a]['p_honest']:.1f}/{100 * tilt[a]['p_gauss_markov']:.1f}"
                      for a in ("roll", "pitch")),
             " ".join(f"{100 * tilt[a]['p_resampled']:.1f}" for a in ("roll", "pitch"))]]


HEADER = ["condition", "config", "seeds", "pooled cov roll pitch %", "blocks",
          "p NEES φ (turn / end)", "p NEES 9 (turn / end)", "KS p roll pitch (turn)",
          "max |z| (seed) roll pitch", "worst-axis cov/seed <.5/.9/.95/.99/≥.99",
          "L/τ roll pitch [s]", "P honest block fails (segments/GM) roll pitch %",
          "P resampled block fails %"]


def format_seed_statistics(stats: list[dict]) -> str:
    """The statistics as text: one line per cell (fields of :data:`HEADER`, ' | '-separated)."""
    if not stats:
        return ""
    st0 = stats[0]
    lines = [f"seed-level statistics over {st0['seeds']} seeds; fixed epochs "
             + ", ".join(f"{k} t={v['t']:.0f} s" for k, v in st0["fixed"].items())
             + f"; an honest filter fails a {st0.get('block', 10)}-seed block in the limit tau -> inf "
             f"with P = "
             f"{100 * st0['tilt']['roll']['p_constant']:.1f} % per axis",
             " | ".join(HEADER)]
    for st in stats:
        lines += [" | ".join(r) for r in _rows(st)]
    return "\n".join(lines)


def seed_statistics_html(stats: list[dict]) -> list[str]:
    """The statistics as parts of the matrix page
    (:func:`aidnav.experiments.consistency_matrix.matrix_page`)."""
    if not stats:
        return []
    rows = [r for st in stats for r in _rows(st)]
    head = html.escape(format_seed_statistics(stats).splitlines()[0])
    return ["<h2>Seed-level statistics</h2>",
            f"<p class='note'>{head}; p: the upper tail of the sum "
            "over the seeds against χ²(R·n) (small: σ over-confident); L: the length of the stretches "
            "over which error/σ stays constant within a run, τ: its correlation time; P honest: a "
            "simulated honest filter whose error/σ is constant over stretches of L (segments) or "
            "Gauss–Markov of τ (GM); P resampled: blocks drawn from these seeds.</p>", H.table(HEADER, rows)]
