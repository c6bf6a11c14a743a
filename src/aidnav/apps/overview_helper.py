"""The overview of ``aidnav process`` drawn by two processes (issue 41): the figures' child
(:mod:`aidnav.apps.run_outputs`) and a :class:`DrawingHelper` it forks once the overview's skeleton is
primed, while the parent still filters.

After the run, each builds the same figure from the job (the helper gets the job's bytes from the child)
and draws half of its panels (:func:`split_panels`): the child the map, the height, the first panel of the
right column and the title; the helper the rest of the right column, whose painted pixels it leaves in
memory shared with the child. The child then copies the helper's box of painted pixels into its own
canvas and writes the PNG. That is the figure drawn whole, pixel for pixel, because the two halves'
artists never meet (each half over the same white background): the child checks that it painted nothing
inside the helper's box and that both built the same figure (:func:`aidnav.report.overview.figure_key`),
and draws the figure whole otherwise (or where the helper failed). With the maps (the parent's job says
so: :meth:`aidnav.apps.run_outputs.OutputsProcess.expect`), the helper writes ``trajectory.geojson`` after
its pixels and the child ``trajectory.kml`` while it waits for them: the parent then only waits.

This module imports only the standard library (the parent imports it with :mod:`.run_outputs`);
matplotlib, numpy and the report modules are the child's (loaded by its warm-up).
"""

from __future__ import annotations

import mmap
import os
import pickle
from pathlib import Path

from .forked import checked_answer, error_answer, frame, receive

__all__ = ["DrawingHelper", "split_panels", "usable_cpus", "MAPS_BASE"]

