"""Monte Carlo runs of one sweep point computed together (:func:`aidnav.experiments.runner.run_batch_task`,
:mod:`aidnav.filters.engine_batch`) give exactly the arrays of the one-run-per-call path."""

from __future__ import annotations

import copy

import numpy as np
import pytest

import aidnav.experiments.estimators as est
from aidnav.experiments import runner
from aidnav.experiments.config import parse_experiment
from aidnav.experiments.estimators import _loose_run_config
from aidnav.filters import loose
from aidnav.filters.loose import run_loose, run_loose_batch, shared_times
from aidnav.filters.preprocess import bridge_gaps

from .conftest import TINY

#: one sweep point, 4 runs of a 40 s flight (straight, U-turn, straight), 15-state loose filter
BATCH = {**copy.deepcopy(TINY), "runs": 4, "sweep": {}}
BATCH["sensors"] = {"imu": {"grade": "tactical"}, "gnss": {"rate_hz": 1}}


@pytest.fixture(scope="module")
def point():
    return parse_experiment(copy.deepcopy(BATCH), "batch").points[0]


@pytest.fixture(scope="module")
def sims(point):
    """Simulated runs 0..3 of the point and their filter configurations (initial states drawn per run)."""
    ctx = runner.point_context(point.key, point.doc)
    out = []
    for run in range(4):
        sim, s_est = runner.simulate_run(ctx, run)
        out.append((sim, _loose_run_config(sim, ctx.estimators[0][2], np.random.default_rng(s_est))))
    return out


def test_batch_task_equals_run_by_run(point):
    """A batch task's per-run results (errors, σ, NEES, counters) equal run_task's, bit for bit."""
    batch = runner.run_batch_task(runner.BatchTask(point.key, point.index, (0, 1, 2, 3), point.doc))
    assert [r["run"] for r in batch] == [0, 1, 2, 3]
    for r in batch:
        one = runner.run_task(runner.RunTask(point.key, point.index, r["run"], point.doc))
        a, b = one["estimators"]["loose"], r["estimators"]["loose"]
        for k in ("time", "error", "sigma", "nees"):
            assert a[k].shape == b[k].shape and np.array_equal(a[k], b[k]), k
        assert a["info"] == b["info"]
        assert r["imu_samples"] == one["imu_samples"]
    # the runs differ (their own sensor errors and initial states): the comparison is not vacuous
    e0, e1 = (batch[i]["estimators"]["loose"]["error"] for i in (0, 1))
    assert not np.array_equal(e0, e1)


def test_pool_worker_one_run_task_equals_run_task(point, monkeypatch):
    """In a pool worker a one-run task takes the batched engine (R = 1, the kernels loaded for the batches):
    the same results as run_task's one-run engine, bit for bit."""
    calls = []
    real = loose.run_loose_batch
    monkeypatch.setattr(runner, "_REUSE_BUFFERS", True)
    monkeypatch.setattr(loose, "run_loose_batch", lambda *a: calls.append(len(a[0])) or real(*a))
    monkeypatch.setattr(est, "run_loose_batch", loose.run_loose_batch)  # the name the batch form calls
    (r,) = runner.run_batch_task(runner.BatchTask(point.key, point.index, (2,), point.doc))
    assert calls == [1]  # the batched engine, one run
    one = runner.run_task(runner.RunTask(point.key, point.index, 2, point.doc))
    assert calls == [1]  # run_task: the one-run engine
    a, b = one["estimators"]["loose"], r["estimators"]["loose"]
    for k in ("time", "error", "sigma", "nees"):
        assert a[k].shape == b[k].shape and np.array_equal(a[k], b[k]), k
    assert a["info"] == b["info"]


def test_batched_filter_equals_run_loose(sims):
    """States, covariance diagonals, final covariances and the innovation log (NIS, innovations, S) of
    run_loose_batch equal run_loose's for every run."""
    res = run_loose_batch([s.imu for s, _ in sims], [s.gnss for s, _ in sims], [c for _, c in sims])
    assert res is not None and len(res) == len(sims)
    for (sim, cfg), b in zip(sims, res, strict=True):
        a = run_loose(sim.imu, sim.gnss, cfg)
        for f in ("time", "state", "bias", "pdiag", "node_time", "final_P"):
            assert np.array_equal(getattr(a, f), getattr(b, f)), f
        for k in ("t", "model", "status", "nis", "nu", "s", "ref", "reinit"):
            assert np.array_equal(a.innovations[k], b.innovations[k], equal_nan=True), k
        for k in a.records:
            assert np.array_equal(a.records[k], b.records[k], equal_nan=True), k
        assert a.counts == b.counts and a.events == b.events
        assert np.isfinite(a.innovations["nis"]).sum() > 0


def test_shared_times_are_what_each_run_computes(sims):
    """The batch's shared sample-time quantities are each run's own (rate, gap variances of bridge_gaps);
    none where the runs' times differ, no shared zeros where the times have a gap."""
    imus = [s.imu for s, _ in sims]
    assert imus[0].time is not imus[1].time  # each run its own copy: the values are compared
    sh = shared_times(imus)
    assert sh is not None and sh.rate_hz == imus[1].rate_hz
    dth, dv, gv = bridge_gaps(imus[1], [])
    assert sh.no_gaps.shape == gv.shape and not np.any(sh.no_gaps) and not np.any(gv)
    assert dth is imus[1].dtheta or np.shares_memory(dth, imus[1].dtheta)
    late = copy.copy(imus[1])
    late.time = imus[1].time + 1e-3
    assert shared_times([imus[0], late]) is None
    gap = copy.copy(imus[1])
    gap.time = imus[1].time.copy()
    gap.time[100:] += 0.5  # a 0.5-s gap (50 nominal intervals) before sample 100
    sh_gap = shared_times([gap, gap])
    assert sh_gap is not None and sh_gap.no_gaps is None and np.any(bridge_gaps(gap, [])[2])


