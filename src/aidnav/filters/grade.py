"""The IMU's grade from the log's static samples (issue 35, session 12: ``imu.grade_from_static``).

Without an ``imu`` section the loose filter models an IMU of unknown grade (:data:`.config.DEFAULT_IMU`:
consumer-grade numbers, 360 deg/h gyro bias, 13 mg accelerometer bias). On a better IMU that σ is honest
but uselessly large (a tactical IMU's roll σ 0.46° against 0.10° of error: RMS ratio 0.22). A log that
starts at rest says more: at rest the gyros read the Earth rate plus their bias and the accelerometers
gravity plus theirs, so with roll and pitch from the specific force three bias components are measured
outright, whatever the heading —

* the gyro bias along the vertical: the levelled rate's vertical component − Ω sin L;
* the gyro bias along the horizontal Earth rate: the levelled rate's horizontal magnitude − Ω cos L;
* the accelerometer bias (and scale factor) along the vertical: |f̄| − γ (normal gravity; its error
  against the true gravity, :data:`GRAVITY_MODEL_UG`, adds to the σ).

Each is one draw of that grade's bias distribution, measured with the standard error of its mean over the
static run (batch means, :func:`aidnav.nav.alignment.coarse_align_static`). The candidate grades
(:data:`GRADE_ROWS`: the representative values of Groves (2013) §4.4 that the project's grade table holds,
:meth:`aidnav.sim.imu.ImuSpec.grade`, and the unknown grade itself) have likelihoods Π N(r; 0, σ_grade² +
se²) of the three residuals; with equal prior probabilities, the filter takes the **loosest grade whose
posterior probability is at least** :data:`ALPHA` (a cautious choice, not the most probable one: a tactical
IMU whose 30-s start cannot tell its 1-deg/h gyro bias from a MEMS one's 10 deg/h is modelled as a MEMS
IMU). One IMU, one grade: the gyro and accelerometer triads are classed together (no IMU pairs a
tactical-grade gyro with a consumer-grade accelerometer; the gyro's three-orders-of-magnitude range is
what makes the test sharp: a consumer gyro reads within a few deg/h of the Earth rate on both components
with a probability of order 1e-5).

What the static samples cannot measure — the bias instability, scale factors and misalignments — comes
from the grade's row, stated in the run's events as such. The white noise (ARW, VRW) is not taken from
the grade: the unstated ones stay the field defaults, raised to what the log shows
(``noise_from_static``). The model is the posterior mixture of the possible grades (:func:`mixture_model`:
each σ the one whose 3σ tail is the mixture's); the navigation, tactical and MEMS grades' models are
adopted (:data:`ADOPTED`); where no adopted grade is possible (a consumer IMU), and a log without
:data:`MIN_STATIC_S` seconds at rest, the unknown-grade model stays.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from aidnav.nav.alignment import coarse_align_static
from aidnav.nav.earth import OMEGA_IE
from aidnav.units import DEG, DEG_H, G0, UG

from .config import DEFAULT_IMU
from .tuning import sensor_error_model

__all__ = ["GRADE_ROWS", "ADOPTED", "ALPHA", "MIN_STATIC_S", "BRIDGE_S", "GRAVITY_MODEL_UG", "grade_models",
           "static_residuals", "grade_posterior", "choose_grade", "mixture_model", "grade_from_static"]

#: The better-than-unknown grades, best first: gyro turn-on bias, instability [deg/h], accelerometer
#: turn-on bias, instability [µg], instability τ [s], gyro / accelerometer scale factor [ppm],
#: misalignment [arcsec] — Groves (2013) §4.4's representative values, the rows of the project's grade
#: table (:meth:`aidnav.sim.imu.ImuSpec.grade`; ``tests/filters/test_grade.py`` holds them equal). The
#: filter cannot import the simulator, so they are written here.
GRADE_ROWS: tuple = (
    ("navigation", (0.005, 0.003, 10.0, 5.0, 3600.0, 5.0, 50.0, 5.0)),
    ("tactical", (1.0, 0.3, 100.0, 50.0, 600.0, 100.0, 300.0, 60.0)),
    ("mems", (10.0, 5.0, 1000.0, 100.0, 300.0, 500.0, 1000.0, 360.0)),
)
#: The grades whose model the filter adopts (a grade not in it counts in the mixture with the unknown-grade
#: model). Session 12–13 kept MEMS out: with its row's model the matrix's MEMS cells fell to roll/pitch
#: 91.6–94.1 % (83–90 % on session 13's tree), with the unknown-grade model they were covered but 4×
#: too large (roll RMS(err)/RMS(σ) 0.25–0.30 with no option and every preset, seeds 0–9 and 10–19). What
#: made the row's model fail was not the row: the levelled tilt's independent σ, which the ZUPTs at rest
#: shrank by up to √2 (:func:`aidnav.filters.preprocess._levelling`, now a joint prior), and a mixture
#: matched on its variance, which left a MEMS IMU whose standstill looks tactical (MEMS posterior 7 %)
#: a σ 4× below its error (:func:`mixture_model`, now matched on its 3σ tail). With both (session 14,
#: q35g) the MEMS row's model covers: grade mems × no option and every preset 95.2–98.5 % roll/pitch,
#: ratios 1.27–1.40 (seeds 0–9), 96.1–100 %, 1.12–1.27 (seeds 10–19).
ADOPTED = ("navigation", "tactical", "mems")
#: the least posterior probability of a grade that the cautious choice still takes as possible
ALPHA = 0.01
#: the shortest static run that can class the IMU [s]
MIN_STATIC_S = 10.0
#: static runs at most this far apart are one standstill [s] (:func:`_longest_run`)
BRIDGE_S = 5.0
#: σ of normal gravity against the true one (gravity anomalies and the deflection of the vertical; Groves
#: 2013 §2.4.7: up to ~1e-4 g) [µg]
GRAVITY_MODEL_UG = 100.0
#: the model keys a grade sets (the rest of the ``imu`` section — noise, time offset, mounting — is kept)
_MODEL_KEYS = ("gyro_bias_sigma_deg_h", "accel_bias_sigma_ug", "gyro_bias_tau_s", "accel_bias_tau_s",
               "gyro_bias_instability_deg_h", "accel_bias_instability_ug", "gyro_bias_rw_deg_h_sqrt_h",
               "accel_bias_rw_ug_sqrt_h", "scale_factors", "gyro_sf_sigma_ppm", "accel_sf_sigma_ppm",
               "sf_tau_s", "gyro_misalignment", "gyro_misalignment_sigma_deg", "accel_misalignment",
               "accel_misalignment_sigma_deg")


def _row_model(row) -> dict:
    """The filter's ``imu`` model keys of a grade row (:func:`.tuning.sensor_error_model`'s rules: turn-on
    constant + instability as a random walk, scale factors and misalignments as states)."""
    gb, gi, ab, ai, tau, gsf, asf, mis = row
    spec = SimpleNamespace(
        gyro_bias=gb * DEG_H, gyro_bias_instability=gi * DEG_H, accel_bias=ab * UG,
        accel_bias_instability=ai * UG, gyro_bias_tau=tau, accel_bias_tau=tau, gyro_scale=gsf * 1e-6,
        accel_scale=asf * 1e-6, gyro_misalignment=mis / 3600.0 * DEG, accel_misalignment=mis / 3600.0 * DEG,
        gyro_arw=0.0, accel_vrw=0.0, gyro_rrw=0.0, accel_rrw=0.0)
    m = sensor_error_model(spec)
    return {k: m[k] for k in _MODEL_KEYS if k in m}


def grade_models() -> list[tuple[str, dict]]:
    """(name, model keys) of every candidate, best first, the unknown grade (:data:`.config.DEFAULT_IMU`)
    last."""
    unknown = {k: DEFAULT_IMU[k] for k in _MODEL_KEYS if k in DEFAULT_IMU}
    return [(name, _row_model(row)) for name, row in GRADE_ROWS] + [("unknown", unknown)]


def _vertical_sigmas(model: dict) -> tuple[float, float]:
    """(gyro bias σ [rad/s], accelerometer σ along the vertical at rest [m/s²]) of a model: the turn-on
    bias σ each; the accelerometer's with its scale factor × g (at rest the vertical axis reads (1 + s)·g)."""
    sg = float(model["gyro_bias_sigma_deg_h"]) * DEG_H
    sa = float(model["accel_bias_sigma_ug"]) * UG
    if model.get("scale_factors"):
        sa = float(np.hypot(sa, float(model.get("accel_sf_sigma_ppm", 0.0)) * 1e-6 * G0))
    return sg, sa


