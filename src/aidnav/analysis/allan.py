"""Allan deviation of inertial sensor outputs (overlapping ADEV via ``allantools.oadev``).

Units: the deviation has the units of the rate samples given (e.g. rad/s for gyros, m/s² for
accelerometers); τ in seconds. For white rate noise of density q (e.g. ARW in rad/√s) the ADEV is
q/√τ; noise-term fitting (ARW, bias instability, RRW from the slopes) is not done here.
"""

from __future__ import annotations

import numpy as np

from aidnav.data import ImuData
from aidnav.nav.earth import G0

_DEG_H = np.pi / 180.0 / 3600.0


def allan_deviation(rate_samples, fs: float, taus=None):
    """Overlapping Allan deviation of uniformly sampled rate data.

    Parameters
    ----------
    rate_samples : (N,) or (N, k) rate samples in any unit u (columns are independent channels).
    fs : sample rate [Hz].
    taus : averaging times [s] (array), or "octave" / "decade" / "all" (passed to allantools);
        None = "octave" (τ = 2^j / fs).

    Returns
    -------
    taus : (M,) averaging times used [s] (requested values rounded to multiples of 1/fs, those with
        fewer than 2 terms dropped).
    adev : (M,) or (M, k) overlapping Allan deviation [u].
    adev_err : same shape, allantools' simple error estimate adev/√n_clusters [u] (a rough 1σ; use
        ``allantools.edf_greenhall`` + ``allantools.confidence_interval`` for proper chi-square bounds).
    n_clusters : (M,) number of overlapping second-difference terms behind each value.
    """
    import allantools

    x = np.asarray(rate_samples, dtype=float)
    one = x.ndim == 1
    x2 = x[:, None] if one else x
    if x2.ndim != 2 or x2.shape[0] < 3:
        raise ValueError("allan_deviation: need (N,) or (N, k) samples with N >= 3")
    if not fs > 0:
        raise ValueError("allan_deviation: fs must be > 0")
    if taus is None:
        taus = "octave"
    elif not isinstance(taus, str):
        taus = np.asarray(taus, dtype=float)
    out_t = None
    devs, errs = [], []
    ns = None
    for c in range(x2.shape[1]):
        t, d, e, n = allantools.oadev(x2[:, c], rate=fs, data_type="freq", taus=taus)
        if out_t is None:
            out_t, ns = np.asarray(t, dtype=float), np.asarray(n).astype(np.int64)
        devs.append(d)
        errs.append(e)
    adev = np.stack(devs, -1)
    err = np.stack(errs, -1)
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


__all__ = ["allan_deviation", "imu_allan"]
