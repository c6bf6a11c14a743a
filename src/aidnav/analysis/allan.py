"""Allan deviation of inertial sensor outputs: overlapping ADEV by one fused numba pass over the phase.

Units: the deviation has the units of the rate samples given (e.g. rad/s for gyros, m/s² for
accelerometers); τ in seconds. For white rate noise of density q (e.g. ARW in rad/√s) the ADEV is
q/√τ; noise-term fitting (ARW, bias instability, RRW) is :mod:`aidnav.analysis.noise_fit`.

Method (IEEE Std 1139 / NIST SP 1065 eq. 11). The phase x (the running integral of the rates, mean removed,
a leading 0: N + 1 values) is formed once per channel; then one pass over it accumulates, for every
cluster size m at once, the sum of the squared second differences (x[k+2m] − 2x[k+m] + x[k])², k = 0 …
N − 2m:

    σ²(mτ₀) = Σ_k (x[k+2m] − 2x[k+m] + x[k])² / (2 (mτ₀)² (N + 1 − 2m)).

The pass goes through the phase in blocks (16384 samples); inside a block every m reads three contiguous
slices (its three lags), which stay in the cache for the m that share them, so the phase is read from
memory about once per distinct lag, never copied, and no full-length temporary is made (allantools forms
four per τ). Each block's partial sum is added to the running total of its m with Neumaier's compensated
summation, so the result does not depend on the summation order to within a few units of the last place:
the same numbers as ``allantools.oadev`` (its τ lists, its rounding of τ to multiples of 1/fs, its
dropping of τ with fewer than 2 terms) to ~1e-15 relative (tests/analysis/test_allan.py), without
allantools at run time.
"""

from __future__ import annotations

import os
import queue
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from aidnav.data import ImuData
from aidnav.jit import njit
from aidnav.units import DEG_H, UG

#: samples per block of the fused pass: three slices of every cluster size stay in the L2 cache
_BLOCK = 16384


# ------------------------------------------------------------------------------------------ kernels
@njit(cache=True, nogil=True)
def _phase_nb(col, mean, dt, out):
    """out[0] = 0, out[k + 1] = dt · Σ_{i≤k} (col[i] − mean): the phase as allantools' ``frequency2phase``
    forms it (the same sequential running sum, so the same numbers to the last bit)."""
    s = 0.0
    out[0] = 0.0
    for k in range(col.shape[0]):
        s += col[k] - mean
        out[k + 1] = s * dt
    return out


@njit(cache=True, nogil=True, fastmath={"reassoc", "nsz"})
def _block_sum(x0, x1, x2):
    """Σ_k ((x2[k] − 2 x1[k]) + x0[k])² over one block (reassociation allowed: the vectorised sum;
    contiguous slices, so the loads are vector loads)."""
    a = 0.0
    for k in range(x0.shape[0]):
        v = (x2[k] - 2.0 * x1[k]) + x0[k]
        a += v * v
    return a


@njit(cache=True, nogil=True)
def _oadev_sums(x, ms):
    """Σ_{k=0}^{P−2m−1} (x[k+2m] − 2x[k+m] + x[k])² for every m of ``ms`` (ascending, P − 2m ≥ 1) in one
    blocked pass over the phase x (P,); the block sums are added with Neumaier's compensation."""
    P = x.shape[0]
    J = ms.shape[0]
    s = np.zeros(J)
    c = np.zeros(J)
    if J == 0:
        return s
    kmax = P - 2 * ms[0]
    for k0 in range(0, kmax, _BLOCK):
        for j in range(J):
            m = ms[j]
            hi = min(k0 + _BLOCK, P - 2 * m)
            if hi <= k0:  # the larger m have fewer terms: none left in this block
                break
            part = _block_sum(x[k0:hi], x[k0 + m:hi + m], x[k0 + 2 * m:hi + 2 * m])
            t = s[j] + part
            if abs(s[j]) >= abs(part):
                c[j] += (s[j] - t) + part
            else:
                c[j] += (part - t) + s[j]
            s[j] = t
    return s + c


