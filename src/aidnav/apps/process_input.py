"""The inputs of one ``aidnav process`` run (issue 36: one processing path): the IMU log as chunks in
time order (:class:`ImuLog`), whatever holds it, with the IMU time offset and the processing window
(``--start/--end``) applied to the chunks as they come.

An interchange Parquet file is read in batches of :data:`CHUNK_ROWS` samples
(:func:`aidnav.io.stream.iter_imu`: memory independent of the log length) by one reader that every pass
over the log shares (:class:`_Shared`: the checks' and the first passes' look at the log's head, then the
run, all from one decoding of the file: a second reader would hold its own pages of every column, ≈ 15 MB
on a one-row-group log); any other format, and a log already in memory, is one chunk: the run is then the
whole-log filter, number for number (its two head statistics, the nominal sample interval and the static
window's rate, are the whole log's).
"""

from __future__ import annotations

import weakref

import numpy as np

from aidnav.data import GnssData, ImuData
from aidnav.errors import InputError

CHUNK_ROWS = 1 << 13  #: IMU samples per chunk of a file read in batches (≈ 1.3 kB of buffers a sample)
#: IMU samples the motion checks compare with the GNSS when the chunks are smaller (10 min at 100 Hz)
CHECK_ROWS = 60_000
#: the chunks read from a file are kept for the passes that start later (the checks, the first passes over
#: the log's first 20 min) while they hold at most this many samples (≈ 7 MB; 21 min at 100 Hz), and
#: dropped once every pass is beyond them
SHARED_ROWS = 1 << 17


class ImuLog:
    """An IMU log as consecutive :class:`aidnav.data.ImuData` chunks (``t0`` of each the time of the
    sample before it): ``chunks()`` a new iterator over them each call, ``span`` the first and last
    sample times, ``rows`` the number of samples (at most, after a window)."""

    def __init__(self, chunks, span: tuple[float, float], rows: int):
        self._chunks, self.span, self.rows = chunks, (float(span[0]), float(span[1])), int(rows)

    @classmethod
    def of(cls, imu: ImuData) -> ImuLog:
        """A log in memory: one chunk."""
        return cls(lambda: iter([imu]), (imu.time[0], imu.time[-1]), len(imu))

    def chunks(self):
        return self._chunks()

    def check_head(self) -> ImuData:
        """The samples the motion checks look at: the first chunk, or the first :data:`CHECK_ROWS`
        samples where the chunks are smaller."""
        it = self.chunks()
        got = [next(it)]
        n = len(got[0])
        while n < CHECK_ROWS:
            c = next(it, None)
            if c is None:
                break
            got.append(c)
            n += len(c)
        return got[0] if len(got) == 1 else _first_rows(got, CHECK_ROWS)

    def shifted(self, offset_s: float) -> ImuLog:
        """The log with ``offset_s`` added to every stamp (IMU clock → GNSS time scale)."""
        if not offset_s:
            return self
        if not np.isfinite(offset_s):
            raise InputError(f"IMU time offset {offset_s}: not a finite number of seconds")
        return ImuLog(lambda: (shift(c, offset_s) for c in self.chunks()),
                      (self.span[0] + offset_s, self.span[1] + offset_s), self.rows)

    def windowed(self, a: float, b: float) -> ImuLog:
        """The samples in [a, b] (the first one's ``t0`` the sample before it; the first chunk's events
        kept)."""
        def chunks():
            prev, events = None, None
            for c in self.chunks():
                events = list(c.events) if events is None else events
                m = (c.time >= a) & (c.time <= b)
                if m.any():
                    k = int(np.flatnonzero(m)[0])
                    t0 = float(c.time[k - 1]) if k > 0 else (c.t0 if prev is None else prev)
                    yield ImuData(c.time[m], c.dtheta[m], c.dv[m], t0=t0, events=events, week=c.week)
                    events = []
                prev = float(c.time[-1])
                if prev > b:
                    return

        span = (max(a, self.span[0]), min(b, self.span[1]))
        part = (span[1] - span[0]) / max(self.span[1] - self.span[0], 1e-9)
        return ImuLog(chunks, span, min(self.rows, int(np.ceil(part * self.rows)) + 1))


def shift(c: ImuData, offset: float) -> ImuData:
    """A chunk with ``offset`` added to its stamps."""
    if not offset:
        return c
    return ImuData(c.time + offset, c.dtheta, c.dv, t0=None if c.t0 is None else c.t0 + offset,
                   events=c.events, week=c.week)


def _first_rows(chunks, n: int) -> ImuData:
    """The first ``n`` samples of consecutive chunks, as one :class:`ImuData`."""
    t = np.concatenate([c.time for c in chunks])[:n]
    dth = np.concatenate([c.dtheta for c in chunks])[:n]
    dv = np.concatenate([c.dv for c in chunks])[:n]
    return ImuData(t, dth, dv, t0=chunks[0].t0, events=list(chunks[0].events), week=chunks[0].week)


