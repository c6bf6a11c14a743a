"""White or time-correlated GNSS position errors? The choice of a run whose configuration states no
``gnss.error_tau_s`` (issue 35, item 4), made from the innovations of a first pass.

A Kalman filter whose model matches its measurements has white innovations (Kailath 1968; Mehra 1970,
*On the identification of variances and adaptive Kalman filtering*): fixes whose errors persist over many
fixes (multipath, residual atmospheric errors of a code solution) leave a white-error filter with
innovations correlated from one fix to the next, since the filter takes each fix as new information
and follows the slow error. The test:

1. a first pass with white errors (``error_tau_s`` 0) over the log's first ``span_s`` seconds
   (:data:`DECIDE_SPAN_S`);
2. the lag-one autocorrelation ρ̂ of its normalised position innovations ν/√S (fixes accepted one after
   the other, pooled over E, N, U; n pairs): for white errors and a consistent filter ρ̂ ≈ N(0, 1/n);
3. **white** when ρ̂ ≤ max(:data:`RHO_MIN`, :data:`Z_WHITE`/√n); else **correlated**: three first-order
   Gauss–Markov error states with τ :data:`~aidnav.filters.preprocess.GNSS_ERROR_TAU_S` and the fixes'
   median σ per axis (the fixes' own σ then the white part, as
   :func:`~aidnav.filters.preprocess.correlated_gnss_errors`).

The test runs at any rate (for code fixes). At 1 Hz or slower it adds the states where the rate rule of
:func:`~aidnav.filters.preprocess.correlated_gnss_errors` says white (1-Hz fixes with correlated errors
get them); above 1 Hz it keeps the rate rule's states where the innovations are correlated — a
receiver's fixes that fast usually are, by its own tracking loops and filtering — and removes them where
they are white (issue 35, session 12). Until then the test was one-sided, because without the states a
filter given ten white fixes a second for minutes leaned on its linearisation more than it could bear
(session 9: the matrix's "parked 10 min then driving", 10-Hz white fixes, ρ̂ ≈ 0.00 over 18,000 pairs;
without the states the matched configuration's roll/pitch/heading coverage fell from 88/96/91 to
65/86/77 %). What it leaned on was the heading that wanders at rest and the tilt's frame, since repaired
(:func:`aidnav.filters.engine._turn_tilt_at_rest`, the tilt turned with the feedback's heading changes,
the re-initialisation that adds variance): the matched configuration (white, as the fixes are) passes
that cell, and the states on white fixes left the no-option and preset position σ 3–4× the error
(RMS(error)/RMS(σ) 0.26–0.31 < 0.3: a σ uselessly large) with the gaps in the σ's favour.

The correlation time itself is not estimated: the innovations of a white-error first pass decay over the
filter's own memory, not the errors', and a maximum-likelihood choice of τ over a grid (5–300 s) from
passes with the states picked 0–300 s for simulated errors of 10, 30 and 100 s (docs/results.md, issue
35 session 9): too unreliable to ship. Nothing is decided here (the rate rule of
:func:`~aidnav.filters.preprocess.correlated_gnss_errors` applies) for carrier-phase fixes (median
horizontal σ below :data:`~aidnav.filters.preprocess.CARRIER_PHASE_SIGMA_M`), velocity-only use, or fewer
than :data:`MIN_PAIRS` pairs of consecutive accepted fixes. :data:`Z_WHITE` is a statistic;
:data:`RHO_MIN` was set between the values measured on the consistency matrix's simulated drives (white
fixes ≤ 0.25, correlated 0.75–0.95: stated at its definition), not fitted to a score. The decision and
the figures it rests on go into the run's events.

**The fixes' stated σ** (issue 35, session 11): a receiver (or a reader's floor for σ = 0) may claim 5 cm
for fixes good to 0.5 m. A filter that believes it rejects most fixes, re-initialises in chains and is
dragged by the ones it takes. The same first pass measures it (covariance matching, Mehra 1970): the
normalised innovations ν²/s of a consistent filter are χ²₁, so the factor k = median(ν²/s)/0.455 (the χ²₁
median; the median, since the gate and the re-initialisations make the tails) over the horizontal (and,
apart, the vertical) position innovations of every fix with one (accepted or rejected) is 1 ± 2.3/√n.
When k > :data:`K_SIGMA` the fixes' σ is understated: ``gnss.pos_std_scale`` (horizontal;
``pos_std_scale_up`` for the vertical) is multiplied by √k and the pass is run again with it (the
first pass's filter, following fixes it trusts, understates its own P too, so one step does not reach
the fixed point), up to :data:`MAX_SIGMA_PASSES` passes, until k ≤ :data:`K_SIGMA`.
A step is kept only when it brings that axis's k down and not below 1/K_SIGMA, else it is undone and the
axis left (the excess is the navigation model's: measured on the consistency matrix's 10-Hz parked drive,
where k_U rose 3.2 → 4.5 → 8.5 as the vertical σ grew). The vertical is tested only when the horizontal
says the fixes' σ is understated: the vertical innovations also carry the height channel's own errors
(the same cell, seed 4: k_U 2–4 with honest fixes and k_H 0.8), and a receiver (or a reader's floor)
that understates σ does so for the whole fix. σ is only ever scaled up (an overstated σ costs accuracy,
not honesty, and a navigation model that is off raises k, never lowers it). A configuration that states
``gnss.pos_std_scale`` or ``pos_std_scale_up`` is kept as stated. The factors and their passes go into
the run's events (the summary's ``gnss_sigma``); the white/correlated test then runs with them.
"""

