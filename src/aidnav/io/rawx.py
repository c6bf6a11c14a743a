"""The raw measurements of a u-blox UBX log: UBX-RXM-RAWX, with the receiver's own σ per measurement.

UBX-RXM-RAWX (class 0x02, id 0x15; u-blox interface description, "UBX-RXM-RAWX"): payload rcvTow (f64,
s of the GPS week), week (u16), leapS (i1), numMeas (u1), recStat, version (u1 each), 2 reserved bytes,
then numMeas blocks of 32 bytes: prMes (f64, m), cpMes (f64, cycles), doMes (f32, Hz), gnssId, svId,
sigId, freqId (u1 each), locktime (u16, ms), cno (u1, dB-Hz), prStdev (bits 0–3: 0.01·2^n m), cpStdev
(bits 0–3: 0.004·n cycles), doStdev (bits 0–3: 0.002·2^n Hz), trkStat (bit 0 pseudorange valid, bit 1
carrier phase valid, bit 2 half-cycle valid, bit 3 half cycle subtracted from the phase), a reserved
byte. Frames are found as :mod:`aidnav.io.sfrbx` finds them (UBX checksum; a bad frame is skipped).

**Why it is read**: RTKLIB's ``convbin`` writes the code, phase, Doppler and C/N0 of the signals it knows
into RINEX and drops the receiver's σ (``prStdev``, ``cpStdev``, ``doStdev``) and the lock time; the
shared walk's observation file (convbin 2.4.3) also has no BeiDou at all, while its log tracks BeiDou-3
on B1C (sigId 5, the pilot, at 1575.42 MHz like GPS L1: the phase of 11 satellites, 7 with a broadcast
D1 ephemeris in the navigation file). :func:`rawx_observations` turns the measurements of one signal per
system into :class:`aidnav.nav.gnss_types.GnssObservations` — the conversions happen here: the σ into
metres (cpStdev × λ, doStdev × λ), the times onto the GPS-week scale of the first epoch, the loss-of-lock
indicator as RTKLIB's ``ublox.c`` forms it (bit 0 where the lock time is 0 or falls, or the half-cycle
flag changes; bit 1 where the half cycle is not resolved) — and :func:`merge_rawx` adds to a RINEX
observation set the satellites it lacks and the receiver's σ of the ones it has.

**BeiDou B1C with a D1 ephemeris**: the D1 clock refers to B3I (BDS-SIS-ICD-B3I, 5.2.4.10); B1C's code
then carries the B1Cp–B3I group delay (a few ns, in CNAV1 only), which the inter-system bias (common
part) and the satellite's range-error state (the rest) take; the phase increments and the Doppler do not
see it. The B1C phase of the walk's satellites is what the time-differenced carrier phase gains.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from aidnav.io.errors import DataError
from aidnav.io.gpstime import SECONDS_PER_WEEK
from aidnav.io.sfrbx import ubx_checksum
from aidnav.nav.gnss_sat import C_LIGHT, FREQ_L1, sat_id
from aidnav.nav.gnss_types import GnssObservations

__all__ = ["RawxMeasurements", "read_rawx", "rawx_observations", "merge_rawx", "RAWX_SIGNALS"]

_SYNC = b"\xb5\x62"
#: u-blox gnssId → RINEX system letter (1 SBAS: svId 120–158 → S20–S58; 6 GLONASS not read: FDMA)
_LETTER = {0: "G", 1: "S", 2: "E", 3: "C"}
#: the signal read per system (u-blox sigId): GPS L1 C/A, SBAS L1 C/A, Galileo E1 C, BeiDou B1C pilot
RAWX_SIGNALS = {"G": 0, "S": 0, "E": 0, "C": 5}
#: carrier frequency [Hz] of each of those signals (all 1575.42 MHz)
_FREQ = {"G": FREQ_L1, "S": FREQ_L1, "E": FREQ_L1, "C": FREQ_L1}


@dataclass
class RawxMeasurements:
    """Every RXM-RAWX measurement of a log, one entry each (N,): ``time`` GPS seconds from the start of
    ``week`` (the first epoch's), ``letter`` system letter, ``sv`` RINEX PRN, ``sig`` u-blox sigId,
    ``lock_ms`` lock time [ms], ``cn0`` [dB-Hz], ``pr`` [m], ``cp`` [cycles], ``do`` [Hz], ``pr_std`` [m],
    ``cp_std`` [cycles], ``do_std`` [Hz], ``trk`` trkStat bits (module doc)."""

    week: int
    time: np.ndarray
    letter: np.ndarray
    sv: np.ndarray
    sig: np.ndarray
    lock_ms: np.ndarray
    cn0: np.ndarray
    pr: np.ndarray
    cp: np.ndarray
    do: np.ndarray
    pr_std: np.ndarray
    cp_std: np.ndarray
    do_std: np.ndarray
    trk: np.ndarray


def read_rawx(path) -> RawxMeasurements:
    """The RXM-RAWX measurements of the UBX log ``path`` (module doc). Raises DataError when the file is
    missing or holds no RXM-RAWX."""
    path = Path(path)
    if not path.exists():
        raise DataError(path, None, "file not found")
    data = path.read_bytes()
    rows, week0 = [], None
    i = data.find(_SYNC)
    while 0 <= i <= len(data) - 8:
        cls, mid, n = data[i + 2], data[i + 3], struct.unpack_from("<H", data, i + 4)[0]
        end = i + 6 + n
        if end + 2 > len(data) or ubx_checksum(data[i + 2:end]) != (data[end], data[end + 1]):
            i = data.find(_SYNC, i + 1)
            continue
        if (cls, mid) == (0x02, 0x15) and n >= 16:
            tow, week, _, nm = struct.unpack_from("<dHbB", data, i + 6)
            week0 = week if week0 is None else week0
            t = (week - week0) * SECONDS_PER_WEEK + tow
            for m in range(min(nm, (n - 16) // 32)):
                f = struct.unpack_from("<ddfBBBBHBBBBB", data, i + 6 + 16 + 32 * m)
                if f[3] in _LETTER:
                    rows.append((t, *f))
        i = data.find(_SYNC, end + 2)
    if not rows:
        raise DataError(path, None, "no UBX-RXM-RAWX measurement")
    a = np.array([r[:4] for r in rows])
    b = np.array([r[4:] for r in rows], np.int64)  # gnss, sv, sig, freq, lock, cno, prs, cps, dos, trk
    letter = np.array([_LETTER[g] for g in b[:, 0]])
    sv = np.where(b[:, 0] == 1, b[:, 1] - 100, b[:, 1])  # SBAS PRN 120-158 -> S20-S58
    return RawxMeasurements(week0, a[:, 0], letter, sv, b[:, 2], b[:, 4], b[:, 5].astype(float), a[:, 1],
                            a[:, 2], a[:, 3], 0.01 * 2.0 ** (b[:, 6] & 15), 0.004 * (b[:, 7] & 15),
                            0.002 * 2.0 ** (b[:, 8] & 15), b[:, 9])


@dataclass
class RawxObservations:
    """:class:`GnssObservations` of the RAWX signals (:func:`rawx_observations`) and the receiver's σ per
    measurement (T, S) on the same grid: ``code_sigma`` [m], ``phase_sigma`` [m] (cpStdev × λ),
    ``rate_sigma`` [m/s] (doStdev × λ); NaN where none."""

    obs: GnssObservations
    code_sigma: np.ndarray
    phase_sigma: np.ndarray
    rate_sigma: np.ndarray


def rawx_observations(meas: RawxMeasurements, systems: str = "GESC", ref_week: int | None = None,
                      times=None) -> RawxObservations:
    """The measurements of :data:`RAWX_SIGNALS`' signal of each system of ``systems`` as observations
    (module doc): epochs ``times`` [s from ``ref_week``] when given (a measurement within 1 ms of one is
    put there: e.g. a RINEX file's epochs), else the log's own; satellites in system, PRN order."""
    week = meas.week if ref_week is None else int(ref_week)
    t_all = meas.time + (meas.week - week) * SECONDS_PER_WEEK
    pick = np.zeros(len(t_all), bool)
    for c in systems:
        if c in RAWX_SIGNALS:
            pick |= (meas.letter == c) & (meas.sig == RAWX_SIGNALS[c])
    tt = np.unique(t_all) if times is None else np.asarray(times, float)
    names = {f"{c}{s:02d}" for c, s in zip(meas.letter[pick], meas.sv[pick], strict=True)}
    ids = np.array(sorted(sat_id(n) for n in names), int)
    T, S = len(tt), len(ids)
    k = np.clip(np.searchsorted(tt, t_all - 1e-3), 0, max(T - 1, 0))
    pick &= np.abs(tt[k] - t_all) < 1e-3 if T else False
    col = {int(i): j for j, i in enumerate(ids)}
    j = np.array([col.get(sat_id(f"{c}{s:02d}"), -1) if p else -1
                  for c, s, p in zip(meas.letter, meas.sv, pick, strict=True)], int)
    sel = j >= 0
    k, j = k[sel], j[sel]
    lam = np.array([C_LIGHT / _FREQ[c] for c in meas.letter[sel]])
    trk = meas.trk[sel]
    out = {n: np.full((T, S), np.nan) for n in ("pr", "cp", "do", "cn0", "prs", "cps", "dos", "lock", "half")}
    out["pr"][k, j] = np.where(trk & 1, meas.pr[sel], np.nan)
    out["cp"][k, j] = np.where(trk & 2, meas.cp[sel], np.nan)
    out["do"][k, j], out["cn0"][k, j] = meas.do[sel], meas.cn0[sel]
    out["prs"][k, j] = np.where(trk & 1, meas.pr_std[sel], np.nan)
    out["cps"][k, j] = np.where(trk & 2, meas.cp_std[sel] * lam, np.nan)
    out["dos"][k, j] = meas.do_std[sel] * lam
    out["lock"][k, j] = meas.lock_ms[sel]
    out["half"][k, j] = trk & 8
    halfv = np.zeros((T, S), bool)
    halfv[k, j] = (trk & 4) > 0
    obs = GnssObservations(tt, week, ids, out["pr"], out["do"], out["cn0"], phase1=out["cp"],
                           lli1=_lli(out["lock"], out["half"], halfv, np.isfinite(out["cp"])),
                           freq1=np.full(S, FREQ_L1))
    return RawxObservations(obs, out["prs"], out["cps"], out["dos"])


def _lli(lock, half, halfv, has_phase) -> np.ndarray:
    """RINEX loss-of-lock indicator (T, S) as RTKLIB's ``ublox.c`` forms it from RAWX: bit 0 (a slip is
    possible) where the lock time is 0, is shorter than at the previous epoch of the satellite, the
    half-cycle-subtracted flag changed; bit 1 where the half cycle is not resolved (an epoch without phase
    between two with it breaks the increment anyway: :func:`aidnav.estimators.tdcp.phase_increments`)."""
    T, S = lock.shape
    lli = np.zeros((T, S), np.int64)
    with np.errstate(invalid="ignore"):
        slip = np.zeros((T, S), bool)
        slip[0] = has_phase[0]
        slip[1:] = has_phase[1:] & ((lock[1:] < lock[:-1]) | (half[1:] != half[:-1]))
        slip |= has_phase & (lock == 0)
    lli[slip] |= 1
    lli[has_phase & ~halfv] |= 2
    return lli


def merge_rawx(obs: GnssObservations, rx: RawxObservations, add_systems: str = "C") -> GnssObservations:
    """``obs`` (e.g. a RINEX file's) with the satellites of ``rx`` of the systems ``add_systems`` that it
    lacks added as columns (their code, phase, Doppler, C/N0 and indicator; ``rx`` must be on ``obs``'s
    epochs: :func:`rawx_observations` with ``times``) and ``phase_sigma1`` the receiver's phase σ [m] of
    every column where ``rx`` has that satellite's phase (a RINEX phase, written from the same RAWX
    measurement, gets its cpStdev). The RINEX columns' values are kept as they are."""
    have = set(int(p) for p in obs.prn)
    add = [int(p) for p, n in zip(rx.obs.prn, rx.obs.names, strict=True)
           if n[0] in add_systems and int(p) not in have]
    prns = [int(p) for p in obs.prn] + add
    merged = obs.subset_sats(prns)
    src = rx.obs.subset_sats(prns)
    new = np.isin(np.asarray(prns), add)
    psig = _pick(rx.phase_sigma, rx.obs.prn, prns)
    if not add:
        return replace(merged, phase_sigma1=psig)
    phase = merged.phase1 if merged.phase1 is not None else np.full(merged.code1.shape, np.nan)
    lli = merged.lli1 if merged.lli1 is not None else np.zeros(merged.code1.shape, np.int64)
    return replace(
        merged, code1=np.where(new, src.code1, merged.code1),
        doppler1=np.where(new, src.doppler1, merged.doppler1),
        cn0=np.where(new, src.cn0, merged.cn0), phase1=np.where(new, src.phase1, phase),
        lli1=np.where(new, np.nan_to_num(src.lli1).astype(np.int64), lli),
        freq1=np.where(new, FREQ_L1, merged.frequencies()), phase_sigma1=psig)


def _pick(a, ids, prns) -> np.ndarray:
    """The columns of ``a`` (T, len(ids)) in the order ``prns`` (NaN where absent)."""
    out = np.full((a.shape[0], len(prns)), np.nan)
    pos = {int(p): j for j, p in enumerate(ids)}
    for k, p in enumerate(prns):
        if p in pos:
            out[:, k] = a[:, pos[p]]
    return out
