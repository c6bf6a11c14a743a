"""aidnav.jit: kernels from an ahead-of-time build, recorded from the JIT, with the same results.

* :func:`aidnav.jit.typekey` must never give one key to two argument lists numba types differently
  (a build's wrapper does not check types: a wrong match would read memory wrongly), checked against
  ``numba.typeof`` over arrays of every layout/dtype/flag, scalars and (named) tuples.
* End to end on a small kernel module (three processes, as in use): record its calls in the record
  mode, build the extension module in the jit mode, call it in the aot mode: outputs bit-identical to
  the JIT's, numba not imported while the build covers the calls; a call it does not cover starts numba
  and still gives the JIT's answer. (The build is optional: ``aidnav[compile]`` and a C compiler; pycc's
  exported wrappers hold the GIL.)
* The build key follows numba's and llvmlite's versions; a kernel with ``depends=KEY`` drops numba's
  cached compilation when KEY changes (a callee in another file changed: numba itself would serve the
  stale one).
"""

from __future__ import annotations

import collections
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from aidnav.jit import typekey

Pair = collections.namedtuple("Pair", "a b")


def _values():
    a = np.arange(12.0).reshape(3, 4)
    ro = np.ones(5)
    ro.flags.writeable = False
    return [
        np.zeros(4), np.zeros(4, np.float32), np.zeros(4, np.int64), np.zeros(4, np.int32), np.zeros(4, bool),
        a, a.T, a[:, ::2], a[::2], np.zeros((2, 3, 4)), ro, np.zeros(0), np.zeros((3, 1)),
        np.zeros(3, dtype=[("x", "f8"), ("y", "i4")]),
        1.0, np.float64(1.0), np.float32(1.0), 3, np.int64(3), np.int32(3), True, np.bool_(True), None,
        (1.0, 2.0), (1.0, 2), (np.zeros(3), 1.0), (), ((1.0,), np.zeros(2)),
        Pair(np.zeros(2), np.zeros(2)), Pair(1.0, np.zeros(2)),
    ]


def test_typekey_never_joins_what_numba_types_apart():
    from numba import typeof

    vals = _values()
    keys = [typekey(v) for v in vals]
    assert all(k is not None for k in keys)
    types = [typeof(v) for v in vals]
    for i in range(len(vals)):
        for j in range(len(vals)):
            if keys[i] == keys[j]:
                assert types[i] == types[j], (vals[i], vals[j], types[i], types[j])
    # and it tells apart what matters for the memory layout
    assert typekey(vals[5]) != typekey(vals[6]) != typekey(vals[7])
    assert typekey(np.zeros(3)) != typekey(vals[10])  # writeable or not
    assert typekey("text") is None and typekey([1.0]) is None and typekey(2**70) is None


KERNELS = '''
import collections
import numpy as np
from aidnav.jit import njit

Out = collections.namedtuple("Out", "total scaled")


@njit(cache=True, fastmath={"reassoc", "nsz"})
def total(a):
    s = 0.0
    for x in a:
        s += x * 1.000001
    return s


@njit(cache=True, nogil=True)
def outer(a, k, pair):
    out = np.empty_like(a)
    for i in range(a.shape[0]):
        out[i] = np.sin(a[i]) * k + pair[0][i % pair[0].shape[0]] * pair[1]
    return Out(total(a), out)


@njit(cache=True, nogil=True)
def spin(n):
    s = 0.0
    for i in range(n):
        s += np.sqrt(i + 1.0)
    return s
'''

