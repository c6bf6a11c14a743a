"""Command-line interface: thin typer commands over the jobs in :mod:`aidnav.apps`.

One grammar for every command (README "Command grammar"): data inputs are named by their role
(``--imu --gnss --obs --nav --truth``), ``-o DIR`` is always an output directory with fixed file
names inside, the datum and time options are the same everywhere (``--height-offset``,
``--truth-height-offset``, ``--time-offset``), lists are repeated options, and the output is a human
summary (``--json`` prints the machine summary instead). Bad input exits with status 2 and
``error: FILE:LINE: what is wrong — what to do``; status 1 is a bug in aidnav.
"""

from __future__ import annotations

import functools
import os
import sys

# Small matrices: single-threaded BLAS is faster than threaded (must be set before numpy loads).
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")
# numpy asks the kernel for transparent huge pages on large arrays (madvise); where the kernel then
# compacts memory on the page fault (THP defrag "madvise", a common default) a large log's arrays cost
# seconds of system time (characterise on a 10-h log: 2.4 s of system CPU, 1.3 s without). Read by numpy
# when it loads; NUMPY_MADVISE_HUGEPAGE=1 in the environment restores numpy's default.
os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")
# Arrow's memory pool: the default (mimalloc) keeps the pages it freed and glibc's heap fragments on long
# runs. Peak RSS of a streamed `process` (issue 29; static 100-Hz logs): 1 h 287 MiB with mimalloc, 258
# with the system allocator, 258 with jemalloc; 10 h 310, 348, 293 MiB; same CPU time. Read by pyarrow
# when it loads (set here, before: switching pools later costs mimalloc's own reservation, ~5 MiB).
# Linux only: pyarrow's Linux wheels have jemalloc (elsewhere an unknown pool name is a logged warning).
if sys.platform.startswith("linux"):
    os.environ.setdefault("ARROW_DEFAULT_MEMORY_POOL", "jemalloc")

from pathlib import Path  # noqa: E402

from aidnav import interrupts as _interrupts  # noqa: E402
from aidnav.console_script import fewer_collections as _fewer_collections  # noqa: E402
from aidnav.console_script import pause_collections as _pause_collections  # noqa: E402

if Path(sys.argv[0]).name == "aidnav" or sys.argv[0].endswith(os.path.join("aidnav", "__main__.py")):
    _interrupts.install(hold=True)  # the aidnav command: a Ctrl-C during the imports is raised in main
    _fewer_collections()  # the command's imports: fewer garbage collections (console_script.GC_YOUNG_OBJECTS)
    _pause_collections()  # and none until the command runs (console_script.pause_collections)

import typer  # noqa: E402

from aidnav.console_script import exit_status as _exit_status  # noqa: E402
from aidnav.console_script import leave as _leave  # noqa: E402
from aidnav.console_script import preload_scipy_blas as _preload_scipy_blas  # noqa: E402
from aidnav.console_script import resume_collections as _resume_collections  # noqa: E402

# rich_markup_mode=None: help texts are printed as written ("[deg]" would otherwise vanish)
app = typer.Typer(add_completion=False, no_args_is_help=True, rich_markup_mode=None,
                  pretty_exceptions_enable=False,
                  help="aidnav: aided inertial navigation (simulate, process, evaluate).")


@functools.cache
def _console(stderr: bool = False):
    """The rich console of stdout (or stderr), made on first use."""
    from rich.console import Console  # lazy: rich: ~40 ms of import that --help and --version never need

    # markup off: file names and messages with brackets are printed as they are
    return Console(stderr=stderr, markup=False, highlight=False, soft_wrap=True)


#: set once a command has reported an interrupt (main reports one that came before or after the command)
_INTERRUPT_REPORTED = False
#: True in the ``aidnav`` command itself (:func:`main`), False where ``app`` is called in-process (tests)
_CONSOLE_SCRIPT = False
#: the figures' child of ``aidnav process`` forked by :func:`main` before typer parses the command line
#: (:func:`_fork_figures_early`), until ``process`` takes it
_FORKED_FIGURES = None
#: the formats the readers know (aidnav.io.formats IMU_FORMATS / GNSS_FORMATS / TRAJECTORY_FORMATS), written
#: out here so that --help needs no numpy; a test checks they name every format
_IMU_FORMATS_HELP = ("aidnav interchange CSV/Parquet, raw rtklibexplorer CSV + its .tag, KF-GINS IMU text, "
                     "ROS 1/2 bag (sensor_msgs/Imu)")
_GNSS_FORMATS_HELP = ("aidnav interchange CSV/Parquet, RTKLIB .pos, KF-GINS GNSS text, NMEA 0183 "
                      "(GGA + RMC/VTG, GST), u-blox UBX (NAV-PVT), ROS 1/2 bag (sensor_msgs/NavSatFix)")
_TRAJECTORY_FORMATS_HELP = ("aidnav interchange trajectory CSV/Parquet, KF-GINS .nav, or GNSS fixes in any "
                            "GNSS format: " + _GNSS_FORMATS_HELP)


