"""Raw GNSS measurement simulation: pseudorange and pseudorange rate (Doppler) of a moving rover and,
optionally, a static base station, from a truth trajectory and an ephemeris table.

Frames and units: truth as in :mod:`aidnav.sim.gnss` (IMU truth, lat/lon [rad], h [m], ENU velocity,
roll/pitch/heading); ECEF [m]; pseudoranges [m]; rates [m/s] (Doppler [Hz] = −rate/λ_L1); times are GPS
seconds on the ephemeris table's reference-week scale: the truth's time t maps to GPS time ``t0_gps + t``.

**Time tags and the receiver clock.** A receiver stamps epoch k with its own clock reading t_r,k
(``t0_gps + start + k/rate``); its clock offset dt_r (two-state model below) means the signals were
received at GPS time t = t_r − dt_r, where the antenna is taken from the truth (cubic Hermite, exact
lever arm: :func:`aidnav.sim.gnss.interpolate_truth`). The satellite signal left at t_tx with
t − t_tx = ρ/c (light-time iteration with the Sagnac-corrected range of
:func:`aidnav.nav.gnss_sat.geo_range`). Then, per satellite j:

P = ρ(r_s,true(t_tx), r_a(t)) + c·dt_r + ISB_sys − c·dt_s,true(t_tx) + I + T + MP + ε,
ρ̇_meas = ρ̇ + c·ḋt_r − c·ḋt_s,true + ε̇  (ionosphere, troposphere and multipath rates neglected: mm/s).

* **Ephemeris error**: the true orbit is the broadcast one plus a constant offset per satellite in its
  radial / along-track / cross-track frame, σ ``eph_sigma_rac_m``; its effect on a range is the
  projection on the line of sight, so base and rover see nearly the same error, differing by about
  |δr|·b/ρ for a baseline b (≈ 2 mm per 20 km and metre of orbit error): the geometry decorrelates it.
* **Satellite clock error**: true − broadcast = bias (σ ``sat_clock_sigma_m``) + drift
  (σ ``sat_clock_drift_sigma_m_s``) per satellite: identical for every receiver (cancels exactly in
  single differences, up to the drift over the ~0.1 ms difference in transmit times).
* **Ionosphere**: I = (1 + s_j)·K(r, j, t) + F(E)·g_j·d_r. K is the Klobuchar L1 delay with the
  coefficients ``iono_alpha``/``iono_beta`` evaluated at each receiver's own position and line of sight
  (so its gradient decorrelates base and rover naturally); s_j ~ N(0, ``iono_scale_sigma``²) per
  satellite is the model's error that a user correcting with the same Klobuchar keeps (common to both
  receivers; ``iono_alpha`` all zero = no ionosphere); g_j is a horizontal gradient (2,) per satellite,
  σ ``iono_gradient_mm_km`` per axis
  [mm of vertical delay per km], F the Klobuchar obliquity factor and d_r the receiver's horizontal
  offset [km] from the reference point (the base, or the rover's start). Differential ionosphere ≈
  F·|g|·b: 2 mm/km ⇒ 4 cm at 20 km (quiet mid-latitude), 10 mm/km and more in disturbed conditions.
* **Troposphere**: T = M(E)·(ZHD + ZWD)(h) + M(E)·δz_r: Saastamoinen in the standard atmosphere at the
  receiver's own height (:func:`aidnav.nav.gnss_sat.tropo_delay`, which a user can model) plus a
  residual zenith delay δz_r. δz_B ~ N(0, σ_z²) for the base; the rover's δz_K = ρ(d)·δz_B +
  √(1 − ρ²)·σ_z·ξ with ρ(d) = exp(−d/L), d its horizontal distance from the base, L
  ``tropo_corr_km`` and ξ ~ N(0, 1) fixed per run, so the residual difference has
  σ_z √(2(1 − ρ)) ≈ σ_z √(2d/L) for d ≪ L. Note that the *modelled* part differs between receivers at
  different heights (≈ 0.3 m zenith per km of height): it does not cancel in a single difference
  unless the user models it.
* **Receiver clock**: bias b and drift d [m, m/s] with ḃ = d + w_f, ḋ = w_g; white-frequency and
  random-walk-frequency PSDs from the Allan-variance coefficients S_f = c²h₀/2, S_g = c²·2π²h₋₂
  (Brown & Hwang); exact discrete transition over the epoch interval T:
  Q = [[S_f T + S_g T³/3, S_g T²/2], [S_g T²/2, S_g T]]. Flicker (h₋₁) is not modelled.
* **Multipath**: first-order Gauss-Markov per satellite and receiver, correlation time
  ``multipath_tau_s`` (rover) / ``base_multipath_tau_s``, stationary σ ``multipath_sigma_m`` times the
  elevation factor of :func:`aidnav.estimators.dgps.elevation_sigma` (independent between receivers).
* **Thermal noise**: white, σ(E) = σ0 √(½ + ½/sin²E) with σ0 ``code_sigma_m`` (``rate_sigma_m_s``
  for the rate).

**Every constellation**: the ephemeris table may hold Galileo, BeiDou and GLONASS records (satellite ids of
:mod:`aidnav.nav.gnss_sat`, e.g. :func:`aidnav.sim.gnss_constellation.nominal_multi_constellation`); each
system's code carries the receiver's inter-system bias ``isb_m[letter]`` (its clock − the GPS clock, the
same for rover and base), its ionosphere the factor (f_L1/f)², its Doppler the wavelength of its signal
(GLONASS: per channel, ``GnssObservations.freq1``).

Satellites below ``mask_deg`` (at each receiver) are NaN. ``sat_windows`` limit the rover's
satellites: (start_s, end_s, max_sats) keeps the ``max_sats`` highest satellites at the window start
(0 = none) during start_s ≤ t − t_truth0 < end_s.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from aidnav.data import Trajectory
from aidnav.jit import njit
from aidnav.nav import gnss_sat
from aidnav.nav.earth import ecef_to_lla, lla_to_ecef, radii
from aidnav.nav.gnss_sat import (
    C_LIGHT,
    FREQ_L1,
    PI_GPS,
    az_el,
    carrier_frequencies,
    eph_state,
    geo_range,
    geo_range_rate,
    klobuchar,
    sat_system,
    tropo_delay,
)
from aidnav.nav.gnss_types import GnssObservations, GpsEphemerides
from aidnav.nav.rotations import wrap_pi
from aidnav.sim.gnss import interpolate_truth  # the same interpolation as the PV fixes

__all__ = [
    "RawGnssSpec",
    "RawGnssSim",
    "simulate_raw_gnss",
    "clock_noise_psd",
    "simulate_clock",
    "static_pseudoranges",
    "limit_satellites",
]

# Klobuchar coefficients used as the default "true" ionosphere (a moderate-activity broadcast set)
DEFAULT_ALPHA = np.array([1.1176e-8, 7.4506e-9, -5.9605e-8, -5.9605e-8])
DEFAULT_BETA = np.array([9.0112e4, 4.9152e4, -1.9661e5, -6.5536e4])


@dataclass
class RawGnssSpec:
    """Settings of the raw GNSS simulation (units in the names; see the module docstring)."""

    rate_hz: float = 1.0
    mask_deg: float = 5.0
    code_sigma_m: float = 0.5
    rate_sigma_m_s: float = 0.05
    multipath_sigma_m: float = 0.3
    multipath_tau_s: float = 5.0
    base_multipath_tau_s: float = 60.0
    eph_sigma_rac_m: tuple = (0.3, 1.0, 0.6)
    sat_clock_sigma_m: float = 0.7
    sat_clock_drift_sigma_m_s: float = 1e-4
    iono_alpha: np.ndarray = field(default_factory=lambda: DEFAULT_ALPHA.copy())
    iono_beta: np.ndarray = field(default_factory=lambda: DEFAULT_BETA.copy())
    iono_scale_sigma: float = 0.3
    iono_gradient_mm_km: float = 2.0
    tropo_zenith_sigma_m: float = 0.03
    tropo_corr_km: float = 50.0
    humidity: float = 0.7
    tropo_model: bool = True  # False: no tropospheric delay at all (geometry tests)
    clock_h0: float = 2e-19
    clock_hm2: float = 2e-20
    clock_bias0_m: float = 3000.0
    clock_drift0_m_s: float = 30.0
    base_clock_bias0_m: float = -1500.0
    base_clock_drift0_m_s: float = 10.0
    lever_arm_b: tuple = (0.0, 0.0, 0.0)
    sat_windows: list = field(default_factory=list)
    isb_m: dict = field(default_factory=dict)  # inter-system biases {letter: that system's clock − GPS's} [m]

    def perfect(self) -> RawGnssSpec:
        """A copy without any error source except the receiver clocks (noise-free, common-mode-free)."""
        return RawGnssSpec(
            rate_hz=self.rate_hz,
            mask_deg=self.mask_deg,
            code_sigma_m=0.0,
            rate_sigma_m_s=0.0,
            multipath_sigma_m=0.0,
            eph_sigma_rac_m=(0.0, 0.0, 0.0),
            sat_clock_sigma_m=0.0,
            sat_clock_drift_sigma_m_s=0.0,
            iono_alpha=self.iono_alpha,
            iono_beta=self.iono_beta,
            iono_scale_sigma=0.0,
            iono_gradient_mm_km=0.0,
            tropo_zenith_sigma_m=0.0,
            humidity=self.humidity,
            tropo_model=self.tropo_model,
            clock_h0=self.clock_h0,
            clock_hm2=self.clock_hm2,
            clock_bias0_m=self.clock_bias0_m,
            clock_drift0_m_s=self.clock_drift0_m_s,
            base_clock_bias0_m=self.base_clock_bias0_m,
            base_clock_drift0_m_s=self.base_clock_drift0_m_s,
            lever_arm_b=self.lever_arm_b,
            sat_windows=list(self.sat_windows),
            isb_m=dict(self.isb_m),
        )


def clock_noise_psd(h0: float, hm2: float) -> tuple[float, float]:
    """(S_f [m²/s], S_g [m²/s³]) of the two-state clock model from Allan coefficients h₀ [s], h₋₂ [1/s]."""
    return C_LIGHT**2 * h0 / 2.0, C_LIGHT**2 * 2.0 * np.pi**2 * hm2


def simulate_clock(n: int, dt: float, h0: float, hm2: float, b0: float, d0: float, rng) -> np.ndarray:
    """(n, 2) receiver clock bias [m] and drift [m/s] on a grid of step ``dt`` [s] (exact discretisation)."""
    sf, sg = clock_noise_psd(h0, hm2)
    q = np.array([[sf * dt + sg * dt**3 / 3, sg * dt**2 / 2], [sg * dt**2 / 2, sg * dt]])
    L = np.linalg.cholesky(q + 1e-30 * np.eye(2))
    z = rng.standard_normal((n, 2)) @ L.T
    out = np.empty((n, 2))
    x = np.array([b0, d0], float)
    for k in range(n):
        if k > 0:
            x = np.array([x[0] + x[1] * dt, x[1]]) + z[k]
        out[k] = x
    return out


# numba keys a cached kernel on its own file: the orbits it inlines (eph_state of every constellation)
# live in nav.gnss_sat, so their source is the kernel's ``depends`` key (aidnav.jit.keep_cache_current)
_ORBITS_KEY = hashlib.sha256(Path(gnss_sat.__file__).read_bytes()).hexdigest()[:20]


@njit(cache=True, depends=_ORBITS_KEY)
def _raw_kernel(
    t_gps,
    rr,
    vr,
    eph,
    eph_err,
    clk_err,
    t_clk_ref,
    clock,
    alpha,
    beta,
    iono_scale,
    iono_grad,
    d_km,
    tropo_res,
    humidity,
    mp_unit,
    mp_sigma,
    noise,
    code_sig,
    rate_sig,
    mask,
    use_trop,
    isb,
    ifac,
):
    """Pseudoranges and rates; see the module docstring. eph (S, N_EPH) one record per satellite; isb (S,)
    the receiver's inter-system bias of each satellite's system [m]; ifac (S,) ionospheric scale
    (f_L1/f)²."""
    T = t_gps.shape[0]
    S = eph.shape[0]
    code = np.full((T, S), np.nan)
    rate = np.full((T, S), np.nan)
    elev = np.full((T, S), np.nan)
    azim = np.full((T, S), np.nan)
    ion = np.full((T, S), np.nan)
    trop = np.full((T, S), np.nan)
    for k in range(T):
        lat, lon, h = ecef_to_lla(rr[k, 0], rr[k, 1], rr[k, 2])
        for j in range(S):
            tau = 0.075
            rs = np.zeros(3)
            vs = np.zeros(3)
            dts = 0.0
            ddts = 0.0
            rho = 0.0
            e = np.zeros(3)
            for _ in range(4):
                rs, vs, dts, ddts = eph_state(eph[j], t_gps[k] - tau)
                # ephemeris error in radial / along / cross
                rn = rs / np.sqrt(rs @ rs)
                cr = np.cross(rs, vs)
                cr = cr / np.sqrt(cr @ cr)
                al = np.cross(cr, rn)
                rs = rs + eph_err[j, 0] * rn + eph_err[j, 1] * al + eph_err[j, 2] * cr
                rho, e = geo_range(rs, rr[k])
                tau = rho / C_LIGHT
            az, el, _ = az_el(e, lat, lon)
            if el < mask:
                continue
            elev[k, j] = el
            azim[k, j] = az
            dt_c = t_gps[k] - tau - t_clk_ref
            sat_clk = dts * C_LIGHT + clk_err[j, 0] + clk_err[j, 1] * dt_c
            sat_clk_rate = ddts * C_LIGHT + clk_err[j, 1]
            e_sc = el / PI_GPS
            fobl = 1.0 + 16.0 * (0.53 - e_sc) ** 3
            iono = 0.0
            if alpha[0] != 0.0 or alpha[1] != 0.0 or alpha[2] != 0.0 or alpha[3] != 0.0:  # all zero: none
                iono = (1.0 + iono_scale[j]) * klobuchar(lat, lon, az, el, t_gps[k], alpha, beta)
            iono += fobl * 1e-3 * (iono_grad[j, 0] * d_km[k, 0] + iono_grad[j, 1] * d_km[k, 1])
            iono *= ifac[j]
            s = np.sin(max(el, 0.035))
            mfac = np.sqrt(0.5 + 0.5 / (s * s))
            tro = tropo_delay(lat, h, el, humidity) if use_trop else 0.0
            tro += tropo_res[k] * 1.001 / np.sqrt(0.002001 + s * s)
            ion[k, j] = iono
            trop[k, j] = tro
            code[k, j] = (
                rho
                + clock[k, 0]
                + isb[j]
                - sat_clk
                + iono
                + tro
                + mp_sigma * mfac * mp_unit[k, j]
                + code_sig * mfac * noise[k, j, 0]
            )
            rate[k, j] = (
                geo_range_rate(rs, vs, rr[k], vr[k], e)
                + clock[k, 1]
                - sat_clk_rate
                + rate_sig * mfac * noise[k, j, 1]
            )
    return code, rate, elev, azim, ion, trop


@dataclass
class RawGnssSim:
    """Simulated raw GNSS data.

    rover, base : :class:`GnssObservations` (base None without a base). eph : the broadcast ephemerides
    the receivers' users get. base_ecef : true base position [m]. truth : dict of truth components
    (clock (T, 2) [m, m/s] of rover and base, antenna ECEF (T, 3), GPS receive times, elevation (T, S),
    iono/tropo delays (T, S) of rover and base, satellite/ephemeris error draws).
    """

    rover: GnssObservations
    base: GnssObservations | None
    eph: GpsEphemerides
    base_ecef: np.ndarray | None
    truth: dict


def limit_satellites(
    obs: GnssObservations,
    elevation: np.ndarray,
    windows,
    t_start: float,
    how: str = "highest",
    azimuth: np.ndarray | None = None,
    min_elev_deg: float = 15.0,
) -> GnssObservations:
    """Copy of ``obs`` with at most ``max_sats`` satellites (the highest at each window's start) inside each
    window (start_s, end_s, max_sats), times relative to ``t_start`` (same scale as ``obs.time``).

    how : "highest" (the ``max_sats`` highest at the window start) or "spread" (two satellites above
    ``min_elev_deg`` whose azimuths differ most, i.e. the best horizontal geometry for a pair; needs
    ``azimuth``; for max_sats != 2 falls back to "highest")."""
    code, rate, cn0 = obs.code1.copy(), obs.doppler1.copy(), obs.cn0.copy()
    rel = obs.time - t_start
    for start, end, nmax in windows:
        m = (rel >= start - 1e-9) & (rel < end - 1e-9)
        if not m.any():
            continue
        k0 = int(np.flatnonzero(m)[0])
        el0 = np.where(np.isfinite(code[k0]), elevation[k0], -np.inf)
        keep = np.argsort(-el0)[: int(nmax)]
        if how == "spread" and int(nmax) == 2 and azimuth is not None:
            cand = np.flatnonzero(el0 >= np.radians(min_elev_deg))
            best, pair = -1.0, keep
            for a in range(len(cand)):
                for b in range(a + 1, len(cand)):
                    d = abs(wrap_pi(azimuth[k0, cand[a]] - azimuth[k0, cand[b]]))
                    if d > best:
                        best, pair = d, np.array([cand[a], cand[b]])
            keep = pair
        keep = keep[np.isfinite(el0[keep])]
        drop = np.setdiff1d(np.arange(code.shape[1]), keep)
        for a in (code, rate, cn0):
            a[np.ix_(np.flatnonzero(m), drop)] = np.nan
    return GnssObservations(
        obs.time,
        obs.ref_week,
        obs.prn,
        code,
        rate,
        cn0,
        None,
        None,
        obs.approx_ecef,
        list(obs.events) + [f"satellites limited in windows {list(windows)}"],
        freq1=obs.freq1,
    )


def simulate_raw_gnss(
    truth: Trajectory,
    eph: GpsEphemerides,
    spec: RawGnssSpec,
    rng: np.random.Generator,
    t0_gps: float,
    base_lla=None,
    start_s: float | None = None,
) -> RawGnssSim:
    """Simulate rover (and base) pseudoranges and rates; see the module docstring.

    truth : IMU truth (time [s from its start or any scale], lat/lon [rad], h [m], vel ENU, rph [rad]).
    eph : broadcast ephemerides (reference-week scale); the truth's time t is GPS time t0_gps + t.
    base_lla : (lat [rad], lon [rad], h [m]) of a static base, or None. start_s : first tag relative to
    the truth's time (default: one epoch interval after its start).
    Returns :class:`RawGnssSim`; observation times are the receivers' tags on the ephemeris scale.
    """
    t = np.asarray(truth.time, float)
    dt = 1.0 / spec.rate_hz
    first = t[0] + (dt if start_s is None else start_s)
    tags_rel = np.arange(first, t[-1] - 0.01 + 1e-9, dt)
    T = len(tags_rel)
    S = len(eph.table)
    ss = np.random.SeedSequence(int(rng.integers(2**31)))
    r_sat, r_clk, r_mp, r_noise, r_base = (np.random.default_rng(s) for s in ss.spawn(5))
    sat = _satellite_errors(r_sat, S, spec)  # common to base and rover
    # receiver clocks (sampled on the tag grid)
    clk_k = simulate_clock(
        T, dt, spec.clock_h0, spec.clock_hm2, spec.clock_bias0_m, spec.clock_drift0_m_s, r_clk
    )
    t_rx_k = tags_rel - clk_k[:, 0] / C_LIGHT  # true reception times (truth scale)
    t_rx_k = np.clip(t_rx_k, t[0], t[-1])
    r_a, v_a, lat, lon, h = _antenna_track(truth, t_rx_k, spec)
    # reference point for the ionospheric gradient / tropospheric correlation
    if base_lla is not None:
        ref = tuple(float(x) for x in base_lla)
    else:
        ref = (float(lat[0]), float(lon[0]), float(h[0]))
    d_km, dz_k, dz_b = _spatial_residuals(lat, lon, ref, sat["tropo_xi"], spec, base_lla is not None, T)
    mp_k = _gm_unit(r_mp, T, S, dt, spec.multipath_tau_s)
    noise_k = r_noise.standard_normal((T, S, 2))
    t_clk_ref = t0_gps + t[0]
    code, rate, el, az, ion, trop = _observe(t0_gps + t_rx_k, r_a, v_a, eph, sat, t_clk_ref, clk_k, d_km,
                                             dz_k, mp_k, noise_k, spec)
    prn = eph.table[:, 0].astype(int)
    tags = t0_gps + tags_rel
    freq = carrier_frequencies(prn, eph.table)
    rover = GnssObservations(tags, eph.ref_week, prn, code, -rate / (C_LIGHT / freq),
                             np.full_like(code, 45.0), None, None, None,
                             ["simulated rover (aidnav.sim.gnss_raw)"], freq1=freq)
    if spec.sat_windows:
        rover = limit_satellites(rover, el, spec.sat_windows, t0_gps + t[0])
    truth_d = {
        "clock": clk_k, "antenna_ecef": r_a, "antenna_vel_ecef": v_a, "t_receive_gps": t0_gps + t_rx_k,
        "elevation": el, "azimuth": az, "iono": ion, "tropo": trop, "eph_err_rac": sat["eph_err"],
        "sat_clock_err": sat["clk_err"], "iono_scale": sat["iono_scale"],
        "iono_gradient_mm_km": sat["iono_grad"], "tropo_residual_rover": dz_k, "tropo_residual_base": dz_b,
        "tags_rel": tags_rel,
    }
    base = base_ecef = None
    if base_lla is not None:
        base_ecef = np.array(lla_to_ecef(*ref))
        base = _base_observations(base_ecef, tags_rel, dt, t0_gps, eph, sat, t_clk_ref, dz_b, spec, r_base,
                                  prn, truth_d)
    return RawGnssSim(rover, base, eph, base_ecef, truth_d)


def _satellite_errors(r_sat, S: int, spec: RawGnssSpec) -> dict:
    """The satellite-level error draws (common to base and rover), in this order: orbit (radial,
    along, cross) [m], clock bias [m] and drift [m/s], iono scale [-] and gradient [mm/km], the two
    tropospheric draws."""
    eph_err = r_sat.standard_normal((S, 3)) * np.asarray(spec.eph_sigma_rac_m, float)
    clk_err = np.column_stack([r_sat.standard_normal(S) * spec.sat_clock_sigma_m,
                               r_sat.standard_normal(S) * spec.sat_clock_drift_sigma_m_s])
    iono_scale = r_sat.standard_normal(S) * spec.iono_scale_sigma
    iono_grad = r_sat.standard_normal((S, 2)) * spec.iono_gradient_mm_km
    tropo_xi = r_sat.standard_normal(2)
    return dict(eph_err=eph_err, clk_err=clk_err, iono_scale=iono_scale, iono_grad=iono_grad,
                tropo_xi=tropo_xi)


def _antenna_track(truth, t_rx_k, spec: RawGnssSpec):
    """The antenna's ECEF position and velocity at the reception times (the truth's IMU carried through
    the lever arm), and the IMU's lat, lon, h there."""
    r_e, v_e, lat, lon, h, v_n, c_bn, w_eb = interpolate_truth(truth, t_rx_k)
    lev = np.asarray(spec.lever_arm_b, float)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    z = np.zeros_like(lat)
    c_en = np.stack([np.stack([-so, co, z], -1), np.stack([-sl * co, -sl * so, cl], -1),
                     np.stack([cl * co, cl * so, sl], -1)], -2)
    c_ne = np.transpose(c_en, (0, 2, 1))
    r_a = r_e + np.einsum("kij,kj->ki", c_ne, c_bn @ lev)
    v_a = v_e + np.einsum("kij,kj->ki", c_ne, np.einsum("kij,kj->ki", c_bn, np.cross(w_eb, lev)))
    return r_a, v_a, lat, lon, h


