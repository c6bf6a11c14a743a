"""Fit of the noise model to one axis's overlapping Allan deviation, with 95% profile-likelihood intervals.

Likelihood. Each overlapping Allan variance is treated as a chi-square variable whose degrees of freedom and
correlations with the others follow from the model and the number of clusters (:mod:`.allan_cov`). The fit
minimises the correlated (whitened) sum of squares of (ln σ̂² − E ln(χ²_ν/ν) − ln σ²_model)/sd(ln(χ²_ν/ν))
over Q², N², σ², K² ≥ 0 and ln T (peak of the GM between max(10 τ_min, 2 s) and the longest fitted τ), with
ν and the correlations re-evaluated at the fit three times. τ with fewer than three independent clusters are
shown but not fitted. Each term's 95% interval is a profile-likelihood interval (rise of the minimum by
χ²₁(0.95) = 3.84, times the reduced χ² when that exceeds 1). On simulated logs the whitened residuals have
unit variance and the minimum at the true parameters follows χ²₅ (tests/analysis/test_characterise.py).

Which terms are reported. All four terms stay in the model (dropping one that the data cannot separate from
another would bias the other's interval). A term other than the white noise is reported ("fitted", with its
interval) only when (i) its interval excludes zero and spans at most a factor ``MAX_CI_RATIO`` in deviation
units, and (ii) removing it raises the minimum by more than the ``DETECT_PROB`` = 99% point of χ² (1 degree
of freedom; 2 for the Gauss-Markov σ and T together). T is reported when its own interval is closed and
within a factor ``MAX_CI_RATIO``. Otherwise the term is "not resolved": no value, only the ends of its
interval (an upper bound, or none).

Short logs (``white_only``). With fewer than ``MIN_FULL_POINTS`` τ to fit, only the white terms
(quantisation and ARW / VRW) are fitted, on the short-τ part where they describe the curve (from the
shortest 3 τ they fit, extended upwards while they still do); the bias instability, its correlation time and
the random walk are reported as not resolvable. Where no τ range is white noise (vibration or disturbance
everywhere), the white term is not resolved and its upper bound min(σ(τ)·√τ) is given.
"""

from __future__ import annotations

import math

import numpy as np

from aidnav.analysis.noise_fit.allan_cov import estimate_edf, estimate_stats
from aidnav.analysis.noise_fit.model import (
    B_PER_GM_SIGMA,
    FLICKER_ADEV,
    GM_PEAK_X,
    TERM_ORDER,
    gm_shape,
    logchi2_moments,
)
from aidnav.analysis.noise_fit.nnls import columns_nb, fit_c_nb, profile_u_nb
from aidnav.analysis.noise_fit.results import AxisFit, TermEstimate
from aidnav.analysis.noise_fit.roots import brentq
from aidnav.units import DEG_H, DEG_SQRT_H, M_S_SQRT_H, UG

CI_PROB = 0.95  #: two-sided probability of the reported intervals
MAX_CI_RATIO = 10.0  #: a term whose 95% interval spans more than this factor is "not resolved"


MIN_CLUSTERS = 3  #: a τ is fitted only when the log holds at least this many independent clusters of it
#: fewer fitted τ than this: only the white terms (Q, N) are fitted; the bias instability and the random
#: walk are reported as not resolvable (a short log; see :func:`fit_allan`)
MIN_FULL_POINTS = 8
#: shortest τ of a Gauss-Markov ADEV peak [s] (and at least 10 × the shortest τ): bias instability is drift
#: over seconds and longer; a shorter bump is coloured sensor noise, and letting the fit place a bump
#: anywhere turns chance wiggles of the white-noise region into "bias instability" (look-elsewhere)
GM_MIN_PEAK_S = 2.0
#: a term other than the white noise is reported only when dropping it costs more than this quantile of the
#: likelihood-ratio χ² (1 degree of freedom; 2 for the Gauss-Markov σ and T): fewer false detections than
#: the 95% intervals alone, and T is not defined without the term
DETECT_PROB = 0.99


