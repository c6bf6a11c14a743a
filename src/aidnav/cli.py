"""Command-line interface: thin typer commands over the library functions."""

from __future__ import annotations

import os

# Small matrices: single-threaded BLAS is faster than threaded (must be set before numpy loads).
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

from pathlib import Path  # noqa: E402

import typer  # noqa: E402
from rich.console import Console  # noqa: E402

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="aidnav: aided inertial navigation (simulate, process, evaluate).")
console = Console()


def _fail(msg: str, code: int = 2):
    console.print(f"[bold red]error:[/] {msg}")
    raise typer.Exit(code)


@app.command()
def simulate(
    scenario: Path | None = typer.Argument(None, help="scenario YAML; default: the built-in figure8"),
    out: Path = typer.Option(Path("out"), "-o", "--out", help="output directory"),
    seed: int | None = typer.Option(None, help="override the scenario's random seed"),
    fmt: str = typer.Option("both", "--format", help="csv, parquet or both"),
):
    """Simulate truth, IMU and GNSS from a scenario file; write tables and a figure."""
    from aidnav.sim.run import ScenarioError, simulate_to_dir

    try:
        written = simulate_to_dir(scenario, out, seed=seed, fmt=fmt, console=console)
    except ScenarioError as e:
        _fail(str(e))
    for p in written:
        console.print(f"wrote {p}")


@app.command()
def evaluate(
    estimate: Path = typer.Argument(..., help="estimated trajectory (interchange CSV/Parquet or .pos)"),
    truth: Path = typer.Option(..., "--truth", help="reference trajectory (interchange or RTKLIB .pos)"),
    out: Path | None = typer.Option(None, "-o", "--out", help="directory for errors.json/.csv and figures"),
):
    """Errors of an estimate against a reference: table of RMS/95%/max; JSON, CSV and figures with -o."""
    from aidnav.analysis.evaluate import evaluate_files

    try:
        _, written = evaluate_files(estimate, truth, out_dir=out, console=console)
    except (OSError, ValueError) as e:
        _fail(str(e))
    for p in written:
        console.print(f"wrote {p}")


@app.command()
def process(
    imu: Path = typer.Option(..., "--imu", help="IMU log: interchange CSV/Parquet or raw rtklibexplorer CSV"),
    gnss: Path = typer.Option(..., "--gnss", help="GNSS fixes: RTKLIB .pos or interchange CSV/Parquet"),
    config: Path | None = typer.Option(None, "--config", help="filter configuration YAML"),
    out: Path = typer.Option(Path("out/trajectory.csv"), "-o", "--out", help="output .csv or .parquet"),
    smooth: bool = typer.Option(False, "--smooth", help="run the RTS smoother as well"),
    outage: list[str] = typer.Option(
        [], "--outage", help="simulated GNSS outage START:LENGTH[:PERIOD] [s after the first fix]"),
):
    """Loosely coupled GNSS/INS on logs: trajectory with σ columns plus a JSON/text summary."""
    from aidnav.io.errors import DataError
    from aidnav.process import ConfigError, format_summary, process_logs

    try:
        with console.status("aidnav process: reading, filtering" + (", smoothing" if smooth else "")):
            s = process_logs(imu, gnss, config, out, smooth=smooth, outages=outage, console=console)
    except (DataError, ConfigError, ValueError) as e:
        _fail(str(e))
    console.print(format_summary(s), markup=False, highlight=False, soft_wrap=True)


satcom_app = typer.Typer(no_args_is_help=True, help="Satcom on the move (seed 003): antenna servo angles.")
app.add_typer(satcom_app, name="satcom")


@satcom_app.command("point")
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
    """Servo azimuth, elevation and polarization [deg] of a satcom antenna on a vehicle (SPEC 4.3)."""
    import json

    from rich.table import Table

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
    console.print(tab)


@app.command("run")
def run_experiment_cmd(
    experiment: Path = typer.Argument(..., help="experiment YAML (see aidnav.experiments.config)"),
    out: Path = typer.Option(..., "-o", "--out", help="campaign directory (what is already there is reused)"),
    workers: int = typer.Option(1, "--workers", min=1, help="worker processes (> 1: a local Dask cluster)"),
    scheduler: str | None = typer.Option(None, "--scheduler", help="address of an existing Dask scheduler"),
    no_dask: bool = typer.Option(False, "--no-dask", help="--workers > 1: a process pool instead of Dask"),
    max_runs: int | None = typer.Option(None, "--max-runs", min=0,
                                        help="compute at most this many runs, then stop (rerun to resume)"),
):
    """Monte Carlo campaign of an experiment file: runs.parquet, epochs.parquet, manifest.json in DIR."""
    from aidnav.experiments.config import ExperimentError
    from aidnav.experiments.runner import CampaignInterrupted, format_result, run_experiment

    if scheduler and workers > 1:
        _fail("give --workers or --scheduler, not both")
    try:
        res = run_experiment(experiment, out, workers=workers, scheduler=scheduler, max_runs=max_runs,
                             backend="processes" if no_dask and workers > 1 and not scheduler else None,
                             console=console)
    except ExperimentError as e:
        _fail(str(e))
    except CampaignInterrupted as e:
        _fail(str(e), 130)
    console.print(format_result(res), markup=False, highlight=False, soft_wrap=True)


