"""Trajectory design for the distributed POS (seed 004): ``design_trajectory`` and its CLI command."""

from __future__ import annotations

import json

import pytest

from aidnav.experiments.design import design_trajectory, write_design

# small grids keep each design to a few covariance analyses (~0.3 s each)
MODES = ("none", "figure8")
SMALL = {"modes": MODES, "t1_values": (0.0, 200.0), "t2_values": (100.0, 400.0)}


@pytest.fixture(scope="module")
def maneuver_only():
    # none's heading is unobservable (predicted ~0.2 deg); the figure-8's is ~0.002 deg
    req = {"heading_deg": 0.02, "pitch_deg": 0.01, "roll_deg": 0.01}
    return design_trajectory(req, grade="seed004_sub", mc_runs=1, **SMALL)


def test_requirement_only_maneuvers_meet_is_not_none(maneuver_only):
    s = maneuver_only.summary
    assert s["feasible"]
    assert s["recommended"]["mode"] != "none"
    assert s["recommended"]["mode"] == "figure8"
    assert s["recommended"]["t2_s"] == 400.0  # the longest candidate that meets
    none = next(m for m in s["per_mode"] if m["mode"] == "none")
    assert none["plan"] is None
    assert all(not c["meets"] for c in s["candidates"] if c["mode"] == "none")
    mc = s["monte_carlo"]
    assert mc["runs"] == 1 and mc["meets"]
    # the Monte Carlo RMS agrees with the covariance prediction within a factor of ~3 (one run)
    for k in ("heading_deg", "pitch_deg", "roll_deg"):
        assert 0.3 < mc["ratio_to_predicted"][k] < 3.0


def test_loose_requirement_prefers_no_maneuver():
    req = {"heading_deg": 1.0, "pitch_deg": 0.1, "roll_deg": 0.1}
    s = design_trajectory(req, grade="high", mc_runs=0, modes=MODES, t1_values=(200.0,),
                          t2_values=(400.0,)).summary
    assert s["recommended"]["mode"] == "none"  # same T2, shorter flight
    assert s["monte_carlo"] is None


def test_impossible_requirement_reports_no_plan(tmp_path, drawn_png):
    req = {"heading_deg": 1e-5, "pitch_deg": 1e-5, "roll_deg": 1e-5}
    d = design_trajectory(req, grade="sub_arw", mc_runs=2, modes=MODES, t1_values=(0.0,), t2_values=(400.0,))
    s = d.summary
    assert not s["feasible"]
    assert s["recommended"] is None and s["monte_carlo"] is None
    assert "no plan meets" in s["message"]
    assert s["closest"]["worst_ratio"] > 1.0
    paths = write_design(d, tmp_path)
    assert [p.name for p in paths] == ["design.json", "design.png"]
    drawn_png(tmp_path / "design.png")


def test_json_keys(maneuver_only, tmp_path):
    write_design(maneuver_only, tmp_path)
    s = json.loads((tmp_path / "design.json").read_text())
    for key in ("grade", "imu", "requirement", "legs", "baseline_km", "nstate", "feasible", "recommended",
                "closest", "per_mode", "candidates", "monte_carlo", "message", "method",
                "t2_at_candidate_limit", "t1_values_s", "t2_values_s"):
        assert key in s, key
    assert set(s["requirement"]) == {"heading_deg", "pitch_deg", "roll_deg"}
    for key in ("mode", "label", "t1_s", "t2_s", "flight_time_s", "predicted", "worst_ratio", "meets"):
        assert key in s["recommended"], key
    assert len(s["candidates"]) == len(MODES) * 2 * 2
    assert set(s["monte_carlo"]) >= {"runs", "rms", "std", "meets", "ratio_to_predicted"}


def test_bad_grade():
    with pytest.raises(ValueError, match="unknown IMU grade"):
        design_trajectory({"heading_deg": 1, "pitch_deg": 1, "roll_deg": 1}, grade="nope")


def test_cli(tmp_path):
    from typer.testing import CliRunner

    from aidnav.cli import app

    r = CliRunner().invoke(app, ["design-trajectory", "--heading", "1e-5", "--pitch", "1e-5", "--roll",
                                 "1e-5", "--modes", "figure8", "--t1", "0", "--t2", "100", "--mc-runs", "0",
                                 "-o", str(tmp_path)])
    assert r.exit_code == 3, r.output
    assert "no plan meets" in r.output
    assert json.loads((tmp_path / "design.json").read_text())["feasible"] is False
