"""The figures, maps and page of ``aidnav process`` drawn beside the filter (issue 41).

:func:`start_outputs` forks, on Linux and from a process with no other thread (as ``characterise`` does with
its :class:`aidnav.apps.characterise.FigureProcess`), a child that imports matplotlib and the report modules
and loads the default font while the parent reads the logs and runs the filter. The command forks it first
thing, before numba and the filters load (the ``aidnav`` console script even before typer parses the command
line: :func:`aidnav.cli._fork_figures_early`): the child needs neither (the report draws with
:mod:`aidnav.nav.plain`), so it costs no numba import and no kernel load, and holds none of their memory.
Once the configuration and the fixes are read, the parent tells the child which panels the overview will
have (:meth:`OutputsProcess.expect`, :func:`expected_panels`); the child builds and draws that figure's
:class:`aidnav.report.overview.Skeleton` (figure, axes, labels, scales, grids: everything that does not
depend on the run's numbers) while the filter runs. After the filter, :func:`write_outputs` sends the
child what the page needs (the decimated trajectory, the
fixes, the summary, the innovation records: a few MB through a pipe); the child draws ``overview.png``
and writes ``run.html`` while the parent writes the maps (``trajectory.kml``, ``trajectory.geojson``);
the parent then waits for the child and raises its error, with the child's traceback as a note. On a
machine with :data:`SPLIT_MIN_CPUS`, the child forks a second drawing process once its skeleton is primed
(:mod:`aidnav.apps.overview_helper`): after the run the two draw half of the overview each and write the
maps, and the parent only waits. The
files are those :func:`aidnav.report.run_page.write_run_outputs` writes in one process (a test compares
the bytes). Where no fork is possible (another OS, a thread running: a Dask worker, a notebook's kernel),
everything is drawn in this process after the filter.
"""

from __future__ import annotations

import os
import pickle
import signal
import sys
import threading
import weakref

from .forked import error_answer, fork_worker, frame, receive, worker_answer
from .overview_helper import MAPS_BASE, DrawingHelper, split_panels, usable_cpus

__all__ = ["OutputsProcess", "start_outputs", "write_outputs", "expected_panels", "FORK_OUTPUTS",
           "IN_PROCESS"]

#: draw in a forked child process (Linux; elsewhere: in this process after the filter)
FORK_OUTPUTS = sys.platform.startswith("linux") and hasattr(os, "fork")
#: ``figures=IN_PROCESS``: drawn in this process, no child (``aidnav fleet``'s workers draw log after log
#: with matplotlib loaded once)
IN_PROCESS = "in-process"
#: the overview's skeleton is built by the child while the filter runs only on a machine with at least this
#: many CPUs (on one, it would take the CPU from the filter). It is built during the parent's numba start
#: and first passes, one thread, so on two cores it runs on the free one: paired runs on this project's
#: 2-core machine (RT priority, load 7–10; docs/results.md, issue 41 session 11), with the command's fewer
#: garbage collections: W1 default outputs 1.43 s with it, 1.65 s without; the 60-s log 1.08 vs 1.24 s
#: (session 10 had set 3 from an idle run where it cost +0.26 s on W1: not reproduced)
SKELETON_MIN_CPUS = 2
#: the overview is drawn by two processes (the child and its :class:`~.overview_helper.DrawingHelper`), which
#: also write the maps, on a machine with at least this many CPUs: W1's first 60 s 0.165 instead of 0.215 s
#: from the job to the PNG, W1 0.19–0.23 instead of 0.26–0.31 s (a captured job replayed in a primed child,
#: RT; docs/results.md, issue 41 session 12)
SPLIT_MIN_CPUS = 2


def _warm_up() -> None:
    """Load what the page's drawing needs before its job comes: the report modules and matplotlib (with
    no numba: they use :mod:`aidnav.nav.plain`), the default font and the PNG writer. A whole overview
    drawn small as a warm-up (sessions 5–7) cost more CPU than it saved once the child no longer loaded
    numba (60-s log: warm-up 0.37 CPU-s, the figure after it 0.55 against 0.57 cold; docs/results.md,
    issue 41 session 8): on two cores that CPU is taken from the filter."""
    from matplotlib import font_manager  # lazy: matplotlib, in the child only
    from PIL import PngImagePlugin  # noqa: F401  # lazy: the PNG writer, in the child only

    import aidnav.report.overview  # noqa: F401  # lazy: matplotlib and the figure's modules
    import aidnav.report.run_page  # noqa: F401  # lazy: the page's modules

    font_manager.get_font(font_manager.findfont(font_manager.FontProperties()))


