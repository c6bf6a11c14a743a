"""The consistency matrix (issue 35): is the filter's σ one a user can bet on, in every condition and with
every configuration?

A *cell* is one condition (a simulated car drive with its IMU grade, GNSS rate and error model, and a gap,
outage or start it stresses) × one configuration of the loosely coupled filter (no option at all, each
vehicle preset of :mod:`aidnav.filters.presets`, or the configuration matched to the simulated sensors,
:func:`aidnav.filters.tuning.loose_config_from_specs`), run over several seeds. Its figures, over all
seeds and over the evaluation epochs (every second of the filter's output, gaps excluded; at each the
filter's last output row at or before it, against the truth interpolated at that row's time):

* ``coverage``: per axis (E, N, U, roll, pitch, heading) the fraction of epochs with |error| ≤ 3σ (σ the
  one the solution reports, :func:`aidnav.filters.result.to_trajectory`); an honest Gaussian σ covers
  99.73 %; the target is ≥ 95 %;
* ``ratio``: per axis RMS(error) / RMS(σ) (1 for an honest σ; < 0.3 flags a σ uselessly large); the
  heading's over the epochs where the filter claims a heading (σ < :data:`HEADING_UNKNOWN_RAD`), roll's and
  pitch's where it claims a tilt (σ < :data:`TILT_UNKNOWN_RAD`);
* ``nees``: the mean normalised estimation error squared of the 9 navigation error states (φ, δv, δp,
  :func:`aidnav.analysis.errors.ins_error_state`) with the filter's full 9×9 covariance at those epochs,
  divided by 9 (1 for an honest filter).

The seed fixes everything a run draws (IMU errors, GNSS noise, the time-correlated GNSS errors and the
matched configuration's initial state), so a cell is reproducible.

Tight-coupling cells (``coupling = "tight"``: 3, 2 or 0 satellites for 60 s over two turns of the drive,
the full nominal 24-satellite GPS sky elsewhere): the same drive and IMU, raw pseudoranges and rates of
:mod:`aidnav.sim.gnss_raw` at 1 Hz (its full error model: orbit, satellite clock, ionosphere with the
broadcast coefficients in the navigation records, troposphere, multipath, noise; TCXO receiver clock) on
the GPS time scale, run through :func:`aidnav.estimators.tight_solution.process_tight` (what ``aidnav
tight`` does: SPP start, static roll/pitch, heading by velocity matching, ZUPTs; with no option the
NHC decided from the log as ``aidnav process`` decides it) with no configuration (``none``), a vehicle
preset (:func:`aidnav.filters.tight.apply_vehicle`), or through
:func:`aidnav.filters.tight.run_tight` with the matched IMU model and a perturbed initial state
(``matched``). Evaluated as the loose cells: every second of the whole run.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from aidnav.analysis.consistency import nees
from aidnav.analysis.errors import ins_error_state, trajectory_errors
from aidnav.data import ImuData, Trajectory
from aidnav.filters.config import LooseConfig
from aidnav.filters.gnss_errors import choose_gnss_errors
from aidnav.filters.loose import run_loose
from aidnav.filters.presets import apply_preset, preset_names
from aidnav.filters.result import to_trajectory
from aidnav.filters.tuning import loose_config_from_specs, perturbed_initial_state
from aidnav.filters.wheeled import no_option_constraint
from aidnav.nav.earth import radii
from aidnav.report import html as H
from aidnav.sim.gnss import GnssSpec
from aidnav.sim.imu import ImuSpec
from aidnav.sim.run import simulate
from aidnav.sim.scenario import parse_scenario

__all__ = ["AXES", "COVERAGE_TARGET", "RATIO_TARGET", "SEED_COVERAGE_BOUND", "GM_TAU_S",
           "HEADING_UNKNOWN_RAD", "TILT_UNKNOWN_RAD", "Condition", "CellResult", "CONDITIONS",
           "configurations", "condition", "simulate_condition", "config_for", "run_cell", "run_matrix",
           "simulate_pedestrian_cell", "tight_result",
           "SeedRun", "aggregate",
           "flags", "format_matrix", "matrix_table", "matrix_page", "variant", "add_gauss_markov"]

AXES = ("E", "N", "U", "roll", "pitch", "heading")
COVERAGE_TARGET = 0.95  #: the issue's acceptance: ≥ 95 % of the epochs within 3σ on every axis
RATIO_TARGET = 0.3  #: RMS(error)/RMS(σ) below this: the σ is uselessly large
#: The coverage bound a test over 10 seeds can hold an honest filter to (issue 35). The sensor constants
#: (biases, scale factors, misalignments) are drawn once per seed, so where they dominate the attitude
#: error a seed is in the worst case wholly inside or wholly outside 3σ: the number of uncovered seeds is
#: Binomial(10, p = 0.0027). P(≥ 1 of 10) = 2.7 % per axis and cell — the issue's 95 % over 10 seeds
#: fails an honest filter that often, and far more often over the matrix's hundreds of axis-cells —
#: while P(≥ 2 of 10) = 3.3e-4. So one seed wholly out is allowed, two are not: 9/10 of the 95 % target.
SEED_COVERAGE_BOUND = 0.9 * 0.95
GM_TAU_S = 30.0  #: correlation time of the time-correlated GNSS position errors [s]
GM_SIGMA_M = (0.5, 0.5, 1.0)  #: their steady-state σ E, N, U [m]
GM_WHITE_M = 0.05  #: the white part of those fixes [m]
EVAL_DT_S = 1.0  #: spacing of the evaluation epochs [s]
EVAL_MAX_DT_S = 0.05  #: an epoch is evaluated at the filter's last output at most this much before it [s]
#: a heading σ at or above this (90°) says "heading unknown" (the filter holds it so until a GNSS course
#: aligns it: static with a gyro that cannot gyrocompass, after an IMU gap): such epochs count for the
#: coverage (always covered) but not for the heading's RMS(error)/RMS(σ), which asks whether a claimed σ
#: is uselessly large; a σ of 180° for a heading no sensor can give is the right answer, not a large one
HEADING_UNKNOWN_RAD = np.pi / 2
#: a roll or pitch σ at or above this (30°: 3σ spans ±90°, every attitude) says "tilt unknown": after an IMU
#: gap of a vehicle that may be at any attitude when it ends (the aircraft and pedestrian presets' bound of
#: 90°, σ 52°: :func:`aidnav.filters.preprocess.bridge_gaps`) until the first fixes re-observe it; such epochs
#: count for the coverage but not for that axis's RMS(error)/RMS(σ), as the heading's unknown ones do
TILT_UNKNOWN_RAD = np.pi / 6

# a car: standing 30 s (coarse alignment), then ~250 s of driving with left and right turns, then a stop
_START = [{"type": "static", "duration_s": 30}]
_DRIVE = [{"type": "accelerate", "duration_s": 10, "to_speed_m_s": 10},
          {"type": "straight", "duration_s": 30}, {"type": "turn", "angle_deg": 90, "duration_s": 15},
          {"type": "straight", "duration_s": 30}, {"type": "turn", "angle_deg": -180, "duration_s": 30},
          {"type": "straight", "duration_s": 30}, {"type": "turn", "angle_deg": 270, "duration_s": 45},
          {"type": "straight", "duration_s": 30}, {"type": "accelerate", "duration_s": 10, "to_speed_m_s": 0},
          {"type": "static", "duration_s": 20}]
# the moving start: already at 10 m/s when the log begins
_MOVING = [{"type": "straight", "duration_s": 20}] + _DRIVE[1:]
# the turn of the IMU gap: 180° in 60 s, the gap in its middle half
_GAP_DRIVE = [{"type": "accelerate", "duration_s": 10, "to_speed_m_s": 10},
              {"type": "straight", "duration_s": 40}, {"type": "turn", "angle_deg": 180, "duration_s": 60},
              {"type": "straight", "duration_s": 60}, {"type": "turn", "angle_deg": -90, "duration_s": 20},
              {"type": "straight", "duration_s": 60}]


# the simulated pedestrian's timeline (sim.pedestrian.walking_truth: 12 s standing, a 3-s start, 100 s of
# walking whose first turn, 90° in 2.5 s, begins 15 s in, a 3-s stop, 15 s standing): not simulated from
# here, only read for its times (the seed statistics' end of the first turn and of the run)
_PEDESTRIAN = [{"type": "static", "duration_s": 12}, {"type": "accelerate", "duration_s": 3},
               {"type": "straight", "duration_s": 15}, {"type": "turn", "duration_s": 2.5},
               {"type": "straight", "duration_s": 82.5}, {"type": "accelerate", "duration_s": 3},
               {"type": "static", "duration_s": 15}]


@dataclass(frozen=True)
class Condition:
    """One row of the matrix: the simulated drive and sensors.

    segments : scenario segments (:mod:`aidnav.sim.scenario`); speed_m_s : the speed at the start;
    grade : IMU grade (:meth:`aidnav.sim.imu.ImuSpec.grade`, with its scale factors and misalignments);
    imu : (key, value) pairs overriding the grade (``sensors.imu`` keys of a scenario);
    rate_hz : GNSS fix rate; velocity : fixes carry velocity; correlated : position errors are first-order
    Gauss–Markov (σ ``GM_SIGMA_M``, τ ``GM_TAU_S``) plus ``GM_WHITE_M`` white, the fixes' σ the total
    (what a receiver that does not know the correlation reports); imu_gap, outage : (start, duration) [s]
    from the start without IMU samples / without GNSS fixes (tight: with only ``satellites`` in view);
    coupling : "loose", or "tight" (raw GNSS, module doc); pedestrian : the tight cell is the simulated
    pedestrian of :mod:`aidnav.sim.pedestrian` (GPS + Galileo at ``rate_hz`` with an L1 carrier phase; its
    own walk; ``segments`` only its timeline) with the IMU's stamps ``imu_late_s`` late (an IMU-GNSS time
    offset).
    """

    name: str
    segments: tuple = tuple(_START + _DRIVE)
    speed_m_s: float = 0.0
    grade: str = "consumer"
    imu: tuple = ()
    rate_hz: float = 1.0
    velocity: bool = True
    correlated: bool = False
    imu_gap: tuple[float, float] | None = None
    outage: tuple[float, float] | None = None
    coupling: str = "loose"
    satellites: int | None = None
    pedestrian: bool = False
    imu_late_s: float = 0.0
    note: str = ""


CONDITIONS: tuple[Condition, ...] = (
    Condition("gnss 1 Hz white", note="position + velocity fixes, white errors"),
    Condition("gnss 1 Hz correlated", correlated=True,
              note=f"Gauss-Markov position errors, τ {GM_TAU_S:g} s"),
    Condition("gnss 10 Hz white", rate_hz=10.0),
    Condition("gnss 10 Hz correlated", rate_hz=10.0, correlated=True),
    Condition("imu gap 30 s in a turn", segments=tuple(_START + _GAP_DRIVE), imu_gap=(95.0, 30.0),
              note="no IMU samples for 30 s in the middle of a 180° turn"),
    Condition("gnss outage 60 s", outage=(120.0, 60.0), note="no fixes over two turns"),
    Condition("parked 10 min then driving", segments=tuple([{"type": "static", "duration_s": 600}] + _DRIVE),
              rate_hz=10.0, velocity=False, note="10 Hz position-only fixes"),
    Condition("moving start, position only", segments=tuple(_MOVING), speed_m_s=10.0, velocity=False,
              note="the log starts at 10 m/s; 1 Hz position-only fixes"),
    Condition("grade navigation", grade="navigation"),
    Condition("grade tactical", grade="tactical"),
    Condition("grade mems", grade="mems"),
    Condition("grade consumer", grade="consumer"),
    Condition("tight 3 satellites", coupling="tight", satellites=3, outage=(120.0, 60.0),
              note="raw GNSS, 3 satellites (the highest) for 60 s over two turns"),
    Condition("tight 2 satellites", coupling="tight", satellites=2, outage=(120.0, 60.0),
              note="raw GNSS, 2 satellites for 60 s"),
    Condition("tight 0 satellites", coupling="tight", satellites=0, outage=(120.0, 60.0),
              note="raw GNSS, none for 60 s (free inertia)"),
    Condition("tight pedestrian phase, IMU 25 ms late", segments=tuple(_PEDESTRIAN), coupling="tight",
              rate_hz=4.0, pedestrian=True,
              imu_late_s=0.025, note="a walker (sim.pedestrian), GPS + Galileo at 4 Hz with carrier phase, "
              "the IMU's stamps 25 ms late"),
)


def condition(name: str) -> Condition:
    """The condition of :data:`CONDITIONS` called ``name``."""
    for c in CONDITIONS:
        if c.name == name:
            return c
    raise ValueError(f"unknown condition {name!r}; known: {', '.join(c.name for c in CONDITIONS)}")


def configurations() -> list[str]:
    """The matrix's columns: ``none`` (no option), each preset, ``matched``."""
    return ["none"] + preset_names() + ["matched"]


