"""The loose filter chunk by chunk (issue 29): memory independent of the log length.

:func:`stream_loose` takes the IMU log as an iterator of :class:`aidnav.data.ImuData` chunks (IMU
stamps on the GNSS time scale, in order) and hands the solution on chunk by chunk to a callback, as
:class:`aidnav.filters.result.FilterResult` pieces (``time``, ``state``, ``bias``, ``pdiag``). The
engine runs each chunk from the carried state of the one before (:func:`aidnav.filters.engine.run_chunk`);
the static detection carries its running sums (:class:`.preprocess.StaticDetector`) and the gap bridge
the window before each chunk, so the solution is the one :func:`aidnav.filters.loose.run_loose` gives
on the whole log, number for number, with two whole-log statistics taken from the head of the log
instead (the first ``head_s`` seconds, at least one chunk): the nominal sample interval of the gap
bridge and the rate of the static window (equal on a regularly sampled log).

With the smoother, or with an estimated IMU time offset (output times are shifted by its final
estimate), the forward outputs go to a spool file (float64 rows) and are read back chunk by chunk
after the pass. The node matrices of the smoother (P⁺, P⁻, Φ: 3n² floats a node) go to a second spool
and the RTS pass reads them backwards in blocks (:func:`_rts_spooled`); what stays in memory per node is
its sample index, δx, the smoothed ds and diag Ps (3n + 1 floats, ≈ 0.5 kB at n = 21).

Each chunk's engine call gets only the records it can reach (:data:`REC_AHEAD_S`), so its log is the
size of the chunk's, not the whole log's. What stays whole-log: the GNSS fixes, their records and the
per-record log (1 Hz: 100 times fewer rows than the IMU; status, NIS, innovation and diag S of at most
:data:`REC_ROWS` rows: ≈ 60 bytes a record), the model id and status of every node-constraint update
(2 bytes per node). A log that needs a
whole-log fit before filtering (the coarse mounting: NHC or an aid in the vehicle frame with no mounting
configured, :func:`needs_whole_log`) is taken whole into the head (every chunk held); full covariances at
given times are for :func:`run_loose`. Given as one chunk, the log is its own head and the result is
:func:`run_loose`'s bit for bit (``aidnav process`` on a log in memory or in any format but interchange
Parquet). A chunk longer than :data:`ENGINE_ROWS` samples (a log given whole, the first passes' 10 or 20
min) is run in engine calls of that many: the arrays of one call (outputs, gap bridge) stay bounded, and
the carried state makes the result the one call's, bit for bit.
"""

from __future__ import annotations

from itertools import chain

import numpy as np

from aidnav.data import ImuData
from aidnav.io.stream import Spool

from .aids import vehicle_frame
from .engine import NEVER, Imu, Log, Output, run_chunk, start_carry
from .layout import L_TOFF, NAV, layout_names
from .loose import loose_setup
from .measurements import MAX_ROWS
from .preprocess import StaticDetector, bridge_gaps, visible_fixes
from .result import FilterResult
from .run_log import calibration_base, gnss_records, log_dict, loose_counts, reinit_events
from .smoother import rts, smooth_outputs


def needs_whole_log(cfg, aids=()) -> bool:
    """Whether the loose filter needs the whole log in memory (the coarse mounting is a whole-log fit):
    the NHC or an aid in the vehicle frame (:class:`aidnav.filters.aids.Aid`) with no mounting given."""
    return bool(cfg.constraints.nhc or vehicle_frame(aids)) and "mounting_rph_deg" not in \
        cfg.imu.model_fields_set


def _concat(chunks):
    if len(chunks) == 1:
        return chunks[0]
    return ImuData(np.concatenate([c.time for c in chunks]), np.concatenate([c.dtheta for c in chunks]),
                   np.concatenate([c.dv for c in chunks]), t0=chunks[0].t0, events=list(chunks[0].events))


def _head(chunks, gnss, head_s):
    """(head ImuData, the chunks it was made of, the iterator): at least ``head_s`` s past the later of
    the first IMU sample and the first GNSS fix (the initialisation looks there)."""
    got = [next(chunks)]
    t_start = max(float(got[0].time[0]), float(gnss.time[0]) if len(gnss) else -np.inf)
    while got[-1].time[-1] < t_start + head_s:
        try:
            got.append(next(chunks))
        except StopIteration:
            break
    return _concat(got), got, chunks


