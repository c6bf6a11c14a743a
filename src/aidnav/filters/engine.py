"""The filter engine (numba): one forward pass and one RTS pass for every INS error-state filter.

A filter is a state layout (:mod:`aidnav.filters.layout`), its process model (:mod:`.ins_errors`;
Gauss-Markov / random constant per calibration state) and its measurement models
(:mod:`aidnav.filters.measurements`, by model id). The engine does:

* **node schedule**: strapdown at the IMU rate (:func:`.ins_errors.propagate_sample`); a *node* every
  ``prop_dt`` s, at every record time (a record in (t_{k−1}, t_k] makes t_k a node; ``use`` False only
  schedules it) and at the last sample; ``Imu.hold`` holds height and up velocity to given values;
  with a time-offset state (``lay[L_TOFF]``) a record is due at its receive time − d̂;
* **predict** at nodes (:mod:`.predict`: :func:`.predict.error_model` once per chunk,
  :func:`.predict.predict_node` at each node: the series or the exact Gauss–Markov blocks, the scalar tail
  and the head's constant states kept out of the products) + bridged-gap variance;
* **one update-with-gate policy** (:func:`.gate.gated_update`): χ² gate by the number of rows
  (``Models.gate[model, m]``, 0 = ungated), and after ``Models.max_rej[model]`` consecutive rejections
  of a model the next one is accepted ungated (a filter that went wrong must be able to come back);
  in :func:`run_filter` (:func:`.gate.policy_update`) that acceptance is a **re-initialisation**, and so is a
  window of accepted updates whose NIS is far out of its χ² band (``Models.win_n[model]`` > 0: the sum
  of the last N accepted NIS above the 99.9 % quantile of χ²(Σ m)): the navigation block of P is scaled
  (:func:`.reinit.inflate_nav`) until the innovation that triggered it is consistent (NIS = m), then the
  update is made ungated; ``Log.reinit`` records why (1: consecutive rejections, 2: NIS window);
* **one innovation log** (:class:`Log`): time, model id, status (1 accepted, 0 rejected, −1 not used),
  NIS, innovation, diag S (≤ ``MAX_ROWS``), record index (−1: node constraint); rows 0..M−1: records;
* **re-initialisation event** at sample ``Init.reset_idx``: heading from a GNSS course and, when the
  velocity integrated with the wrong heading is off by more than 3σ, velocity and position from that
  fix (``reset_nav``); the RTS pass passes nothing back across it;
* **closed-loop feedback** (:func:`feedback`) after each node's updates; **RTS** over the stored nodes
  (:func:`rts`, :func:`smooth_outputs`);
* **epoch records** (tight coupling): with clock states (``lay[L_CLK]``) record times are receiver
  tags, due at t − b̂/c, and b̂ follows d̂ per sample; with ``Records.grp`` a pseudorange record is a
  whole epoch (:func:`.measurements.epoch.epoch_update`: sequential scalar updates, its rejection rule,
  outputs in ``grp``). An INS block of 9 states (no sensor errors) is allowed;
* **exact Markov blocks and open-loop states** (transfer alignment): ``Process.gm`` blocks get their
  exact Φ, Qd (:func:`.predict.exact_blocks`), ``Process.open`` states are propagated as conditional means and
  never reset (:func:`carry_estimates`); :func:`initial_update` applies the records at t0.

Inputs: named tuples :class:`Imu`, :class:`Records`, :class:`Models`, :class:`Process`, :class:`Init`,
:class:`Output`; result :class:`EngineOut`.

**Chunks** (streaming, :mod:`aidnav.filters.stream`): :func:`run_chunk` runs the same pass over a part
of the samples from a :class:`Carry` (:func:`start_carry` before the first) and returns the carry to
continue from in ``EngineOut.carry``; sample indices (``out_idx``, ``node_idx``, ``Init.reset_idx``,
``Output.cov_idx``) and node numbers (``out_node``, ``reset_node``) are global, node arrays hold this
chunk's nodes and the log's node-constraint rows only this chunk's. Chunk by chunk gives exactly the
one-call result (:func:`run_filter` is one chunk).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from aidnav.jit import njit
from aidnav.nav.earth import OMEGA_IE, radii
from aidnav.nav.gnss_sat import C_LIGHT
from aidnav.nav.rotations import dcm_from_quat, quat_from_rotvec, quat_mult, quat_normalize, wrap_pi

from .gate import WIN_MAX, gated_update, policy_update
from .ins_errors import (
    ACC_C,
    ACC_FN,
    new_accumulator,
    noise_count,
    propagate_sample_rows,
    reset_accumulator,
    set_heading,
    turn_tilt_by,
)
from .layout import (
    BG,
    DP,
    DV,
    L_CLK,
    L_N,
    L_NINS,
    L_TOFF,
    L_VDEL,
    NAV,
    PHI,
    RN_LEVER,
    RN_POS,
    RN_SPOS,
    RN_SVEL,
    RN_VEL,
    ST_POS,
    ST_Q,
    ST_VEL,
)
from .measurements import M_GNSS_POS, M_GNSS_VEL, M_PR, MAX_ROWS, MODELS_KEY, N_MODELS, Nav, fill
from .measurements.common import W_FIX, W_IB, W_IE, W_IN
from .measurements.epoch import epoch_out, epoch_record, epoch_update
from .measurements.gnss import W_FN, reset_time_tag
from .output_rows import NO_ROWS, output_rows
from .predict import error_model, open_loop_change, predict_node
from .tilt_turn import TILT_TURN_KEY, keep_post, keep_prior, turn_with_feedback

# parameters of the GNSS velocity model (``Models.par[M_GNSS_VEL]``) for the heading hold after an IMU gap
# (:func:`run_chunk`): mounting heading [rad], least speed of a course [m/s], course σ [rad], heading σ
# above which the heading is held unknown [rad] (0: no hold); the largest acceleration [m/s²] (the motion an
# IMU gap leaves unmodelled in a record used at its closing node: :func:`_unmodelled_motion`)
C_MOUNT_H, C_VMIN, C_SIG, C_HOLD, C_AMAX = 3, 4, 5, 6, 7
GAP_REC_S = 1.0  # records older than this at the sample that ends an IMU gap are not used
#: a sample index or count never reached: ``Models.max_rej`` of a model without the consecutive-rejection
#: rule, ``Init.reset_idx`` of a course alignment not yet found (the one sentinel of the drivers)
NEVER = 2**62
#: the initial heading variance [rad²] (σ ≈ 81°) from which the heading is unknown: held until the course
#: alignment of ``Init.reset_idx``
UNKNOWN_HEADING_VAR = 2.0

# t (N,) [s]; dth, dv (N, 3) raw increments [rad, m/s]; static (N,) bool; gap_var (N, 2) [rad², (m/s)²]
# (attitude, velocity) or (N, 4) [rad², rad², (m/s)², m²] (roll/pitch, heading, velocity, position:
# :func:`aidnav.filters.preprocess.bridge_gaps`) added at the sample after an IMU gap;
# hold (N, 2) height [m] and up velocity [m/s] the strapdown is held to after each sample, or (0, 2)
Imu = namedtuple("Imu", ["t", "dth", "dv", "static", "gap_var", "hold"])
# time-sorted aiding records: t (M,) [s], model (M,) ids, data (M, W) rows of the models, use (M,) bool;
# grp: per-epoch outputs of whole-epoch pseudorange records (measurements.epoch.EpochOut; empty: none)
Records = namedtuple("Records", ["t", "model", "data", "use", "grp"], defaults=(epoch_out(0, 1),))
# par (N_MODELS, P) model parameters; gate (N_MODELS, MAX_ROWS + 1) χ² thresholds by rows (0: off);
# max_rej (N_MODELS,) consecutive rejections before an ungated update; node (K, 2): constraints at
# nodes as (model id, 1: at static samples / 0: at the others); win_n (N_MODELS,) length of the NIS
# window of the re-initialisation test (0: off, at most WIN_MAX; −1: the model never re-initialises the
# navigation block — after max_rej rejections its next update is only accepted ungated); cal (K, 2):
# the calibration states a re-initialisation grows with the navigation block (index in P, prior variance)
Models = namedtuple("Models", ["par", "gate", "max_rej", "node", "win_n", "cal"],
                    defaults=(np.zeros(N_MODELS, np.int64), np.zeros((0, 2))))
# lay: layout table; q: noise PSDs (INS inputs, then one per calibration state); tau (4,): INS bias/SF
# correlation times [s]; aux_tau (n − n_ins,) [s] (≤ 0: random walk); prop_dt [s]; sub: a state subset
# (indices into the INS block; models fill INS rows, the engine takes the subset's columns); reset_pos:
# after each node, position (and a finite v_U) from data[6:10] of its records (outside the filter);
# gm (K, 4): Gauss-Markov blocks discretised exactly (:func:`.predict.exact_blocks`); open (L,): states whose
# estimate is propagated by Φ at every node (:func:`carry_estimates`; open-loop states, never reset)
Process = namedtuple("Process", ["lay", "q", "tau", "aux_tau", "prop_dt", "sub", "reset_pos", "gm", "open"],
                     defaults=(np.zeros(0, np.int64), False, np.zeros((0, 4)), np.zeros(0, np.int64)))
Init = namedtuple("Init", ["t0", "st", "bias", "P", "reset_idx", "reset_heading", "reset_sigma", "reset_nav"])
# decimation (≤ 0: an output after every node instead); store nodes for RTS; P at samples; rows (.output_rows)
Output = namedtuple("Output", ["every", "smooth", "cov_idx", "rows"], defaults=(NO_ROWS,))
# reinit: 0, or why the update was a re-initialisation (1: consecutive rejections, 2: NIS window); a
# log built without it (length 0) is never written to (no re-initialisation without ``Models.win_n``)
Log = namedtuple("Log", ["t", "model", "status", "nis", "nu", "s", "ref", "reinit"],
                 defaults=(np.zeros(0, np.int8),))
Work = namedtuple("Work", ["H", "z", "R"])
EngineOut = namedtuple("EngineOut", ["out_idx", "out_st", "out_bias", "out_pdiag", "out_node", "node_idx",
                                     "S_post", "S_prior", "S_phi", "S_dx", "log", "n_log", "reset_node",
                                     "st", "bias", "P", "cov", "carry"])
# what a pass carries from one chunk of samples to the next: k0 (global index of the chunk's first
# sample), last (the chunk ends the log), tp (time of the previous sample), kn (nodes so far), gi (next
# record), ci (next cov_idx), reset_node; st, bias, P (updated in place), rej (consecutive rejections),
# acc (interval accumulator), gap (6,): bridged-gap variance not yet added (roll/pitch, heading,
# velocity, position), then 1 while the heading is held after a gap, then the computed heading [rad] at
# the last node if that node was static (NaN otherwise: _turn_tilt_at_rest); buf (4, 3) increment buffers
Carry = namedtuple("Carry", ["k0", "last", "tp", "kn", "gi", "ci", "reset_node", "st", "bias", "P", "rej",
                             "acc", "gap", "buf"])


@njit(cache=True)
def feedback(st, bias, dx, nstate):
    """Closed-loop feedback of an error estimate dx into the strapdown state and the sensor errors:
    C_b^n ← (I + [φ̂×]) C_b^n, v ← v − δv̂, p ← p − δp̂, (biases, calibration) b̂ ← b̂ + r̂."""
    q = quat_mult(quat_from_rotvec(dx[PHI:PHI + 3]), st[ST_Q:ST_Q + 4])
    st[ST_Q:ST_Q + 4] = quat_normalize(q)
    for i in range(3):
        st[ST_VEL + i] -= dx[DV + i]
        st[ST_POS + i] -= dx[DP + i]
    for i in range(nstate - NAV):
        bias[i] += dx[NAV + i]


@njit(cache=True)
def _var(P, ix, i):
    """Variance of full-layout state i in the filter's P (index map ``ix``; 0 where it has no such state)."""
    return P[ix[i], ix[i]] if ix[i] >= 0 else 0.0


