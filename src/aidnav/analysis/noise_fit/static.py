"""Static detection: window statistics, motion / slow motion / disturbance, the longest static part.

Motion (driving, turning, tilting) is never analysed: the longest static part is, and the motion is
reported with its time and size. A slow motion (a small, short rotation: someone leaning on a parked car)
is kept and reported as a warning, with the physics of its bounded effect (:func:`static_check`).
"""

from __future__ import annotations

import numpy as np

from aidnav.analysis.noise_fit.prepare import resampled_min_m
from aidnav.analysis.noise_fit.results import NotStaticError
from aidnav.jit import njit
from aidnav.units import DEG

#: a moving span of the static check is "motion" (never analysed) when its window means depart by more than
#: this rate [deg/s], rotate by more than this angle [deg] or depart by more than this specific force
#: [m/s²]; smaller ones are "slow motion" (kept with a warning): see :func:`static_check`
MOTION_GYRO_DEG_S = 1.0
MOTION_ANGLE_DEG = 1.0
MOTION_ACCEL_M_S2 = 0.1


@njit(cache=True, nogil=True)
def window_stats(y, w, nw):
    """Mean and standard deviation of each of ``nw`` consecutive windows of ``w`` rows of y (M, k)."""
    k = y.shape[1]
    mean = np.empty((nw, k))
    std = np.empty((nw, k))
    acc = np.empty(k)
    for b in range(nw):
        acc[:] = 0.0
        for i in range(b * w, (b + 1) * w):
            for c in range(k):
                acc[c] += y[i, c]
        for c in range(k):
            mean[b, c] = acc[c] / w
        acc[:] = 0.0
        for i in range(b * w, (b + 1) * w):
            for c in range(k):
                d = y[i, c] - mean[b, c]
                acc[c] += d * d
        for c in range(k):
            std[b, c] = np.sqrt(acc[c] / w)
    return mean, std


