"""Measurement models of the INS error-state filters (numba), one module per family.

Every model has the uniform signature of :mod:`.common` (``m = model(nav, row, par, lay, H, z, R)``)
and an id below; :func:`fill` dispatches on the id (the engine's only coupling to the models: a new
aid is a module function plus one entry in the table here). The explicit-argument core functions
(:func:`gnss_position`, :func:`gnss_velocity`, :func:`zero_velocity`, :func:`nonholonomic`,
:func:`attitude`, :func:`sapv_angles`) stay importable for the kernels not on the engine.

Conventions: state layout of :mod:`aidnav.filters.layout`; z = (value predicted from the INS) −
(measured value) ≈ H δx; position residuals in local metres ENU so that R is in m².
"""

from __future__ import annotations

from aidnav.jit import njit, overload

from ..layout import BA
from .attitude import attitude, attitude_model, velocity_attitude_matching
from .common import MAX_ROWS, Nav
from .gnss import gnss_position, gnss_position_model, gnss_velocity, gnss_velocity_model
from .height import baro_model
from .ranging import pseudorange_model
from .sapv import sapv_angles, sapv_model
from .vehicle import nhc_model, nonholonomic, odometer_model, zaru_model, zero_velocity, zupt_model

# the model table: the index is the model id (the M_* constants), the name is the one in innovation logs
_TABLE = (("gnss_position", gnss_position_model), ("gnss_velocity", gnss_velocity_model),
          ("zupt", zupt_model), ("zaru", zaru_model), ("nhc", nhc_model), ("odometer", odometer_model),
          ("baro", baro_model), ("attitude", attitude_model), ("sapv", sapv_model),
          ("pseudorange", pseudorange_model), ("velocity_attitude", velocity_attitude_matching))
M_GNSS_POS, M_GNSS_VEL, M_ZUPT, M_ZARU, M_NHC, M_ODO, M_BARO, M_ATT, M_SAPV, M_PR, M_VATT = range(len(_TABLE))
N_MODELS = len(_TABLE)
MODEL_NAMES = tuple(name for name, _ in _TABLE)
_MODELS = tuple(model for _, model in _TABLE)


def _fill_from(first, model, args):
    """Call ``_MODELS[model](*args)`` searching from id ``first`` (numba only: see the overload)."""


@overload(_fill_from)
def _fill_from_impl(first, model, args):
    # compiled once per table entry (``first`` a compile-time constant): the same code as a hand-written
    # if-chain over the ids, each call direct (no function pointers)
    from numba import types  # lazy: runs when numba compiles (aidnav.jit: no numba import in the aot mode)

    if not isinstance(first, types.IntegerLiteral):
        return None  # numba retries with the literal
    i = first.literal_value
    if i == N_MODELS:
        return lambda first, model, args: 0
    fn, nxt = _MODELS[i], i + 1

    def impl(first, model, args):
        if model == first:
            return fn(*args)
        return _fill_from(nxt, model, args)

    return impl


@njit(cache=True)
def fill(model, nav, row, par, lay, H, z, R):
    """Fill H, z, R with model ``model`` (an ``M_*`` id); returns the number of rows (0: no update)."""
    return _fill_from(0, model, (nav, row, par, lay, H, z, R))


__all__ = ["gnss_position", "gnss_velocity", "zero_velocity", "nonholonomic", "attitude", "sapv_angles", "BA",
           "Nav", "MAX_ROWS", "fill", "N_MODELS", "MODEL_NAMES", "gnss_position_model", "gnss_velocity_model",
           "zupt_model", "zaru_model", "nhc_model", "odometer_model", "baro_model", "attitude_model",
           "sapv_model", "pseudorange_model", "velocity_attitude_matching"]
