"""Run a scenario end to end: truth, corrupted IMU, GNSS fixes, files and an overview figure.

This is the library function behind ``aidnav simulate``. Frames and units of everything written follow
``CONVENTIONS.md`` (interchange files: degrees, metres, seconds since the start, ENU velocities, body
RFU IMU increments); see :mod:`aidnav.io.interchange`.
"""

from __future__ import annotations

import json
from contextlib import nullcontext
from importlib import resources
from pathlib import Path

import numpy as np
from rich.console import Console

from aidnav.data import GnssData, ImuData, Trajectory
from aidnav.sim.scenario import Scenario, ScenarioError, load_scenario

__all__ = ["ScenarioError", "simulate_to_dir", "simulate", "load_default_scenario", "default_scenario_path",
           "SimulationResult"]

_FORMATS = {"csv": ("csv",), "parquet": ("parquet",), "both": ("csv", "parquet")}


def default_scenario_path():
    """Traversable of the packaged default scenario (seed 004 mode 4, figure-8: ``figure8.yaml``)."""
    return resources.files("aidnav.sim").joinpath("scenarios", "figure8.yaml")


def load_default_scenario() -> Scenario:
    """The packaged default scenario (figure-8), validated."""
    with resources.as_file(default_scenario_path()) as p:
        return load_scenario(p)


class SimulationResult:
    """What :func:`simulate` produces.

    truth : IMU truth trajectory (lat/lon [rad], height [m], vel ENU [m/s], rph [rad]) at the IMU rate.
    imu_true : error-free increments; imu : corrupted increments (Δθ [rad], Δv [m/s], body RFU).
    gnss : antenna fixes (lat/lon [rad], height [m], vel ENU [m/s], σ). segments : rows
    {index, name, type, start_s, end_s}. imu_errors : realised IMU error constants (SI units, see
    :func:`aidnav.sim.imu.corrupt_imu`). seed : the seed used.
    """

    def __init__(self, scenario: Scenario, seed: int, truth: Trajectory, imu_true: ImuData, imu: ImuData,
                 gnss: GnssData, segments: list[dict], imu_errors: dict):
        self.scenario = scenario
        self.seed = seed
        self.truth = truth
        self.imu_true = imu_true
        self.imu = imu
        self.gnss = gnss
        self.segments = segments
        self.imu_errors = imu_errors


def _where(scn: Scenario) -> str:
    return scn.source or "<scenario>"


def simulate(scn: Scenario, seed: int | None = None, status=None) -> SimulationResult:
    """Generate truth, perfect and corrupted IMU data and GNSS fixes for ``scn`` (no files).

    The random streams come from ``numpy.random.SeedSequence(seed)`` (``seed`` default: the scenario's):
    its first spawned child drives the IMU errors, the second the GNSS noise, so changing one sensor's
    settings never changes the other's draws. ``status`` is an optional callable(str) for progress.
    """
    from aidnav.sim import gnss as gnss_mod
    from aidnav.sim import imu as imu_mod
    from aidnav.sim.trajectory import generate_truth

    say = status or (lambda msg: None)
    seed = int(scn.seed if seed is None else seed)
    where = _where(scn)
    try:
        imu_spec = imu_mod.ImuSpec.from_config(scn.sensors.imu)
    except ValueError as e:
        raise ScenarioError(f"{where}: sensors.imu: {e}") from None
    try:
        gnss_spec = gnss_mod.GnssSpec.from_config(scn.sensors.gnss)
    except ValueError as e:
        raise ScenarioError(f"{where}: sensors.gnss: {e}") from None
    say("generating the truth trajectory")
    truth, imu_true, segments = generate_truth(scn)
    ss_imu, ss_gnss = np.random.SeedSequence(seed).spawn(2)
    say("corrupting the IMU increments")
    imu, realised = imu_mod.corrupt_imu(imu_true, imu_spec, np.random.default_rng(ss_imu))
    say("simulating GNSS fixes")
    gnss = gnss_mod.simulate_gnss(truth, gnss_spec, np.random.default_rng(ss_gnss))
    return SimulationResult(scn, seed, truth, imu_true, imu, gnss, segments, realised)


def _jsonable(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    return x


def simulate_to_dir(scenario_path, out_dir, seed: int | None = None, fmt: str = "both",
                    console: Console | None = None) -> list[Path]:
    """Simulate a scenario file and write its data to ``out_dir``.

    Parameters
    ----------
    scenario_path : scenario YAML (:mod:`aidnav.sim.scenario`), or None for the packaged figure-8.
    out_dir : output directory (created).
    seed : overrides the scenario's ``seed``.
    fmt : "csv", "parquet" or "both".
    console : rich console for the status line (a new one when None).

    Writes ``truth``, ``imu`` (corrupted increments) and ``gnss`` as ``.csv`` and/or ``.parquet``
    (interchange columns: degrees, metres, seconds since the start, ENU, body RFU), ``run.json``
    (scenario name, seed, segment table, realised IMU error constants in SI units) and
    ``trajectory.png``. Returns the written paths. Raises :class:`ScenarioError` for a bad scenario or
    option.
    """
    from aidnav.io.interchange import write_gnss, write_imu, write_trajectory
    from aidnav.report.trajectory_plot import plot_trajectory

    if fmt not in _FORMATS:
        raise ScenarioError(f"format must be one of csv, parquet, both (got {fmt!r})")
    console = console or Console()
    out = Path(out_dir)
    scn = load_scenario(scenario_path) if scenario_path is not None else load_default_scenario()
    written: list[Path] = []
    status_cm = console.status(f"[bold]simulating[/] {scn.name}") if console.is_terminal else nullcontext()
    with status_cm as st:
        def say(msg: str):
            if st is not None:
                st.update(f"[bold]{scn.name}[/]: {msg}")
            else:
                console.log(f"{scn.name}: {msg}")

        res = simulate(scn, seed=seed, status=say)
        out.mkdir(parents=True, exist_ok=True)
        for ext in _FORMATS[fmt]:
            say(f"writing {ext} files")
            written.append(write_trajectory(res.truth, out / f"truth.{ext}"))
            written.append(write_imu(res.imu, out / f"imu.{ext}"))
            written.append(write_gnss(res.gnss, out / f"gnss.{ext}"))
        say("writing run.json")
        info = {"scenario": scn.name, "source": scn.source, "seed": res.seed,
                "duration_s": float(res.truth.time[-1]), "imu_rate_hz": scn.imu_rate_hz,
                "segments": res.segments, "imu_errors_si": _jsonable(res.imu_errors),
                "gnss_events": list(res.gnss.events), "imu_events": list(res.imu.events)}
        p = out / "run.json"
        p.write_text(json.dumps(info, indent=2))
        written.append(p)
        say("plotting")
        written.append(plot_trajectory(res.truth, out / "trajectory.png",
                                       title=f"{scn.name} (seed {res.seed})", segments=res.segments,
                                       gnss=res.gnss))
    return written
