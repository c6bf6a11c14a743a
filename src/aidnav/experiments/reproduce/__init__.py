"""Paper reproductions: ``aidnav reproduce SEED -o DIR`` (seeds 000 … 004, or ``all``).

Each seed is one module ``aidnav.experiments.reproduce.seed_XXX`` (with ``seed_XXX_setup``,
``seed_XXX_runs``, ``seed_XXX_tables``, ``seed_XXX_figures`` helpers where it is large) with a function
``run(out_dir, runs=None, console=None)`` that rebuilds the seed's tables and figures into ``out_dir``
through :class:`aidnav.experiments.reproduce._study.Study`: ``summary.json`` (every row checked against
its target by :func:`aidnav.experiments.reproduce.summary.write_summary`; schema in
``docs/reproduce_schema.md``), ``report.html`` (self-contained) and the paper-vs-ours table on the console
(:mod:`aidnav.experiments.reproduce.page`). ``reproduce all`` also writes ``DIR/index.html``. A seed whose
module does not exist, has no ``run``, or raises ``NotImplementedError`` cannot be reproduced yet:
:func:`reproduce` reports it (:class:`SeedUnavailable`) and no summary is left behind; the CLI exits with
status 2.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path

__all__ = ["SEEDS", "SeedUnavailable", "ReproduceOutcome", "resolve_seeds", "run_seed", "reproduce"]

SEEDS = ("000", "001", "002", "003", "004")


class SeedUnavailable(RuntimeError):
    """A seed that cannot be reproduced yet (no module, no ``run``, or ``NotImplementedError``)."""

    def __init__(self, seed: str, reason: str):
        super().__init__(f"seed {seed} cannot be reproduced yet: {reason}")
        self.seed = seed
        self.reason = reason


@dataclass
class ReproduceOutcome:
    """Result of one seed: ``ok`` with its output directory and summary path, or ``reason`` why not."""

    seed: str
    out_dir: Path
    ok: bool
    summary: Path | None = None
    reason: str | None = None
    result: object = None


def resolve_seeds(spec: str) -> list[str]:
    """``"all"`` → every seed; ``"4"``, ``"04"``, ``"004"``, ``"seed_004"`` → ``["004"]``.

    Raises ValueError for anything else.
    """
    s = str(spec).strip().lower()
    if s == "all":
        return list(SEEDS)
    s = s.removeprefix("seed_").removeprefix("seed")
    if s.isdigit() and f"{int(s):03d}" in SEEDS:
        return [f"{int(s):03d}"]
    raise ValueError(f"unknown seed {spec!r} (expected one of {', '.join(SEEDS)} or all)")


def run_seed(seed: str, out_dir, runs: int | None = None, console=None):
    """Run ``aidnav.experiments.reproduce.seed_<seed>.run(out_dir, runs=runs, console=console)``.

    Raises :class:`SeedUnavailable` when the seed cannot be reproduced (a summary.json that the attempt
    wrote is removed); other exceptions propagate.
    """
    (seed,) = resolve_seeds(seed)
    name = f"{__name__}.seed_{seed}"
    try:
        mod = importlib.import_module(name)
    except ModuleNotFoundError as e:
        if e.name in (name, __name__):
            raise SeedUnavailable(seed, f"module {name} does not exist") from None
        raise
    fn = getattr(mod, "run", None)
    if not callable(fn):
        raise SeedUnavailable(seed, f"module {name} has no run(out_dir, runs=..., console=...)")
    out = Path(out_dir)
    summary = out / "summary.json"
    existed = summary.exists()
    try:
        return fn(out, runs=runs, console=console)
    except NotImplementedError as e:
        if summary.exists() and not existed:
            summary.unlink()
        raise SeedUnavailable(seed, str(e) or "not implemented") from None


def reproduce(spec: str, out_dir, runs: int | None = None, console=None) -> list[ReproduceOutcome]:
    """Reproduce one seed into ``out_dir``, or ``all`` seeds into ``out_dir/seed_XXX``.

    Returns one :class:`ReproduceOutcome` per seed (unavailable seeds are reported, not raised).
    """
    seeds = resolve_seeds(spec)
    out = Path(out_dir)
    outcomes = []
    for seed in seeds:
        d = out if len(seeds) == 1 else out / f"seed_{seed}"
        try:
            res = run_seed(seed, d, runs=runs, console=console)
        except SeedUnavailable as e:
            outcomes.append(ReproduceOutcome(seed, d, False, reason=e.reason))
            continue
        s = d / "summary.json"
        outcomes.append(ReproduceOutcome(seed, d, True, summary=s if s.exists() else None, result=res))
    return outcomes
