"""Interchange files chunk by chunk (issue 29): IMU increments and trajectories read in batches (Parquet
row groups; trajectory CSV through pyarrow's streaming reader), trajectories and tables written in pieces
(Parquet row groups, CSV through pyarrow's writer), rows spooled to disk, so memory does not grow with the
log.

:func:`iter_imu` yields :class:`aidnav.data.ImuData` chunks with exactly what :func:`.interchange.read_imu`
gives on the whole file (the same checks, row numbers in the messages); other formats and CSV are read
whole and then cut into chunks. :class:`TrajectoryWriter` writes the columns of
:func:`.interchange.trajectory_columns` piece by piece; the file appears under its name only when
closed (``abort`` removes the partial one). :func:`trajectory_chunks` gives the pieces of a trajectory
file (:func:`.interchange.read_trajectory`'s numbers, checks and messages; other formats read whole by
the caller and cut by :class:`TrajectoryChunks`); :class:`CsvColumnsWriter` writes named columns;
:class:`Spool` keeps float64 rows in a temporary file and reads them back in chunks, as often as needed;
:class:`Background` runs a consumer of pieces (converting and writing them) in one background thread.
"""

from __future__ import annotations

import json
import os
import queue
import tempfile
import threading
from pathlib import Path

import numpy as np

from aidnav.data import ImuData, Trajectory
from aidnav.io.errors import DataError

__all__ = ["iter_imu", "TrajectoryWriter", "imu_time_span", "trajectory_chunks", "TrajectoryChunks",
           "CsvColumnsWriter", "Spool", "take_rows", "concat_rows", "Background"]

# the largest block of a trajectory CSV read in batches (Arrow holds up to 32 of them: _FileChunks)
CSV_BLOCK_BYTES = 1 << 20
# the read buffer of each column of an IMU Parquet file (:func:`iter_imu`): Arrow's reader holds, per
# column, the buffer, the dictionary page and the page it decodes; W1's 7 columns (one row group, ≈ 1 MB
# pages) 21.3 MiB of Arrow pool with 1 MiB, 15.0 MiB with 64 kiB (issue 41, session 10)
IMU_READ_BUFFER = 1 << 16


def _parquet_imu(path: Path):
    """(ParquetFile, columns used, increments?, metadata dict) of an interchange IMU Parquet file, or None
    when it is not one (another reader takes it)."""
    import pyarrow.parquet as pq  # lazy: pyarrow is heavy to import

    from aidnav.io._table import META_KEY  # lazy: pulls in pyarrow
    from aidnav.io.interchange import IMU_INCREMENT_COLUMNS, IMU_RATE_COLUMNS  # lazy: pulls in numba, pyarrow

    if path.suffix.lower() not in (".parquet", ".pq"):
        return None
    try:  # no pre-buffering: the reader then holds about one row group's pages, not a growing cache
        pf = pq.ParquetFile(path, pre_buffer=False, buffer_size=IMU_READ_BUFFER)
    except Exception:  # noqa: BLE001  (the whole-file reader gives the message)
        return None
    names = set(pf.schema_arrow.names)
    inc = set(IMU_INCREMENT_COLUMNS) <= names
    if "time" not in names or not (inc or set(IMU_RATE_COLUMNS) <= names) or pf.metadata.num_rows < 2:
        pf.close()
        return None
    _numeric_time(path, pf.schema_arrow.field("time").type, pf)
    md = pf.schema_arrow.metadata or {}
    meta = json.loads(md[META_KEY]) if META_KEY in md else {}
    return pf, ["time", *(IMU_INCREMENT_COLUMNS if inc else IMU_RATE_COLUMNS)], inc, meta