from __future__ import annotations

import numpy as np

from aidnav.data import ImuData

from .preprocess import CARRIER_PHASE_SIGMA_M, GNSS_ERROR_TAU_S, gnss_arrays

__all__ = ["DECIDE_SPAN_S", "K_SIGMA", "RHO_MIN", "choose_gnss_errors", "innovation_whiteness",
           "needs_first_pass", "sigma_factor"]

#: the first pass runs over the log's first 10 min at most (enough fixes at any rate ≥ 0.5 Hz)
DECIDE_SPAN_S = 600.0
#: white when ρ̂ is below Z_WHITE/√n (a one-sided 4σ test: a false "correlated" once in 30,000 runs) …
Z_WHITE = 4.0
#: … or below this: the innovations of a white-error filter whose *navigation* model is off (an IMU model
#: that does not cover the sensor, a tilt error) are correlated by the slow navigation error itself, up to
#: ≈ 0.25 at 1 Hz on the consistency matrix's consumer IMU with white fixes; correlated fixes (τ ≫ the
#: spacing) give 0.75–0.95 (docs/results.md, issue 35 session 9). ρ̂ = 0.5 means an innovation correlation
#: time −Δt/ln ρ̂ of 1.4 fix intervals: the fixes are not independent
RHO_MIN = 0.5
MIN_PAIRS = 30
#: the fixes' σ is scaled when the median normalised horizontal innovation² is more than this many times
#: the χ²₁ median: σ understated by more than √2, far outside a consistent filter's 1 ± 2.3/√n (n ≥ 60
#: here; measured: 0.9–1.1 with honest σ on issue 35's simulated car, 18–28 for fixes that claim 5 cm
#: against 0.5 m; docs/results.md, issue 35 session 11, m35r). A statistic's bound, not fitted to a score
K_SIGMA = 2.0
#: at most this many first passes to reach k ≤ K_SIGMA (measured: three for a 10× understated σ)
MAX_SIGMA_PASSES = 4
CHI2_1_MEDIAN = 0.45494


def innovation_whiteness(res) -> tuple[float, int, float]:
    """(ρ̂, n, log-likelihood) of a run's position innovations (``res.records``): the lag-one
    autocorrelation of u = ν/√s over the n pairs of consecutive fixes both accepted (pooled over the
    axes, the mean of each axis removed), and Σ u² + ln s over the accepted fixes (negative
    log-likelihood up to a constant: smaller is likelier)."""
    r = res.records
    ok = (r["pos_status"] == 1) & np.all(np.isfinite(r["pos_innov"]) & (r["pos_s"] > 0), axis=1)
    s = np.where(ok[:, None], r["pos_s"], np.nan)
    u = r["pos_innov"] / np.sqrt(s)
    u = u - np.nanmean(u, axis=0) if ok.any() else u
    pair = ok[1:] & ok[:-1]
    n = int(pair.sum()) * 3
    num = float(np.sum(u[1:][pair] * u[:-1][pair]))
    den = float(np.sum(u[ok] ** 2))
    rho = num / den if n and den > 0 else np.nan
    nll = float(np.sum(u[ok] ** 2 + np.log(s[ok])))
    return rho, n, nll


