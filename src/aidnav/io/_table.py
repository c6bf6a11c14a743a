"""The table layer of the interchange files: CSV (``,``/``;``/tab, ``#`` comment lines before one header,
UTF-8 BOM, quoted names) and Parquet read into float64 columns with their comments/metadata, and the
checks every reader shares (missing columns, NaN/inf, strictly increasing time), each failure naming
the file, the line (for Parquet the 1-based row) and the problem. Used by :mod:`aidnav.io.interchange`.
"""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from aidnav.io._arrow import column_to_f64, f64_to_arrow
from aidnav.io.atomic import replacing
from aidnav.io.errors import DataError

TEXT_COLUMNS = ("utc",)  #: columns of text (not read as data): ISO UTC time (Parquet: a UTC timestamp)

#: unit and frame of the interchange columns, written as Parquet field metadata (``unit``, ``frame``);
#: a column not listed here takes its unit from its name's suffix (:func:`column_unit`)
COLUMN_META = {
    "time": ("s", "GPS seconds of week where gps_week is given (else the input's time scale)"),
    "gps_week": ("week", "GPS week of the epoch"),
    "utc": ("UTC", "UTC instant (leap seconds applied), timestamp[us, UTC]"),
    "lat_deg": ("deg", "WGS-84 geodetic latitude"), "lon_deg": ("deg", "WGS-84 longitude"),
    "height_m": ("m", "WGS-84 ellipsoidal height"),
    "ve": ("m/s", "ENU east"), "vn": ("m/s", "ENU north"), "vu": ("m/s", "ENU up"),
    "roll_deg": ("deg", "body RFU w.r.t. local ENU (docs/conventions.md)"),
    "pitch_deg": ("deg", "body RFU w.r.t. local ENU (docs/conventions.md)"),
    "heading_deg": ("deg", "clockwise from north, [0, 360)"),
    "std_e_m": ("m", "1σ ENU east"), "std_n_m": ("m", "1σ ENU north"), "std_u_m": ("m", "1σ ENU up"),
    "std_ve": ("m/s", "1σ ENU east"), "std_vn": ("m/s", "1σ ENU north"), "std_vu": ("m/s", "1σ ENU up"),
    "std_roll_deg": ("deg", "1σ roll"), "std_pitch_deg": ("deg", "1σ pitch"),
    "std_heading_deg": ("deg", "1σ heading"),
    "quality": ("-", "RTKLIB Q: 1 fixed, 2 float, 3 SBAS, 4 DGPS, 5 single, 6 PPP"),
    **{f"gyro_{a}_rad_s": ("rad/s", "body RFU") for a in "xyz"},
    **{f"accel_{a}_m_s2": ("m/s^2", "body RFU") for a in "xyz"},
    **{f"dtheta_{a}_rad": ("rad", "body RFU") for a in "xyz"},
    **{f"dv_{a}_m_s": ("m/s", "body RFU") for a in "xyz"},
}
_SUFFIX_UNITS = (("_deg_sqrt_h", "deg/sqrt(h)"), ("_deg_h", "deg/h"), ("_deg_s", "deg/s"), ("_ug", "ug"),
                 ("_ppm", "ppm"), ("_m_s2", "m/s^2"), ("_rad_s", "rad/s"), ("_m_s", "m/s"), ("_deg", "deg"),
                 ("_rad", "rad"), ("_m", "m"), ("_s", "s"))


def column_unit(name: str) -> tuple[str, str]:
    """(unit, frame) of an interchange column: :data:`COLUMN_META`, else the unit its name ends with
    (``gyro_bias_x_deg_h`` → deg/h, body RFU for ``_x/_y/_z`` axes), else ("", "")."""
    if name in COLUMN_META:
        return COLUMN_META[name]
    for suf, unit in _SUFFIX_UNITS:
        if name.endswith(suf):
            stem = name[: -len(suf)]
            frame = "body RFU" if stem.endswith(("_x", "_y", "_z")) else ""
            return unit, frame
    return "", ""