def _numeric_time(path, typ, pf=None) -> None:
    """The interchange ``time`` column is a number of seconds: a timestamp, date or string column is
    refused naming the column and what to write instead."""
    import pyarrow as pa  # lazy: pyarrow is heavy to import

    if pa.types.is_integer(typ) or pa.types.is_floating(typ):
        return
    if pf is not None:
        pf.close()
    what = ("a timestamp (date and time)" if pa.types.is_timestamp(typ) or pa.types.is_date(typ)
            else f"of type {typ}")
    raise DataError(path, None, f"column time is {what}: the interchange time column is a number of seconds "
                    "(GPS seconds of week, or any seconds on the GNSS time scale) — convert it, e.g. "
                    "(t − start of the GPS week) in seconds as float64")


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
            from aidnav.io.formats import read_imu as reader  # lazy: pulls in numba
        imu = reader(path)
        for a in range(0, len(imu), chunk_rows):
            b = min(a + chunk_rows, len(imu))
            t0 = imu.t0 if a == 0 else float(imu.time[a - 1])
            yield ImuData(imu.time[a:b], imu.dtheta[a:b], imu.dv[a:b], t0=t0, week=imu.week,
                          events=imu.events if a == 0 else [])
        return
    from aidnav.io._arrow import column_to_f64  # lazy: pulls in pyarrow
    from aidnav.io.interchange import IMU_RATE_COLUMNS  # lazy: pulls in numba, pyarrow

    pf, cols, inc, meta = got
    week = meta.get("gps_week")
    t_prev, row, events = None, 0, [f"{path.name}: IMU format interchange (detected)"]
    if inc and set(IMU_RATE_COLUMNS) <= set(pf.schema_arrow.names):
        events.append("file has both rate and increment columns; the increments were used")
    if not inc:
        events.append("rates converted to increments (rate × Δt over (t_{k-1}, t_k])")
    with pf:
        for batch in pf.iter_batches(batch_size=chunk_rows, columns=cols, use_threads=False):
            # read-only views of the batch's buffers where they are plain float64 (no pandas, no copy):
            # each column is copied once, into the chunk's arrays
            v = [column_to_f64(batch.column(i), copy=False) for i in range(len(cols))]
            for j, c in enumerate(cols):  # the checks and messages of io._table, chunk by chunk
                bad = ~np.isfinite(v[j])
                if bad.any():
                    i = int(np.argmax(bad))
                    x = v[j][i]
                    what = "missing value or NaN" if np.isnan(x) else x
                    raise DataError(path, row + i + 1, f"column {c}: {what} (values must be finite numbers)")
            t = np.array(v[0], dtype=np.float64)
            tt = t if t_prev is None else np.concatenate([[t_prev], t])
            d = np.diff(tt)
            if not (d > 0).all():
                i = int(np.argmax(~(d > 0))) + 1  # index in tt
                kind = "duplicate time" if d[i - 1] == 0 else "time goes backwards"
                r = row + i - (0 if t_prev is None else 1)  # 0-based row of the sample
                raise DataError(path, r + 1, f"time not strictly increasing ({kind}): "
                                f"{float(tt[i])!r} s after {float(tt[i - 1])!r} s at line {r}")
            if t_prev is None:
                t0 = meta.get("t0_s")
                t0 = None if t0 is None or not t0 < t[0] else float(t0)
                if t0 is None and not inc:
                    t0 = float(t[0] - (t[1] - t[0]))
            else:
                t0 = t_prev
            dth, dv = np.empty((len(t), 3)), np.empty((len(t), 3))
            for j in range(3):
                dth[:, j] = v[1 + j]
                dv[:, j] = v[4 + j]
            if not inc:
                dt = np.diff(np.concatenate([[t0], t]))[:, None]
                dth *= dt
                dv *= dt
            yield ImuData(t, dth, dv, t0=t0, events=events if t_prev is None else [],
                          week=None if week is None else int(week))
            t_prev, row = float(t[-1]), row + len(t)


