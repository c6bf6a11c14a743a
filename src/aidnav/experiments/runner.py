"""Monte Carlo campaigns: every run of every sweep point, serially, on local processes or on Dask.

:func:`run_experiment` is the library function behind ``aidnav run EXPERIMENT.yaml -o DIR``:

1. the experiment is read and **every** sweep point validated (:mod:`aidnav.experiments.config`)
   before anything is computed;
2. the runs already on disk (``DIR/runs``, see :mod:`aidnav.experiments.store`) are skipped: an
   interrupted campaign resumes where it stopped;
3. the remaining runs are computed — in this process (``workers=1``), on a local process pool
   (``workers > 1``; ``backend="dask"`` uses a local Dask cluster instead) or on
   an existing Dask scheduler (``scheduler="tcp://host:8786"``) — each result is written to ``DIR/runs``
   as it arrives (a rich progress bar shows the ETA); the local process pool forks its workers where the
   platform allows (Linux) as soon as this process has generated the first point's truth (they start with
   its imports, numba's CPU target and the truth, and take every batch), else spawns them while this process
   computes a first batch (:class:`_Pool`); a local Dask cluster's first batch is computed here, so that
   numba's on-disk cache is warm before the workers load it; the batches shrink towards the end of the
   campaign so that the workers finish together (:func:`make_batches`);
4. when all runs exist, they are merged into ``runs.parquet``, ``epochs.parquet``, ``consistency.json``
   and ``trajectories.parquet`` (the runs computed now from memory, :class:`_Tally`), and ``manifest.json``
   is written.

Reproducibility: run k of every sweep point uses the random stream
``numpy.random.SeedSequence(base_seed).spawn(k + 1)[k]`` (= ``SeedSequence(base_seed, spawn_key=(k,))``),
whose three children drive the IMU errors, the GNSS noise and the estimators (each estimator gets a fresh
generator from the third child: the same initial-state draw for every estimator). Runs are independent
and deterministic, and the tables are merged in a fixed order, so results are bit-identical serially,
on local processes or on a Dask cluster. Sweep points share the streams (common random numbers), so
differences between points are not blurred by different draws.

Work per run: the truth trajectory and the noise-free GNSS fixes depend only on the sweep point's
motion and receiver settings: each worker process generates them once per point (and keeps the last
few; a local worker gets the first point's from this process), and a run only redraws the sensor
errors (:func:`aidnav.sim.imu.corrupt_imu`, GNSS noise) before running the estimators (numba kernels).
"""

from __future__ import annotations

import importlib
import logging
import multiprocessing
import os
import pickle
import platform
import sys
import tempfile
import threading
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

import numba
import numpy as np

from aidnav.interrupts import blocked, worker_ignore

from .config import ExperimentPlan, load_experiment
from .estimators import state_blocks, state_unit
from .run_inputs import (  # noqa: F401  (re-exported: the runner's API and its tests)
    GNSS_KEY,
    TRUTH_KEY,
    GnssTemplate,
    cached_point,
    gnss_template,
    point_context,
    point_truth,
    run_streams,
    simulate_run,
    truth_of_point,
)

__all__ = ["run_experiment", "run_task", "RunTask", "run_batch_task", "BatchTask", "make_batches",
           "CampaignResult", "CampaignInterrupted", "GnssTemplate", "point_truth", "simulate_run",
           "format_result"]

BATCH_RUNS = 8  # runs of a sweep point per task (run_experiment's default batch)
_COMPUTED: set[str] = set()  # sweep points (keys) whose runs this process has computed: kernels loaded
_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


class CampaignInterrupted(RuntimeError):
    """The campaign stopped before all runs were computed (Ctrl-C); the finished runs are on disk."""


@dataclass(frozen=True)
class RunTask:
    """One run to compute: sweep point ``key``/``index``, its canonical document, run number."""

    key: str
    point: int
    run: int
    doc: dict


@dataclass(frozen=True)
class BatchTask:
    """Runs ``runs`` of one sweep point (``key``/``index``, canonical document ``doc``), computed together
    (:func:`run_batch_task`)."""

    key: str
    point: int
    runs: tuple[int, ...]
    doc: dict


