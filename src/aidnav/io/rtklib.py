"""Reader of RTKLIB solution files (``.pos`` text) → :class:`aidnav.data.GnssData`.

Supported layout (RTKLIB ``outsol`` with lat/lon/height in degrees, time in GPST)::

    % header lines start with '%'
    date time lat(deg) lon(deg) height(m) Q ns sdn sde sdu sdne sdeu sdun age ratio
    [vn ve vu sdvn sdve sdvu [sdvne sdveu sdvun]]

with the time either as calendar GPST ``YYYY/MM/DD HH:MM:SS.sss`` or as ``week tow``. Standard
deviations are in NEU order in the file (m, m/s) and are returned in ENU order; velocities are
returned as ENU [ve, vn, vu] (vu positive up).

Time tags: positions and velocities are both kept at the line's stamp (RTKLIB writes the solution's
state at its epoch; no reader shifts a velocity, docs/conventions.md "Time"). Files in this layout need
not come from RTKLIB: the rtklibexplorer ``*_sf.pos`` files are the u-blox receiver's UBX-NAV-PVT
(lat, lon, hMSL, velN/velE/−velD, carrSoln → Q, numSV, hAcc/√2, sAcc/√2, the UTC time + 18 s written to
the ms), whose velocity is 0.13 s late on its positions (measured: docs/results.md, issue 40 session 11);
score a velocity against such a file with :mod:`aidnav.analysis.velocity_reference`.
"""

from __future__ import annotations

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
from aidnav.io.gpstime import calendar_to_week_sow

GAP_FACTOR = 5.0  #: an epoch interval above this multiple of the median one is reported as a gap
_N_POS = 13  # numeric columns after the time: lat lon h Q ns sdn sde sdu sdne sdeu sdun age ratio
_VALID_NUMERIC = (_N_POS, _N_POS + 6, _N_POS + 9)  # without velocity, velocity + σ, + covariances


def _check_header(path: Path, header: list[tuple[int, str]]):
    """Refuse the RTKLIB output options this reader does not convert (named in the error)."""
    for ln, h in header:
        low = h.lower()
        if "latitude" in low and ("utc" in low.split() or "jst" in low.split()):
            raise DataError(path, ln, "time system is not GPST (UTC/JST): write the solution in GPST")
        if "x-ecef" in low or "e-baseline" in low:
            raise DataError(path, ln, "ECEF/ENU-baseline solution format not supported: use lat/lon/height")
        if "latitude(d'\")" in low or "latitude(dms)" in low:
            raise DataError(path, ln, "lat/lon in deg-min-sec not supported: use decimal degrees")


