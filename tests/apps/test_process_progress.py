"""``aidnav process`` shows one progress bar on a terminal and nothing of it when piped."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow

SCN = """name: progress
seed: 4
initial: {lat_deg: 30, lon_deg: 114, height_m: 20, speed_m_s: 0, heading_deg: 60}
segments:
  - {type: static, duration_s: 25}
  - {type: accelerate, duration_s: 8, to_speed_m_s: 12}
  - {type: straight, duration_s: 60}
"""


def _env(**kw):
    env = dict(os.environ, **kw)
    env.pop("AIDNAV_PROGRESS", None)
    return env


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    d = tmp_path_factory.mktemp("prog")
    (d / "s.yaml").write_text(SCN)
    r = subprocess.run([sys.executable, "-m", "aidnav", "simulate", str(d / "s.yaml"), "-o", str(d / "sim"),
                        "--format", "parquet"], capture_output=True, text=True, env=_env())
    assert r.returncode == 0, r.stderr
    return d


def _args(d, out):
    return [sys.executable, "-m", "aidnav", "process", "--imu", str(d / "sim/imu.parquet"), "--gnss",
            str(d / "sim/gnss.parquet"), "-o", str(d / out), "--no-figures"]


def test_bar_on_a_pseudo_terminal(sim):
    from aidnav.progress import run_on_terminal

    rc, out = run_on_terminal(_args(sim, "tty"), env=_env(TERM="xterm-256color", COLUMNS="120"))
    assert rc == 0, out[-2000:]
    assert "filter" in out and "━" in out and "ETA" in out, out[-2000:]
    assert "aidnav process:" in out  # the summary after the bar


def test_piped_output_stays_clean(sim):
    r = subprocess.run(_args(sim, "pipe"), capture_output=True, text=True, env=_env(), timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""
    assert "\x1b[" not in r.stdout and "\r" not in r.stdout and "━" not in r.stdout
    assert r.stdout.startswith("aidnav process:")
