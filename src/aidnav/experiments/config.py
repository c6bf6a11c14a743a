"""Experiment files: a scenario, sensors, estimators, Monte Carlo runs, sweeps and statistics (YAML).

Everything is validated before any computation; every problem becomes an :class:`ExperimentError`
whose message names the file, the line (when known) and the key path, e.g.
``quick.yaml:12: sensors.imu.arw_deg_sqrt: unknown key 'arw_deg_sqrt' (expected one of: ...)`` or
``quick.yaml: sweep: 'sensors.imu.grad': sensors.imu has no parameter 'grad' (expected one of: ...)``.

Example (units in the key names, ``docs/conventions.md``)::

    name: quick
    description: tactical vs MEMS IMU, tuned and mis-tuned filter
    scenario:                       # the motion of aidnav.sim.scenario (or a path to a scenario file)
      initial: {lat_deg: 40, lon_deg: 116, height_m: 7000, speed_m_s: 100, heading_deg: 40}
      imu_rate_hz: 100
      segments:
        - {type: straight, duration_s: 60, name: AB}
        - {type: u_turn, duration_s: 60, name: U}
        - {type: straight, duration_s: 60, name: CD}
    sensors:                        # aidnav.sim.scenario.SensorsConfig (deep-merged over a scenario file's)
      imu: {grade: tactical}
      gnss: {rate_hz: 1, sigma_pos_m: [0.5, 0.5, 1.0]}
    estimators:                     # one or more; type = a registered estimator (default "loose")
      - {name: tuned, type: loose}
      - {name: q_small, type: loose, q_scale: 0.01}
    runs: 4                         # Monte Carlo runs per sweep point (>= 1)
    base_seed: 1                    # run k uses numpy.random.SeedSequence(base_seed).spawn(...)[k]
    sweep:                          # dotted paths into this document; grid (or zip) of the values
      sensors.imu.grade: [tactical, mems]
    statistics:
      quantities: [pos_h, vel_h, att_e, att_n, heading]
      metrics: [std, rms]
      windows: {AB: {segment: AB}, CD: {segment: CD}, last30: {last_s: 30, metrics: [rms]}}
      convergence: {heading_0.05: {quantity: heading, below: 0.05}}
    paper:                          # values printed in a paper, shown beside ours in the report
      - {column: std_CD_heading_deg, paper: 0.02, estimator: tuned,
         point: {sensors.imu.grade: tactical}, target: "ours <= 2 * paper"}

Sweep paths address the *canonical* document (every default filled in): ``scenario.…`` (motion),
``sensors.imu.…``, ``sensors.gnss.…``, ``estimators.<name or index>.…``; list items may be named by
their ``name`` (``scenario.segments.CD.duration_s``; replacing a whole segment keeps its name). The
shorthands ``imu.…``, ``gnss.…`` and ``trajectory.…`` stand for ``sensors.imu.…``, ``sensors.gnss.…``
and ``scenario.…``. A path that does not exist fails before any computation, naming it.

Statistics (computed per run from the per-epoch errors; column names carry units):
``<metric>_<window>_<quantity>_<unit>`` (error std / RMS / mean / max|e| over a window),
``converge_<name>_s`` (first epoch after which |error| — or the filter σ with ``of: sigma`` — stays at or
below ``below`` until the end, or for ``hold_s``), ``nees_<block>_mean``. Quantities: the estimator's
states (``pos_e``, ``vel_u``, ``att_n``, …) and ``pos_h`` (horizontal), ``pos_3d``, ``vel_h``,
``heading`` (= ``att_u``, the misalignment about Up, which is the heading error for small angles).
"""

from __future__ import annotations

import copy
import hashlib
import importlib
import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from aidnav.filters.config import LooseConfig
from aidnav.sim.gnss import GnssSpec
from aidnav.sim.imu import ImuSpec
from aidnav.sim.scenario import (
    SEGMENT_TYPES,
    Initial,
    Scenario,
    ScenarioError,
    Segment,
    SensorsConfig,
    clean_loc,
    join_error_lines,
    load_scenario,
    yaml_line,
)
from aidnav.sim.scenario import (
    error_message as scenario_error_message,
)
from aidnav.sim.trajectory import compile_segments

from . import estimators as est_mod
from .reproduce.summary import check_expression
from .statistics_spec import (
    NonNegative,
    Positive,
    StatisticsSpec,
    StrictModel,
    available_quantities,
    statistic_columns,
)

