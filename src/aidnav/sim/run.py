"""Run a scenario end to end in memory: truth, corrupted IMU and GNSS fixes.

The file job behind ``aidnav simulate`` (files and the overview figure) is
:func:`aidnav.apps.simulate.simulate_to_dir`.
"""

from __future__ import annotations

from importlib import resources

import numpy as np

from aidnav.data import GnssData, ImuData, Trajectory
from aidnav.sim import gnss as gnss_mod
from aidnav.sim import imu as imu_mod
from aidnav.sim.scenario import Scenario, ScenarioError, load_scenario
from aidnav.sim.trajectory import generate_truth

__all__ = ["ScenarioError", "simulate", "load_default_scenario", "default_scenario_path",
           "SimulationResult"]


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
