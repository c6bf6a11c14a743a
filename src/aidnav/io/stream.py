"""Interchange files chunk by chunk (issue 29): IMU increments read from Parquet in batches, trajectories
written in pieces (Parquet row groups, CSV through pyarrow's writer), so memory does not grow with the log.

:func:`iter_imu` yields :class:`aidnav.data.ImuData` chunks with exactly what :func:`.interchange.read_imu`
gives on the whole file (the same checks, row numbers in the messages); other formats and CSV are read
whole and then cut into chunks. :class:`TrajectoryWriter` writes the columns of
:func:`.interchange.trajectory_columns` piece by piece; the file appears under its name only when
closed (``abort`` removes the partial one).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from aidnav.data import ImuData
from aidnav.io.errors import DataError

__all__ = ["iter_imu", "TrajectoryWriter", "imu_time_span"]


def _parquet_imu(path: Path):
    """(ParquetFile, columns used, increments?, metadata dict) of an interchange IMU Parquet file, or None
    when it is not one (another reader takes it)."""
    import pyarrow.parquet as pq

    from aidnav.io._table import _META_KEY
    from aidnav.io.interchange import IMU_INCREMENT_COLUMNS, IMU_RATE_COLUMNS

    if path.suffix.lower() not in (".parquet", ".pq"):
        return None
    try:  # no pre-buffering: the reader then holds about one row group's pages, not a growing cache
        pf = pq.ParquetFile(path, pre_buffer=False, buffer_size=1 << 20)
    except Exception:  # noqa: BLE001  (the whole-file reader gives the message)
        return None
    names = set(pf.schema_arrow.names)
    inc = set(IMU_INCREMENT_COLUMNS) <= names
    if "time" not in names or not (inc or set(IMU_RATE_COLUMNS) <= names) or pf.metadata.num_rows < 2:
        pf.close()
        return None
    md = pf.schema_arrow.metadata or {}
    meta = json.loads(md[_META_KEY]) if _META_KEY in md else {}
    return pf, ["time", *(IMU_INCREMENT_COLUMNS if inc else IMU_RATE_COLUMNS)], inc, meta


def imu_time_span(path) -> tuple[float, float] | None:
    """(first, last) IMU time of an interchange Parquet IMU file, None when the file is not one.

    From the ``time`` column's statistics in the file's metadata (the minimum of the first row group,
    the maximum of the last): no data page is read, so nothing is decompressed (the whole ``time`` column
    of a one-row-group log would be). On a log whose time increases (:func:`iter_imu` checks it) these are
    its first and last stamps. Without statistics the first and last row groups' ``time`` are read."""
    got = _parquet_imu(Path(path))
    if got is None:
        return None
    pf = got[0]
    with pf:
        md, j = pf.metadata, pf.schema.names.index("time")
        first = md.row_group(0).column(j).statistics
        last = md.row_group(md.num_row_groups - 1).column(j).statistics
        if all(s is not None and s.has_min_max and s.physical_type in ("DOUBLE", "FLOAT")
               and s.logical_type.type == "NONE" for s in (first, last)):
            return float(first.min), float(last.max)
        a = pf.read_row_group(0, columns=["time"]).column(0)
        b = pf.read_row_group(pf.num_row_groups - 1, columns=["time"]).column(0)
        return float(a[0].as_py()), float(b[len(b) - 1].as_py())


