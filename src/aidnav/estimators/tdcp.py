"""Time-differenced carrier phase (TDCP): cycle slips and the receiver's displacement between epochs.

Frames and units: ECEF [m]; phase in cycles of L1 (λ = c/f_L1); times GPS seconds on the observations'
reference-week scale; clock terms in metres. Carrier phase λL = ρ + b − c·dt_s − I + T + λN + ε_φ (N
constant while the receiver keeps lock), Doppler rate ρ̇_D = −λD.

**Cycle slips** (:func:`phase_increments`): between epochs k−1 and k of one satellite the phase increment λΔL
is used when both phases exist, the loss-of-lock indicator has no bit 0 at k (RINEX: lock lost, a slip
possible) and it agrees with the Doppler: the statistic s = λΔL − ½(ρ̇_D,k−1 + ρ̇_D,k)Δt (the trapezoidal
integral of the Doppler) is tested at a false-alarm probability α per increment (``false_alarm``, default
:data:`SLIP_FALSE_ALARM` 1e-3; the threshold z that quantile of the run's own statistic, below). Its stated
variance is the Doppler's and the phase's, (Δt²/4)(σ_ρ̇(E_k−1)² + σ_ρ̇(E_k)²) + σ_φ,k−1² + σ_φ,k² (σ_ρ̇(E) =
σ_ρ̇0 √(½ + ½/sin²E), :func:`slip_sigma2`). The trapezoid's own error is the receiver's motion, −e_j·δr: a
walker's 1.9-Hz bounce
seen at 4 Hz (ωΔt ≈ 3 rad, near Nyquist: no polynomial fit of the Dopplers follows it) leaves 5 cm RMS on the
simulated pedestrian (:mod:`aidnav.sim.pedestrian`), where the Doppler's noise leaves 1–3 cm; the constant
half-cycle threshold before issue 40 session 17 flagged 8.4 % of its increments. The motion is common to the
satellites through the geometry, so each interval's statistics are fitted as s_j = e_j·δ + c (δ the motion
error, c the clock's) by weighted least squares and the largest studentized residual is flagged while above z
and two or more degrees of freedom remain (data snooping, Baarda; :func:`slip_outliers`). A satellite
without a line of sight, or an interval with fewer than six, is tested alone on s/σ_s. Both thresholds come
from the run's own statistics, taken over the whole run before the test (not causal; issue 40 session 18,
:func:`slip_threshold`): the studentized residuals of one fit per interval for the geometric test, s/σ_s for
the lone one, each modelled as a Student-t whose degrees of freedom ν make its kurtosis within four (six for
the lone test) robust SDs (:data:`SLIP_TAIL_TRIM`; a slip further out does not count as tail) the sample's,
its scale from the median absolute deviation, its variance factor against the stated one floored at 0.1
(:data:`SLIP_VARIANCE_FLOOR`; fewer than :data:`SLIP_MIN_SAMPLE` = 300 values: the normal quantile on the
stated σ). The real walk's statistic has heavy tails (ν ≈ 5–6: the normal quantile flagged 0.5 % of the lone
satellites' increments at α = 1e-3); the simulated pedestrian's is normal with a factor ≈ 0.3 (the filter's
default Doppler σ 0.1 m/s is twice the simulator's 0.05). The smallest slip found with 99 % probability is
about (z + 2.33)·σ/√(1 − h) (σ the statistic's true σ, h the leverage, z the threshold): with a zenith
Doppler σ of 0.1 m/s and 5 mm phase at 0.25 s, one cycle (19 cm) down to 24° elevation, 1.5 cycles at
15°; with 0.05 m/s (the simulator's, its factor learnt) one cycle down to ≈ 12°. A constant
``slip_threshold_cycles`` gives the old test, |s| > threshold·λ.

**Displacement** (:func:`tdcp_displacement`): with y_j = λΔL_j + Δ(c·dt_s,j) − (|r_s,j(k) − r(k−1)| −
|r_s,j(k−1) − r(k−1)|) (Sagnac-corrected ranges, :func:`aidnav.nav.gnss_sat.geo_range`, from a prior
receiver position r(k−1), e.g. SPP: its metres of error enter as (e_k − e_{k−1})·δr, sub-mm), the model is
y_j = −e_j·Δr + Δb + ε, ε ~ N(0, 2σ_φ²) (ionosphere and troposphere change sub-mm in 0.25 s; ambiguities
cancel). Least squares with ≥ 4 satellites gives Δr, Δb and their covariance; Δr/Δt is the mean velocity
over the interval (at its mid time).

**Receiver phase wind-up** (:func:`receiver_windup`, :func:`windup_increments`; Wu et al. 1993, "Effects of
antenna orientation on GPS carrier phase", manuscripta geodaetica 18; RTKLIB ``windupcorr``): a right-hand
circularly polarised signal (IS-GPS-200 §3.3.1.1) received by an antenna of dipole axes x̂, ŷ (boresight
ẑ = x̂ × ŷ) has the effective dipole D = x̂ − k(k·x̂) + k × ŷ, k the unit vector satellite → receiver; the
wind-up φ_w [cycles] is the angle from the satellite's effective dipole to D about k, over 2π, and the
phase model is λL = ρ + … + λφ_w. Rotating the antenna by θ (right-handed) about its boresight turns D
by −θ about k **for every k** (D' = D cos θ − (k × D) sin θ), so every satellite's φ_w changes by
−θ/2π (the sign of a RHCP wave on crossed dipoles whose ŷ output lags a quarter cycle: the received phase
advances by θ, RINEX's phase falls; tests/estimators/test_tdcp.py simulates it): the same for all, it goes
into the clock change; only rotations about other axes (a tilted or
rocking antenna) change satellites differently. The antenna frame is the body frame (x̂ = body x, ŷ =
body y, boresight the body z: up for the RFU IMU at rest); a constant rotation of x̂, ŷ about the
boresight adds the same constant to every φ_w and cancels in an increment. The satellite's half
(its attitude, sun-dependent) changes by far less than a millimetre over an interval of a second and
is held fixed here (its reference dipoles from the ECEF z axis and k). Measured on the walk: the
increments are 5.2 mm RMS per satellite per 0.25 s, their part that differs between satellites 0.3 mm
RMS (the hand-held antenna is within ~5° of level), against a 12 mm TDCP residual (docs/results.md, issue
40 session 13): a model term with no free parameter that the walk's figures do not need, applied where an
attitude is given (:func:`tdcp_series`'s ``attitude``).
"""