def _spatial_residuals(lat, lon, ref, tropo_xi, spec: RawGnssSpec, with_base: bool, T: int):
    """Distance to the reference point (E, N [km], the ionospheric gradient's argument) and the residual
    zenith tropospheric delays of the rover (T,) and the base, correlated over ``tropo_corr_km``."""
    ref_lat, ref_lon, ref_h = ref
    rm, rn = radii(ref_lat)
    dlon = wrap_pi(lon - ref_lon)
    d_km = np.column_stack([dlon * (rn + ref_h) * np.cos(ref_lat), (lat - ref_lat) * (rm + ref_h)]) / 1e3
    dist = np.hypot(d_km[:, 0], d_km[:, 1])
    sz = spec.tropo_zenith_sigma_m
    if with_base:
        rho_t = np.exp(-dist / spec.tropo_corr_km)
        dz_b = sz * tropo_xi[0]
        dz_k = rho_t * dz_b + np.sqrt(1 - rho_t**2) * sz * tropo_xi[1]
    else:
        dz_b = 0.0
        dz_k = np.full(T, sz * tropo_xi[0])
    return d_km, dz_k, dz_b


def _gm_unit(rng_, n: int, S: int, dt: float, tau: float) -> np.ndarray:
    """(n, S) unit-variance first-order Gauss–Markov sequences with correlation time ``tau`` (0: white)."""
    a = np.exp(-dt / tau) if tau > 0 else 0.0
    w = rng_.standard_normal((n, S))
    out = np.empty((n, S))
    out[0] = w[0]
    for k in range(1, n):
        out[k] = a * out[k - 1] + np.sqrt(1 - a * a) * w[k]
    return out