__all__ = [
    "ExperimentError", "Experiment", "MotionSpec", "StatisticsSpec", "PaperValue", "EstimatorEntry",
    "SweepPoint", "ExperimentPlan", "load_experiment", "parse_experiment", "RUN_FORMAT",
]

#: Version of the per-run result format; part of every point key (changing it invalidates old runs).
RUN_FORMAT = 1

class ExperimentError(ValueError):
    """An experiment that cannot be run; the message names the file, key path and problem."""


class MotionSpec(StrictModel):
    """The ``scenario`` section: the motion of :class:`aidnav.sim.scenario.Scenario` (initial state [deg,
    m, m/s], IMU rate [Hz], transition width [s], segments)."""

    initial: Initial
    imu_rate_hz: Positive = 100.0
    transition_s: NonNegative = 4.0
    segments: list[Segment] = Field(min_length=1)


class PaperValue(StrictModel):
    """A value printed in a paper, shown beside ours (the mean over runs of ``column`` in runs.parquet)
    at the sweep points matching ``point`` (sweep path → value; empty = every point) for ``estimator``
    (None = every estimator). ``target``: an expression over ``ours`` and ``paper`` (e.g.
    ``"ours <= 1.2 * paper"``) whose verdict is shown as *holds*. ``quantity`` and ``unit`` label the row."""

    column: str
    paper: float | None = None
    point: dict[str, Any] = Field(default_factory=dict)
    estimator: str | None = None
    quantity: str | None = None
    unit: str | None = None
    target: str | None = None


class EstimatorEntry(BaseModel):
    """One estimator of the experiment: ``name`` (unique label), ``type`` (a registered estimator) and
    the keys of that type's configuration model."""

    model_config = ConfigDict(extra="allow")
    name: str = Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_-]*$")
    type: str = "loose"


class Experiment(StrictModel):
    """A complete experiment file (see the module docstring)."""

    name: str = "experiment"
    description: str = ""
    imports: list[str] = Field(default_factory=list)
    scenario: MotionSpec
    sensors: SensorsConfig = Field(default_factory=SensorsConfig)
    estimators: list[EstimatorEntry] = Field(default_factory=lambda: [EstimatorEntry(name="loose")],
                                             min_length=1)
    runs: int = Field(ge=1)
    base_seed: int = Field(1, ge=0)
    sweep: dict[str, Annotated[list[Any], Field(min_length=1)]] = Field(default_factory=dict)
    sweep_mode: Literal["grid", "zip"] = "grid"
    statistics: StatisticsSpec = Field(default_factory=StatisticsSpec)
    paper: list[PaperValue] = Field(default_factory=list)


# ------------------------------------------------------------------------------------ sweep points
@dataclass
class SweepPoint:
    """One point of the sweep.

    index : position in the sweep (0-based). values : sweep path (as written) → value. label : text for
    tables. doc : canonical document of this point (sweep applied). experiment : validated model.
    scenario : the :class:`aidnav.sim.scenario.Scenario` simulated. segments : its segment table.
    key : hash of what determines the runs' results (motion, sensors, estimators, imports, base seed).
    """

    index: int
    values: dict[str, Any]
    label: str
    doc: dict
    experiment: Experiment
    scenario: Scenario
    segments: list[dict]
    duration_s: float
    key: str


@dataclass
class ExperimentPlan:
    """A validated experiment and its sweep points (what :func:`aidnav.experiments.runner.run_experiment`
    runs). ``doc`` is the canonical document (defaults filled in), ``text`` the file's contents."""

    experiment: Experiment
    doc: dict
    points: list[SweepPoint]
    source: str | None = None
    text: str | None = None
    estimators: list[str] = field(default_factory=list)

    @property
    def runs(self) -> int:
        return self.experiment.runs

    @property
    def base_seed(self) -> int:
        return self.experiment.base_seed


