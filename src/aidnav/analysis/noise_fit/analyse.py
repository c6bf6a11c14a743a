"""The characterisation of rates and of IMU logs: static check, Allan deviation and fit per axis, vibration.

Speed. The axes run in threads, each Allan deviation (:func:`aidnav.analysis.allan.allan_deviation`, one
fused pass over the phase) followed by its fit (the numba kernels release the GIL).
"""

from __future__ import annotations

import math
import os
import queue
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from aidnav.analysis.allan import allan_deviation
from aidnav.analysis.noise_fit.fit import MIN_CLUSTERS, MIN_FULL_POINTS, fit_allan
from aidnav.analysis.noise_fit.model import AXES
from aidnav.analysis.noise_fit.prepare import resampled_min_m, trapezoid_samples, uniform_rates
from aidnav.analysis.noise_fit.results import Characterisation, NotStaticError, TermEstimate
from aidnav.analysis.noise_fit.static import longest_static, static_check
from aidnav.analysis.noise_fit.timing import Stages
from aidnav.analysis.noise_fit.vibration import psd_peak, vibration_report, vibration_text
from aidnav.data import ImuData


def characterise_rates(rates, fs: float, t_start: float = 0.0, min_m: int = 1, check_static: bool = True,
                       notes: list[str] | None = None, resampled: bool = False,
                       white_only: bool | None = None, sensor: dict | None = None,
                       warnings: list[str] | None = None,
                       workers: int | None = None, time_origin: float = 0.0,
                       timings: dict | None = None, static_result: dict | None = None,
                       on_axis=None, work: np.ndarray | None = None) -> Characterisation:
    """Characterise uniformly sampled rates (the Python API on arrays).

    rates : (M, 6) gyro x, y, z [rad/s] then accel x, y, z [m/s²], body frame, uniform at ``fs`` [Hz]
    (sample k is the average over (t_start + k/fs, t_start + (k+1)/fs]).
    min_m : smallest cluster size fitted. check_static : raise :class:`NotStaticError` when
    :func:`static_check` finds motion (slow motion is kept, with a warning). white_only : see
    :func:`fit_allan`. sensor : statistics of the sensor's own samples for :func:`vibration_report`.
    workers : threads (None: one per CPU); each axis's Allan deviation and fit run together.
    time_origin : the static check's spans and messages are in seconds after it [s]
    (``static["time_origin_s"]``). timings : a dict that receives the wall time of the stages [s].
    static_result : :func:`static_check` of these very rates (same t_start and time_origin) when the caller
    has it already (it is not run again). on_axis : ``on_axis(c, axis_fit, duration_s)`` called (in the
    worker thread) as soon as axis c (0-5, ``AXES``) is fitted, before the vibration report (which may
    still change its quantisation term: see below); the figure's process of ``aidnav characterise``
    draws its panel meanwhile. work : a float64 array of at least M + 1 values that one thread takes for
    its Allan deviations' phase (memory the caller has no more use for: fresh memory costs page faults).
    Returns a :class:`Characterisation` (ADEV at octave-spaced τ = 2^j/fs and the fitted terms, SI).
    """
    y = np.asarray(rates, float)
    if y.ndim != 2 or y.shape[1] != 6:
        raise ValueError(f"characterise_rates: rates must be (M, 6), got {y.shape}")
    notes = list(notes or [])
    warns = list(warnings or [])
    n = len(y)
    dur = n / fs
    if n < 64:
        raise ValueError(f"characterise: only {n} samples ({dur:.3g} s); need at least 64")
    if not np.isfinite(y).all():
        raise ValueError("characterise_rates: rates contain NaN or inf")
    stg = Stages(timings)
    st = static_result if static_result is not None else static_check(y, fs, t_start - time_origin)
    st["time_origin_s"] = float(time_origin)
    if check_static and not st["usable"]:
        raise NotStaticError(st["message"])
    if st.get("note"):
        notes.append(st["note"])
    warns += st["warnings"]
    if st["disturbed"] and st["usable"]:
        notes.append(f"{st['disturbed']} of {st['windows']} one-second windows are disturbed (vibration or "
                     "handling); kept")
    stg.lap("static check")
    if white_only is None:
        n_fit = sum(1 for k in range(int(math.log2(n)) + 1) if 2**k >= min_m and n >= MIN_CLUSTERS * 2**k)
        white_only = n_fit < MIN_FULL_POINTS

    nw = max(1, min(6, workers if workers is not None else (os.cpu_count() or 1)))
    phases: queue.SimpleQueue = queue.SimpleQueue()  # the phase arrays of the threads, reused by the axes
    for i in range(nw):
        phases.put(work if i == 0 and work is not None and work.dtype == np.float64 and work.ndim == 1
                   and len(work) >= n + 1 else None)

    def one_axis(c):
        ph = phases.get()
        ph = np.empty(n + 1) if ph is None else ph
        try:
            taus, adev, _, _ = allan_deviation(y[:, c], fs, taus="octave", workers=1, work=ph,
                                               check_finite=False)  # y was checked above
        finally:
            phases.put(ph)
        a = fit_allan(taus, adev, n, fs, axis=AXES[c], min_m=min_m, white_only=white_only)
        if on_axis is not None:
            on_axis(c, a, dur)
        return a

    if nw == 1:
        axes = [one_axis(c) for c in range(6)]
    else:
        with ThreadPoolExecutor(max_workers=nw) as ex:
            axes = list(ex.map(one_axis, range(6)))
    stg.lap("Allan deviation + fit, per axis in threads")
    for a in axes:
        notes += a.notes
    t_fit = max(float(a.taus[a.used][-1]) for a in axes)
    if white_only:
        t0_fit = min(float(a.taus[a.used][0]) for a in axes)
        warns.append(f"white noise only: {dur:.3g} s of data resolve the white terms (ARW / VRW, fitted on "
                     f"tau {t0_fit:.3g}-{t_fit:.3g} s); the bias instability and the random walk are not "
                     f"resolvable in {dur:.3g} s (they need a log many times longer than their correlation "
                     "time): imu.yaml takes grade defaults for them")
    else:
        notes.append(f"{dur:.6g} s of data: terms whose Allan signature lies beyond tau ~ {t_fit:.4g} s (the "
                     f"longest tau with {MIN_CLUSTERS} independent clusters, the last one fitted) cannot be "
                     "resolved")
    vib = vibration_report(y, fs, axes, sensor)
    if vib["detected"]:
        warns.append(vibration_text(vib))
        for a in axes:  # with vibration, a slope −1 at the short τ is its tail, not quantisation
            qt = a.terms["quantisation"]
            if a.axis in vib["detected"] and qt.fitted:
                a.terms["quantisation"] = TermEstimate(
                    "not resolved", upper=qt.hi, note=f"the slope -1 part of the fit ({qt.value:.3g}) is the "
                    "vibration's tail, not quantisation; kept in the model as a nuisance")
    notes += [w for w in warns if w not in notes]
    stg.lap("vibration report")
    return Characterisation(axes=axes, fs_hz=float(fs), n_samples=n, duration_s=dur,
                            span_s=(float(t_start), float(t_start + dur)), resampled=resampled, static=st,
                            notes=notes, warnings=warns, vibration=vib, white_only=bool(white_only))