# ------------------------------------------------------------------------------------------ fitting
_NGRID = 25


class _Profile:
    """Profile objective of one axis: D(ψ) = min over the other parameters with one of them fixed.

    y = ln(σ̂²) − E[ln(χ²_ν/ν)], s = sd of ln(χ²_ν/ν); Linv whitens the correlation of the estimates;
    ``drop`` : terms held at zero (indices into Q, N, GM, K)."""

    def __init__(self, tau, y, s, Linv, drop=()):
        self.tau, self.y, self.s, self.Linv = tau, y, s, Linv
        self.u_lo = math.log(min(max(10.0 * tau[0], GM_MIN_PEAK_S), tau[-1]) / GM_PEAK_X)
        self.u_hi = math.log(tau[-1] / GM_PEAK_X)
        self.c0 = np.zeros(4)
        self.u_hint = math.nan
        self.drop = tuple(drop)
        # results by (what is fixed, its value, the start): the intervals, the significance tests and the
        # correlation time's interval ask for the same points again (a fifth of the calls, a third of at_u)
        self._memo: dict = {}

    def with_drop(self, drop) -> _Profile:
        p = _Profile(self.tau, self.y, self.s, self.Linv, drop)
        p.u_hint = self.u_hint
        p.c0 = self.c0.copy()
        p.c0[list(drop)] = 0.0
        return p

    def _mask(self, idx, val):
        fixed = np.zeros(4, np.bool_)
        fixv = np.zeros(4)
        fixed[list(self.drop)] = True
        if idx >= 0:
            fixed[idx] = True
            fixv[idx] = val
        return fixed, fixv

    def _memo_get(self, key, compute):
        key = (*key, self.u_hint, self.c0.tobytes())
        r = self._memo.get(key)
        if r is None:
            r = self._memo[key] = compute()
        return tuple(x.copy() if isinstance(x, np.ndarray) else x for x in r)

    def best(self, fix_idx=-1, fix_val=0.0):
        fixed, fixv = self._mask(fix_idx, float(fix_val))
        return self._memo_get(("best", int(fix_idx), float(fix_val)), lambda: profile_u_nb(
            self.tau, self.y, self.s, self.Linv, fixed, fixv, self.u_lo, self.u_hi, _NGRID, self.c0,
            self.u_hint))

    def at_u(self, u):
        fixed, fixv = self._mask(-1, 0.0)
        return self._memo_get(("at_u", float(u)), lambda: fit_c_nb(
            columns_nb(self.tau, float(u)), self.y, self.s, self.Linv, fixed, fixv, self.c0, 60))


def _interval(prof: _Profile, idx: int, c_hat: float, d_min: float, crit: float, cap: float):
    """Profile-likelihood interval (lo, hi) of coefficient ``idx``: where D − D_min = crit."""
    def f(v):
        return prof.best(idx, v)[0] - d_min - crit

    d_min = min(d_min, prof.best(idx, c_hat)[0])  # the same minimiser as the profile (consistency)

    # upper end: expand from the estimate (or from a tiny value when the estimate is zero)
    start = c_hat if c_hat > 0 else cap * 1e-12
    hi_b = start * 2.0
    hi = None
    while hi_b < cap * 1e4:
        if f(hi_b) > 0:
            lo_b = start if c_hat > 0 else 0.0
            hi = brentq(f, lo_b, hi_b, xtol=1e-4 * hi_b, rtol=1e-4)
            break
        start, hi_b = hi_b, hi_b * 4.0
    if hi is None:
        hi = np.inf
    if c_hat <= 0 or f(0.0) <= 0:
        lo = 0.0
    else:
        lo = brentq(f, 0.0, c_hat, xtol=1e-6 * c_hat, rtol=1e-4)
    return lo, hi