def _observe(t_rx, r_a, v_a, eph, sat, t_clk_ref, clk, d_km, dz, mp, noise, spec: RawGnssSpec):
    """:func:`_raw_kernel` of one receiver: (code, rate, elevation, azimuth, iono, tropo)."""
    return _raw_kernel(t_rx, r_a, v_a, eph.table, sat["eph_err"], sat["clk_err"], t_clk_ref, clk,
                       np.asarray(spec.iono_alpha, float), np.asarray(spec.iono_beta, float),
                       sat["iono_scale"], sat["iono_grad"], d_km, dz, spec.humidity, mp,
                       spec.multipath_sigma_m, noise, spec.code_sigma_m, spec.rate_sigma_m_s,
                       np.radians(spec.mask_deg), spec.tropo_model, *_system_terms(eph, spec))


def _system_terms(eph, spec: RawGnssSpec):
    """Per satellite: the receiver's inter-system bias of its system [m] and its ionospheric scale
    (f_L1/f)²."""
    sid = eph.table[:, 0].astype(int)
    isb = np.array([spec.isb_m.get(c, 0.0) for c in sat_system(sid)])
    return isb, (FREQ_L1 / carrier_frequencies(sid, eph.table)) ** 2


def _base_observations(base_ecef, tags_rel, dt, t0_gps, eph, sat, t_clk_ref, dz_b, spec: RawGnssSpec, r_base,
                       prn, truth_d) -> GnssObservations:
    """The static base's observations (its clock, multipath and noise from ``r_base``, in that order);
    its truth added to ``truth_d``."""
    T, S = len(tags_rel), len(eph.table)
    clk_b = simulate_clock(
        T, dt, spec.clock_h0, spec.clock_hm2, spec.base_clock_bias0_m, spec.base_clock_drift0_m_s, r_base
    )
    tb = t0_gps + tags_rel - clk_b[:, 0] / C_LIGHT
    mp_b = _gm_unit(r_base, T, S, dt, spec.base_multipath_tau_s)
    noise_b = r_base.standard_normal((T, S, 2))
    code_b, rate_b, el_b, _, ion_b, trop_b = _observe(tb, np.tile(base_ecef, (T, 1)), np.zeros((T, 3)), eph,
                                                      sat, t_clk_ref, clk_b, np.zeros((T, 2)),
                                                      np.full(T, dz_b), mp_b, noise_b, spec)
    truth_d.update({"base_clock": clk_b, "base_elevation": el_b, "base_iono": ion_b, "base_tropo": trop_b,
                    "base_t_receive_gps": tb})
    freq = carrier_frequencies(prn, eph.table)
    return GnssObservations(t0_gps + tags_rel, eph.ref_week, prn, code_b, -rate_b / (C_LIGHT / freq),
                            np.full_like(code_b, 45.0), None, None, base_ecef.copy(),
                            ["simulated base (aidnav.sim.gnss_raw)"], freq1=freq)