@dataclass
class SimRun:
    """One simulated run of a condition: truth, the IMU log as given to the filter, the fixes."""

    truth: Trajectory
    imu: ImuData
    gnss: object
    imu_spec: ImuSpec
    gnss_spec: GnssSpec
    imu_errors: dict
    seed: int


def _scenario(cond: Condition, seed: int):
    gnss = {"rate_hz": cond.rate_hz, "velocity": cond.velocity,
            "sigma_pos_m": [GM_WHITE_M] * 3 if cond.correlated else [0.5, 0.5, 1.0]}
    if cond.outage is not None:
        gnss["outages"] = [{"start_s": cond.outage[0], "duration_s": cond.outage[1]}]
    return parse_scenario({
        "name": cond.name, "seed": seed, "imu_rate_hz": 100,
        "initial": {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 50.0, "speed_m_s": cond.speed_m_s,
                    "heading_deg": 20.0},
        "segments": [dict(s) for s in cond.segments],
        "sensors": {"imu": {"grade": cond.grade, **dict(cond.imu)}, "gnss": gnss}})


def add_gauss_markov(gnss, sigma_m, tau_s: float, rng: np.random.Generator) -> None:
    """Add first-order Gauss–Markov position errors (steady-state σ ``sigma_m`` E, N, U [m], correlation
    time ``tau_s``, exact discretisation at the fixes' spacing, started stationary) to ``gnss`` in place,
    and set its σ to the total (white σ ⊕ Gauss–Markov σ)."""
    sig = np.asarray(sigma_m, float)
    m = len(gnss.time)
    b = np.zeros((m, 3))
    b[0] = rng.normal(0.0, sig)
    for k in range(1, m):
        a = np.exp(-(gnss.time[k] - gnss.time[k - 1]) / tau_s)
        b[k] = a * b[k - 1] + np.sqrt(1.0 - a * a) * rng.normal(0.0, sig)
    rm, rn = radii(gnss.lat)
    gnss.lat = gnss.lat + b[:, 1] / (rm + gnss.height)
    gnss.lon = gnss.lon + b[:, 0] / ((rn + gnss.height) * np.cos(gnss.lat))
    gnss.height = gnss.height + b[:, 2]
    gnss.std_pos = np.sqrt(gnss.std_pos ** 2 + sig ** 2)


