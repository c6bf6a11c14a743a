"""``aidnav characterise``: a static IMU log → Allan deviation → fitted noise terms, written as
DIR/noise.json, DIR/imu.yaml (the filter's ``imu:`` section) and the figure DIR/allan.png.

Speed: the figure module (matplotlib, ~0.3 s of import) is imported in a thread started with the job, so
that it overlaps the reading of the log; the figure is drawn after the analysis, as before."""

from __future__ import annotations

import threading

from aidnav.analysis.noise_fit import characterise_file as _characterise_file
from aidnav.analysis.noise_fit import print_characterisation

__all__ = ["characterise_file", "print_characterisation"]

#: the default of ``plot``: the Allan figure of :mod:`aidnav.report.allan_plot`
FIGURE = "allan.png"


def _import_figure_module() -> None:
    try:
        import aidnav.report.allan_plot  # noqa: F401  matplotlib: ~0.3 s, imported while the log is read
    except Exception:  # noqa: BLE001  (imported again, with its error, when the figure is drawn)
        pass


def _figure_in_background():
    """``plot(ch, path, title)`` that draws :func:`aidnav.report.allan_plot.plot_allan`, its module being
    imported from now on in a thread."""
    loader = threading.Thread(target=_import_figure_module, name="aidnav-figure-import", daemon=True)
    loader.start()

    def plot(ch, path, title):
        loader.join()
        from aidnav.report.allan_plot import plot_allan  # matplotlib: imported by the thread above

        return plot_allan(ch, path, title)

    return plot


def characterise_file(imu_path, out_dir, static: str | None = None, grade: str | None = None,
                      timings: dict | None = None, plot=FIGURE) -> tuple:
    """:func:`aidnav.analysis.noise_fit.characterise_file` with the figure drawn by
    :func:`aidnav.report.allan_plot.plot_allan` (``plot=None``: no figure; a function
    ``plot(ch, path, title) -> path``: that one)."""
    if plot == FIGURE:
        plot = _figure_in_background()
    return _characterise_file(imu_path, out_dir, static=static, grade=grade, timings=timings, plot=plot)
