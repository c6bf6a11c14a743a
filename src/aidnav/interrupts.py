"""Ctrl-C and SIGTERM without a crash (issue 37): the interrupt is raised as ``KeyboardInterrupt`` at a
point where Python code can take it, never inside numba's glue around a kernel.

Why: a kernel releases the GIL (``nogil``) and Python's SIGINT handler waits for the interpreter; the
first Python code that runs after the kernel returns is numba's own, boxing the kernel's named-tuple
result: its wrapper calls ``numba.core.serialize._numba_unpickle`` to get the tuple's class and calls
that class without checking for NULL. Python's default handler raised ``KeyboardInterrupt`` inside
``_numba_unpickle``; the wrapper then called NULL: SIGSEGV, nothing printed, ``.part`` and spool files
left (reproduced on ``aidnav process`` of the W1 log, core: ``_PyObject_Call(callable=0x0)`` from the
CPython wrapper of ``filters.engine.run_chunk``; the same in ``run_batch`` for ``aidnav run``).

:func:`install` replaces the SIGINT and SIGTERM handlers (in the ``aidnav`` command only) by one that
raises ``KeyboardInterrupt`` where it lands unless the frame it interrupts is numba's (or llvmlite's)
code, a weak-reference callback or a finalizer (there Python would print "Exception ignored" and go
on): then the interrupt is kept and delivered again a few milliseconds later (``SIGALRM``), when the
kernel's result has been boxed and Python code of aidnav runs. Long kernels are cut into chunks by
their drivers (the streamed filter, the Monte Carlo batches), so an interrupt is taken between chunks.
A second SIGINT while one is pending raises at once.

:func:`worker_ignore` is for worker processes (the campaign's process pool): they ignore SIGINT; the
parent, which gets the same Ctrl-C, stops and shuts them down.
"""

from __future__ import annotations

import contextlib
import os
import signal

__all__ = ["install", "worker_ignore", "blocked", "MESSAGE", "pending"]

#: what the ``aidnav`` command prints on SIGINT/SIGTERM (exit status 130); commands add what is on disk
MESSAGE = "interrupted (SIGINT/SIGTERM): the command stopped before completing"

_RETRY_S = 0.005
_state = {"pending": False, "installed": False, "hold": False}
#: frames where an exception is lost or breaks the caller: numba's glue around a kernel call, weak
#: reference callbacks and finalizers (Python prints "Exception ignored" and goes on)
_UNSAFE = (os.sep + "numba" + os.sep, os.sep + "llvmlite" + os.sep, "weakref", os.sep + "gc")
#: code run by ``eval``/``exec`` of a string (``collections.namedtuple`` builds its ``__new__`` so): a
#: ``KeyboardInterrupt`` raised there, or below it and passing through it, sets CPython's "unhandled
#: interrupt" flag (3.11: ``run_eval_code_obj``) even when the command then handles it, and the interpreter
#: ends itself by SIGINT at its exit (status −2, no traceback; issue 41, session 13: a campaign interrupted
#: while rich built a named tuple, or during an import under such code)
_EVAL = "<string>"


def pending() -> bool:
    """Whether an interrupt is waiting to be raised."""
    return _state["pending"]


def _in_eval(frame) -> bool:
    """Whether ``frame`` or one of its callers is code run by ``eval``/``exec`` of a string (:data:`_EVAL`;
    not the program's own outermost frame: ``python -c``'s code is a string too)."""
    while frame is not None and frame.f_back is not None:
        if frame.f_code.co_filename == _EVAL:
            return True
        frame = frame.f_back
    return False


def _unsafe(frame) -> bool:
    return frame is not None and (frame.f_code.co_name == "__del__" or _in_eval(frame)
                                  or any(u in frame.f_code.co_filename for u in _UNSAFE))


def _handler(signum, frame):
    if signum == signal.SIGALRM and not _state["pending"]:
        return
    if signum != signal.SIGALRM and _state["pending"] and signum == signal.SIGINT:
        _raise()  # a second Ctrl-C: at once
    if _state["hold"] or _unsafe(frame):
        _state["pending"] = True
        if not _state["hold"]:
            signal.setitimer(signal.ITIMER_REAL, _RETRY_S)  # again when numba's glue has returned
        return
    _raise()


def _raise():
    _state["pending"] = False
    signal.setitimer(signal.ITIMER_REAL, 0.0)
    raise KeyboardInterrupt


def install(hold: bool = False) -> bool:
    """The handler of this module for SIGINT, SIGTERM (and SIGALRM, its retry); not where SIGINT is
    ignored (a process started in the background by a shell) or outside the main thread. Returns whether
    it was installed. ``hold``: an interrupt is only kept (the command's modules are being imported);
    the next ``install()`` raises it."""
    import threading  # lazy: only when the handlers are installed (every command imports this module)

    _state["hold"] = hold
    if _state["installed"]:
        if not hold and _state["pending"]:
            _raise()
        return True
    if threading.current_thread() is not threading.main_thread():
        return False
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        return False
    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGALRM):
        signal.signal(s, _handler)
    _state["installed"] = True
    return True


def worker_ignore() -> None:
    """In a worker process (forked: it inherits this module's handlers): SIGINT ignored (the Ctrl-C of the
    terminal reaches the whole process group; the parent stops the workers), SIGTERM and SIGALRM back to
    their defaults (the pool ends a broken worker with SIGTERM)."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        for s in (signal.SIGTERM, signal.SIGALRM):
            signal.signal(s, signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})  # (see blocked)
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not the main thread, not POSIX
        pass


@contextlib.contextmanager
def blocked():
    """SIGINT and SIGTERM held back in this thread while the block runs (delivered after it): around
    forking worker processes, which would otherwise take a Ctrl-C with the parent's handler before their
    start-up code ignores it (a traceback, a broken pool). The children inherit the blocked mask;
    :func:`worker_ignore` unblocks it."""
    if not hasattr(signal, "pthread_sigmask"):  # pragma: no cover - not POSIX
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