@app.command("report")
def report_cmd(directory: Path = typer.Argument(..., help="campaign directory written by `aidnav run`")):
    """Self-contained HTML report of a campaign: DIR/report.html (and DIR/statistics.json)."""
    from aidnav.experiments.report import ReportError, write_report
    from aidnav.experiments.reproduce.page import ReproductionError, is_reproduction, report_folder

    if is_reproduction(directory):  # a folder of `aidnav reproduce` (one seed, or all with index.html)
        try:
            paths = report_folder(directory)
        except ReproductionError as e:
            _fail(str(e))
        for p in paths:
            console.print(f"wrote {p}", markup=False, highlight=False)
        return
    try:
        path = write_report(directory)
    except ReportError as e:
        _fail(str(e))
    console.print(f"wrote {path}")


@app.command("reproduce")
def reproduce_cmd(
    seed: str = typer.Argument(..., help="seed to reproduce: 000, 001, 002, 003, 004 or all"),
    out: Path = typer.Option(..., "-o", "--out", help="output directory (all: one sub-directory per seed)"),
    runs: int | None = typer.Option(None, "--runs", min=1, help="Monte Carlo runs (default: the seed's)"),
):
    """Reproduce a seed's tables and figures; DIR/summary.json. Exit status 2 if it cannot be yet."""
    from aidnav.experiments.reproduce import reproduce, resolve_seeds

    try:
        resolve_seeds(seed)
    except ValueError as e:
        _fail(str(e))
    from rich.text import Text

    from aidnav.experiments.reproduce.page import write_index

    outcomes = reproduce(seed, out, runs=runs, console=console)
    for o in outcomes:
        if o.ok:
            console.print(f"seed {o.seed}: done; {o.summary or o.out_dir}", markup=False, highlight=False)
        else:
            console.print(Text.assemble((f"seed {o.seed}", "bold red"),
                                        f": cannot be reproduced yet: {o.reason}"), highlight=False)
    if len(outcomes) > 1 and any(o.ok for o in outcomes):
        console.print(f"wrote {write_index(out, outcomes)}", markup=False, highlight=False)
    if not all(o.ok for o in outcomes):
        raise typer.Exit(2)


@app.command()
def tight(
    imu: Path = typer.Option(..., "--imu", help="IMU log (interchange or raw rtklibexplorer CSV + .tag)"),
    obs: Path = typer.Option(..., "--obs", help="RINEX observation file"),
    nav: Path = typer.Option(..., "--nav", help="RINEX navigation file (GPS broadcast ephemerides)"),
    config: Path | None = typer.Option(None, "--config", help="tight filter configuration YAML"),
    reference: Path | None = typer.Option(None, "--reference", help="reference solution (.pos, Q=1 used)"),
    reference_height_offset: float = typer.Option(0.0, help="added to the reference heights [m]"),
    out: Path = typer.Option(Path("out/tight.csv"), "-o", "--out", help="output .csv or .parquet"),
):
    """Tightly coupled GNSS/INS (pseudorange + Doppler) on an IMU log and RINEX files."""
    import json

    from aidnav.io.errors import DataError
    from aidnav.process import ConfigError
    from aidnav.process_tight import process_tight_files

    try:
        with console.status("aidnav tight: SPP, alignment, tightly coupled filter"):
            s = process_tight_files(imu, obs, nav, config, out, reference, reference_height_offset)
    except (DataError, ConfigError, ValueError, OSError) as e:
        _fail(str(e))
    console.print(json.dumps(s, indent=2, default=float), markup=False, highlight=False, soft_wrap=True)


@app.command()
def characterise(
    imu_log: Path = typer.Argument(..., help="static IMU log: interchange CSV/Parquet (rates or increments) "
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
    from aidnav.analysis.characterise import characterise_file, print_characterisation

    try:
        ch, written = characterise_file(imu_log, out, static=static, grade=grade)
    except (OSError, ValueError) as e:
        _fail(str(e))
    print_characterisation(ch, console)
    for p in written:
        console.print(f"wrote {p}")


@app.command("design-trajectory")
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

    Exit status 1 when no candidate plan meets the requirement."""
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
    print_design(d, console)
    for p in write_design(d, out):
        console.print(f"wrote {p}")
    if not d.summary["feasible"]:
        raise typer.Exit(1)


def main():  # pragma: no cover
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