def static_check(rates, fs: float, t_start: float = 0.0, window_s: float = 1.0,
                 gyro_tol_deg_s: float = 0.05, accel_tol_m_s2: float = 0.1, std_ratio: float = 4.0,
                 max_disturbed_fraction: float = 0.01, motion_gyro_deg_s: float = MOTION_GYRO_DEG_S,
                 motion_angle_deg: float = MOTION_ANGLE_DEG,
                 motion_accel_m_s2: float = MOTION_ACCEL_M_S2) -> dict:
    """Is a log static? From window means and window variances of the gyros and accelerometers.

    rates : (M, 6) gyro [rad/s] and accel [m/s²] rates, uniform at ``fs`` [Hz]; t_start [s] of sample 0's
    interval. Windows of ``window_s`` (at least 10 samples). A window **moves** when the mean of any axis
    departs from the log's median window mean by more than max(tolerance, 8 × the robust spread of the
    window means, 6 × the white-noise scatter of a window mean) (tolerances: gyro ``gyro_tol_deg_s``
    [deg/s], accel ``accel_tol_m_s2`` [m/s²]: turning or tilting); it is **disturbed** when the standard
    deviation inside the window of any axis exceeds ``std_ratio`` × the median window's (vibration bursts,
    handling).

    Consecutive moving windows form an event, sized by its largest window-mean departure (gyro [deg/s],
    accel [m/s²]) and the rotation over it (the departures integrated, largest axis [deg]). An event is
    **motion** when any exceeds ``motion_gyro_deg_s``, ``motion_angle_deg`` or ``motion_accel_m_s2`` (the
    platform is moved: driving, turning, tilting), otherwise **slow motion** (a small, short rotation or
    rocking: someone leaning on a parked car). Why the two are treated differently (see
    :func:`characterise_imu`): the Allan variance at τ is the mean square change between successive
    τ-averages over the whole log, so a short rate excursion a of duration D adds about a²τ²/(D·T_log) at
    τ ≲ D (and a²D/T_log around τ ~ D): for a slow motion (a ≲ 1 deg/s, a fraction of a degree) that is a
    small, reported bias of the white-noise region of a short log and is kept with a warning; motion
    adds a rate change far above the sensor noise at every τ and is never analysed.

    The log is static when no window moves and at most ``max_disturbed_fraction`` of the windows are
    disturbed; it is **usable** when it holds no motion event and at most that fraction is disturbed
    (slow motion only: kept, with the warning in ``warnings``).

    Returns dict: static, usable (bool), windows (count), window_s, moving / disturbed (counts),
    moving_spans_s / disturbed_spans_s (up to 10 [start, end] spans on the input time scale), events
    (list of dicts: start_s, end_s, kind "motion" | "slow motion", peak_gyro_deg_s, angle_deg,
    peak_accel_m_s2), motion_free_spans_s (the spans between motion events, each shortened by one window
    at a motion event; longest first), max_gyro_dev_deg_s, max_accel_dev_m_s2, warnings (list of str),
    message (str, empty when usable).
    """
    y = np.ascontiguousarray(rates, dtype=float)
    w = max(10, int(round(window_s * fs)))
    nw = len(y) // w
    wdt = w / fs
    t_end = t_start + len(y) / fs
    if nw < 3:
        return {"static": True, "usable": True, "windows": nw, "window_s": wdt, "moving": 0, "disturbed": 0,
                "moving_spans_s": [], "disturbed_spans_s": [], "events": [],
                "motion_free_spans_s": [[t_start, t_end]], "max_gyro_dev_deg_s": 0.0,
                "max_accel_dev_m_s2": 0.0, "warnings": [], "message": "",
                "note": "log too short for the static check (fewer than 3 windows)"}
    sdev, dev, moving, disturbed = _window_flags(y, w, nw, gyro_tol_deg_s, accel_tol_m_s2, std_ratio)
    limits = (motion_gyro_deg_s, motion_angle_deg, motion_accel_m_s2)
    events, motion = _motion_events(moving, dev, sdev, t_start, wdt, limits)
    free = _motion_free_spans(motion, t_start, t_end, wdt)
    ms, ds = _spans(moving, t_start, wdt), _spans(disturbed, t_start, wdt)
    static = (not moving.any()) and disturbed.mean() <= max_disturbed_fraction
    usable = (not motion.any()) and disturbed.mean() <= max_disturbed_fraction
    res = {"static": bool(static), "usable": bool(usable), "windows": int(nw), "window_s": wdt,
           "moving": int(moving.sum()), "disturbed": int(disturbed.sum()), "moving_spans_s": ms[:10],
           "disturbed_spans_s": ds[:10], "events": events[:20], "motion_free_spans_s": free[:10],
           "max_gyro_dev_deg_s": float(dev[:, :3].max() / DEG), "max_accel_dev_m_s2": float(dev[:, 3:].max()),
           "warnings": [], "message": ""}
    res["warnings"].extend(_slow_motion_warnings(events, limits))
    if not usable:
        res["message"] = _not_static_message(events, disturbed, max_disturbed_fraction, std_ratio, ds, free)
    return res


def _window_flags(y, w: int, nw: int, gyro_tol_deg_s: float, accel_tol_m_s2: float, std_ratio: float):
    """Per window: the signed and absolute departures of the window means from the median one, and
    whether it moves or is disturbed (criteria in :func:`static_check`)."""
    mean, std = window_stats(y, w, nw)
    med = np.median(mean, axis=0)
    sdev = mean - med
    dev = np.abs(sdev)
    mad = 1.4826 * np.median(dev, axis=0)
    tol = np.r_[np.full(3, gyro_tol_deg_s * DEG), np.full(3, accel_tol_m_s2)]
    floor = np.r_[np.full(3, 1e-3 * DEG), np.full(3, 1e-3)]
    sref = np.maximum(np.median(std, axis=0), floor / std_ratio)
    # a window mean of white noise with the log's typical in-window spread scatters by sref/√w: a
    # vibrating (but parked) vehicle is not "moving" because of that scatter (6σ)
    moving = np.any(dev > np.maximum(np.maximum(tol, 8.0 * mad), 6.0 * sref / np.sqrt(w)), axis=1)
    disturbed = np.any(std > std_ratio * sref, axis=1)
    return sdev, dev, moving, disturbed