class _Shared:
    """The chunks of one reader (``make()``: a new iterator over the file's chunks) shared by every pass
    over the log. The chunks read are kept while they hold at most :data:`SHARED_ROWS` samples; past
    that only those a live pass has yet to reach, and a pass that lags behind the one reading on is
    given a reader of its own (the buffer never holds more than the first passes' span, or the cap). A
    pass that starts after the log's first chunks were dropped reads the file anew. The chunks are the
    same objects in every pass: no consumer changes their arrays in place (they stay writable: numba's
    kernels are compiled for writable arrays)."""

    def __init__(self, make, hold_rows: int | None = None):
        self.make, self.hold = make, SHARED_ROWS if hold_rows is None else int(hold_rows)
        self.src, self.buf, self.first, self.rows, self.done, self.spilled = None, [], 0, 0, False, False
        self.error = None
        self.passes = weakref.WeakSet()

    def chunks(self):
        if self.first > 0:  # the log's first chunks are gone: this pass reads the file itself
            return self.make()
        p = _Pass(self)
        self.passes.add(p)
        return p

    def get(self, p: _Pass):
        """The next chunk of the pass ``p`` (None past the end), read from the file when not read yet."""
        i = p.i
        while i >= self.first + len(self.buf) and not self.done:
            if self.error is not None:  # the file's error (a bad row): every pass that reaches it
                raise self.error
            if self.src is None:
                self.src = self.make()
            try:
                c = next(self.src, None)
            except Exception as e:
                self.error, self.src = e, None
                raise
            if c is None:
                self.done, self.src = True, None
                break
            self.buf.append(c)
            self.rows += len(c)
            self.spilled = self.spilled or self.rows > self.hold
            if self.spilled:
                self._detach_behind(p)
        k = i - self.first
        return self.buf[k] if 0 <= k < len(self.buf) else None

    def _detach_behind(self, p: _Pass) -> None:
        """Past the cap, reading on for ``p``: the passes behind it read on with readers of their own."""
        for q in list(self.passes):
            if q is not p and q.i < p.i:
                q.own = _skip(self.make(), q.i)
                self.passes.discard(q)

    def drop(self) -> None:
        """Past the cap: the chunks before every live pass dropped."""
        if self.spilled:
            low = min((q.i for q in self.passes), default=self.first + len(self.buf))
            while self.buf and self.first < low:
                self.rows -= len(self.buf.pop(0))
                self.first += 1


def _skip(it, n: int):
    """The iterator ``it`` after its first ``n`` items."""
    for _ in range(n):
        next(it, None)
    return it


class _Pass:
    """One pass over a :class:`_Shared` log's chunks (an iterator; ``i`` the next chunk's index; ``own``
    its own reader once detached)."""

    def __init__(self, shared: _Shared):
        self.shared, self.i, self.own = shared, 0, None

    def __iter__(self):
        return self

    def __next__(self):
        c = self.shared.get(self) if self.own is None else next(self.own, None)
        if c is None:
            raise StopIteration
        self.i += 1
        if self.own is None:
            self.shared.drop()
        return c


def open_imu(path, topic: str | None = None, chunk_rows: int | None = None) -> ImuLog:
    """The IMU log of a file: an interchange Parquet file in batches of ``chunk_rows`` samples (default
    :data:`CHUNK_ROWS`), any other format (a ROS bag: its ``topic``) read whole as one chunk."""
    from aidnav.io.formats import detect_imu_format, read_imu  # lazy: the readers of every format
    from aidnav.io.stream import imu_time_span, iter_imu  # lazy: pyarrow

    span = None
    if topic is None:
        try:
            fmt = detect_imu_format(path)
        except Exception:  # noqa: BLE001  (the whole-file reader gives the message)
            fmt = None
        span = imu_time_span(path) if fmt == "interchange" else None  # (its message: a bad time column)
    if span is not None:
        rows = chunk_rows or CHUNK_ROWS
        return ImuLog(_Shared(lambda: iter_imu(path, rows)).chunks, span, _parquet_rows(path))
    imu = read_imu(path, topic=topic)
    if len(imu) < 2:
        from aidnav.io.errors import DataError  # lazy: only on this error

        raise DataError(path, None, "fewer than 2 IMU samples")
    return ImuLog.of(imu)


def _parquet_rows(path) -> int:
    import pyarrow.parquet as pq  # lazy: pyarrow is heavy to import

    with pq.ParquetFile(path) as pf:
        return pf.metadata.num_rows


def window(log: ImuLog, gnss: GnssData, start_s: float | None, end_s: float | None):
    """Cut both logs to ``[start, end]`` seconds after the first IMU sample (``--start/--end``): (log,
    fixes); the fixes' events name the window."""
    if start_s is None and end_s is None:
        return log, gnss
    t0, t_last = log.span
    a = t0 + (start_s or 0.0)
    b = t0 + end_s if end_s is not None else t_last
    if b <= a:
        raise InputError(f"--start/--end: empty window ({start_s} … {end_s} s after the first IMU sample)")
    if a >= t_last:
        raise InputError(f"--start {start_s}: after the end of the IMU log ({t_last - t0:.1f} s long)")
    gnss2 = gnss.subset((gnss.time >= a) & (gnss.time <= b))
    gnss2.events = list(gnss.events) + [f"processing window {a:.3f} … {b:.3f} s"]
    return log.windowed(a, b), gnss2
