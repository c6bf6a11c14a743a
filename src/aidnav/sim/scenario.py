"""Scenario files: pydantic models of the YAML that describes a simulated run.

A scenario gives the initial state, a list of motion *segments* (compiled by
:mod:`aidnav.sim.trajectory`) and the sensor settings (:class:`ImuConfig`, :class:`GnssConfig`).

Units and frames (``docs/conventions.md``): degrees and metres at this boundary (the names carry the
units: ``*_deg``, ``*_m``, ``*_s``, ``*_m_s``, ``*_deg_s``); the trajectory code converts to radians.
Headings are clockwise from true North; turn angles are signed, **positive = clockwise (right)**;
flight-path angles are positive up. Lever arms are in the body frame RFU (x right, y forward, z up).

Every model forbids unknown keys, so a misspelt key gives an error that names it and lists the keys
that were expected. :func:`load_scenario` turns every problem into a :class:`ScenarioError` whose
message names the file, the line (when known) and the key path, e.g.
``figure8.yaml:23: segments.2.rate_deg_s: field required``.

Example::

    name: demo
    seed: 7
    initial: {lat_deg: 40, lon_deg: 116, height_m: 7000, speed_m_s: 100, heading_deg: 40}
    segments:
      - {type: straight, duration_s: 100}
      - {type: turn, angle_deg: 180, rate_deg_s: 0.9, name: U}
      - {type: straight, duration_s: 100, name: CD}
    sensors:
      imu: {grade: tactical}
      gnss: {rate_hz: 1, sigma_pos_m: [0.5, 0.5, 1.0]}
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, model_validator

__all__ = [
    "ScenarioError", "Initial", "StaticSegment", "StraightSegment", "AccelerateSegment", "TurnSegment",
    "ClimbSegment", "STurnsSegment", "OCircleSegment", "Figure8Segment", "UTurnSegment", "Segment",
    "ImuConfig", "GnssConfig", "Outage", "SensorsConfig", "Scenario", "load_scenario", "parse_scenario",
]


class ScenarioError(ValueError):
    """A scenario file that cannot be used; the message names the file, key path and problem."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", validate_default=True)


Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]


# --------------------------------------------------------------------------------------------- initial
class Initial(_Model):
    """Initial state of the vehicle (of the IMU).

    lat_deg, lon_deg : geodetic latitude / longitude [deg]; height_m : ellipsoidal height [m].
    speed_m_s : speed along the velocity vector [m/s] (>= 0).
    roll_deg : constant roll offset [deg] added to the coordinated bank of every turn (0 = wings
    level when not turning). pitch_deg : initial flight-path angle = pitch [deg], nose up positive.
    heading_deg : initial heading = track [deg], clockwise from true North.
    """

    lat_deg: float = Field(ge=-89.0, le=89.0)
    lon_deg: float = Field(ge=-180.0, le=360.0)
    height_m: float = Field(default=0.0, ge=-1000.0, le=1.0e5)
    speed_m_s: NonNegative = 0.0
    roll_deg: float = Field(default=0.0, ge=-90.0, le=90.0)
    pitch_deg: float = Field(default=0.0, ge=-60.0, le=60.0)
    heading_deg: float = Field(default=0.0, ge=-360.0, le=360.0)


# -------------------------------------------------------------------------------------------- segments
class _Segment(_Model):
    name: str | None = Field(default=None, description="label used to find the leg (e.g. 'AB')")


class StaticSegment(_Segment):
    """Standing still for ``duration_s`` [s]; the speed must be 0 when it starts."""

    type: Literal["static"]
    duration_s: Positive


class StraightSegment(_Segment):
    """Constant speed, constant heading and flight-path angle for ``duration_s`` [s]."""

    type: Literal["straight"]
    duration_s: Positive


class AccelerateSegment(_Segment):
    """Constant along-track acceleration over ``duration_s`` [s], straight and at constant flight path.

    Give exactly one of ``accel_m_s2`` [m/s^2] (signed) or ``to_speed_m_s`` [m/s] (final speed).
    """

    type: Literal["accelerate"]
    duration_s: Positive
    accel_m_s2: float | None = None
    to_speed_m_s: NonNegative | None = None

    @model_validator(mode="after")
    def _one_of(self):
        if (self.accel_m_s2 is None) == (self.to_speed_m_s is None):
            raise ValueError("give exactly one of accel_m_s2 or to_speed_m_s")
        return self


