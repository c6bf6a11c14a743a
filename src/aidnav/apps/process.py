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

import os
import time as _time

import numpy as np

from aidnav.apps import common
from aidnav.apps.common import ConfigError, load_model, prepare_out_dir
from aidnav.apps.outages import outage_windows, parse_outage, score_outages
from aidnav.apps.process_input import ImuLog, open_imu
from aidnav.apps.process_stream import ROW_GROUP_ROWS, ProcessRun, run_process
from aidnav.apps.process_summary import format_summary
from aidnav.data import GnssData, ImuData
from aidnav.errors import InputError
from aidnav.filters.config import LooseConfig
from aidnav.io.errors import DataError

__all__ = ["ConfigError", "load_config", "process", "process_logs", "format_summary", "parse_outage",
           "outage_windows", "score_outages", "read_imu_any", "read_gnss_any", "ProcessRun"]


def load_config(path) -> LooseConfig:
    """Read a YAML configuration of the loosely coupled filter (unknown keys are errors)."""
    return load_model(path, LooseConfig)


def read_imu_any(path, topic: str | None = None) -> ImuData:
    """IMU log of any known format (:func:`aidnav.io.formats.read_imu`; topic: of a ROS bag)."""
    from aidnav.io.formats import read_imu  # lazy: pulls in numba

    return read_imu(path, topic=topic)


def read_gnss_any(path, height_offset_m: float = 0.0, topic: str | None = None,
                  vel_topic: str | None = None) -> GnssData:
    """GNSS fixes of any known format, the datum offset added once where the file does not declare
    ellipsoidal heights (:func:`aidnav.io.formats.read_gnss`; topic, vel_topic: of a ROS bag)."""
    from aidnav.io.formats import read_gnss  # lazy: pulls in numba

    return read_gnss(path, height_offset_m=height_offset_m, topic=topic, vel_topic=vel_topic)


def process(imu: ImuData, gnss: GnssData, cfg: LooseConfig | None = None, smooth: bool = False,
            outages: list[str] | None = None, imu_name: str = "imu", gnss_name: str = "gnss",
            skip_checks=(), start_s: float | None = None, end_s: float | None = None,
            aids=()) -> ProcessRun:
    """``aidnav process`` on logs already read (:mod:`aidnav.io`: ellipsoidal heights; ``cfg.imu.
    time_offset_s`` is added to the IMU stamps here, once): the job's one run
    (:func:`aidnav.apps.process_stream.run_process`) with the log as one chunk, every epoch kept →
    :class:`ProcessRun` (``trajectory``, ``forward_trajectory`` when smoothed, ``result`` with every
    epoch). aids : sequence of :class:`aidnav.filters.aids.Aid` (odometer, barometer, magnetometer, ...).
    """
    return run_process(ImuLog.of(imu), gnss, cfg or LooseConfig(), smooth=smooth, outages=outages,
                       imu_name=imu_name, gnss_name=gnss_name, skip_checks=skip_checks, start_s=start_s,
                       end_s=end_s, aids=aids, keep=True)