def iter_imu(path, chunk_rows: int = 1 << 16, reader=None):
    """IMU samples of ``path`` as consecutive :class:`ImuData` chunks of about ``chunk_rows`` samples
    (``t0`` of each: the time of the sample before it). Interchange Parquet is read in batches; any
    other file is read whole by ``reader`` (default :func:`aidnav.io.formats.read_imu`) and cut."""
    path = Path(path)
    got = _parquet_imu(path)
    if got is None:
        if reader is None:
            from aidnav.io.formats import read_imu as reader
        imu = reader(path)
        for a in range(0, len(imu), chunk_rows):
            b = min(a + chunk_rows, len(imu))
            t0 = imu.t0 if a == 0 else float(imu.time[a - 1])
            yield ImuData(imu.time[a:b], imu.dtheta[a:b], imu.dv[a:b], t0=t0, week=imu.week,
                          events=imu.events if a == 0 else [])
        return
    from aidnav.io._arrow import column_to_f64

    pf, cols, inc, meta = got
    week = meta.get("gps_week")
    t_prev, row, events = None, 0, [f"{path.name}: IMU format interchange (detected)"]
    if not inc:
        events.append("rates converted to increments (rate × Δt over (t_{k-1}, t_k])")
    with pf:
        for batch in pf.iter_batches(batch_size=chunk_rows, columns=cols, use_threads=False):
            a = np.column_stack([column_to_f64(batch.column(i)) for i in range(len(cols))])  # no pandas
            for j, c in enumerate(cols):  # the checks and messages of io._table, chunk by chunk
                bad = ~np.isfinite(a[:, j])
                if bad.any():
                    i = int(np.argmax(bad))
                    v = a[i, j]
                    what = "missing value or NaN" if np.isnan(v) else v
                    raise DataError(path, row + i + 1, f"column {c}: {what} (values must be finite numbers)")
            t = a[:, 0].copy()
            tt = t if t_prev is None else np.concatenate([[t_prev], t])
            d = np.diff(tt)
            if not (d > 0).all():
                i = int(np.argmax(~(d > 0))) + 1  # index in tt
                kind = "duplicate time" if d[i - 1] == 0 else "time goes backwards"
                r = row + i - (0 if t_prev is None else 1)  # 0-based row of the sample
                raise DataError(path, r + 1, f"time not strictly increasing ({kind}): {tt[i]!r} s after "
                                f"{tt[i - 1]!r} s at line {r}")
            if t_prev is None:
                t0 = meta.get("t0_s")
                t0 = None if t0 is None or not t0 < t[0] else float(t0)
                if t0 is None and not inc:
                    t0 = float(t[0] - (t[1] - t[0]))
            else:
                t0 = t_prev
            dth, dv = np.ascontiguousarray(a[:, 1:4]), np.ascontiguousarray(a[:, 4:7])
            if not inc:
                dt = np.diff(np.concatenate([[t0], t]))[:, None]
                dth *= dt
                dv *= dt
            yield ImuData(t, dth, dv, t0=t0, events=events if t_prev is None else [],
                          week=None if week is None else int(week))
            t_prev, row = float(t[-1]), row + len(t)


class TrajectoryWriter:
    """A trajectory file (``.parquet``/``.pq`` or ``.csv``) written piece by piece: ``write(traj)`` each
    piece in time order, then ``close()``; columns as :func:`aidnav.io.interchange.write_trajectory`."""

    def __init__(self, path, week: int | None = None):
        self.path, self.week = Path(path), week
        self.part = self.path.with_name(self.path.name + ".part")
        self.kind = "csv" if self.path.suffix.lower() == ".csv" else "parquet"
        self.w = self.f = None
        self.path.parent.mkdir(parents=True, exist_ok=True)

    def write(self, traj) -> None:
        import pyarrow as pa

        from aidnav.io._arrow import f64_to_arrow
        from aidnav.io.interchange import trajectory_columns

        cols = trajectory_columns(traj, week=self.week)
        arrays = [pa.array(v, type=pa.string()) if np.asarray(v).dtype.kind in "USO" else f64_to_arrow(v)
                  for v in cols.values()]
        tbl = pa.Table.from_arrays(arrays, names=list(cols))
        if self.w is None:
            self._open(tbl.schema)
        self.w.write_table(tbl)

    def _open(self, schema):
        from aidnav.io._table import _META_KEY

        week = self.week
        if self.kind == "parquet":
            import pyarrow.parquet as pq

            md = dict(schema.metadata or {})
            md[_META_KEY] = json.dumps({} if week is None else {"gps_week": int(week)}).encode()
            # no dictionary pages: float columns never repeat (4 times faster to write, smaller)
            self.w = pq.ParquetWriter(self.part, schema.with_metadata(md), use_dictionary=False)
        else:
            import pyarrow.csv as pacsv

            self.f = open(self.part, "wb")
            wk = "" if week is None else f"; time = GPS seconds of week {int(week)}, utc = UTC (ISO 8601)"
            self.f.write(("# aidnav trajectory; time [s], lat/lon [deg], height [m] ellipsoidal, velocity "
                          "ENU [m/s], roll/pitch/heading [deg] (heading clockwise from North); std_e_m/"
                          "std_n_m/std_u_m [m]" + wk + "\n").encode())
            self.w = pacsv.CSVWriter(self.f, schema, write_options=pacsv.WriteOptions(quoting_style="none"))

    def close(self) -> Path:
        if self.w is not None:
            self.w.close()
        if self.f is not None:
            self.f.close()
        os.replace(self.part, self.path)
        return self.path

    def abort(self) -> None:
        for x in (self.w, self.f):
            if x is not None:
                try:
                    x.close()
                except Exception:  # noqa: BLE001
                    pass
        if self.part.exists():
            self.part.unlink()
