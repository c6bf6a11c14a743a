"""IMU–GNSS time lag from the turn rate, without a filter (a check on the filter's ``time_offset_s``).

The yaw rate the gyros measure about the local vertical must equal the rate of the GNSS course over
ground while the vehicle drives (a car does not side-slip much), so the lag that best aligns the two
series is the IMU's lateness relative to the GNSS time base — independent of any filter tuning, lever
arm or mounting knowledge. The course is taken from one of two GNSS references, which need not share a
time base inside the receiver:

- ``"velocity"``: the receiver's velocity (ENU) as given in the file;
- ``"position"``: velocities from central differences of the positions, (p[k+1] − p[k−1]) / (t[k+1] −
  t[k−1]), which carry no lag at t[k] (the difference is centred).

A receiver whose velocity comes out of its own navigation filter reports it late relative to its
positions; the two lags then differ by that velocity delay.

Sign convention (docs/conventions.md): ``lag_s`` > 0 means the IMU is late: an event at GNSS time t
appears in the IMU stamps at t + lag. The correction that aligns the IMU with the GNSS is
``time_offset_s = −lag_s`` (added to the IMU stamps, the convention of ``calibration.time_offset``).

Method: the gyro rate is projected on the body "up" axis (the mean specific force over the whole log:
no mounting needed), averaged over the same window the GNSS course rate spans (a central difference
over t[k−1]…t[k+1]), shifted by each candidate lag on a grid, and compared with the course rate by a
least-squares fit with a free gain; the lag minimising the residual on a coarse grid (every 20 ms), then
on the fine grid (``step_s``) within ±60 ms of it, refined by a parabola through the three best grid
points, is returned. The σ is a block-jackknife over 10 contiguous blocks of the
epochs used (turns are sparse events, so the blocks are the independent units).
"""

from __future__ import annotations

import numpy as np

from ..data import GnssData, ImuData
from ..io.motion_checks import centred_velocity as _centred_velocity
from ..io.motion_checks import course_rate as _course_rate
from ..io.motion_checks import turn_rate_residuals as _residual_curve

COARSE_STEP_S = 0.02  #: the coarse lag grid [s] (module doc: method)
FINE_HALF_WIDTH_S = 0.06  #: the fine grid spans the coarse minimum ± this [s]


def parabola_minimum(grid, cost):
    """The minimum of ``cost`` sampled on the uniform ``grid``: the best interior grid point refined by the
    parabola through it and its two neighbours (the step clipped to ±1 grid step). Returns (the refined
    abscissa, the parabola's value there, the index of the best point)."""
    i = int(np.clip(np.argmin(cost), 1, grid.size - 2))
    c0, c1, c2 = cost[i - 1], cost[i], cost[i + 1]
    den = c0 - 2.0 * c1 + c2
    step = grid[1] - grid[0]
    shift = float(np.clip(0.5 * (c0 - c2) / den, -1.0, 1.0)) if den > 0 else 0.0
    return float(grid[i] + shift * step), float(c1 - 0.25 * (c0 - c2) * shift), i


