"""``aidnav evaluate``: an estimated trajectory file against a reference file: statistics, tables, figures.

Files: interchange trajectories (CSV/Parquet, docs/conventions.md "Interchange files") read by
:func:`aidnav.io.interchange.read_trajectory`, or an RTKLIB ``.pos`` solution read by
:func:`aidnav.io.rtklib.read_pos` (a position/velocity reference without attitude, GPS seconds of
week). Both files must share a time scale; errors are estimate − reference at the reference epochs
(:func:`aidnav.analysis.errors.trajectory_errors`). An RTKLIB reference describes the antenna: no
lever arm is applied, so the position errors then contain the IMU–antenna lever arm.

Memory does not grow with the files (issue 29): interchange trajectories are read in batches
(:func:`aidnav.io.stream.trajectory_chunks`; other formats are read whole and cut), the errors are
computed, written to ``errors.csv`` and summarised chunk by chunk
(:func:`aidnav.analysis.error_stream.stream_errors`: the numbers of the whole-trajectory functions), and
the figures are drawn from a decimated copy of the error series.
"""

from __future__ import annotations

import html
import json
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

from aidnav.analysis.error_stream import StreamedErrors, stream_errors
from aidnav.analysis.errors import ErrorSeries
from aidnav.data import GnssData, Trajectory
from aidnav.io.atomic import check_complete, remove_stale, write_text
from aidnav.io.formats import gnss_to_trajectory, read_trajectory_any
from aidnav.io.stream import CsvColumnsWriter, TrajectoryChunks, trajectory_chunks
from aidnav.report.error_plots import plot_errors, plot_nees
from aidnav.report.html import img_file_tag, kv_table, page, table
from aidnav.report.run_page import write_run_page

#: Row order of the printed table (position N/E/U first, as navigation reports usually list them).
CHUNK_ROWS = 1 << 15  #: estimate/reference epochs per piece

TABLE_ORDER = ["pos N", "pos E", "pos U", "pos horizontal", "pos 3D", "vel N", "vel E", "vel U",
               "roll", "pitch", "heading"]


def trajectory_from_gnss(g: GnssData) -> Trajectory:
    """A :class:`Trajectory` from GNSS fixes (:func:`aidnav.io.formats.gnss_to_trajectory`)."""

    return gnss_to_trajectory(g)


def read_any_trajectory(path, notes: list[str] | None = None, height_offset_m: float = 0.0) -> Trajectory:
    """A trajectory of any known format (:func:`aidnav.io.formats.read_trajectory_any`: interchange,
    KF-GINS ``.nav``, or GNSS fixes of any GNSS format); the datum offset added once, by the reader.
    notes : when given, the reader's events (gaps, skipped lines, datum) are appended."""

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


def print_table(stats: pd.DataFrame, errors: ErrorSeries | StreamedErrors, console=None,
                title: str = "Errors") -> None:
    """Rich table of RMS, 95th percentile of |e| and max |e| per quantity, with the epoch counts and notes of
    ``errors``."""
    from rich.console import Console  # lazy: rich is heavy to import
    from rich.table import Table  # lazy: rich is heavy to import

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


def _pieces(path, notes: list[str], height_offset_m: float, chunk_rows: int):
    """The trajectory of ``path`` in pieces: an interchange file read in batches, any other read whole
    (:func:`read_any_trajectory`) and cut."""

    src = trajectory_chunks(path, chunk_rows, height_offset_m, notes)
    if src is None:
        src = TrajectoryChunks(read_any_trajectory(path, notes, height_offset_m=height_offset_m), chunk_rows)
    return src


def _week_of(src):
    """The GPS week a trajectory source knows (file metadata or the trajectory held), else None."""
    meta = getattr(src, "meta", None) or {}
    if meta.get("gps_week") is not None:
        return meta["gps_week"]
    return getattr(getattr(src, "traj", None), "week", None)