# ------------------------------------------------------------------------------- error formatting
def _model_at(loc: tuple, root_model: type[BaseModel] | None = None) -> type[BaseModel] | None:
    """The pydantic model class at a (raw) error location in ``root_model`` (default: Experiment),
    None when unknown."""
    model: Any = Experiment if root_model is None else root_model
    i = 0
    while i < len(loc):
        item = loc[i]
        if isinstance(item, int):
            i += 1
            continue
        if not (isinstance(model, type) and issubclass(model, BaseModel)) or item not in model.model_fields:
            return None
        if item == "segments":
            tag = loc[i + 2] if i + 2 < len(loc) else None
            model = SEGMENT_TYPES.get(tag)
            i += 3
            continue
        ann = model.model_fields[item].annotation
        args = getattr(ann, "__args__", ()) or ()
        cand = [a for a in (ann, *args) if isinstance(a, type) and issubclass(a, BaseModel)]
        if not cand:
            for a in args:
                cand += [b for b in getattr(a, "__args__", ())
                         if isinstance(b, type) and issubclass(b, BaseModel)]
        if not cand:
            return None
        model = cand[0]
        i += 1
        # dict[str, Model]: skip the key
        if i < len(loc) and getattr(ann, "__origin__", None) is dict:
            i += 1
    return model if isinstance(model, type) and issubclass(model, BaseModel) else None


def _format_error(e: dict, prefix: tuple, where: str, root, data,
                  expected=None) -> tuple[str, tuple, str | None]:
    raw = tuple(prefix) + tuple(e["loc"])
    loc, member = clean_loc(raw)
    path = ".".join(str(x) for x in loc) or "(top level)"
    keys = expected(raw[:-1]) if (expected and e["type"] == "extra_forbidden") else None
    msg = scenario_error_message(e, loc, keys)
    line = yaml_line(root, loc) if root is not None else None
    at = f"{where}:{line}" if line is not None else where
    return f"{at}: {path}: {msg}", loc, member


def _format_validation(err: ValidationError, where: str, root=None, data=None, prefix: tuple = (),
                       expected=None) -> str:
    """One line per problem ``file[:line]: key.path: message`` (scalar-or-[x, y, z] unions report the
    branch matching what was written)."""
    if expected is None:
        def expected(raw):
            m = _model_at(raw)
            return list(m.model_fields) if m is not None else None
    items = (_format_error(e, prefix, where, root, data, expected) for e in err.errors())
    return join_error_lines(items, data)


# ----------------------------------------------------------------------------------------- parsing
def _deep_merge(base: dict, over: dict) -> dict:
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def _validate_doc(data: dict, where: str, root=None) -> tuple[Experiment, dict]:
    """Validate a document (scenario already inline); return the model and the canonical document."""
    try:
        exp = Experiment.model_validate(data)
    except ValidationError as e:
        raise ExperimentError(_format_validation(e, where, root, data)) from None
    for mod in exp.imports:
        try:
            importlib.import_module(mod)
        except Exception as e:  # noqa: BLE001 - any import failure is a bad experiment
            raise ExperimentError(f"{where}: imports: cannot import {mod!r}: {e}") from None
    names = [e.name for e in exp.estimators]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ExperimentError(f"{where}: estimators: duplicate name(s) {', '.join(dup)}")
    doc = exp.model_dump(mode="json")
    problems = []
    for i, entry in enumerate(exp.estimators):
        try:
            et = est_mod.get_estimator(entry.type)
        except (KeyError, ImportError) as e:
            line = yaml_line(root, ("estimators", i, "type")) if root is not None else None
            at = f"{where}:{line}" if line is not None else where
            problems.append(f"{at}: estimators.{i}.type: {str(e).strip(chr(34))}")
            continue
        extra = {k: v for k, v in (entry.model_extra or {}).items()}
        try:
            cfg = et.config_model.model_validate(extra)
        except ValidationError as e:
            def expected(raw, _m=et.config_model):
                return ["name", "type", *_m.model_fields] if len(raw) == 2 else None
            problems.append(_format_validation(e, where, root, data, prefix=("estimators", i),
                                               expected=expected))
            continue
        doc["estimators"][i] = {"name": entry.name, "type": entry.type, **cfg.model_dump(mode="json")}
    if problems:
        raise ExperimentError("\n".join(problems))
    return exp, doc


_ALIASES = {"imu": ("sensors", "imu"), "gnss": ("sensors", "gnss"), "trajectory": ("scenario",)}
_SWEEPABLE = ("scenario", "sensors", "estimators")