@njit(cache=True)
def _turn_accumulator(acc, R):
    """The nav-frame sums of the interval being accumulated (Σ C_b^n, Σ C_b^n Δv) turned with the computed
    frame (C_b^n ← R C_b^n, a heading reset inside the interval): the interval's error model (F's
    sensor-error columns C_b^n, its f^n) must be the frame that P's tilt is expressed in after the reset."""
    Cs = R @ acc[ACC_C:ACC_C + 3]
    fn = R @ acc[ACC_FN]
    acc[ACC_C:ACC_C + 3] = Cs
    acc[ACC_FN] = fn


@njit(cache=True)
def _reinit(st, P, ini, ix, held, cal, cal_rows, acc):
    """Re-initialisation event: heading, then velocity and position from ``reset_nav`` =
    [v (3), lat, lon, h, σ_v (3), σ_pos E, N, U, a (3), lever (3)] of the fix that gave the course when the
    velocity is 3σ off: σ of the filter and the fix, or, when the heading was ``held`` unknown until now
    (the filter's velocity covariance, propagated with that heading, is meaningless), of the fix alone;
    the fix's time tag read with the time offset and velocity delay (``cal``: their indices and the
    estimates, :func:`.measurements.gnss.reset_time_tag`); after a ``held`` heading, their covariance is
    first repaired to the prior of ``cal_rows`` (``Models.cal``: :func:`_repair_timing`).
    ``ix`` (≥ 15,): index in P of each state of the full INS layout (−1: not in the filter, a subset).
    ``acc``: the accumulator of the interval the reset falls in, turned with the heading
    (:func:`_turn_accumulator`; issue 35, session 13)."""
    rn_ = ini.reset_nav  # layout.RN_*: the fix's velocity, position, their σ, the lever arm
    C0 = dcm_from_quat(st[ST_Q:ST_Q + 4])
    set_heading(st, P, ini.reset_heading, ini.reset_sigma, ix[PHI + 2], ix[PHI], ix[PHI + 1])
    _turn_accumulator(acc, dcm_from_quat(st[ST_Q:ST_Q + 4]) @ C0.T)
    dvr = np.sqrt((st[ST_VEL] - rn_[RN_VEL]) ** 2 + (st[ST_VEL + 1] - rn_[RN_VEL + 1]) ** 2)
    sv_e, sv_n = rn_[RN_SVEL], rn_[RN_SVEL + 1]
    v2 = sv_e ** 2 + sv_n ** 2 if held else _var(P, ix, DV) + _var(P, ix, DV + 1) + sv_e ** 2
    if np.isnan(rn_[RN_VEL]) or dvr <= 3.0 * np.sqrt(v2):
        return
    # velocity and position integrated with the unknown heading: from the fix (antenna → IMU)
    l_n = dcm_from_quat(st[ST_Q:ST_Q + 4]) @ rn_[RN_LEVER:RN_LEVER + 3]
    lat, lon, h = rn_[RN_POS], rn_[RN_POS + 1], rn_[RN_POS + 2]
    rm, rn = radii(lat)
    st[ST_POS] = lat - l_n[1] / (rm + h)
    st[ST_POS + 1] = lon - l_n[0] / ((rn + h) * np.cos(lat))
    st[ST_POS + 2] = h - l_n[2]
    for i in range(3):
        st[ST_VEL + i] = rn_[RN_VEL + i]
    var = np.empty(6)  # δv (3), δL, δλ, δh
    for i in range(3):
        var[i] = rn_[RN_SVEL + i] ** 2
    var[3] = (rn_[RN_SPOS + 1] / (rm + h)) ** 2
    var[4] = (rn_[RN_SPOS] / ((rn + h) * np.cos(lat))) ** 2
    var[5] = rn_[RN_SPOS + 2] ** 2
    for i in range(6):
        j = ix[DV + i]
        if j >= 0:
            P[j, :] = 0.0
            P[:, j] = 0.0
    for i in range(6):
        j = ix[DV + i]
        if j >= 0:
            P[j, j] = var[i]
    if held:
        _repair_timing(P, cal, cal_rows)
    reset_time_tag(st, P, rn_, ix, cal)