#: the maps' base name in the output folder (``trajectory.kml``, ``trajectory.geojson``)
MAPS_BASE = "trajectory"


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity: ``taskset``, a container's cpuset), else the machine's:
    the helper only pays where a second one is there for it (on one, it costs ≈ 0.13 s on W1's first 60 s)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not Linux
        return os.cpu_count() or 1


def split_panels(right: list[str]) -> list[str]:
    """The panels of the overview's right column ``right`` (:func:`aidnav.report.overview.panel_names`)
    that the helper draws: all but the first, where the column has at least three; none otherwise. The two
    halves then cost about the same: the map, the height, roll/pitch and the title ≈ 85–90 ms, heading, σ
    and NIS ≈ 85–95 ms (W1 and its first 60 s, a primed skeleton; docs/results.md, issue 41 session 12)."""
    return list(right[1:]) if len(right) >= 3 else []


def _maps(out_dir, traj, gnss, summary, kml: bool) -> Path:
    """``trajectory.kml`` (``kml``) or ``trajectory.geojson`` of the job, as the parent writes them."""
    from aidnav.report.maps import write_maps  # lazy: the report's modules (loaded by the warm-up)

    return write_maps(Path(out_dir) / MAPS_BASE, traj, gnss, summary, kml=kml, geojson=not kml)[0]


class DrawingHelper:
    """The child's side of the helper (module doc): :meth:`start` forks it, :meth:`send` passes it the job,
    :meth:`draw` draws the figure (``write_overview``'s ``draw``), :meth:`maps` gives the maps' paths,
    :meth:`end` reaps it."""

    def __init__(self, skeleton, names: list, pid: int, job_w: int, ans_r: int, shm):
        self.skeleton, self.names, self.pid, self.shm = skeleton, names, pid, shm
        self.job_w, self.ans = job_w, os.fdopen(ans_r, "rb")
        self.job = None
        self.kml = None
        self.parts = 0  # how the last figure was drawn: 2 (by both processes) or 1 (whole, here)
        self.answers = 0  # the helper's answers read: its pixels, then the GeoJSON

    @classmethod
    def start(cls, skeleton, min_cpus: int, close_fd: int | None = None, names: list | None = None):
        """A helper for the primed ``skeleton`` (an :class:`aidnav.report.overview.Skeleton`), or None where
        the overview is drawn by one process: no skeleton, a right column too short to split, fewer than
        ``min_cpus`` CPUs, no fork. ``close_fd``: the child's end of its parent's pipe (closed in the
        helper); ``names``: the helper's panels (default :func:`split_panels`)."""
        if skeleton is None or usable_cpus() < min_cpus:
            return None
        names = split_panels(skeleton.right) if names is None else list(names)
        if not names:
            return None
        w, h = skeleton.fig.canvas.get_width_height()
        try:
            shm = mmap.mmap(-1, 4 * w * h)  # anonymous, shared with the helper after the fork
            shm.write(bytes(4 * w * h))  # its pages made now, not while the helper copies into them
            job_r, job_w = os.pipe()
            ans_r, ans_w = os.pipe()
            pid = os.fork()
        except OSError:
            return None
        if pid == 0:  # the helper: never returns
            status = 1
            try:
                for fd in (close_fd, job_w, ans_r):
                    if fd is not None:
                        os.close(fd)
                _help(job_r, ans_w, skeleton, names, shm)
                status = 0
            finally:
                os._exit(status)
        os.close(job_r)
        os.close(ans_w)
        return cls(skeleton, names, pid, job_w, ans_r, shm)

    def send(self, data: bytes, job: tuple) -> None:
        """The job's pickle as the child got it (``data``) and the job itself: (…, out_dir, traj, gnss,
        summary, records, page_follows, maps)."""
        self.job = job
        job_w, self.job_w = self.job_w, None
        try:
            with os.fdopen(job_w, "wb") as f:
                f.write(data)
        except OSError:  # the helper is gone: the figure is drawn whole (draw), the maps here (maps)
            pass

    def _answer(self):
        """The helper's next answer, or None (it failed or ended)."""
        self.answers += 1
        try:
            return pickle.loads(receive(self.ans))
        except Exception:  # noqa: BLE001  (EOFError, a partial answer: done here instead)
            return None

    def draw(self, fig) -> None:
        """Draw ``fig`` into its canvas: this process's panels and the title, then (with the maps) the KML
        while the helper draws, then the helper's pixels put in; the figure whole where that would not be
        exact (module doc)."""
        import numpy as np  # lazy: loaded with matplotlib (the child's)

        from aidnav.report.overview import draw_panels, figure_key  # lazy: matplotlib (the child's)

        sk = self.skeleton
        if fig is sk.fig:
            key = figure_key(fig)
            theirs = [sk.axes[n] for n in self.names]
            px = draw_panels(fig, [ax for ax in fig.axes if not any(ax is a for a in theirs)], title=True)
            self._kml()
            answer = self._answer()
            if answer is not None and answer[0] is not None and answer[1] == key:
                r0, r1, c0, c1 = answer[0]
                if (px[r0:r1, c0:c1] == np.uint32(0xFFFFFFFF)).all():
                    shared = np.frombuffer(self.shm, np.uint32).reshape(px.shape)
                    px[r0:r1, c0:c1] = shared[r0:r1, c0:c1]
                    self.parts = 2
                    return
        for ax in fig.axes:
            ax.set_visible(True)
        fig.canvas.draw()
        self.parts = 1

    def _kml(self) -> None:
        if self.job is not None and self.job[-1] and self.kml is None:
            self.kml = _maps(*self.job[1:4], self.job[4], kml=True)

    def maps(self) -> dict:
        """{"kml", "geojson"} → paths: the KML written here (:meth:`draw`), the GeoJSON by the helper (its
        error raised here; written here where the helper ended without it)."""
        self._kml()
        if not self.answers:  # the pixels' answer (the figure was drawn whole: not read by draw)
            self._answer()
        res = self._answer()
        if res is None:
            gj = _maps(*self.job[1:4], self.job[4], kml=False)
        else:
            gj = checked_answer(res)[1]
        return {"kml": self.kml, "geojson": gj}

    def end(self) -> None:
        """Close the pipes (a helper still waiting for its job ends) and reap the helper."""
        if self.job_w is not None:
            os.close(self.job_w)
            self.job_w = None
        self.ans.close()
        try:
            os.waitpid(self.pid, 0)
        except ChildProcessError:
            pass


def _help(job_r: int, ans_w: int, skeleton, names: list, shm) -> None:
    """The helper's work: read the job, build the figure as ``write_overview`` does, draw the panels
    ``names``, copy their box of painted pixels into ``shm`` and answer (box, figure key), or None where
    the figure is not the skeleton's (other panels than expected) or drawing failed (the child draws it
    whole and reports the error); then, where the job asks for the maps, write the GeoJSON and answer its
    path (or the error)."""
    with os.fdopen(job_r, "rb") as f:
        data = f.read()
    if not data:
        return
    job = pickle.loads(data)
    _, out_dir, traj, gnss, summary, records, _, maps = job
    with os.fdopen(ans_w, "wb") as f:
        f.write(frame(_pixels(traj, gnss, summary, records, skeleton, names, shm)))
        f.flush()
        if maps:
            try:
                res = ("ok", _maps(out_dir, traj, gnss, summary, kml=False))
            except BaseException as e:  # noqa: BLE001  (raised in the child, then in the parent)
                res = error_answer(e)
            f.write(frame(res))


def _pixels(traj, gnss, summary, records, skeleton, names: list, shm):
    """The helper's half of the figure in ``shm``: (painted box, figure key), or None (module doc)."""
    try:
        import numpy as np  # lazy: loaded with matplotlib (the child's)

        from aidnav.report.overview import (  # lazy: matplotlib (loaded by the child's warm-up)
            draw_panels,
            figure_key,
            overview_figure,
            painted_box,
        )

        fig = overview_figure(traj, gnss, summary, records, skeleton=skeleton)  # as write_overview builds it
        if fig is not skeleton.fig:
            return None
        key = figure_key(fig)
        px = draw_panels(fig, [skeleton.axes[n] for n in names], title=False)
        box = painted_box(px)
        if box is not None:
            r0, r1, c0, c1 = box
            np.frombuffer(shm, np.uint32).reshape(px.shape)[r0:r1, c0:c1] = px[r0:r1, c0:c1]
        return box, key
    except Exception:  # noqa: BLE001  (the child draws the figure whole, and meets the error there)
        return None
