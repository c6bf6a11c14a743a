"""Compatibility facade of :mod:`aidnav.analysis.noise_fit` (the IMU noise characterisation, split there
into focused modules). Import from :mod:`aidnav.analysis.noise_fit` in new code.

``characterise_file`` here draws allan.png by default, as it always did; the one import of report from
analysis that this needs is below, marked, and goes once the ``characterise`` command passes
``plot=plot_allan`` to :func:`aidnav.analysis.noise_fit.characterise_file` itself.
"""

from __future__ import annotations

import threading

from aidnav.analysis.noise_fit import *  # noqa: F403
from aidnav.analysis.noise_fit import __all__ as _all
from aidnav.analysis.noise_fit import characterise_file as _characterise_file

__all__ = list(_all)


def _plot_allan_fn():
    # TEMPORARY compatibility (the cli's import path): the one import of report from analysis; remove with
    # this facade once the cli passes ``plot``. Inside a function: matplotlib takes ~0.3 s to import
    from aidnav.report.allan_plot import plot_allan

    return plot_allan


def _plot_allan(ch, path, title):
    return _plot_allan_fn()(ch, path, title=title)


def characterise_file(imu_path, out_dir, static: str | None = None, grade: str | None = None,
                      timings: dict | None = None, plot="default") -> tuple:
    """:func:`aidnav.analysis.noise_fit.characterise_file` with allan.png drawn by
    :func:`aidnav.report.allan_plot.plot_allan` unless ``plot`` says otherwise (None: no figure)."""
    if plot == "default":
        threading.Thread(target=_plot_allan_fn, daemon=True).start()  # the import, while the log is read
        plot = _plot_allan
    return _characterise_file(imu_path, out_dir, static=static, grade=grade, timings=timings, plot=plot)