from __future__ import annotations

from statistics import NormalDist

import numpy as np

from aidnav.nav.earth import dcm_ecef_to_enu, ecef_to_lla
from aidnav.nav.gnss_sat import LAMBDA_L1, geo_range, satellites_from_pseudoranges

#: the phase–Doppler slip test's defaults (module doc, "Cycle slips"): the probability that an increment
#: without a slip is flagged, and the stated noises where the caller gives none (the tight filter's default
#: zenith Doppler σ, ``gnss.rate_sigma_m_s``, and phase σ, ``gnss.phase_sigma_m``)
SLIP_FALSE_ALARM = 1e-3
SLIP_RATE_SIGMA_M_S = 0.1
SLIP_PHASE_SIGMA_M = 0.005
#: the thresholds' tails and scale from the run's own statistics (:func:`slip_threshold`): the windows
#: [robust SDs] of the trimmed kurtosis, the geometric test's residuals and the lone satellites' statistic
#: (one-cycle slips beyond them: they would read as heavy tails; on the simulated pedestrian a low
#: satellite's slip is ≈ 5 robust SDs of the pooled residuals, on the walk a cycle is 11 of the lone
#: statistic's; the wider window estimates the far tail better: 1.3 α against 1.7 α at 4 on a t₅ error
#: with 3 192 values), the floor of the variance factor (the stated σ at most √10 times the run's: the
#: filter's default Doppler σ is twice the simulator's), the fewest statistics for an estimate (else the
#: normal quantile on the stated σ)
SLIP_TAIL_TRIM = 4.0
SLIP_TAIL_TRIM_ALONE = 6.0
SLIP_VARIANCE_FLOOR = 0.1
SLIP_MIN_SAMPLE = 300

__all__ = ["MA_ORDER", "SLIP_FALSE_ALARM", "SLIP_PHASE_SIGMA_M", "SLIP_RATE_SIGMA_M_S", "SLIP_TAIL_TRIM",
           "SLIP_TAIL_TRIM_ALONE", "SLIP_VARIANCE_FLOOR", "SLIP_MIN_SAMPLE", "imu_time_offset",
           "line_of_sight", "phase_increments", "receiver_windup", "running_variance_factor", "slip_outliers",
           "slip_sigma2", "slip_threshold", "slope_variance_ma", "tdcp_displacement", "tdcp_series",
           "windup_increments"]


def phase_increments(time, phase_cycles, lli, range_rate, slip_threshold_cycles: float | None = None,
                     wavelength=LAMBDA_L1, geometry=None, sigma=(SLIP_RATE_SIGMA_M_S, SLIP_PHASE_SIGMA_M),
                     false_alarm: float = SLIP_FALSE_ALARM):
    """Phase increments λΔL [m] (T, S) between consecutive epochs (row k: from k−1 to k; row 0 NaN) with
    cycle slips removed (NaN), and the slips (T, S) as codes: 0 none, 1 loss-of-lock indicator, 2 phase
    disagrees with the Doppler (module doc). range_rate (T, S) [m/s] = −λ·Doppler (NaN: no Doppler: only
    the indicator is checked). wavelength [m]: scalar or (S,) per satellite (GLONASS FDMA channels, BeiDou
    B1I).

    The phase–Doppler test (module doc, "Cycle slips"): with ``slip_threshold_cycles`` the constant
    threshold |s| > slip_threshold_cycles·λ (the test before issue 40 session 17); without it the
    statistical one at ``false_alarm`` per increment: ``geometry`` = (unit vectors receiver → satellite
    (T, S, 3), elevations (T, S) [rad]) (:func:`line_of_sight`; None or NaN: each satellite tested alone,
    the elevation taken as 90°), ``sigma`` = (zenith Doppler σ [m/s], phase σ [m]: scalar or (T, S))."""
    L = np.asarray(phase_cycles, float)
    T, S = L.shape
    dphi = np.full((T, S), np.nan)
    slip = np.zeros((T, S), np.int64)
    if T < 2:
        return dphi, slip
    dt = np.diff(np.asarray(time, float))[:, None]
    lam = np.broadcast_to(np.asarray(wavelength, float), (S,))
    d = lam * (L[1:] - L[:-1])
    lost = (np.asarray(lli, np.int64)[1:] & 1) == 1
    rr = np.asarray(range_rate, float)
    s = d - 0.5 * (rr[1:] + rr[:-1]) * dt
    ok = np.isfinite(d)
    if slip_threshold_cycles is not None:
        with np.errstate(invalid="ignore"):
            bad = np.abs(s) > slip_threshold_cycles * lam
    else:
        los, elev = geometry if geometry is not None else (None, None)
        bad = slip_outliers(s, ok & ~lost, np.broadcast_to(slip_sigma2(dt, elev, sigma), s.shape), los,
                            false_alarm)
    slip[1:][ok & lost] = 1
    slip[1:][ok & ~lost & bad] = 2
    dphi[1:] = np.where(ok & (slip[1:] == 0), d, np.nan)
    return dphi, slip


