"""The ``aidnav`` command as a process (aidnav.cli.main): what `--help` imports, the quick exit (atexit
handlers run, output flushed, exit status kept), scipy's BLAS modules loaded alone for numba, and a
whole `simulate` → `process` run through the console entry point."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from aidnav.cli import _exit_status

SCN = """name: cli-main
seed: 5
initial: {lat_deg: 30, lon_deg: 114, height_m: 20, speed_m_s: 5, heading_deg: 60}
segments:
  - {type: straight, duration_s: 20}
  - {type: turn, angle_deg: 90, duration_s: 20}
  - {type: straight, duration_s: 20}
sensors:
  imu: {grade: tactical}
  gnss: {rate_hz: 1, sigma_pos_m: [0.5, 0.5, 0.5]}
"""


def _python(code: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=600)


def _aidnav(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "aidnav", *args], capture_output=True, text=True,
                          timeout=600)


def test_help_imports_no_numerics():
    r = _python("import sys\nfrom aidnav.cli import app\n"
                "try:\n    app(['--help'])\nexcept SystemExit as e:\n    assert e.code in (0, None)\n"
                "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'numpy', 'numba', 'scipy', "
                "'pandas', 'pyarrow', 'matplotlib', 'rich', 'pydantic', 'yaml'})\nprint('HEAVY', heavy)")
    assert r.returncode == 0, r.stderr
    assert "Usage:" in r.stdout and "process" in r.stdout
    assert "HEAVY []" in r.stdout


def test_exit_status_of_system_exit():
    assert _exit_status(None) == 0
    assert _exit_status(0) == 0
    assert _exit_status(2) == 2
    assert _exit_status("a message") == 1


def test_leave_runs_atexit_flushes_and_keeps_status():
    # a large output through a pipe, an atexit handler and a status: all as at a normal exit
    r = _python("import atexit, sys\natexit.register(lambda: print('handler ran'))\n"
                "sys.stdout.write('x' * 200000)\nsys.stderr.write('to stderr')\n"
                "from aidnav.cli import _leave\n_leave(3)\nprint('not reached')")
    assert r.returncode == 3
    assert r.stdout == "x" * 200000 + "handler ran\n"
    assert r.stderr == "to stderr"


def test_leave_waits_for_a_running_thread():
    r = _python("import threading, time\nfrom aidnav.cli import _leave\n"
                "t = threading.Thread(target=lambda: (time.sleep(0.3), print('thread done')))\nt.start()\n"
                "_leave(4)")
    assert r.returncode == 4
    assert "thread done" in r.stdout


def test_the_command_collects_garbage_less_often_the_library_as_python_does():
    from aidnav.console_script import GC_YOUNG_OBJECTS

    code = "import gc, sys\n{}import aidnav.cli\nprint(*gc.get_threshold())"
    library = _python(code.format(""))
    command = _python(code.format("sys.argv[0] = '/usr/bin/aidnav'\n"))  # as the console script starts
    assert library.returncode == 0 and command.returncode == 0, library.stderr + command.stderr
    default = _python("import gc\nprint(*gc.get_threshold())").stdout.split()
    assert library.stdout.split() == default  # importing the library changes nothing
    assert command.stdout.split() == [str(GC_YOUNG_OBJECTS), *default[1:]]
    kept = _python("import gc\nfrom aidnav.console_script import fewer_collections\n"
                   "gc.set_threshold(10**6, 3, 4)\nfewer_collections()\nprint(*gc.get_threshold())\n"
                   "gc.set_threshold(0)\nfewer_collections()\nprint(gc.get_threshold()[0])")
    assert kept.stdout.split() == ["1000000", "3", "4", "0"]  # higher, or switched off: left as it is


def test_the_command_starts_without_collections_and_resumes_them():
    # the console script: no automatic collection while it starts; resumed with the start's objects frozen
    # (the first young collection does not walk them); the library imported by a program: untouched
    r = _python("import gc, sys\nsys.argv[0] = '/usr/bin/aidnav'\nimport aidnav.cli\nprint(gc.isenabled())\n"
                "from aidnav.console_script import resume_collections\nresume_collections()\n"
                "print(gc.isenabled(), gc.get_freeze_count() > 10000)\nresume_collections()\n"
                "gc.disable()\nresume_collections()\nprint(gc.isenabled())")
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["False", "True", "True", "False"]  # once; an off switched by others is kept
    lib = _python("import gc\nimport aidnav.cli\nprint(gc.isenabled(), gc.get_freeze_count())")
    assert lib.stdout.split() == ["True", "0"]
    # a command other than process collects from its start (process: from its run, the next test)
    cmd = _python("import gc, sys\nfrom aidnav import cli\n"
                  "@cli._command('gc-state')\ndef gc_state():\n    print('GC', gc.isenabled())\n"
                  "sys.argv[1:] = ['gc-state']\ncli.main()")
    assert cmd.returncode == 0 and "GC True" in cmd.stdout, cmd.stdout + cmd.stderr



def test_blas_modules_alone_serve_numba_and_scipy():
    # numba's first dispatch must not import scipy.linalg; np.linalg inside a kernel still works (numba
    # calls scipy's BLAS/LAPACK through the modules loaded alone); scipy.linalg imports afterwards
    r = _python("""
import sys
import numpy as np
from aidnav.cli import _preload_scipy_blas
_preload_scipy_blas()
from numba import njit