def _runs(mask) -> list[tuple[int, int]]:
    """(first, last) indices of each run of True in ``mask``."""
    idx = np.flatnonzero(mask)
    if not len(idx):
        return []
    br = np.flatnonzero(np.diff(idx) > 1)
    return list(zip(np.r_[idx[0], idx[br + 1]].tolist(), np.r_[idx[br], idx[-1]].tolist(), strict=True))


def _spans(mask, t_start: float, wdt: float) -> list[list[float]]:
    """[start, end] times of each run of flagged windows."""
    return [[t_start + a * wdt, t_start + (b + 1) * wdt] for a, b in _runs(mask)]


def _motion_events(moving, dev, sdev, t_start: float, wdt: float, limits):
    """One event per run of moving windows, "motion" when beyond any of ``limits`` (gyro [deg/s], angle
    [deg], accel [m/s²]) else "slow motion" → (events, mask of the windows near motion)."""
    motion_gyro_deg_s, motion_angle_deg, motion_accel_m_s2 = limits
    nw = len(moving)
    events = []
    motion = np.zeros(nw, bool)
    for a, b in _runs(moving):
        pg = float(dev[a:b + 1, :3].max() / DEG)
        ang = float(np.abs(sdev[a:b + 1, :3].sum(axis=0)).max() * wdt / DEG)
        pa = float(dev[a:b + 1, 3:].max())
        kind = "motion" if (pg > motion_gyro_deg_s or ang > motion_angle_deg or pa > motion_accel_m_s2) \
            else "slow motion"
        if kind == "motion":
            motion[max(0, a - 1):b + 2] = True  # one window of margin on each side
        events.append({"start_s": t_start + a * wdt, "end_s": t_start + (b + 1) * wdt, "kind": kind,
                       "peak_gyro_deg_s": pg, "angle_deg": ang, "peak_accel_m_s2": pa})
    return events, motion


def _motion_free_spans(motion, t_start: float, t_end: float, wdt: float) -> list[list[float]]:
    """The spans between motion events (to the log's ends), longest first."""
    nw = len(motion)
    free = []
    for a, b in _runs(~motion):
        lo = t_start if a == 0 else t_start + a * wdt
        hi = t_end if b == nw - 1 else t_start + (b + 1) * wdt
        free.append([lo, hi])
    free.sort(key=lambda s: s[0] - s[1])
    return free


def _slow_motion_warnings(events: list[dict], limits) -> list[str]:
    """One warning per slow-motion event: kept, and what it does to the Allan deviation."""
    motion_gyro_deg_s, motion_angle_deg, motion_accel_m_s2 = limits
    warnings = []
    for e in events:
        if e["kind"] == "slow motion":
            warnings.append(
                f"slow motion at {e['start_s']:.1f}-{e['end_s']:.1f} s: window means depart by up to "
                f"{e['peak_gyro_deg_s']:.3g} deg/s gyro ({e['angle_deg']:.2g} deg of rotation) and "
                f"{e['peak_accel_m_s2']:.3g} m/s2 accel (thresholds of motion {motion_gyro_deg_s:g} deg/s, "
                f"{motion_angle_deg:g} deg, {motion_accel_m_s2:g} m/s2): kept; it raises the Allan deviation "
                f"of the affected axes at tau of about {e['end_s'] - e['start_s']:.3g} s and longer")
    return warnings


