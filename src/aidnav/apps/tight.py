"""Tightly coupled processing of real logs, the ``aidnav tight`` command: IMU + RINEX observations + RINEX
navigation files → trajectory, summary and figures, and the comparison with a reference solution (RTKLIB
``.pos``, fixed epochs only). The solution itself (SPP start, start heading, the carrier phase, the filter)
is :func:`aidnav.estimators.tight_solution.process_tight`, below the files (re-exported here).
"""

from __future__ import annotations

import os

import numpy as np

from aidnav.apps.common import (
    check_solution,
    load_model,
    prepare_out_dir,
    trajectory_path,
    write_summary_files,
)
from aidnav.apps.process import read_gnss_any, read_imu_any
from aidnav.data import GnssData
from aidnav.estimators.tight_solution import process_tight
from aidnav.filters.tight import TightConfig, apply_vehicle, to_trajectory
from aidnav.io.boundary import shift_imu_time
from aidnav.io.nav_sources import format_sources, read_observations_and_navigation
from aidnav.nav.earth import lla_difference_enu
from aidnav.report.run_page import calibration_estimates

__all__ = ["process_tight", "compare_with_reference", "process_tight_files", "score_against_reference",
           "ubx_nav_setting"]


def compare_with_reference(time, lat, lon, h, ref: GnssData, quality: int | None = 1, max_dt: float = 0.01):
    """Horizontal/vertical differences of a solution (time, lat, lon [rad], h [m]) from a reference at its
    epochs (quality ``quality`` only; interpolated linearly in time). Returns dict with the ENU
    differences (K, 3) and their mean, std and RMS per axis, and the horizontal RMS / 95th percentile."""

    sel = np.ones(len(ref), bool) if quality is None or ref.quality is None else ref.quality == quality
    tr = ref.time[sel]
    inside = (tr >= time[0]) & (tr <= time[-1])
    tr = tr[inside]
    la = np.interp(tr, time, lat)
    lo = np.interp(tr, time, np.unwrap(lon))
    hh = np.interp(tr, time, h)
    e, n, u = lla_difference_enu(
        la, lo, hh, ref.lat[sel][inside], ref.lon[sel][inside], ref.height[sel][inside]
    )
    d = np.column_stack([e, n, u])
    d = d[np.all(np.isfinite(d), axis=1)]
    if len(d) == 0:
        return {"diff_enu": d, "n": 0}
    hz = np.hypot(d[:, 0], d[:, 1])
    return {
        "diff_enu": d,
        "n": len(d),
        "mean": d.mean(0),
        "std": d.std(0),
        "rms": np.sqrt((d**2).mean(0)),
        "horizontal_rms": float(np.sqrt((hz**2).mean())),
        "horizontal_p95": float(np.percentile(hz, 95)),
        "vertical_rms": float(np.sqrt((d[:, 2] ** 2).mean())),
    }


def score_against_reference(traj, ref: GnssData) -> dict:
    """Differences from the reference at **every** reference epoch inside the solution's span, and per
    solution quality (RTKLIB Q: 1 fix, 2 float, 5 single): a subset never hides a divergence."""
    out = {}
    groups = [("all", None)]
    if ref.quality is not None:
        groups += [(f"Q={int(q)}", int(q)) for q in np.unique(ref.quality)]
    for name, q in groups:
        c = compare_with_reference(traj.time, traj.lat, traj.lon, traj.height, ref, quality=q)
        if c["n"] == 0:
            continue
        out[name] = {"epochs": c["n"], "horizontal_rms_m": c["horizontal_rms"],
                     "horizontal_p95_m": c["horizontal_p95"], "vertical_rms_m": c["vertical_rms"],
                     "rms_enu_m": [float(x) for x in c["rms"]], "mean_enu_m": [float(x) for x in c["mean"]]}
    return out