def slip_sigma2(dt, elevation, sigma):
    """Variance [m²] (T−1, S) of the phase–Doppler statistic s = λΔL − ½(ρ̇_{k−1} + ρ̇_k)Δt from the stated
    noises alone (module doc): (Δt²/4)(σ_ρ̇(E_{k−1})² + σ_ρ̇(E_k)²) + σ_φ,k−1² + σ_φ,k², σ_ρ̇(E) the zenith
    Doppler σ times √(½ + ½/sin²E) (E clamped at 2°; NaN elevation: the zenith's). dt (T−1, 1) [s];
    elevation (T, S) [rad] or None; sigma = (zenith Doppler σ [m/s], phase σ [m]: scalar or (T, S))."""
    sr, sp = sigma
    if elevation is None:
        fac2 = np.ones((1, 1))
    else:
        s = np.sin(np.maximum(np.where(np.isfinite(elevation), elevation, 0.5 * np.pi), 0.035))
        fac2 = 0.5 + 0.5 / (s * s)
    fac2 = np.broadcast_to(fac2, (dt.shape[0] + 1, fac2.shape[1]))
    v_rate = 0.25 * dt**2 * sr**2 * (fac2[1:] + fac2[:-1])
    sp2 = np.asarray(sp, float) ** 2
    v_phase = 2.0 * sp2 if np.ndim(sp2) == 0 else sp2[1:] + sp2[:-1]
    return v_rate + v_phase


def slip_outliers(s, cand, var, los=None, false_alarm: float = SLIP_FALSE_ALARM):
    """The phase–Doppler test's alarms (T−1, S) bool (module doc, "Cycle slips") on the statistic ``s``
    (T−1, S) [m] of the candidates ``cand`` (T−1, S) (both phases, no lost lock), its stated variance ``var``
    (T−1, S) [m²] (:func:`slip_sigma2`). ``los`` (T, S, 3): unit vectors receiver → satellite at each epoch
    (None or NaN: that satellite is tested alone). ``false_alarm``: the probability that an increment with
    no slip is flagged; the thresholds are :func:`slip_threshold`'s of the run's own statistics (the whole
    run's, taken before the test: not causal): the studentized residuals of one fit per interval for the
    geometric test, s/σ for the satellite-by-satellite one."""
    n_int, S = s.shape
    bad = np.zeros((n_int, S), bool)
    c = cand & np.isfinite(s)
    if not c.any():
        return bad
    geo = c & (np.isfinite(los[1:]).all(axis=2) if los is not None else False)
    geo &= (geo.sum(axis=1) >= 6)[:, None]
    rows = np.flatnonzero(geo.any(axis=1))
    t_geo = [_studentized(s[k], np.flatnonzero(geo[k]), var[k], los[k + 1])[0] for k in rows]
    z_geo = slip_threshold(np.concatenate(t_geo) if t_geo else np.zeros(0), false_alarm)
    for k in rows:
        bad[k, _snoop(s[k], geo[k], var[k], los[k + 1], z_geo)] = True
    z_alone = slip_threshold(s[c] / np.sqrt(var[c]), false_alarm, SLIP_TAIL_TRIM_ALONE)
    with np.errstate(invalid="ignore"):
        bad |= c & ~geo & (np.abs(s) > z_alone * np.sqrt(var))
    return bad


def slip_threshold(z, false_alarm: float = SLIP_FALSE_ALARM, trim: float = SLIP_TAIL_TRIM) -> float:
    """The two-sided threshold on a statistic ``z`` stated in units of its stated σ (a run's sample,
    slips among them) at which an increment without a slip is flagged with probability ``false_alarm``
    (module doc, "Cycle slips"): a Student-t of ν degrees of freedom and scale a, ν where the excess
    kurtosis of the sample within ``trim`` robust SDs (1.4826 MAD) of its median is the t's truncated
    the same way (normal where it is no larger than the normal's), a from the median absolute deviation
    (MAD = a·t_ν(0.75)); its variance a²ν/(ν − 2) floored at :data:`SLIP_VARIANCE_FLOOR` (the stated σ
    at most √10 times the run's). Fewer than :data:`SLIP_MIN_SAMPLE` values: the normal quantile on the
    stated σ."""
    z = np.asarray(z, float)
    z = z[np.isfinite(z)]
    if z.size < SLIP_MIN_SAMPLE:
        return NormalDist().inv_cdf(1.0 - 0.5 * false_alarm)
    d = z - np.median(z)
    mad = float(np.median(np.abs(d)))
    if mad <= 0.0:
        return NormalDist().inv_cdf(1.0 - 0.5 * false_alarm)
    y = d[np.abs(d) <= trim * 1.4826 * mad]
    nu = _student_dof(float(np.mean(y**4) / np.mean(y**2) ** 2 - 3.0), trim)
    if np.isinf(nu):
        q75, q = NormalDist().inv_cdf(0.75), NormalDist().inv_cdf(1.0 - 0.5 * false_alarm)
        var_ratio = 1.0
    else:
        from scipy.special import stdtrit  # lazy: the slip test's Student-t quantiles only

        q75, q = float(stdtrit(nu, 0.75)), float(stdtrit(nu, 1.0 - 0.5 * false_alarm))
        var_ratio = nu / (nu - 2.0)
    a2 = max((mad / q75) ** 2 * var_ratio, SLIP_VARIANCE_FLOOR) / var_ratio
    return q * np.sqrt(a2)