@dataclass
class CampaignResult:
    """What :func:`run_experiment` did.

    complete : all runs exist and the tables were written. computed / reused : runs computed now / found
    on disk. total : runs of the campaign. wall_s : wall time of this call [s]. paths : files written.
    consistency : NEES checks (consistency.json) when complete. timings : breakdown (manifest).
    """

    out_dir: Path
    complete: bool
    computed: int
    reused: int
    total: int
    wall_s: float
    paths: list[Path] = field(default_factory=list)
    consistency: list[dict] = field(default_factory=list)
    timings: dict = field(default_factory=dict)


def _nees_diagonal(e: np.ndarray, var: np.ndarray) -> np.ndarray | None:
    """:func:`aidnav.analysis.consistency.nees` of errors ``e`` (N, k) with the diagonal covariances of
    variances ``var`` (N, k), without building the (N, k, k) matrices: the solve of a diagonal system is
    the division (the same values, ``tests/experiments/test_batch_runs.py``); NaN where e or var is not
    finite; None where nees would meet a singular matrix (a zero variance)."""
    out = np.full(len(e), np.nan)
    ok = np.all(np.isfinite(e), axis=1) & np.all(np.isfinite(var), axis=1)
    if np.any(ok):
        ee, vv = e[ok], var[ok]
        if np.any(vv == 0.0):
            return None
        out[ok] = np.sum(ee * (ee / vv), axis=-1)
    return out


def _process(out, name: str) -> dict:
    """EstimatorOutput → boundary-unit arrays and NEES per block."""
    from aidnav.analysis.consistency import nees  # lazy: pulls in scipy

    out.check(name)
    blocks = state_blocks(out.states)
    n_ep = len(out.time)
    nv = np.full((n_ep, len(blocks)), np.nan)
    for j, idx in enumerate(blocks.values()):
        with np.errstate(all="ignore"):
            v = _nees_diagonal(out.error[:, idx], out.cov[:, idx]) if out.cov.ndim == 2 else None
            if v is not None:
                nv[:, j] = v
                continue
            try:
                nv[:, j] = nees(out.error[:, idx], out.block_cov(idx))
            except np.linalg.LinAlgError:
                var = out.variances()[:, idx]
                nv[:, j] = np.sum(out.error[:, idx] ** 2 / np.where(var > 0, var, np.nan), axis=1)
    fac = np.array([state_unit(s)[1] for s in out.states])
    sig = np.sqrt(np.maximum(out.variances(), 0.0))
    return {"time": np.asarray(out.time, float), "error": out.error * fac, "sigma": sig * fac, "nees": nv,
            "states": list(out.states), "blocks": list(blocks), "info": dict(out.info)}


def run_task(task: RunTask) -> dict:
    """Compute one run (in whatever process): simulate the sensors, run every estimator, return the
    per-epoch arrays (see :func:`aidnav.experiments.store.save_run`) and a timing breakdown [s]."""
    return run_batch_task(BatchTask(task.key, task.point, (task.run,), task.doc), batched=False)[0]