def static_residuals(imu, lat: float, height: float, start: float, stop: float):
    """The three bias components measured by the static samples of ``imu`` in [start, stop) (module doc):
    (r (3,), se (3,)) = gyro vertical, gyro horizontal [rad/s], accelerometer vertical [m/s²] and the
    standard errors of the means they come from."""
    _, _, _, info = coarse_align_static(imu, lat, start, stop, height=height)
    wl = info["w_level"]
    r = np.array([wl[2] - OMEGA_IE * np.sin(lat), np.hypot(wl[0], wl[1]) - OMEGA_IE * np.cos(lat),
                  info["f_norm"] - info["gravity"]])
    sw, sf = float(np.max(info["se_w"])), float(np.max(info["se_f"]))
    return r, np.array([sw, sw, sf])


def grade_posterior(r, se, models=None) -> np.ndarray:
    """Posterior probability of each candidate of ``models`` (default :func:`grade_models`) given the
    residuals ``r`` and their standard errors ``se`` (:func:`static_residuals`), equal priors."""
    models = grade_models() if models is None else models
    ll = np.empty(len(models))
    for i, (_, m) in enumerate(models):
        sg, sa = _vertical_sigmas(m)
        s = np.array([np.hypot(sg, se[0]), np.hypot(sg, se[1]),
                      np.sqrt(sa ** 2 + (GRAVITY_MODEL_UG * UG) ** 2 + se[2] ** 2)])
        ll[i] = float(np.sum(-0.5 * (np.asarray(r) / s) ** 2 - np.log(s)))
    p = np.exp(ll - ll.max())
    return p / p.sum()


