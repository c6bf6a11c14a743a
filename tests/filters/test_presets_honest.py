"""Issue 35, items 5 and 6: every vehicle preset honest, and a re-initialisation that never corrupts the
calibration (:mod:`aidnav.filters.presets`, :func:`aidnav.filters.reinit.scale_nav`).

* The aircraft preset on a car (a vehicle that moves on the ground below an aircraft's take-off speed):
  before, its heading was aligned from the GNSS course only above 15 m/s, so on the matrix's 10 m/s car it
  was never aligned: the whole run navigated with an unknown heading and E/N 3σ coverage was 50–58 % at
  1 Hz and 17–33 % at 10 Hz (NEES/9 up to 10⁶). A fixed-wing aircraft below its take-off speed rolls on its
  wheels (course = heading), so the preset aligns from the course at taxi speed: position covered.
* A re-initialisation scales the IMU's sensor-error states and the calibration with the navigation
  block, each at most back to its prior: with the GNSS time tags shifted by a known amount and three
  accelerometer shocks that make the INS wrong, the car preset's runs re-initialise (6–7 times each) and
  the time-offset estimate still covers the shift.

Bounds as in ``test_consistency_matrix.py``: the issue's 95 % on the position axes (their errors
decorrelate within a run), fixed seeds, deterministic. Attitude is not asserted here (the presets
inherit the default IMU model; its tilt coverage is issue 35's other part).
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.experiments import consistency_matrix as cm
from aidnav.filters.layout import L_LEVER, L_MOUNT, L_NINS, L_TOFF, L_VDEL, NAV
from aidnav.filters.loose import loose_setup, run_loose
from aidnav.filters.presets import apply_preset

POS = slice(0, 3)


@pytest.mark.parametrize("name", ["gnss 1 Hz white", "gnss 10 Hz white"])
def test_aircraft_preset_covers_the_position_of_a_ground_vehicle(name):
    """10 Hz: the issue's 95 %. 1 Hz: 92 % E/N, held to the 10-seed bound: there its runs re-initialise
    after 10 consecutive rejected fixes (10 s), from the tilt the default IMU model does not cover (the
    presets inherit it; issue 35's other part), and such a re-initialisation does not repair the sensor
    errors (``loose._reinit_cal``). Before: E/N 50–58 % (1 Hz), 17–33 % (10 Hz)."""
    cell = cm.run_cell(cm.condition(name), "aircraft", range(10))
    print("\n" + cm.format_matrix([cell]))
    assert cell.failed == 0, cell.errors
    bound = cm.COVERAGE_TARGET if name == "gnss 10 Hz white" else cm.SEED_COVERAGE_BOUND
    assert np.all(cell.coverage[POS] >= bound), cell.coverage
    assert np.all(cell.ratio[POS] >= cm.RATIO_TARGET), cell.ratio


def test_reinitialisation_repairs_the_sensor_errors_and_the_calibration():
    """The states a re-initialisation scales (engine ``Models.cal``): every IMU sensor-error state and every
    GNSS/vehicle calibration state of the layout, each capped at its prior variance (P0's diagonal)."""
    run = cm.simulate_condition(cm.condition("gnss 1 Hz white"), 0)
    su = loose_setup(run.imu, run.gnss, apply_preset(None, "car"), None, [])
    lay, cal, P0 = su.lay, su.models.cal, su.ini.P
    want = set(range(NAV, int(lay[L_NINS])))
    for key, k in ((L_LEVER, 3), (L_TOFF, 1), (L_VDEL, 1), (L_MOUNT, 3)):
        assert lay[key] >= 0
        want |= set(range(int(lay[key]), int(lay[key]) + k))
    assert set(cal[:, 0].astype(int)) == want
    np.testing.assert_allclose(cal[:, 1], np.diag(P0)[cal[:, 0].astype(int)])


#: times [s from the start] of the accelerometer shocks that make the filter wrong (the drive starts at 30 s)
SHOCK_T_S = (90.0, 160.0, 230.0)
SHOCK_DV_M_S = 2.0  #: the velocity each shock puts into the INS that the vehicle did not make [m/s]


def _shocked(imu):
    """The IMU log with a shock at each of :data:`SHOCK_T_S`: the accelerometers clip (a pothole, a kerb),
    so one sample's forward velocity increment is :data:`SHOCK_DV_M_S` off. The INS then really is wrong
    (2 m/s against fixes of 0.1 m/s), the fixes are rejected until the filter re-initialises; the GNSS
    time offset is not touched by it, so the calibration has to come through the repair as it was."""
    for t in SHOCK_T_S:
        imu.dv[np.searchsorted(imu.time, imu.time[0] + t), 1] += SHOCK_DV_M_S
    return imu


@pytest.mark.parametrize("shift", [0.1, -0.2])
def test_reinitialisation_keeps_the_time_offset_honest(shift):
    """GNSS time tags later by s: the IMU stamps need +s. Over 5 seeds of the car preset, each run made to
    re-initialise (NIS window, consecutive rejections) by three accelerometer shocks (:func:`_shocked`),
    the estimate ends within 3σ of s and, over the epochs after the first 40 s of all seeds (the drive
    starts at 30 s), is outside 3σ on at most 5 % (the matrix's 95 % target). Measured (m35u's tree): 6–7
    re-initialisations a run, 0 % / 0.3 % of the epochs out; with re-initialisations that do not repair
    the calibration (``loose._reinit_cal`` without its calibration rows) 11 % / 20 % out, z_end up to 3.9.
    (Before, the runs re-initialised from the tilt the default IMU model did not cover; with the
    unknown-grade model they no longer do: 1 re-initialisation in 5 seeds.)"""
    cond = cm.condition("gnss 1 Hz white")
    n_reinit, out = [], []
    for seed in range(5):
        run = cm.simulate_condition(cond, seed)
        run.gnss.time = run.gnss.time + shift
        res = run_loose(_shocked(run.imu), run.gnss, apply_preset(None, "car"))
        n_reinit.append(sum("re-initialisation" in e for e in res.events))
        i = res.state_names.index("time_offset")
        z = (res.bias[:, i - NAV] - shift) / np.sqrt(res.pdiag[:, i])
        late = res.time - res.time[0] > 40.0
        assert abs(z[-1]) <= 3.0, (seed, res.bias[-1, i - NAV], np.sqrt(res.pdiag[-1, i]))
        out.append(np.abs(z[late]) > 3.0)
    assert np.mean(np.concatenate(out)) <= 0.05, [np.mean(o) for o in out]
    assert min(n_reinit) >= 1 and sum(n_reinit) >= 5, n_reinit  # the check is made across re-initialisations
