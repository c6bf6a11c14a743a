"""The tightly coupled filter's per-call inputs (:func:`aidnav.filters.tight.run_tight`): the whole-epoch
pseudorange/rate rows and the engine records they go into, the IMU input, and the one block of memory
the call's large arrays are carved from.

**One block per call** (issue 40, session 17): each call of ``run_tight`` first-touches its memory — a page
fault per 4 KiB page, ~2 µs each on the shared machine; the walk's call touched ~5 MB outside the kernel's
output rows (the epoch rows, the records, the per-epoch outputs and their copy, the IMU times and
intervals): ~1,300 faults, ~3 ms of a 33 ms call. :class:`Arena` carves those arrays out of one block of at
least 4 MiB that starts on a huge page's boundary, which numpy advises the kernel to back with huge pages
(as :mod:`.output_rows` does for the kernel's per-sample outputs): the same first touch in a handful of
2 MiB faults. Nothing is kept from one call to the next; arrays of the result that are views of the block
keep it alive with them.

**Epoch rows** (:mod:`.measurements.epoch`'s layout, ``E_W`` values per satellite): the satellites'
positions, velocities and clocks from the broadcast ephemerides at the transmit time implied by each
pseudorange (:func:`aidnav.nav.gnss_sat.sat_from_pseudorange_once`, the ephemeris of
:func:`~aidnav.nav.gnss_sat.select_ephemeris`) are computed and written straight into the engine records'
data block (:func:`_fill_epoch_rows`, one compiled call over all epochs; :func:`_fill_sat_columns` the
per-satellite slots), with no (M, S) intermediate arrays: the arithmetic of
:func:`aidnav.nav.gnss_sat.satellite_states_epochs` and the numpy expressions it replaces, but one Kepler
solve per satellite and epoch, warm-started from the satellite's previous epoch (issue 40, session 18:
three before, one for each transmit-time pass; the values differ by a few ulps of E_k, ~1e-8 m).
"""

from __future__ import annotations

import math

import numpy as np

from aidnav.jit import njit
from aidnav.nav.gnss_sat import (
    C_LIGHT,
    E_URA,
    FREQ_L1,
    SYSTEMS,
    dual_frequency_iono,
    sat_from_pseudorange_once,
    select_ephemeris,
)
from aidnav.units import DEG

from . import measurements as ms
from .engine import Imu, Records
from .measurements import epoch as ep
from .preprocess import GAP_FACTOR, bridge_gaps, imu_gaps, surely_no_gap

__all__ = ["Arena", "arena_bytes", "epoch_outputs", "epoch_records", "epoch_rows", "imu_input", "imu_times",
           "rejected_per_satellite", "rotation_variance", "timing_variance"]

HUGE = 2 << 20  # bytes of a huge page (x86-64)
MIN_BLOCK = 4 << 20  # numpy advises huge pages for allocations from 4 MiB on
ALIGN = 64  # bytes: each array starts on a cache line