DRIVER = '''
import os, sys, threading, time, json
import numpy as np
from pathlib import Path
from aidnav import jit
mode = sys.argv[1]
jit.start(mode, build=Path(sys.argv[2]) if mode == "aot" else None)
import kmod
rng = np.random.default_rng(7)
a = rng.standard_normal(1001)
pair = (rng.standard_normal(5), 0.25)
r = kmod.outer(a, 1.5, pair)
np.save(sys.argv[3], np.concatenate([[r.total], r.scaled]))
info = {"numba_after_call": "numba" in sys.modules, "type": type(r).__name__}
# the GIL is released by the nogil kernel: a Python thread keeps counting while it runs
count = [0]
stop = False
def tick():
    while not stop:
        count[0] += 1
t = threading.Thread(target=tick); t.start()
kmod.spin(10)  # warm
c0 = count[0]; kmod.spin(60_000_000); c1 = count[0]
stop = True; t.join()
info["ticks_during_spin"] = c1 - c0
# a call the build does not cover (float32; not made while recording): the JIT answers
if mode != "record":
    b = a.astype(np.float32)
    info["fallback_total"] = float(kmod.total(b))
    info["jit_total_f32"] = float(kmod.total.py_func(b))
    info["numba_after_fallback"] = "numba" in sys.modules
Path(sys.argv[4]).write_text(json.dumps(info))
'''


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """Record (record mode), build (jit mode): the build folder and the kernels' folder."""
    import shutil

    if not (shutil.which("cc") or shutil.which("gcc")) or not (shutil.which("c++") or shutil.which("g++")):
        pytest.skip("no C/C++ compiler on PATH: numba.pycc cannot build (aidnav compile needs one)")
    pytest.importorskip("setuptools", reason="the optional aidnav[compile] extra is not installed")
    d = tmp_path_factory.mktemp("jit")
    (d / "kmod.py").write_text(textwrap.dedent(KERNELS))
    (d / "driver.py").write_text(textwrap.dedent(DRIVER))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(d), os.environ.get("PYTHONPATH", "")]),
               AIDNAV_KERNEL_RECORD=str(d / "record.pkl"), OMP_NUM_THREADS="1")
    subprocess.run([sys.executable, str(d / "driver.py"), "record", "-", str(d / "rec.npy"),
                    str(d / "rec.json")], env=env, check=True, cwd=d)
    code = ("import pickle, sys; from pathlib import Path; from aidnav.apps.kernels import "
            "build_from_records; build_from_records(pickle.loads(Path(sys.argv[1]).read_bytes()), "
            "Path(sys.argv[2]))")
    subprocess.run([sys.executable, "-c", code, str(d / "record.pkl"), str(d / "build")], env=env, check=True,
                   cwd=d)
    return d, env


def _run(d, env, mode):
    subprocess.run([sys.executable, str(d / "driver.py"), mode, str(d / "build"), str(d / f"{mode}.npy"),
                    str(d / f"{mode}.json")], env=env, check=True, cwd=d)
    return np.load(d / f"{mode}.npy"), json.loads((d / f"{mode}.json").read_text())


def test_the_build_covers_the_recorded_calls(built):
    d, _ = built
    table = json.loads((d / "build" / "table.json").read_text())
    names = {e[0] for e in table["exports"]}
    assert names == {"kmod:outer", "kmod:spin"}  # total is called from Python only outside the record run


def test_aot_results_equal_the_jit_and_need_no_numba(built):
    d, env = built
    jit_out, jit_info = _run(d, env, "jit")
    aot_out, aot_info = _run(d, env, "aot")
    assert np.array_equal(jit_out, aot_out)  # bit-identical (fastmath kernel included)
    assert aot_info["type"] == "Out"
    assert not aot_info["numba_after_call"] and jit_info["numba_after_call"]
    # the uncovered float32 call: numba started, same answer as the JIT gives
    assert aot_info["numba_after_fallback"]
    assert aot_info["fallback_total"] == jit_info["fallback_total"]
    f32 = aot_info["jit_total_f32"]  # the interpreted sum in float32 arithmetic: same to its precision
    assert abs(aot_info["fallback_total"] - f32) <= 1e-3 * abs(f32)


def test_aot_without_a_build_is_an_error(tmp_path):
    code = f"from pathlib import Path; from aidnav import jit; jit.start('aot', build=Path(r'{tmp_path}'))"
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert p.returncode != 0 and "no ahead-of-time build" in p.stderr


