"""What a cached kernel's library holds, and what loading it costs (issue 41, session 15).

numba loads a kernel from its cache (``__pycache__/<module>.<kernel>-<line>.py311.<n>.nbc``, one file per
signature) by unpickling the compile result and parsing the library's LLVM bitcode (kept for linking it
into other kernels) beside its machine code: on the 60-s log that parse is most of ``run_chunk``'s ≈ 0.16 s
load, on the command's critical path (target of the 60-s log with its default outputs: ≤ 1.0 s wall). The
library holds every kernel the entry calls, linked in (numba links each callee's library into its caller's:
a callee with ``inline="never"`` is a separate *function* in it, not a separate cache entry).

Printed per cache entry of the kernel: the file's size, the machine code and bitcode sizes, the bitcode's
parse time (``llvmlite.binding.parse_bitcode``, CPU time of the thread, median of 5, in this process), the
functions defined and their instructions (LLVM IR, non-blank lines of function bodies), the globals and how
many are numba's constants (an exception's pickle per raise site: each array allocation, division, reshape
that can raise has one), the array allocations (``NRT_MemInfo_alloc*`` calls), the functions compiled for
more than one signature (their smaller copies: instructions one signature each would save), and for the
engine's loop each measurement model's share (instructions reachable from the model and not from the loop
without models). Diagnostic: reads numba's cache files (pickles) of this source tree; compile them first
(run any command that calls the kernel).

Run: ``python benchmarks/kernel_library.py [MODULE.KERNEL ...]`` (default ``aidnav.filters.engine.run_chunk``)
"""

from __future__ import annotations

import collections
import importlib
import os
import pickle
import re
import statistics
import sys
import time
from pathlib import Path

TARGET_60S = 1.0  # issue 41: the 60-s log with its default outputs, wall [s]
_DEFINE = re.compile(r'^define[^@]*@"?([^"( ]+)')
_CALLEE = re.compile(r'@"?(_Z[^"( ,]+)')
_LABEL = re.compile(r'^[A-Za-z0-9_.$"-]+:')


def entries(qualified: str) -> list[Path]:
    """The cache files (``.nbc``) of kernel ``MODULE.KERNEL`` in its module's ``__pycache__``."""
    mod_name, kernel = qualified.rsplit(".", 1)
    mod = importlib.import_module(mod_name)
    src = Path(mod.__file__)
    tag = f"py{sys.version_info.major}{sys.version_info.minor}"
    return sorted((src.parent / "__pycache__").glob(f"{src.stem}.{kernel}-*.{tag}.*.nbc"))


def functions(ir: str) -> tuple[dict[str, list[str]], dict[str, set[str]]]:
    """Each defined function's body lines (non-blank) and the functions it names."""
    body: dict[str, list[str]] = {}
    calls: dict[str, set[str]] = collections.defaultdict(set)
    cur = None
    for line in ir.splitlines():
        m = _DEFINE.match(line)
        if m:
            cur = m.group(1)
            body[cur] = []
        elif cur is not None and line.startswith("}"):
            cur = None
        elif cur is not None and line.strip():
            body[cur].append(line)
            calls[cur].update(_CALLEE.findall(line))
    return body, calls


def counts(body: dict[str, list[str]]) -> tuple[int, int]:
    """(instructions, array allocations: calls of ``NRT_MemInfo_alloc*``)."""
    total = alloc = 0
    for lines in body.values():
        for line in lines:
            if _LABEL.match(line) or line.lstrip().startswith(";"):
                continue
            total += 1
            alloc += "call" in line and "NRT_MemInfo_alloc" in line
    return total, alloc


def base_name(symbol: str) -> str:
    """``pkg.module.function`` of a numba symbol (``_ZN6aidnav7filters6engine9run_chunkB3v45…``)."""
    m = re.match(r"_ZN((?:\d+[A-Za-z_]\w*?)+?)B\d", symbol)
    if not m:
        return symbol[:60]
    s, out, i = m.group(1), [], 0
    while i < len(s):
        j = i
        while s[j].isdigit():
            j += 1
        n = int(s[i:j])
        out.append(s[j:j + n])
        i = j + n
    return ".".join(out)


