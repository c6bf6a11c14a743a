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

from aidnav.errors import InputError
from aidnav.io.errors import DataError
from aidnav.io.gpstime import SECONDS_PER_WEEK, calendar_to_week_sow, leap_seconds
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
    E_TOES,
    E_URA,
    E_WEEK,
    ERREPH_GLO,
    G_ACC,
    G_FCN,
    G_POS,
    G_VEL,
    N_EPH,
    SYSTEMS,
    sat_id,
    sat_name,
)
from aidnav.nav.gnss_types import GnssObservations, GpsEphemerides

__all__ = ["GpsEphemerides", "GnssObservations", "read_rinex_nav", "read_rinex_obs", "read_rinex_pair",
           "merge_ephemerides", "cnav_span_warning", "CNAV_SPAN_S", "UBX_SOURCES", "UBX_SOURCES_ALL",
           "parse_ubx_sources"]
#: how far [s] from a GPS CNAV row's epoch (the UBX log's middle) the observations may reach before
#: ``read_rinex_pair`` warns: the re-epoched orbit's ½ Δn0-dot τ² term reaches ~0.3 m there (io.gps_cnav)
CNAV_SPAN_S = 600.0
#: what :func:`read_rinex_pair` takes from a UBX log by default (its ``ubx_sources``)
UBX_SOURCES = "inav,lnav,cnav,klobuchar,cpstdev"
#: every source it knows (``rawx``: the RXM-RAWX satellites the observation file lacks; not by default: on
#: the walk its BeiDou code moves the position toward the broadcast frame, away from the offset RTK
#: reference — docs/results.md, issue 40 session 15)
UBX_SOURCES_ALL = UBX_SOURCES + ",rawx"


def _load(path, systems: str):
    """The RINEX file ``path`` read by georinex for the ``systems`` (letters) aidnav knows: (path as a Path,
    the set of those letters, the xarray Dataset). Raises DataError when the file is missing or georinex
    cannot read it."""
    path = Path(path)
    if not path.exists():
        raise DataError(path, None, "file not found")
    use = {s for s in systems if s in SYSTEMS}
    import georinex as gr  # lazy: georinex is heavy to import (after the cheap checks)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        warnings.simplefilter("ignore", DeprecationWarning)
        try:
            return path, use, gr.load(path, use=use)
        except Exception as e:  # georinex raises a variety of errors for bad files
            raise DataError(path, None, f"georinex cannot read this RINEX file: {e}") from e


def _dt64_to_week_sow(t: np.ndarray):
    s = np.datetime_as_string(np.asarray(t).astype("datetime64[ns]"), unit="ns")
    return calendar_to_week_sow(s)


_BDT_GPS_S = 14.0  # GPST − BDT [s]
_BDT_WEEK = 1356  # GPS week of BDT week 0


def _keplerian_row(get, it, js, sid, sys, wk_toc, sow_toc, ref_week):
    """One Keplerian record (GPS, Galileo, BeiDou) on the GPS reference-week scale (module doc)."""
    r = np.zeros(N_EPH)
    r[E_PRN] = sid
    if sys == "C":  # BDT: week − 1356, 14 s behind GPST
        week = get["BDTWeek"][it, js] + _BDT_WEEK
        shift = _BDT_GPS_S
    else:
        week = get["GALWeek" if sys == "E" else "GPSWeek"][it, js]
        shift = 0.0
    r[E_WEEK] = week
    r[E_TOE] = (week - ref_week) * SECONDS_PER_WEEK + get["Toe"][it, js] + shift
    r[E_TOES] = get["Toe"][it, js]
    r[E_TOC] = (wk_toc[it] - ref_week) * SECONDS_PER_WEEK + sow_toc[it] + shift
    for col, key in ((E_AF0, "SVclockBias"), (E_AF1, "SVclockDrift"), (E_AF2, "SVclockDriftRate"),
                     (E_SQRTA, "sqrtA"), (E_ECC, "Eccentricity"), (E_I0, "Io"), (E_OMEGA0, "Omega0"),
                     (E_OMEGA, "omega"), (E_M0, "M0"), (E_DN, "DeltaN"), (E_IDOT, "IDOT"),
                     (E_OMEGADOT, "OmegaDot"), (E_CUC, "Cuc"), (E_CUS, "Cus"), (E_CRC, "Crc"), (E_CRS, "Crs"),
                     (E_CIC, "Cic"), (E_CIS, "Cis")):
        r[col] = get[key][it, js]

    def opt(key, default):
        return get[key][it, js] if key in get else default

    # single-frequency group delay: GPS TGD (L1 C/A), Galileo BGD(E1, E5b) (I/NAV E1-B users), BeiDou TGD1
    r[E_TGD] = {"G": opt("TGD", 0.0), "E": opt("BGDe5b", 0.0), "C": opt("TGD1", 0.0)}[sys]
    r[E_HEALTH] = opt("SatH1", 0.0) if sys == "C" else opt("health", 0.0)
    r[E_IODE] = opt({"G": "IODE", "E": "IODnav", "C": "AODE"}[sys], 0.0)
    r[E_URA] = opt("SISA" if sys == "E" else "SVacc", np.nan)
    fit = opt("FitIntvl", 4.0) if sys == "G" else 4.0
    r[E_FIT] = 4.0 if not np.isfinite(fit) or fit == 0 else fit
    return r


