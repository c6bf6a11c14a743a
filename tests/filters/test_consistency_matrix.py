"""Cells of the consistency matrix (issue 35, :mod:`aidnav.experiments.consistency_matrix`) that run in
seconds: the matched configuration on every IMU grade, with its scale factors and misalignments, and the
configuration of no option at all, 10 seeds each.

Bound. An honest Gaussian σ leaves |error| > 3σ with probability p = 0.0027. The white errors
decorrelate within a run (each run of ~280 epochs holds ≥ 10 independent stretches), but the sensor
constants (biases, scale factors, misalignments) are drawn once per seed, so for them the 10 seeds are the
sample: in the worst case a seed is wholly inside or wholly outside 3σ, and the number of uncovered seeds
is Binomial(10, 0.0027): one of ten with probability 2.7 % per axis (the issue's 95 % would fail an
honest filter that often), two with 3.3e-4. Where the constants dominate (the attitude), the tests hold
the cells to ``cm.SEED_COVERAGE_BOUND`` (one seed out allowed, two not: 85.5 %); elsewhere to the issue's
95 %. The seeds are fixed, so the tests are deterministic. RMS(error)/RMS(σ) ≥ 0.3: the issue's bound on
a σ that is uselessly large. The model before issue 35 (one Gauss–Markov bias state, no scale-factor or
misalignment states) fails the consumer cell's roll/pitch (the test that the check can fail).
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.data import GnssData, Trajectory
from aidnav.experiments import consistency_matrix as cm
from aidnav.nav.earth import radii

SEEDS = range(10)
POS, ATT, HEAD = slice(0, 3), slice(3, 5), 5


def _check(cell, att_bound=cm.COVERAGE_TARGET):
    print("\n" + cm.format_matrix([cell]))
    assert cell.failed == 0, cell.errors
    cov = dict(zip(cm.AXES, cell.coverage, strict=True))
    assert np.all(cell.coverage[POS] >= cm.COVERAGE_TARGET), cov
    assert cell.coverage[HEAD] >= cm.COVERAGE_TARGET, cov
    assert np.all(cell.coverage[ATT] >= att_bound), cov
    assert np.all(cell.ratio >= cm.RATIO_TARGET), dict(zip(cm.AXES, cell.ratio, strict=True))


@pytest.mark.parametrize("grade", ["navigation", "tactical", "mems", "consumer"])
def test_matched_configuration_covers_every_axis_on_every_grade(grade):
    """mems: pitch 95.2 % over the 10 seeds with the accelerometer-misalignment states (issue 35 session
    11; 93.5 % before them, from seeds 4 and 9: 61 and 74 %; seed 4 draws a gyro misalignment entry of
    3.4σ, which its prior cannot cover): held to the 10-seed bound, the margin over 95 % being thin."""
    cell = cm.run_cell(cm.condition(f"grade {grade}"), "matched", SEEDS)
    assert cell.epochs >= 10 * 250
    _check(cell, cm.SEED_COVERAGE_BOUND if grade == "mems" else cm.COVERAGE_TARGET)


@pytest.mark.parametrize("name", ["gnss outage 60 s", "moving start, position only",
                                  "imu gap 30 s in a turn"])
def test_matched_configuration_covers_an_outage_and_a_moving_start(name):
    """Consumer grade: 60 s without fixes over two turns; a log that starts at 10 m/s with 1 Hz
    position-only fixes (before issue 35's sensor model: roll/pitch 42–51 %); 30 s without IMU samples in
    the middle of a 180° turn (measured 99.8/99.9/99.5/99.5/98.6/100.0 %, ratios 0.83–1.20)."""
    _check(cm.run_cell(cm.condition(name), "matched", SEEDS))


def test_matched_configuration_parked_then_driving():
    """10 min parked with 10-Hz position-only fixes, then the drive (issue 35 session 11, m35p): the tilt
    turned with the computed heading's changes at rest and the heading held against spurious
    gyrocompassing (engine._turn_tilt_at_rest, _hold_heading_at_rest). Measured 99.6 99.7 99.7 90.6 99.1
    100.0 %, NEES/9 2.07; main 85e1138: roll/pitch/heading 65.0/86.0/76.8 %, NEES/9 8.67. The roll is held
    to the 10-seed bound: three seeds (1, 8, 9, 71–72 %) are out after the drive starts with the heading
    10 min of z-gyro bias off (σ 23–60°), where the first-order update misassigns the velocity errors.
    Session 12 (n35p): the tilt turns with every heading correction the feedback applies at a moving node
    (the drive's start corrects the heading by tens of degrees): 99.5 99.6 99.8 100.0 99.9 99.4 %, NEES/9
    1.04. In the merge the turn at a moving node was kept to corrections above 5° (turning on every
    correction broke the transfer-alignment smoother's P ≤ forward P and the batched engine's equality):
    roll 91.7 %. Session 13 (p35p): the turn at every moving node, the RTS pass and the batched engine
    seeing it (filters.tilt_turn): 99.5 99.6 99.8 100.0 99.9 99.4 % (seeds 10–19: 97.7 % roll)."""
    _check(cm.run_cell(cm.condition("parked 10 min then driving"), "matched", SEEDS))


@pytest.mark.parametrize("config", ["none", "car", "ship"])
def test_no_option_and_presets_parked_then_driving(config):
    """The same cell with no option and a preset (issue 35 session 12, n35p). Before, on the unknown-grade
    model (n35base f6f0548): none 100.0 100.0 100.0 96.8 99.9 100.0 % but the position σ 4× the error
    (RMS(error)/RMS(σ) 0.26 0.26 0.25: the rate rule's Gauss–Markov states on white 10-Hz fixes), car
    roll/pitch 74.4/79.9 % (the NIS window's re-initialisations at rest scaled the tilt and the
    accelerometer bias, anti-correlated through their one observed sum, by unequal factors: a new exact
    relation between them, and the tilt σ fell to 0.25° against the bound of 0.71°). Now: the white/correlated
    test at any rate (filters.gnss_errors), the re-initialisation adds variance (filters.reinit).
    Ship (session 14, q35t): on main 4ca2cd1 99.7 99.7 95.8 95.4 94.6 99.2 % (seed 0's tilt 6–14° off at
    σ 1–2° while parked: its levelled tilt independent of the accelerometer bias, the split spun by the
    held heading); the start's tilt tied to the accelerometer states (preprocess._start_levelling)."""
    _check(cm.run_cell(cm.condition("parked 10 min then driving"), config, SEEDS))


@pytest.mark.parametrize("config", ["none", "car"])
def test_imu_gap_position_sigma_is_honest_and_useful(config):
    """The 30-s IMU gap in a turn with no option and the car preset, position axes only (their tilt is the
    IMU model's, the no-option cells below): the gap's motion bound (≈ 2 km with these bounds) must give way
    to the first fix after the gap at the gap's closing node, so that no output after the gap carries it
    (before issue 35 session 9: position ratio 0.01–0.05, the one output with a km σ dominating RMS(σ));
    and the σ must still cover (measured on c11a759: none 97.0/95.1/99.8 %, ratio 1.41/1.82/0.80; car
    98.7/96.8/100.0 %, 1.00/1.05/0.78)."""
    cell = cm.run_cell(cm.condition("imu gap 30 s in a turn"), config, SEEDS)
    print("\n" + cm.format_matrix([cell]))
    assert cell.failed == 0, cell.errors
    assert np.all(cell.coverage[POS] >= cm.COVERAGE_TARGET), cell.coverage[POS]
    assert np.all(cell.ratio[POS] >= cm.RATIO_TARGET), cell.ratio[POS]


def test_matched_configuration_at_10_hz_covers_when_it_models_every_sensor_error():
    """10-Hz white fixes, the consumer IMU without its misalignments (the matched model then has no
    misalignment term to leave out): every axis covered, 10 seeds (measured 99.9/99.6/99.8/100/99.7/100 %,
    ratios 0.83-1.08, NEES/9 0.93; with only the accelerometer's misalignment removed from the simulated
    IMU, gyro misalignment states kept: 99.9/99.6/99.8/100/100/100 %, NEES/9 0.97). The 10-Hz fixes alone
    do not make the filter overconfident; the cells below pass since the model leaves no term out."""
    cond = cm.variant(cm.condition("gnss 10 Hz white"), imu=(("misalignment_arcsec", 0.0),))
    _check(cm.run_cell(cond, "matched", SEEDS))


@pytest.mark.parametrize("name", ["gnss 10 Hz white", "gnss 10 Hz correlated"])
def test_matched_configuration_at_10_hz_covers_the_consumer_imu(name):
    """The consumer IMU with its 0.5° accelerometer misalignments at 10 Hz: the issue's 95 % on every
    axis. Before the six accelerometer-misalignment states (issue 35 session 11; a strict xfail of
    session 10) the matched model folded the misalignment into the bias (m·g, exact while level) and the
    z accelerometer's m_zx·a in the first acceleration looked like a pitch error to the 10-Hz fixes: pitch
    92.4 / 91.8 % (white / correlated; seeds 2 and 4 two-thirds out), NEES/9 1.45 / 1.53; with the states
    measured 99.9 99.6 99.8 99.9 100.0 100.0 % / 100.0 99.4 97.9 100.0 100.0 100.0 %, NEES/9 1.02 /
    1.11."""
    _check(cm.run_cell(cm.condition(name), "matched", SEEDS))


@pytest.mark.parametrize("name", ["gnss 1 Hz white", "imu gap 30 s in a turn", "grade mems"])
def test_no_option_does_not_claim_a_tilt_it_cannot_have(name):
    """No option at all (an IMU of unknown grade: the consumer error model, issue 35): before, roll/pitch
    coverage 15–28 % on the consumer IMU (σ 0.07–0.2° against 0.5–2° of error) and the 30-s gap's
    position σ 20–100× too large at its end (ratio 0.01–0.05). Since the tilt turns with a held heading and
    the default model is the unknown grade's with a Gauss–Markov accelerometer bias (session 11, m35u;
    before: roll/pitch 30.9/16.5 % and 84.0/69.9 %), measured: gap 99.6 99.8 100.0 97.3 96.3 100.0 %, NEES/9
    1.51; mems 99.5 97.9 100.0 100.0 100.0 100.0 %, NEES/9 1.19. 1 Hz white was a strict xfail (session 8,
    j35b: the held heading moved by tens of degrees per update; m35u: tilt covered, 97.3/94.9 %, but the
    heading's ratio 0.25): since the time offset is considered, not estimated, while the heading is held
    (session 12, n35u: ``engine._consider_timing``) it passes, 99.7 99.6 100.0 97.8 97.1 100.0 %, ratios
    0.90 1.00 0.82 1.48 1.34 1.00, NEES/9 1.45. With n35c's evaluation at the
    filter's own output rows and n35p's tilt turn at moving nodes: re-measured in session 12's merge.
    Session 13: with the turn at every moving node alone (p35p) the mems roll ratio was 0.29 (a strict xfail
    on that branch); with p35g's grade mixture beside it, measured in the merge: mems 99.9 99.7 100.0 100.0
    100.0 100.0 %, ratios 0.93 1.17 0.75 0.30 0.33 0.68, NEES/9 1.17. Session 14 (q35g: the joint
    levelled tilt prior, the MEMS grade's own model, the mixture's 3σ tail): 1 Hz white 99.2 99.0 100.0
    98.6 100.0 100.0 % | 0.91 0.87 0.78 1.30 1.27 1.13; gap 99.8 99.8 100.0 98.3 100.0 100.0 %; mems 99.7
    97.8 100.0 97.4 98.1 99.7 % | 1.27 1.58 0.78 1.30 1.27 0.98, NEES/9 2.46. With q35t's levelled start
    (σ_w the configured tilt σ's part beyond the accelerometer's) in the merge: 1 Hz white 99.6 99.2 100.0
    99.0 97.6 100.0 % | 1.10 1.11 0.80 1.29 1.28 1.02; mems the same as q35g's to the digit
    (a fine levelling's σ_w is its standard error in both)."""
    _check(cm.run_cell(cm.condition(name), "none", SEEDS), cm.SEED_COVERAGE_BOUND)


@pytest.mark.parametrize("config", ["aircraft", "pedestrian", "ship"])
def test_presets_on_a_mems_imu_are_honest_and_useful(config):
    """A MEMS IMU classed by its standstill (issue 35, session 14, q35g). Before, a MEMS-classed IMU was
    modelled by the unknown-grade (consumer) model: roll σ ~4× the error, RMS(err)/RMS(σ) 0.26 / 0.27 /
    0.29 with coverage 100 % (seeds 10–19: 0.25–0.28 for every configuration). With the MEMS row's model
    alone the levelled tilt's independent σ was shrunk by the ZUPTs (roll/pitch 83–90 %); with the joint
    levelled prior and the posterior mixture matched on its 3σ tail, measured: aircraft 97.3/97.2 % |
    1.31/1.40, pedestrian 97.3/98.4 % | 1.31/1.37, ship 98.5/95.2 % | 1.29/1.37 (seeds 10–19, not used to
    decide anything: 96.4–96.6 % roll, 100 % pitch, ratios 1.13–1.27)."""
    _check(cm.run_cell(cm.condition("grade mems"), config, SEEDS), cm.SEED_COVERAGE_BOUND)


def test_epochs_take_the_filters_own_output_not_an_interpolation_across_a_reset():
    """Known answer: outputs at 100 Hz whose heading σ drops from 180° to 5° at a reset at t = 33.005 s
    and whose heading jumps there; the epoch t = 33 s gets the row at 33.00 (σ 180°, the held heading) —
    linear interpolation between the rows around a reset at 33.000 would give neither σ; an epoch with no
    output within ``EVAL_MAX_DT_S`` before it (a gap) is left out, and each row is used once."""
    t = np.round(np.concatenate([np.arange(30.0, 33.001, 0.01), np.arange(33.01, 34.0, 0.01), [36.0]]), 6)
    n = len(t)
    sig = np.where(t < 33.005, np.pi, np.radians(5.0))
    rph = np.zeros((n, 3))
    rph[:, 2] = np.where(t < 33.005, 2.0, 0.5)
    traj = Trajectory(t, np.full(n, 0.7), np.full(n, 2.0), np.zeros(n), np.zeros((n, 3)), rph,
                         np.ones((n, 3)), np.ones((n, 3)), np.column_stack([sig * 0.01, sig * 0.01, sig]))
    out = cm._output_at(traj, np.array([31.0, 33.0, 33.5, 35.0, 36.0, 36.02]), cm.EVAL_MAX_DT_S)
    np.testing.assert_allclose(out.time, [31.0, 33.0, 33.5, 36.0])
    np.testing.assert_allclose(out.std_att[:, 2], [np.pi, np.pi, np.radians(5.0), np.radians(5.0)])
    np.testing.assert_allclose(out.rph[:, 2], [2.0, 2.0, 0.5, 0.5])


def test_no_option_on_a_navigation_grade_imu_is_honest_and_useful():
    """No option on a navigation-grade IMU (issue 35, session 12, n35g): its 29-s standstill classes it
    (filters.grade) and its σ becomes the grade's — before, the unknown-grade model's: every coverage
    100 % but RMS(err)/RMS(σ) roll 0.23, heading 0.19 (σ uselessly large); measured after: 100 100 100 100
    100 100 % | 0.68 0.69 0.70 0.54 0.46 0.97."""
    _check(cm.run_cell(cm.condition("grade navigation"), "none", SEEDS))


@pytest.mark.parametrize("config", ["aircraft", "car", "pedestrian", "ship"])
def test_presets_after_an_imu_gap_in_a_turn(config):
    """The 30-s IMU gap in a turn with each preset (issue 35, session 13, p35g). Before, the course
    alignment that ends the held heading at the start re-defined the computed frame in the middle of a
    propagation interval while the interval's error model kept the old one (Σ C_b^n, Σ f^n of the samples
    before it): the tilt–accelerometer-bias difference looked observed, the tilt σ fell 0.72° → 0.18° in
    1–2 s with the error at 1–1.6° (pedestrian pitch 81.3 %, aircraft 93.3 %; car/ship roll 93.1 %), and
    the aircraft's and pedestrian's post-gap σ of a tilt that may be anything (52°) decided the ratio
    (0.19–0.28). Measured after: aircraft 96.9/95.5 %, car 95.2/99.2 %, pedestrian 93.8/98.5 % (seeds 4,
    6: the heading after the 30° course re-alignment in the turn), ship 96.7/98.1 %; ratios ≥ 0.64."""
    _check(cm.run_cell(cm.condition("imu gap 30 s in a turn"), config, SEEDS), cm.SEED_COVERAGE_BOUND)


@pytest.mark.parametrize("config", ["none", "car", "pedestrian"])
def test_no_option_and_presets_on_a_tactical_imu_are_honest_and_useful(config):
    """A tactical IMU whose 29-s start cannot rule out a MEMS one (4 of 10 seeds: MEMS posterior 1–5 %)
    is modelled by the posterior mixture of the possible grades (:func:`aidnav.filters.grade.mixture_model`;
    before, the loosest one's, the unknown-grade model: roll/pitch ratio 0.18–0.27 with every coverage
    ≥ 98.8 %). Measured after (session 13, p35g): none 97.8/99.8 % | 0.66/0.54, car 97.8/99.6 % |
    0.65/0.54, pedestrian 97.9/99.8 % | 0.66/0.53; seeds 10–19 (not used to decide anything): 96.0–96.4 %
    roll, ratios ≥ 0.52."""
    _check(cm.run_cell(cm.condition("grade tactical"), config, SEEDS), cm.SEED_COVERAGE_BOUND)


def test_model_without_misalignment_states_is_not_covered_on_a_consumer_imu():
    cell = cm.run_cell(cm.condition("grade consumer"), "matched", SEEDS, sensor_model=False)
    print("\n" + cm.format_matrix([cell]))
    assert cell.coverage[3] < cm.COVERAGE_TARGET and cell.coverage[4] < cm.COVERAGE_TARGET


def test_gauss_markov_errors_have_their_sigma_and_correlation():
    """The simulated time-correlated GNSS errors: steady-state σ and lag-k correlation e^(−kΔt/τ)
    (known answers; 20,000 fixes at 1 Hz, τ 30 s: ~330 correlation times, σ of the σ estimate ≈ 4 %)."""
    m = 20000
    g = GnssData(np.arange(m, dtype=float), np.full(m, 0.7), np.full(m, 2.0), np.zeros(m),
                 std_pos=np.full((m, 3), 0.05))
    lat0, lon0 = g.lat.copy(), g.lon.copy()
    cm.add_gauss_markov(g, (0.5, 0.5, 1.0), 30.0, np.random.default_rng(1))
    rm, rn = radii(lat0)
    e = np.column_stack([(g.lon - lon0) * rn * np.cos(lat0), (g.lat - lat0) * rm, g.height])
    np.testing.assert_allclose(e.std(axis=0), [0.5, 0.5, 1.0], rtol=0.15)
    r10 = np.mean(e[10:, 2] * e[:-10, 2]) / np.mean(e[:, 2] ** 2)
    assert r10 == pytest.approx(np.exp(-10.0 / 30.0), abs=0.08)
    np.testing.assert_allclose(g.std_pos[0], np.sqrt(0.05 ** 2 + np.array([0.5, 0.5, 1.0]) ** 2))


@pytest.mark.parametrize("name", ["tight 2 satellites", "tight 0 satellites"])
def test_tight_cells_matched_configuration_covers_every_axis(name):
    """Tight coupling, raw GNSS of the nominal sky, 2 or 0 satellites for 60 s over two turns, consumer
    IMU with the matched model (its scale-factor and both triads' misalignment states in the tight
    filter's INS block, 33 states): E/N/U/roll/pitch/heading coverage measured 100/100/100/100/99.0/100 %
    with 2 and with 0 satellites, NEES/9 0.69-0.70 (issue 35 session 11; with the gyro misalignment states
    only, issue 40's session 9: pitch 96.8 and 97.7 %, NEES/9 0.73-0.74). Every axis at the issue's 95 %."""
    cell = cm.run_cell(cm.condition(name), "matched", SEEDS)
    assert cell.epochs >= 10 * 250
    _check(cell)


@pytest.mark.parametrize("name", ["tight 2 satellites", "tight 0 satellites"])
def test_tight_cells_no_option_decides_the_nhc_and_covers_every_axis(name):
    """`aidnav tight` with no option decides the NHC from the log as `aidnav process` does (issue 35 item
    6: the smoothed first pass, :func:`aidnav.filters.wheeled.wheeled_vehicle`); without it a wheeled
    vehicle's IMU-to-body rotation (the common part of the sensors' misalignments) is unobservable and the
    pitch followed it: 92.9 % (2 satellites) and 94.6 % (0) before, one seed (4: a 3.4σ gyro misalignment
    entry) wholly out. Now 100/100/100/98.4/100/100 % and 100/100/100/98.5/100/100 % (issue 35/40, session
    12): every axis at the issue's 95 %."""
    _check(cm.run_cell(cm.condition(name), "none", SEEDS))


def test_tight_cell_car_preset():
    """`aidnav tight --vehicle car` (its NHC): 100/100/100/98.2/100/100 % with 2 satellites (session 12,
    the levelled start tilt correlated with the accelerometer states; 96.6 % roll before). Roll/pitch held
    to the 10-seed bound."""
    _check(cm.run_cell(cm.condition("tight 2 satellites"), "car", SEEDS), cm.SEED_COVERAGE_BOUND)


def test_tight_preset_without_nhc_attitude_nees_is_chi2_over_40_seeds():
    """`aidnav tight --vehicle aircraft` (no NHC) on the tight 3-satellite cell, 40 seeds: the attitude
    error's NEES (φ, 3 dof) at the end of the run, summed over the seeds, against χ²(120) — independent
    across seeds, so exact (aidnav.experiments.consistency_seeds). With the accelerometer misalignment folded
    into the bias σ (27 states, main b860b65) the turns read the fold's error as information: mean 1.70 per
    dof, p = 2.5e-6, pitch z² p = 8e-5; with its 6 states (config.UNKNOWN_GRADE_IMU_ACCEL_MISALIGNMENT, issue
    35 session 16) measured 1.12 per dof, p = 0.17 (pitch z² p = 0.09). Held to p ≥ 1e-3 on both."""
    from aidnav.experiments import consistency_seeds as cs

    cond = cm.condition("tight 3 satellites")
    cell = cm.run_cell(cond, "aircraft", range(40))
    assert cell.failed == 0, cell.errors
    end = cs.seed_statistics(cell, cond, n_sim=100)["fixed"]["end"]
    print(end["nees_att"], end["tilt"]["pitch"]["chi2"])
    assert end["nees_att"]["n"] == 40
    assert end["nees_att"]["p_upper"] >= 1e-3
    assert end["tilt"]["pitch"]["chi2"]["p_upper"] >= 1e-3