class TurnSegment(_Segment):
    """Coordinated level turn through ``angle_deg`` [deg] (signed, + = clockwise/right) at a constant rate.

    Give exactly one of ``rate_deg_s`` [deg/s] (magnitude, > 0), ``radius_m`` [m] (> 0; rate = V/R)
    or ``duration_s`` [s] (rate = angle/duration).
    """

    type: Literal["turn"]
    angle_deg: float
    rate_deg_s: Positive | None = None
    radius_m: Positive | None = None
    duration_s: Positive | None = None

    @model_validator(mode="after")
    def _one_of(self):
        given = [k for k in ("rate_deg_s", "radius_m", "duration_s") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of rate_deg_s, radius_m or duration_s"
                             + (f" (got {', '.join(given)})" if given else ""))
        if self.angle_deg == 0:
            raise ValueError("angle_deg must be non-zero (use a straight segment)")
        return self


class ClimbSegment(_Segment):
    """Climb (or descent) at flight-path angle ``flight_path_deg`` [deg] (+ climb, - descend).

    Alternatively give ``vertical_speed_m_s`` [m/s] (+ up): γ = asin(v_U / V).
    The flight-path angle is changed linearly (constant pitch rate) from its value at the segment
    start to γ over the first ``pull_s`` seconds, held, and brought back to 0 (level) over the last
    ``pull_s`` seconds. ``pull_s`` defaults to min(10 s, duration/5). The altitude change is therefore
    V·sin γ·(duration − pull_s) (about; the transitions of ``transition_s`` are symmetric). A
    simultaneous gentle turn through ``angle_deg`` [deg] (+ = right) at a constant rate over the whole
    segment may be added.
    """

    type: Literal["climb"]
    duration_s: Positive
    flight_path_deg: float | None = Field(default=None, ge=-60.0, le=60.0)
    vertical_speed_m_s: float | None = None
    angle_deg: float = 0.0
    pull_s: Positive | None = None

    @model_validator(mode="after")
    def _one_of(self):
        if (self.flight_path_deg is None) == (self.vertical_speed_m_s is None):
            raise ValueError("give exactly one of flight_path_deg or vertical_speed_m_s")
        if self.pull_s is not None and 2 * self.pull_s > self.duration_s:
            raise ValueError(f"pull_s = {self.pull_s} s is more than half of "
                             f"duration_s = {self.duration_s} s")
        return self

    @property
    def pull_time_s(self) -> float:
        """Duration [s] of the pull-up at the start (and of the push-over at the end)."""
        return self.pull_s if self.pull_s is not None else min(10.0, self.duration_s / 5.0)


class STurnsSegment(_Segment):
    """S-turns: heading swings ±``amplitude_deg`` [deg] about the entry heading, ``n_cycles`` times.

    Net heading change 0. The first swing goes to ``direction`` (right = clockwise). Each cycle is 8
    constant-rate turns whose angles follow A·sin(2π t/T_cycle) at their boundaries (see
    :mod:`aidnav.sim.trajectory`).
    """

    type: Literal["s_turns"]
    duration_s: Positive
    amplitude_deg: float = Field(default=30.0, gt=0.0, le=180.0)
    n_cycles: int = Field(default=1, ge=1)
    direction: Literal["right", "left"] = "right"


class OCircleSegment(_Segment):
    """A full 360° circle at a constant rate over ``duration_s`` [s], to the right or left."""

    type: Literal["o_circle"]
    duration_s: Positive
    direction: Literal["right", "left"] = "right"


class Figure8Segment(_Segment):
    """Two opposite 360° circles (first to ``direction``) over ``duration_s`` [s] in total.

    A short straight of ``transition_s`` separates the circles so that the rate reversal does not cut
    the corner: each circle turns through exactly 360°.
    """

    type: Literal["figure8"]
    duration_s: Positive
    direction: Literal["right", "left"] = "right"