def _truncated_kurtosis(nu: float, trim: float) -> float:
    """Excess kurtosis of a Student-t of ``nu`` degrees of freedom (inf: the normal) truncated at ``trim``
    robust SDs (1.4826 MAD) of its centre (numerical moments)."""
    if np.isinf(nu):
        c = trim * 1.4826 * NormalDist().inv_cdf(0.75)
        x = np.linspace(-c, c, 4001)
        f = np.exp(-0.5 * x * x)
    else:
        from scipy.special import stdtrit  # lazy: the slip test's Student-t quantiles only

        c = trim * 1.4826 * float(stdtrit(nu, 0.75))
        x = np.linspace(-c, c, 4001)
        f = (1.0 + x * x / nu) ** (-0.5 * (nu + 1.0))
    m0, m2, m4 = (np.trapezoid(x**p * f, x) for p in (0, 2, 4))
    return float(m4 * m0 / m2**2 - 3.0)


def _student_dof(kurt: float, trim: float) -> float:
    """The degrees of freedom ν in [2.5, 300] whose truncated kurtosis (:func:`_truncated_kurtosis`) is
    ``kurt`` (bisection on log ν; the kurtosis falls with ν); inf at or below ν = 300's."""
    if kurt <= _truncated_kurtosis(300.0, trim):
        return np.inf
    lo, hi = np.log(2.5), np.log(300.0)
    if kurt >= _truncated_kurtosis(2.5, trim):
        return 2.5
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        if _truncated_kurtosis(float(np.exp(mid)), trim) > kurt:
            lo = mid
        else:
            hi = mid
    return float(np.exp(0.5 * (lo + hi)))


def _studentized(s, idx, var, los):
    """The weighted least-squares fit of s_j = e_j·δ + c over the satellites ``idx`` (module doc): the
    studentized residuals r_j/√(var_j(1 − h_j)) and the leverages h."""
    H = np.column_stack([los[idx], np.ones(len(idx))])
    w = 1.0 / var[idx]
    Q = np.linalg.inv(H.T @ (w[:, None] * H))
    r = s[idx] - H @ (Q @ (H.T @ (w * s[idx])))
    h = w * np.einsum("ij,jk,ik->i", H, Q, H)
    return r * np.sqrt(w / np.maximum(1.0 - h, 1e-9)), h


def _snoop(s, use, var, los, z):
    """Data snooping (Baarda) of one interval: the fit of :func:`_studentized` over the satellites ``use``,
    the largest studentized residual flagged while above ``z`` and two or more degrees of freedom remain
    (with one, every residual has the same studentized value: none can be singled out). Returns the
    flagged indices."""
    idx = list(np.flatnonzero(use))
    flagged = []
    while True:
        t = np.abs(_studentized(s, idx, var, los)[0])
        i = int(np.argmax(t))
        if t[i] <= z or len(idx) - 4 < 2:
            return flagged
        flagged.append(idx.pop(i))


def line_of_sight(sat_pos, rx_pos):
    """Unit vectors receiver → satellite (T, S, 3) and elevations (T, S) [rad] of the satellites at
    ``sat_pos`` (T, S, 3) ECEF [m] seen from ``rx_pos`` (T, 3) ECEF [m] (NaN where either is missing; the
    receiver's metres of error do not matter). The up direction is the geodetic normal at the receiver."""
    sp = np.asarray(sat_pos, float)
    rp = np.asarray(rx_pos, float)
    d = sp - rp[:, None, :]
    los = d / np.linalg.norm(d, axis=2, keepdims=True)
    up = np.full(rp.shape, np.nan)
    for k in np.flatnonzero(np.isfinite(rp).all(axis=1)):
        lat, lon, _ = ecef_to_lla(rp[k, 0], rp[k, 1], rp[k, 2])
        up[k] = dcm_ecef_to_enu(lat, lon)[2]
    return los, np.arcsin(np.clip(np.einsum("tsi,ti->ts", los, up), -1.0, 1.0))


def slip_geometry(obs, eph, positions_ecef):
    """:func:`line_of_sight` of the observations' satellites (positions at the transmit times their
    pseudoranges imply, :func:`aidnav.nav.gnss_sat.satellites_from_pseudoranges`) from the prior receiver
    positions ``positions_ecef`` (T, 3) (e.g. SPP; NaN: none, then the nearest epoch's), for
    :func:`phase_increments`' test."""
    T, S = obs.code1.shape
    sp = np.full((T, S, 3), np.nan)
    for k in range(T):
        sp[k] = satellites_from_pseudoranges(eph.table, obs.prn, obs.time[k], obs.code1[k])[0]
    return line_of_sight(sp, _nearest_finite(positions_ecef))


def _nearest_finite(pos):
    """Each epoch's position (T, 3), NaN rows replaced by the next finite one (the last finite at the end;
    all NaN: unchanged)."""
    pos = np.asarray(pos, float)
    fin = np.flatnonzero(np.isfinite(pos).all(axis=1))
    if not fin.size:
        return pos
    return pos[fin[np.clip(np.searchsorted(fin, np.arange(len(pos))), 0, len(fin) - 1)]]