def _u_interval(prof: _Profile, d_min: float, crit: float):
    """Profile interval of u = ln T over the grid range (None at an end that reaches the range end)."""
    us = np.linspace(prof.u_lo, prof.u_hi, 4 * _NGRID)
    d = np.array([prof.at_u(u)[0] for u in us]) - d_min - crit
    inside = d <= 0
    if not inside.any():
        return None, None
    i0, i1 = np.flatnonzero(inside)[[0, -1]]

    def g(u):
        return prof.at_u(u)[0] - d_min - crit

    lo = None if i0 == 0 else brentq(g, us[i0 - 1], us[i0], xtol=1e-5)
    hi = None if i1 == len(us) - 1 else brentq(g, us[i1], us[i1 + 1], xtol=1e-5)
    return lo, hi


def _chi2_ppf(p, df):
    """Quantile of χ²_df at probability p: scipy.stats.chi2.ppf's own formula, 2·P⁻¹(df/2, p) (without the
    import of scipy.stats, half a second at start-up)."""
    from scipy.special import gammaincinv  # lazy: scipy.special: ~0.1 s to import; the warm-up loads it

    return 2.0 * gammaincinv(np.asarray(df, dtype=float) / 2.0, p)


def _why_not(term: str, tau_lo: float, tau_hi: float) -> str:
    if term == "Q":
        return f"no slope −1 at the shortest τ (from {tau_lo:g} s): quantisation below the white noise"
    if term == "GM":
        return (f"no bias-instability bump resolved with its peak inside the fitted τ range {tau_lo:g}-"
                f"{tau_hi:.4g} s: hidden by the other terms or needs a longer log (the peak is at 1.89 T)")
    if term == "K":
        return f"no slope +1/2 resolved up to τ = {tau_hi:.4g} s: random walk too small to see in this log"
    return "white noise not resolved"


