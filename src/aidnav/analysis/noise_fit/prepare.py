"""Data preparation: uniform rates from increments (gaps cut, jitter resampled), trapezoid inversion.

Uniform sampling. The Allan deviation needs uniform samples. Increments with their own Δt (jittered time
stamps) are put on a uniform grid of the median interval by cumulative-sum interpolation: the cumulative
angle (velocity) at the sample times is interpolated linearly (constant rate within each interval, as the
increment model says) to the grid points and differenced, so no angle is lost or counted twice. Averaging
mixes neighbouring samples, which lowers the Allan variance at m grid intervals by about 1/(6m) of its white
part; when a log is resampled the fit therefore starts at the m where that bias is below a quarter of the
estimate's scatter (:func:`resampled_min_m`). A gap (an interval longer than 1.5 × the median) is never
bridged: the longest gap-free part is analysed and the gap reported.
"""

from __future__ import annotations

import numpy as np

from aidnav.data import ImuData

#: first cluster size fitted when the log was resampled onto a uniform grid: linear interpolation of the
#: cumulative sums mixes neighbouring samples and lowers the Allan variance by about 1/(6m) of its white
#: part at m intervals (0.26% at m = 64, below the scatter of a 2-h log there)
RESAMPLED_MIN_M = 64  #: (at most: shorter logs start lower, see resampled_min_m)


# ---------------------------------------------------------------------------- data preparation
def uniform_rates(imu: ImuData, max_gap_ratio: float = 1.5, jitter_tol: float = 1e-3):
    """Uniformly sampled rates from increments with their own intervals.

    Returns (rates (M, 6) [rad/s, m/s²] over uniform intervals of dt, dt [s], t_start [s], resampled
    (bool), notes). Gaps (intervals > ``max_gap_ratio`` × median): the longest gap-free part is used and
    the gaps reported in ``notes``. Jitter (any interval off the median by more than ``jitter_tol``
    relative): increments are averaged onto the uniform grid by cumulative-sum interpolation.
    Memory: one (M, 6) output array and a few (M,) vectors (no stacked copies of the increments).
    """
    t = np.asarray(imu.time, float)
    if len(t) < 3:
        raise ValueError("characterise: need at least 3 IMU samples")
    t0 = imu.t0 if imu.t0 is not None else 2 * t[0] - t[1]
    dt = np.empty(len(t))
    dt[0] = t[0] - t0
    np.subtract(t[1:], t[:-1], out=dt[1:])
    if np.any(dt <= 0):
        raise ValueError("characterise: sample times are not strictly increasing")
    med = float(np.median(dt))
    notes: list[str] = []
    a, b = 0, len(t)
    t_first = float(t0)
    gap = dt > max_gap_ratio * med
    if gap.any():
        # segments between gaps: a gap interval k starts a new segment at k + 1 (the sample over the gap
        # itself is dropped: its increment spans the gap)
        starts = np.r_[0, np.flatnonzero(gap) + 1]
        ends = np.r_[np.flatnonzero(gap), len(t)]
        lens = ends - starts
        j = int(np.argmax(lens))
        a, b = int(starts[j]), int(ends[j])
        big = np.flatnonzero(gap)
        worst = big[np.argmax(dt[big])]
        t_first = float(t[a - 1]) if a > 0 else float(t0)
        notes.append(f"{len(big)} gap(s) in the log (intervals longer than {max_gap_ratio:g} x the median "
                     f"{med:.6g} s; the longest {dt[worst]:.6g} s ending at t = {t[worst]:.3f} s): analysed "
                     f"the longest gap-free part t = {t_first:.3f}-{t[b - 1]:.3f} s "
                     f"({100.0 * (b - a) / len(t):.1f}% of the samples); gaps are never bridged")
        if b - a < 3:
            raise ValueError("characterise: no gap-free part with at least 3 samples")
        dt = dt[a:b]
        med = float(np.median(dt))
    rel = np.max(np.abs(dt - med)) / med
    n_in = b - a
    if rel <= jitter_tol:
        rates = np.empty((n_in, 6))
        np.divide(imu.dtheta[a:b], dt[:, None], out=rates[:, :3])
        np.divide(imu.dv[a:b], dt[:, None], out=rates[:, 3:])
        return rates, med, t_first, False, notes
    # cumulative-sum interpolation onto the uniform grid t_start + j·med (mean rate removed first, for
    # precision of the running sums; added back after), one channel at a time
    edges = np.empty(n_in + 1)
    edges[0] = t_first
    edges[1:] = t[a:b]
    span = edges[-1] - edges[0]
    n = int(np.floor(span / med + 1e-9))
    grid = edges[0] + med * np.arange(n + 1)
    rates = np.empty((n, 6))
    cum = np.empty(n_in + 1)
    cum[0] = 0.0
    for c in range(6):
        inc = imu.dtheta[a:b, c] if c < 3 else imu.dv[a:b, c - 3]
        mean_rate = inc.sum() / span
        np.cumsum(inc - mean_rate * dt, out=cum[1:])
        cg = np.interp(grid, edges, cum)
        rates[:, c] = np.diff(cg) / med + mean_rate
    notes.append(f"time stamps jitter by up to {100 * rel:.2g}% of the median interval {med:.6g} s: "
                 f"increments averaged onto a uniform {1 / med:.6g} Hz grid by cumulative-sum "
                 "interpolation; the shortest tau are not fitted (resampling lowers them), so quantisation "
                 "cannot be resolved")
    return rates, med, t_first, True, notes


