"""Outputs appear whole or not at all, and a run that did not complete is never scored (issue 37).

A `process` killed (SIGKILL: no clean-up at all) while it writes leaves its directory marked
``running``; `evaluate` on it exits 2 naming the incomplete run; the previous run's files are gone, not
presented as the new ones; the next run removes the killed run's ``.part`` and spool files."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from aidnav.io.atomic import IncompleteRunError, check_complete, mark_running, remove_stale, replacing


def cli(*args):
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    env.pop("AIDNAV_DEBUG", None)
    r = subprocess.run([sys.executable, "-m", "aidnav", *map(str, args)], capture_output=True, text=True,
                       env=env, timeout=900)
    return r.returncode, r.stdout + r.stderr


def killed_while_writing(d: Path, *args) -> None:
    """Start `aidnav process … -o d`, SIGKILL it once the filter writes (a ``.part`` or a spool file)."""
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    p = subprocess.Popen([sys.executable, "-m", "aidnav", *map(str, args), "-o", str(d)],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    t0 = time.monotonic()
    while time.monotonic() - t0 < 300:
        if p.poll() is not None:
            pytest.fail("the run completed before it could be killed")
        if d.is_dir() and any(x.suffix in (".part", ".spool") for x in d.iterdir()):
            time.sleep(0.3)
            break
        time.sleep(0.02)
    p.send_signal(signal.SIGKILL)
    p.wait()


def test_replacing_leaves_nothing_on_error(tmp_path):
    target = tmp_path / "a.txt"
    target.write_text("old")
    with pytest.raises(KeyboardInterrupt), replacing(target) as tmp:
        tmp.write_text("half")
        raise KeyboardInterrupt
    assert target.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]
    with replacing(target) as tmp:
        tmp.write_text("new")
    assert target.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


def test_status_and_stale_files(tmp_path):
    (tmp_path / "trajectory.csv").write_text("time\n1\n")
    (tmp_path / "tmpabc.spool").write_bytes(b"x")
    (tmp_path / "trajectory.parquet.part").write_bytes(b"x")
    mark_running(tmp_path, "process", ["trajectory.csv"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]
    (tmp_path / "trajectory.csv").write_text("time\n1\n")
    with pytest.raises(IncompleteRunError, match="did not complete"):
        check_complete(tmp_path / "trajectory.csv")
    done = {"status": "complete", "files": ["trajectory.parquet"]}
    (tmp_path / "summary.json").write_text(json.dumps(done))
    with pytest.raises(IncompleteRunError, match="stale"):
        check_complete(tmp_path / "trajectory.csv")
    check_complete(tmp_path / "summary.json")
    (tmp_path / "summary.json").write_text(json.dumps({"imu": "x"}))  # before issue 37: no status
    check_complete(tmp_path / "trajectory.csv")
    assert remove_stale(tmp_path / "nothing") == []


@pytest.mark.slow
def test_killed_runs_are_refused(data_dir, tmp_path):
    w1 = data_dir / "sim_w1_pyins"
    if not (w1 / "imu.parquet").exists():
        pytest.skip("sim_w1_pyins not present")
    args = ["process", "--imu", w1 / "imu.parquet", "--gnss", w1 / "gnss.csv", "--no-figures"]
    truth = w1 / "truth_10hz.parquet"
    d = tmp_path / "run"
    rc, out = cli(*args, "-o", d)
    assert rc == 0, out
    assert json.loads((d / "summary.json").read_text())["status"] == "complete"
    rc, out = cli("evaluate", "--estimate", d / "trajectory.parquet", "--truth", truth)
    assert rc == 0, out

    # a --smooth run killed: the previous run's trajectory is not left to be scored as the new one
    killed_while_writing(d, *args, "--smooth")
    assert json.loads((d / "summary.json").read_text())["status"] == "running"
    assert not (d / "trajectory.parquet").exists()
    rc, out = cli("evaluate", "--estimate", d / "trajectory.parquet", "--truth", truth)
    assert rc == 2 and "did not complete" in out and str(d) in out, out
    assert "Traceback" not in out

    # a --format csv run killed while writing: no truncated trajectory.csv is scored
    killed_while_writing(d, *args, "--format", "csv")
    rc, out = cli("evaluate", "--estimate", d / "trajectory.csv", "--truth", truth)
    assert rc == 2 and "did not complete" in out, out
    assert any(p.suffix in (".part", ".spool") for p in d.iterdir())  # what the kill left ...

    rc, out = cli(*args, "--format", "csv", "-o", d)
    assert rc == 0, out
    assert not any(p.suffix in (".part", ".spool") for p in d.iterdir())  # ... the next run removed
    doc = json.loads((d / "summary.json").read_text())
    assert doc["status"] == "complete" and "trajectory.csv" in doc["files"]
    rc, out = cli("evaluate", "--estimate", d / "trajectory.csv", "--truth", truth)
    assert rc == 0, out
