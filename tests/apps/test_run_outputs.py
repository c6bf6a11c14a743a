"""The figures, maps and page of ``aidnav process`` drawn by a forked child (issue 41) are the bytes drawn
in the process itself; the NIS bands of the figures without scipy.stats are scipy's."""

from __future__ import annotations

import shutil
import sys
import threading

import pytest

import aidnav.apps.run_outputs as ro
from aidnav.analysis.consistency import chi2_band
from aidnav.apps.process import job_config, process_logs

from .test_process_stream import static_log

FILES = ("overview.png", "run.html", "trajectory.kml", "trajectory.geojson", "summary.json",
         "trajectory.parquet")


@pytest.mark.skipif(not ro.FORK_OUTPUTS, reason="the figures' process is forked on Linux only")
def test_forked_outputs_are_the_in_process_bytes(tmp_path, monkeypatch):
    """... with the overview's skeleton built by the child before the job (the panels guessed right; the
    skeleton's path whatever the machine's CPU count) and drawn by the child and its helper, which also
    write the maps (the parent only waits)."""
    from aidnav.report.overview import panel_names

    monkeypatch.setattr(ro, "SKELETON_MIN_CPUS", 1)
    monkeypatch.setattr(ro, "SPLIT_MIN_CPUS", 1)

    imu, gnss, cfg = static_log(tmp_path, 30)
    child = ro.OutputsProcess()  # the path under test: a forked child draws
    out = tmp_path / "o"  # (the page names the output folder: the same folder for both)
    sent = []
    child.send = lambda *job, send=child.send, **kw: (sent.append(job), send(*job, **kw))[1]
    process_logs(imu, gnss, cfg, out, outages=["10:5"], figures=child, timings=False)
    assert child.maps_in_child
    _, traj, fixes, _, records = sent[0]
    use = job_config(cfg, None, None, None, None, None, None)[0].gnss.use
    assert ro.expected_panels(use, fixes.vel is not None) == panel_names(traj, fixes, records)
    forked = {name: (out / name).read_bytes() for name in FILES}
    shutil.rmtree(out)
    process_logs(imu, gnss, cfg, out, outages=["10:5"], figures=ro.IN_PROCESS, timings=False)
    hold = threading.Event()
    other = threading.Thread(target=hold.wait)  # another thread running: no fork, drawn here
    other.start()
    try:
        assert ro.start_outputs(True) is True and ro.start_outputs(False) is False
    finally:
        hold.set()
        other.join()
    for name in FILES:
        assert forked[name] == (out / name).read_bytes(), name


@pytest.mark.skipif(not ro.FORK_OUTPUTS, reason="the figures' process is forked on Linux only")
def test_page_shows_the_summary_completed_after_the_overview_job(tmp_path):
    """The overview's job goes to the child before the trajectory file is closed and timed; the page
    (drawn by the child) must show the stages' wall times of the summary completed after it."""
    import json

    imu, gnss, cfg = static_log(tmp_path, 30)
    child = ro.OutputsProcess()
    calls = []
    child.send = lambda *job, send=child.send, **kw: (calls.append(kw), send(*job, **kw))[1]
    out = tmp_path / "o"
    process_logs(imu, gnss, cfg, out, figures=child)
    assert calls == [{"page_follows": True}]  # the job went before the timings were known
    timing = json.loads((out / "summary.json").read_text())["timing_s"]
    page = (out / "run.html").read_text()
    assert timing["filter"] > 0
    for k, v in timing.items():
        assert f"&quot;{k}&quot;: {v!r}" in page, k
    with pytest.raises(RuntimeError):  # one job per child
        child.send_page({})


def test_child_dropped_without_a_job_is_ended(tmp_path):
    if not ro.FORK_OUTPUTS:
        pytest.skip("Linux only")
    import os

    child = ro.OutputsProcess()
    pid = child.pid
    del child  # the job never sent (the run failed before its outputs): the child is ended and reaped
    with pytest.raises(ChildProcessError):
        os.waitpid(pid, os.WNOHANG)


def test_chi2_band_of_one_value_is_scipys():
    from scipy.stats import chi2

    for dof in (1, 2, 3, 6, 15, 40, 999):
        for prob in (0.5, 0.95, 0.999):
            lo, hi = chi2_band(dof, 1, prob)
            assert lo == pytest.approx(chi2.ppf(0.5 * (1 - prob), dof), rel=1e-10)
            assert hi == pytest.approx(chi2.ppf(0.5 * (1 + prob), dof), rel=1e-10)
    assert "scipy.stats" in sys.modules  # (imported by this test only)


def test_figures_child_needs_no_numba():
    """The child is forked before the command imports numba: what it loads and draws with must not import
    numba (nor scipy, pyarrow, pandas), else it pays numba's start (≈ 0.5 CPU-s) for nothing."""
    import subprocess  # lazy: this test only

    code = ("import sys, aidnav.apps.run_outputs as r; r._warm_up(); "
            "from aidnav.report.run_page import write_run_outputs; "
            "print(sorted(m for m in ('numba', 'scipy', 'pyarrow', 'pandas') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr
