"""Scenario YAML models: the examples load, bad keys and units give messages naming the key and file."""

from __future__ import annotations

from pathlib import Path

import pytest

from aidnav.sim.scenario import (
    ClimbSegment,
    Figure8Segment,
    ImuConfig,
    Scenario,
    ScenarioError,
    STurnsSegment,
    TurnSegment,
    load_scenario,
    parse_scenario,
)

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
MODES = ["none", "s_turns", "o_circle", "figure8", "climb"]

HEAD = """name: t
initial: {lat_deg: 40, lon_deg: 116, height_m: 7000, speed_m_s: 100, heading_deg: 40}
"""


def _write(tmp_path, text, name="scn.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _error(tmp_path, text) -> str:
    p = _write(tmp_path, text)
    with pytest.raises(ScenarioError) as ei:
        load_scenario(p)
    msg = str(ei.value)
    assert str(p) in msg
    return msg


@pytest.mark.parametrize("mode", MODES)
def test_examples_load(mode):
    scn = load_scenario(EXAMPLES / f"{mode}.yaml")
    assert scn.name == mode
    assert scn.initial.lat_deg == 40.0 and scn.initial.lon_deg == 116.0
    assert scn.initial.heading_deg == 40.0 and scn.initial.speed_m_s == 100.0
    assert scn.initial.height_m == (0.0 if mode == "climb" else 7000.0)
    assert scn.sensors.imu.grade == "tactical"
    assert scn.sensors.gnss.rate_hz == 1.0
    names = [s.name for s in scn.segments]
    assert "AB" in names and "CD" in names
    assert scn.source == str(EXAMPLES / f"{mode}.yaml")


def test_examples_start_with_comment_header():
    for mode in MODES:
        first = (EXAMPLES / f"{mode}.yaml").read_text().splitlines()[0]
        assert first.startswith("#") and "Table 3" in first


@pytest.mark.parametrize("mode", ["none", "s_turns", "o_circle", "figure8", "climb"])
def test_packaged_default_equals_example(mode):
    """The five seed-004 motion modes ship inside the package (reproductions need them when aidnav is
    installed without its source tree) and are identical to examples/."""
    packaged = ROOT / "src" / "aidnav" / "sim" / "scenarios" / f"{mode}.yaml"
    assert packaged.read_bytes() == (EXAMPLES / f"{mode}.yaml").read_bytes()
    from aidnav.sim.run import load_default_scenario

    scn = load_default_scenario()
    assert scn.name == "figure8"
    assert isinstance(scn.segments[1], Figure8Segment)


def test_defaults_and_segment_kinds(tmp_path):
    scn = load_scenario(_write(tmp_path, HEAD + """segments:
  - {type: straight, duration_s: 10}
  - {type: turn, angle_deg: -90, radius_m: 2000}
  - {type: s_turns, duration_s: 80}
  - {type: climb, duration_s: 100, flight_path_deg: 3, angle_deg: 20}
  - {type: accelerate, duration_s: 10, to_speed_m_s: 0}
  - {type: static, duration_s: 5}
"""))
    assert scn.seed == 1 and scn.imu_rate_hz == 100.0 and scn.transition_s == 4.0
    assert isinstance(scn.segments[1], TurnSegment) and scn.segments[1].angle_deg == -90
    s = scn.segments[2]
    assert isinstance(s, STurnsSegment) and s.amplitude_deg == 30.0 and s.n_cycles == 1
    c = scn.segments[3]
    assert isinstance(c, ClimbSegment) and c.pull_time_s == 10.0
    assert scn.sensors.gnss.sigma_pos_m == (0.5, 0.5, 1.0)
    assert scn.sensors.gnss.sigma_vel_m_s == (0.05, 0.05, 0.1)
    assert scn.sensors.gnss.lever_arm_m == (0.0, 0.0, 0.0)
    assert scn.sensors.gnss.latency_s == 0.0 and scn.sensors.gnss.velocity is True
    assert scn.sensors.imu == ImuConfig()


def test_unknown_segment_key_names_key_expected_and_line(tmp_path):
    msg = _error(tmp_path, HEAD + """segments:
  - {type: straight, duration_s: 10}
  - type: turn
    angle_deg: 90
    rate_deg: 3
""")
    assert "segments.1.rate_deg" in msg
    assert "unknown key 'rate_deg'" in msg
    assert "rate_deg_s" in msg  # the expected keys are listed
    assert "scn.yaml:7:" in msg  # line of the bad key


def test_missing_required_field(tmp_path):
    msg = _error(tmp_path, HEAD + """segments:
  - {type: straight, duration_s: 10}
  - {type: u_turn}
""")
    assert "segments.1.duration_s: field required" in msg


def test_turn_both_rate_and_radius(tmp_path):
    msg = _error(tmp_path, HEAD + """segments:
  - {type: turn, angle_deg: 90, rate_deg_s: 1, radius_m: 5000}
""")
    assert "segments.0" in msg and "exactly one of rate_deg_s, radius_m or duration_s" in msg


def test_turn_without_rate(tmp_path):
    msg = _error(tmp_path, HEAD + "segments:\n  - {type: turn, angle_deg: 90}\n")
    assert "segments.0" in msg and "exactly one of" in msg


@pytest.mark.parametrize("seg, key", [
    ("{type: straight, duration_s: 0}", "segments.0.duration_s"),
    ("{type: straight, duration_s: -5}", "segments.0.duration_s"),
    ("{type: turn, angle_deg: 90, rate_deg_s: -1}", "segments.0.rate_deg_s"),
    ("{type: turn, angle_deg: 90, radius_m: 0}", "segments.0.radius_m"),
    ("{type: s_turns, duration_s: 100, n_cycles: 0}", "segments.0.n_cycles"),
    ("{type: u_turn, duration_s: 100, direction: up}", "segments.0.direction"),
])
def test_bad_units_name_the_key(tmp_path, seg, key):
    msg = _error(tmp_path, HEAD + f"segments:\n  - {seg}\n")
    assert key in msg


def test_negative_speed(tmp_path):
    msg = _error(tmp_path, """initial: {lat_deg: 40, lon_deg: 116, speed_m_s: -3}
segments: [{type: static, duration_s: 1}]
""")
    assert "initial.speed_m_s" in msg and "greater than or equal to 0" in msg


def test_unknown_segment_type(tmp_path):
    msg = _error(tmp_path, HEAD + "segments:\n  - {type: loop, duration_s: 10}\n")
    assert "segments.0" in msg and "unknown segment type 'loop'" in msg and "figure8" in msg


def test_unknown_top_level_and_sensor_keys(tmp_path):
    msg = _error(tmp_path, HEAD + """segments: [{type: straight, duration_s: 10}]
imu_rate: 200
sensors:
  imu: {grade: tactical, gyro_bias: 1}
  gnss: {outages: [{start_s: 1, dur_s: 2}]}
""")
    assert "imu_rate: unknown key 'imu_rate'" in msg and "imu_rate_hz" in msg
    assert "sensors.imu.gyro_bias: unknown key" in msg and "gyro_bias_deg_h" in msg
    assert "sensors.gnss.outages.0.dur_s: unknown key" in msg


def test_sigma_needs_three_values(tmp_path):
    msg = _error(tmp_path, HEAD + """segments: [{type: straight, duration_s: 10}]
sensors: {gnss: {sigma_pos_m: [1, 2]}}
""")
    assert "sensors.gnss.sigma_pos_m" in msg


def test_climb_options(tmp_path):
    msg = _error(tmp_path, HEAD + "segments:\n  - {type: climb, duration_s: 100}\n")
    assert "flight_path_deg or vertical_speed_m_s" in msg
    msg = _error(tmp_path, HEAD + "segments:\n"
                 "  - {type: climb, duration_s: 100, flight_path_deg: 2, pull_s: 60}\n")
    assert "pull_s" in msg


def test_invalid_yaml_and_empty(tmp_path):
    msg = _error(tmp_path, HEAD + "segments:\n  - {type: straight, duration_s: 10\n")
    assert "invalid YAML" in msg
    msg = _error(tmp_path, "")
    assert "empty" in msg
    msg = _error(tmp_path, "- 1\n- 2\n")
    assert "mapping" in msg


def test_missing_file(tmp_path):
    with pytest.raises(ScenarioError, match="cannot read"):
        load_scenario(tmp_path / "nope.yaml")


def test_parse_dict_and_no_segments():
    with pytest.raises(ScenarioError, match="segments"):
        parse_scenario({"initial": {"lat_deg": 0, "lon_deg": 0}, "segments": []})
    scn = parse_scenario({"initial": {"lat_deg": 0, "lon_deg": 0},
                          "segments": [{"type": "static", "duration_s": 2}]})
    assert isinstance(scn, Scenario)
    assert issubclass(ScenarioError, ValueError)


def test_imu_overrides_per_axis_and_bias_sign(tmp_path):
    scn = load_scenario(_write(tmp_path, HEAD + """segments: [{type: straight, duration_s: 10}]
sensors:
  imu: {grade: tactical, gyro_bias_deg_h: [1, -2, 3], bias_mode: fixed, arw_deg_sqrt_h: 0.01}
""", "ok.yaml"))
    assert scn.sensors.imu.gyro_bias_deg_h == (1.0, -2.0, 3.0)
    assert scn.sensors.imu.arw_deg_sqrt_h == 0.01
    msg = _error(tmp_path, HEAD + """segments: [{type: straight, duration_s: 10}]
sensors: {imu: {gyro_bias_deg_h: -1}}
""")
    assert "sensors.imu" in msg and "gyro_bias_deg_h" in msg and "bias_mode: fixed" in msg
    msg = _error(tmp_path, HEAD + """segments: [{type: straight, duration_s: 10}]
sensors: {imu: {arw_deg_sqrt_h: -1}}
""")
    assert "sensors.imu.arw_deg_sqrt_h: input should be greater than or equal to 0" in msg
    assert "constrained" not in msg and "tuple" not in msg
