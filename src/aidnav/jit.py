"""Where aidnav's kernels come from: numba's JIT, or an ahead-of-time build of the same kernels.

Every kernel in aidnav is written once, as a numba function decorated with :func:`njit` from here
(numba's own ``njit`` options: ``cache``, ``nogil``, ``inline``, ``fastmath``, ``error_model``: numpy's
unless a kernel names another, :data:`ERROR_MODEL`). What the decorator
returns depends on the mode this module is in when the kernel's module is imported:

* ``"jit"`` (the default, and always in library use and in the tests): numba's own dispatcher,
  exactly as ``numba.njit`` gives it. Nothing else in this module is involved.
* ``"aot"`` (the ``aidnav`` console script, when an ahead-of-time build for this exact source tree,
  Python, numpy and CPU exists: ``aidnav compile`` makes it, :mod:`aidnav.apps.kernels`): a
  :class:`Kernel`. A call from Python looks up the types of its arguments (:func:`typekey`) in the
  build's table and runs the compiled function of that extension module: no numba, no LLVM in the
  process (≈ 150 MiB and ≈ 0.6 s of start-up less per command with numba 0.68). A call the build does
  not cover (other argument types, a kernel no built-in workload reached) starts numba there and
  then and runs the JIT dispatcher of the same function, from numba's cache: slower to start, never
  a different result (the build's functions are the same numba compilations, linked into one module;
  ``tests/test_jit.py`` checks the outputs are bit-identical).
* ``"record"`` (the workloads of ``aidnav compile``): a :class:`Kernel` that runs the JIT dispatcher
  and writes down, for each call from Python, the kernel, its :func:`typekey` and numba's argument
  types; the build exports exactly those.

A build is a CPython extension module made by ``numba.pycc`` (one exported trampoline per recorded
signature, calling the kernel; the kernel itself compiled with its own options and linked in), with a
``table.json`` that maps (kernel, typekey) to the exported name. It lives in the user's cache
(``$AIDNAV_KERNEL_DIR``, else ``$XDG_CACHE_HOME/aidnav/kernels``, else ``~/.cache/aidnav/kernels``)
under a key hashed from every aidnav source file, the Python, numpy, numba and llvmlite versions and
the CPU: a changed source tree or an upgraded numba simply has no build until ``aidnav compile`` runs
again. The build is optional (``aidnav[compile]``: setuptools, and a C compiler); numba's JIT gives the
same results without it. ``AIDNAV_KERNELS=jit``
in the environment keeps the JIT even when a build exists; ``AIDNAV_KERNELS_VERBOSE=1`` names each
kernel a build did not cover (numba started for it).
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import platform
import sys
from pathlib import Path

import numpy as np

#: numba's ``error_model`` for every kernel unless it names its own: ``"numpy"`` — a float division by
#: zero gives ±inf or NaN as numpy's does (the filters' NaN checks then see it), instead of numba's default
#: ``"python"`` model, which tests every division's divisor and raises ``ZeroDivisionError``. The
#: test is in the filters' innermost loops: issue 40, session 18 measured +1.7 to +5.7 % on the tight
#: filter's throughput from it (docs/results.md). Integer division by zero gives 0 under this model:
#: the filters' integer divisors are constants or guarded (the engine's output stride); a kernel that
#: needs the check names ``error_model="python"`` (``tests/test_jit.py`` checks both).
ERROR_MODEL = "numpy"

_mode = "jit"
_table: dict[str, dict] = {}  # kernel name -> {typekey: compiled function} (aot)
_records: dict | None = None  # kernel name -> {typekey: numba argument types} (record)
_record_path: str | None = None
_numba_started = False
_started = False
_numba_hooks: list = []  # called once, just before numba is imported for a kernel (cli: its start-up)
build_loaded: str | None = None  # the build directory in use (aot), for messages and tests


def mode() -> str:
    """The mode kernels are made in now: ``"jit"``, ``"aot"`` or ``"record"``."""
    return _mode


def njit(*args, depends: str | None = None, **options):
    """numba's ``njit`` (same options), or a :class:`Kernel` in the aot/record modes (module doc).

    depends : a key (e.g. a hash of the sources of the functions the kernel calls in other modules, such
    as the model table's :data:`aidnav.filters.measurements.MODELS_KEY`); with ``cache=True``, numba's
    cached compilations of the kernel are dropped when the key differs from the one they were made with
    (:func:`keep_cache_current`): numba itself keys its cache on the kernel's own source file only."""
    if args:  # @njit without parentheses
        (fn,) = args
        return njit(depends=depends, **options)(fn)
    options.setdefault("error_model", ERROR_MODEL)

    def decorate(fn):
        if _mode == "jit":
            import numba  # lazy: numba (and LLVM) only where a kernel is made in the JIT mode

            d = numba.njit(**options)(fn)
            if depends is not None and options.get("cache"):
                keep_cache_current(d, depends)
            return d
        return Kernel(fn, options, depends)

    return decorate


def keep_cache_current(dispatcher, key: str) -> bool:
    """Drop ``dispatcher``'s cached compilations (numba's public ``Dispatcher.recompile``, which with no
    signature compiled yet only flushes its cache) when ``key`` differs from the one recorded beside
    them (``<qualname>.depends`` in ``dispatcher.stats.cache_path``), and record ``key``. Returns whether
    the cache was dropped. Under ``NUMBA_DISABLE_JIT=1`` (a plain function) nothing happens."""
    stats = getattr(dispatcher, "stats", None)
    if stats is None or not hasattr(dispatcher, "recompile"):
        return False
    fn = dispatcher.py_func
    stamp = Path(stats.cache_path) / f"{fn.__module__.rsplit('.', 1)[-1]}.{fn.__qualname__}.depends"
    try:
        if stamp.read_text() == key:
            return False
    except OSError:
        pass
    dispatcher.recompile()
    try:
        stamp.parent.mkdir(parents=True, exist_ok=True)
        tmp = stamp.with_name(f"{stamp.name}.{os.getpid()}")
        tmp.write_text(key)
        os.replace(tmp, stamp)
    except OSError:  # a read-only cache: numba does not write there either
        pass
    return True


class Kernel:
    """A numba kernel in the aot/record modes: served by the ahead-of-time build where it covers the
    call, else by numba's JIT dispatcher of the same function (made on first need)."""

    def __init__(self, fn, options: dict, depends: str | None = None):
        functools.update_wrapper(self, fn)
        self.py_func = fn
        self.options = dict(options)
        self.depends = depends
        self.name = f"{fn.__module__}:{fn.__qualname__}"
        self._dispatcher = None

    def __call__(self, *args, **kwargs):
        built = _table.get(self.name)
        if built is not None and not kwargs:
            f = built.get(typekey(args))
            if f is not None:
                return f(*args)
        if _mode == "aot" and os.environ.get("AIDNAV_KERNELS_VERBOSE"):
            print(f"aidnav.jit: {self.name}{' with these argument types' if built else ''} not in the build "
                  f"(numba's JIT): {typekey(args)!r}", file=sys.stderr)
        d = self.dispatcher
        if _records is not None and not kwargs:
            _record(self, d, args)
        return d(*args, **kwargs)

    @property
    def dispatcher(self):
        """numba's JIT dispatcher of this kernel (numba started on the first call)."""
        if self._dispatcher is None:
            _start_numba()
            import numba  # lazy: only a call the build does not cover gets here

            self._dispatcher = numba.njit(**self.options)(self.py_func)
            if self.depends is not None and self.options.get("cache"):
                keep_cache_current(self._dispatcher, self.depends)
        return self._dispatcher

    def __getattr__(self, name):  # signatures, overloads, targetoptions, ...: the dispatcher's
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.dispatcher, name)

    def __repr__(self):
        return f"<aidnav kernel {self.name} ({_mode})>"


