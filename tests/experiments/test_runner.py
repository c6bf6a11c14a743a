"""Campaign runner: identical results on every backend, resuming, NEES of tuned vs mis-tuned filters."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys

import numpy as np
import pyarrow.parquet as pq
import pytest

from aidnav.experiments import run_inputs, runner, store
from aidnav.experiments.runner import CampaignInterrupted, run_experiment

TABLES = ("runs.parquet", "epochs.parquet")


def _same_tables(a, b):
    for name in TABLES:
        ta, tb = pq.read_table(a / name), pq.read_table(b / name)
        assert ta.equals(tb), name
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


def test_tiny_campaign_tables(tiny_serial):
    out, res = tiny_serial
    assert res.complete and res.computed == 6 and res.reused == 0
    runs = pq.read_table(out / "runs.parquet").to_pydict()
    assert runs["point"] == [0, 0, 0, 1, 1, 1]
    assert runs["run"] == [0, 1, 2, 0, 1, 2]
    assert runs["imu.grade"] == ["tactical"] * 3 + ["mems"] * 3
    assert runs["estimator"] == ["loose"] * 6
    for c in ("std_AB_pos_h_m", "rms_CD_heading_deg", "rms_last5_vel_h_m_s", "converge_h1_s",
              "nees_pos_mean"):
        assert c in runs and all(np.isfinite(runs[c])), c
    ep = pq.read_table(out / "epochs.parquet").to_pydict()
    assert set(ep["point"]) == {0, 1}
    t = np.array(ep["time_s"])[np.array(ep["point"]) == 0]
    assert np.allclose(np.diff(t), 0.5)  # the GNSS rate (2 Hz)
    for c in ("pos_e_m_mean", "pos_e_m_std", "pos_e_m_rms", "pos_e_m_sigma", "att_u_deg_sigma", "nees_att"):
        assert c in ep, c
    # nothing run-dependent in the tables
    cols = list(runs) + list(ep)
    assert not any(w in c for c in cols for w in ("wall", "host", "timing", "elapsed", "seconds"))
    man = json.loads((out / "manifest.json").read_text())
    assert man["seeds"]["base_seed"] == 7 and man["runs"] == 3
    assert man["experiment"]["text"].startswith("name: tiny")
    assert man["timings"]["computed_runs"] == 6 and man["host"]["node"]
    assert [p["label"] for p in man["points"]] == ["imu.grade=tactical", "imu.grade=mems"]


_DASK_CAMPAIGN = """
import logging, sys
from distributed import LocalCluster
from aidnav.experiments.runner import run_experiment
with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                  silence_logs=logging.ERROR) as cluster:
    r = run_experiment(sys.argv[1], sys.argv[2], scheduler=cluster.scheduler_address, progress=False)
