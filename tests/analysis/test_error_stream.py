"""The streamed evaluation (aidnav.analysis.error_stream) against the whole-trajectory functions.

A synthetic estimate (100 Hz, with gaps, heading through north, σ columns) and reference (10 Hz, epochs
between and on estimate epochs, some outside the estimate's span, one with a non-finite position) are
cut into pieces much smaller than the logs; the streamed statistics, fractions within σ and NEES report
must equal what trajectory_errors → error_statistics / fraction_within_sigma / consistency_report give on
the whole trajectories: bit for bit while a statistics row is summarised in memory, to 1e-12 relative
(the order of the additions) when the values are read back in chunks (``cap`` below the count), with the
95th percentile, the maximum and the counts exact either way.
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.analysis.consistency import consistency_report, nees
from aidnav.analysis.error_stream import order_statistics, percentile_of, stream_errors
from aidnav.analysis.errors import error_statistics, fraction_within_sigma, trajectory_errors
from aidnav.data import Trajectory
from aidnav.io.stream import TrajectoryChunks


def _logs(n=6000, lon0_deg=114.0, seed=3):
    rng = np.random.default_rng(seed)
    t = 1000.0 + 0.01 * np.arange(n)
    t = np.delete(t, np.r_[2000:2100, 4000:4003])  # a 1-s gap and a short one
    m = len(t)
    lat = np.radians(30.0) + 1e-6 * np.sin(t / 7.0)
    lon = np.radians(lon0_deg) + 2e-6 * (t - t[0])
    lon = (lon + np.pi) % (2 * np.pi) - np.pi
    h = 50.0 + np.sin(t / 3.0)
    vel = np.column_stack([np.cos(t), np.sin(t), 0.1 * t % 1.0])
    rph = np.column_stack([0.01 * np.sin(t), 0.02 * np.cos(t), (0.05 * (t - t[0]) - 0.3) % (2 * np.pi)])
    sp = np.abs(rng.normal(0.5, 0.1, (m, 3)))
    sp[100:110, 0] = 0.0  # σ = 0: left out of the NEES
    est = Trajectory(t, lat + rng.normal(0, 5e-8, m), lon + rng.normal(0, 5e-8, m), h + rng.normal(0, 0.3, m),
                     vel + rng.normal(0, 0.05, (m, 3)), (rph + rng.normal(0, 1e-3, (m, 3))) % (2 * np.pi),
                     std_pos=sp, std_vel=np.full((m, 3), 0.05), std_att=np.full((m, 3), 1e-3))
    tr = np.concatenate([[990.0, 995.0], 1000.0 + 0.1 * np.arange(600) + 0.0037, t[::37], [1070.0, 1080.0]])
    tr = np.unique(tr)
    f = np.interp
    ref_lat, ref_lon, ref_h = f(tr, t, lat), f(tr, t, lon), f(tr, t, h)
    ref_lat[50] = np.nan  # a reference epoch without a position
    ref = Trajectory(tr, ref_lat, ref_lon, ref_h, np.column_stack([f(tr, t, vel[:, i]) for i in range(3)]),
                     np.column_stack([f(tr, t, rph[:, i]) for i in range(3)]))
    return est, ref


def _whole(est, ref):
    e = trajectory_errors(est, ref)
    sp = np.where(e.std_pos > 0, e.std_pos, np.nan)
    cov = np.zeros((len(e), 3, 3))
    cov[:, np.arange(3), np.arange(3)] = sp**2
    return e, consistency_report(nees(e.pos, cov), 3)


class _Counted(TrajectoryChunks):
    """Pieces of a whole trajectory, recording the largest piece handed on."""

    largest = 0

    def _batches(self):
        for c in super()._batches():
            _Counted.largest = max(_Counted.largest, len(c))
            yield c


@pytest.mark.parametrize("cap", [1 << 20, 97])
@pytest.mark.parametrize("lon0", [114.0, 179.9995])  # the second crosses ±180° in the estimate
def test_streamed_equals_whole(cap, lon0):
    est, ref = _logs(lon0_deg=lon0)
    e, rep = _whole(est, ref)
    _Counted.largest = 0
    pieces = []
    s = stream_errors(_Counted(est, 333), _Counted(ref, 41), cap=cap, on_piece=pieces.append)
    assert 0 < _Counted.largest <= 333 < len(est) // 10  # nothing longer than a piece went through
    assert s.counts() == e.counts() and s.notes == e.notes
    assert s.n_outside == 4 and s.n_gap > 0 and s.n_invalid == 1  # every exclusion is exercised
    assert (s.t0, s.t1) == (e.time[0], e.time[-1])
    cols = {k: np.concatenate([p.columns()[k] for p in pieces]) for k in e.columns()}
    exact = cap > len(e) and lon0 < 179
    for k, v in e.columns().items():  # the per-epoch errors (errors.csv)
        np.testing.assert_allclose(cols[k], v, rtol=0 if exact else 1e-12, atol=0 if exact else 1e-9)
    want = error_statistics(e)
    assert list(s.statistics.index) == list(want.index)
    assert (s.statistics[["n", "unit"]] == want[["n", "unit"]]).all().all()
    num = ["RMS", "mean", "std", "p95", "max"]
    if exact:
        assert (s.statistics[num].to_numpy() == want[num].to_numpy()).all()
    else:
        np.testing.assert_allclose(s.statistics[num].to_numpy(), want[num].to_numpy(), rtol=1e-12, atol=1e-12)
    if lon0 < 179:  # the percentile and the maximum by selection: exact
        assert (s.statistics[["p95", "max"]].to_numpy() == want[["p95", "max"]].to_numpy()).all()
    for k in (1.0, 3.0):
        w = fraction_within_sigma(e, k)
        assert s.within[k].equals(w) if lon0 < 179 else (s.within[k]["n"] == w["n"]).all()
    got, ref_rep = s.nees.to_dict(), rep.to_dict()
    mean_g, mean_w = got.pop("mean"), ref_rep.pop("mean")
    assert got == ref_rep
    assert mean_g == pytest.approx(mean_w, rel=0 if exact else 1e-12)


def test_chunk_size_does_not_change_the_result():
    est, ref = _logs()
    a = stream_errors(TrajectoryChunks(est, 10**6), TrajectoryChunks(ref, 10**6))
    b = stream_errors(TrajectoryChunks(est, 7), TrajectoryChunks(ref, 3))
    assert a.statistics.equals(b.statistics) and a.counts() == b.counts()


def test_figure_copy_is_decimated_and_bounded():
    est, ref = _logs()
    e = trajectory_errors(est, ref)
    s = stream_errors(TrajectoryChunks(est, 500), TrajectoryChunks(ref, 50), figure_points=100)
    assert 50 < len(s.figure.time) <= 100
    stride = int(np.round(np.median(np.diff(np.searchsorted(e.time, s.figure.time)))))
    np.testing.assert_array_equal(s.figure.time, e.time[::stride])
    full = stream_errors(TrajectoryChunks(est, 500), TrajectoryChunks(ref, 50))
    np.testing.assert_array_equal(full.figure.pos, e.pos)  # under the limit: the whole series


def test_order_statistics_exact_with_small_cap():
    rng = np.random.default_rng(0)
    for x in (np.abs(rng.standard_normal(5001)), np.round(np.abs(rng.standard_cauchy(4000)), 1),
              np.full(3000, 0.25)):
        chunks = [x[i:i + 128] for i in range(0, len(x), 128)]

        def read(chunks=chunks):
            return iter(chunks)

        srt = np.sort(x)
        ks = [0, 17, len(x) // 2, len(x) - 1]
        got = order_statistics(read, len(x), ks, 0.0, float(x.max()), cap=64)
        assert [got[k] for k in ks] == [srt[k] for k in ks]
        n, top = len(x), float(x.max())
        p = percentile_of(lambda k, n=n, top=top, read=read: order_statistics(read, n, k, 0.0, top, cap=64),
                          n, 95)
        assert p == np.percentile(x, 95)


def test_time_checks_across_pieces():
    est, ref = _logs()
    bad = Trajectory(*(np.array(getattr(ref, k), copy=True) for k in
                       ("time", "lat", "lon", "height", "vel", "rph")))
    bad.time[40] = bad.time[39]  # in a later piece than the first (pieces of 10)
    with pytest.raises(ValueError, match="reference: time must be strictly increasing"):
        stream_errors(TrajectoryChunks(est, 100), TrajectoryChunks(bad, 10))
    with pytest.raises(ValueError, match="estimate trajectory is empty"):
        stream_errors(TrajectoryChunks(Trajectory(*(np.zeros((0, 3)) if k in ("vel", "rph") else np.zeros(0)
                                                    for k in ("time", "lat", "lon", "height", "vel", "rph"))),
                                       10), TrajectoryChunks(ref, 10), max_dt=1.0)