def static_pseudoranges(
    eph: GpsEphemerides, t_gps: float, rx_ecef, clock_m: float = 0.0, mask_deg: float = 5.0
):
    """Error-free pseudoranges [m] (S,) of a static receiver at ``rx_ecef`` whose clock reads GPS time +
    clock_m/c,
    tagged t_gps (receiver time): geometric (Sagnac) range + clock_m − c·dt_s (broadcast clock), no
    atmosphere; NaN below ``mask_deg``. Also returns the elevations (S,) [rad]. For geometry tests."""
    S = len(eph.table)
    rr = np.asarray(rx_ecef, float).reshape(1, 3)
    code, _, el, _, _, _ = _raw_kernel(
        np.array([t_gps - clock_m / C_LIGHT]),
        rr,
        np.zeros((1, 3)),
        eph.table,
        np.zeros((S, 3)),
        np.zeros((S, 2)),
        t_gps,
        np.array([[clock_m, 0.0]]),
        np.zeros(4),
        np.zeros(4),
        np.zeros(S),
        np.zeros((S, 2)),
        np.zeros((1, 2)),
        np.zeros(1),
        0.0,
        np.zeros((1, S)),
        0.0,
        np.zeros((1, S, 2)),
        0.0,
        0.0,
        np.radians(mask_deg),
        False,
        np.zeros(S),
        np.ones(S),
    )
    return code[0], el[0]
