"""NMEA 0183 GNSS logs (GGA + RMC / VTG, optional GST) → :class:`aidnav.data.GnssData`, via ``pynmea2``.

Sentences are grouped into epochs by their UTC time of day (VTG, which has no time, belongs to the
epoch of the sentence before it; a sentence whose time matches one of the last few epochs joins it, so
GGA/RMC/GST of mixed talkers ``GP``/``GN``/``GL``/``GA``/``BD`` and out-of-order GST are merged). Per epoch:

* position from **GGA**: latitude/longitude [deg], height = orthometric altitude (MSL) + geoid
  separation → ellipsoidal height [m] (``height_datum = "ellipsoid"``: a configured height offset is not
  applied, :mod:`aidnav.io.formats`). When no GGA gives the separation the heights are above MSL
  (``height_datum = "msl"``: the configured offset applies; without one a warning says so); when only
  some do, the others take the nearest given separation (an event counts them). GGA fix quality 0
  (invalid), 6 (dead reckoning), 7 (manual) and 8 (simulation) are not fixes and are skipped (counted);
  1 GPS → Q 5 (single), 2 DGPS → 4, 3 PPS → 5, 4 RTK fixed → 1, 5 RTK float → 2, 9 SBAS → 3 (RTKLIB Q,
  the quality rules of :mod:`aidnav.io._std`).
* velocity from **RMC** (speed over ground [knots] × 1852/3600, true course [deg]) or else **VTG**
  (speed [km/h] / 3.6, true track [deg]): ve = s·sin(course), vn = s·cos(course), **vu = NaN** (not
  measured). No velocity sentence: vel None.
* σ from **GST** (σ latitude, σ longitude, σ altitude [m] → σ N, E, U) when present; otherwise from the
  GGA **HDOP**: σE = σN = HDOP × UERE, σU = 2 × HDOP × UERE with the stated
  :data:`aidnav.io._std.NMEA_UERE_M`; the events (printed on the console by ``process``) say which
  epochs use which.
* time: UTC time of day + the date of RMC (or ``date=`` when the log has no RMC), with day roll-over;
  converted to GPST with the leap seconds (:func:`aidnav.io.gpstime.leap_seconds`) and returned as GPS
  seconds of week of the first epoch's week (stated in the events). A leap second (``23:59:60``) is
  read as the 86,401st second of its day, on GPS time between the seconds around it.

What a receiver may print is read, never a crash: lines that are not NMEA (binary UBX mixed in),
sentences with a bad or missing checksum (a truncated last line), unreadable fields (a time 25:00:00,
a latitude with a letter) and empty fields before a fix are skipped and counted with their line
numbers; CRLF line ends are fine. A log with no usable GGA, or an epoch time that goes backwards,
raises :class:`DataError` naming the file and line.
"""

from __future__ import annotations

import datetime as _dt
import math
from pathlib import Path

import numpy as np

from aidnav.data import GnssData
from aidnav.io._std import DEFAULT_POS_STD_M, NMEA_UERE_M, ZERO_POS_STD_FLOOR_M, check_std
from aidnav.io.errors import DataError
from aidnav.io.gpstime import GPS_EPOCH_UNIX, SECONDS_PER_WEEK, gpst_unix_to_week_sow, leap_seconds
from aidnav.units import KNOT

_GGA_Q = {1: 5, 2: 4, 3: 5, 4: 1, 5: 2, 9: 3}  # GGA fix quality → RTKLIB Q
MAX_LISTED = 5
_RECENT = 4  # a sentence joins one of the last _RECENT epochs with its time of day


def _f(x) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return math.nan
    return v if math.isfinite(v) else math.nan


def _tod(field: str) -> float:
    """'hhmmss[.sss]' → seconds of the UTC day (23:59:60.x → 86400.x, a leap second); ValueError else."""
    if len(field) < 6 or not field[:6].isdigit():
        raise ValueError(f"time {field!r} is not hhmmss.sss")
    h, m, sec = int(field[:2]), int(field[2:4]), float(field[4:])
    if h > 23 or m > 59 or not 0 <= sec < 61 or (sec >= 60 and (h, m) != (23, 59)):
        raise ValueError(f"time {field!r} out of range")
    return h * 3600.0 + m * 60.0 + sec


def _date(field: str) -> _dt.date | None:
    """'ddmmyy' → date (years 80-99 → 19xx, else 20xx); None when empty or not a date."""
    if len(field) != 6 or not field.isdigit():
        return None
    d, m, y = int(field[:2]), int(field[2:4]), int(field[4:])
    try:
        return _dt.date(1900 + y if y >= 80 else 2000 + y, m, d)
    except ValueError:
        return None


