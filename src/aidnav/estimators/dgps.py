"""Code-based GNSS positioning: single-point positioning (SPP) with a residual check, base/rover relative
positioning from pseudorange single differences (seed 001 eqs. 1–5, iterated per SPEC 2.2.2), and dead
reckoning of the relative position during outages (seed eqs. 6–7 with the frame rotation of SPEC 2.2.5).

Frames and units: ECEF e [m]; ENU n [m]; the relative position is in the ENU frame **of the base**
(n_B); angles [rad] inside, azimuth clockwise from North; clock terms in metres (c × seconds); times
GPS seconds on a reference-week scale (:mod:`aidnav.nav.gnss_sat`).

Measurement model (usual sign): P = ρ + c·dt_r − c·dt_s + I + T + ε, with the satellite clock dt_s
from the broadcast ephemeris (relativistic term, T_GD for L1 C/A). The seed writes
P = ρ + c(dt^j − dT) (receiver clock with the opposite sign), so its cΔT_BK = c(dT_B − dT_K) equals
**c(dt_rK − dt_rB)** here: the rover's minus the base's clock offset, in metres.

**Weighting** (both SPP and the relative solution): σ²(E) = σ0² (½ + ½/sin²E), i.e. σ0 at the zenith,
1.6 σ0 at 30°, 4.1 σ0 at 10° (the simulator's thermal noise follows the same law). A single difference
has variance σ_B² + σ_K².

**SPP** (:func:`spp`): Gauss-Newton on [x, y, z, c·dt_r] from the Earth's centre (or a given start),
Sagnac-corrected ranges, Klobuchar ionosphere (when coefficients are given) and Saastamoinen
troposphere once the position is known, elevation mask applied from the second iteration on.
**Residual check** (RAIM-like): T = vᵀWv of the post-fit residuals against the χ²(n−4) quantile at the
false-alarm probability ``p_fa``. With n − 4 ≥ 2 the satellite with the largest standardized residual
|v_i|/√((W⁻¹ − HQHᵀ)_ii) is flagged and excluded, and the check repeats; with n − 4 = 1 a fault is
detected but cannot be identified (all standardized residuals are equal); with n = 4 (zero redundancy)
the residuals are zero and nothing can be checked: ``status`` says so.

**Relative positioning** (:func:`relative_position`): ΔP_j = P_K^j − P_B^j over the common satellites,
unknowns ΔX = [Δx_E, Δx_N, Δx_U, cΔT_BK] in n_B; rows [−e_j^T, 1] with e_j the n_B unit vector from the
current rover estimate to satellite j; the residual is ΔP − (ρ̂_K − ρ̂_B + cΔT̂) with exact (Sagnac)
ranges, each receiver's satellite position at its own transmit time. ``iterate=False`` gives the seed's
single linearisation about the base (second-order error ≈ |Δx|²/(2ρ), SPEC 2.2.2). Optionally the
model difference of the tropospheric delays (heights differ on an approach: ≈ 0.3 m zenith per km) is
removed. The base position need only be roughly known: an error δp_B moves the result by about
|δp_B|·|Δx|/ρ (0.1 m for 100 m at 20 km).

**Dead reckoning** (:func:`dead_reckon`): Δx(t+T) = Δx(t) + C_e^{n_B} C_{n_K}^e v^{n_K}(t)·T (Euler, the
seed's eq. 7) or the trapezoid of successive velocities (``method="trapezoid"``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from aidnav.nav.earth import dcm_ecef_to_enu, ecef_to_lla, lla_to_ecef
from aidnav.nav.gnss_sat import (
    C_LIGHT,
    az_el,
    geo_range,
    geo_range_rate,
    klobuchar,
    sat_from_pseudorange,
    select_ephemeris,
    tropo_delay,
)

__all__ = [
    "elevation_sigma",
    "satellites_from_pseudoranges",
    "SppResult",
    "spp",
    "spp_velocity",
    "RelativeSolution",
    "relative_position",
    "range_az_el",
    "dead_reckon",
    "spp_series",
]

_ZERO4 = np.zeros(4)


@njit(cache=True)
def elevation_sigma(sigma0, el):
    """σ(E) = σ0 √(½ + ½/sin²E) [m] (E clamped at 2°)."""
    s = np.sin(max(el, 0.035))
    return sigma0 * np.sqrt(0.5 + 0.5 / (s * s))


@njit(cache=True)
def _satellites(eph_table, prns, t_rx, pr, use_tgd, max_age):
    s = prns.shape[0]
    pos = np.full((s, 3), np.nan)
    vel = np.full((s, 3), np.nan)
    clk = np.full(s, np.nan)
    clk_rate = np.full(s, np.nan)
    for j in range(s):
        if not np.isfinite(pr[j]):
            continue
        i = select_ephemeris(eph_table, prns[j], t_rx, max_age)
        if i < 0:
            continue
        p, v, dts, ddts = sat_from_pseudorange(eph_table[i], t_rx, pr[j], use_tgd)
        pos[j] = p
        vel[j] = v
        clk[j] = dts * C_LIGHT
        clk_rate[j] = ddts * C_LIGHT
    return pos, vel, clk, clk_rate


def satellites_from_pseudoranges(eph_table, prns, t_rx, pr, use_tgd: bool = True, max_age_s: float = 7200.0):
    """Satellite states at the transmit times implied by the pseudoranges of one epoch.

    eph_table : (K, N_EPH) ephemeris records (reference-week scale); prns (S,); t_rx receiver tag [s];
    pr (S,) [m] (NaN = no measurement). Returns (pos (S, 3) ECEF of transmit time [m], vel (S, 3) [m/s],
    clk (S,) c·dt_s [m], clk_rate (S,) c·ḋt_s [m/s]); NaN where no measurement or no ephemeris.
    """
    return _satellites(
        np.ascontiguousarray(eph_table, float),
        np.asarray(prns, np.int64),
        float(t_rx),
        np.asarray(pr, float),
        bool(use_tgd),
        float(max_age_s),
    )


@njit(cache=True)
def _wls(
    sat_pos, pr_corr, sigma0, x0, alpha, beta, use_iono, use_tropo, humidity, mask, t_sow, use, max_iter
):
    """Weighted Gauss-Newton SPP core. Returns (x, Q, v, el, az, sig, used, iters, ok)."""
    s = sat_pos.shape[0]
    x = x0.copy()
    v = np.full(s, np.nan)
    el = np.full(s, np.nan)
    az = np.full(s, np.nan)
    sig = np.full(s, np.nan)
    used = np.zeros(s, np.bool_)
    Q = np.full((4, 4), np.nan)
    iters = 0
    ok = False
    for it in range(max_iter):
        iters = it + 1
        known = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] > 1e12
        lat, lon, h = 0.0, 0.0, 0.0
        if known:
            lat, lon, h = ecef_to_lla(x[0], x[1], x[2])
        H = np.zeros((s, 4))
        w = np.zeros(s)
        n = 0
        for j in range(s):
            used[j] = False
            if not use[j] or not np.isfinite(pr_corr[j]) or not np.isfinite(sat_pos[j, 0]):
                continue
            r, e = geo_range(sat_pos[j], x[:3])
            corr = 0.0
            sj = sigma0
            if known:
                az[j], el[j], enu = az_el(e, lat, lon)
                if el[j] < mask:
                    continue
                if use_iono:
                    corr += klobuchar(lat, lon, az[j], el[j], t_sow, alpha, beta)
                if use_tropo:
                    corr += tropo_delay(lat, h, el[j], humidity)
                sj = elevation_sigma(sigma0, el[j])
            sig[j] = sj
            v[j] = pr_corr[j] - (r + x[3] + corr)
            H[j, 0], H[j, 1], H[j, 2], H[j, 3] = -e[0], -e[1], -e[2], 1.0
            w[j] = 1.0 / (sj * sj)
            used[j] = True
            n += 1
        if n < 4:
            return x, Q, v, el, az, sig, used, iters, False
        N = np.zeros((4, 4))
        b = np.zeros(4)
        for j in range(s):
            if used[j]:
                N += w[j] * np.outer(H[j], H[j])
                b += w[j] * H[j] * v[j]
        if np.linalg.cond(N) > 1e14:
            return x, Q, v, el, az, sig, used, iters, False
        Q = np.linalg.inv(N)
        dx = Q @ b
        x += dx
        if np.sqrt(dx[0] ** 2 + dx[1] ** 2 + dx[2] ** 2) < 1e-4 and known:
            ok = True
            break
    # post-fit residuals at the solution
    for j in range(s):
        if used[j]:
            r, e = geo_range(sat_pos[j], x[:3])
            lat, lon, h = ecef_to_lla(x[0], x[1], x[2])
            corr = 0.0
            if use_iono:
                corr += klobuchar(lat, lon, az[j], el[j], t_sow, alpha, beta)
            if use_tropo:
                corr += tropo_delay(lat, h, el[j], humidity)
            v[j] = pr_corr[j] - (r + x[3] + corr)
    return x, Q, v, el, az, sig, used, iters, ok


@dataclass
class SppResult:
    """One SPP epoch.

    ecef (3,) [m]; lat, lon [rad]; h [m]; clock_m : c·dt_r [m]; cov (4, 4) [m²] (σ0-scaled (HᵀWH)⁻¹,
    ECEF + clock); cov_enu (3, 3) [m²]; dop : {gdop, pdop, hdop, vdop, tdop, ...} (unweighted);
    residuals (S,) post-fit [m] (NaN for unused); elevation, azimuth (S,) [rad]; used (S,) bool;
    excluded : PRNs excluded by the residual check; test_stat, threshold : vᵀWv and its χ² limit (NaN
    without redundancy); status : "ok", "excluded", "fault detected, not identified",
    "no redundancy: unchecked", "too few satellites" or "no convergence".
    """

    ecef: np.ndarray
    lat: float
    lon: float
    h: float
    clock_m: float
    cov: np.ndarray
    cov_enu: np.ndarray
    dop: dict
    residuals: np.ndarray
    elevation: np.ndarray
    azimuth: np.ndarray
    used: np.ndarray
    excluded: list = field(default_factory=list)
    test_stat: float = float("nan")
    threshold: float = float("nan")
    status: str = "ok"
    iterations: int = 0

    @property
    def n_used(self) -> int:
        return int(self.used.sum())

    @property
    def valid(self) -> bool:
        return self.status not in ("too few satellites", "no convergence")


def _dop_from_geometry(el, az, used):
    from aidnav.nav.gnss_sat import dop

    u = np.column_stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])[used]
    return dop(u)


def spp(
    sat_pos,
    sat_clk,
    pr,
    prns=None,
    t_sow: float = 0.0,
    x0=None,
    sigma0: float = 1.0,
    iono_alpha=None,
    iono_beta=None,
    tropo: bool = True,
    humidity: float = 0.7,
    mask_deg: float = 10.0,
    p_fa: float = 1e-3,
    max_exclusions: int = 2,
    max_iter: int = 12,
    exclude=None,
) -> SppResult:
    """Single-point position of one epoch by iterated weighted least squares with a residual check.

    sat_pos (S, 3) satellite ECEF at transmit time [m] and sat_clk (S,) c·dt_s [m]
    (:func:`satellites_from_pseudoranges`); pr (S,) pseudoranges [m]; prns (S,) labels for ``excluded``;
    t_sow GPS time [s] (for Klobuchar); x0 (4,) start [m] (default: Earth's centre); sigma0 zenith code σ
    [m]; iono_alpha/beta Klobuchar coefficients (None: no ionospheric correction); tropo: Saastamoinen
    standard atmosphere; mask_deg elevation mask; p_fa false-alarm probability of the residual test;
    exclude (S,) bool of satellites not to use. Method in the module docstring.
    """
    from scipy.special import chdtri

    sat_pos = np.ascontiguousarray(sat_pos, float).reshape(-1, 3)
    s = len(sat_pos)
    prns = np.arange(s) if prns is None else np.asarray(prns)
    pr_corr = np.asarray(pr, float) + np.asarray(sat_clk, float)
    use = np.ones(s, np.bool_) if exclude is None else ~np.asarray(exclude, bool)
    use &= np.isfinite(pr_corr) & np.all(np.isfinite(sat_pos), axis=1)
    use_iono = iono_alpha is not None and iono_beta is not None
    alpha = np.asarray(iono_alpha if use_iono else _ZERO4, float)
    beta = np.asarray(iono_beta if use_iono else _ZERO4, float)
    start = np.zeros(4) if x0 is None else np.asarray(x0, float).copy()
    excluded: list = []
    status = "ok"
    while True:
        x, Q, v, el, az, sig, used, iters, ok = _wls(
            sat_pos,
            pr_corr,
            float(sigma0),
            start,
            alpha,
            beta,
            use_iono,
            bool(tropo),
            float(humidity),
            np.radians(mask_deg),
            float(t_sow),
            use,
            max_iter,
        )
        n = int(used.sum())
        if n < 4:
            status = "too few satellites"
            break
        if not ok:
            status = "no convergence"
            break
        dof = n - 4
        if dof == 0:
            status = "no redundancy: unchecked"
            T = thr = float("nan")
            break
        w = np.where(used, 1.0 / sig**2, 0.0)
        T = float(np.nansum(w * np.where(used, v, 0.0) ** 2))
        thr = float(chdtri(dof, p_fa))
        if T <= thr:
            status = "ok" if not excluded else "excluded"
            break
        if dof == 1 or len(excluded) >= max_exclusions:
            status = "fault detected, not identified" if dof == 1 else "fault detected, exclusions exhausted"
            break
        # standardized residuals
        lat, lon, _ = ecef_to_lla(x[0], x[1], x[2])
        idx = np.flatnonzero(used)
        H = np.zeros((len(idx), 4))
        for k, j in enumerate(idx):
            _, e = geo_range(sat_pos[j], x[:3])
            H[k] = [-e[0], -e[1], -e[2], 1.0]
        Qv = np.diag(sig[idx] ** 2) - H @ Q @ H.T
        zstd = np.abs(v[idx]) / np.sqrt(np.maximum(np.diag(Qv), 1e-12))
        worst = idx[int(np.argmax(zstd))]
        excluded.append(prns[worst].item() if hasattr(prns[worst], "item") else prns[worst])
        use[worst] = False
        start = x.copy()
    lat, lon, h = ecef_to_lla(x[0], x[1], x[2])
    cov_enu = np.full((3, 3), np.nan)
    if np.all(np.isfinite(Q)):
        C = dcm_ecef_to_enu(lat, lon)
        cov_enu = C @ Q[:3, :3] @ C.T
    d = _dop_from_geometry(el, az, used) if used.sum() >= 4 else _dop_from_geometry(el, az, used & False)
    res = SppResult(
        ecef=x[:3].copy(),
        lat=float(lat),
        lon=float(lon),
        h=float(h),
        clock_m=float(x[3]),
        cov=Q,
        cov_enu=cov_enu,
        dop=d,
        residuals=np.where(used, v, np.nan),
        elevation=el,
        azimuth=az,
        used=used,
        excluded=excluded,
        status=status,
        iterations=int(iters),
    )
    if status not in ("too few satellites", "no convergence", "no redundancy: unchecked"):
        res.test_stat, res.threshold = T, thr
    return res


def spp_velocity(sat_pos, sat_vel, sat_clk_rate, rate, rx_ecef, used=None, sigma: float = 0.1):
    """Receiver velocity from pseudorange rates (Doppler) by least squares.

    sat_pos, sat_vel (S, 3) [m, m/s] ECEF of transmit time; sat_clk_rate (S,) c·ḋt_s [m/s]; rate (S,)
    measured pseudorange rate −λD [m/s]; rx_ecef (3,) receiver position. Model:
    ρ̇_meas = e·(v_s − v_r) + Sagnac rate + c·ḋt_r − c·ḋt_s. Returns (v_ecef (3,), clock_drift c·ḋt_r [m/s],
    cov (4, 4), residuals (S,)); NaN with fewer than 4 usable satellites.
    """
    sat_pos = np.asarray(sat_pos, float)
    s = len(sat_pos)
    use = np.ones(s, bool) if used is None else np.asarray(used, bool).copy()
    use &= np.isfinite(rate) & np.all(np.isfinite(sat_pos), axis=1)
    rr = np.asarray(rx_ecef, float)
    x = np.zeros(4)
    nanres = (np.full(3, np.nan), float("nan"), np.full((4, 4), np.nan), np.full(s, np.nan))
    if use.sum() < 4:
        return nanres
    for _ in range(3):
        H = np.zeros((s, 4))
        v = np.full(s, np.nan)
        for j in np.flatnonzero(use):
            _, e = geo_range(sat_pos[j], rr)
            pred = geo_range_rate(sat_pos[j], sat_vel[j], rr, x[:3], e)
            v[j] = rate[j] + sat_clk_rate[j] - (pred + x[3])
            H[j] = [-e[0], -e[1], -e[2], 1.0]
        Hu = H[use]
        N = Hu.T @ Hu
        dx = np.linalg.solve(N, Hu.T @ v[use])
        x += dx
        if np.linalg.norm(dx) < 1e-6:
            break
    Q = np.linalg.inv(N) * sigma**2
    return x[:3], float(x[3]), Q, v


# ------------------------------------------------------------------------------- relative positioning
@dataclass
class RelativeSolution:
    """Rover relative to the base, one epoch.

    enu (3,) Δx in the base's ENU frame [m]; clock_m : cΔT_BK = c(dt_rK − dt_rB) [m]; cov (4, 4) [m²]
    σ-scaled (HᵀWH)⁻¹; range_m, azimuth, elevation [rad] of the rover from the base; residuals (S,) [m];
    used (S,) bool; iterations; dop (from the rows used); ok.
    """

    enu: np.ndarray
    clock_m: float
    cov: np.ndarray
    range_m: float
    azimuth: float
    elevation: float
    residuals: np.ndarray
    used: np.ndarray
    iterations: int
    dop: dict
    ok: bool


def range_az_el(enu):
    """Range [m], azimuth (clockwise from North, [0, 2π)) and elevation [rad] of ENU vector(s) (..., 3)."""
    d = np.asarray(enu, float)
    r = np.linalg.norm(d, axis=-1)
    az = np.mod(np.arctan2(d[..., 0], d[..., 1]), 2 * np.pi)
    el = np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1]))
    return r, az, el


def relative_position(
    base_ecef,
    sat_pos_b,
    pr_b,
    sat_pos_k,
    pr_k,
    sigma0: float = 1.0,
    iterate: bool = True,
    tropo_difference: bool = False,
    humidity: float = 0.7,
    mask_deg: float = 5.0,
    x0=None,
    max_iter: int = 20,
    tol_m: float = 1e-7,
    sigma0_base: float | None = None,
    weighting: str = "elevation",
) -> RelativeSolution:
    """Relative position of the rover in the base's ENU frame from pseudorange single differences.

    base_ecef (3,) the (roughly known) base position [m]; sat_pos_b, sat_pos_k (S, 3) satellite ECEF at
    the transmit times of the base's and the rover's signals (:func:`satellites_from_pseudoranges`);
    pr_b, pr_k (S,) pseudoranges [m] (satellite clocks need not be applied: they cancel; NaN = none).
    sigma0 : zenith σ of one pseudorange [m] (rover; ``sigma0_base`` for the base, default the same).
    iterate : Gauss-Newton to ``tol_m`` (else the seed's single linearisation about the base).
    tropo_difference : subtract the model difference T(rover) − T(base) (Saastamoinen, standard
    atmosphere at each height). x0 (4,) start [E, N, U, cΔT] (default 0: the base).
    weighting : "elevation" (σ² = σ_K²(E_K) + σ_B²(E_B)) or "equal" (σ² = sigma0², the seed's eq. 5).
    """
    pb = np.asarray(base_ecef, float)
    lat_b, lon_b, h_b = ecef_to_lla(pb[0], pb[1], pb[2])
    C = dcm_ecef_to_enu(lat_b, lon_b)  # C_e^{n_B}
    spb = np.asarray(sat_pos_b, float).reshape(-1, 3)
    spk = np.asarray(sat_pos_k, float).reshape(-1, 3)
    dp = np.asarray(pr_k, float) - np.asarray(pr_b, float)
    s = len(dp)
    sb0 = sigma0 if sigma0_base is None else sigma0_base
    ok_meas = np.isfinite(dp) & np.all(np.isfinite(spb), 1) & np.all(np.isfinite(spk), 1)
    rho_b = np.full(s, np.nan)
    el_b = np.full(s, np.nan)
    for j in np.flatnonzero(ok_meas):
        rho_b[j], e = geo_range(spb[j], pb)
        _, el_b[j], _ = az_el(e, lat_b, lon_b)
    use = ok_meas & (el_b >= np.radians(mask_deg))
    x = np.zeros(4) if x0 is None else np.asarray(x0, float).copy()
    n_it = 0
    Q = np.full((4, 4), np.nan)
    v = np.full(s, np.nan)
    ok = use.sum() >= 4
    tb = np.zeros(s)
    if tropo_difference:
        for j in np.flatnonzero(use):
            tb[j] = tropo_delay(lat_b, h_b, el_b[j], humidity)
    for it in range(max_iter if iterate else 1):
        if not ok:
            break
        n_it = it + 1
        pk = pb + C.T @ x[:3]
        lat_k, lon_k, h_k = ecef_to_lla(pk[0], pk[1], pk[2])
        H = np.zeros((s, 4))
        w = np.zeros(s)
        for j in np.flatnonzero(use):
            rk, e = geo_range(spk[j], pk)
            _, el_k, _ = az_el(e, lat_k, lon_k)
            corr = 0.0
            if tropo_difference:
                corr = tropo_delay(lat_k, h_k, el_k, humidity) - tb[j]
            v[j] = dp[j] - (rk - rho_b[j] + x[3] + corr)
            en = C @ e
            H[j] = [-en[0], -en[1], -en[2], 1.0]
            if weighting == "equal":
                w[j] = 1.0 / sigma0**2
            else:
                w[j] = 1.0 / (elevation_sigma(sigma0, el_k) ** 2 + elevation_sigma(sb0, el_b[j]) ** 2)
        Hu, wu = H[use], w[use]
        N = Hu.T @ (Hu * wu[:, None])
        if np.linalg.cond(N) > 1e14:
            ok = False
            break
        Q = np.linalg.inv(N)
        dx = Q @ (Hu.T @ (wu * v[use]))
        x += dx
        if np.linalg.norm(dx[:3]) < tol_m and abs(dx[3]) < tol_m:
            break
    if ok and iterate:  # post-fit residuals
        pk = pb + C.T @ x[:3]
        lat_k, lon_k, h_k = ecef_to_lla(pk[0], pk[1], pk[2])
        for j in np.flatnonzero(use):
            rk, e = geo_range(spk[j], pk)
            corr = 0.0
            if tropo_difference:
                _, el_k, _ = az_el(e, lat_k, lon_k)
                corr = tropo_delay(lat_k, h_k, el_k, humidity) - tb[j]
            v[j] = dp[j] - (rk - rho_b[j] + x[3] + corr)
    r, az, el = range_az_el(x[:3])
    from aidnav.nav.gnss_sat import dop

    d = dop(-np.asarray([H[j, :3] for j in np.flatnonzero(use)])) if ok else dop(np.zeros((0, 3)))
    return RelativeSolution(
        enu=x[:3].copy(),
        clock_m=float(x[3]),
        cov=Q,
        range_m=float(r),
        azimuth=float(az),
        elevation=float(el),
        residuals=np.where(use, v, np.nan),
        used=use,
        iterations=n_it,
        dop=d,
        ok=bool(ok),
    )


# ----------------------------------------------------------------------------------- dead reckoning
def dead_reckon(
    time,
    vel_enu_rover,
    lat_rover,
    lon_rover,
    base_lat,
    base_lon,
    dx0,
    rotate: bool = True,
    method: str = "euler",
):
    """Relative position of the rover in the base's ENU frame by integrating its velocity (seed eqs. 6–7).

    time (N,) [s]; vel_enu_rover (N, 3) rover velocity in its own ENU frame [m/s]; lat_rover, lon_rover
    (N,) [rad] (for C_{n_K}^e); base_lat, base_lon [rad]; dx0 (3,) relative position at time[0] [m].
    rotate : use v^{n_B} = C_e^{n_B} C_{n_K}^e v^{n_K} (SPEC 2.2.5; False = the seed's unrotated sum).
    method : "euler" (Δx_{k+1} = Δx_k + v_k T_k, the seed's eq. 7) or "trapezoid" (½(v_k + v_{k+1}) T_k).
    Returns (N, 3) relative ENU positions [m].
    """
    t = np.asarray(time, float)
    v = np.asarray(vel_enu_rover, float).reshape(-1, 3)
    if rotate:
        la, lo = np.asarray(lat_rover, float), np.asarray(lon_rover, float)
        sl, cl, so, co = np.sin(la), np.cos(la), np.sin(lo), np.cos(lo)
        # C_{n_K}^e v (columns of C_e^n transposed)
        ve = np.column_stack(
            [
                -so * v[:, 0] - sl * co * v[:, 1] + cl * co * v[:, 2],
                co * v[:, 0] - sl * so * v[:, 1] + cl * so * v[:, 2],
                cl * v[:, 1] + sl * v[:, 2],
            ]
        )
        v = ve @ dcm_ecef_to_enu(float(base_lat), float(base_lon)).T
    dt = np.diff(t)
    if method == "euler":
        inc = v[:-1] * dt[:, None]
    elif method == "trapezoid":
        inc = 0.5 * (v[:-1] + v[1:]) * dt[:, None]
    else:
        raise ValueError("method must be 'euler' or 'trapezoid'")
    out = np.empty_like(v)
    out[0] = dx0
    out[1:] = np.asarray(dx0, float) + np.cumsum(inc, axis=0)
    return out


# --------------------------------------------------------------------------------------- batch SPP
def spp_series(
    obs,
    eph,
    sigma0: float = 1.0,
    iono: str = "klobuchar",
    mask_deg: float = 10.0,
    p_fa: float = 1e-3,
    velocity: bool = True,
    iono_window_s: float = 60.0,
    x0=None,
):
    """SPP (and Doppler velocity) for every epoch of :class:`aidnav.io.rinex.GnssObservations`.

    iono : "klobuchar" (header coefficients; none when the file has none), "none", or "dual": L1
    delay from the geometry-free code combination I₁ = (P₂ − P₁)/(γ − 1), γ = (f₁/f₂)², averaged over a
    centred window of ``iono_window_s`` seconds per satellite (the combination's noise is ≈ 2.3× the code
    noise; the ionosphere changes little over a minute). Returns a dict of arrays: time, ecef (T, 3),
    lat, lon, h, clock_m, vel_enu (T, 3), clock_drift, n_used, status (list), pdop, excluded (list),
    residuals (T, S), events (list of str: satellites without ephemeris, exclusions, epochs without a fix).
    """
    from aidnav.nav.gnss_sat import dual_frequency_iono

    eph = eph.to_week(obs.ref_week) if eph.ref_week != obs.ref_week else eph
    T, S = obs.code1.shape
    pr_all = obs.code1.copy()
    if iono == "dual":
        if obs.code2 is None:
            raise ValueError("iono='dual' needs an L2 code in the observation file")
        i1s = dual_frequency_iono(obs.time, obs.code1, obs.code2, iono_window_s)
        pr_all = obs.code1 - i1s
    alpha = beta = None
    if iono == "klobuchar":
        alpha, beta = eph.iono_alpha, eph.iono_beta
    use_tgd = iono != "dual"
    rate_all = obs.range_rate()
    out = {
        k: np.full(T, np.nan) for k in ("lat", "lon", "h", "clock_m", "clock_drift", "pdop", "hdop", "vdop")
    }
    out["time"] = obs.time
    out["ecef"] = np.full((T, 3), np.nan)
    out["vel_enu"] = np.full((T, 3), np.nan)
    out["n_used"] = np.zeros(T, int)
    out["status"] = []
    out["excluded"] = []
    out["residuals"] = np.full((T, S), np.nan)
    xprev = None if x0 is None else np.asarray(x0, float)
    no_eph = np.zeros(S, int)
    for k in range(T):
        pos, vel, clk, clk_rate = satellites_from_pseudoranges(
            eph.table, obs.prn, obs.time[k], pr_all[k], use_tgd=use_tgd
        )
        no_eph += np.isfinite(pr_all[k]) & ~np.all(np.isfinite(pos), axis=1)
        r = spp(
            pos,
            clk,
            pr_all[k],
            prns=obs.prn,
            t_sow=obs.time[k],
            x0=xprev,
            sigma0=sigma0,
            iono_alpha=alpha,
            iono_beta=beta,
            mask_deg=mask_deg,
            p_fa=p_fa,
        )
        out["status"].append(r.status)
        out["excluded"].append(r.excluded)
        if not r.valid:
            continue
        xprev = np.r_[r.ecef, r.clock_m]
        out["ecef"][k] = r.ecef
        out["lat"][k], out["lon"][k], out["h"][k], out["clock_m"][k] = r.lat, r.lon, r.h, r.clock_m
        out["n_used"][k] = r.n_used
        out["pdop"][k], out["hdop"][k], out["vdop"][k] = r.dop["pdop"], r.dop["hdop"], r.dop["vdop"]
        out["residuals"][k] = r.residuals
        if velocity:
            ve, drift, _, _ = spp_velocity(pos, vel, clk_rate, rate_all[k], r.ecef, used=r.used)
            if np.all(np.isfinite(ve)):
                out["vel_enu"][k] = dcm_ecef_to_enu(r.lat, r.lon) @ ve
                out["clock_drift"][k] = drift
    events = []
    for j in np.flatnonzero(no_eph):
        events.append(
            f"G{int(obs.prn[j]):02d}: {no_eph[j]} epoch(s) with a pseudorange but no usable ephemeris; "
            "skipped"
        )
    excl = [p for ex in out["excluded"] for p in ex]
    for p in sorted(set(excl), key=int):
        events.append(f"G{int(p):02d}: excluded by the residual check at {excl.count(p)} epoch(s)")
    n_bad = sum(st in ("too few satellites", "no convergence") for st in out["status"])
    if n_bad:
        events.append(f"{n_bad} epoch(s) without a solution (too few satellites or no convergence)")
    out["events"] = events
    return out


def lla_ecef(lat, lon, h) -> np.ndarray:
    """(lat, lon [rad], h [m]) → ECEF (3,) or (N, 3) [m]."""
    x, y, z = lla_to_ecef(np.asarray(lat, float), np.asarray(lon, float), np.asarray(h, float))
    return np.stack([x, y, z], -1)
