"""The one run of ``aidnav process`` (issues 29, 36): IMU chunks → plausibility checks → the filter chunk
by chunk → each piece of the solution checked, scored, decimated, written (and kept, for the library's
:func:`aidnav.apps.process.process`).

The IMU log comes as chunks (:class:`aidnav.apps.process_input.ImuLog`: an interchange Parquet file in
batches; any other format, and a log in memory, as one chunk: then the whole-log filter, number for
number). The filter is :func:`aidnav.filters.stream.stream_loose`; each piece of the solution is checked
(:func:`aidnav.apps.common.check_solution`, joined to the last epoch before it), scored at the withheld
fixes and handed to ``write`` (e.g. :class:`aidnav.io.stream.TrajectoryWriter`, row groups of
:data:`ROW_GROUP_ROWS` epochs); the figures and maps get a decimated copy (at most :data:`FIGURE_POINTS`
epochs). After the first chunk (the whole-log set-up done) the freed heap is given back to the system
(:func:`trim_heap`).
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field
from itertools import chain

import numpy as np

from aidnav.apps.common import check_solution
from aidnav.apps.outages import outage_errors, outage_score, outage_windows, parse_outage, withheld_fixes
from aidnav.apps.process_input import ImuLog, window
from aidnav.apps.process_summary import finish_summary, run_summary
from aidnav.data import GnssData, ImuData, Trajectory
from aidnav.errors import InputError
from aidnav.io.stream import concat_rows, take_rows

FIGURE_POINTS = 20000  #: at most this many epochs go to overview.png, the maps and run.html
#: the decimated rows of the latest pieces are joined into one block when there are this many pieces or
#: rows (a long log gives a few rows a piece, 28 small arrays each; the join's copy stays small)
DEC_JOIN, DEC_JOIN_ROWS = 32, 2048
#: epochs per row group of a Parquet trajectory (pieces held until then: 28 columns, ≈ 7 MB; the writer
#: keeps ≈ 24 kB of metadata per row group until the end, ≈ 10 MB over 10 h at one row group a chunk)
ROW_GROUP_ROWS = 1 << 15

_CHECKED = ("time", "lat", "lon", "height", "vel", "rph", "std_pos")  # what the checks and scores read


@dataclass
class ProcessRun:
    """What a run gives: the summary, the decimated trajectory for the figures, the filter's
    :class:`aidnav.filters.result.FilterResult` (records, counts, calibration; its arrays the last epoch
    only, or every epoch with ``keep``), the fixes the filter saw (after ``--start/--end``: records line
    up), the withheld mask and outage windows; with ``keep`` the whole trajectory and, when smoothed, the
    forward one."""

    trajectory: Trajectory | None
    summary: dict
    result: object = None
    forward_trajectory: Trajectory | None = None
    withheld: np.ndarray | None = None
    windows: list = field(default_factory=list)
    gnss: GnssData | None = None
    decimated: Trajectory | None = None


def _join(a: Trajectory | None, b: Trajectory) -> Trajectory:
    """The last epoch of ``a`` followed by ``b`` (checks and interpolation across a chunk boundary): the
    columns of :data:`_CHECKED` only."""
    if a is None:
        return b
    k = len(a.time) - 1
    return Trajectory(*(None if getattr(b, c) is None else np.concatenate([getattr(a, c)[k:], getattr(b, c)])
                        for c in _CHECKED))


class Sink:
    """Check, score, decimate, write (unless ``write`` is None) and keep (with ``keep``) the pieces of one
    solution."""

    def __init__(self, gnss, withheld, fig_dt, write=None, keep: bool = False):
        self.gnss, self.withheld, self.fig_dt, self.write = gnss, withheld, fig_dt, write
        self.prev, self.t_err, self.herr, self.dec, self.next_t = None, [], [], [], -np.inf
        self.recent, self.n_recent = [], 0  # decimated rows of the latest pieces (joined into dec: DEC_JOIN)
        self.kept = [] if keep else None

    def __call__(self, traj: Trajectory):
        j = _join(self.prev, traj)
        check_solution(j, "the loosely coupled filter")
        if self.withheld.any():
            t, e = outage_errors(j, self.gnss, self.withheld,
                                 after=-np.inf if self.prev is None else float(self.prev.time[-1]))
            self.t_err.append(t)
            self.herr.append(e)
        if self.write is not None:
            self.write(traj)
        if self.kept is not None:
            self.kept.append(traj)
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
        t = np.concatenate(self.t_err) if self.t_err else np.zeros(0)
        return outage_score(t, np.concatenate(self.herr) if self.herr else np.zeros(0), wins, self.withheld,
                            self.gnss)

    def decimated(self) -> Trajectory:
        return concat_rows(self.dec + self.recent)

    def whole(self) -> Trajectory | None:
        """Every piece kept, as one trajectory (None without ``keep``)."""
        return None if self.kept is None else concat_rows(self.kept)


#: the no-option vehicle decision (:func:`aidnav.filters.wheeled.no_option_constraint`) looks at the log's
#: first 20 min at most: the memory it holds stays bounded whatever the log's length (issue 29), and 20 min
#: hold the 30 s of motion with 90° of turning the decision needs in any log that has them early
DECIDE_SPAN_S = 1200.0


def _prefix(log: ImuLog, span_s: float) -> ImuData:
    """The IMU log's first ``span_s`` seconds in memory (a new pass over its chunks, stopped there)."""
    cs, end = [], None
    for c in log.chunks():
        end = float(c.time[0]) + span_s if end is None else end
        keep = c.time <= end
        if not keep.all():
            if keep.any():
                cs.append(ImuData(c.time[keep], c.dtheta[keep], c.dv[keep], t0=c.t0, events=list(c.events)))
            break
        cs.append(c)
    if len(cs) == 1:
        return cs[0]
    return ImuData(np.concatenate([c.time for c in cs]), np.concatenate([c.dtheta for c in cs]),
                   np.concatenate([c.dv for c in cs]), t0=cs[0].t0, events=list(cs[0].events))