def simulate_condition(cond: Condition, seed: int) -> SimRun:
    """The simulated run of ``cond`` with ``seed`` (IMU gap removed, correlated errors added)."""
    scn = _scenario(cond, seed)
    sim = simulate(scn, seed)
    gnss = sim.gnss
    if cond.correlated:
        add_gauss_markov(gnss, GM_SIGMA_M, GM_TAU_S, np.random.default_rng([seed, 35]))
    imu = sim.imu
    if cond.imu_gap is not None:
        t0 = imu.time[0]
        keep = (imu.time < t0 + cond.imu_gap[0]) | (imu.time >= t0 + cond.imu_gap[0] + cond.imu_gap[1])
        imu = ImuData(imu.time[keep], imu.dtheta[keep], imu.dv[keep], t0=imu.t0)
    return SimRun(sim.truth, imu, gnss, ImuSpec.from_config(scn.sensors.imu),
                  GnssSpec.from_config(scn.sensors.gnss), sim.imu_errors, seed)


def config_for(name: str, cond: Condition, run: SimRun, sensor_model: bool = True) -> LooseConfig:
    """The configuration ``name`` (:func:`configurations`) for a run: ``none`` = :class:`LooseConfig`
    (what ``aidnav process`` assumes without options; :func:`run_cell` then decides the NHC from the log as
    ``process`` does, :func:`aidnav.filters.wheeled.no_option_constraint`), a preset over it, or
    ``matched``: the noise model of the simulated sensors (:func:`loose_config_from_specs`,
    ``sensor_model`` passed on), the initial state drawn around the truth with its σ, and the Gauss–Markov
    GNSS error states where the errors are."""
    if name == "none":
        return LooseConfig()
    if name != "matched":
        return apply_preset(None, name)
    pos_s, vel_s, att_s = (1.0, 1.0, 1.0), (0.1, 0.1, 0.1), (0.5, 0.5, 3.0)
    lla, vel, rph = perturbed_initial_state(run.truth, np.random.default_rng([run.seed, 36]), pos_s, vel_s,
                                            att_s)
    # the simulated fixes' errors as they are: Gauss–Markov where the condition makes them so, white
    # otherwise (stated: unstated, a 10-Hz log gets the rate's Gauss–Markov states, a 1-Hz one a first pass)
    over = {"gnss": {"error_tau_s": GM_TAU_S, "error_sigma_m": GM_SIGMA_M} if cond.correlated
            else {"error_tau_s": 0.0}}
    return loose_config_from_specs(run.imu_spec, run.gnss_spec, init_rph_deg=rph, init_lla_deg_m=lla,
                                   init_vel=vel, position_sigma_m=pos_s, velocity_sigma_m_s=vel_s,
                                   attitude_sigma_deg=att_s, sensor_model=sensor_model, **over)


