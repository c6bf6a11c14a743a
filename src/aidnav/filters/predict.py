"""The predict of the filter engine (numba): the error model of a chunk and its discretisation at a node.

:func:`error_model` builds a chunk's arrays once: F, G of the INS model (:mod:`.ins_errors`) and of the
filter (calibration states' Gauss–Markov or random-walk rows, the clock), Φ and Qd, the independent
scalar states after the clock block (:func:`tail_start`: diagonal F, noise of their own; tight coupling's
range errors, discretised and predicted as scalars, :func:`.kalman.discretize_tail`,
:func:`.kalman.predict_tail`) and the head's constant states (a zero F row and no noise: scale factors and
misalignments of a model without their process noise, :func:`head_split`), which stay out of the series
and the products (:func:`discretize_head`, :func:`.kalman.discretize_split`, :func:`.kalman.predict_split`:
Φ's rows there are eᵢ); the head's series runs over F's nonzero entries (:func:`.kalman.discretize_sparse`)
and its diagonal rows (a bias's Gauss–Markov or random-walk row, the clock drift: :func:`diagonal_last`)
are scaled in the predict, not multiplied (issue 40). :func:`predict_node` is the predict over the
interval that ends at a node,
inlined in :func:`.engine.run_chunk`; :func:`exact_blocks` replaces the series by the exact Φ, Qd of
Gauss–Markov blocks (transfer alignment's flexure). The engine (:mod:`.engine`) owns the node loop, the
updates and the feedback; this module only the propagation of P.
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.models.distributed_pos import flexure_transition

from .ins_errors import fill_model, interval_model, model_arrays
from .kalman import (
    discretize,
    discretize_sparse_ws,
    discretize_split,
    discretize_tail,
    predict,
    predict_split,
    predict_tail,
    sparse_work,
)
from .layout import L_CLK, NAV


@njit(cache=True)
def tail_start(F, G, nd):
    """First state of the independent scalar tail: ``nd`` when every state from it on has a diagonal F
    row and column and noise inputs no other state shares (else n: no tail)."""
    n, m = F.shape[0], G.shape[1]
    for i in range(nd, n):
        for j in range(n):
            if j != i and (F[i, j] != 0.0 or F[j, i] != 0.0):
                return n
        for c in range(m):
            if G[i, c] != 0.0:
                for j in range(n):
                    if j != i and G[j, c] != 0.0:
                        return n
    return nd


@njit(cache=True)
def head_split(F, G, q, nd):
    """The head's order for :func:`.kalman.predict_split`: the states i < ``nd`` with dynamics first, then
    the constant ones (a zero row of F and no noise: G[i, c]·q[c] = 0 for every input c). Returns (order,
    number with dynamics)."""
    const = np.zeros(nd, np.bool_)
    for i in range(nd):
        c = True
        for j in range(F.shape[1]):
            if F[i, j] != 0.0:
                c = False
        for j in range(G.shape[1]):
            if G[i, j] * q[j] != 0.0:
                c = False
        const[i] = c
    hd = np.concatenate((np.flatnonzero(~const), np.flatnonzero(const))).astype(np.int64)
    return hd, nd - int(const.sum())


@njit(cache=True)
def diagonal_last(F, hd, d):
    """The head's order ``hd`` (:func:`head_split`) with its d states with dynamics reordered: those with
    a full F row first, then the diagonal ones (F's only nonzero entry in the row on the diagonal, so
    Φ's too: sensor biases as Gauss–Markov processes or random walks, a clock drift), for
    :func:`.kalman.predict_split`. Returns (order, number of full rows f)."""
    diag = np.zeros(d, np.bool_)
    for a in range(d):
        ia = hd[a]
        diag[a] = True
        for j in range(F.shape[1]):
            if j != ia and F[ia, j] != 0.0:
                diag[a] = False
    out = np.concatenate((hd[:d][~diag], hd[:d][diag], hd[d:])).astype(np.int64)
    return out, d - int(diag.sum())


@njit(cache=True)
def error_model(lay, proc, nfull, mins, naux, n, nins, nsub):
    """The error model's arrays of a chunk: F, G of the full INS layout (``Fi``, ``Gi``) and of the filter
    (``F``, ``G`` with the calibration states' Gauss–Markov or random-walk rows and the clock), Φ and Qd,
    and the split of the independent scalar states after the clock block (tight coupling's range errors):
    ``nd`` the first of them (``n`` when none), the head's arrays (``Fh``, ``Gh``, noise ``qh``), the tail's
    noise PSD ``qt`` (G row² · q) predicted by scaling; with a tail, the head's order ``hd`` (states with
    dynamics first, d of them, then the constant ones: :func:`head_split`, found on the INS model filled
    at a generic nominal — every entry it can set nonzero is) and the work arrays of
    :func:`.kalman.discretize_split` and :func:`.kalman.predict_split`: the constant states stay out of the
    series and the products (Φ's constant rows are eᵢ, set here once)."""
    ic = lay[L_CLK]
    Fi, Gi, _, _ = model_arrays(nfull, mins)
    F, G, Phi, Qd = model_arrays(n, mins + naux)
    for j in range(naux):  # calibration states: Gauss-Markov (τ > 0) or random walk / constant
        if proc.aux_tau[j] > 0:
            F[nins + j, nins + j] = -1.0 / proc.aux_tau[j]
        G[nins + j, mins + j] = 1.0
    if ic >= 0:
        F[ic, ic + 1] = 1.0  # clock bias [m] integrates the drift [m/s]
    nd = tail_start(F, G, ic + 2 if (ic >= 0 and nsub == 0 and proc.gm.shape[0] == 0) else n)
    mh = mins + nd - nins if nd < n else 0
    nh = nd if nd < n else 0
    Fh, Gh, _, _ = model_arrays(nh, mh)
    qh = proc.q[:mh].copy()
    if nd < n:
        Fh[nins:nd, nins:nd] = F[nins:nd, nins:nd]
        Gh[nins:nd, mins:] = G[nins:nd, mins:mh]
        c = np.cos(np.arange(9) + 0.3)  # a generic nominal: every entry fill_model can set is nonzero
        fill_model(Fi, Gi, 0.7, 100.0, c[:3], c[3:6] + 9.8, np.outer(c[6:9], c[:3]) + np.eye(3), c[3:6],
                   c[6:9], proc.tau)
        Fh[:nins, :nins] = Fi[:nins, :nins]
        Gh[:nins, :mins] = Gi[:nins, :mins]
    hd, d = head_split(Fh, Gh, qh, nh)
    hd, f = diagonal_last(Fh, hd, d)
    for e in range(d, nh):
        Phi[hd[e], hd[e]] = 1.0
    qt = np.zeros(n)
    for i in range(nd, n):
        for c in range(G.shape[1]):
            qt[i] += G[i, c] * G[i, c] * proc.q[c]
    sp = (hd, d, np.zeros((d, d)), np.zeros((d, nh - d)), np.zeros((d, mh)), np.zeros((d, d)),
          np.zeros((d, nh - d)), np.zeros((d, d)), f, sparse_work(nh))  # order, d, F_DD, F_DC, G_D, Φ_DD,
    # Φ_DC, Qd_DD, f, the series' work arrays (allocated once per chunk, not at each node: issue 40)
    wk = (np.zeros((f, nh)), np.zeros((nh, f)), np.zeros((nh, n)), np.zeros((f, n)), np.zeros((f, nh)),
          np.zeros((f, f)), np.zeros(nh))
    return Fi, Gi, F, G, Phi, Qd, nd, Fh, Gh, qh, qt, sp, wk


@njit(cache=True, inline="always")  # per node: inlined in run_chunk (issue 40)
def predict_node(st, acc, x, P, T, proc, em, dims):
    """The predict over the interval ``T`` that ends at a node: F, G of the interval (the subset's rows
    and columns where the filter runs on one), Φ and Qd, P propagated (with a scalar tail: the head's
    states with dynamics as a matrix, its constant states and the tail by their structure; else the full
    matrices, with the exact Gauss–Markov blocks); ``x`` zeroed (the engine then carries the open-loop
    estimates through Φ: :func:`.engine.carry_estimates`). Returns the body rate of the interval (for the
    models)."""
    Fi, Gi, F, G, Phi, Qd, nd, Fh, Gh, qh, qt, sp, wk = em
    nins, mins = dims[0], dims[1]  # INS states, noise inputs
    sub = proc.sub
    n, nsub = P.shape[0], sub.shape[0]
    wb = interval_model(Fi, Gi, st, acc, proc.tau[0], proc.tau[1], proc.tau[2], proc.tau[3])
    x[:] = 0.0
    if nd < n:  # (F's INS block is not read here: discretize_head takes Fi, discretize_tail F's tail)
        discretize_head(Fi, Gi, Fh, Gh, qh, T, Phi, Qd, sp, (nins, mins))
        discretize_tail(F, qt, T, Phi, Qd, nd)
        if sp[1] < nd:  # constant states in the head
            predict_split(x, P, Phi, Qd, sp[0], sp[1], wk, sp[8])
        else:  # (the same numbers; fewer index look-ups)
            predict_tail(x, P, Phi, Qd, nd)
    else:
        if nsub:
            for i in range(n):
                F[i, :], G[i, :] = Fi[sub[i]][sub], Gi[sub[i], :mins]
        else:
            F[:nins, :nins] = Fi[:nins, :nins]
            G[:nins, :mins] = Gi[:nins, :mins]
        discretize(F, G, proc.q, T, Phi, Qd)
        exact_blocks(Phi, Qd, proc.gm, T)
        predict(x, P, Phi, Qd)
    return wb


@njit(cache=True, inline="always")  # per node: inlined in run_chunk (issue 40)
def discretize_head(Fi, Gi, Fh, Gh, qh, T, Phi, Qd, sp, dims):
    """Φ, Qd of the head (the states before the scalar tail) from the INS model ``Fi``, ``Gi`` of the
    interval: the states with dynamics by the series, their coupling into the constant states
    (:func:`.kalman.discretize_split`), written into Φ's and Qd's rows of those states."""
    nins, mins = dims
    hd, d, Fd, Fdc, Gd, Phd, Phdc, Qdd, _, ws = sp
    nc = hd.shape[0] - d
    if nc == 0:  # no constant state: the head as it is
        Fh[:nins, :nins] = Fi[:nins, :nins]
        Gh[:nins, :mins] = Gi[:nins, :mins]
        discretize_sparse_ws(Fh, Gh, qh, T, Phd, Qdd, ws)
        Phi[:d, :d] = Phd
        Qd[:d, :d] = Qdd
        return
    for a in range(d):  # the INS rows from Fi, Gi (the interval's), the others' constant rows from Fh, Gh
        ia = hd[a]
        if ia < nins:
            for b in range(d):
                ib = hd[b]
                Fd[a, b] = Fi[ia, ib] if ib < nins else 0.0
            for e in range(nc):
                ie = hd[d + e]
                Fdc[a, e] = Fi[ia, ie] if ie < nins else 0.0
            for c in range(mins):  # (two contiguous loops, no test per entry)
                Gd[a, c] = Gi[ia, c]
            Gd[a, mins:] = 0.0
        else:
            for b in range(d):
                Fd[a, b] = Fh[ia, hd[b]]
            for e in range(nc):
                Fdc[a, e] = Fh[ia, hd[d + e]]
            for c in range(Gh.shape[1]):
                Gd[a, c] = Gh[ia, c]
    discretize_split(Fd, Fdc, Gd, qh, T, Phd, Phdc, Qdd, ws)
    for a in range(d):
        ia = hd[a]
        for b in range(d):
            Phi[ia, hd[b]] = Phd[a, b]
            Qd[ia, hd[b]] = Qdd[a, b]
        for e in range(nc):
            Phi[ia, hd[d + e]] = Phdc[a, e]


@njit(cache=True)
def open_loop_change(Phi, bias, opn, n):
    """Φ x̂ − x̂ (n,) for the estimate x̂ that is zero but at the open-loop states ``opn`` (indices ≥ 9, their
    estimates ``bias[i − 9]``), for :func:`.engine.carry_estimates` at each node: the products over those
    columns of Φ only, no product with the zeros and no allocation but the result (issue 40). Equal to
    the matrix product to rounding, exactly where a row has one open column (tight coupling's range errors:
    the diagonal tail)."""
    dx = np.zeros(n)
    for i in opn:
        xi = bias[i - NAV]
        for j in range(n):
            dx[j] += Phi[j, i] * xi
    for i in opn:
        dx[i] -= bias[i - NAV]
    return dx


@njit(cache=True)
def exact_blocks(Phi, Qd, gm, T):
    """Φ, Qd of the Gauss-Markov blocks ``gm`` over T [s], exact, in place of the Taylor series (which
    fails at ‖F‖T ≈ 1: a wing flexure at β ≈ 1 s⁻¹ and T = 1 s). Rows (i, j, β [1/s], σ): j < 0: first
    order at state i, ẋ = −βx + w, Φ = e^{−βT}, Qd = σ²(1 − e^{−2βT}); j ≥ 0: second order, x at i and
    ẋ at j, ẍ + 2βẋ + β²x = η, Q_η = 4β³σ² (:func:`aidnav.models.distributed_pos.flexure_transition`).
    The blocks must be decoupled in F from the other states (as every calibration state is: the engine
    gives them only their own dynamics), so their rows and columns are replaced whole."""
    for r in range(gm.shape[0]):
        i, j, beta, sig = int(gm[r, 0]), int(gm[r, 1]), gm[r, 2], gm[r, 3]
        for a in (i, j):
            if a >= 0:
                Phi[a, :], Phi[:, a], Qd[a, :], Qd[:, a] = 0.0, 0.0, 0.0, 0.0
        if j < 0:
            e = np.exp(-beta * T)
            Phi[i, i], Qd[i, i] = e, sig * sig * (1.0 - e * e)
            continue
        ph, qd = flexure_transition(beta, sig, T)
        Phi[i, i], Phi[i, j], Phi[j, i], Phi[j, j] = ph[0, 0], ph[0, 1], ph[1, 0], ph[1, 1]
        Qd[i, i], Qd[i, j], Qd[j, i], Qd[j, j] = qd[0, 0], qd[0, 1], qd[1, 0], qd[1, 1]
