"""GPS time helpers: GPST counted like Unix time ↔ (GPS week, seconds of week), calendar strings.

Time scales (``docs/conventions.md``): GNSS-timed data carry GPS time as (week, seconds of week). RTKLIB
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


# ====================================================================================== UTC ↔ GPST
#: UTC instants (seconds since 1970-01-01 UTC, POSIX count) from which GPST − UTC takes the value, [s].
#: IERS leap seconds since the GPS epoch (GPST − UTC = 0 s on 1980-01-06). No leap second has been
#: inserted after 2017-01-01 up to the writing of this table (IERS Bulletin C); a new one must be added
#: here, and only here.
_LEAP_TABLE = [
    ("1981-07-01", 1), ("1982-07-01", 2), ("1983-07-01", 3), ("1985-07-01", 4), ("1988-01-01", 5),
    ("1990-01-01", 6), ("1991-01-01", 7), ("1992-07-01", 8), ("1993-07-01", 9), ("1994-07-01", 10),
    ("1996-01-01", 11), ("1997-07-01", 12), ("1999-01-01", 13), ("2006-01-01", 14), ("2009-01-01", 15),
    ("2012-07-01", 16), ("2015-07-01", 17), ("2017-01-01", 18),
]
_LEAP_UTC = np.array([np.datetime64(d, "s").astype(np.int64) for d, _ in _LEAP_TABLE], dtype=float)
_LEAP_VAL = np.array([v for _, v in _LEAP_TABLE], dtype=float)


def leap_seconds(t_utc_unix) -> np.ndarray | float:
    """GPST − UTC [s] at the UTC instants ``t_utc_unix`` (POSIX seconds since 1970-01-01 UTC).

    Raises ValueError for instants before the GPS epoch (1980-01-06), where GPS time is not defined."""
    t = np.asarray(t_utc_unix, dtype=float)
    if np.any(t < GPS_EPOCH_UNIX):
        raise ValueError("UTC time before the GPS epoch 1980-01-06: not a GNSS time stamp")
    idx = np.searchsorted(_LEAP_UTC, t, side="right")
    out = np.where(idx > 0, _LEAP_VAL[np.maximum(idx - 1, 0)], 0.0)
    return float(out) if out.ndim == 0 else out


def utc_unix_to_gpst_unix(t_utc_unix):
    """UTC (POSIX seconds, as ROS stamps, NMEA and UBX UTC fields give it) → GPST counted like Unix [s]."""
    t = np.asarray(t_utc_unix, dtype=float)
    out = t + leap_seconds(t)
    return float(out) if out.ndim == 0 else out


def gpst_unix_to_utc_unix(t_gpst_unix):
    """GPST counted like Unix [s] → UTC POSIX seconds (inverse of :func:`utc_unix_to_gpst_unix`)."""
    t = np.asarray(t_gpst_unix, dtype=float)
    approx = t - leap_seconds(np.maximum(t - 18.0, GPS_EPOCH_UNIX))
    out = t - leap_seconds(np.maximum(approx, GPS_EPOCH_UNIX))
    return float(out) if out.ndim == 0 else out


def week_sow_to_utc_iso(week, sow) -> np.ndarray:
    """(GPS week, seconds of week [s]) → UTC ISO 8601 strings 'YYYY-MM-DDTHH:MM:SS.ssssssZ' (μs)."""
    utc = np.atleast_1d(gpst_unix_to_utc_unix(week_sow_to_gpst_unix(week, sow)))
    us = np.round(utc * 1e6).astype(np.int64)
    dt = np.datetime64("1970-01-01T00:00:00", "us") + us.astype("timedelta64[us]")
    return np.char.add(np.datetime_as_string(dt, unit="us"), "Z")
