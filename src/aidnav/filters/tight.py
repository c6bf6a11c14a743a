"""Tightly coupled GNSS/INS on the filter engine (:mod:`aidnav.filters.engine`): closed-loop error-state
EKF with pseudorange and pseudorange-rate updates, and its RTS smoother.

Frames and units: n = ENU, b = RFU (IMU), e = ECEF; strapdown state (lat, lon [rad], h [m], v^n [m/s],
q_b^n); receiver clock bias b [m] and drift d [m/s]; GNSS times are receiver tags on the GPS
reference-week scale, IMU times on the same GPS scale.

**States** (§2.1, seed eq. 8): ``states=11`` = [φ, δv, δL δλ δh, δt_u, δf] (the seed's model),
``states=17`` = [φ, δv, δp, ε (gyro bias), ∇ (accel bias), δt_u, δf]: the layout of
:mod:`aidnav.filters.layout` with the clock block (``L_CLK``) after the INS block of 9 or 15 states
(21 with ``imu.scale_factors``, 27 with ``imu.gyro_misalignment``, 33 with ``imu.accel_misalignment``: the
loose filter's sensor states, so
free inertia — an outage, too few satellites — grows with the full error model, issue 35 item 3). Without
an ``imu`` section the model is that of an IMU of unknown grade (:data:`.config.UNKNOWN_GRADE_IMU`:
Groves' consumer row through :func:`.tuning.sensor_error_model`, 27 states, noise raised to the log's
static samples), also under the car preset; under a preset without the NHC (aircraft, pedestrian, ship) with
the accelerometer misalignment as states (:data:`.config.UNKNOWN_GRADE_IMU_ACCEL_MISALIGNMENT`, 33);
δt_u = b − b̂ [m], δf = d − d̂ [m/s] (true − estimated, ρ_GPS = ρ_true + b). Clock dynamics: δṫ_u = δf +
w_b, δḟ = −δf/τ_f + w_d (τ_f ≤ 0: random walk), PSDs S_b = c²h₀/2, S_d = c²·2π²h₋₂ (Allan
coefficients of the receiver oscillator). With ``gnss.range_errors`` (default) one more state per satellite
with a usable ephemeris (``L_RERR``): its pseudorange error in units of σ_j(E), RTKLIB's single-frequency
budget (:func:`aidnav.nav.gnss_sat.range_error_sigma`), a unit-variance Gauss-Markov process of
correlation time ``range_error_tau_s`` (docs/models.md §6.3); with four satellites the position σ then
says what the range errors can do to it.

**Every constellation** (issue 40): Galileo, BeiDou and GLONASS satellites of the observations (ids of
:mod:`aidnav.nav.gnss_sat`) enter like GPS ones; one inter-system bias state per non-GPS system with a
usable satellite (``L_ISB``, after the clock: that system's receiver clock − the GPS clock [m], random walk
of PSD ``isb_psd_m2_s``, initial σ ``isb_sigma_m``; rates share the drift), a σ factor per system
(``system_sigma_factor``, RTKLIB's EFACT_*) and the Klobuchar delay scaled by (f_L1/f)² of the satellite's
signal (GLONASS per channel).

**Measurements**: each GNSS epoch is one engine record (:mod:`aidnav.filters.measurements.epoch`): due at
the receive time t_tag − b̂/c, the INS antenna moved back to it; clock start and jumps (median residual
beyond ``clock_jump_m``) re-initialise b̂; mask, Klobuchar (RTKLIB's default coefficients when the
navigation file has none; σ 50 % of the delay) / dual-frequency ionosphere and Saastamoinen
troposphere at the INS position; one scalar row per pseudorange and per rate, gated by the χ²(1)
quantile of ``gate_probability``; after ``max_consecutive_rejections`` rejected epochs the next epoch is
not gated (the engine's rule). Any number of satellites is used: with fewer than four the clock and the
position are only partly observable, and the covariance says so. Satellite positions/clocks come from
the broadcast ephemerides at the transmit time implied by each pseudorange, before the engine. With
``phase_increments`` (the L1 phase increments between epochs with cycle slips removed, from
:mod:`aidnav.apps.tight`) each epoch record also holds one time-differenced carrier-phase (delta-range)
row per satellite against four clone states of the previous epoch's antenna position and clock
(``L_TDCP``; :mod:`.measurements.epoch`). Optional velocity records (``velocity_fixes``, e.g. TDCP mean
velocities) go through the loosely coupled filter's GNSS velocity model. ZUPTs (and ZARU)
at static samples and the NHC (``constraints``, the ``process`` schema; ``apply_vehicle`` for the
vehicle presets) are the engine's node constraints. The engine feeds back after each node and, with
``smooth``, runs the RTS pass over the nodes (no information passed back across a heading reset).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from aidnav.nav.earth import gravity, radii
from aidnav.nav.gnss_sat import C_LIGHT, iono_fallback_note, klobuchar_coefficients
from aidnav.nav.rotations import dcm_from_euler, quat_from_euler
from aidnav.units import DEG

from . import measurements as ms
from .chi2 import chi2_isf as _chi2_isf
from .config import (
    UNKNOWN_GRADE_IMU,
    UNKNOWN_GRADE_IMU_ACCEL_MISALIGNMENT,
    Constraints,
    FilterSettings,
    ImuNoise,
    Initialisation,
)
from .engine import NEVER, Init, Models, Output, Process, run_filter
from .ins_errors import noise_count
from .layout import L_CLK, L_ISB, L_N, L_NINS, L_RERR, L_SIZE, L_TDCP
from .loose import LooseResult
from .loose import to_trajectory as nav_trajectory
from .measurements import epoch as ep
from .output_rows import whole_run_rows
from .prior import given_initial_state, initial_covariance, levelled_tilt_covariance, process_noise
from .smoother import rts, smooth_outputs
from .tight_input import (
    Arena,
    arena_bytes,
    epoch_outputs,
    epoch_records,
    epoch_rows,
    imu_input,
    imu_times,
    rejected_per_satellite,
    rotation_variance,
    timing_variance,
)

__all__ = ["CLOCK_GRADES", "RawGnssAiding", "TightConfig", "TightResult", "apply_vehicle", "clock_allan",
           "clock_drift_psd", "clock_hm2_from_psd",
           "rotation_variance", "run_tight", "tight_layout", "timing_variance",
           "tight_nav_covariance_m", "to_trajectory"]
N_CLONE = 4  # clone states of the time-differenced carrier phase: antenna position ECEF (3), clock bias


# Allan-variance coefficients (h0 [s], h-2 [1/s]) of receiver oscillators: Brown & Hwang, "Introduction to
# Random Signals and Applied Kalman Filtering", Table 9.1 (temperature-compensated crystal, ovenized
# crystal, rubidium); flicker (h-1) is not modelled
CLOCK_GRADES = {"tcxo": (2e-19, 2e-20), "ocxo": (8e-20, 4e-23), "rubidium": (2e-20, 4e-29)}


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class RawGnssAiding(_Strict):
    """How raw pseudoranges and rates are used (units in the names)."""

    lever_arm_m: tuple[float, float, float] = Field((0.0, 0.0, 0.0), description="IMU→antenna, body RFU [m]")
    code_sigma_m: float = Field(1.0, gt=0, description="zenith pseudorange σ; σ(E) = σ0 √(½+½/sin²E)")
    rate_sigma_m_s: float = Field(0.1, gt=0, description="zenith pseudorange-rate σ [m/s]")
    mask_deg: float = Field(10.0, description="elevation mask [deg]")
    use_rate: bool = True
    code_min_sats: int = Field(
        1,
        ge=1,
        description="use pseudoranges only at epochs with at least this many "
        "satellites (above the mask); 99 = rate (Doppler) updates only",
    )
    gate_probability: float = Field(0.9999, gt=0, le=1, description="per-satellite χ²(1) gate; 1 disables")
    max_consecutive_rejections: int = Field(20, ge=1, description="then the next epoch is not gated")
    iono: Literal["klobuchar", "none", "dual"] = "klobuchar"
    iono_window_s: float = Field(60.0, gt=0, description="smoothing window of the dual-frequency delay [s]")
    tropo: bool = True
    humidity: float = Field(0.7, ge=0, le=1)
    clock_grade: Literal["tcxo", "ocxo", "rubidium"] = Field(
        "tcxo", description="receiver oscillator: its Allan coefficients h0, h-2 (CLOCK_GRADES) unless "
        "clock_h0 / clock_hm2 are given; consumer receivers have a TCXO")
    clock_h0: float | None = Field(None, ge=0, description="white-frequency Allan coefficient h0 [s]")
    clock_hm2: float | None = Field(None, ge=0,
                                    description="random-walk-frequency Allan coefficient h-2 [1/s]")
    clock_from_log: bool = Field(
        True, description="raise the drift's random-walk PSD (h-2) to the wander of the log's own SPP clock "
        "drift (clock_drift_psd) where it exceeds the grade's; a given clock_hm2 is kept as given")
    clock_tau_s: float = Field(
        0.0, description="drift correlation time τ_f [s] (seed: Markov); <= 0 random walk"
    )
    clock_bias_sigma_m: float = Field(30.0, gt=0, description="σ of the initial clock bias [m]")
    clock_drift_sigma_m_s: float = Field(1.0, gt=0, description="σ of the initial clock drift [m/s]")
    clock_jump_m: float = Field(1.0e4, gt=0, description="median residual that re-initialises the clock [m]")
    max_eph_age_s: float = Field(7200.0, gt=0, description="|t − toe| limit of an ephemeris [s]")
    range_errors: bool = Field(
        True, description="per-satellite Gauss-Markov range-error states with the σ of RTKLIB's "
        "single-frequency error budget (URA, ionosphere, troposphere, code bias; docs/models.md)")
    range_error_tau_s: float = Field(1800.0, gt=0, description="correlation time of the range errors [s]")
    ubx_nav: str | None = Field(
        "auto", description="the receiver's UBX log whose broadcast ephemerides (RXM-SFRBX) are added to "
        "the navigation file's (aidnav.io.nav_sources): 'auto' the log the observation file's header names "
        "as its source (RTKLIB convbin's 'log:' comment) where it lies beside it or in its parent directory; "
        "'none' or null the navigation file alone; a path (relative to the configuration file) that log")
    systems: str = Field("GECR", pattern="^[GECRS]+$", description="satellite systems used where the "
                         "navigation file has their ephemerides (G GPS, E Galileo, C BeiDou, R GLONASS, "
                         "S SBAS ranging: on the GPS clock, σ factor 3; not in the default)")
    isb_sigma_m: float = Field(100.0, gt=0, description="σ of the initial inter-system biases (Galileo, "
                               "BeiDou, GLONASS receiver clock − the GPS one) [m]")
    isb_m: dict[str, float] = Field(default_factory=dict, description="initial inter-system biases "
                                    "{letter: m} of a receiver whose biases are known (give isb_sigma_m "
                                    "their σ); 0 for the others")
    isb_psd_m2_s: float = Field(1e-4, ge=0, description="random-walk PSD of the inter-system biases [m²/s]")
    system_sigma_factor: dict[str, float] = Field(
        default_factory=lambda: {"G": 1.0, "E": 1.0, "C": 1.0, "R": 1.5, "S": 3.0},
        description="zenith code and rate σ factor per system (RTKLIB's EFACT_*: GLONASS 1.5, SBAS 3)")
    use_phase: bool = Field(True, description="time-differenced L1 carrier phase (where the observations "
                            "have it), entered as tdcp_model says (aidnav tight)")
    tdcp_model: Literal["velocity", "rows"] = Field(
        "velocity", description="how the carrier phase enters: 'velocity', the TDCP mean velocity of each "
        "interval with 4+ unslipped satellites as a velocity record at its middle; 'rows', one delta-range "
        "row per satellite between consecutive epochs against clone states of the previous epoch (also with "
        "1-3 satellites; on the shared walk its height drifts 0.8 m in 134 s, vertical RMS 4.2 m against "
        "3.0 m: docs/results.md, issue 40 session 9)")
    phase_sigma_m: float = Field(0.005, gt=0, description="carrier-phase σ per epoch [m] where the receiver "
                                 "gives none (its cpStdev from the UBX log is used for the TDCP velocities "
                                 "where read: aidnav.io.rawx; the 'rows' model takes this one)")
    slip_threshold_cycles: float | None = Field(
        None, gt=0, description="a constant phase-Doppler disagreement that is a cycle slip [cycles] (the "
        "test before issue 40 session 17, 0.5 there); null: the statistical test at slip_false_alarm "
        "(aidnav.estimators.tdcp.phase_increments)")
    slip_false_alarm: float = Field(1e-3, gt=0, lt=0.5, description="probability that a phase increment "
                                    "without a slip is flagged by the phase-Doppler test (its threshold "
                                    "on the statistic over its stated sigma, rate_sigma_m_s and the "
                                    "phase's, a Student-t quantile with the tails and scale of the run's "
                                    "own statistics: aidnav.estimators.tdcp.slip_threshold)")
    time_offset_from_phase: bool = Field(
        True, description="where the configuration gives no imu.time_offset_s and TDCP velocities are used "
        "(aidnav tight): the IMU-GNSS time offset from the specific force's norm, which the IMU and the "
        "carrier phase both give without an attitude (aidnav.estimators.tdcp.imu_time_offset), as "
        "imu.time_offset_s, and its sigma as time_offset_sigma_s")
    time_offset_sigma_s: float = Field(
        0.0, ge=0, description="sigma of the IMU-GNSS time offset left after imu.time_offset_s [s] (the "
        "tight filter has no state for it): at each velocity record the velocity variance grows by "
        "(sigma·|Δf|)² per axis, Δf the IMU's specific-force change since the previous one — the velocity "
        "error a timing error δt leaves between them, δt·Δa (0: the offset is exact)")


@lru_cache(maxsize=64)
def chi2_isf(m: int, p: float) -> float:
    """The gates' χ²(m) quantile (:func:`.chi2.chi2_isf`), remembered: the same few per run."""
    return float(_chi2_isf(m, p))