def fit_allan(taus, adev, n_samples: int, fs: float, axis: str = "gyro_x", min_m: int = 1,
              white_only: bool | None = None) -> AxisFit:
    """Fit the noise model of the module docstring to one axis's overlapping Allan deviation.

    Parameters
    ----------
    taus : (M,) averaging times [s] (multiples of 1/fs; octave spacing recommended).
    adev : (M,) overlapping ADEV [u] (u = rad/s or m/s²; any consistent unit works).
    n_samples : number of rate samples behind the ADEV (the EDF needs it); fs : their rate [Hz].
    axis : label (one of ``AXES``: its prefix decides the sensor in reports).
    min_m : smallest cluster size fitted (τ below min_m/fs are shown but not fitted).
    white_only : fit only the white terms (quantisation Q and white noise N) and report the bias
        instability and the random walk as not resolvable; None (default) = when fewer than
        ``MIN_FULL_POINTS`` τ can be fitted (a short log: the longer-τ terms are out of its reach, and the
        five parameters of the full model would leave almost no degrees of freedom).

    Method (module docstring): all four terms at once (Q², N², σ², K² ≥ 0, T with its ADEV peak inside
    the fitted τ range) by correlated least squares of the log Allan variances, whose degrees of freedom
    and correlations follow exactly from the model and the number of clusters; 95% profile-likelihood
    intervals; a term is reported only when the data support it.

    Returns an :class:`AxisFit` with terms in [u·√s] (white), [u·s] (quantisation Q), [u] (σ_GM, B),
    [s] (T), [u/√s] (random walk K), 95% intervals, and notes on what could not be resolved.
    """
    tau = np.asarray(taus, float)
    adev = np.asarray(adev, float)
    m = np.rint(tau * fs).astype(int)
    n_phase = int(n_samples) + 1
    ok = np.isfinite(adev) & (adev > 0) & (m >= 1) & (n_phase - 2 * m >= 1)
    # τ with fewer than MIN_CLUSTERS independent clusters are shown but not fitted: their chi-square has
    # one or two degrees of freedom, far from the Gaussian log-likelihood used
    used = ok & (m >= min_m) & (n_samples >= MIN_CLUSTERS * m)
    notes: list[str] = []
    if white_only is None:
        white_only = bool(used.sum() < MIN_FULL_POINTS)
    n_min = 3 if white_only else 5
    if used.sum() < n_min:
        raise ValueError(f"{axis}: fewer than {n_min} usable Allan deviation points (log too short or "
                         "constant)")
    avar = adev**2
    if white_only:  # the white-noise region: the shortest 3 τ that the white terms fit, extended upwards
        _white_region(tau, avar, m, n_phase, used, axis, notes)
    tu, au = tau[used], avar[used]
    tau_lo, tau_hi = float(tu[0]), float(tu[-1])
    drop = (2, 3) if white_only else ()
    n_par = 2 if white_only else 5

    # EDFs and correlations of the estimates from the model itself (exact for Gaussian noise, see
    # estimate_stats), re-evaluated at the fit three times starting from white noise
    c_hat, u_hat = np.array([0.0, float(np.min(au * tu)), 0.0, 0.0]), math.log(tu[-1])
    for _ in range(3):
        nu, Linv = estimate_stats(tu, m[used], n_phase, c_hat, math.exp(u_hat))
        b, sd = logchi2_moments(nu)
        full = _Profile(tu, np.log(au) - b, sd, Linv, drop=drop)
        d_full, u_hat, c_hat = full.best()
    full.u_hint, full.c0 = u_hat, c_hat.copy()
    nu_all = np.full(len(tau), np.nan)
    nu_all[ok] = estimate_edf(tau[ok], m[ok], n_phase, c_hat, math.exp(u_hat))  # ν only
    parts = np.column_stack([3.0 * c_hat[0] / tau**2, c_hat[1] / tau,
                             c_hat[2] * gm_shape(tau / math.exp(u_hat)), c_hat[3] * tau / 3.0])
    alpha = np.array([(2, 0, -1, -2)[k] for k in np.argmax(parts, axis=1)])
    n_pts = len(tu)
    disp = max(1.0, d_full / max(1, n_pts - n_par))  # reduced chi-square of the fit, when above 1
    if disp > 2.0:
        notes.append(f"{axis}: the model fits the Allan variance with chi-square {d_full:.3g} for "
                     f"{n_pts - n_par} degrees of freedom; intervals widened accordingly")
    crit = float(_chi2_ppf(CI_PROB, 1)) * disp
    # every term stays in the model (no selection: dropping a term that the data cannot separate from
    # another would bias the other's interval); a term is reported when its own interval allows it
    prof, d_min = full, d_full
    dof = max(1, n_pts - int(np.sum(c_hat > 0)) - (1 if c_hat[2] > 0 else 0))

    # ADEV intervals (95%)
    nn = np.where(ok, nu_all, 1.0)
    adev_lo = adev * np.sqrt(nn / _chi2_ppf(0.5 * (1 + CI_PROB), nn))
    adev_hi = adev * np.sqrt(nn / _chi2_ppf(0.5 * (1 - CI_PROB), nn))

    caps = np.min(au[:, None] / columns_nb(tu, u_hat), axis=0)  # each term alone ≤ the data
    caps[2] = float(np.max(au)) / 0.38
    span_s = n_samples / fs
    short = (f"not resolvable in {span_s:.3g} s of data: only the white terms were fitted (tau "
             f"{tau_lo:.3g}-{tau_hi:.3g} s); a bias instability or random walk needs a log many times "
             "longer than its correlation time")
    terms = _term_estimates(prof, c_hat, d_min, crit, caps, drop, disp, short, (tau_lo, tau_hi))
    qt = terms["quantisation"]
    if min_m > 1 and qt.fitted:  # a slope −1 above the resampling's reach is not quantisation
        terms["quantisation"] = TermEstimate(
            "not resolved", upper=qt.hi, note=f"the slope -1 part of the fit from tau {tau_lo:.3g} s on "
            f"({qt.value:.3g}) is not quantisation on a resampled log (vibration's tail or the resampling); "
            "kept in the model as a nuisance")
    if white_only and not terms["white"].fitted:
        # every term adds to the Allan variance: N²/τ ≤ σ²(τ) at each τ, a bound that holds whatever else
        # the curve holds (vibration, disturbance)
        ub = float(np.min(adev_hi[ok] * np.sqrt(tau[ok])))
        w = terms["white"]
        w.upper = ub if w.upper is None else min(w.upper, ub)
        fu, un = (DEG_SQRT_H, "deg/sqrt(h)") if axis.startswith("gyro") else (M_S_SQRT_H, "m/s/sqrt(h)")
        w.note += (f"; white noise below {ub / fu:.4g} {un} (the 95% upper ADEV limits x sqrt(tau): the "
                   f"curve is not white noise anywhere in the {span_s:.3g} s of data)")
    if white_only and terms["white"].fitted:
        terms["white"].note = (f"white noise only: the bias instability and the random walk are not "
                               f"resolvable in {span_s:.3g} s of data (tau {tau_lo:.3g}-{tau_hi:.3g} s "
                               "fitted)")
    _gm_terms(terms, prof, d_min, crit, u_hat, short if white_only else None, adev_hi[used], axis)
    return AxisFit(axis=axis, taus=tau, adev=adev, adev_lo=adev_lo, adev_hi=adev_hi, edf=nn, alpha=alpha,
                   used=used, terms=terms, coef=np.array(c_hat, float), t_corr=math.exp(u_hat),
                   deviance=float(d_min), dof=dof, dispersion=disp, notes=notes, white_only=white_only)


