"""``aidnav characterise``: a static IMU log → Allan deviation → fitted noise terms, written as
DIR/noise.json, DIR/imu.yaml (the filter's ``imu:`` section) and the figure DIR/allan.png.

Speed (issue 29). The figure's work (matplotlib's import, ~0.3 s CPU, and the drawing, ~0.5 s) holds
Python's lock for most of it, so a thread does not run it beside the analysis. On Linux the figure is
drawn by a child process forked when the job starts (:class:`FigureProcess`): the child imports
matplotlib and warms its text and font caches while the parent reads the log, draws each axis's panel as
soon as the parent has fitted it (the pickled fit, ~2 kB, sent through a pipe), and finishes the figure
(its title, the PNG) from the final characterisation while the parent writes noise.json and imu.yaml. The
file is the one :func:`aidnav.report.allan_plot.plot_allan` writes in-process (tests compare the bytes);
an error in the child is raised in the parent with the child's traceback. Elsewhere (no ``fork``) the
figure module is imported in a thread started with the job and the figure is drawn after the analysis.
"""

from __future__ import annotations

import os
import pickle
import signal
import sys
import threading

from .forked import error_answer, fork_worker, worker_answer

__all__ = ["characterise_file", "print_characterisation", "FigureProcess"]

#: the default of ``plot``: the Allan figure of :mod:`aidnav.report.allan_plot`
FIGURE = "allan.png"
#: draw the figure in a forked child process (Linux; elsewhere: in this process after the analysis)
FORK_FIGURE = sys.platform.startswith("linux") and hasattr(os, "fork")


def print_characterisation(ch, console=None) -> None:
    """:func:`aidnav.analysis.noise_fit.print_characterisation` (the analysis modules are imported when
    the job runs, after the figure's process is forked: see :func:`characterise_file`)."""
    # lazy: the analysis loads after the figure's process is forked
    from aidnav.analysis.noise_fit import print_characterisation as _print

    _print(ch, console)


def _import_console() -> None:
    try:
        # lazy: rich: ~40 ms, the summary printed next
        import aidnav.analysis.noise_fit.console  # noqa: F401
    except Exception:  # noqa: BLE001  (imported again, with its error, when the summary is printed)
        pass


def _import_figure_module() -> None:
    try:
        # lazy: matplotlib: ~0.3 s, imported while the log is read
        import aidnav.report.allan_plot  # noqa: F401
    except Exception:  # noqa: BLE001  (imported again, with its error, when the figure is drawn)
        pass


def _figure_in_background():
    """``plot(ch, path, title)`` that draws :func:`aidnav.report.allan_plot.plot_allan`, its module being
    imported from now on in a thread."""
    loader = threading.Thread(target=_import_figure_module, name="aidnav-figure-import", daemon=True)
    loader.start()

    def plot(ch, path, title):
        loader.join()
        from aidnav.report.allan_plot import plot_allan  # lazy: matplotlib, imported by the thread above

        return plot_allan(ch, path, title)

    return plot


def _draw_in_child(job_fd: int):
    """The child's work: import the figure module and warm it up, then read the messages of
    :class:`FigureProcess` from ``job_fd``: ("axis", c, axis fit, duration [s], title) as each axis is
    fitted (its panel is built and drawn at once: :class:`aidnav.report.allan_plot.AllanFigure`), then
    ("job", ch, path, title, changed) (changed: the axes whose fit changed after their message). The
    figure is finished from the panels drawn, or drawn again whole from ``ch`` when any panel differs
    from the final characterisation's (vibration found on its axis, a changed fit, a message missing).
    Returns ("ok", path, "panels" | "whole"), ("error", pickled exception or None, traceback text) or None
    (no job: the parent closed the pipe without one)."""
    fig = early = None
    try:  # matplotlib imported and warmed up, the figure and its image made ahead of the data
        from aidnav.report.allan_plot import AllanFigure, warm_up  # lazy: matplotlib, in the child only

        warm_up()
        fig = AllanFigure("Allan deviation")
        fig._draw_ready()
    except Exception:  # noqa: BLE001  (the figure is then drawn whole at the end, and an error reported)
        early = False
    with os.fdopen(job_fd, "rb") as f:
        while True:
            try:
                msg = pickle.load(f)
            except EOFError:
                return None
            if msg[0] != "axis":
                break
            if early is False:
                continue
            try:  # any failure here: the figure is drawn whole at the end (where an error is reported)
                _, c, a, dur, title = msg
                if early is None:
                    fig.span_s, early = dur, {}
                    fig.set_title(title)
                early[c] = title
                fig.panel(c, a)
            except Exception:  # noqa: BLE001
                early = False
    try:
        from aidnav.report.allan_plot import panel_title, plot_allan  # lazy: matplotlib, in the child only

        _, ch, path, title, changed = msg
        if (fig is not None and early and set(early) == set(range(len(ch.axes))) and not any(changed)
                and all(t == title for t in early.values()) and fig.span_s == ch.duration_s
                and all(fig.title(c) == panel_title(a, ch.vibration) for c, a in enumerate(ch.axes))):
            return "ok", fig.save(path), "panels"
        return "ok", plot_allan(ch, path, title), "whole"
    except BaseException as e:  # noqa: BLE001  (raised in the parent)
        return error_answer(e)


