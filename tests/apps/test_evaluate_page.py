"""``aidnav evaluate`` writes a page, linked from the run's page when the estimate is a process output
(issue 38), and a simulated clock is not labelled GPS time."""

from __future__ import annotations

import json

import numpy as np

from aidnav.apps.evaluate import evaluate_files
from aidnav.data import Trajectory
from aidnav.io.interchange import write_trajectory
from aidnav.report.run_page import write_run_page


def _traj(dx=0.0):
    n = 200
    t = 10.0 + 0.1 * np.arange(n)  # a simulated clock: no GPS week
    lat = np.radians(30.0) + 1e-7 * np.arange(n) + dx
    return Trajectory(t, lat, np.full(n, np.radians(114.0)), np.full(n, 20.0), np.zeros((n, 3)),
                      np.zeros((n, 3)), std_pos=np.tile([0.5, 0.5, 1.0], (n, 1)))


def test_evaluation_page_linked_from_run_page(tmp_path):
    run = tmp_path / "run"
    est = write_trajectory(_traj(1e-7), run / "trajectory.parquet")
    (run / "summary.json").write_text(json.dumps({"imu": "imu.csv", "gnss": "gnss.csv"}))
    write_run_page(run / "run.html", {"imu": "imu.csv", "gnss": "gnss.csv"})
    truth = write_trajectory(_traj(), tmp_path / "truth.csv")
    _, written = evaluate_files(est, truth, out_dir=tmp_path / "ev")
    page = tmp_path / "ev" / "evaluation.html"
    assert page in written and "<table" in page.read_text() and "<img" in page.read_text()
    run_html = (run / "run.html").read_text()
    assert "Evaluation against a reference" in run_html and "../ev/evaluation.html" in run_html
    assert json.loads((run / "summary.json").read_text())["evaluation"]["page"] == "../ev/evaluation.html"
    ej = json.loads((tmp_path / "ev" / "errors.json").read_text())
    assert ej["time_scale"] == "the files' own clock, no GPS week"  # no GPS week in either file
