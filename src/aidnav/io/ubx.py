"""u-blox UBX logs: the receiver's own fixes (UBX-NAV-PVT) → :class:`aidnav.data.GnssData`, via ``pyubx2``.

Per NAV-PVT message (u-blox interface description, UBX-NAV-PVT):

* time: the UTC date/time fields with ``nano`` (when ``validDate`` and ``validTime``) converted to
  GPST with the leap seconds (:mod:`aidnav.io.gpstime`) give the epoch to the ns and the GPS week;
  they must agree with ``iTOW`` (GPS time of week [ms], rounded to the ms) within 1 s or the file is
  refused (wrong leap-second table or corrupt data); epochs without a valid UTC time use ``iTOW``.
  Returned as seconds of week of the first epoch's week (stated in the events).
* position: ``lat``, ``lon`` [deg], ``height`` [mm] above the **ellipsoid** → [m] (``hMSL`` is not
  used: no datum offset is needed for NAV-PVT).
* velocity: ``velN, velE, velD`` [mm/s] → ENU [m/s] = [velE, velN, −velD] / 1000.
* σ: u-blox accuracy estimates taken as 1σ per axis: E = N = ``hAcc``, U = ``vAcc`` [mm → m], each
  velocity component ``sAcc`` [mm/s → m/s] (σ = 0 floored, see :mod:`aidnav.io._std`).
* kept only when ``gnssFixOK`` = 1, ``fixType`` 3 (3-D) or 4 (GNSS + dead reckoning) and not
  ``invalidLlh``; others are counted in the events. quality (RTKLIB Q): ``carrSoln`` 2 → 1 (fixed),
  1 → 2 (float), else ``diffSoln`` → 4 (DGPS), else 5 (single).

Other UBX messages (RAWX, SFRBX ...) and NMEA mixed into the log are skipped (counted); frames with a
bad checksum are skipped and counted. No NAV-PVT at all raises :class:`DataError` (a raw-only log
needs RINEX conversion and the tight filter).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from aidnav.data import GnssData
from aidnav.io._std import (
    DEFAULT_POS_STD_M,
    DEFAULT_VEL_STD_M_S,
    ZERO_POS_STD_FLOOR_M,
    ZERO_VEL_STD_FLOOR_M_S,
    check_std,
)
from aidnav.io.errors import DataError
from aidnav.io.gpstime import GPS_EPOCH_UNIX, SECONDS_PER_WEEK, utc_unix_to_gpst_unix


def _no_frame(errors: list[str]) -> str:
    """Why no UBX frame was read: every frame refused (bad checksums: a corrupted file), or none there."""
    if not errors:
        return "; no UBX frame found"
    what = "a bad checksum" if any("checksum" in e.lower() for e in errors) else "an unreadable frame"
    return (f"; every UBX frame was refused ({len(errors)}, {what}; first: {errors[0]}): the log was "
            "corrupted (bytes changed in transfer?) — use the receiver's original file")


def _utc_unix(p) -> float:
    d = np.datetime64(f"{p.year:04d}-{p.month:02d}-{p.day:02d}T{p.hour:02d}:{p.min:02d}:{p.second:02d}", "s")
    return float(d.astype(np.int64)) + p.nano * 1e-9


def read_ubx(path, min_pos_std_m: float = ZERO_POS_STD_FLOOR_M,
             min_vel_std_m_s: float = ZERO_VEL_STD_FLOOR_M_S) -> GnssData:
    """Read the NAV-PVT fixes of a UBX log → GnssData (GPS seconds of week [s], lat/lon [rad],
    ellipsoidal height [m], ENU velocity [m/s], σ ENU [m], [m/s], RTKLIB-style quality). See the module
    docstring for the fields and the time conversion."""
    from pyubx2 import ERR_LOG, UBX_PROTOCOL, UBXReader  # lazy: pyubx2 is heavy to import

    path = Path(path)
    name = path.name
    errors: list[str] = []
    ids: Counter = Counter()
    rows = []
    skipped: Counter = Counter()
    try:
        f = open(path, "rb")
    except OSError as e:
        raise DataError(path, None, f"cannot read file: {e.strerror or e}") from None
    with f:
        rdr = UBXReader(f, protfilter=UBX_PROTOCOL, quitonerror=ERR_LOG,
                        errorhandler=lambda err: errors.append(str(err)))
        for _raw, p in rdr:
            if p is None:
                continue
            ids[p.identity] += 1
            if p.identity != "NAV-PVT":
                continue
            if not p.gnssFixOk:
                skipped["gnssFixOK = 0"] += 1
                continue
            if p.fixType not in (3, 4):
                skipped[f"fixType {p.fixType}"] += 1
                continue
            if getattr(p, "invalidLlh", 0):
                skipped["invalidLlh"] += 1
                continue
            utc = _utc_unix(p) if (p.validDate and p.validTime) else np.nan
            q = 1 if p.carrSoln == 2 else 2 if p.carrSoln == 1 else 4 if p.diffSoln else 5
            rows.append((p.iTOW * 1e-3, utc, p.lat, p.lon, p.height * 1e-3, p.velE * 1e-3, p.velN * 1e-3,
                         -p.velD * 1e-3, p.hAcc * 1e-3, p.vAcc * 1e-3, p.sAcc * 1e-3, q, ids["NAV-PVT"]))
    events: list[str] = []
    other = {k: v for k, v in ids.items() if k != "NAV-PVT"}
    if other:
        events.append(f"{name}: UBX messages not used: "
                      + ", ".join(f"{v} × {k}" for k, v in sorted(other.items())))
    if errors:
        events.append(f"{name}: {len(errors)} unreadable UBX frame(s) skipped (first: {errors[0]})")
    for why, n in sorted(skipped.items()):
        events.append(f"{name}: {n} NAV-PVT epoch(s) without a usable fix ({why}) skipped")
    if not ids["NAV-PVT"]:
        raise DataError(path, None, "no UBX-NAV-PVT message: aidnav reads the receiver's fixes from "
                        "NAV-PVT (a raw RXM-RAWX log needs RINEX conversion, e.g. RTKLIB convbin, and "
                        "'aidnav tight')" + (f"; found {', '.join(sorted(ids))}" if ids else
                                             _no_frame(errors)))
    if not rows:
        raise DataError(path, None, "no NAV-PVT message with a valid 3-D fix")
    a = np.array(rows, dtype=float)
    msg_no = a[:, 12].astype(np.int64)
    itow = a[:, 0]
    ok_utc = np.isfinite(a[:, 1])
    if ok_utc.any():
        t_gpst = utc_unix_to_gpst_unix(a[ok_utc, 1])
        weeks = np.round((t_gpst - GPS_EPOCH_UNIX - itow[ok_utc]) / SECONDS_PER_WEEK)
        resid = t_gpst - (GPS_EPOCH_UNIX + weeks * SECONDS_PER_WEEK + itow[ok_utc])
        if np.any(np.abs(resid) > 1.0):
            k = int(np.argmax(np.abs(resid) > 1.0))
            raise DataError(path, None, f"NAV-PVT #{msg_no[ok_utc][k]}: UTC fields and iTOW disagree by "
                                        f"{resid[k]:+.3f} s after the leap seconds")
        # week of every epoch: carried from the nearest epoch with a valid date
        wk = np.interp(np.arange(len(a)), np.flatnonzero(ok_utc), weeks)
        wk = np.round(wk)
        week = int(wk[0])
        # a log that crosses the week end: iTOW restarts at 0; count on past 604800 s
        sow = itow + (wk - week) * SECONDS_PER_WEEK
        # iTOW is rounded to the ms; the UTC fields with ``nano`` give the epoch to the ns: use them
        sow[ok_utc] = t_gpst - GPS_EPOCH_UNIX - week * SECONDS_PER_WEEK
        wmsg = (f"time = GPS seconds of week {week} (UTC date/time + nano + leap seconds, checked against "
                "iTOW; iTOW where the UTC time is not valid)")
    else:
        week = None
        sow = itow
        wmsg = "time = GPS seconds of week (iTOW); GPS week unknown (no valid UTC date in the log)"
    d = np.diff(sow)
    bad = d <= 0
    if bad.any():
        k = int(np.argmax(bad)) + 1
        raise DataError(path, None, f"NAV-PVT #{msg_no[k]}: epoch {sow[k]:.3f} s of week does not increase "
                                    f"(previous {sow[k - 1]:.3f} s)")

    def line_of(i):
        return f"NAV-PVT #{msg_no[i]}"

    std_pos = check_std(path, a[:, [8, 8, 9]], ["hAcc", "hAcc", "vAcc"], line_of, "position",
                        DEFAULT_POS_STD_M, min_pos_std_m, "m", events)
    std_vel = check_std(path, a[:, [10, 10, 10]], ["sAcc"] * 3, line_of, "velocity", DEFAULT_VEL_STD_M_S,
                        min_vel_std_m_s, "m/s", events)
    events.append(f"{name}: UBX NAV-PVT; {wmsg}; {len(a)} epochs; ellipsoidal height; σ = hAcc (E, N), vAcc "
                  "(U), sAcc (velocity)")
    return GnssData(sow, np.radians(a[:, 2]), np.radians(a[:, 3]), a[:, 4], vel=a[:, 5:8], std_pos=std_pos,
                 std_vel=std_vel, quality=a[:, 11].astype(np.int64), events=events, week=week,
                 height_datum="ellipsoid")
