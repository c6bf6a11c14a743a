"""RTKLIB time-tag files (``<data file>.tag``) and the mapping of a raw IMU log to GPS time.

Tag file layout (RTKLIB demo5/EX, little endian)::

    bytes 0-59   ASCII header, e.g. "TIMETAG RTKLIB demo5", NUL padded
    bytes 60-63  uint32  logger tick at the start of the log [ms] (the logger's own ms counter)
    bytes 64-67  uint32  start time: whole seconds of GPST counted like Unix time (RTKLIB gtime_t.time)
    bytes 68-75  float64 fraction of a second of the start time
    then 8-byte records: uint32 tick [ms since the start of the log], uint32 byte offset

RTKLIB's ``writefile`` writes each chunk of received bytes to the data file and then the record
``(tick - tick_start, ftell(data file))``: the offset is the file size **after** the chunk, and the
tick is when the chunk was written (its arrival at the logger). So the bytes ``[offset[j-1],
offset[j])`` arrived at ``start + tick[j]``, and a line ending at byte ``e`` (one past its newline)
arrived at the tick of the first record with ``offset >= e``.

Line endings: both rtklibexplorer IMU logs were written with CRLF line ends (the tag offsets count
the CR bytes) but are stored with LF only: the last tag offset exceeds the file size by exactly the
number of lines. :func:`line_end_offsets` detects this and corrects the offsets.

Time mapping of an IMU log (:func:`fit_stamp_clock`). Each IMU line carries its own stamp (ms since
IMU power-up: a smooth crystal clock, 1 ms resolution); the tag gives each line's arrival time at
the logger, which is the (unknown) output time plus a positive latency: serial/USB transport plus the
wait for the logger's next write. The logger writes on its ~15.6 ms timer tick, so the latency is
close to uniform on [L0, L0 + 16 ms] with a few stalls (up to 35 ms on the drive log, 100 ms on the
walk log). Measured residuals of the fit below (arrival minus fitted line, ms, both logs):

* drive ``imu_1934.csv`` (54,859 lines): min −1.3, 0.1 % −0.6, 1 % 0.0, 5 % 0.9, median 7.9,
  95 % 15.0, 99 % 16.0, max 34.4; clock drift +13.2 ppm (IMU clock slow against the logger clock);
  the 1 % quantile of ten consecutive 55-s windows stays within ±0.2 ms of the line, so a straight
  line (offset + drift) is adequate.
* walk ``imu_1730.csv`` (20,455 lines): min −2, 1 % 0, median 8, 99 % 16, max 99; drift ≈ 0 ppm.

A least-squares line therefore passes through the *middle* of the latency band (about 8 ms late:
the mean latency, not the delay of the data) and is pulled by the stalls. The right estimator for
"arrival = true time + positive jitter" is the lower envelope. We fit a low **quantile regression**
line (pinball loss, default quantile 0.01): it is a lower envelope that is insensitive to any number
of late arrivals and tolerates up to 1 % of early outliers (e.g. a mis-attributed line), which the
exact lower convex hull would not; its bias above the hull is about 1 % of the 16 ms band (0.16 ms).
The estimated offset still contains the minimum transport latency L0 (a 45-byte line at 115200 baud
takes 4 ms) and any delay inside the IMU before it prints the line: neither is observable from the
tag. Compared with the GNSS velocity (turn rate and acceleration cross-correlated with the gyro and
accelerometer), the IMU data of the drive set appear 0.10–0.13 s *later* on this mapping than the
GNSS motion (gyro yaw rate vs GNSS course rate: 0.105 s; accelerometer vs GNSS velocity
differences: 0.135 s); the data's author configures ``imu_t_off = -0.125 s`` for it. Such an offset belongs
to the configuration or to a filter state (``time_offset_s`` of the IMU reader), not to this fit.

Times here are GPST seconds counted like Unix time (see :mod:`aidnav.io.gpstime`); readers convert to
GPS seconds of week at the end.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from aidnav.io.errors import DataError
from aidnav.io.gpstime import gpst_unix_to_week_sow

HEADER_LEN = 60
FIXED_LEN = 76  # header + tick + start seconds + fraction
RECORD = np.dtype([("tick", "<u4"), ("offset", "<u4")])


@dataclass
class TimeTag:
    """Content of an RTKLIB time-tag file.

    path : the tag file.
    header : ASCII header text (NULs stripped), e.g. "TIMETAG RTKLIB demo5".
    tick_start_ms : logger tick at the start of the log [ms] (logger's free-running counter).
    start_gpst : log start time, GPST seconds counted like Unix time [s] (integer + fraction).
    tick_ms : (K,) int64, ms since the start of the log at which each chunk was written.
    offset : (K,) int64, data-file size in bytes after each chunk (one past its last byte).
    events : notes about the file (e.g. a trailing partial record).
    """

    path: str
    header: str
    tick_start_ms: int
    start_gpst: float
    tick_ms: np.ndarray
    offset: np.ndarray
    events: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.tick_ms)

    @property
    def start_week_sow(self) -> tuple[int, float]:
        """(GPS week, seconds of week [s]) of the log start."""
        return gpst_unix_to_week_sow(self.start_gpst)

    def arrival_gpst(self, end_offsets) -> np.ndarray:
        """Arrival time (GPST-like-Unix [s]) of the data ending at byte ``end_offsets`` (one past the end).

        The tick of the first record whose offset is ≥ the end offset; NaN where the data lies beyond
        the last record.
        """
        e = np.asarray(end_offsets, dtype=np.int64)
        j = np.searchsorted(self.offset, e, side="left")
        out = np.full(e.shape, np.nan)
        ok = j < len(self.offset)
        out[ok] = self.start_gpst + self.tick_ms[j[ok]] * 1e-3
        return out

    @property
    def tick_quantum_ms(self) -> float:
        """Median non-zero spacing of the record ticks [ms]: the logger's write period (~15.6 ms)."""
        d = np.diff(self.tick_ms)
        d = d[d > 0]
        return float(np.median(d)) if len(d) else float("nan")


def read_timetag(path) -> TimeTag:
    """Read an RTKLIB time-tag file (layout in the module docstring).

    Returns a :class:`TimeTag` (start time in GPST seconds counted like Unix time, ticks in ms).
    Raises :class:`DataError` (file, problem) when the file is too short, has no "TIMETAG" header,
    or its ticks or offsets decrease; a trailing partial record is ignored and reported in ``events``.
    """
    path = Path(path)
    raw = path.read_bytes()
    if len(raw) < FIXED_LEN:
        raise DataError(path, None, f"{len(raw)} bytes, a time-tag file has at least {FIXED_LEN}")
    header = raw[:HEADER_LEN].split(b"\0", 1)[0].decode("ascii", errors="replace").strip()
    if not header.startswith("TIMETAG"):
        raise DataError(path, None, f"header {header[:30]!r} does not start with 'TIMETAG'")
    tick0 = int(np.frombuffer(raw, "<u4", 1, HEADER_LEN)[0])
    sec = int(np.frombuffer(raw, "<u4", 1, HEADER_LEN + 4)[0])
    frac = float(np.frombuffer(raw, "<f8", 1, HEADER_LEN + 8)[0])
    if not (0.0 <= frac < 1.0):
        raise DataError(path, None, f"start-time fraction {frac!r} not in [0, 1)")
    events = []
    nrec, rest = divmod(len(raw) - FIXED_LEN, RECORD.itemsize)
    if rest:
        events.append(f"{path.name}: trailing partial record of {rest} bytes ignored")
    rec = np.frombuffer(raw, RECORD, nrec, FIXED_LEN)
    tick = rec["tick"].astype(np.int64)
    off = rec["offset"].astype(np.int64)
    for name, a in (("tick", tick), ("offset", off)):
        bad = np.flatnonzero(np.diff(a) < 0)
        if len(bad):
            i = int(bad[0]) + 1
            raise DataError(path, None, f"record {i} (byte {FIXED_LEN + 8 * i}): {name} decreases "
                                        f"({a[i - 1]} → {a[i]}); {len(bad)} such records")
    return TimeTag(str(path), header, tick0, sec + frac, tick, off, events)


def line_end_offsets(data: bytes, tag: TimeTag, name: str = "data") -> tuple[np.ndarray, list[str]]:
    """Byte offsets (as the logger counted them) one past the end of each line of ``data``.

    data : the data file's bytes as stored; lines end with '\\n' (a last line without it counts too).
    tag : its time tag; ``tag.offset[-1]`` is the size of the file as logged.
    Returns (ends (L,) int64, notes). When the stored file has LF line ends but the logged size equals
    the stored size plus the number of LF bytes (the logger wrote CRLF, the copy lost the CRs), the
    offsets are corrected by one byte per preceding line; a size mismatch of any other kind is
    noted and the offsets are used as stored.
    """
    buf = np.frombuffer(data, np.uint8)
    nl = np.flatnonzero(buf == 10)
    ends = nl + 1
    if len(data) and data[-1:] != b"\n":
        ends = np.append(ends, len(data))
    ends = ends.astype(np.int64)
    notes = []
    logged = int(tag.offset[-1]) if len(tag) else 0
    if logged == len(data):
        return ends, notes
    if logged == len(data) + len(nl) and not np.any(buf == 13):
        ends = ends + np.minimum(np.arange(1, len(ends) + 1), len(nl))
        notes.append(f"{name}: logged size {logged} B = stored {len(data)} B + {len(nl)} line ends: the "
                     "logger wrote CRLF line ends, stored as LF; tag offsets corrected for it")
        return ends, notes
    notes.append(f"{name}: logged size {logged} B differs from stored size {len(data)} B; tag offsets "
                 "used as stored (lines beyond the last tag record have no arrival time)")
    return ends, notes


@dataclass
class ClockFit:
    """Fitted map from a sensor's own clock to GPS time: t = gpst_ref + scale · (stamp − stamp_ref).

    gpst_ref : GPST (counted like Unix time) [s] of the sample with stamp ``stamp_ref_s``.
    stamp_ref_s : reference stamp [s] (the first sample used in the fit).
    scale : GPST seconds per sensor-clock second; drift_ppm = (scale − 1)·1e6.
    quantile : the quantile of the arrival latency the line was fitted to (lower envelope).
    residual_ms : statistics of arrival − fitted time [ms] (keys: n, min, p0_1, p1, p5, median, p95,
        p99, p99_9, max, mean_ls_offset (least-squares line minus this line), n_early (< −2 ms),
        n_late (> median + 3·(p95 − p5)), tick_quantum (the logger's write period)).
    """

    gpst_ref: float
    stamp_ref_s: float
    scale: float
    quantile: float
    residual_ms: dict = field(default_factory=dict)

    @property
    def drift_ppm(self) -> float:
        """Sensor clock rate error against the logger clock [ppm] (positive: sensor clock slow)."""
        return (self.scale - 1.0) * 1e6

    @property
    def offset_s(self) -> float:
        """GPST (counted like Unix time) [s] of sensor stamp 0, i.e. of the IMU's power-up per the fit."""
        return self.gpst_ref - self.scale * self.stamp_ref_s

    def __call__(self, stamp_s) -> np.ndarray:
        """GPST counted like Unix time [s] of sensor stamps ``stamp_s`` [s]."""
        return self.gpst_ref + self.scale * (np.asarray(stamp_s, dtype=float) - self.stamp_ref_s)

    def summary(self) -> str:
        """One-line human-readable description."""
        r = self.residual_ms
        wk, sow = gpst_unix_to_week_sow(self.offset_s)
        return (f"stamp→GPST fit (quantile {self.quantile:g} lower envelope): IMU stamp 0 at GPS week {wk} "
                f"sow {sow:.4f} s, drift {self.drift_ppm:+.2f} ppm; arrival − fit [ms]: "
                f"min {r.get('min', np.nan):.2f}, p1 {r.get('p1', np.nan):.2f}, "
                f"median {r.get('median', np.nan):.2f}, p99 {r.get('p99', np.nan):.2f}, "
                f"max {r.get('max', np.nan):.2f}; least-squares line "
                f"{r.get('mean_ls_offset', np.nan):.2f} ms later; {r.get('n_late', 0)} late arrivals, "
                f"{r.get('n_early', 0)} early (< −2 ms)")


def _quantile_line(xc: np.ndarray, y: np.ndarray, q: float, b0: float, half_width: float):
    """Minimise the pinball loss of y − (a + b·xc) over (a, b); returns (a, b).

    For a fixed slope the optimal intercept is the q-quantile of y − b·xc; the remaining function of b
    is convex (partial minimum of a jointly convex function), so a golden-section search is exact.
    """

    k = min(len(y) - 1, int(np.floor(q * len(y))))  # order statistic that minimises over the intercept

    def loss(b):
        r = y - b * xc
        a = np.partition(r, k)[k]
        e = r - a
        return float(np.sum(np.maximum(q * e, (q - 1.0) * e))), a

    lo, hi = b0 - half_width, b0 + half_width
    g = (np.sqrt(5.0) - 1.0) / 2.0
    for _ in range(8):  # widen the bracket if the minimum sits on its edge
        c, d = hi - g * (hi - lo), lo + g * (hi - lo)
        fc, fd = loss(c)[0], loss(d)[0]
        while hi - lo > 1e-11:  # slope to 1e-11: < 0.04 ms over an hour
            if fc <= fd:
                hi, d, fd = d, c, fc
                c = hi - g * (hi - lo)
                fc = loss(c)[0]
            else:
                lo, c, fc = c, d, fd
                d = lo + g * (hi - lo)
                fd = loss(d)[0]
        b = 0.5 * (lo + hi)
        if abs(b - (b0 - half_width)) > 1e-9 and abs(b - (b0 + half_width)) > 1e-9:
            break
        b0, half_width = b, half_width * 10.0
        lo, hi = b0 - half_width, b0 + half_width
    return loss(b)[1], b


def fit_stamp_clock(stamp_s, arrival_gpst, quantile: float = 0.01, tick_quantum_ms: float = float("nan"),
                    ) -> ClockFit:
    """Fit GPST = gpst_ref + scale · (stamp − stamp_ref) to the lower envelope of arrival times.

    stamp_s : (N,) sensor clock stamps [s] (e.g. IMU ms-since-power-up / 1000), increasing.
    arrival_gpst : (N,) arrival times at the logger, GPST counted like Unix time [s]; NaN entries are
        ignored. Model: arrival = true time + latency, latency ≥ 0 and jittery (see module docstring);
        the line is the ``quantile`` regression (default 0.01: robust lower envelope).
    tick_quantum_ms : the logger's write period, only reported.
    Returns a :class:`ClockFit` with residual statistics in ms.
    """
    x = np.asarray(stamp_s, dtype=float)
    y = np.asarray(arrival_gpst, dtype=float)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if len(x) < 2 or x[-1] == x[0]:
        raise ValueError("fit_stamp_clock: need at least two samples with distinct stamps and arrival times")
    x_ref, y_ref = x[0], y[0]
    xc, yc = x - x_ref, y - y_ref
    # least-squares line: centre of the latency band, start value for the slope
    xm, ym = xc.mean(), yc.mean()
    b_ls = float(np.sum((xc - xm) * (yc - ym)) / np.sum((xc - xm) ** 2))
    a_ls = ym - b_ls * xm
    a, b = _quantile_line(xc, yc, quantile, b_ls, 2e-4)
    res = (yc - (a + b * xc)) * 1e3
    p = np.percentile(res, [0, 0.1, 1, 5, 50, 95, 99, 99.9, 100])
    keys = ["min", "p0_1", "p1", "p5", "median", "p95", "p99", "p99_9", "max"]
    stats = {k: float(v) for k, v in zip(keys, p, strict=True)}
    stats["n"] = int(len(res))
    stats["mean_ls_offset"] = float(((a_ls + b_ls * xm) - (a + b * xm)) * 1e3)
    stats["n_early"] = int(np.sum(res < -2.0))
    stats["n_late"] = int(np.sum(res > stats["median"] + 3.0 * (stats["p95"] - stats["p5"])))
    stats["tick_quantum"] = float(tick_quantum_ms)
    return ClockFit(gpst_ref=float(y_ref + a), stamp_ref_s=float(x_ref), scale=float(b), quantile=quantile,
                    residual_ms=stats)