@dataclass
class SeedRun:
    """One seed of a cell at its evaluation epochs: ``time`` (K,) [s from the run's start], ``err`` and
    ``sigma`` (K, 6) in :data:`AXES` order [m, rad] (error = estimate − truth), ``nees`` (L,) the 9
    navigation states' NEES per dof at the covariance epochs ``nees_time`` (L,), ``nees_att`` (L,) the
    attitude error's (φ, 3 dof) NEES there (not divided)."""

    seed: int
    time: np.ndarray
    err: np.ndarray
    sigma: np.ndarray
    nees: np.ndarray
    nees_time: np.ndarray
    nees_att: np.ndarray


@dataclass
class CellResult:
    """Figures of one cell (module doc): per-axis ``coverage`` and ``ratio`` (:data:`AXES` order),
    ``nees`` (mean / 9), ``epochs`` evaluated over ``seeds`` runs, ``failed`` runs (exceptions, with
    their messages in ``errors``), the per-seed coverage of the worst axis and each seed's
    :class:`SeedRun` (``runs``: what the seed-level statistics of :mod:`aidnav.analysis.seed_consistency`
    and a block of the seeds, :func:`aggregate`, are computed from)."""

    condition: str
    config: str
    coverage: np.ndarray
    ratio: np.ndarray
    nees: float
    epochs: int
    seeds: int
    failed: int = 0
    errors: list = field(default_factory=list)
    per_seed_min: list = field(default_factory=list)
    runs: list = field(default_factory=list, repr=False)

    @property
    def ok(self) -> bool:
        return self.failed == 0 and not flags(self)


