"""Engine records of GNSS fixes and SAPV epochs (federated filter), and the per-fix view of the log."""

from __future__ import annotations

import numpy as np

from . import M_GNSS_POS, M_GNSS_VEL, M_SAPV
from .sapv import sapv_input_check, sapv_rows


def gnss_records(g, use_pos: bool, use_vel: bool):
    """Records of the fixes ``g`` (the tuple of :func:`aidnav.filters.preprocess.gnss_arrays`): per fix a
    position, then a velocity record (``use`` False still schedules the node; a velocity without its east
    component is not used). Returns (records fields t, model, data, use; the order of the records in
    [positions, velocities])."""
    g_t, g_lat, g_lon, g_h, g_vel, g_spos, g_svel = g
    m = len(g_t)
    t = np.r_[g_t, g_t].astype(float)
    mdl = np.r_[np.full(m, M_GNSS_POS), np.full(m, M_GNSS_VEL)].astype(np.int64)
    rows = np.r_[np.column_stack([g_lat, g_lon, g_h, g_spos]), np.column_stack([g_vel, g_svel])]
    use = np.r_[np.full(m, use_pos), use_vel & ~np.isnan(g_vel[:, 0])].astype(np.bool_)
    o = np.lexsort((mdl, np.r_[np.arange(m), np.arange(m)], t))
    return (np.ascontiguousarray(t[o]), mdl[o], np.ascontiguousarray(rows[o]), use[o]), o


def sapv_records(sapv, use: bool):
    """Records of :class:`aidnav.sim.sapv.SapvData` (``sapv_model`` rows; None or empty: none) and why each
    epoch cannot be used (:func:`.sapv.sapv_input_check`)."""
    if sapv is None or len(sapv) == 0:
        empty = (np.zeros(0), np.zeros(0, np.int64), np.zeros((0, 7)), np.zeros(0, np.bool_))
        return empty, np.zeros(0, "<U20")
    skip = sapv_input_check(sapv)
    return (np.ascontiguousarray(sapv.time, float), np.full(len(sapv), M_SAPV, np.int64), sapv_rows(sapv),
            (skip == "") & use), skip


def per_fix(log: dict, order: np.ndarray, m: int) -> dict:
    """Log rows of :func:`gnss_records` (the first 2m) back in fix order: {key: (positions, velocities)}."""
    out = {}
    for k, v in log.items():
        a = np.empty_like(v[:2 * m])
        a[order] = v[:2 * m]
        out[k] = (a[:m], a[m:])
    return out