def process_tight_files(imu_path, obs_path, nav_path, config_path=None, out_dir="out", truth=None,
                        truth_height_offset_m: float = 0.0, fmt: str = "parquet",
                        time_offset_s: float | None = None, smooth: bool = False, progress=None,
                        figures: bool = True, vehicle: str | None = None, ubx_nav=None) -> dict:
    """File-level job behind ``aidnav tight``: read IMU + RINEX obs/nav (+ optional reference ``truth``,
    RTKLIB ``.pos`` or interchange, with its own datum offset), run :func:`process_tight`, write
    ``trajectory.<fmt>``, ``summary.json`` and ``summary.txt`` into ``out_dir``. ``ubx_nav``: the UBX log
    whose broadcast ephemerides are added — a path, "auto" or "none" (:mod:`aidnav.io.nav_sources`); None:
    the configuration's ``gnss.ubx_nav`` (default "auto"; a relative path there is the configuration
    file's)."""
    from aidnav.io.interchange import write_trajectory  # lazy: pulls in pyarrow

    out_dir = prepare_out_dir(out_dir)
    traj_path = trajectory_path(out_dir, fmt)
    cfg = TightConfig() if config_path is None else load_model(config_path, TightConfig)
    events: list[str] = []
    cfg = apply_vehicle(cfg, vehicle, events)
    if time_offset_s is not None:
        cfg = cfg.model_copy(update={"imu": cfg.imu.model_copy(update={"time_offset_s": time_offset_s})})
    imu = read_imu_any(imu_path)
    if "time_offset_s" in cfg.imu.model_fields_set:  # a given offset: the stamps shifted here, once
        imu = shift_imu_time(imu, cfg.imu.time_offset_s)
        cfg = cfg.model_copy(update={"imu": cfg.imu.model_copy(update={"time_offset_s": 0.0})})
    # none given: the stamps as they are, and process_tight may estimate it (gnss.time_offset_from_phase)
    obs, eph, rinex_events, sources = read_observations_and_navigation(
        obs_path, nav_path, cfg.gnss.systems, *ubx_nav_setting(cfg, ubx_nav, config_path))
    events += rinex_events
    res, sp = process_tight(imu, obs, eph, cfg, events=events, smooth=smooth)
    traj = to_trajectory(res)
    check_solution(traj, "the tightly coupled filter")
    write_trajectory(traj, traj_path, week=getattr(obs, "ref_week", None))
    summary = {"imu": str(imu_path), "obs": str(obs_path), "nav": str(nav_path), "output": str(traj_path),
               "states": cfg.states, "ins_states": cfg.nins, "filter_states": res.nstate,
               "smoothed": bool(smooth), "vehicle": vehicle,
               "ionosphere": res.iono_model, "ephemerides": sources,
               "systems": sorted({n[0] for n in obs.names}),
               "events": imu.events + events}
    if res.isb_systems:  # inter-system biases at the end (that system's receiver clock − the GPS one)
        summary["inter_system_bias_m"] = {c: {"value": float(res.isb[-1, k]),
                                              "std": float(res.isb_std[-1, k])}
                                          for k, c in enumerate(res.isb_systems)}
    # what changes the solution by metres is said where the user looks: the summary's warnings (issue 38)
    summary["warnings"] = [e.removeprefix("warning: ") for e in summary["events"]
                           if e.startswith("warning:") or _iono_note(e)]
    if truth is not None:
        ref = read_gnss_any(truth, truth_height_offset_m)
        summary["reference"] = {"file": str(truth), "height_offset_m": truth_height_offset_m,
                                **score_against_reference(traj, ref)}

    summary["calibration"] = calibration_estimates(res)
    if figures:
        from aidnav.report.overview import tight_records  # lazy: pulls in matplotlib

        # lazy: pulls in matplotlib
        from aidnav.report.reference_plot import nis_table, write_reference_figure
        from aidnav.report.run_page import write_run_outputs  # lazy: only on this branch

        ok = np.isfinite(sp["lat"])
        spp = GnssData(sp["time"][ok], sp["lat"][ok], sp["lon"][ok], sp["h"][ok])
        records = tight_records(res.epochs)
        # the page: aidnav's own SPP fixes named as such, the NIS table, and with --truth the reference
        # track and the differences from it against time (issue 38)
        page = {**summary, "gnss_label": "SPP fixes (aidnav)", "nis": nis_table(records)}
        extra = []
        if truth is not None:
            fig = write_reference_figure(out_dir / "reference.png", traj, ref, spp, "SPP fixes (aidnav)",
                                         f"reference {os.path.basename(str(truth))}")
            extra.append((fig, "Solution against the reference: tracks and E/N/U differences"))
        write_run_outputs(out_dir, traj, spp, page, records, figures=extra, progress=progress)
    write_summary_files(out_dir, summary, format_tight_summary(summary))  # last: "status": "complete"
    return summary


def ubx_nav_setting(cfg: TightConfig, option, config_path) -> tuple:
    """(setting, base directory) of the UBX log for :func:`aidnav.io.nav_sources.resolve_ubx_nav`: the
    command-line ``option`` (a path relative to the current directory, "auto" or "none") when given, else
    the configuration's ``gnss.ubx_nav`` (a relative path there is the configuration file's)."""
    if option is not None:
        return str(option), None
    return cfg.gnss.ubx_nav, (os.path.dirname(os.path.abspath(config_path)) if config_path else None)


def _iono_note(event: str) -> bool:
    """An event saying the ionosphere is not corrected or corrected with default coefficients."""
    e = f" {event.lower()} "
    return ("ionosph" in e or "klobuchar" in e) and (" no " in e or "default" in e)


def format_tight_summary(s: dict) -> str:
    """Human-readable summary of ``aidnav tight``."""
    lines = [f"aidnav tight: {s['imu']} + {s['obs']} + {s['nav']}", f"output: {s['output']}",
             f"states: {s['states']}" + (f" (INS block {s['ins_states']}, {s['filter_states']} in the filter)"
                                         if "ins_states" in s else "")]
    if s.get("ionosphere"):
        lines.append(f"ionosphere: {s['ionosphere']}")
    if s.get("ephemerides"):
        lines.append(format_sources(s["ephemerides"]))
    ref = s.get("reference")
    if ref:
        for k, v in ref.items():
            if isinstance(v, dict):
                lines.append(f"vs {ref['file']} [{k}]: {v['epochs']} epochs, horizontal RMS "
                             f"{v['horizontal_rms_m']:.3f} m, p95 {v['horizontal_p95_m']:.3f} m, "
                             "vertical RMS "
                             f"{v['vertical_rms_m']:.3f} m")
    lines += [f"warning: {w}" for w in s.get("warnings", [])]
    lines += [f"event: {e}" for e in s["events"]]
    return "\n".join(lines) + "\n"
