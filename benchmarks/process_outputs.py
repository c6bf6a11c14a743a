"""``aidnav process`` with its default outputs (overview, maps, page) against ``--no-figures`` (issue 41).

Each run is the command in a fresh process, started as the ``aidnav`` console script starts it (``python -c``
with ``sys.argv[0]`` = ``aidnav`` before ``aidnav.cli`` is imported: the console script's start, i.e. the
collector paused and Ctrl-C held during the imports), its wall time, CPU time (user + system, of it and of
the figures' child and the child's drawing helper) and peak resident set (``wait4``: the largest of the
command and the processes it forks for the figures) measured from outside. For W1 the peak of the summed
proportional set size of the command and its descendants (``/proc``, sampled every 10 ms) is taken in
**separate, untimed runs**: reading ``/proc/PID/smaps_rollup`` walks the process's page tables under its
memory-map lock, and every 10 ms that blocked W1 ``--no-figures`` ≈ 4,900 times (voluntary context
switches) and added 0.35–0.47 s to its wall time (issue 41, session 14: the benchmark's ``--no-figures``
1.57 s against 1.06–1.11 s from the command line). Cases:

* W1 (``../shared/data/sim_w1_pyins``, one hour at 100 Hz, ``examples/sim_w1_pyins.yaml``): default outputs
  and ``--no-figures`` alternately, N pairs: the median ratio of the pairs' wall times (target ≤ 1.3) and
  the default's peak memory (target ≤ 300 MiB);
* W1's first 60 s with the default outputs (target ≤ 1.0 s wall, warm: numba's cache loaded, no
  ``aidnav compile`` build: the command as a user runs it, ``$AIDNAV_KERNELS`` unset, with
  ``AIDNAV_KERNEL_DIR`` an empty folder, i.e. a fresh install on which ``aidnav compile`` never ran);
* a synthetic static log (``benchmarks/memory.py``'s) of 1 h and of 4 h with the default outputs: peak
  memory at 4 h within 5 % of 1 h's.

The aidnav package's bytecode is compiled first (``python -m compileall``, as ``pip install`` does for an
installed package): where ``PYTHONDONTWRITEBYTECODE`` is set, a source tree would otherwise compile every
aidnav module from source at each command (≈ 0.1 CPU-s of the 60-s log's ≈ 1 CPU-s; issue 41, session 9).

The machine is shared: the load average is printed with the figures, and the CPU times beside the wall
times (with two free cores the figures' child runs beside the filter; on a loaded machine it competes).

Run: ``python benchmarks/process_outputs.py [--pairs N] [--skip-static]``
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import memory  # noqa: E402  (the static log and its child-process builder)

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("AIDNAV_DATA", ROOT.parent / "shared" / "data"))
W1 = DATA / "sim_w1_pyins"
CFG = ROOT / "examples" / "sim_w1_pyins.yaml"
#: the builds' folder of the timed commands: an empty one (no ``aidnav compile`` build: numba's JIT, from its
#: cache, on the path a fresh install takes)
NO_BUILD = Path(tempfile.mkdtemp(prefix="aidnav-no-kernel-build-"))
TARGETS = {"ratio": 1.3, "peak_mib": 300.0, "growth_4h": 0.05, "wall_60s": 1.0}


def _tree(pid: int) -> list[int]:
    out, todo = [], [pid]
    while todo:
        q = todo.pop()
        out.append(q)
        try:
            for task in os.listdir(f"/proc/{q}/task"):
                with open(f"/proc/{q}/task/{task}/children") as f:
                    todo += [int(c) for c in f.read().split()]
        except OSError:
            pass
    return out


def _pss_mib(pids: list[int]) -> float:
    """Summed proportional set size of the processes [MiB] (pages shared after a fork counted once)."""
    total = 0
    for q in pids:
        try:
            with open(f"/proc/{q}/smaps_rollup") as f:
                for line in f:
                    if line.startswith("Pss:"):
                        total += int(line.split()[1])
                        break
        except OSError:
            pass
    return total / 1024.0


class TreeMemory:
    """The peak of the summed PSS of a process and its descendants, sampled every 10 ms in a thread."""

    def __init__(self, pid: int):
        import threading

        self.pid, self.peak, self._stop = pid, 0.0, threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self):
        while not self._stop.wait(0.01):
            self.peak = max(self.peak, _pss_mib(_tree(self.pid)))

    def stop(self) -> float:
        self._stop.set()
        self._t.join()
        return self.peak


PSS: dict[str, list[float]] = {}


#: the ``aidnav`` console script's start (``sys.argv[0]`` names ``aidnav`` when ``aidnav.cli`` is imported)
COMMAND = [sys.executable, "-c",
           "import sys; sys.argv[0] = 'aidnav'; from aidnav.cli import main; sys.exit(main())"]


def run(args, figures: bool, label: str | None = None) -> tuple[float, float, float]:
    """(wall [s], CPU [s], peak RSS [MiB]) of ``aidnav process ARGS`` (JIT kernels from numba's cache);
    with ``label``, the peak summed PSS of the command and its figures' child goes to ``PSS[label]``
    (the sampler slows the command: such a run's wall time is not a timing)."""
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1",
               AIDNAV_KERNEL_DIR=str(NO_BUILD))
    env.pop("AIDNAV_KERNELS", None)  # the default (auto): what a user runs
    cmd = [*COMMAND, "process", *map(str, args)]
    if not figures:
        cmd.append("--no-figures")
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    mem = TreeMemory(p.pid) if label else None
    _, status, ru = os.wait4(p.pid, 0)
    if mem is not None:
        PSS.setdefault(label, []).append(mem.stop())
    wall = time.perf_counter() - t0
    err = p.stderr.read().decode()
    p.stderr.close()
    if status != 0:
        raise SystemExit(f"aidnav process {' '.join(map(str, args))} failed:\n{err}")
    return wall, ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024.0


def compile_bytecode() -> str:
    """The aidnav package's ``.pyc`` files written (what ``pip install`` does for an installed package)."""
    import aidnav  # lazy: the package under test (PYTHONPATH), for its folder

    pkg = Path(aidnav.__file__).resolve().parent
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(pkg)], check=True,
                   stdout=subprocess.DEVNULL)
    return str(pkg)