class UTurnSegment(_Segment):
    """A 180° turn at a constant rate over ``duration_s`` [s], to the right or left."""

    type: Literal["u_turn"]
    duration_s: Positive
    direction: Literal["right", "left"] = "right"


Segment = Annotated[
    StaticSegment | StraightSegment | AccelerateSegment | TurnSegment | ClimbSegment | STurnsSegment
    | OCircleSegment | Figure8Segment | UTurnSegment,
    Field(discriminator="type"),
]

SEGMENT_TYPES: dict[str, type[BaseModel]] = {
    "static": StaticSegment, "straight": StraightSegment, "accelerate": AccelerateSegment,
    "turn": TurnSegment, "climb": ClimbSegment, "s_turns": STurnsSegment, "o_circle": OCircleSegment,
    "figure8": Figure8Segment, "u_turn": UTurnSegment,
}


# --------------------------------------------------------------------------------------------- sensors
Vec3 = tuple[float, float, float]
NonNegVec3 = tuple[NonNegative, NonNegative, NonNegative]
PosVec3 = tuple[Positive, Positive, Positive]
_Err = NonNegative | NonNegVec3 | None  # one value for the three axes, or [x, y, z]


class ImuConfig(_Model):
    """IMU error settings. ``grade`` picks a preset (see :mod:`aidnav.sim.imu`); any value given
    here overrides the preset, either one value for all three axes or ``[x, y, z]`` (body RFU).
    Units at this boundary (``docs/conventions.md``):

    gyro_bias_deg_h [deg/h], arw_deg_sqrt_h [deg/√h], accel_bias_ug [μg], vrw_m_s_sqrt_h [m/s/√h],
    gyro_bias_instability_deg_h [deg/h], accel_bias_instability_ug [μg], bias_corr_time_s [s],
    gyro_scale_ppm / accel_scale_ppm [ppm], misalignment_arcsec [arcsec],
    gyro_quant_rad [rad] / accel_quant_m_s [m/s] (increment quantisation, 0 = none).
    ``bias_mode``: "random" (turn-on biases drawn with the given σ, default of the IMU model) or
    "fixed" (the biases are the given values). ``perfect: true`` gives error-free increments.
    """

    grade: str = "tactical"
    gyro_bias_deg_h: float | Vec3 | None = None  # 1σ (random) or signed value (fixed)
    arw_deg_sqrt_h: _Err = None
    accel_bias_ug: float | Vec3 | None = None
    vrw_m_s_sqrt_h: _Err = None
    gyro_bias_instability_deg_h: _Err = None
    accel_bias_instability_ug: _Err = None
    bias_corr_time_s: Positive | PosVec3 | None = None
    gyro_scale_ppm: _Err = None
    accel_scale_ppm: _Err = None
    misalignment_arcsec: _Err = None
    gyro_quant_rad: NonNegative | None = None
    accel_quant_m_s: NonNegative | None = None
    bias_mode: Literal["random", "fixed"] | None = None
    perfect: bool = False

    @model_validator(mode="after")
    def _bias_sign(self):
        if self.bias_mode != "fixed":
            for k in ("gyro_bias_deg_h", "accel_bias_ug"):
                v = getattr(self, k)
                if v is not None and min(v if isinstance(v, tuple) else (v,)) < 0:
                    raise ValueError(f"{k} is a standard deviation (>= 0) unless bias_mode: fixed")
        return self


class Outage(_Model):
    """A GNSS outage: no fixes for ``start_s`` <= t < ``start_s + duration_s`` [s since the start]."""

    start_s: NonNegative
    duration_s: Positive


class GnssConfig(_Model):
    """GNSS receiver settings.

    rate_hz [Hz]; sigma_pos_m : 1σ white position noise [E, N, U] [m]; sigma_vel_m_s : 1σ velocity
    noise [E, N, U] [m/s]; lever_arm_m : antenna position in the body frame RFU [x right, y forward,
    z up] [m]; outages : intervals without fixes; latency_s : fix time-tag delay [s] (>= 0);
    velocity : whether fixes carry velocity.
    """

    rate_hz: Positive = 1.0
    sigma_pos_m: NonNegVec3 = (0.5, 0.5, 1.0)
    sigma_vel_m_s: NonNegVec3 = (0.05, 0.05, 0.1)
    lever_arm_m: Vec3 = (0.0, 0.0, 0.0)
    outages: list[Outage] = Field(default_factory=list)
    latency_s: NonNegative = 0.0
    velocity: bool = True


