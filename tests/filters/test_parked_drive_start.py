"""Issue 35 (session 12): parked, then driving — the heading a long stop leaves, and the static test's σ.

1. **The drive's start** (matched configuration, the matrix's consumer IMU and 10-Hz position-only fixes,
   parked 300 s): after a stop the heading σ has grown with the z gyro bias (tens of degrees, honestly), so
   the first seconds of acceleration correct the heading by tens of degrees. The tilt error belongs to the
   body's roll and pitch; in the navigation frame it turns with every heading correction the feedback
   applies (the exact composition of the two rotations; the first-order model drops it as second order).
   Left unturned, P's tilt rows — and their covariance with the body-frame accelerometer bias, the one
   sum the stop observed — stay in a frame tens of degrees off, the drive then separates tilt and bias
   along the wrong axes, and the roll σ falls to 0.1–0.2° with the error at 0.8–1.4° (the matrix's parked
   cell, matched: roll 90.6 %, seeds 1, 8, 9 after the drive starts). Asserted: roll and pitch within 3σ
   at ≥ 95 % of the epochs of the drive's first 85 s, per seed.
2. **The static test reads the σ the filter uses** (the review's unmended item): fixes without a receiver
   velocity are static when their position-difference speed over a baseline their σ resolves is below the
   threshold (:func:`aidnav.filters.preprocess.static_baseline_s`). A file that states σ ten times too small
   (σ = 0, floored), with the σ factor the first pass measures (``gnss.pos_std_scale``), must give the
   same flags as the same fixes with their σ stated right; reading the stated σ gave a baseline ten times
   too short, whose speed noise (0.34 m/s) is above the 0.1 m/s threshold: a parked car read as moving.
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.experiments import consistency_matrix as cm
from aidnav.filters.config import LooseConfig
from aidnav.filters.loose import run_loose
from aidnav.filters.preprocess import static_flags
from aidnav.filters.result import to_trajectory

PARKED_S = 300.0
_PARKED = cm.condition("parked 10 min then driving")
COND = cm.variant(_PARKED, segments=tuple([{"type": "static", "duration_s": PARKED_S}]
                                         + [dict(s) for s in _PARKED.segments[1:5]]))


@pytest.mark.parametrize("seed", [1, 8])
def test_tilt_covered_when_the_drive_corrects_the_heading(seed):
    run = cm.simulate_condition(COND, seed)
    res = run_loose(run.imu, run.gnss, cm.config_for("matched", COND, run))
    traj = to_trajectory(res)
    tt = run.truth.time
    ev = np.arange(tt[0] + PARKED_S, tt[-1], 1.0)
    k = np.clip(np.searchsorted(traj.time, ev), 0, len(traj.time) - 1)
    j = np.clip(np.searchsorted(tt, traj.time[k]), 0, len(tt) - 1)
    err = (traj.rph[k] - run.truth.rph[j] + np.pi) % (2 * np.pi) - np.pi
    cover = np.mean(np.abs(err) <= 3.0 * traj.std_att[k], axis=0)
    assert np.all(cover[:2] >= 0.95), cover


def test_static_test_reads_the_sigma_the_filter_uses():
    cond = cm.variant(_PARKED, segments=({"type": "static", "duration_s": 60.0},))
    run = cm.simulate_condition(cond, 0)
    honest = static_flags(run.imu, run.gnss, LooseConfig())
    g = run.gnss
    g.std_pos = g.std_pos / 10.0  # σ understated ten times (the fixes' noise is 0.5 m)
    cfg = LooseConfig(gnss={"pos_std_scale": 10.0})  # what the first pass's σ factor finds
    flags = static_flags(run.imu, g, cfg)
    mid = (run.imu.time > run.imu.time[0] + 15.0) & (run.imu.time < run.imu.time[-1] - 15.0)
    assert honest[mid].mean() > 0.9  # the honest fixes say static away from the ends
    assert np.array_equal(flags, honest)