def clock_allan(g: RawGnssAiding) -> tuple[float, float]:
    """(h0, h-2) of the receiver clock: the configured ones, else those of ``clock_grade``."""
    h0, hm2 = CLOCK_GRADES[g.clock_grade]
    return (h0 if g.clock_h0 is None else g.clock_h0), (hm2 if g.clock_hm2 is None else g.clock_hm2)


def clock_drift_psd(t, drift, max_frac: float = 0.25, min_pairs: int = 20):
    """The receiver clock's wander as the log's snapshot solutions show it: the PSD S_d [m²/s³] of a
    random-walk drift (δḟ = w_d) whose increments over a lag L have the variance of the drift series'
    own, E[(d(t+L) − d(t))²] = 2σ_n² + S_d·L (σ_n: the white noise of each snapshot drift, the Doppler's),
    fitted by least squares over the lags L = Δ, 2Δ, 4Δ, … up to ``max_frac`` of the span (Δ the median
    epoch interval; a lag needs ``min_pairs`` pairs of finite drifts). The mean square is about zero,
    as the Allan variance's: a frequency drift (a warming oscillator's ramp D, increments D·L) counts
    as the random walk of the same variance over those lags — the filter has no drift-rate state.
    ``t`` [s], ``drift`` [m/s] (NaN: no solution). Returns (S_d, σ_n², number of lags) or None when fewer
    than three lags qualify."""
    t = np.asarray(t, float)
    d = np.asarray(drift, float)
    if t.size < 4:
        return None
    step = float(np.median(np.diff(t)))
    if not step > 0:
        return None
    lags, msq = [], []
    m = 1
    while m * step <= max_frac * (t[-1] - t[0]) + 1e-9 and m < t.size:
        dt = t[m:] - t[:-m]
        dd = d[m:] - d[:-m]
        ok = np.isfinite(dd) & (np.abs(dt - m * step) <= 0.5 * step)
        if ok.sum() >= min_pairs:
            lags.append(float(np.mean(dt[ok])))
            msq.append(float(np.mean(dd[ok] ** 2)))
        m *= 2
    if len(lags) < 3:
        return None
    a = np.column_stack([np.ones(len(lags)), lags])
    c0, s_d = np.linalg.lstsq(a, np.array(msq), rcond=None)[0]
    return max(float(s_d), 0.0), max(float(c0), 0.0) / 2.0, len(lags)