def _fail(msg: str, code: int = 2):
    global _INTERRUPT_REPORTED
    _INTERRUPT_REPORTED = _INTERRUPT_REPORTED or code == 130
    _console(stderr=True).print(f"error: {msg}")
    raise typer.Exit(code)


def _user_errors() -> tuple[type[BaseException], ...]:
    """Exceptions that are the user's to fix: exit 2 with the message, no traceback."""
    import yaml  # lazy: yaml is heavy to import

    errs: list[type[BaseException]] = [ValueError, OSError, yaml.YAMLError, UnicodeDecodeError]
    try:
        from pydantic import ValidationError  # lazy: pydantic is heavy to import

        errs.append(ValidationError)
    except ImportError:  # pragma: no cover - pydantic is a dependency
        pass
    return tuple(errs)


def guarded(fn, collects_from_its_run: bool = False):
    """Every command fails the same way: user errors → exit 2 with ``error: …``; anything else → exit 1
    with ``internal error`` and the traceback only when ``AIDNAV_DEBUG`` is set.

    In the ``aidnav`` command the garbage collector, paused while it starts
    (:func:`aidnav.console_script.pause_collections`), runs again from here, or with
    ``collects_from_its_run`` from where the command's job says its run starts (``process``: its
    ``started`` callback, after its imports, reading, checks and first passes)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        if _CONSOLE_SCRIPT:  # a command runs (not --help): kernels from a build, or numba starts
            _start_kernels()
            if not collects_from_its_run:
                _resume_collections()
        try:
            return fn(*args, **kwargs)
        except (typer.Exit, typer.Abort, SystemExit):
            raise
        except KeyboardInterrupt:  # SIGINT/SIGTERM (aidnav.interrupts): exit 130, said so
            _fail(f"{_interrupts.MESSAGE}; {_interrupted_note(kwargs)}", 130)
        except _user_errors() as e:
            msg = str(e)
            if isinstance(e, OSError) and e.filename is not None and str(e.filename) not in msg:
                msg = f"{e.filename}: {e.strerror}"
            elif isinstance(e, OSError) and e.strerror:
                msg = f"{e.filename}: {e.strerror}" if e.filename else e.strerror
            _fail(msg or type(e).__name__)
        except Exception as e:  # a bug: say so, exit 1
            if os.environ.get("AIDNAV_DEBUG"):
                raise
            _console(stderr=True).print(f"internal error (a bug in aidnav, please report it): "
                                        f"{type(e).__name__}: {e} (set AIDNAV_DEBUG=1 for the traceback)")
            raise typer.Exit(1) from None

    return wrapper


def _interrupted_note(kwargs) -> str:
    """What an interrupted command left: its output directory marked incomplete (issue 37)."""
    out = kwargs.get("out")
    if out is not None:
        from aidnav.io.atomic import run_status  # lazy: loaded when the command runs (--help: typer only)

        if run_status(out) == "complete":  # interrupted after its last file: the result is whole
            return f"the results in {out} are complete (summary.json status complete); only the report " \
                   "on the screen was cut short"
        return f"{out} holds no complete result: run the same command again"
    return "nothing complete was written: run the same command again"


def _command(*args, collects_from_its_run: bool = False, **kwargs):
    """``@app.command`` with the error guard (:func:`guarded`)."""

    def deco(fn):
        return app.command(*args, **kwargs)(guarded(fn, collects_from_its_run))

    return deco


def _version_callback(value: bool):
    if value:
        from aidnav import __version__  # lazy: loaded when the command runs (--help: typer only)

        typer.echo(f"aidnav {__version__}")
        raise typer.Exit(0)


@app.callback()
def _main(version: bool = typer.Option(False, "--version", callback=_version_callback, is_eager=True,
                                       help="print the version and exit")):
    """aidnav: aided inertial navigation (simulate, process, evaluate)."""


def _print_summary(summary: dict, text: str, as_json: bool):
    import json  # lazy: only this command needs it

    if as_json:
        typer.echo(json.dumps(summary, indent=2, default=float))
    else:
        _console().print(text)


@_command()
def simulate(
    scenario: Path | None = typer.Argument(None, help="scenario YAML; default: the built-in figure8"),
    out: Path = typer.Option(Path("out"), "-o", "--out", help="output directory"),
    seed: int | None = typer.Option(None, help="override the scenario's random seed"),
    fmt: str = typer.Option("both", "--format", help="csv, parquet or both"),
):
    """Simulate truth, IMU and GNSS from a scenario file; write tables and a figure into DIR."""
    from aidnav.apps.common import prepare_out_dir  # lazy: loaded when the command runs (--help: typer only)

    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.apps.simulate import simulate_to_dir

    if fmt not in ("csv", "parquet", "both"):
        _fail(f"--format {fmt}: expected csv, parquet or both")
    prepare_out_dir(out)
    written = simulate_to_dir(scenario, out, seed=seed, fmt=fmt, console=_console())
    for p in written:
        _console().print(f"wrote {p}")


@_command(name="compile")
def compile_cmd(
    also: list[str] = typer.Option([], "--also", help="another aidnav command line (quoted) whose kernel "
                                   "calls the build should cover too; repeatable"),
    status: bool = typer.Option(False, "--status", help="only say whether a build matches this installation"),
):
    """Optional ahead-of-time build of the kernels (once per install; needs `pip install 'aidnav[compile]'`
    and a C compiler): commands then start without numba/LLVM, with the same results."""
    import shlex  # lazy: only this command needs it

    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.apps.kernels import build_status, compile_kernels

    st = build_status()
    if status:
        _console().print(f"build for this installation: {'present' if st['matches'] else 'none'} "
                         f"({st['folder']})")
        raise typer.Exit(0 if st["matches"] else 1)
    try:
        summary = compile_kernels([shlex.split(a) for a in also], progress=lambda m: _console().print(m))
    except RuntimeError as e:  # a workload or the C compiler failed: say what, exit 2
        _fail(f"aidnav compile: {e}")
    _console().print(f"built {summary['entry_points']} entry points of {summary['kernels']} kernels in "
                     f"{summary['seconds']:.0f} s: {summary['folder']}")


@_command()
def evaluate(
    estimate: Path = typer.Option(..., "--estimate", help="estimated trajectory: "
                                  + _TRAJECTORY_FORMATS_HELP),
    truth: Path = typer.Option(..., "--truth", help="reference trajectory: " + _TRAJECTORY_FORMATS_HELP),
    truth_height_offset: float = typer.Option(0.0, "--truth-height-offset",
                                              help="added to the reference heights, e.g. a geoid undulation "
                                              "for a .pos above mean sea level [m]; not applied to a file "
                                              "that declares ellipsoidal heights (a warning says so)"),
    out: Path | None = typer.Option(None, "-o", "--out", help="directory for errors.json/.csv and figures"),
):
    """Errors of an estimate against a reference: table of RMS/95%/max; JSON, CSV and figures with -o."""
    from aidnav.apps.common import prepare_out_dir  # lazy: loaded when the command runs (--help: typer only)
    from aidnav.apps.evaluate import evaluate_files  # lazy: loaded when the command runs (--help: typer only)

    if out is not None:
        prepare_out_dir(out)
    _, written = evaluate_files(estimate, truth, out_dir=out, console=_console(),
                                truth_height_offset_m=truth_height_offset)
    for p in written:
        _console().print(f"wrote {p}")


@_command(collects_from_its_run=True)
def process(
    imu: Path = typer.Option(..., "--imu", help="IMU log: " + _IMU_FORMATS_HELP),
    gnss: Path = typer.Option(..., "--gnss", help="GNSS fixes: " + _GNSS_FORMATS_HELP),
    config: Path | None = typer.Option(None, "--config", help="filter configuration YAML"),
    odometer: Path | None = typer.Option(None, "--odometer", help="odometer CSV: the same as --aid "
                                         "odometer=FILE"),
    baro: Path | None = typer.Option(None, "--baro", help="barometer CSV: the same as --aid baro=FILE"),
    aid: list[str] = typer.Option([], "--aid", help="an aid's file as NAME=FILE, repeatable; NAME an aid "
                                  "of aidnav.filters.aids.AIDS (files and settings: docs/adding-an-aid.md)"),
    out: Path = typer.Option(Path("out"), "-o", "--out", help="output directory: trajectory.parquet|csv, "
                             "summary.json, summary.txt"),
    fmt: str = typer.Option("parquet", "--format", help="trajectory file format: parquet or csv"),
    smooth: bool = typer.Option(False, "--smooth", help="run the RTS smoother as well"),
    outage: list[str] = typer.Option(
        [], "--outage", help="simulated GNSS outage START:LENGTH[:PERIOD] [s after the first fix]; "
        "repeatable"),
    height_offset: float | None = typer.Option(None, "--height-offset", help="added to the GNSS heights, "
                                               "e.g. "
                                               "the geoid undulation for heights above mean sea level [m] "
                                               "(overrides gnss.height_offset_m)"),
    time_offset: float | None = typer.Option(None, "--time-offset", help="added to the IMU time stamps [s] "
                                             "(overrides imu.time_offset_s)"),
    start: float | None = typer.Option(None, "--start", help="process from this many seconds after the first "
                                       "IMU sample"),
    end: float | None = typer.Option(None, "--end", help="process up to this many seconds after the first "
                                     "IMU sample"),
    skip_check: list[str] = typer.Option([], "--skip-check", help="skip a plausibility check by name "
                                         "(imu-rate, imu-accel, imu-gyro, imu-up, imu-gyro-scale, imu-axes, "
                                         "gnss-latlon, overlap, time-scale); repeatable"),
    as_json: bool = typer.Option(False, "--json", help="print the JSON summary instead of the text"),
    no_figures: bool = typer.Option(False, "--no-figures", help="skip overview.png, the KML/GeoJSON maps and "
                                    "run.html"),
    kfgins_nav: bool = typer.Option(False, "--kfgins-nav", help="also write DIR/trajectory.nav in KF-GINS's "
                                    "navigation-result format"),
    output_rate: float | None = typer.Option(None, "--output-rate", help="output rate [Hz] (default: every "
                                             "IMU sample; overrides filter.output_rate_hz)"),
    vehicle: str | None = typer.Option(None, "--vehicle", help="vehicle preset under the configuration: car "
                                       "(NHC), aircraft, pedestrian, ship; none: conservative defaults"),
    imu_topic: str | None = typer.Option(None, "--imu-topic", help="ROS bag: the sensor_msgs/Imu topic "
                                         "(needed when the bag has several)"),
    gnss_topic: str | None = typer.Option(None, "--gnss-topic", help="ROS bag: the sensor_msgs/NavSatFix "
                                          "topic (needed when the bag has several)"),
    gnss_vel_topic: str | None = typer.Option(None, "--gnss-vel-topic", help="ROS bag: the TwistStamped / "
                                              "TwistWithCovarianceStamped velocity topic"),
):
    """Loosely coupled GNSS/INS on logs: DIR/trajectory with σ columns, summary, overview.png, maps
    (KML, GeoJSON) and run.html."""
    from aidnav.apps.run_outputs import start_outputs  # lazy: (the standard library only)

    # the figures' process forked first: before numba and the filters load here (it needs neither) and
    # before the progress bar's thread starts; it imports matplotlib while this process reads and filters.
    # In the aidnav command it was forked before typer parsed the command line (_fork_figures_early)
    figures = _take_forked_figures(not no_figures) or start_outputs(not no_figures)
    from aidnav.apps.common import run_directory  # lazy: loaded when the command runs (--help: typer only)
    from aidnav.apps.process import format_summary, process_logs  # lazy: (as above)
    from aidnav.filters.aids import parse_aid  # lazy: numpy and the filters only when a command runs
    from aidnav.progress import progress_bar  # lazy: loaded when the command runs (--help: typer only)

    aid_paths = [("odometer", odometer)] * (odometer is not None) + [("baro", baro)] * (baro is not None)
    aid_paths += [parse_aid(a) for a in aid]
    with progress_bar("aidnav process") as bar, run_directory(out, "process"):
        s = process_logs(imu, gnss, config, out, smooth=smooth, outages=outage, fmt=fmt,
                         height_offset_m=height_offset, time_offset_s=time_offset, start_s=start, end_s=end,
                         skip_checks=skip_check, progress=bar, figures=figures, started=_resume_collections,
                         waiting=_console,
                         aid_paths=aid_paths, kfgins_nav=kfgins_nav,
                         output_rate_hz=output_rate, vehicle=vehicle, imu_topic=imu_topic,
                         gnss_topic=gnss_topic, gnss_vel_topic=gnss_vel_topic)
    _print_summary(s, format_summary(s), as_json)


@_command("fleet")
def fleet_cmd(
    manifest: Path = typer.Argument(..., help="CSV: name,imu,gnss[,config,truth,vehicle,vehicle_id,"
                                    "time_offset,height_offset,smooth], paths relative to the manifest"),
    out: Path = typer.Option(..., "-o", "--out", help="output directory: DIR/<name>/ per log, fleet.parquet, "
                             "fleet.html (what is already done there is kept)"),
    workers: int | None = typer.Option(None, "--workers", min=1, help="worker processes of a local Dask "
                                       "cluster (default: the CPUs; 1: this process alone)"),
    scheduler: str | None = typer.Option(None, "--scheduler", help="address of an existing Dask scheduler"),
    figures: bool = typer.Option(False, "--figures/--no-figures", help="also each log's overview.png, maps "
                                 "and run.html (about 1 CPU-s a log)"),
    retry_failed: bool = typer.Option(False, "--retry-failed", help="process the logs that failed before "
                                      "again"),
):
    """Process every log of a manifest in parallel (Dask): DIR/<name>/ as `aidnav process` writes it,
    DIR/fleet.parquet and DIR/fleet.html. Exit status 3 when a log failed (the others are done)."""
    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.apps.fleet import format_fleet, run_fleet
    from aidnav.progress import progress_bar  # lazy: loaded when the command runs (--help: typer only)

    if scheduler and workers is not None:
        _fail("give --workers or --scheduler, not both")
    with progress_bar("aidnav fleet", unit="logs") as bar:
        res = run_fleet(manifest, out, workers=workers, scheduler=scheduler, figures=figures,
                        retry_failed=retry_failed, progress=bar)
    _console().print(format_fleet(res), end="")
    if res.failed:
        raise typer.Exit(3)


@_command()
def convert(
    imu: Path | None = typer.Option(None, "--imu", help="IMU log of any known format (interchange, raw "
                                    "rtklibexplorer + .tag, KF-GINS, ROS bag)"),
    gnss: Path | None = typer.Option(None, "--gnss", help="GNSS log of any known format (interchange, RTKLIB "
                                     ".pos, KF-GINS, NMEA, UBX, ROS bag)"),
    out: Path = typer.Option(Path("converted"), "-o", "--out",
                             help="output directory: imu.<fmt>, gnss.<fmt>"),
    fmt: str = typer.Option("parquet", "--format", help="parquet or csv"),
    height_offset: float = typer.Option(0.0, "--height-offset", help="added to the GNSS heights (datum of "
                                        "the file → ellipsoid) [m]; recorded in the file"),
):
    """Any readable log → the interchange format (time scale and conversions recorded in the file)."""
    import math  # lazy: only this command needs it

    from aidnav.apps.common import prepare_out_dir  # lazy: loaded when the command runs (--help: typer only)

    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.io.convert import convert as convert_file

    if imu is None and gnss is None:
        _fail("give --imu and/or --gnss")
    if fmt not in ("parquet", "csv"):
        _fail(f"--format {fmt}: expected parquet or csv")
    if not math.isfinite(height_offset):
        _fail(f"--height-offset {height_offset}: not a finite number")
    prepare_out_dir(out)
    for kind, src in (("imu", imu), ("gnss", gnss)):
        if src is None:
            continue
        s = convert_file(src, out / f"{kind}.{fmt}", kind=kind,
                         height_offset_m=height_offset if kind == "gnss" else 0.0)
        _console().print(f"wrote {s['output']}: {s['samples']} {kind} samples from {src} ({s['format']})")
        for n in s["notes"]:
            _console().print(f"  {n}")


satcom_app = typer.Typer(no_args_is_help=True, help="Satcom on the move (seed 003): antenna servo angles.")
app.add_typer(satcom_app, name="satcom")


@satcom_app.command("point")
@guarded
def satcom_point(
    lat: float = typer.Option(..., "--lat", help="vehicle geodetic latitude [deg]"),
    lon: float = typer.Option(..., "--lon", help="vehicle longitude [deg, east +]"),
    height: float = typer.Option(0.0, "--height", help="ellipsoidal height [m]"),
    roll: float = typer.Option(0.0, "--roll", help="roll [deg], right wing down +"),
    pitch: float = typer.Option(0.0, "--pitch", help="pitch [deg], nose up +"),
    heading: float = typer.Option(0.0, "--heading", help="heading [deg], clockwise from true North"),
    sat_lon: float = typer.Option(..., "--sat-lon", help="GEO satellite longitude [deg, east +]"),
    polarization: str = typer.Option("vertical", "--polarization", help="vertical or horizontal"),
    as_json: bool = typer.Option(False, "--json", help="print a JSON object instead of a table"),
):
    """Servo azimuth, elevation and polarization [deg] of a satcom antenna on a vehicle (§4.3)."""
    import json  # lazy: only this command needs it

    from rich.table import Table  # lazy: rich is heavy to import

    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.nav.geo_pointing import servo_angles

    try:
        r = servo_angles(lat, lon, height, roll, pitch, heading, sat_lon, polarization=polarization)
    except ValueError as e:
        _fail(str(e))
    if as_json:
        typer.echo(json.dumps(r))
        return
    tab = Table(title=f"GEO {sat_lon:g} deg, {polarization}")
    tab.add_column("angle")
    tab.add_column("deg", justify="right")
    for k in ("azimuth_deg", "elevation_deg", "polarization_deg"):
        tab.add_row(k.removesuffix("_deg"), f"{r[k]:.4f}")
    _console().print(tab)


@_command("run")
def run_experiment_cmd(
    experiment: Path = typer.Argument(..., help="experiment YAML (see aidnav.experiments.config)"),
    out: Path = typer.Option(..., "-o", "--out", help="campaign directory (what is already there is reused)"),
    workers: int = typer.Option(1, "--workers", min=1, help="worker processes (> 1: a local process pool)"),
    scheduler: str | None = typer.Option(None, "--scheduler", help="address of an existing Dask scheduler"),
    dask: bool = typer.Option(False, "--dask", help="--workers > 1: a local Dask cluster instead of the "
                              "process pool"),
    no_dask: bool = typer.Option(False, "--no-dask", hidden=True, help="the process pool (the default)"),
    max_runs: int | None = typer.Option(None, "--max-runs", min=0,
                                        help="compute at most this many runs, then stop (rerun to resume)"),
):
    """Monte Carlo campaign of an experiment file: runs.parquet, epochs.parquet, manifest.json in DIR."""
    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.experiments.config import ExperimentError

    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.experiments.runner import CampaignInterrupted, format_result, run_experiment

    if scheduler and workers > 1:
        _fail("give --workers or --scheduler, not both")
    try:
        res = run_experiment(experiment, out, workers=workers, scheduler=scheduler, max_runs=max_runs,
                             backend="dask" if dask and not no_dask and workers > 1 else None,
                             console=_console)  # made once needed: after the workers start
    except ExperimentError as e:
        _fail(str(e))
    except CampaignInterrupted as e:
        _fail(str(e), 130)
    _console().print(format_result(res), markup=False, highlight=False, soft_wrap=True)


@_command("report")
def report_cmd(directory: Path = typer.Argument(..., help="campaign directory written by `aidnav run`")):
    """Self-contained HTML report of a campaign: DIR/report.html (and DIR/statistics.json)."""
    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.experiments.report import ReportError, write_report

    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.experiments.reproduce.page import ReproductionError, is_reproduction, report_folder

    if is_reproduction(directory):  # a folder of `aidnav reproduce` (one seed, or all with index.html)
        try:
            paths = report_folder(directory)
        except ReproductionError as e:
            _fail(str(e))
        for p in paths:
            _console().print(f"wrote {p}", markup=False, highlight=False)
        return
    try:
        path = write_report(directory)
    except ReportError as e:
        _fail(str(e))
    _console().print(f"wrote {path}")


@_command("reproduce")
def reproduce_cmd(
    seed: str = typer.Argument(..., help="seed to reproduce: 000, 001, 002, 003, 004 or all"),
    out: Path = typer.Option(..., "-o", "--out", help="output directory (all: one sub-directory per seed)"),
    runs: int | None = typer.Option(None, "--runs", min=1, help="Monte Carlo runs (default: the seed's)"),
):
    """Reproduce a seed's tables and figures; DIR/summary.json. Exit status 2 if it cannot be yet."""
    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.experiments.reproduce import reproduce, resolve_seeds

    try:
        resolve_seeds(seed)
    except ValueError as e:
        _fail(str(e))
    from rich.text import Text  # lazy: rich is heavy to import

    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.experiments.reproduce.page import write_index

    outcomes = reproduce(seed, out, runs=runs, console=_console())
    for o in outcomes:
        if o.ok:
            _console().print(f"seed {o.seed}: done; {o.summary or o.out_dir}", markup=False, highlight=False)
        else:
            _console().print(Text.assemble((f"seed {o.seed}", "bold red"),
                                        f": cannot be reproduced yet: {o.reason}"), highlight=False)
    if len(outcomes) > 1 and any(o.ok for o in outcomes):
        _console().print(f"wrote {write_index(out, outcomes)}", markup=False, highlight=False)
    if not all(o.ok for o in outcomes):
        raise typer.Exit(2)


