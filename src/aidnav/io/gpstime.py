"""GPS time helpers: GPST counted like Unix time ↔ (GPS week, seconds of week), calendar strings.

Time scales (``CONVENTIONS.md``): GNSS-timed data carry GPS time as (week, seconds of week). RTKLIB
stores GPS time internally as ``gtime_t.time``: whole seconds of **GPST counted like Unix time**, i.e.
seconds since 1970-01-01 00:00:00 *on the GPS time scale*. Both that count and GPS weeks are on the
GPST scale, so no leap seconds enter anywhere here: the GPS epoch 1980-01-06 00:00:00 GPST is simply
``GPS_EPOCH_UNIX = 315964800`` in that count.

All functions are vectorised with numpy and accept scalars or arrays (float64 seconds).
Seconds of week are float64: at 6e5 s their resolution is ~1e-10 s.
"""

from __future__ import annotations

import numpy as np

GPS_EPOCH_UNIX = 315964800  #: 1980-01-06 00:00:00 in seconds counted like Unix time [s]
SECONDS_PER_WEEK = 604800  #: [s]

_GPS_EPOCH = np.datetime64("1980-01-06T00:00:00", "ns")
_NS_PER_WEEK = np.int64(SECONDS_PER_WEEK) * np.int64(1_000_000_000)


def gpst_unix_to_week_sow(t, week=None):
    """GPST-like-Unix seconds → (GPS week, seconds of week).

    t : GPST seconds counted like Unix time [s] (scalar or array).
    week : if None, each element gets its own week and its seconds of week in [0, 604800).
        If given (int), seconds of week are counted from the start of that week for every element
        (they may then be ≥ 604800 or negative): use this to keep a log that crosses a week boundary
        strictly increasing (pass the week of its first sample).
    Returns (week, sow): week as int (scalar input or ``week`` given) or int64 array; sow [s] float64.
    """
    t = np.asarray(t, dtype=float)
    since = t - GPS_EPOCH_UNIX
    if week is None:
        w = np.floor(since / SECONDS_PER_WEEK)
        sow = since - w * SECONDS_PER_WEEK
        w = w.astype(np.int64)
        if w.ndim == 0:
            return int(w), float(sow)
        return w, sow
    week = int(week)
    sow = since - week * SECONDS_PER_WEEK
    return week, (float(sow) if sow.ndim == 0 else sow)


def week_sow_to_gpst_unix(week, sow):
    """(GPS week, seconds of week [s]) → GPST seconds counted like Unix time [s] (float64)."""
    out = GPS_EPOCH_UNIX + np.asarray(week, dtype=float) * SECONDS_PER_WEEK + np.asarray(sow, dtype=float)
    return float(out) if out.ndim == 0 else out


def _to_datetime64(strings) -> np.ndarray:
    """'YYYY/MM/DD HH:MM:SS.sss' (or ISO 'YYYY-MM-DD[T ]HH:MM:SS') → datetime64[ns] array.

    Raises ValueError naming the index of the first string that cannot be read.
    """
    s = np.atleast_1d(np.asarray(strings, dtype=str))
    iso = np.char.replace(np.char.replace(np.char.strip(s), "/", "-"), " ", "T")
    try:
        return iso.astype("datetime64[ns]")
    except ValueError:
        for i, x in enumerate(iso):
            try:
                np.datetime64(x, "ns")
            except ValueError as e:
                raise ValueError(f"element {i}: cannot read calendar time {str(s[i])!r} ({e})") from None
        raise


def calendar_to_week_sow(strings, week=None):
    """Calendar GPST strings 'YYYY/MM/DD HH:MM:SS.sss' → (GPS week, seconds of week [s]).

    The strings are on the **GPST** scale (as RTKLIB writes them with its default ``GPST`` time
    system): no leap seconds are applied. Any number of decimals (0–9) is read exactly (via integer
    nanoseconds), then converted to float64 seconds of week.
    strings : one string or a sequence/array of them.
    week : as in :func:`gpst_unix_to_week_sow` (None: each string gets its own week).
    Returns (week, sow) as scalars for a single string, arrays otherwise.
    Raises ValueError naming the index of the first unreadable string.
    """
    scalar = np.ndim(strings) == 0
    dt = _to_datetime64(strings)
    ns = (dt - _GPS_EPOCH).astype(np.int64)
    if week is None:
        w = ns // _NS_PER_WEEK
        sow = (ns - w * _NS_PER_WEEK).astype(float) * 1e-9
    else:
        w = np.full(ns.shape, int(week), dtype=np.int64)
        sow = (ns - np.int64(week) * _NS_PER_WEEK).astype(float) * 1e-9
    if scalar:
        return int(w[0]), float(sow[0])
    if week is not None:
        return int(week), sow
    return w, sow


def calendar_to_gpst_unix(strings):
    """Calendar GPST strings 'YYYY/MM/DD HH:MM:SS.sss' → GPST seconds counted like Unix time [s]."""
    scalar = np.ndim(strings) == 0
    dt = _to_datetime64(strings)
    ns = (dt - np.datetime64("1970-01-01T00:00:00", "ns")).astype(np.int64)
    whole = ns // 1_000_000_000
    t = whole.astype(float) + (ns - whole * 1_000_000_000).astype(float) * 1e-9
    return float(t[0]) if scalar else t


def gpst_unix_to_calendar(t) -> np.ndarray | str:
    """GPST-like-Unix seconds → calendar string 'YYYY/MM/DD HH:MM:SS.sss' (GPST, millisecond)."""
    t = np.asarray(t, dtype=float)
    ms = np.round(t * 1000.0).astype(np.int64)
    dt = np.datetime64("1970-01-01T00:00:00", "ms") + ms.astype("timedelta64[ms]")
    s = np.char.replace(np.char.replace(np.datetime_as_string(dt, unit="ms"), "T", " "), "-", "/")
    return str(s) if s.ndim == 0 else s
