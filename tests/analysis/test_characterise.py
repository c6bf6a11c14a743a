"""IMU characterisation (issue 19): Allan deviation → fitted noise terms → filter ``imu:`` section.

Acceptance (reduced here, full in ``benchmarks/characterise.py``): static logs of 2 h at 100 Hz from the
core IMU model (tactical and MEMS presets plus a random walk) → each term's 95% interval holds the true
value, ARW/VRW within 10%; the ``imu:`` section it writes gives a filter whose NEES on a simulated flight
with the same IMU is inside its chi-square band. Guard rails: moving logs, gaps, jitter, short logs.

Frames and units as in CONVENTIONS (body RFU; rad, m/s inside; deg/√h, m/s/√h, deg/h, µg at the boundary).
"""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from scipy.signal import lfilter
from scipy.stats import binom

from aidnav.analysis import characterise as C
from aidnav.analysis.noise_fit import allan_cov as AC
from aidnav.analysis.noise_fit import model as NFM
from aidnav.data import ImuData
from aidnav.sim.imu import ImuSpec, corrupt_imu

# random walks added to the presets (as in benchmarks/characterise.py) [deg/h/√h, µg/√h]
RRW = {"tactical": (0.8, 100.0), "mems": (9.0, 180.0)}


def grade_spec(grade: str, rrw=True) -> ImuSpec:
    u = ImuSpec.grade(grade).to_units()
    g, a = RRW[grade] if rrw else (0.0, 0.0)
    return ImuSpec.from_units(arw_deg_sqrt_h=u["arw_deg_sqrt_h"], vrw_m_s_sqrt_h=u["vrw_m_s_sqrt_h"],
                              gyro_bias_instability_deg_h=u["gyro_bias_instability_deg_h"],
                              accel_bias_instability_ug=u["accel_bias_instability_ug"],
                              bias_corr_time_s=u["gyro_bias_corr_time_s"][0], gyro_rrw_deg_h_sqrt_h=g,
                              accel_rrw_ug_sqrt_h=a, name=grade)


def static_log(spec: ImuSpec, seed: int, seconds: float = 7200.0, fs: float = 100.0, t0: float = 0.0,
               jitter: float = 0.0) -> ImuData:
    """A static log (zero rate, 1 g on z) with the errors of ``spec``; ``jitter`` = relative half-width of
    uniformly jittered intervals."""
    n = int(round(seconds * fs))
    rng = np.random.default_rng(seed + 1_000_003)
    dt = np.full(n, 1.0 / fs) * (1.0 + jitter * rng.uniform(-1.0, 1.0, n))
    t = t0 + np.cumsum(dt)
    truth = ImuData(t, np.zeros((n, 3)), np.column_stack([np.zeros((n, 2)), 9.80665 * dt]), t0=t0)
    return corrupt_imu(truth, spec, np.random.default_rng(seed))[0]


def truth_terms(spec: ImuSpec) -> dict:
    return {s: {"white": (spec.gyro_arw if g else spec.accel_vrw)[0],
                "gm_sigma": (spec.gyro_bias_instability if g else spec.accel_bias_instability)[0],
                "bias_instability": C.B_PER_GM_SIGMA * (spec.gyro_bias_instability if g
                                                        else spec.accel_bias_instability)[0],
                "gm_tau": (spec.gyro_bias_tau if g else spec.accel_bias_tau)[0],
                "rrw": (spec.gyro_rrw if g else spec.accel_rrw)[0], "quantisation": 0.0}
            for s, g in (("gyro", True), ("accel", False))}


# ------------------------------------------------------------------------------------- model pieces
def test_gauss_markov_constants():
    """ADEV of a first-order GM peaks at 0.6174 σ at τ = 1.8926 T; flicker floor 0.6643 B; B = 0.9294 σ."""
    r = minimize_scalar(lambda x: -NFM.gm_shape(np.array([x]))[0], bounds=(0.5, 5.0), method="bounded",
                        options={"xatol": 1e-10})
    assert r.x == pytest.approx(C.GM_PEAK_X, rel=1e-6)
    assert math.sqrt(-r.fun) == pytest.approx(C.GM_PEAK_ADEV, rel=1e-9)
    assert C.FLICKER_ADEV == pytest.approx(0.6643, abs=1e-4)
    assert C.B_PER_GM_SIGMA == pytest.approx(0.9294, abs=1e-4)
    # series branch joins the closed form; RRW-like and white-like limits (El-Sheimy 2008)
    x = np.array([0.05 - 1e-12, 0.05 + 1e-12])
    assert NFM.gm_shape(x)[0] == pytest.approx(NFM.gm_shape(x)[1], rel=1e-9)
    assert NFM.gm_shape(np.array([1e-4]))[0] == pytest.approx(2e-4 / 3, rel=1e-3)
    assert NFM.gm_shape(np.array([1e4]))[0] == pytest.approx(2e-4, rel=1e-3)


