"""``aidnav fleet``: many logs of a manifest processed in parallel (issue 41), one process per worker on
Dask (a local cluster by default, an existing scheduler when given), summarised in one table and page.

The manifest is a CSV file with the columns ``name, imu, gnss`` and the optional ``config``, ``truth``,
``vehicle`` (the preset of ``aidnav process --vehicle``), ``vehicle_id`` (which physical vehicle: the
group of the fleet page's distributions), ``time_offset``, ``height_offset`` (``--time-offset``,
``--height-offset``) and ``smooth`` (true/false). Paths are relative to the manifest's folder; an empty
cell is "not given". ``name`` is the log's sub-directory: letters, digits, ``.``, ``_``, ``-``.

Each log is a task that runs :func:`aidnav.apps.process.process_logs` in the worker's process (numba's
kernels loaded once per worker, not per log) into ``DIR/<name>/``, as ``aidnav process`` writes it but
without the stages' wall times (the outputs then depend on the inputs only: the same bytes on any
cluster). Any failure of a log is its row's ``status`` (``failed``) and ``error``; the others go on.
The worker writes the log's row last, ``DIR/<name>/fleet_row.json`` (renamed into place), keyed by
the manifest row: a rerun after a kill redoes only the logs without a row (and, with ``retry_failed``,
the failed ones). At the end ``DIR/fleet.parquet`` (a row per log, manifest order) and
``DIR/fleet.html`` (:mod:`aidnav.report.fleet_page`) are written from the rows.

Paths handed to the workers are absolute: workers of an external scheduler need the same file system.
"""

from __future__ import annotations

import csv
import hashlib
import json
import math
import os
import re
import time as _time
from dataclasses import asdict, dataclass
from pathlib import Path

from aidnav.apps.common import prepare_out_dir
from aidnav.errors import InputError

__all__ = ["FleetLog", "read_manifest", "run_log", "run_fleet", "FleetResult", "ROW_FILE"]

ROW_FILE = "fleet_row.json"  #: a log's row, written last by its task: the log is done
REQUIRED = ("name", "imu", "gnss")
OPTIONAL = ("config", "truth", "vehicle", "vehicle_id", "time_offset", "height_offset", "smooth")
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


