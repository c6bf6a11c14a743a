"""Is the vehicle wheeled? The no-option run's decision on the non-holonomic constraint (issue 35, item 6).

A wheeled vehicle does not slide sideways or jump: its velocity, resolved in the body frame, keeps one
direction fixed in the body (forward or backward along the vehicle's axis, whatever the mounting). A
ship (leeway, currents), an aircraft (crab in a crosswind, angle of attack) or a walker's device (held at
any angle) does not. :func:`wheeled_vehicle` tests that on a solution computed **without** the constraint
(the no-option run's first pass), over the epochs where GNSS fixes aided it, the vehicle moved fast
enough for its course to mean something and the attitude was known:

* epochs: a GNSS fix was used, speed ≥ :data:`MIN_SPEED_M_S`, roll, pitch and heading σ ≤
  :data:`MAX_ATT_SIGMA_DEG`, speed ≤ :data:`MAX_SPEED_M_S` everywhere (faster than any road vehicle:
  not wheeled);
* the body axis u of the motion: the principal eigenvector of Σ ûûᵀ over the unit body-frame velocities û
  (the mounting, and driving backwards, do not matter);
* the angle δ of each û off ±u; **wheeled** when the median δ ≤ :data:`MEDIAN_DEG` and the 90th percentile
  ≤ :data:`P90_DEG`, over at least :data:`MIN_EPOCHS_S` seconds of such epochs that include
  :data:`MIN_TURN_DEG` of turning (a straight line cannot tell a crab angle from a mounting).

The bounds are physics, not fits: a road vehicle's sideslip in normal driving stays below about 1° (a
lateral acceleration of 0.3 g on tyres of ~0.1 g/deg cornering stiffness per axle load; Gillespie,
*Fundamentals of Vehicle Dynamics*, 1992, ch. 6) and its IMU, ≤ 2 m from the rear axle, adds ω × l
(≤ 2° at 10 m/s in a 0.15 rad/s turn): the median of a car's δ is the attitude error (σ ≤ 1° here) plus
≤ 1° of slip, so ≤ 2°; its 90th percentile, with turns and the attitude's 1.6σ, ≤ 5°. Against that, the
drift angle of a ship making 10 kn in a 1-kn cross current is 6° (varying with its heading), an
aircraft's crab in a 20-kn crosswind at 100 kn 11° (and its angle of attack changes with every climb),
and a hand-held device turns by tens of degrees against its path. The test is one-sided: a vehicle it
calls wheeled gets the NHC with the cautious σ of :data:`NHC_SIGMA_M_S` (twice the car preset's) and the
NIS-window re-initialisation that undoes a wrong constraint.
"""

from __future__ import annotations

import numpy as np

from aidnav.nav.rotations import dcm_from_euler

MIN_SPEED_M_S = 3.0
MAX_SPEED_M_S = 70.0  # the car preset's bound (250 km/h)
MAX_ATT_SIGMA_DEG = 1.0
MEDIAN_DEG = 2.0
P90_DEG = 5.0
MIN_EPOCHS_S = 30.0
MIN_TURN_DEG = 90.0
#: NHC σ of a vehicle found wheeled by this test [m/s]: the configuration default, twice the car preset's
NHC_SIGMA_M_S = 0.1
#: σ per axis of the unknown IMU → rear-axle lever arm [m] (an IMU anywhere in a car or van body)
NHC_LEVER_ARM_SIGMA_M = 1.0

__all__ = ["NHC_LEVER_ARM_SIGMA_M", "NHC_SIGMA_M_S", "no_option_constraint", "wheeled_vehicle"]


