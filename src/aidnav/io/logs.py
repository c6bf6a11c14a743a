"""Readers of raw IMU logs of other tools (converted to aidnav conventions on reading).

:func:`read_rtklibexplorer_imu` reads the raw IMU CSV of rtklibexplorer/GNSS_IMU (data sets
``rtklibexplorer_drive_0708``, ``rtklibexplorer_walk_0827``) and maps it to GPS time with its RTKLIB
time-tag file (:mod:`aidnav.io.timetag`).
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from aidnav.data import ImuData
from aidnav.io._arrow import column_to_f64
from aidnav.io.errors import DataError
from aidnav.io.gpstime import gpst_unix_to_week_sow
from aidnav.io.timetag import fit_stamp_clock, line_end_offsets, read_timetag
from aidnav.units import G0

N_FIELDS = 7
GAP_FACTOR = 5.0  #: a sample interval above this multiple of the median one is reported as a gap
MAX_LISTED = 10  #: line numbers listed per kind of problem before summarising

# sensor axes → body RFU
_AXES = {
    "RFU": np.eye(3),
    # b_RFU = [y_FRD, x_FRD, -z_FRD]
    "FRD": np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]),
}


def _report(events: list[str], name: str, lines: np.ndarray, what: str):
    """Append one event per line (up to MAX_LISTED) and a summary for the rest."""
    for ln in lines[:MAX_LISTED]:
        events.append(f"{name}:{int(ln)}: {what}")
    if len(lines) > MAX_LISTED:
        events.append(f"{name}: {len(lines) - MAX_LISTED} more lines: {what} "
                      f"(lines {int(lines[MAX_LISTED])}…{int(lines[-1])})")


def read_rtklibexplorer_imu(path, tag_path=None, axes: str = "RFU", mounting=None,
                            skip_first_line: bool = True, time_offset_s: float = 0.0,
                            tag_quantile: float = 0.01, return_fit: bool = False):
    """Read a raw rtklibexplorer IMU CSV log and map it to GPS time → :class:`ImuData`.

    File: comma-separated, no header, per line ``ax, ay, az`` [g], ``gx, gy, gz`` [deg/s], ``stamp``
    [integer ms since IMU power-up]. Conversion: specific force × g0 = 9.80665 m/s² (the unit "g" of
    the file, as the data's author uses it; not local gravity); rates deg/s → rad/s.

    Axes: the sensor axes are read as ``axes`` (default "RFU": x right, y forward, z up, as the
    rtklibexplorer sensor is used here; "FRD" is also accepted) and turned into body RFU; then the
    optional ``mounting`` rotation C_sensor→body (3×3) is applied: v_body = mounting · v_RFU.

    Time: each line is mapped by its byte offset to its arrival time in the tag file (``tag_path``;
    default ``<path>.tag`` beside the log) and the IMU stamps are fitted to the lower envelope of those
    arrival times (:func:`aidnav.io.timetag.fit_stamp_clock`, quantile ``tag_quantile``); the fitted
    line gives each sample's GPST, and ``time_offset_s`` (a configured IMU time correction) is added.
    The tag cannot see delays inside the IMU before it prints a line: on the drive set the IMU motion
    appears 0.10–0.14 s after the GNSS motion on this mapping (turn rate and acceleration
    cross-correlated), so about −0.12 s belongs there (the data's author configures −0.125 s on his
    own, cruder mapping); better estimate it as a filter state. Returned times are **GPS seconds of
    week**, counted from the week of the first sample (they go on past 604800 s if the log crosses a
    week end); the week is stated in ``events``.

    Increments: over each interval (t_{k-1}, t_k] by the **trapezoid rule**, Δθ_k = ½(ω_{k-1} + ω_k)
    (t_k − t_{k-1}) and the same for Δv. The samples are point values of the (internally filtered)
    rates at their stamps; the trapezoid is exact for rates varying linearly over an interval and has
    no timing bias, whereas the rectangle rule on the end sample, ω_k·Δt_k, shifts the signal by half
    an interval (~5 ms here, i.e. a first-order time error during manoeuvres). Sums of increments over
    many samples are the same with both rules (they differ only at the two ends), so biases and noise
    levels are unaffected. The first sample has no predecessor: it gets ω_0·Δt with Δt the first
    interval, and ``t0`` = t_0 − Δt.

    Data problems are reported in ``ImuData.events`` as "file:line: problem" and the line is skipped:
    lines without 7 fields (e.g. the walk log's truncated last line), unreadable numbers, NaN/inf
    values, duplicate or backwards stamps; gaps > 5× the median interval are reported (and bridged by
    the trapezoid). The first line is skipped by default (``skip_first_line``) because the logger can
    start in the middle of a line (as the data's author does); a complete, newline-terminated last
    line is kept. Raises :class:`DataError` only when nothing usable is left or the tag file is bad.

    Returns ImuData (time [s of GPS week], dtheta [rad], dv [m/s], body RFU), or (ImuData, ClockFit)
    with ``return_fit=True``.
    """
    path = Path(path)
    name = path.name
    tag_path = Path(tag_path) if tag_path is not None else path.with_name(path.name + ".tag")
    c_axes = _axes_matrix(axes, mounting)

    data = path.read_bytes()
    if not data:
        raise DataError(path, None, "empty file")
    tag = read_timetag(tag_path)
    events = list(tag.events)

    buf, lines = _screen_lines(data, name, skip_first_line, events)
    arr, good = _parse_kept(path, buf, lines, events)
    arr, good, stamp_ms = _clean_stamps(arr, good, lines.line_no, name, events)
    if len(arr) < 2:
        raise DataError(path, None, f"only {len(arr)} usable IMU line(s)")

    # time mapping: each line's arrival time from the tag, lower-envelope fit of the IMU clock
    ends, notes = line_end_offsets(data, tag, name)
    events.extend(notes)
    arrival = tag.arrival_gpst(ends[good])
    stamp_s = stamp_ms * 1e-3
    fit = fit_stamp_clock(stamp_s, arrival, quantile=tag_quantile, tick_quantum_ms=tag.tick_quantum_ms)
    n_unmapped = int(np.sum(~np.isfinite(arrival)))
    if n_unmapped:
        events.append(f"{name}: {n_unmapped} lines lie beyond the last tag record; "
                      "their time is extrapolated")
    t_gpst = fit(stamp_s) + time_offset_s
    week, t = gpst_unix_to_week_sow(t_gpst, week=gpst_unix_to_week_sow(t_gpst[0])[0])
    events.append(f"{name}: time = GPS seconds of week {week} (tag {tag_path.name}, log start "
                  f"{tag.start_week_sow[1]:.3f} s); {fit.summary()}"
                  + (f"; configured IMU time offset {time_offset_s:+.4f} s added" if time_offset_s else ""))

    dt = np.diff(t)
    med = float(np.median(dt))
    gap = np.flatnonzero(dt > GAP_FACTOR * med)
    for i in gap[:MAX_LISTED]:
        events.append(f"{name}:{int(lines.line_no[good[i + 1]])}: gap of {dt[i] * 1e3:.1f} ms before this "
                      f"sample (median interval {med * 1e3:.2f} ms), at {t[i + 1]:.3f} s of week; bridged")
    if len(gap) > MAX_LISTED:
        events.append(f"{name}: {len(gap) - MAX_LISTED} more gaps > {GAP_FACTOR:g}× the median interval")

    dtheta, dv = _increments(arr, c_axes, dt)
    imu = ImuData(t, dtheta, dv, t0=float(t[0] - dt[0]), events=events, week=int(week))
    return (imu, fit) if return_fit else imu


def _axes_matrix(axes: str, mounting) -> np.ndarray:
    """C sensor axes → body RFU, then the optional ``mounting`` rotation (3×3) applied."""
    if axes not in _AXES:
        raise ValueError(f"axes must be one of {sorted(_AXES)}, got {axes!r}")
    c_axes = _AXES[axes]
    if mounting is not None:
        m = np.asarray(mounting, dtype=float)
        if m.shape != (3, 3) or not np.allclose(m @ m.T, np.eye(3), atol=1e-9):
            raise ValueError("mounting must be a 3x3 rotation matrix (C_sensor→body)")
        c_axes = m @ c_axes
    return c_axes


@dataclass
class _Lines:
    """The log's lines: byte ranges [start, stop) without the line end, numbers from 1, kept or not."""

    starts: np.ndarray
    stops: np.ndarray
    line_no: np.ndarray
    keep: np.ndarray


def _screen_lines(data: bytes, name: str, skip_first_line: bool, events: list[str]):
    """Split the log into lines and drop (reporting each) the first line when asked, empty lines,
    lines without ``N_FIELDS`` fields and a last line without a line end → (bytes as uint8, _Lines)."""
    buf = np.frombuffer(data, np.uint8)
    nl = np.flatnonzero(buf == 10)
    starts = np.r_[0, nl + 1].astype(np.int64)
    stops = np.r_[nl, len(data)].astype(np.int64)  # exclusive, without the '\n'
    terminated = np.r_[np.ones(len(nl), bool), False]
    if stops[-1] == starts[-1]:  # file ends with '\n': no trailing partial line
        starts, stops, terminated = starts[:-1], stops[:-1], terminated[:-1]
    n_lines = len(starts)
    line_no = np.arange(1, n_lines + 1)

    # fields per line from the comma positions
    commas = np.flatnonzero(buf == 44)
    nfields = np.bincount(np.searchsorted(nl, commas, side="left"), minlength=n_lines)[:n_lines] + 1
    length = stops - starts
    keep = np.ones(n_lines, bool)
    if skip_first_line and n_lines:
        keep[0] = False
        how = "" if nfields[0] == N_FIELDS else f"{nfields[0]} fields, expected {N_FIELDS}; "
        events.append(f"{name}:1: first line skipped ({how}the logger can start in the middle of a line)")
    blank = keep & (length - (buf[np.maximum(stops - 1, 0)] == 13) <= 0)
    _report(events, name, line_no[blank], "empty line; skipped")
    keep &= ~blank
    wrong = keep & (nfields != N_FIELDS)
    for k in np.unique(nfields[wrong]):
        sel = wrong & (nfields == k)
        _report(events, name, line_no[sel], f"{k} fields, expected {N_FIELDS}; line skipped")
    keep &= ~wrong
    cut = keep & ~terminated
    _report(events, name, line_no[cut], "last line has no line end (cut short?); line skipped")
    keep &= ~cut
    return buf, _Lines(starts, stops, line_no, keep)


def _parse_kept(path: Path, buf: np.ndarray, lines: _Lines, events: list[str]):
    """Parse the kept lines in one go (their bytes only) → (finite values n×7, their line indices);
    lines with a field that is not a number or a NaN/inf value are reported and dropped."""
    name = path.name
    starts, stops, line_no, keep = lines.starts, lines.stops, lines.line_no, lines.keep
    n_bytes = len(buf)
    # parse the remaining lines in one go: mask out the bytes of the dropped lines
    drop = np.flatnonzero(~keep)
    delta = np.zeros(n_bytes + 1, np.int32)
    np.add.at(delta, starts[drop], 1)
    np.add.at(delta, np.minimum(stops[drop] + 1, n_bytes), -1)
    byte_keep = np.cumsum(delta[:-1]) == 0
    good = np.flatnonzero(keep)
    if len(good) == 0:
        raise DataError(path, None, "no readable IMU lines")
    cols = list(range(N_FIELDS))
    text = buf[byte_keep].tobytes()

    try:
        tbl = pacsv.read_csv(io.BytesIO(text),
                             read_options=pacsv.ReadOptions(autogenerate_column_names=True),
                             convert_options=pacsv.ConvertOptions(
                                 column_types={f"f{i}": pa.float64() for i in cols}))
        arr = np.column_stack([column_to_f64(tbl.column(i)) for i in cols])
    except (pa.ArrowInvalid, ValueError):  # a field that is not a number: find it (slow path, pandas)
        import pandas as pd  # lazy: pandas is heavy to import

        raw = pd.read_csv(io.BytesIO(text), header=None, names=cols, dtype=str, engine="c",
                          keep_default_na=False)
        arr = np.column_stack([pd.to_numeric(raw[c].str.strip(), errors="coerce").to_numpy(float)
                               for c in cols])
        lower = raw.apply(lambda s: s.str.strip().str.lower())
        nan_text = lower.isin(["nan", "inf", "-inf", "+inf", "infinity", "-infinity"]).to_numpy()
        unreadable = np.isnan(arr) & ~nan_text
        bad = unreadable.any(axis=1)
        _report(events, name, line_no[good[bad]], "field is not a number; line skipped")
        arr, good = arr[~bad], good[~bad]
    if len(arr) != len(good):
        raise DataError(path, None, f"parsed {len(arr)} rows from {len(good)} lines (internal mismatch)")

    nonfinite = ~np.isfinite(arr).all(axis=1)
    _report(events, name, line_no[good[nonfinite]], "NaN or inf value; line skipped")
    return arr[~nonfinite], good[~nonfinite]


def _clean_stamps(arr: np.ndarray, good: np.ndarray, line_no: np.ndarray, name: str, events: list[str]):
    """Report stamps that are not whole ms (kept); drop duplicate and backward stamps (reported) so
    that the stamps increase strictly → (values, line indices, stamps [ms])."""
    stamp_ms = arr[:, 6]
    frac = stamp_ms != np.round(stamp_ms)
    if frac.any():
        _report(events, name, line_no[good[frac]], "time stamp is not an integer number of ms (kept)")
    # strictly increasing stamps: drop duplicates and samples that go backwards
    if len(stamp_ms) > 1:
        prev_max = np.maximum.accumulate(stamp_ms)[:-1]
        dup = np.r_[False, stamp_ms[1:] == prev_max]
        back = np.r_[False, stamp_ms[1:] < prev_max]
        _report(events, name, line_no[good[dup]], "duplicate time stamp; line skipped")
        _report(events, name, line_no[good[back]], "time stamp goes backwards; line skipped")
        ok = ~(dup | back)
        arr, good = arr[ok], good[ok]
        stamp_ms = stamp_ms[ok]
    return arr, good, stamp_ms


def _increments(arr: np.ndarray, c_axes: np.ndarray, dt: np.ndarray):
    """Trapezoid increments (Δθ [rad], Δv [m/s]) in body axes; the first sample gets ω_0·Δt_1."""
    # units and axes: g → m/s², deg/s → rad/s; sensor axes → body RFU (→ mounting)
    f_b = (arr[:, 0:3] * G0) @ c_axes.T
    w_b = np.radians(arr[:, 3:6]) @ c_axes.T
    dtheta = np.empty_like(w_b)
    dv = np.empty_like(f_b)
    dt0 = dt[0]
    dtheta[0] = w_b[0] * dt0
    dv[0] = f_b[0] * dt0
    dtheta[1:] = 0.5 * (w_b[1:] + w_b[:-1]) * dt[:, None]
    dv[1:] = 0.5 * (f_b[1:] + f_b[:-1]) * dt[:, None]
    return dtheta, dv
