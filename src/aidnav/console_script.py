"""The ``aidnav`` console script's start and exit (:mod:`aidnav.cli`): scipy's BLAS modules loaded on
their own and a quick exit without the interpreter's teardown (issue 29: the fixed cost of a command).
numba is used as it is: nothing of it is replaced (issue 36)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ["preload_scipy_blas", "exit_status", "leave", "fewer_collections", "GC_YOUNG_OBJECTS",
           "pause_collections", "resume_collections"]

#: the cyclic garbage collector's young-generation threshold in the ``aidnav`` command (Python's default: 700
#: allocations). A command allocates a few million objects that live as long as it does (numba's types and
#: typing templates, the kernels' cache loads, matplotlib in the figures' child): at 700, ``aidnav process``
#: ran 317 collections on W1's first 60 s (≈ 0.11 s) and 339 on W1 (≈ 0.15 s, two of the whole heap), nearly
#: all of them finding nothing to free; at 50,000, 4 collections (≈ 0.04 s) and the same peak memory
#: (issue 41, session 11: docs/results.md)
GC_YOUNG_OBJECTS = 50_000


def preload_scipy_blas() -> None:
    """Load scipy's two Cython BLAS/LAPACK modules on their own, before the first kernel call.

    numba sets up its CPU target when the first jitted function is called or loaded from its cache,
    whatever that function does, and the set-up imports ``scipy.linalg.cython_blas`` (numba.np.arraymath
    asks whether BLAS is there). That import runs all of ``scipy/linalg/__init__``: ~0.15 s of every
    command (scipy.linalg, scipy's array-API layer, numpy.f2py, numpy.testing), although numba only ever
    uses the two extension modules, through their C API. Loaded here under their own names (~2 ms), they
    are what numba's import finds in ``sys.modules``; ``import scipy.linalg`` later still works and finds
    them too (only the attribute ``scipy.linalg.cython_blas`` is not set on the package). Nothing is done
    when scipy.linalg is already imported, and on any surprise the normal import happens later."""
    import importlib.machinery  # lazy: the console script's start imports only what every command needs
    import importlib.util  # lazy: the console script's start imports only what every command needs

    names = [f"scipy.linalg.{m}" for m in ("cython_blas", "cython_lapack")]
    if "scipy.linalg" in sys.modules or any(n in sys.modules for n in names):
        return
    try:
        scipy_spec = importlib.util.find_spec("scipy")
        folder = Path(scipy_spec.submodule_search_locations[0]) / "linalg"
        for name in names:
            leaf = name.rsplit(".", 1)[1]
            path = next(folder / (leaf + s) for s in importlib.machinery.EXTENSION_SUFFIXES
                        if (folder / (leaf + s)).is_file())
            spec = importlib.util.spec_from_file_location(name, path)
            module = importlib.util.module_from_spec(spec)
            sys.modules[name] = module
            spec.loader.exec_module(module)
    except Exception:  # any surprise (no scipy, another layout): leave it to the normal import
        for name in names:
            sys.modules.pop(name, None)


def fewer_collections() -> None:
    """Raise the garbage collector's young-generation threshold to :data:`GC_YOUNG_OBJECTS` for this
    process (the command's; not where the library is imported by other programs). The older generations'
    thresholds are kept; a threshold already higher (or the collector's automatic runs switched off,
    threshold 0) is left as it is."""
    import gc  # lazy: the console script's start imports only what every command needs

    young, *older = gc.get_threshold()
    if 0 < young < GC_YOUNG_OBJECTS:
        gc.set_threshold(GC_YOUNG_OBJECTS, *older)


#: set by :func:`pause_collections` (the collector's automatic runs switched off by it, not yet back on)
_PAUSED = False


def pause_collections() -> None:
    """Switch the garbage collector's automatic runs off while the command starts (its imports, typer's
    parsing, numba's start and the kernels' cache loads, the configuration and the reading): everything
    allocated then lives as long as the command, and a collection finds next to nothing to free (a full
    collection at the checks and at the run's start found 650 and 730 objects, RSS unchanged: issue 41,
    session 11). At :data:`GC_YOUNG_OBJECTS` that was still 3 young collections of 11–16 ms each on the
    60-s log's path before its run, and 3 in the figures' child (which, forked meanwhile, keeps the
    collector off: it draws one figure and exits). :func:`resume_collections` switches it back on. Nothing
    is done where the automatic runs are already off."""
    global _PAUSED
    import gc  # lazy: the console script's start imports only what every command needs

    if gc.isenabled():
        gc.disable()
        _PAUSED = True


def resume_collections() -> None:
    """The automatic runs back on after :func:`pause_collections` (else nothing): the objects of the start
    are first moved to the collector's permanent generation (``gc.freeze``), so that no later collection
    walks them again (the first young collection after the pause would otherwise walk all of them)."""
    global _PAUSED
    import gc  # lazy: the console script's start imports only what every command needs

    if _PAUSED:
        _PAUSED = False
        gc.freeze()
        gc.enable()


def exit_status(code) -> int:
    """The exit status Python gives ``SystemExit(code)``: None → 0, an int as it is, else 1 (the code is
    printed to stderr, as Python does)."""
    if code is None:
        return 0
    if isinstance(code, int):
        return code
    print(code, file=sys.stderr)
    return 1


def leave(status: int):
    """End the process now, as a normal exit would but without the interpreter's teardown.

    Tearing down the modules a command loaded (numba's and LLVM's objects above all) costs ~0.2 s of
    CPU that nothing needs. The atexit handlers run and stdout/stderr are flushed as at a normal exit;
    files are closed by the code that wrote them (every writer uses ``with``). A normal exit is taken
    when another thread is still running (a normal exit would wait for it) or when flushing fails (a
    closed pipe: Python's own handling) or under a profiler, tracer or debugger (they write their
    results after the program returns)."""
    import atexit  # lazy: the console script's start imports only what every command needs
    import threading  # lazy: the console script's start imports only what every command needs

    if threading.active_count() > 1 or sys.getprofile() is not None or sys.gettrace() is not None:
        sys.exit(status)
    atexit._run_exitfuncs()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):
        sys.exit(status)
    os._exit(status)