def _angle(value: str, hemi: str, deg_digits: int) -> float:
    """NMEA 'dddmm.mmmm' + hemisphere → signed degrees (NaN when empty or unreadable)."""
    if len(value) <= deg_digits or hemi not in ("N", "S", "E", "W"):
        return math.nan
    d, m = _f(value[:deg_digits]), _f(value[deg_digits:])
    if math.isnan(d) or math.isnan(m) or not 0 <= m < 60:
        return math.nan
    return (d + m / 60.0) * (-1.0 if hemi in ("S", "W") else 1.0)


def _field(data, i) -> str:
    return data[i].strip() if i < len(data) else ""


def read_nmea(path, date: str | _dt.date | None = None, min_pos_std_m: float = ZERO_POS_STD_FLOOR_M
              ) -> GnssData:
    """Read an NMEA log → GnssData (GPS seconds of week [s], lat/lon [rad], ellipsoidal height [m] (or
    MSL, see ``height_datum``), ENU velocity [m/s] with vu NaN, std_pos ENU [m] from GST or HDOP,
    quality = RTKLIB Q). See the module doc.

    date : UTC date of the first epoch ('YYYY-MM-DD' or a date) for logs without RMC sentences.
    """
    path = Path(path)
    name = path.name
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise DataError(path, None, f"cannot read file: {e.strerror or e}") from None
    events: list[str] = []
    epochs, n_other, bad, talkers = _epochs(raw)
    if n_other:
        events.append(f"{name}: {n_other} line(s) that are not NMEA sentences skipped")
    if bad:
        where = ", ".join(f"{a} ({b})" for a, b in bad[:MAX_LISTED])
        events.append(f"{name}: {len(bad)} NMEA sentence(s) with a bad checksum (or none) or unreadable "
                      f"fields skipped (lines {where}{' …' if len(bad) > MAX_LISTED else ''})")
    if not any("gga" in e for e in epochs):
        if bad:  # every GGA was refused: say why (issue 37)
            bad_lines = [a for a, _ in bad[:MAX_LISTED]]
            raise DataError(path, bad_lines[0], f"no GGA sentence with a good checksum: {len(bad)} NMEA "
                            "sentence(s) have a bad checksum or unreadable fields (lines "
                            f"{', '.join(map(str, bad_lines))}{' …' if len(bad) > MAX_LISTED else ''}): the "
                            "log was corrupted (bytes or line ends changed in transfer?) — use the "
                            "receiver's original file")
        raise DataError(path, None, "no GGA sentence: an NMEA log needs GGA (position and height)"
                        + ("; RMC alone has no height" if any("rmc" in e for e in epochs) else ""))
    _dates(path, epochs, date)

    rows, n_no_gga, skipped_q = _rows(path, epochs)
    if n_no_gga:
        events.append(f"{name}: {n_no_gga} epoch(s) without GGA (no height) skipped")
    for q, n in sorted(skipped_q.items()):
        events.append(f"{name}: {n} GGA epoch(s) with fix quality {q} or empty position fields (not a GNSS "
                      "fix) skipped")
    if not rows:
        raise DataError(path, None, "no GGA sentence with a valid fix")
    a = np.array(rows, dtype=float)
    line_no = a[:, 10].astype(np.int64)
    height, datum = _heights(name, a[:, 3], a[:, 12], events)
    week, sow, leap = _gps_time(path, a[:, 0], a[:, 11], line_no, epochs)
    vel = a[:, [4, 5]]
    vel = None if np.isnan(vel).all() else np.column_stack([vel, np.full(len(a), np.nan)])
    sp = _sigma(name, a[:, 6:9], a[:, 13], events)
    std_pos = check_std(path, None if np.isnan(sp).all() else sp, ["GST σlon", "GST σlat", "GST σalt"],
                        lambda i: int(line_no[i]), "position", DEFAULT_POS_STD_M, min_pos_std_m, "m", events)
    tk = ", ".join(sorted(t for t in talkers if t))
    events.append(f"{name}: NMEA ({'talkers ' + tk if tk else 'no talker'}), UTC → GPST (+{leap[0]:g} s leap "
                  f"seconds); time = GPS seconds of week {week}; {len(a)} epochs; heights "
                  f"{'MSL + geoid separation (ellipsoidal)' if datum == 'ellipsoid' else 'above MSL'}; "
                  "velocity from speed/course: vu not measured (NaN)"
                  + ("" if vel is not None else "; no RMC/VTG: no velocity"))
    return GnssData(sow, np.radians(a[:, 1]), np.radians(a[:, 2]), height, vel=vel, std_pos=std_pos,
                    quality=a[:, 9].astype(np.int64), events=events, week=int(week), height_datum=datum)