@njit(cache=True)
def _repair_timing(P, cal, cal_rows):
    """The time offset and velocity delay (indices ``cal[0]``, ``cal[1]``) learnt while the heading was held
    unknown were learnt against a velocity integrated with that heading, whose covariance meant nothing:
    as suspect as that velocity, which the reset replaces; their variance goes back to the prior of
    ``cal_rows`` (rows index, prior variance, …; ``Models.cal``), uncorrelated, their estimates kept (a
    calibration is repaired, never thrown away: issue 35, item 5). Without it a course reset read the fix
    with an offset learnt 3.5σ off (0.30 ± 0.08 s against 0) and moved the INS by a·(d̂ + τ̂)."""
    for r in range(cal_rows.shape[0]):
        i = int(cal_rows[r, 0])
        if i >= 0 and (i == cal[0] or i == cal[1]):
            P[i, :] = 0.0
            P[:, i] = 0.0
            P[i, i] = cal_rows[r, 1]


@njit(cache=True)
def _add_gap(st, P, gap, ix):
    """Add the variance of an IMU gap (``gap``: roll/pitch [rad²], heading [rad²], velocity [(m/s)²],
    position [m²] per axis, metres → δL, δλ, δh at the current position) to P's diagonal; zeroes
    ``gap[0:4]``. ``ix``: index in P of each full-layout state (−1: none)."""
    rm, rn = radii(st[0])
    sp = np.array([1.0 / (rm + st[2]) ** 2, 1.0 / ((rn + st[2]) * np.cos(st[0])) ** 2, 1.0])
    for i in range(3):
        a, b, c = ix[PHI + i], ix[DV + i], ix[DP + i]
        if a >= 0:
            P[a, a] += gap[1] if i == 2 else gap[0]
        if b >= 0:
            P[b, b] += gap[2]
        if c >= 0:
            P[c, c] += gap[3] * sp[i]
    for j in range(4):
        gap[j] = 0.0


@njit(cache=True)
def _course_heading(st, P, row, pv, iu, ie, inn):
    """Heading from the GNSS course of velocity record ``row`` (v ENU, σ) when it is meaningful (speed
    above ``pv[C_VMIN]`` and 5 times its σ): IMU heading = course + mounting heading, σ ``pv[C_SIG]``
    and the course's own (:func:`.ins_errors.set_heading`). Returns whether it was set."""
    sp = np.sqrt(row[0] * row[0] + row[1] * row[1])
    sg = np.sqrt(row[3] * row[3] + row[4] * row[4])
    if not (sp > pv[C_VMIN] and sp > 5.0 * sg):
        return False
    h = np.arctan2(row[0], row[1]) + pv[C_MOUNT_H]
    s = np.sqrt(pv[C_SIG] ** 2 + (sg / sp) ** 2)
    set_heading(st, P, h, s, iu, ie, inn)
    return True


