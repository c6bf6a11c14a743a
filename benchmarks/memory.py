"""Peak memory of ``aidnav process`` and ``aidnav evaluate`` against the log length (issue 29, "Scale").

Runs the command (a child process each; its maximum resident set from ``wait4``) on:

* W1 (``../shared/data/sim_w1_pyins``, one hour at 100 Hz, ``examples/sim_w1_pyins.yaml``), forward and
  with ``--smooth``; targets ≤ 200 MiB and ≤ 250 MiB;
* a synthetic static log of 1 h and of 10 h at 100 Hz (level IMU at rest: gravity and the Earth rate plus
  white noise; GNSS at 1 Hz on the spot; given initial state, ZUPT on), made in a temporary directory
  chunk by chunk; targets: 10 h ≤ 250 MiB, memory at 10 h within 10 % of memory at 1 h, wall at 10 h ≤ 5 s.

``aidnav evaluate`` (streamed: memory independent of the lengths): W1's forward trajectory against its 10-Hz
truth, and a synthetic 100-Hz estimate (Parquet, σ columns) of 1 h and of 10 h against a 10-Hz reference
(Parquet; ``--eval-csv``: the estimate as CSV too, ``--eval-csv-only``: as CSV only); target: memory at
10 h within 10 % of memory at 1 h.

Also printed: the floor, step by step (the peak RSS of ``python -c "import numpy, pyarrow, numba"``, the
same plus numba's first dispatch of a cached trivial kernel, and ``aidnav process`` on a 60-s piece of
the 1-h log), and the load average (the machine is shared: wall times move with it; memory does not).
The console script loads numba's cache without parsing the kernels' bitcode (:mod:`aidnav.numba_load`)
and uses Arrow's jemalloc pool (:mod:`aidnav.cli`). ``--evaluate-only`` runs the evaluate rows alone.
``--figures`` keeps the figures (default ``--no-figures``: the figures are a separate cost, made from a
decimated copy). ``--process-only``: the static-log ``process`` rows alone (no W1, no floor, no evaluate).
The streamed ``process`` converts and writes its output in a background thread while the filter runs
(:class:`aidnav.io.stream.Background`): its wall time depends on a second core being free (on the shared
machine: ``chrt -f 1 python benchmarks/memory.py --process-only`` gives the run both cores). The growth
from 1 h to 10 h is printed in MiB too: the ratio only holds on a smaller floor if the growth is small.
``--per-process [N]`` (issue 41, session 10): W1 with the default outputs and ``--no-figures``, N runs each
(default 3), alternating: per process (the command, its figures' child) the peak of its resident set (RSS),
proportional set (PSS: a page shared with k processes counted 1/k) and unique set (USS: private pages),
and the peaks of their sums over both, sampled every 4 ms from ``/proc/PID/smaps_rollup``, beside the
command's ``ru_maxrss`` from ``wait4`` (Linux: the largest peak RSS of the command and the children it
reaped, not their sum). The sums of RSS count twice the pages that parent and child share after the fork;
PSS and USS do not, but the PSS depends on what else maps the same files (other Python processes of the
same environment on a shared machine lower it).
Run: ``python benchmarks/memory.py [--hours-long 10] [--evaluate-only] [--process-only]
[--eval-csv | --eval-csv-only] [--per-process [N]]``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: the data sets: ``$AIDNAV_DATA``, else ``../shared/data`` beside the repository
DATA = Path(os.environ.get("AIDNAV_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
W1 = DATA / "sim_w1_pyins"
W1_CFG = Path(__file__).resolve().parents[1] / "examples" / "sim_w1_pyins.yaml"
MIB = 1024 * 1024


def run(args, figures=False, command="process") -> tuple[float, float, float]:
    """(peak RSS [MiB], wall [s], CPU user + system [s]) of ``aidnav COMMAND ARGS`` in a child process."""
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    cmd = [sys.executable, "-c", "from aidnav.cli import main; main()", command, *map(str, args)]
    if not figures and command == "process":
        cmd.append("--no-figures")
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    err = p.stderr.read().decode()
    p.stderr.close()
    if status != 0:
        raise SystemExit(f"aidnav {command} {' '.join(map(str, args))} failed:\n{err}")
    return ru.ru_maxrss / 1024.0, wall, ru.ru_utime + ru.ru_stime


def static_log(d: Path, hours: float, rate: float = 100.0, seed: int = 1) -> tuple[Path, Path, Path]:
    """IMU (Parquet, written in row groups), GNSS (CSV) and a configuration of a static log."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    lat = np.radians(30.0)
    g, om = 9.79, 7.292115e-5
    dt = 1.0 / rate
    n = int(round(hours * 3600 * rate))
    rng = np.random.default_rng(seed)
    imu = d / f"imu_{hours:g}h.parquet"
    names = ["time", "dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad", "dv_x_m_s", "dv_y_m_s", "dv_z_m_s"]
    w = None
    for a in range(0, n, 1 << 18):
        m = min(1 << 18, n - a)
        t = (np.arange(a, a + m) + 1) * dt
        dth = np.array([0.0, om * np.cos(lat), om * np.sin(lat)]) * dt + rng.normal(0, 1e-5, (m, 3))
        dv = np.array([0.0, 0.0, g]) * dt + rng.normal(0, 1e-4, (m, 3))
        tbl = pa.table([t, *dth.T, *dv.T], names=names)
        if w is None:
            w = pq.ParquetWriter(imu, tbl.schema)
        w.write_table(tbl)
    w.close()
    gnss = d / f"gnss_{hours:g}h.csv"
    k = int(hours * 3600)
    tg = np.arange(1, k + 1, dtype=float)
    e = rng.normal(0, 0.5, (k, 3))
    cols = np.column_stack([tg, 30.0 + e[:, 1] / 111e3, 114.0 + e[:, 0] / 96e3, 50.0 + e[:, 2],
                            np.full((k, 3), 0.5)])
    np.savetxt(gnss, cols, delimiter=",", fmt="%.10f",
               header="time,lat_deg,lon_deg,height_m,std_e_m,std_n_m,std_u_m", comments="")
    cfg = d / "static.yaml"
    cfg.write_text("imu: {arw_deg_sqrt_h: 0.1, vrw_m_s_sqrt_h: 0.05}\n"
                   "gnss: {use: position}\n"
                   "init: {mode: given, lat_deg: 30.0, lon_deg: 114.0, height_m: 50.0,"
                   " velocity_m_s: [0, 0, 0], roll_deg: 0, pitch_deg: 0, heading_deg: 0}\n"
                   "filter: {prop_dt_s: 1.0}\n")
    return imu, gnss, cfg


