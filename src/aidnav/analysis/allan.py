"""Allan deviation of inertial sensor outputs (overlapping ADEV via ``allantools.oadev``).

Units: the deviation has the units of the rate samples given (e.g. rad/s for gyros, m/s² for
accelerometers); τ in seconds. For white rate noise of density q (e.g. ARW in rad/√s) the ADEV is
q/√τ; noise-term fitting (ARW, bias instability, RRW from the slopes) is not done here.
"""

from __future__ import annotations

import sys
import threading
from contextlib import contextmanager

import numpy as np

from aidnav.data import ImuData
from aidnav.nav.earth import G0

_DEG_H = np.pi / 180.0 / 3600.0


_ALLOC_LOCK = threading.Lock()
_ALLOC_DEPTH = 0


@contextmanager
def reuse_freed_memory():
    """Let glibc's malloc keep and reuse large freed blocks inside the block (restored after).

    allantools forms four full-length temporaries per τ; by default glibc serves each from a fresh
    ``mmap`` and unmaps it when freed, so every one is paid again in page faults (about a third of the
    time of an Allan deviation of 3.6 million samples). Raising the mmap and trim thresholds keeps them in
    the heap for reuse. Re-entrant and thread-safe; on exit the defaults (128 KiB) are set back and the
    heap is trimmed. A no-op where the C library is not glibc."""
    global _ALLOC_DEPTH
    libc = _glibc()
    if libc is None:
        yield
        return
    with _ALLOC_LOCK:
        _ALLOC_DEPTH += 1
        if _ALLOC_DEPTH == 1:
            libc.mallopt(_M_MMAP_THRESHOLD, 1 << 30)
            libc.mallopt(_M_TRIM_THRESHOLD, 1 << 30)
    try:
        yield
    finally:
        with _ALLOC_LOCK:
            _ALLOC_DEPTH -= 1
            if _ALLOC_DEPTH == 0:
                libc.mallopt(_M_MMAP_THRESHOLD, 128 * 1024)
                libc.mallopt(_M_TRIM_THRESHOLD, 128 * 1024)
                libc.malloc_trim(0)


_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc malloc.h
_LIBC: list = []


def _glibc():
    if not _LIBC:
        lib = None
        if sys.platform.startswith("linux"):
            try:
                import ctypes

                cand = ctypes.CDLL("libc.so.6")
                if all(hasattr(cand, f) for f in ("mallopt", "malloc_trim", "gnu_get_libc_version")):
                    lib = cand
            except OSError:
                lib = None
        _LIBC.append(lib)
    return _LIBC[0]


def _phase(col: np.ndarray, fs: float, out: np.ndarray) -> np.ndarray:
    """Phase (running integral) of one rate channel, as allantools' ``frequency2phase`` makes it: mean
    removed (precision of the running sum), cumulative sum × 1/fs, a leading 0 (N + 1 values). Written into
    ``out`` (N + 1,) without further temporaries."""
    np.subtract(col, np.mean(col), out=out[1:])
    np.cumsum(out[1:], out=out[1:])
    out[1:] *= 1.0 / float(fs)
    out[0] = 0.0
    return out


def allan_deviation(rate_samples, fs: float, taus=None, workers: int | None = None):
    """Overlapping Allan deviation of uniformly sampled rate data.

    Parameters
    ----------
    rate_samples : (N,) or (N, k) rate samples in any unit u (columns are independent channels).
    fs : sample rate [Hz].
    taus : averaging times [s] (array), or "octave" / "decade" / "all" (passed to allantools);
        None = "octave" (τ = 2^j / fs).
    workers : threads for the channels (None: as many as CPUs, at most k). allantools' numpy kernels
        release the GIL, so channels run in parallel.

    Returns
    -------
    taus : (M,) averaging times used [s] (requested values rounded to multiples of 1/fs, those with
        fewer than 2 terms dropped).
    adev : (M,) or (M, k) overlapping Allan deviation [u].
    adev_err : same shape, allantools' simple error estimate adev/√n_clusters [u] (a rough 1σ; use
        ``allantools.edf_greenhall`` + ``allantools.confidence_interval`` for proper chi-square bounds).
    n_clusters : (M,) number of overlapping second-difference terms behind each value.

    The deviations are computed by ``allantools.oadev``. Each channel's phase (the running integral of
    the rates, mean removed) is formed here once, in place, and given to allantools as ``data_type="phase"``:
    the same numbers as ``data_type="freq"`` (which forms the same phase with several full-length
    temporaries per call), with less memory traffic.
    """
    import os
    from concurrent.futures import ThreadPoolExecutor

    import allantools

    x = np.asarray(rate_samples, dtype=float)
    one = x.ndim == 1
    x2 = x[:, None] if one else x
    if x2.ndim != 2 or x2.shape[0] < 3:
        raise ValueError("allan_deviation: need (N,) or (N, k) samples with N >= 3")
    if not fs > 0:
        raise ValueError("allan_deviation: fs must be > 0")
    if not np.all(np.isfinite(x2)):
        raise ValueError("allan_deviation: samples contain NaN or inf")
    if taus is None:
        taus = "octave"
    elif not isinstance(taus, str):
        taus = np.asarray(taus, dtype=float)
    k = x2.shape[1]

    def one_channel(c):
        ph = _phase(x2[:, c], fs, np.empty(x2.shape[0] + 1))
        return allantools.oadev(ph, rate=fs, data_type="phase", taus=taus)

    nw = max(1, min(k, workers if workers is not None else (os.cpu_count() or 1)))
    with reuse_freed_memory():
        if nw == 1:
            res = [one_channel(c) for c in range(k)]
        else:
            with ThreadPoolExecutor(max_workers=nw) as ex:
                res = list(ex.map(one_channel, range(k)))
    out_t = np.asarray(res[0][0], dtype=float)
    ns = np.asarray(res[0][3]).astype(np.int64)
    adev = np.stack([r[1] for r in res], -1)
    err = np.stack([r[2] for r in res], -1)
    if one:
        adev, err = adev[:, 0], err[:, 0]
    return out_t, adev, err, ns


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
        "gyro_adev_deg_h": adev[:, :3] / _DEG_H, "accel_adev_ug": adev[:, 3:] / (G0 * 1e-6),
        "n_clusters": n, "fs_hz": fs,
    }


__all__ = ["allan_deviation", "imu_allan", "reuse_freed_memory"]
