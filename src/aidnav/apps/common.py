"""What every job behind the CLI shares: configuration files, the output directory, the summary
files and the last check of a solution before it is written."""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path

import numpy as np
import yaml

from aidnav.errors import DivergenceError, InputError
from aidnav.io.atomic import SUMMARY, mark_running, remove_stale
from aidnav.io.atomic import write_text as _write_text

#: the extensions a trajectory can be written with (``--format``)
TRAJECTORY_FORMATS = ("parquet", "csv")


class ConfigError(InputError):
    """A configuration file that does not validate; the message names the key."""


def load_model(path, model):
    """Read a YAML file into the pydantic ``model`` (unknown keys are errors; messages name keys)."""
    from pydantic import ValidationError  # lazy: pydantic is heavy to import

    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as e:
        raise ConfigError(f"{path}: cannot read configuration: {e}") from e
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of keys at the top level")
    try:
        return model.model_validate(data)
    except ValidationError as e:
        lines = []
        for err in e.errors():
            key = ".".join(str(p) for p in err["loc"])
            lines.append(f"{key}: {err['msg']}")
        raise ConfigError(f"{path}: invalid configuration — fix these keys:\n  "
                          + "\n  ".join(lines)) from None


def prepare_out_dir(out) -> Path:
    """Check ``-o DIR`` before any work and create it: a directory (not a file, not under a file),
    writable. A path that looks like a file name (``.csv``/``.parquet``/``.json``) is refused with the
    grammar (``-o`` names a directory for every command)."""
    out = Path(out)
    if out.suffix.lower() in (".csv", ".parquet", ".pq", ".json", ".txt", ".png", ".html"):
        raise InputError(f"-o {out}: -o names an output directory (files inside get fixed names); "
                         f"give e.g. -o {out.with_suffix('')}")
    if out.exists() and not out.is_dir():
        raise InputError(f"-o {out}: exists and is not a directory")
    for parent in out.parents:
        if parent.exists():
            if not parent.is_dir():
                raise InputError(f"-o {out}: {parent} is a file, not a directory")
            break
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(f"-o {out}: cannot create the output directory: {e.strerror}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(f"-o {out}: the output directory is not writable")
    return out


def trajectory_path(out_dir: Path, fmt: str) -> Path:
    fmt = fmt.lower().lstrip(".")
    if fmt not in TRAJECTORY_FORMATS:
        raise InputError(f"--format {fmt}: expected one of {', '.join(TRAJECTORY_FORMATS)}")
    return Path(out_dir) / f"trajectory.{fmt}"


#: the files a run of ``process``/``tight`` writes into its directory (a new run removes them first)
RUN_OUTPUTS = ("trajectory.parquet", "trajectory.csv", "trajectory.nav", "summary.txt", "overview.png",
               "trajectory.kml", "trajectory.geojson", "run.html")


@contextlib.contextmanager
def run_directory(out_dir, job: str):
    """The run status of an output directory (issue 37): on entry the previous run's outputs and a killed
    run's leftovers (``*.part``, ``tmp*.spool``) are removed and ``summary.json`` says ``running``; the job
    writes its summary last (:func:`write_summary_files`: ``complete``); an exception (Ctrl-C included)
    leaves ``interrupted`` or ``failed`` there, so that ``evaluate`` and ``report`` refuse the directory."""
    mark_running(prepare_out_dir(out_dir), job, RUN_OUTPUTS)
    try:
        yield
    except BaseException as e:
        status = "interrupted" if isinstance(e, KeyboardInterrupt) else "failed"
        remove_stale(out_dir)  # a .part a helper process (the figures' child) left when it was ended
        with contextlib.suppress(OSError, ValueError):
            doc = json.loads((Path(out_dir) / SUMMARY).read_text(encoding="utf-8"))
            if doc.get("status") != "complete":
                _write_text(Path(out_dir) / SUMMARY, json.dumps({**doc, "status": status,
                                                                 "error": str(e) or type(e).__name__},
                                                                indent=2) + "\n")
        raise


def write_summary_files(out_dir: Path, summary: dict, text: str) -> list[Path]:
    """``summary.txt`` (people) and ``summary.json`` (machines; written last, with ``"status":
    "complete"`` and the list of the run's ``files``) in the output directory, each under a temporary
    name until complete."""
    out_dir = Path(out_dir)
    js, tx = out_dir / SUMMARY, out_dir / "summary.txt"
    _write_text(tx, text)
    files = sorted(p.name for p in out_dir.iterdir() if p.name in RUN_OUTPUTS) + [SUMMARY]
    summary.update(status="complete", files=files)  # (in place: what --json prints is the file)
    _write_text(js, json.dumps(summary, indent=2, default=_json_default))
    return [js, tx]


def _json_default(o):
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


#: a position change between output samples faster than this is a jump, not motion [m/s] ...
MAX_PLAUSIBLE_SPEED_M_S = 3000.0
#: ... unless it is shorter than this: a GNSS update after an outage may correct a drift of tens or
#: hundreds of metres in one step (that is the filter working, and it is reported as an update) [m]
MIN_JUMP_M = 10_000.0
#: a position σ above this says the filter has lost the solution [m]
MAX_PLAUSIBLE_POS_STD_M = 1.0e5


def check_solution(traj, what: str = "filter") -> None:
    """Refuse to write a solution that is not one: NaN/inf, position jumps faster than
    :data:`MAX_PLAUSIBLE_SPEED_M_S` and longer than :data:`MIN_JUMP_M`, position σ beyond
    :data:`MAX_PLAUSIBLE_POS_STD_M`.

    Raises :class:`DivergenceError` naming the first bad epoch and what to check (one pass of a numba
    kernel over the rows for the NaN and jump tests: :mod:`aidnav.apps.check_kernels`)."""
    from aidnav.apps.check_kernels import first_jump, nonfinite_rows  # lazy: pulls in numba

    f = [np.ascontiguousarray(x, dtype=np.float64) for x in (traj.time, traj.lat, traj.lon, traj.height)]
    vel, rph = (np.ascontiguousarray(np.asarray(x, dtype=np.float64).reshape(len(f[0]), -1))
                for x in (traj.vel, traj.rph))
    n_bad, i = nonfinite_rows(f[1], f[2], f[3], vel, rph)
    if n_bad:
        raise DivergenceError(f"{what} diverged: NaN/inf in the solution from t={traj.time[i]:.3f} s "
                              f"({n_bad} samples); check the IMU units and the noise "
                              "configuration; nothing was written")
    i, step, dt = first_jump(*f, MAX_PLAUSIBLE_SPEED_M_S, MIN_JUMP_M)
    if i >= 0:
        raise DivergenceError(f"{what} diverged: the position jumps {step / max(dt, 1e-9) * dt:.1f} m in "
                              f"{dt:.3f} s at t={traj.time[i + 1]:.3f} s; check the GNSS file and "
                              "the IMU units; nothing was written")
    if traj.std_pos is not None:
        sp = np.asarray(traj.std_pos)
        if np.isfinite(sp).all() and sp.size and float(sp.max()) > MAX_PLAUSIBLE_POS_STD_M:
            i = int(np.argmax(sp.max(axis=1)))
            raise DivergenceError(f"{what} diverged: position σ {sp[i].max():.3g} m at "
                                  f"t={traj.time[i]:.3f} s "
                                  "(no aiding reached the filter?); nothing was written")