def trajectory_logs(d: Path, hours: float, csv: bool = False, rate: float = 100.0, ref_rate: float = 10.0,
                    seed: int = 1) -> tuple[Path, Path]:
    """A synthetic estimate (``rate`` Hz, with σ; Parquet or CSV) and reference (``ref_rate`` Hz, Parquet) of
    a vehicle driving circles, written piece by piece (:class:`aidnav.io.stream.TrajectoryWriter`)."""
    import numpy as np

    from aidnav.io.stream import TrajectoryWriter

    rng = np.random.default_rng(seed)
    n = int(round(hours * 3600 * rate))
    step = int(round(rate / ref_rate))
    est = TrajectoryWriter(d / f"est_{hours:g}h.{'csv' if csv else 'parquet'}")
    ref = TrajectoryWriter(d / f"ref_{hours:g}h.parquet")
    for a in range(0, n, 1 << 18):
        k = np.arange(a, min(a + (1 << 18), n))
        est.write(_circles(1000.0 + k / rate, rng, 1.0))
        sel = k % step == 0
        ref.write(_circles(1000.0 + k[sel] / rate, rng, 0.0))
    return est.close(), ref.close()


def make_trajectory_logs(d: Path, hours: float, csv: bool) -> tuple[Path, Path]:
    """:func:`trajectory_logs` in a child process (the parent stays small: see :func:`make_log`)."""
    code = ("import sys; sys.path.insert(0, sys.argv[1]); from pathlib import Path; import memory; "
            "memory.trajectory_logs(Path(sys.argv[2]), float(sys.argv[3]), csv=sys.argv[4] == '1')")
    args = [str(Path(__file__).parent), str(d), str(hours), str(int(csv))]
    subprocess.run([sys.executable, "-c", code, *args], check=True)
    return d / f"est_{hours:g}h.{'csv' if csv else 'parquet'}", d / f"ref_{hours:g}h.parquet"


