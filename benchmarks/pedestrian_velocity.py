"""Issue 40 (report only): the tight filter's velocity and its σ on a simulated pedestrian with the truth.

The pedestrian of :mod:`aidnav.sim.pedestrian` (speed 1.3 m/s ± 0.2 m/s at 1.9 steps/s, a vertical bounce,
turns; the consumer IMU grade; GPS + Galileo raw GNSS at 4 Hz with carrier phase of σ 5 mm), run through
``aidnav tight``'s solution (:func:`aidnav.estimators.tight_solution.process_tight`, no configuration),
forward and smoothed. Printed per seed and pooled, while walking:

* **intervals**: the estimate's mean velocity over each GNSS interval (0.25 s) minus the truth's (the
  truth's position difference), as the walk is scored (:func:`aidnav.analysis.velocity_reference.
  interval_velocity_errors`): horizontal RMS, the 3σ coverage per ENU axis with the filter's σ at the
  interval's middle, and the mean (e/σ)² per axis (1 for an honest σ; its χ² band from the number of
  independent intervals is printed);
* **instants**: the velocity error at the filter's outputs every 0.25 s against the truth: the same figures.

Cases (:data:`CASES`): the default (the IMU-GNSS time offset from the specific force's norm,
``gnss.time_offset_from_phase``); the IMU's stamps 25 ms late; both without that offset (session 15's
model: a late IMU reproduces the walk's optimistic velocity σ); without the Doppler rows.
Targets (issue 40, the walk's velocity σ): 3σ coverage ≥ 95 % per axis, forward and smoothed.
``--seeds N`` (default 3); ``--cases "a;b"`` (semicolon-separated: a name may hold a comma; default
every case of :data:`CASES`).
"""

from __future__ import annotations

import argparse
import os

import numpy as np

from aidnav.analysis.velocity_reference import interval_velocity_errors
from aidnav.data import ImuData
from aidnav.estimators.tight_solution import process_tight
from aidnav.filters.tight import TightConfig, to_trajectory
from aidnav.sim.pedestrian import simulate_pedestrian

#: name: (TightConfig keyword arguments, the IMU's stamps late by this much [s]: an IMU-GNSS time offset the
#: tight filter has no state for)
_OFF = {"gnss": {"time_offset_from_phase": False}}  # session 15's model: the IMU stamps taken as they are
CASES = {"default": ({}, 0.0), "imu late 25 ms": ({}, 0.025), "no offset from the phase": (_OFF, 0.0),
         "no offset from the phase, imu late 25 ms": (_OFF, 0.025),
         "no Doppler rows": ({"gnss": {"use_rate": False}}, 0.0)}


def score(res, run):
    """(interval errors (K, 3), their σ (K, 3), instant errors (M, 3), their σ (M, 3)) while walking."""
    tr = to_trajectory(res)
    truth, obs = run.truth, run.obs
    t = obs.time
    lat, lon, h = (np.interp(t, truth.time, a) for a in (truth.lat, truth.lon, truth.height))
    iv = interval_velocity_errors(res.time, res.state[:, 3:6], t, lat, lon, h)
    mid = 0.5 * (iv.t_start + iv.t_end)
    walk = (iv.t_start >= run.walk[0] + 1.0) & (iv.t_end <= run.walk[1] - 1.0)
    sv = np.column_stack([np.interp(mid, tr.time, tr.std_vel[:, i]) for i in range(3)])
    ti = mid[walk]
    k = np.clip(np.searchsorted(tr.time, ti), 0, len(tr.time) - 1)
    vt = np.column_stack([np.interp(tr.time[k], truth.time, truth.vel[:, i]) for i in range(3)])
    return iv.err[walk], sv[walk], tr.vel[k] - vt, tr.std_vel[k]


def figures(e, s):
    """(horizontal RMS, coverage (3,) %, mean (e/σ)² (3,))."""
    return (float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2))), 100 * np.mean(np.abs(e) <= 3 * s, axis=0),
            np.mean((e / s) ** 2, axis=0))


def line(name, e, s):
    h, cov, nees = figures(e, s)
    return (f"{name}: H RMS {h:.4f} m/s, V RMS {np.sqrt(np.mean(e[:, 2] ** 2)):.4f}, median sigma E/N/U "
            f"{' / '.join(f'{x:.4f}' for x in np.median(s, axis=0))}, 3-sigma coverage "
            f"{' / '.join(f'{x:.1f}' for x in cov)} % (target >= 95), mean (e/sigma)^2 "
            f"{' / '.join(f'{x:.2f}' for x in nees)} ({len(e)})")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--cases", default=";".join(CASES), help="semicolon-separated names of CASES")
    a = ap.parse_args()
    print(f"simulated pedestrian, aidnav tight no configuration; load {os.getloadavg()[0]:.2f}")
    cases = [c.strip() for c in a.cases.split(";") if c.strip()]
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        ap.error(f"unknown case(s) {unknown}; known: {'; '.join(CASES)}")
    for case in cases:
        pooled = {False: [], True: []}
        for seed in range(a.seeds):
            run = simulate_pedestrian(seed)
            kw, late = CASES[case]
            if late:
                run.imu = ImuData(run.imu.time + late, run.imu.dtheta, run.imu.dv, t0=run.imu.t0 + late)
            for smooth in (False, True):
                c0 = os.times()
                cfg = TightConfig(**kw) if kw else TightConfig()
                res, _ = process_tight(run.imu, run.obs, run.eph, cfg, smooth=smooth)
                c1 = os.times()
                sc = score(res, run)
                pooled[smooth].append(sc)
                kind = "smoothed" if smooth else "forward"
                print(f"{case} seed {seed} {kind} (CPU {c1.user - c0.user:.1f} s)", flush=True)
                print("   ", line("intervals", sc[0], sc[1]), flush=True)
                print("   ", line("instants ", sc[2], sc[3]), flush=True)
        for smooth in (False, True):
            kind = "smoothed" if smooth else "forward"
            e, s, ei, si = (np.concatenate([p[i] for p in pooled[smooth]]) for i in range(4))
            print(f"{case}, {kind}, {a.seeds} seeds pooled:")
            print("   ", line("intervals", e, s))
            print("   ", line("instants ", ei, si), flush=True)
    print(f"load {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