def _discard(part: Path, *files) -> None:
    """Abandon a file being written: close ``files`` (a writer, then its file; None where not opened yet),
    ignoring their errors, and remove the partial file ``part``."""
    for x in files:
        if x is not None:
            try:
                x.close()
            except Exception:  # noqa: BLE001  (the file is abandoned: its error does not matter)
                pass
    part.unlink(missing_ok=True)


class TrajectoryWriter:
    """A trajectory file (``.parquet``/``.pq`` or ``.csv``) written piece by piece: ``write(traj)`` each
    piece in time order, then ``close()``; columns as :func:`aidnav.io.interchange.write_trajectory`.

    Parquet: each piece is a row group, or with ``row_group_rows`` the pieces are held (as Arrow columns)
    until they have at least that many rows and written as one row group: the writer keeps the metadata
    of every row group until the file is closed (≈ 24 kB for the 28 columns of a trajectory), so small
    row groups would make its memory grow with the log."""

    def __init__(self, path, week: int | None = None, row_group_rows: int | None = None):
        self.path, self.week = Path(path), week
        self.part = self.path.with_name(self.path.name + ".part")
        self.kind = "csv" if self.path.suffix.lower() == ".csv" else "parquet"
        self.w = self.f = None
        self.rg, self.held, self.n_held = row_group_rows if self.kind == "parquet" else None, [], 0
        self.path.parent.mkdir(parents=True, exist_ok=True)

    def write(self, traj) -> None:
        from aidnav.io._table import arrow_table  # lazy: pyarrow is heavy to import
        from aidnav.io.interchange import trajectory_columns  # lazy: pulls in pyarrow

        cols = trajectory_columns(traj, week=self.week)
        tbl = arrow_table(cols, parquet=self.kind == "parquet")  # units per field, utc a timestamp
        if self.w is None:
            self.open_table(tbl.schema)
        if not self.rg:
            self.w.write_table(tbl)
            return
        self.held.append(tbl)
        self.n_held += tbl.num_rows
        if self.n_held >= self.rg:
            self._flush()

    def _flush(self) -> None:
        """The pieces held, as one row group."""
        import pyarrow as pa  # lazy: pyarrow is heavy to import

        if self.held:
            tbl = self.held[0] if len(self.held) == 1 else pa.concat_tables(self.held)
            self.held, self.n_held = [], 0
            self.w.write_table(tbl, row_group_size=max(1, tbl.num_rows))

    def open_table(self, schema):
        from aidnav.io._table import META_KEY  # lazy: pulls in pyarrow

        week = self.week
        if self.kind == "parquet":
            import pyarrow.parquet as pq  # lazy: pyarrow is heavy to import

            md = dict(schema.metadata or {})
            md[META_KEY] = json.dumps({} if week is None else {"gps_week": int(week)}).encode()
            # no dictionary pages: float columns never repeat (4 times faster to write, smaller)
            self.w = pq.ParquetWriter(self.part, schema.with_metadata(md), use_dictionary=False)
        else:
            import pyarrow.csv as pacsv  # lazy: pyarrow is heavy to import

            self.f = open(self.part, "wb")
            wk = "" if week is None else f"; time = GPS seconds of week {int(week)}, utc = UTC (ISO 8601)"
            self.f.write(("# aidnav trajectory; time [s], lat/lon [deg], height [m] ellipsoidal, velocity "
                          "ENU [m/s], roll/pitch/heading [deg] (heading clockwise from North); std_e_m/"
                          "std_n_m/std_u_m [m]" + wk + "\n").encode())
            opts = pacsv.WriteOptions(quoting_style="none", quoting_header="none")
            self.w = pacsv.CSVWriter(self.f, schema, write_options=opts)

    def close(self) -> Path:
        if self.w is not None:
            self._flush()
            self.w.close()
        if self.f is not None:
            self.f.close()
        os.replace(self.part, self.path)
        return self.path

    def abort(self) -> None:
        self.held = []
        _discard(self.part, self.w, self.f)