def _start_numba() -> None:
    """Import numba for the kernels of the aot/record modes: the start-up hooks, the typing of a
    :class:`Kernel` as its dispatcher (kernels call kernels)."""
    global _numba_started
    if _numba_started:
        return
    _numba_started = True
    for hook in _numba_hooks:
        hook()
    from numba.core.typing.typeof import typeof_impl  # lazy: numba's start

    @typeof_impl.register(Kernel)
    def _typeof_kernel(val, c):
        return typeof_impl(val.dispatcher, c)


def typekey(value):
    """A hashable key that is equal for two values exactly when numba types them the same as
    arguments (arrays: dtype, dimensions, layout, writeable, aligned; scalars; tuples and named
    tuples element by element); None for a value this module does not serve from a build."""
    if isinstance(value, np.ndarray):
        f = value.flags
        layout = "C" if f.c_contiguous else ("F" if f.f_contiguous else "A")
        dt = value.dtype
        return ("a", dt.str if dt.fields is None else str(dt.descr), value.ndim, layout, f.writeable,
                f.aligned)
    if isinstance(value, bool | np.bool_):
        return "b"
    if isinstance(value, float):  # also numpy.float64
        return "f8"
    if isinstance(value, int):
        return "i8" if -(2**63) <= value < 2**63 else None
    if isinstance(value, tuple):
        keys = tuple(typekey(v) for v in value)
        if any(k is None for k in keys):
            return None
        cls = type(value)
        return ("t", None if cls is tuple else f"{cls.__module__}.{cls.__qualname__}", keys)
    if isinstance(value, np.generic):
        return ("g", value.dtype.str)
    if value is None:
        return "n"
    return None


def _record(kernel: Kernel, dispatcher, args) -> None:
    key = typekey(args)
    if key is None:
        return
    from numba.core import types  # lazy: record mode only

    argtypes = tuple(dispatcher.typeof_pyval(a) for a in args)
    if any(isinstance(t, types.Omitted) for t in argtypes):
        return
    seen = _records.setdefault(kernel.name, {})
    if key in seen and seen[key] != argtypes:
        raise AssertionError(f"typekey {key!r} of {kernel.name} stands for two numba signatures: "
                             f"{seen[key]} and {argtypes}")
    seen[key] = argtypes