def test_no_build_folder_no_source_hash(tmp_path):
    """A fresh install (no ``aidnav compile`` ever ran: no builds' folder, or an empty one) starts in the JIT
    mode without hashing the sources for a build key; a folder with something in it is looked in."""
    code = ("from aidnav import jit\n"
            "def key():\n    print('hashed')\n    return 'none'\n"
            "jit.build_key = key\nprint(jit.start())")
    (tmp_path / "empty").mkdir()
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "0123456789abcdef0123").mkdir()  # another tree's build: not this one
    for folder, out in (("missing", ["jit"]), ("empty", ["jit"]), ("other", ["hashed", "jit"])):
        env = {**os.environ, "AIDNAV_KERNEL_DIR": str(tmp_path / folder), "AIDNAV_KERNELS": "auto"}
        p = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
        assert p.stdout.split() == out, (folder, p.stdout, p.stderr)


def test_the_build_key_follows_the_sources(tmp_path, monkeypatch):
    from aidnav import jit

    monkeypatch.setenv("AIDNAV_KERNEL_DIR", str(tmp_path))
    key = jit.build_key()
    assert len(key) == 20 and jit.build_path(key) == Path(tmp_path) / key
    assert jit.build_key() == key  # deterministic
    real = jit._version
    for dist in ("numba", "llvmlite"):  # an upgraded numba or llvmlite: another build
        monkeypatch.setattr(jit, "_version", lambda d, _x=dist: "9.9.9" if d == _x else real(d))
        assert jit.build_key() != key
    monkeypatch.setattr(jit, "_version", real)


CALLEE = """
from aidnav.jit import njit
@njit(cache=True)
def g(x):
    return x + {add}
"""
CALLER = """
import sys
from aidnav.jit import njit
from callee import g
@njit(cache=True, depends=sys.argv[1])
def f(x):
    return g(x) * 2.0
print(f(1.0), sum(f.stats.cache_hits.values()))
"""


def test_depends_drops_a_stale_cached_caller(tmp_path):
    """numba caches ``f`` keyed on f's file only: after g's file changes it would still serve f with the
    old g inlined; with ``depends`` = a key of g's source, the changed key drops f's cached code."""
    (tmp_path / "caller.py").write_text(CALLER)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]))
    env.pop("NUMBA_CACHE_DIR", None)

    def run(add, key):
        (tmp_path / "callee.py").write_text(CALLEE.format(add=add))
        p = subprocess.run([sys.executable, str(tmp_path / "caller.py"), key], env=env, capture_output=True,
                           text=True, cwd=tmp_path)
        assert p.returncode == 0, p.stderr
        value, hits = p.stdout.split()
        return value, int(hits) > 0

    assert run(1.0, "k1") == ("4.0", False)  # compiled, cached
    assert run(1.0, "k1") == ("4.0", True)  # from the cache
    assert run(5.0, "k2")[0] == "12.0"  # the callee changed, its key too: recompiled with the new g


@pytest.mark.parametrize("value, message", [("bogus", "expected auto, jit, aot or record"),
                                            ("aot", "no ahead-of-time build")])
def test_a_bad_kernel_mode_is_a_clear_error(tmp_path, value, message):
    env = dict(os.environ, AIDNAV_KERNELS=value, AIDNAV_KERNEL_DIR=str(tmp_path / "none"))
    p = subprocess.run([sys.executable, "-m", "aidnav", "simulate", "-o", str(tmp_path / "o")], env=env,
                       capture_output=True, text=True)
    assert p.returncode == 2 and message in p.stderr and "Traceback" not in p.stderr


def test_kernels_take_numpys_error_model_unless_they_name_another():
    """:data:`aidnav.jit.ERROR_MODEL`: a float division by zero gives inf / NaN (numpy's model: no divisor
    test in the filters' loops); a kernel that names ``error_model="python"`` still raises."""
    from aidnav.jit import njit

    def ratio(a, b):
        return a / b

    fast = njit(ratio)
    checked = njit(error_model="python")(ratio)
    assert fast(1.0, 0.0) == np.inf
    assert np.isnan(fast(0.0, 0.0))
    with pytest.raises(ZeroDivisionError):
        checked(1.0, 0.0)
