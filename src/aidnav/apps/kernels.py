"""``aidnav compile``: an ahead-of-time build of the kernels the commands call (:mod:`aidnav.jit`).

1. **Record.** The built-in workloads (below) run as ``aidnav`` commands in child processes with
   ``AIDNAV_KERNELS=record``: a short simulated flight, then ``process`` on it (streamed Parquet and
   in-memory CSV, forward and ``--smooth``), ``evaluate``, ``characterise`` on a 2-h static MEMS log;
   each call of a kernel from Python is
   written down with its argument types. A user's own command can be added with ``--also "ARGS"``
   (its kernel calls recorded the same way).
2. **Build.** One CPython extension module (``numba.pycc``, used through its public ``CC`` class only)
   exports a trampoline per recorded signature; the trampoline calls the kernel, which numba compiles
   with its own options (``fastmath``, ...) and links in. ``table.json`` maps (kernel, argument
   typekey) to the exported name. (pycc's exported wrappers hold the GIL: a ``nogil`` kernel served
   from the build does not run beside another thread.)

Optional (issue 36): the build needs the ``aidnav[compile]`` extra (setuptools, which ``numba.pycc``
builds with) and a C compiler; without it every command runs on numba's JIT with the same results.
The build is written into :func:`aidnav.jit.build_path` (the key hashes the source tree, Python,
numpy, numba, llvmlite and the CPU) through a temporary folder renamed into place. The console script
then serves the covered calls from it and falls back to numba's JIT for anything else.
"""

from __future__ import annotations

import importlib
import json
import os
import pickle
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from aidnav import jit

__all__ = ["compile_kernels", "workloads", "build_from_records", "build_status"]


def workloads(data: Path, out: Path) -> list[list[str]]:
    """The commands whose kernel calls the build covers (``data``: the folder of the simulated flight,
    written by the first command, and of the static log, written before: :data:`_STATIC_LOG`)."""
    imu_pq, imu_csv, gnss = data / "imu.parquet", data / "imu.csv", data / "gnss.csv"
    return [
        ["simulate", "-o", str(data), "--format", "both"],
        ["process", "--imu", str(imu_pq), "--gnss", str(gnss), "-o", str(out / "p1"), "--no-figures"],
        ["process", "--imu", str(imu_pq), "--gnss", str(gnss), "-o", str(out / "p2"), "--no-figures",
         "--smooth"],
        ["process", "--imu", str(imu_csv), "--gnss", str(gnss), "-o", str(out / "p3"), "--no-figures"],
        ["process", "--imu", str(imu_csv), "--gnss", str(gnss), "-o", str(out / "p4"), "--smooth",
         "--format", "csv"],
        ["evaluate", "--estimate", str(out / "p1" / "trajectory.parquet"), "--truth",
         str(data / "truth.parquet"), "-o", str(out / "e1")],
        ["characterise", "--imu", str(data / "static.parquet"), "-o", str(out / "c1")],
    ]


#: a static MEMS log for the ``characterise`` workload: 2 h at 100 Hz (long enough for every fitted term)
_STATIC_LOG = """
import sys
import numpy as np
from aidnav.data import ImuData
from aidnav.io.interchange import write_imu
from aidnav.sim.imu import ImuSpec, corrupt_imu
n, dt = 720_000, 0.01
t = dt * np.arange(1, n + 1)
truth = ImuData(t, np.zeros((n, 3)), np.tile([0.0, 0.0, 9.80665 * dt], (n, 1)), t0=0.0)
write_imu(corrupt_imu(truth, ImuSpec.grade("mems"), np.random.default_rng(29))[0], sys.argv[1])
"""


def _run(args: list[str], env: dict) -> None:
    cmd = [sys.executable, "-m", "aidnav", *args]
    p = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"aidnav {shlex.join(args)} failed while recording kernel calls:\n{p.stderr}")


def record(commands: list[list[str]], record_file: Path, progress=None) -> dict:
    """Run ``commands`` as ``aidnav`` commands in record mode; returns the merged records."""
    env = dict(os.environ, AIDNAV_KERNELS="record", AIDNAV_KERNEL_RECORD=str(record_file))
    for args in commands:
        if progress:
            progress(f"recording: aidnav {args[0]}")
        _run(args, env)
    return pickle.loads(record_file.read_bytes()) if record_file.is_file() else {}


def _resolve(name: str):
    """The kernel (a numba dispatcher in this process's jit mode) named ``module:qualname``."""

    module, qualname = name.split(":")
    obj = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


