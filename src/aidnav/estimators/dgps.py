"""Code-based GNSS relative positioning: base/rover relative
positioning from pseudorange single differences (seed 001 eqs. 1–5, iterated per §2.2 item 2), and dead
reckoning of the relative position during outages (seed eqs. 6–7 with the frame rotation of §2.2 item 5).

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

SPP itself is :mod:`aidnav.estimators.spp`; the satellite states of an epoch and the weights are in
:mod:`aidnav.nav.gnss_sat`.

**Relative positioning** (:func:`relative_position`): ΔP_j = P_K^j − P_B^j over the common satellites,
unknowns ΔX = [Δx_E, Δx_N, Δx_U, cΔT_BK] in n_B; rows [−e_j^T, 1] with e_j the n_B unit vector from the
current rover estimate to satellite j; the residual is ΔP − (ρ̂_K − ρ̂_B + cΔT̂) with exact (Sagnac)
ranges, each receiver's satellite position at its own transmit time. ``iterate=False`` gives the seed's
single linearisation about the base (second-order error ≈ |Δx|²/(2ρ), §2.2 item 2). Optionally the
model difference of the tropospheric delays (heights differ on an approach: ≈ 0.3 m zenith per km) is
removed. The base position need only be roughly known: an error δp_B moves the result by about
|δp_B|·|Δx|/ρ (0.1 m for 100 m at 20 km).

**Dead reckoning** (:func:`dead_reckon`): Δx(t+T) = Δx(t) + C_e^{n_B} C_{n_K}^e v^{n_K}(t)·T (Euler, the
seed's eq. 7) or the trapezoid of successive velocities (``method="trapezoid"``).
"""


from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aidnav.estimators.spp import SppResult, lla_ecef, spp, spp_series, spp_velocity  # noqa: F401
from aidnav.nav.earth import dcm_ecef_to_enu, ecef_to_lla
from aidnav.nav.gnss_sat import (  # noqa: F401  (satellite helpers re-exported for existing callers)
    C_LIGHT,
    az_el,
    dop,
    elevation_sigma,
    geo_range,
    satellites_from_pseudoranges,
    tropo_delay,
)
from aidnav.nav.gnss_sat import satellite_states as _satellites  # noqa: F401
from aidnav.nav.rotations import wrap_2pi

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
    az = wrap_2pi(np.arctan2(d[..., 0], d[..., 1]))
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
    rotate : use v^{n_B} = C_e^{n_B} C_{n_K}^e v^{n_K} (§2.2 item 5; False = the seed's unrotated sum).
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
