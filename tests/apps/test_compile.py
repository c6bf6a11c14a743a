"""``aidnav compile`` end to end (issue 29): the ahead-of-time build of the real kernels serves
``aidnav process`` without numba or LLVM in the process, and the trajectory equals the JIT's byte for
byte (forward and ``--smooth``); ``--status`` tells whether a build matches.

Runs the whole build (the built-in workloads in record mode, then numba.pycc): minutes on a cold
numba cache, so marked slow. The build is optional (issue 36): it needs the ``aidnav[compile]`` extra
(setuptools) and a C/C++ compiler (skips without them); without them ``aidnav compile`` says so (exit 2).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pyarrow.parquet as pq
import pytest

pytestmark = pytest.mark.slow

WRAP = ("import sys, atexit, json; "
        "atexit.register(lambda: print('MODULES ' + json.dumps({'numba': 'numba' in sys.modules, "
        "'llvmlite': 'llvmlite' in sys.modules}), file=sys.stderr)); "
        "from aidnav.cli import main; main()")


def _aidnav(args, env, wrap=False):
    cmd = [sys.executable, "-c", WRAP, *args] if wrap else [sys.executable, "-m", "aidnav", *args]
    return subprocess.run(cmd, env=env, capture_output=True, text=True)


@pytest.fixture(scope="module")
def compiled(tmp_path_factory):
    if not (shutil.which("cc") or shutil.which("gcc")) or not (shutil.which("c++") or shutil.which("g++")):
        pytest.skip("no C/C++ compiler on PATH: numba.pycc cannot build")
    pytest.importorskip("setuptools", reason="the optional aidnav[compile] extra is not installed")
    d = tmp_path_factory.mktemp("compile")
    env = dict(os.environ, AIDNAV_KERNEL_DIR=str(d / "kernels"), OMP_NUM_THREADS="1")
    env.pop("AIDNAV_KERNELS", None)
    assert _aidnav(["compile", "--status"], env).returncode == 1  # nothing built yet
    p = _aidnav(["compile"], env)
    assert p.returncode == 0, p.stdout + p.stderr
    p = _aidnav(["simulate", "-o", str(d / "sim"), "--format", "parquet"], env)
    assert p.returncode == 0, p.stderr
    return d, env


def test_status_after_the_build(compiled):
    d, env = compiled
    p = _aidnav(["compile", "--status"], env)
    assert p.returncode == 0 and "present" in p.stdout
    table = json.loads(next((d / "kernels").glob("*/table.json")).read_text())
    names = {e[0] for e in table["exports"]}
    assert "aidnav.filters.engine:run_chunk" in names  # the streamed filter's kernel is in the build


@pytest.mark.parametrize("smooth", [False, True], ids=["forward", "smooth"])
def test_process_from_the_build_equals_the_jit_without_numba(compiled, smooth):
    d, env = compiled
    args = ["process", "--imu", str(d / "sim" / "imu.parquet"), "--gnss", str(d / "sim" / "gnss.parquet"),
            "--no-figures", *(["--smooth"] if smooth else [])]
    tag = "s" if smooth else "f"
    aot = _aidnav([*args, "-o", str(d / f"aot_{tag}")], dict(env, AIDNAV_KERNELS_VERBOSE="1"), wrap=True)
    jit = _aidnav([*args, "-o", str(d / f"jit_{tag}")], dict(env, AIDNAV_KERNELS="jit"), wrap=True)
    assert aot.returncode == 0 and jit.returncode == 0, aot.stderr + jit.stderr
    mods = json.loads(aot.stderr.split("MODULES ", 1)[1].splitlines()[0])
    assert "not in the build" not in aot.stderr, aot.stderr
    assert mods == {"numba": False, "llvmlite": False}
    assert json.loads(jit.stderr.split("MODULES ", 1)[1].splitlines()[0])["numba"]
    a = pq.read_table(d / f"aot_{tag}" / "trajectory.parquet")
    b = pq.read_table(d / f"jit_{tag}" / "trajectory.parquet")
    assert a.equals(b)