def _write_records() -> None:
    """Merge this process's records into the record file (record mode, at exit)."""
    if not _records or not _record_path:
        return
    import pickle  # lazy: only this path of the kernels' start needs it (every command starts here)

    path = Path(_record_path)
    merged = pickle.loads(path.read_bytes()) if path.is_file() else {}
    for name, sigs in _records.items():
        merged.setdefault(name, {}).update(sigs)
    path.write_bytes(pickle.dumps(merged))


def kernel_dir() -> Path:
    """The folder holding the ahead-of-time builds (module doc)."""
    if os.environ.get("AIDNAV_KERNEL_DIR"):
        return Path(os.environ["AIDNAV_KERNEL_DIR"])
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "aidnav" / "kernels"


def _cpu() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            lines = [ln for ln in f.read().splitlines() if ln.startswith(("model name", "flags"))]
        return "\n".join(sorted(set(lines)))
    except OSError:
        return platform.processor()


def _version(dist: str) -> str:
    """The installed version of distribution ``dist`` (its metadata: numba itself is not imported)."""
    from importlib.metadata import PackageNotFoundError, version  # lazy: only when a build key is made

    try:
        return version(dist)
    except PackageNotFoundError:
        return "none"


def build_key() -> str:
    """Hash of every aidnav source file, the Python, numpy, numba and llvmlite versions and the CPU: the
    name of the build that matches this process (an upgraded numba or llvmlite has no build until
    ``aidnav compile`` runs again)."""
    h = hashlib.sha256()
    root = Path(__file__).resolve().parent
    for p in sorted(root.rglob("*.py")):
        h.update(str(p.relative_to(root)).encode())
        h.update(p.read_bytes())
    h.update(f"{sys.version}|{np.__version__}|{_version('numba')}|{_version('llvmlite')}|"
             f"{platform.machine()}|{_cpu()}".encode())
    return h.hexdigest()[:20]


def _any_build() -> bool:
    """Whether the builds' folder holds anything: where it does not (no ``aidnav compile`` ever ran, the
    usual fresh install), the build key — a hash of every source file, ≈ 30 ms of every command — is not
    computed."""
    try:
        with os.scandir(kernel_dir()) as it:
            return any(True for _ in it)
    except OSError:
        return False


def build_path(key: str | None = None) -> Path:
    """The folder of the build for ``key`` (default: this process's :func:`build_key`)."""
    return kernel_dir() / (key or build_key())


def load_build(folder: Path) -> bool:
    """Serve kernels from the build in ``folder`` (its extension module and ``table.json``); False when
    there is none or it cannot be loaded (the JIT is used then)."""
    global build_loaded
    import importlib.util  # lazy: only this path of the kernels' start needs it (every command starts here)

    try:
        meta = json.loads((folder / "table.json").read_text())
        spec = importlib.util.spec_from_file_location(meta["module"], folder / meta["file"])
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except (OSError, ValueError, KeyError, ImportError):
        return False
    for name, key, export in meta["exports"]:
        _table.setdefault(name, {})[_as_key(key)] = getattr(module, export)
    build_loaded = str(folder)
    return True


def _as_key(k):
    """A typekey back from JSON (lists to tuples)."""
    return tuple(_as_key(v) for v in k) if isinstance(k, list) else k


def start(requested: str | None = None, on_numba=(), build: Path | None = None) -> str:
    """Choose the mode before any kernel module is imported (the console script): ``requested`` or
    ``$AIDNAV_KERNELS``: ``jit``; ``record`` (records to ``$AIDNAV_KERNEL_RECORD``); ``aot`` (the build
    in ``build``, default the one matching this process: an error when there is none); ``auto`` (the
    default: ``aot`` when a build matches, else ``jit``). ``on_numba``: called once before numba is
    imported (at once in the jit mode). Returns the mode."""
    global _mode, _records, _record_path, _started
    if _started:
        return _mode
    _started = True
    requested = requested or os.environ.get("AIDNAV_KERNELS", "auto")
    _numba_hooks.extend(on_numba)
    if requested == "record":
        import atexit  # lazy: only this path of the kernels' start needs it (every command starts here)

        _mode, _records = "record", {}
        _record_path = os.environ.get("AIDNAV_KERNEL_RECORD") or str(kernel_dir() / "record.pkl")
        atexit.register(_write_records)
    elif requested in ("auto", "aot") and (build is not None or _any_build()) and \
            load_build(build or build_path()):
        _mode = "aot"
    elif requested == "aot":
        raise RuntimeError(f"AIDNAV_KERNELS=aot: no ahead-of-time build in {build or build_path()} "
                           "(run `aidnav compile`)")
    elif requested not in ("auto", "jit"):
        raise ValueError(f"AIDNAV_KERNELS={requested}: expected auto, jit, aot or record")
    else:
        _mode = "jit"
        for hook in on_numba:
            hook()
    return _mode