def _resolve_path(doc: dict, path: str, where: str) -> list:
    """Sweep path → list of keys/indices into the canonical document; ExperimentError naming it."""
    parts = path.split(".")
    if parts[0] in _ALIASES:
        parts = list(_ALIASES[parts[0]]) + parts[1:]
    if parts[0] not in _SWEEPABLE:
        raise ExperimentError(f"{where}: sweep: {path!r}: cannot sweep over {parts[0]!r} (sweep paths start "
                              f"with {', '.join(_SWEEPABLE)}, or the shorthands {', '.join(_ALIASES)})")
    node: Any = doc
    out: list = []
    for j, p in enumerate(parts):
        here = ".".join(str(x) for x in out) or "the experiment"
        if isinstance(node, dict):
            if p not in node:
                raise ExperimentError(f"{where}: sweep: {path!r}: {here} has no parameter {p!r} "
                                      f"(expected one of: {', '.join(map(str, node))})")
            out.append(p)
            node = node[p]
        elif isinstance(node, list):
            if p.lstrip("-").isdigit() and -len(node) <= int(p) < len(node):
                k = int(p) % len(node)
            else:
                named = [i for i, it in enumerate(node) if isinstance(it, dict) and it.get("name") == p]
                if not named:
                    names = [str(it.get("name")) for it in node if isinstance(it, dict) and it.get("name")]
                    raise ExperimentError(
                        f"{where}: sweep: {path!r}: {here} has no item {p!r} (give an index 0-{len(node) - 1}"
                        + (f" or a name: {', '.join(names)})" if names else ")"))
                k = named[0]
            out.append(k)
            node = node[k]
        else:
            raise ExperimentError(f"{where}: sweep: {path!r}: {here} is a value, not a section "
                                  f"(no parameter {'.'.join(parts[j:])!r} inside it)")
    return out


def _set_path(doc: dict, parts: list, value) -> None:
    node = doc
    for p in parts[:-1]:
        node = node[p]
    old = node[parts[-1]]
    value = copy.deepcopy(value)
    if isinstance(value, dict) and isinstance(old, dict) and "name" in old and "name" not in value \
            and isinstance(parts[-1], int):
        value["name"] = old["name"]  # replacing a whole (named) list item keeps its name
    node[parts[-1]] = value


def _label_value(v) -> str:
    if isinstance(v, dict):
        if "type" in v:
            rest = ", ".join(f"{k}={v[k]}" for k in v if k not in ("type", "name") and v[k] is not None)
            return f"{v['type']}({rest})" if rest else str(v["type"])
        return json.dumps(v, sort_keys=True, separators=(",", ":"))
    if isinstance(v, list):
        return json.dumps(v, separators=(",", ":"))
    return str(v)


def _point_key(doc: dict) -> str:
    payload = {"format": RUN_FORMAT, "scenario": doc["scenario"], "sensors": doc["sensors"],
               "estimators": doc["estimators"], "imports": doc["imports"], "base_seed": doc["base_seed"]}
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()


def build_scenario(exp: Experiment, name: str = "experiment", where: str | None = None) -> Scenario:
    """The :class:`aidnav.sim.scenario.Scenario` of a (validated) experiment point."""
    m = exp.scenario
    scn = Scenario.model_validate({"name": name, "initial": m.initial.model_dump(),
                                   "imu_rate_hz": m.imu_rate_hz, "transition_s": m.transition_s,
                                   "segments": [s.model_dump() for s in m.segments],
                                   "sensors": exp.sensors.model_dump()})
    scn._source = where
    return scn


