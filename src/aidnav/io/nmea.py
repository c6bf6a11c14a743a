"""NMEA 0183 GNSS logs (GGA + RMC / VTG, optional GST) → :class:`aidnav.data.GnssData`, via ``pynmea2``.

Sentences are grouped into epochs by their UTC time of day (VTG, which has no time, belongs to the
epoch of the sentence before it). Per epoch:

* position from **GGA**: latitude/longitude [deg], height = orthometric altitude (MSL) + geoid
  separation → ellipsoidal height [m]. A GGA without geoid separation gives heights above MSL: a
  warning event says so (set ``gnss.height_offset_m``). GGA fix quality 0 (invalid), 6 (dead
  reckoning), 7 (manual) and 8 (simulation) are not fixes and are skipped (counted in the events);
  1 GPS → Q 5 (single), 2 DGPS → 4, 3 PPS → 5, 4 RTK fixed → 1, 5 RTK float → 2, 9 SBAS → 3 (RTKLIB Q).
* velocity from **RMC** (speed over ground [knots] × 1852/3600, true course [deg]) or else **VTG**
  (speed [km/h] / 3.6, true track [deg]): ve = s·sin(course), vn = s·cos(course), **vu = NaN** (not
  measured). No velocity sentence: vel None.
* σ from **GST** (σ latitude, σ longitude, σ altitude [m] → σ N, E, U) when present; otherwise
  std_pos is None and an event names the σ the filter uses.
* time: UTC time of day + the date of RMC (or ``date=`` when the log has no RMC), with day roll-over;
  converted to GPST with the leap seconds (:func:`aidnav.io.gpstime.utc_unix_to_gpst_unix`) and
  returned as GPS seconds of week of the first epoch's week (stated in the events).

Lines that are not NMEA (e.g. binary UBX mixed in) or fail their checksum are skipped and counted;
a log with no usable GGA raises :class:`DataError`.
"""

from __future__ import annotations

import datetime as _dt
import math
from pathlib import Path

import numpy as np

from aidnav.data import GnssData
from aidnav.io._std import DEFAULT_POS_STD_M, ZERO_POS_STD_FLOOR_M, check_std
from aidnav.io.errors import DataError
from aidnav.io.gpstime import GPS_EPOCH_UNIX, SECONDS_PER_WEEK, gpst_unix_to_week_sow, leap_seconds
from aidnav.units import KNOT

_GGA_Q = {1: 5, 2: 4, 3: 5, 4: 1, 5: 2, 9: 3}  # GGA fix quality → RTKLIB Q
MAX_LISTED = 5


def _f(x) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def _tod(ts) -> float:
    return ts.hour * 3600.0 + ts.minute * 60.0 + ts.second + ts.microsecond * 1e-6


