"""Measurement models of the INS error-state filters (numba), one module per family.

Every model has the uniform signature of :mod:`.common` (``m = model(nav, row, par, lay, H, z, R)``)
and an id below; :func:`fill` dispatches on the id (the engine's only coupling to the models: a new
aid is a module function plus one entry in the table and one branch of :func:`fill` here). The
explicit-argument core functions
(:func:`gnss_position`, :func:`gnss_velocity`, :func:`zero_velocity`, :func:`nonholonomic`,
:func:`attitude`, :func:`sapv_angles`) stay importable for the kernels not on the engine.

Conventions: state layout of :mod:`aidnav.filters.layout`; z = (value predicted from the INS) −
(measured value) ≈ H δx; position residuals in local metres ENU so that R is in m².
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from aidnav.jit import njit

from ..layout import BA
from .attitude import attitude, attitude_model, velocity_attitude_matching
from .common import MAX_ROWS, Nav
from .gnss import gnss_position, gnss_position_model, gnss_velocity, gnss_velocity_model
from .height import baro_model
from .magnetometer import mag_heading_model
from .ranging import pseudorange_model
from .sapv import sapv_angles, sapv_model
from .vehicle import nhc_model, nonholonomic, odometer_model, zaru_model, zero_velocity, zupt_model

# the model table: the index is the model id (the M_* constants), the name is the one in innovation logs
_TABLE = (("gnss_position", gnss_position_model), ("gnss_velocity", gnss_velocity_model),
          ("zupt", zupt_model), ("zaru", zaru_model), ("nhc", nhc_model), ("odometer", odometer_model),
          ("baro", baro_model), ("attitude", attitude_model), ("sapv", sapv_model),
          ("pseudorange", pseudorange_model), ("velocity_attitude", velocity_attitude_matching),
          ("mag_heading", mag_heading_model))
(M_GNSS_POS, M_GNSS_VEL, M_ZUPT, M_ZARU, M_NHC, M_ODO, M_BARO, M_ATT, M_SAPV, M_PR, M_VATT,
 M_MAG) = range(len(_TABLE))
N_MODELS = len(_TABLE)
MODEL_NAMES = tuple(name for name, _ in _TABLE)
MODELS = tuple(model for _, model in _TABLE)


def _sources_key() -> str:
    """Hash of the sources of this package (the models, the table, :func:`fill`): the ``depends`` key of
    every cached kernel that dispatches through :func:`fill` (numba keys a cached kernel on its own source
    file only; :func:`aidnav.jit.keep_cache_current`)."""
    h = hashlib.sha256()
    for p in sorted(Path(__file__).resolve().parent.glob("*.py")):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()[:20]


MODELS_KEY = _sources_key()


@njit(cache=True, depends=MODELS_KEY)
def fill(model, nav, row, par, lay, H, z, R):
    """Fill H, z, R with model ``model`` (an ``M_*`` id); returns the number of rows (0: no update).

    A plain dispatch, one branch per entry of the table above in its order (``tests/filters/
    test_model_dispatch.py`` checks the two agree): the same code under numba and in plain Python
    (``NUMBA_DISABLE_JIT=1``: the engine can be stepped through in a debugger)."""
    if model == M_GNSS_POS:
        return gnss_position_model(nav, row, par, lay, H, z, R)
    if model == M_GNSS_VEL:
        return gnss_velocity_model(nav, row, par, lay, H, z, R)
    if model == M_ZUPT:
        return zupt_model(nav, row, par, lay, H, z, R)
    if model == M_ZARU:
        return zaru_model(nav, row, par, lay, H, z, R)
    if model == M_NHC:
        return nhc_model(nav, row, par, lay, H, z, R)
    if model == M_ODO:
        return odometer_model(nav, row, par, lay, H, z, R)
    if model == M_BARO:
        return baro_model(nav, row, par, lay, H, z, R)
    if model == M_ATT:
        return attitude_model(nav, row, par, lay, H, z, R)
    if model == M_SAPV:
        return sapv_model(nav, row, par, lay, H, z, R)
    if model == M_PR:
        return pseudorange_model(nav, row, par, lay, H, z, R)
    if model == M_VATT:
        return velocity_attitude_matching(nav, row, par, lay, H, z, R)
    if model == M_MAG:
        return mag_heading_model(nav, row, par, lay, H, z, R)
    return 0


__all__ = ["gnss_position", "gnss_velocity", "zero_velocity", "nonholonomic", "attitude", "sapv_angles", "BA",
           "Nav", "MAX_ROWS", "fill", "N_MODELS", "MODEL_NAMES", "gnss_position_model", "gnss_velocity_model",
           "zupt_model", "zaru_model", "nhc_model", "odometer_model", "baro_model", "attitude_model",
           "sapv_model", "pseudorange_model", "velocity_attitude_matching", "mag_heading_model", "MODELS",
           "MODELS_KEY"]