@_command()
def tight(
    imu: Path = typer.Option(..., "--imu", help="IMU log (interchange or raw rtklibexplorer CSV + .tag)"),
    obs: Path = typer.Option(..., "--obs", help="RINEX observation file"),
    nav: Path = typer.Option(..., "--nav", help="RINEX navigation file (GPS broadcast ephemerides)"),
    config: Path | None = typer.Option(None, "--config", help="tight filter configuration YAML"),
    truth: Path | None = typer.Option(None, "--truth", help="reference solution (.pos or interchange): "
                                      "scored "
                                      "at every epoch and per solution quality"),
    truth_height_offset: float = typer.Option(0.0, "--truth-height-offset",
                                              help="added to the reference heights, e.g. the geoid "
                                              "undulation of a .pos above mean sea level [m]"),
    time_offset: float | None = typer.Option(None, "--time-offset", help="added to the IMU time stamps [s] "
                                             "(overrides imu.time_offset_s)"),
    out: Path = typer.Option(Path("out"), "-o", "--out", help="output directory: trajectory.parquet|csv, "
                             "summary.json, summary.txt"),
    fmt: str = typer.Option("parquet", "--format", help="trajectory file format: parquet or csv"),
    smooth: bool = typer.Option(False, "--smooth", help="run the RTS smoother as well (the smoothed "
                                "solution is written; the innovations stay the forward ones)"),
    as_json: bool = typer.Option(False, "--json", help="print the JSON summary instead of the text"),
    no_figures: bool = typer.Option(False, "--no-figures", help="skip overview.png, maps and run.html"),
    vehicle: str | None = typer.Option(None, "--vehicle", help="vehicle preset under the configuration, as "
                                       "in process: car (NHC), aircraft, pedestrian, ship"),
    ubx_nav: str | None = typer.Option(None, "--ubx-nav", help="u-blox UBX log whose broadcast ephemerides "
                                       "(RXM-SFRBX) are added to the navigation file's: a path, 'auto' (the "
                                       "log the observation file's header names, beside it or in its parent "
                                       "directory) or 'none'; default: the configuration's gnss.ubx_nav, "
                                       "'auto'"),
):
    """Tightly coupled GNSS/INS (pseudorange + Doppler) on an IMU log and RINEX files."""
    from aidnav.apps.common import run_directory  # lazy: loaded when the command runs (--help: typer only)

    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.apps.tight import format_tight_summary, process_tight_files
    from aidnav.progress import progress_bar  # lazy: loaded when the command runs (--help: typer only)

    with progress_bar("aidnav tight") as bar, run_directory(out, "tight"):
        bar.stage("SPP, alignment, tightly coupled filter", total=None)
        s = process_tight_files(imu, obs, nav, config, out, truth, truth_height_offset, fmt=fmt,
                                time_offset_s=time_offset, smooth=smooth, progress=bar,
                                figures=not no_figures, vehicle=vehicle, ubx_nav=ubx_nav)
    _print_summary(s, format_tight_summary(s), as_json)