# --------------------------------------------------------------------------------------- τ lists
def _cluster_sizes(n_phase: int, fs: float, taus) -> np.ndarray:
    """Cluster sizes m (ascending, unique) for the τ request, as allantools' ``tau_generator`` makes them
    from a phase of ``n_phase`` points: "octave" 1, 2, 4, …; "decade" 1, 2, 4, 10, 20, 40, …; "log10"
    about 10 per decade; "all" 1 … n_phase; or τ [s] rounded to multiples of 1/fs. Only 0 < m < n_phase."""
    rate = float(fs)
    if taus is None or (isinstance(taus, list) and not taus):
        taus = "octave"
    if isinstance(taus, str):
        if taus == "all":
            t = (1.0 / rate) * np.linspace(1.0, n_phase, n_phase)
        elif taus == "octave":
            maxn = np.floor(np.log2(n_phase))
            t = (1.0 / rate) * np.logspace(0, int(maxn), int(maxn + 1), base=2.0)
        elif taus == "log10":
            maxn = np.log10(n_phase)
            t = (1.0 / rate) * np.logspace(0, maxn, int(10 * maxn), base=10.0)
        elif taus == "decade":
            maxn = np.floor(np.log10(n_phase))
            t = np.array([f * (1.0 / rate) * 10.0**k for k in range(int(maxn + 1)) for f in (1.0, 2.0, 4.0)])
        else:
            raise ValueError(f"allan_deviation: taus {taus!r}: expected 'octave', 'decade', 'log10', 'all' "
                             "or averaging times [s]")
    else:
        t = np.asarray(taus, dtype=float).ravel()
        if not np.all(np.isfinite(t)):
            raise ValueError("allan_deviation: taus contain NaN or inf")
    m = np.round(t * rate)
    m = np.unique(m[(m < n_phase) & (m > 0)])
    return m


def allan_deviation(rate_samples, fs: float, taus=None, workers: int | None = None,
                    work: np.ndarray | None = None, check_finite: bool = True):
    """Overlapping Allan deviation of uniformly sampled rate data.

    Parameters
    ----------
    rate_samples : (N,) or (N, k) rate samples in any unit u (columns are independent channels).
    fs : sample rate [Hz].
    taus : averaging times [s] (array), or "octave" / "decade" / "log10" / "all" (allantools' lists);
        None = "octave" (τ = 2^j / fs).
    workers : threads for the channels (None: as many as CPUs, at most k); the kernels release the GIL.
    work : float64 array of at least N + 1 values for the phase (one thread; a caller that computes many
        deviations passes one array to all, so that the memory is not asked of the system each time).
    check_finite : False when the caller has checked the samples already (a pass over them less).

    Returns
    -------
    taus : (M,) averaging times used [s] (requested values rounded to multiples of 1/fs, those with
        fewer than 2 terms dropped).
    adev : (M,) or (M, k) overlapping Allan deviation [u].
    adev_err : same shape, the simple error estimate adev/√n_clusters [u] (a rough 1σ, as allantools
        gives it; the chi-square intervals of :mod:`aidnav.analysis.noise_fit` are the proper ones).
    n_clusters : (M,) number of overlapping second-difference terms behind each value (N + 1 − 2m).

    One fused pass per channel over its phase (module docstring): the numbers of ``allantools.oadev``
    (``data_type="freq"``) to ~1e-15 relative.
    """
    x = np.asarray(rate_samples, dtype=float)
    one = x.ndim == 1
    x2 = x[:, None] if one else x
    if x2.ndim != 2 or x2.shape[0] < 3:
        raise ValueError("allan_deviation: need (N,) or (N, k) samples with N >= 3")
    if not fs > 0:
        raise ValueError("allan_deviation: fs must be > 0")
    if check_finite and not np.all(np.isfinite(x2)):
        raise ValueError("allan_deviation: samples contain NaN or inf")
    n_phase = x2.shape[0] + 1
    m = _cluster_sizes(n_phase, fs, taus)
    n = n_phase - 2 * m
    m = m[n > 1]  # allantools drops τ with fewer than 2 terms
    n = n[n > 1]
    if not len(m):
        raise ValueError(f"allan_deviation: no averaging time with at least 2 terms in {x2.shape[0]} samples")
    ms = m.astype(np.int64)
    k = x2.shape[1]
    dt = 1.0 / float(fs)

    nw = max(1, min(k, workers if workers is not None else (os.cpu_count() or 1)))
    bufs: queue.SimpleQueue = queue.SimpleQueue()  # one phase array per thread, reused for its channels
    for _ in range(nw):
        bufs.put(work if nw == 1 and work is not None and len(work) >= n_phase else None)

    def one_channel(c):
        col = x2[:, c]  # a strided column of (N, k): read in place, not copied
        buf = bufs.get()
        if buf is None:
            buf = np.empty(n_phase)
        try:
            ph = _phase_nb(col, float(np.mean(col)), dt, buf[:n_phase])
            return _oadev_sums(ph, ms)
        finally:
            bufs.put(buf)

    if nw == 1:
        sums = [one_channel(c) for c in range(k)]
    else:
        with ThreadPoolExecutor(max_workers=nw) as ex:
            sums = list(ex.map(one_channel, range(k)))
    s = np.stack(sums, -1)
    adev = np.sqrt(s / (2.0 * n[:, None])) / m[:, None] * float(fs)
    err = adev / np.sqrt(n[:, None])
    if one:
        adev, err = adev[:, 0], err[:, 0]
    return m / float(fs), adev, err, n.astype(np.int64)


