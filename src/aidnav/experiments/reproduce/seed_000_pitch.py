"""Seed 000: "with SAPV the pitch error is below ~2′ after 30 s" (§1.3), read as the seed's one run.

The seed shows one simulated run with Table 1's constant drift 0.1°/h and accelerometer bias 500 µg: values,
not σ of a draw (:data:`.seed_000_setup.SEED_RUN_IMU`, the same on every axis). A claim shown on one run is
reproduced when the typical run meets it: the spec row states that more than half of the runs with the
seed's biases keep |pitch error| below 2′ from 30 s on, resolved at 2 binomial standard errors over
``PITCH_RUNS_FACTOR × runs`` runs (the first ``runs`` share the main Monte Carlo's random streams).

Why some runs do not: on a static base the level tilt is seen through the GPS velocity (σ 0.5 m/s), which
resolves a tilt of g·φ only as fast as a straight-line fit resolves a slope (σ_φ ≈ σ_v √(12/T³)/g); the
SAPV elevation observes the tilt about the horizontal axis across the line of sight, not the tilt about the
line of sight's horizontal direction, whose share in pitch is sin α (α: antenna azimuth from the nose).
At 30 s that tilt is still converging (the filter's own pitch σ is in the table); from ≈ 60 s on the pitch
error is well below 1′. The sensitivity rows show the other readings: biases drawn per run with Table 1's
values as σ (the bias-tied tilt :func:`pitch_bias_model` adds), and the sign pattern of the horizontal
accelerometer biases that the antenna sees least.
"""

from __future__ import annotations

import math

import numpy as np

from aidnav.filters.federated import run_federated

from .seed_000_setup import (
    ACCEL_BIAS_UG,
    ADVERSE_RUN_IMU,
    ARCMIN,
    FED,
    HEADING_DEG,
    PHI0_DEG,
    SEED_RUN_IMU,
    SETTLE_S,
    SWEEP_RUNS,
    VARIANTS,
    _series,
    geometry_check,
    simulate_case,
)
from .summary import resolved_row, summary_row

#: runs of the seed's-run pitch set per Monte Carlo run (cheap: one filter per run)
PITCH_RUNS_FACTOR = 10
PITCH_LIMIT_ARCMIN = 2.0

__all__ = ["PITCH_RUNS_FACTOR", "pitch_bias_model", "fixed_bias_pitch", "pitch_sigma", "pitch_rows"]


def pitch_bias_model() -> dict:
    """The pitch error the accelerometer bias leaves with SAPV on the static base (arc-minutes).

    GPS holds the level velocity: g (up × φ) + ∇ → 0, so the filter can only split the level tilt from the
    horizontal accelerometer bias by their priors: a share k = σφ² / (σφ² + (σ∇/g)²) of the bias-equivalent
    tilt (z × ∇)/g stays in the attitude. The SAPV elevation observes the tilt about the horizontal axis
    across the line of sight; the tilt about the line of sight's horizontal direction (azimuth α from the
    nose, clockwise) stays, k (∇x cos α − ∇y sin α)/g (body x right, y forward), and its share in pitch (the
    tilt about x) is sin α. Returns ``k``, ``alpha_deg``, ``sigma`` (1σ for biases drawn with Table 1's σ on
    each axis), ``seed`` (Table 1's biases as values, the same on every axis), ``adverse`` (x +, y −).
    """
    g = geometry_check()
    a = math.radians(g["az_deg"])
    tilt = ACCEL_BIAS_UG * 1e-6 / ARCMIN  # σ∇/g as a tilt [arcmin] (µg of standard gravity over g)
    sphi = PHI0_DEG[0] * 60.0  # the filter's level-tilt prior σ [arcmin]
    k = sphi**2 / (sphi**2 + tilt**2)
    return {"k": k, "alpha_deg": g["az_deg"], "sigma": k * math.sin(a) * tilt,
            "seed": k * math.sin(a) * abs(math.cos(a) - math.sin(a)) * tilt,
            "adverse": k * math.sin(a) * abs(math.cos(a) + math.sin(a)) * tilt}


def fixed_bias_pitch(n: int, base_seed: int, duration_s: float, imu=SEED_RUN_IMU) -> np.ndarray:
    """Largest |pitch error| [arcmin] after ``SETTLE_S`` of the federated SINS/GPS/SAPV filter in each of
    ``n`` runs with the IMU overrides ``imu`` (run i uses child i of ``SeedSequence(base_seed)``, as the main
    Monte Carlo does)."""
    out = []
    for ss in np.random.SeedSequence(base_seed).spawn(n):
        sim, sv, cfg = simulate_case(ss, duration_s, imu=imu)
        s = _series(run_federated(sim.imu, sim.gnss, sv, cfg, VARIANTS[FED]), sim.truth)
        out.append(float(np.max(np.abs(s["pitch"][s["t"] > SETTLE_S]))))
    return np.asarray(out)


