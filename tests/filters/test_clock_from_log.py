"""The receiver clock's wander measured on the log (issue 40, session 15: ``gnss.clock_from_log``):
:func:`aidnav.filters.tight.clock_drift_psd` against a simulated random-walk drift (known PSD) and a pure
frequency ramp (closed form), and the walk's clock, which ramps like a warming oscillator."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from aidnav.filters.tight import CLOCK_GRADES, TightConfig, clock_drift_psd, clock_hm2_from_psd
from aidnav.nav.gnss_sat import C_LIGHT


def test_random_walk_drift_psd_recovered():
    """A drift random walk of PSD 0.05 m²/s³ (h-2 ≈ 2.8e-20, a TCXO's order) sampled at 1 Hz with 0.3 m/s
    white snapshot noise, 2,000 s, lags up to 100 s: the estimate is unbiased with a relative SD of 0.22
    over 300 seeds (measured: mean ratio 1.008, 0.5–99.5 % quantiles 0.56–1.53); one fixed seed within
    3 SDs."""
    s_true, sn, n = 0.05, 0.3, 2000
    rng = np.random.default_rng(1)
    d = np.cumsum(rng.normal(0.0, np.sqrt(s_true), n)) + rng.normal(0.0, sn, n)
    s_d, noise_var, n_lags = clock_drift_psd(np.arange(n, dtype=float), d, max_frac=0.05)
    assert n_lags == 7  # 1, 2, …, 64 s ≤ 0.05 × 1999 s
    assert abs(s_d / s_true - 1.0) < 3 * 0.22, s_d
    assert 0.0 <= noise_var < 4 * sn**2


def test_frequency_ramp_is_the_random_walk_of_its_variance_over_the_lags():
    """A warming oscillator's drift ramp D·t (no noise): the increments over a lag L are D·L, their mean
    square D²L² (about zero, as the Allan variance), and the least-squares line through (L, D²L²) over the
    lags Δ, 2Δ, 4Δ, … ≤ a quarter of the span has the slope Σ(L−L̄)(L²−m)/Σ(L−L̄)² — computed here from the
    lags alone. A scatter about the mean increment (a robust spread, a detrended series) would give 0."""
    step, n, ramp = 0.25, 537, -0.2  # the walk's epochs and its clock's ramp [m/s²]
    t = 408640.0 + step * np.arange(n)
    s_d, _, n_lags = clock_drift_psd(t, -60.0 + ramp * (t - t[0]))
    lags = step * 2.0 ** np.arange(8)  # 0.25 … 32 s ≤ 134 / 4
    assert n_lags == len(lags)
    x, y = lags - lags.mean(), ramp**2 * lags**2
    assert s_d == pytest.approx(np.sum(x * (y - y.mean())) / np.sum(x * x), rel=1e-9)


def test_too_short_or_gappy_logs_say_nothing():
    assert clock_drift_psd(np.arange(3.0), np.zeros(3)) is None
    t = np.arange(30.0)  # lags 1, 2, 4 s ≤ 7.25 s, but only 1 finite drift in 3
    d = np.where(np.arange(30) % 3 == 0, 1.0, np.nan)
    assert clock_drift_psd(t, d) is None


def test_hm2_conversion_and_the_switch():
    assert clock_hm2_from_psd(C_LIGHT**2 * 2.0 * np.pi**2 * CLOCK_GRADES["tcxo"][1]) == pytest.approx(2e-20)
    assert TightConfig().gnss.clock_from_log and TightConfig().gnss.clock_hm2 is None


def test_walk_clock_wanders_beyond_a_tcxo(data_dir):
    """The walk's receiver clock drift (SPP, 4 GPS satellites) falls from −60 to −81 m/s in 115 s, a ramp
    of about −0.2 m/s² (a warming oscillator), then holds: over the lags up to 32 s it wanders as a random
    walk of PSD ~0.9 m²/s³ (measured 0.93), 26× the TCXO grade's 0.035 — the prior the filter had, which
    gave its drift 1.2 m/s of σ over 40 s where it moved 8 m/s."""
    d = data_dir / "rtklibexplorer_walk_0827"
    if not d.is_dir():
        pytest.skip("walk data set not found")
    from aidnav.estimators.spp import spp_series
    from aidnav.io.rinex import read_rinex_nav, read_rinex_obs

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        nav = read_rinex_nav(d / "rinex_converted" / "gnss_1730.nav")
        obs = read_rinex_obs(d / "rinex_converted" / "gnss_1730.obs")
    sp = spp_series(obs, nav)
    dr = sp["clock_drift"]
    ok = np.isfinite(dr)
    slope = np.polyfit(sp["time"][ok][:400], dr[ok][:400], 1)[0]
    assert -0.25 < slope < -0.15, slope
    s_d, _, _ = clock_drift_psd(sp["time"], dr)
    tcxo = C_LIGHT**2 * 2.0 * np.pi**2 * CLOCK_GRADES["tcxo"][1]
    assert s_d > 10 * tcxo, (s_d, tcxo)
