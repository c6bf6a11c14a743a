"""Where the time of ``aidnav process`` goes: a timeline of the command, its figures' child and the child's
drawing helper (issue 41).

Each run starts the command as the ``aidnav`` console script starts (``sys.argv[0]`` = ``aidnav``; the
kernels from numba's cache, ``$AIDNAV_KERNELS`` unset, an empty ``AIDNAV_KERNEL_DIR``: no ahead-of-time
build) in a fresh process whose stages are timed from outside aidnav's code: the first import of the big
packages (an import hook), aidnav's own stage functions (wrapped once their module is loaded: nothing is
imported earlier than the command imports it), and numba's kernel loads (numba's public event API: each
hold of its compiler lock, ``numba:compiler_lock``, is one load from the cache here). Times are seconds from
just before the process is started (``time.perf_counter``: one monotonic clock for every process), the
median over the runs; ``>`` a stage's start, ``<`` its end, ``[child]``/``[helper]`` the figures' processes.
The hooks cost ≈ 20 ms of their own. Also printed: the wall and CPU time of each run (``wait4``: the command
and the children it reaped) and the load average, and the target of the issue for the 60-s log (≤ 1.0 s
wall with the default outputs, measured without hooks by ``process_outputs.py``).

Run: ``python benchmarks/process_timeline.py [--runs N] [--no-figures] [-- PROCESS ARGS]`` (default: W1's
first 60 s with ``examples/sim_w1_pyins.yaml``, as ``process_outputs.py`` cuts it).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: aidnav's stage functions wrapped in the timed process: module → names (a class attribute as Class.name)
STAGES = {
    "aidnav.cli": ["_start_kernels", "_resume_collections", "_leave"],
    "aidnav.apps.run_outputs": ["start_outputs", "_warm_up", "_skeleton", "_job", "write_outputs"],
    "aidnav.apps.process": ["job_config", "read_gnss_any", "open_imu"],
    "aidnav.apps.process_stream": ["_checks", "run_summary"],
    "aidnav.apps.common": ["write_summary_files"],
    "aidnav.filters.gnss_errors": ["choose_gnss_errors"],
    "aidnav.filters.stream": ["stream_loose"],
    "aidnav.apps.overview_helper": ["_pixels", "_maps", "DrawingHelper.start"],
    "aidnav.report.overview": ["overview_figure", "draw_panels", "save_png"],
    "aidnav.report.run_page": ["write_run_page"],
}
PACKAGES = ("typer", "pydantic", "numpy", "yaml", "numba", "pyarrow", "rich", "matplotlib")
TARGET_60S = 1.0


def _child(t0: float, argv: list[str]) -> None:
    """The timed process: hooks installed, then the console script's main."""
    import functools  # lazy: the timed process only
    import importlib.abc  # lazy: the timed process only
    import importlib.machinery  # lazy: the timed process only

    def ev(name: str) -> None:
        os.write(2, f"TL {os.getpid()} {time.perf_counter() - t0:.4f} {name}\n".encode())

    def wrap(owner, name: str) -> None:
        fn = getattr(owner, name)

        @functools.wraps(fn)
        def timed(*a, **k):
            ev(f"> {name}")
            try:
                return fn(*a, **k)
            finally:
                ev(f"< {name}")

        setattr(owner, name, timed)

    def loaded(module) -> None:
        for attr in STAGES.get(module.__name__, ()):
            owner, _, name = attr.rpartition(".")
            wrap(getattr(module, owner) if owner else module, name)
        if module.__name__ == "numba":
            _numba_loads(ev)

    class Finder(importlib.abc.MetaPathFinder):
        seen: set = set()

        def find_spec(self, name, path, target=None):
            if name in PACKAGES and name not in self.seen:
                self.seen.add(name)
                ev(f"import {name}")
            if name not in STAGES and name != "numba":
                return None
            spec = importlib.machinery.PathFinder.find_spec(name, path)
            if spec is None or spec.loader is None:
                return spec
            run = spec.loader.exec_module

            def exec_module(module):
                run(module)
                loaded(module)

            spec.loader.exec_module = exec_module
            return spec

    sys.meta_path.insert(0, Finder())
    ev("interpreter up")
    sys.argv = ["aidnav", *argv]
    from aidnav.cli import main  # lazy: after the hooks

    sys.exit(main())


