"""Experiment files: validation before any computation, sweeps, canonical documents."""

from __future__ import annotations

import copy

import pytest

from aidnav.experiments import runner
from aidnav.experiments.config import ExperimentError, load_experiment, parse_experiment


def _bad(tmp_path, tiny_doc, write_exp, mutate, name="bad.yaml"):
    mutate(tiny_doc)
    return write_exp(tmp_path / name, tiny_doc)


@pytest.fixture
def no_compute(monkeypatch):
    """Fail the test if any run is computed."""
    def boom(task):  # pragma: no cover - only called on failure
        raise AssertionError("a run was computed")

    monkeypatch.setattr(runner, "run_task", boom)
    monkeypatch.setattr(runner, "run_batch_task", boom)


@pytest.mark.parametrize("mutate, expected", [
    (lambda d: d.update(runz=3), ["runz", "unknown key", "runs"]),
    (lambda d: d["sensors"]["imu"].update(arw_deg_sqrt=0.1), ["sensors.imu.arw_deg_sqrt", "arw_deg_sqrt_h"]),
    (lambda d: d["estimators"][0].update(q_scal=0.1), ["estimators.0.q_scal", "q_scale"]),
    (lambda d: d["estimators"][0].update(config={"imu": {"arw": 1}}), ["estimators.0.config.imu.arw"]),
    (lambda d: d["scenario"]["segments"][0].update(duration_s="15 min"),
     ["scenario.segments.0.duration_s", "valid number"]),
    (lambda d: (d["scenario"]["segments"][0].pop("duration_s"),
                d["scenario"]["segments"][0].update(duration_min=1)),
     ["scenario.segments.0.duration_min", "duration_s"]),
    (lambda d: d["sensors"]["gnss"].update(rate_hz=-1), ["sensors.gnss.rate_hz", "greater than 0"]),
    (lambda d: (d["sensors"]["imu"].update(grade="militray"), d.update(sweep={})),
     ["sensors.imu", "militray"]),
    (lambda d: d.update(runs=0), ["runs", "greater than or equal to 1"]),
    (lambda d: d.update(sweep={"sensors.imu.grad": ["tactical"]}), ["sweep", "sensors.imu.grad", "'grad'"]),
    (lambda d: d.update(sweep={"trajectory.maneuver": ["figure8"]}),
     ["sweep", "trajectory.maneuver", "'maneuver'"]),
    (lambda d: d.update(sweep={"scenario.segments.EF.duration_s": [1]}), ["sweep", "'EF'", "AB, U, CD"]),
    (lambda d: d.update(sweep={"runs": [1, 2]}), ["sweep", "cannot sweep over 'runs'"]),
    (lambda d: d.update(sweep={"imu.grade": ["tactical", "foo"]}), ["sweep point imu.grade=foo", "'foo'"]),
    (lambda d: d.update(sweep={"imu.grade": []}), ["sweep.imu.grade", "at least 1"]),
    (lambda d: d["estimators"].append({"name": "x", "type": "tight"}), ["estimators.1.type", "'tight'"]),
    (lambda d: d["statistics"]["windows"].update(EF={"segment": "EF"}),
     ["statistics.windows.EF.segment", "'EF'"]),
    (lambda d: d["statistics"]["quantities"].append("pos_x"), ["statistics.quantities.3", "'pos_x'"]),
    (lambda d: d["scenario"]["segments"].insert(0, {"type": "static", "duration_s": 5}),
     ["scenario.segments.0", "moving"]),
    (lambda d: d.update(paper=[{"column": "std_XY_pos_h_m", "paper": 1.0}]),
     ["paper.0.column", "std_XY_pos_h_m"]),
    (lambda d: d.update(paper=[{"column": "std_CD_pos_h_m", "paper": 1.0, "target": "ours < import"}]),
     ["paper.0.target"]),
])
def test_bad_experiment_fails_before_computing(tmp_path, tiny_doc, write_exp, no_compute, mutate, expected):
    path = _bad(tmp_path, tiny_doc, write_exp, mutate)
    out = tmp_path / "out"
    with pytest.raises(ExperimentError) as ei:
        runner.run_experiment(path, out, progress=False)
    msg = str(ei.value)
    assert msg.startswith("bad.yaml"), msg
    for e in expected:
        assert e in msg, msg
    assert not out.exists()  # nothing computed, nothing written


