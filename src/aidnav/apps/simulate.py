"""``aidnav simulate``: a scenario file → truth, IMU and GNSS files and an overview figure.

Frames and units of everything written follow the interchange conventions (degrees, metres, seconds
since the start, ENU velocities, body RFU IMU increments); see :mod:`aidnav.io.interchange`.
"""

from __future__ import annotations

import json
from contextlib import nullcontext
from pathlib import Path

import numpy as np
from rich.console import Console

from aidnav.io.interchange import write_gnss, write_imu, write_trajectory
from aidnav.report.trajectory_plot import plot_trajectory
from aidnav.sim.run import load_default_scenario, simulate
from aidnav.sim.scenario import ScenarioError, load_scenario

__all__ = ["simulate_to_dir"]

_FORMATS = {"csv": ("csv",), "parquet": ("parquet",), "both": ("csv", "parquet")}


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
    if fmt not in _FORMATS:
        raise ScenarioError(f"format must be one of csv, parquet, both (got {fmt!r})")
    console = console or Console()
    out = Path(out_dir)
    scn = load_scenario(scenario_path) if scenario_path is not None else load_default_scenario()
    written: list[Path] = []
    status_cm = console.status(f"simulating {scn.name}") if console.is_terminal else nullcontext()
    with status_cm as st:
        def say(msg: str):
            if st is not None:
                st.update(f"{scn.name}: {msg}")
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
