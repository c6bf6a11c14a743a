"""The streamed reading of ``aidnav characterise`` (issue 29): a uniform interchange Parquet log read in
batches straight into its rates gives the characterisation of the whole-log path, to the last bit; other
logs (jitter, gaps, rates, motion) take or match the whole-log path."""

from __future__ import annotations

import json

import numpy as np
import pytest

from aidnav.analysis.noise_fit import file_job as FJ
from aidnav.analysis.noise_fit.prepare import uniform_interval
from aidnav.data import ImuData
from aidnav.io.interchange import write_imu
from aidnav.sim.imu import ImuSpec, corrupt_imu

SPEC = ImuSpec.from_units(arw_deg_sqrt_h=0.2, vrw_m_s_sqrt_h=0.05, gyro_bias_instability_deg_h=5.0,
                          accel_bias_instability_ug=50.0, bias_corr_time_s=60.0)


def _log(seed: int, seconds: float = 900.0, fs: float = 100.0, t0: float = 1000.0, jitter: float = 0.0,
         turn: bool = False) -> ImuData:
    n = int(round(seconds * fs))
    rng = np.random.default_rng(seed)
    dt = np.full(n, 1.0 / fs) * (1.0 + jitter * rng.uniform(-1.0, 1.0, n))
    t = t0 + np.cumsum(dt)
    w = np.zeros((n, 3))
    if turn:  # a 90° turn about z from 400 s to 410 s: motion, cut off
        w[(t > t0 + 400.0) & (t <= t0 + 410.0), 2] = np.pi / 20.0
    truth = ImuData(t, w * dt[:, None], np.column_stack([np.zeros((n, 2)), 9.80665 * dt]), t0=t0)
    return corrupt_imu(truth, SPEC, np.random.default_rng(seed + 1))[0]


def _both_paths(tmp_path, monkeypatch, imu: ImuData, rows: int = 7000):
    """noise.json of the streamed path (batches of ``rows``) and of the whole-log path on the same file."""
    log = write_imu(imu, tmp_path / "static.parquet")
    monkeypatch.setattr(FJ, "STREAM_ROWS", rows)
    streamed = FJ._uniform_rates_streamed(log)
    ch1, _ = FJ.characterise_file(log, tmp_path / "a")
    with monkeypatch.context() as m:
        m.setattr(FJ, "_uniform_rates_streamed", lambda path: None)
        ch2, _ = FJ.characterise_file(log, tmp_path / "b")
    j1 = json.loads((tmp_path / "a" / "noise.json").read_text())
    j2 = json.loads((tmp_path / "b" / "noise.json").read_text())
    return streamed, (ch1, j1), (ch2, j2)


def test_streamed_rates_equal_the_whole_log_path(tmp_path, monkeypatch):
    imu = _log(1)
    streamed, (ch1, j1), (ch2, j2) = _both_paths(tmp_path, monkeypatch, imu)
    assert streamed is not None
    rates, dt, t_start, base0, events, work = streamed
    assert work.dtype == np.float64 and len(work) >= len(rates) + 1
    # the rates are the increments over their own intervals, bit for bit (13 batches of 7000 rows)
    d = np.diff(np.r_[imu.t0, imu.time])
    np.testing.assert_array_equal(rates, np.column_stack([imu.dtheta, imu.dv]) / d[:, None])
    assert dt == np.median(d) and t_start == imu.t0 and base0 == imu.time[0] and events == []
    assert j1 == j2
    for a, b in zip(ch1.axes, ch2.axes, strict=True):
        np.testing.assert_array_equal(a.adev, b.adev)
        np.testing.assert_array_equal(a.coef, b.coef)


def test_moving_log_streamed_cuts_the_same_static_part(tmp_path, monkeypatch):
    streamed, (ch1, j1), (ch2, j2) = _both_paths(tmp_path, monkeypatch, _log(2, turn=True))
    assert streamed is not None
    assert any("longest static part" in w for w in ch1.warnings)
    assert j1 == j2


def test_jittered_log_takes_the_whole_log_path(tmp_path, monkeypatch):
    streamed, (ch1, j1), (ch2, j2) = _both_paths(tmp_path, monkeypatch, _log(3, seconds=600.0, jitter=0.05))
    assert streamed is None and ch1.resampled and j1 == j2


def test_gap_takes_the_whole_log_path(tmp_path, monkeypatch):
    imu = _log(4, seconds=600.0)
    keep = np.ones(len(imu), bool)
    keep[30_000:30_300] = False
    gappy = ImuData(imu.time[keep], imu.dtheta[keep], imu.dv[keep], t0=imu.t0)
    streamed, (ch1, j1), (ch2, j2) = _both_paths(tmp_path, monkeypatch, gappy)
    assert streamed is None and any("1 gap(s)" in n for n in ch1.notes) and j1 == j2


@pytest.mark.parametrize(("dt", "expected"), [
    ([0.01, 0.01, 0.01, 0.01], 0.01),
    ([0.01, 0.01, 0.010009, 0.01], 0.01),  # 0.09% of jitter: within 0.1%
    ([0.01, 0.01, 0.01002, 0.01], None),  # 0.2%: jitter
    ([0.01, 0.01, 0.02, 0.01], None),  # a gap
    ([0.01, 0.0, 0.01, 0.01], None),  # not increasing
])
def test_uniform_interval(dt, expected):
    assert uniform_interval(np.array(dt)) == expected