class FigureProcess:
    """``plot(ch, path, title) -> path`` (:func:`aidnav.report.allan_plot.plot_allan`) served by a child
    process forked now, which imports matplotlib and warms it up at once (module docstring).

    ``axis_done(c, axis_fit, duration_s, title)`` (from the analysis's worker threads) sends each axis as
    soon as it is fitted: the child draws its panel while the other axes are fitted. Call it once (it
    then waits for the child's answer and raises its error, with the child's traceback as a note), or
    ``close()`` it without a figure (the child is ended). Linux only (``fork`` of a process whose other
    threads, if any, the child never needs: it runs Python, numpy and matplotlib only).
    ``draw(job_fd)`` : the child's work (tests)."""

    def __init__(self, draw=_draw_in_child):
        pid, self._job_w, res_r = fork_worker(draw)
        self.pid, self._res_r, self._reaped = pid, res_r, False
        self._lock = threading.Lock()
        self._sent: dict[int, bytes] = {}  # each axis as sent (pickled), to tell whether it changed after
        #: after the call: "panels" (the figure finished from the panels drawn as the axes came) or "whole"
        self.drawn_from: str | None = None
        self._path = None

    def axis_done(self, c: int, a, duration_s: float, title: str) -> None:
        """Send axis c's fit to the child (never raises: the figure is then drawn whole at the end)."""
        try:
            data = pickle.dumps(a)
            msg = pickle.dumps(("axis", c, a, duration_s, title))
            with self._lock:
                if self._job_w is None:
                    return
                self._sent[c] = data
                self._job_w.write(msg)
                self._job_w.flush()
        except Exception:  # noqa: BLE001  (a child gone: reported by the call)
            pass

    def __call__(self, ch, path, title):
        self.send(ch, path, title)
        return self.result()

    def send(self, ch, path, title) -> None:
        """Send the job (the final characterisation) to the child; :meth:`result` waits for its answer."""
        if self._job_w is None:
            raise RuntimeError("FigureProcess: called twice or after close()")
        changed = [pickle.dumps(a) != self._sent.get(c) for c, a in enumerate(getattr(ch, "axes", ()))]
        data = pickle.dumps(("job", ch, path, title, changed))
        with self._lock:
            job_w, self._job_w = self._job_w, None
        try:
            with job_w:
                job_w.write(data)
        except BrokenPipeError:  # the child is gone: its status is reported by result()
            pass
        self._path = path

    def result(self):
        """The figure's path once the child has written it; the child's error raised here."""
        res_r, self._res_r = self._res_r, None
        try:
            res = worker_answer(self.pid, res_r, f"the figure process ended without drawing {self._path}")
        finally:
            self._reaped = True
        self.drawn_from = res[2] if len(res) > 2 else None
        return res[1]

    def close(self) -> None:
        """End the child without a figure (after an error of the analysis); nothing after a call."""
        with self._lock:
            job_w, self._job_w = self._job_w, None
        if job_w is not None:
            try:
                job_w.close()
            except OSError:  # a write the child did not read
                pass
        if self._res_r is not None:
            os.close(self._res_r)
            self._res_r = None
        if not self._reaped:
            self._reaped = True
            try:
                os.kill(self.pid, signal.SIGKILL)  # it may be importing matplotlib: no need to wait for it
                os.waitpid(self.pid, 0)
            except (ChildProcessError, ProcessLookupError):
                pass


def characterise_file(imu_path, out_dir, static: str | None = None, grade: str | None = None,
                      timings: dict | None = None, plot=FIGURE) -> tuple:
    """:func:`aidnav.analysis.noise_fit.characterise_file` with the figure drawn by
    :func:`aidnav.report.allan_plot.plot_allan` (``plot=None``: no figure; a function
    ``plot(ch, path, title) -> path``: that one). The default figure is drawn by a forked child process
    on Linux (:class:`FigureProcess`), forked before this module imports the analysis (numba, scipy): the
    child imports them with matplotlib on the other core while this process does the same. Only from a
    process with no other thread (a fork there could copy a lock another thread holds: notebooks, servers);
    otherwise the figure is drawn here, the same file."""
    if plot == FIGURE and FORK_FIGURE and threading.active_count() == 1:
        fig = FigureProcess()

        def draw(ch, path, title):
            fig.send(ch, path, title)
            _import_console()  # while the child finishes the figure: the summary's module (rich) is next
            return fig.result()

        draw.axis_done = fig.axis_done
        try:
            # lazy: the analysis loads after the figure's process is forked
            from aidnav.analysis.noise_fit import characterise_file as _characterise_file

            return _characterise_file(imu_path, out_dir, static=static, grade=grade, timings=timings,
                                      plot=draw)
        finally:
            fig.close()
    # lazy: the analysis loads after the figure's process is forked
    from aidnav.analysis.noise_fit import characterise_file as _characterise_file

    if plot == FIGURE:
        plot = _figure_in_background()
    return _characterise_file(imu_path, out_dir, static=static, grade=grade, timings=timings, plot=plot)