def uniform_interval(dt: np.ndarray, max_gap_ratio: float = 1.5, jitter_tol: float = 1e-3) -> float | None:
    """The median of the sample intervals ``dt`` [s] when :func:`uniform_rates` (same tolerances) would
    take them as they are, without gap or jitter (its rates are then the increments / their intervals,
    its interval that median); None otherwise. ``dt`` is reordered (its median is taken in place)."""
    lo, hi = float(dt.min()), float(dt.max())
    med = float(np.median(dt, overwrite_input=True))
    if not (lo > 0 and med > 0) or hi > max_gap_ratio * med:
        return None
    # = max |dt − med| / med (the rounded difference is monotonic in dt)
    return med if max(hi - med, med - lo) / med <= jitter_tol else None


def resampled_min_m(n: int) -> int:
    """First cluster size fitted on a resampled log of ``n`` samples.

    Cumulative-sum resampling lowers the white part of the Allan variance at m intervals by about
    1/(6m); the estimate at m scatters by about √(2/ν) with ν ≈ 1.5 n/m degrees of freedom (white noise).
    The bias stays below a quarter of that scatter from m³ ≥ n/3 on: the smallest power of two with it,
    at least 8 (a 2% bias) and at most ``RESAMPLED_MIN_M`` (64: a 2-h log at 100 Hz)."""
    m = 8
    while m < RESAMPLED_MIN_M and m**3 < n / 3.0:
        m *= 2
    return m


def trapezoid_samples(imu: ImuData) -> np.ndarray:
    """The sensor's point samples (N, 6) [rad/s, m/s²] behind trapezoid increments.

    Raw logs of point-sampled rates are read as Δθ_k = ½(ω_{k−1} + ω_k)(t_k − t_{k−1}) and Δθ_0 = ω_0
    (t_0 − t0) (:func:`aidnav.io.logs.read_rtklibexplorer_imu`); the exact inverse is
    ω_k = 2Δθ_k/Δt_k − ω_{k−1}, i.e. ω_k = (−1)^k Σ_{j≤k} (−1)^j r_j with r_0 = Δθ_0/Δt_0 and
    r_j = 2Δθ_j/Δt_j (rounding error ~1e-16 × |r| × √k). The trapezoid averages neighbouring samples
    (gain cos(π f Δt) at frequency f): a vibration near the Nyquist frequency is much weaker in the
    increments than in the sensor's output, which is what a data sheet or a vibration spec quotes."""
    t = np.asarray(imu.time, float)
    dt = np.diff(t, prepend=imu.t0 if imu.t0 is not None else 2 * t[0] - t[1])
    out = np.empty((len(t), 6))
    sign = np.where(np.arange(len(t)) % 2 == 0, 1.0, -1.0)
    for c in range(6):
        inc = imu.dtheta[:, c] if c < 3 else imu.dv[:, c - 3]
        r = 2.0 * inc / dt
        r[0] = inc[0] / dt[0]
        out[:, c] = sign * np.cumsum(sign * r)
    return out