class Background:
    """``fn(*args, **kw)`` for each ``put(*args, **kw)``, in order, in one background thread, with at most
    ``maxsize`` calls waiting (``put`` blocks until one is done: memory stays bounded). The work overlaps
    the caller's where it releases the GIL (Arrow's encoding, compression and file writes; numpy; numba
    kernels compiled with ``nogil``).

    An exception in ``fn`` is raised in the caller at the next ``put`` or at ``close`` (the calls after
    it are skipped); ``close`` waits for every call; ``abort`` (the caller's error path) skips the calls
    still waiting and waits for the one running, so that what ``fn`` writes to can then be closed."""

    _END = object()

    def __init__(self, fn, maxsize: int = 2):
        self.fn, self.q, self.error, self.stop = fn, queue.Queue(maxsize), None, False
        self.t = threading.Thread(target=self._run, name="aidnav-background", daemon=True)
        self.t.start()

    def _run(self) -> None:
        while (item := self.q.get()) is not self._END:
            if self.error is None and not self.stop:
                try:
                    self.fn(*item[0], **item[1])
                except BaseException as e:  # noqa: BLE001  (raised in the caller)
                    self.error = e

    def _raise(self) -> None:
        if self.error is not None:
            raise self.error

    def put(self, *args, **kw) -> None:
        self._raise()
        self.q.put((args, kw))

    def _end(self) -> None:
        if self.t.is_alive():
            self.q.put(self._END)
            self.t.join()

    def close(self) -> None:
        self._end()
        self._raise()

    def abort(self) -> None:
        self.stop = True
        self._end()


# ================================================================================= trajectory pieces
_TRAJ_FIELDS = ("time", "lat", "lon", "height", "vel", "rph", "std_pos", "std_vel", "std_att")


def take_rows(tr, m):
    """The rows ``m`` (slice, indices or mask) of a :class:`aidnav.data.Trajectory`."""

    def f(x):
        return None if x is None else x[m]

    return Trajectory(*(f(getattr(tr, k)) for k in _TRAJ_FIELDS),
                      extra={k: v[m] for k, v in tr.extra.items()}, week=tr.week)


def concat_rows(parts):
    """The :class:`aidnav.data.Trajectory` of ``parts`` one after the other (same columns)."""

    def c(name):
        xs = [getattr(p, name) for p in parts]
        return None if xs[0] is None else np.concatenate(xs)

    extra = {k: np.concatenate([p.extra[k] for p in parts]) for k in parts[0].extra}
    return Trajectory(*(c(k) for k in _TRAJ_FIELDS), extra=extra, week=parts[0].week)


def _has(a) -> bool:
    return a is not None and np.size(a) > 0 and bool(np.any(np.isfinite(a)))


class TrajectoryChunks:
    """A trajectory as consecutive pieces of about ``chunk_rows`` epochs, as often as iterated.

    ``has`` : {"vel", "rph", "std_pos", "std_vel", "std_att"} → whether the trajectory has finite values
    of it anywhere (a file: whether it has the columns, which the reader requires finite). This class
    cuts a trajectory held whole; :func:`trajectory_chunks` makes the ones that read a file in batches.
    """

    def __init__(self, traj=None, chunk_rows: int = 1 << 15, has: dict | None = None):
        self.traj, self.chunk_rows = traj, int(chunk_rows)
        self.has = has if has is not None else {k: _has(getattr(traj, k)) for k in
                                                ("vel", "rph", "std_pos", "std_vel", "std_att")}

    def _batches(self):
        n = len(self.traj.time)
        for a in range(0, n, self.chunk_rows):
            yield take_rows(self.traj, slice(a, min(a + self.chunk_rows, n)))

    def __iter__(self):
        return self._batches()

    def times(self):
        """The ``time`` column [s], piece by piece."""
        for c in self:
            yield np.asarray(c.time, dtype=float)


