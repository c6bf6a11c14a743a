"""Velocity against a reference's own positions: mean velocities over the reference's intervals, and lags.

A position fix describes its stamp. A receiver's *velocity* need not: a Doppler or position-difference
average, or a navigation filter, reports a velocity that describes an earlier time. The formats say
nothing of it (RTKLIB ``.pos`` and u-blox NAV-PVT give the velocity "at" the solution's epoch), so the
readers keep every velocity at its stamp (docs/conventions.md, "Time") and a velocity score that must not
depend on that receiver's habit is taken against the positions instead:

* the difference of two reference positions, d_k = (p_k − p_{k−1}) / (t_k − t_{k−1}), **is by definition**
  the mean velocity over I_k = [t_{k−1}, t_k]; the estimate's mean velocity over the same interval is the
  integral of its velocity samples (trapezoid, linear between samples) divided by the interval. Their
  difference needs no time-tag convention and no shift (:func:`interval_velocity_errors`). Its floor is
  the reference's position noise: σ_p·√2 / Δt per axis (white position errors).
* A series is **late** by L when it describes at t what happened at t − L. With a series s(t) (linear
  between its samples), the mean of s over [t_{k−1} + L, t_k + L] equals d_k when s is the true velocity
  late by L; :func:`velocity_lateness` returns the L of least horizontal RMS on a grid, refined by a
  parabola — a *check* on a stated convention, not a correction to apply.

Closed forms (what the test holds the functions to): a backward difference stamped at its interval's end,
(p_k − p_{k−1}) / Δt at t_k, has the kernel of a boxcar over [t_k − Δt, t_k]: its frequency response is
e^{−iπfΔt}·sinc(fΔt), a pure delay of Δt/2 at every frequency (so, late by Δt/2); a central difference
(p_{k+1} − p_{k−1}) / (2Δt) at t_k has the real response sinc(2fΔt) (no lag); for constant acceleration a
the backward difference is a·(t_k − Δt/2) exactly.

The reference's own noise (its position differences are noisy too, and a filtered RTK solution's more so
in motion) is measured by the **three-cornered hat** (:func:`three_cornered_hat`; Gray & Allan 1974, the
clock-comparison method): with three estimates a, b, r of one quantity whose errors are independent,
var(a − r) = σ_a² + σ_r², var(b − r) = σ_b² + σ_r², var(a − b) = σ_a² + σ_b², so σ_r² = ½[var(a − r) +
var(b − r) − var(a − b)] and likewise σ_a², σ_b². With a and b two TDCP velocities of disjoint satellite
sets (independent phase noise) and r the reference, it gives the reference's noise without a truth;
errors common to a and b (the antenna's motion) count as signal, and errors r shares with them (the same
receiver's phase) lower σ_r²: the estimate is a lower bound on the reference's own noise.

Frames and units: positions geodetic (lat, lon [rad], ellipsoidal or any consistent height [m]) turned into
the tangent-plane ENU frame at the first reference position (:func:`aidnav.nav.earth.lla_to_enu`; over
a few hundred metres its axes turn by d/R ≈ 5e-5 rad from the local ones: negligible here); velocities
ENU [m/s]; times [s] on one scale (docs/conventions.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..nav.earth import lla_to_enu
from .timing import parabola_minimum

__all__ = ["IntervalVelocity", "interval_velocity_errors", "velocity_lateness", "reference_enu",
           "three_cornered_hat"]


@dataclass
class IntervalVelocity:
    """Per reference interval I_k = [t_start, t_end]: ``ref`` (K, 3) the reference's mean velocity
    (position difference) and ``err`` (K, 3) the estimate's mean over I_k minus it, ENU [m/s]."""

    t_start: np.ndarray
    t_end: np.ndarray
    ref: np.ndarray
    err: np.ndarray

    def __len__(self) -> int:
        return len(self.t_start)

    def rms_horizontal(self, mask=None) -> float:
        """√mean(dvE² + dvN²) [m/s] over the intervals (``mask``: a subset)."""
        e = self.err if mask is None else self.err[mask]
        return float(np.sqrt(np.mean(np.sum(e[:, :2] ** 2, axis=1))))

    def rms_vertical(self, mask=None) -> float:
        """√mean(dvU²) [m/s]."""
        e = self.err if mask is None else self.err[mask]
        return float(np.sqrt(np.mean(e[:, 2] ** 2)))


def reference_enu(lat, lon, height) -> np.ndarray:
    """(N, 3) ENU [m] of reference positions relative to the first one."""
    e, n, u = lla_to_enu(lat, lon, height, lat[0], lon[0], height[0])
    return np.column_stack([e, n, u])


def _cumulative(time, vel):
    """Running trapezoid integral (N, 3) of ``vel`` (linear between its samples) from time[0]."""
    inc = 0.5 * (vel[1:] + vel[:-1]) * np.diff(time)[:, None]
    return np.vstack([np.zeros((1, vel.shape[1])), np.cumsum(inc, axis=0)])


