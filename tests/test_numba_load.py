"""aidnav.numba_load: numba's cached libraries loaded without parsing their bitcode (issue 29)."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap

from aidnav.numba_load import elf_defined_symbols

MODULE = """
import numba
import numpy as np


@numba.njit(cache=True)
def inner(x):
    return np.sin(x) * 2.0 + 1.0


@numba.njit(cache=True)
def outer(a):
    s = 0.0
    for v in a:
        s += inner(v)
    return s
"""

RUN = """
import sys
sys.path.insert(0, sys.argv[1])
import numpy as np
import numba
import llvmlite.binding as ll
from numba.core.codegen import CPUCodeLibrary
from aidnav.numba_load import install

lazy = sys.argv[2] == "lazy"
if lazy:
    assert install()
import cached_mod
a = np.linspace(0.0, 1.0, 11)
print(repr(cached_mod.outer(a)), repr(cached_mod.inner(0.5)))
if lazy:  # loaded from the cache without the bitcode parsed
    lib = cached_mod.outer.overloads[cached_mod.outer.signatures[0]].library
    assert lib._shared_module is None and lib._aidnav_bitcode, "not loaded lazily"


@numba.njit
def caller(a):  # compiled now, against the cached inner: the bitcode is parsed on demand
    return cached_mod.inner(a[0]) + cached_mod.outer(a)


print(repr(caller(a)))
print(len(cached_mod.outer.stats.cache_hits))
"""


def _run(tmp_path, mode):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    p = subprocess.run([sys.executable, "-c", RUN, str(tmp_path), mode], capture_output=True, text=True,
                       env=env, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    return p.stdout.split("\n")


def test_lazy_bitcode_load_gives_the_same_results(tmp_path):
    (tmp_path / "cached_mod.py").write_text(textwrap.dedent(MODULE))
    first = _run(tmp_path, "plain")  # compiles and writes the cache
    plain = _run(tmp_path, "plain")  # numba's own load from the cache
    lazy = _run(tmp_path, "lazy")  # the lazy load, and a new compilation linking against it
    assert plain[2] == "1" and lazy[2] == "1"  # both loaded from the cache
    assert first[:2] == plain[:2] == lazy[:2]
    x = [float(v) for v in lazy[0].split()]
    exp_outer = sum(2.0 * math.sin(0.1 * k) + 1.0 for k in range(11))
    assert abs(x[0] - exp_outer) < 1e-12 and abs(x[1] - (2.0 * math.sin(0.5) + 1.0)) < 1e-15


def test_elf_symbols_cover_the_bitcode_definitions(tmp_path, monkeypatch):
    """The names numba reads from the parsed bitcode are all in the object's ELF symbol table."""
    import importlib

    import llvmlite.binding as ll
    import numpy as np

    (tmp_path / "cached_mod2.py").write_text(textwrap.dedent(MODULE))
    monkeypatch.syspath_prepend(str(tmp_path))
    mod = importlib.import_module("cached_mod2")
    mod.outer(np.ones(3))
    lib = mod.outer.overloads[mod.outer.signatures[0]].library
    name, kind, (obj, bitcode) = lib.serialize_using_object_code()
    m = ll.parse_bitcode(bitcode)
    defined = {g.name for gs in (m.functions, m.global_variables) for g in gs if not g.is_declaration}
    got = elf_defined_symbols(obj)
    assert kind == "object" and defined and defined <= got
    assert elf_defined_symbols(b"not an object") is None