def wheeled_vehicle(time, vel, rph, std_att, aided_times) -> dict:
    """The test of the module doc on a solution without the NHC: ``time`` (N,) [s], ``vel`` (N, 3) ENU
    [m/s], ``rph`` (N, 3) and ``std_att`` (N, 3) [rad] (IMU body RFU), ``aided_times`` the times of the
    GNSS fixes the filter used. Returns a dict: ``wheeled`` (bool), ``reason`` (one line), ``median_deg``,
    ``p90_deg``, ``seconds``, ``turn_deg``, ``axis`` (u in the body frame, or None)."""
    time = np.asarray(time, float)
    out = {"wheeled": False, "median_deg": np.nan, "p90_deg": np.nan, "seconds": 0.0, "turn_deg": 0.0,
           "axis": None}
    if len(time) < 2 or len(aided_times) < 2:
        return dict(out, reason="too short a log to tell")
    speed = np.hypot(vel[:, 0], vel[:, 1])
    vmax = float(np.nanmax(speed))
    if vmax > MAX_SPEED_M_S:
        return dict(out, reason=f"speed up to {vmax:.0f} m/s, above any road vehicle's {MAX_SPEED_M_S:g} m/s")
    k = np.clip(np.searchsorted(time, np.asarray(aided_times, float)), 0, len(time) - 1)
    k = np.unique(k)
    sa = np.asarray(std_att, float)[k]
    ok = (speed[k] >= MIN_SPEED_M_S) & np.all(np.isfinite(sa), axis=1) & \
        np.all(sa <= np.radians(MAX_ATT_SIGMA_DEG), axis=1)
    k = k[ok]
    if len(k) < 3:
        return dict(out, reason=f"too few moving epochs with a known attitude ({len(k)}) to tell")
    dt = float(np.median(np.diff(np.asarray(aided_times, float))))
    seconds = len(k) * dt
    vb = np.empty((len(k), 3))
    for j, i in enumerate(k):
        vb[j] = dcm_from_euler(rph[i, 0], rph[i, 1], rph[i, 2]).T @ vel[i]
    ub = vb / np.linalg.norm(vb, axis=1)[:, None]
    w, v = np.linalg.eigh(ub.T @ ub)
    u = v[:, np.argmax(w)]
    delta = np.degrees(np.arccos(np.clip(np.abs(ub @ u), 0.0, 1.0)))
    course = np.unwrap(np.arctan2(vel[k, 0], vel[k, 1]))
    turn = float(np.degrees(np.max(course) - np.min(course)))
    med, p90 = float(np.median(delta)), float(np.percentile(delta, 90))
    out.update(median_deg=med, p90_deg=p90, seconds=seconds, turn_deg=turn, axis=u)
    if seconds < MIN_EPOCHS_S or turn < MIN_TURN_DEG:
        return dict(out, reason=f"too little motion to tell ({seconds:.0f} s above {MIN_SPEED_M_S:g} m/s "
                    f"with a known attitude, {turn:.0f} deg of turning; needs {MIN_EPOCHS_S:g} s, "
                    f"{MIN_TURN_DEG:g} deg)")
    wheeled = med <= MEDIAN_DEG and p90 <= P90_DEG
    verdict = "wheeled: velocity along one body axis" if wheeled else "not a wheeled vehicle"
    return dict(out, wheeled=wheeled,
                reason=f"{verdict} (angle of the body-frame velocity off its axis: median {med:.2f} deg, "
                       f"90th percentile {p90:.2f} deg; wheeled needs <= {MEDIAN_DEG:g} / {P90_DEG:g} deg; "
                       f"over {seconds:.0f} s moving, {turn:.0f} deg of turning)")


def no_option_constraint(imu, gnss, cfg, withheld, events, aids=(), first_events=None):
    """Issue 35, item 6: with no ``constraints`` section in the configuration and no vehicle preset (no
    option), decide from the log whether the non-holonomic constraint is safe: a first pass without it
    (forward filter), then :func:`wheeled_vehicle` on its solution; a wheeled vehicle
    gets the NHC with the cautious σ of :data:`NHC_SIGMA_M_S`, the unknown lever
    arm's σ, the mounting estimated (coarse from the log, then a state) and the NIS-window
    re-initialisation (``gnss.nis_window`` 10, unless stated), which undoes a wrong constraint. The
    decision goes into ``events``. Returns (the configuration to use, the first pass's
    :class:`~aidnav.filters.result.FilterResult` when the configuration is unchanged (the run itself
    when no smoother is wanted) or None); the first pass's own events are ``first_events``' (a list
    passed in, or dropped)."""
    from .loose import run_loose, to_trajectory  # lazy: filters.loose imports the engine (numba)

    if "constraints" in cfg.model_fields_set or cfg.constraints.nhc:
        return cfg, None
    first_events = first_events if first_events is not None else []
    res = run_loose(imu, gnss, cfg, withheld=withheld, smooth=False, events=first_events, aids=aids)
    tr = to_trajectory(res)
    used = res.records["pos_status"] == 1
    d = wheeled_vehicle(tr.time, tr.vel, tr.rph, tr.std_att, np.asarray(gnss.time)[used])
    if not d["wheeled"]:
        events.append(f"vehicle from the log: NHC off, {d['reason']}")
        return cfg, res
    con = cfg.constraints.model_copy(update={"nhc": True, "nhc_sigma_m_s": NHC_SIGMA_M_S,
                                             "nhc_lever_arm_sigma_m": NHC_LEVER_ARM_SIGMA_M})
    upd = {"constraints": con}
    if "nis_window" not in cfg.gnss.model_fields_set:
        upd["gnss"] = cfg.gnss.model_copy(update={"nis_window": 10})
    events.append(f"vehicle from the log: {d['reason']}: NHC on with sigma {NHC_SIGMA_M_S:g} m/s "
                  f"(lever arm sigma {NHC_LEVER_ARM_SIGMA_M:g} m), mounting estimated, NIS-window "
                  "re-initialisation (10 fixes); a constraints section in the configuration decides instead")
    return cfg.model_copy(update=upd), None