def receiver_windup(rs, rr, c_ae) -> float:
    """Receiver phase wind-up [cycles] in (−½, ½] of an antenna at ``rr`` (3,) ECEF [m] whose axes are the
    columns of ``c_ae`` (3, 3) (antenna → ECEF; x̂, ŷ the dipoles, ẑ the boresight), for the satellite at
    ``rs`` (3,) ECEF [m] (module doc; the satellite's half fixed)."""
    k = np.asarray(rr, float) - np.asarray(rs, float)
    k /= np.linalg.norm(k)
    c = np.asarray(c_ae, float)
    exr, eyr = c[:, 0], c[:, 1]
    dr = exr - k * (k @ exr) + np.cross(k, eyr)
    # the satellite's reference dipoles: ŷ_s ⊥ (ECEF z, k), x̂_s = ŷ_s × k (any smooth choice: it cancels)
    eys = np.cross(np.array([0.0, 0.0, 1.0]), k)
    eys /= np.linalg.norm(eys)
    exs = np.cross(eys, k)
    ds = exs - k * (k @ exs) - np.cross(k, eys)
    cosp = float(np.clip(ds @ dr / (np.linalg.norm(ds) * np.linalg.norm(dr)), -1.0, 1.0))
    ph = np.arccos(cosp) / (2.0 * np.pi)
    return -ph if k @ np.cross(ds, dr) < 0.0 else ph


def windup_increments(sat_pos, rx_pos, c_ae, wavelength=LAMBDA_L1):
    """λΔφ_w [m] (T, S) of the receiver wind-up between consecutive epochs (row k: from k−1 to k; row 0
    and missing inputs NaN), to subtract from the phase increments λΔL. sat_pos (T, S, 3), rx_pos (T, 3)
    ECEF [m]; c_ae (T, 3, 3) antenna (body) → ECEF; wavelength scalar or (S,) [m]. An increment is taken
    modulo one cycle into (−½, ½]: rotations of less than half a turn per interval (a walker at 4 Hz turns
    at most a few rad/s)."""
    sp = np.asarray(sat_pos, float)
    T, S = sp.shape[:2]
    w = np.full((T, S), np.nan)
    for k in range(T):
        if not (np.isfinite(rx_pos[k]).all() and np.isfinite(c_ae[k]).all()):
            continue
        for j in range(S):
            if np.isfinite(sp[k, j]).all():
                w[k, j] = receiver_windup(sp[k, j], rx_pos[k], c_ae[k])
    d = np.full((T, S), np.nan)
    d[1:] = w[1:] - w[:-1]
    d[1:] -= np.round(d[1:])
    return d * np.broadcast_to(np.asarray(wavelength, float), (S,))


def tdcp_displacement(rs_prev, rs_cur, r_prev, y_phase, sigma_phase_m=0.005, with_chi2: bool = False):
    """Receiver displacement Δr (3,) [m] and clock change Δb [m] between two epochs (module doc).

    rs_prev, rs_cur (S, 3) satellite ECEF at the two epochs [m]; r_prev (3,) prior receiver position at the
    first epoch; y_phase (S,) λΔL + Δ(c·dt_s) [m] (NaN: not used); sigma_phase_m the phase σ per epoch [m],
    scalar or (S,) per satellite (weighted least squares). Returns (x (4,) = [Δr, Δb], cov (4, 4), used
    (S,) bool) — with ``with_chi2`` also the weighted residual sum of squares rᵀWr (χ²(n − 4) when the σ
    are right) — or None with fewer than 4 satellites."""
    rs_prev = np.asarray(rs_prev, float)
    rs_cur = np.asarray(rs_cur, float)
    r0 = np.asarray(r_prev, float)
    used = np.isfinite(y_phase) & np.isfinite(rs_prev).all(axis=1) & np.isfinite(rs_cur).all(axis=1)
    if used.sum() < 4:
        return None
    H, z = [], []
    for j in np.flatnonzero(used):
        r1, e = geo_range(rs_cur[j], r0)
        r0j, _ = geo_range(rs_prev[j], r0)
        H.append([-e[0], -e[1], -e[2], 1.0])
        z.append(y_phase[j] - (r1 - r0j))
    H = np.array(H)
    w = 1.0 / (2.0 * np.broadcast_to(np.asarray(sigma_phase_m, float), used.shape)[used] ** 2)
    N = H.T @ (w[:, None] * H)
    if np.linalg.cond(N) > 1e12:
        return None
    Q = np.linalg.inv(N)
    x = Q @ H.T @ (w * np.array(z))
    if with_chi2:
        r = np.array(z) - H @ x
        return x, Q, used, float(np.sum(w * r * r))
    return x, Q, used


def running_variance_factor(chi2, dof) -> np.ndarray:
    """The a-posteriori variance factor of a series of least-squares solutions, causal: at each one
    Σ rᵀWr / Σ dof over it and the earlier ones (``chi2`` (K,), NaN: no solution; ``dof`` (K,) its degrees of
    freedom), floored at 1 (the stated σ are a lower bound; 1 before any degree of freedom). With the stated σ
    k times too small the factor tends to k² (the weighted residuals are k²·χ²(dof))."""
    c = np.cumsum(np.where(np.isfinite(chi2), chi2, 0.0))
    d = np.cumsum(np.where(np.isfinite(chi2), np.asarray(dof, float), 0.0))
    return np.where(d > 0, np.maximum(1.0, c / np.maximum(d, 1.0)), 1.0)


