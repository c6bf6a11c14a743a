"""RINEX navigation and observation files (GPS) → aidnav arrays, read with georinex.

Times are GPS time on a *reference-week* scale (:mod:`aidnav.nav.gnss_sat`): seconds from the start of
``ref_week``; for an observation file ``ref_week`` is the week of its first epoch, and the ephemerides
read for it should be put on the same scale (:meth:`GpsEphemerides.to_week`).

* :func:`read_rinex_nav`: GPS LNAV broadcast ephemerides → :class:`GpsEphemerides` (one row per record in
  the column layout of :mod:`aidnav.nav.gnss_sat`, toe/toc on the reference-week scale), plus the
  Klobuchar coefficients of the header when present.
* :func:`read_rinex_obs`: GPS code, Doppler and C/N0 (L1 C/A and, when present, an L2 code) →
  :class:`GnssObservations`. Epoch times are read from the file's epoch lines themselves (exact to the
  7 decimals of RINEX 3; georinex's datetimes are truncated to microseconds). Doppler [Hz] is kept
  as in the file (positive for an approaching satellite); :meth:`GnssObservations.range_rate` gives the
  pseudorange rate −λ·D [m/s].

georinex prints many xarray ``FutureWarning``s while loading; they are silenced here.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from aidnav.io.errors import DataError
from aidnav.io.gpstime import SECONDS_PER_WEEK, calendar_to_week_sow
from aidnav.nav.gnss_sat import (
    E_AF0,
    E_AF1,
    E_AF2,
    E_CIC,
    E_CIS,
    E_CRC,
    E_CRS,
    E_CUC,
    E_CUS,
    E_DN,
    E_ECC,
    E_FIT,
    E_HEALTH,
    E_I0,
    E_IDOT,
    E_IODE,
    E_M0,
    E_OMEGA,
    E_OMEGA0,
    E_OMEGADOT,
    E_PRN,
    E_SQRTA,
    E_TGD,
    E_TOC,
    E_TOE,
    E_URA,
    E_WEEK,
    N_EPH,
)
from aidnav.nav.gnss_types import GnssObservations, GpsEphemerides

__all__ = ["GpsEphemerides", "GnssObservations", "read_rinex_nav", "read_rinex_obs"]


def _load(path: Path, **kw):
    import georinex as gr  # lazy: georinex is heavy to import

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        warnings.simplefilter("ignore", DeprecationWarning)
        try:
            return gr.load(path, **kw)
        except Exception as e:  # georinex raises a variety of errors for bad files
            raise DataError(path, None, f"georinex cannot read this RINEX file: {e}") from e


def _dt64_to_week_sow(t: np.ndarray):
    s = np.datetime_as_string(np.asarray(t).astype("datetime64[ns]"), unit="ns")
    return calendar_to_week_sow(s)


def read_rinex_nav(path, ref_week: int | None = None) -> GpsEphemerides:
    """Read the GPS records of a RINEX 2/3 navigation file.

    ref_week : week of the time scale (default: the week of the earliest toc). Records with a NaN
    field are dropped and reported in ``events``. Returns :class:`GpsEphemerides`.
    """
    path = Path(path)
    if not path.exists():
        raise DataError(path, None, "file not found")
    nav = _load(path, use="G")
    events: list[str] = []
    if "sv" not in nav.dims or nav.sizes.get("sv", 0) == 0:
        raise DataError(path, None, "no GPS ephemeris in this navigation file")
    rows = []
    wk_toc, sow_toc = _dt64_to_week_sow(nav.time.values)
    wk_toc = np.atleast_1d(wk_toc)
    sow_toc = np.atleast_1d(sow_toc)
    if ref_week is None:
        ref_week = int(np.min(wk_toc))
    get = {k: nav[k].values for k in nav.data_vars}
    need = ("sqrtA", "GPSWeek", "Toe", "Eccentricity", "M0")
    if "time" not in nav.dims or any(k not in get for k in need):
        missing = ", ".join(k for k in need if k not in get)
        raise DataError(path, None, f"not a RINEX navigation file (no GPS ephemeris fields: {missing}; "
                        f"found {', '.join(list(get)[:6]) or 'none'}): is it an observation file? Give "
                        "the navigation (ephemeris) file to --nav and the observation file to --obs")
    for it in range(nav.sizes["time"]):
        for js, sv in enumerate(nav.sv.values):
            sv = str(sv)
            if not sv.startswith("G"):
                continue
            if np.isnan(get["sqrtA"][it, js]):
                continue
            r = np.zeros(N_EPH)
            r[E_PRN] = int(sv[1:])
            week = get["GPSWeek"][it, js]
            r[E_WEEK] = week
            r[E_TOE] = (week - ref_week) * SECONDS_PER_WEEK + get["Toe"][it, js]
            r[E_TOC] = (wk_toc[it] - ref_week) * SECONDS_PER_WEEK + sow_toc[it]
            r[E_AF0] = get["SVclockBias"][it, js]
            r[E_AF1] = get["SVclockDrift"][it, js]
            r[E_AF2] = get["SVclockDriftRate"][it, js]
            r[E_SQRTA] = get["sqrtA"][it, js]
            r[E_ECC] = get["Eccentricity"][it, js]
            r[E_I0] = get["Io"][it, js]
            r[E_OMEGA0] = get["Omega0"][it, js]
            r[E_OMEGA] = get["omega"][it, js]
            r[E_M0] = get["M0"][it, js]
            r[E_DN] = get["DeltaN"][it, js]
            r[E_IDOT] = get["IDOT"][it, js]
            r[E_OMEGADOT] = get["OmegaDot"][it, js]
            r[E_CUC] = get["Cuc"][it, js]
            r[E_CUS] = get["Cus"][it, js]
            r[E_CRC] = get["Crc"][it, js]
            r[E_CRS] = get["Crs"][it, js]
            r[E_CIC] = get["Cic"][it, js]
            r[E_CIS] = get["Cis"][it, js]
            r[E_TGD] = get["TGD"][it, js] if "TGD" in get else 0.0
            r[E_HEALTH] = get["health"][it, js] if "health" in get else 0.0
            r[E_IODE] = get["IODE"][it, js] if "IODE" in get else 0.0
            r[E_URA] = get["SVacc"][it, js] if "SVacc" in get else np.nan
            fit = get["FitIntvl"][it, js] if "FitIntvl" in get else 4.0
            r[E_FIT] = 4.0 if not np.isfinite(fit) or fit == 0 else fit
            bad = [k for k in range(N_EPH) if k != E_URA and not np.isfinite(r[k])]
            if bad:
                events.append(
                    f"{path.name}: {sv} record at toc {sow_toc[it]:.0f} has missing fields; dropped"
                )
                continue
            rows.append(r)
    if not rows:
        raise DataError(path, None, "no complete GPS ephemeris record in this navigation file")
    table = np.array(rows)
    table = table[np.lexsort((table[:, E_TOE], table[:, E_PRN]))]
    alpha = beta = None
    for key in ("ionospheric_corr_GPS", "ionospheric_corr"):
        ic = nav.attrs.get(key)
        if isinstance(ic, dict) and "GPSA" in ic and "GPSB" in ic:
            alpha, beta = np.asarray(ic["GPSA"], float), np.asarray(ic["GPSB"], float)
        elif ic is not None and np.size(ic) == 8:
            a = np.asarray(ic, float).ravel()
            alpha, beta = a[:4], a[4:]
        if alpha is not None:
            break
    if alpha is None:
        events.append(f"{path.name}: no GPS Klobuchar coefficients in the header")
    unhealthy = int(np.sum(table[:, E_HEALTH] != 0))
    if unhealthy:
        events.append(f"{path.name}: {unhealthy} record(s) flagged unhealthy (not used)")
    return GpsEphemerides(table, int(ref_week), alpha, beta, events)


def _epoch_lines(path: Path) -> np.ndarray:
    """Exact epoch times (datetime strings) of a RINEX 3 observation file, from its '>' lines."""
    out = []
    with open(path, encoding="ascii", errors="replace") as f:
        for line in f:
            if line.startswith(">") and len(line) > 29:
                flag = line[31:32].strip() or "0"
                if flag not in ("0", "1"):
                    continue
                y, mo, d, hh, mi = (int(x) for x in line[1:29].split()[:5])
                sec = line[1:29].split()[5]
                whole, _, frac = sec.partition(".")
                out.append(
                    f"{y:04d}-{mo:02d}-{d:02d}T{hh:02d}:{mi:02d}:{int(whole):02d}.{(frac + '0' * 9)[:9]}"
                )
    return np.array(out)


def _lli_rinex3(path: Path, code: str, prn: np.ndarray, n_epochs: int) -> np.ndarray:
    """Loss-of-lock indicators (n_epochs, len(prn)) of the GPS observation ``code`` of a RINEX 3 file, read
    from its fixed columns (value F14.3, LLI I1, SSI I1 per observation; epochs with event flag 0/1, as
    :func:`_epoch_lines`); 0 where blank."""
    out = np.zeros((n_epochs, len(prn)), np.int64)
    col = {int(p): j for j, p in enumerate(prn)}
    types: list[str] = []
    k, use, in_header, cont = -1, False, True, 0
    with open(path, encoding="ascii", errors="replace") as f:
        for line in f:
            if in_header:
                gps = line[0] == "G" or (cont and line[0] == " ")
                if line[60:79].startswith("SYS / # / OBS TYPES") and gps:
                    if line[0] == "G":
                        cont = int(line[3:6])
                    types += line[7:58].split()
                    cont = cont if len(types) < cont else 0
                elif "END OF HEADER" in line:
                    in_header = False
                continue
            if line.startswith(">"):
                flag = line[31:32].strip() or "0"
                use = flag in ("0", "1")
                k += use
                continue
            if not use or line[0] != "G" or code not in types or k >= n_epochs:
                continue
            j = col.get(int(line[1:3]))
            c = 3 + 16 * types.index(code) + 14
            if j is not None and len(line) > c and line[c].isdigit():
                out[k, j] = int(line[c])
    return out


def read_rinex_obs(path, ref_week: int | None = None) -> GnssObservations:
    """Read the GPS L1 C/A code (C1C), Doppler (D1C), C/N0 (S1C), L1 carrier phase (L1C) with its
    loss-of-lock indicator, and an L2 code (C2L/C2S/C2X/C2W/C2P, first present) of a RINEX 3 observation
    file (RINEX 2: C1/P2/D1/S1/L1).

    ref_week : week of the time scale (default: the first epoch's). Returns :class:`GnssObservations`.
    Epochs with a non-zero event flag other than 1 (power failure) are skipped by georinex and here.
    """
    path = Path(path)
    if not path.exists():
        raise DataError(path, None, "file not found")
    obs = _load(path, use="G")
    events: list[str] = []
    if obs.sizes.get("sv", 0) == 0:
        raise DataError(path, None, "no GPS observations in this file")
    names = list(obs.data_vars)

    def first(*cands):
        return next((c for c in cands if c in names), None)

    c1 = first("C1C", "C1")
    d1 = first("D1C", "D1")
    s1 = first("S1C", "S1")
    c2 = first("C2L", "C2S", "C2X", "C2W", "C2P", "P2", "C2")
    if c1 is None:
        raise DataError(path, None, f"no L1 C/A code observation (have {', '.join(names)})")
    exact = _epoch_lines(path) if float(obs.attrs.get("version", 3)) >= 3 else np.array([])
    tt = obs.time.values.astype("datetime64[ns]")
    if len(exact) == len(tt):
        ex = exact.astype("datetime64[ns]")
        if np.all(np.abs((ex - tt).astype(np.int64)) < 2000):
            tt = ex
    else:
        events.append(
            f"{path.name}: epoch lines ({len(exact)}) do not match georinex's epochs ({len(tt)}); "
            "times from georinex (µs resolution)"
        )
    week, sow = _dt64_to_week_sow(np.datetime_as_string(tt, unit="ns"))
    week = np.atleast_1d(week)
    sow = np.atleast_1d(sow)
    if ref_week is None:
        ref_week = int(week[0])
    t = (week - ref_week) * SECONDS_PER_WEEK + sow
    if np.any(np.diff(t) <= 0):
        raise DataError(path, None, "epoch times are not strictly increasing")
    prn = np.array([int(str(s)[1:]) for s in obs.sv.values])

    def arr(k):
        return None if k is None else np.asarray(obs[k].values, float)

    code1 = arr(c1)
    dop = arr(d1) if d1 else np.full_like(code1, np.nan)
    cn0 = arr(s1) if s1 else np.full_like(code1, np.nan)
    code2 = arr(c2)
    l1 = first("L1C", "L1")
    phase1 = arr(l1)
    lli1 = None
    if l1 is not None:
        lli1 = np.zeros(phase1.shape, np.int64)
        if float(obs.attrs.get("version", 3)) >= 3 and len(exact) == len(t):
            lli1 = _lli_rinex3(path, l1, prn, len(t))
        else:
            events.append(f"{path.name}: {l1} loss-of-lock indicators not read (RINEX 2); slips only from "
                          "the phase-Doppler test")
    if d1 is None:
        events.append(f"{path.name}: no L1 Doppler")
    dt = np.diff(t)
    if len(dt):
        med = np.median(dt)
        for k in np.flatnonzero(dt > 5 * med):
            events.append(f"{path.name}: gap of {dt[k]:.2f} s after t={t[k]:.3f}")
    pos = obs.attrs.get("position")
    approx = np.asarray(pos, float) if pos is not None and np.size(pos) == 3 else None
    if approx is not None and not np.any(approx):
        approx = None
    return GnssObservations(t, int(ref_week), prn, code1, dop, cn0, code2, c2, approx, events, phase1, lli1)
