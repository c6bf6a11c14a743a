"""Single-point positioning (SPP) with a residual check, Doppler velocity and the per-epoch series used by
the tight filter's start and course (seed 001 and the walk data set).

Frames and units: ECEF [m]; angles [rad]; clock terms in metres (c × seconds); GPS seconds on a
reference-week scale (:mod:`aidnav.nav.gnss_sat`). Measurement model P = ρ + c·dt_r − c·dt_s + I + T + ε
with the satellite clock from the broadcast ephemeris; weights σ²(E) = σ0² (½ + ½/sin²E)
(:func:`aidnav.nav.gnss_sat.elevation_sigma`).

**SPP** (:func:`spp`): Gauss-Newton on [x, y, z, c·dt_r] from the Earth's centre (or a given start),
Sagnac-corrected ranges, Klobuchar ionosphere (when coefficients are given) and Saastamoinen
troposphere once the position is known, elevation mask applied from the second iteration on.
**Residual check** (RAIM-like): T = vᵀWv of the post-fit residuals against the χ²(n−4) quantile at the
false-alarm probability ``p_fa``. With n − 4 ≥ 2 the satellite with the largest standardized residual
|v_i|/√((W⁻¹ − HQHᵀ)_ii) is flagged and excluded, and the check repeats; with n − 4 = 1 a fault is
detected but cannot be identified (all standardized residuals are equal); with n = 4 (zero redundancy)
the residuals are zero and nothing can be checked: ``status`` says so.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass, field

import numpy as np

from aidnav.filters.chi2 import chi2_isf
from aidnav.jit import njit
from aidnav.nav.earth import dcm_ecef_to_enu, ecef_to_lla, lla_to_ecef
from aidnav.nav.gnss_sat import (
    FREQ_L1,
    SYS_GPS,
    SYS_SBS,
    SYSTEM_SIGMA_FACTOR,
    SYSTEMS,
    az_el,
    carrier_frequencies,
    dop,
    dual_frequency_iono,
    elevation_sigma,
    geo_range,
    geo_range_rate,
    iono_fallback_note,
    klobuchar,
    klobuchar_coefficients,
    sat_name,
    satellites_from_pseudoranges,
    tropo_delay,
)

__all__ = ["SppResult", "spp", "spp_velocity", "spp_series", "lla_ecef"]

_ZERO4 = np.zeros(4)
# settings of the atmospheric corrections and the mask of :func:`_wls`: Klobuchar α, β (4,), use_iono,
# use_tropo, humidity [0-1], elevation mask [rad], GPS time of week [s]
Atmosphere = namedtuple("Atmosphere", ["alpha", "beta", "use_iono", "use_tropo", "humidity", "mask", "t_sow"])


@njit(cache=True)
def _wls(sat_pos, pr_corr, sigma0, x0, atm, use, max_iter, col, ifac, sfac):
    """Weighted Gauss-Newton SPP core; ``atm``: :data:`Atmosphere` settings; ``col`` (S,) the state column
    of each satellite's clock (3: the reference clock, 4 + k: reference + inter-system bias k), ``ifac``
    (S,) the Klobuchar scale (f_L1/f)², ``sfac`` (S,) the σ factor of its system. Returns (x, Q, v, el, az,
    sig, used, iters, ok)."""
    alpha, beta, use_iono, use_tropo, humidity, mask, t_sow = atm
    s = sat_pos.shape[0]
    nx = x0.shape[0]
    x = x0.copy()
    v = np.full(s, np.nan)
    el = np.full(s, np.nan)
    az = np.full(s, np.nan)
    sig = np.full(s, np.nan)
    used = np.zeros(s, np.bool_)
    Q = np.full((nx, nx), np.nan)
    iters = 0
    ok = False
    for it in range(max_iter):
        iters = it + 1
        known = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] > 1e12
        lat, lon, h = 0.0, 0.0, 0.0
        if known:
            lat, lon, h = ecef_to_lla(x[0], x[1], x[2])
        H = np.zeros((s, nx))
        w = np.zeros(s)
        n = 0
        for j in range(s):
            used[j] = False
            if not use[j] or not np.isfinite(pr_corr[j]) or not np.isfinite(sat_pos[j, 0]):
                continue
            r, e = geo_range(sat_pos[j], x[:3])
            corr = 0.0
            sj = sigma0 * sfac[j]
            if known:
                az[j], el[j], enu = az_el(e, lat, lon)
                if el[j] < mask:
                    continue
                if use_iono:
                    corr += ifac[j] * klobuchar(lat, lon, az[j], el[j], t_sow, alpha, beta)
                if use_tropo:
                    corr += tropo_delay(lat, h, el[j], humidity)
                sj = elevation_sigma(sigma0 * sfac[j], el[j])
            sig[j] = sj
            clk = x[3] + (x[col[j]] if col[j] > 3 else 0.0)
            v[j] = pr_corr[j] - (r + clk + corr)
            H[j, 0], H[j, 1], H[j, 2], H[j, 3] = -e[0], -e[1], -e[2], 1.0
            if col[j] > 3:
                H[j, col[j]] = 1.0
            w[j] = 1.0 / (sj * sj)
            used[j] = True
            n += 1
        if n < nx:
            return x, Q, v, el, az, sig, used, iters, False
        N = np.zeros((nx, nx))
        b = np.zeros(nx)
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
                corr += ifac[j] * klobuchar(lat, lon, az[j], el[j], t_sow, alpha, beta)
            if use_tropo:
                corr += tropo_delay(lat, h, el[j], humidity)
            v[j] = pr_corr[j] - (r + x[3] + (x[col[j]] if col[j] > 3 else 0.0) + corr)
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
    reference_system: str = "G"  # the system whose receiver clock ``clock_m`` is
    isb_m: dict = field(default_factory=dict)  # inter-system biases [m]: {letter: clock − reference clock}
    isb_std_m: dict = field(default_factory=dict)

    @property
    def n_used(self) -> int:
        return int(self.used.sum())

    @property
    def valid(self) -> bool:
        return self.status not in ("too few satellites", "no convergence")


def _dop_from_geometry(el, az, used):
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
    freq=None,
) -> SppResult:
    """Single-point position of one epoch by iterated weighted least squares with a residual check.

    sat_pos (S, 3) satellite ECEF at transmit time [m] and sat_clk (S,) c·dt_s [m]
    (:func:`satellites_from_pseudoranges`); pr (S,) pseudoranges [m]; prns (S,) labels for ``excluded``;
    t_sow GPS time [s] (for Klobuchar); x0 (4,) start [m] (default: Earth's centre); sigma0 zenith code σ
    [m]; iono_alpha/beta Klobuchar coefficients (None: no ionospheric correction); tropo: Saastamoinen
    standard atmosphere; mask_deg elevation mask; p_fa false-alarm probability of the residual test;
    exclude (S,) bool of satellites not to use. Method in the module docstring.

    Several systems (``prns`` are satellite ids, :mod:`aidnav.nav.gnss_sat`): the first system present in
    the order G, E, C, R is the reference (``clock_m``), every other one adds an inter-system bias unknown
    (``isb_m``: its receiver clock − the reference one), its Klobuchar delay is scaled by (f_L1/f)² and its
    σ0 by :data:`aidnav.nav.gnss_sat.SYSTEM_SIGMA_FACTOR`; a solution needs 3 + (number of systems)
    satellites. ``freq`` (S,) [Hz] overrides the signal frequencies of the ids (GLONASS channels).
    """
    sat_pos = np.ascontiguousarray(sat_pos, float).reshape(-1, 3)
    s = len(sat_pos)
    prns = np.arange(s) if prns is None else np.asarray(prns)
    pr_corr = np.asarray(pr, float) + np.asarray(sat_clk, float)
    use = np.ones(s, np.bool_) if exclude is None else ~np.asarray(exclude, bool)
    use &= np.isfinite(pr_corr) & np.all(np.isfinite(sat_pos), axis=1)
    use_iono = iono_alpha is not None and iono_beta is not None
    alpha = np.asarray(iono_alpha if use_iono else _ZERO4, float)
    beta = np.asarray(iono_beta if use_iono else _ZERO4, float)
    sfac, sysn, ifac = _signals(prns, s, freq)
    x0 = np.zeros(4) if x0 is None else np.asarray(x0, float)
    excluded: list = []
    status = "ok"
    T = thr = float("nan")
    while True:
        present, ref, others, col, start = _clock_columns(use, sysn, x0)
        x, Q, v, el, az, sig, used, iters, ok = _wls(
            sat_pos,
            pr_corr,
            float(sigma0),
            start,
            Atmosphere(alpha, beta, use_iono, bool(tropo), float(humidity), np.radians(mask_deg),
                       float(t_sow)),
            use,
            max_iter,
            col,
            ifac,
            sfac,
        )
        gone = [k for k in present if not (used & (sysn == k)).any()]
        if gone and len(gone) < len(present):  # a system with every satellite below the mask: without it
            use &= ~np.isin(sysn, gone)
            continue
        nx = 4 + len(others)
        n = int(used.sum())
        if n < nx:
            status = "too few satellites"
            break
        if not ok:
            status = "no convergence"
            break
        dof = n - nx
        if dof == 0:
            status = "no redundancy: unchecked"
            T = thr = float("nan")
            break
        w = np.where(used, 1.0 / sig**2, 0.0)
        T = float(np.nansum(w * np.where(used, v, 0.0) ** 2))
        thr = float(chi2_isf(dof, p_fa))
        if T <= thr:
            status = "ok" if not excluded else "excluded"
            break
        if dof == 1 or len(excluded) >= max_exclusions:
            status = "fault detected, not identified" if dof == 1 else "fault detected, exclusions exhausted"
            break
        worst = _worst_satellite(sat_pos, x, Q, v, sig, used, col, nx)
        excluded.append(prns[worst].item() if hasattr(prns[worst], "item") else prns[worst])
        use[worst] = False
        x0 = x[:4].copy()
    res = _spp_result(x, Q, v, el, az, used, excluded, status, int(iters), ref, others)
    if status not in ("too few satellites", "no convergence", "no redundancy: unchecked"):
        res.test_stat, res.threshold = T, thr
    return res


def _signals(prns, s: int, freq):
    """Per satellite: the σ0 factor of its system, its clock's system (SBAS ranges on the GPS clock) and
    its Klobuchar scale (f_L1/f)² (1 where the frequency is unknown)."""
    ids = np.asarray(prns, np.int64) if np.issubdtype(np.asarray(prns).dtype, np.integer) else np.arange(s)
    sfac = np.array([SYSTEM_SIGMA_FACTOR[SYSTEMS[k]] for k in ids // 100])
    sysn = np.where(ids // 100 == SYS_SBS, SYS_GPS, ids // 100)  # SBAS ranges on the GPS clock
    f = carrier_frequencies(ids) if freq is None else np.asarray(freq, float)
    ifac = np.where(np.isfinite(f), (FREQ_L1 / f) ** 2, 1.0)
    return sfac, sysn, ifac


def _clock_columns(use, sysn, x0):
    """The systems present among the used satellites, the reference one (the first), the others (one
    inter-system bias unknown each), each satellite's clock column and the start state."""
    present = [k for k in range(len(SYSTEMS)) if (use & (sysn == k)).any()]
    ref = present[0] if present else 0
    others = present[1:]
    col = np.array([3 if k == ref or k not in others else 4 + others.index(k) for k in sysn], np.int64)
    start = np.zeros(4 + len(others))
    start[:min(4, len(x0))] = x0[:4]
    return present, ref, others, col, start


def _worst_satellite(sat_pos, x, Q, v, sig, used, col, nx: int) -> int:
    """Index of the used satellite with the largest standardized residual |v| / σ_v."""
    idx = np.flatnonzero(used)
    H = np.zeros((len(idx), nx))
    for k, j in enumerate(idx):
        _, e = geo_range(sat_pos[j], x[:3])
        H[k, :4] = [-e[0], -e[1], -e[2], 1.0]
        if col[j] > 3:
            H[k, col[j]] = 1.0
    Qv = np.diag(sig[idx] ** 2) - H @ Q @ H.T
    zstd = np.abs(v[idx]) / np.sqrt(np.maximum(np.diag(Qv), 1e-12))
    return idx[int(np.argmax(zstd))]


def _spp_result(x, Q, v, el, az, used, excluded, status, iters, ref, others) -> SppResult:
    """The :class:`SppResult` of the last solution (geodetic position, ENU covariance, DOP)."""
    lat, lon, h = ecef_to_lla(x[0], x[1], x[2])
    cov_enu = np.full((3, 3), np.nan)
    if np.all(np.isfinite(Q)):
        C = dcm_ecef_to_enu(lat, lon)
        cov_enu = C @ Q[:3, :3] @ C.T
    geo_ok = used.sum() >= 4 and np.all(np.isfinite(el[used]))
    d = _dop_from_geometry(el, az, used if geo_ok else used & False)
    res = SppResult(
        ecef=x[:3].copy(),
        lat=float(lat),
        lon=float(lon),
        h=float(h),
        clock_m=float(x[3]),
        cov=Q[:4, :4],
        cov_enu=cov_enu,
        dop=d,
        residuals=np.where(used, v, np.nan),
        elevation=el,
        azimuth=az,
        used=used,
        excluded=excluded,
        status=status,
        iterations=iters,
        reference_system=SYSTEMS[ref],
        isb_m={SYSTEMS[k]: float(x[4 + i]) for i, k in enumerate(others)},
        isb_std_m={SYSTEMS[k]: float(np.sqrt(Q[4 + i, 4 + i])) for i, k in enumerate(others)},
    )
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

    iono : "klobuchar" (header coefficients; RTKLIB's default ones when the file has none), "none",
    or "dual": L1 delay from the geometry-free code combination I₁ = (P₂ − P₁)/(γ − 1), γ = (f₁/f₂)²,
    averaged over a
    centred window of ``iono_window_s`` seconds per satellite (the combination's noise is ≈ 2.3× the code
    noise; the ionosphere changes little over a minute). Returns a dict of arrays: time, ecef (T, 3),
    lat, lon, h, clock_m (the clock of ``reference_system`` (T,): the first system of G, E, C, R with
    satellites), isb_m ({letter: (T,)} inter-system biases [m] to it), vel_enu (T, 3), clock_drift, n_used,
    status (list), pdop, excluded (list),
    residuals (T, S), events (list of str: satellites without ephemeris, exclusions, epochs without a fix).
    """
    eph = eph.to_week(obs.ref_week) if eph.ref_week != obs.ref_week else eph
    obs = obs.with_frequencies(eph)  # GLONASS channels from the records
    T, S = obs.code1.shape
    pr_all = obs.code1.copy()
    if iono == "dual":
        if obs.code2 is None:
            raise ValueError("iono='dual' needs an L2 code in the observation file")
        i1s = dual_frequency_iono(obs.time, obs.code1, obs.code2, iono_window_s)
        pr_all = obs.code1 - i1s
    alpha = beta = None
    iono_events = []
    if iono == "klobuchar":
        # no coefficients in the file: RTKLIB's defaults (σ 50 % of the delay), as rtkcmn.c ionmodel does
        alpha, beta, src = klobuchar_coefficients(eph.iono_alpha, eph.iono_beta)
        if src == "default":
            iono_events.append(iono_fallback_note())
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
    out["isb_m"] = {}
    out["reference_system"] = np.full(T, "", dtype="<U1")
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
            freq=obs.freq1,
        )
        out["status"].append(r.status)
        out["excluded"].append(r.excluded)
        if not r.valid:
            continue
        xprev = np.r_[r.ecef, r.clock_m]
        for c, v in r.isb_m.items():  # relative to the epoch's reference system (GPS when it has satellites)
            out["isb_m"].setdefault(c, np.full(T, np.nan))[k] = v
        out["reference_system"][k] = r.reference_system
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
    events = iono_events
    for j in np.flatnonzero(no_eph):
        events.append(
            f"{sat_name(obs.prn[j])}: {no_eph[j]} epoch(s) with a pseudorange but no usable ephemeris; "
            "skipped"
        )
    excl = [p for ex in out["excluded"] for p in ex]
    for p in sorted(set(excl), key=int):
        events.append(f"{sat_name(p)}: excluded by the residual check at {excl.count(p)} epoch(s)")
    n_bad = sum(st in ("too few satellites", "no convergence") for st in out["status"])
    if n_bad:
        events.append(f"{n_bad} epoch(s) without a solution (too few satellites or no convergence)")
    out["events"] = events
    return out


def lla_ecef(lat, lon, h) -> np.ndarray:
    """(lat, lon [rad], h [m]) → ECEF (3,) or (N, 3) [m]."""
    x, y, z = lla_to_ecef(np.asarray(lat, float), np.asarray(lon, float), np.asarray(h, float))
    return np.stack([x, y, z], -1)