def interval_means(time, vel, t_start, t_end) -> np.ndarray:
    """Mean of ``vel`` (N, 3), linear between its ``time`` samples, over each [t_start, t_end] (K, 3)."""
    time = np.asarray(time, float)
    return _window_means(time, _cumulative(time, np.asarray(vel, float)), t_start, t_end)


def _window_means(time, cum, t_start, t_end) -> np.ndarray:
    """Means over [t_start, t_end] (K, c) from the running integral ``cum`` (N, c) at ``time``."""
    a = np.column_stack([np.interp(t_start, time, cum[:, i]) for i in range(cum.shape[1])])
    b = np.column_stack([np.interp(t_end, time, cum[:, i]) for i in range(cum.shape[1])])
    return (b - a) / (np.asarray(t_end) - np.asarray(t_start))[:, None]


def _intervals(ref_time, enu, use, span, max_interval_s):
    t = np.asarray(ref_time, float)
    use = np.ones(t.size, bool) if use is None else np.asarray(use, bool)
    dt = np.diff(t)
    limit = 1.5 * float(np.median(dt)) if max_interval_s is None else float(max_interval_s)
    ok = use[1:] & use[:-1] & (dt > 0) & (dt <= limit) & (t[:-1] >= span[0]) & (t[1:] <= span[1])
    k = np.flatnonzero(ok) + 1
    d = (enu[k] - enu[k - 1]) / dt[k - 1][:, None]
    return t[k - 1], t[k], d


def interval_velocity_errors(est_time, est_vel, ref_time, ref_lat, ref_lon, ref_height, use=None,
                             max_interval_s: float | None = None) -> IntervalVelocity:
    """The estimate's mean velocity over each reference interval minus the reference's position difference
    over it (module doc). est_time (N,) [s], est_vel (N, 3) ENU [m/s]; ref_* (M,) with lat/lon [rad];
    ``use`` (M,) bool: epochs usable as interval ends (e.g. ``quality == 1``); an interval counts when both
    ends are used, it lies inside the estimate's span and it is at most ``max_interval_s`` long (default
    1.5 × the median interval: a gap is not an interval)."""
    est_time = np.asarray(est_time, float)
    enu = reference_enu(np.asarray(ref_lat, float), np.asarray(ref_lon, float), np.asarray(ref_height, float))
    t0, t1, d = _intervals(ref_time, enu, use, (est_time[0], est_time[-1]), max_interval_s)
    return IntervalVelocity(t0, t1, d, interval_means(est_time, est_vel, t0, t1) - d)


def velocity_lateness(series_time, series_vel, ref_time, ref_lat, ref_lon, ref_height, use=None,
                      max_lag_s: float = 0.4, step_s: float = 0.005,
                      max_interval_s: float | None = None) -> tuple[float, float]:
    """Lateness L [s] of a velocity series against the reference's positions (module doc): the L that
    minimises the horizontal RMS of mean(series over [t_{k−1} + L, t_k + L]) − d_k, on a grid of
    ±``max_lag_s`` in ``step_s`` steps refined by a parabola through the three best points. Returns (L, the
    RMS at L [m/s]). L > 0: the series describes at t what the positions show at t − L. Intervals whose
    shifted window leaves the series' span are dropped at every L alike."""
    st = np.asarray(series_time, float)
    sv = np.asarray(series_vel, float)
    enu = reference_enu(np.asarray(ref_lat, float), np.asarray(ref_lon, float), np.asarray(ref_height, float))
    span = (st[0] + max_lag_s, st[-1] - max_lag_s)
    t0, t1, d = _intervals(ref_time, enu, use, span, max_interval_s)
    if t0.size < 3:
        raise ValueError("fewer than 3 reference intervals inside the series' span")
    lags = np.arange(-max_lag_s, max_lag_s + 0.5 * step_s, step_s)
    cum = _cumulative(st, sv[:, :2])
    cost = np.empty(lags.size)
    for i, lag in enumerate(lags):
        m = _window_means(st, cum, t0 + lag, t1 + lag)
        cost[i] = np.mean(np.sum((m - d[:, :2]) ** 2, axis=1))
    lag, c_min, _ = parabola_minimum(lags, cost)
    return lag, float(np.sqrt(max(c_min, 0.0)))


def three_cornered_hat(a, b, r) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Error variances (σ_a², σ_b², σ_r²) per column of three estimates (K, ...) of the same quantity with
    independent errors (module doc), from the sample variances of their pairwise differences (rows with a
    NaN in any of the three left out). A negative value (sampling noise about a small variance) is
    returned as it is."""
    a, b, r = (np.asarray(x, float) for x in (a, b, r))
    ok = np.isfinite(a) & np.isfinite(b) & np.isfinite(r)
    if a.ndim > 1:
        ok = ok.all(axis=tuple(range(1, a.ndim)))
    var_ar, var_br, var_ab = (np.var(x[ok], axis=0, ddof=1) for x in (a - r, b - r, a - b))
    return (0.5 * (var_ar + var_ab - var_br), 0.5 * (var_br + var_ab - var_ar),
            0.5 * (var_ar + var_br - var_ab))