def pitch_sigma(res, t_s: float) -> float:
    """The filter's own 1σ of the pitch error [arcmin] at ``t_s`` s: the attitude covariance (E, N, U tilt)
    projected on the body right axis (heading ``HEADING_DEG``, level). ``res`` keeps its covariance."""
    k = int(np.searchsorted(res.time - res.time[0], t_s - 1e-9))
    h = math.radians(HEADING_DEG)
    u = np.array([math.sin(h + math.pi / 2), math.cos(h + math.pi / 2), 0.0])  # body x (right) in ENU
    return float(math.sqrt(u @ res.cov[k][:3, :3] @ u) / ARCMIN)


def pitch_rows(drawn_max, runs: int, base_seed: int, duration_s: float, sigma_t: dict):
    """(spec rows, informative rows of the other readings) of the pitch claim. ``drawn_max``: per-run
    largest |pitch| after ``SETTLE_S`` of the main Monte Carlo (biases drawn per run); ``sigma_t``:
    {t [s]: the filter's pitch σ}."""
    from scipy.stats import norm

    lim = PITCH_LIMIT_ARCMIN
    n = PITCH_RUNS_FACTOR * runs
    seed_max = fixed_bias_pitch(n, base_seed, duration_s)
    adv_max = fixed_bias_pitch(min(runs, SWEEP_RUNS), base_seed, duration_s, ADVERSE_RUN_IMU)
    pb = pitch_bias_model()
    frac = float(np.mean(seed_max < lim))
    se = math.sqrt(max(frac * (1 - frac), 0.25 / n) / n)  # binomial (never 0: one run flips it)
    sig = ", ".join(f"{v:.2f}′ at {t:g} s" for t, v in sigma_t.items())
    share = math.sin(math.radians(pb["alpha_deg"]))
    why = (f"the pitch error is still converging at {SETTLE_S:g} s: the tilt about the line of sight's "
           f"horizontal direction (sin α = {share:.2f} of it in pitch) is seen only through the GPS velocity "
           f"(0.5 m/s); the filter's own pitch σ is {sig}")
    row = summary_row(f"fraction of the seed's runs (Table 1's biases as values: 0.1°/h, 500 µg on every "
                      f"axis) whose |pitch error| stays below {lim:g}′ after {SETTLE_S:g} s, SINS/GPS/SAPV: "
                      "the typical run meets the seed's claim (> 1/2)", "-", frac, None, "ours > 0.5",
                      spec=True, stderr=se, margin=(frac - 0.5, se))
    spec = [resolved_row(row, n, why),
            summary_row(f"the seed's runs: largest |pitch error| after {SETTLE_S:g} s over all {n} runs "
                        f"({int(np.sum(seed_max >= lim))} reach {lim:g}′; informative)", "arcmin",
                        float(np.max(seed_max))),
            summary_row(f"the seed's runs: median of the per-run largest |pitch error| after {SETTLE_S:g} s",
                        "arcmin", float(np.median(seed_max)))]
    dm = np.asarray(drawn_max)
    fd = float(np.mean(dm < lim))
    sens = [
        summary_row(f"biases drawn per run (σ = Table 1): fraction of runs below {lim:g}′ after "
                    f"{SETTLE_S:g} s ({len(dm)} runs; largest {float(np.max(dm)):.2f}′; informative)", "-",
                    fd,
                    stderr=math.sqrt(max(fd * (1 - fd), 0.25 / len(dm)) / len(dm))),
        summary_row(f"biases drawn per run: the bias-tied pitch error alone, 1σ k·sin α·σ∇/g (k = "
                    f"{pb['k']:.3f} from the priors, α = {pb['alpha_deg']:.1f}°)", "arcmin", pb["sigma"]),
        summary_row(f"the same, fraction of runs it keeps below {lim:g}′, P(|N(0, {pb['sigma']:.2f}′)| < "
                    f"{lim:g}′)", "-", float(2 * norm.cdf(lim / pb["sigma"]) - 1)),
        summary_row("Table 1's biases as values (+ on every axis): the bias-tied pitch error, "
                    "k·sin α·|cos α − sin α|·∇/g", "arcmin", pb["seed"]),
        summary_row(f"horizontal accelerometer biases of opposite sign (x +500, y −500 µg; bias-tied pitch "
                    f"{pb['adverse']:.2f}′): fraction of {len(adv_max)} runs below {lim:g}′ after "
                    f"{SETTLE_S:g} s (informative)", "-", float(np.mean(adv_max < lim))),
    ]
    return spec, sens