def sigma_factor(res) -> tuple[float, float, int]:
    """(k_h, k_u, n): the medians of ν²/s of a run's horizontal and vertical position innovations
    (``res.records``; every fix with an innovation, accepted or rejected) over the χ²₁ median, and the
    number n of horizontal ones (module doc)."""
    r = res.records
    ok = (r["pos_status"] >= 0) & np.all(np.isfinite(r["pos_innov"]) & (r["pos_s"] > 0), axis=1)
    u2 = r["pos_innov"][ok] ** 2 / r["pos_s"][ok]
    if not len(u2):
        return np.nan, np.nan, 0
    return (float(np.median(u2[:, :2]) / CHI2_1_MEDIAN), float(np.median(u2[:, 2]) / CHI2_1_MEDIAN),
            2 * len(u2))


def _with_scale(cfg, scale):
    """``cfg`` with the fixes' horizontal and vertical σ scaled by ``scale`` (2)."""
    upd = {"pos_std_scale": float(scale[0]), "pos_std_scale_up": float(scale[1] / scale[0])}
    return cfg.model_copy(update={"gnss": cfg.gnss.model_copy(update=upd)})


def _with_tau(cfg, tau, sigma=None):
    upd = {"error_tau_s": float(tau)}
    if sigma is not None:
        upd["error_sigma_m"] = sigma
    return cfg.model_copy(update={"gnss": cfg.gnss.model_copy(update=upd)})


def _test_applies(gnss, cfg):
    """The fixes' median position σ per axis when the test of the module doc applies to ``gnss`` under
    ``cfg`` (no ``error_tau_s`` stated, positions used, enough code fixes), else None."""
    g = cfg.gnss
    if "error_tau_s" in g.model_fields_set or g.use == "velocity" or len(gnss) < MIN_PAIRS:
        return None
    med = np.nanmedian(gnss_arrays(gnss, cfg)[5], axis=0) * np.asarray(g.pos_std_scales)
    if not np.nanmax(med[:2]) >= CARRIER_PHASE_SIGMA_M:
        return None  # carrier-phase fixes: the rate rule (white) of preprocess.correlated_gnss_errors
    return med


def _scale_applies(gnss, cfg) -> bool:
    """Whether the fixes' σ factor of the module doc is measured: positions used, enough fixes, no
    ``gnss.pos_std_scale`` stated."""
    g = cfg.gnss
    stated = {"pos_std_scale", "pos_std_scale_up"} & g.model_fields_set
    return not stated and g.use != "velocity" and len(gnss) >= MIN_PAIRS


def needs_first_pass(gnss, cfg) -> bool:
    """Whether :func:`choose_gnss_errors` would run a first pass (the caller need not hold the log's
    prefix otherwise)."""
    return _scale_applies(gnss, cfg) or _test_applies(gnss, cfg) is not None


def _scale_sigma(run, cfg, span, events):
    """(cfg, the first pass's result): ``cfg`` with ``gnss.pos_std_scale`` (horizontal) and
    ``pos_std_scale_up`` (vertical) raised by the factors of the module doc, over the passes
    ``run(cfg)``: an axis's step is kept only when its k then falls and stays ≥ 1/K_SIGMA (the fixes' σ
    explained the excess), else undone and the axis left (the excess is the navigation model's, not the
    fixes'). The factors and passes go into ``events``."""
    s0 = np.array(cfg.gnss.pos_std_scales[1:])
    scale, prev, live, ks, undone = s0.copy(), s0.copy(), np.ones(2, bool), [], np.zeros(2, bool)
    first = None
    for i in range(MAX_SIGMA_PASSES):
        res = run(_with_scale(cfg, scale) if ks else cfg)
        first = res if first is None else first
        k = np.array(sigma_factor(res))
        if not (k[2] >= 2 * MIN_PAIRS and np.all(np.isfinite(k[:2]))):
            events.append(f"GNSS sigma: {span}: {int(k[2]) // 2} fixes with a position innovation, too few "
                          "to test their stated sigma; kept")
            return (_with_scale(cfg, prev) if ks else cfg), first
        if ks:  # the last step must have moved k towards the fixed point without passing it
            bad = (scale != prev) & ((k[:2] >= ks[-1][:2]) | (k[:2] < 1.0 / K_SIGMA))
            scale, live, undone = np.where(bad, prev, scale), live & ~bad, undone | bad
        else:  # the vertical only with the horizontal (module doc)
            live[1] = k[0] > K_SIGMA
        ks.append(k)
        step = live & (k[:2] > K_SIGMA)
        if not step.any() or i == MAX_SIGMA_PASSES - 1:
            break
        prev, scale = scale, np.where(step, scale * np.sqrt(k[:2]), scale)
    figs = ", then ".join(f"{k[0]:.3g}/{k[1]:.3g}" for k in ks)
    stat = (f"{span}: median normalised innovation^2 / chi2(1) median, horizontal/vertical, {figs} over "
            f"{int(ks[-1][2])} horizontal innovations; > {K_SIGMA:g} scales while it falls towards 1")
    left = [a for a, u in zip(("horizontal", "vertical"), undone, strict=True) if u]
    left = (f"; {' and '.join(left)} not scaled: k did not fall towards 1 with the fixes' sigma (it rose, "
            f"or fell below {1 / K_SIGMA:g}): the excess is not theirs") if left else ""
    f = scale / s0
    if np.all(f == 1.0):
        events.append(f"GNSS sigma: as stated ({stat}{left}); gnss.pos_std_scale scales it")
        return cfg, first
    events.append(f"GNSS sigma: the fixes' stated position sigma is understated: scaled by {f[0]:.3g} "
                  f"horizontal, {f[1]:.3g} vertical ({stat}{left}; covariance matching, "
                  "filters.gnss_errors); gnss.pos_std_scale and pos_std_scale_up state it")
    return _with_scale(cfg, scale), first


