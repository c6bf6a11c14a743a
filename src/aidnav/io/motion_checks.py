"""Plausibility checks from physics (issue 37): the IMU against the GNSS track, before any filtering.

Thresholds on the IMU alone (a gyro above 20 rad/s) never fire for a car; these checks compare what the
IMU says with what the GNSS track says, so a unit, axis or time-scale mistake shows as a ratio or a shift
that is far from its physical value whatever the vehicle does:

* ``imu-up`` — gravity: the mean specific force over the log points along the body's up axis (+z of
  RFU) within 60°; a z axis that reads −g is an FRD/NED IMU read as RFU (x forward, y right, z down),
  gravity along x or y is an axis order mistake.
* ``imu-gyro-scale`` — the gyro's turn rate about the up axis (the mean specific force) against the
  rate of the GNSS course over ground while moving: their ratio is 1 (a car does not side-slip much);
  57.3 is deg/s labelled rad/s (or increments in degrees, e.g. KF-GINS ``.imu`` written in degrees);
  1/57.3 the reverse.
* ``imu-axes`` — the same ratio near −1: the gyro turns the other way than the vehicle; a mirrored
  (left-handed) axis set: two axes swapped or one axis' sign flipped.
* ``time-scale`` — the shift of the IMU turn rate that best matches the GNSS course rate, searched over
  ±25 s and whole hours: more than ``TIME_SCALE_MIN_S`` (5 s) is a time-scale mistake (18 s: GNSS in UTC
  against an IMU in GPS time — the leap seconds; whole hours: a time zone). Shifts below it are latency,
  the filter's own time-offset state (and a short log's turn-rate match cannot tell a second apart from
  noise). The search needs ``MIN_SPAN_S`` (100 s) of moving epochs: shorter logs are not judged.

Each check is skippable by name (``--skip-check``), raises :class:`DataError` naming the cause and the
fix, and says nothing where the log cannot tell (fewer than 20 moving epochs, no turns).

The turn-rate comparison (:func:`course_rate`, :func:`centred_velocity`, :func:`turn_rate_residuals`)
is shared with :func:`aidnav.analysis.timing.imu_gnss_lag` (the filter-free lag estimate).
"""

from __future__ import annotations

import numpy as np

from aidnav.io.errors import DataError
from aidnav.nav.earth import lla_to_enu

#: name → what it checks (merged into :data:`aidnav.io.sanity.CHECKS`)
MOTION_CHECKS = {
    "imu-up": "the mean specific force (gravity) along the body's +z axis within 60° (RFU, not FRD/NED; "
              "axes in the right order)",
    "imu-gyro-scale": "the gyro's turn rate about the up axis equals the GNSS course rate (gyro in rad/s, "
                      "increments in radians: not degrees)",
    "imu-axes": "the gyro turns the same way as the GNSS course (a right-handed axis set, no swapped or "
                "sign-flipped axis)",
    "time-scale": "the IMU turn rate matches the GNSS course rate within 1 s (the same time scale: not UTC "
                  "against GPS time, not a time zone)",
}

DEG = np.pi / 180.0
#: the smallest shift [s] the time-scale check calls a time-scale mistake: far above any IMU/GNSS latency
#: (fractions of a second, estimated by the filter), below the leap seconds of every GPS-era log since 1999
TIME_SCALE_MIN_S = 5.0
#: the time-scale search compares the turn rates over at least this span of moving epochs [s]: over a
#: one-minute log a shift of seconds matches some turns by chance (measured: 60-s cuts of the drive matched
#: best 24 s away), so shorter logs are not judged (4 × the search range)
MIN_SPAN_S = 100.0
MAX_SHIFT_S = 25.0  #: the time-scale search: ±this [s] (18 s of leap seconds inside), and whole hours
MAX_EPOCHS = 800  #: moving GNSS epochs compared at most
HOURS = (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12)


#: a central difference over t[k−1]…t[k+1] longer than this many nominal fix intervals (the median) spans a
#: gap (an outage, withheld or rejected fixes): the chord between its ends is not the track at t[k]
GAP_FACTOR = 2.5


def _across_gap(time) -> np.ndarray:
    """(n − 2,) mask of the central differences t[k−1]…t[k+1], k = 1…n−2, that span a gap."""
    t = np.asarray(time, float)
    if t.size < 3:
        return np.zeros(0, bool)
    return (t[2:] - t[:-2]) > GAP_FACTOR * 2.0 * float(np.median(np.diff(t)))


