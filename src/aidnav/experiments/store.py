"""Results store of a campaign directory: per-run files, then merged Parquet tables.

Layout of ``DIR``:

* ``runs/<point key[:16]>/r<run>.npz`` — one file per (sweep point, run), written atomically as each run
  finishes: per estimator the epochs ``time`` [s], the errors (estimate − truth) and the filter's 1σ in
  boundary units (m, m/s, deg; ``<name>.error``, ``<name>.sigma``, columns = its states), the NEES per
  block (``<name>.nees``) and a JSON ``meta`` (point key, run, state names, timings, counters). The point
  key hashes everything in the experiment that determines a run's result (motion, sensors, estimators,
  imports, base seed; not the statistics, the number of runs or the sweep's other points), so a rerun
  reuses exactly the runs that are still valid (a resumed, extended or partly edited campaign recomputes
  nothing else). It does not cover the code: after changing the simulation or an estimator, use a new
  directory.
* ``runs.parquet`` — one row per (sweep point, estimator, run): ``point``, ``label``, one column per sweep
  path, ``estimator``, ``run``, then the statistics of :func:`statistic_columns`.
* ``epochs.parquet`` — one row per (sweep point, estimator, epoch): ``time_s``, ``runs`` and per state
  ``<state>_<unit>_mean`` / ``_std`` (across runs, ddof = 1) / ``_rms`` / ``_sigma`` (mean filter 1σ over
  runs), and ``nees_<block>`` (mean NEES over runs).
* ``consistency.json`` — NEES verdicts per (point, estimator, block)
  (:func:`aidnav.analysis.consistency.consistency_report`).
* ``trajectories.parquet`` — the truth of each sweep point, decimated (for the report's map).
* ``manifest.json`` — written by the runner (experiment, version, seeds, timings, host).

The Parquet tables hold nothing run-dependent (no wall times, hosts or paths): the same experiment gives
identical tables whatever the order or place the runs were computed in. Tables are built from numpy
arrays with pyarrow at the edge; nothing here loops over epochs in Python.
"""

from __future__ import annotations

import json
import math
import os
import warnings
import zipfile
from pathlib import Path

import numpy as np

import aidnav
from aidnav.io.atomic import replacing

from . import statistics_spec as _config
from .estimators import state_blocks, state_unit
from .statistics_spec import (
    available_quantities,
    quantity_column,
    spec_quantities,
    statistic_columns,  # noqa: F401  (re-exported)
    window_metrics,
)

__all__ = ["package_version", "run_path", "save_run", "load_run", "existing_runs", "statistic_columns",
           "run_statistics", "epoch_summary", "merge_campaign", "prepare_merge", "write_trajectories",
           "write_json", "run_arrays"]


def package_version() -> str:
    """Installed version of aidnav (:data:`aidnav.__version__`)."""
    return aidnav.__version__


