"""The filter engine over a batch of Monte Carlo runs that share a trajectory (numba).

Runs of one sweep point have the same IMU sample times, the same record times and models and the same
process and measurement models; they differ in their sensor errors and noise (the increments and the
record values) and in their initial state. :func:`run_batch` advances all of them together: one loop
over the samples, and inside it one loop over the runs, so that the per-run work of a sample (the
strapdown of :func:`.ins_errors.propagate_sample`) of independent runs overlaps in the processor, and
the node schedule, the record search and the output decimation are done once for the batch.

Per-run state and inputs are held in contiguous arrays with the run as the leading index (``st`` (R, 10),
``P`` (R, n, n), increments (R, N, 3), ...), so that each run's slice is exactly the C-contiguous vector
or matrix the engine's own functions take: every operation on a run is the engine's
(:func:`.ins_errors.propagate_sample`, :func:`.ins_errors.interval_model`, :func:`.kalman.discretize`,
:func:`.kalman.predict`, :func:`.gate.policy_update` with the measurement models of
:func:`.measurements.fill`, :func:`.engine.feedback` and :func:`.tilt_turn.turn_with_feedback`), called
in the same order with the same arguments as in :func:`.engine.run_chunk`: each run's result is
bit-identical to a one-run call of :func:`.engine.run_filter` (``tests/experiments/test_batch_runs.py``).

Scope (what a Monte Carlo campaign of the loose filter uses; :func:`batchable` says whether a set of
one-run inputs qualifies, else run them one by one): the INS block only (15 or 21 states, no
calibration or clock states, no state subset), no node constraints, no IMU gaps, no held vertical
channel, no re-initialisation event, no smoother, a fixed output decimation, the first sample used.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from aidnav.jit import njit
from aidnav.nav.rotations import dcm_from_quat

from .engine import (
    EngineOut,
    Log,
    Work,
    carry_estimates,
    feedback,
    node_rates,
)
from .gate import WIN_MAX, policy_update
from .ins_errors import (
    ACC_FN,
    ACC_TN,
    interval_model,
    model_arrays,
    noise_count,
    propagate_sample,
    reset_accumulator,
)
from .kalman import discretize, predict
from .layout import L_N, L_NINS, L_SIZE, NAV, ST_Q
from .measurements import MAX_ROWS, MODELS_KEY, N_MODELS, Nav, fill
from .measurements.gnss import W_FN
from .predict import exact_blocks
from .tilt_turn import TILT_TURN_KEY, turn_with_feedback

__all__ = ["BatchIn", "BatchInit", "BatchOut", "run_batch", "batchable", "stack_inputs", "run_outputs"]

# inputs of a batch: t (N,) sample times [s], t0 [s] the time before the first sample; dth, dv (R, N, 3) raw
# increments of each run (a run's rows are its one-run arrays: simulated in place, no copy); rec_t (M,),
# rec_model (M,) the shared record times and models, rec_data (R, M, W) and rec_use (R, M) each run's rows
# and flags; every: output decimation (> 0)
BatchIn = namedtuple("BatchIn", ["t", "t0", "dth", "dv", "rec_t", "rec_model", "rec_data", "rec_use",
                                 "every"])
# initial states: st (R, 10), bias (R, n − 9), P (R, n, n)
BatchInit = namedtuple("BatchInit", ["st", "bias", "P"])
# per run r: out_st[r] (n_out, 10), out_bias[r], out_pdiag[r], the log's per-run columns, final st, bias, P;
# shared: out_idx, out_node, node_idx, the log's t, model and ref columns, n_log
BatchOut = namedtuple("BatchOut", ["out_idx", "out_st", "out_bias", "out_pdiag", "out_node", "node_idx",
                                   "log_t", "log_model", "log_ref", "status", "nis", "nu", "s", "reinit",
                                   "n_log", "st", "bias", "P"])
# one run's slices at a node (its strapdown state, sensor errors and their copy for the strapdown, P,
# accumulator, increment buffers, rejection counters, NIS windows, log, records) and the node's shared work
# arrays (error state, F, G, Φ, Qd of the INS block, measurement work arrays, rates, the index in P of each
# INS state: tilt_turn.turn_with_feedback's ``ix``)
_Run = namedtuple("_Run", ["st", "bias", "ib", "P", "acc", "buf", "rej", "win", "log", "data", "use"])
_NodeWork = namedtuple("_NodeWork", ["x", "F", "G", "Phi", "Qd", "wk", "w", "ix"])


@njit(cache=True, depends=MODELS_KEY + TILT_TURN_KEY)
def _node(ru, wo, proc, mod, rec_t, rec_model, g0, tk, dt):
    """One run's node at sample time tk (the node block of :func:`.engine.run_chunk` for the scope of
    this module): predict, the records g0.. due by tk, feedback. Returns the next record."""
    st, bias, P, acc, x, wk, w = ru.st, ru.bias, ru.P, ru.acc, wo.x, wo.wk, wo.w
    lay, nins = proc.lay, proc.lay[L_NINS]
    T = acc[ACC_TN, 0]
    C = dcm_from_quat(st[ST_Q:ST_Q + 4])
    wb = interval_model(wo.F, wo.G, st, acc, proc.tau[0], proc.tau[1], proc.tau[2], proc.tau[3])
    discretize(wo.F, wo.G, proc.q, T, wo.Phi, wo.Qd)
    exact_blocks(wo.Phi, wo.Qd, proc.gm, T)
    x[:] = 0.0
    predict(x, P, wo.Phi, wo.Qd)
    carry_estimates(st, bias, wo.Phi, proc.open, nins)
    node_rates(st, wb, ru.buf[0], dt, w)
    w[W_FN] = acc[ACC_FN] / T
    gi = g0
    while gi < rec_t.shape[0] and rec_t[gi] <= tk:
        if ru.use[gi]:
            md = rec_model[gi]
            m = fill(md, Nav(st, C, w, tk - rec_t[gi], bias), ru.data[gi], mod.par[md], lay, wk.H, wk.z, wk.R)
            if m > 0:
                policy_update(x, P, wk, m, md, mod, ru.rej, ru.win, ru.log, gi)
        gi += 1
    feedback(st, bias, x, nins)
    turn_with_feedback(x, P, True, wo.ix)  # a moving node (no static samples here)
    ru.ib[:] = bias[:nins - NAV]
    reset_accumulator(acc)
    return gi


@njit(cache=True, depends=MODELS_KEY + TILT_TURN_KEY)
def run_batch(inp, mod, proc, ini):
    """Forward pass of R runs together (module doc): inputs :class:`BatchIn`, the engine's
    :class:`.engine.Models` and :class:`.engine.Process` (shared), initial states :class:`BatchInit`.
    Returns :class:`BatchOut`."""
    t, rec_t, every, dth, dv = inp.t, inp.rec_t, inp.every, inp.dth, inp.dv
    R, N = inp.dth.shape[0], inp.dth.shape[1]
    n, M = proc.lay[L_N], rec_t.shape[0]
    nins = proc.lay[L_NINS]
    st, bias, P = ini.st.copy(), ini.bias.copy(), ini.P.copy()
    ib = bias[:, :nins - NAV].copy()
    acc, buf = np.zeros((R, 7, 3)), np.zeros((R, 4, 3))
    F, G, Phi, Qd = model_arrays(n, noise_count(n))
    wk = Work(np.zeros((MAX_ROWS, n)), np.zeros(MAX_ROWS), np.zeros((MAX_ROWS, MAX_ROWS)))
    wo = _NodeWork(np.zeros(n), F, G, Phi, Qd, wk, np.zeros((5, 3)), np.arange(n))
    rej, win = np.zeros((R, N_MODELS), np.int64), np.zeros((R, N_MODELS, WIN_MAX + 2))
    log_t, log_model, log_ref = rec_t.copy(), inp.rec_model.astype(np.int8), np.arange(M)
    status, nis, reinit = np.full((R, M), -1, np.int8), np.full((R, M), np.nan), np.zeros((R, M), np.int8)
    nu, s = np.full((R, M, MAX_ROWS), np.nan), np.full((R, M, MAX_ROWS), np.nan)
    n_out = (N + every - 1) // every
    out_idx, out_node = np.empty(n_out, np.int64), np.empty(n_out, np.int64)
    out_st, out_bias = np.empty((R, n_out, 10)), np.empty((R, n_out, n - NAV))
    out_pdiag = np.empty((R, n_out, n))
    node_idx = np.empty(N, np.int64)
    gi = 0
    while gi < M and rec_t[gi] <= inp.t0:
        gi += 1
    tp, kn, oi, T = inp.t0, 0, 0, 0.0
    for k in range(N):
        dt, tp = t[k] - tp, t[k]
        for r in range(R):  # the per-sample path of every run (T: the same interval for all)
            b = buf[r]
            T = propagate_sample(st[r], acc[r], dth[r, k], dv[r, k], ib[r], dt, b[0], b[1], b[2], b[3])
        t_due = rec_t[gi] if gi < M else np.inf
        if (T >= proc.prop_dt - 1e-9 or t_due <= t[k] or k == N - 1) and T > 0.0:
            g1 = gi
            for r in range(R):
                log = Log(log_t, log_model, status[r], nis[r], nu[r], s[r], log_ref, reinit[r])
                ru = _Run(st[r], bias[r], ib[r], P[r], acc[r], buf[r], rej[r], win[r], log, inp.rec_data[r],
                          inp.rec_use[r])
                g1 = _node(ru, wo, proc, mod, rec_t, inp.rec_model, gi, t[k], dt)
            gi = g1
            node_idx[kn] = k
            kn += 1
        if k % every == 0:
            out_idx[oi], out_node[oi] = k, kn - 1
            for r in range(R):
                out_st[r, oi] = st[r]
                out_bias[r, oi] = bias[r]
                for i in range(n):
                    out_pdiag[r, oi, i] = P[r, i, i]
            oi += 1
    return BatchOut(out_idx[:oi], out_st[:, :oi], out_bias[:, :oi], out_pdiag[:, :oi], out_node[:oi],
                    node_idx[:kn], log_t, log_model, log_ref, status, nis, nu, s, reinit, M, st, bias, P)


# ------------------------------------------------------------------------------------- Python side
def _same(a, b) -> bool:
    if isinstance(a, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return np.array_equal(a, b)


def batchable(imus, recs, mods, procs, inis, every) -> str | None:
    """Why these one-run inputs of :func:`.engine.run_filter` (an :class:`.engine.Imu`, records, models,
    process, init per run, and the decimation) cannot run as one batch, or None when they can."""
    lay = procs[0].lay
    if not (len(lay) == L_SIZE and lay[L_N] == lay[L_NINS] and np.all(lay[2:] < 0)):
        return "calibration or clock states"
    if len(procs[0].sub) or len(procs[0].gm) or len(procs[0].open) or procs[0].reset_pos:
        return "a state subset, exact Markov blocks, open-loop states or position resets"
    if len(mods[0].node):
        return "node constraints"
    if every <= 0:
        return "outputs at the nodes"
    i0 = imus[0]
    for im in imus:
        if len(im.hold) or np.any(im.gap_var) or np.any(im.static) or not np.array_equal(im.t, i0.t):
            return "held vertical channel, IMU gaps, static samples or different sample times"
    for ini in inis:
        if ini.reset_idx >= 0 or ini.t0 != inis[0].t0:
            return "a re-initialisation event or different start times"
    for rec, mod, proc in zip(recs, mods, procs, strict=True):
        r0 = recs[0]
        if (len(rec.grp.t) or not np.array_equal(rec.t, r0.t) or not np.array_equal(rec.model, r0.model)
                or rec.data.shape != r0.data.shape):
            return "different or whole-epoch records"
        if not (_same(tuple(mod), tuple(mods[0])) and _same(tuple(proc), tuple(procs[0]))):
            return "different models"
    return None


def _rows(arrs):
    """arrs as one (R, ...) array: the array they are the consecutive rows of (no copy), else a stack."""
    b = arrs[0].base
    if (isinstance(b, np.ndarray) and b.flags.c_contiguous and b.shape == (len(arrs),) + arrs[0].shape
            and all(a.base is b and a.ctypes.data == b[i].ctypes.data for i, a in enumerate(arrs))):
        return b
    return np.stack(arrs)


def stack_inputs(imus, recs, inis, every):
    """The :class:`BatchIn` and :class:`BatchInit` of :func:`run_batch` from one-run inputs (engine
    :class:`.engine.Imu`, records and init per run) and the output decimation."""
    inp = BatchIn(imus[0].t, inis[0].t0, _rows([im.dth for im in imus]), _rows([im.dv for im in imus]),
                  recs[0].t, recs[0].model, np.stack([r.data for r in recs]), np.stack([r.use for r in recs]),
                  every)
    return inp, BatchInit(np.stack([i.st for i in inis]), np.stack([i.bias for i in inis]),
                          np.stack([i.P for i in inis]))


def run_outputs(b: BatchOut, r: int) -> EngineOut:
    """Run r of a batch as the :class:`.engine.EngineOut` of a one-run call (the fields of a forward pass
    without smoother; the smoother's and covariance fields are empty)."""
    log = Log(b.log_t, b.log_model, b.status[r], b.nis[r], b.nu[r], b.s[r], b.log_ref, b.reinit[r])
    return EngineOut(b.out_idx, b.out_st[r], b.out_bias[r], b.out_pdiag[r], b.out_node, b.node_idx, None,
                     None, None, None, log, b.n_log, -1, b.st[r], b.bias[r], b.P[r],
                     np.zeros((0,) + b.P.shape[1:]), None)
