"""Errors of an estimated trajectory against a reference, chunk by chunk (issue 29): memory independent of
the length of either.

:func:`stream_errors` takes both trajectories as pieces (:class:`aidnav.io.stream.TrajectoryChunks`) and
gives what :func:`.errors.trajectory_errors`, :func:`.errors.error_statistics`,
:func:`.errors.fraction_within_sigma` and :func:`.consistency.consistency_report` give on the whole
trajectories, without holding them:

* the estimate is walked piece by piece, each piece with the last epoch of the one before, and each
  reference epoch is interpolated in the piece that brackets it (:func:`.errors.errors_at`: the same
  bracketing epochs, so the same numbers); the gap threshold (``max_dt=None``: 5 × the median estimate
  interval) comes from a first pass over the estimate's ``time`` column;
* the per-epoch errors go to ``on_piece`` (e.g. the ``errors.csv`` writer) and, per statistics row, their
  finite values to a temporary file (:class:`aidnav.io.stream.Spool`, 8 bytes a value);
* statistics: when a row's values number at most ``cap`` (default 2²⁰: 8 MiB, 29 hours of a 10-Hz
  reference) they are read back and summarised by :func:`.errors.statistics_row` itself: the same
  numbers, bit for bit. Above ``cap`` the file is read in chunks: sums for RMS, mean and the
  (two-pass) standard deviation (equal to the whole-array numbers up to the order of the additions,
  ~1e-15 relative), and the 95th percentile **exactly** by selection (:func:`order_statistics`: a
  4096-bin histogram pass narrows the rank to one bin, a second pass sorts that bin's values; more
  passes only while a bin still holds more than ``cap`` values), interpolated as ``numpy.percentile``
  does. The median of the estimate's intervals is found the same way;
* fractions within k·σ are integer counts (exact); the position NEES (diagonal σ) counts inside/above/
  below its χ² band and its mean as above (:func:`.consistency.report_from_counts`);
* the figures get a decimated copy of the used epochs: every s-th one, s doubling whenever more than
  ``figure_points`` are kept (all of them below that: the figures of the whole series).

The longitude of the estimate is unwrapped piece by piece from the last unwrapped value before it: the
same values as the whole-trajectory unwrap unless the estimate crosses ±180°, where they differ by the
rounding of the accumulated 2π corrections (~1e-15 rad).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from aidnav.analysis.consistency import ConsistencyReport, chi2_band, nees, report_from_counts
from aidnav.analysis.errors import (
    AUTO_GAP_FACTOR,
    QUANTITIES,
    ErrorParts,
    ErrorSeries,
    check_time,
    errors_at,
    exclusion_notes,
    statistics_frame,
    statistics_row,
    statistics_series,
    within_flags,
    within_frame,
)
from aidnav.io.stream import Spool, concat_rows, take_rows

CAP = 1 << 20  #: values of one row summarised in memory (exactly as the whole-array path) up to this many
FIGURE_POINTS = 4000  #: at most this many epochs go to the figures (about 4 per pixel column of the PNGs)
_READ = 1 << 16  #: values per read of a spool
_BINS = 4096


# ------------------------------------------------------------------------------------ order statistics
def order_statistics(read, n: int, ranks, lo: float, hi: float, cap: int = CAP) -> dict[int, float]:
    """The values of rank ``ranks`` (0-based, in ascending order) among the ``n`` values that ``read()``
    yields (an iterable of 1-D float arrays, the same values on every call; each call is one pass), all in
    [``lo``, ``hi``]: {rank: value}. Exact, holding at most ``cap`` values: a pass histograms the values
    into 4096 equal bins of [lo, hi] and the next one looks only at the bin that holds the rank (a bin
    whose values are all equal is answered at once; one that holds all of its set is histogrammed again
    over its own extremes)."""
    out: dict[int, float] = {}
    # work items: (filters (lo, scale, bin) that select a set, ranks within it, its range, rank of its first)
    todo = [((), sorted({int(k) for k in ranks}), float(lo), float(hi), 0)]
    while todo:
        chain, ks, a, b, off = todo.pop()
        scale = _BINS / (b - a) if b > a else 0.0
        hist = np.zeros(_BINS, np.int64)
        got, m, mn, mx = [], 0, np.inf, -np.inf
        for v in read():
            for a0, s0, j0 in chain:
                v = v[_bin(v, a0, s0) == j0]
            if not len(v):
                continue
            m += len(v)
            mn, mx = min(mn, float(v.min())), max(mx, float(v.max()))
            if m <= cap:
                got.append(v)
            else:
                got = []
            hist += np.bincount(_bin(v, a, scale), minlength=_BINS)
        if m <= cap or mn == mx:
            srt = np.sort(np.concatenate(got)) if m <= cap else None
            for k in ks:
                out[off + k] = float(srt[k]) if srt is not None else mn
            continue
        if hist.max() == m:  # no narrowing (a range wider than the set): again over the set's extremes
            todo.append((chain, ks, mn, mx, off))
            continue
        cum = np.cumsum(hist)
        groups: dict[int, list[int]] = {}
        for k in ks:
            groups.setdefault(int(np.searchsorted(cum, k, side="right")), []).append(k)
        w = (b - a) / _BINS
        for j, kk in groups.items():
            before = int(cum[j - 1]) if j else 0
            todo.append((chain + ((a, scale, j),), [k - before for k in kk], a + j * w, a + (j + 1) * w,
                         off + before))
    return out


def _bin(v: np.ndarray, a: float, scale: float) -> np.ndarray:
    return np.clip(np.floor((v - a) * scale), 0, _BINS - 1).astype(np.int64)


def percentile_of(order_stat, n: int, pct: float) -> float:
    """``numpy.percentile(x, pct)`` (linear method) of ``n`` values from ``order_stat(ranks)`` → {rank:
    value} (the same floating-point steps as numpy)."""
    q = np.true_divide(pct, 100)
    vi = (n - 1) * q
    if vi >= n - 1:
        return float(order_stat([n - 1])[n - 1])
    i = int(np.floor(vi))
    g = vi - np.floor(vi)
    v = order_stat([i, i + 1])
    a, b = np.float64(v[i]), np.float64(v[i + 1])
    d = b - a
    return float(b - d * (1 - g) if g >= 0.5 else a + d * g)


# ------------------------------------------------------------------------------------- spooled values
class _Values:
    """The finite values of one quantity, in a temporary file."""

    def __init__(self, directory):
        self.spool = Spool(directory, 1)

    @property
    def n(self) -> int:
        return self.spool.rows

    def add(self, v) -> None:
        v = np.asarray(v, dtype=float)
        self.spool.write(v[np.isfinite(v)])

    def chunks(self):
        for c in self.spool.read(_READ):
            yield c[:, 0]

    def load(self) -> np.ndarray:
        return np.concatenate(list(self.chunks())) if self.n else np.zeros(0)

    def mean(self, cap: int) -> float:
        if self.n <= cap:
            return float(self.load().mean())
        return float(sum(float(c.sum()) for c in self.chunks()) / self.n)

    def statistics(self, q: str, unit: str, cap: int) -> dict:
        """The row of :func:`.errors.statistics_row` (module doc: exact in memory up to ``cap`` values)."""
        n = self.n
        if n <= cap:
            return statistics_row(q, unit, self.load())
        s = ss = 0.0
        mx = 0.0
        for c in self.chunks():
            s += float(c.sum())
            ss += float((c * c).sum())
            mx = max(mx, float(np.abs(c).max()))
        mean = s / n
        var = sum(float(((c - mean) ** 2).sum()) for c in self.chunks()) / n

        def absolute():
            for c in self.chunks():
                yield np.abs(c)

        p95 = percentile_of(lambda ks: order_statistics(absolute, n, ks, 0.0, mx, cap), n, 95)
        return {"quantity": q, "RMS": float(np.sqrt(ss / n)), "mean": mean, "std": float(np.sqrt(var)),
                "p95": p95, "max": mx, "n": n, "unit": unit}

    def median(self, cap: int) -> float:
        """``numpy.median`` of the values."""
        n = self.n
        if n <= cap:
            return float(np.median(self.load()))
        lo = min(float(c.min()) for c in self.chunks())
        hi = max(float(c.max()) for c in self.chunks())
        ks = [(n - 1) // 2] if n % 2 else [n // 2 - 1, n // 2]
        v = order_statistics(self.chunks, n, ks, lo, hi, cap)
        return float(np.mean([v[k] for k in ks]))

    def close(self) -> None:
        self.spool.close()


# ------------------------------------------------------------------------------------------- result
@dataclass
class StreamedErrors:
    """What the whole-trajectory functions give, from :func:`stream_errors`.

    statistics : :func:`.errors.error_statistics`'s table; within : {k: :func:`.errors.fraction_within_sigma`
    table}; nees : the position NEES report (diagonal σ) or None without position σ; n_used, t0, t1 : epochs
    evaluated and the first/last of them [s]; est_span, ref_span : first and last epoch of each input
    (None: empty); figure : a decimated :class:`ErrorSeries` (module doc) and
    figure_nees its NEES values (or None); notes : the notes of :class:`ErrorSeries`.
    """

    statistics: pd.DataFrame
    within: dict[float, pd.DataFrame]
    nees: ConsistencyReport | None
    n_used: int
    t0: float
    t1: float
    figure: ErrorSeries
    figure_nees: np.ndarray | None
    est_span: tuple[float, float] | None = None
    ref_span: tuple[float, float] | None = None
    n_reference: int = 0
    n_outside: int = 0
    n_gap: int = 0
    n_invalid: int = 0
    max_dt: float = np.inf
    notes: list[str] = field(default_factory=list)

    def counts(self) -> dict[str, int | float]:
        """Epoch bookkeeping as :meth:`ErrorSeries.counts`."""
        return {"reference": int(self.n_reference), "used": int(self.n_used),
                "outside_span": int(self.n_outside), "in_gaps": int(self.n_gap),
                "invalid_reference": int(self.n_invalid), "max_dt_s": float(self.max_dt)}


class _Decimated:
    """Every s-th used epoch (s doubling to keep at most ``limit``), as columns."""

    def __init__(self, limit: int):
        self.limit, self.stride, self.count, self.cols = int(limit), 1, 0, None

    def add(self, cols: dict[str, np.ndarray]) -> None:
        m = len(cols["time"])
        g = self.count + np.arange(m)
        self.count += m
        keep = g % self.stride == 0
        new = {k: v[keep] for k, v in cols.items()}
        new["_g"] = g[keep]
        self.cols = new if self.cols is None else {k: np.concatenate([self.cols[k], new[k]]) for k in new}
        while len(self.cols["_g"]) > self.limit:
            self.stride *= 2
            keep = self.cols["_g"] % self.stride == 0
            self.cols = {k: v[keep] for k, v in self.cols.items()}


_FIG_FIELDS = ("time", "pos", "vel", "att", "std_pos", "std_vel", "std_att")


class _ReferenceFeed:
    """The reference pieces cut at given times (each epoch handed on once, in order, time checked)."""

    def __init__(self, chunks):
        self.it, self.pend, self.first, self.last = iter(chunks), None, None, None

    def upto(self, t_end: float):
        while True:
            if self.pend is None:
                self.pend = next(self.it, None)
                if self.pend is None:
                    return
                tr = np.asarray(self.pend.time, dtype=float)
                check_time(tr if self.last is None else np.concatenate([[self.last], tr]), "reference")
                if len(tr):
                    self.first = float(tr[0]) if self.first is None else self.first
                    self.last = float(tr[-1])
            k = int(np.searchsorted(self.pend.time, t_end, side="right"))
            if k == 0:
                if not len(self.pend.time):
                    self.pend = None
                    continue
                return
            n = len(self.pend.time)
            yield take_rows(self.pend, slice(0, k))
            self.pend = take_rows(self.pend, slice(k, n)) if k < n else None


def _median_interval(est, directory, cap: int) -> float:
    """Median of the estimate's sampling intervals [s] over the whole file (its ``time`` column only)."""
    d, last = _Values(directory), None
    try:
        for t in est.times():
            t = np.asarray(t, dtype=float)
            if len(t):
                d.add(np.diff(t if last is None else np.concatenate([[last], t])))
                last = float(t[-1])
        return d.median(cap) if d.n else np.nan
    finally:
        d.close()