def run_batch_task(task: BatchTask, batched: bool = True) -> list[dict]:
    """Compute runs ``task.runs`` of one sweep point (in whatever process): simulate each run's sensors,
    then run every estimator on all of them together where it has a batched form
    (:attr:`aidnav.experiments.estimators.EstimatorType.batch`, e.g. the loose filter on
    :mod:`aidnav.filters.engine_batch`: its outputs identical to run by run; ``batched`` False: run by run
    always); one result per run, as :func:`run_task`. A batch's estimator time is shared equally among
    its runs in the timing breakdown. In a local pool's worker a task of one run takes the batched form too
    (R = 1, the same results): the worker has loaded its kernels for the batches before, and the one-run
    engine's would be loaded at the campaign's end, where the batches shrink to one run (≈ 0.13 s of each
    worker's time on the campaign's last tasks, issue 41 session 11)."""
    for v in _THREAD_VARS:
        os.environ.setdefault(v, "1")
    t0, c0 = time.perf_counter(), time.process_time()
    _COMPUTED.add(task.key)
    ctx = point_context(task.key, task.doc)
    truth = truth_of_point(ctx)[0]
    gnss_template(ctx, truth)
    nr = len(task.runs)
    setup = (time.perf_counter() - t0) / nr
    tm = [{"setup_s": setup, "estimators_s": {}, "errors_s": 0.0} for _ in task.runs]
    sims, seeds = [], []
    together = batched and (nr > 1 or _REUSE_BUFFERS)  # the batched form (a pool worker: for one run too)
    # the runs' increments as rows of (R, N, 3) arrays: the batched filter reads them there, no copy
    n_imu = len(truth_of_point(ctx)[1])
    inc = _increments(nr, n_imu) if together else None
    for i, run in enumerate(task.runs):
        a = time.perf_counter()
        sim, s_est = simulate_run(ctx, run, None if inc is None else (inc[0][i], inc[1][i]))
        sims.append(sim)
        seeds.append(s_est)
        tm[i]["sim_s"] = time.perf_counter() - a
    res = [{} for _ in task.runs]
    for name, et, cfg in ctx.estimators:
        a = time.perf_counter()
        outs = None
        if together and et.batch is not None:
            outs = et.batch(sims, cfg, [np.random.default_rng(s) for s in seeds])
        if outs is not None:
            for t in tm:
                t["estimators_s"][name] = (time.perf_counter() - a) / nr
        else:
            outs = []
            for i in range(nr):
                a = time.perf_counter()
                outs.append(et.fn(sims[i], cfg, np.random.default_rng(seeds[i])))
                tm[i]["estimators_s"][name] = time.perf_counter() - a
        for i, out in enumerate(outs):
            b = time.perf_counter()
            res[i][name] = _process(out, name)
            tm[i]["errors_s"] += time.perf_counter() - b
    cpu = (time.process_time() - c0) / nr  # CPU time of this process, shared equally
    for t in tm:
        t["total_s"] = t["setup_s"] + t["sim_s"] + sum(t["estimators_s"].values()) + t["errors_s"]
        t["cpu_s"] = cpu
    return [{"key": task.key, "point": task.point, "run": run, "imu_samples": len(sims[i].imu),
             "timing": tm[i], "estimators": res[i]} for i, run in enumerate(task.runs)]


_BUFFERS = threading.local()  # a pool worker's increment arrays, reused from batch to batch (per thread)
_REUSE_BUFFERS = False  # set in the pool's workers (_worker_init)


def _increments(nr: int, n: int) -> list[np.ndarray]:
    """Two (nr, n, 3) arrays for a batch's corrupted increments (every element is written by the runs).
    In a pool worker the same memory serves every batch of up to the first batch's size: a batch of 8
    30-min runs at 100 Hz needs 2 × 35 MB, above glibc's largest mmap threshold, so new arrays would be
    fresh pages each time (≈ 2,000 page faults a run)."""
    if not _REUSE_BUFFERS:
        return [np.empty((nr, n, 3)) for _ in range(2)]
    have = getattr(_BUFFERS, "inc", None)
    if have is None or have[0].shape[0] < nr or have[0].shape[1] != n:
        have = _BUFFERS.inc = [np.empty((nr, n, 3)) for _ in range(2)]
    return [a[:nr] for a in have]