def course_rate(time, v_e, v_n):
    """Rate of the course over ground about the up axis [rad/s] (counter-clockwise positive), centred;
    NaN where the difference spans a gap (:data:`GAP_FACTOR`)."""
    course = np.arctan2(v_n, v_e)  # angle from east, counter-clockwise = yaw about up
    fin = np.isfinite(course)
    course[fin] = np.unwrap(course[fin])  # missing velocities stay NaN (their neighbours' rates too)
    rate = np.full_like(course, np.nan)
    rate[1:-1] = (course[2:] - course[:-2]) / (time[2:] - time[:-2])
    rate[1:-1][_across_gap(time)] = np.nan
    return rate


def centred_velocity(gnss):
    """ENU velocity from central differences of the positions (no lag at the epoch); NaN where the
    difference spans a gap (:data:`GAP_FACTOR`)."""
    e, n, _ = lla_to_enu(gnss.lat, gnss.lon, gnss.height, gnss.lat[0], gnss.lon[0], gnss.height[0])
    t = gnss.time
    v_e, v_n = np.full_like(e, np.nan), np.full_like(n, np.nan)
    v_e[1:-1] = (e[2:] - e[:-2]) / (t[2:] - t[:-2])
    v_n[1:-1] = (n[2:] - n[:-2]) / (t[2:] - t[:-2])
    gap = _across_gap(t)
    v_e[1:-1][gap], v_n[1:-1][gap] = np.nan, np.nan
    v_e[[0, -1]], v_n[[0, -1]] = v_e[[1, -2]], v_n[[1, -2]]  # ends: never used (no centred course rate)
    return v_e, v_n


def turn_rate_residuals(lags, imu_time, cum_up, t_lo, t_hi, rate):
    """(mean squared residual, gain) of rate_imu(window shifted by lag) = gain × rate, for each lag."""
    cost = np.empty(lags.size)
    gains = np.empty(lags.size)
    xx = float(rate @ rate)
    for i, lag in enumerate(lags):
        a = np.interp(t_lo + lag, imu_time, cum_up)
        b = np.interp(t_hi + lag, imu_time, cum_up)
        y = (b - a) / (t_hi - t_lo)
        k = float(rate @ y) / xx
        cost[i] = np.mean((y - k * rate) ** 2)
        gains[i] = k
    return cost, gains


def _skip(name, skip) -> bool:
    return name in (skip or ())


_TRACK: dict = {}  #: the course rate and speed of the fix series being checked (check_motion clears it)


def _moving(gnss, t_imu, margin, min_speed=3.0):
    """Indices of the GNSS epochs with a centred course rate, moving, whose windows ± margin lie inside
    the IMU span; and the course rate."""
    t_g = np.asarray(gnss.time, float)
    key = id(gnss)
    if _TRACK.get("key") != key:  # the course rate of this fix series, once per check
        if gnss.vel is not None and np.isfinite(gnss.vel[:, :2]).mean() > 0.5:
            v_e, v_n = gnss.vel[:, 0].astype(float), gnss.vel[:, 1].astype(float)
        else:
            v_e, v_n = centred_velocity(gnss)
        _TRACK.update(key=key, rate=course_rate(t_g, v_e, v_n), speed=np.hypot(v_e, v_n))
    rate, speed = _TRACK["rate"], _TRACK["speed"]
    ok = np.isfinite(rate) & (speed > min_speed)
    idx = np.flatnonzero(ok)
    idx = idx[(idx >= 1) & (idx <= t_g.size - 2)]
    idx = idx[(t_g[idx - 1] - margin >= t_imu[0]) & (t_g[idx + 1] + margin <= t_imu[-1])]
    if idx.size > MAX_EPOCHS:  # evenly spread: the check's cost independent of the log length
        idx = idx[np.linspace(0, idx.size - 1, MAX_EPOCHS).astype(np.int64)]
    return idx, rate, t_g


def up_axis(imu):
    """Unit vector of the mean specific force in the body frame (up, as the IMU measures it)."""
    f = np.asarray(imu.dv, float).sum(axis=0)
    nrm = float(np.linalg.norm(f))
    return f / nrm if nrm > 0 else np.array([0.0, 0.0, 1.0])