def _check_point(exp: Experiment, doc: dict, where: str, root=None) -> tuple[Scenario, list[dict], float]:
    """Checks that need more than the schema (before any computation): flyable motion, sensor specs,
    estimator configurations, statistics windows and quantities."""
    scn = build_scenario(exp, exp.name, where)
    try:
        cm = compile_segments(scn)
    except ScenarioError as e:
        msg = str(e)
        if msg.startswith(f"{where}: segments."):
            msg = f"{where}: scenario.{msg[len(where) + 2:]}"
        raise ExperimentError(msg) from None
    try:
        ImuSpec.from_config(exp.sensors.imu)
    except ValueError as e:
        raise ExperimentError(f"{where}: sensors.imu: {e}") from None
    try:
        GnssSpec.from_config(exp.sensors.gnss)
    except ValueError as e:
        raise ExperimentError(f"{where}: sensors.gnss: {e}") from None
    states_of: dict[str, tuple[str, ...]] = {}
    for i, entry in enumerate(doc["estimators"]):
        et = est_mod.get_estimator(entry["type"])
        cfg = et.config_model.model_validate({k: v for k, v in entry.items() if k not in ("name", "type")})
        states_of[entry["name"]] = et.states
        if et.check is None:
            continue
        try:
            et.check(cfg, scn)
        except ValidationError as e:
            def expected(raw, _type=entry["type"]):
                m = _model_at(tuple(raw[3:]), LooseConfig) if _type == "loose" else None
                return list(m.model_fields) if m is not None else None
            raise ExperimentError(_format_validation(e, where, root, None, prefix=("estimators", i, "config"),
                                                     expected=expected)) from None
        except ValueError as e:
            raise ExperimentError(f"{where}: estimators.{i} ({entry['name']}): {e}") from None
    st = exp.statistics
    seg_names = [r["name"] for r in cm.table]
    for wname, w in st.windows.items():
        if w.segment is not None and w.segment not in seg_names:
            raise ExperimentError(f"{where}: statistics.windows.{wname}.segment: no segment named "
                                  f"{w.segment!r} (segments: {', '.join(seg_names)})")
        if w.last_s is not None and w.last_s > cm.duration_s:
            raise ExperimentError(f"{where}: statistics.windows.{wname}.last_s: {w.last_s:g} s is longer "
                                  f"than the run ({cm.duration_s:g} s)")
        if w.start_s is not None and w.start_s >= cm.duration_s:
            raise ExperimentError(f"{where}: statistics.windows.{wname}.start_s: {w.start_s:g} s is after "
                                  f"the end of the run ({cm.duration_s:g} s)")
    avail = {q for s in states_of.values() for q in available_quantities(s)}
    for j, q in enumerate(st.quantities or []):
        if q not in avail:
            raise ExperimentError(f"{where}: statistics.quantities.{j}: unknown quantity {q!r} "
                                  f"(expected one of: {', '.join(sorted(avail))})")
    for cname, c in st.convergence.items():
        if c.quantity not in avail:
            raise ExperimentError(f"{where}: statistics.convergence.{cname}.quantity: unknown quantity "
                                  f"{c.quantity!r} (expected one of: {', '.join(sorted(avail))})")
    return scn, cm.table, cm.duration_s


def _sweep_points(doc: dict, where: str) -> list[tuple[dict[str, Any], list[tuple[list, Any]]]]:
    sweep: dict = doc["sweep"]
    if not sweep:
        return [({}, [])]
    resolved = {p: _resolve_path(doc, p, where) for p in sweep}
    seen: dict[tuple, str] = {}
    for p, parts in resolved.items():
        t = tuple(parts)
        for q, other in seen.items():
            if t[:len(q)] == q or q[:len(t)] == t:
                raise ExperimentError(f"{where}: sweep: {p!r} and {other!r} address the same parameter")
        seen[t] = p
    paths = list(sweep)
    if doc["sweep_mode"] == "zip":
        n = {len(v) for v in sweep.values()}
        if len(n) > 1:
            raise ExperimentError(f"{where}: sweep: sweep_mode zip needs lists of equal length, got "
                                  + ", ".join(f"{p}: {len(v)}" for p, v in sweep.items()))
        combos = list(zip(*sweep.values(), strict=True))
    else:
        combos = list(itertools.product(*sweep.values()))
    return [({p: v for p, v in zip(paths, c, strict=True)},
             [(resolved[p], v) for p, v in zip(paths, c, strict=True)]) for c in combos]