@_command()
def spp(
    obs: Path = typer.Option(..., "--obs", help="RINEX observation file (GPS L1 C/A code and Doppler)"),
    nav: Path = typer.Option(..., "--nav", help="RINEX navigation file (GPS broadcast ephemerides)"),
    out: Path = typer.Option(Path("spp"), "-o", "--out", help="output directory: solution.parquet|csv, "
                             "summary.json, summary.txt, run.html, maps"),
    fmt: str = typer.Option("parquet", "--format", help="solution file format: parquet or csv"),
    iono: str = typer.Option("klobuchar", "--iono", help="ionosphere: klobuchar (the navigation file's "
                             "coefficients), none, or dual (L1/L2 code combination)"),
    mask: float = typer.Option(10.0, "--mask", help="elevation mask [deg]"),
    code_sigma: float = typer.Option(3.0, "--code-sigma", help="code range σ [m]: the fixes' σ = DOP × it"),
    as_json: bool = typer.Option(False, "--json", help="print the JSON summary instead of the text"),
    no_figures: bool = typer.Option(False, "--no-figures", help="skip overview.png, maps and run.html"),
    ubx_nav: str = typer.Option("auto", "--ubx-nav", help="u-blox UBX log whose broadcast ephemerides "
                                "(RXM-SFRBX) are added to the navigation file's: a path, 'auto' (the log the "
                                "observation file's header names, beside it or in its parent directory) or "
                                "'none'"),
):
    """Single point positioning on RINEX files: a GNSS solution file (interchange: process --gnss and
    evaluate read it), a summary and run.html."""
    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.apps.spp import format_spp_summary, spp_files

    s = spp_files(obs, nav, out, fmt=fmt, iono=iono, mask_deg=mask, code_sigma_m=code_sigma,
                  figures=not no_figures, ubx_nav=ubx_nav)
    _print_summary(s, format_spp_summary(s), as_json)