def _not_static_message(events: list[dict], disturbed, max_disturbed_fraction: float, std_ratio: float,
                        ds, free) -> str:
    """Why the log cannot be analysed as a whole, and the longest parts without motion to choose."""
    nw = len(disturbed)
    parts = []
    mot = [e for e in events if e["kind"] == "motion"]
    if mot:
        parts.append(f"it moves in {len(mot)} span(s) (window means depart from the median by up to "
                     f"{max(e['peak_gyro_deg_s'] for e in mot):.3g} deg/s gyro, "
                     f"{max(e['peak_accel_m_s2'] for e in mot):.3g} m/s2 accel; first spans "
                     + ", ".join(f"{e['start_s']:.1f}-{e['end_s']:.1f} s" for e in mot[:3]) + ")")
    if disturbed.mean() > max_disturbed_fraction:
        parts.append(f"{disturbed.sum()} of {nw} windows are disturbed (in-window spread above "
                     f"{std_ratio:g} x the typical; first spans "
                     + ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in ds[:3]) + ")")
    sugg = ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in free[:3])
    return ("the log is not static: " + "; ".join(parts)
            + ". Allan analysis needs a static log: the longest parts without motion are "
            f"{sugg}; choose a static part with --static START:END")


def longest_static(rates, fs: float, t_rel: float, resampled: bool, st: dict,
                    chosen: bool = False) -> tuple[int, int]:
    """Sample range [i0, i1) of the longest static part of ``rates`` (not usable as a whole: ``st``).

    chosen : the rates are a part the user chose as static: its own motion-free spans (``st``) are
    candidates too (its median level is the parked one; small disturbances in it are kept and reported).
    Candidates are (also) the runs of quiet one-second windows (the in-window spread of every axis within
    4 × its 5th percentile over the windows: a moving vehicle shakes far more than a parked one,
    engine vibration included), less one window at each end that borders a loud one; each is checked
    with :func:`static_check` on its own level (the median window of a mostly moving log says nothing of
    the parked level) and cut down to its longest part without motion. Raises :class:`NotStaticError`
    (naming the candidates) when none is long enough to fit."""
    y = np.ascontiguousarray(rates, dtype=float)
    n = len(y)
    w = max(10, int(round(fs)))
    nw = n // w
    cands = []
    if nw >= 3:
        _, std = window_stats(y, w, nw)
        floor = np.r_[np.full(3, 1e-3 * DEG), np.full(3, 1e-3)] / 4.0
        ref = np.maximum(np.percentile(std, 5, axis=0), floor)
        quiet = np.all(std <= 4.0 * ref, axis=1)
        idx = np.flatnonzero(quiet)
        if len(idx):
            br = np.flatnonzero(np.diff(idx) > 1)
            for a, b in zip(np.r_[idx[0], idx[br + 1]], np.r_[idx[br], idx[-1]], strict=True):
                s0 = int(a + (a > 0)) * w
                s1 = n if b == nw - 1 else int(b) * w
                if s1 > s0:
                    cands.append((s0, s1))
    if chosen:
        for lo, hi in st["motion_free_spans_s"]:
            cands.append((max(0, int(round((lo - t_rel) * fs))), min(n, int(round((hi - t_rel) * fs)))))
    cands.sort(key=lambda c: c[0] - c[1])
    best = None
    for s0, s1 in cands:
        if best is not None and s1 - s0 <= best[1] - best[0]:
            break
        for _ in range(3):
            sub = static_check(y[s0:s1], fs, t_rel + s0 / fs)
            if sub["usable"] or not any(e["kind"] == "motion" for e in sub["events"]):
                break
            lo, hi = sub["motion_free_spans_s"][0]
            s0, s1 = max(s0, int(round((lo - t_rel) * fs))), min(s1, int(round((hi - t_rel) * fs)))
        need = max(64, 12 * (resampled_min_m(s1 - s0) if resampled else 1))
        if sub["usable"] and s1 - s0 >= need and (best is None or s1 - s0 > best[1] - best[0]):
            best = (s0, s1)
    if best is None:
        spans = ", ".join(f"{t_rel + a / fs:.1f}-{t_rel + b / fs:.1f} s" for a, b in cands[:3]) or "none"
        raise NotStaticError(st["message"].split(". Allan analysis")[0]
                             + f". No static part is long enough to analyse (quiet parts: {spans}; times in "
                             "s after the first sample); choose a static part with --static START:END")
    return best