def stream_errors(est, ref, max_dt: float | None = None, on_piece=None, spool_dir=None, cap: int = CAP,
                  figure_points: int = FIGURE_POINTS, sigmas=(1.0, 3.0), prob: float = 0.95
                  ) -> StreamedErrors:
    """Errors of the estimate ``est`` against the reference ``ref`` (both
    :class:`aidnav.io.stream.TrajectoryChunks`, same time scale), chunk by chunk (module doc).

    max_dt : as :func:`.errors.trajectory_errors`; on_piece : called with the :class:`ErrorSeries` of each
    piece of used epochs, in time order; spool_dir : directory of the temporary files (None: the system's);
    cap : values summarised in memory per statistics row; sigmas : the k of the fractions within k·σ;
    prob : the NEES band probability. Raises ValueError as :func:`.errors.trajectory_errors` (time not
    strictly increasing, empty estimate).
    """
    if max_dt is None:
        med = _median_interval(est, spool_dir, cap)
        max_dt = AUTO_GAP_FACTOR * med if np.isfinite(med) else np.inf
    max_dt = float(max_dt)
    parts = ErrorParts(vel=est.has["vel"] and ref.has["vel"], att=est.has["rph"] and ref.has["rph"],
                       std_pos=est.has["std_pos"], std_vel=est.has["std_vel"], std_att=est.has["std_att"])
    probe = ErrorSeries(time=np.zeros(0), pos=np.zeros((0, 3)), vel=np.zeros((0, 3)) if parts.vel else None,
                        att=np.zeros((0, 3)) if parts.att else None)
    rows = [(q, u) for q, u in QUANTITIES if q in statistics_series(probe)]
    acc = _Accumulator(rows, parts, spool_dir, figure_points, sigmas, prob)
    feed = _ReferenceFeed(ref)

    buf = prev = lon_u = None
    t_first = t_last = None
    try:
        for ch in est:
            if not len(ch.time):
                continue
            buf = ch if prev is None else concat_rows([prev, ch])
            check_time(np.asarray(buf.time, dtype=float), "estimate")
            lon = np.asarray(buf.lon, dtype=float)
            lon_u = np.unwrap(lon) if prev is None else np.unwrap(np.concatenate([lon_u[-1:], lon[1:]]))
            if t_first is None:
                t_first = float(buf.time[0])
            t_last = float(buf.time[-1])
            for piece in feed.upto(t_last):
                acc.add(errors_at(buf, piece, max_dt, lon_u, parts), on_piece)
            prev = take_rows(buf, slice(len(buf.time) - 1, None))
        if buf is None:
            raise ValueError("estimate trajectory is empty")
        for piece in feed.upto(np.inf):  # after the estimate's span
            acc.add(errors_at(buf, piece, max_dt, lon_u, parts), on_piece)
        res = acc.result(max_dt, t_first, t_last, cap)
        res.est_span = (t_first, t_last)
        res.ref_span = None if feed.first is None else (feed.first, feed.last)
        return res
    finally:
        acc.close()