def clock_hm2_from_psd(s_d: float) -> float:
    """h-2 [1/s] of a drift random walk of PSD ``s_d`` [m²/s³]: S_d = c²·2π²·h-2 (the module doc)."""
    return float(s_d) / (C_LIGHT**2 * 2.0 * np.pi**2)


class TightConfig(_Strict):
    """Configuration of :func:`run_tight` (the loosely coupled filter's sections plus ``gnss``). The INS
    block (:attr:`nins`): 9 states (``states=11``), else 15, 21 with ``imu.scale_factors``, 27 with
    ``imu.gyro_misalignment``, 33 with ``imu.accel_misalignment`` (the loose filter's layouts)."""

    states: Literal[11, 17] = 17
    # no imu section: the error model of an IMU of unknown grade (what a phone or any consumer IMU is),
    # with its scale-factor and misalignment states (config.UNKNOWN_GRADE_IMU; issue 35 item 3, issue 40)
    imu: ImuNoise = Field(default_factory=lambda: ImuNoise(**UNKNOWN_GRADE_IMU))
    gnss: RawGnssAiding = RawGnssAiding()
    init: Initialisation = Initialisation()
    constraints: Constraints = Constraints()
    filter: FilterSettings = FilterSettings()
    rotation_noise: bool = Field(
        False, description="gyro scale-factor and misalignment errors (imu.gyro_sf_sigma_ppm, "
        "imu.gyro_misalignment_sigma_deg; not states here) as attitude noise that grows with the body's "
        "rotation: (σ_sf² + σ_m²)·|Δθ|² per axis for each prop_dt block of net rotation Δθ")

    @property
    def nins(self) -> int:
        """Size of the INS error block: 9, 15, 21 (scale factors), 27 (and gyro misalignment) or 33 (and
        accelerometer misalignment)."""
        return 9 if self.states == 11 else self.imu.nins