def build_from_records(records: dict, folder: Path, progress=None) -> dict:
    """Compile the recorded signatures into one extension module in ``folder`` (created); must run in
    a process whose kernels are numba's dispatchers (the jit mode). Returns the table written."""
    import numba  # lazy: the build is numba's
    from llvmlite import binding as llvm  # lazy: as numba
    from numba.pycc import CC  # lazy: as numba

    module_name = "aidnav_kernels_" + folder.name.replace("-", "_")
    cc = CC(module_name)
    cc.output_dir = str(folder)
    cc.verbose = False
    cc.target_cpu = llvm.get_host_cpu_name()
    exports = []
    for name in sorted(records):
        kernel = _resolve(name)
        for key, argtypes in records[name].items():
            if argtypes not in kernel.overloads:
                kernel.compile(argtypes)
            sig = kernel.overloads[argtypes].signature
            export = f"k{len(exports)}"
            n = len(argtypes)
            params = ", ".join(f"a{i}" for i in range(n))
            ns = {"kernel": kernel}
            exec(f"def trampoline({params}):\n    return kernel({params})\n", ns)  # noqa: S102
            cc.export(export, sig)(ns["trampoline"])
            exports.append([name, key, export])
    if progress:
        progress(f"compiling {len(exports)} entry points into one module")
    folder.mkdir(parents=True, exist_ok=True)
    cc.compile()
    so = next(p for p in folder.iterdir() if p.name.startswith(module_name) and p.suffix in (".so", ".pyd"))
    table = {"module": module_name, "file": so.name, "exports": exports, "numba": numba.__version__,
             "python": sys.version.split()[0], "built": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    (folder / "table.json").write_text(json.dumps(table))
    return table


def compile_kernels(also: list[list[str]] = (), progress=None, keep: Path | None = None) -> dict:
    """Record the built-in workloads (and ``also``), build, and put the build in place; returns a
    summary (folder, entry points, seconds)."""
    check_requirements()
    t0 = time.perf_counter()
    key = jit.build_key()
    target = jit.build_path(key)
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="aidnav-compile-", dir=target.parent) as tmp:
        tmp = Path(tmp)
        data, out = tmp / "data", tmp / "out"
        data.mkdir()
        subprocess.run([sys.executable, "-c", _STATIC_LOG, str(data / "static.parquet")], check=True,
                       env=dict(os.environ, AIDNAV_KERNELS="jit"))
        records = record([*workloads(data, out), *also], tmp / "record.pkl", progress)
        if not records:
            raise RuntimeError("the workloads recorded no kernel call")
        staging = tmp / key
        env = dict(os.environ, AIDNAV_KERNELS="jit")
        (tmp / "records.pkl").write_bytes(pickle.dumps(records))
        code = ("import pickle, sys; from pathlib import Path; from aidnav.apps.kernels import "
                "build_from_records; build_from_records(pickle.loads(Path(sys.argv[1]).read_bytes()), "
                "Path(sys.argv[2]))")
        if progress:
            progress(f"building {sum(len(v) for v in records.values())} signatures of {len(records)} kernels")
        p = subprocess.run([sys.executable, "-c", code, str(tmp / "records.pkl"), str(staging)], env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if p.returncode != 0:
            raise RuntimeError(f"the ahead-of-time build failed:\n{p.stdout[-4000:]}")
        if jit.build_key() != key:  # a source file changed while recording/building
            raise RuntimeError("aidnav's source files changed during the build: run `aidnav compile` again")
        if keep is not None:
            shutil.copytree(out, keep, dirs_exist_ok=True)
        if target.exists():
            shutil.rmtree(target)
        staging.rename(target)
    _prune(target.parent, keep=KEEP_BUILDS)
    table = json.loads((target / "table.json").read_text())
    return {"folder": str(target), "kernels": len({e[0] for e in table["exports"]}),
            "entry_points": len(table["exports"]), "seconds": time.perf_counter() - t0}


def check_requirements() -> None:
    """The optional build's requirements (``pip install 'aidnav[compile]'``: setuptools; a C compiler):
    an :class:`aidnav.errors.InputError` naming what is missing (the JIT needs neither)."""
    import importlib.util  # lazy: only when a build is asked for

    from aidnav.errors import InputError  # lazy: as importlib.util

    missing = [] if importlib.util.find_spec("setuptools") else ["setuptools (pip install 'aidnav[compile]')"]
    cc = os.environ.get("CC", "cc").split()[0]
    if not any(shutil.which(c) for c in (cc, "gcc", "clang")):
        missing.append("a C compiler (cc, gcc or clang on PATH)")
    if missing:
        raise InputError("aidnav compile needs " + " and ".join(missing) + " — install them, or keep numba's "
                         "JIT (every command works without a build, with the same results)")


#: builds kept in the cache folder (the newest; other source trees or Python/numpy versions may use them)
KEEP_BUILDS = 4


def _prune(base: Path, keep: int) -> None:
    """Remove all but the ``keep`` newest builds under ``base``."""
    builds = sorted((p for p in base.iterdir() if (p / "table.json").is_file()),
                    key=lambda p: (p / "table.json").stat().st_mtime, reverse=True)
    for old in builds[keep:]:
        shutil.rmtree(old, ignore_errors=True)


def build_status() -> dict:
    """Whether a build matches this source tree, and the builds present."""
    key = jit.build_key()
    folder = jit.build_path(key)
    base = jit.kernel_dir()
    present = sorted(p.name for p in base.glob("*") if (p / "table.json").is_file()) if base.is_dir() else []
    return {"key": key, "folder": str(folder), "matches": (folder / "table.json").is_file(),
            "builds": present}