def run_process(log: ImuLog, gnss, cfg, smooth=False, outages=None, imu_name="imu", gnss_name="gnss",
                skip_checks=(), start_s=None, end_s=None, aids=(), write=None, keep: bool = False,
                progress=None, spool_dir=None, background: bool = True, started=None) -> ProcessRun:
    """One ``aidnav process`` run over ``log`` (module doc): ``cfg.imu.time_offset_s`` is added to the IMU
    stamps here, once; ``start_s``/``end_s`` cut both logs (seconds after the first IMU sample); ``write``
    gets each piece of the solution (a :class:`aidnav.data.Trajectory`) in time order; ``keep``: the
    whole solution (and the filter's arrays) in the result too. progress : called with the number of IMU
    samples of each chunk done.

    ``background``: each piece of the solution is converted, checked, scored and written in one
    background thread (:class:`aidnav.io.stream.Background`, at most 2 pieces waiting) while the filter
    runs the next chunk (the engine releases the GIL) — the same pieces in the same order, so the same
    file and numbers; a failure there is raised here. ``started``: called once just before the run (after
    the checks and the first passes; the ``aidnav`` command resumes its garbage collector there)."""
    from aidnav.filters.gnss_errors import (  # lazy: the filters load with the job
        choose_gnss_errors,
        needs_first_pass,
    )
    from aidnav.filters.result import to_trajectory  # lazy: the filters load with the job
    from aidnav.filters.stream import stream_loose  # lazy: the filters load with the job
    from aidnav.filters.wheeled import no_option_constraint  # lazy: the filters load with the job
    from aidnav.io.stream import Background  # lazy: pyarrow

    applied = float(cfg.imu.time_offset_s)
    if applied:  # applied here, once; a configuration that states no offset lets the filter estimate it
        cfg = cfg.model_copy(update={"imu": cfg.imu.model_copy(update={"time_offset_s": 0.0})})
        log = log.shifted(applied)
    log, gnss = window(log, gnss, start_s, end_s)
    chunks = log.chunks()
    head = next(chunks, None)
    if head is None:
        raise InputError(f"--start {start_s} / --end {end_s}: no IMU sample in that window")
    warnings = _checks(log, head, gnss, imu_name, gnss_name, skip_checks)
    wins = outage_windows([parse_outage(o) for o in (outages or [])], gnss.time[0], gnss.time[-1])
    withheld = withheld_fixes(gnss, wins)
    fig_dt = max((log.span[1] - log.span[0]) / FIGURE_POINTS, 1e-9)
    sink = Sink(gnss, withheld, fig_dt, write, keep)
    fwd = Sink(gnss, withheld, np.inf, keep=keep) if smooth and (wins or keep) else None
    pieces = {False: [], True: []} if keep else None
    n_imu = [0]

    def consume(piece, forward=False):
        if pieces is not None:
            pieces[forward].append(piece)
        if forward:  # the forward solution of a smoothed run: scored at the outages only
            if fwd is not None:
                fwd(to_trajectory(piece))
            return
        sink(to_trajectory(piece))

    def count(m):
        if not n_imu[0]:  # the first chunk done: the whole-log set-up is over
            trim_heap()
        n_imu[0] += m
        if progress is not None:
            progress(m)

    events: list[str] = []
    decide_nhc = "constraints" not in cfg.model_fields_set and not cfg.constraints.nhc
    decide_gnss = needs_first_pass(gnss, cfg)  # the fixes' σ; white/correlated errors (filters.gnss_errors)
    prefix = _prefix(log, DECIDE_SPAN_S) if decide_nhc or decide_gnss else None  # in memory once
    if decide_nhc:
        # no option (issue 35): the NHC decided from a first pass over the log's first DECIDE_SPAN_S
        # (filters.wheeled)
        before = len(events)
        cfg = no_option_constraint(prefix, gnss, cfg, withheld, events, aids)[0]
        if log.span[1] - log.span[0] > DECIDE_SPAN_S:
            events[before:] = [f"{e} (decided from the log's first {DECIDE_SPAN_S:g} s)"
                               for e in events[before:]]
    if decide_gnss:  # the fixes' σ, white/correlated errors: a first pass's innovations (filters.gnss_errors)
        cfg = choose_gnss_errors(prefix, gnss, cfg, withheld, events, aids)
    del prefix
    if started is not None:
        started()
    t0 = _time.perf_counter()
    bg = Background(consume) if background else None  # here: a failure above leaves no thread behind
    try:
        res = stream_loose(chain([head], chunks), gnss, cfg, consume if bg is None else bg.put,
                           withheld=withheld, smooth=smooth, events=events, aids=aids, spool_dir=spool_dir,
                           progress=count)
        if bg is not None:
            bg.close()  # every piece written (or its error raised)
    except BaseException:
        if bg is not None:
            bg.abort()  # the thread stopped before the caller closes what it writes to
        raise
    t_filt = _time.perf_counter() - t0
    trim_heap()  # the run's temporaries freed: what follows (summary, maps, figures' job) starts lower
    if pieces is not None:
        _whole_result(res, pieces)
    offset_event = [f"IMU time offset {applied:+.4f} s added to the IMU stamps"] if applied else []
    summary = run_summary(res, n_imu[0], head.rate_hz, gnss, withheld, wins,
                          head.events + offset_event + gnss.events + events, warnings, t_filt)
    if wins:
        summary["outage_score"] = sink.score(wins)
        if fwd is not None:
            summary["outage_score_forward"] = fwd.score(wins)
    finish_summary(summary, res, applied, warnings)
    return ProcessRun(sink.whole(), summary, res, None if fwd is None else fwd.whole(), withheld, wins, gnss,
                      sink.decimated())


