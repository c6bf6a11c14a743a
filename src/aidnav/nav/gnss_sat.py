"""GPS satellite orbits, clocks and signal-path models (numba): broadcast ephemeris, Sagnac, DOP,
Klobuchar ionosphere, Saastamoinen troposphere.

Frames and units: e = ECEF WGS-84 [m, m/s]; n = ENU of the receiver; angles [rad]; times are GPS
seconds counted from the start of a *reference week* (the week of the data's first epoch, so that a
log crossing a week end stays increasing): ``t = (week − ref_week)·604800 + sow``.

Ephemeris records are rows of a float64 array (column indices ``E_*`` below), so that kernels can
take a whole table: broadcast ephemerides from RINEX (:mod:`aidnav.io.rinex`) and the Keplerian
almanac-like orbits of the simulated constellation (:mod:`aidnav.sim.gnss_constellation`, the same
format with zero harmonic terms) go through the same code.

Satellite state (:func:`eph_state`, IS-GPS-200 Table 20-IV, with the analytic time derivative):
position and velocity in the ECEF frame *of the transmit time* (not rotated), satellite clock offset
dt_s = a_f0 + a_f1 Δt + a_f2 Δt² + Δt_r with the relativistic term Δt_r = F e √A sin E_k
(F = −4.442807633e-10 s/√m), and its rate. The group delay T_GD is **not** applied here (L1 C/A users
subtract it: :func:`sat_from_pseudorange` does when asked).

Signal path (:func:`geo_range`): the range from a satellite position at transmit time (ECEF of transmit
time) to a receiver at receive time (ECEF of receive time) is |r_s − r_r| + ω_e (x_s y_r − y_s x_r)/c,
the first-order Sagnac (Earth-rotation) correction (≤ 30 m; the neglected second order is < 1 mm);
its rate adds ω_e/c (v_sy x_r + y_s v_rx − v_sx y_r − x_s v_ry) to e·(v_s − v_r).
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.units import DEG

from .earth import OMEGA_IE, ecef_to_lla

C_LIGHT = 299792458.0  #: speed of light [m/s]
GM_GPS = 3.986005e14  #: GPS value of the Earth's gravitational constant (IS-GPS-200) [m^3/s^2]
OMEGA_E_GPS = 7.2921151467e-5  #: Earth rotation rate of IS-GPS-200 [rad/s] (= OMEGA_IE)
F_REL = -4.442807633e-10  #: relativistic clock constant F = −2√μ/c² [s/√m]
FREQ_L1 = 1575.42e6  #: GPS L1 [Hz]
FREQ_L2 = 1227.60e6  #: GPS L2 [Hz]
LAMBDA_L1 = C_LIGHT / FREQ_L1  #: L1 wavelength [m]
PI_GPS = 3.1415926535898  #: π as IS-GPS-200 defines it (semicircles ↔ rad)

# ephemeris record columns
E_PRN, E_WEEK, E_TOE, E_TOC, E_AF0, E_AF1, E_AF2 = 0, 1, 2, 3, 4, 5, 6
E_SQRTA, E_ECC, E_I0, E_OMEGA0, E_OMEGA, E_M0, E_DN, E_IDOT, E_OMEGADOT = 7, 8, 9, 10, 11, 12, 13, 14, 15
E_CUC, E_CUS, E_CRC, E_CRS, E_CIC, E_CIS = 16, 17, 18, 19, 20, 21
E_TGD, E_HEALTH, E_IODE, E_URA, E_FIT = 22, 23, 24, 25, 26
N_EPH = 27
EPH_COLUMNS = (
    "prn",
    "week",
    "toe",
    "toc",
    "af0",
    "af1",
    "af2",
    "sqrtA",
    "e",
    "i0",
    "Omega0",
    "omega",
    "M0",
    "deltaN",
    "IDOT",
    "OmegaDot",
    "Cuc",
    "Cus",
    "Crc",
    "Crs",
    "Cic",
    "Cis",
    "TGD",
    "health",
    "IODE",
    "URA",
    "fit_h",
)
#: toe and toc in an ephemeris record are on the reference-week scale of the table (see module doc).


@njit(cache=True)
def eph_state(eph, t):
    """Satellite state from one ephemeris record ``eph`` (N_EPH,) at GPS time ``t`` [s] (GPS system time
    of transmission, reference-week scale).

    Returns (pos (3,) ECEF of time t [m], vel (3,) [m/s], dts [s] satellite clock offset incl. the
    relativistic term, ddts [s/s] its rate). IS-GPS-200 Table 20-IV; E_k by Newton iteration to 1e-14.
    """
    a = eph[E_SQRTA] ** 2
    ecc = eph[E_ECC]
    n0 = np.sqrt(GM_GPS / (a * a * a))
    tk = t - eph[E_TOE]
    n = n0 + eph[E_DN]
    mk = eph[E_M0] + n * tk
    ek = mk
    for _ in range(30):
        d = (ek - ecc * np.sin(ek) - mk) / (1.0 - ecc * np.cos(ek))
        ek -= d
        if abs(d) < 1e-14:
            break
    se, ce = np.sin(ek), np.cos(ek)
    den = 1.0 - ecc * ce
    sq = np.sqrt(1.0 - ecc * ecc)
    vk = np.arctan2(sq * se, ce - ecc)
    phi = vk + eph[E_OMEGA]
    s2, c2 = np.sin(2.0 * phi), np.cos(2.0 * phi)
    du = eph[E_CUS] * s2 + eph[E_CUC] * c2
    dr = eph[E_CRS] * s2 + eph[E_CRC] * c2
    di = eph[E_CIS] * s2 + eph[E_CIC] * c2
    u = phi + du
    r = a * den + dr
    inc = eph[E_I0] + di + eph[E_IDOT] * tk
    xp, yp = r * np.cos(u), r * np.sin(u)
    omk_dot = eph[E_OMEGADOT] - OMEGA_E_GPS
    om = eph[E_OMEGA0] + omk_dot * tk - OMEGA_E_GPS * eph[E_TOE]
    so, co = np.sin(om), np.cos(om)
    si, ci = np.sin(inc), np.cos(inc)
    pos = np.empty(3)
    pos[0] = xp * co - yp * ci * so
    pos[1] = xp * so + yp * ci * co
    pos[2] = yp * si
    # derivatives
    ek_dot = n / den
    vk_dot = ek_dot * sq / den
    u_dot = vk_dot * (1.0 + 2.0 * (eph[E_CUS] * c2 - eph[E_CUC] * s2))
    r_dot = a * ecc * se * ek_dot + 2.0 * vk_dot * (eph[E_CRS] * c2 - eph[E_CRC] * s2)
    i_dot = eph[E_IDOT] + 2.0 * vk_dot * (eph[E_CIS] * c2 - eph[E_CIC] * s2)
    xp_dot = r_dot * np.cos(u) - r * u_dot * np.sin(u)
    yp_dot = r_dot * np.sin(u) + r * u_dot * np.cos(u)
    vel = np.empty(3)
    vel[0] = xp_dot * co - yp_dot * ci * so + yp * si * so * i_dot - pos[1] * omk_dot
    vel[1] = xp_dot * so + yp_dot * ci * co - yp * si * co * i_dot + pos[0] * omk_dot
    vel[2] = yp_dot * si + yp * ci * i_dot
    dt = t - eph[E_TOC]
    dts = eph[E_AF0] + eph[E_AF1] * dt + eph[E_AF2] * dt * dt + F_REL * ecc * eph[E_SQRTA] * se
    ddts = eph[E_AF1] + 2.0 * eph[E_AF2] * dt + F_REL * ecc * eph[E_SQRTA] * ce * ek_dot
    return pos, vel, dts, ddts


@njit(cache=True)
def sat_from_pseudorange(eph, t_rx, pr, use_tgd):
    """Satellite state at the transmit time implied by a pseudorange.

    t_rx : receiver time tag [s] (reference-week scale; includes the receiver clock offset);
    pr : pseudorange [m]. Transmit time in satellite time t_sv = t_rx − pr/c, in GPS time
    t = t_sv − dt_s(t) (two fixed-point passes). ``use_tgd``: subtract T_GD from dt_s (L1 C/A user).
    Returns (pos, vel (ECEF of transmit time), dts [s], ddts [s/s]).
    """
    t_sv = t_rx - pr / C_LIGHT
    t = t_sv
    for _ in range(2):
        _, _, dts, _ = eph_state(eph, t)
        t = t_sv - dts
    pos, vel, dts, ddts = eph_state(eph, t)
    if use_tgd:
        dts -= eph[E_TGD]
    return pos, vel, dts, ddts


@njit(cache=True)
def geo_range(rs, rr):
    """Range [m] with the first-order Sagnac correction and the unit vector e^e receiver → satellite.

    rs : satellite position at transmit time (ECEF of that time), rr : receiver ECEF at receive time.
    """
    d0, d1, d2 = rs[0] - rr[0], rs[1] - rr[1], rs[2] - rr[2]
    r = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    e = np.empty(3)
    e[0], e[1], e[2] = d0 / r, d1 / r, d2 / r
    return r + OMEGA_E_GPS * (rs[0] * rr[1] - rs[1] * rr[0]) / C_LIGHT, e


@njit(cache=True)
def geo_range_rate(rs, vs, rr, vr, e):
    """Range rate [m/s] e·(v_s − v_r) with the first-order Sagnac rate term (see module doc)."""
    rate = e[0] * (vs[0] - vr[0]) + e[1] * (vs[1] - vr[1]) + e[2] * (vs[2] - vr[2])
    return rate + OMEGA_E_GPS / C_LIGHT * (vs[1] * rr[0] + rs[1] * vr[0] - vs[0] * rr[1] - rs[0] * vr[1])


@njit(cache=True)
def az_el(e_ecef, lat, lon):
    """Azimuth (clockwise from North, [0, 2π)) and elevation [rad] of the ECEF unit vector ``e_ecef``
    seen from (lat, lon) [rad]; also returns the ENU unit vector (3,)."""
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    enu = np.empty(3)
    enu[0] = -so * e_ecef[0] + co * e_ecef[1]
    enu[1] = -sl * co * e_ecef[0] - sl * so * e_ecef[1] + cl * e_ecef[2]
    enu[2] = cl * co * e_ecef[0] + cl * so * e_ecef[1] + sl * e_ecef[2]
    az = np.arctan2(enu[0], enu[1])
    if az < 0.0:
        az += 2.0 * np.pi
    el = np.arcsin(min(1.0, max(-1.0, enu[2])))
    return az, el, enu


@njit(cache=True)
def klobuchar(lat, lon, az, el, t_sow, alpha, beta):
    """GPS broadcast (Klobuchar) ionospheric L1 group delay [m] (IS-GPS-200 20.3.3.5.2.5).

    lat, lon : user geodetic [rad]; az, el : satellite azimuth/elevation [rad]; t_sow : GPS seconds
    (any week scale: only t mod 86400 enters); alpha, beta (4,) broadcast coefficients [s, s/sc, ...].
    Night-time floor 5 ns; obliquity F = 1 + 16 (0.53 − E)³ with E in semicircles. For L2 multiply by
    (f1/f2)².
    """
    e_sc = el / PI_GPS
    psi = 0.0137 / (e_sc + 0.11) - 0.022
    phi_i = lat / PI_GPS + psi * np.cos(az)
    if phi_i > 0.416:
        phi_i = 0.416
    elif phi_i < -0.416:
        phi_i = -0.416
    lam_i = lon / PI_GPS + psi * np.sin(az) / np.cos(phi_i * PI_GPS)
    phi_m = phi_i + 0.064 * np.cos((lam_i - 1.617) * PI_GPS)
    t = 4.32e4 * lam_i + t_sow
    t = t - np.floor(t / 86400.0) * 86400.0
    f = 1.0 + 16.0 * (0.53 - e_sc) ** 3
    amp = alpha[0] + phi_m * (alpha[1] + phi_m * (alpha[2] + phi_m * alpha[3]))
    per = beta[0] + phi_m * (beta[1] + phi_m * (beta[2] + phi_m * beta[3]))
    if amp < 0.0:
        amp = 0.0
    if per < 72000.0:
        per = 72000.0
    x = 2.0 * np.pi * (t - 50400.0) / per
    if abs(x) < 1.57:
        delay = f * (5e-9 + amp * (1.0 - x * x / 2.0 + x**4 / 24.0))
    else:
        delay = f * 5e-9
    return C_LIGHT * delay


@njit(cache=True)
def std_atmosphere(h, rel_humidity):
    """Standard atmosphere at height h [m] (clamped at ≥ 0): pressure [hPa], temperature [K], water-vapour
    partial pressure [hPa] (Magnus-type formula used by RTKLIB's Saastamoinen model)."""
    hg = max(h, 0.0)
    p = 1013.25 * (1.0 - 2.2557e-5 * hg) ** 5.2568
    tk = 15.0 - 6.5e-3 * hg + 273.15
    e = 6.108 * rel_humidity * np.exp((17.15 * tk - 4684.0) / (tk - 38.45))
    return p, tk, e


@njit(cache=True)
def saastamoinen_zenith(lat, h, p_hpa, t_k, e_hpa):
    """Saastamoinen zenith hydrostatic and wet delays [m] from pressure [hPa], temperature [K] and
    water-vapour pressure [hPa] at (lat [rad], h [m]):
    ZHD = 0.0022768 P / (1 − 0.00266 cos 2φ − 0.00028 h[km]); ZWD = 0.002277 (1255/T + 0.05) e."""
    zhd = 0.0022768 * p_hpa / (1.0 - 0.00266 * np.cos(2.0 * lat) - 0.00028 * max(h, 0.0) * 1e-3)
    zwd = 0.002277 * (1255.0 / t_k + 0.05) * e_hpa
    return zhd, zwd


@njit(cache=True)
def trop_mapping(el):
    """Tropospheric mapping function of Black & Eisner (1984), m(E) = 1.001/√(0.002001 + sin²E), as in
    RTCA DO-229 (valid above ~3°; elevations below 2° are clamped to 2°)."""
    s = np.sin(max(el, 2.0 * DEG))
    return 1.001 / np.sqrt(0.002001 + s * s)


@njit(cache=True)
def tropo_delay(lat, h, el, rel_humidity):
    """Slant tropospheric delay [m]: Saastamoinen zenith delays in the standard atmosphere at the receiver
    height (relative humidity ``rel_humidity`` in [0, 1]) times :func:`trop_mapping`. 0 for h outside
    [−100 m, 20 km] (above most of the atmosphere the model does not hold; aircraft stay below)."""
    if h < -100.0 or h > 2.0e4 or el <= 0.0:
        return 0.0
    p, tk, e = std_atmosphere(h, rel_humidity)
    zhd, zwd = saastamoinen_zenith(lat, h, p, tk, e)
    return (zhd + zwd) * trop_mapping(el)


@njit(cache=True)
def select_ephemeris(eph_table, prn, t, max_age):
    """Index of the healthy record of ``prn`` whose toe is closest to ``t`` with |t − toe| ≤ max_age [s];
    −1 if none."""
    best = -1
    best_d = max_age
    for i in range(eph_table.shape[0]):
        if int(eph_table[i, E_PRN]) != prn or eph_table[i, E_HEALTH] != 0.0:
            continue
        d = abs(t - eph_table[i, E_TOE])
        if d <= best_d:
            best_d = d
            best = i
    return best


@njit(cache=True)
def sat_states(eph_table, eph_idx, t):
    """Positions (S, 3), velocities (S, 3), clocks dts (S,) [s] and rates (S,) of the records
    ``eph_idx`` (S,) at GPS time ``t`` (no transmit-time iteration: for geometry and visibility)."""
    s = eph_idx.shape[0]
    pos = np.full((s, 3), np.nan)
    vel = np.full((s, 3), np.nan)
    dts = np.full(s, np.nan)
    ddts = np.full(s, np.nan)
    for j in range(s):
        if eph_idx[j] < 0:
            continue
        p, v, c, cd = eph_state(eph_table[eph_idx[j]], t)
        pos[j] = p
        vel[j] = v
        dts[j] = c
        ddts[j] = cd
    return pos, vel, dts, ddts


def dop(enu_unit, weights=None) -> dict:
    """Dilution of precision from ENU unit vectors receiver → satellite (n, 3) (n ≥ 4; rows [−e, 1]).

    Returns {gdop, pdop, hdop, vdop, tdop, edop, ndop}; inf where the geometry is singular. With
    ``weights`` (n,) the weighted form (HᵀWH)⁻¹ is used.
    """
    u = np.asarray(enu_unit, float).reshape(-1, 3)
    h = np.column_stack([-u, np.ones(len(u))])
    w = np.ones(len(u)) if weights is None else np.asarray(weights, float)
    inf = {k: float("inf") for k in ("gdop", "pdop", "hdop", "vdop", "tdop", "edop", "ndop")}
    if len(u) < 4:
        return inf
    n = h.T @ (h * w[:, None])
    if np.linalg.cond(n) > 1e12:
        return inf
    q = np.linalg.inv(n)
    d = np.diag(q)
    return {
        "gdop": float(np.sqrt(d.sum())),
        "pdop": float(np.sqrt(d[:3].sum())),
        "hdop": float(np.sqrt(d[:2].sum())),
        "vdop": float(np.sqrt(d[2])),
        "tdop": float(np.sqrt(d[3])),
        "edop": float(np.sqrt(d[0])),
        "ndop": float(np.sqrt(d[1])),
    }


def visible(sat_pos, rx_ecef, mask_deg: float = 5.0):
    """Elevation mask test: (visible (S,) bool, azimuth (S,) [rad], elevation (S,) [rad]) of satellites
    at ECEF ``sat_pos`` (S, 3) seen from the receiver ``rx_ecef`` (3,)."""
    sp = np.asarray(sat_pos, float).reshape(-1, 3)
    rr = np.asarray(rx_ecef, float)
    lat, lon, _ = ecef_to_lla(rr[0], rr[1], rr[2])
    az = np.full(len(sp), np.nan)
    el = np.full(len(sp), np.nan)
    for j in range(len(sp)):
        if not np.all(np.isfinite(sp[j])):
            continue
        _, e = geo_range(sp[j], rr)
        az[j], el[j], _ = az_el(e, lat, lon)
    vis = np.isfinite(el) & (el >= np.radians(mask_deg))
    return vis, az, el


def dual_frequency_iono(time, code1, code2, window_s: float) -> np.ndarray:
    """L1 ionospheric delay [m] per epoch and satellite from the geometry-free code combination
    I₁ = (P₂ − P₁)/(γ − 1), γ = (f₁/f₂)², averaged over a centred window of ``window_s`` seconds per
    satellite (the combination's noise is ≈ 2.3× the code noise; the ionosphere changes little over a
    minute). time (T,) [s]; code1, code2 (T, S) pseudoranges [m], NaN where missing → (T, S), NaN where
    no L1/L2 pair."""
    gam = (FREQ_L1 / FREQ_L2) ** 2
    i1 = (code2 - code1) / (gam - 1.0)
    out = np.full_like(i1, np.nan)
    half = window_s / 2
    for j in range(i1.shape[1]):
        ok = np.isfinite(i1[:, j])
        tj, ij = time[ok], i1[ok, j]
        if not len(tj):
            continue
        cs = np.concatenate([[0.0], np.cumsum(ij)])
        lo = np.searchsorted(tj, tj - half, "left")
        hi = np.searchsorted(tj, tj + half, "right")
        out[np.flatnonzero(ok), j] = (cs[hi] - cs[lo]) / (hi - lo)
    return out


__all__ = [
    "dual_frequency_iono",
    "C_LIGHT",
    "GM_GPS",
    "OMEGA_E_GPS",
    "F_REL",
    "FREQ_L1",
    "FREQ_L2",
    "LAMBDA_L1",
    "N_EPH",
    "EPH_COLUMNS",
    "eph_state",
    "sat_from_pseudorange",
    "geo_range",
    "geo_range_rate",
    "az_el",
    "klobuchar",
    "klobuchar_coefficients",
    "KLOBUCHAR_DEFAULT_ALPHA",
    "KLOBUCHAR_DEFAULT_BETA",
    "iono_fallback_note",
    "std_atmosphere",
    "saastamoinen_zenith",
    "trop_mapping",
    "tropo_delay",
    "select_ephemeris",
    "sat_states",
    "dop",
    "visible",
    "OMEGA_IE",
    "range_error_sigma",
    "ERR_BRDCI",
    "ERR_ION",
    "ERR_SAAS",
    "ERR_TROP",
    "ERR_CBIAS",
]


# ------------------------------------------------------- satellites of an epoch, measurement weights
@njit(cache=True)
def elevation_sigma(sigma0, el):
    """σ(E) = σ0 √(½ + ½/sin²E) [m] (E clamped at 2°)."""
    s = np.sin(max(el, 0.035))
    return sigma0 * np.sqrt(0.5 + 0.5 / (s * s))


@njit(cache=True)
def satellite_states(eph_table, prns, t_rx, pr, use_tgd, max_age):
    """numba core of :func:`satellites_from_pseudoranges` (arrays already typed)."""
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


@njit(cache=True)
def satellite_states_epochs(eph_table, prns, t_rx, pr, use_tgd, max_age):
    """:func:`satellite_states` of every epoch in one call (M epochs, S satellites: t_rx (M,), pr (M, S)),
    and the URA [m] of the ephemeris record used (NaN where none). Returns pos (M, S, 3), vel (M, S, 3),
    clk (M, S), clk_rate (M, S), ura (M, S)."""
    m, s = pr.shape
    pos, vel = np.full((m, s, 3), np.nan), np.full((m, s, 3), np.nan)
    clk, clk_rate, ura = np.full((m, s), np.nan), np.full((m, s), np.nan), np.full((m, s), np.nan)
    for k in range(m):
        pos[k], vel[k], clk[k], clk_rate[k] = satellite_states(eph_table, prns, t_rx[k], pr[k], use_tgd,
                                                               max_age)
        for j in range(s):
            if np.isfinite(pos[k, j, 0]):
                ura[k, j] = eph_table[select_ephemeris(eph_table, prns[j], t_rx[k], max_age), E_URA]
    return pos, vel, clk, clk_rate, ura


def satellites_from_pseudoranges(eph_table, prns, t_rx, pr, use_tgd: bool = True, max_age_s: float = 7200.0):
    """Satellite states at the transmit times implied by the pseudoranges of one epoch.

    eph_table : (K, N_EPH) ephemeris records (reference-week scale); prns (S,); t_rx receiver tag [s];
    pr (S,) [m] (NaN = no measurement). Returns (pos (S, 3) ECEF of transmit time [m], vel (S, 3) [m/s],
    clk (S,) c·dt_s [m], clk_rate (S,) c·ḋt_s [m/s]); NaN where no measurement or no ephemeris.
    """
    return satellite_states(
        np.ascontiguousarray(eph_table, float),
        np.asarray(prns, np.int64),
        float(t_rx),
        np.asarray(pr, float),
        bool(use_tgd),
        float(max_age_s),
    )


# ------------------------------------------- Klobuchar coefficients when the navigation file has none
#: RTKLIB's fallback Klobuchar coefficients (``rtkcmn.c``, ``ionmodel``: ``ion_default[]``, commented
#: "2004/1/1"; used when ``norm(ion, 8) <= 0``, i.e. no coefficients were broadcast/read), α [s, s/sc,
#: s/sc², s/sc³] and β [s, s/sc, s/sc², s/sc³]. RTKLIB's σ of the broadcast-model correction is
#: ERR_BRDCI (50 %) of the applied delay (``pntpos.c``, ``ionocorr``); aidnav states the same σ.
KLOBUCHAR_DEFAULT_ALPHA = np.array([0.1118e-07, -0.7451e-08, -0.5961e-07, 0.1192e-06])
KLOBUCHAR_DEFAULT_BETA = np.array([0.1167e06, -0.2294e06, -0.1311e06, 0.1049e07])


def klobuchar_coefficients(alpha, beta):
    """(α, β, source) for the Klobuchar model: the given coefficients ("broadcast") or, when there are none
    (None, or all zero as RTKLIB tests), RTKLIB's defaults ("default"; :data:`KLOBUCHAR_DEFAULT_ALPHA`)."""
    if alpha is None or beta is None or (np.all(np.asarray(alpha) == 0) and np.all(np.asarray(beta) == 0)):
        return KLOBUCHAR_DEFAULT_ALPHA.copy(), KLOBUCHAR_DEFAULT_BETA.copy(), "default"
    return np.asarray(alpha, float), np.asarray(beta, float), "broadcast"


def iono_fallback_note() -> str:
    """The one-line statement of the fallback for summaries and the console."""
    return ("no Klobuchar coefficients in the navigation file: RTKLIB's default coefficients "
            f"(rtkcmn.c ion_default, 2004/1/1) applied, sigma {100 * ERR_BRDCI:.0f} % of the delay")


# ------------------------------------------- single-frequency range-error budget (RTKLIB pntpos.c)
ERR_BRDCI = 0.5  #: broadcast (Klobuchar) ionosphere residual, fraction of the delay [-]
ERR_ION = 5.0  #: ionospheric delay σ with no ionospheric model [m]
ERR_SAAS = 0.3  #: Saastamoinen model residual σ at zenith [m]
ERR_TROP = 3.0  #: tropospheric delay σ with no tropospheric model [m]
ERR_CBIAS = 0.3  #: code bias σ [m]


@njit(cache=True)
def range_error_sigma(el, ura, iono_mode, iono_delay, tropo):
    """σ [m] of the time-correlated part of one L1 pseudorange error, RTKLIB's single-point budget
    (``pntpos.c``: ``ERR_*`` constants above, ``var_uraeph``, ``ionocorr``, ``tropcorr``):
    σ² = URA² + σ_ion² + σ_trop² + ERR_CBIAS², with σ_ion = ERR_BRDCI·I_Klobuchar (``iono_mode`` 1),
    ERR_ION (0: no ionospheric model) or 0 (2: dual-frequency delay removed); σ_trop =
    ERR_SAAS/(sin E + 0.1) with the Saastamoinen model (``tropo``), ERR_TROP/(sin E + 0.1) without.
    ura : the ephemeris' user range accuracy [m] (NaN or ≤ 0: 6144 m, RTKLIB's unknown-accuracy value);
    el [rad]; iono_delay [m] (the Klobuchar delay applied)."""
    u = ura if ura > 0.0 else 6144.0
    if iono_mode == 1:
        si = ERR_BRDCI * iono_delay
    elif iono_mode == 0:
        si = ERR_ION
    else:
        si = 0.0
    st = (ERR_SAAS if tropo else ERR_TROP) / (np.sin(max(el, 0.0)) + 0.1)
    return np.sqrt(u * u + si * si + st * st + ERR_CBIAS * ERR_CBIAS)