@_command()
def characterise(
    imu: Path = typer.Option(..., "--imu", help="static IMU log: interchange CSV/Parquet (rates or "
                             "increments) "
                             "or raw rtklibexplorer CSV"),
    out: Path = typer.Option(Path("characterise"), "-o", "--out", help="output directory"),
    static: str | None = typer.Option(None, "--static", help="START:END in seconds after the first "
                                      "sample (either may be empty): the static part to analyse (default: "
                                      "the whole log; motion in it is cut off and reported)"),
    grade: str | None = typer.Option(None, "--grade", help="IMU preset for terms the log cannot resolve "
                                     "(default: the one nearest in ARW/VRW)"),
):
    """Allan deviation → fitted IMU noise terms: DIR/allan.png, DIR/noise.json, DIR/imu.yaml.

    The longest static part of the log (or of --static) is analysed; motion, slow motion and vibration are
    reported as warnings. A short log gives the white-noise terms only (and says so)."""
    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.apps.characterise import characterise_file, print_characterisation
    from aidnav.apps.common import prepare_out_dir  # lazy: loaded when the command runs (--help: typer only)

    prepare_out_dir(out)
    ch, written = characterise_file(imu, out, static=static, grade=grade)
    print_characterisation(ch, _console())
    for p in written:
        _console().print(f"wrote {p}")


