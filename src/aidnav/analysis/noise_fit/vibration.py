"""Vibration: sample spread against the fitted white noise, and the dominant frequency (Welch PSD peak).

Vibration (zero-mean, a large sample spread, often at one frequency: an engine) is not motion: it is
reported per axis and shows in the Allan deviation at the shortest τ, which the fit then leaves out.
"""

from __future__ import annotations

import math

import numpy as np

from aidnav.analysis.noise_fit.results import AxisFit, json_float
from aidnav.analysis.noise_fit.static import window_stats
from aidnav.units import DEG


def psd_peak(x: np.ndarray, fs: float, f_min: float = 1.0, nseg: int = 512, max_segs: int = 256):
    """Dominant frequency [Hz] above ``f_min`` of one channel (Welch: Hann windows of ``nseg`` samples, at
    most ``max_segs`` of them spread over the record) and the fraction of the variance above ``f_min``
    that lies within ±1 Hz of it. (nan, nan) when the record is too short."""
    x = np.asarray(x, float)
    nseg = min(nseg, 1 << int(math.floor(math.log2(max(len(x), 2)))))
    if nseg < 32:
        return math.nan, math.nan
    n_avail = (len(x) - nseg) // (nseg // 2) + 1
    starts = np.linspace(0, len(x) - nseg, min(max_segs, n_avail)).astype(np.int64)
    seg = x[starts[:, None] + np.arange(nseg)]
    seg = seg - seg.mean(axis=1, keepdims=True)
    p = (np.abs(np.fft.rfft(seg * np.hanning(nseg), axis=1)) ** 2).mean(axis=0)
    f = np.fft.rfftfreq(nseg, 1.0 / fs)
    hi = f > f_min
    if not hi.any() or p[hi].sum() <= 0:
        return math.nan, math.nan
    fp = float(f[hi][np.argmax(p[hi])])
    share = float(p[hi & (np.abs(f - fp) <= 1.0)].sum() / p[hi].sum())
    return fp, share


VIBRATION_RATIO = 2.0  #: sample spread above this × the white noise's (N·√fs) is reported as vibration
#: ... and so is a spectrum with more than this share of its variance above 1 Hz within ±1 Hz of its peak
#: (white noise: about 2 Hz / (fs/2), 4% at 100 Hz; an engine's vibration: most of it)
VIBRATION_SHARE = 0.25


def vibration_report(rates, fs: float, axes: list[AxisFit], sensor: dict | None = None) -> dict:
    """Spread of the samples against the fitted white noise, per axis: vibration, reported.

    rates : (M, 6) analysed uniform rates [rad/s, m/s²] at ``fs``; axes : the fits (their white term N);
    sensor : optional {"std": (6,), "peak_hz": (6,), "share": (6,), "what": str} of the sensor's own
    samples when they differ from the analysed rates (resampled or trapezoid increments).

    White rate noise of density N sampled at fs has a standard deviation N·√fs. A sample spread well above
    it (ratio > ``VIBRATION_RATIO``; N: the fitted value or its upper bound), or a spectrum concentrated at
    one frequency (share > ``VIBRATION_SHARE``), is vibration (engine, pumps, fans): zero-mean, at
    frequencies above the τ the fit uses, so it shows in the Allan deviation at the shortest τ (a hump
    near τ ~ 1/(2f), then a −1 slope) and not in the fitted terms. Reported per axis: std [deg/s | m/s²]
    of the analysed rates and of the sensor samples, the white-noise std, their ratio, the dominant
    frequency above 1 Hz and the share of the variance within ±1 Hz of it."""
    y = np.ascontiguousarray(rates, dtype=float)
    _, std_a = window_stats(y, len(y), 1)
    std_a = std_a[0]
    if sensor is None:
        std_s = std_a
        pk = [psd_peak(y[:, c], fs) for c in range(6)]
        what = "analysed rates (the sensor's samples)"
    else:
        std_s = np.asarray(sensor["std"], float)
        pk = list(zip(sensor["peak_hz"], sensor["share"], strict=True))
        what = sensor["what"]
    out = {"samples": what, "ratio_threshold": VIBRATION_RATIO, "axes": {}, "detected": []}
    for c, a in enumerate(axes):
        g = a.sensor == "gyro"
        f, unit = (DEG, "deg_s") if g else (1.0, "m_s2")
        w = a.terms["white"]
        n_ref = w.value if w.fitted else (w.upper if w.upper is not None else math.sqrt(max(a.coef[1], 0.0)))
        white_std = n_ref * math.sqrt(fs)
        ratio = float(std_s[c] / white_std) if white_std > 0 else None
        share = pk[c][1]
        vib = bool((ratio is not None and ratio > VIBRATION_RATIO)
                   or (math.isfinite(share) and share > VIBRATION_SHARE))
        d = {f"std_{unit}": float(std_s[c] / f), f"analysed_std_{unit}": float(std_a[c] / f),
             f"white_noise_std_{unit}": float(white_std / f), "ratio": ratio,
             "peak_hz": json_float(pk[c][0]), "peak_share": json_float(share), "vibration": vib}
        out["axes"][a.axis] = d
        if d["vibration"]:
            out["detected"].append(a.axis)
    return out


def vibration_text(vib: dict) -> str:
    parts = []
    for ax in vib["detected"]:
        d = vib["axes"][ax]
        unit = "deg/s" if ax.startswith("gyro") else "m/s2"
        k = "std_deg_s" if ax.startswith("gyro") else "std_m_s2"
        pk = "" if d["peak_hz"] is None else \
            f" at {d['peak_hz']:.3g} Hz ({d['peak_share']:.0%} of it within 1 Hz)"
        rt = "" if d["ratio"] is None else f", {d['ratio']:.3g} x the white noise"
        parts.append(f"{ax} {d[k]:.3g} {unit}{pk}{rt}")
    return ("vibration (zero-mean, above the fitted tau; it shows as the hump and -1 slope of the Allan "
            f"deviation at the shortest tau, not in the fitted terms), std of the {vib['samples']}: "
            + "; ".join(parts))