class _Accumulator:
    """Counts, spooled values, within-σ counts, NEES counts and the decimated copy of the used epochs."""

    def __init__(self, rows, parts: ErrorParts, spool_dir, figure_points, sigmas, prob):
        self.rows, self.parts, self.sigmas, self.prob = rows, parts, tuple(sigmas), prob
        self.values = {q: _Values(spool_dir) for q, _ in rows}
        self.nees_values = _Values(spool_dir) if parts.std_pos else None
        self.n = {"ref": 0, "out": 0, "gap": 0, "inv": 0, "used": 0, "nees_in": 0, "nees_above": 0,
                  "nees_below": 0, "nees_fin": 0}
        self.within: dict[tuple[float, str], list[int]] = {}
        self.fig = _Decimated(figure_points)
        self.t0 = self.t1 = np.nan

    def add(self, e: ErrorSeries, on_piece) -> None:
        n = self.n
        n["ref"] += e.n_reference
        n["out"] += e.n_outside
        n["gap"] += e.n_gap
        n["inv"] += e.n_invalid
        if not len(e.time):
            return
        n["used"] += len(e.time)
        if not np.isfinite(self.t0):
            self.t0 = float(e.time[0])
        self.t1 = float(e.time[-1])
        for q, (v, _) in statistics_series(e).items():
            self.values[q].add(v)
        for k in self.sigmas:
            for q, (v, s, _) in e.components().items():
                if s is not None:
                    a = within_flags(v, s, k)
                    c = self.within.setdefault((k, q), [0, 0])
                    c[0] += int(a.sum())
                    c[1] += a.size
        cols = {k: getattr(e, k) for k in _FIG_FIELDS if getattr(e, k) is not None}
        if self.nees_values is not None:
            v = _position_nees(e)
            lo, hi = chi2_band(3, 1, self.prob)
            fin = np.isfinite(v)
            n["nees_fin"] += int(fin.sum())
            n["nees_in"] += int((fin & (v >= lo) & (v <= hi)).sum())
            n["nees_above"] += int((fin & (v > hi)).sum())
            n["nees_below"] += int((fin & (v < lo)).sum())
            self.nees_values.add(v)
            cols["nees"] = v
        self.fig.add(cols)
        if on_piece is not None:
            on_piece(e)

    def result(self, max_dt, t_first, t_last, cap) -> StreamedErrors:
        n = self.n
        stats = statistics_frame([self.values[q].statistics(q, u, cap) for q, u in self.rows])
        within = {}
        for k in self.sigmas:
            fr = {q: (c / m if m else np.nan, m) for (kk, q), (c, m) in self.within.items() if kk == k}
            within[k] = within_frame(fr, k)
        rep = None
        nv = self.nees_values
        if nv is not None and nv.n:
            rep = report_from_counts("NEES", 3, 1, n["used"], self.prob, np.zeros(0), n["nees_fin"],
                                     n["nees_in"], n["nees_above"], n["nees_below"], nv.mean(cap), nv.n)
        c = self.fig.cols or {}
        fig = ErrorSeries(**{k: c.get(k, None) for k in _FIG_FIELDS})
        if fig.time is None:
            fig = ErrorSeries(time=np.zeros(0), pos=np.zeros((0, 3)))
        notes = exclusion_notes(n["ref"], n["out"], n["gap"], n["inv"], t_first, t_last, max_dt)
        return StreamedErrors(statistics=stats, within=within, nees=rep, n_used=n["used"], t0=self.t0,
                              t1=self.t1, figure=fig, figure_nees=c.get("nees"), n_reference=n["ref"],
                              n_outside=n["out"], n_gap=n["gap"], n_invalid=n["inv"], max_dt=max_dt,
                              notes=notes)

    def close(self) -> None:
        for v in self.values.values():
            v.close()
        if self.nees_values is not None:
            self.nees_values.close()


def _position_nees(e: ErrorSeries) -> np.ndarray:
    """Position NEES with the diagonal covariance of the estimate's σ (σ = 0 or NaN: NaN)."""
    sp = np.where(e.std_pos > 0, e.std_pos, np.nan)
    cov = np.zeros((len(e.time), 3, 3))
    idx = np.arange(3)
    cov[:, idx, idx] = sp**2
    return nees(e.pos, cov)