def process_logs(imu_path, gnss_path, config_path=None, out_dir="out", smooth=False,
                 outages: list[str] | None = None, console=None, fmt: str = "parquet",
                 height_offset_m: float | None = None, time_offset_s: float | None = None,
                 start_s: float | None = None, end_s: float | None = None, skip_checks=(),
                 progress=None, figures: bool = True, aid_paths=(),
                 kfgins_nav: bool = False, output_rate_hz: float | None = None,
                 vehicle: str | None = None, timings: bool = True, imu_topic: str | None = None,
                 gnss_topic: str | None = None, gnss_vel_topic: str | None = None, started=None,
                 waiting=None) -> dict:
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
    gnss_vel_topic : the topics of ROS bags (``--imu-topic``, ``--gnss-topic``, ``--gnss-vel-topic``).
    started : called once when the filter's run starts (:func:`aidnav.apps.process_stream.run_process`:
    after the reading, the checks and the first passes); the ``aidnav`` command switches its garbage
    collector back on there (:func:`aidnav.console_script.resume_collections`). waiting : called while the
    figures' child draws (:func:`aidnav.apps.run_outputs.write_outputs`); the command makes the console it
    prints the summary with there (rich's import, ≈ 25 ms, off the path). console : not used (kept for
    callers that pass one)."""
    from aidnav.apps.run_outputs import (  # lazy: the figures' fork
        SKELETON_MIN_CPUS,
        OutputsProcess,
        expected_panels,
        start_outputs,
        write_outputs,
    )
    from aidnav.filters.aids import AIDS, read_aid  # lazy: the filters load with the job
    from aidnav.io.sanity import validate_skip  # lazy: with the job
    from aidnav.progress import NullProgress  # lazy: rich

    figures = start_outputs(figures)  # forked now where possible: matplotlib loads beside the filter
    t_start = _time.perf_counter()
    skip_checks = validate_skip(skip_checks)
    out_dir = prepare_out_dir(out_dir)
    traj_path = common.trajectory_path(out_dir, fmt)
    cfg, notes = job_config(config_path, vehicle, height_offset_m, time_offset_s, start_s, end_s,
                            output_rate_hz)
    bar = progress if progress is not None else NullProgress()
    bar.stage("reading", total=2, unit="files")
    gnss = read_gnss_any(gnss_path, height_offset_m=cfg.gnss.height_offset_m, topic=gnss_topic,
                         vel_topic=gnss_vel_topic)
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
    if isinstance(figures, OutputsProcess) and (os.cpu_count() or 1) >= SKELETON_MIN_CPUS:
        # the child builds the overview's skeleton while this filters, where a core is free for it
        figures.expect(expected_panels(cfg.gnss.use, gnss.vel is not None))
    aids = [read_aid(name, path, cfg) for name, path in aid_paths]  # times on the GNSS time scale
    log = open_imu(imu_path, topic=imu_topic)  # Parquet in batches; any other format read whole
    bar.advance(1)
    t_read = _time.perf_counter()
    bar.stage("filter + writing" + (" + smoother" if smooth else ""), total=log.rows, unit="IMU samples")
    out = _Writers(traj_path, out_dir / "trajectory.nav" if kfgins_nav else None, gnss.week)
    try:
        run = run_process(log, gnss, cfg, smooth=smooth, outages=outages, imu_name=str(imu_path),
                          gnss_name=str(gnss_path), skip_checks=skip_checks, start_s=start_s, end_s=end_s,
                          aids=aids, write=out.write, progress=bar.advance, spool_dir=out_dir,
                          started=started)
        summary = {"imu": str(imu_path), "gnss": str(gnss_path),
                   **{name: next((a.source for a in aids if a.name == name), None) for name in AIDS},
                   "config": str(config_path) if config_path else None, "output": str(traj_path),
                   "gnss_height_offset_m": datum, "gnss_height_datum": height_datum,
                   **run.summary, "notes": notes}
        if isinstance(figures, OutputsProcess):  # the overview drawn while the trajectory file is closed;
            # the page (which shows the timings) waits for the summary's last values (write_outputs)
            figures.send(out_dir, run.decimated, run.gnss, summary, run.result.records, page_follows=True)
        out.close()
    except BaseException:
        out.abort()
        if isinstance(figures, OutputsProcess):
            figures.close()
        raise
    t_filt = t_write = _time.perf_counter()
    summary["timing_s"] = {"read": t_read - t_start, "filter": t_filt - t_read, "write": t_write - t_filt}
    if not timings:
        del summary["timing_s"]
    if figures:  # overview.png, trajectory.kml / .geojson, run.html
        write_outputs(figures, out_dir, run.decimated, run.gnss, summary, run.result.records, progress=bar,
                      waiting=waiting)
    common.write_summary_files(out_dir, summary, format_summary(summary))  # last: "status": "complete"
    return summary


#: what ``aidnav process`` assumes without ``--config`` (the note of its summary)
NO_CONFIG_NOTE = (
    "no --config: what a cautious engineer assumes of an unknown vehicle: a consumer MEMS IMU (ARW 0.3 "
    "deg/sqrt(h), VRW 0.1 m/s/sqrt(h), raised to what the log's static samples show; gyro bias 100 deg/h, "
    "accel bias 5 mg), lever arm, time offset and GNSS velocity delay estimated, automatic alignment (static "
    "roll/pitch, heading from GNSS course), ZUPT on, NHC only where the log shows a wheeled vehicle "
    "(velocity along one body axis in a first pass without it; then sigma 0.1 m/s with NIS-window "
    "re-initialisation), correlated GNSS errors above 1 Hz (code fixes), IMU gaps bounded by 100 m/s, "
    "20 m/s^2, 180 deg/s")


def job_config(config_path, vehicle, height_offset_m, time_offset_s, start_s, end_s,
               output_rate_hz) -> tuple[LooseConfig, list[str]]:
    """The configuration of a job from its file (or the defaults), the ``--vehicle`` preset under it and
    the command-line overrides: (configuration, notes for the summary)."""
    notes: list[str] = []
    if config_path is None:
        cfg = LooseConfig()
        notes.append(NO_CONFIG_NOTE)
    else:
        cfg = load_config(config_path)
    if vehicle is not None:  # the preset under the configuration: keys the YAML states win
        from aidnav.filters.presets import apply_preset  # lazy: only with --vehicle

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
    return cfg, notes


class _Writers:
    """The trajectory file (and with ``nav_path`` the KF-GINS ``.nav`` file) written piece by piece."""

    def __init__(self, traj_path, nav_path, week):
        from aidnav.io.kfgins import NavWriter  # lazy: pyarrow, with the writers
        from aidnav.io.stream import TrajectoryWriter  # lazy: pyarrow

        self.w = [TrajectoryWriter(traj_path, week=week, row_group_rows=ROW_GROUP_ROWS)]
        if nav_path is not None:
            self.w.append(NavWriter(nav_path, week=week))

    def write(self, traj) -> None:
        for w in self.w:
            w.write(traj)

    def close(self) -> None:
        for w in self.w:
            w.close()

    def abort(self) -> None:
        for w in self.w:
            w.abort()
