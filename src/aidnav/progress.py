"""One progress bar with an ETA for long commands (``process``, ``tight``, ``evaluate``,
``design-trajectory``), drawn with rich.

Driven by chunk callbacks, never per sample: the numba kernels run over chunks of samples (or epochs,
or runs) and the caller reports after each chunk, e.g.::

    with progress_bar("filter", total=len(imu), unit="samples") as bar:
        for start, stop in chunks(len(imu), 200_000):
            run_kernel(start, stop)      # numba, whole chunk
            bar.update(stop)             # or bar.advance(stop - start)

A :class:`ProgressBar` is itself a callback ``bar(done, total=None)``, so it can be handed to a
function taking ``on_progress=``. Several stages share the one bar: :meth:`ProgressBar.stage` renames
it and restarts it with a new total.

Quiet when not on a terminal: the bar is drawn on standard error only when both standard error and
standard output are terminals (or when a rich ``Console`` with ``force_terminal=True`` is passed), so
piped or redirected output stays clean — no escape codes, no carriage returns, no text at all.
``AIDNAV_PROGRESS=0`` turns it off, ``AIDNAV_PROGRESS=1`` forces it on.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterator

__all__ = ["ProgressBar", "progress_bar", "chunks", "progress_enabled", "NullProgress"]

#: Callback type: ``on_progress(done, total)``; total may be None to keep the current one.
ProgressCallback = Callable[..., None]


def _isatty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # closed or replaced streams
        return False


def progress_enabled(console=None) -> bool:
    """Whether a bar should be drawn: ``AIDNAV_PROGRESS`` when set (0/1), else on a console that is a
    terminal (a passed console: its own ``is_terminal``, which honours ``force_terminal``; the default:
    standard error and standard output both terminals)."""
    env = os.environ.get("AIDNAV_PROGRESS")
    if env is not None and env.strip() != "":
        return env.strip().lower() not in ("0", "false", "no", "off")
    if console is not None:
        return bool(console.is_terminal)
    return _isatty(sys.stderr) and _isatty(sys.stdout)


def chunks(n: int, size: int) -> Iterator[tuple[int, int]]:
    """[start, stop) index ranges covering ``range(n)`` in pieces of ``size`` (the last may be shorter)."""
    if size < 1:
        raise ValueError(f"chunk size must be >= 1 (got {size})")
    if n < 0:
        raise ValueError(f"n must be >= 0 (got {n})")
    for a in range(0, n, size):
        yield a, min(n, a + size)


class NullProgress:
    """The do-nothing bar (not on a terminal): same methods as :class:`ProgressBar`."""

    enabled = False

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def __call__(self, done, total=None) -> None:
        pass

    def update(self, done, total=None) -> None:
        pass

    def advance(self, n=1) -> None:
        pass

    def stage(self, description: str, total=None, unit: str | None = None) -> None:
        pass

    def log(self, message: str) -> None:
        pass


class ProgressBar:
    """A rich progress bar (description, bar, percentage, done/total with unit, elapsed, ETA) on
    ``console`` (default: a new one on standard error). Use as a context manager."""

    enabled = True

    def __init__(self, description: str, total: float | None = None, unit: str = "", console=None,
                 transient: bool = False):
        from rich.console import Console  # lazy: rich is heavy to import
        from rich.progress import (  # lazy: rich is heavy to import
            BarColumn,
            Progress,
            TaskProgressColumn,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self.console = console if console is not None else Console(stderr=True)
        self.unit = unit
        cols = [TextColumn("[bold]{task.description}"), BarColumn(), TaskProgressColumn(),
                TextColumn("{task.completed:,.0f}/{task.fields[total_text]} {task.fields[unit]}"),
                TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn()]
        self._progress = Progress(*cols, console=self.console, transient=transient,
                                  redirect_stdout=False, redirect_stderr=False)
        self._task = self._progress.add_task(description, total=total, unit=unit,
                                             total_text=self._total_text(total))

    @staticmethod
    def _total_text(total) -> str:
        return "?" if total is None else f"{total:,.0f}"

    def __enter__(self) -> ProgressBar:
        self._progress.start()
        return self

    def __exit__(self, *exc) -> bool:
        self._progress.stop()
        return False

    def update(self, done: float, total: float | None = None) -> None:
        """Set the amount done (and optionally a new total)."""
        kw = {"completed": done}
        if total is not None:
            kw.update(total=total, total_text=self._total_text(total))
        self._progress.update(self._task, **kw)

    __call__ = update

    def advance(self, n: float = 1) -> None:
        """Add ``n`` to the amount done."""
        self._progress.advance(self._task, n)

    def stage(self, description: str, total: float | None = None, unit: str | None = None) -> None:
        """Next stage on the same bar: new description and total, restarted at 0 (and its ETA)."""
        if unit is not None:
            self.unit = unit
        self._progress.reset(self._task, total=total, completed=0, description=description, unit=self.unit,
                             total_text=self._total_text(total))

    def log(self, message: str) -> None:
        """A line printed above the bar."""
        self._progress.console.print(message)


def progress_bar(description: str, total: float | None = None, unit: str = "", console=None,
                 enabled: bool | None = None, transient: bool = False) -> ProgressBar | NullProgress:
    """A :class:`ProgressBar`, or a :class:`NullProgress` when ``enabled`` is False or (None) when
    :func:`progress_enabled` says there is no terminal."""
    if enabled is None:
        enabled = progress_enabled(console)
    if not enabled:
        return NullProgress()
    return ProgressBar(description, total, unit, console, transient)


def run_on_terminal(cmd: list[str], env: dict | None = None, timeout: float = 300.0) -> tuple[int, str]:
    """Run ``cmd`` with a POSIX pseudo-terminal as its stdin/stdout/stderr and return (exit status,
    everything it wrote, decoded): how a user's terminal sees a command's progress bar."""
    import pty  # lazy: POSIX only, and only the terminal check of the tests uses it
    import subprocess  # lazy: with pty, for the terminal check only

    master, slave = pty.openpty()
    try:
        p = subprocess.Popen(cmd, stdin=slave, stdout=slave, stderr=slave, env=env, close_fds=True)
        os.close(slave)
        got = []
        while True:
            try:
                data = os.read(master, 65536)
            except OSError:  # EIO: the child closed the terminal
                break
            if not data:
                break
            got.append(data)
        rc = p.wait(timeout=timeout)
    finally:
        os.close(master)
    return rc, b"".join(got).decode("utf-8", "replace")
