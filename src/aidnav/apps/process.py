"""``aidnav process``: read IMU + GNSS logs, run the loosely coupled filter (and smoother), score
simulated outages, write the trajectory, a summary and the figures into one output directory.

Times stay on the input's scale (GPS seconds of week for GNSS-timed logs). Outages are given in
seconds after the first GNSS epoch: ``START:LENGTH[:PERIOD]``; with a period they repeat while the
whole outage fits before the last GNSS epoch. Withheld fixes are kept aside and scored (horizontal
error of the output, interpolated to each withheld epoch, against the withheld fix; fixes with
quality Q = 1 only when the file has a quality column).

Conversions (datum offset, IMU time offset) happen once, here at the boundary through
:mod:`aidnav.io`; the filter receives ellipsoidal heights and IMU stamps on the GNSS time scale.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field

import numpy as np

from aidnav.apps import common
from aidnav.apps.common import ConfigError, check_solution, load_model, prepare_out_dir
from aidnav.apps.process_parts import (
    finish_summary,
    outage_windows,
    parse_outage,
    run_summary,
    score_outages,
)
from aidnav.data import GnssData, ImuData
from aidnav.errors import InputError
from aidnav.filters.config import LooseConfig
from aidnav.filters.wheeled import no_option_constraint
from aidnav.io.errors import DataError

__all__ = ["ConfigError", "load_config", "process", "process_logs", "format_summary", "parse_outage",
           "outage_windows", "score_outages", "read_imu_any", "read_gnss_any", "ProcessRun"]


def load_config(path) -> LooseConfig:
    """Read a YAML configuration of the loosely coupled filter (unknown keys are errors)."""
    return load_model(path, LooseConfig)


def read_imu_any(path, topic: str | None = None) -> ImuData:
    """IMU log of any known format (:func:`aidnav.io.formats.read_imu`; topic: of a ROS bag)."""
    from aidnav.io.formats import read_imu

    return read_imu(path, topic=topic)


def read_gnss_any(path, height_offset_m: float = 0.0, topic: str | None = None,
                  vel_topic: str | None = None) -> GnssData:
    """GNSS fixes of any known format, the datum offset added once where the file does not declare
    ellipsoidal heights (:func:`aidnav.io.formats.read_gnss`; topic, vel_topic: of a ROS bag)."""
    from aidnav.io.formats import read_gnss

    return read_gnss(path, height_offset_m=height_offset_m, topic=topic, vel_topic=vel_topic)


@dataclass
class ProcessRun:
    """What :func:`process` returns: the trajectory, the summary and the filter result."""

    trajectory: object
    summary: dict
    result: object = None
    forward_trajectory: object = None
    withheld: np.ndarray | None = None
    windows: list = field(default_factory=list)
    gnss: GnssData | None = None  # the fixes the filter saw (after --start/--end): records line up


def window(imu: ImuData, gnss: GnssData, start_s: float | None, end_s: float | None):
    """Cut both logs to ``[start, end]`` seconds after the first IMU sample (``--start/--end``)."""
    if start_s is None and end_s is None:
        return imu, gnss
    t0 = float(imu.time[0])
    a = t0 + (start_s or 0.0)
    b = t0 + end_s if end_s is not None else float(imu.time[-1])
    if b <= a:
        raise InputError(f"--start/--end: empty window ({start_s} … {end_s} s after the first IMU sample)")
    if a >= imu.time[-1]:
        raise InputError(f"--start {start_s}: after the end of the IMU log ({imu.time[-1] - t0:.1f} s long)")
    m = (imu.time >= a) & (imu.time <= b)
    k = int(np.flatnonzero(m)[0])
    t_prev = float(imu.time[k - 1]) if k > 0 else imu.t0
    imu2 = ImuData(imu.time[m], imu.dtheta[m], imu.dv[m], t0=t_prev, events=list(imu.events))
    gnss2 = gnss.subset((gnss.time >= a) & (gnss.time <= b))
    gnss2.events = list(gnss.events) + [f"processing window {a:.3f} … {b:.3f} s"]
    return imu2, gnss2


def process(imu: ImuData, gnss: GnssData, cfg: LooseConfig | None = None, smooth: bool = False,
            outages: list[str] | None = None, imu_name: str = "imu", gnss_name: str = "gnss",
            skip_checks=(), start_s: float | None = None, end_s: float | None = None,
            aids=()) -> ProcessRun:
    """In-memory ``aidnav process``: logs already read (:mod:`aidnav.io`: ellipsoidal heights, IMU on
    the GNSS time scale, i.e. ``cfg.imu.time_offset_s`` is applied here, once) → :class:`ProcessRun`.
    aids : sequence of :class:`aidnav.filters.aids.Aid` (odometer, barometer, magnetometer, ...).
    """
    from aidnav.filters.loose import LooseResult, run_loose, to_trajectory
    from aidnav.io.sanity import check_gnss, check_imu, check_motion, check_overlap

    cfg = cfg or LooseConfig()
    warnings: list[str] = []
    applied_offset = float(cfg.imu.time_offset_s)  # configured; the filter may refine it (calibration)
    if cfg.imu.time_offset_s:
        from aidnav.io.boundary import shift_imu_time

        imu = shift_imu_time(imu, cfg.imu.time_offset_s)
        cfg = cfg.model_copy(update={"imu": cfg.imu.model_copy(update={"time_offset_s": 0.0})})
    imu, gnss = window(imu, gnss, start_s, end_s)
    warnings += check_imu(imu, imu_name, skip_checks)
    warnings += check_gnss(gnss, gnss_name, skip_checks)
    warnings += check_overlap(imu, gnss, imu_name, gnss_name, skip_checks)
    warnings += check_motion(imu, gnss, imu_name, gnss_name, skip_checks)  # units, axes, time from physics
    wins = outage_windows([parse_outage(o) for o in (outages or [])], gnss.time[0], gnss.time[-1])
    withheld = np.zeros(len(gnss), bool)
    for a, b in wins:
        withheld |= (gnss.time >= a) & (gnss.time < b)
    events: list[str] = []
    t0 = _time.perf_counter()
    decided: list[str] = []  # no option: the NHC decided from a first pass (filters.wheeled)
    first: list[str] = []
    cfg, res = no_option_constraint(imu, gnss, cfg, withheld, decided, aids, first_events=first)
    if res is not None and not smooth:  # the first pass is the run (nothing changed)
        events += first
    else:
        res = run_loose(imu, gnss, cfg, withheld=withheld, smooth=smooth, events=events, aids=aids)
    events += decided
    t_filt = _time.perf_counter() - t0
    traj = to_trajectory(res)
    check_solution(traj, "the loosely coupled filter")
    summary = run_summary(res, len(imu), imu.rate_hz, gnss, withheld, wins, imu.events + gnss.events + events,
                          warnings, t_filt)
    fwd = None
    if wins:
        summary["outage_score"] = score_outages(traj, gnss, wins, withheld)
        if res.smoothed and res.forward_state is not None:
            fwd = to_trajectory(LooseResult(res.time, res.forward_state, res.bias, res.forward_pdiag,
                                            res.node_time))
            summary["outage_score_forward"] = score_outages(fwd, gnss, wins, withheld)
    finish_summary(summary, res, applied_offset, warnings)
    return ProcessRun(traj, summary, res, fwd, withheld, wins, gnss=gnss)


def process_logs(imu_path, gnss_path, config_path=None, out_dir="out", smooth=False,
                 outages: list[str] | None = None, console=None, fmt: str = "parquet",
                 height_offset_m: float | None = None, time_offset_s: float | None = None,
                 start_s: float | None = None, end_s: float | None = None, skip_checks=(),
                 progress=None, figures: bool = True, aid_paths=(),
                 kfgins_nav: bool = False, output_rate_hz: float | None = None,
                 vehicle: str | None = None, timings: bool = True, imu_topic: str | None = None,
                 gnss_topic: str | None = None, gnss_vel_topic: str | None = None) -> dict:
    """Run the whole ``aidnav process`` job into the directory ``out_dir``; returns the summary dict
    (also written as ``summary.json`` and ``summary.txt`` beside ``trajectory.<fmt>``).

    height_offset_m / time_offset_s override ``gnss.height_offset_m`` / ``imu.time_offset_s`` of the
    configuration (``--height-offset``, ``--time-offset``). progress : an
    :class:`aidnav.progress.ProgressBar` (stages: reading, filter, writing, figures). figures : also write
    ``overview.png``, ``trajectory.kml``, ``trajectory.geojson`` and ``run.html`` (drawn by a child forked
    now where possible: :mod:`aidnav.apps.run_outputs`; or an :class:`~aidnav.apps.run_outputs.OutputsProcess`
    forked by the caller). kfgins_nav : also write
    ``trajectory.nav`` in KF-GINS's navigation-result format. timings : the stages' wall times in the
    summary (``timing_s``); without them the outputs depend on the inputs only (``aidnav fleet``).
    aid_paths : (name, path) of each aid file (``--aid NAME=FILE``; names of
    :data:`aidnav.filters.aids.AIDS`), read by its aid's reader with the settings of its configuration
    section; the summary names each aid's file under the aid's name. imu_topic, gnss_topic,
    gnss_vel_topic : the topics of ROS bags (``--imu-topic``, ``--gnss-topic``, ``--gnss-vel-topic``)."""
    from aidnav.apps.run_outputs import start_outputs, write_outputs  # lazy: the figures' fork
    from aidnav.io.interchange import write_trajectory
    from aidnav.io.sanity import validate_skip
    from aidnav.progress import NullProgress

    figures = start_outputs(figures)  # forked now where possible: matplotlib loads beside the filter
    t_start = _time.perf_counter()
    skip_checks = validate_skip(skip_checks)
    out_dir = prepare_out_dir(out_dir)
    traj_path = common.trajectory_path(out_dir, fmt)
    notes: list[str] = []
    if config_path is None:
        cfg = LooseConfig()
        notes.append("no --config: what a cautious engineer assumes of an unknown vehicle: a consumer MEMS "
                     "IMU (ARW 0.3 deg/sqrt(h), VRW 0.1 m/s/sqrt(h), raised to what the log's static samples "
                     "show; gyro bias 100 deg/h, accel bias 5 mg), lever arm, time offset and GNSS velocity "
                     "delay estimated, automatic alignment (static roll/pitch, heading from GNSS course), "
                     "ZUPT on, NHC only where the log shows a wheeled vehicle (velocity along one body "
                     "axis in a first pass without it; then sigma 0.1 m/s with NIS-window "
                     "re-initialisation), correlated GNSS errors above 1 Hz (code fixes), IMU gaps bounded "
                     "by 100 m/s, 20 m/s^2, 180 deg/s")
    else:
        cfg = load_config(config_path)
    if vehicle is not None:  # the preset under the configuration: keys the YAML states win
        from aidnav.filters.presets import apply_preset

        cfg = apply_preset(cfg, vehicle)
        notes.append(f"--vehicle {vehicle}: constraints and noise of the {vehicle} preset under the "
                     "configuration")
    for opt, v in (("--height-offset", height_offset_m), ("--time-offset", time_offset_s),
                   ("--start", start_s), ("--end", end_s)):
        if v is not None and not np.isfinite(v):
            raise InputError(f"{opt} {v}: not a finite number")
    if output_rate_hz is not None:
        if not output_rate_hz > 0:
            raise InputError(f"--output-rate {output_rate_hz}: expected a rate > 0 Hz")
        filt = cfg.filter.model_copy(update={"output_rate_hz": output_rate_hz})
        cfg = cfg.model_copy(update={"filter": filt})
    if height_offset_m is not None:
        gnss_cfg = cfg.gnss.model_copy(update={"height_offset_m": height_offset_m})
        cfg = cfg.model_copy(update={"gnss": gnss_cfg})
    if time_offset_s is not None:
        cfg = cfg.model_copy(update={"imu": cfg.imu.model_copy(update={"time_offset_s": time_offset_s})})
    bar = progress if progress is not None else NullProgress()
    datum = cfg.gnss.height_offset_m
    bar.stage("reading", total=2, unit="files")
    gnss = read_gnss_any(gnss_path, height_offset_m=datum, topic=gnss_topic, vel_topic=gnss_vel_topic)
    datum, height_datum = gnss.height_offset_m, gnss.height_datum  # the offset the reader applied
    if imu_topic is not None:
        from aidnav.io.formats import detect_imu_format  # lazy: only with --imu-topic

        if detect_imu_format(imu_path) != "rosbag":
            raise InputError(f"--imu-topic {imu_topic}: {imu_path} is not a ROS bag (topics are for bags)")
    bar.advance(1)
    # the offset is applied by the reader; the filter must not see it again
    cfg = cfg.model_copy(update={"gnss": cfg.gnss.model_copy(update={"height_offset_m": 0.0})})
    if len(gnss) < 1:
        raise DataError(gnss_path, None, "no GNSS fixes")
    from aidnav.filters.aids import AIDS, read_aid  # lazy: the filters load with the job

    aids = [read_aid(name, path, cfg) for name, path in aid_paths]  # times on the GNSS time scale
    from aidnav.apps.process_stream import stream_process, streamable

    if not kfgins_nav and streamable(imu_path, cfg, aids, start_s, end_s):
        # chunk by chunk: memory independent of the log length; figures from a decimated copy
        bar.advance(1)
        t_read = _time.perf_counter()
        n_rows = _parquet_rows(imu_path)
        bar.stage("filter + writing" + (" + smoother" if smooth else ""), total=n_rows, unit="IMU samples")
        run_s, fig_traj, result = stream_process(
            imu_path, gnss, cfg, traj_path, gnss.week, smooth=smooth, outages=outages, imu_name=str(imu_path),
            gnss_name=str(gnss_path), skip_checks=skip_checks, aids=aids, progress=bar.advance)
        t_filt = t_write = _time.perf_counter()
    else:
        imu = read_imu_any(imu_path, topic=imu_topic)
        bar.advance(1)
        if len(imu) < 2:
            raise DataError(imu_path, None, "fewer than 2 IMU samples")
        t_read = _time.perf_counter()
        bar.stage("filter" + (" + smoother" if smooth else ""), total=len(imu), unit="IMU samples")
        run = process(imu, gnss, cfg, smooth=smooth, outages=outages, imu_name=str(imu_path),
                      gnss_name=str(gnss_path), skip_checks=skip_checks, start_s=start_s, end_s=end_s,
                      aids=aids)
        bar.update(len(imu))
        del imu
        t_filt = _time.perf_counter()
        bar.stage("writing the trajectory", total=1, unit="files")
        write_trajectory(run.trajectory, traj_path, week=gnss.week)
        if kfgins_nav:  # KF-GINS navigation text (week, SOW, lat, lon, h, vN, vE, vD, roll, pitch, yaw)
            write_trajectory(run.trajectory, out_dir / "trajectory.nav", week=gnss.week)
        bar.advance(1)
        t_write = _time.perf_counter()
        run_s, fig_traj, result, gnss = run.summary, run.trajectory, run.result, run.gnss
    summary = {"imu": str(imu_path), "gnss": str(gnss_path),
               **{name: next((a.source for a in aids if a.name == name), None) for name in AIDS},
               "config": str(config_path) if config_path else None, "output": str(traj_path),
               "gnss_height_offset_m": datum, "gnss_height_datum": height_datum,
               **run_s, "notes": notes}
    summary["timing_s"] = {"read": t_read - t_start, "filter": t_filt - t_read, "write": t_write - t_filt}
    if not timings:
        del summary["timing_s"]
    if figures:  # overview.png, trajectory.kml / .geojson, run.html
        write_outputs(figures, out_dir, fig_traj, gnss, summary, result.records, progress=bar)
    common.write_summary_files(out_dir, summary, format_summary(summary))  # last: "status": "complete"
    return summary


def _parquet_rows(path) -> int:
    import pyarrow.parquet as pq

    with pq.ParquetFile(path) as pf:
        return pf.metadata.num_rows


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