def read_nmea(path, date: str | _dt.date | None = None, min_pos_std_m: float = ZERO_POS_STD_FLOOR_M
              ) -> GnssData:
    """Read an NMEA log → GnssData (GPS seconds of week [s], lat/lon [rad], ellipsoidal height [m],
    ENU velocity [m/s] with vu NaN, std_pos ENU [m] from GST, quality = RTKLIB Q). See the module doc.

    date : UTC date of the first epoch ('YYYY-MM-DD' or a date) for logs without RMC sentences.
    """
    import pynmea2  # lazy: pynmea2 is heavy to import

    path = Path(path)
    name = path.name
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise DataError(path, None, f"cannot read file: {e.strerror or e}") from None
    events: list[str] = []
    epochs: list[dict] = []
    by_key: dict = {}
    cur = None
    n_other = n_bad = 0
    bad_lines: list[int] = []
    for ln, bline in enumerate(raw.split(b"\n"), start=1):
        s = bline.strip()
        if not s:
            continue
        i = s.find(b"$")
        if i < 0 or len(s) - i < 7:
            n_other += 1
            continue
        try:
            msg = pynmea2.parse(s[i:].decode("ascii"), check=True)
        except (pynmea2.ParseError, UnicodeDecodeError, ValueError, AttributeError):
            n_bad += 1
            if len(bad_lines) < MAX_LISTED:
                bad_lines.append(ln)
            continue
        kind = type(msg).__name__
        if kind in ("GGA", "RMC", "GST"):
            if msg.timestamp is None:
                continue
            key = round(_tod(msg.timestamp), 3)
            if cur is None or cur["tod"] != key:
                cur = {"tod": key, "line": ln}
                epochs.append(cur)
            by_key[key] = cur
            if kind == "GGA":
                cur["gga"] = (msg, ln)
            elif kind == "RMC":
                cur["rmc"] = msg
            else:
                cur["gst"] = msg
        elif kind == "VTG" and cur is not None:
            cur["vtg"] = msg
    if n_other:
        events.append(f"{name}: {n_other} line(s) that are not NMEA sentences skipped")
    if n_bad:
        events.append(f"{name}: {n_bad} NMEA sentence(s) with a bad checksum or unreadable fields skipped "
                      f"(lines {', '.join(map(str, bad_lines))}{' …' if n_bad > len(bad_lines) else ''})")
    if not any("gga" in e for e in epochs):
        if n_bad:  # every GGA was refused: say why (issue 37)
            raise DataError(path, bad_lines[0], f"no GGA sentence with a good checksum: {n_bad} NMEA "
                            "sentence(s) have a bad checksum or unreadable fields (lines "
                            f"{', '.join(map(str, bad_lines))}{' …' if n_bad > len(bad_lines) else ''}): the "
                            "log was corrupted (bytes or line ends changed in transfer?) — use the "
                            "receiver's original file")
        raise DataError(path, None, "no GGA sentence: an NMEA log needs GGA (position and height)"
                        + ("; RMC alone has no height" if any("rmc" in e for e in epochs) else ""))

    # dates: RMC's date, carried forward with roll-over at midnight; epochs before the first RMC
    # take the first RMC's date
    if date is not None and not isinstance(date, _dt.date):
        try:
            date = _dt.date.fromisoformat(str(date))
        except ValueError:
            raise DataError(path, None, f"date {date!r}: expected YYYY-MM-DD") from None
    first_rmc = next((e for e in epochs if "rmc" in e and e["rmc"].datestamp is not None), None)
    if first_rmc is None and date is None:
        raise DataError(path, None, "no RMC sentence with a date: NMEA GGA carries only the time of day; "
                                    "the date must come from RMC (or ZDA) sentences: log them, or in Python "
                                    "read the file with aidnav.io.nmea.read_nmea(path, date='YYYY-MM-DD') "
                                    "and write an interchange file (aidnav.io.interchange.write_gnss)")
    day = first_rmc["rmc"].datestamp if first_rmc is not None else date
    if first_rmc is not None:
        # walk back from the first RMC to the start (roll-over backwards)
        k0 = epochs.index(first_rmc)
        for k in range(k0, -1, -1):
            if k < k0 and epochs[k]["tod"] > epochs[k + 1]["tod"] + 43200:
                day = day - _dt.timedelta(days=1)
            epochs[k]["date"] = day
        day = first_rmc["rmc"].datestamp
        start = k0 + 1
    else:
        epochs[0]["date"] = day
        start = 1
    for k in range(start, len(epochs)):
        e = epochs[k]
        if "rmc" in e and e["rmc"].datestamp is not None:
            day = e["rmc"].datestamp
        elif e["tod"] < epochs[k - 1]["tod"] - 43200:
            day = day + _dt.timedelta(days=1)
        e["date"] = day

    rows = []
    skipped_q: dict[int, int] = {}
    n_no_gga = 0
    no_sep = 0
    for e in epochs:
        if "gga" not in e:
            n_no_gga += 1
            continue
        g, ln = e["gga"]
        q = int(_f(g.gps_qual)) if not math.isnan(_f(g.gps_qual)) else 0
        alt = _f(g.altitude)
        if q not in _GGA_Q or math.isnan(alt) or not g.lat or not g.lon:
            skipped_q[q] = skipped_q.get(q, 0) + 1
            continue
        lat, lon = g.latitude, g.longitude
        sep = _f(g.geo_sep)
        if math.isnan(sep):
            no_sep += 1
            sep = 0.0
        ve = vn = math.nan
        if "rmc" in e and e["rmc"].status == "A" and e["rmc"].spd_over_grnd is not None:
            spd, crs = _f(e["rmc"].spd_over_grnd) * KNOT, _f(e["rmc"].true_course)
        elif "vtg" in e:
            spd, crs = _f(e["vtg"].spd_over_grnd_kmph) / 3.6, _f(e["vtg"].true_track)
            if math.isnan(spd):
                spd = _f(e["vtg"].spd_over_grnd_kts) * KNOT
        else:
            spd = crs = math.nan
        if not math.isnan(spd):
            if spd == 0.0:
                ve = vn = 0.0
            elif not math.isnan(crs):
                ve, vn = spd * math.sin(math.radians(crs)), spd * math.cos(math.radians(crs))
        sd = (math.nan,) * 3
        if "gst" in e:
            st = e["gst"]
            sd = (_f(st.std_dev_longitude), _f(st.std_dev_latitude), _f(st.std_dev_altitude))
        d = e["date"]
        day = (_dt.date(d.year, d.month, d.day) - _dt.date(1970, 1, 1)).days * 86400  # midnight UTC [s]
        rows.append((day, lat, lon, alt + sep, ve, vn, *sd, _GGA_Q[q], ln, e["tod"]))
    if n_no_gga:
        events.append(f"{name}: {n_no_gga} epoch(s) without GGA (no height) skipped")
    for q, n in sorted(skipped_q.items()):
        events.append(f"{name}: {n} GGA epoch(s) with fix quality {q} (not a GNSS fix) skipped")
    if not rows:
        raise DataError(path, None, "no GGA sentence with a valid fix")
    if no_sep:
        events.append(f"warning: {name}: {no_sep} GGA sentence(s) without geoid separation: their heights "
                      "are above mean sea level, not ellipsoidal; set gnss.height_offset_m (the geoid "
                      "undulation)")
    a = np.array(rows, dtype=float)
    line_no = a[:, 10].astype(np.int64)
    # whole seconds and the time of day kept apart: a POSIX count in float64 has only ~0.2 μs resolution
    day, tod = a[:, 0], a[:, 11]
    leap = leap_seconds(day + tod)
    week = gpst_unix_to_week_sow(day[0] + leap[0] + tod[0])[0]
    sow = (day + leap - GPS_EPOCH_UNIX - week * SECONDS_PER_WEEK) + tod
    d = np.diff(sow)
    if np.any(d <= 0):
        i = int(np.argmax(d <= 0)) + 1
        raise DataError(path, int(line_no[i]), f"epoch time {sow[i]:.3f} s of week does not increase "
                                               f"(previous {sow[i - 1]:.3f} s)")
    vel = a[:, [4, 5]]
    vel = None if np.isnan(vel).all() else np.column_stack([vel, np.full(len(a), np.nan)])
    sp = a[:, 6:9]
    std_pos = check_std(path, None if np.isnan(sp).all() else sp, ["GST σlon", "GST σlat", "GST σalt"],
                        lambda i: int(line_no[i]), "position", DEFAULT_POS_STD_M, min_pos_std_m, "m", events)
    events.append(f"{name}: NMEA, UTC → GPST (+{leap[0]:g} s leap seconds); "
                  f"time = GPS seconds of week {week}; {len(a)} epochs; heights MSL + geoid separation; "
                  "velocity from speed/course: vu not measured (NaN)"
                  + ("" if vel is not None else "; no RMC/VTG: no velocity"))
    return GnssData(sow, np.radians(a[:, 1]), np.radians(a[:, 2]), a[:, 3], vel=vel, std_pos=std_pos,
                    quality=a[:, 9].astype(np.int64), events=events, week=int(week))