def characterise_imu(imu: ImuData, static: tuple[float | None, float | None] | None = None,
                     check_static: bool = True, increments: str = "interval",
                     workers: int | None = None, timings: dict | None = None,
                     on_axis=None) -> Characterisation:
    """Characterise an IMU log (increments with their own Δt; rates, any rate, jitter and gaps allowed).

    static : (start, end) [s] after the log's first time stamp (either None = open) to analyse only that
    part; None = the whole log. Gaps → the longest gap-free part (reported); jitter → cumulative-sum
    resampling (reported).

    Motion (check_static). The part is checked by :func:`static_check`. Motion (driving, turning,
    tilting: rates or tilts far above the sensor noise) is never analysed: the longest part without it is
    (the part chosen with ``static`` included), and the motion is reported with its time and size, as
    gaps are; with no part long enough, :class:`NotStaticError` names the spans. Slow motion (a small,
    short rotation or rocking, below ``MOTION_GYRO_DEG_S`` / ``MOTION_ANGLE_DEG`` / ``MOTION_ACCEL_M_S2``)
    is kept with a warning: cutting it out would shorten a short log further (or split it), and its effect
    is bounded and stated: a rate excursion a of duration D adds about a²τ²/(D·T_log) to the Allan
    variance at τ ≲ D, a small part of the white-noise region that a short log's fit uses, and it enters
    the reported intervals through the fit's dispersion. Vibration (zero-mean, large sample spread) is
    not motion: it is kept and reported by :func:`vibration_report` (std per axis, dominant frequency).

    workers, timings, on_axis : see :func:`characterise_rates` (timings: wall time of the stages [s]).
    increments : how the increments relate to the sensor's samples, for the vibration report only:
    "interval" (Δθ/Δt is the sensor's output: rate logs, simulated increments) or "trapezoid"
    (Δθ_k = ½(ω_{k−1} + ω_k)Δt_k, as raw rtklibexplorer logs are read; :func:`trapezoid_samples`).
    """
    if increments not in ("interval", "trapezoid"):
        raise ValueError(f"increments must be 'interval' or 'trapezoid', got {increments!r}")
    stg = Stages(timings)
    notes = list(imu.events)
    warns: list[str] = []
    base0 = float(imu.time[0])
    samples = trapezoid_samples(imu) if increments == "trapezoid" else None
    if static is not None:
        a, b = static
        base = float(imu.time[0])
        lo = base + (a or 0.0)
        hi = base + b if b is not None else np.inf
        m = (imu.time > lo) & (imu.time <= hi)
        if m.sum() < 3:
            raise ValueError(f"--static {a}:{b}: fewer than 3 samples in that part of the log")
        idx = np.flatnonzero(m)
        t0 = imu.time[idx[0] - 1] if idx[0] > 0 else imu.t0
        imu = ImuData(imu.time[m], imu.dtheta[m], imu.dv[m], t0=t0)
        if samples is not None:
            samples = samples[m]
        notes.append(f"static part {a or 0:g}-{'end' if b is None else f'{b:g}'} s after the first sample "
                     "analysed")
    rates, dt, t_start, resampled, n2 = uniform_rates(imu)
    notes += n2
    fs = 1.0 / dt
    stg.lap("uniform rates")
    rates, t_start, st = _static_part(rates, dt, t_start, base0, resampled, warns, chosen=static is not None,
                                      check_static=check_static)
    stg.lap("static check")
    min_m = resampled_min_m(len(rates)) if resampled else 1
    if resampled:
        notes.append(f"resampled log of {len(rates)} samples: the fit starts at tau = {min_m} intervals (the "
                     "resampling bias 1/(6m) of the white part is then below a quarter of the scatter)")
    sensor = None
    if samples is not None or resampled:
        t_hi = t_start + len(rates) * dt
        sel = (imu.time > t_start + 0.5 * dt) & (imu.time <= t_hi + 0.5 * dt)
        if samples is not None:
            x = samples[sel]
            what = "sensor's samples (trapezoid increments inverted)"
        else:
            dts = np.diff(imu.time, prepend=imu.t0)[sel]
            x = np.column_stack([imu.dtheta[sel], imu.dv[sel]]) / dts[:, None]
            what = "sensor's samples (increments / their own intervals)"
        if len(x) >= 3:
            pk = [psd_peak(x[:, c], fs) for c in range(6)]
            sensor = {"std": x.std(axis=0), "peak_hz": [p[0] for p in pk], "share": [p[1] for p in pk],
                      "what": what}
        stg.lap("sensor samples")
    imu = samples = None  # the log is no longer needed (memory: the caller holds no reference either)
    return characterise_rates(rates, fs, t_start=t_start, min_m=min_m, check_static=check_static, notes=notes,
                              resampled=resampled, sensor=sensor, warnings=warns, workers=workers,
                              time_origin=base0, timings=timings, static_result=st, on_axis=on_axis)