def tdcp_series(obs, eph, positions_ecef, sigma_phase_m: float = 0.005,
                slip_threshold_cycles: float | None = None, attitude=None, variance_factor: bool = True,
                rate_sigma_m_s: float = SLIP_RATE_SIGMA_M_S, slip_false_alarm: float = SLIP_FALSE_ALARM):
    """TDCP mean velocities of a whole observation set: dict with t_mid (T−1,) [s], vel_enu (T−1, 3) [m/s],
    vel_cov_enu (T−1, 3, 3), drift (T−1,) [m/s], n_used (T−1,), slips (T, S) codes of
    :func:`phase_increments`, windup (T, S) the wind-up increments removed [m] (zeros without
    ``attitude``), variance_factor (T−1,) the factor applied to each covariance (module doc; 1 where
    none). positions_ecef (T, 3): prior receiver positions (e.g. SPP; NaN: none). attitude (T, 3, 3):
    optional antenna (= body) → ECEF rotation at each epoch: the receiver wind-up is then removed from the
    phase increments (:func:`windup_increments`).

    **Weights and σ**: each phase's σ is the receiver's own (``obs.phase_sigma1``, u-blox cpStdev) where
    given, else ``sigma_phase_m``; an increment's variance is the sum of its two epochs' (σ_{k−1}² + σ_k²).
    With ``variance_factor`` the covariance is scaled by the a-posteriori variance factor of the least
    squares so far, Σ rᵀWr / Σ (n − 4) over this and the earlier intervals (causal, no constant; floored at
    1: the stated σ are a lower bound). The receiver's cpStdev is its tracking loop's noise: on the shared
    walk it orders the phases' errors (their residual against the RTK displacement grows from 5 to 31 mm
    as it grows from 1 to 10 mm) but it is ~3× too small in scale (multipath, a hand-held antenna in
    turns), which is what the factor measures (docs/results.md, issue 40 session 15)."""
    if obs.phase1 is None:
        raise ValueError("no L1 carrier phase in the observations")
    eph = eph.to_week(obs.ref_week) if eph.ref_week != obs.ref_week else eph
    obs = obs.with_frequencies(eph)  # wavelengths per satellite (GLONASS channels from the records)
    T, S = obs.code1.shape
    sp = np.full((T, S, 3), np.nan)
    sc = np.full((T, S), np.nan)
    for k in range(T):
        sp[k], _, sc[k], _ = satellites_from_pseudoranges(eph.table, obs.prn, obs.time[k], obs.code1[k])
    pos = np.asarray(positions_ecef, float)
    sig = np.full((T, S), float(sigma_phase_m)) if np.ndim(sigma_phase_m) == 0 else \
        np.broadcast_to(np.asarray(sigma_phase_m, float), (T, S))
    if obs.phase_sigma1 is not None:
        sig = np.where(np.isfinite(obs.phase_sigma1) & (obs.phase_sigma1 > 0), obs.phase_sigma1, sig)
    dphi, slips = phase_increments(obs.time, obs.phase1, obs.lli1, obs.range_rate(), slip_threshold_cycles,
                                   obs.wavelengths(), line_of_sight(sp, _nearest_finite(pos)),
                                   (rate_sigma_m_s, sig), slip_false_alarm)
    wind = np.zeros((T, S))
    if attitude is not None:  # the line of sight from the nearest prior position (metres do not matter)
        fin = np.flatnonzero(np.isfinite(pos).all(axis=1))
        near = fin[np.clip(np.searchsorted(fin, np.arange(T)), 0, len(fin) - 1)] if fin.size else np.arange(T)
        wind = windup_increments(sp, pos[near], np.asarray(attitude, float), obs.wavelengths())
        dphi = dphi - np.where(np.isfinite(wind), wind, 0.0)
    out = dict(t_mid=0.5 * (obs.time[1:] + obs.time[:-1]), vel_enu=np.full((T - 1, 3), np.nan),
               vel_cov_enu=np.full((T - 1, 3, 3), np.nan), drift=np.full(T - 1, np.nan),
               n_used=np.zeros(T - 1, np.int64), slips=slips, windup=wind, variance_factor=np.ones(T - 1))
    chi2 = np.full(T - 1, np.nan)
    dof = np.zeros(T - 1, np.int64)
    for k in range(1, T):
        r0 = pos[k - 1] if np.isfinite(pos[k - 1]).all() else pos[k]
        if not np.isfinite(r0).all():
            continue
        y = dphi[k] + (sc[k] - sc[k - 1])
        # the increment's σ as tdcp_displacement takes it (its variance 2σ² = σ_{k−1}² + σ_k²)
        sol = tdcp_displacement(sp[k - 1], sp[k], r0, y, np.sqrt(0.5 * (sig[k - 1] ** 2 + sig[k] ** 2)), True)
        if sol is None:
            continue
        x, cov, used, chi2[k - 1] = sol
        dof[k - 1] = int(used.sum()) - 4
        if variance_factor:
            out["variance_factor"][k - 1] = running_variance_factor(chi2[:k], dof[:k])[-1]
            cov = cov * out["variance_factor"][k - 1]
        dt = obs.time[k] - obs.time[k - 1]
        lat, lon, _ = ecef_to_lla(r0[0], r0[1], r0[2])
        C = dcm_ecef_to_enu(lat, lon)
        out["vel_enu"][k - 1] = C @ x[:3] / dt
        out["vel_cov_enu"][k - 1] = C @ cov[:3, :3] @ C.T / dt**2
        out["drift"][k - 1] = x[3] / dt
        out["n_used"][k - 1] = int(used.sum())
    return out