#: the most IMU samples one engine call gets: a longer chunk (a log given whole, the first passes' head) is
#: run in pieces of this size (the engine's outputs and the gap bridge's arrays are per call: a whole-log
#: call holds them for every sample; the carried state makes the pieces the one call's result)
ENGINE_ROWS = 1 << 13


def _pieces(c, rows: int):
    """``c`` in consecutive pieces of at most ``rows`` samples (``t0`` of each the sample before it)."""
    n = len(c)
    if n <= rows:
        yield c
        return
    for a in range(0, n, rows):
        b = min(a + rows, n)
        yield ImuData(c.time[a:b], c.dtheta[a:b], c.dv[a:b], t0=c.t0 if a == 0 else float(c.time[a - 1]),
                      events=c.events if a == 0 else [], week=c.week)


def _lookahead(first, rest, rows: int | None = None):
    """(piece, is_last) over the chunks ``first`` then the iterator ``rest``, each cut into pieces of at
    most ``rows`` samples."""
    pend, rows = None, rows or ENGINE_ROWS
    for c in chain(first, rest):
        for p in _pieces(c, rows):
            if pend is not None:
                yield pend, False
            pend = p
    yield pend, True


def stream_loose(chunks, gnss, cfg, emit, withheld=None, smooth: bool = False, events: list | None = None,
                 aids=(), head_s: float = 60.0, spool_dir=None, progress=None):
    """Loosely coupled GNSS/INS (and RTS smoother) over a log given in chunks (module doc).

    chunks : iterator of :class:`aidnav.data.ImuData` (consecutive, ``t0`` of the first one the start
        of its first interval); cfg : :class:`aidnav.filters.config.LooseConfig` with
        ``imu.time_offset_s`` already applied to the stamps (0); emit : called with each piece of the
        solution (a :class:`FilterResult` with ``time``, ``state``, ``bias``, ``pdiag``, ``layout``,
        ``smoothed``) in time order; with the smoother also ``emit(piece, forward=True)`` first for the
        forward pieces. progress : called with the number of IMU samples of each chunk done.
        A log that needs a whole-log fit (:func:`needs_whole_log`) is taken whole into the head.
    Returns a :class:`FilterResult` whose arrays hold the last output epoch only, with ``records``,
    ``counts``, ``innovations`` (the record rows; ``nu`` and ``s`` :data:`REC_ROWS` columns wide unless a
    record used more), ``final_P``, ``events`` as :func:`run_loose`.
    """
    events = events if events is not None else []
    chunks = iter(chunks)
    if needs_whole_log(cfg, aids):  # the coarse mounting is fitted on the whole log: every chunk in the head
        head_s = np.inf
    head, first, rest = _head(chunks, gnss, head_s)
    fw = _Forward(head, gnss, cfg, withheld, events, aids, smooth, spool_dir, emit)
    try:
        for ch, last in _lookahead(first, rest):
            fw.chunk(ch, last)
            if progress is not None:
                progress(len(ch))
        log = fw.log()
        events += reinit_events(log)
        d_hat = fw.time_offset()
        smoothed = fw.emit_spooled(d_hat) if fw.spool is not None else False
    finally:
        fw.close()
    return fw.result(log, gnss, smoothed)