def test_error_names_line(tmp_path, tiny_doc, write_exp):
    path = _bad(tmp_path, tiny_doc, write_exp, lambda d: d["sensors"]["imu"].update(arw_deg_sqrt=0.1))
    with pytest.raises(ExperimentError) as ei:
        load_experiment(path)
    line = next(i for i, t in enumerate(path.read_text().splitlines(), 1) if "arw_deg_sqrt" in t)
    assert str(ei.value).startswith(f"bad.yaml:{line}: ")


def test_not_a_mapping_and_empty(tmp_path):
    p = tmp_path / "e.yaml"
    p.write_text("")
    with pytest.raises(ExperimentError, match="empty"):
        load_experiment(p)
    p.write_text("- 1\n- 2\n")
    with pytest.raises(ExperimentError, match="mapping"):
        load_experiment(p)
    with pytest.raises(ExperimentError, match="cannot read"):
        load_experiment(tmp_path / "missing.yaml")


def test_sweep_grid_zip_and_aliases(tiny_doc):
    d = tiny_doc
    d["sweep"] = {"imu.grade": ["tactical", "mems"], "gnss.rate_hz": [1, 5]}
    plan = parse_experiment(d)
    assert [p.values for p in plan.points] == [
        {"imu.grade": "tactical", "gnss.rate_hz": 1}, {"imu.grade": "tactical", "gnss.rate_hz": 5},
        {"imu.grade": "mems", "gnss.rate_hz": 1}, {"imu.grade": "mems", "gnss.rate_hz": 5}]
    assert plan.points[3].doc["sensors"]["imu"]["grade"] == "mems"
    assert plan.points[3].doc["sensors"]["gnss"]["rate_hz"] == 5
    assert len({p.key for p in plan.points}) == 4
    d["sweep_mode"] = "zip"
    plan = parse_experiment(d)
    assert [p.label for p in plan.points] == ["imu.grade=tactical, gnss.rate_hz=1",
                                              "imu.grade=mems, gnss.rate_hz=5"]
    d["sweep"]["gnss.rate_hz"] = [1, 2, 5]
    with pytest.raises(ExperimentError, match="equal length"):
        parse_experiment(d)


def test_sweep_named_segment_keeps_name_and_estimator_by_name(tiny_doc):
    d = tiny_doc
    d["sweep"] = {"scenario.segments.U": [{"type": "u_turn", "duration_s": 10},
                                          {"type": "o_circle", "duration_s": 20}],
                  "estimators.loose.q_scale": [1.0, 0.01]}
    plan = parse_experiment(d)
    assert len(plan.points) == 4
    seg = plan.points[2].doc["scenario"]["segments"][1]
    assert seg["type"] == "o_circle" and seg["name"] == "U"
    assert plan.points[1].doc["estimators"][0]["q_scale"] == 0.01
    assert plan.points[2].duration_s == pytest.approx(50.0)
    assert plan.points[0].label == "scenario.segments.U=u_turn(duration_s=10), estimators.loose.q_scale=1.0"


def test_point_keys_ignore_statistics_and_runs(tiny_doc):
    a = parse_experiment(copy.deepcopy(tiny_doc))
    d = tiny_doc
    d["runs"] = 50
    d["statistics"] = {"metrics": ["mean"]}
    d["name"] = "other"
    b = parse_experiment(d)
    assert [p.key for p in a.points] == [p.key for p in b.points]
    d["base_seed"] = 8
    c = parse_experiment(d)
    assert [p.key for p in c.points] != [p.key for p in a.points]


def test_scenario_file_reference(tmp_path, tiny_doc, write_exp, quick_file):
    d = tiny_doc
    sub = tmp_path / "a"
    sub.mkdir()
    (sub / "motion.yaml").write_text((quick_file.parent / "none.yaml").read_text())
    d["scenario"] = "motion.yaml"  # relative to the experiment file
    d["sensors"] = {"imu": {"grade": "mems"}}
    d["statistics"]["windows"] = {"CD": {"segment": "CD"}}
    plan = load_experiment(write_exp(sub / "e.yaml", d))
    p = plan.points[0]
    assert [s["name"] for s in p.segments] == ["AB", "U", "CD"]
    assert p.doc["sensors"]["imu"]["grade"] == "tactical"  # swept
    assert p.doc["sensors"]["gnss"]["sigma_pos_m"] == [0.5, 0.5, 1.0]  # from the scenario file


def test_quick_example_is_valid(quick_file):
    plan = load_experiment(quick_file)
    assert len(plan.points) == 2 and plan.runs >= 3
    assert plan.estimators == ["tuned", "q_small"]
    assert all(p.duration_s <= 600 for p in plan.points)
