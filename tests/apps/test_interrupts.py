"""Ctrl-C at random moments (issue 37): `aidnav process` on the W1 log and `aidnav run` on a campaign end
with exit status 130 and the message, never a crash; nothing partial is left (no ``.part``, no spool);
the rerun (process) or the resume (run) gives what an uninterrupted run gives.

The moments are drawn with a fixed seed. The issue asks for 20 of each; the test does ``AIDNAV_SIGINT_TRIES``
(default 2 for process, 1 for each kind of run: CI time) — `AIDNAV_SIGINT_TRIES=20` runs the full study."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]
TRIES = os.environ.get("AIDNAV_SIGINT_TRIES")


def _env():
    env = dict(os.environ, PYTHONWARNINGS="ignore", PYTHONFAULTHANDLER="1")
    env.pop("AIDNAV_DEBUG", None)
    return env


def cli(*args):
    r = subprocess.run([sys.executable, "-m", "aidnav", *map(str, args)], capture_output=True, text=True,
                       env=_env(), timeout=900)
    return r.returncode, r.stdout + r.stderr


def _default_sigint():  # a shell's background job inherits SIGINT ignored: a terminal's command does not
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def interrupted(delay: float, *args, sig=signal.SIGINT):
    """Run the command, send ``sig`` after ``delay`` s (SIGINT as a terminal's Ctrl-C would: the process
    group, workers included); (exit status, output)."""
    p = subprocess.Popen([sys.executable, "-m", "aidnav", *map(str, args)], stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True, env=_env(), start_new_session=True,
                         preexec_fn=_default_sigint)
    try:
        out, _ = p.communicate(timeout=delay)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, sig) if sig == signal.SIGINT else p.send_signal(sig)
        out, _ = p.communicate(timeout=600)
    return p.returncode, out


def leftovers(d: Path) -> list[str]:
    return sorted(p.name for p in d.rglob("*") if p.name.endswith(".part") or p.name.endswith(".spool")
                  or ".tmp" in p.name)


def test_sigint_process_w1(data_dir, tmp_path):
    w1 = data_dir / "sim_w1_pyins"
    if not (w1 / "imu.parquet").exists():
        pytest.skip("sim_w1_pyins not present")
    args = ["process", "--imu", w1 / "imu.parquet", "--gnss", w1 / "gnss.csv", "--no-figures"]
    rc, out = cli(*args, "-o", tmp_path / "ref")  # (numba may compile here: not timed)
    assert rc == 0, out
    t0 = time.monotonic()
    rc, out = cli(*args, "-o", tmp_path / "int0")  # a complete run the interrupted ones replace
    wall = time.monotonic() - t0
    assert rc == 0, out
    ref = json.loads((tmp_path / "ref/summary.json").read_text())
    rng = np.random.default_rng(37)
    n = int(TRIES or 2)
    codes = []
    for k, delay in enumerate(rng.uniform(0.3, 0.9, n) * wall):  # moments within a run's duration
        d = tmp_path / f"int{k % 2}"  # two directories: a rerun into an interrupted one as well
        rc, out = interrupted(float(delay), *args, "-o", d)
        codes.append(rc)
        if rc == 0:  # it finished before the signal (a fast machine)
            continue
        assert rc == 130, out
        assert "error: interrupted" in out, out
        assert "Fatal Python error" not in out and "Traceback" not in out, out
        assert leftovers(d) == [], out
        if (d / "summary.json").exists():  # complete only when the signal came after the last file
            done = json.loads((d / "summary.json").read_text())["status"] == "complete"
            assert done == ("are complete" in out), out
    print(f"process W1: exit statuses {codes}")
    assert codes.count(130) >= max(1, n // 2), codes  # (0: it completed before the signal)
    rc, out = cli(*args, "-o", tmp_path / "int0")
    assert rc == 0, out
    again = json.loads((tmp_path / "int0/summary.json").read_text())
    for key in ("calibration", "nis", "counts", "gnss_position_accepted", "final_state"):
        if key in ref:
            assert again[key] == ref[key], key
    a = (tmp_path / "ref/trajectory.parquet").read_bytes()
    b = (tmp_path / "int0/trajectory.parquet").read_bytes()
    assert a == b
    assert leftovers(tmp_path / "int0") == []


@pytest.mark.parametrize("workers", [1, 2])
def test_sigint_campaign(tmp_path, workers):
    exp = REPO / "examples/experiment_quick.yaml"
    extra = ["--workers", "2", "--no-dask"] if workers == 2 else []
    rc, out = cli("run", exp, "-o", tmp_path / "ref", *extra)
    assert rc == 0, out
    rng = np.random.default_rng(370 + workers)
    n = int(TRIES or 1)
    codes = []
    for k, delay in enumerate(rng.uniform(0.5, 4.0, n)):
        for attempt in range(5):  # a campaign that completed before the signal (a fast machine, warm
            # caches) is run again, a fresh campaign, with the signal at half the moment
            d = tmp_path / f"camp{k}_{attempt}"
            rc, out = interrupted(float(delay) / 2**attempt, "run", exp, "-o", d, *extra)
            if rc != 0:
                break
        codes.append(rc)
        if rc == 0:
            continue
        last = d  # the latest interrupted campaign: resumed below
        assert rc == 130, out
        assert "error: interrupted" in out, out
        assert "Fatal Python error" not in out and "Traceback" not in out, out
        assert leftovers(d) == [], out
        assert not (d / "manifest.json").exists()  # `aidnav report` refuses it until resumed
    print(f"campaign, workers={workers}: exit statuses {codes}")
    assert codes.count(130) >= max(1, n // 2), codes  # (0: it completed before the signal)
    d = last
    rc, out = cli("run", exp, "-o", d, *extra)  # resume
    assert rc == 0, out
    assert leftovers(d) == []
    import pandas as pd

    key = ["point", "estimator", "run"]
    a, b = (pd.read_parquet(p / "runs.parquet").sort_values(key).reset_index(drop=True)
            for p in (tmp_path / "ref", d))
    pd.testing.assert_frame_equal(a, b)


_IN_EXEC = """
import signal, time
from aidnav import interrupts
# a terminal's program: SIGINT not ignored (a process of the test run may have inherited SIG_IGN, e.g. a
# pool worker's start-up run in that process; install() then rightly declines, as in a background job)
signal.signal(signal.SIGINT, signal.default_int_handler)
signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGALRM})
assert interrupts.install()
g = {"signal": signal}
try:
    exec("signal.raise_signal(signal.SIGINT)\\nx = 1\\ndone = True", g)  # lands in code run from a string
    time.sleep(1.0)  # the retry (SIGALRM, a few ms) raises it here at the latest
    print("not raised")
except KeyboardInterrupt:
    print("raised", "after" if g.get("done") else "inside")  # the string's code ran to its end first
"""


def test_an_interrupt_in_code_run_from_a_string_is_raised_after_it():
    # CPython 3.11 marks a KeyboardInterrupt that leaves eval/exec of a string as unhandled, even when the
    # program handles it, and then ends itself by SIGINT at its exit (status -2): `aidnav run` interrupted
    # while rich built a named tuple (issue 41, session 13). The interrupt waits until the string's code ends
    r = subprocess.run([sys.executable, "-c", _IN_EXEC], capture_output=True, text=True, env=_env(),
                       timeout=60)
    assert r.returncode == 0, (r.returncode, r.stdout, r.stderr)
    # where the retry lands (right after the string's code, or in the sleep) depends on the machine's load:
    # the string's code ran to its end before it (not "inside"), and the program handled it (status 0)
    assert r.stdout.split("\n")[0] == "raised after", r.stdout