def evaluate_files(estimate_path, truth_path, out_dir=None, console=None, max_dt: float | None = None,
                   time_scale: str | None = None, truth_height_offset_m: float = 0.0,
                   chunk_rows: int = CHUNK_ROWS) -> tuple[pd.DataFrame, list[Path]]:
    """Compare an estimate file with a reference ("truth") file, chunk by chunk (module doc).

    estimate_path, truth_path : interchange trajectory files, or RTKLIB ``.pos`` (see module doc).
    out_dir : when given, writes ``errors.json`` (statistics, epoch counts, fraction within 1σ/3σ,
        position NEES summary), ``errors.csv`` (per-epoch errors, angles in deg, σ columns prefixed ``std_``)
        and the PNG figures of :mod:`aidnav.report.error_plots`.
    console : rich Console for the table (a new one if None).
    max_dt : gap threshold for :func:`trajectory_errors` [s]; time_scale : label of the time axis
    (default: "GPS SOW" when either file knows its GPS week, else "the files' own clock, no GPS week" — a
    simulated clock is not labelled GPS time).
    truth_height_offset_m : added to the reference heights [m] (datum of the reference file).
    chunk_rows : epochs per piece of either file.

    Returns (statistics DataFrame of :func:`error_statistics`, list of files written).
    Raises ``ValueError`` when no reference epoch falls inside the estimate's span (e.g. files in
    different time scales).
    """

    check_complete(estimate_path, "the estimate")  # not a file of an interrupted or failed run
    check_complete(truth_path, "the reference")
    read_notes: list[str] = []
    est = _pieces(estimate_path, read_notes, 0.0, chunk_rows)
    ref = _pieces(truth_path, read_notes, truth_height_offset_m, chunk_rows)
    out = None if out_dir is None else Path(out_dir)
    csv = None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        remove_stale(out, ("errors.json",))  # a killed run's leftovers; the old summary goes first
        csv = CsvColumnsWriter(out / "errors.csv")
    try:
        errors = stream_errors(est, ref, max_dt=max_dt, spool_dir=out,
                               on_piece=None if csv is None else (lambda e: csv.write(e.columns())))
    except BaseException:
        if csv is not None:
            csv.abort()
        raise
    if csv is not None:
        csv.close()
    errors.notes[:0] = read_notes
    if errors.n_used == 0:
        if csv is not None:
            csv.path.unlink(missing_ok=True)

        def span(s):
            return f"[{float(s[0])!r}, {float(s[1])!r}]" if s else "[]"

        raise ValueError(f"no reference epoch can be evaluated: estimate spans {span(errors.est_span)} s, "
                         f"reference {span(errors.ref_span)} s ({'; '.join(errors.notes)}); are both in the "
                         "same time scale?")
    stats = errors.statistics
    print_table(stats, errors, console, title=f"{Path(estimate_path).name} vs {Path(truth_path).name}")
    if time_scale is None:
        gps = _week_of(est) is not None or _week_of(ref) is not None
        time_scale = "GPS SOW" if gps else "the files' own clock, no GPS week"

    written: list[Path] = []
    if out is None:
        return stats, written
    summary = {"estimate": str(estimate_path), "truth": str(truth_path), "time_scale": time_scale,
               "t0": errors.t0, "t1": errors.t1, "epochs": errors.counts(),
               "notes": list(errors.notes), "statistics": _records(stats),
               "within_1sigma": _records(errors.within[1.0]),
               "within_3sigma": _records(errors.within[3.0])}

    figs = plot_errors(errors.figure, out, time_scale=time_scale)
    if errors.nees is not None:
        # diagonal covariance from the estimate's σ only (its cross-correlations are not in the file)
        summary["position_nees"] = _clean({**errors.nees.to_dict(),
                                           "covariance": "diagonal from the estimate's σ"})
        figs.append(plot_nees(errors.figure.time, errors.figure_nees, 3, out / "position_nees.png",
                              label="position NEES (diagonal σ)", time_scale=time_scale))

    summary["figures"] = [p.name for p in figs]
    jpath = out / "errors.json"
    write_text(jpath, json.dumps(_clean(summary), indent=2) + "\n")
    written += [jpath, csv.path, *figs]
    written += write_evaluation_page(out, summary, stats, figs, estimate_path)
    return stats, written


def write_evaluation_page(out: Path, summary: dict, stats, figs, estimate_path) -> list[Path]:
    """``OUT/evaluation.html`` (the error table, epoch counts, notes and figures) and, when the estimate
    is the trajectory of an ``aidnav process`` run (its folder has ``summary.json`` and ``run.html``),
    a link to it on that run's page (``summary.json`` gains ``evaluation``; ``run.html`` is rewritten
    with its figures). Returns the files written."""
    rows = [[str(i)] + [f"{v:.4g}" if isinstance(v, float) else str(v) for v in r]
            for i, r in zip(stats.index, stats.itertuples(index=False), strict=True)]
    body = [f"<h1>Errors of {Path(summary['estimate']).name} against {Path(summary['truth']).name}</h1>",
            kv_table([["estimate", summary["estimate"]], ["reference", summary["truth"]],
                ["time axis", summary["time_scale"]], ["epochs", json.dumps(summary["epochs"])]]),
            "<h2>Statistics</h2>", table(["quantity", *map(str, stats.columns)], rows)]
    if summary.get("notes"):
        body.append("<h2>Notes</h2><ul>" + "".join(f"<li>{_esc(n)}</li>" for n in summary["notes"]) + "</ul>")
    for f in figs:
        body.append(img_file_tag(f, f.stem.replace("_", " ")))
    ep = out / "evaluation.html"
    ep.write_text(page(f"evaluation: {Path(summary['estimate']).name}", body), encoding="utf-8")
    written = [ep]
    run_dir = Path(estimate_path).resolve().parent
    sj, rp = run_dir / "summary.json", run_dir / "run.html"
    if sj.exists() and rp.exists():
        try:
            s = json.loads(sj.read_text())
        except ValueError:
            return written
        s["evaluation"] = {"page": os.path.relpath(ep.resolve(), run_dir), "truth": summary["truth"]}
        sj.write_text(json.dumps(s, indent=2) + "\n")
        figs_run = [(p, "Overview") for p in [run_dir / "overview.png"] if p.exists()]
        written.append(write_run_page(rp, s, figs_run))
    return written


def _esc(x) -> str:
    return html.escape(str(x))