def choose_grade(r, se, models=None) -> tuple[str, dict, np.ndarray]:
    """The cautious class and the model (module doc) → (name, model keys, posterior of every candidate):
    the class is the loosest candidate with posterior ≥ :data:`ALPHA`; the model is the posterior mixture
    of the candidates with posterior ≥ :data:`ALPHA` (:func:`mixture_model`, each one not in
    :data:`ADOPTED` by the unknown-grade model) — the loosest's alone where it is the only one."""
    models = grade_models() if models is None else models
    p = grade_posterior(r, se, models)
    i = max(j for j in range(len(models)) if p[j] >= ALPHA)
    unknown = models[-1][1]
    parts = [(float(p[j]), models[j][1] if models[j][0] in ADOPTED else unknown)
             for j in range(len(models)) if p[j] >= ALPHA]
    return models[i][0], mixture_model(parts), p


#: the model keys that are a σ (mixed as variances) and a random walk's density (mixed as PSDs)
_SIGMA_KEYS = ("gyro_bias_sigma_deg_h", "accel_bias_sigma_ug", "gyro_bias_rw_deg_h_sqrt_h",
               "accel_bias_rw_ug_sqrt_h", "gyro_sf_sigma_ppm", "accel_sf_sigma_ppm",
               "gyro_misalignment_sigma_deg", "accel_misalignment_sigma_deg")
_FLAG_KEYS = ("scale_factors", "gyro_misalignment", "accel_misalignment")


def mixture_model(parts) -> dict:
    """One model for an IMU that is one of several grades with probabilities ``parts`` [(p, model keys)]
    (renormalised): each sensor error's σ (and each random walk's density) is that of the one Gaussian
    whose 3σ tail is the scale mixture's, Σ p_i erfc(3σ/(σ_i √2)) = erfc(3/√2) (:func:`_tail_sigma`): a
    σ whose 3σ bet is as safe as the mixture's, for whichever grade the IMU is; between the smallest and
    the loosest grade's. Not the mixture's variance Σ p_i σ_i² (session 13): a scale mixture is heavier-
    tailed than the Gaussian of its variance, whose 3σ then under-covers the looser grade's IMUs — a MEMS
    IMU whose 29-s standstill reads tactical (posterior MEMS 7 %, tactical 62 %, navigation 31 %) got an
    accelerometer σ of 0.6 mg against a realised 2.8 mg (the matrix's MEMS seed 5: pitch 0–50 % covered;
    the tail-matched σ 1.4 mg). A grade without a state (``False``, or no key) adds nothing to it; a state
    any grade has is on. The bias correlation times are those of the grade that contributes most of that
    bias's variance."""
    w = np.array([q for q, _ in parts], float)
    w = w / w.sum()
    ms = [m for _, m in parts]
    out: dict = {}
    for k in _FLAG_KEYS:
        if any(k in m for m in ms):
            out[k] = any(bool(m.get(k, False)) for m in ms)
    for k in _SIGMA_KEYS:
        if any(k in m for m in ms):
            out[k] = _tail_sigma(w, [float(m.get(k, 0.0)) for m in ms])
    for k, ref in (("gyro_bias_tau_s", "gyro_bias_sigma_deg_h"), ("accel_bias_tau_s", "accel_bias_sigma_ug")):
        if any(k in m for m in ms):
            j = int(np.argmax([wi * float(m.get(ref, 0.0)) ** 2 for wi, m in zip(w, ms, strict=True)]))
            out[k] = float(ms[j].get(k, 0.0))
    return out