class _FileChunks(TrajectoryChunks):
    """An interchange trajectory file (CSV or Parquet) read in batches."""

    def __init__(self, path: Path, names: list[str], kind: str, csv_head, meta: dict, chunk_rows: int,
                 height_offset_m: float):
        # lazy: pulls in numba, pyarrow
        from aidnav.io.interchange import (
            GNSS_STD_POS_COLUMNS,
            OLD_STD_ATT,
            OLD_STD_VEL,
            STD_ATT_COLUMNS,
            STD_VEL_COLUMNS,
            TRAJ_STD_POS,
        )

        have = set(names)

        def has(*sets):
            return any(set(x) <= have for x in sets)

        super().__init__(None, chunk_rows, {"vel": True, "rph": True,
                                            "std_pos": has(TRAJ_STD_POS, GNSS_STD_POS_COLUMNS),
                                            "std_vel": has(STD_VEL_COLUMNS, OLD_STD_VEL),
                                            "std_att": has(STD_ATT_COLUMNS, OLD_STD_ATT)})
        self.path, self.names, self.kind, self.csv_head, self.meta = path, names, kind, csv_head, meta
        self.offset = float(height_offset_m)

    def _tables(self, columns=None):
        """(row of the first record, {name: float64 column}) per batch; a CSV the streaming reader cannot
        parse is read whole by the file reader (which names the problem, or reads what is left)."""
        from aidnav.io._arrow import column_to_f64  # lazy: pulls in pyarrow
        from aidnav.io._table import TEXT_COLUMNS  # lazy: pulls in pyarrow

        cols = [c for c in (columns or self.names) if c not in TEXT_COLUMNS]
        row, held, n_held = 0, [], 0  # rows yielded; batches held for the next piece (CSV: small blocks)
        try:
            for b in self._arrow_batches(cols):
                if held and n_held + b.num_rows > self.chunk_rows:
                    yield row, _joined(held, cols)
                    row, held, n_held = row + n_held, [], 0
                held.append({c: column_to_f64(b.column(c)) for c in cols})
                n_held += b.num_rows
            if held:
                yield row, _joined(held, cols)
        except DataError:
            raise
        except Exception:  # noqa: BLE001  (the whole-file reader gives the message or the values)
            from aidnav.io._table import open_table  # lazy: pulls in pyarrow

            t = open_table(self.path)
            n = len(t)
            for a in range(row, n, self.chunk_rows):
                yield a, {c: t.cols[c][a:a + self.chunk_rows] for c in cols if c in t.cols}

    def _arrow_batches(self, cols):
        if self.kind == "parquet":
            import pyarrow.parquet as pq  # lazy: pyarrow is heavy to import

            with pq.ParquetFile(self.path, pre_buffer=False, buffer_size=1 << 20) as pf:
                for b in pf.iter_batches(batch_size=self.chunk_rows, columns=cols, use_threads=False):
                    if not all(_numeric(b.schema.field(c).type) for c in cols):
                        raise ValueError("non-numeric column")
                    yield b
            return
        import pyarrow as pa  # lazy: pyarrow is heavy to import
        import pyarrow.csv as pacsv  # lazy: pyarrow is heavy to import

        skip, delim, line_len = self.csv_head
        # Arrow's streaming reader reads up to 32 blocks ahead of its consumer (its background read-ahead
        # queue): a block of a piece's size (32,768 rows, ≈ 12 MiB) held up to ≈ 390 MiB, or the whole
        # file when shorter. Blocks of at most CSV_BLOCK_BYTES bound that (≈ 35 MiB of Arrow pool at
        # 1 MiB, 1 h or 3 h alike); _tables joins the small batches into pieces of about chunk_rows.
        ro = pacsv.ReadOptions(skip_rows=skip, column_names=self.names, use_threads=True,
                               block_size=min(CSV_BLOCK_BYTES, max(1 << 16, int(self.chunk_rows * line_len))))
        po = pacsv.ParseOptions(delimiter=delim, ignore_empty_lines=False)
        co = pacsv.ConvertOptions(column_types={n: pa.float64() for n in cols}, include_columns=cols)
        with pacsv.open_csv(self.path, read_options=ro, parse_options=po, convert_options=co) as r:
            for b in r:
                if any(b.column(i).null_count for i in range(b.num_columns)):  # empty field or line
                    raise ValueError("empty field")
                yield b

    def __iter__(self):
        from aidnav.io._table import InterchangeTable  # lazy: pulls in pyarrow
        from aidnav.io.interchange import trajectory_from_table  # lazy: pulls in numba, pyarrow

        first = 1 if self.kind == "parquet" else self.csv_head[0] + 1
        last_t = None
        for row, d in self._tables():
            t = InterchangeTable(self.path, d, first + row, self.kind, self.meta)
            if last_t is not None and len(t):  # the check of the whole-file reader across batches
                InterchangeTable(self.path, {"time": np.array([last_t, d["time"][0]])}, first + row - 1,
                       self.kind).increasing_time()
            tr = trajectory_from_table(t)
            if self.offset:
                tr.height = tr.height + self.offset
            last_t = float(tr.time[-1])
            yield tr

    def times(self):
        for _, d in self._tables(["time"]):
            yield d["time"]


