"""``aidnav process`` with memory independent of the log length (issue 29).

The IMU file is read in batches (:func:`aidnav.io.stream.iter_imu`), the filter runs chunk by chunk
(:func:`aidnav.filters.stream.stream_loose`), each piece of the solution is checked
(:func:`aidnav.apps.common.check_solution`, joined to the last epoch before it), scored at the withheld
fixes and written (:class:`aidnav.io.stream.TrajectoryWriter`, row groups of :data:`ROW_GROUP_ROWS`
epochs); the figures and maps get a decimated copy (at most :data:`FIGURE_POINTS` epochs). The numbers
are :func:`aidnav.apps.process.process`'s. After the first chunk (the whole-log set-up done) the freed
heap is given back to the system (:func:`trim_heap`).
:func:`streamable` says when this path applies (interchange Parquet IMU, no ``--start/--end``, no
whole-log mounting fit); :func:`aidnav.apps.process.process_logs` takes it then.
"""

from __future__ import annotations

import time as _time

import numpy as np

from aidnav.apps.common import check_solution
from aidnav.data import Trajectory
from aidnav.io.stream import concat_rows, take_rows

FIGURE_POINTS = 20000  #: at most this many epochs go to overview.png, the maps and run.html
#: the decimated rows of the latest pieces are joined into one block when there are this many pieces or
#: rows (a long log gives a few rows a piece, 28 small arrays each; the join's copy stays small)
DEC_JOIN, DEC_JOIN_ROWS = 32, 2048
CHUNK_ROWS = 1 << 13  #: IMU samples per chunk (the per-chunk buffers are about 1.3 kB per sample)
#: epochs per row group of a Parquet trajectory (pieces held until then: 28 columns, ≈ 7 MB; the writer
#: keeps ≈ 24 kB of metadata per row group until the end, ≈ 10 MB over 10 h at one row group a chunk)
ROW_GROUP_ROWS = 1 << 15


def streamable(imu_path, cfg, aids=(), start_s=None, end_s=None) -> bool:
    """Whether ``process_logs`` can stream this job (module doc)."""
    from aidnav.filters.stream import needs_whole_log
    from aidnav.io.formats import detect_imu_format
    from aidnav.io.stream import imu_time_span

    if start_s is not None or end_s is not None or needs_whole_log(cfg, aids):
        return False
    try:
        if detect_imu_format(imu_path) != "interchange":
            return False
    except Exception:  # noqa: BLE001  (the whole-file reader gives the message)
        return False
    return imu_time_span(imu_path) is not None


_CHECKED = ("time", "lat", "lon", "height", "vel", "rph", "std_pos")  # what the checks and scores read


def _join(a: Trajectory | None, b: Trajectory) -> Trajectory:
    """The last epoch of ``a`` followed by ``b`` (checks and interpolation across a chunk boundary): the
    columns of :data:`_CHECKED` only."""
    if a is None:
        return b
    k = len(a.time) - 1
    return Trajectory(*(None if getattr(b, c) is None else np.concatenate([getattr(a, c)[k:], getattr(b, c)])
                        for c in _CHECKED))


class _Sink:
    """Check, score, decimate and (unless ``write`` is None) write the pieces of one solution."""

    def __init__(self, gnss, withheld, fig_dt, write=None):
        self.gnss, self.withheld, self.fig_dt, self.write = gnss, withheld, fig_dt, write
        self.prev, self.t_err, self.herr, self.dec, self.next_t = None, [], [], [], -np.inf
        self.recent, self.n_recent = [], 0  # decimated rows of the latest pieces (joined into dec: DEC_JOIN)

    def __call__(self, traj: Trajectory):
        from aidnav.apps.process_parts import outage_errors

        j = _join(self.prev, traj)
        check_solution(j, "the loosely coupled filter")
        if self.withheld.any():
            t, e = outage_errors(j, self.gnss, self.withheld,
                                 after=-np.inf if self.prev is None else float(self.prev.time[-1]))
            self.t_err.append(t)
            self.herr.append(e)
        if self.write is not None:
            self.write(traj)
        # decimated copy: the first epoch at or after each multiple of fig_dt
        b = np.floor(traj.time / self.fig_dt)
        keep = np.concatenate([[b[0] > self.next_t], b[1:] > b[:-1]])
        if keep.any():
            self.recent.append(take_rows(traj, keep))
            self.n_recent += len(self.recent[-1].time)
            if len(self.recent) >= DEC_JOIN or self.n_recent >= DEC_JOIN_ROWS:
                self.dec.append(concat_rows(self.recent))
                self.recent, self.n_recent = [], 0
        self.next_t = b[-1]
        self.prev = take_rows(traj, [len(traj.time) - 1])  # (a copy: the piece is not kept)

    def score(self, wins):
        from aidnav.apps.process_parts import outage_score

        t = np.concatenate(self.t_err) if self.t_err else np.zeros(0)
        return outage_score(t, np.concatenate(self.herr) if self.herr else np.zeros(0), wins, self.withheld,
                            self.gnss)

    def decimated(self) -> Trajectory:
        return concat_rows(self.dec + self.recent)