@dataclass
class TightResult:
    """Output of :func:`run_tight`.

    time (N,) [s, GPS on the input scale]; state (N, 10) lat, lon, h, vE, vN, vU, q; bias (N, nb) gyro
    [rad/s] and accel [m/s²] bias estimates (17 states); clock (N, 2) b̂ [m], d̂ [m/s]; pdiag (N, n)
    covariance diagonal (smoothed when ``smoothed``; the forward ones in ``forward_state``,
    ``forward_pdiag``, ``forward_clock``; the smoothed covariance at the nodes in ``smoothed_cov``);
    epochs : dict of per-GNSS-epoch arrays of the forward pass (time = GPS receive
    time, n_avail, n_pr, n_rate, n_rejected, pr_innov/pr_s/rate_innov/rate_s (M, S), elevation (M, S),
    P_nav (M, 9, 9) and state (M, 10) after the epoch's update, clock (M, 2)); counts; events.
    """

    time: np.ndarray
    state: np.ndarray
    bias: np.ndarray
    clock: np.ndarray
    pdiag: np.ndarray
    epochs: dict = field(default_factory=dict)
    counts: dict = field(default_factory=dict)
    events: list = field(default_factory=list)
    nstate: int = 17
    final_P: np.ndarray | None = None
    smoothed: bool = False
    forward_state: np.ndarray | None = None
    forward_pdiag: np.ndarray | None = None
    forward_clock: np.ndarray | None = None
    node_time: np.ndarray | None = None  # (K,) times of the filter's nodes [s]
    smoothed_cov: np.ndarray | None = None  # (K, n, n) smoothed covariance at the nodes (``smooth``)
    range_error: np.ndarray | None = None  # (N, R) forward range-error estimates û [-] (σ units), R states
    range_error_prn: np.ndarray | None = None  # (R,) PRN of each range-error state
    iono_model: str = ""  # the ionospheric correction applied and its σ (for the summary)
    isb_systems: str = ""  # letters of the systems with an inter-system bias state (clock − GPS clock)
    isb: np.ndarray | None = None  # (N, len(isb_systems)) forward inter-system bias estimates [m]
    isb_std: np.ndarray | None = None  # (N, len(isb_systems)) their σ [m]
    cov_time: np.ndarray | None = None  # (K,) times of the kept forward covariances (``cov_times``) [s]
    cov: np.ndarray | None = None  # (K, n, n) those covariances


def tight_layout(states: int, n_range: int = 0, n_isb: int = 0, nins: int = 15, phase: bool = False
                 ) -> np.ndarray:
    """Layout table (:mod:`aidnav.filters.layout`): INS block of 9 (11 states) or ``nins`` (15, 21 with
    scale factors, 27 with the gyro misalignment too, 33 with the accelerometer's), then the clock,
    then ``n_isb`` inter-system biases (``L_ISB``, none: 0), then with ``phase`` the 4 clone states of the
    time-differenced carrier phase (``L_TDCP``), then ``n_range`` per-satellite range-error states
    (``L_RERR``, none: 0; kept last: they are the open-loop Gauss-Markov block)."""
    lay = np.full(L_SIZE, -1, np.int64)
    lay[L_NINS] = 9 if states == 11 else nins
    lay[L_CLK] = lay[L_NINS]
    lay[L_N] = lay[L_NINS] + 2
    if n_isb:
        lay[L_ISB] = lay[L_N]
        lay[L_N] += n_isb
    if phase:
        lay[L_TDCP] = lay[L_N]
        lay[L_N] += N_CLONE
    if n_range:
        lay[L_RERR] = lay[L_N]
        lay[L_N] += n_range
    return lay


def _noise_vector(cfg: TightConfig, n_range: int = 0, n_isb: int = 0, n_clone: int = 0) -> np.ndarray:
    nfull = max(cfg.nins, 15)
    m = noise_count(nfull)  # the INS noise inputs of ins_errors (12, 18, 24 or 30), then the clock's two
    q = np.zeros(m + 2 + n_isb + n_clone + n_range)  # clone states: constant between epochs (q 0)
    q[:m] = process_noise(cfg, nfull)  # reads cfg.imu (the loose schema's section)
    g = cfg.gnss
    h0, hm2 = clock_allan(g)
    q[m] = C_LIGHT**2 * h0 / 2.0
    q[m + 1] = C_LIGHT**2 * 2.0 * np.pi**2 * hm2
    q[m + 2:m + 2 + n_isb] = g.isb_psd_m2_s  # inter-system biases: random walk
    q[m + 2 + n_isb + n_clone:] = 2.0 / g.range_error_tau_s  # unit-variance Gauss-Markov: q = 2σ²/τ
    return q