def _joined(held: list[dict], cols) -> dict:
    """The float64 columns of consecutive batches, one array each."""
    if len(held) == 1:
        return held[0]
    return {c: np.concatenate([h[c] for h in held]) for c in cols}


def _numeric(t) -> bool:
    import pyarrow as pa  # lazy: pyarrow is heavy to import

    return pa.types.is_integer(t) or pa.types.is_floating(t)


def _csv_head(path: Path):
    """(lines before the first record, delimiter, bytes per line) of an interchange CSV file, and its
    header names and comment metadata; None when it has no header."""
    from aidnav.io._table import T0_RE, WEEK_RE, csv_delimiter  # lazy: pulls in pyarrow

    with open(path, "rb") as f:
        head = f.read(1 << 16)
    if head.startswith(b"\xef\xbb\xbf"):
        head = head[3:]
    lines = head.split(b"\n")
    meta, header, k = {}, None, 0
    for i, ln in enumerate(lines[:-1]):
        k = i
        text = ln.decode("utf-8", errors="replace").strip()
        if text.startswith("#"):
            for rx, key, conv in ((T0_RE, "t0_s", float), (WEEK_RE, "gps_week", int)):
                m = rx.match(text)
                if m:
                    try:
                        meta[key] = conv(m.group(1))
                    except ValueError:
                        pass
            continue
        if text:
            header = text
            break
    if header is None:
        return None
    delim = csv_delimiter(path, header, k + 1)
    names = [h.strip().strip('"').strip() for h in header.split(delim)]
    body = lines[k + 1:-1]
    line_len = (sum(len(x) + 1 for x in body) / len(body)) if body else 200.0
    return (k + 1, delim, line_len), names, meta


def trajectory_chunks(path, chunk_rows: int = 1 << 15, height_offset_m: float = 0.0,
                      notes: list[str] | None = None) -> TrajectoryChunks | None:
    """An interchange trajectory file (CSV/Parquet with ``heading_deg``) as :class:`TrajectoryChunks` read in
    batches (``height_offset_m`` added to the heights, as :func:`aidnav.io.formats.read_trajectory_any`;
    ``notes`` gets its note), or None when ``path`` is not one (the caller reads it whole)."""
    path = Path(path)
    try:
        if not path.is_file():
            return None
        suf = path.suffix.lower()
        if suf in (".parquet", ".pq"):
            import pyarrow.parquet as pq  # lazy: pyarrow is heavy to import

            from aidnav.io._table import META_KEY  # lazy: pulls in pyarrow

            with pq.ParquetFile(path) as pf:
                schema, rows = pf.schema_arrow, pf.metadata.num_rows
            names, kind, head = schema.names, "parquet", None
            md = schema.metadata or {}
            meta = json.loads(md[META_KEY]) if META_KEY in md else {}
            if rows == 0:
                return None
        elif suf == ".csv":
            got = _csv_head(path)
            if got is None:
                return None
            head, names, meta = got
            kind = "csv"
        else:
            return None
    except Exception:  # noqa: BLE001  (not readable here: the whole-file reader names the problem)
        return None
    from aidnav.io.interchange import TRAJECTORY_COLUMNS  # lazy: pulls in numba, pyarrow

    if not set(TRAJECTORY_COLUMNS) <= set(names) or len(set(names)) != len(names):
        return None
    if height_offset_m and notes is not None:
        notes.append(f"{path.name}: datum offset {float(height_offset_m):+.3f} m added to every height")
    return _FileChunks(path, list(names), kind, head, meta, chunk_rows, height_offset_m)