def _epochs(raw: bytes):
    """The log's GGA/RMC/GST/VTG sentences grouped by time of day → (epochs: dicts with ``tod``,
    ``line`` and per kind ``(fields, line)``; lines that are not NMEA; refused sentences ``(line,
    why)``; talkers)."""
    import pynmea2  # lazy: pynmea2 is heavy to import

    epochs: list[dict] = []
    cur = None
    n_other = 0
    bad: list[tuple[int, str]] = []
    talkers: set[str] = set()
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
            kind = type(msg).__name__
            data = list(msg.data)
            tod = _tod(_field(data, 0)) if kind in ("GGA", "RMC", "GST") and _field(data, 0) else None
        except Exception as e:  # noqa: BLE001  (pynmea2 raises many kinds for what receivers print)
            bad.append((ln, str(e).split("\n")[0][:80] or type(e).__name__))
            continue
        if kind in ("GGA", "RMC", "GST"):
            if tod is None:  # no time yet (before the first fix)
                continue
            key = round(tod, 3)
            hit = next((e for e in reversed(epochs[-_RECENT:]) if e["tod"] == key), None)
            if hit is None:
                hit = {"tod": key, "line": ln}
                epochs.append(hit)
            cur = hit
            talkers.add(getattr(msg, "talker", "") or "")
            cur.setdefault(kind.lower(), (data, ln))
        elif kind == "VTG" and cur is not None:
            cur.setdefault("vtg", (data, ln))
    return epochs, n_other, bad, talkers


def _rows(path, epochs: list[dict]):
    """One row per epoch with a usable GGA fix: (midnight UTC [s], lat, lon [deg], alt, ve, vn, GST σ
    E/N/U, RTKLIB Q, line, time of day, geoid separation, HDOP) → (rows, epochs without GGA, skipped
    count per fix quality)."""
    rows = []
    skipped_q: dict[int, int] = {}
    n_no_gga = 0
    for e in epochs:
        if "gga" not in e:
            n_no_gga += 1
            continue
        g, ln = e["gga"]
        qf = _f(_field(g, 5))
        q = int(qf) if not math.isnan(qf) else 0
        lat = _angle(_field(g, 1), _field(g, 2), 2)
        lon = _angle(_field(g, 3), _field(g, 4), 3)
        alt = _f(_field(g, 8))
        if q not in _GGA_Q or math.isnan(alt) or math.isnan(lat) or math.isnan(lon):
            skipped_q[q] = skipped_q.get(q, 0) + 1
            continue
        if abs(lat) > 90 or abs(lon) > 180:
            raise DataError(path, ln, f"GGA latitude {lat:.6f} / longitude {lon:.6f} deg out of range")
        ve, vn = _velocity(e)
        sd = (math.nan,) * 3
        if "gst" in e:
            st = e["gst"][0]
            sd = (_f(_field(st, 6)), _f(_field(st, 5)), _f(_field(st, 7)))
        d = e["date"]
        day = (_dt.date(d.year, d.month, d.day) - _dt.date(1970, 1, 1)).days * 86400  # midnight UTC [s]
        rows.append((day, lat, lon, alt, ve, vn, *sd, _GGA_Q[q], ln, e["tod"], _f(_field(g, 10)),
                     _f(_field(g, 7))))
    return rows, n_no_gga, skipped_q


def _gps_time(path, day: np.ndarray, tod: np.ndarray, line_no: np.ndarray, epochs: list[dict]):
    """UTC midnight + time of day → (GPS week of the first epoch, GPS seconds of that week, leap
    seconds per epoch); the epochs must increase."""
    # whole seconds and the time of day kept apart: a POSIX count in float64 has only ~0.2 μs resolution
    try:  # the leap-second count of a 23:59:60 epoch is the one before it
        leap = leap_seconds(day + np.minimum(tod, 86399.0))
    except ValueError:
        raise DataError(path, int(line_no[0]), f"date {epochs[0]['date']} is before the GPS epoch "
                                               "(1980-01-06): the RMC date or date= is wrong") from None
    week = gpst_unix_to_week_sow(day[0] + leap[0] + tod[0])[0]
    sow = (day + leap - GPS_EPOCH_UNIX - week * SECONDS_PER_WEEK) + tod
    d = np.diff(sow)
    if np.any(d <= 0):
        i = int(np.argmax(d <= 0)) + 1
        raise DataError(path, int(line_no[i]), f"epoch time {sow[i]:.3f} s of week does not increase "
                                               f"(previous {sow[i - 1]:.3f} s, line {int(line_no[i - 1])}): "
                                               "a receiver restart or two logs joined; split the file")
    return week, sow, leap