def flags(cell: CellResult) -> list[str]:
    """The cell's defects: axes below the coverage target, axes below the ratio target, failed runs."""
    out = [f"{a} cov {c:.2f}" for a, c in zip(AXES, cell.coverage, strict=True)
           if not c >= COVERAGE_TARGET]
    out += [f"{a} ratio {r:.2f}" for a, r in zip(AXES, cell.ratio, strict=True) if r < RATIO_TARGET]
    if cell.failed:
        out.append(f"{cell.failed} run(s) failed")
    return out


def _truth_at(truth: Trajectory, t: np.ndarray) -> Trajectory:
    """The truth interpolated (linearly; the heading unwrapped) at the epochs ``t`` (the filter's output
    epochs are the IMU's shifted by an estimated time offset)."""
    tt = truth.time

    def li(a):
        return np.interp(t, tt, a)

    rph = np.column_stack([li(truth.rph[:, 0]), li(truth.rph[:, 1]), li(np.unwrap(truth.rph[:, 2]))])
    return Trajectory(np.asarray(t, float), li(truth.lat), li(truth.lon), li(truth.height),
                      np.column_stack([li(truth.vel[:, i]) for i in range(3)]), rph)


def _loose_seed(cond: Condition, config: str, seed: int, sensor_model: bool):
    """The :class:`SeedRun` of one loose seed."""
    run = simulate_condition(cond, seed)
    cfg = config_for(config, cond, run, sensor_model)
    if config == "none":  # what `aidnav process` does with no option: the NHC decided from the log
        cfg = no_option_constraint(run.imu, run.gnss, cfg, None, [])[0]
    # as `aidnav process` does for every configuration that does not state gnss.error_tau_s: white or
    # correlated GNSS errors from a first pass's innovations
    cfg = choose_gnss_errors(run.imu, run.gnss, cfg, None, [])
    cov_t = np.arange(run.truth.time[0], run.truth.time[-1], EVAL_DT_S) - 1e-6
    res = run_loose(run.imu, run.gnss, cfg, cov_times=cov_t)
    return evaluate(res, run)


def _output_at(traj: Trajectory, ev: np.ndarray, max_dt: float) -> Trajectory:
    """The filter's own output rows at the evaluation epochs ``ev``: for each, the last output at or before
    it, if within ``max_dt`` [s] (each row once). Not interpolated: between two outputs that a reset
    separates (the course alignment that ends a heading held unknown, σ 180° → 5°, falls on a fix's time,
    and so on an evaluation epoch) an interpolated σ (e.g. 90°) and attitude are neither output's; the
    truth is interpolated at the rows' times instead (:func:`_truth_at`)."""
    i = np.searchsorted(traj.time, ev + 1e-9, side="right") - 1
    ok = i >= 0
    i = np.unique(i[ok][ev[ok] - traj.time[i[ok]] <= max_dt])

    def sub(a):
        return None if a is None else a[i]

    return Trajectory(traj.time[i], traj.lat[i], traj.lon[i], traj.height[i], traj.vel[i], traj.rph[i],
                      sub(traj.std_pos), sub(traj.std_vel), sub(traj.std_att))