def _initial_P(cfg: TightConfig, lat, h, att_sig, n_range: int = 0, n_isb: int = 0, n_clone: int = 0
               ) -> np.ndarray:
    nn = cfg.nins
    n = nn + 2 + n_isb + n_clone + n_range
    P15 = initial_covariance(cfg, max(nn, 15), lat, h, att_sig)  # reads cfg.imu, cfg.init (loose schema)
    P = np.eye(n)  # range-error states: unit variance (stationary)
    P[:nn, :nn] = P15[:nn, :nn]
    P[nn, nn] = cfg.gnss.clock_bias_sigma_m**2
    P[nn + 1, nn + 1] = cfg.gnss.clock_drift_sigma_m_s**2
    for k in range(n_isb):
        P[nn + 2 + k, nn + 2 + k] = cfg.gnss.isb_sigma_m**2
    for k in range(n_clone):  # no clone before the first epoch
        P[nn + 2 + n_isb + k, nn + 2 + n_isb + k] = 0.0
    return P


def _vehicle_models(cfg: TightConfig, par, gates, have_static: bool, gated: bool) -> np.ndarray:
    """Node constraints of ``cfg.constraints`` (the loosely coupled filter's schema and models): ZUPT
    (and ZARU) at static samples, the NHC (no mounting states here: the configured mounting is exact).
    Fills their parameters and gates; returns the (model, static-only) pairs."""
    from aidnav.nav.rotations import dcm_from_euler  # lazy: as run_tight's own imports (import time)

    from .config import DEG  # lazy: as run_tight's

    c = cfg.constraints
    V = ms.vehicle
    par[ms.M_ZUPT, 0], par[ms.M_ZARU, 0] = c.zupt_sigma_m_s, c.zaru_sigma_deg_s * DEG
    mr = np.array(cfg.imu.mounting_rph_deg) * DEG
    par[ms.M_NHC, V.V_SIG], par[ms.M_NHC, V.V_MIN_SPEED] = c.nhc_sigma_m_s, c.nhc_min_speed_m_s
    par[ms.M_NHC, V.V_LEVER:V.V_LEVER + 3] = c.nhc_lever_arm_m
    par[ms.M_NHC, V.V_CBV:V.V_CBV + 9] = dcm_from_euler(mr[0], mr[1], mr[2]).ravel()
    par[ms.M_NHC, V.V_LEVER_SIG] = c.nhc_lever_arm_sigma_m
    gates[ms.M_NHC, 1:] = 25.0 if gated else 0.0
    node = []
    if c.zupt and have_static:
        node.append((ms.M_ZUPT, 1))
        if c.zaru_sigma_deg_s > 0:
            node.append((ms.M_ZARU, 1))
    if c.nhc:
        node.append((ms.M_NHC, 0))
    return np.array(node, np.int64).reshape(-1, 2)


def apply_vehicle(cfg: TightConfig, name: str | None, events: list | None = None) -> TightConfig:
    """``cfg`` with the vehicle preset ``name`` of ``aidnav process --vehicle``
    (:data:`aidnav.filters.presets.PRESETS`) applied under it: the sections the two schemas share
    (``imu``, ``init``, ``constraints``); a key the configuration states explicitly wins. Preset keys
    of sections tight does not have (loose-only GNSS fix settings, mounting calibration) are listed in
    ``events``. Without an ``imu`` section the IMU model is the unknown-grade one, with the accelerometer
    misalignment as states where the preset has no NHC (issue 35 session 16). Unknown names raise
    ValueError naming the known ones."""
    from .presets import PRESETS, preset_names  # lazy: only with --vehicle

    if name is None:
        return cfg
    if name not in PRESETS:
        raise ValueError(f"--vehicle {name!r}: unknown vehicle; known: {', '.join(preset_names())}")
    data = cfg.model_dump(exclude_unset=True)
    merged: dict = {k: v for k, v in data.items()}
    skipped = []
    nhc = {**PRESETS[name].get("constraints", {}), **data.get("constraints", {})}.get("nhc", False)
    for section, vals in PRESETS[name].items():
        if section not in ("imu", "init", "constraints"):
            skipped += [f"{section}.{k}" for k in vals]
            continue
        # without an imu section the IMU model stays the unknown-grade one (the default's), its noise
        # from the log's static samples included: a phone at rest shows its own noise, vibrating or not;
        # without the NHC with the accelerometer misalignment as states (config.UNKNOWN_GRADE_IMU_ACCEL_
        # MISALIGNMENT: only the turns then split the tilt from the bias, and the folded misalignment's
        # error in a turn would be read as information on that split)
        unknown = UNKNOWN_GRADE_IMU if nhc else UNKNOWN_GRADE_IMU_ACCEL_MISALIGNMENT
        over = unknown if section == "imu" and "imu" not in data else {}
        merged[section] = {**vals, **over, **data.get(section, {})}
    if events is not None and skipped:
        events.append(f"--vehicle {name}: {', '.join(skipped)} of the preset not used by the tightly coupled "
                      "filter (no such state or setting here)")
    return TightConfig.model_validate(merged)