def imu_gnss_lag(imu: ImuData, gnss: GnssData, reference: str = "velocity", max_lag_s: float = 0.5,
                 step_s: float = 0.005, min_speed_m_s: float = 3.0, min_turn_rate_deg_s: float = 0.0,
                 skip_s: float = 0.0) -> dict:
    """Estimate the IMU's lateness relative to a GNSS reference from the turn rate (module docstring).

    imu : increments on GNSS time (stamps as read, before any configured time offset).
    gnss : fixes with ENU velocity (reference "velocity") or positions (reference "position").
    reference : "velocity" or "position".
    max_lag_s, step_s : the lag grid, ±max_lag_s in steps of step_s [s].
    min_speed_m_s : epochs slower than this are left out (the course is noise at low speed) [m/s].
    skip_s : leave out the first skip_s seconds of GNSS (a start-up transient) [s].

    Returns a dict: ``lag_s`` (IMU lateness [s]), ``sigma_s`` (block-jackknife 1σ [s]), ``time_offset_s``
    (= −lag_s, the correction to add to the IMU stamps), ``gain`` (IMU turn rate / course rate at the
    lag; ≈ 1 when the up axis and the scale are right), ``epochs`` (number used), ``reference``.
    Raises ValueError when too few moving epochs remain (fewer than 20).
    """
    if reference not in ("velocity", "position"):
        raise ValueError(f"reference must be 'velocity' or 'position', not {reference!r}")
    t_g = np.asarray(gnss.time, dtype=float)
    if reference == "velocity":
        if gnss.vel is None:
            raise ValueError("reference 'velocity' needs GNSS velocities; this file has none: use 'position'")
        v_e, v_n = gnss.vel[:, 0], gnss.vel[:, 1]
    else:
        v_e, v_n = _centred_velocity(gnss)
    rate = _course_rate(t_g, v_e, v_n)
    speed = np.hypot(v_e, v_n)
    t_imu = np.asarray(imu.time, dtype=float)
    ok = (np.isfinite(rate) & (speed > min_speed_m_s) & (t_g >= t_g[0] + skip_s)
          & (np.abs(rate) >= np.radians(min_turn_rate_deg_s)))
    idx = np.flatnonzero(ok)
    idx = idx[(idx >= 1) & (idx <= t_g.size - 2)]
    idx = idx[(t_g[idx - 1] - max_lag_s >= t_imu[0]) & (t_g[idx + 1] + max_lag_s <= t_imu[-1])]
    if idx.size < 20:
        raise ValueError(f"only {idx.size} GNSS epochs faster than {min_speed_m_s} m/s overlap the IMU log: "
                         "the lag needs a drive with turns")
    up = imu.dv.sum(axis=0)
    up = up / np.linalg.norm(up)  # the specific force points up on average (it is −gravity)
    cum_up = np.cumsum(imu.dtheta @ up)  # ∫ω·up dt up to each stamp (a constant offset cancels)
    lags = np.arange(-max_lag_s, max_lag_s + 0.5 * step_s, step_s)
    t_lo, t_hi, r = t_g[idx - 1], t_g[idx + 1], rate[idx]
    if np.sqrt(np.mean(r * r)) < np.radians(0.5):
        raise ValueError(f"the course rate over the {idx.size} moving epochs is below 0.5 deg/s RMS: "
                         "the lag needs a drive with turns")

    # coarse to fine: the cost over ±max_lag_s every COARSE_STEP_S, then every step_s around its minimum
    # (the turn-rate cost varies on the scale of the turns, tenths of a second: the coarse grid cannot
    # step over its minimum), the jackknife on the fine grid only
    coarse = np.arange(-max_lag_s, max_lag_s + 0.5 * COARSE_STEP_S, max(COARSE_STEP_S, step_s))
    c_cost, _ = _residual_curve(coarse, t_imu, cum_up, t_lo, t_hi, r)
    mid = coarse[int(np.argmin(c_cost))]
    half = FINE_HALF_WIDTH_S
    lags = lags[(lags >= mid - half - 1e-12) & (lags <= mid + half + 1e-12)]
    cost, gains = _residual_curve(lags, t_imu, cum_up, t_lo, t_hi, r)
    lag, _, i_best = parabola_minimum(lags, cost)
    blocks = np.array_split(np.arange(idx.size), 10)
    jack = []
    for b in blocks:
        keep = np.setdiff1d(np.arange(idx.size), b)
        c_b, _ = _residual_curve(lags, t_imu, cum_up, t_lo[keep], t_hi[keep], r[keep])
        jack.append(parabola_minimum(lags, c_b)[0])
    jack = np.asarray(jack)
    sigma = float(np.sqrt((jack.size - 1) / jack.size * np.sum((jack - jack.mean()) ** 2)))
    return {"lag_s": lag, "sigma_s": sigma, "time_offset_s": -lag, "gain": float(gains[i_best]),
            "epochs": int(idx.size), "reference": reference}