def arrow_table(cols: dict, parquet: bool = True) -> pa.Table:
    """Named 1-D columns as an Arrow table; for Parquet each field carries ``unit`` and ``frame``
    metadata (:func:`column_unit`) and ``utc`` (ISO 8601 text) becomes a timestamp[us, UTC] column."""
    fields, arrays = [], []
    for n, v in cols.items():
        v = np.asarray(v)
        if v.dtype.kind in "USO":
            if parquet and n == "utc":
                us = np.array([str(x).rstrip("Z") for x in v], dtype="datetime64[us]")
                arr = pa.array(us, type=pa.timestamp("us", tz="UTC"))
            else:
                arr = pa.array([str(x) for x in v], type=pa.string())
        else:
            arr = f64_to_arrow(v)
        unit, frame = column_unit(n)
        md = {b"unit": unit.encode(), b"frame": frame.encode()} if parquet and (unit or frame) else None
        fields.append(pa.field(n, arr.type, metadata=md))
        arrays.append(arr)
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields))


META_KEY = b"aidnav"
T0_RE = re.compile(r"^#\s*t0_s\s*[=:]\s*(\S+)")
WEEK_RE = re.compile(r"^#\s*gps_week\s*[=:]\s*(\d+)\s*$")
_CSV_EXT = (".csv",)
_PARQUET_EXT = (".parquet", ".pq")


# ============================================================================================ tables
class InterchangeTable:
    """Numeric columns of a file with the map from row index to file line (for messages)."""

    def __init__(self, path: Path, cols: dict[str, np.ndarray], first_line: int, kind: str,
                 meta: dict | None = None):
        self.path = path
        self.cols = cols
        self.first_line = first_line  # file line (CSV) or row number (Parquet) of row 0
        self.kind = kind
        self.meta = meta or {}

    def line(self, i: int) -> int:
        return self.first_line + int(i)

    def __len__(self) -> int:
        return len(next(iter(self.cols.values()))) if self.cols else 0

    def fail(self, i: int | None, problem: str):
        raise DataError(self.path, None if i is None else self.line(i), problem)

    def require(self, names: list[str], what: str):
        missing = [c for c in names if c not in self.cols]
        if missing:
            raise DataError(self.path, self.first_line - 1 if self.kind == "csv" else None,
                            f"missing {what} column(s): {', '.join(missing)} "
                            f"(have: {', '.join(self.cols) or 'none'})")

    def has_all(self, names: list[str], what: str) -> bool:
        """True if all ``names`` are present, False if none; DataError if only some are."""
        present = [c for c in names if c in self.cols]
        if not present:
            return False
        if len(present) != len(names):
            self.require(names, what)
        return True

    def finite(self, names: list[str]):
        for c in names:
            bad = ~np.isfinite(self.cols[c])
            if bad.any():
                i = int(np.argmax(bad))
                v = self.cols[c][i]
                self.fail(i, f"column {c}: {'missing value or NaN' if np.isnan(v) else v} "
                             "(values must be finite numbers)")

    def increasing_time(self):
        t = self.cols["time"]
        d = np.diff(t)
        bad = ~(d > 0)
        if bad.any():
            i = int(np.argmax(bad)) + 1
            kind = "duplicate time" if d[i - 1] == 0 else "time goes backwards"
            self.fail(i, f"time not strictly increasing ({kind}): {float(t[i])!r} s after "
                         f"{float(t[i - 1])!r} s at line {self.line(i - 1)}")

    def get(self, names: list[str]) -> np.ndarray:
        return np.column_stack([self.cols[c] for c in names])


def _kind(path: Path) -> str:
    name = path.name.lower()
    if name.endswith(_CSV_EXT):
        return "csv"
    if name.endswith(_PARQUET_EXT):
        return "parquet"
    raise DataError(path, None, f"unknown file type '{path.suffix}' (use .csv or .parquet)")


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as e:
        raise DataError(path, None, f"cannot read file: {e.strerror or e}") from None