class Arena:
    """One block of ``nbytes`` (at least :data:`MIN_BLOCK`) starting on a huge page's boundary; ``empty``
    and ``full`` hand out consecutive C-contiguous arrays of it, and plain numpy arrays once it is used up
    (the same values, only the page faults differ)."""

    def __init__(self, nbytes: int):
        size = max(int(nbytes), MIN_BLOCK)
        raw = np.empty(size + HUGE, np.uint8)  # numpy: madvise(MADV_HUGEPAGE) (>= 4 MiB)
        o = -raw.ctypes.data % HUGE
        self.buf, self.pos = raw[o:o + size], 0

    def empty(self, shape, dtype=float) -> np.ndarray:
        dt = np.dtype(dtype)
        shape = (int(shape),) if isinstance(shape, (int, np.integer)) else tuple(shape)
        n = math.prod(shape) * dt.itemsize
        start = -(-self.pos // ALIGN) * ALIGN
        if start + n > self.buf.size:
            return np.empty(shape, dt)
        self.pos = start + n
        return self.buf[start:start + n].view(dt).reshape(shape)

    def full(self, shape, value, dtype=float) -> np.ndarray:
        a = self.empty(shape, dtype)
        a.fill(value)
        return a


def arena_bytes(imu, obs, velocity_fixes=None) -> int:
    """Bytes of the :class:`Arena` of a ``run_tight`` call: the records' data block and per-epoch outputs
    (the epochs and satellites of ``obs``, the velocity records), the IMU times, intervals (twice where
    there are gaps), gap variances and bridged increments, the output times; a cache line per array on
    top."""
    (M, S), n_imu = obs.code1.shape, len(imu.time)
    R = M + (0 if velocity_fixes is None else len(velocity_fixes[0]))
    out_row = 8 * (1 + 6 + 5 * S + 81 + 2 + 10)  # one record's EpochOut values
    imu = 8 * n_imu * (1 + 2 * 2 + 2 + 6 + 1)  # times, intervals + scratch, gap variances, copies, out
    return R * S * ep.E_W * 8 + R * out_row + imu + 64 * ALIGN


@njit(cache=True)
def _fill_epoch_rows(eph_table, prns, t_rx, obs, ion, dphi, wl, opts, data, at):
    """Fill the epoch rows ``data[at[k]]`` (S·E_W values each, NaN beforehand) of the M epochs: satellite
    position, velocity (columns 0-5), ρ + c·dt_s (6: where the position is finite), ρ̇ + c·ḋt_s (7), the
    dual-frequency delay ``ion`` (8; (0, 0): none), URA (9) and with ``dphi`` (M, S) ((0, 0): none) the
    TDCP values (E_PHASE…: y = λΔL + Δ(c·dt_s), the previous epoch's position, the interval).
    ``obs`` = (code (M, S), Doppler (M, S)), ``wl`` (S,) wavelengths, ``opts`` = (use T_GD, max age [s]).
    Returns per satellite the epochs with a pseudorange but no usable ephemeris, and whether it has a
    usable ephemeris at some epoch (a finite position)."""
    code, dop = obs
    M, S = code.shape
    use_tgd, max_age = opts[0] != 0.0, opts[1]
    no_eph, usable = np.zeros(S, np.int64), np.zeros(S, np.bool_)
    clk, prev = np.full(S, np.nan), np.full(S, np.nan)  # c·dt_s of this epoch and the previous one
    warm = np.full((S, 4), np.nan)  # per satellite: its last Kepler solve (E, M, 1 − e cos E), its record
    tdcp = dphi.shape[0] == M and M > 1
    for k in range(M):
        r = data[at[k]]
        for j in range(S):
            o = j * ep.E_W
            prev[j], clk[j] = clk[j], np.nan
            if ion.shape[0] == M:
                r[o + 8] = ion[k, j]
            if not np.isfinite(code[k, j]):
                continue
            i = select_ephemeris(eph_table, prns[j], t_rx[k], max_age)
            if i < 0:
                no_eph[j] += 1
                continue
            w = warm[j]
            if w[3] != i:
                w[0], w[3] = np.nan, i
            x, y, z, vx, vy, vz, dts, ddts = sat_from_pseudorange_once(eph_table[i], t_rx[k], code[k, j],
                                                                       use_tgd, w)
            r[o], r[o + 1], r[o + 2], r[o + 3], r[o + 4], r[o + 5] = x, y, z, vx, vy, vz
            clk[j] = dts * C_LIGHT
            if np.isfinite(x):
                r[o + 6] = code[k, j] + clk[j]
                usable[j] = True
            else:
                no_eph[j] += 1
            r[o + 7] = -wl[j] * dop[k, j] + ddts * C_LIGHT
            r[o + 9] = eph_table[i, E_URA]
        if tdcp and k > 0:
            rp = data[at[k - 1]]
            for j in range(S):
                o, q = j * ep.E_W, j * ep.E_W + ep.E_PHASE
                if np.isfinite(r[o]) and np.isfinite(rp[o]):
                    r[q] = dphi[k, j] + clk[j] - prev[j]
                r[q + 1], r[q + 2], r[q + 3] = rp[o], rp[o + 1], rp[o + 2]
                r[q + 4] = t_rx[k] - t_rx[k - 1]
    return no_eph, usable


@njit(cache=True)
def _fill_sat_columns(data, at, cols):
    """Columns 10-13 of every epoch row ``data[at[k]]``: per satellite ``cols`` (S, 4) (range-error slot,
    inter-system-bias slot, Klobuchar scale, σ factor; NaN: none)."""
    S = cols.shape[0]
    for k in range(at.shape[0]):
        r = data[at[k]]
        for j in range(S):
            o = j * ep.E_W + 10
            r[o], r[o + 1], r[o + 2], r[o + 3] = cols[j, 0], cols[j, 1], cols[j, 2], cols[j, 3]


def epoch_rows(obs, eph, g, events: list, data, at, phase_increments=None):
    """The whole-epoch pseudorange/rate rows of :mod:`.measurements.epoch` written into the records' data
    block ``data`` (rows ``at``, NaN beforehand): satellite position, velocity, corrected code and rate,
    dual-frequency ionosphere, URA, the range-error and inter-system-bias state of each satellite, the
    Klobuchar scale (f_L1/f)² and the system's σ factor. Returns the satellites that get a range-error
    state and the systems that get a bias state (one per non-GPS system with a usable satellite). With
    ``phase_increments`` (M, S) [m]: the TDCP values y = λΔL + Δ(c·dt_s), the satellite's previous
    position and the interval."""
    none = np.empty((0, 0))
    if g.iono == "dual":
        if obs.code2 is None:
            raise ValueError("iono = dual needs an L2 code")
        ion = dual_frequency_iono(obs.time, obs.code1, obs.code2, g.iono_window_s)
        ion = np.ascontiguousarray(ion, float)
    else:
        ion = none
    dphi = none if phase_increments is None else np.ascontiguousarray(phase_increments, float)
    code = np.ascontiguousarray(obs.code1, float)
    dop = np.ascontiguousarray(obs.doppler1, float)
    opts = np.array([float(g.iono != "dual"), float(g.max_eph_age_s)])
    f, sysid = obs.frequencies(), np.asarray(obs.prn, np.int64) // 100  # (wavelengths(): C / f)
    no_eph, usable = _fill_epoch_rows(np.ascontiguousarray(eph.table, float), np.asarray(obs.prn, np.int64),
                                      np.ascontiguousarray(obs.time, float), (code, dop), ion, dphi,
                                      np.ascontiguousarray(C_LIGHT / f, float), opts, data, at)
    if no_eph.any():
        names = obs.names
        for j in np.flatnonzero(no_eph):
            events.append(f"{names[j]}: {int(no_eph[j])} epoch(s) with a pseudorange but no usable "
                          "ephemeris; skipped")
    # range-error states: one per satellite with a usable ephemeris somewhere in the log
    with_eph = np.flatnonzero(usable) if g.range_errors else np.zeros(0, int)
    cols = np.full((len(usable), 4), np.nan)
    cols[with_eph, 0] = np.arange(len(with_eph))
    # inter-system biases: one per non-GPS system with a usable satellite; Klobuchar scale, σ factor
    isb_sys = [c for c in "ECR" if usable[sysid == SYSTEMS.index(c)].any()]
    for k, c in enumerate(isb_sys):
        cols[sysid == SYSTEMS.index(c), 1] = k
    cols[:, 2] = np.where(np.isfinite(f), (FREQ_L1 / f) ** 2, 1.0)
    cols[:, 3] = [g.system_sigma_factor.get(SYSTEMS[i], 1.0) for i in sysid]
    _fill_sat_columns(data, at, cols)
    return with_eph, isb_sys


def epoch_records(t_obs, velocity_fixes, S: int, arena: Arena):
    """Engine records with their data block NaN (the epoch rows for :func:`epoch_rows`): one whole-epoch
    pseudorange record per epoch and, with ``velocity_fixes``, velocity records among them in time order.
    Returns (Records, indices of the epoch records in time order, the row of each epoch record)."""
    M = len(t_obs)
    W = S * ep.E_W
    if velocity_fixes is None:
        data = arena.full((M, W), np.nan)
        at = np.arange(M)
        return Records(np.asarray(t_obs, float), np.full(M, ms.M_PR, np.int64), data, np.ones(M, np.bool_),
                       ep.epoch_out(M, S, arena.full)), at, at
    tv, vv, sv = (np.ascontiguousarray(a, float) for a in velocity_fixes)
    t, model, at, keep = _record_order(np.ascontiguousarray(t_obs, float), tv, vv, sv, ms.M_PR, ms.M_GNSS_VEL)
    data = arena.full((len(t), W), np.nan)
    data[at[M:], 0:3], data[at[M:], 3:6] = vv[keep], sv[keep]
    rec = Records(t, model, data, np.ones(len(t), np.bool_), ep.epoch_out(len(t), S, arena.full))
    return rec, np.flatnonzero(model == ms.M_PR), at[:M]


@njit(cache=True)
def _record_order(t_obs, tv, vv, sv, m_pr, m_vel):
    """The records in time order: the M epochs ``t_obs`` and the K velocity records whose time ``tv``,
    velocity ``vv`` and σ ``sv`` (K, 3) are finite (their indices ``keep``), sorted stably (epochs first
    at a tie: numpy's stable argsort of the concatenation). Returns (times, model, the row of each record
    — the epochs', then the kept velocity records' —, keep). One call for ~10 numpy ones (session 18)."""
    M = t_obs.shape[0]
    keep = np.empty(tv.shape[0], np.int64)
    K = 0
    for i in range(tv.shape[0]):
        good = np.isfinite(tv[i])
        for c in range(3):
            good = good and np.isfinite(vv[i, c]) and np.isfinite(sv[i, c])
        if good:
            keep[K] = i
            K += 1
    keep = keep[:K]
    t_all = np.empty(M + K)
    t_all[:M] = t_obs
    for i in range(K):
        t_all[M + i] = tv[keep[i]]
    order = np.argsort(t_all, kind="mergesort")
    t, model, at = np.empty(M + K), np.empty(M + K, np.int64), np.empty(M + K, np.int64)
    for r in range(M + K):
        o = order[r]
        t[r], at[o] = t_all[o], r
        model[r] = m_pr if o < M else m_vel
    return t, model, at, keep


@njit(cache=True)
def _compact_rows(a, sel):
    """Rows ``sel`` (ascending, so sel[i] >= i) of ``a`` moved to its first rows, in place."""
    for i in range(sel.shape[0]):
        s = sel[i]
        if s != i:
            a[i, :] = a[s, :]


@njit(cache=True)
def _compact_epoch_out(t, cnt, node, sat, sel):
    """:func:`_compact_rows` of every per-record output array (``sat`` (5, R, S): each of its five) in one
    call (issue 40, session 18: eight calls were ~0.1 ms of dispatch)."""
    _compact_rows(t.reshape(-1, 1), sel)
    _compact_rows(cnt, sel)
    _compact_rows(node, sel)
    for i in range(sat.shape[0]):
        _compact_rows(sat[i], sel)


def epoch_outputs(grp, sel):
    """The per-epoch outputs of the epoch records ``sel`` (ascending) by name (:func:`.measurements.epoch.
    epoch_fields`): each array's rows ``sel`` moved to its first rows in place, and views of those (the
    clock-jump flags kept whole). ``grp`` is the call's own (:func:`epoch_records`), used up by this."""
    n = len(sel)
    if n != len(grp.t):
        _compact_epoch_out(grp.t, grp.cnt, grp.node, grp.sat, np.asarray(sel, np.int64))
    return ep.epoch_fields(grp, slice(0, n))


@njit(cache=True)
def rejected_per_satellite(nu, s, gate):
    """Per satellite (column) the epochs whose innovation ``nu`` (M, S) lies outside the gate: ν² > gate·s
    (NaN: not counted)."""
    out = np.zeros(nu.shape[1], np.int64)
    for k in range(nu.shape[0]):
        for j in range(nu.shape[1]):
            if nu[k, j] * nu[k, j] > gate * s[k, j]:  # numpy's square: the same product
                out[j] += 1
    return out


def imu_times(imu, offset: float, arena: Arena) -> np.ndarray:
    """The IMU times on the GNSS scale, t + ``offset`` [s] (into ``arena``); the log's own array where the
    offset is 0 (t + 0.0 is t: no copy)."""
    if offset == 0.0:
        return np.ascontiguousarray(imu.time, float)
    return np.add(imu.time, offset, out=arena.empty(len(imu.time)))


def imu_input(imu, cfg, t_imu, k0: int, static, events: list, rec_t=None, arena: Arena | None = None) -> Imu:
    """The engine's IMU input from sample ``k0`` on: increments with gaps bridged, the static flags for
    the ZUPTs, the attitude variance of gyro scale factor and misalignment per node
    (``cfg.rotation_noise``) and the velocity variance of the time offset's σ at the velocity records
    (times ``rec_t``: :func:`timing_variance`); the large arrays from ``arena``."""
    stat = np.zeros(len(t_imu), np.bool_) if static is None else np.asarray(static, np.bool_)
    empty = None if arena is None else arena.empty
    dth_in, dv_in = imu.dtheta, imu.dv
    # bridge_gaps' rule (its (N, 4) gap variances not used here): the median only where a gap is possible
    if not surely_no_gap(np.asarray(imu.time, float), float(imu.t0), GAP_FACTOR):
        _, med, gaps = imu_gaps(imu, empty=empty)
        if len(gaps):
            dth_in, dv_in = bridge_gaps(imu, events, med=med, empty=empty)[:2]  # (as before the engine)
    sl = slice(k0, None)
    # (attitude, velocity) variance added at the next node
    gap_var = np.zeros((len(t_imu) - k0, 2)) if arena is None else arena.full((len(t_imu) - k0, 2), 0.0)
    if cfg.rotation_noise:
        im = cfg.imu
        gap_var[:, 0] = rotation_variance(t_imu[sl], dth_in[sl], im.gyro_sf_sigma_ppm * 1e-6,
                                          im.gyro_misalignment_sigma_deg * DEG, float(cfg.filter.prop_dt_s))
    if cfg.gnss.time_offset_sigma_s > 0 and rec_t is not None and len(rec_t) > 1:
        gap_var[:, 1] = timing_variance(t_imu[sl], dv_in[sl], np.asarray(rec_t, float),
                                        cfg.gnss.time_offset_sigma_s)
    return Imu(t_imu[sl], dth_in[sl], dv_in[sl], stat[sl], gap_var, np.zeros((0, 2)))


def rotation_variance(t, dth, sf, mis, block_s):
    """Attitude variance [rad²] per IMU sample from gyro scale-factor (σ ``sf`` [-]) and misalignment
    (σ ``mis`` [rad]) errors that are not states: over each block of ``block_s`` seconds the error they
    leave is (S + M)·Δθ, Δθ the block's net body rotation (sum of the increments ``dth`` (N, 3)); on any
    navigation axis its variance is at most (σ_sf² + σ_m²)·|Δθ|² (a rotated diagonal S, off-diagonal M),
    placed at the block's last sample. Blocks are independent (a constant error over a steady turn of K
    blocks grows K times faster than this; back-and-forth rotation cancels in the truth, not here)."""
    out = np.zeros(len(t))
    if len(t) == 0 or sf <= 0 and mis <= 0:
        return out
    blk = np.floor((np.asarray(t) - t[0]) / block_s).astype(np.int64)
    ends = np.flatnonzero(np.diff(np.r_[blk, blk[-1] + 1]))
    net = np.add.reduceat(np.asarray(dth, float), np.r_[0, ends[:-1] + 1], axis=0)
    out[ends] = (sf * sf + mis * mis) * (net * net).sum(axis=1)
    return out


def timing_variance(t, dv, rec_t, sigma_s: float) -> np.ndarray:
    """Per IMU sample (N,) the velocity variance [(m/s)²] per axis that an IMU-GNSS timing error of σ
    ``sigma_s`` [s] leaves between consecutive velocity records: the strapdown integrates a(t + δt) for
    a(t), so the velocity it carries from one record (the last velocity update) to the next is off by
    δt·(a(t_j) − a(t_{j−1})) — bounded, not a random walk: without records (an outage) nothing is added;
    its variance (σ·|Δf|)², Δf the specific-force change between the samples at the records (body frame:
    the turn between records neglected; a 5-sample mean at each end), is put at the sample of record j (the
    engine adds it at that node). ``t`` (N,) sample times, ``dv`` (N, 3) increments, ``rec_t`` (M,) record
    times, all on one scale."""
    t = np.asarray(t, float)
    dt = np.diff(np.concatenate([[t[0] - np.median(np.diff(t))], t]))
    f = np.asarray(dv, float) / dt[:, None]
    f = np.column_stack([np.convolve(f[:, i], np.full(5, 0.2), mode="same") for i in range(3)])  # 5 samples
    k = np.unique(np.clip(np.searchsorted(t, np.sort(rec_t)), 0, len(t) - 1))
    out = np.zeros(len(t))
    if k.size > 1:
        df = np.linalg.norm(f[k[1:]] - f[k[:-1]], axis=1)
        out[k[1:]] = (sigma_s * df) ** 2
    return out
