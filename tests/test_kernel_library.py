"""``benchmarks/kernel_library.py``: what a cached kernel's library holds (issue 41, session 15)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np

IR = """\
@.const.picklebuf.1 = internal constant i8 0
@.const.x = internal constant i8 0
define i32 @_ZN3pkg3mod4mainB2v1E5Array(ptr %a) {
entry:
  %m = call ptr @NRT_MemInfo_alloc_aligned(i64 8, i32 32)
  %r = call i32 @_ZN3pkg3mod6helperB2v2Ed(double 1.0)
  br label %exit

exit:                                             ; preds = %entry
  ; a comment
  ret i32 0
}

define i32 @_ZN3pkg3mod6helperB2v2Ed(double %x) {
  ret i32 0
}

define i32 @_ZN3pkg3mod6helperB2v3Ex(i64 %x) {
  %y = add i64 %x, 1
  ret i32 0
}
"""


def _bench():
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "kernel_library.py"
    spec = importlib.util.spec_from_file_location("kernel_library", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench


def test_functions_calls_and_counts_of_a_known_module():
    b = _bench()
    body, calls = b.functions(IR)
    main, h2, h3 = (f"_ZN3pkg3mod{s}" for s in ("4mainB2v1E5Array", "6helperB2v2Ed", "6helperB2v3Ex"))
    assert list(body) == [main, h2, h3]
    assert calls[main] == {h2}  # the allocator is not a numba symbol
    total, alloc = b.counts(body)
    assert (total, alloc) == (3 + 1 + 2 + 1, 1)  # labels and comments are not instructions
    assert b.base_name(main) == "pkg.mod.main" and b.base_name(h3) == "pkg.mod.helper"
    assert b.base_name("_ZN7cpython3pkg3mod4mainB2v1E") == "cpython.pkg.mod.main"
    size = {f: len(v) for f, v in body.items()}
    assert b.reach([main], calls, size) == {main, h2}
    assert b.reach([main], calls, size, stop={h2}) == {main}


def test_a_cached_kernel_is_found_and_described(tmp_path, capsys, monkeypatch):
    """A kernel with one array allocation, compiled for two signatures into a cache in a temporary package:
    its two entries are found and each reports one allocation."""
    pkg = tmp_path / "kl_probe_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "kern.py").write_text(
        "import numpy as np\nimport numba\n\n\n@numba.njit(cache=True)\ndef twice(x):\n"
        "    out = np.empty(x.shape[0])\n    for i in range(x.shape[0]):\n        out[i] = 2 * x[i]\n"
        "    return out\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    from kl_probe_pkg import kern

    assert kern.twice(np.arange(3.0))[2] == 4.0
    assert kern.twice(np.arange(3, dtype=np.int32))[2] == 4.0
    b = _bench()
    paths = b.entries("kl_probe_pkg.kern.twice")
    assert len(paths) == 2
    for p in paths:
        b.report(p)
    out = capsys.readouterr().out
    assert out.count("array allocations: 1\n") == 2, out
    sys.modules.pop("kl_probe_pkg.kern", None)
    sys.modules.pop("kl_probe_pkg", None)