@njit(cache=True)
def node_rates(st, wb, dthc, dt, w):
    """Rows of ``Nav.w``: mean ω_ib^b, ω_ib^b of the last sample, ω_ie^n, ω_in^n."""
    sl, cl = np.sin(st[0]), np.cos(st[0])
    rm, rn = radii(st[0])
    w[W_IB] = wb
    w[W_FIX] = dthc / dt
    w[W_IE, 0], w[W_IE, 1], w[W_IE, 2] = 0.0, OMEGA_IE * cl, OMEGA_IE * sl
    w[W_IN, 0] = -st[4] / (rm + st[2])
    w[W_IN, 1] = OMEGA_IE * cl + st[3] / (rn + st[2])
    w[W_IN, 2] = OMEGA_IE * sl + st[3] * sl / cl / (rn + st[2])


@njit(cache=True, inline="always")  # per sample and node: the record times alone (issue 40)
def _rec_time(rt, i, bias, ic):
    """Time of record i (``rt``: ``Records.t``): the tag, or with clock states (ic ≥ 0) the tag − b̂/c."""
    return rt[i] - bias[ic - NAV] / C_LIGHT if ic >= 0 else rt[i]


@njit(cache=True, inline="always")  # per sample and node: ``Records.t`` only (rec's 20 arrays: 20 refcounts)
def _due_time(rt, i, bias, ic, itoff):
    """Time on the IMU clock at which record i is due (``rt``: ``Records.t``): its receive time
    (:func:`_rec_time`) − d̂, the time-offset estimate (itoff ≥ 0); +inf past the last record."""
    if i >= rt.shape[0]:
        return np.inf
    t = _rec_time(rt, i, bias, ic)
    return t - bias[itoff - NAV] if itoff >= 0 else t


@njit(cache=True)
def _subset(wk, m, sub, ws):
    """The Work whose H the update uses: wk, or with a state subset its columns ``sub`` (in ws)."""
    if sub.shape[0] == 0:
        return wk
    for r in range(m):
        for i in range(sub.shape[0]):
            ws.H[r, i] = wk.H[r, sub[i]]
    return ws


@njit(cache=True)
def start_carry(rec, proc, ini, last):
    """The :class:`Carry` before the first sample (``last``: the first chunk is the whole log)."""
    bias = ini.bias.copy()
    itoff, ic = proc.lay[L_TOFF], proc.lay[L_CLK]
    gi = 0
    while _due_time(rec.t, gi, bias, ic, itoff) <= ini.t0:
        gi += 1
    return Carry(0, last, ini.t0, 0, gi, 0, -1, ini.st.copy(), bias, ini.P.copy(),
                 np.zeros(N_MODELS, np.int64), new_accumulator(), _new_gap(), np.zeros((4, 3)))


@njit(cache=True, depends=MODELS_KEY + TILT_TURN_KEY)
def run_filter(imu, rec, mod, proc, ini, out):
    """Forward pass of the closed-loop error-state filter (module doc) over all samples in one call;
    returns :class:`EngineOut`."""
    return run_chunk(imu, rec, mod, proc, ini, out, start_carry(rec, proc, ini, True))


@njit(cache=True)
def _new_gap():
    """The carry's ``gap`` array before the first sample (:class:`Carry`)."""
    gap = np.zeros(6)
    gap[5] = np.nan
    return gap


@njit(cache=True, inline="always")  # per node: inlined in run_chunk
def _turn_tilt_at_rest(st, P, gap, ix, static):
    """At a node whose interval was static (the vehicle does not turn), every change of the computed
    heading since the last node — the strapdown's drift with the z gyro's bias error, the feedback of a
    heading correction — is a change of the heading *error*: the computed frame turned about the vertical
    while the true one stood still. The tilt error belongs to the body's roll and pitch, so in the
    navigation frame it turns with that change (φ_EN ← R φ_EN, R the rotation applied to C_b^n, as at a
    heading reset: :func:`.ins_errors.set_heading`), and with it its covariance with the body-frame sensor
    errors; the first-order model holds φ_EN still instead (the term δb_z × φ is of second order). Without
    the turn, a heading that wanders at rest (a consumer gyro's z bias, σ hundreds of deg/h) makes the
    accelerometer bias's image C_b^n b_a turn against a still tilt: a rotation that separates the tilt from
    the bias in the filter's model but not in the sensor, and the tilt σ falls far below what the bias
    allows (issue 35, parked 10 min then driving). ``gap[5]``: the computed heading at the last node when
    that node was static, NaN otherwise. Returns the turn [rad] (0: none; :func:`.rts_nodes.keep_prior`)."""
    if not static:  # a moving node: nothing to turn, and the next static node has no heading to turn from
        gap[5] = np.nan
        return 0.0
    ie, inn, dh = ix[PHI], ix[PHI + 1], 0.0
    C = dcm_from_quat(st[ST_Q:ST_Q + 4])
    h = np.arctan2(C[0, 1], C[1, 1])
    if not np.isnan(gap[5]):
        if ie >= 0 and inn >= 0:
            dh = wrap_pi(h - gap[5])
            turn_tilt_by(P, ie, inn, dh)
        _hold_heading_at_rest(st, P, ix)
    gap[5] = h
    return dh


@njit(cache=True, inline="always")  # per node: inlined in run_chunk
def _hold_heading_at_rest(st, P, ix):
    """At rest, with a gyro that cannot gyrocompass (the horizontal gyro bias σ above the horizontal Earth
    rate Ω cos L: the Earth rate would fix the heading to worse than 1 rad), the heading and the z gyro
    bias are not observable: the only coupling, Ω cos L · ψ into the east tilt rate, is indistinguishable
    from the horizontal gyro bias. The linearised model nonetheless separates them once the computed
    heading wanders (its Earth-rate column stays fixed in the navigation frame while the bias's image
    C_b^n b_g turns): the updates then move the heading and the z bias on that spurious information and
    claim a σ they do not have. So before the updates of a static node the correlations of the heading
    and the z gyro bias with every other state are zeroed (their own 2×2 block kept, so the heading σ
    grows with the z bias as it should): the updates cannot move them at rest."""
    iu, ibz, ibx, iby = ix[PHI + 2], ix[BG + 2], ix[BG], ix[BG + 1]
    if iu < 0 or ibz < 0 or ibx < 0 or iby < 0:
        return
    wh = OMEGA_IE * np.cos(st[ST_POS])
    if 0.5 * (P[ibx, ibx] + P[iby, iby]) <= wh * wh:
        return
    for j in range(P.shape[0]):
        if j != iu and j != ibz:
            P[iu, j], P[j, iu], P[ibz, j], P[j, ibz] = 0.0, 0.0, 0.0, 0.0


