"""Issue 35, item 4: white or correlated GNSS errors, chosen from a first pass's innovations
(:mod:`aidnav.filters.gnss_errors`) when the configuration does not state ``gnss.error_tau_s``.

The consistency matrix's simulated car (consumer IMU, 300 s) with 1-Hz position + velocity fixes: white
errors (σ 0.5/0.5/1 m) leave the first pass's normalised innovations nearly white (lag-one
autocorrelation ≤ 0.25 on these seeds) and the choice is white; first-order Gauss–Markov errors (τ 30 s,
σ 0.5/0.5/1 m, 5 cm white; the fixes state the total σ) give 0.75–0.95 and the choice is the three
Gauss–Markov states — at 1 Hz, where the rate rule alone (states only above 1 Hz) took them as white. With
the states, the car preset's position σ covers the correlated errors (10 seeds, E/N/U 96.4/96.8/95.2 %;
before 84.3/80.9/82.4 %).
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.apps.process import process
from aidnav.experiments import consistency_matrix as cm
from aidnav.filters.config import LooseConfig
from aidnav.filters.gnss_errors import choose_gnss_errors


@pytest.mark.parametrize("name, correlated", [("gnss 1 Hz white", False), ("gnss 1 Hz correlated", True)])
def test_first_pass_innovations_tell_correlated_from_white_errors(name, correlated):
    run = cm.simulate_condition(cm.condition(name), 0)
    events: list[str] = []
    cfg = choose_gnss_errors(run.imu, run.gnss, LooseConfig(), None, events)
    ev = [e for e in events if e.startswith("GNSS error model")]
    assert len(ev) == 1, events
    assert "error_tau_s" in cfg.gnss.model_fields_set
    if correlated:
        assert cfg.gnss.error_tau_s > 0 and "correlated" in ev[0], ev
        assert np.allclose(cfg.gnss.error_sigma_m, np.median(run.gnss.std_pos, axis=0))
    else:
        assert cfg.gnss.error_tau_s == 0 and ": white" in ev[0], ev


def test_stated_error_model_is_kept():
    run = cm.simulate_condition(cm.condition("gnss 1 Hz correlated"), 0)
    cfg = LooseConfig.model_validate({"gnss": {"error_tau_s": 0.0}})
    events: list[str] = []
    out = choose_gnss_errors(run.imu, run.gnss, cfg, None, events)  # the σ test still runs (its own event)
    assert out.gnss.error_tau_s == 0.0 and not any(e.startswith("GNSS error model") for e in events), events
    stated = LooseConfig.model_validate({"gnss": {"error_tau_s": 0.0, "pos_std_scale": 1.0}})
    events = []
    assert choose_gnss_errors(run.imu, run.gnss, stated, None, events) is stated and not events


def test_car_preset_covers_correlated_errors_at_1_hz():
    """E/N at the issue's 95 %; U at the 10-seed bound (seed 0 draws a U error of −2.4σ at the start,
    which the filter's height then carries for minutes: U coverage 84.7 % over seeds 0–2)."""
    cell = cm.run_cell(cm.condition("gnss 1 Hz correlated"), "car", range(10))
    print("\n" + cm.format_matrix([cell]))
    assert cell.failed == 0, cell.errors
    assert np.all(cell.coverage[:2] >= cm.COVERAGE_TARGET), cell.coverage[:3]
    assert cell.coverage[2] >= cm.SEED_COVERAGE_BOUND, cell.coverage[:3]
    assert np.all(cell.ratio[:3] >= cm.RATIO_TARGET), cell.ratio[:3]


def test_process_summary_says_which_model_and_why():
    """``aidnav process`` with no option on the 1-Hz correlated fixes: the summary's ``gnss_error_model``
    names the choice and the autocorrelation it rests on."""
    run = cm.simulate_condition(cm.condition("gnss 1 Hz correlated"), 0)
    why = process(run.imu, run.gnss).summary["gnss_error_model"]
    assert why is not None and why.startswith("GNSS error model: correlated") and "autocorrelation" in why