def _glonass_row(get, it, js, sid, t_utc, ref_week):
    """One GLONASS record: the PZ-90 state at t_b (the record's UTC epoch + leap seconds, module doc)."""
    r = np.zeros(N_EPH)
    r[E_PRN] = sid
    unix = t_utc.astype("datetime64[ns]").astype(np.int64) / 1e9
    wk, sow = _dt64_to_week_sow(np.datetime_as_string(t_utc.astype("datetime64[ns]"), unit="ns"))
    tb = (int(wk) - ref_week) * SECONDS_PER_WEEK + float(sow) + leap_seconds(unix)
    r[E_WEEK] = wk
    r[E_TOE] = r[E_TOC] = tb
    r[E_AF0], r[E_AF1] = get["SVclockBias"][it, js], get["SVrelFreqBias"][it, js]  # −τ_n, +γ_n
    for k, ax in enumerate("XYZ"):  # georinex gives metres
        r[G_POS + k], r[G_VEL + k] = get[ax][it, js], get["d" + ax][it, js]
        r[G_ACC + k] = get["d" + ax + "2"][it, js]
    r[G_FCN] = get["FreqNum"][it, js]
    r[E_HEALTH] = get["health"][it, js] if "health" in get else 0.0
    r[E_URA] = ERREPH_GLO
    return r


def _sbas_row(get, it, js, sid, sow_toc, wk_toc, ref_week):
    """One SBAS record: the GEO state at t0 (the record's GPS epoch), clock a_Gf0, a_Gf1."""
    r = np.zeros(N_EPH)
    r[E_PRN] = sid
    r[E_WEEK] = wk_toc[it]
    r[E_TOE] = r[E_TOC] = (wk_toc[it] - ref_week) * SECONDS_PER_WEEK + sow_toc[it]
    r[E_AF0], r[E_AF1] = get["SVclockBias"][it, js], get["SVrelFreqBias"][it, js]
    for k, ax in enumerate("XYZ"):  # georinex gives metres
        r[G_POS + k], r[G_VEL + k] = get[ax][it, js], get["d" + ax][it, js]
        r[G_ACC + k] = get["d" + ax + "2"][it, js]
    r[E_HEALTH] = get["health"][it, js] if "health" in get else 0.0
    ura = get["URA"][it, js] if "URA" in get else np.nan
    r[E_URA] = ura if np.isfinite(ura) and ura > 0 else np.nan
    return r


