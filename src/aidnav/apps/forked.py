"""A forked child that does one piece of work for its parent (Linux): the parent writes the job to a pipe,
the child's ``work(job_fd)`` reads it and its pickled answer comes back through a second pipe. Used by
the figures of ``process`` (:mod:`.run_outputs`) and of ``characterise``, which fork before the long work
so that matplotlib is imported and warmed up while the parent computes."""

from __future__ import annotations

import os
import pickle
import struct
import traceback


def fork_worker(work):
    """Fork a child that runs ``work(job_fd)`` once and writes its pickled result back, then exits
    (never returns in the child; status 0 when ``work`` returned). Returns, in the parent, ``(pid,
    job_w, res_r)``: the child's pid, the job pipe's write end as a binary file, the result pipe's read
    end as a file descriptor."""
    job_r, job_w = os.pipe()
    res_r, res_w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: never returns
        status = 1
        try:
            os.close(job_w)
            os.close(res_r)
            res = work(job_r)
            with os.fdopen(res_w, "wb") as f:
                f.write(pickle.dumps(res))
            status = 0
        finally:
            os._exit(status)
    os.close(job_r)
    os.close(res_w)
    return pid, os.fdopen(job_w, "wb"), res_r


def frame(msg) -> bytes:
    """``msg`` pickled as one message of a pipe: its length (8 bytes), then the pickle (a reader can pass
    the pickle's bytes on as they came: :func:`receive`)."""
    data = pickle.dumps(msg, protocol=pickle.HIGHEST_PROTOCOL)
    return struct.pack("<Q", len(data)) + data


def receive(f) -> bytes:
    """The next message's pickle (:func:`frame`) from the binary file ``f``; EOFError at its end."""
    head = f.read(8)
    if len(head) < 8:
        raise EOFError
    (n,) = struct.unpack("<Q", head)
    data = f.read(n)
    if len(data) < n:
        raise EOFError
    return data


def error_answer(e: BaseException) -> tuple:
    """The answer of a child whose work raised ``e`` (in its ``except`` clause): ``("error", the pickled
    exception, the traceback text)``, the exception None when it does not pickle (its text only);
    :func:`worker_answer` raises it in the parent."""
    try:
        exc = pickle.dumps(e)
    except Exception:  # noqa: BLE001  (an exception that does not pickle: its text only)
        exc = None
    return "error", exc, traceback.format_exc()


def worker_answer(pid: int, res_r: int, missing: str) -> tuple:
    """Read the answer of the child ``pid`` (:func:`fork_worker`) from ``res_r`` and reap the child. Its
    ``("ok", …)`` tuple is returned; its ``("error", pickled exception, traceback text)`` is raised here,
    with the child's traceback as a note (a RuntimeError carrying the traceback when the exception does
    not unpickle); ``missing``: what to say when the child ended without an answer."""
    with os.fdopen(res_r, "rb") as f:
        out = f.read()
    _, status = os.waitpid(pid, 0)
    res = pickle.loads(out) if out else None
    if not res:
        raise RuntimeError(f"{missing} (wait status {status})")
    return checked_answer(res)


def checked_answer(res: tuple) -> tuple:
    """A child's answer (:func:`worker_answer`) as it is where it is ``("ok", …)``; its error raised."""
    if res[0] == "ok":
        return res
    _, exc, tb = res
    try:
        exc = pickle.loads(exc)
    except Exception:  # noqa: BLE001  (None, or an exception that does not unpickle)
        exc = RuntimeError(f"the figure process failed:\n{tb}")
    else:
        exc.add_note(f"(raised in the figure process)\n{tb}")
    raise exc
