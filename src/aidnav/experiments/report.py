"""Campaign report: ``aidnav report DIR`` → ``DIR/report.html`` (self-contained: figures embedded as
base64 PNG) and ``DIR/statistics.json`` (the tables' numbers, machine-readable).

Reads what :func:`aidnav.experiments.runner.run_experiment` wrote (``manifest.json``, ``runs.parquet``,
``epochs.parquet``, ``consistency.json``, ``trajectories.parquet``; ``summary.json`` of a reproduction
when present) and shows:

* the experiment, versions, seeds, host and timings;
* NEES consistency per sweep point, estimator and state block: mean NEES against its χ² band and the
  verdict of :func:`aidnav.analysis.consistency.consistency_report` — an inconsistent filter is flagged;
* statistics side by side: one column per (sweep point, estimator), mean ± std over the runs;
* the paper's values beside ours where the experiment (``paper:``) or a reproduction summary gives them;
* figures: trajectory map; per sweep point and estimator, the errors vs time with ±1σ/±3σ envelopes from
  the filter (shaded) and from the Monte Carlo spread (lines: mean ± 1/3 std across runs), and the mean
  NEES with its χ² band.

Units: position m (ENU), velocity m/s (ENU), attitude deg (misalignment φ E, N, U; U = heading error for
small angles); time in seconds since the start of the simulated run.
"""

from __future__ import annotations

import html
import json
import warnings
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from aidnav.analysis.consistency import chi2_band
from aidnav.nav.earth import lla_to_enu
from aidnav.report.html import DPI, img_tag, kv_table, page, png_b64
from aidnav.report.html import fmt as _fmt
from aidnav.report.html import table as _table

from .reproduce.summary import evaluate_target

__all__ = ["write_report", "ReportError", "paper_rows"]



class ReportError(ValueError):
    """The directory does not hold a complete campaign."""


# --------------------------------------------------------------------------------------- figures
def _png(fig: Figure) -> str:
    return png_b64(fig, DPI)


def _blocks(states: list[str]) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for s in states:
        out.setdefault(s.split("_", 1)[0], []).append(s)
    return out


def _state_cols(ep_cols: list[str]) -> list[str]:
    """State column stems (``pos_e_m``) present in epochs.parquet."""
    return [c[:-5] for c in ep_cols if c.endswith("_mean") and not c.startswith("nees_")]


def _axis_label(stem: str) -> str:
    """``pos_e_m`` → ``pos_e [m]``, ``vel_u_m_s`` → ``vel_u [m/s]``."""
    for unit in ("m_s", "deg", "m", "si"):
        if stem.endswith("_" + unit):
            return f"{stem[:-len(unit) - 1]} [{unit.replace('_', '/')}]"
    return stem


def _error_figure(t, ep: dict, stems: list[str], title: str) -> str:
    blocks = _blocks(stems)
    ncol = max(len(v) for v in blocks.values())
    h = 0.9 + 2.2 * len(blocks)
    fig = Figure(figsize=(4.0 * ncol, h))  # fixed margins: constrained layout doubles the drawing time
    FigureCanvasAgg(fig)
    fig.subplots_adjust(left=0.065, right=0.99, bottom=0.5 / h, top=1 - 0.45 / h, wspace=0.28, hspace=0.1)
    axes = fig.subplots(len(blocks), ncol, sharex=True, squeeze=False)
    for r, (_, cols) in enumerate(blocks.items()):
        for c in range(ncol):
            ax = axes[r, c]
            if c >= len(cols):
                ax.set_visible(False)
                continue
            s = cols[c]
            mean, std, sig = ep[f"{s}_mean"], ep[f"{s}_std"], ep[f"{s}_sigma"]
            if np.any(np.isfinite(sig)):
                ax.fill_between(t, -3 * sig, 3 * sig, color="tab:orange", alpha=0.18, lw=0,
                                label="filter ±3σ")
                ax.fill_between(t, -sig, sig, color="tab:orange", alpha=0.35, lw=0, label="filter ±1σ")
            if np.any(np.isfinite(std)):
                ax.plot(t, mean + std, color="tab:blue", lw=0.7, label="MC mean ±1σ")
                ax.plot(t, mean - std, color="tab:blue", lw=0.7)
                ax.plot(t, mean + 3 * std, color="tab:blue", lw=0.7, ls="--", label="MC mean ±3σ")
                ax.plot(t, mean - 3 * std, color="tab:blue", lw=0.7, ls="--")
            ax.plot(t, mean, color="k", lw=0.8, label="MC mean error")
            ax.axhline(0.0, color="0.5", lw=0.4)
            ax.set_ylabel(_axis_label(s), fontsize="small")
            ax.grid(True, alpha=0.3)
            fin = np.concatenate([x[np.isfinite(x)] for x in (3 * sig, mean + 3 * std, mean - 3 * std)])
            if fin.size:
                lim = np.percentile(np.abs(fin), 98) * 1.2
                if lim > 0:
                    ax.set_ylim(-lim, lim)
    axes[0, 0].legend(loc="upper right", fontsize="x-small")
    for c in range(ncol):
        axes[-1, c].set_xlabel("time since start [s]")
    fig.suptitle(title)
    return _png(fig)