class SensorsConfig(_Model):
    """The ``sensors`` section: ``imu`` and ``gnss``."""

    imu: ImuConfig = Field(default_factory=ImuConfig)
    gnss: GnssConfig = Field(default_factory=GnssConfig)


# -------------------------------------------------------------------------------------------- scenario
class Scenario(_Model):
    """A complete scenario.

    name, description : labels. seed : base random seed (int). initial : :class:`Initial`.
    imu_rate_hz : IMU sample rate [Hz] (truth is written at the same rate).
    transition_s : width [s] of the raised-cosine smoothing of every command change (acceleration,
    turn rate, flight-path rate); it never exceeds the neighbouring primitive durations.
    segments : the motion, in order. sensors : :class:`SensorsConfig`.
    """

    name: str = "scenario"
    description: str = ""
    seed: int = 1
    initial: Initial
    imu_rate_hz: Positive = 100.0
    transition_s: NonNegative = 4.0
    segments: list[Segment] = Field(min_length=1)
    sensors: SensorsConfig = Field(default_factory=SensorsConfig)

    _source: str | None = PrivateAttr(default=None)

    @property
    def source(self) -> str | None:
        """The file this scenario was read from (None when built in code)."""
        return self._source



# ------------------------------------------------------------------------------------ error reporting
def _expected_keys(loc: tuple) -> list[str] | None:
    """Field names of the model at ``loc`` (pydantic error location), None if not a model."""
    model: Any = Scenario
    i = 0
    while i < len(loc):
        item = loc[i]
        if isinstance(item, int):
            i += 1
            continue
        if model is None or not (isinstance(model, type) and issubclass(model, BaseModel)):
            return None
        if item not in model.model_fields:
            return None
        ann = model.model_fields[item].annotation
        nxt = loc[i + 1] if i + 1 < len(loc) else None
        if item == "segments":
            # loc: segments, <index>, <tag>, ...
            tag = loc[i + 2] if i + 2 < len(loc) else None
            model = SEGMENT_TYPES.get(tag)
            i += 3
            continue
        args = getattr(ann, "__args__", ()) or ()
        cand = [a for a in (ann, *args) if isinstance(a, type) and issubclass(a, BaseModel)]
        if not cand and isinstance(nxt, int):  # list[Model]
            for a in args:
                cand += [b for b in getattr(a, "__args__", ())
                         if isinstance(b, type) and issubclass(b, BaseModel)]
        model = cand[0] if cand else None
        i += 1
    if isinstance(model, type) and issubclass(model, BaseModel):
        return list(model.model_fields)
    return None


def clean_loc(loc: tuple) -> tuple[tuple, str | None]:
    """Drop the tags pydantic inserts in a location: the segment type after a segment index, and the
    member of a scalar-or-[x, y, z] union ("constrained-float", "tuple[...]"). Returns the cleaned
    location and the union member tag (None if there was none)."""
    out = []
    member = None
    skip = False
    for j, item in enumerate(loc):
        if skip:
            skip = False
            continue
        if isinstance(item, str) and ("[" in item or item in ("float", "constrained-float", "int")):
            member = item
            continue
        out.append(item)
        if j >= 1 and loc[j - 1] == "segments" and isinstance(item, int) and j + 1 < len(loc) \
                and loc[j + 1] in SEGMENT_TYPES:
            skip = True
    return tuple(out), member


def _value_at(data, loc: tuple):
    for item in loc:
        try:
            data = data[item]
        except (KeyError, IndexError, TypeError):
            return None
    return data


def yaml_line(root, loc: tuple) -> int | None:
    """1-based line of the YAML node at ``loc`` (the key when the last item is a mapping key)."""
    node = root
    line = None
    for item in loc:
        if isinstance(node, yaml.MappingNode):
            hit = None
            for k, v in node.value:
                if isinstance(k, yaml.ScalarNode) and k.value == item:
                    hit = (k, v)
                    break
            if hit is None:
                break
            line = hit[0].start_mark.line + 1
            node = hit[1]
        elif isinstance(node, yaml.SequenceNode) and isinstance(item, int) and item < len(node.value):
            node = node.value[item]
            line = node.start_mark.line + 1
        else:
            break
    return line