def test_estimate_statistics_match_greenhall_and_simulation():
    """EDFs from the exact covariance agree with Greenhall's approximation for white FM (m ≥ 64; below,
    Greenhall's is up to 10% lower than the exact discrete sum); for a white + GM + random-walk mixture the
    whitened residuals of simulated log-Allan variances have unit variance."""
    import allantools

    n = 1 << 15
    ms = 2 ** np.arange(0, 13)
    taus = ms * 0.01
    nu, _ = AC.estimate_stats(taus, ms, n + 1, np.array([0.0, 1.0, 0.0, 0.0]), 600.0)
    gh = np.array([allantools.edf_greenhall(0, 2, int(m), n + 1, overlapping=True) for m in ms])
    np.testing.assert_allclose(nu[6:], gh[6:], rtol=0.01)
    np.testing.assert_allclose(nu[3:6], gh[3:6], rtol=0.1)
    # mixture: 200 simulated series
    coef = np.array([0.0, 1e-4, 1e-4, 1e-6])
    t_corr = 20.0
    rng = np.random.default_rng(11)
    phi = math.exp(-0.01 / t_corr)
    logs = []
    for _ in range(200):
        w = rng.standard_normal((3, n))
        gm = lfilter([1e-2 * math.sqrt(1 - phi * phi)], [1.0, -phi], w[1],
                     zi=[phi * 1e-2 * rng.standard_normal()])[0]
        y = 1e-2 / math.sqrt(0.01) * w[0] + gm + np.cumsum(1e-3 * math.sqrt(0.01) * w[2])
        x = np.r_[0.0, np.cumsum(y)] * 0.01
        logs.append([np.log(np.mean((x[2 * m:] - 2 * x[m:-m] + x[:-2 * m]) ** 2) / (2 * (m * 0.01) ** 2))
                     for m in ms])
    logs = np.array(logs)
    nu, linv = AC.estimate_stats(taus, ms, n + 1, coef, t_corr)
    b, sd = NFM.logchi2_moments(nu)
    z = ((logs - np.log(C.model_avar(taus, coef, t_corr)) - b) / sd) @ linv.T
    per_tau = (z**2).mean(axis=0)
    assert np.all((per_tau > 0.6) & (per_tau < 1.5)), per_tau
    assert (z**2).sum(axis=1).mean() == pytest.approx(len(ms), rel=0.15)


# ------------------------------------------------------------------------------------------ fitting
def test_white_noise_only():
    """ARW/VRW within their intervals and 2%; nothing else is reported."""
    spec = ImuSpec.from_units(arw_deg_sqrt_h=0.2, vrw_m_s_sqrt_h=0.05)
    ch = C.characterise_imu(static_log(spec, 1, seconds=1800.0))
    for a in ch.axes:
        q = spec.gyro_arw[0] if a.sensor == "gyro" else spec.accel_vrw[0]
        w = a.terms["white"]
        assert w.fitted and w.covers(q) and abs(w.value / q - 1) < 0.02, (a.axis, w, q)
        for k in ("quantisation", "gm_sigma", "gm_tau", "bias_instability", "rrw"):
            assert not a.terms[k].fitted, (a.axis, k, a.terms[k])


def test_quantisation_is_seen():
    """An angle quantum q with residual carry (white phase noise of variance q²/12 when the per-sample
    noise is a few quanta) gives the IEEE 952 coefficient Q = q/√12; the accelerometers show none."""
    q = 4e-7  # rad; the per-sample angle noise is 1.45e-6 rad
    spec = ImuSpec.from_units(arw_deg_sqrt_h=0.05, vrw_m_s_sqrt_h=0.02, gyro_quant_rad=q)
    ch = C.characterise_imu(static_log(spec, 2, seconds=3600.0))
    for a in ch.axes[:3]:
        t = a.terms["quantisation"]
        assert t.fitted and t.covers(q / math.sqrt(12.0)), (a.axis, t)
        assert a.terms["white"].covers(spec.gyro_arw[0])
    assert not any(a.terms["quantisation"].fitted for a in ch.axes[3:])


def test_separated_terms_are_resolved():
    """When the terms are apart in τ (GM with T = 20 s, a strong random walk), one hour resolves all four:
    ARW/VRW, bias instability, T and random walk are reported with intervals that hold the truth."""
    spec = ImuSpec.from_units(arw_deg_sqrt_h=0.3, vrw_m_s_sqrt_h=0.1, gyro_bias_instability_deg_h=10.0,
                              accel_bias_instability_ug=200.0, bias_corr_time_s=20.0,
                              gyro_rrw_deg_h_sqrt_h=60.0, accel_rrw_ug_sqrt_h=1500.0)
    truth = truth_terms(spec)
    ch = C.characterise_imu(static_log(spec, 500, seconds=3600.0))
    fitted = covered = 0
    for a in ch.axes:
        for k in ("white", "gm_sigma", "gm_tau", "rrw", "bias_instability"):
            fitted += a.terms[k].fitted
            covered += a.terms[k].fitted and a.terms[k].covers(truth[a.sensor][k])
    assert fitted >= 26 and covered >= fitted - 2, (fitted, covered)  # of 30
    t_fitted = [a.terms["gm_tau"].value for a in ch.axes if a.terms["gm_tau"].fitted]
    assert t_fitted and all(t == pytest.approx(20.0, rel=0.5) for t in t_fitted)
    vals, com = C.imu_section(ch, grade="mems")
    assert "merged" in com["gyro_bias_instability_deg_h"] and "merged" in com["accel_bias_tau_s"]
    # the merged Gauss-Markov keeps the driving noise 2σ²/T + K² of the fitted terms
    g = [ch.axes[i].terms for i in range(3)]
    sig, k = max(t["gm_sigma"].value for t in g), max(t["rrw"].value for t in g)
    t_fit = min(t["gm_tau"].value for t in g)
    s_eff = vals["gyro_bias_instability_deg_h"] * C.DEG_H
    assert 2 * s_eff**2 / vals["gyro_bias_tau_s"] == pytest.approx(2 * sig**2 / t_fit + k**2, rel=1e-6)


N_LOGS_UNIT = 5  # per grade here; 50 in benchmarks/characterise.py


