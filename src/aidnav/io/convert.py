"""``aidnav convert IN -o OUT``: any readable IMU or GNSS log → the interchange format (CSV or Parquet).

The output holds what aidnav reads (body RFU increments; ENU, degrees, ellipsoidal heights, GPS seconds
of week) plus its provenance: the source file and format, the time scale and every conversion the
reader made (its events), as ``#`` comment lines (CSV) or the ``aidnav`` metadata key (Parquet). Reading
the output with :func:`aidnav.io.formats.read_imu` / ``read_gnss`` gives the same arrays as reading the
source.
"""

from __future__ import annotations

import inspect
from pathlib import Path

from aidnav.io import formats
from aidnav.io.errors import DataError
from aidnav.io.rosbag import FIX_TYPE, IMU_TYPE, bag_reader

KINDS = ("auto", "imu", "gnss")


def _out_kind(out_path: Path):
    name = out_path.name.lower()
    if not name.endswith((".csv", ".parquet", ".pq")):
        raise DataError(out_path, None, f"output must be .csv or .parquet (got '{out_path.suffix}')")


def detect_kind(path) -> str:
    """"imu" or "gnss" for a log of either kind (an interchange file by its columns; a ROS bag holding
    both is ambiguous: DataError asking for ``kind``)."""
    path = Path(path)
    imu_err = gnss_err = None
    try:
        fi = formats.detect_imu_format(path)
    except DataError as e:
        fi, imu_err = None, e
    try:
        fg = formats.detect_gnss_format(path)
    except DataError as e:
        fg, gnss_err = None, e
    if fi == "rosbag":
        with bag_reader(path) as rd:
            types = {c.msgtype for c in rd.connections}
        if IMU_TYPE in types and FIX_TYPE in types:
            raise DataError(path, None, "the bag holds IMU and GNSS messages: choose kind 'imu' or 'gnss'")
        return "imu" if IMU_TYPE in types else "gnss"
    if fi == "interchange" and fg == "interchange":
        from aidnav.io.interchange import read_table  # lazy: pulls in pyarrow

        cols, _ = read_table(path)
        return "gnss" if "lat_deg" in cols else "imu"
    if fi is not None:
        return "imu"
    if fg is not None:
        return "gnss"
    # neither: the more specific message (a missing .tag beats "unknown format")
    for err in (imu_err, gnss_err):
        if "unknown format" not in err.problem:
            raise err
    seen = gnss_err.problem.split("Seen: ", 1)[-1]
    raise DataError(path, None, "unknown format: expected one of: IMU logs — " + "; ".join(
        f"{k}: {v}" for k, v in formats.IMU_FORMATS.items()) + "; GNSS logs — " + "; ".join(
        f"{k}: {v}" for k, v in formats.GNSS_FORMATS.items()) + f". Seen: {seen}")


def convert(in_path, out_path, kind: str = "auto", fmt: str | None = None, height_offset_m: float = 0.0,
            **read_options) -> dict:
    """Read ``in_path`` (any known IMU or GNSS format; ``kind`` "auto", "imu" or "gnss"; ``fmt`` to
    name the source format) and write it to ``out_path`` (.csv or .parquet) in the interchange format.

    height_offset_m : datum offset applied to GNSS heights (recorded). read_options : passed to the
    reader (e.g. ``topic``, ``axes``, ``stamps``, ``date``; None values are ignored, an option the
    reader of that kind does not take is a ValueError).
    Returns a summary: ``{"kind", "format", "input", "output", "samples", "week", "notes"}``.
    """
    from aidnav.io import interchange  # lazy: pulls in pyarrow

    in_path, out_path = Path(in_path), Path(out_path)
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    _out_kind(out_path)
    if out_path.resolve() == in_path.resolve():
        raise DataError(out_path, None, "output is the input file")
    if kind == "auto":
        kind = detect_kind(in_path)
    reader = formats.read_imu if kind == "imu" else formats.read_gnss
    accepted = set(inspect.signature(reader).parameters)
    wrong = sorted(k for k, v in read_options.items() if v is not None and k not in accepted)
    if wrong:
        raise ValueError(f"option(s) {', '.join(wrong)} do not apply to {kind.upper()} logs")
    read_options = {k: v for k, v in read_options.items() if v is not None}
    if kind == "imu":
        if height_offset_m:
            raise ValueError("height_offset_m applies to GNSS logs only")
        data = formats.read_imu(in_path, fmt, **read_options)
        src_fmt = fmt or formats.detect_imu_format(in_path)
    else:
        data = formats.read_gnss(in_path, fmt, height_offset_m=height_offset_m, **read_options)
        src_fmt = fmt or formats.detect_gnss_format(in_path)
    notes = [f"converted by aidnav from {in_path.name} ({kind}, format {src_fmt})",
             "time scale: " + (f"GPS seconds of week {data.week}" if data.week is not None
                               else "as in the source (seconds; GPS seconds of week for GNSS-timed logs)"),
             *[f"reader: {e}" for e in data.events]]
    if kind == "imu":
        interchange.write_imu(data, out_path, notes=notes)
    else:
        interchange.write_gnss(data, out_path, notes=notes)
    return {"kind": kind, "format": src_fmt, "input": str(in_path), "output": str(out_path),
            "samples": len(data), "week": data.week, "notes": notes}