class _Forward:
    """The forward pass of :func:`stream_loose`: the set-up on the head, then one engine call a chunk from
    the carried state; the outputs emitted (or spooled, for the smoother or a time-offset shift), the
    per-record log and the node matrices kept."""

    def __init__(self, head, gnss, cfg, withheld, events, aids, smooth, spool_dir, emit):
        self.su = su = loose_setup(head, gnss, cfg, withheld, events, aids)
        self.cfg, self.lay, self.n, self.k0 = su.cfg, su.lay, su.n, su.k0
        self.events, self.emit, self.smooth = events, emit, smooth
        self.ini, self.rt = su.ini, su.reset_time
        if self.rt is not None and not self.rt <= head.time[-1]:
            self.ini = self.ini._replace(reset_idx=NEVER)  # found below in its chunk (inf: never)
        dt_head = np.diff(np.concatenate([[head.t0], head.time]))
        self.med, rate = float(np.median(dt_head)), head.rate_hz
        self.nwin = max(2, int(round(1.0 / self.med)))
        # static flags for every run: the ZUPT/ZARU where the configuration asks for them, and the engine's
        # tilt turn and heading hold at rest (engine._turn_tilt_at_rest) always
        self.zupt = self.cfg.constraints.zupt
        self.static = StaticDetector(visible_fixes(gnss, withheld), self.cfg, rate)
        self.out = Output(su.out_every, bool(smooth), np.zeros(0, np.int64))
        self.M = len(su.rec.t)
        self.rec_log = None
        self.window = su.rec.grp.t.shape[0] == 0  # (epoch records index the whole log: not windowed)
        self.node_model, self.node_status, self.static_used, self.n_nodes = [], [], 0, 0
        self.spool = self.node_spool = None
        # with the smoother: per node its sample and δx (Φ, P⁻, P⁺ on disk)
        self.node_idx_l, self.node_dx = [], []
        n = self.n
        if smooth or self.lay[L_TOFF] >= 0:
            self.spool = Spool(spool_dir, 3 + 10 + (n - NAV) + n)
        if smooth:
            self.node_spool = Spool(spool_dir, 3 * n * n)
        self.cy = start_carry(su.rec, su.proc, self.ini, False)
        self.tail, self.n_seen, self.t_prev, self.last_piece = None, 0, head.t0, None

    def _prepare(self, ch):
        """The chunk's increments with the gap bridge (the window before it carried) and static flags
        (the carried sums)."""
        m, tail, cfg = len(ch), self.tail, self.cfg
        if tail is None:
            dth, dv, gap_var = bridge_gaps(ch, self.events, med=self.med, bounds=cfg.motion)
        else:
            j = ImuData(np.concatenate([tail.time, ch.time]), np.concatenate([tail.dtheta, ch.dtheta]),
                        np.concatenate([tail.dv, ch.dv]), t0=tail.t0)
            dth, dv, gap_var = bridge_gaps(j, self.events, med=self.med, start=len(tail), bounds=cfg.motion)
        st_fl = self.static(ch.time, ch.dtheta, ch.dv, self.t_prev)
        keep = max(0, min(self.nwin, m))
        self.tail = ImuData(ch.time[m - keep:], ch.dtheta[m - keep:], ch.dv[m - keep:],
                            t0=float(ch.time[m - keep - 1]) if m - keep > 0 else self.t_prev)
        self.t_prev = float(ch.time[-1])
        return dth, dv, gap_var, st_fl

    def chunk(self, ch, last: bool) -> None:
        """One engine call over the chunk ``ch`` (``last``: the log's last)."""
        su, m = self.su, len(ch)
        dth, dv, gap_var, st_fl = self._prepare(ch)
        a = max(0, self.k0 - self.n_seen)  # samples before the first one used (automatic initialisation)
        self.n_seen += m
        if a >= m:
            return
        t = ch.time[a:]
        kb, rt = self.cy.k0, self.rt
        if self.ini.reset_idx == NEVER and rt is not None and np.isfinite(rt) and t[-1] >= rt:
            self.ini = self.ini._replace(reset_idx=kb + int(np.searchsorted(t, rt, side="left")))
        self.static_used += int(st_fl[a:].sum()) if self.zupt else 0  # the ZUPT samples
        # the records this chunk can reach (the engine's own bound, with a margin): its log then holds
        # those rows, not the whole log's (memory and time independent of the log length)
        g0 = self.cy.gi
        g1 = self.M if last or not self.window else min(
            self.M, int(np.searchsorted(su.rec.t, t[-1] + REC_AHEAD_S, side="right")) + 1)
        rec_k = _rec_window(su.rec, g0, g1) if self.window else su.rec
        gb = g0 if self.window else 0  # global index of the window's first record
        cy = self.cy._replace(last=last, gi=self.cy.gi - gb)
        imu_k = Imu(t, dth[a:], dv[a:], st_fl[a:], gap_var[a:], np.zeros((0, 2)))
        r = run_chunk(imu_k, rec_k, su.models, su.proc, self.ini, self.out, cy)
        self.cy = r.carry._replace(gi=r.carry.gi + gb)
        if self.rec_log is None:
            self.rec_log = _new_rec_log(su.rec)
        m_k = len(rec_k.t)
        _keep_rows(self.rec_log, r.log, g0, self.cy.gi, gb)
        self.node_model.append(r.log.model[m_k:r.n_log].copy())
        self.node_status.append(r.log.status[m_k:r.n_log].copy())
        self.n_nodes += len(r.node_idx)
        if self.smooth and len(r.node_idx):
            self.node_idx_l.append(r.node_idx.copy())
            self.node_dx.append(r.S_dx.copy())
            k = len(r.node_idx)
            self.node_spool.write(np.concatenate([r.S_post.reshape(k, -1), r.S_prior.reshape(k, -1),
                                                  r.S_phi.reshape(k, -1)], axis=1))
        if len(r.out_idx):
            tt = t[r.out_idx - kb]
            if self.spool is not None:
                self.spool.write(np.column_stack([tt, r.out_idx, r.out_node, r.out_st, r.out_bias,
                                                  r.out_pdiag]))
            else:
                self.last_piece = _piece(tt, r.out_st, r.out_bias, r.out_pdiag, self.lay)
                self.emit(self.last_piece)

    def log(self) -> dict:
        """The per-record log of the whole run (:func:`aidnav.filters.run_log.log_dict`)."""
        if self.rec_log is None:
            raise ValueError("no IMU sample after the initialisation")
        self.rec_log["ref"] = np.arange(self.M, dtype=np.int64)
        return log_dict(Log(**self.rec_log), self.M)

    def time_offset(self) -> float:
        """The final IMU time-offset estimate d̂ (0 without its state; an event names it): the output
        times are shifted by it."""
        lay, cy = self.lay, self.cy
        d_hat = float(cy.bias[lay[L_TOFF] - NAV]) if lay[L_TOFF] >= 0 else 0.0
        if d_hat:
            sd = float(np.sqrt(cy.P[lay[L_TOFF], lay[L_TOFF]]))
            self.events.append(f"IMU time offset estimated {d_hat:+.4f} s (sigma {sd:.4f} s): output times "
                               "shifted by it")
        return d_hat

    def emit_spooled(self, d_hat: float) -> bool:
        """The spooled forward outputs emitted (times shifted by ``d_hat``), smoothed where the smoother
        runs (the forward pieces first, ``forward=True``); returns whether they were smoothed."""
        n, lay, emit = self.n, self.lay, self.emit
        ds = node_idx = S_dx = pd_nodes = None
        smoothed = False
        if self.smooth and self.n_nodes > 1:
            node_idx, S_dx = np.concatenate(self.node_idx_l), np.concatenate(self.node_dx)
            ds, pd_nodes = _rts_spooled(self.node_spool, S_dx, n, self.cy.reset_node)
            smoothed = True
        nb = n - NAV
        for rows in self.spool.read(1 << 13):
            tt, oi, on = rows[:, 0] + d_hat, rows[:, 1].astype(np.int64), rows[:, 2].astype(np.int64)
            st, b, pd = rows[:, 3:13], rows[:, 13:13 + nb], rows[:, 13 + nb:]
            if smoothed:
                emit(_piece(tt, st, b, pd, lay), forward=True)
                st, b = smooth_outputs(oi, np.ascontiguousarray(st), np.ascontiguousarray(b), on,
                                       node_idx, ds, S_dx, n)
                pd = pd_nodes[np.clip(on, 0, len(node_idx) - 1)]
            self.last_piece = _piece(tt, st, b, pd, lay, smoothed)
            emit(self.last_piece)
        return smoothed

    def close(self) -> None:
        for sp in (self.spool, self.node_spool):
            if sp is not None:
                sp.close()

    def result(self, log, gnss, smoothed: bool) -> FilterResult:
        """The run's :class:`FilterResult`: the last output epoch, the records, counts, log, final P."""
        n, lay, cfg = self.n, self.lay, self.cfg
        node_m = np.concatenate(self.node_model) if self.node_model else np.zeros(0, np.int8)
        node_s = np.concatenate(self.node_status) if self.node_status else np.zeros(0, np.int8)
        cnt = loose_counts({"model": np.concatenate([log["model"], node_m]),
                            "status": np.concatenate([log["status"], node_s])},
                           self.n_nodes, self.static_used, self.n_seen, self.k0)
        if smoothed:  # the size of the node matrices (of run_loose; here on disk, read back in blocks)
            cnt["smoother_memory_mb"] = 4 * self.n_nodes * n * n * 8 / 1e6
        res = self.last_piece if self.last_piece is not None else _piece(
            np.zeros(0), np.zeros((0, 10)), np.zeros((0, n - NAV)), np.zeros((0, n)), lay)
        res.records = gnss_records(log, self.su.rmap, len(gnss))
        res.counts, res.final_P, res.innovations, res.events = cnt, self.cy.P.copy(), log, self.events
        res.state_names, res.calibration_base = layout_names(lay), calibration_base(cfg)
        res.gnss_time = np.asarray(gnss.time, float)
        res.node_time = np.zeros(0)
        return res


