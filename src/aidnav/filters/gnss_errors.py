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

The test is one-sided: it runs where the rate rule of
:func:`~aidnav.filters.preprocess.correlated_gnss_errors` says white (fixes at 1 Hz or slower), and can
only add the states there (1-Hz fixes with correlated errors get them). Above 1 Hz the rate rule's states
stay: a receiver's fixes that fast are correlated by its own tracking loops and filtering, and a filter
given ten white fixes a second for minutes leans on its linearisation more than it can bear (measured on
the consistency matrix's "parked 10 min then driving", 10-Hz white fixes: the test rightly says white,
ρ̂ ≈ 0.00 over 18,000 pairs, and without the states the matched configuration's roll/pitch/heading
coverage falls from 88/96/91 to 65/86/77 %, while the no-option U coverage moves from 40 to 49 %:
docs/results.md, issue 35 session 9).

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
"""

from __future__ import annotations

import numpy as np

from aidnav.data import ImuData

from .preprocess import CARRIER_PHASE_SIGMA_M, GNSS_ERROR_TAU_S, gnss_arrays

__all__ = ["DECIDE_SPAN_S", "RHO_MIN", "choose_gnss_errors", "innovation_whiteness", "needs_first_pass"]

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


def _with_tau(cfg, tau, sigma=None):
    upd = {"error_tau_s": float(tau)}
    if sigma is not None:
        upd["error_sigma_m"] = sigma
    return cfg.model_copy(update={"gnss": cfg.gnss.model_copy(update=upd)})


def _test_applies(gnss, cfg):
    """The fixes' median position σ per axis when the test of the module doc applies to ``gnss`` under
    ``cfg`` (no ``error_tau_s`` stated, positions used, enough code fixes at 1 Hz or slower), else None."""
    g = cfg.gnss
    if "error_tau_s" in g.model_fields_set or g.use == "velocity" or len(gnss) < MIN_PAIRS:
        return None
    med = np.nanmedian(gnss_arrays(gnss, cfg)[5] * g.pos_std_scale, axis=0)
    if not np.nanmax(med[:2]) >= CARRIER_PHASE_SIGMA_M:
        return None  # carrier-phase fixes: the rate rule (white) of preprocess.correlated_gnss_errors
    if float(np.median(np.diff(np.asarray(gnss.time, float)))) < 1.0 - 1e-6:
        return None  # above 1 Hz: the rate rule's Gauss-Markov states (module doc)
    return med


def needs_first_pass(gnss, cfg) -> bool:
    """Whether :func:`choose_gnss_errors` would run a first pass (the caller need not hold the log's
    prefix otherwise)."""
    return _test_applies(gnss, cfg) is not None


def choose_gnss_errors(imu, gnss, cfg, withheld, events, aids=(), span_s: float = DECIDE_SPAN_S):
    """The configuration with ``gnss.error_tau_s`` (and ``error_sigma_m``) chosen by the test of the module
    doc when the configuration states neither; the decision and its figures appended to ``events``.
    ``imu``: the log (or its first ``span_s`` seconds; the passes use no more)."""
    from .stream import stream_loose  # lazy: filters.stream imports the engine (numba)

    med = _test_applies(gnss, cfg)
    if med is None:
        return cfg
    g = cfg.gnss
    t0 = float(imu.time[0])
    k = imu.time <= t0 + span_s
    head = imu if k.all() else ImuData(imu.time[k], imu.dtheta[k], imu.dv[k], t0=imu.t0)
    gsel = np.asarray(gnss.time) <= float(head.time[-1])
    wh = None if withheld is None else np.asarray(withheld, bool)
    wh = (~gsel) if wh is None else (wh | ~gsel)
    dt = float(np.median(np.diff(np.asarray(gnss.time, float)[gsel]))) if gsel.sum() > 1 else np.nan

    def run(c):  # the streamed engine (its kernel is the one the run itself then uses: loaded once)
        res = stream_loose([head], gnss, c, lambda *a, **k: None, withheld=wh, events=[], aids=aids)
        return innovation_whiteness(res)

    rho, n, _ = run(_with_tau(cfg, 0.0))
    span = f"first pass over {float(head.time[-1]) - t0:.0f} s"
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