def evaluate(res, run: SimRun) -> SeedRun:
    """The :class:`SeedRun` of one run at the evaluation epochs (a loose or a tight result: each through
    its own trajectory conversion)."""
    if hasattr(res, "clock"):
        from aidnav.filters.tight import to_trajectory as tight_trajectory  # lazy: tight cells only

        traj = tight_trajectory(res)
    else:
        traj = to_trajectory(res)
    tt = run.truth.time
    est = _output_at(traj, np.arange(tt[0], tt[-1], EVAL_DT_S), EVAL_MAX_DT_S)
    err = trajectory_errors(est, _truth_at(run.truth, est.time), max_dt=0.0)
    e = np.hstack([err.pos, err.att])
    s = np.hstack([err.std_pos, err.std_att])
    ne, ne_att, t_ne = np.full(0, np.nan), np.full(0, np.nan), np.full(0, np.nan)
    if res.cov is not None and len(res.cov_time):
        idx, keep = np.unique(np.searchsorted(res.time, res.cov_time), return_index=True)
        ok = idx < len(res.time)
        idx, cov = idx[ok], res.cov[keep[ok]]
        x = ins_error_state(res, _truth_at(run.truth, res.time[idx]), None, idx)[:, :9]
        ne = nees(x, cov[:, :9, :9]) / 9.0
        ne_att, t_ne = nees(x[:, :3], cov[:, :3, :3]), res.time[idx]
    return SeedRun(run.seed, est.time, e, s, ne, t_ne, ne_att)


TIGHT_SOW = 345600.0  #: GPS seconds of week at the tight cells' start (the sky of the nominal constellation)
TIGHT_WEEK = 2381


def simulate_tight(cond: Condition, seed: int):
    """The tight cell's run of ``cond`` with ``seed``: (:class:`SimRun` with the IMU on the GPS time
    scale, the observations with ``cond.satellites`` kept in the ``cond.outage`` window, the ephemerides).
    The IMU draws are those of :func:`simulate_condition`; the raw GNSS draws its own stream."""
    from aidnav.nav.gnss_sat import E_URA  # lazy: tight cells only
    from aidnav.sim.gnss_constellation import nominal_constellation  # lazy: tight cells only
    from aidnav.sim.gnss_raw import RawGnssSpec, limit_satellites, simulate_raw_gnss  # lazy: tight only

    run = simulate_condition(replace(cond, outage=None), seed)
    eph = nominal_constellation(TIGHT_WEEK, TIGHT_SOW, 24)
    # a broadcast record states its user range accuracy (ICD URA index 0: 2.0 m, as
    # nominal_multi_constellation sets); the nominal GPS table leaves it 0, which the filter reads as
    # "unknown" (6144 m, RTKLIB's value): its range-error states would then swallow every pseudorange
    eph.table[:, E_URA] = 2.0
    spec = RawGnssSpec(rate_hz=cond.rate_hz)
    eph.iono_alpha, eph.iono_beta = spec.iono_alpha, spec.iono_beta  # a navigation file's broadcast set
    raw = simulate_raw_gnss(run.truth, eph, spec, np.random.default_rng([seed, 40]), TIGHT_SOW)
    t0 = TIGHT_SOW + run.truth.time[0]
    obs = raw.rover
    if cond.outage is not None:
        a, d = cond.outage
        obs = limit_satellites(obs, raw.truth["elevation"], [(a, a + d, int(cond.satellites or 0))], t0)
    imu = ImuData(run.imu.time + TIGHT_SOW, run.imu.dtheta, run.imu.dv, t0=run.imu.t0 + TIGHT_SOW)
    return replace(run, imu=imu), obs, eph