@njit(cache=True, inline="always")  # per node: inlined in run_chunk (issue 40)
def _gap_at_node(st, P, gap, ix, hold_thr, static):
    """The variance an IMU gap added since the last node; a heading σ left above the hold threshold holds
    the heading unknown (``gap[4]``) until a GNSS course re-aligns it; the tilt turned with the heading's
    change at rest (:func:`_turn_tilt_at_rest`; ``static``: the node is static and its heading is not held
    unknown before the first alignment — a held heading is :func:`_hold_heading`'s). Returns that turn."""
    iu = ix[PHI + 2]
    dh = _turn_tilt_at_rest(st, P, gap, ix, static and gap[4] == 0.0)  # (a held heading: _hold_heading's)
    att = gap[0] > 0.0 or gap[1] > 0.0  # the hold below only where the attitude's variance grew
    if att or gap[2] > 0.0 or gap[3] > 0.0:  # (indices of the full layout through ix: a subset has its own)
        _add_gap(st, P, gap, ix)
        if att and hold_thr > 0.0 and iu >= 0 and P[iu, iu] >= hold_thr * hold_thr:
            gap[4] = min(P[iu, iu], np.pi * np.pi)  # heading unknown until a course re-aligns it
            P[iu, :], P[:, iu] = 0.0, 0.0
            P[iu, iu] = gap[4]
    return dh


@njit(cache=True)
def _unmodelled_motion(R, m, md, pv, dtu):
    """R of a GNSS record grown by the motion an IMU gap leaves unmodelled between the record's time and
    the node's (``dtu`` [s]): the acceleration, uniform within ±``pv[C_AMAX]`` (σ = a/√3 per axis, as
    :func:`aidnav.filters.preprocess.bridge_gaps`), moves a position by a·Δt²/2 and a velocity by a·Δt
    beyond what the velocity state (in P, through the model's −Δt on δv) accounts for."""
    a = pv[C_AMAX] / np.sqrt(3.0) if pv.shape[0] > C_AMAX else 0.0
    g = a * dtu * dtu / 2.0 if md == M_GNSS_POS else (a * dtu if md == M_GNSS_VEL else 0.0)
    for i in range(m):
        R[i, i] += g * g


@njit(cache=True)
def _consider_timing(H, R, m, P, tc):
    """A fix read while the heading is held unknown (before the first course alignment, after an IMU gap)
    does not update the time offset and velocity delay (indices ``tc``; −1: not estimated): their columns
    of ``H`` (m rows) are the INS's v^n and a^n, whose horizontal direction is the held heading's, i.e.
    unknown; a heading error ψ puts an innovation of up to 2|v| (|a|·Δt) along any direction, and near
    ψ = 180° along v (a) itself, which the linear model can only read as a time offset (issue 35, m35u's
    no-``vu`` run: 0.43 s learnt from one velocity fix at the start of motion with the heading 156° off,
    then confirmed by the fixes at constant speed, where an offset and an along-track shift look alike).
    So they are *considered*, not estimated: their correlations with the other states are zeroed (their
    own block kept, as the held heading's are) and their part of the innovation, H_T P_TT H_Tᵀ, goes into
    R, so the update is honest about them and leaves them as they are."""
    for a in tc:
        if a < 0:
            continue
        for j in range(P.shape[0]):
            if j != tc[0] and j != tc[1]:
                P[a, j], P[j, a] = 0.0, 0.0
    for i in range(m):
        for j in range(m):
            for a in tc:
                for b in tc:
                    if a >= 0 and b >= 0:
                        R[i, j] += H[i, a] * P[a, b] * H[j, b]
    for a in tc:
        if a >= 0:
            for i in range(m):
                H[i, a] = 0.0


@njit(cache=True, depends=MODELS_KEY, inline="always")  # per node: inlined in run_chunk (issue 40)
def _update_records(x, P, nv, C, rec, gi, tk, hd, upd, tm):
    """The records due at the node at IMU time ``tk`` (in (t_{k-1}, t_k] on the IMU clock), each by its model:
    a whole pseudorange epoch by its scalar updates, any other by the gate policy (R grown by
    :func:`_unmodelled_motion` at a node that closes an IMU gap); a velocity record re-aligns a heading held
    unknown, while it is held the time states are considered (:func:`_consider_timing`). ``nv``: (strapdown
    state, node rates, biases); ``hd``: (gap variances and heading-hold flag, the sample closes a gap, INS
    index map, heading index, GNSS velocity model parameters, time states' indices, the initial heading
    held, the records are whole epochs); ``upd``: :func:`_node_constraints`'; ``tm``: (clock, time-offset
    index). Returns the next record's index and the attitude matrix. (One function, issue 40: each inlined
    binding of ``rec``, ``upd``, ``hd``, ``nv`` costs a reference-count pair per array.)

    At the node that closes an IMU gap: records more than ``GAP_REC_S`` older than it are not used (the
    INS cannot be moved back across the unknown motion); the rest, and the first record due after the node
    (within ``GAP_REC_S``; not a pseudorange epoch) when it is nearer to the node than any record used, are
    used now with R grown by the unmodelled motion over their distance from the node — so the gap's
    covariance bound gives way to the first fix after the gap whichever side of the first IMU sample the
    time-offset estimate puts it (issue 35)."""
    st, w, bias = nv
    gap, gap_k, ix, iu, pv, tcal, held, epochs = hd
    mod, lay, rej, win, log, wk, sub, ws = upd
    ic, itoff = tm
    lim, near = tk, GAP_REC_S
    while True:
        while _due_time(rec.t, gi, bias, ic, itoff) <= lim:
            tr = _rec_time(rec.t, gi, bias, ic)
            dtu = abs(tk - _due_time(rec.t, gi, bias, ic, itoff)) if gap_k else 0.0
            # a record inside an IMU gap cannot be moved back across the unknown motion: not used
            if rec.use[gi] and not (gap_k and tk - tr > GAP_REC_S):
                near = min(near, dtu)
                md = rec.model[gi]
                if gap[4] > 0.0 and md == M_GNSS_VEL and _course_heading(st, P, rec.data[gi], pv, iu, ix[PHI],
                                                                         ix[PHI + 1]):
                    gap[4] = 0.0
                    C = dcm_from_quat(st[ST_Q:ST_Q + 4])
                nav = Nav(st, C, w, tk - tr, bias)  # the models add d̂ to dt_back themselves
                if epochs and md == M_PR:  # a whole epoch: its scalar updates and rejection rule
                    gate = mod.gate[md, 1] if rej[md] < mod.max_rej[md] else 0.0
                    ok = epoch_update(x, P, nav, rec.data[gi], mod.par[md], lay, gate, rec.grp, gi, tr)
                    rej[md] = 0 if ok else rej[md] + 1
                    log.status[gi] = 1 if ok else 0
                else:
                    m = fill(md, nav, rec.data[gi], mod.par[md], lay, wk.H, wk.z, wk.R)
                    if m > 0:
                        if dtu > 0.0:
                            _unmodelled_motion(wk.R, m, md, pv, dtu)
                        if held or gap[4] > 0.0:
                            _consider_timing(wk.H, wk.R, m, P, tcal)
                        policy_update(x, P, _subset(wk, m, sub, ws), m, md, mod, rej, win, log, gi)
            gi += 1
        if not gap_k or lim > tk:
            break
        j = gi
        while j < rec.t.shape[0] and not rec.use[j]:
            j += 1
        nxt = _due_time(rec.t, j, bias, ic, itoff)
        ahead = j < rec.t.shape[0] and epochs and rec.model[j] == M_PR  # (an epoch: not taken ahead)
        if ahead or not nxt - tk < near:
            break
        lim = nxt  # the first fix after the gap, moved back to the node
    return gi, C