#: the two-sided tail probability of a Gaussian beyond 3σ (0.27 %): what a 3σ bet loses
_TAIL3 = math.erfc(3.0 / math.sqrt(2.0))


def _tail_sigma(w, sig) -> float:
    """The σ of the one Gaussian whose 3σ tail probability is the scale mixture's Σ w_i N(0, σ_i²):
    Σ w_i erfc(3s / (σ_i √2)) = erfc(3/√2), solved by bisection (between min and max σ_i: the tail is
    decreasing in s)."""
    w = np.asarray(w, float)
    sig = np.asarray(sig, float)
    lo, hi = float(sig.min()), float(sig.max())
    if hi <= 0.0 or hi - lo <= 1e-12 * hi:
        return hi

    def tail(s):
        return sum(wi * math.erfc(3.0 * s / (si * math.sqrt(2.0))) for wi, si in zip(w, sig, strict=True)
                   if si > 0.0)

    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if tail(mid) > _TAIL3 else (lo, mid)
    return 0.5 * (lo + hi)


def _longest_run(static, time, bridge_s: float = BRIDGE_S) -> tuple[int, int]:
    """(first, end) sample indices of the longest span of ``static`` samples (``time`` [s]) whose runs are
    at most ``bridge_s`` apart (a receiver's speed noise breaks a standstill into short runs; a sample in
    such a break that did move adds to the residuals: a looser grade, the safe side); (0, 0) when none."""
    s = np.asarray(static, bool)
    if not s.any():
        return 0, 0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], s.astype(np.int8), [0]])))
    a, b = list(edges[::2]), list(edges[1::2])
    spans = [[a[0], b[0]]]
    for i in range(1, len(a)):
        if time[a[i]] - time[spans[-1][1] - 1] <= bridge_s:
            spans[-1][1] = b[i]
        else:
            spans.append([a[i], b[i]])
    j = int(np.argmax([time[e - 1] - time[f] for f, e in spans]))
    return int(spans[j][0]), int(spans[j][1])


def grade_from_static(imu, static, lat: float, height: float, cfg, events):
    """``imu.grade_from_static``: class the IMU by its longest static run (``static``: per-sample flags,
    :func:`.preprocess.static_flags`) and model it by that grade (module doc). ``lat`` [rad], ``height``
    [m]: where it stands. The decision goes into ``events``. Returns the configuration to use."""
    im = cfg.imu
    if not im.grade_from_static or len(imu) < 2:
        return cfg
    t = imu.time
    a, b = _longest_run(static, t)
    if b - a < 2 or t[b - 1] - t[a] < MIN_STATIC_S:
        events.append(f"IMU grade unknown: no static run of {MIN_STATIC_S:g} s to class it by (the "
                      "unknown-grade model)")
        return cfg
    r, se = static_residuals(imu, lat, height, t[a], t[b - 1] + 1e-9)
    name, model, p = choose_grade(r, se)
    names = [n for n, _ in grade_models()]
    possible = [n for n, q in zip(names, p, strict=True) if q >= ALPHA]
    adopt = any(n in ADOPTED for n in possible)
    how = ("the grade's model (bias instability, scale factors, misalignment: the grade table's)"
           if possible == [name] else "the posterior mixture of the models of " + ", ".join(possible)
           + (" (" + ", ".join(n for n in possible if n not in ADOPTED) + ": the unknown-grade model)"
              if any(n not in ADOPTED for n in possible) else ""))
    events.append(
        f"IMU grade from {t[b - 1] - t[a]:.1f} s static: bias components gyro vertical {r[0] / DEG_H:.3g}, "
        f"horizontal {r[1] / DEG_H:.3g} deg/h (se {se[0] / DEG_H:.2g}), accelerometer vertical "
        f"{r[2] / UG:.4g} ug (se {se[2] / UG:.2g}); posterior "
        + ", ".join(f"{n} {q:.2g}" for (n, _), q in zip(grade_models(), p, strict=True))
        + f" -> {name}: " + (how if adopt else "the unknown-grade model"))
    if not adopt:
        return cfg
    # a key the configuration states with a value of its own (not the default model's) is kept
    own = {k for k in im.model_fields_set if k in DEFAULT_IMU and getattr(im, k) != DEFAULT_IMU[k]}
    return cfg.model_copy(update={"imu": im.model_copy(update={k: v for k, v in model.items()
                                                                 if k not in own})})
