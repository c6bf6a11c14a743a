"""Seed 003: the superseded per-axis chase of §4.5 (a sensitivity case beside the total-rotation bound)."""

from __future__ import annotations

import pytest

from aidnav.experiments.reproduce.seed_003 import W_MAX_DEG_S, per_axis_chase


def test_per_axis_chase_closes_each_angle_on_its_own_and_turns_faster_than_w_max():
    """Known answers of the per-axis rule for the §4.5 correction (+0.3°, −0.5°, +2°), w_max 0.5°/s, T_f 1 s:
    heading closes at 2°/w_max = 4 s, pitch and roll at |Δ|/T_f ≈ 1 s; while all three chase, the total
    rotation per interrupt is √(0.5² + 0.3² + 0.5²)·dt ≈ 0.0077° > w_max·dt = 0.005° (why the total bound of
    SPEC §4.2 item 3 is the default)."""
    dt = 0.01
    ch = per_axis_chase(dt=dt)
    assert ch["close_time_s"]["heading"] == pytest.approx(2.0 / W_MAX_DEG_S, abs=dt + 1e-9)
    for a in ("pitch", "roll"):
        assert ch["close_time_s"][a] == pytest.approx(1.0, abs=0.1)
    assert ch["max_rot_deg"] == pytest.approx((0.5**2 + 0.3**2 + 0.5**2) ** 0.5 * dt, rel=0.05)
    assert ch["max_rot_deg"] > 1.5 * W_MAX_DEG_S * dt
    # without yaw the level angles close exactly at |Δ|/T_f (within one interrupt)
    still = per_axis_chase(yaw_rate_deg_s=0.0, dt=dt)
    for a in ("pitch", "roll"):
        assert still["close_time_s"][a] == pytest.approx(1.0, abs=dt + 1e-9)