#: the order of the moving average a second difference of the TDCP positions makes of white phase noise:
#: a_k shares the phase epochs k − 1, k, k + 1 with a_{k±1} and a_{k±2} (correlation −2/3 and 1/6)
MA_ORDER = 2


def slope_variance_ma(x, e, idx, order: int, w=None) -> float:
    """Variance of a (weighted) least-squares slope Σwxy/Σwx² whose errors are a moving average of
    ``order``: the truncated-kernel (uniform weights) sandwich Σ_i Σ_{|idx_i − idx_j| ≤ order} w_i x_i e_i
    w_j x_j e_j / (Σwx²)² (Hansen–Hodrick), ``x`` the regressor, ``e`` the residuals, ``w`` the weights
    (None: 1), ``idx`` (increasing integers) the epochs: only pairs whose epochs are at most ``order`` apart
    count (not neighbours in the arrays across a gap); never below the white sandwich Σw²x²e²/(Σwx²)² (the
    truncated sum is not bound to be positive).

    Why not Newey–West's Bartlett weights (1 − l/(L+1)): they shrink the lag-1 and lag-2 autocovariances,
    which are exact here, not estimation noise to damp; with a regressor that alternates in sign from epoch
    to epoch (a walker's steps at 1.9 Hz seen at 4 Hz) the negative autocovariances (−2/3, 1/6 of white phase
    noise differenced twice) add (1 + 4/3 + 1/3 = 8/3 times the white variance at most) and the shrunk sum
    left the σ of :func:`imu_time_offset` 1.24× small over 120 simulated walks (issue 40, session 17)."""
    x, e, idx = np.asarray(x, float), np.asarray(e, float), np.asarray(idx, np.int64)
    w = np.ones_like(x) if w is None else np.asarray(w, float)
    xe = w * x * e
    white = float(np.sum(xe * xe))
    var = white
    for lag in range(1, order + 1):
        i = np.flatnonzero(np.isin(idx + lag, idx))
        var += 2.0 * float(np.sum(xe[i] * xe[np.searchsorted(idx, idx[i] + lag)]))
    return max(var, white) / max(float(np.sum(w * x * x)), 1e-30) ** 2


#: the variance ratio (to the median epoch's) above which :func:`imu_time_offset` down-weighs an epoch (1:
#: every epoch above the median; 9, a σ 3× the typical one, left SD z 1.14 on the simulated pedestrian)
NORM_WEIGHT_RATIO = 1.0


def _norm_weights(a, vel_cov, k, delta):
    """Weights (n,) of the TDCP specific-force norms at the epochs ``k`` (:func:`imu_time_offset`): 1 without
    ``vel_cov``, else min(1, r·median V / V_k) with V_k = uᵀ(C_k + C_{k−1})u/Δ², u = a/‖a‖,
    r = :data:`NORM_WEIGHT_RATIO` (0 where V is not finite or not positive)."""
    if vel_cov is None:
        return np.ones(len(k))
    C = np.asarray(vel_cov, float)
    u = a / np.linalg.norm(a, axis=1)[:, None]
    var = np.einsum("ki,kij,kj->k", u, C[k] + C[k - 1], u) / delta ** 2
    good = np.isfinite(var) & (var > 0)
    if not good.any():
        return np.zeros(len(k))
    ref = NORM_WEIGHT_RATIO * np.median(var[good])
    return np.where(good, np.minimum(1.0, ref / np.where(good, var, 1.0)), 0.0)