#: the records given to a chunk: those stamped up to this long after its last sample (the engine looks
#: 100 s ahead: a time offset or clock bias beyond that is refused there)
REC_AHEAD_S = 200.0


def _rec_window(rec, a, b):
    """The records ``a:b`` (views: the engine's types are unchanged)."""
    return rec._replace(t=rec.t[a:b], model=rec.model[a:b], data=rec.data[a:b], use=rec.use[a:b])


#: innovation columns kept per record row: the record models of the loose filter (GNSS position and
#: velocity, odometer, barometer) have at most 3 rows (the engine's log has MAX_ROWS; widened if needed)
REC_ROWS = 3


def _new_rec_log(rec) -> dict:
    """The engine's log rows of every record before any is done (the fields of :class:`.engine.Log`
    but ``ref``, added at the end; ``t`` the records' own array; ``nu`` and ``s`` :data:`REC_ROWS`
    wide): the only per-record whole-log arrays (≈ 60 bytes a record)."""
    M = len(rec.t)
    return dict(t=rec.t, model=rec.model.astype(np.int8), status=np.full(M, -1, np.int8),
                nis=np.full(M, np.nan), nu=np.full((M, REC_ROWS), np.nan), s=np.full((M, REC_ROWS), np.nan),
                reinit=np.zeros(M, np.int8))