def check_up(imu, path, skip=()) -> None:
    """``imu-up``: gravity along +z (module doc)."""
    if _skip("imu-up", skip) or len(imu) < 2:
        return
    u = up_axis(imu)
    i = int(np.argmax(np.abs(u)))
    if u[2] >= np.cos(np.radians(60.0)):
        return
    ang = np.degrees(np.arccos(np.clip(u[2], -1.0, 1.0)))
    where = f"the mean specific force (gravity, {u[0]:+.2f}, {u[1]:+.2f}, {u[2]:+.2f} as a unit vector)"
    if i == 2:
        raise DataError(path, None, f"columns dv_z/accel_z_m_s2: {where} points along −z "
                        f"({ang:.0f}° from +z): the z axis "
                        "points down — an FRD/NED IMU (x forward, y right, z down) read as RFU (x right, y "
                        "forward, z up). Convert: x_RFU = y, y_RFU = x, z_RFU = −z for both the gyro and "
                        "the accelerometer (or --skip-check imu-up for an IMU mounted upside down)")
    axis = "xyz"[i]
    raise DataError(path, None, f"columns dv_{axis}/accel_{axis}_m_s2: {where} lies along "
                    f"the {'+' if u[i] > 0 else '−'}"
                    f"{axis} axis ({ang:.0f}° from +z): the axes are in another order than RFU (x right, "
                    "y forward, z up). Reorder the columns (gyro and accelerometer alike), or --skip-check "
                    "imu-up for an IMU mounted on its side")


def check_motion(imu, gnss, imu_path, gnss_path, skip=()) -> list[str]:
    """``imu-gyro-scale``, ``imu-axes`` and ``time-scale`` (module doc) on IMU increments and GNSS fixes
    on the same (intended) time scale. Raises :class:`DataError`; returns warnings (none yet)."""
    names = ("imu-gyro-scale", "imu-axes", "time-scale")
    _TRACK.clear()
    if all(_skip(n, skip) for n in names) or len(imu) < 2 or len(gnss) < 25:
        return []
    t_imu = np.asarray(imu.time, float)
    cum_up = np.cumsum(np.asarray(imu.dtheta, float) @ up_axis(imu))
    near = np.arange(-MAX_SHIFT_S, MAX_SHIFT_S + 1e-9, 0.1)

    def fit(margin, lags):
        idx, rate, t_g = _moving(gnss, t_imu, margin)
        if idx.size < 20:
            return None
        r = rate[idx]
        if np.sqrt(np.mean(r * r)) < 1.0 * DEG:  # no turns to compare
            return None
        cost, gains = turn_rate_residuals(lags, t_imu, cum_up, t_g[idx - 1], t_g[idx + 1], r)
        return cost, gains, float(np.mean(r * r)), idx.size, float(t_g[idx[-1]] - t_g[idx[0]])

    # the gain near zero shift (the epochs of the whole log): units and axes
    small = np.arange(-1.0, 1.0 + 1e-9, 0.05)
    base = fit(1.0, small)
    if base is None:
        return []
    c_s, g_s, rr, n, _ = base
    j = int(np.argmin(c_s))
    shift, gain, best = float(small[j]), float(g_s[j]), float(c_s[j])
    # explained fraction of the course rate's variance at the best shift (the gain free)
    explained = 1.0 - best / (best + gain * gain * rr) if gain * gain * rr > 0 else 0.0
    # the shift over ±MAX_SHIFT_S and whole hours: time scales (where the log is long enough)
    wide = fit(MAX_SHIFT_S, near)
    if wide is not None and wide[4] < MIN_SPAN_S:
        wide = None  # too little motion to tell a shift of seconds from chance (a one-minute log)
    if wide is not None:
        cost, gains, rr_w, n_w, _ = wide
        i0, ib = int(np.argmin(np.abs(near))), int(np.argmin(cost))
        at0 = float(cost[i0])
        if abs(near[ib]) > TIME_SCALE_MIN_S and cost[ib] < 0.5 * at0:
            shift, gain, best = float(near[ib]), float(gains[ib]), float(cost[ib])
            explained = 1.0 - best / (best + gain * gain * rr_w) if gain * gain * rr_w > 0 else 0.0
    else:
        at0 = np.inf
    for h in HOURS:  # whole-hour shifts (a time zone), where the logs overlap enough
        for sgn in (-1, 1):
            lags = sgn * 3600.0 * h + np.arange(-2.0, 2.0 + 1e-9, 0.1)
            f = fit(float(np.max(np.abs(lags))), lags)
            if f is not None and f[3] >= 0.5 * n and f[4] >= MIN_SPAN_S and float(np.min(f[0])) < 0.5 * best:
                j = int(np.argmin(f[0]))
                shift, gain, best = float(lags[j]), float(f[1][j]), float(f[0][j])
                at0 = min(at0, 2.0 * best)
    if explained < 0.5 and abs(shift) < 1.0:
        return []  # the turn rates do not match at any shift: nothing this check can tell
    rel = f"(ratio of the IMU turn rate about the up axis to the GNSS course rate over {n} moving epochs)"
    if not _skip("time-scale", skip) and abs(shift) > TIME_SCALE_MIN_S and best < 0.5 * at0:
        leap = abs(abs(shift) - 18.0) < 1.5
        hours = abs(shift) > 1800.0
        cause = ("the GNSS file is in UTC and the IMU in GPS time (or the reverse): they differ by the 18 "
                 "leap seconds" if leap else "a time zone or a local-time clock: a whole number of hours"
                 if hours else "the two files are on different time scales")
        late = "late" if shift > 0 else "early"
        raise DataError(gnss_path, None, f"column time: the IMU turn rate matches the GNSS course rate "
                        f"{abs(shift):.1f} s {late} ({imu_path} against this file; at 0 s it does not): "
                        f"{cause}. Give "
                        f"--time-offset {-shift:+.1f} (added to the IMU stamps) or convert the GNSS times "
                        "to GPS time (or --skip-check time-scale)")
    if not _skip("imu-gyro-scale", skip):
        if 20.0 < abs(gain) < 200.0:
            raise DataError(imu_path, None, f"columns gyro_*/dtheta_*: the gyro turns "
                            f"{abs(gain):.1f} times faster than the "
                            f"GNSS course {rel}: 57.3 is degrees read as radians — the gyro is in deg/s "
                            "(or the increments in degrees) but labelled rad/s (rad): multiply by π/180 "
                            "(or --skip-check imu-gyro-scale)")
        if 0.005 < abs(gain) < 0.05:
            raise DataError(imu_path, None, f"columns gyro_*/dtheta_*: the gyro turns "
                            f"{1 / abs(gain):.1f} times slower than "
                            f"the GNSS course {rel}: radians read as degrees — multiply by 180/π "
                            "(or --skip-check imu-gyro-scale)")
    if not _skip("imu-axes", skip) and abs(shift) <= 1.0:
        hand = handedness(imu, gnss)
        if hand is not None and hand < -0.5:
            raise DataError(imu_path, None, "gyro and accelerometer axes: the axes are mirrored "
                            "(left-handed): the "
                            "accelerometer's turn (centripetal) acceleration points to the side opposite "
                            f"to the one the GNSS course turns to (handedness {hand:+.2f}; +1 for a "
                            "right-handed set) — two axes swapped (e.g. x and y) or one axis' sign flipped. "
                            "Give the axes as RFU (x right, y forward, z up), gyro and accelerometer alike "
                            "(or --skip-check imu-axes)")
    return []