@dataclass(frozen=True)
class FleetLog:
    """One row of the manifest, paths resolved."""

    name: str
    imu: str
    gnss: str
    config: str | None = None
    truth: str | None = None
    vehicle: str | None = None
    vehicle_id: str | None = None
    time_offset: float | None = None
    height_offset: float | None = None
    smooth: bool = False

    def key(self, figures: bool) -> str:
        """What the log's outputs depend on (a row with another key is redone)."""
        text = json.dumps({**asdict(self), "figures": bool(figures)}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def read_manifest(path) -> list[FleetLog]:
    """The manifest's logs (module doc); a bad cell is ``InputError`` ``FILE:LINE: what — what to do``."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as e:
        raise InputError(f"{path}: cannot read the manifest: {e.strerror}") from None
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        raise InputError(f"{path}:1: empty manifest — give a header line with the columns name,imu,gnss")
    head = [h.strip() for h in rows[0]]
    missing = [c for c in REQUIRED if c not in head]
    if missing:
        raise InputError(f"{path}:1: missing column(s) {', '.join(missing)} — the header needs name,imu,gnss "
                         f"(optional: {', '.join(OPTIONAL)})")
    unknown = [c for c in head if c not in REQUIRED + OPTIONAL]
    if unknown:
        raise InputError(f"{path}:1: unknown column(s) {', '.join(unknown)} — expected name, imu, gnss and "
                         f"optionally {', '.join(OPTIONAL)}")
    base = path.resolve().parent
    logs, seen = [], {}
    for line, cells in enumerate(rows[1:], start=2):
        if not any(c.strip() for c in cells):
            continue
        if len(cells) != len(head):
            raise InputError(f"{path}:{line}: {len(cells)} cells, the header has {len(head)} — one cell per "
                             "column (empty for not given)")
        r = {h: c.strip() for h, c in zip(head, cells, strict=True)}
        name = r["name"]
        if not _NAME.match(name):
            raise InputError(f"{path}:{line}: name {name!r} — a name is the log's folder: letters, digits, "
                             "'.', '_', '-', starting with a letter or digit")
        if name in seen:
            raise InputError(f"{path}:{line}: name {name!r} already on line {seen[name]} — names must be "
                             "unique")
        seen[name] = line
        for c in ("imu", "gnss"):
            if not r[c]:
                raise InputError(f"{path}:{line}: empty {c} — give the {c.upper()} log's path")

        smooth = (r.get("smooth") or "false").lower()
        if smooth not in ("true", "false", "1", "0", "yes", "no"):
            raise InputError(f"{path}:{line}: smooth {r['smooth']!r} — give true or false")
        file = {c: None if not r.get(c) else str((base / r[c]).resolve()) for c in ("imu", "gnss", "config",
                                                                                      "truth")}
        num = {c: _number(r.get(c), f"{path}:{line}: {c}") for c in ("time_offset", "height_offset")}
        logs.append(FleetLog(name, file["imu"], file["gnss"], file["config"], file["truth"],
                             r.get("vehicle") or None, r.get("vehicle_id") or None, num["time_offset"],
                             num["height_offset"], smooth in ("true", "1", "yes")))
    if not logs:
        raise InputError(f"{path}:2: no logs in the manifest — one line per log after the header")
    return logs


def _number(v: str | None, where: str) -> float | None:
    if not v:
        return None
    try:
        x = float(v)
    except ValueError:
        x = math.nan
    if not math.isfinite(x):
        raise InputError(f"{where} {v!r} is not a finite number — give seconds/metres")
    return x


# ------------------------------------------------------------------------------------------ one log
def _error_text(e: BaseException) -> str:
    from aidnav.io.errors import DataError  # lazy: with the job's modules, on a failure only

    user = isinstance(e, (InputError, DataError, ValueError, OSError))
    msg = str(e) or type(e).__name__
    if isinstance(e, OSError) and e.filename is not None and str(e.filename) not in msg:
        msg = f"{e.filename}: {e.strerror}"
    return msg if user else f"internal error (a bug in aidnav): {type(e).__name__}: {msg}"


def _write_row(folder: Path, row: dict) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / (ROW_FILE + ".part")
    tmp.write_text(json.dumps(row, indent=1, sort_keys=True, allow_nan=True) + "\n")
    os.replace(tmp, folder / ROW_FILE)


def run_log(log: FleetLog, out_dir: str, figures: bool = True) -> dict:
    """Process one log into ``out_dir/<name>/`` (a Dask task; also called in-process): its row, also
    written to ``out_dir/<name>/fleet_row.json``. Never raises for the log's own failure."""
    from aidnav.apps.process import process_logs  # lazy: the job's modules, in the worker
    from aidnav.apps.run_outputs import IN_PROCESS  # lazy: with the job's modules

    folder = Path(out_dir) / log.name
    t0 = _time.perf_counter()
    row = {"name": log.name, "vehicle_id": log.vehicle_id or log.vehicle or "all", "key": log.key(figures)}
    try:
        s = process_logs(log.imu, log.gnss, log.config, folder, smooth=log.smooth,
                         figures=IN_PROCESS if figures else False,
                         height_offset_m=log.height_offset, time_offset_s=log.time_offset,
                         vehicle=log.vehicle, timings=False)
        row.update(status="ok", error="", **summary_row(s))
        if log.truth:
            row.update(truth_row(folder / "trajectory.parquet", log.truth))
    except Exception as e:  # noqa: BLE001  (one bad log never stops the others: its row says why)
        row.update(status="failed", error=_error_text(e))
    row["wall_s"] = _time.perf_counter() - t0
    _write_row(folder, row)
    return row


_LIST_NAMES = {"lever_arm_m": ("lever_arm_x_m", "lever_arm_y_m", "lever_arm_z_m"),
               "mounting_rph_deg": ("mounting_roll_deg", "mounting_pitch_deg", "mounting_heading_deg")}


def summary_row(s: dict) -> dict:
    """The fleet table's columns of a run's summary: counts, σ consistency (mean NIS over its dof, in
    its 95 % band or not), outage score, every calibration estimate with its 1σ."""
    row = {"imu_samples": s.get("imu_samples"), "gnss_fixes": s.get("gnss_fixes"),
           "duration_s": (s["imu_samples"] / s["imu_rate_hz"]) if s.get("imu_rate_hz") else None,
           "gnss_position_rejected": s.get("gnss_position_rejected"),
           "reinitialisations": len(s.get("reinitialisations") or []),
           "warnings": len(s.get("warnings") or [])}
    for name, v in (s.get("nis") or {}).items():
        row[f"nis_{name}_mean"] = v["mean"]
        row[f"nis_{name}_ratio"] = v["mean"] / v["dof"] if v.get("dof") else None
        row[f"nis_{name}_in_band"] = bool(v["in_band"])
    o = s.get("outage_score") or {}
    if o:
        row["outage_end_error_median_m"] = o.get("end_error_median_m")
        row["outage_rms_m"] = o.get("rms_m")
    for name, v in (s.get("calibration") or {}).items():
        if not isinstance(v, dict):
            continue
        val, std = v.get("value"), v.get("std")
        if isinstance(val, list):
            names = _LIST_NAMES.get(name) or tuple(f"{name}_{k}" for k in range(len(val)))
            stds = std if isinstance(std, list) else [None] * len(val)
            for n, x, sd in zip(names, val, stds, strict=False):
                row[n], row[n + "_std"] = x, sd
        else:
            row[name], row[name + "_std"] = val, std
        row[name + "_estimated"] = bool(v.get("estimated", True))
    return row


def truth_row(estimate, truth) -> dict:
    """Accuracy against a reference file: RMS and 95th percentile of the horizontal, vertical and 3-D
    position errors, heading RMS (:func:`aidnav.apps.evaluate.evaluate_files`, nothing printed)."""
    import io  # lazy: with rich, for the quiet console

    from rich.console import Console  # lazy: rich is heavy to import

    from aidnav.apps.evaluate import evaluate_files  # lazy: pulls in pandas

    stats, _ = evaluate_files(estimate, truth, console=Console(file=io.StringIO()))
    out = {}
    for q, col in (("pos horizontal", "h"), ("pos U", "v"), ("pos 3D", "3d"), ("heading", "heading")):
        if q in stats.index:
            unit = "deg" if col == "heading" else "m"
            out[f"err_{col}_rms_{unit}"] = float(stats.loc[q, "RMS"])
            out[f"err_{col}_p95_{unit}"] = float(stats.loc[q, "p95"])
    return out


# ------------------------------------------------------------------------------------------ the fleet
@dataclass
class FleetResult:
    rows: list[dict]
    reused: int
    computed: int
    paths: dict
    backend: dict

    @property
    def failed(self) -> list[dict]:
        return [r for r in self.rows if r.get("status") != "ok"]


def _done_row(folder: Path, key: str, retry_failed: bool) -> dict | None:
    try:
        row = json.loads((folder / ROW_FILE).read_text())
    except (OSError, ValueError):
        return None
    if row.get("key") != key or (retry_failed and row.get("status") != "ok"):
        return None
    return row


def run_fleet(manifest, out_dir, *, workers: int | None = None, scheduler: str | None = None,
              figures: bool = False, retry_failed: bool = False, progress=None) -> FleetResult:
    """Process every log of ``manifest`` into ``out_dir`` (module doc). ``workers``: processes of the local
    Dask cluster (default: the CPUs, at most the logs to do; 1: in this process, no cluster);
    ``scheduler``: the address of an existing Dask scheduler instead. ``progress``: a
    :class:`aidnav.progress.ProgressBar` (one step per log)."""
    logs = read_manifest(manifest)
    out = prepare_out_dir(out_dir).resolve()
    rows: dict[str, dict] = {}
    todo = []
    for log in logs:
        row = _done_row(out / log.name, log.key(figures), retry_failed)
        if row is None:
            todo.append(log)
        else:
            rows[log.name] = row
    if progress is not None:
        progress.stage("aidnav fleet", total=len(logs), unit="logs")
        progress.advance(len(rows))
    info: dict = {"kind": "none" if not todo else None}

    def done(row):
        rows[row["name"]] = row
        if progress is not None:
            progress.advance(1)

    if todo:
        n = workers if workers is not None else (os.cpu_count() or 1)
        if scheduler is None and min(n, len(todo)) <= 1:
            info = {"kind": "in-process", "workers": 1}
            for log in todo:
                done(run_log(log, str(out), figures))
        else:
            info = _dask(todo, str(out), figures, min(n, len(todo)), scheduler, done)
    ordered = [rows[log.name] for log in logs]
    paths = write_fleet_outputs(out, ordered)
    return FleetResult(ordered, len(logs) - len(todo), len(todo), paths, info)


def _dask(todo: list[FleetLog], out: str, figures: bool, workers: int, scheduler: str | None, done) -> dict:
    from distributed import Client, LocalCluster, as_completed  # lazy: distributed is heavy to import

    cluster = None
    if scheduler:
        client = Client(scheduler)
        info = {"kind": "dask", "scheduler": scheduler}
    else:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
        info = {"kind": "dask", "scheduler": "LocalCluster"}
    try:
        info["workers"] = len(client.scheduler_info().get("workers", {}))
        futures = {client.submit(run_log, log, out, figures, pure=False,
                                 key=f"aidnav-fleet-{log.name}-{log.key(figures)}"): log for log in todo}
        for fut in as_completed(futures):
            log = futures[fut]
            try:
                row = fut.result()
            except Exception as e:  # noqa: BLE001  (the worker died on this log: its row says so)
                row = {"name": log.name, "vehicle_id": log.vehicle_id or log.vehicle or "all",
                       "key": log.key(figures), "status": "failed",
                       "error": f"the worker running it failed: {type(e).__name__}: {e}"}
                _write_row(Path(out) / log.name, row)
            done(row)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return info


# ------------------------------------------------------------------------------------------ outputs
_FIRST = ("name", "vehicle_id", "status", "error")
_LAST = ("wall_s", "key")


def fleet_table(rows: list[dict]):
    """The rows as one Arrow table: the columns of every row (a row without one: null), the names and
    status first, the wall time and key last."""
    import pyarrow as pa  # lazy: pyarrow is heavy to import

    cols: list[str] = list(_FIRST)
    for r in rows:
        cols += [c for c in r if c not in cols and c not in _LAST]
    cols += list(_LAST)
    data = {}
    for c in cols:
        vals = [r.get(c) for r in rows]
        kinds = {type(v) for v in vals if v is not None}
        if kinds <= {bool}:
            typ = pa.bool_()
        elif kinds <= {int}:
            typ = pa.int64()
        elif kinds <= {int, float}:
            typ = pa.float64()
            vals = [None if v is None else float(v) for v in vals]
        else:
            typ = pa.string()
            vals = [None if v is None else str(v) for v in vals]
        data[c] = pa.array(vals, type=typ)
    return pa.table(data)


def write_fleet_outputs(out: Path, rows: list[dict]) -> dict:
    """``fleet.parquet`` and ``fleet.html`` of the rows (each renamed into place)."""
    import pyarrow.parquet as pq  # lazy: pyarrow is heavy to import

    from aidnav.report.fleet_page import fleet_page_html  # lazy: pulls in matplotlib

    table = fleet_table(rows)
    pq_path, html_path = out / "fleet.parquet", out / "fleet.html"
    tmp = out / "fleet.parquet.part"
    pq.write_table(table, tmp)
    os.replace(tmp, pq_path)
    tmp = out / "fleet.html.part"
    tmp.write_text(fleet_page_html(table.to_pylist()), encoding="utf-8")
    os.replace(tmp, html_path)
    return {"parquet": pq_path, "html": html_path}


def format_fleet(res: FleetResult) -> str:
    """The text the command prints."""
    ok = sum(r.get("status") == "ok" for r in res.rows)
    lines = [f"aidnav fleet: {len(res.rows)} logs, {ok} ok, {len(res.failed)} failed "
             f"({res.computed} processed now, {res.reused} done before); {res.backend}"]
    lines += [f"failed: {r['name']}: {r.get('error')}" for r in res.failed]
    lines += [f"wrote {p}" for p in res.paths.values()]
    return "\n".join(lines) + "\n"