@njit(cache=True, depends=MODELS_KEY, inline="always")  # per node: inlined in run_chunk (issue 40)
def _node_constraints(x, P, nav, static, tk, no_row, upd, li):
    """The node constraints (ZUPT, ZARU at static samples, NHC at moving ones) at IMU time ``tk``, each
    logged; returns the next free log row. ``upd``: the update context (models, layout, rejection counts,
    NIS windows, the innovation log, the work arrays, the state subset and its work arrays)."""
    mod, lay, rej, win, log, wk, sub, ws = upd
    for c in range(mod.node.shape[0]):
        md = mod.node[c, 0]
        if (mod.node[c, 1] == 1) == static:
            m = fill(md, nav, no_row, mod.par[md], lay, wk.H, wk.z, wk.R)
            if m > 0:
                log.t[li], log.model[li] = tk, md
                policy_update(x, P, _subset(wk, m, sub, ws), m, md, mod, rej, win, log, li)
                li += 1
    return li


@njit(cache=True)
def _constraint_counts(node):
    """Node constraints (``Models.node``) at moving (0), static (1) samples: none skips their binding."""
    c = np.zeros(2, np.int64)
    for r in range(node.shape[0]):
        c[1 if node[r, 1] == 1 else 0] += 1
    return c


@njit(cache=True, inline="always")  # per node: inlined in run_chunk (issue 40)
def _hold_heading(P, iu, ini, before_alignment, gap):
    """A heading without information keeps its variance and no correlation: before the first alignment
    (``before_alignment``: an unknown initial heading, σ above ≈ 81°, with an alignment to come — a
    linearised filter would otherwise "gyrocompass" from a gyro bias model it cannot separate from the
    heading at a standstill, or from noise), or after an IMU gap (``gap[4]``) until a GNSS course
    re-aligns it."""
    if before_alignment:
        P[iu, :], P[:, iu] = 0.0, 0.0
        P[iu, iu] = ini.P[iu, iu]
    elif gap[4] > 0.0:
        P[iu, :], P[:, iu] = 0.0, 0.0
        P[iu, iu] = gap[4]


@njit(cache=True, inline="always")  # per sample: inlined (no call per sample)
def _write_output(o, oi, k, st, bias, nb, P, node):
    """The output row ``oi`` (sample ``k``): state, the first ``nb`` biases, diagonal of P, last node.
    Returns ``oi + 1``."""
    out_idx, out_st, out_bias, out_pdiag, out_node = o
    out_idx[oi] = k
    for i in range(10):
        out_st[oi, i] = st[i]
    for i in range(nb):
        out_bias[oi, i] = bias[i]
    for i in range(out_pdiag.shape[1]):
        out_pdiag[oi, i] = P[i, i]
    out_node[oi] = node
    return oi + 1


@njit(cache=True, inline="always")  # per sample: inlined (no call per sample)
def _gap_sample(gap, gap_var, k):
    """Sample ``k``'s gap variances added to ``gap`` (roll/pitch, heading, velocity, position; with two
    columns the attitude one counts for both angles). Returns whether the sample closes a gap."""
    if gap_var.shape[1] >= 4:
        for j in range(4):
            gap[j] += gap_var[k, j]
        return gap_var[k, 3] > 0.0
    gap[0] += gap_var[k, 0]
    gap[1] += gap_var[k, 0]
    gap[2] += gap_var[k, 1]
    return False


@njit(cache=True, inline="always")  # per node: inlined in run_chunk (issue 40)
def _after_updates(st, bias, P, rec, gs, flags, lay):
    """After a node's updates: the position (and height rate) reset to the records g0 … gi−1 (``gs``; if
    ``flags[0]``, ``Process.reset_pos``), each whole-epoch record's state written back (``flags[1]``)."""
    g0, gi = gs
    for g in range(g0, gi if flags[0] else g0):
        st[0], st[1], st[2] = rec.data[g, 6], rec.data[g, 7], rec.data[g, 8]
        if not np.isnan(rec.data[g, 9]):
            st[5] = rec.data[g, 9]
    for g in range(g0, gi if flags[1] else g0):
        epoch_record(rec.grp, g, st, bias, P, lay)


@njit(cache=True)
def _chunk_log(rec, cap):
    """The innovation log of a chunk: one row per record (filled in as they are used), then the node
    constraints' rows, ``cap`` in all."""
    log = Log(np.full(cap, np.nan), np.full(cap, -1, np.int8), np.full(cap, -1, np.int8),
              np.full(cap, np.nan), np.full((cap, MAX_ROWS), np.nan), np.full((cap, MAX_ROWS), np.nan),
              np.full(cap, -1, np.int64), np.zeros(cap, np.int8))
    for i in range(rec.t.shape[0]):
        log.t[i], log.model[i], log.ref[i] = rec.t[i], rec.model[i], i
    return log