def choose_gnss_errors(imu, gnss, cfg, withheld, events, aids=(), span_s: float = DECIDE_SPAN_S):
    """The configuration with ``gnss.pos_std_scale`` (when the configuration states none) and
    ``gnss.error_tau_s`` (and ``error_sigma_m``) chosen by the tests of the module doc when the
    configuration states neither; the decisions and their figures appended to ``events``.
    ``imu``: the log (or its first ``span_s`` seconds; the passes use no more)."""
    from .stream import stream_loose  # lazy: filters.stream imports the engine (numba)

    if not needs_first_pass(gnss, cfg):
        return cfg
    t0 = float(imu.time[0])
    k = imu.time <= t0 + span_s
    head = imu if k.all() else ImuData(imu.time[k], imu.dtheta[k], imu.dv[k], t0=imu.t0)
    gsel = np.asarray(gnss.time) <= float(head.time[-1])
    wh = None if withheld is None else np.asarray(withheld, bool)
    wh = (~gsel) if wh is None else (wh | ~gsel)
    dt = float(np.median(np.diff(np.asarray(gnss.time, float)[gsel]))) if gsel.sum() > 1 else np.nan

    def run(c):  # the streamed engine (its kernel is the one the run itself then uses: loaded once)
        return stream_loose([head], gnss, c, lambda *a, **k: None, withheld=wh, events=[], aids=aids)

    span = f"first pass over {float(head.time[-1]) - t0:.0f} s"
    if _scale_applies(gnss, cfg):
        # where the white/correlated test applies (code fixes) the passes are white-error ones
        white = _test_applies(gnss, cfg) is not None
        scaled, res = _scale_sigma(run, _with_tau(cfg, 0.0) if white else cfg, span, events)
        if "pos_std_scale" in scaled.gnss.model_fields_set:
            cfg, res = _with_scale(cfg, scaled.gnss.pos_std_scales[1:]), None
        res = res if white else None  # the first pass is the white/correlated test's own when kept
    else:
        res = None
    med = _test_applies(gnss, cfg)
    if med is None:
        return cfg
    g = cfg.gnss
    rho, n, _ = innovation_whiteness(res if res is not None else run(_with_tau(cfg, 0.0)))
    if not n >= MIN_PAIRS or not np.isfinite(rho):
        events.append(f"GNSS error model: {span}: {n // 3} pairs of consecutive accepted fixes, too few to "
                      "test the innovations; the rate rule decides")
        return cfg
    bound = max(RHO_MIN, Z_WHITE / np.sqrt(n))
    if rho <= bound:
        events.append(f"GNSS error model: white ({span}: lag-one autocorrelation of the normalised position "
                      f"innovations {rho:+.3f} <= {bound:.3f} over {n} pairs); gnss.error_tau_s sets "
                      "correlated-error states")
        return _with_tau(cfg, 0.0)
    sig = g.error_sigma_m if "error_sigma_m" in g.model_fields_set else tuple(float(v) for v in med)
    events.append(f"GNSS error model: correlated ({span} at {1 / dt:.2g} Hz: lag-one autocorrelation of the "
                  f"white-error filter's normalised position innovations {rho:+.3f} > {bound:.3f} over {n} "
                  f"pairs): 3 Gauss-Markov states, tau {GNSS_ERROR_TAU_S:g} s (the error sources' physics; "
                  f"not estimated), sigma E/N/U {sig[0]:.3g}/{sig[1]:.3g}/{sig[2]:.3g} m (the fixes' median; "
                  "their own sigma the white part); gnss.error_tau_s: 0 treats them as white")
    return _with_tau(cfg, GNSS_ERROR_TAU_S, sig)
