"""What a loosely coupled run reports from the engine's innovation log: the log as a dict with model
names, the per-GNSS-fix view, update counts, re-initialisation events, and the configured values the
calibration states correct. Shared by the in-memory (:mod:`.loose`), streamed (:mod:`.stream`), tight and
federated drivers."""

from __future__ import annotations

import numpy as np

from . import measurements as ms
from .aids import AIDS

__all__ = ["loose_counts", "reinit_events", "REINIT_WHY"]


def loose_counts(log, n_nodes, static_used, n_imu, k0) -> dict:
    """``FilterResult.counts`` of the loose filter from its innovation log (:func:`log_dict`)."""
    mdl = log["model"]
    cnt = dict(zupt_updates=int((mdl == ms.M_ZUPT).sum()),
               nhc_updates=int(((mdl == ms.M_NHC) & (log["status"] == 1)).sum()),
               nhc_rejected=int(((mdl == ms.M_NHC) & (log["status"] == 0)).sum()),
               nodes=n_nodes, static_samples=static_used, imu_samples_used=n_imu - k0, imu_samples_skipped=k0)
    for md, name in ((k.model, k.name) for k in AIDS.values()):  # the aids': <name>_updates, _rejected
        if np.any(mdl == md):
            cnt[f"{name}_updates"] = int(((mdl == md) & (log["status"] == 1)).sum())
            cnt[f"{name}_rejected"] = int(((mdl == md) & (log["status"] == 0)).sum())
    return cnt


def calibration_base(cfg) -> dict:
    """The configured values the calibration states correct (their estimates are added to these)."""
    return {"time_offset_s": float(cfg.imu.time_offset_s), "lever_arm_m": list(cfg.gnss.lever_arm_m),
            "mounting_rph_deg": list(cfg.imu.mounting_rph_deg), "odometer_scale": 0.0}


def log_dict(log, n_log) -> dict:
    """The engine's innovation log (first ``n_log`` rows) as a dict of arrays, with model names."""
    d = {k: getattr(log, k)[:n_log] for k in log._fields}
    d["model_name"] = np.array(ms.MODEL_NAMES, dtype=object)[np.maximum(d["model"], 0)]
    return d


REINIT_WHY = {1: "consecutive rejections", 2: "NIS window far out of its chi-square band"}


def reinit_events(log) -> list[str]:
    """One event per re-initialisation in the engine's log (:func:`log_dict`): time, model, why."""
    out = []
    for k in np.flatnonzero(log["reinit"] > 0):
        how = ("scaled by the window's mean NIS per dof" if int(log["reinit"][k]) == 2 else
               "inflated to the innovation")
        out.append(f"re-initialisation at t={log['t'][k]:.3f}: {log['model_name'][k]} innovation NIS "
                   f"{log['nis'][k]:.1f} ({REINIT_WHY[int(log['reinit'][k])]}): position/velocity/attitude "
                   f"(and calibration) covariance {how} and the update accepted")
    return out


def gnss_records(log, rmap, m) -> dict:
    """Per-GNSS-fix view of the log: status (1/0/−1), NIS, innovation and diag S (3 components; a
    velocity component that was not measured is NaN)."""
    rec = dict(pos_status=np.full(m, -1, np.int8), vel_status=np.full(m, -1, np.int8),
               pos_reinit=np.zeros(m, np.int8), vel_reinit=np.zeros(m, np.int8))
    for k in ("pos_innov", "pos_s", "vel_innov", "vel_s"):
        rec[k] = np.full((m, 3), np.nan)
    rec["pos_nis"], rec["vel_nis"] = np.full(m, np.nan), np.full(m, np.nan)
    if rmap is None:
        return rec
    mdl, src = rmap
    for md, p in ((ms.M_GNSS_POS, "pos"), (ms.M_GNSS_VEL, "vel")):
        j = np.flatnonzero(mdl == md)
        i = src[j]
        rec[f"{p}_status"][i] = log["status"][j]
        rec[f"{p}_reinit"][i] = log["reinit"][j]
        rec[f"{p}_nis"][i] = log["nis"][j]
        rec[f"{p}_innov"][i] = log["nu"][j, :3]
        rec[f"{p}_s"][i] = log["s"][j, :3]
    return rec
