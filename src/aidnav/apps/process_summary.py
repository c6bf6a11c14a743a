"""What ``aidnav process`` reports of a run: the summary dict (``summary.json``: counts, NIS, outage
scores, calibration, NIS windows, re-initialisations) and its text (``summary.txt``)."""

from __future__ import annotations

import numpy as np


def run_summary(res, n_imu, rate_hz, gnss, withheld, wins, events, warnings, t_filt) -> dict:
    """The summary of a loose-filter run (before the outage scores and the calibration)."""
    rec = res.records
    pos_ok = rec["pos_status"] == 1
    return {
        "smoothed": res.smoothed,
        "time_scale": "input (GPS seconds of week for GNSS-timed logs)",
        "imu_samples": n_imu, "imu_rate_hz": rate_hz, "gnss_fixes": len(gnss),
        "gnss_withheld": int(withheld.sum()),
        "gnss_position_accepted": int(pos_ok.sum()),
        "gnss_position_rejected": int((rec["pos_status"] == 0).sum()),
        "gnss_velocity_accepted": int((rec["vel_status"] == 1).sum()),
        "gnss_velocity_rejected": int((rec["vel_status"] == 0).sum()),
        "rejected_fix_times": [float(t) for t in gnss.time[rec["pos_status"] == 0]][:100],
        "counts": res.counts,
        "nis": nis_summary(rec),
        "outage_windows": [[a, b] for a, b in wins],
        # which GNSS error model the run used and why (white or Gauss-Markov states: filters.gnss_errors,
        # filters.preprocess.correlated_gnss_errors; None when the configuration stated it)
        "gnss_error_model": next((e for e in events if e.startswith(("GNSS error model", "GNSS at "))), None),
        # the fixes' stated σ as measured by the first pass and the factor applied (filters.gnss_errors;
        # None when the configuration stated gnss.pos_std_scale or no first pass ran)
        "gnss_sigma": next((e for e in events if e.startswith("GNSS sigma")), None),
        "events": events,
        "warnings": warnings,
        "timing_s": {"filter": t_filt},
    }


def finish_summary(summary, res, applied_offset, warnings) -> None:
    """Calibration and NIS health into the summary (in place)."""
    from aidnav.filters.result import nis_health, summary_calibration  # lazy: pulls in numba

    # sensor errors (biases, scale factors) and the self-calibration (time offset added to the IMU
    # stamps, lever arm, mounting, odometer scale) with σ, under the names of docs/conventions.md
    summary["calibration"] = summary_calibration(res, {"time_offset_s": applied_offset})
    health = nis_health(res)  # windows where the innovations say σ is wrong, and which way
    summary["nis_windows_far_out"] = health.get("windows", [])
    summary["reinitialisations"] = reinitialisations(res)
    warnings += health.get("warnings", [])


def reinitialisations(res) -> list[dict]:
    """The filter's re-initialisations (engine policy: consecutive rejections or an NIS window far out of
    its chi-square band): time, model, why, the NIS of the innovation that triggered it."""
    from aidnav.filters.run_log import REINIT_WHY  # lazy: pulls in numba

    log = getattr(res, "innovations", None) or {}
    if "reinit" not in log:
        return []
    return [{"time": float(log["t"][k]), "model": str(log["model_name"][k]),
             "why": REINIT_WHY[int(log["reinit"][k])], "nis": float(log["nis"][k])}
            for k in np.flatnonzero(log["reinit"] > 0)]


def nis_summary(rec: dict) -> dict:
    """Mean NIS per measurement type over accepted updates, with its degrees of freedom and the
    two-sided 95 % band of the mean of N χ²(dof) draws (normal approximation, 2·dof/N variance)."""
    out = {}
    for name, st, nis, dof in (("gnss_position", "pos_status", "pos_nis", 3),
                               ("gnss_velocity", "vel_status", "vel_nis", None)):
        if st not in rec or nis not in rec:
            continue
        ok = (rec[st] == 1) & np.isfinite(rec[nis])
        n = int(ok.sum())
        if n == 0:
            continue
        if dof is None:  # velocity fixes may lack components: dof from the recorded innovations
            inn = rec.get("vel_innov")
            d = (np.isfinite(inn[ok]).sum(axis=1).astype(float) if inn is not None
                 else np.full(n, 3.0))
        else:
            d = np.full(n, float(dof))
        mean_dof = float(d.mean())
        half = 1.96 * np.sqrt(2.0 * mean_dof / n)
        m = float(rec[nis][ok].mean())
        out[name] = {"mean": m, "dof": mean_dof, "n": n,
                     "band95": [mean_dof - half, mean_dof + half],
                     "in_band": bool(mean_dof - half <= m <= mean_dof + half)}
    return out


#: the self-calibration quantities the text summary prints (all of them are in summary.json)
CALIBRATION_SHOWN = ("time_offset_s", "lever_arm_m", "mounting_rph_deg", "odometer_scale",
                     "gnss_velocity_delay_s")


def _fmt_val(v) -> str:
    if v is None:
        return "n/a"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(f"{x:.4g}" for x in v) + "]"
    return f"{v:.4g}"


def format_summary(s: dict) -> str:
    """Human-readable summary text."""
    lines = [f"aidnav process: {s['imu']} + {s['gnss']}",
             f"output: {s['output']} (smoothed: {s['smoothed']})",
             f"IMU samples {s['imu_samples']} at {s['imu_rate_hz']:.1f} Hz; GNSS fixes {s['gnss_fixes']}, "
             f"withheld {s['gnss_withheld']}",
             f"GNSS position accepted {s['gnss_position_accepted']}, rejected {s['gnss_position_rejected']}; "
             f"velocity accepted {s['gnss_velocity_accepted']}, rejected {s['gnss_velocity_rejected']}",
             f"counts: {s['counts']}"]
    for name, v in s.get("calibration", {}).items():
        if isinstance(v, dict) and v.get("estimated") and name in CALIBRATION_SHOWN:
            lines.append(f"calibration {name}: {_fmt_val(v['value'])} ± {_fmt_val(v['std'])} (1σ, estimated)")
    for name, v in s.get("nis", {}).items():
        lo, hi = v["band95"]
        lines.append(f"NIS {name}: mean {v['mean']:.2f} over {v['n']} updates (dof {v['dof']:.2f}, 95 % band "
                     f"{lo:.2f}…{hi:.2f}: {'in band' if v['in_band'] else 'OUT OF BAND'})")
    for key, title in (("outage_score", "outage score"), ("outage_score_forward", "outage score (forward)")):
        if key in s:
            o = s[key]
            if o.get("end_error_median_m") is not None:
                lines.append(f"{title}: {o['n_outages']} outages, end-of-outage horizontal error median "
                             f"{o['end_error_median_m']:.2f} m, p95 {o['end_error_p95_m']:.2f} m, max "
                             f"{o['end_error_max_m']:.2f} m; RMS over {o['n_scored']} withheld fixes "
                             f"{o['rms_m']:.3f} m"
                             + (f"; scored on {o['reference']}" if o.get("reference") else ""))
    lines += [f"warning: {w}" for w in s.get("warnings", [])]
    lines += [f"event: {e}" for e in s["events"]] + [f"note: {n}" for n in s["notes"]]
    return "\n".join(lines) + "\n"