def _circles(t, rng, noise: float):
    """A vehicle on a 300-s circle at times ``t``; with ``noise``: estimation noise and σ columns."""
    import numpy as np

    from aidnav.data import Trajectory

    m = len(t)
    w = 2 * np.pi * t / 300.0
    e = rng.normal(0, 1, (m, 9)) * noise
    std = np.full((m, 3), 0.3) if noise else None
    return Trajectory(t, np.radians(30.0) + 2e-5 * np.sin(w) + 5e-8 * e[:, 0],
                      np.radians(114.0) + 2e-5 * np.cos(w) + 5e-8 * e[:, 1], 50.0 + np.sin(w) + 0.3 * e[:, 2],
                      np.column_stack([-np.sin(w), np.cos(w), np.zeros(m)]) * 2.6 + 0.05 * e[:, 3:6],
                      (np.column_stack([0 * w, 0 * w, w + np.pi / 2]) + 1e-3 * e[:, 6:9]) % (2 * np.pi),
                      std_pos=std, std_vel=None if std is None else std / 6,
                      std_att=None if std is None else std / 300)


def make_log(d: Path, hours: float, seed: int) -> tuple[Path, Path, Path]:
    """:func:`static_log` in a child process (and the 60-s piece ``imu_60s.parquet`` of the IMU file).

    The parent stays small: Linux reports as a child's peak RSS (``ru_maxrss``) at least what the parent
    held when it forked (fork copies the page tables; vfork and exec keep the old high-water mark), so
    a parent that had built the logs itself would raise every figure measured after it."""
    code = ("import sys; sys.path.insert(0, sys.argv[1]); from pathlib import Path; import memory; "
            "import pyarrow.parquet as pq; d = Path(sys.argv[2]); "
            "i, g, c = memory.static_log(d, float(sys.argv[3]), seed=int(sys.argv[4])); "
            "pq.write_table(pq.read_table(i).slice(0, 6000), d / 'imu_60s.parquet')")
    subprocess.run([sys.executable, "-c", code, str(Path(__file__).parent), str(d), str(hours), str(seed)],
                   check=True)
    return d / f"imu_{hours:g}h.parquet", d / f"gnss_{hours:g}h.csv", d / "static.yaml"


def floor(d: Path, gnss: Path, cfg: Path) -> float:
    """Peak RSS on the first 60 s of the log (imports, numba dispatch, fixed buffers)."""
    return run(["--imu", d / "imu_60s.parquet", "--gnss", gnss, "--config", cfg, "-o", d / "o60"])[0]


FIRST_DISPATCH = """
import numpy, pyarrow, pyarrow.parquet, numba
@numba.njit(cache=True)
def f(x):
    return x + 1.0
f(1.0)
"""


def python_rss(code: str, cwd: Path) -> float:
    """Peak RSS [MiB] of ``python -c CODE`` in a child process."""
    p = subprocess.Popen([sys.executable, "-c", code], cwd=cwd)
    _, status, ru = os.wait4(p.pid, 0)
    if status != 0:
        raise SystemExit(f"python -c {code!r} failed")
    return ru.ru_maxrss / 1024.0


_SMAPS = {"Rss:": "rss", "Pss:": "pss", "Private_Clean:": "uss", "Private_Dirty:": "uss"}


def _smaps(pid: int) -> dict | None:
    """RSS, PSS, USS [MiB] of a process (``/proc/PID/smaps_rollup``), None when it is gone."""
    got = {"rss": 0.0, "pss": 0.0, "uss": 0.0}
    try:
        with open(f"/proc/{pid}/smaps_rollup") as f:
            for line in f:
                k = _SMAPS.get(line.split(maxsplit=1)[0])
                if k:
                    got[k] += int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return got


def _children(pid: int) -> list[int]:
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as f:
            return [int(c) for c in f.read().split()]
    except OSError:
        return []