@njit(cache=True)
def _chunk_sizes(imu, rec, out, cy, prop_dt):
    """The most nodes and outputs a chunk can produce: every record that can fall due in it (all of them
    in the last chunk, else those stamped up to 100 s after its last sample: a time offset or receiver
    clock bias beyond 100 s is refused) plus the nodes of the propagation interval."""
    n_imu, M = imu.t.shape[0], rec.t.shape[0]
    m_due = (M if cy.last else min(M, np.searchsorted(rec.t, imu.t[-1] + 100.0, side="right") + 1)) - cy.gi
    max_nodes = min(m_due + int((imu.t[-1] - cy.tp) / prop_dt) + 3 + n_imu // max(1, int(prop_dt * 1000.0)),
                    n_imu + 1)
    return max_nodes, (n_imu + out.every - 1) // out.every if out.every > 0 else max_nodes


@njit(cache=True)
def _index_map(nfull, sub, nins):
    """The index in P of each state of the full INS layout (−1: not there; a subset has its own)."""
    nsub = sub.shape[0]
    ix = np.full(nfull, -1, np.int64)
    for i in range(nsub if nsub else nins):
        ix[sub[i] if nsub else i] = i
    return ix


# nogil: the streamed job overlaps writing with it (issue 29)
@njit(cache=True, nogil=True, depends=MODELS_KEY + TILT_TURN_KEY)
def run_chunk(imu, rec, mod, proc, ini, out, cy):
    """The forward pass over the samples ``imu`` from the carry ``cy`` (module doc: chunks)."""
    n_imu = imu.t.shape[0]
    lay = proc.lay
    n, nins = lay[L_N], lay[L_NINS]
    nfull, ic, sub = max(nins, 15), lay[L_CLK], proc.sub
    mins, nsub = noise_count(nfull), sub.shape[0]
    n = nsub if nsub else n
    nb, naux, nh = (nins if nsub else n) - NAV, 0 if nsub else n - nins, nins if nsub else n
    M = rec.t.shape[0]
    st, bias, P, x = cy.st, cy.bias, cy.P, np.zeros(n)
    k0, kn0 = cy.k0, cy.kn
    itoff, tcal = lay[L_TOFF], (-1, -1) if nsub else (lay[L_TOFF], lay[L_VDEL])  # time states (in P)
    ix = _index_map(nfull, sub, nins)
    iu = ix[PHI + 2]
    # an unknown heading with an alignment to come stays unknown until then (_hold_heading)
    hold_h = ini.reset_idx > 0 and iu >= 0 and ini.P[iu, iu] >= UNKNOWN_HEADING_VAR
    ib = bias[:nins - NAV].copy()  # INS sensor errors only: the strapdown reads no clock or calibration
    em = error_model(lay, proc, nfull, mins, naux, n, nins, nsub)
    wk = Work(np.zeros((MAX_ROWS, nh)), np.zeros(MAX_ROWS), np.zeros((MAX_ROWS, MAX_ROWS)))
    ws, dxf = Work(np.zeros((MAX_ROWS, n)), wk.z, wk.R), np.zeros(nh)
    w = np.zeros((5, 3))  # rows W_IB, W_FIX, W_IE, W_IN and W_FN (mean f^n, models with a time offset)
    no_row = np.zeros(rec.data.shape[1])  # the row of a node constraint (unused)
    prop_dt = proc.prop_dt
    max_nodes, n_out = _chunk_sizes(imu, rec, out, cy, prop_dt)
    out_idx, out_node = np.empty(n_out, np.int64), np.empty(n_out, np.int64)  # out_node: last node ≤ sample
    out_st, out_bias, out_pdiag = output_rows(out.rows, cy.k0 == 0 and cy.last, n_out, max(nb, 1), n)
    o = (out_idx, out_st, out_bias, out_pdiag, out_node)
    node_idx = np.empty(max_nodes, np.int64)
    ns = max_nodes if out.smooth else 1
    S_post, S_prior, S_phi = np.zeros((ns, n, n)), np.zeros((ns, n, n)), np.zeros((ns, n, n))
    S_dx = np.zeros((ns, n))
    S = (S_post, S_prior, S_phi, S_dx)  # what the RTS pass keeps of a node (.tilt_turn)
    log, li = _chunk_log(rec, M + max_nodes * mod.node.shape[0]), M
    win = np.zeros((N_MODELS, WIN_MAX + 2))  # NIS windows of the re-initialisation test
    rej = cy.rej
    upd = (mod, lay, rej, win, log, wk, sub, ws)  # the update context of the records and node constraints
    cov_out = np.zeros((out.cov_idx.shape[0], n, n))
    ci, reset_node, gi, acc = cy.ci, cy.reset_node, cy.gi, cy.acc
    gap = cy.gap  # (6,): variances to add at the next node, the heading-hold flag, the last heading
    pv = mod.par[M_GNSS_VEL]
    hold_thr = pv[C_HOLD] if pv.shape[0] > C_HOLD else 0.0  # (other filters: fewer parameters)
    buf = cy.buf  # Δθ_c, Δv_c of the sample, of the previous one (rows: no views per sample, issue 40)
    tp, kn, oi, ev = cy.tp, cy.kn, 0, out.every  # ev 1: no integer division per sample (issue 40)
    hold, epochs, ncon = imu.hold.shape[0] == n_imu, rec.grp.t.shape[0] > 0, _constraint_counts(mod.node)
    # a record is due when its time on the IMU clock has come: its receive time (the tag, or with clock
    # states tag − b̂/c) − d̂, the time-offset estimate; b̂ changes at every sample, d̂ at the feedback
    t_due = _due_time(rec.t, gi, bias, ic, itoff)
    for k in range(n_imu):
        dt, tp = imu.t[k] - tp, imu.t[k]
        T = propagate_sample_rows(st, acc, imu.dth, imu.dv, k, ib, dt, buf)
        if ic >= 0:
            bias[ic - NAV] += bias[ic - NAV + 1] * dt
            t_due = _due_time(rec.t, gi, bias, ic, itoff)
        if hold:
            st[ST_POS + 2], st[ST_VEL + 2] = imu.hold[k, 0], imu.hold[k, 1]
        gap_k = _gap_sample(gap, imu.gap_var, k)
        if k0 + k == ini.reset_idx:
            reset_node = kn  # the next node is the first one after the re-initialisation
            _reinit(st, P, ini, ix, hold_h, (-1, -1, bias) if nsub else (itoff, lay[L_VDEL], bias),
                    mod.cal, acc)
        is_node = T >= prop_dt - 1e-9 or t_due <= imu.t[k] or (cy.last and k == n_imu - 1)
        if is_node and T > 0.0:
            if kn - kn0 >= max_nodes:
                raise ValueError("run_chunk: more nodes than a chunk can hold (record times > 100 s late)")
            C = dcm_from_quat(st[ST_Q:ST_Q + 4])
            wb = predict_node(st, acc, x, P, T, proc, em, (nins, mins, nh))
            carry_estimates(st, bias, em[4], proc.open, nh)  # em[4]: Φ of the interval
            g0, held, sk = gi, hold_h and k0 + k < ini.reset_idx, imu.static[k]  # held: _hold_heading
            dh = _gap_at_node(st, P, gap, ix, hold_thr, imu.static[k] and not held)
            keep_prior(out.smooth, S, kn - kn0, em[4], P, dh, ix)  # dh: the tilt turned at rest
            node_rates(st, wb, buf[0], dt, w)
            w[W_FN] = acc[ACC_FN] / T
            hd = (gap, gap_k, ix, iu, pv, tcal, held, epochs)
            gi, C = _update_records(x, P, (st, w, bias), C, rec, gi, imu.t[k], hd, upd, (ic, itoff))
            if ncon[1 if sk else 0] > 0:  # (none: no binding of the update context, issue 40)
                li = _node_constraints(x, P, Nav(st, C, w, 0.0, bias), sk, imu.t[k], no_row, upd, li)
            if nsub:  # the subset's estimate in the INS block
                dxf[sub] = x
            feedback(st, bias, dxf if nsub else x, nh)
            dh = turn_with_feedback(dxf if nsub else x, P, held or gap[4] > 0 or not imu.static[k], ix)
            ib[:] = bias[:nins - NAV]
            _hold_heading(P, iu, ini, held, gap)
            _after_updates(st, bias, P, rec, (g0, gi), (proc.reset_pos, epochs), lay)
            t_due = _due_time(rec.t, gi, bias, ic, itoff)  # d̂ may have changed
            node_idx[kn - kn0] = k0 + k
            keep_post(out.smooth, S, kn - kn0, P, x, dh, ix)
            kn += 1
            reset_accumulator(acc)
        if (ev == 1 or (k0 + k) % ev == 0) if ev > 0 else (kn > kn0 and node_idx[kn - 1 - kn0] == k0 + k):
            oi = _write_output(o, oi, k0 + k, st, bias, nb, P, kn - 1)
        while ci < out.cov_idx.shape[0] and out.cov_idx[ci] == k0 + k:
            cov_out[ci] = P
            ci += 1
    nxt = Carry(k0 + n_imu, cy.last, tp, kn, gi, ci, reset_node, st, bias, P, rej, acc, cy.gap, cy.buf)
    nk = kn - kn0
    return EngineOut(out_idx[:oi], out_st[:oi], out_bias[:oi], out_pdiag[:oi], out_node[:oi], node_idx[:nk],
                     S_post[:nk], S_prior[:nk], S_phi[:nk], S_dx[:nk], log, li, reset_node, st, bias, P,
                     cov_out, nxt)