def reach(roots, calls, size, stop=frozenset()) -> set[str]:
    seen, todo = set(), list(roots)
    while todo:
        f = todo.pop()
        if f in seen or f not in size or f in stop:
            continue
        seen.add(f)
        todo.extend(calls[f])
    return seen


def model_shares(body, calls) -> list[tuple[str, int]]:
    """Each measurement model's instructions beyond the engine loop's own (run_chunk's libraries only)."""
    from aidnav.filters.measurements import MODELS  # lazy: the engine's model table, for its names

    size = {f: len(b) for f, b in body.items()}
    roots = [f for f in size if base_name(f) == "aidnav.filters.engine.run_chunk"]
    models = {m.py_func.__name__: [f for f in size if base_name(f).endswith("." + m.py_func.__name__)]
              for m in MODELS}
    every = {f for fs in models.values() for f in fs}
    core = reach(roots, calls, size, stop=every)
    out = [("(the loop and what it calls besides the models)", sum(size[f] for f in core))]
    for name, fs in models.items():
        out.append((name, sum(size[f] for f in reach(fs, calls, size) - core)))
    return out


def report(path: Path) -> None:
    import llvmlite.binding as ll  # lazy: numba's LLVM, for the bitcode

    data = pickle.loads(path.read_bytes())
    _, kind, payload = data[0]
    obj, bitcode = payload if kind == "object" else (b"", payload)
    times, cpu = [], []
    for _ in range(5):
        t, c = time.perf_counter(), time.thread_time()
        module = ll.parse_bitcode(bitcode)
        times.append(time.perf_counter() - t)
        cpu.append(time.thread_time() - c)
    ir = str(module)
    body, calls = functions(ir)
    total, alloc = counts(body)
    glob = [g.name for g in module.global_variables]
    raises = sum(g.startswith(".const.picklebuf") for g in glob)
    consts = sum(g.startswith(".const.") for g in glob)
    print(f"{path.name}: {path.stat().st_size / 1e6:.2f} MB; machine code {len(obj) / 1e6:.2f} MB, bitcode "
          f"{len(bitcode) / 1e6:.2f} MB, parse_bitcode {1e3 * statistics.median(cpu):.1f} CPU-ms "
          f"(median of 5; wall {1e3 * statistics.median(times):.1f} ms; load {os.getloadavg()[0]:.2f})")
    print(f"  {len(body)} functions defined, {total:,} instructions; {len(glob):,} globals ({consts:,} "
          f"numba constants, of them {raises:,} exceptions' pickles: one per raise site); array "
          f"allocations: {alloc}")
    by_name = collections.defaultdict(list)
    for f, b in body.items():
        if not f.startswith("_ZN7cpython"):
            by_name[base_name(f)].append(len(b))
    dups = sorted(((n, sorted(v)) for n, v in by_name.items() if len(v) > 1), key=lambda kv: -sum(kv[1][:-1]))
    waste = sum(sum(v[:-1]) for _, v in dups)
    print(f"  compiled for more than one signature: {len(dups)} functions, {waste:,} instructions in the "
          f"smaller copies ({100 * waste / total:.1f} %)" + "".join(
              f"\n    {n}: {v}" for n, v in dups[:6]))
    if any(base_name(f) == "aidnav.filters.engine.run_chunk" for f in body):
        print("  instructions by measurement model (reachable from it and not from the loop without models):")
        for name, n in model_shares(body, calls):
            print(f"    {name}: {n:,} ({100 * n / total:.1f} %)")


def main(argv: list[str]) -> int:
    kernels = argv or ["aidnav.filters.engine.run_chunk"]
    print(f"target (issue 41): the 60-s log with its default outputs <= {TARGET_60S} s wall; each kernel's "
          "load from numba's cache is on that path")
    found = False
    for k in kernels:
        for path in entries(k):
            found = True
            report(path)
    if not found:
        print("no cache entry found: first run a command that calls the kernel (numba compiles, caches it)")
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
