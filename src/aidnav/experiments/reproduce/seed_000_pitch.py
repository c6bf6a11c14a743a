"""Seed 000: "with SAPV the level accuracy (精度) is below 2′ once the attitude is estimated (30 s)" (§1.3).

Decided 2026-12-06: the seed's "精度 < 2′" is an accuracy over runs, not an every-epoch maximum, and the level
biases are drawn per run from Table 1's σ (500 µg, 0.1°/h). The spec row is the **per-epoch RMS of the pitch
error over runs**, its largest value from 30 s on, below 2′, over ``PITCH_RUNS_FACTOR × runs`` runs (the
first ``runs`` are the main Monte Carlo's). The largest |pitch error| of any run after 30 s is shown without
a target.

Sensitivity: Table 1's biases read as values, +500 µg and 0.1°/h on every axis (the former spec row,
:data:`.seed_000_setup.SEED_RUN_IMU`): a fixed equal bias nearly cancels the one tilt the antenna cannot see,
the tilt about the line of sight's horizontal direction (its pitch share sin α, α the antenna azimuth from
the nose), which the filter can only split from the horizontal accelerometer bias by their priors
(:func:`pitch_bias_model`: k·sin α·|cos α − sin α|·∇/g for equal biases against k·sin α·σ∇/g at 1σ for drawn
ones). On a static base the level tilt is otherwise seen through the GPS velocity (σ 0.5 m/s), which resolves
a tilt of g·φ only as fast as a straight-line fit resolves a slope; the covariance rows show how the filter's
own pitch σ at 30 s scales with the GPS velocity σ.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from aidnav.filters.federated import run_federated

from .seed_000_setup import (
    ACCEL_BIAS_UG,
    ADVERSE_RUN_IMU,
    ARCMIN,
    CENTRAL,
    FED,
    GPS_SIGMA_VEL_M_S,
    GPS_VEL_SWEEP_M_S,
    HEADING_DEG,
    PAPER_T2,
    PHI0_DEG,
    SEED_RUN_IMU,
    SETTLE_S,
    SWEEP_RUNS,
    VARIANTS,
    geometry_check,
    seed_series,
    simulate_case,
)
from .summary import resolved_row, summary_row

#: runs of the drawn-bias pitch set per Monte Carlo run (one filter per run; the first ``runs`` are the main
#: Monte Carlo's): the per-epoch RMS over 4 × 30 runs has a relative standard error of ≈ 6 %
PITCH_RUNS_FACTOR = 4
PITCH_LIMIT_ARCMIN = 2.0
#: the seed's Table 2 pitch error with SAPV over its one run: (mean, std) [arcmin] (§1.2 item 11: arc-minutes)
PAPER_PITCH_SAPV = (PAPER_T2["pitch"]["mean"][1], PAPER_T2["pitch"]["std"][1])

__all__ = ["PITCH_RUNS_FACTOR", "pitch_bias_model", "fixed_bias_pitch", "pitch_sigma",
           "pitch_sigma_vs_gps_velocity", "pitch_rows", "per_epoch_rms"]


def pitch_bias_model(level_deg: float = PHI0_DEG[0]) -> dict:
    """The pitch error the accelerometer bias leaves with SAPV on the static base (arc-minutes).

    GPS holds the level velocity: g (up × φ) + ∇ → 0, so the filter can only split the level tilt from the
    horizontal accelerometer bias by their priors: a share k = σφ² / (σφ² + (σ∇/g)²) of the bias-equivalent
    tilt (z × ∇)/g stays in the attitude. The SAPV elevation observes the tilt about the horizontal axis
    across the line of sight; the tilt about the line of sight's horizontal direction (azimuth α from the
    nose, clockwise) stays, k (∇x cos α − ∇y sin α)/g (body x right, y forward), and its share in pitch (the
    tilt about x) is sin α. Returns ``k``, ``alpha_deg``, ``sigma`` (1σ for biases drawn with Table 1's σ on
    each axis), ``seed`` (Table 1's biases as values, the same on every axis), ``adverse`` (x +, y −).
    ``level_deg``: the filter's level-tilt prior σ [deg] (the initial level error, P_0 matched).
    """
    g = geometry_check()
    a = math.radians(g["az_deg"])
    tilt = ACCEL_BIAS_UG * 1e-6 / ARCMIN  # σ∇/g as a tilt [arcmin] (µg of standard gravity over g)
    sphi = abs(level_deg) * 60.0  # the filter's level-tilt prior σ [arcmin]
    k = sphi**2 / (sphi**2 + tilt**2)
    return {"k": k, "alpha_deg": g["az_deg"], "sigma": k * math.sin(a) * tilt,
            "seed": k * math.sin(a) * abs(math.cos(a) - math.sin(a)) * tilt,
            "adverse": k * math.sin(a) * abs(math.cos(a) + math.sin(a)) * tilt}


def fixed_bias_pitch(n: int, base_seed: int, duration_s: float, imu=SEED_RUN_IMU, phi0=PHI0_DEG,
                     skip: int = 0) -> dict:
    """The pitch error of the federated SINS/GPS/SAPV filter in runs ``skip`` … ``n − 1`` with the IMU
    overrides ``imu`` (None: biases drawn per run) and the initial misalignment ``phi0`` (run i uses child i
    of ``SeedSequence(base_seed)``, as the main Monte Carlo does): ``max`` the largest |pitch error| and
    ``ms`` its mean square over the epochs after ``SETTLE_S``, per run [arcmin, arcmin²]; ``t`` the epochs
    [s] and ``series`` (runs, epochs) the pitch error [arcmin]."""
    mx, ms, ser, t = [], [], [], None
    for ss in np.random.SeedSequence(base_seed).spawn(n)[skip:]:
        sim, sv, cfg = simulate_case(ss, duration_s, imu=imu, phi0_deg=phi0)
        s = seed_series(run_federated(sim.imu, sim.gnss, sv, cfg, VARIANTS[FED]), sim.truth)
        p = s["pitch"][s["t"] > SETTLE_S]
        mx.append(float(np.max(np.abs(p))))
        ms.append(float(np.mean(p**2)))
        ser.append(s["pitch"])
        t = s["t"]
    return {"max": np.asarray(mx), "ms": np.asarray(ms), "t": t,
            "series": np.asarray(ser) if ser else np.zeros((0, 0))}


def per_epoch_rms(series) -> tuple[np.ndarray, np.ndarray]:
    """(RMS over runs at each epoch, its standard error by the delta method on the mean square) of a
    (runs, epochs) array."""
    x2 = np.square(np.asarray(series, float))
    n = x2.shape[0]
    ms = x2.mean(axis=0)
    r = np.sqrt(ms)
    if n < 2:
        return r, np.full_like(r, np.nan)
    se = x2.std(axis=0, ddof=1) / np.sqrt(n) / (2 * np.maximum(r, 1e-300))
    return r, se


def pitch_sigma(res, t_s: float) -> float:
    """The filter's own 1σ of the pitch error [arcmin] at ``t_s`` s: the attitude covariance (E, N, U tilt)
    projected on the body right axis (heading ``HEADING_DEG``, level). ``res`` keeps its covariance."""
    k = int(np.searchsorted(res.time - res.time[0], t_s - 1e-9))
    h = math.radians(HEADING_DEG)
    u = np.array([math.sin(h + math.pi / 2), math.cos(h + math.pi / 2), 0.0])  # body x (right) in ENU
    return float(math.sqrt(u @ res.cov[k][:3, :3] @ u) / ARCMIN)


def pitch_sigma_vs_gps_velocity(base_seed: int, duration_s: float, sigmas=GPS_VEL_SWEEP_M_S,
                                times=(SETTLE_S, 60.0), phi0=PHI0_DEG) -> dict:
    """Covariance study: the filter's own pitch σ [arcmin] at ``times`` [s] when the GPS velocity σ it assumes
    is each of ``sigmas`` [m/s] (SINS/GPS/SAPV, centralized = fusion-reset). On the static base the
    covariance does not depend on the noise draw, so one realisation gives it; ``phi0``: the initial
    misalignment [deg] (P_0 matched). Returns {σ_v: {t: σ}}."""

    ss = np.random.SeedSequence(base_seed).spawn(1)[0]
    sim, sv, cfg = simulate_case(ss, min(duration_s, max(times) + 1.0), phi0_deg=phi0)
    out = {}
    for sig in sigmas:  # the fixes' σ columns set the filter's R (the fixes themselves are Table 1's)
        g = replace(sim.gnss, std_vel=np.full_like(sim.gnss.std_vel, sig))
        res = run_federated(sim.imu, g, sv, cfg, VARIANTS[CENTRAL], keep_cov=True)
        out[sig] = {t: pitch_sigma(res, t) for t in times}
    return out


def pitch_rows(main_series, t, runs: int, base_seed: int, duration_s: float, sigma_t: dict, phi0,
               level_sweep: dict | None = None):
    """(spec rows, informative rows, sensitivity rows, figure data) of the pitch claim. ``main_series``:
    (runs, epochs) pitch error of the main Monte Carlo's federated filter [arcmin] at the epochs ``t`` [s]
    (biases drawn per run); ``sigma_t``: {t [s]: the filter's pitch σ}; ``phi0``: the initial
    misalignment of the runs [deg]; ``level_sweep``: :func:`.seed_000_runs.level0_sweep` (the pitch claim at
    other initial level errors, quoted in the reason)."""
    from scipy.stats import norm  # lazy: scipy is heavy to import

    lim = PITCH_LIMIT_ARCMIN
    n = PITCH_RUNS_FACTOR * runs
    extra = fixed_bias_pitch(n, base_seed, duration_s, imu=None, phi0=phi0, skip=runs)
    P = np.asarray(main_series) if extra["series"].size == 0 else np.vstack([main_series, extra["series"]])
    rms_t, se_t = per_epoch_rms(P)
    after = t >= SETTLE_S - 1e-9
    k = int(np.flatnonzero(after)[np.argmax(rms_t[after])])
    worst, worst_se = float(rms_t[k]), float(se_t[k])
    above = np.flatnonzero(rms_t >= lim)
    t_below = float(t[above[-1] + 1]) if len(above) and above[-1] + 1 < len(t) else float(t[0])
    pmax = float(np.max(np.abs(P[:, after])))
    # sensitivity: Table 1's biases as values, the same on every axis (the former spec row), and the
    # opposite-sign pattern
    n_fix = min(runs, SWEEP_RUNS * 3)
    fx = fixed_bias_pitch(n_fix, base_seed, duration_s, phi0=phi0)
    fr, fse = per_epoch_rms(fx["series"])
    fk = int(np.flatnonzero(after)[np.argmax(fr[after])])
    pm, ps = PAPER_PITCH_SAPV
    sig30 = sigma_t.get(SETTLE_S, float("nan"))
    limit = (f"The filter's own pitch σ at {SETTLE_S:g} s is {sig30:.2f}′, a property of the model and "
             "not of "
             "the runs: the tilt about the line of sight's horizontal direction, which the antenna does not "
             f"see (its share in pitch sin α = {math.sin(math.radians(geometry_check()['az_deg'])):.2f}), is "
             f"observed only through the GPS velocity (σ {GPS_SIGMA_VEL_M_S:g} m/s at 1 Hz), which resolves "
             f"a tilt g·φ only as a straight-line fit resolves a slope: by {SETTLE_S:g} s not below 2′ (the "
             "covariance rows show it for a smaller GPS velocity σ). So the row fails at the seed's 30 s "
             "and holds from the epoch given; a genuine fail of the seed's '30 s 以内' (within 30 s), not a "
             "statistic choice: the SPEC's statistic is per epoch (the RMS pooled over "
             f"{SETTLE_S:g}-{duration_s:g} s, "
             f"{float(np.sqrt(np.mean(rms_t[after] ** 2))):.2f}′, would hold)")
    show = [x for x in (level_sweep or {}) if x in (PHI0_DEG[0], abs(phi0[0]))]
    if show:
        limit += (". Initial level errors (the seed gives none; fitted to Table 2 state 1, 'Level fit' "
                  "table): the filter's own pitch σ at 30 s is "
                  + ", ".join(f"{level_sweep[x]['sigma30']:.2f}′ at {x:g}°" for x in show)
                  + " (the per-epoch RMS of the sweep's runs: "
                  + ", ".join(f"{level_sweep[x]['rms30']:.2f} ± {level_sweep[x]['rms30_se']:.2f}′"
                              for x in show)
                  + "): the prior moves it little; Table 1's GPS velocity, not the prior, keeps it above 2′")
    spec = [resolved_row(summary_row(
        f"pitch error, per-epoch RMS over runs (biases drawn per run), largest from {SETTLE_S:g} s on (at "
        f"{t[k]:g} s): the seed's level accuracy (精度) < {lim:g}′ once the attitude is estimated; "
        "the seed's "
        f"Table 2, whole run: mean {pm:g}′, std {ps:g}′", "arcmin", worst, None, f"ours < {lim:g}", spec=True,
        stderr=worst_se, margin=(lim - worst, worst_se), runs=P.shape[0]), P.shape[0], why=(
        f"the per-epoch RMS over runs is {worst:.2f} ± {worst_se:.2f}′ at {t[k]:g} s and stays below "
        f"{lim:g}′ "
        f"from {t_below:g} s on. {limit}. With the biases fixed at +500 µg on "
        f"every axis (the former reading, 'Pitch: bias reading') the largest RMS is {float(fr[fk]):.2f}′"))]
    info = [
        summary_row(f"pitch error, per-epoch RMS over runs: first epoch from which it stays below {lim:g}′",
                    "s", t_below, runs=P.shape[0]),
        summary_row(f"pitch error, per-epoch RMS over runs, mean over the epochs after {SETTLE_S:g} s",
                    "arcmin",
                    float(np.sqrt(np.mean(rms_t[after] ** 2))), runs=P.shape[0]),
        summary_row(f"largest |pitch error| of any run after {SETTLE_S:g} s (no target: the seed gives no "
                    f"maximum; {int(np.sum(np.max(np.abs(P[:, after]), axis=1) >= lim))} of {P.shape[0]} "
                    "runs "
                    f"touch {lim:g}′)", "arcmin", pmax, runs=P.shape[0]),
    ]
    for sv_, st in pitch_sigma_vs_gps_velocity(base_seed, duration_s, phi0=phi0).items():
        info.append(summary_row(
            f"covariance study: the filter's own pitch σ at {SETTLE_S:g} s if the GPS velocity σ were "
            f"{sv_:g} m/s (Table 1: {GPS_SIGMA_VEL_M_S:g}; at 60 s: {st[60.0]:.2f}′; informative)", "arcmin",
            st[SETTLE_S]))
    sig = ", ".join(f"{v:.2f}′ at {tt:g} s" for tt, v in sigma_t.items())
    info.append(summary_row(f"the filter's own pitch σ (run 0): {sig}", "arcmin", sigma_t.get(SETTLE_S)))
    adv = fixed_bias_pitch(min(runs, SWEEP_RUNS), base_seed, duration_s, ADVERSE_RUN_IMU, phi0=phi0)
    ar, _ = per_epoch_rms(adv["series"])
    pb = pitch_bias_model(phi0[0])
    acc = math.sqrt(float(np.mean(fx["ms"])))
    sens = [
        summary_row(f"fixed +500 µg / 0.1°/h on every axis (the former reading): per-epoch RMS over runs, "
                    f"largest from {SETTLE_S:g} s on (same target; the fixed equal bias nearly cancels the "
                    "tilt "
                    "the antenna cannot see)", "arcmin", float(fr[fk]), None, f"ours < {lim:g}",
                    stderr=float(fse[fk]), margin=(lim - float(fr[fk]), float(fse[fk])), runs=n_fix),
        summary_row(f"fixed +500 µg on every axis: RMS of the pitch error pooled over {SETTLE_S:g}-"
                    f"{duration_s:g} s (the former spec statistic)", "arcmin", acc, runs=n_fix),
        summary_row(f"horizontal accelerometer biases of opposite sign (x +500, y −500 µg; bias-tied pitch "
                    f"{pb['adverse']:.2f}′): per-epoch RMS over runs, largest from {SETTLE_S:g} s "
                    "on", "arcmin",
                    float(np.max(ar[after])), runs=len(adv["max"])),
        summary_row(f"biases drawn per run: the bias-tied pitch error alone, 1σ k·sin α·σ∇/g (k = "
                    f"{pb['k']:.3f} from the priors, α = {pb['alpha_deg']:.1f}°)", "arcmin", pb["sigma"]),
        summary_row("fixed equal biases (+ on every axis): the bias-tied pitch error, "
                    "k·sin α·|cos α − sin α|·∇/g",
                    "arcmin", pb["seed"]),
        summary_row(f"the bias-tied error alone keeps a run below {lim:g}′ with probability P(|N(0, "
                    f"{pb['sigma']:.2f}′)| < {lim:g}′)", "-", float(2 * norm.cdf(lim / pb["sigma"]) - 1)),
    ]
    fig = {"t": t, "rms": rms_t, "se": se_t, "fixed_rms": fr, "adverse_rms": ar, "runs": P.shape[0],
           "n_fixed": n_fix, "max_abs": np.max(np.abs(P), axis=0)}
    return spec, info, sens, fig