def per_process(args, figures: bool) -> dict:
    """Peaks of RSS/PSS/USS of ``aidnav process ARGS`` and of its figures' child, and of their sums,
    sampled every 4 ms; ``maxrss``: the command's ``ru_maxrss`` (``wait4``)."""
    import threading  # lazy: this mode only

    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    cmd = [sys.executable, "-c", "from aidnav.cli import main; main()", "process", *map(str, args)]
    if not figures:
        cmd.append("--no-figures")
    p = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    peak: dict = {}
    stop = threading.Event()

    def sample():
        while not stop.wait(0.004):
            tot = {"rss": 0.0, "pss": 0.0, "uss": 0.0}
            for role, q in [("command", p.pid), *(("child", c) for c in _children(p.pid))]:
                m = _smaps(q)
                if m is None:
                    continue
                for k, v in m.items():
                    peak[role, k] = max(peak.get((role, k), 0.0), v)
                    tot[k] += v
            for k, v in tot.items():
                peak["sum", k] = max(peak.get(("sum", k), 0.0), v)

    t = threading.Thread(target=sample, daemon=True)
    t.start()
    _, status, ru = os.wait4(p.pid, 0)
    stop.set()
    t.join()
    err = p.stderr.read().decode()
    p.stderr.close()
    if status != 0:
        raise SystemExit(f"aidnav process failed:\n{err}")
    peak["maxrss"] = ru.ru_maxrss / 1024.0
    return peak


def per_process_rows(d: Path, n: int) -> None:
    """W1, default outputs and ``--no-figures`` alternately, ``n`` runs each: medians of the peaks."""
    import statistics  # lazy: this mode only

    a = ["--imu", W1 / "imu.parquet", "--gnss", W1 / "gnss.csv", "--config", W1_CFG, "-o", d / "w1"]
    run(a)  # warm the numba cache
    got = {True: [], False: []}
    for _ in range(n):
        for fig in (True, False):
            got[fig].append(per_process(a, fig))
    for fig, name in ((True, "default outputs"), (False, "--no-figures")):
        rs = got[fig]

        def med(key, rs=rs):
            return statistics.median(r.get(key, 0.0) for r in rs)

        mx = [r["maxrss"] for r in rs]
        print(f"W1 {name}: ru_maxrss {min(mx):.1f}–{max(mx):.1f} MiB (median {statistics.median(mx):.1f}; "
              f"target ≤ 300 MiB with the default outputs); medians of {n} runs [MiB]:")
        for role in ("command", "child", "sum"):
            if (role, "rss") in rs[0]:
                print(f"  {role:8s} RSS {med((role, 'rss')):6.1f}  PSS {med((role, 'pss')):6.1f}  "
                      f"USS {med((role, 'uss')):6.1f}")