def make_batches(tasks: list[RunTask], size: int, workers: int | None = None) -> list[BatchTask]:
    """Consecutive runs of the same sweep point in batches of at most ``size`` runs.

    workers : for that many parallel workers, batches that shrink towards the end of the campaign (at most
        ⌈remaining runs / (2 workers)⌉ runs each, down to one): the workers finish together instead of one
        computing a last full batch while the others wait. None: all batches of ``size``.
    """
    out: list[list[RunTask]] = []
    cap = size
    for i, t in enumerate(tasks):
        if not out or out[-1][0].key != t.key or len(out[-1]) >= cap:
            out.append([])
            if workers:
                cap = max(1, min(size, -(-(len(tasks) - i) // (2 * workers))))
        out[-1].append(t)
    return [BatchTask(b[0].key, b[0].point, tuple(t.run for t in b), b[0].doc) for b in out]


# ----------------------------------------------------------------------------------- backends
def _serial(tasks, on_result):
    for t in tasks:
        for r in run_batch_task(t):
            on_result(r)


def keep_freed_memory() -> bool:
    """glibc only (Linux): large arrays from the heap instead of fresh ``mmap`` pages (threshold 32 MiB,
    glibc's largest), and freed memory kept in the process instead of returned at once (trim threshold
    1 GiB), through glibc's documented ``mallopt``. A run allocates and frees ~10 MB of arrays; a worker
    that gets them as fresh pages each time pays a page fault per 4 KiB (a forked worker of a 100-run
    campaign: ~2,800 faults and ~5 ms of system time a run; docs/results.md, issue 41 session 10). For
    worker processes only (the pool's): their heap then stays at its largest. Returns whether it was set."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes  # lazy: only where glibc's mallopt is called

        libc = ctypes.CDLL(None)
        m_trim_threshold, m_mmap_threshold = -1, -3  # <malloc.h>
        ok = libc.mallopt(m_mmap_threshold, 32 << 20)
        return bool(ok) and bool(libc.mallopt(m_trim_threshold, 1 << 30))
    except (OSError, AttributeError):  # another C library (musl has no mallopt)
        return False


def _worker_init(seed: str | None):
    """Start-up of a local worker process (:class:`_Pool`): single-threaded BLAS, freed memory kept
    (:func:`keep_freed_memory`); with spawn, the truth and noise-free GNSS fixes that the main process
    already generated (pickled to the file ``seed``) fill this process's caches and the modules a run needs
    are imported, while the main process computes the first batch."""
    worker_ignore()  # Ctrl-C reaches the process group: the parent stops the pool
    for v in _THREAD_VARS:
        os.environ.setdefault(v, "1")
    keep_freed_memory()
    global _REUSE_BUFFERS
    _REUSE_BUFFERS = True
    if seed:
        with open(seed, "rb") as f:
            truth, gnss = pickle.load(f)
        for cache, items in ((TRUTH_KEY, truth), (GNSS_KEY, gnss)):
            for k, v in items.items():
                cached_point(cache, k, lambda v=v: v)
    importlib.import_module("aidnav.analysis.consistency")
    importlib.import_module("aidnav.analysis.errors")


def _worker_ready() -> int:
    return os.getpid()


def _prepare_point(task: BatchTask):
    """The context, truth and GNSS template of ``task``'s point, generated here (and cached)."""
    ctx = point_context(task.key, task.doc)
    truth = truth_of_point(ctx)
    return ctx, truth, gnss_template(ctx, truth[0])


def _compiled_here() -> bool:
    """Whether numba compiled a kernel of aidnav in this process (its on-disk cache was cold: a first run
    after an install or an edit), from the dispatchers' public ``stats``."""
    for name, mod in list(sys.modules.items()):
        if not name.startswith("aidnav.") or mod is None:
            continue
        for v in list(vars(mod).values()):
            st = getattr(v, "stats", None) if isinstance(v, numba.core.dispatcher.Dispatcher) else None
            if st is not None and st.cache_misses:
                return True
    return False


def _seed_file(task: BatchTask, folder: Path) -> Path:
    """The truth and GNSS template of ``task``'s point (generated here, cached) pickled for the workers."""
    ctx, truth, tmpl = _prepare_point(task)
    gk = (ctx.sim_key, ctx.gnss_key)
    path = folder / "point.pickle"
    with open(path, "wb") as f:
        pickle.dump(({ctx.sim_key: truth}, {gk: tmpl}), f, protocol=pickle.HIGHEST_PROTOCOL)
    return path


#: how the local process pool starts its workers: fork where the platform has it safely (Linux): a worker is
#: then a copy of this process, with its imported modules, loaded numba kernels and cached truth (no
#: start-up); spawn elsewhere (:func:`_worker_init`)
START_METHOD = "fork" if sys.platform.startswith("linux") else "spawn"


class _Pool:
    """The local process pool of a campaign (``backend="processes"``), started before the progress bar (no
    other thread in this process when it forks).

    ``first`` : the campaign's first batch. With spawn it is computed here while the workers start
    (interpreter, imports, and the truth pickled from here: :func:`_worker_init`), so that numba compiles
    or loads its kernels once and caches them on disk before the workers load them; its results are in
    ``early``. With fork, this process generates the point's truth and GNSS template and the workers start
    at once: they inherit the truth, the imports and numba's started CPU target, load the run's kernels from
    numba's cache in parallel, and take ``first`` as their first task (``early`` is empty); a first batch
    computed here before forking would leave a core idle while it runs (issue 41, session 10). Where that
    truth had to be compiled (numba's cache cold), ``first`` is computed here before forking as with spawn:
    the workers then inherit its kernels instead of each compiling them.

    ``tasks`` : the other batches, submitted as soon as the workers exist (before the progress bar's import
    and set-up, and, with spawn, before this process computes ``first``): :meth:`run` collects them.
    :meth:`close` after the last result lets the workers exit while this process merges (:meth:`join`).
    """

    def __init__(self, workers: int, first: BatchTask | None, method: str | None = None, tasks=()):
        method = method or START_METHOD
        self.early, self._tmp, self.ex, self.futs, self._closing = [], None, None, [], None
        try:
            if method == "fork" and first is not None:
                _prepare_point(first)
                if _compiled_here():
                    self.early = run_batch_task(first)
                else:
                    tasks = [first] + list(tasks)
            seed = None
            if method != "fork" and first is not None:
                self._tmp = tempfile.TemporaryDirectory(prefix="aidnav_pool_")
                seed = str(_seed_file(first, Path(self._tmp.name)))
            with blocked():  # a Ctrl-C now reaches this process after the workers ignore it
                ctx = multiprocessing.get_context(method)
                self.ex = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_init,
                                              initargs=(seed,))
                # all workers start now (fork: at the first submit; spawn: one per submit while none is idle)
                self._ready = [self.ex.submit(_worker_ready) for _ in range(workers)]
                self.futs = [self.ex.submit(run_batch_task, t) for t in tasks]
            if method != "fork" and first is not None:
                self.early = run_batch_task(first)
        except BaseException:
            self.close(wait=False)
            raise

    def run(self, on_result):
        """Hand each run of the submitted batches to ``on_result`` as their batch finishes."""
        prepare_merge()  # while the workers compute (the merge's imports, ~0.1 s)
        try:
            for f in as_completed(self.futs):
                for r in f.result():
                    on_result(r)
            for f in self._ready:
                f.result()
        except BaseException:
            for f in self.futs:
                f.cancel()
            raise

    def close(self, wait: bool = True, background: bool = False):
        """Stop the pool (``wait``: for the workers' exit; else cancel what has not started). ``background``
        (every result in): the workers exit while this process goes on; :meth:`join` waits for them."""
        if self.ex is not None and background:
            self._closing = threading.Thread(target=self.ex.shutdown, name="aidnav-pool-close")
            self._closing.start()
        elif self.ex is not None:
            self.ex.shutdown(wait=wait, cancel_futures=not wait)
        if self._tmp is not None:
            self._tmp.cleanup()

    def join(self):
        """Wait for the workers' exit after :meth:`close` in the background (their CPU time is then counted
        in this process's ``RUSAGE_CHILDREN``)."""
        if self._closing is not None:
            self._closing.join()
            self._closing = None


def prepare_merge() -> None:
    """Import what the merge needs (:func:`aidnav.experiments.store.prepare_merge`), in this process while
    the workers compute."""
    from . import store  # lazy: pyarrow; the workers do not write the tables

    store.prepare_merge()


def _dask(tasks, on_result, workers: int, scheduler: str | None, info: dict):
    from distributed import Client, LocalCluster, as_completed  # lazy: distributed is heavy to import

    cluster = None
    if scheduler:
        client = Client(scheduler)
        info["scheduler"] = scheduler
    else:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=logging.ERROR)
        client = Client(cluster)
        info["scheduler"] = "LocalCluster"
    info["dask_workers"] = len(client.scheduler_info().get("workers", {}))
    futs = []
    try:
        futs = [client.submit(run_batch_task, t, pure=False) for t in tasks]
        for f in as_completed(futs):
            for r in f.result():
                on_result(r)
    except BaseException:
        client.cancel(futs)
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


# ----------------------------------------------------------------------------------- campaign
def _host() -> dict:
    return {"node": platform.node(), "platform": platform.platform(), "python": sys.version.split()[0],
            "cpus": os.cpu_count(), "machine": platform.machine()}


def _versions() -> dict:
    from . import store  # lazy: pulls in pyarrow

    return {"aidnav": store.package_version(), "numpy": np.__version__, "numba": numba.__version__}


def run_experiment(experiment, out_dir, *, workers: int = 1, scheduler: str | None = None,
                   backend: str | None = None, max_runs: int | None = None, console=None,
                   progress: bool = True, batch: int | None = None) -> CampaignResult:
    """Run (or resume) a campaign into ``out_dir`` (see the module docstring).

    Parameters
    ----------
    experiment : path of an experiment YAML, or an :class:`~aidnav.experiments.config.ExperimentPlan`.
    out_dir : campaign directory (created).
    workers : processes (> 1: a local process pool with that many workers, or a Dask ``LocalCluster`` of
        single-threaded workers with ``backend="dask"``).
    scheduler : address of an existing Dask scheduler (its workers need aidnav installed).
    backend : "serial", "processes" or "dask"; default: dask with a scheduler, else serial for one worker and
        the process pool for more (the fastest: its forked workers inherit the loaded kernels and truth).
    max_runs : compute at most this many new runs, then stop without merging (a campaign cut short on
        purpose; rerun to complete it).
    console : rich console for the progress bar and messages, or a function that makes one (called once, when
        a message or the bar needs it: after a local pool's workers have started; default: a console on
        stderr); progress : show the bar.
    batch : runs of a sweep point computed together in one task (:func:`run_batch_task`; they share the
        trajectory); default :data:`BATCH_RUNS`, fewer where that leaves a worker fewer than two tasks;
        1: one run per task.

    Raises :class:`~aidnav.experiments.config.ExperimentError` (before computing anything) for a bad
    experiment and :class:`CampaignInterrupted` on Ctrl-C (finished runs stay on disk).
    """
    t_start = time.perf_counter()
    plan = experiment if isinstance(experiment, ExperimentPlan) else load_experiment(experiment)
    console = _console_maker(console)
    if backend is None:  # the fastest correct one (issue 41): the process pool locally, Dask on a scheduler
        backend = "dask" if scheduler else ("processes" if workers > 1 else "serial")
    if backend not in ("serial", "processes", "dask"):
        raise ValueError(f"backend must be serial, processes or dask (got {backend!r})")
    if workers < 1:
        raise ValueError("workers must be >= 1")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    todo, n_total, n_reused = _pending(plan, out, max_runs, console)

    for v in _THREAD_VARS:  # single-threaded BLAS in the workers (inherited by spawned processes)
        os.environ.setdefault(v, "1")
    info = {"kind": backend, "workers": workers if backend != "serial" else 1}
    t_comp = time.perf_counter()
    tally = _compute(plan, out, todo, n_total, n_reused, backend, workers, scheduler, info, batch, console,
                     progress)
    t_compute = time.perf_counter() - t_comp
    try:  # the pool's workers exit meanwhile
        return _finish(plan, out, tally, t_start, t_compute, n_total, n_reused, info, console)
    finally:
        if tally.pool is not None:
            tally.pool.join()


def _finish(plan: ExperimentPlan, out: Path, tally: _Tally, t_start: float, t_compute: float, n_total: int,
            n_reused: int, info: dict, console) -> CampaignResult:
    """The campaign's tables and manifest once its runs are computed (:func:`run_experiment`)."""
    from . import store  # lazy: pyarrow; the workers do not write the tables

    computed = tally.computed
    complete = n_reused + computed == n_total
    timings = {"compute_wall_s": t_compute, "computed_runs": computed, "reused_runs": n_reused,
               "per_run_sums": tally.agg,
               "runs_per_s": computed / t_compute if computed and t_compute > 0 else None,
               "imu_samples_per_s": (tally.agg["imu_samples"] / t_compute if computed and t_compute > 0
                                     else None)}
    result = CampaignResult(out, complete, computed, n_reused, n_total, 0.0, timings=timings)
    if not complete:
        result.wall_s = time.perf_counter() - t_start
        console().print(f"stopped after {computed} new runs: {n_reused + computed} of {n_total} on disk; "
                      "rerun to complete")
        return result

    t_m = time.perf_counter()
    merged = store.merge_campaign(plan, out, tally.kept)
    tally.kept.clear()
    merged["paths"].append(store.write_trajectories(out, plan, point_truth))
    timings["merge_s"] = time.perf_counter() - t_m
    result.wall_s = time.perf_counter() - t_start
    timings["wall_s"] = result.wall_s
    manifest = _manifest(plan, out, merged["paths"], timings, info)
    merged["paths"].append(store.write_json(out / "manifest.json", manifest))
    result.paths = merged["paths"]
    result.consistency = merged["consistency"]
    return result


def _console_maker(console):
    """A function that gives the campaign's console (:func:`run_experiment`'s ``console``: a console, a
    function that makes one, or None for a console on stderr), made on its first call (rich.console's
    import, ~25 ms, after a local pool's workers have started)."""
    made = []

    def get():
        if not made:
            if console is not None and not callable(console):
                made.append(console)
            elif console is not None:
                made.append(console())
            else:
                from rich.console import Console  # lazy: rich is heavy (imported after the workers start)

                made.append(Console(stderr=True))
        return made[0]

    return get


def _pending(plan: ExperimentPlan, out: Path, max_runs: int | None,
             console) -> tuple[list[RunTask], int, int]:
    """The runs of the campaign still to compute (at most ``max_runs``), the number of runs in all and the
    number already on disk; removes a manifest that no longer describes the campaign."""
    from . import store  # lazy: pyarrow; the workers do not write the tables

    tasks = [RunTask(p.key, p.index, k, p.doc) for p in plan.points for k in range(plan.runs)]
    done = store.existing_runs(out, plan)
    todo = [t for t in tasks if (t.key, t.run) not in done]
    if max_runs is not None:
        todo = todo[:max(0, int(max_runs))]
    if todo:  # the tables and manifest on disk (if any) no longer describe the campaign: until it completes
        (out / "manifest.json").unlink(missing_ok=True)  # `aidnav report` refuses the directory
    n_total, n_reused = len(tasks), len(tasks) - len([t for t in tasks if (t.key, t.run) not in done])
    if n_reused:
        console().print(f"{out}: {n_reused} of {n_total} runs already on disk, {n_total - n_reused} to "
                        "compute")
    return todo, n_total, n_reused


#: the runs' arrays a campaign keeps in memory for its merge (:class:`_Tally`) [bytes]; beyond, the merge
#: reads them back from their files
KEEP_BYTES = 512 << 20


class _Tally:
    """Saves each finished run to the campaign directory, keeps its arrays for the merge while they fit in
    :data:`KEEP_BYTES` (``kept``: {(point key, run): arrays}, no reading back of files just written: ≈ 0.1 s
    of a 100-run campaign's serial merge) and sums its timings (the manifest's ``per_run_sums``);
    ``computed`` counts the runs."""

    def __init__(self, out: Path, advance=None):
        from . import store  # lazy: pyarrow; the workers do not write the tables

        self.store, self.out, self.advance, self.computed = store, out, advance, 0
        self.pool: _Pool | None = None  # the local process pool, its workers exiting (_compute)
        self.kept: dict = {}
        self._kept_bytes = 0
        self.agg = {"setup_s": 0.0, "sim_s": 0.0, "errors_s": 0.0, "estimators_s": {}, "worker_total_s": 0.0,
                    "worker_cpu_s": 0.0, "imu_samples": 0}

    def __call__(self, res: dict) -> None:
        agg = self.agg
        arrays = self.store.run_arrays(res)
        self.store.save_run(self.out, res, arrays)
        size = sum(a.nbytes for e in arrays["estimators"].values() for a in e.values()
                   if isinstance(a, np.ndarray))
        if self._kept_bytes + size <= KEEP_BYTES:
            self.kept[(res["key"], int(res["run"]))] = arrays
            self._kept_bytes += size
        self.computed += 1
        tm = res["timing"]
        for k in ("setup_s", "sim_s", "errors_s"):
            agg[k] += tm[k]
        agg["worker_total_s"] += tm["total_s"]
        agg["worker_cpu_s"] += tm.get("cpu_s", 0.0)
        for k, v in tm["estimators_s"].items():
            agg["estimators_s"][k] = agg["estimators_s"].get(k, 0.0) + v
        agg["imu_samples"] += res["imu_samples"]
        if self.advance is not None:
            self.advance()


def _compute(plan: ExperimentPlan, out: Path, todo: list[RunTask], n_total: int, n_reused: int, backend: str,
             workers: int, scheduler: str | None, info: dict, batch: int | None, console,
             progress: bool) -> _Tally:
    """Compute the runs ``todo`` in batches on ``backend`` with a progress bar; returns the tally of the runs
    saved. Raises :class:`CampaignInterrupted` on Ctrl-C (the finished runs are on disk)."""
    par = backend != "serial"
    size = batch or max(1, min(BATCH_RUNS, -(-len(todo) // (2 * workers)) if par else BATCH_RUNS))
    first = pool = None
    # a forked worker inherits what this process has loaded: when it has already computed this point (a
    # second campaign in one session), the first batch need not be computed here first
    inherited = backend == "processes" and START_METHOD == "fork" and bool(todo) and todo[0].key in _COMPUTED
    if len(todo) > 1 and par and not scheduler and not inherited:
        # the first runs here (Dask, spawn; fork: only where numba compiled, _Pool): numba compiles (or loads)
        # its kernels once and caches them on disk, so that the local workers load them (or, forked, inherit
        # them) instead of each compiling them again
        first = make_batches(todo[:min(2, size)], size)[0]
        todo = todo[len(first.runs):]
    todo = make_batches(todo, size, workers if par else None)
    if backend == "processes":
        try:
            pool = _Pool(workers, first, tasks=todo)
        except KeyboardInterrupt:
            raise CampaignInterrupted(f"interrupted: {n_reused} of {n_total} runs are in {out / 'runs'}; run "
                                      "the same command again to resume") from None

    # lazy: rich is heavy to import (after the fork: the workers do not need it)
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    cols = [TextColumn("{task.description}", markup=False), BarColumn(), MofNCompleteColumn(),
            TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn()]
    with Progress(*cols, console=console(), disable=not progress or not todo, transient=False) as bar:
        task_id = bar.add_task(f"{plan.experiment.name}: runs", total=n_total, completed=n_reused)
        on_result = _Tally(out, lambda: bar.advance(task_id))
        ok = False
        try:
            for r in pool.early if pool is not None else []:
                on_result(r)
            if first is not None and pool is None:
                for r in run_batch_task(first):
                    on_result(r)
            if backend == "processes":
                pool.run(on_result)  # with fork, the first batch too
            elif not todo:
                pass
            elif backend == "serial":
                _serial(todo, on_result)
            else:
                _dask(todo, on_result, workers, scheduler, info)
            ok = True
        except KeyboardInterrupt:
            raise CampaignInterrupted(f"interrupted: {n_reused + on_result.computed} of {n_total} runs are "
                                      f"in {out / 'runs'}; run the same command again to resume") from None
        finally:
            if pool is not None:
                pool.close(wait=ok, background=ok)
    on_result.pool = pool
    return on_result


def _manifest(plan: ExperimentPlan, out: Path, paths: list[Path], timings: dict, info: dict) -> dict:
    """The campaign's manifest.json: the experiment, versions, seeds, points, estimators, timings, backend,
    host and the files written (``paths`` and the manifest itself)."""
    from . import store  # lazy: pyarrow; the workers do not write the tables

    return {
        "experiment": {"name": plan.experiment.name, "description": plan.experiment.description,
                       "source": plan.source, "text": plan.text, "document": plan.doc},
        "versions": _versions(),
        "aidnav_version": store.package_version(),
        "runs": plan.runs,
        "seeds": {"base_seed": plan.base_seed,
                  "scheme": "run k: numpy.random.SeedSequence(base_seed).spawn(k + 1)[k] "
                            "(= SeedSequence(base_seed, spawn_key=(k,))); its spawn(3) children drive the "
                            "IMU errors, the GNSS noise and the estimators; the same for every sweep point",
                  "spawn_keys": list(range(plan.runs))},
        "points": [{"index": p.index, "label": p.label, "values": p.values, "key": p.key,
                    "run_dir": str(store.run_path(out, p.key, 0).parent.relative_to(out)),
                    "duration_s": p.duration_s, "segments": p.segments} for p in plan.points],
        "estimators": [{"name": e["name"], "type": e["type"]} for e in plan.doc["estimators"]],
        "timings": timings,
        "backend": info,
        "host": _host(),
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "files": [p.name for p in paths] + ["manifest.json"],
    }


def format_result(res: CampaignResult) -> str:
    """Plain-text summary of a campaign for the console: runs, timings, NEES verdicts, files."""
    lines = []
    tm = res.timings
    if not res.complete:
        lines.append(f"{res.out_dir}: {res.reused + res.computed} of {res.total} runs on disk "
                     f"({res.computed} computed now); run again to complete")
        return "\n".join(lines)
    rate = tm.get("runs_per_s")
    sps = tm.get("imu_samples_per_s")
    lines.append(f"{res.out_dir}: {res.total} runs ({res.computed} computed, {res.reused} reused) in "
                 f"{res.wall_s:.1f} s" + (f"; {rate:.2f} runs/s, {sps:,.0f} IMU samples/s" if rate else ""))
    for c in res.consistency:
        flag = "consistent" if c.get("consistent") else f"INCONSISTENT ({c['verdict']})"
        lines.append(f"  NEES {c['block']:<4} {c['estimator']:<12} {c['label']}: mean {c['mean']:.3g} "
                     f"(band {c['band'][0]:.3g}-{c['band'][1]:.3g}), {flag}")
    for p in res.paths:
        lines.append(f"wrote {p}")
    return "\n".join(lines)
