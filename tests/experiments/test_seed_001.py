"""Seed-001 reproduction end to end through the CLI (a subprocess, quick settings: 2 runs)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from aidnav.experiments.reproduce.page import browser_layout
from aidnav.experiments.reproduce.summary import _ROW_KEYS, check_row


@pytest.mark.slow
def test_cli_reproduce_001_end_to_end(tmp_path):
    out = tmp_path / "s1"
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    cmd = [sys.executable, "-m", "aidnav.cli", "reproduce", "001", "-o", str(out), "--runs", "2"]
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "Approach, outage and 2 satellites" in r.stdout  # the table on the console
    d = json.loads((out / "summary.json").read_text())
    assert d["seed"] == "001" and d["runs"] == 2
    for t in d["tables"]:
        for row in t["rows"]:
            assert set(row) == set(_ROW_KEYS)
            check_row(row)  # holds and verdict recomputed from the target
    main = [t for t in d["tables"] if t["kind"] != "sensitivity"]
    rows = {r["quantity"]: r for t in main for r in t["rows"]}
    spec = [r for r in rows.values() if r["spec"]]
    assert {q[:3] for q in rows if "sign test" in q} == {"(a)", "(b)"}
    # two runs cannot give p < 0.01: the sign-test rows fail and say why
    for q, row in rows.items():
        if "sign test" in q and row["spec"]:
            assert row["verdict"] == "fails" and "7 runs" in row["reason"]
    assert all(r["verdict"] == "holds" for r in spec if "sign test" not in r["quantity"])
    assert [t["kind"] for t in d["tables"]].count("sensitivity") == 3
    html = (out / "report.html").read_text()
    assert html.count("data:image/png;base64,") == len(d["figures"]) >= 5
    got = browser_layout(out / "report.html", tmp_path / "browser")
    if got is not None:
        assert got[2] == len(d["figures"]) and got[0] <= 1400 and got[1] <= 1400, got
    # `aidnav report` rewrites the page from the summary
    r = subprocess.run([sys.executable, "-m", "aidnav.cli", "report", str(out)], capture_output=True,
                       text=True, env=env, timeout=300)
    assert r.returncode == 0 and (out / "report.html").read_text() == html