def simulate_pedestrian_cell(cond: Condition, seed: int):
    """The pedestrian cell's run (``cond.pedestrian``) with ``seed``: (:class:`SimRun` with the truth from
    0 and the IMU on the GPS time scale, its stamps ``cond.imu_late_s`` late; the observations with the
    carrier phase; the ephemerides). Every draw from ``seed``
    (:func:`aidnav.sim.pedestrian.simulate_pedestrian`)."""
    from aidnav.sim.pedestrian import SOW, simulate_pedestrian  # lazy: the pedestrian cell only

    p = simulate_pedestrian(seed, grade=cond.grade, rate_hz=cond.rate_hz)
    tr = p.truth
    truth = Trajectory(tr.time - SOW, tr.lat, tr.lon, tr.height, tr.vel, tr.rph)
    late = cond.imu_late_s + TIGHT_SOW - SOW  # (the same week second: SOW is TIGHT_SOW)
    imu = ImuData(p.imu.time + late, p.imu.dtheta, p.imu.dv, t0=p.imu.t0 + late)
    return SimRun(truth, imu, p.obs, ImuSpec.grade(cond.grade), GnssSpec(), {}, seed), p.obs, p.eph


def _run_tight_cell(cond: Condition, config: str, run: SimRun, obs, eph, sensor_model: bool, cov_t):
    """The tight filter's result of one seed with the configuration ``config`` (module doc). The pedestrian
    cell's ``matched`` is ``aidnav tight`` (its start, the carrier phase, the time offset from the phase)
    with the matched IMU model: :func:`aidnav.filters.tight.run_tight` alone reads no phase."""
    from aidnav.estimators.tight_solution import process_tight  # lazy: tight cells only
    from aidnav.filters.tight import TightConfig, apply_vehicle, run_tight  # lazy: tight cells only

    if config != "matched":
        cfg = apply_vehicle(TightConfig(), None if config == "none" else config)
        return process_tight(run.imu, obs, eph, cfg, cov_times=cov_t)[0]
    lc = config_for("matched", cond, run, sensor_model)
    if cond.pedestrian:
        return process_tight(run.imu, obs, eph, TightConfig(imu=lc.imu), cov_times=cov_t)[0]
    ini = lc.init.model_copy(update={"mode": "given"})
    cfg = TightConfig(imu=lc.imu, init=ini, constraints={"zupt": False})
    return run_tight(run.imu, obs, eph, cfg, cov_times=cov_t)


def tight_result(cond: Condition, config: str, seed: int, sensor_model: bool = True):
    """(the tight filter's result of one seed, times from the run's start; its :class:`SimRun`)."""
    run, obs, eph = (simulate_pedestrian_cell if cond.pedestrian else simulate_tight)(cond, seed)
    cov_t = np.arange(run.truth.time[0], run.truth.time[-1], EVAL_DT_S) - 1e-6 + TIGHT_SOW
    res = _run_tight_cell(cond, config, run, obs, eph, sensor_model, cov_t)
    return replace(res, time=res.time - TIGHT_SOW, cov_time=res.cov_time - TIGHT_SOW), run


def _tight_seed(cond: Condition, config: str, seed: int, sensor_model: bool):
    """The :class:`SeedRun` of one tight seed (:func:`evaluate` on :func:`tight_result`)."""
    return evaluate(*tight_result(cond, config, seed, sensor_model))


def run_cell(cond: Condition, config: str, seeds, sensor_model: bool = True) -> CellResult:
    """Run the cell ``cond`` × ``config`` over ``seeds`` (module doc)."""
    runs, errors = [], []
    for seed in seeds:
        try:
            if cond.coupling == "tight":
                r = _tight_seed(cond, config, seed, sensor_model)
            else:
                r = _loose_seed(cond, config, seed, sensor_model)
        except Exception as ex:  # a diverged or refused run is a defect of the cell, reported as such
            errors.append(f"seed {seed}: {type(ex).__name__}: {ex}")
            continue
        r.err[:, 3:] = (r.err[:, 3:] + np.pi) % (2 * np.pi) - np.pi
        runs.append(r)
    return aggregate(cond.name, config, runs, len(seeds), errors)