def _line_stats(body: bytes):
    """Per line of ``body``: start, end (excluding the newline), comma count, non-blank flag."""
    a = np.frombuffer(body, dtype=np.uint8)
    nl = np.flatnonzero(a == 10)
    ends = nl if (len(a) and a[-1] == 10) else np.append(nl, len(a))
    starts = np.concatenate([[0], nl + 1])[: len(ends)]
    nlines = len(ends)
    # line index of every comma / blank character (searchsorted over the newline positions)
    commas = np.bincount(np.searchsorted(nl, np.flatnonzero(a == 44)), minlength=nlines)[:nlines]
    blank_pos = np.flatnonzero((a == 32) | (a == 9) | (a == 13))
    nblank = np.bincount(np.searchsorted(nl, blank_pos), minlength=nlines)[:nlines]
    nonblank = (ends - starts - nblank) > 0
    return starts, ends, commas, nonblank


_DELIM_NAMES = {",": "','", ";": "';'", "\t": "tabs"}


def csv_delimiter(path: Path, header: str, line: int) -> str:
    """The field separator of a CSV file from its header line: ',' or else ';' or a tab."""
    for d in (",", ";", "\t"):
        if d in header:
            return d
    if len(header.split()) > 1:
        raise DataError(path, line, "header columns separated by spaces: separate them with ',' "
                                    "(';' and tabs are also read)")
    return ","


def _read_csv(path: Path) -> InterchangeTable:
    raw = _read_bytes(path)
    if raw.startswith(b"\xef\xbb\xbf"):  # UTF-8 byte-order mark (spreadsheet exports)
        raw = raw[3:]
    # comment lines and the header
    pos, line_no, comments = 0, 0, []
    header = None
    while pos < len(raw):
        nxt = raw.find(b"\n", pos)
        nxt = len(raw) if nxt < 0 else nxt
        text = raw[pos:nxt].decode("utf-8", errors="replace").strip()
        line_no += 1
        pos = nxt + 1
        if text.startswith("#"):
            comments.append(text)
            continue
        if not text:
            continue
        header = text
        break
    if header is None:
        raise DataError(path, None, "empty file (no header line)")
    header_line = line_no
    delim = csv_delimiter(path, header, header_line)
    names = [h.strip().strip('"').strip() for h in header.split(delim)]
    if any(not n for n in names):
        raise DataError(path, header_line, f"empty column name in the header: {header!r}")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise DataError(path, header_line, f"duplicate column(s) in the header: {', '.join(dup)}")
    body = raw[min(pos, len(raw)):]
    if delim != ",":
        if b"," in body:
            k = body.find(b",")
            ln = header_line + 1 + body.count(b"\n", 0, k)
            raise DataError(path, ln, f"a ',' in a file whose header is separated by {_DELIM_NAMES[delim]}: "
                                      "decimal commas are not supported (write 1.5, not 1,5)")
        body = body.replace(delim.encode(), b",")
    starts, ends, commas, nonblank = _line_stats(body)
    # drop trailing blank lines
    keep = len(ends)
    while keep > 0 and not nonblank[keep - 1]:
        keep -= 1
    if keep == 0:
        raise DataError(path, header_line, "no data lines after the header")
    commas, nonblank = commas[:keep], nonblank[:keep]
    first = header_line + 1
    if not nonblank.all():
        i = int(np.argmin(nonblank))
        raise DataError(path, first + i, "blank line inside the data")
    bad = commas != len(names) - 1
    if bad.any():
        i = int(np.argmax(bad))
        raise DataError(path, first + i, f"wrong number of fields: {commas[i] + 1} "
                                         f"(the header has {len(names)})")
    body = body[: ends[keep - 1]]
    ropts = pacsv.ReadOptions(column_names=names, use_threads=True)
    copts = pacsv.ConvertOptions(column_types={n: (pa.string() if n in TEXT_COLUMNS else pa.float64())
                                               for n in names})
    names = [n for n in names if n not in TEXT_COLUMNS]  # text columns (utc) are not data
    try:
        tbl = pacsv.read_csv(io.BytesIO(body), read_options=ropts, convert_options=copts)
        cols = {n: column_to_f64(tbl.column(n)) for n in names}
    except pa.ArrowInvalid:
        sopts = pacsv.ConvertOptions(column_types={n: pa.string() for n in ropts.column_names},
                                     strings_can_be_null=False)
        tbl = pacsv.read_csv(io.BytesIO(body), read_options=ropts, convert_options=sopts)
        cols = {}
        for n in names:
            # lazy: pandas is heavy to import
            import pandas as pd  # only for columns that are not plain numbers

            s = pd.Series(tbl.column(n).to_numpy(zero_copy_only=False), dtype=object).str.strip()
            num = pd.to_numeric(s, errors="coerce").to_numpy(dtype=float)
            lit_nan = s.str.lower().isin(["nan", "+nan", "-nan"]).to_numpy()
            badv = np.isnan(num) & ~lit_nan & (s != "").to_numpy()
            if badv.any():
                i = int(np.argmax(badv))
                raise DataError(path, first + i, f"column {n}: non-numeric value {s.iloc[i]!r}") from None
            cols[n] = num
    meta = {}
    for c in comments:
        m = T0_RE.match(c)
        if m:
            try:
                meta["t0_s"] = float(m.group(1))
            except ValueError:
                pass
        m = WEEK_RE.match(c)
        if m:
            meta["gps_week"] = int(m.group(1))
    return InterchangeTable(path, cols, first, "csv", meta)