@_command("design-trajectory")
def design_trajectory_cmd(
    heading: float = typer.Option(..., "--heading", help="required heading accuracy on AB, CD [deg, 1σ]"),
    pitch: float = typer.Option(..., "--pitch", help="required pitch accuracy [deg, 1σ]"),
    roll: float = typer.Option(..., "--roll", help="required roll accuracy [deg, 1σ]"),
    grade: str = typer.Option("sub_arw", "--grade",
                              help="seed004_high|medium|low|sub, or high_arw|medium_arw|low_arw|sub_arw (the "
                              "seed's 'random drift' read as an ARW, as the seed-004 reproduction does)"),
    t1: str = typer.Option("0,200,400", "--t1", help="candidate straight legs before AB [s]"),
    t2: str = typer.Option("100,200,400,600,800", "--t2", help="candidate lengths of AB and CD [s]"),
    modes: str = typer.Option("none,s_turns,o_circle,figure8,climb", "--modes", help="maneuvers to consider"),
    legs: str = typer.Option("AB,CD", "--legs", help="imaging legs (segment names)"),
    baseline_km: float = typer.Option(20.0, "--baseline-km", help="GNSS baseline: 20, 40 or 60 km"),
    mc_runs: int = typer.Option(3, "--mc-runs", min=0, help="Monte Carlo runs confirming the plan (0: none)"),
    out: Path = typer.Option(Path("design"), "-o", "--out", help="output directory"),
):
    """Recommend maneuver, T1 and the longest T2 meeting an attitude requirement (seed 004 design).

    Exit status 3 when no candidate plan meets the requirement (1 is reserved for bugs)."""
    # lazy: loaded when the command runs (--help: typer only)
    from aidnav.experiments.design import design_trajectory, print_design, write_design

    def _list(v):
        return [x.strip() for x in v.split(",") if x.strip()]

    try:
        d = design_trajectory({"heading_deg": heading, "pitch_deg": pitch, "roll_deg": roll}, grade=grade,
                              modes=_list(modes), t1_values=[float(x) for x in _list(t1)],
                              t2_values=[float(x) for x in _list(t2)], legs=tuple(_list(legs)),
                              baseline_km=baseline_km, mc_runs=mc_runs)
    except (ValueError, OSError) as e:
        _fail(str(e))
    print_design(d, _console())
    for p in write_design(d, out):
        _console().print(f"wrote {p}")
    if not d.summary["feasible"]:
        raise typer.Exit(3)