def _nees_figure(t, ep: dict, blocks: list[str], dof: dict, runs: int, prob: float, title: str) -> str:
    h = 0.9 + 2.1 * len(blocks)
    fig = Figure(figsize=(9.0, h))
    FigureCanvasAgg(fig)
    fig.subplots_adjust(left=0.09, right=0.98, bottom=0.5 / h, top=1 - 0.45 / h, hspace=0.1)
    axes = fig.subplots(len(blocks), 1, sharex=True, squeeze=False)[:, 0]
    for ax, b in zip(axes, blocks, strict=True):
        m = ep[f"nees_{b}"]
        lo, hi = chi2_band(dof[b], runs, prob)
        ax.fill_between(t, lo, hi, color="tab:green", alpha=0.18, lw=0,
                        label=f"{100 * prob:g}% χ² band, {runs} runs ({lo:.3g}, {hi:.3g})")
        ax.plot(t, m, color="tab:blue", lw=0.8, label=f"mean NEES {b}")
        ax.axhline(dof[b], color="k", lw=0.6, ls="--", label=f"expected {dof[b]}")
        fin = np.isfinite(m)
        if fin.any() and np.nanmax(m) > 20 * hi:
            ax.set_yscale("log")
        ax.set_ylabel(f"NEES {b} (dof {dof[b]})")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize="x-small")
    axes[-1].set_xlabel("time since start [s]")
    fig.suptitle(title)
    return _png(fig)