def _format_one(e: dict, loc: tuple, where: str, root) -> str:
    path = ".".join(str(x) for x in loc) or "(top level)"
    msg = error_message(e, loc, _expected_keys(tuple(e["loc"])[:-1]))
    line = yaml_line(root, loc) if root is not None else None
    at = f"{where}:{line}" if line is not None else where
    return f"{at}: {path}: {msg}"


def error_message(e: dict, loc: tuple, keys=None) -> str:
    """Readable message of one pydantic error ``e`` at the cleaned location ``loc``; ``keys``: the keys
    allowed where an unknown key was found (listed in the message). Shared with experiment files."""
    msg = e["msg"]
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, "):]
    elif msg:
        msg = msg[0].lower() + msg[1:]
    if e["type"] == "extra_forbidden":
        msg = f"unknown key '{loc[-1]}'" + (f" (expected one of: {', '.join(keys)})" if keys else "")
    elif e["type"] == "missing" and loc and isinstance(loc[-1], int):
        msg = f"missing value {loc[-1]} (too few values in the list)"
    elif e["type"] == "missing":
        msg = "field required"
    elif e["type"] == "union_tag_invalid":
        msg = (f"unknown segment type {e['input'].get('type')!r} "
               f"(expected one of: {', '.join(SEGMENT_TYPES)})")
    elif e["type"] == "union_tag_not_found":
        msg = f"segment has no 'type' key (expected one of: {', '.join(SEGMENT_TYPES)})"
    return msg


def _format_errors(err: ValidationError, where: str, root=None, data=None) -> str:
    """One line per problem: ``file[:line]: key.path: message``."""
    items = []
    for e in err.errors():
        loc, member = clean_loc(tuple(e["loc"]))
        items.append((_format_one(e, loc, where, root), loc, member))
    return join_error_lines(items, data)


def join_error_lines(items, data) -> str:
    """The message of a validation error from its (text, cleaned loc, union member) items, one line each,
    without repeats. For a scalar-or-[x, y, z] union only the branch that matches what was written (a list
    or not) is reported, unless no error came from that branch. Shared with experiment files."""
    lines: list[str] = []
    other_branch: dict[tuple, list[str]] = {}
    reported: set[tuple] = set()
    for text, loc, member in items:
        if member is not None and loc:
            field_loc = loc[:-1] if isinstance(loc[-1], int) else loc
            if member.startswith("tuple") != isinstance(_value_at(data, field_loc), list):
                other_branch.setdefault(field_loc, []).append(text)
                continue
            reported.add(field_loc)
        if text not in lines:
            lines.append(text)
    for field_loc, texts in other_branch.items():
        if field_loc not in reported:
            lines.extend(t for t in texts if t not in lines)
    return "\n".join(lines)


def parse_scenario(data: dict, where: str = "<scenario>", root=None) -> Scenario:
    """Validate a scenario given as a dict (the parsed YAML); raise :class:`ScenarioError`."""
    if not isinstance(data, dict):
        raise ScenarioError(f"{where}: a scenario must be a mapping of keys (got {type(data).__name__})")
    try:
        scn = Scenario.model_validate(data)
    except ValidationError as e:
        raise ScenarioError(_format_errors(e, where, root, data)) from None
    scn._source = where
    return scn


def load_scenario(path) -> Scenario:
    """Read and validate a scenario YAML file; raise :class:`ScenarioError` naming file, line and key."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ScenarioError(f"{path}: cannot read scenario file ({e.strerror or e})") from None
    except UnicodeDecodeError as e:
        raise ScenarioError(f"{path}: not a text file (byte {e.start} is not UTF-8): a scenario is a YAML "
                            "text file — give the .yaml file (see examples/)") from None
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        at = f"{path}:{mark.line + 1}" if mark is not None else str(path)
        raise ScenarioError(f"{at}: invalid YAML: {getattr(e, 'problem', None) or e}") from None
    if data is None:
        raise ScenarioError(f"{path}: empty scenario file")
    return parse_scenario(data, str(path), root)