def _white_region(tau, avar, m, n_phase: int, used, axis: str, notes: list[str]) -> None:
    """White-only fit: keep in ``used`` the white-noise region, the shortest 3 τ that the white terms
    fit, extended upwards while they still fit; say in ``notes`` what is left out."""
    idx = np.flatnonzero(used)
    crit_w = float(_chi2_ppf(DETECT_PROB, 1))
    d3 = [_white_deviance(tau[idx[j:j + 3]], avar[idx[j:j + 3]], m[idx[j:j + 3]], n_phase)
          for j in range(len(idx) - 2)]
    j0 = next((j for j, d in enumerate(d3) if d <= crit_w), int(np.argmin(d3)))
    k = j0 + 3
    d_prev = d3[j0]
    while k < len(idx):
        d_new = _white_deviance(tau[idx[j0:k + 1]], avar[idx[j0:k + 1]], m[idx[j0:k + 1]], n_phase)
        if d_new - d_prev > crit_w:
            break
        k += 1
        d_prev = d_new
    used[idx[:j0]] = False
    used[idx[k:]] = False
    if j0 or k < len(idx):
        notes.append(f"{axis}: white-noise region tau {tau[idx[j0]]:.3g}-{tau[idx[k - 1]]:.3g} s"
                     + ("; shorter tau depart from the white terms (vibration)" if j0 else "")
                     + (f"; from {tau[idx[k]]:.3g} s on the Allan deviation departs from them (other "
                        "noise or a disturbance)" if k < len(idx) else "") + ": shown, not fitted")


