"""What every reproduction shares: its output folder, figures, summary, report page, console table and
``python -m`` entry point.

A seed module builds its Monte Carlo and its tables; :class:`Study` does the rest::

    st = Study(SEED, TITLE, out_dir, runs=runs, base_seed=base_seed, console=console)
    st.say("seed 00X: 20 runs")
    fig, axs = st.figure(2, 1)
    ...
    st.save(fig, "fig1_heading.png")
    doc = st.finish(tables, notes)   # summary.json + report.html + the table on the console

and at the end of the module::

    if __name__ == "__main__":  # pragma: no cover
        sys.exit(main(run, SEED, DEFAULT_RUNS))
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from .page import print_summary, write_seed_page
from .summary import write_summary

__all__ = ["Study", "main", "figure", "mean_se", "ratio_se", "rms_ratio_se", "paired", "sign_test",
           "runs_needed", "cjk_font", "use_cjk_font", "CJK_FAMILIES"]

#: font families that carry the seeds' Chinese characters (e.g. 精度), first found wins (Debian/Ubuntu:
#: ``apt-get install fonts-noto-cjk``; CI installs it in ``.ci/run``)
CJK_FAMILIES = ("Noto Sans CJK SC", "Noto Sans CJK JP", "Noto Sans CJK TC", "Noto Serif CJK SC",
                "Source Han Sans SC", "WenQuanYi Zen Hei", "Droid Sans Fallback")


def cjk_font() -> str | None:
    """The family of an installed font with CJK glyphs (registered with matplotlib's font manager when its
    cache predates the font's installation), or None when none is installed."""
    from matplotlib import font_manager as fm  # lazy: matplotlib is heavy to import

    def found():
        names = {f.name for f in fm.fontManager.ttflist}
        return next((c for c in CJK_FAMILIES if c in names), None)

    fam = found()
    if fam is None:
        for path in fm.findSystemFonts():
            base = Path(path).name
            if ("CJK" in base and "Regular" in base) or base.startswith(("wqy-zenhei", "DroidSansFallback")):
                try:
                    fm.fontManager.addfont(path)
                except (OSError, RuntimeError, ValueError):  # an unreadable font file: skip it
                    continue
        fam = found()
    return fam


def use_cjk_font() -> str | None:
    """Make matplotlib fall back to a CJK font (after its default DejaVu Sans) for glyphs DejaVu lacks, so
    that the seeds' characters do not render as boxes; returns the family used (None: none installed, the
    figures then keep DejaVu Sans and warn on a CJK glyph). Sets ``rcParams["font.family"]`` once."""
    import matplotlib  # lazy: matplotlib is heavy to import

    fam = cjk_font()
    if fam is not None:
        cur = list(matplotlib.rcParams["font.family"])
        if fam not in cur:
            base = ["DejaVu Sans"] if cur in (["sans-serif"], ["DejaVu Sans"]) else cur
            matplotlib.rcParams["font.family"] = [*base, fam]
    return fam


# ------------------------------------------------------------------ Monte Carlo standard errors
def mean_se(x) -> tuple[float, float]:
    """(mean, its standard error) of per-run values (se NaN for one run)."""
    x = np.asarray(x, float)
    n = x.size
    se = float(np.std(x, ddof=1) / math.sqrt(n)) if n > 1 else float("nan")
    return float(np.mean(x)), se


def ratio_se(a, b) -> tuple[float, float]:
    """mean(a) / mean(b) of paired per-run values and its delta-method standard error."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = a.size
    A, B = a.mean(), b.mean()
    r = A / B
    if n < 2:
        return float(r), float("nan")
    c = np.cov(a, b, ddof=1) / n
    rel2 = c[0, 0] / A**2 + c[1, 1] / B**2 - 2 * c[0, 1] / (A * B)
    return float(r), float(abs(r) * math.sqrt(max(rel2, 0.0)))


def rms_ratio_se(ms_a, ms_b) -> tuple[float, float]:
    """sqrt(mean(ms_a) / mean(ms_b)) of paired per-run mean squares and its standard error."""
    r2, se2 = ratio_se(ms_a, ms_b)
    r = math.sqrt(r2)
    return r, se2 / (2 * r)


def paired(a, b) -> tuple[float, float]:
    """(mean of a − b, its standard error) over paired runs."""
    return mean_se(np.asarray(a, float) - np.asarray(b, float))


def runs_needed(d: float, se: float, runs: int, k: float = 2.0) -> int:
    """Runs that would bring the standard error ``se`` (of ``runs`` runs) below |d|/k (se ∝ 1/√runs)."""
    if not (math.isfinite(d) and math.isfinite(se)) or d == 0:
        return -1
    return int(math.ceil(runs * (k * se / abs(d)) ** 2))


def sign_test(a, b) -> tuple[int, int, float]:
    """Paired sign test of a > b: (runs with a > b, runs with a ≠ b, one-sided p-value of at least that
    many under P(a > b) = 1/2)."""
    from scipy.stats import binom  # lazy: scipy is heavy to import

    d = np.asarray(a, float) - np.asarray(b, float)
    k, n = int(np.sum(d > 0)), int(np.sum(d != 0))
    return k, n, float(binom.sf(k - 1, n, 0.5)) if n else 1.0



def figure(nrows: int = 1, ncols: int = 1, w: float = 8.0, h: float = 4.5):
    """A matplotlib figure (Agg canvas, no pyplot state) and its (nrows, ncols) axes array."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # lazy: matplotlib is heavy to import
    from matplotlib.figure import Figure  # lazy: matplotlib is heavy to import

    fig = Figure(figsize=(w, h))
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols, squeeze=False)