def _skeleton(panels):
    """The overview's :class:`~aidnav.report.overview.Skeleton` for ``panels``, drawn once; None where that
    fails (the figure is then built after the run, and its error reported there)."""
    try:
        from aidnav.report.overview import Skeleton  # lazy: matplotlib (loaded by the warm-up)

        skeleton = Skeleton(panels)
        skeleton.prime()
        return skeleton
    except Exception:  # noqa: BLE001  (built again after the run, where an error is reported)
        return None


def _serve(job_fd: int):
    """The child's work: warm up, read the expected panels (:meth:`OutputsProcess.expect`, optional), build
    their skeleton and fork its drawing helper, then read one job (out_dir, traj, gnss, summary, records)
    and write the overview, then the page (with the summary that follows the job where the parent sent
    one: :meth:`OutputsProcess.send`'s ``page_follows``), and the maps where the job says so. Returns
    ("ok", paths), ("error", pickled exception or None, traceback) or None (the parent closed the pipe
    without a job)."""
    try:
        _warm_up()
    except Exception:  # noqa: BLE001  (the same import fails again below, and is reported)
        pass
    skeleton = helper = None
    with os.fdopen(job_fd, "rb") as f:
        try:
            try:
                raw = receive(f)
                msg = pickle.loads(raw)
                if msg[0] == _PANELS:
                    skeleton = _skeleton(msg[1])
                    helper = DrawingHelper.start(skeleton, SPLIT_MIN_CPUS, f.fileno())
                    raw = receive(f)
            except EOFError:
                return None
            try:
                return "ok", _job(f, raw, skeleton, helper)
            except BaseException as e:  # noqa: BLE001  (raised in the parent)
                return error_answer(e)
        finally:
            if helper is not None:
                helper.end()


def _job(f, raw: bytes, skeleton, helper) -> dict:
    """The child's job (:func:`_serve`): the overview (with the helper, where there is one), the page, the
    maps where the job asks for them. Returns the paths written."""
    from aidnav.report.run_page import write_run_outputs  # lazy: matplotlib (loaded by the warm-up)

    job = pickle.loads(raw)
    if helper is not None:
        helper.send(raw, job)
    _, out_dir, traj, gnss, summary, records, page_follows, maps = job

    def page_summary():  # the summary completed by the parent meanwhile (its timings)
        return pickle.loads(receive(f))[1] if page_follows else summary

    paths = write_run_outputs(out_dir, traj, gnss, summary, records, maps=maps and helper is None,
                              skeleton=skeleton, page_summary=page_summary,
                              draw=None if helper is None else helper.draw)
    if maps and helper is not None:
        paths.update(helper.maps())
    return paths


#: the first word of each message to the child: the expected panels (:meth:`OutputsProcess.expect`), the job
#: (:meth:`OutputsProcess.send`), the page's summary (:meth:`OutputsProcess.send_page`)
_PANELS, _JOB, _PAGE = "panels", "job", "page"


def expected_panels(use: str, has_velocity: bool) -> list[str]:
    """The right column of the overview (:func:`aidnav.report.overview.panel_names`) that a loosely
    coupled run gives, known before the run: roll/pitch, heading, position and attitude 1σ, a NIS panel
    for the positions (``use`` of the GNSS configuration: both, position) and one for the velocities
    (both, velocity, where the fixes have them). A guess: the child builds the figure afresh where the run
    gives other panels (a measurement type without any update has none)."""
    return ["rp", "heading", "spos", "satt"] + ["nis:pos"] * (use != "velocity") + \
        ["nis:vel"] * (use != "position" and has_velocity)


def _close(f) -> None:
    try:
        f.close()
    except OSError:  # the child is gone (a broken pipe at the flush): its status is reported by result()
        pass


def _end(pid: int, fds: list) -> None:
    """Close the pipes and end the child (a job never sent: the parent failed before its outputs)."""
    for f in fds:
        try:
            f.close() if hasattr(f, "close") else os.close(f)
        except OSError:
            pass
    try:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
    except (ChildProcessError, ProcessLookupError):
        pass


