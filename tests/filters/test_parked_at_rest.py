"""Issue 35 (session 11): at rest with position-only fixes, what the filter cannot know stays unknown.

The matrix's condition "parked 10 min then driving" (consumer IMU, 10-Hz position-only fixes) with the
matched configuration, cut to its first 200 s parked. At a standstill with position fixes:

* the tilt and the accelerometer bias are seen only as their sum (φ·g + C_b^n b_a): whatever the filter
  learns, the tilt σ per axis cannot fall below the closed form of one observed sum of two independent
  priors, (σ_φ0⁻² + (σ_ba/g)⁻²)^(-1/2) (0.42° here); the bias's random walk only raises it;
* the heading and the z gyro bias: a consumer gyro (horizontal bias σ far above the Earth rate Ω cos L)
  cannot gyrocompass, so the heading's σ grows with the z bias's, σ_ψ(t) ≥ (σ_ψ0² + (σ_bz·t)²)^(1/2) less
  the z bias's own small learning (asserted at 90 % of it);
* and 3σ covers the roll, pitch and heading errors.

On main 85e1138 five of the six cases fail: the tilt σ falls to 0.31° and 0.30° (bound 0.42°), the heading
σ is 9.3° and 9.9° at 120 s (bound 12.4°), and seed 1's roll is covered at 35.5 % of the epochs (1.0–1.6°
off at σ 0.3°; over the full 600 s parked seeds 2 and 5 reach heading errors of +50° and −93° at σ 7–10°):
the linearised model let the
heading that wanders at rest turn the accelerometer bias's image against a still tilt, and its Earth-rate
column against the gyro bias's image, and so separated what the sensors do not separate
(:func:`aidnav.filters.engine._turn_tilt_at_rest`, :func:`aidnav.filters.engine._hold_heading_at_rest`).
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.experiments import consistency_matrix as cm
from aidnav.filters.loose import run_loose
from aidnav.filters.result import to_trajectory
from aidnav.units import DEG, DEG_H

PARKED_S = 200.0
COND = cm.variant(cm.condition("parked 10 min then driving"),
                  segments=({"type": "static", "duration_s": PARKED_S},))


@pytest.fixture(scope="module", params=[1, 5])
def parked(request):
    run = cm.simulate_condition(COND, request.param)
    cfg = cm.config_for("matched", COND, run)
    return run, cfg, run_loose(run.imu, run.gnss, cfg)


def test_tilt_sigma_keeps_what_the_accelerometer_bias_allows(parked):
    run, cfg, res = parked
    s_phi = cfg.init.attitude_sigma_deg[0] * DEG
    s_ba = cfg.imu.accel_bias_sigma_ug * 1e-6  # [g] = [rad] of tilt
    bound = 1.0 / np.sqrt(1.0 / s_phi ** 2 + 1.0 / s_ba ** 2)
    late = res.time >= res.time[0] + 60.0
    tilt = np.sqrt(0.5 * (res.pdiag[late, 0] + res.pdiag[late, 1]))  # per axis (the trace: turn-invariant)
    assert tilt.min() >= 0.97 * bound, (np.degrees(tilt.min()), np.degrees(bound))


def test_heading_sigma_grows_with_the_z_gyro_bias(parked):
    run, cfg, res = parked
    s0 = cfg.init.attitude_sigma_deg[2] * DEG
    s_bz = cfg.imu.gyro_bias_sigma_deg_h * DEG_H
    for t in (60.0, 120.0, 190.0):
        k = np.searchsorted(res.time, res.time[0] + t)
        bound = np.sqrt(s0 ** 2 + (s_bz * t) ** 2)
        assert np.sqrt(res.pdiag[k, 2]) >= 0.9 * bound, (t, np.degrees(np.sqrt(res.pdiag[k, 2])),
                                                           np.degrees(bound))


def test_attitude_errors_covered(parked):
    run, cfg, res = parked
    traj = to_trajectory(res)
    tt = run.truth.time
    ev = np.arange(tt[0], tt[-1], 1.0)
    k = np.clip(np.searchsorted(traj.time, ev), 0, len(traj.time) - 1)
    j = np.clip(np.searchsorted(tt, traj.time[k]), 0, len(tt) - 1)
    err = traj.rph[k] - run.truth.rph[j]
    err = (err + np.pi) % (2 * np.pi) - np.pi
    cover = np.mean(np.abs(err) <= 3.0 * traj.std_att[k], axis=0)
    assert np.all(cover >= 0.95), cover