def _numba_loads(ev) -> None:
    """One event pair per outermost hold of numba's compiler lock (numba's event API; registered when numba
    has been imported): a kernel's load from the cache (or its compilation), numba's CPU target set up by
    the first one."""
    import numba.core.event as nev  # lazy: numba, once the command has imported it

    class Loads(nev.Listener):
        depth = 0

        def on_start(self, event):
            self.depth += 1
            if self.depth == 1:
                ev("> numba")

        def on_end(self, event):
            self.depth -= 1
            if self.depth == 0:
                ev("< numba")

    nev.register("numba:compiler_lock", Loads())


def _run(args: list[str]) -> tuple[list[tuple[int, float, str]], float, float]:
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1",
               AIDNAV_KERNEL_DIR=tempfile.mkdtemp(prefix="aidnav-no-build-"))
    env.pop("AIDNAV_KERNELS", None)
    t0 = time.perf_counter()
    p = subprocess.Popen([sys.executable, __file__, "--child", repr(t0), *map(str, args)], env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    err = p.stderr.read().decode()
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    os.rmdir(env["AIDNAV_KERNEL_DIR"])
    if status != 0:
        raise SystemExit(f"aidnav process failed:\n{err}")
    events = []
    for line in err.splitlines():
        if line.startswith("TL "):
            _, pid, t, name = line.split(" ", 3)
            events.append((int(pid), float(t), name))
    return events, wall, ru.ru_utime + ru.ru_stime


def _labelled(events) -> list[tuple[str, float]]:
    """(label, time) of one run: the processes named by what they do, repeated stages numbered; numba's
    holds of its compiler lock as ("numba k", start) and ("numba k ms", duration)."""
    parent = events[0][0]
    role = {parent: ""}
    for pid, _, name in events:
        if name == "> _warm_up":
            role[pid] = "[child] "
        elif name == "> _pixels":
            role[pid] = "[helper] "
    count: dict[str, int] = {}
    out, held = [], None
    for pid, t, name in sorted(events, key=lambda e: e[1]):
        if name in ("> numba", "< numba"):
            if name == "> numba":
                held = t
                count["numba"] = count.get("numba", 0) + 1
            elif held is not None:
                out += [(f"numba {count['numba']}", held), (f"numba {count['numba']} ms", t - held)]
            continue
        label = role.get(pid, "[?] ") + name
        count[label] = count.get(label, 0) + 1
        out.append((label if count[label] == 1 else f"{label} #{count[label]}", t))
    return out


def main(argv: list[str]) -> int:
    if argv[:1] == ["--child"]:
        _child(float(argv[1]), argv[2:])
        return 0
    runs = int(argv[argv.index("--runs") + 1]) if "--runs" in argv else 5
    if "--" in argv:
        args = argv[argv.index("--") + 1:]
    else:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        import process_outputs  # lazy: its W1 paths and the 60-s cut

        tmp = Path(tempfile.mkdtemp(prefix="aidnav-timeline-"))
        args = ["process", *process_outputs.cut_60s(tmp), "-o", tmp / "out"]
        args += ["--no-figures"] * ("--no-figures" in argv)
    print(f"aidnav {' '.join(map(str, args))}: {runs} runs (+1 not counted); {os.cpu_count()} CPUs, "
          "load average " + " ".join(f"{x:.2f}" for x in os.getloadavg()))
    _run(args)  # caches warm
    walls, cpus, times = [], [], {}
    for _ in range(runs):
        events, wall, cpu = _run(args)
        walls.append(wall)
        cpus.append(cpu)
        for label, t in _labelled(events):
            times.setdefault(label, []).append(t)
    order = {label: i for i, label in enumerate(times)}
    rows = sorted((statistics.median(ts), order[label], label, len(ts)) for label, ts in times.items()
                  if not label.endswith(" ms"))
    small = []
    for t, _, label, n in rows:
        note = f"  (in {n} of {runs} runs)" if n < runs else ""
        if label.startswith("numba "):
            ms = 1e3 * statistics.median(times[label + " ms"])
            if ms < 2.0:
                small.append(ms)
                continue
            label = f"numba's compiler lock held {ms:.1f} ms (kernel loads; the first sets up numba)"
        print(f"  {t:7.3f} s  {label}{note}")
    print(f"  (and {len(small)} holds of numba's compiler lock under 2 ms, {sum(small):.1f} ms in all)")
    w = statistics.median(walls)
    print(f"wall {w:.3f} s (min {min(walls):.3f}), CPU {statistics.median(cpus):.3f} s, median of {runs} "
          f"(hooks included; the issue's target for the 60-s log with the default outputs: <= {TARGET_60S} "
          f"s, measured without hooks by process_outputs.py); load average "
          + " ".join(f"{x:.2f}" for x in os.getloadavg()))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
