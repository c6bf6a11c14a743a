"""A whole GNSS epoch of pseudoranges and rates as one record (tight coupling), for the engine.

Row of an epoch (``S`` satellites × ``E_W`` values): per satellite r_s ECEF (3) [m], v_s ECEF (3)
[m/s], ρ + c·dt_s [m] (NaN: no pseudorange or no ephemeris), ρ̇ + c·ḋt_s [m/s] (NaN: no rate), the
dual-frequency ionospheric delay [m] (NaN: none), the ephemeris' URA [m], the satellite's slot in the
range-error states (NaN: none), its system's slot in the inter-system bias states (NaN: the GPS clock
itself), the Klobuchar scale (f_L1/f)² of its signal (NaN: 1) and the σ factor of its system (NaN: 1).
Parameters (``E_*``): lever arm, mask, zenith σ's,
atmosphere switches, Klobuchar α β, the clock-jump threshold and the clock σ's.

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
  and no pseudorange accepted.

Rows: z_ρ = (ρ_meas − I − T) − (|r_s − r_a| + Sagnac + b̂), H = [e^nᵀ H_pos, 1 (δt_u)];
z_ρ̇ = ρ̇_meas − (e·(v_s − v_a) + Sagnac rate + d̂), H = [e^nᵀ H_vel, 1 (δf)] (H_pos, H_vel: the antenna
rows of :func:`.gnss.gnss_position` / :func:`.gnss.gnss_velocity`; e^n: ENU unit vector to the satellite).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from aidnav.jit import njit
from aidnav.nav.earth import dcm_ecef_to_enu, lla_to_ecef
from aidnav.nav.gnss_sat import az_el, geo_range, geo_range_rate, klobuchar, range_error_sigma, tropo_delay

from ..kalman import update_scalar
from ..layout import L_CLK, L_ISB, L_RERR, NAV, ST_VEL
from .common import W_IB, W_IN
from .gnss import gnss_position, gnss_velocity

E_W = 14  # values per satellite in a row
E_LEVER, E_MASK, E_SIG_CODE, E_SIG_RATE, E_IONO, E_TROPO, E_HUMID, E_RATE = 0, 3, 4, 5, 6, 7, 8, 9
E_JUMP, E_SIG_B, E_SIG_D, E_CODE_MIN, E_ALPHA, E_BETA, E_NPAR = 10, 11, 12, 13, 14, 18, 22
# per-epoch outputs (filled in place): GPS receive time, satellites above the mask, pseudoranges and
# rates used, rows rejected, (M, S) innovations / their variance / elevation, after the epoch's node:
# 9×9 navigation covariance, clock (b̂, d̂), strapdown state; flags [clock initialised, jumps]
EpochOut = namedtuple("EpochOut", ["t", "navail", "npr", "nrate", "nrej", "pr_nu", "pr_s", "rate_nu",
                                   "rate_s", "el", "P_nav", "clk", "state", "flags"])


def epoch_out(M: int, S: int) -> EpochOut:
    """Empty per-epoch outputs for M epochs of S satellites (M = 0: no epoch records)."""
    nan2 = [np.full((M, S), np.nan) for _ in range(5)]
    z = [np.zeros(M, np.int64) for _ in range(4)]
    return EpochOut(np.full(M, np.nan), *z, *nan2, np.zeros((M, 9, 9)), np.full((M, 2), np.nan),
                    np.zeros((M, 10)), np.zeros(2, np.int64))


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
def _clock_start(P, nav, row, par, lay, grp, ra, va):
    """Clock start / jump from the median pseudorange (and at the start rate) residuals."""
    S = row.shape[0] // E_W
    res, res_r = np.full(S, np.nan), np.full(S, np.nan)
    for j in range(S):
        o = j * E_W
        if np.isnan(row[o + 6]) or np.isnan(row[o]):
            continue
        rho, e = geo_range(row[o:o + 3], ra)
        res[j] = row[o + 6] - rho
        if lay[L_ISB] >= 0 and not np.isnan(row[o + 11]):
            res[j] -= nav.bias[lay[L_ISB] + int(row[o + 11]) - NAV]
        if not np.isnan(row[o + 7]):
            res_r[j] = row[o + 7] - geo_range_rate(row[o:o + 3], row[o + 3:o + 6], ra, va, e)
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
    _clock_start(P, nav, row, par, lay, grp, ra, va)
    lat, lon, hh = nav.st[0], nav.st[1], nav.st[2]
    alpha, beta = par[E_ALPHA:E_ALPHA + 4].copy(), par[E_BETA:E_BETA + 4].copy()
    n_vis = 0
    for j in range(S):
        o = j * E_W
        if not (np.isnan(row[o + 6]) or np.isnan(row[o])):
            _, e = geo_range(row[o:o + 3], ra)
            if az_el(e, lat, lon)[1] >= par[E_MASK]:
                n_vis += 1
    use_code = n_vis >= par[E_CODE_MIN]
    ir, isb = lay[L_RERR], lay[L_ISB]
    h = np.zeros(n)
    nrej = 0
    for j in range(S):
        o = j * E_W
        if np.isnan(row[o + 6]) or np.isnan(row[o]):
            continue
        rho, e = geo_range(row[o:o + 3], ra)
        en = Cen @ e
        az, el, _ = az_el(e, lat, lon)
        grp.el[g, j] = el
        if el < par[E_MASK]:
            continue
        grp.navail[g] += 1
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
            ok, nu, s = update_scalar(x, P, h, par[E_SIG_CODE] ** 2 * mfac, row[o + 6] - corr - pred, gate)
            grp.pr_nu[g, j], grp.pr_s[g, j] = nu, s
            grp.npr[g] += ok
            nrej += not ok
        if par[E_RATE] > 0 and not np.isnan(row[o + 7]):
            rr = geo_range_rate(row[o:o + 3], row[o + 3:o + 6], ra, va, e)
            _row(h, en, Hv, nn, ib + 1)
            ok, nu, s = update_scalar(x, P, h, par[E_SIG_RATE] ** 2 * mfac,
                                      row[o + 7] - (rr + nav.bias[bi + 1]), gate)
            grp.rate_nu[g, j], grp.rate_s[g, j] = nu, s
            grp.nrate[g] += ok
            nrej += not ok
    grp.nrej[g] = nrej
    return not (nrej > 0 and grp.npr[g] == 0)


@njit(cache=True)
def epoch_record(grp, g, st, bias, P, lay):
    """Outputs of epoch g after its node's feedback: P_nav, clock, strapdown state."""
    grp.P_nav[g] = P[:9, :9]
    grp.clk[g, 0] = bias[lay[L_CLK] - NAV]
    grp.clk[g, 1] = bias[lay[L_CLK] - NAV + 1]
    grp.state[g] = st


__all__ = ["E_W", "EpochOut", "epoch_out", "epoch_update", "epoch_record"]