class CsvColumnsWriter:
    """A CSV file of named float columns written piece by piece through pyarrow's writer (header line, no
    quotes, NaN as an empty field, floats as their shortest exact decimal), under ``PATH.part`` until
    ``close`` renames it (``abort`` removes it)."""

    def __init__(self, path):
        self.path, self.w, self.f = Path(path), None, None
        self.part = self.path.with_name(self.path.name + ".part")

    def write(self, cols: dict) -> None:
        import pyarrow as pa  # lazy: pyarrow is heavy to import
        import pyarrow.csv as pacsv  # lazy: pyarrow is heavy to import

        arrays = []
        for v in cols.values():  # NaN → null (an empty field), without pa.array (it imports pandas)
            a = np.ascontiguousarray(v, dtype=float)
            ok = ~np.isnan(a)
            valid = None if ok.all() else pa.py_buffer(np.packbits(ok, bitorder="little"))
            arrays.append(pa.Array.from_buffers(pa.float64(), len(a), [valid, pa.py_buffer(a)]))
        tbl = pa.Table.from_arrays(arrays, names=list(cols))
        if self.w is None:
            self.f = open(self.part, "wb")
            opts = pacsv.WriteOptions(quoting_style="none", quoting_header="none")
            self.w = pacsv.CSVWriter(self.f, tbl.schema, write_options=opts)
        self.w.write_table(tbl)

    def close(self) -> Path:
        if self.w is not None:
            self.w.close()
            self.f.close()
            os.replace(self.part, self.path)
        return self.path

    def abort(self) -> None:
        _discard(self.part, self.w, self.f)


class Spool:
    """float64 rows of ``width`` columns in a temporary file (``directory``), read back in chunks of rows
    any number of times (after the last ``write``); ``close`` removes the file."""

    def __init__(self, directory, width: int):
        fd, self.path = tempfile.mkstemp(suffix=".spool", dir=directory)
        self.f, self.width, self.rows = os.fdopen(fd, "wb"), int(width), 0

    def write(self, rows) -> None:
        rows = np.ascontiguousarray(rows, np.float64)
        rows.tofile(self.f)
        self.rows += rows.size // self.width

    def read(self, chunk: int):
        """The rows as (m, width) arrays of at most ``chunk`` rows."""
        if not self.f.closed:
            self.f.close()
        with open(self.path, "rb") as f:
            for a in range(0, self.rows, chunk):
                m = min(chunk, self.rows - a)
                yield np.fromfile(f, np.float64, m * self.width).reshape(m, self.width)

    def read_reverse(self, chunk: int):
        """(first row, rows) of blocks of at most ``chunk`` rows, the last block first."""
        if not self.f.closed:
            self.f.close()
        with open(self.path, "rb") as f:
            for a in reversed(range(0, self.rows, chunk)):
                m = min(chunk, self.rows - a)
                f.seek(a * self.width * 8)
                yield a, np.fromfile(f, np.float64, m * self.width).reshape(m, self.width)

    def close(self) -> None:
        self.f.close()
        if os.path.exists(self.path):
            os.remove(self.path)