def parse_experiment(data, where: str = "<experiment>", root=None, base_dir=None,
                     text: str | None = None) -> ExperimentPlan:
    """Validate an experiment given as a dict (the parsed YAML) and expand its sweep.

    ``base_dir``: directory for a ``scenario:`` given as a file path (default: the current directory).
    Every sweep point is validated (schema, flyable motion, sensor specs, estimator configurations,
    statistics) before returning; raises :class:`ExperimentError` naming the key otherwise.
    """
    if not isinstance(data, dict):
        raise ExperimentError(f"{where}: an experiment must be a mapping of keys (got {type(data).__name__})")
    data = dict(data)
    scen = data.get("scenario")
    if isinstance(scen, str):
        p = Path(scen)
        if not p.is_absolute():
            p = Path(base_dir or ".") / p
        try:
            scn = load_scenario(p)
        except ScenarioError as e:
            raise ExperimentError(f"{where}: scenario: {e}") from None
        except OSError as e:
            raise ExperimentError(f"{where}: scenario: cannot read {p}: {e}") from None
        data["scenario"] = {"initial": scn.initial.model_dump(), "imu_rate_hz": scn.imu_rate_hz,
                            "transition_s": scn.transition_s,
                            "segments": [s.model_dump(exclude_none=True) for s in scn.segments]}
        over = data.get("sensors") or {}
        if not isinstance(over, dict):
            raise ExperimentError(f"{where}: sensors: must be a mapping")
        data["sensors"] = _deep_merge(scn.sensors.model_dump(exclude_unset=True), over)
    exp, doc = _validate_doc(data, where, root)
    # problems of the base experiment are reported as such (not as a sweep point's), unless the sweep
    # changes what is wrong (then every point is checked below)
    try:
        base_check = _check_point(exp, doc, where, root)
        base_error = None
    except ExperimentError as e:
        base_check, base_error = None, e
    points: list[SweepPoint] = []
    for i, (values, sets) in enumerate(_sweep_points(doc, where)):
        pdoc = copy.deepcopy(doc)
        for parts, v in sets:
            _set_path(pdoc, parts, v)
        label = ", ".join(f"{p}={_label_value(v)}" for p, v in values.items()) or "base"
        pwhere = where if not values else f"{where}: sweep point {label}"
        pdoc_valid = dict(pdoc)
        pdoc_valid["sweep"] = {}
        pexp, pcanon = _validate_doc(pdoc_valid, pwhere) if values else (exp, doc)
        pcanon = copy.deepcopy(pcanon)
        pcanon["sweep"] = {}
        if not values and base_check is not None:
            scn, table, duration = base_check
        else:
            try:
                scn, table, duration = _check_point(pexp, pcanon, pwhere)
            except ExperimentError:
                if base_error is not None:
                    raise base_error from None
                raise
        points.append(SweepPoint(index=i, values=values, label=label, doc=pcanon, experiment=pexp,
                                 scenario=scn,
                                 segments=table, duration_s=duration, key=_point_key(pcanon)))
    keys = [p.key for p in points]
    if len(set(keys)) != len(keys):
        dup = [p.label for p in points if keys.count(p.key) > 1]
        raise ExperimentError(f"{where}: sweep: points {', '.join(dup)} are the same experiment")
    _check_paper(exp, doc, points, where)
    return ExperimentPlan(experiment=exp, doc=doc, points=points, source=where, text=text,
                          estimators=[e.name for e in exp.estimators])


def _check_paper(exp: Experiment, doc: dict, points: list[SweepPoint], where: str) -> None:
    cols = set(statistic_columns(exp.statistics, [(e["name"], est_mod.get_estimator(e["type"]).states)
                                                  for e in doc["estimators"]]))
    names = [e.name for e in exp.estimators]
    for j, pv in enumerate(exp.paper):
        if pv.column not in cols:
            raise ExperimentError(f"{where}: paper.{j}.column: no statistic {pv.column!r} (columns: "
                                  f"{', '.join(sorted(cols))})")
        if pv.estimator is not None and pv.estimator not in names:
            raise ExperimentError(f"{where}: paper.{j}.estimator: no estimator {pv.estimator!r} "
                                  f"(estimators: {', '.join(names)})")
        for path in pv.point:
            if path not in doc["sweep"]:
                raise ExperimentError(f"{where}: paper.{j}.point: {path!r} is not a sweep path "
                                      f"(sweep: {', '.join(doc['sweep']) or 'none'})")
        if not any(all(p.values.get(k) == v for k, v in pv.point.items()) for p in points):
            raise ExperimentError(f"{where}: paper.{j}.point: no sweep point matches {pv.point}")
        if pv.target is not None:
            try:
                check_expression(pv.target, {"ours", "paper"})
            except ValueError as e:
                raise ExperimentError(f"{where}: paper.{j}.target: {e}") from None


def load_experiment(path) -> ExperimentPlan:
    """Read, validate and expand an experiment YAML file (see the module docstring).

    Raises :class:`ExperimentError` (file, line, key path, problem) for anything that cannot be run.
    """
    p = Path(path)
    where = p.name
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise ExperimentError(f"{p}: cannot read: {e.strerror or e}") from None
    except UnicodeDecodeError as e:
        raise ExperimentError(f"{p}: not a text file (byte {e.start} is not UTF-8): an experiment is a "
                              "YAML text file — give the .yaml file (see examples/experiment_quick.yaml)") \
            from None
    try:
        root = yaml.compose(text)
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise ExperimentError(f"{where}: not valid YAML: {e}") from None
    if data is None:
        raise ExperimentError(f"{where}: the file is empty")
    return parse_experiment(data, where, root=root, base_dir=p.parent, text=text)
