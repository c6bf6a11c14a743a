"""Campaign report and the run/report commands."""

from __future__ import annotations

import json
import re
import shutil

import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from aidnav.cli import app
from aidnav.experiments.report import ReportError, write_report


def test_quick_report(quick_campaign):
    out, _ = quick_campaign
    page = (out / "report.html").read_text()
    assert page.startswith("<!DOCTYPE html>")
    imgs = re.findall(r'src="data:image/png;base64,', page)
    assert len(imgs) == 1 + 2 * 2 * 2  # map + (errors, NEES) per point and estimator
    assert "src=\"http" not in page and "<script" not in page  # self-contained
    for s in ("Filter consistency (NEES)", "Statistics (mean ± std over the runs)", "std_CD_heading_deg",
              "sensors.imu.grade=tactical | tuned", "sensors.imu.grade=mems | q_small", "Sweep points"):
        assert s in page, s
    st = json.loads((out / "statistics.json").read_text())
    assert {r["column"] for r in st["statistics"]} >= {"rms_last60_pos_h_m", "converge_heading_0.1deg_s"}


def test_paper_values_and_summary_in_report(tiny_serial, tmp_path):
    src, _ = tiny_serial
    out = tmp_path / "c"
    shutil.copytree(src, out)
    man = json.loads((out / "manifest.json").read_text())
    man["experiment"]["document"]["paper"] = [
        {"column": "std_CD_heading_deg", "paper": 1e-6, "point": {"imu.grade": "tactical"},
         "estimator": "loose", "quantity": "heading std CD", "unit": "deg", "target": "ours <= 1.5 * paper"},
        {"column": "rms_all_pos_h_m", "paper": None, "point": {}, "estimator": None, "quantity": None,
         "unit": None, "target": None}]
    (out / "manifest.json").write_text(json.dumps(man))
    (out / "summary.json").write_text(json.dumps({
        "seed": "004", "title": "Transfer alignment", "aidnav_version": "x", "runs": 3, "base_seed": 7,
        "tables": [{"name": "Table 4", "caption": "heading std", "rows": [
            {"quantity": "heading std, none", "unit": "deg", "paper": 0.2483, "ours": 0.21,
             "target": "ours <= 1.2 * paper", "holds": True}]}], "figures": [], "notes": ["erratum E1"]}))
    write_report(out)
    page = (out / "report.html").read_text()
    assert "Paper values beside ours" in page and "heading std CD" in page and "does not hold" in page
    assert "Reproduction of seed 004" in page and "0.2483" in page and "erratum E1" in page
    paper = json.loads((out / "statistics.json").read_text())["paper"]
    assert len(paper) == 1 + 2  # one matching point, then every point for the second entry
    assert paper[0]["holds"] is False and paper[1]["holds"] is None


def test_report_needs_a_campaign(tmp_path):
    with pytest.raises(ReportError, match="not a complete campaign"):
        write_report(tmp_path)
    r = CliRunner().invoke(app, ["report", str(tmp_path)])
    assert r.exit_code == 2 and "aidnav run" in r.output


@pytest.mark.slow
def test_cli_run_workers_and_report(tiny_file, tiny_serial, tmp_path):
    out = tmp_path / "cli"
    r = CliRunner().invoke(app, ["run", str(tiny_file), "-o", str(out), "--workers", "2"])
    assert r.exit_code == 0, r.output
    assert "6 runs (6 computed, 0 reused)" in r.output and "NEES" in r.output
    for name in ("runs.parquet", "epochs.parquet"):
        assert pq.read_table(out / name).equals(pq.read_table(tiny_serial[0] / name))
    assert json.loads((out / "manifest.json").read_text())["backend"]["kind"] == "processes"
    r = CliRunner().invoke(app, ["report", str(out)])
    assert r.exit_code == 0 and (out / "report.html").exists()


def test_cli_run_errors(tmp_path, write_exp):
    bad = write_exp(tmp_path / "bad.yaml", None, runs=0)
    r = CliRunner().invoke(app, ["run", str(bad), "-o", str(tmp_path / "o")])
    assert r.exit_code == 2 and "runs" in r.output and "greater than or equal to 1" in r.output
    assert not (tmp_path / "o").exists()
    ok = write_exp(tmp_path / "ok.yaml")
    r = CliRunner().invoke(app, ["run", str(ok), "-o", str(tmp_path / "o"), "--workers", "2",
                                 "--scheduler", "tcp://x:1"])
    assert r.exit_code == 2 and "not both" in r.output
    r = CliRunner().invoke(app, ["run", str(ok), "-o", str(tmp_path / "o"), "--max-runs", "2"])
    assert r.exit_code == 0 and "2 of 6 runs on disk" in r.output