def write_json(path, obj) -> Path:
    """Write JSON atomically (NaN/inf become null)."""
    def clean(x):
        if isinstance(x, float) and not math.isfinite(x):
            return None
        if isinstance(x, dict):
            return {str(k): clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        if isinstance(x, np.ndarray):
            return clean(x.tolist())
        if isinstance(x, (np.floating, np.integer, np.bool_)):
            return clean(x.item())
        return x

    path = Path(path)
    tmp = path.with_name(path.name + f".tmp{os.getpid()}")
    tmp.write_text(json.dumps(clean(obj), indent=2, allow_nan=False))
    os.replace(tmp, path)
    return path


# ----------------------------------------------------------------------------------- run files
def run_path(out_dir, key: str, run: int) -> Path:
    """``DIR/runs/<key[:16]>/r<run:05d>.npz``."""
    return Path(out_dir) / "runs" / key[:16] / f"r{run:05d}.npz"


def run_arrays(result: dict) -> dict:
    """A run's result (from :func:`aidnav.experiments.runner.run_task`) as :func:`load_run` reads it back
    from its file: {"key", "run", "estimators": {name: {time, error, sigma, nees (float64, C order),
    states, blocks, info}}} (what :func:`merge_campaign` takes from memory instead of the file)."""
    ests = {}
    for name, r in result["estimators"].items():
        ests[name] = {k: np.ascontiguousarray(r[k], dtype=np.float64)
                      for k in ("time", "error", "sigma", "nees")}
        ests[name].update(states=list(r["states"]), blocks=list(r["blocks"]), info=r.get("info", {}))
    return {"key": result["key"], "run": int(result["run"]), "estimators": ests}


def save_run(out_dir, result: dict, arrays_of: dict | None = None) -> Path:
    """Write one run's result (from :func:`aidnav.experiments.runner.run_task`) atomically; ``arrays_of``:
    its :func:`run_arrays` when already made."""
    path = run_path(out_dir, result["key"], result["run"])
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {}
    meta = {"key": result["key"], "run": int(result["run"]), "imu_samples": int(result["imu_samples"]),
            "timing": result["timing"], "estimators": {}}
    for name, r in (arrays_of or run_arrays(result))["estimators"].items():
        for k in ("time", "error", "sigma", "nees"):
            arrays[f"{name}.{k}"] = r[k]
        meta["estimators"][name] = {"states": r["states"], "blocks": r["blocks"], "info": r["info"]}
    arrays["meta"] = np.array(json.dumps(meta))
    tmp = path.with_name(path.name + f".tmp{os.getpid()}")
    with open(tmp, "wb") as f:
        np.savez(f, **arrays)
    os.replace(tmp, path)
    return path


def load_run(path) -> dict | None:
    """A run file as {meta..., "estimators": {name: {time, error, sigma, nees, states, blocks, info}}};
    None when it is missing or unreadable (an interrupted write)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            ests = {}
            for name, m in meta["estimators"].items():
                ests[name] = {k: z[f"{name}.{k}"] for k in ("time", "error", "sigma", "nees")} | m
    except (OSError, KeyError, ValueError, zipfile.BadZipFile, EOFError):
        return None
    meta["estimators"] = ests
    return meta


def _run_ok(path, key: str) -> bool:
    try:
        with np.load(path, allow_pickle=False) as z:
            return json.loads(str(z["meta"]))["key"] == key
    except (OSError, KeyError, ValueError, zipfile.BadZipFile, EOFError):
        return False


def existing_runs(out_dir, plan) -> set[tuple[str, int]]:
    """(point key, run) pairs of ``plan`` whose run files exist in ``out_dir`` and are readable."""
    done = set()
    for p in plan.points:
        d = run_path(out_dir, p.key, 0).parent
        if not d.is_dir():
            continue
        for k in range(plan.runs):
            f = run_path(out_dir, p.key, k)
            if f.exists() and _run_ok(f, p.key):
                done.add((p.key, k))
    return done


# ----------------------------------------------------------------------------------- statistics
def _quantity(q: str, err: np.ndarray, sig: np.ndarray, states) -> tuple[np.ndarray, np.ndarray]:
    """(R, N) error and σ of a quantity from (R, N, n) state arrays (boundary units)."""
    states = list(states)
    if q in states:
        i = states.index(q)
        return err[..., i], sig[..., i]
    need, kind = _config.DERIVED_QUANTITIES[q]
    idx = [states.index(s) for s in need]
    if kind == "alias":
        return err[..., idx[0]], sig[..., idx[0]]
    return np.sqrt(np.sum(err[..., idx] ** 2, axis=-1)), np.sqrt(np.sum(sig[..., idx] ** 2, axis=-1))


def _window_mask(t: np.ndarray, w, segments: list[dict]) -> np.ndarray:
    if w.segment is not None:
        row = next(r for r in segments if r["name"] == w.segment)
        return (t >= row["start_s"]) & (t <= row["end_s"])
    if w.last_s is not None:
        return t > t[-1] - w.last_s
    m = np.ones(len(t), dtype=bool)
    if w.start_s is not None:
        m &= t >= w.start_s
    if w.end_s is not None:
        m &= t <= w.end_s
    return m


def _metric(m: str, e: np.ndarray) -> np.ndarray:
    """Metric over the time axis of (R, n) values (NaN-aware; NaN for an empty window)."""
    r = e.shape[0]
    if e.shape[1] == 0:
        return np.full(r, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        if m == "std":
            return np.nanstd(e, axis=1)
        if m == "rms":
            return np.sqrt(np.nanmean(e * e, axis=1))
        if m == "mean":
            return np.nanmean(e, axis=1)
        if m == "max":
            return np.nanmax(np.abs(e), axis=1)
    raise ValueError(f"unknown metric {m!r}")


def _convergence(t: np.ndarray, val: np.ndarray, below: float, hold_s: float | None) -> np.ndarray:
    """(R,) time of the first epoch from which val <= below holds to the end (or for hold_s)."""
    ok = np.abs(val) <= below  # NaN → False
    r, n = ok.shape
    out = np.full(r, np.nan)
    if n == 0:
        return out
    if hold_s is None:
        suffix = np.logical_and.accumulate(ok[:, ::-1], axis=1)[:, ::-1]
        good = suffix
    else:
        bad = np.concatenate([np.zeros((r, 1), dtype=np.int64), np.cumsum(~ok, axis=1)], axis=1)
        j_end = np.searchsorted(t, t + hold_s, side="right")
        inside = t + hold_s <= t[-1] + 1e-9
        good = ((bad[:, j_end] - bad[:, :n]) == 0) & inside[None, :]
    has = good.any(axis=1)
    first = np.argmax(good, axis=1)
    out[has] = t[first[has]]
    return out


def run_statistics(t: np.ndarray, err: np.ndarray, sig: np.ndarray, nees: np.ndarray, states, blocks,
                   stats: _config.StatisticsSpec, segments: list[dict]) -> dict[str, np.ndarray]:
    """Per-run statistics of one estimator at one sweep point.

    t : (N,) epochs [s]; err, sig : (R, N, n) errors and filter σ in boundary units; nees : (R, N, B) per
    block; segments : the point's segment table. Returns column → (R,) values (see
    :func:`statistic_columns`; quantities the estimator does not have are left out).
    """
    qs = spec_quantities(stats, states)
    cols: dict[str, np.ndarray] = {}
    cache = {q: _quantity(q, err, sig, states) for q in qs}
    for wname, w, m in window_metrics(stats):
        mask = _window_mask(t, w, segments)
        for q in qs:
            cols[f"{m}_{wname}_{quantity_column(q)}"] = _metric(m, cache[q][0][:, mask])
    for cname, c in stats.convergence.items():
        if c.quantity not in available_quantities(tuple(states)):
            continue
        e, s = cache[c.quantity] if c.quantity in cache else _quantity(c.quantity, err, sig, states)
        cols[f"converge_{cname}_s"] = _convergence(t, e if c.of == "error" else s, c.below, c.hold_s)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for j, b in enumerate(blocks):
            cols[f"nees_{b}_mean"] = np.nanmean(nees[:, :, j], axis=1)
    return cols


def epoch_summary(err: np.ndarray, sig: np.ndarray, nees: np.ndarray, states,
                  blocks) -> dict[str, np.ndarray]:
    """Per-epoch summaries across runs: ``<state>_<unit>_{mean,std,rms,sigma}`` and ``nees_<block>``.

    std uses ddof = 1 (NaN for one run); sigma is the mean of the runs' filter 1σ; rms = √mean(e²).
    """
    out: dict[str, np.ndarray] = {}
    r = err.shape[0]
    # without a NaN, numpy's nan-functions return what mean/std return (they replace the NaNs in a copy, then
    # make the same sums in the same order): those, without the copies
    e_mean, e_std = (np.nanmean, np.nanstd) if np.isnan(err).any() else (np.mean, np.std)
    s_mean = np.nanmean if np.isnan(sig).any() else np.mean
    n_mean = np.nanmean if np.isnan(nees).any() else np.mean
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for i, s in enumerate(states):
            c = f"{s}_{state_unit(s)[0]}"
            e = err[:, :, i]
            out[f"{c}_mean"] = e_mean(e, axis=0)
            out[f"{c}_std"] = e_std(e, axis=0, ddof=1) if r > 1 else np.full(e.shape[1], np.nan)
            out[f"{c}_rms"] = np.sqrt(e_mean(e * e, axis=0))
            out[f"{c}_sigma"] = s_mean(sig[:, :, i], axis=0)
        for j, b in enumerate(blocks):
            out[f"nees_{b}"] = n_mean(nees[:, :, j], axis=0)
    return out


def _consistency(t, nees, blocks, states, spec) -> list[dict]:
    from aidnav.analysis.consistency import chi2_band, consistency_report  # lazy: pulls in scipy

    out = []
    if len(t) == 0:
        return out
    dt = float(np.median(np.diff(t))) if len(t) > 1 else spec.epoch_spacing_s
    step = max(1, int(round(spec.epoch_spacing_s / dt))) if dt > 0 else 1
    idx = np.arange(0, len(t), step)
    bidx = state_blocks(states)
    r = nees.shape[0]
    for j, b in enumerate(blocks):
        dof = len(bidx[b])
        rep = consistency_report(nees[:, idx, j], dof, prob=spec.prob, alpha=spec.alpha)
        lo, hi = chi2_band(dof, r, spec.prob)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            m = np.nanmean(nees[:, :, j], axis=0)
        fin = np.isfinite(m)
        frac_all = float(np.mean((m[fin] >= lo) & (m[fin] <= hi))) if fin.any() else float("nan")
        d = rep.to_dict()
        d.update(block=b, epoch_spacing_s=float(step * dt), fraction_inside_all_epochs=frac_all,
                 consistent=rep.consistent)
        out.append(d)
    return out


# ----------------------------------------------------------------------------------- merging
def _arrow():
    """pyarrow, pyarrow.parquet and :func:`aidnav.io._arrow.to_arrow` (Arrow arrays without ``pa.array``,
    which imports pandas), imported where the tables are written: a campaign's workers, forked before the
    merge, never load them (≈ 50 ms)."""
    import pyarrow as pa  # lazy: the tables only (see above)
    import pyarrow.parquet as pq  # lazy: the tables only (see above)

    from aidnav.io._arrow import to_arrow  # lazy: pyarrow (see above)

    return pa, pq, to_arrow


def prepare_merge() -> None:
    """Import what :func:`merge_campaign` imports on its first call (pyarrow and the NEES bands'
    scipy.special, ≈ 0.15 s): a campaign on worker processes calls it while they compute, so that the merge
    after the last run is shorter."""
    from aidnav.analysis.consistency import binom_ppf, chi2_band  # lazy: pulls in scipy.special

    _arrow()
    chi2_band(1, 2)
    binom_ppf(0.5, 2, 0.5)


def _sweep_column(values: list):
    to_arrow = _arrow()[2]
    if all(isinstance(v, str) for v in values):
        return to_arrow(values, "string")
    if all(isinstance(v, bool) for v in values):
        return to_arrow(values, "bool")
    if all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return to_arrow(values, "int64")
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return to_arrow([float(v) for v in values], "float64")
    return to_arrow([json.dumps(v, sort_keys=True) for v in values], "string")


def _load_point(out_dir, point, runs: int, estimators: list[str], loaded: dict):
    data = {e: {"time": None, "error": [], "sigma": [], "nees": [], "states": None, "blocks": None}
            for e in estimators}
    for k in range(runs):
        f = run_path(out_dir, point.key, k)
        r = loaded.get((point.key, k)) or load_run(f)
        if r is None or r["key"] != point.key:
            raise FileNotFoundError(f"run file {f} is missing or unreadable")
        for e in estimators:
            x = r["estimators"][e]
            d = data[e]
            if d["time"] is None:
                d["time"], d["states"], d["blocks"] = x["time"], x["states"], x["blocks"]
            elif not np.array_equal(d["time"], x["time"]):
                raise ValueError(f"point {point.label}, estimator {e}: run {k} has other epochs than run 0")
            for a in ("error", "sigma", "nees"):
                d[a].append(x[a])
    for d in data.values():
        for a in ("error", "sigma", "nees"):
            d[a] = np.stack(d[a])
    return data


def merge_campaign(plan, out_dir, loaded: dict | None = None) -> dict:
    """Merge the run files of a complete campaign into runs.parquet, epochs.parquet and
    consistency.json (see the module docstring). Returns {"paths": [...], "consistency": [...]}.

    loaded : {(point key, run): :func:`run_arrays` of the run} for runs still in memory (the runs this
        process has just saved): taken from there instead of being read back from their files (the same
        arrays, so the same tables)."""
    loaded = loaded or {}
    pa, pq, to_arrow = _arrow()
    out = Path(out_dir)
    stats = plan.experiment.statistics
    est_names = plan.estimators
    sweep_paths = list(plan.doc["sweep"])
    run_cols: dict[str, list] = {"point": [], "label": [], **{p: [] for p in sweep_paths},
                                 "estimator": [], "run": []}
    stat_rows: list[dict[str, np.ndarray]] = []
    epoch_parts: list[tuple[int, str, np.ndarray, int, dict]] = []
    consistency = []
    all_states: list[tuple[str, tuple[str, ...]]] = []
    for p in plan.points:
        data = _load_point(out, p, plan.runs, est_names, loaded)
        for e in est_names:
            d = data[e]
            states, blocks, t = tuple(d["states"]), list(d["blocks"]), d["time"]
            if (e, states) not in all_states:
                all_states.append((e, states))
            cols = run_statistics(t, d["error"], d["sigma"], d["nees"], states, blocks, stats, p.segments)
            for k in range(plan.runs):
                run_cols["point"].append(p.index)
                run_cols["label"].append(p.label)
                for sp in sweep_paths:
                    run_cols[sp].append(p.values[sp])
                run_cols["estimator"].append(e)
                run_cols["run"].append(k)
            stat_rows.append(cols)
            epoch_parts.append((p.index, e, t, plan.runs,
                                epoch_summary(d["error"], d["sigma"], d["nees"], states, blocks)))
            for c in _consistency(t, d["nees"], blocks, states, stats.consistency):
                consistency.append({"point": p.index, "label": p.label, "estimator": e, **c})
    # runs.parquet
    scols = statistic_columns(stats, all_states)
    arrays = {"point": to_arrow(run_cols["point"], "int32"), "label": to_arrow(run_cols["label"], "string")}
    for sp in sweep_paths:
        arrays[sp] = _sweep_column(run_cols[sp])
    arrays["estimator"] = to_arrow(run_cols["estimator"], "string")
    arrays["run"] = to_arrow(run_cols["run"], "int32")
    for c in scols:
        arrays[c] = to_arrow(np.concatenate([row.get(c, np.full(plan.runs, np.nan)) for row in stat_rows]),
                             "float64")
    paths = []
    with replacing(out / "runs.parquet") as tmp:  # whole or not at all (issue 37)
        pq.write_table(pa.table(arrays), tmp)
    paths.append(out / "runs.parquet")
    # epochs.parquet
    ecols: list[str] = []
    for *_, summ in epoch_parts:
        for c in summ:
            if c not in ecols:
                ecols.append(c)
    n_tot = sum(len(t) for _, _, t, _, _ in epoch_parts)
    ep = {"point": to_arrow(np.concatenate([np.full(len(t), i, np.int32) for i, _, t, _, _ in epoch_parts])
                            if n_tot else np.zeros(0, np.int32), "int32"),
          "estimator": to_arrow([e for _, e, t, _, _ in epoch_parts for _ in range(len(t))], "string"),
          "time_s": to_arrow(np.concatenate([t for _, _, t, _, _ in epoch_parts]), "float64"),
          "runs": to_arrow(np.concatenate([np.full(len(t), r, np.int32) for _, _, t, r, _ in epoch_parts]),
                           "int32")}
    for c in ecols:
        ep[c] = to_arrow(np.concatenate([s.get(c, np.full(len(t), np.nan)) for _, _, t, _, s in epoch_parts]),
                         "float64")
    with replacing(out / "epochs.parquet") as tmp:
        pq.write_table(pa.table(ep), tmp)
    paths.append(out / "epochs.parquet")
    paths.append(write_json(out / "consistency.json", {"experiment": plan.experiment.name,
                                                        "checks": consistency}))
    return {"paths": paths, "consistency": consistency}


def write_trajectories(out_dir, plan, truth_of, max_points: int = 2000) -> Path:
    """``DIR/trajectories.parquet``: the truth of every sweep point (``truth_of(point)`` →
    :class:`aidnav.data.Trajectory`), decimated to at most ``max_points`` samples: point, time_s,
    lat_deg, lon_deg, height_m."""
    pa, pq, to_arrow = _arrow()
    cols: dict[str, list] = {"point": [], "time_s": [], "lat_deg": [], "lon_deg": [], "height_m": []}
    for p in plan.points:
        tr = truth_of(p)
        step = max(1, int(math.ceil(len(tr.time) / max_points)))
        sl = np.r_[np.arange(0, len(tr.time), step), len(tr.time) - 1]
        sl = np.unique(sl)
        cols["point"].append(np.full(len(sl), p.index, np.int32))
        cols["time_s"].append(tr.time[sl])
        cols["lat_deg"].append(np.degrees(tr.lat[sl]))
        cols["lon_deg"].append(np.degrees(tr.lon[sl]))
        cols["height_m"].append(tr.height[sl])
    table = pa.table({k: to_arrow(np.concatenate(v), "int32" if k == "point" else "float64")
                      for k, v in cols.items()})
    path = Path(out_dir) / "trajectories.parquet"
    with replacing(path) as tmp:
        pq.write_table(table, tmp)
    return path
