"""The consistency matrix (issue 35): conditions × configurations of the loosely coupled filter (and of the
tightly coupled one with 3, 2 and 0 satellites for 60 s, raw GNSS), each over 10 seeds of a simulated
car, → 3σ coverage per axis (E, N, U, roll, pitch, heading), RMS(error)/RMS(σ) and NEES
(:mod:`aidnav.experiments.consistency_matrix`).

Targets (issue 35): every cell ≥ 95 % 3σ coverage on every axis and RMS(error)/RMS(σ) ≥ 0.3; a cell that
misses either is flagged ``FAIL``. Prints the matrix, the targets, the machine load and the time taken;
writes an HTML page (``--html``, default ``out/consistency_matrix.html``) and the
figures as JSON (``--json``).

Run: ``python benchmarks/consistency_matrix.py`` (the whole matrix, ~10 CPU-min);
``--seeds 3``, ``--conditions "gnss 1 Hz white,grade mems"``, ``--configs matched,car`` (``presets``: every
vehicle preset) for a part;
``--legacy-sensor-model``: the matched configuration without the sensor modelling of issue 35 (one
Gauss–Markov bias state, no scale-factor states, no misalignment), the code before it.

``--tight-seeds 40``: the tight rows over their own seed count (issue 35, session 16). The matrix and its
pass count stay the ``--seeds`` figure (each tight cell's first ``--seeds`` seeds, the default figure);
then the tight cells pooled over all their seeds, and the seed-level statistics
(:mod:`aidnav.experiments.consistency_seeds`: each block of ``--seeds`` seeds, χ² p-values of the per-seed
NEES at the end of the first turn and of the run, KS of the roll/pitch z, the per-seed worst-axis
coverage distribution, the probability that an honest filter fails a block), also on the page.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402


def _condition_names(text, cm):
    """The comma-separated condition names of ``text`` (a name may hold a comma itself: "moving start,
    position only"): the longest run of pieces that names a condition, piece by piece."""
    known = {c.name for c in cm.CONDITIONS}
    parts = [t.strip() for t in text.split(",") if t.strip()]
    out, i = [], 0
    while i < len(parts):
        j = next((j for j in range(len(parts), i, -1) if ", ".join(parts[i:j]) in known), i + 1)
        out.append(", ".join(parts[i:j]))
        i = j
    return out


def _first_seeds(cell, stop, cm):
    """``cell`` over its seeds before ``stop`` alone (the matrix's --seeds figure of a tight cell run over
    more seeds); its failed seeds' messages start "seed N:"."""
    runs = [r for r in cell.runs if r.seed < stop]
    errors = [e for e in cell.errors if int(e.split(":")[0].split()[1]) < stop]
    if len(runs) == len(cell.runs) and len(errors) == len(cell.errors):
        return cell
    return cm.aggregate(cell.condition, cell.config, runs, None, errors)


def main(argv=None):
    from aidnav.experiments import consistency_matrix as cm

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--first-seed", type=int, default=0, help="first seed (a 2nd block: 10)")
    ap.add_argument("--tight-seeds", type=int, default=0, help="seeds of the tight rows (default: --seeds)")
    ap.add_argument("--conditions", default="", help="comma-separated names (default: all)")
    ap.add_argument("--configs", default="", help="comma-separated: none, presets, matched (default: all)")
    ap.add_argument("--legacy-sensor-model", action="store_true")
    ap.add_argument("--html", default="out/consistency_matrix.html")
    ap.add_argument("--json", default="")
    a = ap.parse_args(argv)
    conds = [cm.condition(n) for n in _condition_names(a.conditions, cm)] or list(cm.CONDITIONS)
    configs = [c.strip() for c in a.configs.split(",") if c.strip()] or cm.configurations()
    presets = [c for c in cm.configurations() if c not in ("none", "matched")]
    configs = [p for c in configs for p in (presets if c == "presets" else [c])]  # "presets": every one
    load0 = os.getloadavg()
    t0, c0 = time.perf_counter(), time.process_time()
    print(f"consistency matrix: {len(conds)} conditions x {len(configs)} configurations x {a.seeds} seeds "
          f"from seed {a.first_seed}; sensor model: {'legacy' if a.legacy_sensor_model else 'issue 35'}",
          flush=True)
    seeds = range(a.first_seed, a.first_seed + a.seeds)
    n_tight = a.tight_seeds if a.tight_seeds > 0 else a.seeds
    tight = range(a.first_seed, a.first_seed + n_tight)
    loose_c = [c for c in conds if c.coupling != "tight"]
    tight_c = [c for c in conds if c.coupling == "tight"]

    def show(c):
        print(cm.format_matrix([c]).splitlines()[-1], flush=True)

    full = cm.run_matrix(loose_c, configs, seeds, not a.legacy_sensor_model, show) if loose_c else []
    full += cm.run_matrix(tight_c, configs, tight, not a.legacy_sensor_model, show) if tight_c else []
    # the matrix's figure: every cell over --seeds seeds (a tight cell's first --seeds of its seeds)
    cells = [_first_seeds(c, a.first_seed + a.seeds, cm) for c in full]
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    print()
    print(cm.format_matrix(cells))
    for c in cells:
        for e in c.errors:
            print(f"  {c.condition} / {c.config}: {e}")
    n_fail = sum(not c.ok for c in cells)
    print(f"\ntargets: 3σ coverage >= {100 * cm.COVERAGE_TARGET:.0f} % on every axis, RMS(err)/RMS(σ) >= "
          f"{cm.RATIO_TARGET} -> {len(cells) - n_fail} of {len(cells)} cells pass")
    extra, stats = [], []
    if n_tight > a.seeds and tight_c:
        from aidnav.experiments import consistency_seeds as cs  # lazy: only with --tight-seeds

        pooled = [c for c in full if c.condition in {t.name for t in tight_c}]
        print(f"\ntight rows pooled over {n_tight} seeds (from seed {a.first_seed}):")
        print(cm.format_matrix(pooled))
        n_ok = sum(c.ok for c in pooled)
        print(f"pooled over {n_tight} seeds: {n_ok} of {len(pooled)} tight cells pass")
        stats = [cs.seed_statistics(c, cm.condition(c.condition), block=a.seeds) for c in pooled]
        row = cs.row_statistics(pooled, stats)
        print()
        print(cs.format_seed_statistics(stats))
        print(cs.format_row_statistics(row))
        extra = [f"<h2>Tight rows pooled over {n_tight} seeds</h2>",
                 f"<p class='note'>{n_ok} of {len(pooled)} tight cells pass pooled over {n_tight} seeds</p>",
                 cm.matrix_table(pooled)]
        extra += cs.seed_statistics_html(stats) + [f"<p class='note'>{cs.format_row_statistics(row)}</p>"]
    print(f"time: {wall:.0f} s wall, {cpu:.0f} s CPU; load average before {load0[0]:.2f}, after "
          f"{os.getloadavg()[0]:.2f} ({os.cpu_count()} CPUs)")
    notes = [f"{a.seeds} seeds per cell (from seed {a.first_seed}); "
             f"sensor model: {'legacy' if a.legacy_sensor_model else 'issue 35'}; "
             f"targets: coverage ≥ {100 * cm.COVERAGE_TARGET:.0f} %, ratio ≥ {cm.RATIO_TARGET}; "
             f"{len(cells) - n_fail} of {len(cells)} cells pass",
             "coverage: fraction of 1-s epochs with |error| ≤ 3σ (all seeds); ratio: RMS(error)/RMS(σ); "
             "NEES/9: mean NEES of the 9 navigation error states with the full covariance, per dof"]
    Path(a.html).parent.mkdir(parents=True, exist_ok=True)
    page = cm.matrix_page(cells, "aidnav consistency matrix", notes, extra)
    Path(a.html).write_text(page, encoding="utf-8")
    print(f"page: {a.html}")
    if a.json:
        Path(a.json).write_text(json.dumps([dict(condition=c.condition, config=c.config,
                                                 coverage=[float(x) for x in c.coverage],
                                                 ratio=[float(x) for x in c.ratio], nees=float(c.nees),
                                                 epochs=c.epochs, failed=c.failed, errors=c.errors)
                                            for c in cells] + ([{"seed_statistics": stats}] if stats else []),
                                           indent=1, default=float), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