def handedness(imu, gnss) -> float | None:
    """+1 for a right-handed IMU axis set, −1 for a mirrored one; None where the log cannot tell.

    The horizontal specific force (the part normal to the up axis) of a vehicle is its longitudinal
    acceleration along its direction of travel d plus its centripetal acceleration along its left l,
    both measured by GNSS (speed change; speed × course rate). A least-squares fit of the two body
    vectors d and l over the moving epochs gives l = u × d in a right-handed set and −u × d in a
    mirrored one (u: up); a permutation of the axes keeps every dot product (so the gyro's turn rate about
    u cannot tell) but reverses the cross product."""
    t_imu = np.asarray(imu.time, float)
    _TRACK.clear()
    idx, rate, t_g = _moving(gnss, t_imu, 0.0)
    if idx.size < 20:
        return None
    if gnss.vel is not None and np.isfinite(gnss.vel[:, :2]).mean() > 0.5:
        v = np.asarray(gnss.vel[:, :2], float)
    else:
        v = np.column_stack(centred_velocity(gnss))
    lo, hi = idx - 1, idx + 1
    dt = t_g[hi] - t_g[lo]
    speed = np.hypot(v[:, 0], v[:, 1])
    a_long = (speed[hi] - speed[lo]) / dt
    a_lat = speed[idx] * rate[idx]  # to the left (counter-clockwise turn)
    cum = np.cumsum(np.asarray(imu.dv, float), axis=0)
    f = np.column_stack([np.interp(t_g[hi], t_imu, cum[:, j]) - np.interp(t_g[lo], t_imu, cum[:, j])
                         for j in range(3)]) / dt[:, None]
    u = up_axis(imu)
    f_h = f - np.outer(f @ u, u)
    f_h -= f_h.mean(axis=0)  # a constant tilt of the mean
    A = np.column_stack([a_long - a_long.mean(), a_lat - a_lat.mean()])
    if np.linalg.cond(A) > 30.0 or np.std(a_lat) < 0.3 or np.std(a_long) < 0.1:
        return None
    coef, *_ = np.linalg.lstsq(A, f_h, rcond=None)
    d, left = coef[0], coef[1]
    nd, nl = np.linalg.norm(d), np.linalg.norm(left)
    if nd < 0.3 or nl < 0.3:  # the fit did not find the vehicle's axes
        return None
    return float(np.cross(u, d / nd) @ (left / nl))