def _map_figure(traj, points: list[dict]) -> str | None:
    if traj is None or traj.num_rows == 0:
        return None

    d = {c: traj.column(c).to_numpy() for c in traj.column_names}
    fig = Figure(figsize=(7.0, 6.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    groups: list[tuple[np.ndarray, list[str]]] = []  # distinct trajectories and the points using them
    for p in points:
        m = d["point"] == p["index"]
        if not m.any():
            continue
        key = np.concatenate([d["lat_deg"][m], d["lon_deg"][m], d["height_m"][m]])
        for k, labels in groups:
            if len(k) == len(key) and np.array_equal(k, key):
                labels.append(p["label"])
                break
        else:
            groups.append((key, [p["label"]]))
    ref = None
    for key, labels in groups:
        lat, lon, h = np.split(key, 3)
        lat, lon = np.radians(lat), np.radians(lon)
        if ref is None:
            ref = (lat[0], lon[0], h[0])
        e, n, _ = lla_to_enu(lat, lon, h, *ref)
        label = "truth" if len(groups) == 1 else "; ".join(labels)[:80]
        ax.plot(e / 1000, n / 1000, lw=1.2, label=label)
        ax.plot(e[0] / 1000, n[0] / 1000, "o", color="tab:green", ms=5)
        ax.plot(e[-1] / 1000, n[-1] / 1000, "s", color="tab:red", ms=5)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("East [km]")
    ax.set_ylabel("North [km]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small", loc="best")
    ax.set_title("Trajectory (o start, □ end)"
                 + ("" if len(groups) > 1 else "; the same for every sweep point"))
    return _png(fig)


# ----------------------------------------------------------------------------------------- tables
def _col_stats(runs: dict, point: int, est: str, col: str) -> tuple[float, float, int]:
    m = (runs["point"] == point) & (runs["estimator"] == est)
    v = runs[col][m]
    v = v[np.isfinite(v)]
    if v.size == 0:
        return float("nan"), float("nan"), 0
    return float(v.mean()), float(v.std(ddof=1)) if v.size > 1 else float("nan"), int(v.size)


def paper_rows(manifest: dict, runs: dict) -> list[dict]:
    """Rows comparing the experiment's ``paper`` values with ours (mean over the runs) per matching
    sweep point and estimator: quantity, point, estimator, column, unit, paper, ours, ours_std, target,
    holds (computed from the target)."""
    doc = manifest["experiment"]["document"]
    rows = []
    for pv in doc.get("paper", []):
        ests = [pv["estimator"]] if pv.get("estimator") else [e["name"] for e in manifest["estimators"]]
        for p in manifest["points"]:
            if not all(p["values"].get(k) == v for k, v in pv.get("point", {}).items()):
                continue
            for e in ests:
                ours, sd, n = _col_stats(runs, p["index"], e, pv["column"]) if pv["column"] in runs else \
                    (float("nan"), float("nan"), 0)
                holds = None
                if pv.get("target"):
                    holds = bool(evaluate_target(pv["target"], ours, pv.get("paper"))) if n else False
                rows.append({"quantity": pv.get("quantity") or pv["column"], "point": p["label"],
                             "estimator": e, "column": pv["column"], "unit": pv.get("unit") or "",
                             "paper": pv.get("paper"), "ours": ours, "ours_std": sd, "runs": n,
                             "target": pv.get("target"), "holds": holds})
    return rows


def _load(out: Path):
    need = ["manifest.json", "runs.parquet", "epochs.parquet"]
    missing = [n for n in need if not (out / n).exists()]
    if missing:
        raise ReportError(f"{out}: not a complete campaign (missing {', '.join(missing)}: never run, or "
                          "interrupted or cut short by --max-runs); run `aidnav run EXPERIMENT.yaml -o DIR` "
                          "(again, to resume) first")
    manifest = json.loads((out / "manifest.json").read_text())
    rt = pq.read_table(out / "runs.parquet")
    runs = {c: rt.column(c).to_numpy(zero_copy_only=False) for c in rt.column_names}
    et = pq.read_table(out / "epochs.parquet")
    epochs = {c: et.column(c).to_numpy(zero_copy_only=False) for c in et.column_names}
    cons = []
    if (out / "consistency.json").exists():
        cons = json.loads((out / "consistency.json").read_text()).get("checks", [])
    traj = pq.read_table(out / "trajectories.parquet") if (out / "trajectories.parquet").exists() else None
    summary = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else None
    return manifest, runs, epochs, cons, traj, summary, rt.column_names


def _meta_table(manifest: dict) -> str:
    """The campaign's identity and timings (experiment, versions, runs, seeds, backend, host)."""
    points = manifest["points"]
    ests = [e["name"] for e in manifest["estimators"]]
    n_runs = int(manifest["runs"])
    tm = manifest.get("timings", {})
    host = manifest.get("host", {})
    be = manifest.get("backend", {})
    meta = [["experiment file", manifest["experiment"].get("source") or "–"],
            ["aidnav version", manifest.get("aidnav_version", "?")],
            ["Monte Carlo runs per point", n_runs],
            ["base seed", manifest["seeds"]["base_seed"]],
            ["seed scheme", manifest["seeds"]["scheme"]],
            ["sweep points", len(points)], ["estimators", ", ".join(ests)],
            ["backend", f"{be.get('kind', '?')} ({be.get('workers', 1)} worker(s)"
                        + (f", {be['scheduler']}" if be.get("scheduler") else "") + ")"],
            ["host", f"{host.get('node', '?')}, {host.get('cpus', '?')} CPUs, "
                     f"Python {host.get('python', '?')}"],
            ["runs computed / reused", f"{tm.get('computed_runs', '?')} / {tm.get('reused_runs', '?')}"],
            ["wall time", f"{_fmt(tm.get('wall_s'))} s (compute {_fmt(tm.get('compute_wall_s'))} s, "
                          f"merge {_fmt(tm.get('merge_s'))} s)"],
            ["created", manifest.get("created", "?")]]
    return kv_table(meta)


def _points_section(points: list[dict]) -> list[str]:
    """The sweep points: values, duration, segments and run files."""
    return ["<h2>Sweep points</h2>",
            _table(["point", "sweep values", "duration [s]", "segments", "run files"],
                   [[p["index"], p["label"], _fmt(p["duration_s"]),
                     ", ".join(f"{s['name']} {s['start_s']:g}–{s['end_s']:g} s" for s in p["segments"]),
                     p.get("run_dir", "")] for p in points])]


def _consistency_section(cons: list[dict], prob: float) -> list[str]:
    """The NEES verdict of every point, estimator and state block."""
    parts = ["<h2>Filter consistency (NEES)</h2>"]
    parts.append('<p class="note">Mean NEES per state block over all runs and epochs, against the χ² band of '
                 'the run-average (R·ε̄ ~ χ²(R·dof)); verdict of <code>analysis.consistency.consistency_report'
                 '</code> on epochs spaced by the given interval (filter errors are correlated in time). '
                 'Diagonal-covariance NEES where the estimator reports only variances.</p>')
    crow = []
    for c in cons:
        ok = c.get("consistent", c.get("verdict") == "consistent")
        verdict = ("consistent", "good") if ok else \
            (f"INCONSISTENT ({html.escape(str(c['verdict']))})", "bad")
        crow.append([c["label"], c["estimator"], c["block"], c["dof"], _fmt(c["mean"]),
                     f"{_fmt(c['band'][0])} – {_fmt(c['band'][1])}", _fmt(c["fraction_inside"]),
                     _fmt(c.get("fraction_min")), _fmt(c.get("fraction_inside_all_epochs")),
                     _fmt(c.get("epoch_spacing_s")), verdict])
    parts.append(_table(["point", "estimator", "block", "dof", "mean NEES", f"{100 * prob:g}% band (R runs)",
                         "fraction inside", "min. expected", "fraction inside (all epochs)", "spacing [s]",
                         "verdict"], crow))
    return parts


def _statistics_section(runs: dict, run_cols: list[str], manifest: dict) -> tuple[list[str], list[dict]]:
    """The per-run statistics side by side (mean ± std over the runs), and the same as JSON records."""
    doc = manifest["experiment"]["document"]
    points = manifest["points"]
    ests = [e["name"] for e in manifest["estimators"]]
    parts: list[str] = []
    skip = ("point", "label", "estimator", "run", *doc.get("sweep", {}))
    stat_cols = [c for c in run_cols if c not in skip]
    stats_json = []
    header = ["statistic"] + [f"{p['label']} | {e}" for p in points for e in ests]
    srows = []
    for col in stat_cols:
        row = [col]
        for p in points:
            for e in ests:
                m, s, n = _col_stats(runs, p["index"], e, col)
                row.append("–" if n == 0 else f"{_fmt(m)} ± {_fmt(s)}")
                stats_json.append({"point": p["index"], "label": p["label"], "estimator": e, "column": col,
                                   "mean": m, "std": s, "runs": n})
        srows.append(row)
    parts.append("<h2>Statistics (mean ± std over the runs)</h2>")
    parts.append('<p class="note">Columns <code>&lt;metric&gt;_&lt;window&gt;_&lt;quantity&gt;_&lt;unit&gt;'
                 '</code>: error std / RMS / mean / max|e| over the window, per run; '
                 '<code>converge_*_s</code>: convergence time [s since start]; <code>nees_*_mean</code>: '
                 'time-averaged NEES. Per-run values: <code>runs.parquet</code>.</p>')
    parts.append(_table(header, srows))
    return parts, stats_json


def _paper_section(prow: list[dict]) -> list[str]:
    """The paper's values beside ours (:func:`paper_rows`), when the experiment gives any."""
    parts: list[str] = []
    if prow:
        parts.append("<h2>Paper values beside ours</h2>")
        rows = []
        for r in prow:
            holds = "–" if r["holds"] is None else \
                (("holds", "good") if r["holds"] else ("does not hold", "bad"))
            rows.append([r["quantity"], r["point"], r["estimator"], r["unit"], _fmt(r["paper"]),
                         f"{_fmt(r['ours'])} ± {_fmt(r['ours_std'])}", r["target"] or "–", holds])
        parts.append(_table(["quantity", "point", "estimator", "unit", "paper", "ours (mean ± std)", "target",
                             "holds"], rows))
    return parts


def _summary_section(summary: dict | None) -> list[str]:
    """The tables and notes of a seed reproduction stored with the campaign, if any."""
    parts: list[str] = []
    if summary:
        parts.append(f"<h2>Reproduction of seed {html.escape(str(summary.get('seed')))}: "
                     f"{html.escape(str(summary.get('title', '')))}</h2>")
        for t in summary.get("tables", []):
            parts.append(f"<h3>{html.escape(t['name'])}: {html.escape(t.get('caption', ''))}</h3>")
            rows = []
            for r in t["rows"]:
                holds = "–" if r.get("holds") is None else (("holds", "good") if r["holds"]
                                                            else ("does not hold", "bad"))
                rows.append([r["quantity"], r.get("unit", ""), _fmt(r.get("paper")), _fmt(r.get("ours")),
                             r.get("target") or "–", holds])
            parts.append(_table(["quantity", "unit", "paper", "ours", "target", "holds"], rows))
        for n in summary.get("notes", []):
            parts.append(f'<p class="note">{html.escape(n)}</p>')
    return parts


def _figure_section(traj, points: list[dict], ests: list[str], epochs: dict, cons: list[dict],
                    prob: float) -> list[str]:
    """The trajectory map, and per point and estimator the error and NEES figures."""
    parts = ["<h2>Figures</h2>"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        img = _map_figure(traj, points)
        if img:
            parts.append(img_tag(img, "trajectory map"))
        stems = _state_cols(list(epochs))
        dof_of = {}
        for c in cons:
            dof_of[(c["point"], c["estimator"], c["block"])] = c["dof"]
        for p in points:
            for e in ests:
                m = (epochs["point"] == p["index"]) & (epochs["estimator"] == e)
                if not m.any():
                    continue
                t = epochs["time_s"][m]
                ep = {k: v[m] for k, v in epochs.items() if k not in ("point", "estimator")}
                have = [s for s in stems if np.any(np.isfinite(ep[f"{s}_mean"]))]
                r_here = int(ep["runs"][0])
                parts.append(f"<h3>{html.escape(p['label'])} — {html.escape(e)}</h3>")
                if have:
                    img = _error_figure(t, ep, have, f"{p['label']} — {e}: error (estimate − truth), "
                                                     f"{r_here} runs")
                    parts.append(img_tag(img, f"errors {e}"))
                blocks = [k[5:] for k in ep if k.startswith("nees_") and np.any(np.isfinite(ep[k]))]
                dof = {b: dof_of.get((p["index"], e, b), len(_blocks(have).get(b, [1]))) for b in blocks}
                if blocks:
                    img = _nees_figure(t, ep, blocks, dof, r_here, prob, f"{p['label']} — {e}: NEES")
                    parts.append(img_tag(img, f"NEES {e}"))
    return parts


def write_report(out_dir, path=None, figures: bool = True) -> Path:
    """Write the campaign report of ``out_dir`` (see the module docstring) and return its path
    (default ``out_dir/report.html``). Also writes ``out_dir/statistics.json``.

    Raises :class:`ReportError` when ``out_dir`` does not hold a complete campaign.
    """
    out = Path(out_dir)
    manifest, runs, epochs, cons, traj, summary, run_cols = _load(out)
    path = Path(path) if path is not None else out / "report.html"
    doc = manifest["experiment"]["document"]
    points = manifest["points"]
    ests = [e["name"] for e in manifest["estimators"]]
    prob = float(doc.get("statistics", {}).get("consistency", {}).get("prob", 0.95))
    title = f"aidnav campaign: {manifest['experiment']['name']}"
    parts: list[str] = [f"<h1>{html.escape(title)}</h1>"]
    if manifest["experiment"].get("description"):
        parts.append(f"<p>{html.escape(manifest['experiment']['description'])}</p>")
    parts.append(_meta_table(manifest))
    parts += _points_section(points)
    parts += _consistency_section(cons, prob)
    stat_parts, stats_json = _statistics_section(runs, run_cols, manifest)
    parts += stat_parts
    prow = paper_rows(manifest, runs)
    parts += _paper_section(prow)
    parts += _summary_section(summary)
    if figures:
        parts += _figure_section(traj, points, ests, epochs, cons, prob)
    parts.append('<p class="note">Errors are estimate − truth: position ENU [m], velocity ENU [m/s], '
                 'attitude as the misalignment φ (E, N, U) [deg] with C(est) = (I − [φ×]) C(true). '
                 'Generated by <code>aidnav report</code>.</p>')
    path.write_text(page(title, parts), encoding="utf-8")
    from .store import write_json  # lazy: pulls in pydantic

    write_json(out / "statistics.json", {"experiment": manifest["experiment"]["name"],
                                         "statistics": stats_json, "paper": prow, "consistency": cons})
    return path