def _static_part(rates, dt: float, t_start: float, base0: float, resampled: bool, warns: list[str],
                 chosen: bool, check_static: bool):
    """The static check of uniform rates and, when they are not usable as a whole, their longest static
    part (a warning in ``warns``). Returns (rates, t_start, static check of those rates or None)."""
    fs = 1.0 / dt
    if not check_static:
        return rates, t_start, None
    st = static_check(rates, fs, t_start - base0)
    if st["usable"]:
        return rates, t_start, st
    i0, i1 = longest_static(rates, fs, t_start - base0, resampled, st, chosen=chosen)
    why = st["message"].split(": ", 1)[1].split(". Allan analysis")[0]
    what = "chosen part" if chosen else "log"
    warns.append(f"the {what} is not static ({why}; times in s after the first sample): analysed "
                 "its longest static part, "
                 f"{t_start - base0 + i0 * dt:.1f}-{t_start - base0 + i1 * dt:.1f} s "
                 f"({100.0 * (i1 - i0) / len(rates):.0f}% of its samples); motion is never analysed")
    # another part: checked again by characterise_rates
    return rates[i0:i1], t_start + i0 * dt, None


def characterise_uniform(rates, dt: float, t_start: float, base0: float, notes: list[str] | None = None,
                         workers: int | None = None, timings: dict | None = None,
                         on_axis=None, work: np.ndarray | None = None) -> Characterisation:
    """:func:`characterise_imu` of a log whose increments were uniformly spaced (no gap, no jitter) and
    are given as their rates already (``rates`` (M, 6) = increments / ``dt``, what :func:`uniform_rates`
    gives for such a log): the same static check, longest static part and analysis, the same results.
    t_start : start of the first interval [s]; base0 : time of the first sample [s] (the static check's
    times are after it); notes : the reader's events; on_axis, work : see :func:`characterise_rates`."""
    stg = Stages(timings)
    warns: list[str] = []
    rates, t_start, st = _static_part(rates, dt, t_start, base0, False, warns, chosen=False,
                                      check_static=True)
    stg.lap("static check")
    return characterise_rates(rates, 1.0 / dt, t_start=t_start, min_m=1, notes=list(notes or []),
                              warnings=warns, workers=workers, time_origin=base0, timings=timings,
                              static_result=st, on_axis=on_axis, work=work)