@njit
def add(a, b):
    return a + b

add(1.0, 2.0)
assert 'scipy.linalg' not in sys.modules, 'numba imported scipy.linalg'

@njit
def solve_dot(A, b):
    return np.linalg.solve(A, b), np.dot(A, b), np.linalg.cholesky(A)

rng = np.random.default_rng(1)
M = rng.normal(size=(6, 6)); A = M @ M.T + 6 * np.eye(6); b = rng.normal(size=6)
x, y, L = solve_dot(A, b)
assert np.allclose(x, np.linalg.solve(A, b), rtol=1e-12, atol=0)
assert np.allclose(y, A @ b, rtol=1e-12, atol=0)
assert np.allclose(L, np.linalg.cholesky(A), rtol=1e-12, atol=0)
import scipy.linalg
from scipy.linalg import cython_blas
assert cython_blas is sys.modules['scipy.linalg.cython_blas']
assert np.allclose(scipy.linalg.solve(A, b), x)
print('OK')
""")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "OK"


@pytest.fixture(scope="module")
def sim_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli_main")
    (d / "scn.yaml").write_text(SCN)
    r = _aidnav("simulate", str(d / "scn.yaml"), "-o", str(d / "sim"), "--format", "parquet")
    assert r.returncode == 0, r.stderr
    return d


def test_console_entry_process(sim_dir):
    import pyarrow.parquet as pq

    out = sim_dir / "est"
    r = _aidnav("process", "--imu", str(sim_dir / "sim/imu.parquet"), "--gnss",
                str(sim_dir / "sim/gnss.parquet"), "-o", str(out), "--no-figures", "--json")
    assert r.returncode == 0, r.stderr
    printed = json.loads(r.stdout)  # the whole summary reached the pipe before the quick exit
    assert printed == json.loads((out / "summary.json").read_text())
    assert printed["imu_samples"] == pq.read_metadata(sim_dir / "sim/imu.parquet").num_rows
    rows = pq.read_metadata(out / "trajectory.parquet").num_rows  # the file was closed before the exit
    assert rows == printed["counts"]["imu_samples_used"] > 0.9 * printed["imu_samples"]
    r = _aidnav("process", "--imu", str(sim_dir / "missing.parquet"), "--gnss",
                str(sim_dir / "sim/gnss.parquet"), "-o", str(sim_dir / "bad"))
    assert r.returncode == 2
    assert r.stderr.startswith("error:") and "missing.parquet" in r.stderr


def test_figures_child_forked_early_only_for_process_with_figures():
    from aidnav.cli import _fork_figures_early

    # no fork for these (decided before anything is forked)
    for argv in (["simulate", "x.yaml"], ["process", "--imu", "a", "--no-figures"], ["process", "--help"], [],
                 ["--version"], ["evaluate", "process"]):
        assert _fork_figures_early(argv) is None, argv
    # nor where the process may run on one CPU only (its affinity): the child's work would only move earlier
    r = _python("import os\nos.sched_setaffinity(0, {min(os.sched_getaffinity(0))})\n"
                "from aidnav.cli import _fork_figures_early\n"
                "print(_fork_figures_early(['process', '--imu', 'a', '--gnss', 'b']))")
    assert r.returncode == 0 and r.stdout.split() == ["None"], r.stdout + r.stderr


_SPY = """
import os, sys
sys.argv[0] = 'aidnav'
sys.argv[1:] = {argv!r}
from aidnav import cli
from aidnav.apps import run_outputs
forked, starts = [], []
early, start = cli._fork_figures_early, run_outputs.start_outputs
def spy(argv):
    forked.append(early(argv))
    return forked[-1]
def counted(*a, **k):
    r = start(*a, **k)
    if isinstance(r, run_outputs.OutputsProcess) and all(r is not x for x in starts):
        starts.append(r)  # a child forked (an OutputsProcess passed in is returned as it is)
    return r
cli._fork_figures_early, run_outputs.start_outputs = spy, counted
def leave(status):
    f = forked[0]
    try:
        os.waitpid(f.pid, os.WNOHANG)
        alive = True
    except ChildProcessError:
        alive = False
    print('FORKED', f is not None, 'ALIVE', alive, 'FORKS', len(starts), 'STATUS', status, flush=True)
    os._exit(0)
cli._leave = leave
cli.main()
"""


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="the early fork needs two usable CPUs")
def test_figures_child_forked_before_parsing_taken_by_process_or_ended(sim_dir):
    # the console script forks the figures' child before typer parses (cli._fork_figures_early): a command
    # line typer rejects ends it (reaped: no child left behind); process takes it (no second fork) and
    # writes the figures with it
    r = _python(_SPY.format(argv=["process", "--bogus-option"]))
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["FORKED", "True", "ALIVE", "False", "FORKS", "1", "STATUS", "2"]
    out = sim_dir / "early"
    r = _python(_SPY.format(argv=["process", "--imu", str(sim_dir / "sim/imu.parquet"), "--gnss",
                                  str(sim_dir / "sim/gnss.parquet"), "-o", str(out)]))
    assert r.returncode == 0, r.stderr
    assert r.stdout.split()[-8:] == ["FORKED", "True", "ALIVE", "False", "FORKS", "1", "STATUS", "0"]
    assert (out / "overview.png").stat().st_size > 0 and (out / "run.html").is_file()
