"""Containers of GPS ephemerides and raw observations (shared by io.rinex, sim.gnss_raw, estimators.dgps
and filters.tight).

Times are GPS seconds from the start of a reference week (:mod:`aidnav.nav.gnss_sat`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from aidnav.nav.gnss_sat import C_LIGHT, E_PRN, E_TOC, E_TOE, carrier_frequencies, sat_name

SECONDS_PER_WEEK = 604800

__all__ = ["GpsEphemerides", "GnssObservations"]


@dataclass
class GpsEphemerides:
    """GPS broadcast ephemerides.

    table : (K, N_EPH) records (columns of :mod:`aidnav.nav.gnss_sat`; toe, toc in seconds from the start
    of ``ref_week``). ref_week : GPS week of the time scale. iono_alpha, iono_beta : Klobuchar
    coefficients (4,) or None when the file has none. events : notes.
    """

    table: np.ndarray
    ref_week: int
    iono_alpha: np.ndarray | None = None
    iono_beta: np.ndarray | None = None
    events: list[str] = field(default_factory=list)

    @property
    def prns(self) -> np.ndarray:
        return np.unique(self.table[:, E_PRN].astype(int))

    def to_week(self, ref_week: int) -> GpsEphemerides:
        """The same records with toe/toc counted from the start of ``ref_week``."""
        t = self.table.copy()
        shift = (self.ref_week - int(ref_week)) * SECONDS_PER_WEEK
        t[:, E_TOE] += shift
        t[:, E_TOC] += shift
        return GpsEphemerides(t, int(ref_week), self.iono_alpha, self.iono_beta, list(self.events))


@dataclass
class GnssObservations:
    """GNSS observations of one receiver.

    time : (T,) receiver time tags [s from the start of ``ref_week``] (include the receiver clock offset).
    prn : (S,) satellite ids (:mod:`aidnav.nav.gnss_sat`: 100·system + PRN; GPS ids are the PRNs); the
    "L1" arrays hold each system's first signal (GPS L1 C/A, Galileo E1, BeiDou B1I, GLONASS G1) at
    ``freq1`` (S,) [Hz] (None: from the ids, GLONASS channels unknown until :meth:`with_frequencies`).
    code1 : (T, S) L1 C/A pseudorange [m] (NaN = none); doppler1 : (T, S)
    L1 Doppler [Hz]; cn0 : (T, S) L1 C/N0 [dB-Hz]; code2 : (T, S) L2 pseudorange [m] or None;
    code2_type : its RINEX code (e.g. "C2L"). approx_ecef : header position [m] or None. phase1 : (T, S)
    L1 carrier phase [cycles] and lli1 its loss-of-lock indicator (bit 0: lock lost, a cycle slip is
    possible; bit 1: half-cycle ambiguity), both None when the file has no L1 phase. phase_sigma1 : (T, S)
    the receiver's own σ of each L1 phase [m] (u-blox RXM-RAWX cpStdev, :mod:`aidnav.io.rawx`; RINEX has
    none) or None.
    """

    time: np.ndarray
    ref_week: int
    prn: np.ndarray
    code1: np.ndarray
    doppler1: np.ndarray
    cn0: np.ndarray
    code2: np.ndarray | None = None
    code2_type: str | None = None
    approx_ecef: np.ndarray | None = None
    events: list[str] = field(default_factory=list)
    phase1: np.ndarray | None = None  # (T, S) L1 carrier phase [cycles] (NaN = none), or None
    lli1: np.ndarray | None = None  # (T, S) its loss-of-lock indicator (RINEX bits; 0 where none)
    freq1: np.ndarray | None = None  # (S,) carrier frequency of the L1 arrays [Hz] (None: from the ids)
    phase_sigma1: np.ndarray | None = None  # (T, S) the receiver's σ of each L1 phase [m] (NaN: none)

    def __len__(self) -> int:
        return len(self.time)

    @property
    def names(self) -> list[str]:
        """RINEX satellite names ("G05", "E11", ...)."""
        return [sat_name(p) for p in self.prn]

    def frequencies(self) -> np.ndarray:
        """Carrier frequency [Hz] (S,) of the L1 arrays (NaN: a GLONASS satellite of unknown channel)."""
        return np.asarray(self.freq1, float) if self.freq1 is not None else carrier_frequencies(self.prn)

    def wavelengths(self) -> np.ndarray:
        """Carrier wavelength [m] (S,) of the L1 arrays (FDMA: per GLONASS channel)."""
        return C_LIGHT / self.frequencies()

    def with_frequencies(self, eph) -> GnssObservations:
        """The same observations with ``freq1`` from the ids and the GLONASS channels of ``eph``'s records
        where it is not given (a given one stays: e.g. BeiDou B1C at 1575.42 MHz, :mod:`aidnav.io.rawx`)."""
        f = carrier_frequencies(self.prn, eph.table)
        if self.freq1 is not None:
            f = np.where(np.isfinite(self.freq1), self.freq1, f)
        return replace(self, freq1=f)

    def range_rate(self) -> np.ndarray:
        """Pseudorange rate [m/s] = −λ · Doppler (T, S) (λ per satellite: :meth:`wavelengths`)."""
        return -self.wavelengths() * self.doppler1

    def subset_sats(self, prns) -> GnssObservations:
        """Only the satellites ``prns`` (in that order; missing ones are all-NaN columns)."""
        idx = [int(np.flatnonzero(self.prn == p)[0]) if p in self.prn else -1 for p in prns]

        def pick(a):
            if a is None:
                return None
            out = np.full((a.shape[0], len(idx)), np.nan)
            for k, i in enumerate(idx):
                if i >= 0:
                    out[:, k] = a[:, i]
            return out

        return GnssObservations(
            self.time,
            self.ref_week,
            np.asarray(prns, int),
            pick(self.code1),
            pick(self.doppler1),
            pick(self.cn0),
            pick(self.code2),
            self.code2_type,
            self.approx_ecef,
            list(self.events),
            pick(self.phase1),
            None if self.lli1 is None else np.nan_to_num(pick(self.lli1.astype(float))).astype(np.int64),
            None if self.freq1 is None else np.array([self.freq1[i] if i >= 0 else np.nan for i in idx]),
            pick(self.phase_sigma1),
        )