def stream_process(imu_path, gnss, cfg, traj_path, week, smooth=False, outages=None, imu_name="imu",
                   gnss_name="gnss", skip_checks=(), aids=(), progress=None,
                   chunk_rows: int | None = None, background: bool = True):
    """The streamed :func:`aidnav.apps.process.process` + writing: returns (summary of the run, decimated
    trajectory for the figures, the filter's :class:`FilterResult` (last epoch, records, counts)).

    ``background``: each piece of the solution is converted, checked, scored and written in one
    background thread (:class:`aidnav.io.stream.Background`, at most 2 pieces waiting) while the filter
    runs the next chunk (the engine releases the GIL) — the same pieces in the same order, so the same
    file and numbers; a failure there is raised here and the partial file removed."""
    from aidnav.apps.process_parts import finish_summary, outage_windows, parse_outage, run_summary
    from aidnav.filters.result import to_trajectory
    from aidnav.filters.stream import stream_loose
    from aidnav.io.sanity import check_gnss, check_imu, check_motion, check_overlap
    from aidnav.io.stream import Background, TrajectoryWriter, imu_time_span, iter_imu

    applied = float(cfg.imu.time_offset_s)
    if applied:  # applied here, once; a configuration that states no offset lets the filter estimate it
        cfg = cfg.model_copy(update={"imu": cfg.imu.model_copy(update={"time_offset_s": 0.0})})
    chunks = iter_imu(imu_path, chunk_rows or CHUNK_ROWS)
    head = next(chunks)
    offset_event = [f"IMU time offset {applied:+.4f} s added to the IMU stamps"] if applied else []

    def shifted(first, rest):
        yield _shift(first, applied)
        for c in rest:
            yield _shift(c, applied)

    warnings = check_imu(_shift(head, applied), imu_name, skip_checks)  # the first chunk
    warnings += check_gnss(gnss, gnss_name, skip_checks)
    ta, tb = imu_time_span(imu_path)

    class _Span:
        time = np.array([ta + applied, tb + applied])

    warnings += check_overlap(_Span, gnss, imu_name, gnss_name, skip_checks)
    warnings += check_motion(_shift(_check_head(imu_path), applied), gnss, imu_name, gnss_name, skip_checks)
    wins = outage_windows([parse_outage(o) for o in (outages or [])], gnss.time[0], gnss.time[-1])
    withheld = np.zeros(len(gnss), bool)
    for a, b in wins:
        withheld |= (gnss.time >= a) & (gnss.time < b)
    fig_dt = max((tb - ta) / FIGURE_POINTS, 1e-9)
    writer = TrajectoryWriter(traj_path, week=week, row_group_rows=ROW_GROUP_ROWS)
    sink = _Sink(gnss, withheld, fig_dt, writer.write)
    fwd = _Sink(gnss, withheld, np.inf) if smooth and wins else None
    n_imu = [0]

    def consume(piece, forward=False):
        if forward:  # the forward solution of a smoothed run: scored at the outages only
            if fwd is not None:
                fwd(to_trajectory(piece))
            return
        sink(to_trajectory(piece))

    bg = Background(consume) if background else None
    emit = consume if bg is None else bg.put

    def count(m):
        if not n_imu[0]:  # the first chunk done: the whole-log set-up is over
            trim_heap()
        n_imu[0] += m
        if progress is not None:
            progress(m)

    events: list[str] = []
    if "constraints" not in cfg.model_fields_set and not cfg.constraints.nhc:
        # the no-option NHC decision (apps.process._no_option_constraint) needs a first pass over the whole
        # log: a streamed job does not make it
        events.append("vehicle from the log: not decided in a streamed job (the test needs a first pass over "
                      "the whole log): NHC off; a constraints section in the configuration decides")
    t0 = _time.perf_counter()
    try:
        res = stream_loose(shifted(head, chunks), gnss, cfg, emit, withheld=withheld, smooth=smooth,
                           events=events, aids=aids, spool_dir=writer.path.parent,
                           progress=count)
        if bg is not None:
            bg.close()  # every piece written (or its error raised)
        writer.close()
    except BaseException:
        if bg is not None:
            bg.abort()  # the thread stopped before the writer is closed
        writer.abort()
        raise
    t_filt = _time.perf_counter() - t0
    rate = 1.0 / float(np.median(np.diff(head.time)))
    summary = run_summary(res, n_imu[0], rate, gnss, withheld, wins, head.events + offset_event + gnss.events
                          + events, warnings, t_filt)
    if wins:
        summary["outage_score"] = sink.score(wins)
        if fwd is not None:
            summary["outage_score_forward"] = fwd.score(wins)
    finish_summary(summary, res, applied, warnings)
    return summary, sink.decimated(), res


def trim_heap() -> None:
    """Give the freed heap back to the system (glibc's ``malloc_trim``; elsewhere nothing): reading the
    GNSS file and the whole-log set-up (records, initialisation, static test) free their temporaries
    between blocks that stay, and the allocator would keep those pages resident for the rest of the run
    (−3 to −4 MiB of peak RSS on a 10-h log, none on a 1-h one)."""
    import ctypes

    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError, TypeError):
        pass


#: IMU samples read (again) for the motion checks of a streamed job (10 min at 100 Hz)
CHECK_ROWS = 60_000


def _check_head(imu_path):
    """The first :data:`CHECK_ROWS` samples of the log (the motion checks compare them with the GNSS)."""
    from aidnav.io.stream import iter_imu

    return next(iter_imu(imu_path, CHECK_ROWS))


def _shift(c, offset):
    from aidnav.data import ImuData

    if not offset:
        return c
    return ImuData(c.time + offset, c.dtheta, c.dv, t0=None if c.t0 is None else c.t0 + offset,
                   events=c.events, week=c.week)