print(r.complete, r.computed)
"""


@pytest.mark.slow
def test_identical_serial_processes_and_dask(tiny_file, tiny_serial, tmp_path):
    serial_dir, _ = tiny_serial
    proc = tmp_path / "proc"
    r = run_experiment(tiny_file, proc, workers=2, backend="processes", progress=False)
    assert r.complete and r.computed == 6
    _same_tables(serial_dir, proc)
    # the Dask campaign in a child interpreter: a scheduler run in this process (a local cluster's is) leaves
    # distributed's process-wide offload thread alive until the process ends, and a later test of this
    # process that forks (the figures' processes) needs a process with no other thread (issue 41)
    dsk = tmp_path / "dask"
    run = subprocess.run([sys.executable, "-c", _DASK_CAMPAIGN, str(tiny_file), str(dsk)],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split()[-2:] == ["True", "6"]  # complete, computed
    _same_tables(serial_dir, dsk)
    assert json.loads((dsk / "manifest.json").read_text())["backend"]["kind"] == "dask"


def test_same_runs_bitwise(tiny_serial, tiny_file, tmp_path):
    """Each run file is reproduced bit for bit by a fresh computation."""
    out, _ = tiny_serial
    plan = runner.load_experiment(tiny_file)
    p = plan.points[1]
    res = runner.run_task(runner.RunTask(p.key, p.index, 2, p.doc))
    old = store.load_run(store.run_path(out, p.key, 2))
    for k in ("time", "error", "sigma", "nees"):
        assert np.array_equal(res["estimators"]["loose"][k], old["estimators"]["loose"][k]), k


def test_resume_after_limit(tiny_file, tiny_serial, tmp_path, monkeypatch):
    out = tmp_path / "c"
    r1 = run_experiment(tiny_file, out, max_runs=4, progress=False)
    assert not r1.complete and r1.computed == 4
    assert not (out / "runs.parquet").exists()
    files = sorted((out / "runs").rglob("*.npz"))
    assert len(files) == 4
    before = {f: (f.stat().st_mtime_ns, f.read_bytes()) for f in files}
    calls = []
    real = runner.run_batch_task

    def spy(task):  # the runs computed (a task is a batch of runs of one point)
        calls.extend((task.key, r) for r in task.runs)
        return real(task)

    monkeypatch.setattr(runner, "run_batch_task", spy)
    r2 = run_experiment(tiny_file, out, progress=False)
    assert r2.complete and r2.computed == 2 and r2.reused == 4
    assert len(calls) == 2
    assert not any(store.run_path(out, k, r) in before for k, r in calls)
    for f, (mtime, data) in before.items():
        assert f.stat().st_mtime_ns == mtime and f.read_bytes() == data
    _same_tables(tiny_serial[0], out)
    # a third call recomputes nothing and rewrites identical tables
    calls.clear()
    r3 = run_experiment(tiny_file, out, progress=False)
    assert r3.computed == 0 and r3.reused == 6 and not calls
    _same_tables(tiny_serial[0], out)


def test_resume_from_prepopulated_runs(tiny_file, tiny_serial, tmp_path):
    """DIR/runs pre-populated with a subset of runs (one of them truncated by a kill mid-write)."""
    src, _ = tiny_serial
    out = tmp_path / "pre"
    files = sorted((src / "runs").rglob("*.npz"))
    for f in files[:3]:
        dst = out / f.relative_to(src)
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(f, dst)
    broken = out / files[3].relative_to(src)
    broken.parent.mkdir(parents=True, exist_ok=True)
    broken.write_bytes(files[3].read_bytes()[:1000])
    r = run_experiment(tiny_file, out, progress=False)
    assert r.complete and r.reused == 3 and r.computed == 3
    _same_tables(src, out)


def test_keyboard_interrupt_keeps_finished_runs(tiny_file, tmp_path, monkeypatch):
    out = tmp_path / "k"
    real = runner.run_batch_task
    n = {"calls": 0}

    def flaky(task):
        n["calls"] += 1
        if n["calls"] == 3:
            raise KeyboardInterrupt
        return real(task)

    monkeypatch.setattr(runner, "run_batch_task", flaky)
    with pytest.raises(CampaignInterrupted, match="2 of 6 runs"):
        run_experiment(tiny_file, out, progress=False, batch=1)  # one run a task: interrupted at the third
    assert len(list((out / "runs").rglob("*.npz"))) == 2
    monkeypatch.setattr(runner, "run_batch_task", real)
    r = run_experiment(tiny_file, out, progress=False)
    assert r.complete and r.computed == 4 and r.reused == 2


def test_more_runs_reuses_the_first_ones(tiny_file, tiny_serial, tmp_path):
    """Run k's stream does not depend on the number of runs: extending a campaign reuses its runs."""
    import yaml

    src, _ = tiny_serial
    out = tmp_path / "more"
    shutil.copytree(src / "runs", out / "runs")
    doc = yaml.safe_load(tiny_file.read_text())
    doc["runs"] = 4
    f = tmp_path / "tiny4.yaml"
    f.write_text(yaml.safe_dump(doc))
    r = run_experiment(f, out, progress=False)
    assert r.reused == 6 and r.computed == 2
    a = pq.read_table(src / "runs.parquet").to_pandas()
    b = pq.read_table(out / "runs.parquet").to_pandas()
    b = b[b["run"] < 3].reset_index(drop=True)
    assert a.equals(b)