def _dates(path, epochs: list[dict], date) -> None:
    """Each epoch's UTC date: RMC's date, carried forward with roll-over at midnight; epochs before the
    first RMC take the first RMC's date (walking back over midnight); ``date`` for logs without RMC."""
    if date is not None and not isinstance(date, _dt.date):
        try:
            date = _dt.date.fromisoformat(str(date))
        except ValueError:
            raise DataError(path, None, f"date {date!r}: expected YYYY-MM-DD") from None
    for e in epochs:
        e["rmc_date"] = _date(_field(e["rmc"][0], 8)) if "rmc" in e else None
    first_rmc = next((e for e in epochs if e["rmc_date"] is not None), None)
    if first_rmc is None and date is None:
        raise DataError(path, None, "no RMC sentence with a date: NMEA GGA carries only the time of day; "
                                    "the date must come from RMC (or ZDA) sentences: log them, or in Python "
                                    "read the file with aidnav.io.nmea.read_nmea(path, date='YYYY-MM-DD') "
                                    "and write an interchange file (aidnav.io.interchange.write_gnss)")
    if first_rmc is not None:
        day = first_rmc["rmc_date"]
        k0 = epochs.index(first_rmc)
        for k in range(k0, -1, -1):  # walk back from the first RMC to the start (roll-over backwards)
            if k < k0 and epochs[k]["tod"] > epochs[k + 1]["tod"] + 43200:
                day = day - _dt.timedelta(days=1)
            epochs[k]["date"] = day
        day = first_rmc["rmc_date"]
        start = k0 + 1
    else:
        day = date
        epochs[0]["date"] = day
        start = 1
    for k in range(start, len(epochs)):
        e = epochs[k]
        if e["rmc_date"] is not None:
            day = e["rmc_date"]
        elif e["tod"] < epochs[k - 1]["tod"] - 43200:
            day = day + _dt.timedelta(days=1)
        e["date"] = day


def _velocity(e: dict) -> tuple[float, float]:
    """(ve, vn) [m/s] of an epoch from RMC (status A) or else VTG; NaN when neither says."""
    spd = crs = math.nan
    if "rmc" in e and _field(e["rmc"][0], 1) == "A" and _field(e["rmc"][0], 6):
        spd, crs = _f(_field(e["rmc"][0], 6)) * KNOT, _f(_field(e["rmc"][0], 7))
    elif "vtg" in e:
        v = e["vtg"][0]
        spd, crs = _f(_field(v, 6)) / 3.6, _f(_field(v, 0))
        if math.isnan(spd):
            spd = _f(_field(v, 4)) * KNOT
    if math.isnan(spd):
        return math.nan, math.nan
    if spd == 0.0:
        return 0.0, 0.0
    if math.isnan(crs):
        return math.nan, math.nan
    return spd * math.sin(math.radians(crs)), spd * math.cos(math.radians(crs))


def _heights(name: str, alt: np.ndarray, sep: np.ndarray, events: list[str]) -> tuple[np.ndarray, str]:
    """Ellipsoidal heights (MSL + separation) and the datum; see the module docstring."""
    have = ~np.isnan(sep)
    if not have.any():
        events.append(f"{name}: no GGA gives the geoid separation: heights are above mean sea level "
                      "(gnss.height_offset_m, the geoid undulation, turns them ellipsoidal)")
        return alt.copy(), "msl"
    if not have.all():
        idx = np.flatnonzero(have)
        j = np.clip(np.searchsorted(idx, np.arange(len(sep))), 1, len(idx) - 1) if len(idx) > 1 else \
            np.zeros(len(sep), dtype=int)
        if len(idx) > 1:
            k = np.arange(len(sep))
            j = np.where(np.abs(idx[j - 1] - k) <= np.abs(idx[j] - k), j - 1, j)
        sep = np.where(have, sep, sep[idx[j]])
        events.append(f"{name}: {int((~have).sum())} GGA sentence(s) without geoid separation: the nearest "
                      "given separation is used there")
    return alt + sep, "ellipsoid"


def _sigma(name: str, gst: np.ndarray, hdop: np.ndarray, events: list[str]) -> np.ndarray:
    """σ ENU per epoch: GST where given, else HDOP × UERE (module docstring), else NaN."""
    sp = gst.copy()
    no_gst = np.isnan(sp).any(axis=1)
    use = no_gst & np.isfinite(hdop) & (hdop > 0)
    sp[use] = hdop[use, None] * NMEA_UERE_M * np.array([1.0, 1.0, 2.0])
    n_gst = int((~no_gst).sum())
    if use.any():
        events.append(f"{name}: position σ of {int(use.sum())} epoch(s) without GST from the GGA HDOP: "
                      f"σE = σN = HDOP × {NMEA_UERE_M:g} m (UERE), σU = 2 × HDOP × {NMEA_UERE_M:g} m"
                      + (f"; {n_gst} epoch(s) from GST" if n_gst else ""))
    elif n_gst:
        events.append(f"{name}: position σ from GST ({n_gst} epochs)")
    return sp
