"""Monte Carlo campaign throughput: 100 runs of a 30-minute 100 Hz flight, tactical IMU, 1 Hz GNSS,
15-state loosely coupled filter (:mod:`aidnav.experiments.runner`).

Reports the total wall time of the campaign (validation, runs, writing the run files, merging the
Parquet tables) serially — one run per task (the one-run-per-call path, ``serial1``) and in batches of
runs that advance together (:mod:`aidnav.filters.engine_batch`, the runner's default) — and with 2
workers each taking batches (a local process pool and/or a Dask ``LocalCluster``), runs/s, and
simulated+filtered IMU samples/s overall (runs × 180,000 samples / wall time), with the
breakdown summed over the runs: truth generation (once per worker), sensor simulation (IMU error
corruption + GNSS noise), the filter, the error/NEES evaluation, and the merge. The serial case is
preceded by one warm-up run in the same process (numba compilation or cache load, reported apart);
the workers of the parallel cases start cold (their start-up is part of the wall time).

The machine is often shared: beside the wall figures each case prints CPU-time figures — the runs' own
(``time.process_time`` inside the tasks) and the whole campaign's: this process plus the worker processes'
whole CPU time, their start-up included (``RUSAGE_CHILDREN``, the workers having ended) — with the samples
per campaign CPU-second times the number of cores (what the case would give with that many free cores,
serial phases such as the merge aside), and the load average. Wall figures of the parallel cases are the
machine's share unless the campaign gets both cores (e.g. ``chrt -f 1``). The warm-up imports what the
merge needs (pyarrow's pandas, scipy.stats) so that trees which import them at different times compare
alike.

Stretch target: >= 3,000,000 samples/s overall on this 2-core machine, with ``aidnav run --workers 2`` and
no other option (issue 41): the case ``cli`` runs that command in a fresh process (its start, imports and
kernel loads counted), the campaign written as an experiment file.

Run: ``python benchmarks/montecarlo.py [--runs 100] [--workers 2] [--backends serial1,serial,processes,
dask,cli] [--batch N] [--json out.json]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

TARGET = 3_000_000


def experiment(runs: int) -> dict:
    """The benchmark campaign: 1800 s at 100 Hz (180,000 IMU samples per run)."""
    return {
        "name": "montecarlo_benchmark",
        "description": "30 min figure-8 flight, tactical IMU, 1 Hz GNSS, 15-state loose filter",
        "scenario": {
            "initial": {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 7000.0, "speed_m_s": 100.0,
                        "heading_deg": 40.0},
            "imu_rate_hz": 100,
            "segments": [{"type": "straight", "duration_s": 300, "name": "lead_in"},
                         {"type": "figure8", "duration_s": 900, "name": "8"},
                         {"type": "straight", "duration_s": 300, "name": "AB"},
                         {"type": "u_turn", "duration_s": 100, "name": "U"},
                         {"type": "straight", "duration_s": 200, "name": "CD"}],
        },
        "sensors": {"imu": {"grade": "tactical"}, "gnss": {"rate_hz": 1}},
        "estimators": [{"name": "loose15", "type": "loose", "states": 15}],
        "runs": runs,
        "base_seed": 1,
        "statistics": {"quantities": ["pos_h", "vel_h", "att_e", "att_n", "heading"],
                       "windows": {"AB": {"segment": "AB"}, "CD": {"segment": "CD"},
                                   "last60": {"last_s": 60, "metrics": ["rms"]}}},
    }


def bench(plan, out: Path, **kw) -> dict:
    from aidnav.experiments.runner import run_experiment

    shutil.rmtree(out, ignore_errors=True)
    ch0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0, c0 = time.perf_counter(), time.process_time()
    res = run_experiment(plan, out, progress=False, **kw)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    ch1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    # the worker processes (ended and waited for by the time run_experiment returns): start-up included
    children = (ch1.ru_utime + ch1.ru_stime) - (ch0.ru_utime + ch0.ru_stime)
    assert res.complete
    tm = res.timings
    s = tm["per_run_sums"]
    samples = s["imu_samples"]
    return {"wall_s": wall, "runs": res.computed, "runs_per_s": res.computed / wall, "samples": samples,
            "samples_per_s": samples / wall, "compute_wall_s": tm["compute_wall_s"], "merge_s": tm["merge_s"],
            "truth_setup_s": s["setup_s"], "sensor_sim_s": s["sim_s"],
            "filter_s": sum(s["estimators_s"].values()),
            "errors_nees_s": s["errors_s"], "worker_total_s": s["worker_total_s"],
            "filter_samples_per_s": samples / max(sum(s["estimators_s"].values()), 1e-9),
            "sensor_sim_samples_per_s": samples / max(s["sim_s"], 1e-9), "worker_cpu_s": s["worker_cpu_s"],
            # this process (all of a serial campaign) plus the worker processes' whole CPU time (their
            # start-up: interpreter, imports, numba cache loads, truth; and their runs)
            "campaign_cpu_s": cpu + children, "children_cpu_s": children,
            "samples_per_cpu_s": samples / max(s["worker_cpu_s"], 1e-9), "load": os.getloadavg()[0]}


def bench_cli(runs: int, workers: int, out: Path) -> dict:
    """``aidnav run EXPERIMENT --workers N -o DIR`` in a fresh process, no other option: wall time from the
    command's start to its exit, CPU time of it and its workers (RUSAGE_CHILDREN)."""
    import yaml

    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    exp = out / "experiment.yaml"
    exp.write_text(yaml.safe_dump(experiment(runs)))
    import aidnav  # lazy: the package under test (PYTHONPATH), for its folder

    # the package's bytecode, as an installed package has it (pip compiles it at install; a source tree under
    # PYTHONDONTWRITEBYTECODE would compile every module from source in the timed command)
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(Path(aidnav.__file__).resolve().parent)],
                   check=True, stdout=subprocess.DEVNULL)
    ch0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "aidnav", "run", str(exp), "-o", str(out / "campaign"),
                        "--workers", str(workers)], capture_output=True, text=True,
                       env=dict(os.environ, AIDNAV_PROGRESS="0"))
    wall = time.perf_counter() - t0
    ch1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise RuntimeError(f"aidnav run failed ({p.returncode}): {p.stderr[-2000:]}")
    man = json.loads((out / "campaign" / "manifest.json").read_text())
    samples = runs * 180_000
    cpu = (ch1.ru_utime + ch1.ru_stime) - (ch0.ru_utime + ch0.ru_stime)
    tm = man.get("timings", {})
    return {"wall_s": wall, "runs": runs, "runs_per_s": runs / wall, "samples": samples,
            "samples_per_s": samples / wall, "campaign_cpu_s": cpu, "backend": man.get("backend"),
            "load": os.getloadavg()[0],
            # where the wall went: the command's start (interpreter, imports, the experiment read) until the
            # campaign's clock starts, the runs (the workers' start and the first point's truth included),
            # the merge (tables, trajectories), and the rest (manifest, summary, exit)
            "start_s": wall - tm.get("wall_s", wall), "compute_wall_s": tm.get("compute_wall_s"),
            "merge_s": tm.get("merge_s")}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--backends", default="serial1,serial,processes,dask,cli",
                    help="comma-separated: serial1 (one run per task), serial (batches), processes (process "
                         "pool), dask (LocalCluster), cli (`aidnav run --workers N`, a fresh process)")
    ap.add_argument("--batch", type=int, default=None, help="runs per task (default: the runner's)")
    ap.add_argument("--json", type=Path, default=None, help="also write the numbers here")
    args = ap.parse_args()

    from aidnav.experiments import runner
    from aidnav.experiments.config import parse_experiment

    plan = parse_experiment(experiment(args.runs), "montecarlo_benchmark")
    p = plan.points[0]
    t0 = time.perf_counter()
    # numba compile / cache load (one-run and batched kernels), truth
    runner.run_batch_task(runner.BatchTask(p.key, p.index, (0, 1), p.doc))
    runner.run_task(runner.RunTask(p.key, p.index, 0, p.doc))
    # what the main process imports for the merge (already imported here by older trees' runner): the same
    # for every tree measured
    import pandas  # noqa: F401  (pyarrow's table writer imports it)
    import scipy.stats  # noqa: F401

    from aidnav.experiments import store  # noqa: F401
    warm = time.perf_counter() - t0
    print(f"host {platform.node()}, {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}; "
          f"warm-up run (compile/cache load + truth) {warm:.2f} s")
    results = {"warmup_s": warm, "runs": args.runs, "imu_samples_per_run": 180_000, "cases": {}}
    tmp = Path(tempfile.mkdtemp(prefix="aidnav_mc_bench_"))
    try:
        for b in [x.strip() for x in args.backends.split(",") if x.strip()]:
            if b == "cli":
                r = bench_cli(args.runs, args.workers, tmp / "cli")
                results["cases"][f"aidnav run --workers {args.workers}"] = r
                c_all = r["samples"] / max(r["campaign_cpu_s"], 1e-9)
                print(f"\naidnav run --workers {args.workers} (no other option; executor "
                      f"{r['backend'].get('kind')}): {r['runs']} runs in {r['wall_s']:.2f} s = "
                      f"{r['samples_per_s']:,.0f} IMU samples/s (wall from the command's start, load average "
                      f"{r['load']:.1f}; {'meets' if r['samples_per_s'] >= TARGET else 'below'} the "
                      f"{TARGET:,} target); CPU {r['campaign_cpu_s']:.2f} s: on 2 free cores "
                      f"{2 * c_all:,.0f} samples/s (serial phases aside)")
                if r["compute_wall_s"] is not None:
                    print(f"  wall: command start to the campaign {r['start_s']:.2f} s, runs "
                          f"{r['compute_wall_s']:.2f} s, merge {r['merge_s']:.2f} s, rest "
                          f"{r['wall_s'] - r['start_s'] - r['compute_wall_s'] - r['merge_s']:.2f} s")
                continue
            ser = b.startswith("serial")
            kw = {"backend": "serial" if ser else b, "workers": 1 if ser else args.workers,
                  "batch": 1 if b == "serial1" else args.batch}
            r = bench(plan, tmp / b, **kw)
            name = {"serial1": "serial, one run per task", "serial": "serial, batched"}.get(
                b, f"{b} x{args.workers}, batched")
            results["cases"][name] = r
            cores = 1 if ser else args.workers
            print(f"\n{name}: {r['runs']} runs in {r['wall_s']:.2f} s = {r['runs_per_s']:.2f} runs/s, "
                  f"{r['samples_per_s']:,.0f} IMU samples/s overall (wall, load average {r['load']:.1f}; "
                  f"{'meets' if r['samples_per_s'] >= TARGET else 'below'} the {TARGET:,} target)")
            c_all = r["samples"] / max(r["campaign_cpu_s"], 1e-9)
            sc = r["samples_per_cpu_s"]
            own = r["campaign_cpu_s"] - r["children_cpu_s"]
            print(f"  CPU time: runs {r['worker_cpu_s']:.2f} s ({sc:,.0f} samples/CPU-s), "
                  f"whole campaign {r['campaign_cpu_s']:.2f} s (this process {own:.2f} s, worker processes "
                  f"with their start-up {r['children_cpu_s']:.2f} s; {c_all:,.0f} samples/CPU-s): "
                  f"on {cores} free core(s) {c_all * cores:,.0f} samples/s, on 2 free cores {2 * c_all:,.0f} "
                  f"({'meets' if 2 * c_all >= TARGET else 'below'} the {TARGET:,} target)")
            print(f"  summed over runs: filter {r['filter_s']:.2f} s "
                  f"({r['filter_samples_per_s']:,.0f} samples/s), "
                  f"sensor simulation {r['sensor_sim_s']:.2f} s "
                  f"({r['sensor_sim_samples_per_s']:,.0f} samples/s), "
                  f"errors+NEES {r['errors_nees_s']:.2f} s, truth/setup {r['truth_setup_s']:.2f} s")
            print(f"  compute wall {r['compute_wall_s']:.2f} s (workers busy {r['worker_total_s']:.2f} s), "
                  f"merge {r['merge_s']:.2f} s, "
                  f"other {r['wall_s'] - r['compute_wall_s'] - r['merge_s']:.2f} s")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
