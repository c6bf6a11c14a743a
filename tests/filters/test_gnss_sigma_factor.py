"""Issue 35: fixes whose stated σ is far too small (the readers' 5-cm floor for σ = 0 against 0.5/0.5/1 m
of noise) — the first pass of :mod:`aidnav.filters.gnss_errors` measures the factor by covariance
matching (median normalised innovation² over the χ²₁ median) and scales the fixes' σ.

Known answers: the true factors are 10 (horizontal) and 20 (vertical); a consistent filter's median
normalised innovation² per axis is the χ²₁ median (k = 1), so the iteration stops within k ≤ K_SIGMA = 2
of the fixed point: the scale is within a factor √2 of the truth (measured on seeds 0–7: 8.6–9.1
horizontal, 16.4–20.7 vertical). Fixes with honest σ (the same scenario unaltered) are kept as stated
(k 0.84–0.98 horizontal, 0.72–1.14 vertical, measured). The run itself, with no option: horizontal RMS
≤ 1.2 m (the issue's bound) on seeds 0, 1 and 5, where main (e82c72a) gives 2.30, 2.12 and 3.78 m
(chains of rejections and re-initialisations; docs/results.md, issue 35 session 11, m35r)."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.apps.process import process
from aidnav.filters.config import LooseConfig
from aidnav.filters.gnss_errors import K_SIGMA, choose_gnss_errors
from aidnav.io._std import ZERO_POS_STD_FLOOR_M
from aidnav.sim.run import simulate

from .test_issue35_regressions import _errors, _scenario

TRUE_FACTOR = np.array([0.5, 1.0]) / ZERO_POS_STD_FLOOR_M  # horizontal, vertical


def _floored(seed):
    sim = simulate(_scenario(1.0), seed)
    g = sim.gnss.subset(np.ones(len(sim.gnss), bool))
    g.std_pos = np.full((len(g), 3), ZERO_POS_STD_FLOOR_M)
    return sim, g


@pytest.mark.parametrize("seed", [0, 1, 5])
def test_understated_sigma_is_measured_and_the_run_holds(seed):
    sim, g = _floored(seed)
    events: list[str] = []
    cfg = choose_gnss_errors(sim.imu, g, LooseConfig(), None, events)
    scale = np.array(cfg.gnss.pos_std_scales[1:])
    assert np.all(np.abs(np.log(scale / TRUE_FACTOR)) <= np.log(np.sqrt(K_SIGMA))), (scale, events)
    assert any(e.startswith("GNSS sigma: the fixes' stated position sigma is understated") for e in events)
    run = process(sim.imu, g)
    assert run.summary["gnss_sigma"].startswith("GNSS sigma: the fixes' stated position sigma is understated")
    _, e, n, _, m = _errors(run, sim.truth)
    assert np.sqrt(np.mean(e[m] ** 2 + n[m] ** 2)) <= 1.2


def test_honest_sigma_is_kept():
    sim = simulate(_scenario(1.0), 0)
    events: list[str] = []
    cfg = choose_gnss_errors(sim.imu, sim.gnss, LooseConfig(), None, events)
    assert "pos_std_scale" not in cfg.gnss.model_fields_set
    assert any(e.startswith("GNSS sigma: as stated") for e in events), events