def cut_60s(d: Path) -> list:
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    imu = pq.read_table(W1 / "imu.parquet")
    pq.write_table(imu.filter(pc.less_equal(imu["time"], 60.0)), d / "imu60.parquet")
    lines = (W1 / "gnss.csv").read_text().splitlines(keepends=True)
    (d / "gnss60.csv").write_text("".join(ln for ln in lines if not ln[:1].isdigit()
                                          or float(ln.split(",", 1)[0]) <= 60.0))
    return ["--imu", d / "imu60.parquet", "--gnss", d / "gnss60.csv", "--config", CFG]


def main(argv: list[str]) -> int:
    pairs = int(argv[argv.index("--pairs") + 1]) if "--pairs" in argv else 5
    if not W1.is_dir():
        print(f"no {W1}: the benchmark needs the W1 log")
        return 2
    ok = True
    print(f"bytecode of {compile_bytecode()} compiled (as an installed package has it)")
    print(f"aidnav process, default outputs vs --no-figures; {os.cpu_count()} CPUs, load average "
          + " ".join(f"{x:.2f}" for x in os.getloadavg()))
    with tempfile.TemporaryDirectory(prefix="aidnav-outputs-") as tmp:
        tmp = Path(tmp)
        w1 = ["--imu", W1 / "imu.parquet", "--gnss", W1 / "gnss.csv", "--config", CFG, "-o", tmp / "w1"]
        run(w1, False)  # numba's cache loaded once (compiled after a source change), not counted
        res = {True: [], False: []}
        for _ in range(pairs):
            for fig in (True, False):
                res[fig].append(run(w1, fig))
        for fig in (True, False):  # the PSS sampler apart: it slows the command it samples
            run(w1, fig, f"w1 {fig}")
        ratios = [a[0] / b[0] for a, b in zip(res[True], res[False], strict=True)]
        cpu_ratio = statistics.median(a[1] / b[1] for a, b in zip(res[True], res[False], strict=True))
        for fig, name in ((True, "default outputs"), (False, "--no-figures")):
            w, c, m = (statistics.median(x[k] for x in res[fig]) for k in range(3))
            print(f"  W1 1 h, {name:15s}: wall {w:6.3f} s, CPU {c:6.3f} s, peak {m:6.1f} MiB "
                  f"(median of {pairs})")
        r = statistics.median(ratios)
        peak = max(x[2] for x in res[True])
        verdict = "PASS" if r <= TARGETS["ratio"] else "FAIL"
        ok &= verdict == "PASS"
        print(f"  W1: default / --no-figures wall, median of {pairs} pairs: {r:.2f} (target <= "
              f"{TARGETS['ratio']}: {verdict}); CPU ratio {cpu_ratio:.2f}; load average "
              + " ".join(f"{x:.2f}" for x in os.getloadavg()))
        print(f"  W1 peak summed PSS of the command and the figures' processes (every 10 ms, in untimed "
              f"runs): default "
              f"{max(PSS['w1 True']):.1f} MiB, --no-figures {max(PSS['w1 False']):.1f} MiB")
        verdict = "PASS" if peak <= TARGETS["peak_mib"] else "FAIL"
        ok &= verdict == "PASS"
        print(f"  W1 default outputs: peak memory {peak:.1f} MiB, largest of {pairs} (target <= "
              f"{TARGETS['peak_mib']:.0f}: {verdict})")

        short = [*cut_60s(tmp), "-o", tmp / "s60"]
        run(short, True)
        got = [run(short, True) for _ in range(pairs)]
        w = statistics.median(x[0] for x in got)
        verdict = "PASS" if w <= TARGETS["wall_60s"] else "FAIL"
        ok &= verdict == "PASS"
        print(f"  W1 first 60 s, default outputs: wall {w:.3f} s (min {min(x[0] for x in got):.3f}), CPU "
              f"{statistics.median(x[1] for x in got):.3f} s (target wall <= {TARGETS['wall_60s']}: "
              f"{verdict}); "
              "load average " + " ".join(f"{x:.2f}" for x in os.getloadavg()))

        if "--skip-static" not in argv:
            peaks = {}
            for hours in (1.0, 4.0):
                d = tmp / f"static{hours:g}"
                d.mkdir()
                imu, gnss, cfg = memory.make_log(d, hours, seed=1)
                peaks[hours] = run(["--imu", imu, "--gnss", gnss, "--config", cfg, "-o", d / "out"], True)
            g = peaks[4.0][2] / peaks[1.0][2] - 1.0
            verdict = "PASS" if g <= TARGETS["growth_4h"] else "FAIL"
            ok &= verdict == "PASS"
            print(f"  static log, default outputs: peak 1 h {peaks[1.0][2]:.1f} MiB, 4 h "
                  f"{peaks[4.0][2]:.1f} MiB "
                  f"(+{100 * g:.1f} %, target <= {100 * TARGETS['growth_4h']:.0f} %: {verdict}); wall 1 h "
                  f"{peaks[1.0][0]:.2f} s, 4 h {peaks[4.0][0]:.2f} s")
    NO_BUILD.rmdir()
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