def _split_lines(path: Path):
    """The file's lines → header lines ``(line, text)``, data line numbers, data tokens, and whether
    the file ends with a line end."""
    text = path.read_text(encoding="ascii", errors="replace")
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
        ends_newline = True
    else:
        ends_newline = False

    header: list[tuple[int, str]] = []
    data_ln: list[int] = []
    tokens: list[list[str]] = []
    for i, line in enumerate(lines, start=1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("%"):
            header.append((i, s))
            continue
        data_ln.append(i)
        tokens.append(s.split())
    return header, data_ln, tokens, ends_newline


def _find_problems(tokens: list[list[str]], expected: int, calendar: bool):
    """Every malformed line: wrong field count, a field that is not a finite number, bad time →
    ``problems`` {data index: what}, the indices with the expected field count, their numeric fields."""
    problems: dict[int, str] = {}
    for k, t in enumerate(tokens):
        if len(t) != expected:
            problems[k] = f"{len(t)} fields, expected {expected}"
    ok_idx = [k for k in range(len(tokens)) if k not in problems]
    try:
        num = np.array([tokens[k][2:] for k in ok_idx], dtype=float)
    except ValueError:
        num = np.full((len(ok_idx), expected - 2), np.nan)
        for j, k in enumerate(ok_idx):
            try:
                num[j] = np.array(tokens[k][2:], dtype=float)
            except ValueError as e:
                problems[k] = f"not a number ({e})"
    for j in np.flatnonzero(~np.isfinite(num).all(axis=1)):
        problems.setdefault(ok_idx[j], "NaN or inf value")
    if calendar:
        strings = [f"{tokens[k][0]} {tokens[k][1]}" for k in ok_idx]
        try:
            calendar_to_week_sow(strings)
        except ValueError:
            for j, k in enumerate(ok_idx):
                try:
                    calendar_to_week_sow(strings[j])
                except ValueError as e:
                    problems.setdefault(k, f"time not readable ({e})")
    else:
        for k in ok_idx:
            try:
                float(tokens[k][0]), float(tokens[k][1])
            except ValueError:
                problems.setdefault(k, f"time 'week tow' not readable: {tokens[k][0]} {tokens[k][1]}")
    return problems, ok_idx, num


def _times(tok: list[list[str]], calendar: bool):
    """The kept lines' time tokens → (week of the first epoch, GPS seconds of that week)."""
    if calendar:
        week_each, _ = calendar_to_week_sow([f"{t[0]} {t[1]}" for t in tok])
        week = int(week_each[0])
        _, sow = calendar_to_week_sow([f"{t[0]} {t[1]}" for t in tok], week=week)
    else:
        wk = np.array([t[0] for t in tok], dtype=float)
        tow = np.array([t[1] for t in tok], dtype=float)
        week = int(wk[0])
        sow = (wk - week) * 604800.0 + tow
    return week, sow


def _check_times(path: Path, sow, ln: list[int], events: list[str]):
    """Refuse time going backwards; report gaps > ``GAP_FACTOR`` × the median interval in ``events``."""
    name = path.name
    dts = np.diff(sow)
    back = np.flatnonzero(dts <= 0)
    if len(back):
        k = int(back[0]) + 1
        raise DataError(path, ln[k], f"time {sow[k]:.3f} s of week does not increase "
                                     f"(previous {sow[k - 1]:.3f} s)")
    if len(dts):
        med = float(np.median(dts))
        gaps = np.flatnonzero(dts > GAP_FACTOR * med)
        for k in gaps[:10]:
            events.append(f"{name}:{ln[k + 1]}: gap of {dts[k]:.3f} s before this epoch "
                          f"(median interval {med:.3f} s)")
        if len(gaps) > 10:
            events.append(f"{name}: {len(gaps) - 10} more gaps > {GAP_FACTOR:g}× the median interval")


def read_pos(path, height_offset_m: float = 0.0, min_pos_std_m: float = ZERO_POS_STD_FLOOR_M,
             min_vel_std_m_s: float = ZERO_VEL_STD_FLOOR_M_S) -> GnssData:
    """Read an RTKLIB ``.pos`` solution (GPST, lat/lon in degrees) into :class:`GnssData`.

    path : the ``.pos`` file.
    height_offset_m : added to every height [m]. RTKLIB writes ellipsoidal heights, but the
        rtklibexplorer sets (``gnss_1934_sf.pos``, ``gnss_1730_sf.pos``) hold heights above mean sea
        level (u-blox NAV-PVT ``hMSL``): pass the geoid undulation there, −21.4 m, to get the
        ellipsoidal height aidnav uses (h_ellipsoid = h_file + height_offset_m).

    Returns GnssData with time in **GPS seconds of week** (of the first epoch's week; counted on past
    604800 s if the file crosses a week end; the week is named in ``events``), lat/lon [rad],
    height [m], std_pos ENU [m] (= sde, sdn, sdu of the file), vel ENU [m/s] (= ve, vn, vu) and
    std_vel ENU [m/s] when the file has velocity columns, quality = Q (1 fix, 2 float, 5 single ...).

    σ = 0 is floored to ``min_pos_std_m`` / ``min_vel_std_m_s`` with a warning event; a negative σ
    is refused (:mod:`aidnav.io._std`).

    Raises :class:`DataError` "file:line: problem" for a malformed line, an unsupported format or
    time going backwards. Only a malformed *last* line (a file cut while being written) is skipped and
    reported in ``events``. Gaps > 5× the median epoch interval are reported in ``events``.
    """
    path = Path(path)
    name = path.name
    events: list[str] = []
    header, data_ln, tokens, ends_newline = _split_lines(path)
    _check_header(path, header)
    if not tokens:
        raise DataError(path, None, "no solution lines")

    # the time takes two tokens: 'YYYY/MM/DD HH:MM:SS.sss' or 'week tow'
    calendar = "/" in tokens[0][0] or "-" in tokens[0][0]
    expected = len(tokens[0])
    if expected - 2 not in _VALID_NUMERIC:
        raise DataError(path, data_ln[0], f"{expected} fields; expected "
                                          f"{', '.join(str(n + 2) for n in _VALID_NUMERIC)}")
    problems, ok_idx, num = _find_problems(tokens, expected, calendar)
    if problems:
        first = min(problems)
        last = len(tokens) - 1
        if first < last or last == 0:
            raise DataError(path, data_ln[first], problems[first])
        tail = "" if ends_newline else " (no line end)"
        events.append(f"{name}:{data_ln[last]}: {problems[last]}; truncated last line{tail} skipped")
        keep = ok_idx[:-1] if ok_idx and ok_idx[-1] == last else ok_idx
        num = num[: len(keep)]
    else:
        keep = ok_idx
    tok = [tokens[k] for k in keep]
    ln = [data_ln[k] for k in keep]
    n = len(tok)
    week, sow = _times(tok, calendar)
    _check_times(path, sow, ln, events)

    lat = np.radians(num[:, 0])
    lon = np.radians(num[:, 1])
    if np.any(np.abs(lat) > np.pi / 2):
        k = int(np.flatnonzero(np.abs(lat) > np.pi / 2)[0])
        raise DataError(path, ln[k], f"latitude {num[k, 0]} deg out of range")
    height = num[:, 2] + height_offset_m
    quality = np.round(num[:, 3]).astype(int)
    def line_of(i):
        return ln[i]

    # sde, sdn, sdu (file: sdn sde sdu); σ = 0 floored, negative refused (aidnav.io._std)
    std_pos = check_std(path, num[:, [6, 5, 7]], ["sde(m)", "sdn(m)", "sdu(m)"], line_of, "position",
                        DEFAULT_POS_STD_M, min_pos_std_m, "m", events)
    vel = std_vel = None
    if expected - 2 > _N_POS:
        vel = num[:, [14, 13, 15]]  # ve, vn, vu (file: vn ve vu)
        std_vel = check_std(path, num[:, [17, 16, 18]], ["sdve", "sdvn", "sdvu"], line_of, "velocity",
                            DEFAULT_VEL_STD_M_S, min_vel_std_m_s, "m/s", events)
    events.append(f"{name}: time = GPS seconds of week {week}; {n} epochs"
                  + (f"; height offset {height_offset_m:+.3f} m added" if height_offset_m else ""))
    # RTKLIB's header states the height kind: "(lat/lon/height=WGS84/ellipsoidal,…)" or ".../geodetic"
    # (above the geoid, i.e. MSL); a file without that line does not say
    head = " ".join(h for _, h in header).lower()
    datum = "ellipsoid" if "/ellipsoidal" in head else "msl" if "/geodetic" in head else "unknown"
    return GnssData(sow, lat, lon, height, vel=vel, std_pos=std_pos, std_vel=std_vel,
                    quality=quality, events=events, week=week, height_datum=datum,
                    height_offset_m=float(height_offset_m))