def _term_estimates(prof, c_hat, d_min: float, crit: float, caps, drop, disp: float, short: str,
                    tau_range) -> dict[str, TermEstimate]:
    """Quantisation, white, Gauss-Markov σ and random walk: fitted when significant and their 95%
    profile interval is narrow enough, otherwise "not resolved" with the reason."""
    tau_lo, tau_hi = tau_range
    terms: dict[str, TermEstimate] = {}
    for idx, name in ((0, "quantisation"), (1, "white"), (2, "gm_sigma"), (3, "rrw")):
        t = TERM_ORDER[idx]
        if idx in drop:
            terms[name] = TermEstimate("not resolved", note=short)
            continue
        lo2, hi2 = _interval(prof, idx, float(c_hat[idx]), d_min, crit, float(caps[idx]))
        v, lo, hi = math.sqrt(max(c_hat[idx], 0.0)), math.sqrt(lo2), _sqrt_or_none(hi2)
        dof_t = 2 if idx == 2 else 1
        if idx != 1 and lo > 0 and prof.best(idx, 0.0)[0] - d_min < _chi2_ppf(DETECT_PROB, dof_t) * disp:
            terms[name] = TermEstimate("not resolved", upper=hi, note=f"not significant at {DETECT_PROB:.0%} "
                                       "(likelihood ratio)" + (" of σ and T together" if idx == 2 else ""))
        elif lo > 0 and hi is not None and hi / lo <= MAX_CI_RATIO:
            terms[name] = TermEstimate("fitted", v, lo, hi)
        elif lo > 0:
            span = "is open above" if hi is None else f"spans a factor {hi / lo:.3g}"
            terms[name] = TermEstimate("not resolved", upper=hi, note=f"its 95% interval {span}")
        else:
            terms[name] = TermEstimate("not resolved", upper=hi, note=_why_not(t, tau_lo, tau_hi))
    return terms


def _gm_terms(terms: dict[str, TermEstimate], prof, d_min: float, crit: float, u_hat: float,
              white_only_note: str | None, adev_hi_used, axis: str) -> None:
    """Add the Gauss-Markov correlation time and the bias instability (B = B_PER_GM_SIGMA · σ_GM) to
    ``terms``; ``white_only_note``: the reason of a white-only fit (None: a full fit)."""
    gm = terms["gm_sigma"]
    if gm.fitted:
        ulo, uhi = _u_interval(prof, d_min, crit)
        if ulo is None or uhi is None or math.exp(uhi - ulo) > MAX_CI_RATIO:
            span = ("reaches the end of the τ range the log resolves" if (ulo is None or uhi is None)
                    else f"spans a factor {math.exp(uhi - ulo):.3g}")
            terms["gm_tau"] = TermEstimate("not resolved", lo=None if ulo is None else math.exp(ulo),
                                           upper=None if uhi is None else math.exp(uhi),
                                           note=f"Gauss-Markov correlation time: its 95% interval {span}")
        else:
            terms["gm_tau"] = TermEstimate("fitted", math.exp(u_hat), math.exp(ulo), math.exp(uhi))
    else:
        terms["gm_tau"] = TermEstimate("not resolved", note=gm.note)
    if gm.fitted:
        terms["bias_instability"] = TermEstimate("fitted", B_PER_GM_SIGMA * gm.value, B_PER_GM_SIGMA * gm.lo,
                                                 B_PER_GM_SIGMA * gm.hi)
    elif white_only_note is not None:
        terms["bias_instability"] = TermEstimate("not resolved", note=white_only_note)
    else:
        floor = float(np.min(adev_hi_used) / FLICKER_ADEV)  # a flicker floor would be below every limit
        fu, un = (DEG_H, "deg/h") if axis.startswith("gyro") else (UG, "ug")
        terms["bias_instability"] = TermEstimate(
            "not resolved", upper=None if gm.upper is None else B_PER_GM_SIGMA * gm.upper,
            note=gm.note + f"; a flat flicker floor would be below {floor / fu:.4g} {un} (the ADEV's 95% "
            "upper limits / 0.6643)")


def _white_deviance(tau, avar, m, n_phase) -> float:
    """Minimum of the white-terms (Q, N) objective on these τ (statistics re-evaluated at the fit)."""
    c_hat, u = np.array([0.0, float(np.min(avar * tau)), 0.0, 0.0]), math.log(tau[-1])
    d = math.inf
    for _ in range(3):
        nu, Linv = estimate_stats(tau, m, n_phase, c_hat, math.exp(u))
        b, sd = logchi2_moments(nu)
        d, u, c_hat = _Profile(tau, np.log(avar) - b, sd, Linv, drop=(2, 3)).best()
    return float(d)


def _sqrt_or_none(x: float) -> float | None:
    return math.sqrt(x) if np.isfinite(x) else None