def aggregate(condition: str, config: str, runs: list[SeedRun], n_seeds: int | None = None,
              errors: list | None = None) -> CellResult:
    """The cell's figures (module doc) from its seeds' ``runs`` (the attitude errors already wrapped to
    ±π); ``n_seeds`` the seeds asked for (default: ``len(runs)``), ``errors`` the failed ones' messages.
    A block of a cell's seeds is ``aggregate(name, config, runs[i:j])``: the cell those seeds alone give."""
    errors = list(errors or [])
    n_seeds = len(runs) + len(errors) if n_seeds is None else n_seeds
    if not runs:
        nan6 = np.full(6, np.nan)
        return CellResult(condition, config, nan6, nan6, np.nan, 0, n_seeds, len(errors), errors)
    per = [float(np.min(np.mean(np.abs(r.err) <= 3.0 * r.sigma, axis=0))) for r in runs]
    e, s = np.vstack([r.err for r in runs]), np.vstack([r.sigma for r in runs])
    good = np.all(np.isfinite(e) & np.isfinite(s), axis=1)
    e, s = e[good], s[good]
    cov = np.mean(np.abs(e) <= 3.0 * s, axis=0)
    ratio = np.sqrt(np.mean(e ** 2, axis=0)) / np.sqrt(np.mean(s ** 2, axis=0))
    for a, bound in ((3, TILT_UNKNOWN_RAD), (4, TILT_UNKNOWN_RAD), (5, HEADING_UNKNOWN_RAD)):
        known = s[:, a] < bound  # the attitude ratios: epochs where the filter claims that angle
        if np.any(known):
            ratio[a] = np.sqrt(np.mean(e[known, a] ** 2)) / np.sqrt(np.mean(s[known, a] ** 2))
    n_all = np.concatenate([r.nees for r in runs])
    n_mean = float(np.nanmean(n_all)) if np.any(np.isfinite(n_all)) else np.nan
    return CellResult(condition, config, cov, ratio, n_mean, int(len(e)), n_seeds, len(errors), errors,
                      per, list(runs))


def run_matrix(conditions=None, configs=None, seeds=range(10), sensor_model: bool = True,
               progress=None) -> list[CellResult]:
    """Every cell of ``conditions`` (default :data:`CONDITIONS`) × ``configs`` (default
    :func:`configurations`) over ``seeds``; ``progress(cell)`` is called after each cell."""
    out = []
    for cond in conditions or CONDITIONS:
        for cfg in configs or configurations():
            cell = run_cell(cond, cfg, list(seeds), sensor_model)
            out.append(cell)
            if progress is not None:
                progress(cell)
    return out


def format_matrix(cells: list[CellResult]) -> str:
    """The matrix as fixed-width text: one row per cell, coverage and ratio per axis, NEES/9, flags."""
    head = (f"{'condition':<30} {'config':<10} " + " ".join(f"{a[:4]:>5}" for a in AXES) + " | "
            + " ".join(f"{a[:4]:>5}" for a in AXES) + f" | {'NEES/9':>7}  flags")
    lines = [f"{'':<41} 3σ coverage [%]{'':<21}| RMS(err)/RMS(σ)", head, "-" * len(head)]
    for c in cells:
        cov = " ".join(f"{100 * v:5.1f}" for v in c.coverage)
        rat = " ".join(f"{v:5.2f}" for v in c.ratio)
        fl = flags(c)
        lines.append(f"{c.condition:<30} {c.config:<10} {cov} | {rat} | {c.nees:7.2f}  "
                     + ("FAIL: " + ", ".join(fl) if fl else "ok"))
    return "\n".join(lines)


def _cell_html(v, bad: bool, fmt: str):
    return (fmt.format(v), "bad" if bad else "good")


def matrix_table(cells: list[CellResult]) -> str:
    """The matrix as an HTML table (:mod:`aidnav.report.html`): coverage and ratio per axis, the cells
    below the targets marked."""
    header = ["condition", "config"] + [f"cov {a} %" for a in AXES] + [f"ratio {a}" for a in AXES] + \
        ["NEES/9", "epochs", "failed"]
    rows = []
    for c in cells:
        rows.append([c.condition, c.config]
                    + [_cell_html(100 * v, not v >= COVERAGE_TARGET, "{:.1f}") for v in c.coverage]
                    + [_cell_html(v, not v >= RATIO_TARGET, "{:.2f}") for v in c.ratio]
                    + [H.fmt(c.nees), c.epochs, c.failed])
    return H.table(header, rows)


def matrix_page(cells: list[CellResult], title: str, notes: list[str], extra: list[str] | None = None) -> str:
    """A self-contained HTML page of the matrix (:mod:`aidnav.report.html`); ``extra``: more HTML parts
    after the matrix (the seed-level statistics, :mod:`aidnav.experiments.consistency_seeds`)."""
    conds = [[c.name, c.grade, f"{c.rate_hz:g} Hz" + ("" if c.velocity else ", position only"),
              "correlated" if c.correlated else "white", c.note] for c in CONDITIONS]
    parts = [f"<h1>{title}</h1>", "".join(f"<p class='note'>{n}</p>" for n in notes),
             matrix_table(cells), *(extra or []), "<h2>Conditions</h2>",
             H.table(["condition", "IMU grade", "GNSS", "GNSS errors", "note"], conds)]
    return H.page(title, parts)


def variant(cond: Condition, **changes) -> Condition:
    """``cond`` with fields changed (e.g. a shorter drive for a test)."""
    return replace(cond, **changes)