def _read_parquet(path: Path, copy: bool = True) -> InterchangeTable:
    try:
        # ParquetFile.read, not pq.read_table: the latter goes through pyarrow.dataset, which imports
        # pandas, and returns one chunk per row group (3x slower on a 10-h IMU log)
        with pq.ParquetFile(path) as pf:
            tbl = pf.read()
    except (OSError, pa.ArrowException) as e:
        raise DataError(path, None, f"cannot read Parquet file: {e}") from None
    if tbl.num_rows == 0:
        raise DataError(path, None, "empty file (no rows)")
    cols = {}
    for n in tbl.column_names:
        if n in TEXT_COLUMNS:
            continue
        col = tbl.column(n)
        if pa.types.is_integer(col.type) or pa.types.is_floating(col.type):
            cols[n] = column_to_f64(col, copy=copy)
        else:
            # lazy: pandas is heavy to import
            import pandas as pd  # only for columns that are not plain numbers

            s = pd.Series(col.to_numpy(zero_copy_only=False), dtype=object)
            num = pd.to_numeric(s, errors="coerce").to_numpy(dtype=float)
            badv = np.isnan(num) & s.notna().to_numpy()
            if badv.any():
                i = int(np.argmax(badv))
                raise DataError(path, i + 1, f"column {n}: non-numeric value {s.iloc[i]!r}")
            cols[n] = num
    meta = {}
    md = tbl.schema.metadata or {}
    if META_KEY in md:
        try:
            meta = json.loads(md[META_KEY])
        except ValueError:
            meta = {}
    return InterchangeTable(path, cols, 1, "parquet", meta)


def read_table(path) -> tuple[dict[str, np.ndarray], dict]:
    """Numeric columns of an interchange CSV/Parquet file as float arrays, plus its metadata.

    Checks the file structure only (fields per line, numeric values); the typed readers check columns.
    """
    t = open_table(path)
    return t.cols, t.meta


def open_table(path, copy: bool = True) -> InterchangeTable:
    """The table of a CSV/Parquet file; copy=False: Parquet float64 columns may be read-only views of the
    Arrow buffers (for a reader that copies what it keeps: one pass less over a large file)."""
    path = Path(path)
    return _read_csv(path) if _kind(path) == "csv" else _read_parquet(path, copy=copy)


def write_table_file(cols: dict, path, comments: list[str], meta: dict) -> Path:
    """Write named 1-D columns: CSV via pandas (floats as repr, exact round trip) or Parquet via pyarrow
    (no pandas on that path: it is the fast one)."""
    path = Path(path)
    kind = _kind(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with replacing(path) as tmp:  # under PATH.part until complete (issue 37)
        if kind == "csv":
            import pandas as pd  # lazy: pandas is heavy to import

            with open(tmp, "w", encoding="utf-8", newline="") as f:
                for c in comments:
                    f.write(f"# {c}\n")
                pd.DataFrame(cols).to_csv(f, index=False, lineterminator="\n")  # shortest exact round trip
        else:
            tbl = arrow_table(cols)  # units per field, utc a timestamp (issue 38)
            md = dict(tbl.schema.metadata or {})
            md[META_KEY] = json.dumps(meta).encode()
            pq.write_table(tbl.replace_schema_metadata(md), tmp)
    return path


# =============================================================================================== IMU