def _keep_rows(rec_log, log, a, b, base) -> None:
    """Rows ``a:b`` (whole-log record indices) of ``rec_log`` from the engine's ``log`` of a chunk whose
    first record is ``base``; ``nu``/``s`` widened to the engine's width when a row uses more columns."""
    for k in ("status", "nis", "nu", "s", "reinit"):
        v = getattr(log, k)[a - base:b - base]
        if v.ndim == 2:
            w = rec_log[k].shape[1]
            if w < v.shape[1] and not np.isnan(v[:, w:]).all():
                for kk in ("nu", "s"):
                    old = rec_log[kk]
                    rec_log[kk] = np.full((len(old), MAX_ROWS), np.nan)
                    rec_log[kk][:, :w] = old
                w = rec_log[k].shape[1]
            v = v[:, :w]
        rec_log[k][a:b] = v


RTS_BLOCK = 1024  #: nodes per block of the spooled RTS pass (3n² floats each: 10.6 MB at n = 21)


def _rts_spooled(node_spool, S_dx, n, brk, block: int | None = None):
    """:func:`.smoother.rts` over the node matrices (P⁺, P⁻, Φ rows of ``node_spool``) read backwards in
    blocks of ``block`` nodes: (ds (K, n), diag Ps (K, n)), the numbers of one call on all nodes. A block
    is extended by the smoothed node after it, its P⁺ replaced by that node's Ps and its δx by δx + ds
    (so the recursion steps over the boundary exactly as it does inside a block)."""
    K, nn, block = len(S_dx), n * n, block or RTS_BLOCK
    ds, pd = np.zeros((K, n)), np.empty((K, n))
    after = None  # (P_s, P⁻, Φ, δx + ds) of the node after the block
    for a, rows in node_spool.read_reverse(block):
        m = len(rows)
        mats = [np.ascontiguousarray(rows[:, i * nn:(i + 1) * nn]).reshape(m, n, n) for i in range(3)]
        post, prior, phi, dx = *mats, S_dx[a:a + m]
        if after is not None:
            post, prior, phi, dx = (np.concatenate([x, y[None]])
                                    for x, y in zip([*mats, dx], after, strict=True))
        d, P = rts(post, prior, phi, np.ascontiguousarray(dx), brk - a if a <= brk <= a + m else -1)
        ds[a:a + m], pd[a:a + m] = d[:m], np.einsum("kii->ki", P[:m])
        after = (P[0], prior[0], phi[0], S_dx[a] + d[0])
    return ds, pd


def _piece(t, st, b, pd, lay, smoothed=False) -> FilterResult:
    return FilterResult(time=t, state=st, bias=b, pdiag=pd, node_time=np.zeros(0), layout=lay,
                        smoothed=smoothed)