def main() -> None:
    if "--per-process" in sys.argv:
        k = sys.argv.index("--per-process") + 1
        n = int(sys.argv[k]) if k < len(sys.argv) and sys.argv[k].isdigit() else 3
        print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())} (2 cores shared)")
        with tempfile.TemporaryDirectory() as td:
            per_process_rows(Path(td), n)
        print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        return
    long_h = float(sys.argv[sys.argv.index("--hours-long") + 1]) if "--hours-long" in sys.argv else 10.0
    if "--evaluate-only" in sys.argv:  # only the evaluate rows (no W1)
        with tempfile.TemporaryDirectory() as td:
            print(f"load average {os.getloadavg()[0]:.1f} (2 cores shared)")
            evaluate_rows(Path(td), long_h, _eval_formats())
            print(f"load average {os.getloadavg()[0]:.1f}")
        return
    figures, only = "--figures" in sys.argv, "--process-only" in sys.argv
    print(f"load average {os.getloadavg()[0]:.1f} (2 cores shared)")
    with tempfile.TemporaryDirectory() as td:
        d = Path(td)
        rows = []
        if W1.exists() and not only:
            a = ["--imu", W1 / "imu.parquet", "--gnss", W1 / "gnss.csv", "--config", W1_CFG, "-o", d / "w1"]
            run(a)  # warm the numba cache
            rows.append(("W1 forward", *run(a, figures), "≤ 200 MiB"))
            rows.append(("W1 --smooth", *run([*a, "--smooth"], figures), "≤ 250 MiB"))
        i1, g1, c1 = make_log(d, 1.0, 1)
        if not only:
            floor_rows(d, g1, c1, rows)
        r1 = run(["--imu", i1, "--gnss", g1, "--config", c1, "-o", d / "s1"], figures)
        rows.append(("static 1 h, 100 Hz", *r1, ""))
        il, gl, cl = make_log(d, long_h, 2)
        rl = run(["--imu", il, "--gnss", gl, "--config", cl, "-o", d / "sl"], figures)
        rows.append((f"static {long_h:g} h, 100 Hz", *rl, "≤ 250 MiB, wall ≤ 5 s (CPU on a loaded machine)"))
        for name, mem, wall, cpu, target in rows:
            print(f"{name:36s} peak RSS {mem:7.1f} MiB  wall {wall:6.2f} s  CPU {cpu:6.2f} s  {target}")
        print(f"memory {long_h:g} h / 1 h: {rl[0] / r1[0]:.3f} (target ≤ 1.10)")
        print(f"memory growth {long_h:g} h − 1 h: {rl[0] - r1[0]:.1f} MiB "
              "(≤ 15 MiB keeps the ratio ≤ 1.10 on a floor ≈ 130 MiB lower)")
        checks = [(name, mem, float(target.split()[1])) for name, mem, _, _, target in rows
                  if target.startswith("≤") and "MiB" in target]
        checks.append((f"static {long_h:g} h wall [s]", rl[1], 5.0))
        checks.append((f"memory {long_h:g} h / 1 h", rl[0] / r1[0], 1.10))
        checks.append((f"memory growth {long_h:g} h − 1 h [MiB]", rl[0] - r1[0], 15.0))
        for name, got, target in checks:
            print(f"  {name}: {got:.2f} against ≤ {target:g}: {'PASS' if got <= target else 'FAIL'}")
        if not only:
            evaluate_rows(d, long_h, _eval_formats())
        print(f"load average {os.getloadavg()[0]:.1f}")


def _eval_formats() -> list[str]:
    if "--eval-csv-only" in sys.argv:
        return ["csv"]
    return ["parquet", "csv"] if "--eval-csv" in sys.argv else ["parquet"]


def floor_rows(d: Path, gnss: Path, cfg: Path, rows: list) -> None:
    """The floor rows: imports, numba's first dispatch, ``aidnav process`` on 60 s of the log."""
    nan = float("nan")
    imports = "import numpy, pyarrow, numba"
    rows.append((f"floor: {imports}", python_rss(imports, d), nan, nan, "(interpreter + imports)"))
    (d / "fd.py").write_text(FIRST_DISPATCH)
    python_rss("import fd", d)  # writes the trivial kernel's cache
    rows.append(("floor: + numba's first dispatch", python_rss("import fd", d), nan, nan,
                 "(a cached trivial kernel)"))
    rows.append(("floor: 60 s of the static log", floor(d, gnss, cfg), nan, nan,
                 "(aidnav process, fixed part)"))


def evaluate_rows(d: Path, long_h: float, formats: list[str]) -> None:
    """``aidnav evaluate``: W1 (when its forward trajectory was made above) and the synthetic logs."""
    rows = []
    w1 = d / "w1" / "trajectory.parquet"
    if w1.exists():
        args = ["--estimate", w1, "--truth", W1 / "truth_10hz.parquet", "-o", d / "ew1"]
        rows.append(("evaluate W1 (1 h, 10-Hz truth)", *run(args, command="evaluate")))
    got = {}
    for fmt in formats:
        for hours in (1.0, long_h):
            e, r = make_trajectory_logs(d, hours, fmt == "csv")
            got[fmt, hours] = run(["--estimate", e, "--truth", r, "-o", d / f"ev_{fmt}_{hours:g}"],
                                  command="evaluate")
            rows.append((f"evaluate {hours:g} h {fmt} (100 Hz vs 10 Hz)", *got[fmt, hours]))
            e.unlink()
            r.unlink()
    for name, mem, wall, cpu in rows:
        print(f"{name:36s} peak RSS {mem:7.1f} MiB  wall {wall:6.2f} s  CPU {cpu:6.2f} s")
    for fmt in formats:
        print(f"evaluate memory {long_h:g} h / 1 h ({fmt}): {got[fmt, long_h][0] / got[fmt, 1.0][0]:.3f} "
              "(target ≤ 1.10)")


if __name__ == "__main__":
    main()
