"""Compatibility facade of :mod:`aidnav.analysis.noise_fit` (the IMU noise characterisation, split there
into focused modules). Import from :mod:`aidnav.analysis.noise_fit` in new code; the file job with its
figure is :func:`aidnav.apps.characterise.characterise_file`.
"""

from __future__ import annotations

from aidnav.analysis.noise_fit import *  # noqa: F403
from aidnav.analysis.noise_fit import __all__ as _all

__all__ = list(_all)