def imu_time_offset(imu, t_epoch, vel_mean, gravity_m_s2: float, max_lag_s: float = 0.2,
                    step_s: float = 0.001, min_epochs: int = 40, vel_cov=None):
    """The IMU-GNSS time offset d [s] to add to the IMU stamps, from the specific force's **norm**, which
    the IMU and the carrier phase both give without an attitude (a walker's steps: ±2–3 m/s² at 2 Hz).

    GNSS side: the TDCP mean velocities ``vel_mean`` (K, 3) ENU [m/s] over the intervals [t_k, t_{k+1}]
    of ``t_epoch`` (K + 1,) [s] give at each inner epoch of two equal intervals Δ the second difference of
    position, a_k = (v̄_k − v̄_{k−1})/Δ: the acceleration seen through a triangle kernel Λ of half-width Δ
    (unit area, centred on t_k: no lag), and the specific force's norm s_k = ‖a_k − g^n‖ − g (g^n =
    (0, 0, −``gravity_m_s2``)). IMU side: f^b = Δv/Δt through the same kernel — the second difference of
    its double integral P(t) = ∫∫f^b, (P(t + Δ) − 2P(t) + P(t − Δ))/Δ² — at the stamps t_k − d, each f^b
    turned into the body frame at t_k by the gyro's angle θ (small turns: f + (θ(s) − θ(t_k)) × f, so
    that the kernel mean is of one frame's vector), and its norm minus g. For each lag d
    on a grid of ``step_s`` over ±``max_lag_s`` the least squares s_k = α·s_imu,k(d) + β (α absorbs the
    accelerometer's scale, β its bias along the force); d̂ is the least residual, refined by a parabola
    through its neighbours; its σ the linearised slope's (x = α ∂s/∂d) with the residuals' correlation of
    the second difference counted (:func:`slope_variance_ma`, order :data:`MA_ORDER`).

    **Weights** (``vel_cov`` (K, 3, 3), the TDCP velocities' covariance, e.g. :func:`tdcp_series`'s
    ``vel_cov_enu``; None: all epochs alike): with V_k = uᵀ(C_k + C_{k−1})u/Δ² (u the force's direction: the
    variance of s_k the least squares of the two intervals state; the cross-covariance of their shared
    phase epoch is left out, it is the MA part the σ counts) each a_k weighs min(1, r·median V / V_k),
    r = :data:`NORM_WEIGHT_RATIO` — epochs stated noisier than the median are down-weighted, none is
    up-weighted (on the walk the stated σ spans 0.02–28× the median in variance: the receiver's cpStdev
    orders the phases' errors but not on this scale, issue 40 session 15). An interval solved from a few
    satellites (on the simulated pedestrian 1.6 % of the intervals keep 4–6 of 17: the slip test fails most
    of them at once, with the phase noise-free too) has a vertical acceleration σ of ~1 m/s² against
    0.2 m/s²: unweighted, those epochs made the residuals' kurtosis 118 and one epoch up to 65 % of the
    sandwich, whose σ then scattered from seed to seed (the variance's CV 0.66) and fell 1.14× short over
    seeds 0–119; weighted, CV 0.22, SD z 1.10 (seeds 120–239: 1.12 either way, the σ still ≈ 10 % small;
    issue 40, session 18; `aidnav tight` does not pass ``vel_cov``:
    on the walk it moves d̂ from −22 to −37 ms and the smoothed velocity's N ratio from 1.20 to 1.23).
    Returns (d̂, σ_d, n epochs) or None (fewer than ``min_epochs`` usable epochs, or the least residual on
    the grid's edge)."""
    t_e = np.asarray(t_epoch, float)
    v = np.asarray(vel_mean, float)
    dt_i = np.diff(t_e)
    k = np.arange(1, len(t_e) - 1)
    ok = (np.isfinite(v[k]).all(axis=1) & np.isfinite(v[k - 1]).all(axis=1)
          & (np.abs(dt_i[k] - dt_i[k - 1]) < 1e-3 * dt_i[k]))
    k = k[ok]
    delta = dt_i[k]
    a = (v[k] - v[k - 1]) / delta[:, None]
    a[:, 2] += gravity_m_s2
    s_g = np.linalg.norm(a, axis=1) - gravity_m_s2
    w = _norm_weights(a, vel_cov, k, delta)
    if np.count_nonzero(w > 0) < min_epochs:
        return None
    t_imu = np.concatenate([[imu.t0], imu.time])
    dth = getattr(imu, "dtheta", None)
    th = np.vstack([np.zeros(3), np.cumsum(np.zeros_like(imu.dv) if dth is None else dth, axis=0)])
    th_mid = 0.5 * (th[1:] + th[:-1])  # the rotation angle at each increment's middle

    def double_integral(inc):  # ∫∫ of the increments' rate, at the sample times
        v = np.vstack([np.zeros(3), np.cumsum(inc, axis=0)])
        return np.vstack([np.zeros(3), np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t_imu)[:, None], axis=0)])

    pos = double_integral(imu.dv)
    pos_rot = double_integral(np.cross(th_mid, imu.dv))  # ∫∫ θ × f: the turn within the kernel (below)

    def at(p, tc):
        return np.column_stack([np.interp(tc, t_imu, p[:, i], left=np.nan, right=np.nan) for i in range(3)])

    def s_imu(d):
        # the kernel mean of f in the body frame at t_k (small turns: f_t = f_s + (θ_s − θ_t) × f_s)
        tc = t_e[k] - d
        sec = [(at(pos, tc - delta) - 2.0 * at(pos, tc) + at(pos, tc + delta)) / delta[:, None] ** 2
               for pos in (pos, pos_rot)]
        f = sec[0] + sec[1] - np.cross(at(th, tc), sec[0])
        return np.linalg.norm(f, axis=1) - gravity_m_s2

    lags = np.arange(-max_lag_s, max_lag_s + 0.5 * step_s, step_s)
    inside = np.isfinite(s_imu(-max_lag_s)) & np.isfinite(s_imu(max_lag_s)) & (w > 0)
    if inside.sum() < min_epochs:
        return None
    y, wi = s_g[inside], w[inside]
    sw = np.sqrt(wi)
    rss = np.full(lags.size, np.inf)
    fits = []
    for j, d in enumerate(lags):
        x = s_imu(d)[inside]
        A = np.column_stack([x, np.ones_like(x)])
        c, *_ = np.linalg.lstsq(A * sw[:, None], y * sw, rcond=None)
        rss[j] = float(np.sum(wi * (y - A @ c) ** 2))
        fits.append(c)
    j = int(np.argmin(rss))
    if j == 0 or j == lags.size - 1:
        return None
    r0, r1, r2 = rss[j - 1], rss[j], rss[j + 1]
    den = r0 - 2.0 * r1 + r2
    d_hat = lags[j] + (0.5 * step_s * (r0 - r2) / den if den > 0 else 0.0)
    alpha, beta = fits[j]
    x = alpha * (s_imu(lags[j] + step_s)[inside] - s_imu(lags[j] - step_s)[inside]) / (2.0 * step_s)
    e = y - alpha * s_imu(lags[j])[inside] - beta
    sigma = float(np.sqrt(slope_variance_ma(x, e, k[inside], MA_ORDER, wi)))
    return float(d_hat), sigma, int(y.size)
