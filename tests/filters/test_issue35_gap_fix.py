"""Issue 35, item 3: the covariance bound of a 30-s IMU gap gives way to the first fix after the gap,
whichever side of the first IMU sample after the gap the time offset puts that fix.

The matrix's condition "imu gap 30 s in a turn" (consumer IMU, 1 Hz position + velocity fixes, the gap in
the middle of a 180° turn) with the matched configuration, one seed, and the IMU–GNSS time offset stated
(no offset state) 20 ms off the truth either way: with −20 ms the IMU samples are stamped 20 ms early, so
the first fix after the gap (at the gap's end) is due 20 ms *after* the first IMU sample after it; with
+20 ms, 20 ms before. Before the fix (session 8's engine), the negative case left the first outputs after
the gap with the motion bound's σ (the fix 1 s before the gap's end, moved back over a second of unknown
motion) until the next node; now the gap's closing node uses the nearer fix (moved by 20 ms, R grown by
the unmodelled motion a·Δt²/2) and the first output after the gap is already aided: its horizontal σ is
that of a fix (≤ 2 m), and 3σ covers its error, with either sign.

With the offset *stated* −20 ms, main (b338b4c) used the fix 0.98 s before the gap's end at the closing
node, moved back over that second without the unmodelled motion: its σ was small and did not cover the
error (the −20 ms case fails there; +20 ms passes). The failure of the issue needs the time-offset
*state*: the skip rule measures a record's age by its tag, its due time is tag − d̂, so with d̂ < 0 the fix
1 s before is skipped while the one at the gap's end is due just after the node. The last test is that
case as the matrix runs it (no option, seeds 0 and 1 of the condition, with the GNSS tags 50 ms early so
that the offset estimates are negative — asserted, so the test cannot silently lose its case): on main
seed 0's outputs after the gap carried the motion bound's σ (4.2 km; the cell's position ratio 0.01–0.05).
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.experiments import consistency_matrix as cm
from aidnav.filters.gnss_errors import choose_gnss_errors
from aidnav.filters.loose import run_loose
from aidnav.filters.result import to_trajectory
from aidnav.filters.wheeled import no_option_constraint
from aidnav.nav.earth import lla_difference_enu

COND = cm.condition("imu gap 30 s in a turn")


@pytest.fixture(scope="module")
def gap_run():
    return cm.simulate_condition(COND, 0)


def _check_after_gap(run, tr, shift_s, bound_m):
    """Horizontal σ ≤ ``bound_m`` over the first 0.5 s of outputs after the gap, 3σ covering the error
    (the outputs are stamped ``shift_s`` off the truth's time)."""
    t_end = run.imu.time[0] + COND.imu_gap[0] + COND.imu_gap[1]  # first IMU sample after the gap
    first = np.flatnonzero(tr.time >= t_end + shift_s - 0.2)[:70]
    first = first[tr.time[first] > t_end - 1.0]
    sh = np.hypot(tr.std_pos[first, 0], tr.std_pos[first, 1])
    assert sh.max() <= bound_m, f"horizontal sigma after the gap up to {sh.max():.1f} m"
    t = run.truth
    it = np.searchsorted(t.time, tr.time[first] - shift_s - 1e-6)
    e, n, _ = lla_difference_enu(tr.lat[first], tr.lon[first], tr.height[first], t.lat[it], t.lon[it],
                                 t.height[it])
    assert np.all(np.abs(e) <= 3 * tr.std_pos[first, 0]) and np.all(np.abs(n) <= 3 * tr.std_pos[first, 1])


@pytest.mark.parametrize("offset_s", [-0.02, 0.02])
def test_first_fix_after_an_imu_gap_bounds_the_sigma_whatever_the_offset_sign(gap_run, offset_s):
    run = gap_run
    cfg = cm.config_for("matched", COND, run)
    cfg = cfg.model_copy(update={"imu": cfg.imu.model_copy(update={"time_offset_s": offset_s})})
    events: list[str] = []
    tr = to_trajectory(run_loose(run.imu, run.gnss, cfg, events=events))
    assert any("IMU gap of 30" in e for e in events)
    _check_after_gap(run, tr, offset_s, 2.0)


#: the GNSS time tags of the last test are this much early [s]: the IMU stamps need it, d̂ < 0
TAG_SHIFT_S = -0.05


@pytest.mark.parametrize("seed", [0, 1])
def test_gap_with_a_negative_time_offset_estimate(seed):
    """No option, as the matrix runs it, with the GNSS tags :data:`TAG_SHIFT_S` early (a true offset <
    0); the offset estimate d̂ < 0 (asserted); the outputs after the gap: horizontal σ ≤ 10 m (the fix
    20–120 ms after the node, moved back with the velocity's σ and the unmodelled motion) and covering.
    (Until session 12 the tags were not shifted: the case needed seeds whose estimate of a zero offset
    came out negative, −0.01…−0.03 s; with the offset considered, not estimated, while the heading is held
    — ``engine._consider_timing`` — those estimates are +0.014 and +0.025 s, and a true offset makes the
    case instead of the estimation error.)"""
    run = cm.simulate_condition(COND, seed)
    run.gnss.time = run.gnss.time + TAG_SHIFT_S
    cfg = no_option_constraint(run.imu, run.gnss, cm.config_for("none", COND, run), None, [])[0]
    cfg = choose_gnss_errors(run.imu, run.gnss, cfg, None, [])
    events: list[str] = []
    res = run_loose(run.imu, run.gnss, cfg, events=events)
    d_hat = [float(e.split()[4]) for e in events if e.startswith("IMU time offset estimated")]
    assert len(d_hat) == 1 and d_hat[0] < 0.0, events
    _check_after_gap(run, to_trajectory(res), TAG_SHIFT_S, 10.0)