@pytest.fixture(scope="module")
def coverage_counts():
    """Per grade, sensor and term: (covered, fitted) counts over N_LOGS_UNIT logs × 3 axes."""
    out = {}
    for grade in ("tactical", "mems"):
        spec = grade_spec(grade)
        truth = truth_terms(spec)
        cnt = {}
        err = {"gyro": 0.0, "accel": 0.0}
        for i in range(N_LOGS_UNIT):
            ch = C.characterise_imu(static_log(spec, 19_000 + i))
            for a in ch.axes:
                for k, v in truth[a.sensor].items():
                    c = cnt.setdefault((a.sensor, k), [0, 0])
                    c[0] += a.terms[k].covers(v)
                    c[1] += a.terms[k].fitted
                w = a.terms["white"]
                err[a.sensor] = max(err[a.sensor], abs(w.value / truth[a.sensor]["white"] - 1)
                                    if w.fitted else np.inf)
        out[grade] = (cnt, err)
    return out


@pytest.mark.parametrize("grade", ["tactical", "mems"])
def test_coverage_of_fitted_terms(coverage_counts, grade):
    """Each term's interval holds the truth. With 15 independent intervals per term (5 logs × 3 axes), a
    method whose 95% intervals are right gives ≥ 12 hits except with probability 3.6% per term (binomial;
    the counts are fixed by the seeds); the 50-log run of the benchmark gives the acceptance numbers."""
    cnt, err = coverage_counts[grade]
    n = 3 * N_LOGS_UNIT
    k_min = 12
    assert binom.cdf(k_min - 1, n, 0.95) < 0.04
    bad = {f"{s}.{k}": c for (s, k), c in cnt.items() if c[0] < k_min}
    assert not bad, (grade, bad)
    assert err["gyro"] < 0.10 and err["accel"] < 0.10, err


def test_short_log_reports_what_it_cannot_resolve():
    """10 minutes of a MEMS IMU: the white noise is fitted, the bias terms are not (upper bounds only),
    and imu.yaml takes the grade defaults and says so."""
    spec = grade_spec("mems")
    ch = C.characterise_imu(static_log(spec, 5, seconds=600.0))
    assert all(a.terms["white"].fitted for a in ch.axes)
    assert not any(a.terms["gm_tau"].fitted for a in ch.axes)
    for a in ch.axes:
        t = a.terms["bias_instability"]
        assert t.fitted or (t.status == "not resolved" and t.value is None and t.note)
    vals, com = C.imu_section(ch, grade="mems")
    assert "grade default (mems)" in com["gyro_bias_tau_s"]
    assert "cannot show" in com["gyro_bias_sigma_deg_h"]
    assert vals["arw_deg_sqrt_h"] == pytest.approx(0.3, rel=0.05)


# -------------------------------------------------------------------------------------- guard rails
def test_moving_log_is_refused():
    """A 90° turn and a tilt in the middle of a static log: NotStaticError names when it moves."""
    fs, n = 100.0, 60_000
    rng = np.random.default_rng(3)
    y = rng.normal(0.0, 1e-3, (n, 6))
    y[:, 5] += 9.80665
    y[30_000:31_000, 2] += math.radians(9.0)  # 90° in 10 s about z
    y[40_000:, 3] += 0.2  # tilt: specific force changes
    with pytest.raises(C.NotStaticError, match="not static") as e:
        C.characterise_rates(y, fs, t_start=1000.0)
    assert "1300.0-1310.0 s" in str(e.value) and "--static" in str(e.value)
    # the static part alone passes
    ch = C.characterise_rates(y[:29_000], fs)
    assert ch.static["static"]


def test_gap_is_reported_and_not_bridged():
    spec = ImuSpec.from_units(arw_deg_sqrt_h=0.2, vrw_m_s_sqrt_h=0.05)
    imu = static_log(spec, 4, seconds=900.0)
    keep = np.ones(len(imu), bool)
    keep[30_000:30_300] = False  # 3 s missing
    gappy = ImuData(imu.time[keep], imu.dtheta[keep], imu.dv[keep], t0=imu.t0)
    ch = C.characterise_imu(gappy)
    text = " ".join(ch.notes)
    assert "1 gap(s)" in text and "never bridged" in text
    assert ch.span_s[0] == pytest.approx(303.01, abs=0.02) and ch.span_s[1] == pytest.approx(900.0, abs=0.02)
    assert ch.axes[0].terms["white"].covers(spec.gyro_arw[0])


def test_jittered_time_stamps_are_resampled():
    """±5% jitter: cumulative-sum resampling onto the median grid; ARW/VRW still inside their intervals."""
    spec = ImuSpec.from_units(arw_deg_sqrt_h=0.2, vrw_m_s_sqrt_h=0.05)
    ch = C.characterise_imu(static_log(spec, 6, seconds=1800.0, jitter=0.05))
    assert ch.resampled and any("cumulative-sum interpolation" in s for s in ch.notes)
    for a in ch.axes:
        q = spec.gyro_arw[0] if a.sensor == "gyro" else spec.accel_vrw[0]
        assert a.terms["white"].covers(q), (a.axis, a.terms["white"], q)
        assert not a.terms["quantisation"].fitted
        assert a.used[:6].sum() == 0  # τ below 64 intervals are not fitted


def test_uniform_rates_conserves_the_integral():
    """Resampled rates integrate to the cumulative increments at every grid point (no angle lost)."""
    spec = ImuSpec.from_units(arw_deg_sqrt_h=0.2, vrw_m_s_sqrt_h=0.05)
    imu = static_log(spec, 7, seconds=60.0, jitter=0.1, t0=50.0)
    rates, dt, t_start, resampled, _ = C.uniform_rates(imu)
    assert resampled and t_start == 50.0
    edges = np.r_[imu.t0, imu.time]
    cum = np.vstack((np.zeros((1, 6)), np.cumsum(np.concatenate((imu.dtheta, imu.dv), axis=1), axis=0)))
    grid = t_start + dt * np.arange(1, len(rates) + 1)
    want = np.column_stack([np.interp(grid, edges, cum[:, c]) for c in range(6)])
    got = np.cumsum(rates, axis=0) * dt
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.abs(cum).max())


