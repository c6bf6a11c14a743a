"""The broadcast navigation words of a u-blox UBX log: UBX-RXM-SFRBX frames, read once for every decoder.

A UBX frame is ``B5 62``, class, id, a little-endian u16 payload length, the payload and an 8-bit Fletcher
checksum (CK_A, CK_B) over class … payload (u-blox interface description, "UBX frame structure"). The
log is scanned for frames; one whose checksum fails is skipped (the scan resumes one byte later) and
counted; NMEA and other bytes between frames are skipped.

UBX-RXM-SFRBX (class 0x02, id 0x13) payload: gnssId, svId, sigId, freqId, numWords, chn, version,
reserved (u1 each), then numWords little-endian u32 words ("dwrd"), in the order the receiver decoded
them. What a word holds depends on the signal: :mod:`aidnav.io.gps_lnav` (GPS L1 C/A LNAV),
:mod:`aidnav.io.galileo_inav` (Galileo E1-B I/NAV). UBX-RXM-RAWX (0x02 0x15) gives the receiver's GPS
week (u16 at payload byte 8) and time of week (f64 at byte 0): the week resolves the 10-bit week number of
the GPS LNAV message, the span of the log's epochs is where :mod:`aidnav.io.gps_cnav` fits its records.
"""

from __future__ import annotations

import struct
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from aidnav.io.errors import DataError
from aidnav.io.gpstime import SECONDS_PER_WEEK

__all__ = ["SfrbxLog", "read_sfrbx", "near_week"]

_SYNC = b"\xb5\x62"


@dataclass
class SfrbxLog:
    """The SFRBX frames of a log: ``frames`` (gnssId, svId, sigId, words) in log order, the GPS week of
    the first RXM-RAWX (None without one), the GPS time [s from the start of ``rawx_week``] of the first
    and last RXM-RAWX (``rawx_span``, None without one) and ``counts`` of what the scan met."""

    frames: list = field(default_factory=list)
    rawx_week: int | None = None
    rawx_span: tuple[float, float] | None = None
    counts: Counter = field(default_factory=Counter)

    def of(self, gnss_id: int) -> list:
        """(svId, sigId, words) of the frames of one system (u-blox gnssId: 0 GPS, 2 Galileo)."""
        return [(sv, sig, w) for g, sv, sig, w in self.frames if g == gnss_id]


def ubx_checksum(body: bytes) -> tuple[int, int]:
    """UBX's 8-bit Fletcher checksum (CK_A, CK_B) of a frame's class, id, length and payload."""
    a = b = 0
    for x in body:
        a = (a + x) & 0xFF
        b = (b + a) & 0xFF
    return a, b


def read_sfrbx(path) -> SfrbxLog:
    """The RXM-SFRBX frames (and the first RXM-RAWX week) of the UBX log ``path``. Raises DataError when
    the file is missing."""
    path = Path(path)
    if not path.exists():
        raise DataError(path, None, "file not found")
    data = path.read_bytes()
    out = SfrbxLog()
    i = data.find(_SYNC)
    while 0 <= i <= len(data) - 8:
        cls, mid, n = data[i + 2], data[i + 3], struct.unpack_from("<H", data, i + 4)[0]
        end = i + 6 + n
        if end + 2 > len(data) or ubx_checksum(data[i + 2:end]) != (data[end], data[end + 1]):
            out.counts["UBX frames with a bad checksum (skipped)"] += 1
            i = data.find(_SYNC, i + 1)
            continue
        p = data[i + 6:end]
        if (cls, mid) == (0x02, 0x13) and n >= 8 and n == 8 + 4 * p[4]:
            out.frames.append((p[0], p[1], p[2], struct.unpack_from(f"<{p[4]}I", p, 8)))
        elif (cls, mid) == (0x02, 0x15) and n >= 16:
            tow, week = struct.unpack_from("<dH", p, 0)
            if out.rawx_week is None:
                out.rawx_week = week
            t = (week - out.rawx_week) * SECONDS_PER_WEEK + tow
            lo, hi = out.rawx_span or (t, t)
            out.rawx_span = (min(lo, t), max(hi, t))
        out.counts["UBX frames"] += 1
        i = data.find(_SYNC, end + 2)
    return out


def near_week(t_sow: float, wn: int, tow: float) -> int:
    """The week of a time of week ``t_sow`` (a toe, a toc) given the current week ``wn`` and time of week
    ``tow`` (the nearer one: ± half a week)."""
    if t_sow - tow > SECONDS_PER_WEEK / 2:
        return wn - 1
    if t_sow - tow < -SECONDS_PER_WEEK / 2:
        return wn + 1
    return wn