@pytest.mark.parametrize("rate_hz,latency_s", [(5, 0.3), (1, 0.0), (2, 0.3), (2, 0.013), (50, 0.0)])
def test_gnss_template_matches_simulate_gnss(rate_hz, latency_s):
    from dataclasses import replace

    from aidnav.sim.gnss import GnssSpec, simulate_gnss
    from aidnav.sim.scenario import parse_scenario
    from aidnav.sim.trajectory import generate_truth

    scn = parse_scenario({"initial": {"lat_deg": 45, "lon_deg": 179.9999, "speed_m_s": 30, "heading_deg": 80},
                          "imu_rate_hz": 50,
                          "segments": [{"type": "straight", "duration_s": 10},
                                       {"type": "u_turn", "duration_s": 10}]})
    truth, _, _ = generate_truth(scn)
    spec = GnssSpec(rate_hz=rate_hz, sigma_pos_enu=[1, 2, 3], sigma_vel_enu=[0.1, 0.2, 0.3],
                    lever_arm_b=[0.3, 1.0, 0.5], outages=[(3.0, 2.5)], latency_s=latency_s)
    tmpl = runner.GnssTemplate.build(truth, spec)
    base = simulate_gnss(truth, replace(spec, sigma_pos_enu=np.zeros(3), sigma_vel_enu=np.zeros(3)),
                         np.random.default_rng(0))
    for k in ("time", "lat", "lon", "height", "vel"):  # from the samples around the fixes: the same bits
        assert np.array_equal(getattr(tmpl.base, k), getattr(base, k)), k
    sub = run_inputs._around(truth, tmpl.base.time, latency_s)
    assert (len(sub) < len(truth) / 2) == (rate_hz <= 2)  # the samples around (else the whole truth)
    for seed in (1, 2):
        a = simulate_gnss(truth, spec, np.random.default_rng(seed))
        b = tmpl.draw(np.random.default_rng(seed))
        assert np.array_equal(a.time, b.time)
        for k in ("lat", "lon", "height", "vel", "std_pos", "std_vel"):
            np.testing.assert_allclose(getattr(b, k), getattr(a, k), rtol=0, atol=1e-12, err_msg=k)
        assert a.events == b.events


def test_quick_nees_tuned_consistent_mistuned_flagged(quick_campaign):
    out, res = quick_campaign
    checks = json.loads((out / "consistency.json").read_text())["checks"]
    tuned = [c for c in checks if c["estimator"] == "tuned"]
    bad = [c for c in checks if c["estimator"] == "q_small"]
    assert len(tuned) == 6 and len(bad) == 6  # 2 points x 3 blocks
    for c in tuned:
        assert c["consistent"], c
        lo, hi = c["band"]
        assert lo <= c["mean"] <= hi, c
        assert c["fraction_inside_all_epochs"] >= 0.8, c
    for point in (0, 1):
        flagged = [c for c in bad if c["point"] == point and not c["consistent"]]
        assert len(flagged) >= 2 and all(c["verdict"] == "optimistic" for c in flagged), bad
    # the report flags it
    page = (out / "report.html").read_text()
    rows = re.findall(r"<tr>(.*?)</tr>", page)
    nees_rows = [r for r in rows if "INCONSISTENT" in r or ">consistent<" in r]
    assert nees_rows
    assert all("<td>q_small</td>" in r for r in nees_rows if "INCONSISTENT (optimistic)" in r)
    assert any("<td>q_small</td>" in r and "INCONSISTENT (optimistic)" in r for r in nees_rows)
    assert not any("<td>tuned</td>" in r and "INCONSISTENT" in r for r in nees_rows)


def test_merge_from_memory_equals_merge_from_files(tiny_file, tiny_serial, tmp_path):
    """The campaign's merge takes the runs it has just computed from memory (``_Tally.kept``); merged from
    their files instead (a resumed campaign, or one beyond ``KEEP_BYTES``), the tables are the same bytes."""
    src, res = tiny_serial
    assert res.complete
    out = tmp_path / "from_files"
    shutil.copytree(src / "runs", out / "runs")
    plan = runner.load_experiment(tiny_file)
    store.merge_campaign(plan, out)  # nothing in memory: every run read from its file
    store.write_trajectories(out, plan, runner.point_truth)
    _same_tables(src, out)
    assert (src / "consistency.json").read_bytes() == (out / "consistency.json").read_bytes()