def test_static_option_errors(tmp_path):
    with pytest.raises(ValueError, match="START:END"):
        C.characterise_file(tmp_path / "x.csv", tmp_path, static="10-20")
    with pytest.raises(ValueError, match="END must be after START"):
        C.characterise_file(tmp_path / "x.csv", tmp_path, static="20:10")


# ---------------------------------------------------------------------------------------- outputs
def test_cli_writes_allan_png_noise_json_and_imu_yaml(tmp_path, drawn_png):
    """`aidnav characterise LOG --static A:B -o DIR` on a rate CSV; imu.yaml validates as the imu: section."""
    import pandas as pd
    import yaml
    from typer.testing import CliRunner

    from aidnav.cli import app
    from aidnav.filters.config import ImuNoise

    spec = grade_spec("mems")
    imu = static_log(spec, 8, seconds=900.0, t0=345600.0)
    dt = np.diff(np.r_[imu.t0, imu.time])
    df = pd.DataFrame({"time": imu.time})
    for j, c in enumerate(("gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s")):
        df[c] = imu.dtheta[:, j] / dt
    for j, c in enumerate(("accel_x_m_s2", "accel_y_m_s2", "accel_z_m_s2")):
        df[c] = imu.dv[:, j] / dt
    log = tmp_path / "imu_rates.csv"
    df.to_csv(log, index=False, float_format="%.17g")
    out = tmp_path / "char"
    res = CliRunner().invoke(app, ["characterise", "--imu", str(log), "--static", "100:", "-o", str(out)])
    assert res.exit_code == 0, res.output
    drawn_png(out / "allan.png")
    nd = json.loads((out / "noise.json").read_text())
    gx = nd["axes"]["gyro_x"]
    assert gx["arw_deg_sqrt_h"]["status"] == "fitted"
    lo, hi = gx["arw_deg_sqrt_h"]["ci95"]
    assert lo <= 0.3 <= hi
    assert set(nd["axes"]) == set(C.AXES) and "vrw_m_s_sqrt_h" in nd["axes"]["accel_z"]
    assert nd["span_s"][0] == pytest.approx(345700.0, abs=0.05)
    text = (out / "imu.yaml").read_text()
    sec = yaml.safe_load(text)["imu"]
    ImuNoise.model_validate(sec)  # keys and ranges of the filter configuration
    assert text.count("#") >= len(sec) and "fitted" in text and "grade default" in text
    assert "ARW" in res.output and "wrote" in res.output
    # a log that moves (a 11.5 deg/s turn at 500-510 s): its longest static part is analysed and the motion
    # is reported, as gaps are
    df.loc[50_000:51_000, "gyro_z_rad_s"] += 0.2
    df.to_csv(log, index=False, float_format="%.17g")
    res = CliRunner().invoke(app, ["characterise", "--imu", str(log), "-o", str(out)])
    assert res.exit_code == 0, res.output
    nd = json.loads((out / "noise.json").read_text())
    warn = " ".join(nd["warnings"])
    assert "not static" in warn and "500.0-511.0 s" in warn and "longest static part" in warn
    assert nd["span_s"][0] == pytest.approx(345600.0, abs=0.05)
    assert nd["span_s"][1] == pytest.approx(345600.0 + 499.0, abs=1.01)  # one window of margin
    # a log that turns every few seconds has no static part long enough: an error with exit status 2
    turns = (np.arange(len(df)) // 150) % 2 == 1
    df.loc[turns, "gyro_z_rad_s"] += 0.3
    df.to_csv(log, index=False, float_format="%.17g")
    res = CliRunner().invoke(app, ["characterise", "--imu", str(log), "-o", str(out)])
    assert res.exit_code == 2 and "not static" in res.output


# ------------------------------------------------------------- statistics: exact and continuum lag sums
def _brute_force_cov(ms, n, tau0, coef, t_corr):
    """Covariance of the overlapping Allan variance estimates by the full double sum over all pairs of
    second differences (Isserlis, with the model's phase structure function): O(N²) per pair."""
    S = np.array([AC._phase_sf(tau0 * float(h), coef, t_corr) for h in range(n + 2)])
    a = (1.0, -2.0, 1.0)
    out = np.zeros((len(ms), len(ms)))
    for p, m1 in enumerate(ms.astype(int)):
        for r, m2 in enumerate(ms.astype(int)):
            M1, M2 = n + 1 - 2 * m1, n + 1 - 2 * m2
            lag = np.arange(M2)[None, :] - np.arange(M1)[:, None]
            c = -0.5 * sum(a[i] * a[j] * S[np.abs(lag + j * m2 - i * m1)] for i in range(3) for j in range(3))
            out[p, r] = 2.0 * np.sum(c * c) / (4.0 * (m1 * tau0) ** 2 * (m2 * tau0) ** 2 * M1 * M2)
    return out


@pytest.mark.parametrize("coef, t_corr, tol", [
    ((1e-8, 1e-4, 0.0, 0.0), 1.0, 1e-12),  # quantisation + white: piecewise polynomial, summed exactly
    ((1e-8, 1e-4, 2e-4, 1e-5), 2.0, 1e-6),  # all four terms: the Gauss-Markov tails are integrated
    ((0.0, 1e-4, 4e-4, 0.0), 0.3, 1e-5),  # short correlation time (30 samples): the worst case of the tails
])
def test_estimate_covariance_equals_the_brute_force_double_sum(coef, t_corr, tol):
    """The lag sums of ``_avar_cov_nb`` (pair counts in closed form, the structure function from a table
    of integer lags, the Gauss-Markov tails by quadrature) equal the O(N²) double sum on a short log."""
    n, tau0 = 600, 0.01
    ms = 2.0 ** np.arange(8)
    coef = np.array(coef)
    want = _brute_force_cov(ms, n, tau0, coef, t_corr)
    got = AC.avar_cov_nb(ms, float(n + 1), tau0, coef, t_corr)
    scale = np.sqrt(np.outer(np.diag(want), np.diag(want)))
    assert np.max(np.abs(got - want) / scale) < tol


@pytest.mark.parametrize("coef, t_corr", [((1e-8, 1e-4, 0.0, 0.0), 1.0), ((1e-8, 1e-4, 2e-4, 1e-5), 2.0),
                                           ((0.0, 1e-4, 4e-4, 3e-6), 300.0)])
def test_estimate_variances_alone_are_the_covariance_diagonal_to_the_bit(coef, t_corr):
    """``_avar_var_nb`` (the EDFs of every τ shown, issue 29: without the covariances) gives the diagonal
    of ``_avar_cov_nb`` bit for bit, on the octave τ of a 10-h log at 100 Hz (short cores summed exactly,
    long ones and the Gauss-Markov tails integrated), and ν of ``_estimate_stats``."""
    n, tau0 = 3_600_000, 0.01
    ms = 2.0 ** np.arange(21)
    coef = np.array(coef)
    np.testing.assert_array_equal(AC.avar_var_nb(ms, float(n + 1), tau0, coef, t_corr),
                                  np.diag(AC.avar_cov_nb(ms, float(n + 1), tau0, coef, t_corr)))
    tau = ms * tau0
    np.testing.assert_array_equal(AC.estimate_edf(tau, ms, n + 1, coef, t_corr),
                                  AC.estimate_stats(tau, ms, n + 1, coef, t_corr)[0])


def test_continuum_lag_sum_is_the_large_m_limit_of_the_exact_sum():
    """Cores longer than ``EXACT_LAGS`` lags use the continuum form ∫ n(ℓ) c₁₂(ℓ)² dℓ. Against the exact
    sum over the integer lags its relative error is −1.25/m² for white noise (the kinks of c₁₂ at integer
    lags; 5.6e-7 where the continuum takes over) and below 1e-7 for the random walk and Gauss-Markov terms;
    it does not depend on the number of samples (n(ℓ) is in closed form)."""
    tau0 = 0.01
    for n in (200_001.0, 3_600_001.0):
        for coef, t_corr in (((0.0, 1e-4, 0.0, 0.0), 1.0), ((0.0, 0.0, 0.0, 1e-6), 1.0),
                             ((0.0, 0.0, 1e-4, 0.0), 50.0)):
            coef = np.array(coef)
            gm = coef[2] > 0
            for m in (64, 256, 1500):
                M = n - 2.0 * m
                tail = 12.0 * t_corr / tau0 if gm else 0.0
                lo, hi = -2.0 * m - tail, 2.0 * m + tail
                S = np.array([AC._phase_sf(tau0 * h, coef, t_corr) for h in range(int(4 * m + tail) + 8)])
                exact = AC._core_sum(int(lo), int(hi), m, m, M, M, S, tau0, coef, t_corr)
                cont = AC._quad_lags(lo - 0.5, hi + 0.5, float(m), float(m), M, M, tau0, coef, t_corr,
                                    max(16.0, t_corr / tau0 / 4.0) if gm else 1e18)
                err = cont / exact - 1.0
                if coef[1] > 0:
                    assert err == pytest.approx(-1.25 / m**2, rel=1e-2), (n, m, err)
                else:
                    assert abs(err) < 1e-7, (coef, n, m, err)


def test_resampled_min_m():
    """The resampling bias 1/(6m) stays below a quarter of the estimate's scatter from m³ ≥ n/3 on."""
    assert [C.resampled_min_m(n) for n in (600, 1_800, 3_400, 180_000, 720_000, 3_600_000)] == \
        [8, 16, 16, 64, 64, 64]


# ---------------------------------------------------- short logs, motion, vibration (issue 19, real data)
def test_short_log_fits_white_noise_only():
    """40 s of a jittered MEMS log: only the white terms are fitted (from the short-tau part), stated as
    such; the bias instability and the random walk are reported as not resolvable and imu.yaml takes grade
    defaults for them, saying why."""
    spec = grade_spec("mems")
    ch = C.characterise_imu(static_log(spec, 41, seconds=40.0, jitter=0.05))
    assert ch.white_only and ch.resampled
    truth = truth_terms(spec)
    for a in ch.axes:
        assert a.white_only and a.used[a.taus < 0.155].sum() == 0  # the fit starts at 16 intervals
        w = a.terms["white"]
        assert w.fitted and w.covers(truth[a.sensor]["white"]) and "white noise only" in w.note, (a.axis, w)
        for k in ("bias_instability", "gm_sigma", "gm_tau", "rrw"):
            t = a.terms[k]
            assert t.status == "not resolved" and t.value is None and "not resolvable" in t.note, (a.axis, k)
    assert any(w.startswith("white noise only") for w in ch.warnings)
    nd = C.noise_dict(ch)
    assert nd["fit"].startswith("white noise only")
    text = C.imu_yaml(ch, grade="mems")
    assert "White noise only" in text and "not resolvable in 40 s" in text
    vals, com = C.imu_section(ch, grade="mems")
    assert "grade default (mems): not resolvable" in com["gyro_bias_instability_deg_h"]
    assert "white noise only" in com["arw_deg_sqrt_h"]
    assert vals["arw_deg_sqrt_h"] == pytest.approx(0.3, rel=0.25)


def test_slow_motion_is_kept_with_a_warning_and_motion_is_cut_off():
    """A slow rotation (0.3 deg/s for 1 s) is kept and reported with its time and size; a turn (20 deg/s
    for 5 s) is never analysed: the longest part without it is, and the turn is reported."""
    spec = ImuSpec.from_units(arw_deg_sqrt_h=0.2, vrw_m_s_sqrt_h=0.05)
    imu = static_log(spec, 42, seconds=1200.0)
    dth = imu.dtheta.copy()
    dth[30_000:30_100, 0] += math.radians(0.3) * 0.01  # 0.3 deg/s about x for 1 s at 300 s
    dth[90_000:90_500, 2] += math.radians(20.0) * 0.01  # 20 deg/s about z for 5 s at 900 s
    ch = C.characterise_imu(ImuData(imu.time, dth, imu.dv, t0=imu.t0))
    warn = " ".join(ch.warnings)
    assert "slow motion at 300.0-301.0 s" in warn and "0.3 deg/s gyro" in warn
    assert "not static" in warn and "900.0-905.0 s" in warn and "20 deg/s" in warn
    assert ch.span_s == pytest.approx((0.0, 899.0), abs=0.02)  # the longest part, one window of margin
    ev = ch.static["events"]
    assert [e["kind"] for e in ev] == ["slow motion"]
    assert ev[0]["peak_gyro_deg_s"] == pytest.approx(0.3, rel=0.1)
    for a in ch.axes:  # the white noise is unaffected (15 min of data: within 3%)
        q = spec.gyro_arw[0] if a.sensor == "gyro" else spec.accel_vrw[0]
        w = a.terms["white"]
        assert w.fitted and abs(w.value / q - 1) < 0.03, (a.axis, w)
    # the array API refuses a log with motion, naming it and the parts without it
    rates, dt, t0, _, _ = C.uniform_rates(ImuData(imu.time, dth, imu.dv, t0=imu.t0))
    with pytest.raises(C.NotStaticError, match="900.0-905.0 s") as e:
        C.characterise_rates(rates, 1.0 / dt, t_start=t0)
    assert "0.0-899.0 s" in str(e.value)


def test_vibration_is_reported_not_fitted():
    """A 30 Hz vibration (1 deg/s rms on gyro x, 0.2 m/s² on accel z) on a white-noise log: reported per axis
    with its std and frequency, flagged only where it is, and the white noise is still fitted; a slope −1
    at the short τ is then not called quantisation. A white-noise log reports no vibration."""
    spec = ImuSpec.from_units(arw_deg_sqrt_h=0.2, vrw_m_s_sqrt_h=0.05)
    quiet = C.characterise_imu(static_log(spec, 43, seconds=600.0))
    assert quiet.vibration["detected"] == []
    imu = static_log(spec, 43, seconds=600.0)
    t = imu.time
    dt = np.diff(np.r_[imu.t0, t])
    # the increment of a sinusoid over each interval (an averaged rate, as a sensor's output would be)
    ph = 2 * np.pi * 30.0
    integ = (np.cos(ph * (t - dt)) - np.cos(ph * t)) / ph
    dth, dv = imu.dtheta.copy(), imu.dv.copy()
    dth[:, 0] += math.radians(1.0) * math.sqrt(2) * integ
    dv[:, 2] += 0.2 * math.sqrt(2) * integ
    ch = C.characterise_imu(ImuData(t, dth, dv, t0=imu.t0))
    vib = ch.vibration
    assert set(vib["detected"]) == {"gyro_x", "accel_z"}
    gx, az = vib["axes"]["gyro_x"], vib["axes"]["accel_z"]
    # std of 30 Hz averaged over 10 ms: sinc(0.3) = 0.858 of the point value, plus the white noise
    assert gx["std_deg_s"] == pytest.approx(math.hypot(0.858, gx["white_noise_std_deg_s"]), rel=0.05)
    assert az["std_m_s2"] == pytest.approx(math.hypot(0.2 * 0.858, az["white_noise_std_m_s2"]), rel=0.05)
    assert gx["peak_hz"] == pytest.approx(30.0, abs=0.3) and gx["peak_share"] > 0.9
    assert any("vibration" in w and "gyro_x" in w for w in ch.warnings)
    for a in ch.axes:
        q = spec.gyro_arw[0] if a.sensor == "gyro" else spec.accel_vrw[0]
        assert a.terms["white"].covers(q), (a.axis, a.terms["white"])
        assert not a.terms["quantisation"].fitted


def test_trapezoid_samples_invert_the_raw_log_increments():
    """Point samples ω_k → trapezoid increments as the rtklibexplorer reader forms them → back, exactly."""
    rng = np.random.default_rng(44)
    n = 20_000
    t = 1000.0 + np.cumsum(rng.choice([0.008, 0.009, 0.010, 0.011], n))
    w = rng.normal(size=(n, 6)) + [0.0, 0.0, 0.0, 0.0, 0.0, 9.8]
    dt = np.diff(t)
    inc = np.empty_like(w)
    inc[0] = w[0] * 0.01
    inc[1:] = 0.5 * (w[1:] + w[:-1]) * dt[:, None]
    imu = ImuData(t, inc[:, :3], inc[:, 3:], t0=t[0] - 0.01)
    np.testing.assert_allclose(C.trapezoid_samples(imu), w, rtol=0, atol=1e-11)


def test_real_drive_log_static_start(data_dir, tmp_path, drawn_png):
    """rtklibexplorer_drive_0708: the car is parked with the engine running until it drives off about 34 s
    after the first IMU sample (38 s after the first GNSS epoch: the IMU log starts 3.5 s later).

    ``--static 0:38``: the drive-off is cut (reported), the slow rotation at 19-20 s (0.24 deg/s, 0.24 deg) is
    kept and reported as a warning with its time and size; the white terms (ARW/VRW) are fitted from the
    short-tau part and stated as white noise only; the bias instability, its correlation time and the random
    walk are not claimed (imu.yaml: grade defaults, saying so); the engine vibration is reported: std of the
    sensor's samples on raw x/y 0.62 / 2.33 deg/s (README: 0.64 / 2.37 over the first 30 s) at 31 Hz.
    Without ``--static`` the same parked part is found."""
    import yaml
    from typer.testing import CliRunner

    from aidnav.cli import app

    log = data_dir / "rtklibexplorer_drive_0708" / "imu_1934.csv"
    if not log.is_file():
        pytest.skip(f"rtklibexplorer_drive_0708/imu_1934.csv not found under {data_dir}")
    out = tmp_path / "drive"
    res = CliRunner().invoke(app, ["characterise", "--imu", str(log), "--static", "0:38", "-o", str(out)])
    assert res.exit_code == 0, res.output
    drawn_png(out / "allan.png")
    nd = json.loads((out / "noise.json").read_text())
    t_first = nd["static_check"]["time_origin_s"]
    assert nd["span_s"][0] - t_first == pytest.approx(0.0, abs=0.05)
    assert 32.0 <= nd["span_s"][1] - t_first <= 34.5  # the drive-off (34 s) is not analysed
    warn = nd["warnings"]
    assert any("not static" in w and "34.0-37.0 s" in w for w in warn)
    slow = [e for e in nd["static_check"]["events"] if e["kind"] == "slow motion"]
    assert len(slow) == 1 and 18.5 <= slow[0]["start_s"] <= 20.0 and 0.1 < slow[0]["peak_gyro_deg_s"] < 0.5
    assert any(w.startswith("slow motion at 19.0-20.0 s") for w in warn)
    # white terms only, stated as such
    assert nd["fit"].startswith("white noise only")
    n_white = 0
    for ax, d in nd["axes"].items():
        wkey = "arw_deg_sqrt_h" if ax.startswith("gyro") else "vrw_m_s_sqrt_h"
        w = d[wkey]
        if w["status"] == "fitted":
            n_white += 1
            assert "white noise only" in w["note"]
        else:  # no white-noise region on this axis: an upper bound from the curve
            assert w["upper_bound"] is not None and "white noise below" in w["note"]
        for k, v in d.items():  # nothing beyond the white terms is claimed
            if isinstance(v, dict) and "status" in v and not k.startswith(("arw", "vrw", "quantisation")):
                assert v["status"] == "not resolved" and "value" not in v, (ax, k)
    assert n_white >= 5 and all(nd["axes"][g]["arw_deg_sqrt_h"]["status"] == "fitted"
                                for g in ("gyro_x", "gyro_y", "gyro_z"))
    assert 0.1 < nd["axes"]["gyro_z"]["arw_deg_sqrt_h"]["value"] < 1.0  # the data author's 0.23 deg/sqrt(h)
    text = (out / "imu.yaml").read_text()
    assert "White noise only" in text
    sec = yaml.safe_load(text)["imu"]
    assert set(sec) >= {"arw_deg_sqrt_h", "vrw_m_s_sqrt_h", "gyro_bias_instability_deg_h"}
    for line in text.splitlines():
        if line.strip().startswith(("gyro_bias_instability", "accel_bias_instability", "gyro_bias_tau",
                                    "accel_bias_tau")):
            assert "grade default" in line and "not resolvable" in line, line
    # the engine vibration: reported, on the raw x/y axes (body RFU = sensor axes here) in the range the
    # data README gives
    vib = nd["vibration"]
    assert vib["samples"].startswith("sensor's samples (trapezoid")
    for ax in ("gyro_x", "gyro_y"):
        d = vib["axes"][ax]
        assert 0.6 <= d["std_deg_s"] <= 2.4 and d["vibration"], (ax, d)
        assert d["peak_hz"] == pytest.approx(31.0, abs=1.0) and d["peak_share"] > 0.5
    # the data README's figures (0.64 / 2.37 deg/s over the first 30 s; ours over 38 s): within 5 %
    assert vib["axes"]["gyro_x"]["std_deg_s"] == pytest.approx(0.64, rel=0.05)
    assert vib["axes"]["gyro_y"]["std_deg_s"] == pytest.approx(2.37, rel=0.05)
    peaks = [float(m) for w in warn if w.startswith("vibration") for m in re.findall(r" at ([0-9.]+) Hz", w)]
    assert peaks and all(abs(f - 31.0) <= 1.0 for f in peaks), warn
    assert "vibration" in res.output and "slow motion" in res.output
    # no --static: the parked start is found (the drive, cruising included, is not "static")
    ch = C.characterise_file(log, tmp_path / "auto")[0]
    t0 = ch.static["time_origin_s"]
    assert ch.span_s[0] - t0 < 1.0 and 30.0 < ch.span_s[1] - t0 <= 34.5
    assert any("the log is not static" in w for w in ch.warnings)


# ------------------------------------------------------------------- the filter with the fitted noise
@pytest.mark.parametrize("case", ["tactical", "separated"])
def test_imu_yaml_gives_consistent_filter(case, loose_error_state):
    """Characterise a 2-h static log, put the imu: section into the filter tuned to the simulated sensors
    (``loose_config_from_specs``), and run it on a 20-minute simulated flight made with the same IMU (10
    runs): the run-averaged NEES of the 9 navigation states (attitude, velocity, position) at 4 epochs lies
    in the two-sided chi-square band at 1 − 0.05/4 (Bonferroni).
    "tactical": the preset's noise; ARW/VRW are fitted, the bias terms are grade defaults (a 2-h log does
    not resolve them); the truth-model tuning passes too. "separated": GM (T = 20 s) + random walk, all
    fitted and merged into the filter's one Gauss-Markov bias; the truth-model tuning, which has no random
    walk, is optimistic here (printed, not asserted)."""
    from aidnav.analysis.consistency import chi2_band, nees
    from aidnav.filters.config import LooseConfig
    from aidnav.filters.loose import run_loose
    from aidnav.filters.tuning import loose_config_from_specs, perturbed_initial_state
    from aidnav.sim.gnss import GnssSpec, simulate_gnss
    from aidnav.sim.scenario import parse_scenario
    from aidnav.sim.trajectory import generate_truth

    if case == "tactical":  # the preset's noise: a 2-h log resolves ARW/VRW, the bias terms are defaults
        spec = ImuSpec.from_units(gyro_bias_deg_h=1.0, accel_bias_ug=100.0, arw_deg_sqrt_h=0.1,
                                  vrw_m_s_sqrt_h=0.03, gyro_bias_instability_deg_h=0.3,
                                  accel_bias_instability_ug=50.0, bias_corr_time_s=600.0)
    else:  # terms apart in τ: everything fitted, Gauss-Markov and random walk merged for the filter
        spec = ImuSpec.from_units(gyro_bias_deg_h=1.0, accel_bias_ug=100.0, arw_deg_sqrt_h=0.1,
                                  vrw_m_s_sqrt_h=0.03, gyro_bias_instability_deg_h=3.0,
                                  accel_bias_instability_ug=100.0, bias_corr_time_s=20.0,
                                  gyro_rrw_deg_h_sqrt_h=10.0, accel_rrw_ug_sqrt_h=500.0)
    ch = C.characterise_imu(static_log(spec, 99, seconds=7200.0))
    section, comments = C.imu_section(ch, grade="tactical")

    scn = parse_scenario(dict(
        name="char-flight", seed=1, imu_rate_hz=50.0,
        initial=dict(lat_deg=30.0, lon_deg=114.0, height_m=1000.0, speed_m_s=100.0, heading_deg=0.0),
        segments=[dict(type="straight", duration_s=60), dict(type="turn", angle_deg=90, rate_deg_s=3),
                  dict(type="s_turns", duration_s=240, amplitude_deg=45, n_cycles=2),
                  dict(type="accelerate", duration_s=30, to_speed_m_s=150),
                  dict(type="figure8", duration_s=240), dict(type="turn", angle_deg=-180, rate_deg_s=3),
                  dict(type="straight", duration_s=500)]))
    truth, imu_true, _ = generate_truth(scn)
    gspec = GnssSpec(rate_hz=1.0, sigma_pos_enu=[0.5, 0.5, 1.0], sigma_vel_enu=[0.05, 0.05, 0.1],
                     lever_arm_b=[0.0, 1.0, 0.5])
    epochs = np.array([250.0, 500.0, 800.0, 1100.0])
    runs = 10
    eps = {"fitted": [], "truth": []}
    no_bias = {"gyro_bias": np.zeros(3), "accel_bias": np.zeros(3)}
    for ss in np.random.SeedSequence(1919).spawn(runs):
        s_imu, s_gnss, s_init = ss.spawn(3)
        imu, _ = corrupt_imu(imu_true, spec, np.random.default_rng(s_imu))
        gnss = simulate_gnss(truth, gspec, np.random.default_rng(s_gnss))
        lla, vel, rph = perturbed_initial_state(truth, np.random.default_rng(s_init))
        base = loose_config_from_specs(spec, gspec, init_rph_deg=rph, init_lla_deg_m=lla, init_vel=vel)
        d = base.model_dump()
        d["imu"].update(section)
        for key, cfg in (("truth", base), ("fitted", LooseConfig.model_validate(d))):
            res = run_loose(imu, gnss, cfg, cov_times=epochs)
            idx = np.searchsorted(res.time, epochs)
            # navigation part only (the biases here drift, so the bias residual is not compared)
            e = loose_error_state(res, truth, no_bias, idx)[:, :9]
            eps[key].append(nees(e, res.cov[:, :9, :9]))
    lo, hi = chi2_band(9, runs, 1.0 - 0.05 / len(epochs))
    means = {k: np.mean(v, axis=0) for k, v in eps.items()}
    print(f"\nNEES (9 states, {runs} runs) at {epochs} s: fitted {np.round(means['fitted'], 2)}, "
          f"truth-model {np.round(means['truth'], 2)}; band [{lo:.2f}, {hi:.2f}]; imu section {section}")
    if case == "tactical":
        assert np.all((means["truth"] > lo) & (means["truth"] < hi)), means
    assert np.all((means["fitted"] > lo) & (means["fitted"] < hi)), means


def test_chi2_quantiles_are_scipy_stats():
    """The fit's χ² quantiles (scipy.special, without importing scipy.stats) are scipy.stats.chi2.ppf's."""
    from scipy.stats import chi2

    from aidnav.analysis.noise_fit.fit import _chi2_ppf

    nu = np.array([1.0, 2.0, 3.7, 40.0, 2.5e4])
    for p in (0.025, 0.5, 0.95, 0.975, 0.99):
        np.testing.assert_array_equal(_chi2_ppf(p, nu), chi2.ppf(p, nu))
        assert _chi2_ppf(p, 1) == chi2.ppf(p, 1) and _chi2_ppf(p, 2) == chi2.ppf(p, 2)