def test_not_batchable_falls_back(sims):
    """Runs with different fix times cannot share a batch: run_loose_batch says so (None), and the batch
    task computes them run by run."""
    (s0, c0), (s1, c1) = sims[0], sims[1]
    g1 = s1.gnss.subset(np.arange(len(s1.gnss)) != 5)
    assert run_loose_batch([s0.imu, s1.imu], [s0.gnss, g1], [c0, c1]) is None
    assert run_loose_batch([s0.imu, s1.imu], [s0.gnss, s1.gnss], [c0, c1]) is not None


def test_campaign_batched_equals_one_run_per_task(tiny_file, tiny_serial, tmp_path):
    """The campaign (batched by default) writes the same tables as with one run per task."""
    from .test_runner import _same_tables

    out = tmp_path / "one"
    r = runner.run_experiment(tiny_file, out, progress=False, batch=1)
    assert r.complete and r.computed == 6
    _same_tables(tiny_serial[0], out)


def test_make_batches():
    t = [runner.RunTask(k, i, r, {}) for k, i in (("a", 0), ("b", 1)) for r in range(5)]
    b = runner.make_batches(t, 2)
    assert [(x.key, x.runs) for x in b] == [("a", (0, 1)), ("a", (2, 3)), ("a", (4,)), ("b", (0, 1)),
                                            ("b", (2, 3)), ("b", (4,))]


def test_make_batches_shrink_for_workers():
    """For parallel workers the batches shrink towards the end (at most ⌈remaining / (2 workers)⌉ runs), keep
    the runs in order and never span two sweep points."""
    t = [runner.RunTask("a", 0, r, {}) for r in range(98)] + [runner.RunTask("b", 1, r, {}) for r in range(5)]
    b = runner.make_batches(t, 8, workers=2)
    assert [r for x in b for r in x.runs] == [x.run for x in t]
    assert all(len({x.key}) == 1 for x in b)
    sizes = [len(x.runs) for x in b]
    assert max(sizes) == 8 and sizes[-3:] == [1, 1, 1]
    left = len(t)
    for x in b:  # the cap at each batch's start
        assert len(x.runs) <= max(1, -(-left // 4))
        left -= len(x.runs)
    assert [len(x.runs) for x in runner.make_batches(t[:10], 8)] == [8, 2]  # no workers: fixed size


@pytest.mark.slow
@pytest.mark.parametrize("method,warm,cold_cache", [("spawn", True, False), ("fork", True, False),
                                                    ("fork", False, False), ("fork", False, True)])
def test_process_pool_start_methods(tiny_file, tiny_serial, tmp_path, monkeypatch, method, warm, cold_cache):
    """The local process pool gives the serial tables whether its workers are forked (Linux default: they
    inherit the truth generated here and take every batch; after a first batch here where numba had to
    compile, ``cold_cache``) or spawned (they get the truth pickled from the main process)."""
    import multiprocessing

    from .test_runner import _same_tables

    if method not in multiprocessing.get_all_start_methods():
        pytest.skip(f"no {method} here")
    monkeypatch.setattr(runner, "START_METHOD", method)
    if not warm:
        monkeypatch.setattr(runner, "_COMPUTED", set())
    monkeypatch.setattr(runner, "_compiled_here", lambda: cold_cache)
    seen = []

    class Pool(runner._Pool):  # records the runs computed in this process before the workers take over
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            seen.append([r["run"] for r in self.early])

    monkeypatch.setattr(runner, "_Pool", Pool)
    out = tmp_path / method
    r = runner.run_experiment(tiny_file, out, workers=2, backend="processes", progress=False, batch=2)
    assert r.complete and r.computed == 6
    _same_tables(tiny_serial[0], out)
    assert seen == [[0, 1] if method == "spawn" or cold_cache else []]


@pytest.mark.parametrize("case", ["plain", "nan rows", "zero variance", "negative variance"])
def test_nees_of_diagonal_covariance_equals_solve(case):
    """The runner's NEES of a diagonal covariance (a division) equals nees() on the (N, k, k) matrices (a
    solve) bit for bit; a zero variance falls back to the same path as before (None here)."""
    from aidnav.analysis.consistency import nees

    rng = np.random.default_rng(5)
    n = 20000
    e = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-4, 4, (n, 3))
    var = 10.0 ** rng.uniform(-8, 6, (n, 3))
    if case == "nan rows":
        e[::7, 1] = np.nan
        var[::11, 2] = np.inf
    if case == "negative variance":
        var[::5, 0] *= -1.0
    if case == "zero variance":
        var[3, 1] = 0.0
        assert runner._nees_diagonal(e, var) is None
        with pytest.raises(np.linalg.LinAlgError):
            nees(e, np.einsum("ki,ij->kij", var, np.eye(3)))
        return
    P = np.zeros((n, 3, 3))
    P[:, np.arange(3), np.arange(3)] = var
    a, b = runner._nees_diagonal(e, var), nees(e, P)
    assert np.array_equal(a, b, equal_nan=True)
    assert np.isfinite(a).sum() > n // 2