def _start_kernels() -> None:
    """Kernels for this command (:mod:`aidnav.jit`): from the ahead-of-time build that matches this
    source tree, Python, numpy, numba, llvmlite and CPU (``aidnav compile``, optional), else numba's JIT
    (the same results). scipy's BLAS modules are loaded alone either way."""
    from aidnav import jit  # lazy: loaded when the command runs (--help: typer only)

    _preload_scipy_blas()  # the kernels' BLAS calls (numba's JIT and the build alike) import it at first use
    try:
        mode = jit.start()
    except (ValueError, RuntimeError) as e:  # AIDNAV_KERNELS unknown, or aot without a build
        _fail(str(e))
    if mode == "jit" and "AIDNAV_KERNELS" not in os.environ and sys.stderr.isatty():
        _console(stderr=True).print("[dim]tip: `aidnav compile` (optional: aidnav[compile] and a C compiler; "
                                    "once per install) makes every command start faster[/dim]")


def _fork_figures_early(argv: list[str]):
    """The figures' child of ``aidnav process`` (:func:`aidnav.apps.run_outputs.start_outputs`) forked at
    the command's start, before typer parses the command line (≈ 0.1 s: its 21 pydantic adapters) and
    before numpy loads: its imports of matplotlib and the overview's skeleton then start that much
    earlier beside this process's work, and are ready before the filter's job on a short log (issue 41,
    session 14). Only for ``process`` without ``--no-figures`` or ``--help`` (a first word that is the
    command: the app has no option that takes a value), and where the process may run on two CPUs (its
    affinity: on one, the child's work would only move earlier on the same CPU, and it would import numpy
    itself instead of sharing the parent's pages: +0.09 CPU-s measured with ``taskset -c 1``); anything
    else, or a command line that typer then rejects, gets no child or has it ended (:func:`main`).
    Returns the child or None."""
    if argv[:1] != ["process"] or {"--no-figures", "--help"} & set(argv):
        return None
    from aidnav.apps.overview_helper import usable_cpus  # lazy: the standard library only
    from aidnav.apps.run_outputs import SKELETON_MIN_CPUS, OutputsProcess, start_outputs  # lazy: (as above)

    if usable_cpus() < SKELETON_MIN_CPUS:
        return None
    figures = start_outputs(True)
    return figures if isinstance(figures, OutputsProcess) else None