def read_rinex_nav(path, ref_week: int | None = None, systems: str = "GECR") -> GpsEphemerides:
    """Read the GPS, Galileo, BeiDou and GLONASS records (``systems``: RINEX letters) of a RINEX 2/3
    navigation file.

    ref_week : week of the time scale (default: the week of the earliest toc). Every record is put on the
    GPS scale here (module doc of :mod:`aidnav.nav.gnss_sat`: BDT + 14 s, GLONASS UTC + leap seconds);
    satellites are ids 100·system + PRN (GPS: the PRN). Records with a NaN field are dropped and reported
    in ``events``. Returns :class:`GpsEphemerides`.
    """
    path, use, nav = _load(path, systems)
    events: list[str] = []
    if "sv" not in nav.dims or nav.sizes.get("sv", 0) == 0:
        raise DataError(path, None, f"no {'/'.join(sorted(use))} ephemeris in this navigation file")
    rows = []
    wk_toc, sow_toc = _dt64_to_week_sow(nav.time.values)
    wk_toc = np.atleast_1d(wk_toc)
    sow_toc = np.atleast_1d(sow_toc)
    if ref_week is None:
        ref_week = int(np.min(wk_toc))
    get = {k: nav[k].values for k in nav.data_vars}
    if "time" not in nav.dims or not ({"sqrtA", "X"} & set(get)):
        raise DataError(path, None, f"not a RINEX navigation file (no ephemeris fields; found "
                        f"{', '.join(list(get)[:6]) or 'none'}): is it an observation file? Give "
                        "the navigation (ephemeris) file to --nav and the observation file to --obs")
    for it in range(nav.sizes["time"]):
        for js, sv in enumerate(nav.sv.values):
            sv = str(sv).split("_")[0]  # georinex names a second record at the same time "E01_1"
            sys = sv[0]
            if sys not in use:
                continue
            sid = sat_id(sv)
            if sys in "RS":
                if "X" not in get or np.isnan(get["X"][it, js]):
                    continue
                r = (_glonass_row(get, it, js, sid, nav.time.values[it], int(ref_week)) if sys == "R" else
                     _sbas_row(get, it, js, sid, sow_toc, wk_toc, int(ref_week)))
            else:
                if "sqrtA" not in get or np.isnan(get["sqrtA"][it, js]):
                    continue
                r = _keplerian_row(get, it, js, sid, sys, wk_toc, sow_toc, int(ref_week))
            bad = [k for k in range(N_EPH) if k != E_URA and not np.isfinite(r[k])]
            if bad:
                events.append(
                    f"{path.name}: {sv} record at toc {sow_toc[it]:.0f} has missing fields; dropped"
                )
                continue
            rows.append(r)
    if not rows:
        raise DataError(path, None, "no complete GPS/Galileo/BeiDou/GLONASS ephemeris record in this "
                        "navigation file")
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
    per = {s: int(np.sum(table[:, E_PRN] // 100 == SYSTEMS.index(s))) for s in SYSTEMS}
    if any(per[s] for s in "ECRS"):
        events.append(f"{path.name}: records per system "
                      + ", ".join(f"{s} {n}" for s, n in per.items() if n))
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


#: the first signal aidnav uses per system (code, Doppler, C/N0, phase candidates, first present per
#: satellite): GPS L1 C/A, Galileo E1 (C/X/B), BeiDou B1I (C2I; C1I in RINEX 3.01), GLONASS G1 C/A
_SIGNALS = {"G": (("C1C", "C1"), ("D1C", "D1"), ("S1C", "S1"), ("L1C", "L1")),
            "E": (("C1C", "C1X", "C1B"), ("D1C", "D1X", "D1B"), ("S1C", "S1X", "S1B"), ("L1C", "L1X", "L1B")),
            "C": (("C2I", "C1I"), ("D2I", "D1I"), ("S2I", "S1I"), ("L2I", "L1I")),
            "R": (("C1C", "C1"), ("D1C", "D1"), ("S1C", "S1"), ("L1C", "L1")),
            "S": (("C1C", "C1"), ("D1C", "D1"), ("S1C", "S1"), ("L1C", "L1"))}


def _lli_rinex3(path: Path, phase_code: dict, names: list, n_epochs: int) -> np.ndarray:
    """Loss-of-lock indicators (n_epochs, len(names)) of each system's phase observation ``phase_code[sys]``
    of a RINEX 3 file, read from its fixed columns (value F14.3, LLI I1, SSI I1 per observation; epochs
    with event flag 0/1, as :func:`_epoch_lines`); 0 where blank."""
    out = np.zeros((n_epochs, len(names)), np.int64)
    col = {nm: j for j, nm in enumerate(names)}
    types: dict[str, list[str]] = {}
    k, use, in_header, cur = -1, False, True, ""
    with open(path, encoding="ascii", errors="replace") as f:
        for line in f:
            if in_header:
                if line[60:79].startswith("SYS / # / OBS TYPES"):
                    if line[0] != " ":
                        cur = line[0]
                        types[cur] = []
                    types[cur] += line[7:58].split()
                elif "END OF HEADER" in line:
                    in_header = False
                continue
            if line.startswith(">"):
                flag = line[31:32].strip() or "0"
                use = flag in ("0", "1")
                k += use
                continue
            sv = line[0:3].replace(" ", "0")
            j = col.get(sv)
            if not use or j is None or k >= n_epochs:
                continue
            code = phase_code.get(sv[0])
            if code is None or code not in types.get(sv[0], []):
                continue
            c = 3 + 16 * types[sv[0]].index(code) + 14
            if len(line) > c and line[c].isdigit():
                out[k, j] = int(line[c])
    return out


def read_rinex_obs(path, ref_week: int | None = None, systems: str = "G") -> GnssObservations:
    """Read each system's first signal (``systems``: RINEX letters of G, E, C, R; :data:`_SIGNALS`): code,
    Doppler, C/N0, carrier phase with its loss-of-lock indicator, and for GPS an L2 code
    (C2L/C2S/C2X/C2W/C2P, first present) of a RINEX 3 observation file (RINEX 2: C1/P2/D1/S1/L1).

    ref_week : week of the time scale (default: the first epoch's). Returns :class:`GnssObservations`
    (satellite ids of :mod:`aidnav.nav.gnss_sat`; other systems of the file, e.g. SBAS, are not read and
    named in ``events``). Epochs with a non-zero event flag other than 1 (power failure) are skipped by
    georinex and here. GLONASS frequencies: :meth:`GnssObservations.with_frequencies` with the ephemerides.
    """
    path, use, obs = _load(path, systems)
    events: list[str] = []
    if obs.sizes.get("sv", 0) == 0:
        raise DataError(path, None, f"no {'/'.join(sorted(use))} observations in this file")
    names = list(obs.data_vars)
    svs = [str(v) for v in obs.sv.values]
    svs_ok = [j for j, v in enumerate(svs) if v[0] in use]

    def first(*cands):
        return next((c for c in cands if c in names), None)

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
    T, S = len(t), len(svs_ok)
    prn = np.array([sat_id(svs[j]) for j in svs_ok], np.int64)
    arrays = [np.full((T, S), np.nan) for _ in range(4)]  # code, Doppler, C/N0, phase
    used: dict[str, list] = {}
    for c, j in enumerate(svs_ok):
        sysl = svs[j][0]
        for m, cands in enumerate(_SIGNALS[sysl]):
            for key in cands:
                if key in names:
                    v = np.asarray(obs[key].values[:, j], float)
                    if np.isfinite(v).any():
                        arrays[m][:, c] = v
                        used.setdefault(sysl, [None] * 4)
                        used[sysl][m] = used[sysl][m] or key
                        break
    code1, dop, cn0, phase1 = arrays
    if not np.isfinite(code1).any():
        raise DataError(path, None, f"no first-signal code observation (have {', '.join(names)})")
    gps = np.array([svs[j][0] == "G" for j in svs_ok])
    c2 = first("C2L", "C2S", "C2X", "C2W", "C2P", "P2", "C2") if gps.any() else None
    code2 = None
    if c2 is not None:
        code2 = np.full((T, S), np.nan)
        code2[:, gps] = np.asarray(obs[c2].values, float)[:, [j for j in svs_ok if svs[j][0] == "G"]]
    have_phase = np.isfinite(phase1).any()
    lli1 = None
    if have_phase:
        lli1 = np.zeros((T, S), np.int64)
        if float(obs.attrs.get("version", 3)) >= 3 and len(exact) == len(t):
            lli1 = _lli_rinex3(path, {s_: u[3] for s_, u in used.items() if u[3]}, [svs[j] for j in svs_ok],
                               len(t))
        else:
            events.append(f"{path.name}: phase loss-of-lock indicators not read (RINEX 2); slips only from "
                          "the phase-Doppler test")
    else:
        phase1 = None
    if not np.isfinite(dop).any():
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


_SYSTEM_NAMES = {"G": "GPS", "E": "Galileo", "C": "BeiDou", "R": "GLONASS", "S": "SBAS", "J": "QZSS",
                 "I": "NavIC"}


def _header_systems(path: Path) -> list[str]:
    """System letters with observation types in a RINEX 3 observation header (RINEX 2: none)."""
    out = []
    with open(path, encoding="ascii", errors="replace") as f:
        for line in f:
            if line[60:79].startswith("SYS / # / OBS TYPES") and line[0] != " ":
                out.append(line[0])
            if "END OF HEADER" in line:
                break
    return out


def read_rinex_pair(obs_path, nav_path, systems: str = "GECR", ubx_nav=None,
                    ubx_sources: str = UBX_SOURCES) -> tuple[GnssObservations, GpsEphemerides, list[str]]:
    """The observations of every system of ``systems`` (letters of G, E, C, R, S) that has ephemerides in
    the navigation file, with the ephemerides on the observations' week; ``events`` name the systems of
    the observation file left out and why (no ephemeris; not asked for; QZSS, NavIC: not supported).

    ubx_nav : a u-blox UBX log (or None) whose broadcast ephemerides (RXM-SFRBX) are merged into the
    navigation file's: Galileo I/NAV (:mod:`aidnav.io.galileo_inav`) when ``systems`` has E, GPS LNAV
    (:mod:`aidnav.io.gps_lnav`) and GPS CNAV from L2C/L5 (:mod:`aidnav.io.gps_cnav`) when it has G.
    **The merge rule**: a record is identified by (satellite, IODE/IODnav, toe); a UBX record whose
    identity the navigation file already holds is dropped (the file's record is kept: the same broadcast,
    equal to the RINEX rounding, < 1 mm on the walk); every other Galileo or GPS LNAV record is added
    beside the file's. The ephemeris used at an epoch is then the healthy record of the satellite with the
    nearest toe (:func:`aidnav.nav.gnss_sat.select_ephemeris`; the later record on a tie, and the UBX
    ones sort after the file's of the same toe), so a satellite with a RINEX ephemeris keeps it unless
    the log holds one of a toe nearer the epoch (a newer upload), and a satellite missing from the file
    gets the log's. A GPS CNAV record is added only for a satellite with no LNAV record at all (file or
    log): LNAV is the L1 C/A user's message, CNAV fills the satellites whose LNAV subframes the log lacks.
    When the navigation file has no Klobuchar coefficients, the log's (CNAV type 30) are used.

    ubx_sources : which of the log's data are used, comma-separated (:data:`UBX_SOURCES`, all by default):
    ``inav`` Galileo I/NAV records, ``lnav`` GPS LNAV records, ``cnav`` GPS CNAV records, ``klobuchar`` the
    log's Klobuchar coefficients, ``cpstdev`` the receiver's phase σ of each phase (RXM-RAWX cpStdev,
    :func:`_add_rawx`), ``rawx`` (not by default, :data:`UBX_SOURCES_ALL`) also the RXM-RAWX measurements
    of the systems with an ephemeris that the observation file lacks."""
    if not Path(obs_path).exists():  # a missing observation file is named first (as before)
        raise DataError(Path(obs_path), None, "file not found")
    eph = read_rinex_nav(nav_path, systems=systems)
    if ubx_nav is not None and ("E" in systems or "G" in systems):
        eph = _add_ubx_nav(eph, ubx_nav, systems, ubx_sources)
    have = "".join(c for c in SYSTEMS if np.any(eph.table[:, E_PRN] // 100 == SYSTEMS.index(c)))
    obs = read_rinex_obs(obs_path, systems=have or "G")
    eph = eph.to_week(obs.ref_week) if eph.ref_week != obs.ref_week else eph
    events = []
    if ubx_nav is not None:
        events += cnav_span_warning(eph.table, obs.time, Path(ubx_nav).name)
        sources = parse_ubx_sources(ubx_sources)
        if sources & {"rawx", "cpstdev"}:
            obs = _add_rawx(obs, ubx_nav, have if "rawx" in sources else "", events)
    for c in _header_systems(Path(obs_path)):
        if c in SYSTEMS and c not in systems:
            events.append(f"{Path(obs_path).name}: {_SYSTEM_NAMES[c]} observations not used (systems "
                          f"{systems}; add {c} to gnss.systems to use them)")
        elif c in SYSTEMS and c not in have:
            events.append(f"{Path(obs_path).name}: {_SYSTEM_NAMES[c]} observations but no {_SYSTEM_NAMES[c]} "
                          f"ephemeris in {Path(nav_path).name}: not used")
        elif c not in SYSTEMS:
            events.append(f"{Path(obs_path).name}: {_SYSTEM_NAMES.get(c, c)} observations not used (aidnav "
                          "reads GPS, Galileo, BeiDou, GLONASS and SBAS)")
    return obs, eph, events


def parse_ubx_sources(text: str) -> set[str]:
    """The set of :func:`read_rinex_pair`'s ``ubx_sources`` (comma-separated names of :data:`UBX_SOURCES`);
    an unknown name raises InputError."""
    sources = {x.strip() for x in str(text).split(",") if x.strip()}
    unknown = sources - set(UBX_SOURCES_ALL.split(","))
    if unknown:
        raise InputError(f"UBX navigation source(s) {', '.join(sorted(unknown))} unknown: use a "
                         f"comma-separated subset of {UBX_SOURCES_ALL}")
    return sources


def cnav_span_warning(table: np.ndarray, times: np.ndarray, name: str) -> list[str]:
    """A warning (list of one) when observations at ``times`` reach farther than :data:`CNAV_SPAN_S` from
    the epoch of a GPS CNAV row of ``table`` (IODE −1, :mod:`aidnav.io.gps_cnav`: re-epoched to the middle
    of the UBX log ``name``); else []."""
    cnav = table[:, E_IODE] < 0
    if not cnav.any() or len(times) == 0:
        return []
    far = float(np.max(np.abs(table[cnav, E_TOE][:, None] - np.asarray(times)[[0, -1]][None, :])))
    if far <= CNAV_SPAN_S:
        return []
    return [f"warning: {name}: its GPS CNAV orbits are fitted to the log's own epochs and the observations "
            f"reach {far:.0f} s from them (> {CNAV_SPAN_S:.0f} s: errors over 0.3 m): is the log the one the "
            "observations were converted from?"]


def merge_ephemerides(eph: GpsEphemerides, table: np.ndarray) -> tuple[GpsEphemerides, int]:
    """``eph`` with the rows of ``table`` (same week scale) whose (satellite, IODE, toe) it lacks
    (:func:`read_rinex_pair`'s merge rule), and how many were added."""
    have = {(int(r[E_PRN]), int(r[E_IODE]), round(float(r[E_TOE]))) for r in eph.table}
    new = np.array([r for r in table if (int(r[E_PRN]), int(r[E_IODE]), round(float(r[E_TOE]))) not in have])
    new = new.reshape(-1, N_EPH)
    both = np.vstack([eph.table, new])
    order = np.arange(len(both))  # a tie of toe keeps the file's record first (select_ephemeris: last wins)
    both = both[np.lexsort((order, both[:, E_TOE], both[:, E_PRN]))]
    return GpsEphemerides(both, eph.ref_week, eph.iono_alpha, eph.iono_beta, list(eph.events)), len(new)


def _add_rawx(obs: GnssObservations, ubx_path, have: str, events: list) -> GnssObservations:
    """``obs`` with the UBX log's RXM-RAWX measurements merged in (:func:`aidnav.io.rawx.merge_rawx`): the
    receiver's phase σ (cpStdev) of every phase, and the satellites of the systems of ``have`` (those with
    ephemerides; "" none) of which the observation file has none (the converter did not know their signal:
    the walk's BeiDou B1C) added. A log without RXM-RAWX leaves ``obs`` as it is (an event says so)."""
    from aidnav.io.rawx import merge_rawx, rawx_observations, read_rawx  # lazy: only with a UBX log

    name = Path(ubx_path).name
    try:
        meas = read_rawx(ubx_path)
    except DataError as e:
        events.append(f"{name}: no receiver measurement added ({e.problem})")
        return obs
    in_file = {n[0] for n in obs.names}
    add = "".join(c for c in have if c not in in_file)
    rx = rawx_observations(meas, "".join(in_file) + add, obs.ref_week, obs.time)
    out = merge_rawx(obs, rx, add)
    new = [n for n in out.names if n not in set(obs.names)]
    with_sig = int(np.isfinite(out.phase_sigma1).any(axis=0).sum())
    events.append(f"{name}: the receiver's phase sigma (RXM-RAWX cpStdev) for {with_sig} satellite(s)"
                  + (f"; RXM-RAWX measurements of {len(new)} satellite(s) the observation file lacks added "
                     f"({' '.join(new)}; the signals of aidnav.io.rawx.RAWX_SIGNALS)" if new else ""))
    return out


def _add_ubx_nav(eph: GpsEphemerides, ubx_path, systems: str,
                 ubx_sources: str = UBX_SOURCES) -> GpsEphemerides:
    """``eph`` with the records of the UBX log ``ubx_path`` merged in (:func:`read_rinex_pair`: its rule and
    ``ubx_sources``), on ``eph``'s week. A source with no complete record adds none (an event says so); a
    log where every asked source has none is refused."""
    from aidnav.io.galileo_inav import read_ubx_galileo_inav  # lazy: the UBX decoders only with a log
    from aidnav.io.gps_cnav import read_ubx_gps_cnav  # lazy: as above
    from aidnav.io.gps_lnav import read_ubx_gps_lnav  # lazy: as above
    from aidnav.io.sfrbx import read_sfrbx  # lazy: as above

    sources = parse_ubx_sources(ubx_sources)
    log = read_sfrbx(ubx_path)
    name = Path(ubx_path).name
    events, errors, asked = list(eph.events), [], 0
    for key, letter, reader, what in (("inav", "E", read_ubx_galileo_inav, "Galileo I/NAV"),
                                      ("lnav", "G", read_ubx_gps_lnav, "GPS LNAV"),
                                      ("cnav", "G", read_ubx_gps_cnav, "GPS CNAV")):
        rows = key in sources and letter in systems
        iono = key == "cnav" and "klobuchar" in sources and eph.iono_alpha is None
        if not (rows or iono):
            continue
        asked += rows
        try:
            got = reader(ubx_path, ref_week=eph.ref_week, log=log)
        except DataError as e:
            if rows:
                errors.append(e)
                events.append(f"{name}: no {what} record added ({e.problem})")
            continue
        if iono and got.iono_alpha is not None:  # the file has no Klobuchar coefficients: the log's
            eph = GpsEphemerides(eph.table, eph.ref_week, got.iono_alpha, got.iono_beta, eph.events)
            events.append(f"{name}: GPS Klobuchar coefficients from the log's {what} (the navigation file "
                          "has none): alpha " + ", ".join(f"{a:.3g}" for a in got.iono_alpha) + "; beta "
                          + ", ".join(f"{b:.3g}" for b in got.iono_beta))
        if not rows:
            continue
        table = got.table
        if key == "cnav":  # only for satellites without an LNAV record
            table = table[~np.isin(table[:, E_PRN], eph.table[:, E_PRN])]
        before = set(eph.table[:, E_PRN].astype(int))
        eph, n = merge_ephemerides(eph, table)
        new = sorted(set(eph.table[:, E_PRN].astype(int)) - before)
        events += got.events + [f"{name}: {n} {what} record(s) added to the navigation file's"
                                + (f" (new: {', '.join(sat_name(s) for s in new)})" if new else "")]
    if asked and len(errors) == asked:  # every asked source failed
        raise errors[0]
    return GpsEphemerides(eph.table, eph.ref_week, eph.iono_alpha, eph.iono_beta, events)