def imu_allan(imu: ImuData, taus=None, max_gap_ratio: float = 1.5) -> dict:
    """Allan deviation of the 6 IMU axes from increments divided by their intervals.

    Parameters
    ----------
    imu : increments Δθ [rad], Δv [m/s], body RFU; must be uniformly sampled (a gap longer than
        ``max_gap_ratio`` × the median interval raises ValueError naming the count: ADEV needs uniform data).
    taus : as :func:`allan_deviation`.

    Returns
    -------
    dict with ``taus_s`` (M,) [s]; ``gyro_adev_rad_s``, ``gyro_adev_err_rad_s`` (M, 3) [rad/s];
    ``accel_adev_m_s2``, ``accel_adev_err_m_s2`` (M, 3) [m/s²]; the same in boundary units
    ``gyro_adev_deg_h`` [deg/h] and ``accel_adev_ug`` [µg]; ``n_clusters`` (M,); ``fs_hz``.
    """
    t = imu.time
    if len(t) < 3:
        raise ValueError("imu_allan: need at least 3 samples")
    dt = np.diff(np.concatenate(([imu.t0], t))) if imu.t0 is not None else np.diff(t, prepend=2 * t[0] - t[1])
    med = float(np.median(dt))
    gaps = int(np.sum(dt > max_gap_ratio * med))
    if gaps or np.any(dt <= 0):
        raise ValueError(f"imu_allan: {gaps} gap(s) longer than {max_gap_ratio} x the median interval "
                         f"{med:g} s (or non-increasing times); ADEV needs uniform samples")
    fs = 1.0 / med
    rates = np.concatenate((imu.dtheta, imu.dv), axis=1) / dt[:, None]
    taus_s, adev, err, n = allan_deviation(rates, fs, taus)
    return {
        "taus_s": taus_s,
        "gyro_adev_rad_s": adev[:, :3], "gyro_adev_err_rad_s": err[:, :3],
        "accel_adev_m_s2": adev[:, 3:], "accel_adev_err_m_s2": err[:, 3:],
        "gyro_adev_deg_h": adev[:, :3] / DEG_H, "accel_adev_ug": adev[:, 3:] / UG,
        "n_clusters": n, "fs_hz": fs,
    }


__all__ = ["allan_deviation", "imu_allan"]
