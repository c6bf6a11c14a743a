"""The end-of-outage score (:func:`aidnav.apps.outages.outage_end_errors`, :func:`first_updates`): an
outage whose last withheld fix is stamped at or after the first update after it is ended on the last
output before that update, against the reference interpolated to that output's time (issue 35, session 16,
s35k) — known answers on made-up runs."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from aidnav.apps.outages import first_updates, outage_end_errors
from aidnav.data import GnssData, Trajectory
from aidnav.filters.layout import NAV
from aidnav.nav.earth import radii

LAT0, H, V = 0.7, 100.0, 10.0  # moving east at V m/s: fixes on the truth, the output off it by err(t)


def _err(t):
    """Output's east error: 0.1 (t − a)² inside each outage [2, 6), [7, 9); in the first the output takes
    the next fix at 5.7 s (error 0 from then on)."""
    e = np.zeros_like(t)
    for a, b in ((2.0, 6.0), (7.0, 9.0)):
        m = (t >= a) & (t < b)
        e[m] = 0.1 * (t[m] - a) ** 2
    e[(t >= 5.7) & (t < 6.0)] = 0.0
    return e


def _run():
    _, rn = radii(LAT0)
    k = 1.0 / ((rn + H) * np.cos(LAT0))
    t = np.round(np.arange(0.0, 10.0 + 1e-9, 0.01), 9)
    n = len(t)
    traj = Trajectory(time=t, lat=np.full(n, LAT0), lon=(V * t + _err(t)) * k, height=np.full(n, H),
                      vel=np.zeros((n, 3)), rph=np.zeros((n, 3)), std_pos=np.ones((n, 3)))
    tg = np.arange(0.0, 10.0 + 1e-9, 0.25)
    m = len(tg)
    gnss = GnssData(time=tg, lat=np.full(m, LAT0), lon=V * tg * k, height=np.full(m, H))
    wins = [(2.0, 6.0), (7.0, 9.0)]
    withheld = np.zeros(m, bool)
    for a, b in wins:
        withheld |= (tg >= a) & (tg < b)
    return traj, gnss, withheld, wins


def test_an_end_after_the_update_is_taken_on_the_last_output_before_it():
    traj, gnss, withheld, wins = _run()
    ends = outage_end_errors(traj, gnss, withheld, wins, [5.7, 9.0])
    # first: the last output before 5.7 s is 5.69 s (0.1 · 3.69² m; the reference interpolated to 5.69 s,
    # not the fix at 5.5 s, which is 1.9 m behind); second: its last withheld fix 8.75 s is before 9.0 s
    np.testing.assert_allclose(ends, [0.1 * 3.69 ** 2, 0.1 * 1.75 ** 2], rtol=1e-4)
    # without the update times (or with the update after the last withheld fix): the fix's own error
    old = outage_end_errors(traj, gnss, withheld, wins, None)
    np.testing.assert_allclose(old, [0.0, 0.1 * 1.75 ** 2], atol=1e-6, rtol=1e-4)
    np.testing.assert_allclose(outage_end_errors(traj, gnss, withheld, wins, [5.76, np.nan]), old, atol=1e-6)


def test_first_updates_follow_the_online_offset_and_skip_rejected_fixes():
    """IMU time u every 0.01 s; the online offset estimate is 0 until u = 6.5 s and −0.25 s after (final),
    so the outputs are stamped u − 0.25. The fix tagged 6.0 s (first after [2, 6)) is due at u = 6.0 − 0 →
    output time 5.75 s; after [7, 9) the fix at 9.0 s is rejected and the one at 9.25 s is due at
    u = 9.25 + 0.25 = 9.5 → output time 9.25 s; nothing follows [9.5, 10)."""
    u = np.round(np.arange(0.0, 10.0 + 1e-9, 0.01), 9)
    d = np.where(u < 6.5, 0.0, -0.25)
    tg = np.arange(0.0, 10.0 + 1e-9, 0.25)
    pos = np.ones(len(tg), np.int8)
    pos[tg == 9.0] = 0
    pos[tg >= 9.5] = -1
    vel = np.full(len(tg), -1, np.int8)
    res = SimpleNamespace(time=u - 0.25, bias=d[:, None], state_names=["x"] * NAV + ["time_offset"],
                          records={"pos_status": pos, "vel_status": vel}, gnss_time=tg)
    t_up = first_updates(res, [(2.0, 6.0), (7.0, 9.0), (9.5, 10.0)])
    np.testing.assert_allclose(t_up[:2], [5.75, 9.25], atol=1e-9)
    assert np.isnan(t_up[2])
    # no time-offset state: the update's time is its tag
    res0 = SimpleNamespace(time=u, bias=np.zeros((len(u), 0)), state_names=["x"] * NAV,
                           records={"pos_status": pos, "vel_status": vel}, gnss_time=tg)
    np.testing.assert_allclose(first_updates(res0, [(2.0, 6.0)]), [6.0], atol=1e-9)