def run_tight(imu, obs, eph, cfg: TightConfig | None = None, init_state=None, static=None, heading_reset=None,
              events: list | None = None, output_rate_hz: float | None = None,
              smooth: bool = False, velocity_fixes=None, cov_times=None, phase_increments=None,
              level=None) -> TightResult:
    """Tightly coupled GNSS/INS over whole logs.

    imu : :class:`aidnav.data.ImuData` (increments, body RFU; time on the GNSS scale: GPS seconds on the
    observations' reference-week scale). obs : :class:`aidnav.nav.gnss_types.GnssObservations` (receiver
    tags, L1 code, Doppler; L2 code for ``iono="dual"``). eph : broadcast ephemerides (put on the
    observations' week). cfg : :class:`TightConfig`.
    init_state : (t0 [s], lat, lon [rad], h [m], v^n (3,), (roll, pitch, heading) [rad]) to start from;
    default: ``cfg.init`` in "given" mode (degrees) at the IMU's first time.
    static : optional (N,) bool per IMU sample for ZUPTs (``cfg.constraints.zupt``).
    heading_reset : optional (t [s], heading [rad]) to set the heading at (e.g. a GNSS course).
    velocity_fixes : optional (t (K,) receiver tags [s], v_ENU (K, 3) [m/s], σ (K, 3) [m/s]) velocity
    records of the antenna (e.g. time-differenced carrier phase, :mod:`aidnav.estimators.tdcp`, at the
    middle of each interval), the loosely coupled filter's velocity model, gated by ``gate_probability``.
    phase_increments : optional (M, S) λΔL [m] of each satellite from the previous epoch to this one (row
    0 and cycle slips NaN; :func:`aidnav.estimators.tdcp.phase_increments`): time-differenced carrier-phase
    rows in the epoch records against clone states of the previous epoch (:mod:`.measurements.epoch`).
    smooth : also run the RTS smoother (``state``, ``clock``, ``pdiag`` are then the smoothed ones).
    cov_times : optional times [s] at which to keep the full forward covariance (``cov_time``, ``cov``:
    the first IMU sample at or after each; outside the processed span dropped).
    level : optional (f^b (3,) [m/s²], σ_w [rad]) when ``init_state``'s roll and pitch come from levelling
    on that mean specific force: the start tilt is then correlated with the accelerometer states
    (:func:`.prior.levelled_tilt_covariance`) instead of ``init.attitude_sigma_deg``'s independent σ.
    """
    cfg = cfg or TightConfig()
    events = events if events is not None else []
    if eph.ref_week != obs.ref_week:
        eph = eph.to_week(obs.ref_week)
    g = cfg.gnss
    nnav = cfg.nins
    arena = Arena(arena_bytes(imu, obs, velocity_fixes))  # the large arrays in one block (.tight_input)
    t_imu = imu_times(imu, cfg.imu.time_offset_s, arena)
    if init_state is None:
        init_state = (float(imu.t0 + cfg.imu.time_offset_s),
                      *given_initial_state(cfg.init, "run_tight without init_state"))
    t0, lat0, lon0, h0, v0, rph0 = init_state
    k0 = int(np.searchsorted(t_imu, t0, side="right"))
    q0 = quat_from_euler(rph0[0], rph0[1], rph0[2])
    st0 = np.array([lat0, lon0, h0, *np.asarray(v0, float), *q0], float)
    mod, gate, iono_model = _tight_models(cfg, eph, static is not None, events)
    obs = obs.with_frequencies(eph)  # GLONASS channels from the records
    rec, sel, at = epoch_records(obs.time, velocity_fixes, obs.code1.shape[1], arena)
    with_eph, isb_sys = epoch_rows(obs, eph, g, events, rec.data, at, phase_increments)
    nb, nr, nc = len(isb_sys), len(with_eph), N_CLONE if phase_increments is not None else 0
    lay = tight_layout(cfg.states, nr, nb, nnav, nc > 0)
    n = int(lay[L_N])
    P0 = _initial_P(cfg, lat0, h0, np.array(cfg.init.attitude_sigma_deg) * DEG, nr, nb, nc)
    if level is not None and nnav >= 15:
        # tied with the true specific force at rest (normal gravity), not the measured one (prior's doc)
        P0 = levelled_tilt_covariance(P0, nnav, level[0], dcm_from_euler(*rph0), level[1], gravity(lat0, h0))
    if velocity_fixes is not None:
        par, gates, max_rej = mod.par, mod.gate, mod.max_rej
        par[ms.M_GNSS_VEL, 0:3] = g.lever_arm_m
        gates[ms.M_GNSS_VEL, 1:4] = [chi2_isf(m, 1.0 - g.gate_probability) if g.gate_probability < 1 else 0.0
                                     for m in (1, 2, 3)]
        max_rej[ms.M_GNSS_VEL] = g.max_consecutive_rejections
    vt = None  # the velocity records used: the times the timing noise applies at
    if velocity_fixes is not None:
        vt = np.asarray(velocity_fixes[0], float)[np.all(np.isfinite(velocity_fixes[1]), axis=1)]
    imu_in = imu_input(imu, cfg, t_imu, k0, static, events, vt, arena)
    reset_idx, reset_heading = -1, 0.0
    if heading_reset is not None:
        reset_idx = int(np.searchsorted(t_imu[k0:], heading_reset[0], side="left"))
        reset_heading = float(heading_reset[1])
    rate_hz = output_rate_hz or cfg.filter.output_rate_hz
    out_every = max(1, int(round(imu.rate_hz / rate_hz))) if rate_hz else 1
    taus = np.array([cfg.imu.gyro_bias_tau_s, cfg.imu.accel_bias_tau_s, cfg.imu.sf_tau_s, cfg.imu.sf_tau_s])
    # range-error estimates decay as the Gauss-Markov conditional mean between updates (open-loop states)
    aux_tau = np.r_[0.0, g.clock_tau_s, np.zeros(nb + nc), np.full(nr, g.range_error_tau_s)]
    proc = Process(lay, _noise_vector(cfg, nr, nb, nc), taus, aux_tau, float(cfg.filter.prop_dt_s),
                   open=np.arange(n - nr, n, dtype=np.int64))
    bias0 = np.zeros(n - 9)
    if nb:
        bias0[int(lay[L_ISB]) - 9:int(lay[L_ISB]) - 9 + nb] = [g.isb_m.get(c, 0.0) for c in isb_sys]
    init = Init(float(t0), st0, bias0, P0, reset_idx, reset_heading,
                cfg.init.course_heading_sigma_deg * DEG, np.full(15, np.nan))
    cov_idx = np.zeros(0, np.int64)
    if cov_times is not None:
        cov_idx = np.searchsorted(imu_in.t, np.sort(np.atleast_1d(np.asarray(cov_times, float))) - 1e-6)
        cov_idx = cov_idx[cov_idx < len(imu_in.t)].astype(np.int64)
    n_out = -(-len(imu_in.t) // out_every)  # the outputs into one block the kernel fills (.output_rows)
    rows = whole_run_rows(n_out, max(n - 9, 1), n)
    r = run_filter(imu_in, rec, mod, proc, init, Output(out_every, bool(smooth), cov_idx, rows))
    ge = epoch_outputs(rec.grp, sel)
    if gate > 0:
        _gate_events(ge, gate, obs.names, events)
    t_out = t_imu[k0:]
    res = _tight_result(r, ge, obs, lay, nnav, with_eph, isb_sys, iono_model, events, t_out, arena)
    res.counts.update(imu_samples_skipped=k0, velocity_records=len(rec.t) - len(sel))
    if nc:
        events.append(f"time-differenced carrier phase: {res.counts['tdcp_used']} delta-range rows used, "
                      f"{res.counts['tdcp_rejected']} outside the innovation gate")
    if cov_times is not None:
        res.cov_time, res.cov = imu_in.t[cov_idx], r.cov
    if smooth and len(r.node_idx) > 1:
        _smooth_into(res, r, lay, nnav, t_out)
    return res


def _tight_models(cfg: TightConfig, eph, with_static: bool, events: list):
    """The measurement models of :func:`run_tight` (:class:`Models`: the pseudorange/rate epoch row
    parameters, gates and rejection limits, the vehicle constraints), the pseudorange gate and the
    ionosphere model's description (the fallback's note into ``events``)."""
    g = cfg.gnss
    gate = chi2_isf(1, 1.0 - g.gate_probability) if g.gate_probability < 1 else 0.0
    use_iono = g.iono == "klobuchar"
    alpha, beta, iono_src = klobuchar_coefficients(eph.iono_alpha, eph.iono_beta)
    iono_model = {"klobuchar": f"Klobuchar ({iono_src} coefficients), sigma 50 % of the delay",
                  "dual": "dual-frequency code (L1/L2)", "none": "none"}[g.iono]
    if use_iono and iono_src == "default":
        events.append(iono_fallback_note())
    par = np.zeros((ms.N_MODELS, 24))
    e = par[ms.M_PR]
    e[ep.E_LEVER:ep.E_LEVER + 3] = g.lever_arm_m
    e[[ep.E_MASK, ep.E_SIG_CODE, ep.E_SIG_RATE, ep.E_IONO, ep.E_TROPO, ep.E_HUMID, ep.E_RATE]] = (
        np.radians(g.mask_deg), g.code_sigma_m, g.rate_sigma_m_s, use_iono, g.tropo, g.humidity, g.use_rate)
    e[[ep.E_JUMP, ep.E_SIG_B, ep.E_SIG_D, ep.E_CODE_MIN, ep.E_SIG_PHASE]] = (
        g.clock_jump_m, g.clock_bias_sigma_m, g.clock_drift_sigma_m_s, g.code_min_sats, g.phase_sigma_m)
    if use_iono:
        e[ep.E_ALPHA:ep.E_ALPHA + 4], e[ep.E_BETA:ep.E_BETA + 4] = alpha, beta
    gates = np.zeros((ms.N_MODELS, ms.MAX_ROWS + 1))
    gates[ms.M_PR, 1] = gate
    max_rej = np.full(ms.N_MODELS, NEVER, np.int64)
    max_rej[ms.M_PR] = g.max_consecutive_rejections
    mod = Models(par, gates, max_rej, _vehicle_models(cfg, par, gates, with_static, gate > 0))
    return mod, gate, iono_model


def _gate_events(ge, gate: float, names, events: list) -> None:
    """One event per satellite with pseudoranges or rates outside the innovation gate."""
    rej_pr = rejected_per_satellite(ge.pr_nu, ge.pr_s, float(gate))
    rej_rate = rejected_per_satellite(ge.rate_nu, ge.rate_s, float(gate))
    for j in np.flatnonzero(rej_pr + rej_rate):
        events.append(f"{names[j]}: {int(rej_pr[j])} pseudorange(s) and {int(rej_rate[j])} "
                      "rate(s) outside the innovation gate (rejected unless the gate was suspended)")


def _tight_result(r, ge, obs, lay, nnav: int, with_eph, isb_sys, iono_model: str, events: list,
                  t_out, arena=None) -> TightResult:
    """The forward :class:`TightResult` of the engine's run ``r`` (per-epoch records ``ge``, counts, the
    clock, range errors and inter-system biases; ``t_out``: the IMU times from the first sample on; the
    output times into ``arena``'s block where given)."""
    n, nr, nb = int(lay[L_N]), len(with_eph), len(isb_sys)
    epochs = dict(time=ge.t, n_avail=ge.navail, n_pr=ge.npr, n_rate=ge.nrate, n_rejected=ge.nrej,
                  n_tdcp=ge.ntd, n_tdcp_rejected=ge.ntdrej,
                  pr_innov=ge.pr_nu, pr_s=ge.pr_s, rate_innov=ge.rate_nu, rate_s=ge.rate_s, elevation=ge.el,
                  P_nav=ge.P_nav, clock=ge.clk, state=ge.state, prn=obs.prn)
    model, status = r.log.model[:r.n_log], r.log.status[:r.n_log]  # (run_log.log_dict's, no names)
    cnt = dict(zupt_updates=int(np.count_nonzero(model == ms.M_ZUPT)),
               nhc_updates=int(np.count_nonzero(model == ms.M_NHC)), clock_jumps=int(ge.flags[1]),
               epochs=int(np.isfinite(ge.t).sum()), pr_used=int(ge.npr.sum()), rate_used=int(ge.nrate.sum()),
               rejected=int(ge.nrej.sum()), imu_samples_skipped=0, nodes=len(r.node_idx),
               velocity_records=0, tdcp_used=int(ge.ntd.sum()), tdcp_rejected=int(ge.ntdrej.sum()),
               velocity_used=int(np.count_nonzero((model == ms.M_GNSS_VEL) & (status == 1))))
    ck = slice(int(lay[L_CLK]) - 9, int(lay[L_CLK]) - 7)
    t_res = t_out[r.out_idx] if arena is None else np.take(t_out, r.out_idx, out=arena.empty(len(r.out_idx)),
                                                           mode="clip")
    res = TightResult(time=t_res, state=r.out_st, bias=r.out_bias[:, :nnav - 9],
                      clock=r.out_bias[:, ck], pdiag=r.out_pdiag, epochs=epochs, counts=cnt, events=events,
                      nstate=n, final_P=r.P, range_error=r.out_bias[:, n - nr - 9:n - 9],
                      range_error_prn=np.asarray(obs.prn)[with_eph], iono_model=iono_model,
                      isb_systems="".join(isb_sys))
    if nb:
        i0 = int(lay[L_ISB]) - 9
        res.isb = r.out_bias[:, i0:i0 + nb]
        res.isb_std = np.sqrt(r.out_pdiag[:, i0 + 9:i0 + 9 + nb])
    return res


def _smooth_into(res: TightResult, r, lay, nnav: int, t_out) -> None:
    """The RTS smoother over the run ``r``: ``res``'s state, biases, clock and σ become the smoothed ones
    (the forward ones kept as ``forward_*``)."""
    n = int(lay[L_N])
    ck = slice(int(lay[L_CLK]) - 9, int(lay[L_CLK]) - 7)
    ds, Ps = _rts_without_clone(r, lay)
    sm_st, sm_b = smooth_outputs(r.out_idx, r.out_st, r.out_bias, r.out_node, r.node_idx, ds, r.S_dx, n)
    res.forward_state, res.forward_pdiag, res.forward_clock = res.state, res.pdiag, res.clock
    res.state, res.bias, res.clock = sm_st, sm_b[:, :nnav - 9], sm_b[:, ck]
    res.pdiag = np.einsum("kii->ki", Ps)[np.clip(r.out_node, 0, len(r.node_idx) - 1)]
    res.smoothed, res.node_time, res.smoothed_cov = True, t_out[r.node_idx], Ps


def _rts_without_clone(r, lay):
    """The RTS pass over the states other than the TDCP clone (which each epoch re-takes inside its
    update, so that its prior and posterior at a node are of different epochs): their marginal chain is
    exact (no state depends on the clone); the clone's smoothed error is left 0 and its σ the forward one."""
    ic = int(lay[L_TDCP])
    if ic < 0:
        return rts(r.S_post, r.S_prior, r.S_phi, r.S_dx, r.reset_node)
    n = int(lay[L_N])
    keep = np.r_[0:ic, ic + N_CLONE:n]
    sub = np.ix_(np.arange(len(r.S_post)), keep, keep)
    ds_k, Ps_k = rts(np.ascontiguousarray(r.S_post[sub]), np.ascontiguousarray(r.S_prior[sub]),
                     np.ascontiguousarray(r.S_phi[sub]), np.ascontiguousarray(r.S_dx[:, keep]), r.reset_node)
    ds, Ps = np.zeros((len(ds_k), n)), r.S_post.copy()
    ds[:, keep] = ds_k
    Ps[sub] = Ps_k
    return ds, Ps


def tight_nav_covariance_m(P_nav: np.ndarray, lat: float, h: float) -> np.ndarray:
    """9×9 nav covariance (φ, δv, δL δλ δh) → (φ, δv, δE δN δU in metres)."""
    rm, rn = radii(lat)
    T = np.eye(9)
    T[6:9, 6:9] = [[0, (rn + h) * np.cos(lat), 0], [rm + h, 0, 0], [0, 0, 1]]
    return T @ P_nav @ T.T


def to_trajectory(res: TightResult):
    """TightResult → :class:`aidnav.data.Trajectory` (σ columns, bias and clock columns); the navigation
    part is the loosely coupled filter's conversion (same state layout for the first 9 + 6 states)."""
    bias = res.bias[:, :6] if res.bias.shape[1] >= 6 else res.bias[:, :0]
    traj = nav_trajectory(LooseResult(res.time, res.state, bias, res.pdiag, res.time))
    traj.extra.update({"clock_bias_m": res.clock[:, 0], "clock_drift_m_s": res.clock[:, 1]})
    return traj