def _checks(log: ImuLog, head, gnss, imu_name, gnss_name, skip_checks) -> list[str]:
    """The plausibility checks before filtering (:mod:`aidnav.io.sanity`): the IMU's first chunk, the
    fixes, their overlap (the log's span), the IMU against the GNSS track (:meth:`ImuLog.check_head`)."""
    from aidnav.io.sanity import check_gnss, check_imu, check_motion, check_overlap  # lazy: with the job

    warnings = check_imu(head, imu_name, skip_checks)
    warnings += check_gnss(gnss, gnss_name, skip_checks)

    class _Span:
        time = np.array(log.span)

    warnings += check_overlap(_Span, gnss, imu_name, gnss_name, skip_checks)
    warnings += check_motion(log.check_head(), gnss, imu_name, gnss_name, skip_checks)
    return warnings


def _whole_result(res, pieces) -> None:
    """The filter's result with every epoch (in place): the pieces' arrays joined (``forward_*``: the
    forward pieces of a smoothed run)."""
    main, fwd = pieces[False], pieces[True]
    if main:
        for k in ("time", "state", "bias", "pdiag"):
            setattr(res, k, np.concatenate([getattr(p, k) for p in main]))
    if fwd:
        res.forward_state = np.concatenate([p.state for p in fwd])
        res.forward_pdiag = np.concatenate([p.pdiag for p in fwd])


def trim_heap() -> None:
    """Give the freed heap back to the system (glibc's ``malloc_trim``; elsewhere nothing): reading the
    GNSS file and the whole-log set-up (records, initialisation, static test) free their temporaries
    between blocks that stay, and the allocator would keep those pages resident for the rest of the run
    (−3 to −4 MiB of peak RSS on a 10-h log, none on a 1-h one)."""
    import ctypes  # lazy: only here

    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError, TypeError):
        pass