class OutputsProcess:
    """A forked child that writes ``overview.png`` and ``run.html`` of one run (module doc). ``send`` the
    job once, then ``result()``; an instance dropped without a job ends its child."""

    def __init__(self, serve=_serve):
        pid, self._job_w, res_r = fork_worker(serve)
        self.pid = pid
        self._res_r = res_r
        self._sender = None
        self.maps_in_child = False  # the maps written by the child and its helper (expect, send)
        self._finalizer = weakref.finalize(self, _end, pid, [self._job_w, res_r])

    def expect(self, panels: list[str]) -> None:
        """Tell the child the overview's panels (:func:`expected_panels`) before the job: it builds their
        skeleton while this process runs the filter. At most once, before :meth:`send`."""
        if self._job_w is None or self._sender is not None:
            raise RuntimeError("OutputsProcess: expect after send")
        # where the child will have a drawing helper, the two write the maps (the parent only waits)
        self.maps_in_child = usable_cpus() >= SPLIT_MIN_CPUS and bool(split_panels(panels))
        try:
            self._job_w.write(frame((_PANELS, list(panels))))  # a few bytes: the pipe takes them now
            self._job_w.flush()
        except (BrokenPipeError, OSError):  # the child is gone: its status is reported by result()
            pass

    def send(self, out_dir, traj, gnss, summary, records, page_follows: bool = False) -> None:
        """The job: the child draws from these (pickled now: later changes are not seen). page_follows : the
        page's summary comes later (:meth:`send_page`; the overview is drawn meanwhile), else the page is
        written with ``summary``."""
        job_w = self._job_w
        if job_w is None or self._sender is not None:
            raise RuntimeError("OutputsProcess: send called twice")
        if not page_follows:
            self._job_w = None
        data = frame((_JOB, str(out_dir), traj, gnss, summary, records, page_follows, self.maps_in_child))

        def write():  # in a thread: the child may still be warming up, the maps are written meanwhile
            try:
                job_w.write(data)
                job_w.flush()
            except (BrokenPipeError, OSError):  # the child is gone: its status is reported by result()
                pass
            finally:
                if not page_follows:
                    _close(job_w)

        self._sender = threading.Thread(target=write, name="aidnav-outputs-job", daemon=True)
        self._sender.start()

    def send_page(self, summary) -> None:
        """The page's summary, after a :meth:`send` with ``page_follows`` (pickled now; a few kB)."""
        job_w, self._job_w = self._job_w, None
        if job_w is None or self._sender is None:
            raise RuntimeError("OutputsProcess: send_page without a job that awaits it")
        self._sender.join()  # the job's bytes first
        try:
            job_w.write(frame((_PAGE, summary)))
        except (BrokenPipeError, OSError):  # the child is gone: its status is reported by result()
            pass
        finally:
            _close(job_w)

    @property
    def page_awaited(self) -> bool:
        """A job was sent whose page's summary is still to come (:meth:`send_page`)."""
        return self._sender is not None and self._job_w is not None

    def result(self) -> dict:
        """The paths the child wrote; its error raised here."""
        if self._sender is not None:
            self._sender.join()
        self._finalizer.detach()
        res = worker_answer(self.pid, self._res_r, "the figure process ended without writing the overview")
        return res[1]

    def close(self) -> None:
        """End the child without outputs (nothing after ``result``)."""
        self._finalizer()


def start_outputs(figures=True):
    """What ``process_logs(figures=...)`` draws with: an :class:`OutputsProcess` forked now where that is
    possible (Linux, no other thread), else ``figures`` itself (True or :data:`IN_PROCESS`: in this process;
    False: none). An
    :class:`OutputsProcess` given is returned as it is (the command forks before its progress bar's
    thread starts)."""
    if figures is True and FORK_OUTPUTS and threading.active_count() == 1:
        try:
            return OutputsProcess()
        except OSError:  # no fork (limits): drawn here
            return True
    return figures


def write_outputs(figures, out_dir, traj, gnss, summary, records, progress=None, waiting=None) -> dict:
    """Everything a run leaves to look at (:func:`aidnav.report.run_page.write_run_outputs`): by the
    child of ``figures`` (an :class:`OutputsProcess`) with the maps written here meanwhile, or all here
    (``figures`` True). ``waiting``: called after the maps, while the child still draws (what the caller
    needs next, made then). Returns {"overview", "run_page", "kml", "geojson"} → paths."""
    if not isinstance(figures, OutputsProcess):
        from aidnav.report.run_page import write_run_outputs  # lazy: pulls in matplotlib

        return write_run_outputs(out_dir, traj, gnss, summary, records, progress=progress)
    from pathlib import Path  # lazy: the maps' base name only

    from aidnav.report.maps import write_maps  # lazy: the maps (no matplotlib)

    if progress is not None:
        progress.stage("figures and maps", total=3, unit="steps")
    if figures.page_awaited:  # the overview's job went before the trajectory file was closed
        figures.send_page(summary)
    else:
        figures.send(out_dir, traj, gnss, summary, records)
    maps = {}
    if not figures.maps_in_child:
        maps["kml"], maps["geojson"] = write_maps(Path(out_dir) / MAPS_BASE, traj, gnss, summary)
    if progress is not None:
        progress.advance(1)
    if waiting is not None:
        waiting()
    paths = figures.result()
    if progress is not None:
        progress.advance(2)
    return {**paths, **maps}