def _take_forked_figures(wanted: bool):
    """The figures' child forked by :func:`main` (None where there is none); ended where the command
    draws no figures after all."""
    global _FORKED_FIGURES
    figures, _FORKED_FIGURES = _FORKED_FIGURES, None
    if figures is not None and not wanted:
        figures.close()
        return None
    return figures


def main():  # pragma: no cover - the console script (tests call `app` in-process, and main in a subprocess)
    """The ``aidnav`` command: the typer app, with numba's start-up made cheaper and a quick exit."""
    global _CONSOLE_SCRIPT, _FORKED_FIGURES
    _CONSOLE_SCRIPT = True
    _fewer_collections()  # a command's few million long-lived objects: fewer garbage collections
    _pause_collections()  # and none while it starts (console_script.pause_collections)
    try:
        try:
            _interrupts.install()  # SIGINT/SIGTERM raised where Python can take them (not numba's glue): 130
            _FORKED_FIGURES = _fork_figures_early(sys.argv[1:])  # process: drawn beside typer's parsing
            app()
            status = 0
        except SystemExit as e:
            status = _exit_status(e.code)
    except KeyboardInterrupt:
        status = 130
    _take_forked_figures(False)  # a child that process never took (typer rejected the command line): ended
    if status == 130 and not _INTERRUPT_REPORTED:  # before or after a command (typer: exit 130, silent)
        print(f"error: {_interrupts.MESSAGE}", file=sys.stderr)
    import signal  # lazy: only this command needs it

    for sig in (signal.SIGINT, signal.SIGTERM):  # the exit itself is not interrupted
        signal.signal(sig, signal.SIG_IGN)
    _leave(status)


if __name__ == "__main__":  # pragma: no cover
    main()
