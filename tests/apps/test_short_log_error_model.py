"""A log too short for the GNSS error model's test (issue 41, session 10): no first pass, and the summary
says why; the boundary is T/(2τ) = 10 independent samples of a 30-s correlated error (600 s of fixes)."""

from __future__ import annotations

import numpy as np

from aidnav.apps.process import process_logs
from aidnav.apps.process_stream import MIN_ERROR_TEST_SAMPLES, long_enough_for_error_test
from aidnav.data import GnssData
from aidnav.filters.preprocess import GNSS_ERROR_TAU_S

from .test_process_stream import static_log


def _fixes(n, dt):
    t = 100.0 + dt * np.arange(n)
    z = np.zeros(n)
    return GnssData(t, z + 0.5, z + 2.0, z, std_pos=np.full((n, 3), 0.5))


def test_boundary_is_ten_independent_samples():
    assert MIN_ERROR_TEST_SAMPLES * 2 * GNSS_ERROR_TAU_S == 600.0
    for n, dt, ok in ((600, 1.0, True), (599, 1.0, False), (300, 2.0, True), (299, 2.0, False),
                      (3600, 1.0, True), (60, 1.0, False)):
        events = []
        assert long_enough_for_error_test(_fixes(n, dt), 100.0, events) is ok, (n, dt)
        assert bool(events) is not ok
    events = []
    long_enough_for_error_test(_fixes(60, 1.0), 100.0, events)
    assert "fixes cover 60 s, 1.0 independent samples" in events[0]


def test_one_minute_log_runs_no_first_pass(tmp_path):
    imu, gnss, cfg = static_log(tmp_path, 60)
    s = process_logs(imu, gnss, cfg, tmp_path / "o", figures=False, timings=False)
    ev = [e for e in s["events"] if e.startswith("GNSS error model")]
    assert len(ev) == 1 and ev[0].startswith("GNSS error model: not tested")
    assert "first pass over" not in ev[0]
