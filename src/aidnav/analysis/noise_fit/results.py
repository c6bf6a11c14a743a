"""Result containers of the characterisation: one term, one axis, the whole log; the error for a moving log.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from aidnav.analysis.noise_fit.model import AXES, TERM_ORDER, model_avar


def json_float(x) -> float | None:
    """float(x), or None when it is not finite (JSON has no NaN / inf)."""
    x = float(x)
    return x if math.isfinite(x) else None


class NotStaticError(ValueError):
    """The log (or the chosen part) moves: the message names when and by how much."""


# --------------------------------------------------------------------------------------- results
@dataclass
class TermEstimate:
    """One noise term of one axis, SI units (see :class:`AxisFit` for which).

    status : "fitted" (value with a 95% interval [lo, hi]) or "not resolved" (the data do not support a
    value: the term is not significant, or its interval reaches zero, is open or spans more than
    ``MAX_CI_RATIO``; then no value, only the interval's ends ``lo`` (None = 0) and ``upper``
    (None = unbounded)). ``note`` says why in words.
    """

    status: str
    value: float | None = None
    lo: float | None = None
    hi: float | None = None
    upper: float | None = None
    note: str = ""

    @property
    def fitted(self) -> bool:
        return self.status == "fitted"

    def covers(self, truth: float) -> bool:
        """True if ``truth`` lies in the reported interval ([lo, hi], or [0, upper] when not resolved)."""
        if self.fitted:
            return self.lo <= truth <= self.hi
        return (self.lo is None or self.lo <= truth) and (self.upper is None or truth <= self.upper)

    def scaled(self, f: float) -> dict:
        """JSON-ready dict with every number divided by ``f`` (SI → boundary units)."""
        d = {"status": self.status}
        if self.value is not None:
            d.update(value=self.value / f, ci95=[self.lo / f, self.hi / f])
        else:
            if self.lo is not None:
                d["lower_bound"] = self.lo / f
            d["upper_bound"] = None if self.upper is None else self.upper / f
        if self.note:
            d["note"] = self.note
        return d


@dataclass
class AxisFit:
    """Allan deviation and fitted noise terms of one axis.

    taus [s]; adev, adev_lo, adev_hi [u] (95% chi-square interval); edf : equivalent degrees of freedom;
    alpha : power-law noise type of the largest term at each τ (2 quantisation, 0 white, −1 Gauss-Markov,
    −2 random walk); used : τ included in the fit. u = rad/s (gyro) or m/s² (accel).
    terms (SI): ``white`` N [u·√s] (ARW rad/√s, VRW m/s/√s); ``quantisation`` Q [u·s] (rad, m/s);
    ``gm_sigma`` [u] and ``gm_tau`` [s]; ``bias_instability`` B = 0.9294 σ_GM [u]; ``rrw`` K [u/√s].
    coef : maximum-likelihood (Q², N², σ_GM², K²) [SI]; t_corr : T [s]; deviance, dof, dispersion : of
    the fit (dispersion = max(1, minimum/dof) scales the profile threshold); white_only : only Q and N
    were fitted (a short log: σ_GM and K held at zero and reported as not resolvable).
    """

    axis: str
    taus: np.ndarray
    adev: np.ndarray
    adev_lo: np.ndarray
    adev_hi: np.ndarray
    edf: np.ndarray
    alpha: np.ndarray
    used: np.ndarray
    terms: dict[str, TermEstimate]
    coef: np.ndarray
    t_corr: float
    deviance: float
    dof: int
    dispersion: float
    notes: list[str] = field(default_factory=list)
    white_only: bool = False

    @property
    def sensor(self) -> str:
        return self.axis.split("_")[0]

    def model_adev(self, taus=None, term: str | None = None) -> np.ndarray:
        """ADEV of the fitted model (or of one term "Q", "N", "GM", "K") at ``taus`` [s] (default: the
        analysed τ)."""
        tau = self.taus if taus is None else np.asarray(taus, float)
        c = np.array(self.coef, float)
        if term is not None:
            keep = np.array([t == term for t in TERM_ORDER], float)
            c = c * keep
        return np.sqrt(model_avar(tau, c, self.t_corr))


@dataclass
class Characterisation:
    """Result of :func:`characterise_rates` / :func:`characterise_imu`.

    axes : the six :class:`AxisFit` (gyro x, y, z [rad/s], accel x, y, z [m/s²]); fs_hz : uniform
    sample rate analysed; n_samples; duration_s; span_s : (start, end) of the analysed part on the
    input's time scale [s]; resampled : the log was put on a uniform grid; static : result of
    :func:`static_check`; notes : what was done and found, in words (gaps, resampling, short log);
    warnings : the findings a user must not miss (slow motion kept, motion cut off, vibration), also in
    notes; vibration : :func:`vibration_report` of the analysed part; white_only : only the white terms
    were fitted (a short log).
    """

    axes: list[AxisFit]
    fs_hz: float
    n_samples: int
    duration_s: float
    span_s: tuple[float, float]
    resampled: bool
    static: dict
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    vibration: dict = field(default_factory=dict)
    white_only: bool = False

    def axis(self, name: str) -> AxisFit:
        return self.axes[AXES.index(name)]