# ------------------------------------------- open-loop states, update at t0
@njit(cache=True)
def carry_estimates(st, bias, Phi, opn, nstate):
    """Open-loop states ``opn`` (indices ≥ 9, no state subset): their estimate, kept in ``bias`` like
    every calibration state, is propagated as the conditional mean x̂ ← Φ x̂ at each node (the
    closed-loop engine otherwise holds it: right for a random constant, wrong for a Markov process such
    as a flexure); the change (and what Φ carries into the other states) is fed back. The updates
    then add to that estimate and it is never reset: with Φ linear in these states this is the
    open-loop estimator x̂⁻ = Φ x̂⁺, x̂⁺ = x̂⁻ + K ν, exactly, and the RTS pass sees a prior of zero."""
    if opn.shape[0] == 0:
        return
    feedback(st, bias, open_loop_change(Phi, bias, opn, nstate), nstate)


@njit(cache=True, depends=MODELS_KEY)
def initial_update(rec, mod, proc, ini):
    """The records at or before ``ini.t0`` (which :func:`run_filter` skips) as one node at t0 without
    prediction: the update of an initialisation from measurements at t0 (transfer alignment). Returns
    (st, bias, P) after the updates and their feedback, the :class:`Log` of those records and the
    update dx (for an RTS pass that includes t0)."""
    n = proc.lay[L_N]
    st, bias, P, x = ini.st.copy(), ini.bias.copy(), ini.P.copy(), np.zeros(n)
    wk = Work(np.zeros((MAX_ROWS, n)), np.zeros(MAX_ROWS), np.zeros((MAX_ROWS, MAX_ROWS)))
    w = np.zeros((5, 3))
    node_rates(st, np.zeros(3), np.zeros(3), 1.0, w)
    g = 0
    while g < rec.t.shape[0] and rec.t[g] <= ini.t0:
        g += 1
    log = Log(rec.t[:g].copy(), rec.model[:g].astype(np.int8), np.full(g, -1, np.int8), np.full(g, np.nan),
              np.full((g, MAX_ROWS), np.nan), np.full((g, MAX_ROWS), np.nan), np.arange(g),
              np.zeros(g, np.int8))
    rej = np.zeros(N_MODELS, np.int64)
    C = dcm_from_quat(st[ST_Q:ST_Q + 4])
    for i in range(g):
        if rec.use[i]:
            md = rec.model[i]
            nav = Nav(st, C, w, ini.t0 - rec.t[i], bias)
            m = fill(md, nav, rec.data[i], mod.par[md], proc.lay, wk.H, wk.z, wk.R)
            if m > 0:
                gated_update(x, P, wk, m, md, mod, rej, log, i)
    feedback(st, bias, x, n)
    return st, bias, P, log, x
