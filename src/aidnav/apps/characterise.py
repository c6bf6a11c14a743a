"""``aidnav characterise``: a static IMU log → Allan deviation → fitted noise terms, written as
DIR/noise.json, DIR/imu.yaml (the filter's ``imu:`` section) and the figure DIR/allan.png."""

from __future__ import annotations

from aidnav.analysis.noise_fit import characterise_file as _characterise_file
from aidnav.analysis.noise_fit import print_characterisation
from aidnav.report.allan_plot import plot_allan

__all__ = ["characterise_file", "print_characterisation"]


def characterise_file(imu_path, out_dir, static: str | None = None, grade: str | None = None,
                      timings: dict | None = None, plot=plot_allan) -> tuple:
    """:func:`aidnav.analysis.noise_fit.characterise_file` with the figure drawn by
    :func:`aidnav.report.allan_plot.plot_allan` (``plot=None``: no figure)."""
    return _characterise_file(imu_path, out_dir, static=static, grade=grade, timings=timings, plot=plot)
