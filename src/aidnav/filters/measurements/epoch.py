"""A whole GNSS epoch of pseudoranges and rates as one record (tight coupling), for the engine.

Row of an epoch (``S`` satellites × ``E_W`` values): per satellite r_s ECEF (3) [m], v_s ECEF (3)
[m/s], ρ + c·dt_s [m] (NaN: no pseudorange or no ephemeris), ρ̇ + c·ḋt_s [m/s] (NaN: no rate), the
dual-frequency ionospheric delay [m] (NaN: none), the ephemeris' URA [m], the satellite's slot in the
range-error states (NaN: none), its system's slot in the inter-system bias states (NaN: the GPS clock
itself), the Klobuchar scale (f_L1/f)² of its signal (NaN: 1), the σ factor of its system (NaN: 1),
and for the time-differenced carrier phase: y = λΔL + Δ(c·dt_s) from the previous epoch [m] (NaN: no
phase at both epochs, or a cycle slip), the satellite's position at the previous epoch (3) [m] and the
interval [s]. Parameters (``E_*``): lever arm, mask, zenith σ's, atmosphere switches, Klobuchar α β, the
clock-jump threshold, the clock σ's and the carrier phase's σ.

:func:`epoch_update` does, at the INS antenna moved back to the receive time t_tag − b̂/c:

* clock start / jumps: b̂ (and, at the first epoch, d̂) from the median residuals, variance reset;
* mask and ionosphere (Klobuchar or dual) and troposphere (Saastamoinen) at the INS position;
* one scalar row per pseudorange and per rate (:func:`aidnav.filters.kalman.update_scalar`), each
  gated by the χ²(1) threshold ``gate`` (0: not gated), σ(E) = σ0 √(½ + ½/sin²E);
* with range-error states (``lay[L_RERR]`` ≥ 0, slot k of a satellite in its row): the pseudorange of
  satellite j is ρ + σ_j(E)·u_j, u_j a unit-variance Gauss-Markov state (true − estimated like the
  clock; state lay[L_RERR] + k), σ_j(E) the single-frequency error budget
  (:func:`aidnav.nav.gnss_sat.range_error_sigma`) at the satellite's elevation, URA and applied
  ionospheric delay: the row gains σ_j at u_j and the prediction σ_j·û_j;
* several systems (``lay[L_ISB]`` ≥ 0, slot k of a satellite's system in its row): the pseudorange gains
  the inter-system bias β_k (that system's receiver clock − the GPS clock [m], true − estimated like the
  clock; state lay[L_ISB] + k): the row gains 1 at β_k and the prediction β̂_k; rates share the drift;
* the epoch counts as rejected (the engine's consecutive-rejection rule) when some row was rejected
  and no pseudorange accepted;
* **time-differenced carrier phase** (``lay[L_TDCP]`` ≥ 0): one delta-range row per satellite with y
  (:func:`tdcp_row`) against a *stochastic clone* of the previous epoch: after each epoch's rows the
  clone states are set to that epoch's antenna position (ECEF) and receive-time clock bias with their
  covariance copied (:func:`clone_epoch`), constant until the next epoch. The rows need no velocity
  model, work with any number of satellites and leave the clock change to the clock states; used when
  the clone is of the previous epoch of the row (an epoch not processed, a clock start or jump: none).

Rows: z_ρ = (ρ_meas − I − T) − (|r_s − r_a| + Sagnac + b̂), H = [e^nᵀ H_pos, 1 (δt_u)];
z_ρ̇ = ρ̇_meas − (e·(v_s − v_a) + Sagnac rate + d̂), H = [e^nᵀ H_vel, 1 (δf)] (H_pos, H_vel: the antenna
rows of :func:`.gnss.gnss_position` / :func:`.gnss.gnss_velocity`; e^n: ENU unit vector to the satellite);
z_φ = y − (ρ̂_k − ρ̂_{k−1} + b̂(t_k) − b̂_c), ρ̂_k = |r_s,k − r_a| + Sagnac, ρ̂_{k−1} = |r_s,k−1 − r̂_c| + Sagnac
(satellite motion and Earth rotation over the interval), b̂(t_k) = b̂ − d̂·dt_back (the clock at the receive
time), H = [e_k^nᵀ H_pos, 1 (δt_u), −dt_back (δf), e_{k−1}ᵀ (clone position, ECEF), −1 (clone clock)],
σ² = 2σ_φ²(½ + ½/sin²E)·(system factor)² (ionosphere and troposphere change by sub-mm in an interval;
carrier wind-up of a turning antenna is common to all satellites: the clock change takes it).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from aidnav.jit import njit
from aidnav.nav.earth import dcm_ecef_to_enu, lla_to_ecef
from aidnav.nav.gnss_sat import az_el, geo_range, geo_range_rate, klobuchar, range_error_sigma, tropo_delay

from ..kalman import update_scalar_ws
from ..layout import DV, L_CLK, L_ISB, L_NINS, L_RERR, L_TDCP, NAV, ST_VEL
from .common import W_IB, W_IN
from .gnss import gnss_position, gnss_velocity

E_W = 19  # values per satellite in a row
E_PHASE = 14  # offset of the TDCP values of a satellite: y [m], r_s at the previous epoch (3), Δt [s]
E_LEVER, E_MASK, E_SIG_CODE, E_SIG_RATE, E_IONO, E_TROPO, E_HUMID, E_RATE = 0, 3, 4, 5, 6, 7, 8, 9
E_JUMP, E_SIG_B, E_SIG_D, E_CODE_MIN, E_ALPHA, E_BETA, E_SIG_PHASE, E_NPAR = 10, 11, 12, 13, 14, 18, 22, 23
# per-epoch outputs (filled in place), in five arrays (issue 40, session 17: the engine binds the records at
# each node, and every binding of a tuple costs one atomic reference-count pair per array — 16 arrays were
# 16 pairs): t (M,) GPS receive time; cnt (M, 6) satellites above the mask, pseudoranges and rates used,
# rows rejected, TDCP rows used and rejected (``C_*``); sat (5, M, S) innovations and their variance of the
# pseudoranges and the rates, elevation (``S_*``); node (M, 93) after the epoch's node: clock (b̂, d̂),
# strapdown state (10), 9×9 navigation covariance (``N_*``); flags [clock initialised, jumps, 1 + the
# epoch of the clone (0: none)]. :func:`epoch_fields` names them (:class:`EpochFields`).
EpochOut = namedtuple("EpochOut", ["t", "cnt", "sat", "node", "flags"])
C_AVAIL, C_PR, C_RATE, C_REJ, C_TD, C_TDREJ = range(6)
S_PR_NU, S_PR_S, S_RATE_NU, S_RATE_S, S_EL = range(5)
N_CLK, N_STATE, N_PNAV, N_W = 0, 2, 12, 93
EpochFields = namedtuple("EpochFields", ["t", "navail", "npr", "nrate", "nrej", "ntd", "ntdrej", "pr_nu",
                                         "pr_s", "rate_nu", "rate_s", "el", "P_nav", "clk", "state", "flags"])


def epoch_out(M: int, S: int, full=None) -> EpochOut:
    """Empty per-epoch outputs for M epochs of S satellites (M = 0: no epoch records); ``full``: an
    allocator like ``np.full`` (:class:`aidnav.filters.tight_input.Arena`'s: one block for a call's
    arrays)."""
    full = np.full if full is None else full
    node = full((M, N_W), 0.0)
    node[:, N_CLK:N_CLK + 2] = np.nan
    return EpochOut(full(M, np.nan), full((M, 6), 0, np.int64), full((5, M, S), np.nan), node,
                    np.zeros(3, np.int64))


def epoch_fields(grp: EpochOut, sel=slice(None)) -> EpochFields:
    """The per-epoch outputs ``grp`` by name (views of ``grp`` where ``sel`` is a slice, copies of the epochs
    ``sel`` where it is an index array; ``flags`` as it is): t, navail, npr, nrate, nrej, ntd, ntdrej (M,),
    pr_nu, pr_s, rate_nu, rate_s, el (M, S), P_nav (M, 9, 9), clk (M, 2), state (M, 10), flags (3,)."""
    cnt, sat, node = grp.cnt[sel], grp.sat[:, sel], grp.node[sel]
    pnav = node[:, N_PNAV:].reshape(len(node), 9, 9)
    return EpochFields(grp.t[sel], *[cnt[:, i] for i in range(6)], *[sat[i] for i in range(5)], pnav,
                       node[:, N_CLK:N_CLK + 2], node[:, N_STATE:N_STATE + 10], grp.flags)


@njit(cache=True)
def _antenna(nav, lever, Hp, Hv):
    """Antenna ECEF position (moved back by dt_back) and velocity; Hp, Hv: antenna position / velocity
    rows (ENU) of the error state."""
    st = nav.st
    z3 = np.zeros(3)
    gnss_position(st, nav.C, lever, st[0], st[1], st[2], 0.0, Hp, z3)
    gnss_velocity(st, nav.C, lever, nav.w[W_IB], nav.w[W_IN], st[ST_VEL:ST_VEL + 3], Hv, z3)
    v_n = st[ST_VEL:ST_VEL + 3] + z3
    Cen = dcm_ecef_to_enu(st[0], st[1])
    pe = np.zeros(3)
    pe[0], pe[1], pe[2] = lla_to_ecef(st[0], st[1], st[2])
    return pe + Cen.T @ (nav.C @ lever - v_n * nav.dt_back), Cen.T @ v_n, Cen


@njit(cache=True)
def _geometry(row, ra, lat, lon, geo):
    """Each satellite's geometry at the antenna ``ra`` (ECEF) at (lat, lon) [rad], once per epoch: rows of
    ``geo`` (S, 6) = [range with the Sagnac term, e^e (3), azimuth, elevation] where the row has a code and
    a satellite position (others left as they are). The clock start, the visible count and the updates
    read them (issue 40, session 16: each satellite's range and azimuth/elevation were computed 3 and 2
    times an epoch, an allocation and six libm calls each; the same arithmetic, so the same bits)."""
    for j in range(row.shape[0] // E_W):
        o = j * E_W
        if np.isnan(row[o + 6]) or np.isnan(row[o]):
            continue
        rho, e = geo_range(row[o:o + 3], ra)
        az, el, _ = az_el(e, lat, lon)
        geo[j, 0], geo[j, 1], geo[j, 2], geo[j, 3], geo[j, 4], geo[j, 5] = rho, e[0], e[1], e[2], az, el


@njit(cache=True)
def _clock_start(P, nav, row, par, lay, grp, geo, ra, va):
    """Clock start / jump from the median pseudorange (and at the start rate) residuals (``geo``: the
    satellites' geometry, :func:`_geometry`)."""
    S = row.shape[0] // E_W
    res, res_r = np.full(S, np.nan), np.full(S, np.nan)
    for j in range(S):
        o = j * E_W
        if np.isnan(row[o + 6]) or np.isnan(row[o]):
            continue
        res[j] = row[o + 6] - geo[j, 0]
        if lay[L_ISB] >= 0 and not np.isnan(row[o + 11]):
            res[j] -= nav.bias[lay[L_ISB] + int(row[o + 11]) - NAV]
        if not np.isnan(row[o + 7]):
            res_r[j] = row[o + 7] - geo_range_rate(row[o:o + 3], row[o + 3:o + 6], ra, va, geo[j, 1:4])
    ok = np.isfinite(res)
    if ok.sum() == 0:
        return
    ib, bi = lay[L_CLK], lay[L_CLK] - NAV
    med = np.median(res[ok])
    init = grp.flags[0] == 1
    if init and abs(med - nav.bias[bi]) <= par[E_JUMP]:
        return
    if init:
        grp.flags[1] += 1
    nav.bias[bi] = med
    P[ib, :] = 0.0
    P[:, ib] = 0.0
    P[ib, ib] = par[E_SIG_B] ** 2
    okd = np.isfinite(res_r)
    if not init and okd.sum() > 0:
        nav.bias[bi + 1] = np.median(res_r[okd])
        P[ib + 1, :] = 0.0
        P[:, ib + 1] = 0.0
        P[ib + 1, ib + 1] = par[E_SIG_D] ** 2
    grp.flags[0] = 1


@njit(cache=True)
def _row(h, en, Ha, nn, ic):
    """h = [e^nᵀ Ha (INS block of nn states: the antenna's position and velocity depend on its first 15
    at most; scale-factor and misalignment columns stay 0), 1 at the clock state ic]."""
    h[:] = 0.0
    for c in range(min(nn, Ha.shape[1])):
        h[c] = en[0] * Ha[0, c] + en[1] * Ha[1, c] + en[2] * Ha[2, c]
    h[ic] = 1.0


@njit(cache=True)
def epoch_update(x, P, nav, row, par, lay, gate, grp, g, t_gps):
    """All satellites of epoch ``g`` (row layout: module doc) as sequential scalar updates of x, P.
    Returns True unless the epoch counts as rejected (module doc)."""
    S = row.shape[0] // E_W
    n = P.shape[0]
    ib, bi = lay[L_CLK], lay[L_CLK] - NAV
    nn = lay[1]  # INS block
    lever = par[E_LEVER:E_LEVER + 3].copy()
    Hp, Hv = np.zeros((3, 15)), np.zeros((3, 15))  # INS block of 9 or 15 states
    ra, va, Cen = _antenna(nav, lever, Hp, Hv)
    grp.t[g] = t_gps
    f0, f1 = grp.flags[0], grp.flags[1]
    lat, lon, hh = nav.st[0], nav.st[1], nav.st[2]
    geo, en = np.empty((S, 6)), np.empty(3)  # the satellites' geometry (_geometry); Cen e
    _geometry(row, ra, lat, lon, geo)
    _clock_start(P, nav, row, par, lay, grp, geo, ra, va)
    tdcp = _clone_of_previous(row, lay, grp, t_gps) and f0 == grp.flags[0] and f1 == grp.flags[1]
    alpha, beta = par[E_ALPHA:E_ALPHA + 4].copy(), par[E_BETA:E_BETA + 4].copy()
    n_vis = 0
    for j in range(S):
        o = j * E_W
        if not (np.isnan(row[o + 6]) or np.isnan(row[o])) and geo[j, 5] >= par[E_MASK]:
            n_vis += 1
    use_code = n_vis >= par[E_CODE_MIN]
    ir, isb = lay[L_RERR], lay[L_ISB]
    hw = np.zeros((3, n))  # the row h, then update_scalar_ws's work rows (one allocation per epoch)
    h, uw = hw[0], hw[1:]
    nrej = 0
    for j in range(S):
        o = j * E_W
        if np.isnan(row[o + 6]) or np.isnan(row[o]):
            continue
        rho, e, az, el = geo[j, 0], geo[j, 1:4], geo[j, 4], geo[j, 5]
        for a in range(3):  # Cen e (a 3 × 3 product: no BLAS call)
            en[a] = Cen[a, 0] * e[0] + Cen[a, 1] * e[1] + Cen[a, 2] * e[2]
        grp.sat[S_EL, g, j] = el
        if el < par[E_MASK]:
            continue
        grp.cnt[g, C_AVAIL] += 1
        corr, i_mode = 0.0, 0
        ifac = 1.0 if np.isnan(row[o + 12]) else row[o + 12]
        sfac = 1.0 if np.isnan(row[o + 13]) else row[o + 13]
        if par[E_IONO] > 0:
            corr += ifac * klobuchar(lat, lon, az, el, t_gps, alpha, beta)
            i_mode = 1
        if not np.isnan(row[o + 8]):
            corr += row[o + 8]
            i_mode = 2
        i_delay = corr
        if par[E_TROPO] > 0:
            corr += tropo_delay(lat, hh, el, par[E_HUMID])
        s_el = np.sin(max(el, 0.035))
        mfac = (0.5 + 0.5 / (s_el * s_el)) * sfac * sfac
        if use_code:
            _row(h, en, Hp, nn, ib)
            pred = rho + nav.bias[bi]
            if isb >= 0 and not np.isnan(row[o + 11]):
                ik = isb + int(row[o + 11])
                h[ik] = 1.0
                pred += nav.bias[ik - NAV]
            if ir >= 0 and not np.isnan(row[o + 10]):
                iu = ir + int(row[o + 10])
                h[iu] = range_error_sigma(el, row[o + 9], i_mode, i_delay, par[E_TROPO] > 0)
                pred += h[iu] * nav.bias[iu - NAV]
            ok, nu, s = update_scalar_ws(x, P, h, par[E_SIG_CODE] ** 2 * mfac, row[o + 6] - corr - pred, gate,
                                         uw)
            grp.sat[S_PR_NU, g, j], grp.sat[S_PR_S, g, j] = nu, s
            grp.cnt[g, C_PR] += ok
            nrej += not ok
        if par[E_RATE] > 0 and not np.isnan(row[o + 7]):
            rr = geo_range_rate(row[o:o + 3], row[o + 3:o + 6], ra, va, e)
            _row(h, en, Hv, nn, ib + 1)
            ok, nu, s = update_scalar_ws(x, P, h, par[E_SIG_RATE] ** 2 * mfac,
                                         row[o + 7] - (rr + nav.bias[bi + 1]), gate, uw)
            grp.sat[S_RATE_NU, g, j], grp.sat[S_RATE_S, g, j] = nu, s
            grp.cnt[g, C_RATE] += ok
            nrej += not ok
        if tdcp and not np.isnan(row[o + E_PHASE]):
            z = tdcp_row(nav, row, o, lay, ra, Cen, Hp, h)
            ok, nu, s = update_scalar_ws(x, P, h, 2.0 * par[E_SIG_PHASE] ** 2 * mfac, z, gate, uw)
            grp.cnt[g, C_TD] += ok
            grp.cnt[g, C_TDREJ] += not ok
    grp.cnt[g, C_REJ] = nrej
    if lay[L_TDCP] >= 0:
        clone_epoch(x, P, nav, lay, ra, Cen, Hp)
        grp.flags[2] = g + 1
    return not (nrej > 0 and grp.cnt[g, C_PR] == 0)


@njit(cache=True)
def _clone_of_previous(row, lay, grp, t_gps):
    """True when the clone states hold the epoch the row's phase increments start at (its receive time
    ``Δt`` before this one, to 1 ms: an epoch not processed or a clock jump in between fail it)."""
    if lay[L_TDCP] < 0 or grp.flags[2] == 0:
        return False
    for o in range(0, row.shape[0], E_W):
        if not np.isnan(row[o + E_PHASE + 4]):
            return abs(t_gps - grp.t[grp.flags[2] - 1] - row[o + E_PHASE + 4]) < 1e-3
    return False


@njit(cache=True)
def tdcp_row(nav, row, o, lay, ra, Cen, Hp, h):
    """The time-differenced carrier-phase row of the satellite at offset ``o`` of ``row`` (module doc):
    fills h (n,) and returns z = y − ŷ. ``ra``: the INS antenna (ECEF) at the receive time, ``Cen`` ECEF →
    ENU, ``Hp`` its ENU position rows (:func:`_antenna`)."""
    ic, icl = lay[L_CLK], lay[L_TDCP]
    rho1, e1 = geo_range(row[o:o + 3], ra)
    rc = nav.bias[icl - NAV:icl - NAV + 3]
    rho0, e0 = geo_range(row[o + E_PHASE + 1:o + E_PHASE + 4], rc)
    en = Cen @ e1
    _row(h, en, Hp, lay[L_NINS], ic)
    for i in range(3):  # the antenna moved back along the velocity: its error too (Hp has dt_back 0)
        h[DV + i] -= en[i] * nav.dt_back
    h[ic + 1] = -nav.dt_back
    for i in range(3):
        h[icl + i] = e0[i]
    h[icl + 3] = -1.0
    b_k = nav.bias[ic - NAV] - nav.bias[ic - NAV + 1] * nav.dt_back
    return row[o + E_PHASE] - (rho1 - rho0 + b_k - nav.bias[icl + 3 - NAV])


@njit(cache=True)
def clone_epoch(x, P, nav, lay, ra, Cen, Hp):
    """The clone states := this epoch's antenna position, ECEF, and receive-time clock bias (true −
    estimated, c = A δx with A = [−Cᵉₙ H_pos; the clock row at the receive time]): estimate A x, covariance
    rows A P and A P Aᵀ, nominal values the INS antenna ``ra`` and b̂ − d̂·dt_back (the feedback adds the
    estimate to them, as to every calibration state)."""
    ic, icl, nn = lay[L_CLK], lay[L_TDCP], lay[L_NINS]
    n = P.shape[0]
    A = np.zeros((4, n))
    CH = Cen.T @ Hp
    for r in range(3):
        for c in range(min(nn, CH.shape[1])):  # the antenna depends on the first 15 INS states at most
            A[r, c] = -CH[r, c]
        for i in range(3):
            A[r, DV + i] += Cen[i, r] * nav.dt_back
    A[3, ic], A[3, ic + 1] = 1.0, -nav.dt_back
    AP = A @ P
    APA = AP @ A.T
    xc = A @ x
    for r in range(4):
        for c in range(n):
            P[icl + r, c] = AP[r, c]
            P[c, icl + r] = AP[r, c]
    for r in range(4):
        for c in range(4):
            P[icl + r, icl + c] = APA[r, c]
        x[icl + r] = xc[r]
    for i in range(3):
        nav.bias[icl - NAV + i] = ra[i]
    nav.bias[icl - NAV + 3] = nav.bias[ic - NAV] - nav.bias[ic - NAV + 1] * nav.dt_back


@njit(cache=True)
def epoch_record(grp, g, st, bias, P, lay):
    """Outputs of epoch g after its node's feedback (``grp.node[g]``): clock, strapdown state, P_nav."""
    nd = grp.node[g]
    nd[N_CLK] = bias[lay[L_CLK] - NAV]
    nd[N_CLK + 1] = bias[lay[L_CLK] - NAV + 1]
    for i in range(10):
        nd[N_STATE + i] = st[i]
    for i in range(9):
        for j in range(9):
            nd[N_PNAV + 9 * i + j] = P[i, j]


__all__ = ["E_W", "E_PHASE", "EpochOut", "EpochFields", "epoch_out", "epoch_fields", "epoch_update",
           "epoch_record", "tdcp_row", "clone_epoch"]
