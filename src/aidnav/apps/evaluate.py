"""``aidnav evaluate``: an estimated trajectory file against a reference file: statistics, tables, figures.

Files: interchange trajectories (CSV/Parquet, CONVENTIONS "Interchange files") read by
:func:`aidnav.io.interchange.read_trajectory`, or an RTKLIB ``.pos`` solution read by
:func:`aidnav.io.rtklib.read_pos` (a position/velocity reference without attitude, GPS seconds of
week). Both files must share a time scale; errors are estimate − reference at the reference epochs
(:func:`aidnav.analysis.errors.trajectory_errors`). An RTKLIB reference describes the antenna: no
lever arm is applied, so the position errors then contain the IMU–antenna lever arm.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from aidnav.analysis.consistency import consistency_report, nees
from aidnav.analysis.errors import (
    ErrorSeries,
    error_statistics,
    fraction_within_sigma,
    trajectory_errors,
)
from aidnav.data import GnssData, Trajectory
from aidnav.report.error_plots import plot_errors, plot_nees

#: Row order of the printed table (position N/E/U first, as navigation reports usually list them).
TABLE_ORDER = ["pos N", "pos E", "pos U", "pos horizontal", "pos 3D", "vel N", "vel E", "vel U",
               "roll", "pitch", "heading"]


def trajectory_from_gnss(g: GnssData) -> Trajectory:
    """A :class:`Trajectory` from GNSS fixes (:func:`aidnav.io.formats.gnss_to_trajectory`)."""
    from aidnav.io.formats import gnss_to_trajectory

    return gnss_to_trajectory(g)


def read_any_trajectory(path, notes: list[str] | None = None, height_offset_m: float = 0.0) -> Trajectory:
    """A trajectory of any known format (:func:`aidnav.io.formats.read_trajectory_any`: interchange,
    KF-GINS ``.nav``, or GNSS fixes of any GNSS format); the datum offset added once, by the reader.
    notes : when given, the reader's events (gaps, skipped lines, datum) are appended."""
    from aidnav.io.formats import read_trajectory_any

    return read_trajectory_any(path, height_offset_m=height_offset_m, notes=notes)


def _clean(x):
    """JSON-safe value: NaN/inf → None, numpy scalars → Python."""
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_clean(v) for v in x]
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _records(df: pd.DataFrame) -> list[dict]:
    return [_clean({"quantity": q, **row}) for q, row in df.to_dict(orient="index").items()]


def print_table(stats: pd.DataFrame, errors: ErrorSeries, console=None, title: str = "Errors") -> None:
    """Rich table of RMS, 95th percentile of |e| and max |e| per quantity, with the epoch counts."""
    from rich.console import Console
    from rich.table import Table

    console = console or Console()
    c = errors.counts()
    table = Table(title=title, caption="estimate − reference; 95% = 95th percentile of |e|")
    for col in ("quantity", "unit", "RMS", "95%", "max", "n"):
        table.add_column(col, justify="left" if col in ("quantity", "unit") else "right")
    for q in TABLE_ORDER:
        if q not in stats.index:
            continue
        r = stats.loc[q]
        table.add_row(q, r["unit"], f"{r['RMS']:.4g}", f"{r['p95']:.4g}", f"{r['max']:.4g}", str(int(r["n"])))
    console.print(table)
    console.print(f"{c['used']} of {c['reference']} reference epochs used; excluded: {c['outside_span']} "
                  f"outside the estimate's span, {c['in_gaps']} in estimate gaps > {c['max_dt_s']:.3g} s, "
                  f"{c['invalid_reference']} with invalid reference position")
    for note in errors.notes:
        console.print(f"note: {note}", markup=False)


def evaluate_files(estimate_path, truth_path, out_dir=None, console=None, max_dt: float | None = None,
                   time_scale: str = "GPS SOW",
                   truth_height_offset_m: float = 0.0) -> tuple[pd.DataFrame, list[Path]]:
    """Compare an estimate file with a reference ("truth") file.

    estimate_path, truth_path : interchange trajectory files, or RTKLIB ``.pos`` (see module doc).
    out_dir : when given, writes ``errors.json`` (statistics, epoch counts, fraction within 1σ/3σ,
        position NEES summary), ``errors.csv`` (per-epoch errors, angles in deg, ``_std`` columns)
        and the PNG figures of :mod:`aidnav.report.error_plots`.
    console : rich Console for the table (a new one if None).
    max_dt : gap threshold for :func:`trajectory_errors` [s]; time_scale : label of the time axis.
    truth_height_offset_m : added to the reference heights [m] (datum of the reference file).

    Returns (statistics DataFrame of :func:`error_statistics`, list of files written).
    Raises ``ValueError`` when no reference epoch falls inside the estimate's span (e.g. files in
    different time scales).
    """
    read_notes: list[str] = []
    est = read_any_trajectory(estimate_path, read_notes)
    ref = read_any_trajectory(truth_path, read_notes, height_offset_m=truth_height_offset_m)
    errors = trajectory_errors(est, ref, max_dt=max_dt)
    errors.notes[:0] = read_notes
    if errors.n_used == 0:
        te, tr = np.asarray(est.time), np.asarray(ref.time)

        def span(t):
            return f"[{float(t[0])!r}, {float(t[-1])!r}]" if len(t) else "[]"

        raise ValueError(f"no reference epoch can be evaluated: estimate spans {span(te)} s, reference "
                         f"{span(tr)} s ({'; '.join(errors.notes)}); are both in the same time scale?")
    stats = error_statistics(errors)
    print_table(stats, errors, console, title=f"{Path(estimate_path).name} vs {Path(truth_path).name}")

    written: list[Path] = []
    if out_dir is None:
        return stats, written
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    summary = {"estimate": str(estimate_path), "truth": str(truth_path), "time_scale": time_scale,
               "t0": float(errors.time[0]), "t1": float(errors.time[-1]), "epochs": errors.counts(),
               "notes": list(errors.notes), "statistics": _records(stats),
               "within_1sigma": _records(fraction_within_sigma(errors, 1.0)),
               "within_3sigma": _records(fraction_within_sigma(errors, 3.0))}

    figs = plot_errors(errors, out, time_scale=time_scale)
    if errors.std_pos is not None:
        # diagonal covariance from the estimate's σ only (its cross-correlations are not in the file)
        sp = np.where(errors.std_pos > 0, errors.std_pos, np.nan)  # σ = 0 or NaN: epoch left out
        cov = np.zeros((len(errors), 3, 3))
        idx = np.arange(3)
        cov[:, idx, idx] = sp**2
        v = nees(errors.pos, cov)
        if np.any(np.isfinite(v)):
            summary["position_nees"] = _clean(
                {**consistency_report(v, 3).to_dict(), "covariance": "diagonal from the estimate's σ"})
            figs.append(plot_nees(errors.time, v, 3, out / "position_nees.png",
                                  label="position NEES (diagonal σ)", time_scale=time_scale))

    summary["figures"] = [p.name for p in figs]
    jpath = out / "errors.json"
    jpath.write_text(json.dumps(_clean(summary), indent=2) + "\n")
    cpath = out / "errors.csv"
    errors.to_dataframe().to_csv(cpath, index=False, float_format="%.17g")
    written += [jpath, cpath, *figs]
    return stats, written