class Study:
    """One reproduction: ``out`` (created), ``runs``, ``base_seed``, the figures saved so far, the console.

    ``runs`` must be >= 1; ``console`` (a rich Console) or None (silent).
    """

    def __init__(self, seed: str, title: str, out_dir, runs: int, base_seed: int = 1, console=None):
        runs = int(runs)
        if runs < 1:
            raise ValueError(f"seed {seed}: runs must be >= 1")
        self.seed, self.title = str(seed), str(title)
        self.runs, self.base_seed = runs, int(base_seed)
        self.out = Path(out_dir)
        self.out.mkdir(parents=True, exist_ok=True)
        self.console = console
        self.figures: list[str] = []
        self.t_start = time.perf_counter()
        self.cjk_font = use_cjk_font()

    @property
    def elapsed_s(self) -> float:
        return time.perf_counter() - self.t_start

    def say(self, msg: str) -> None:
        """A progress line on the console (nothing without one); data strings are not markup."""
        if self.console is not None:
            self.console.print(str(msg), markup=False, highlight=False)

    figure = staticmethod(figure)

    def save(self, fig, name: str, dpi: int = 110) -> str:
        """Save ``fig`` as ``out/name`` (PNG), record it as a figure of the study, return ``name``."""
        fig.tight_layout()
        fig.savefig(self.out / name, dpi=dpi)
        if name not in self.figures:
            self.figures.append(name)
        return name

    def add_figure(self, name: str) -> str:
        """Record a PNG that a helper already wrote into ``out``."""
        if not (self.out / name).is_file():
            raise FileNotFoundError(f"seed {self.seed}: figure {name} was not written")
        if name not in self.figures:
            self.figures.append(name)
        return name

    def finish(self, tables: list[dict], notes: list[str] = (), *, print_tables: bool = True,
               extra: dict | None = None) -> dict:
        """Write ``summary.json`` (every row checked against its target), ``report.html`` (figures
        embedded) and print the paper-vs-ours table. Returns the summary as written."""
        ex = {"elapsed_s": round(self.elapsed_s, 1)}
        ex.update(extra or {})
        path = write_summary(self.out, seed=self.seed, title=self.title, runs=self.runs,
                             base_seed=self.base_seed, tables=tables, figures=self.figures,
                             notes=list(notes), extra=ex)
        doc = json.loads(path.read_text())
        page = write_seed_page(self.out, doc)
        if self.console is not None:
            if print_tables:
                print_summary(self.console, doc)
            self.say(f"seed {self.seed}: wrote {path} and {page} ({self.elapsed_s:.0f} s)")
        return doc


def main(run, seed: str, default_runs: int | None, argv=None) -> int:
    """``python -m aidnav.experiments.reproduce.seed_XXX OUT_DIR [--runs N] [--base-seed S]``.

    Exit status 0 when every spec row holds, 1 otherwise."""
    from rich.console import Console  # lazy: rich is heavy to import

    ap = argparse.ArgumentParser(prog=f"python -m aidnav.experiments.reproduce.seed_{seed}",
                                 description=f"Reproduce seed {seed}: summary.json, report.html, figures.")
    ap.add_argument("out_dir")
    ap.add_argument("--runs", type=int, default=None, help=f"Monte Carlo runs (default {default_runs})")
    ap.add_argument("--base-seed", type=int, default=1)
    a = ap.parse_args(argv)
    doc = run(a.out_dir, runs=a.runs, base_seed=a.base_seed, console=Console())
    v = doc["verdicts"]["spec"]
    return 0 if v["fails"] == 0 and v["unresolved"] == 0 else 1
