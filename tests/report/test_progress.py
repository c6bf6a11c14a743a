"""aidnav.progress: the bar draws on a terminal (a forced-terminal console and a real pseudo-terminal)
and nothing at all is written when the output is piped."""

from __future__ import annotations

import io
import os
import subprocess
import sys

import pytest
from rich.console import Console

from aidnav.progress import NullProgress, ProgressBar, chunks, progress_bar, progress_enabled

SCRIPT = """
import sys
from aidnav.progress import chunks, progress_bar
n = 1_000_000
with progress_bar("filter", total=n, unit="samples") as bar:
    for a, b in chunks(n, 250_000):
        bar.update(b)
    bar.stage("smoother", total=4, unit="chunks")
    for _ in range(4):
        bar.advance(1)
print("result 42")
"""


def _env(**kw):
    env = dict(os.environ)
    env.pop("AIDNAV_PROGRESS", None)
    env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p)
    env.update(kw)
    return env


def test_chunks_cover_the_range():
    assert list(chunks(10, 4)) == [(0, 4), (4, 8), (8, 10)]
    assert list(chunks(0, 4)) == []
    with pytest.raises(ValueError, match="chunk size"):
        list(chunks(10, 0))


def test_bar_draws_on_a_forced_terminal(monkeypatch):
    monkeypatch.delenv("AIDNAV_PROGRESS", raising=False)
    buf = io.StringIO()
    con = Console(file=buf, force_terminal=True, width=120)
    bar = progress_bar("filter", total=1000, unit="samples", console=con)
    assert isinstance(bar, ProgressBar)
    with bar:
        for _, b in chunks(1000, 250):
            bar(b)  # the bar is a callback (done, total)
    out = buf.getvalue()
    assert "━" in out and "ETA" in out and "filter" in out
    assert "1,000/1,000 samples" in out and "100%" in out
    assert "\x1b[" in out  # terminal control sequences


def test_quiet_when_not_a_terminal(monkeypatch):
    monkeypatch.delenv("AIDNAV_PROGRESS", raising=False)
    buf = io.StringIO()
    con = Console(file=buf)  # a StringIO is no terminal
    bar = progress_bar("filter", total=1000, console=con)
    assert isinstance(bar, NullProgress)
    with bar:
        bar.update(500)
        bar.advance(500)
        bar.stage("x", 3)
        bar.log("hidden")
    assert buf.getvalue() == ""
    monkeypatch.setenv("AIDNAV_PROGRESS", "1")
    assert progress_enabled(con)
    monkeypatch.setenv("AIDNAV_PROGRESS", "0")
    assert not progress_enabled(Console(file=io.StringIO(), force_terminal=True))


def test_piped_output_stays_clean():
    r = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=120,
                       env=_env())
    assert r.returncode == 0, r.stderr
    assert r.stdout == "result 42\n"
    assert r.stderr == ""


@pytest.mark.skipif(sys.platform == "win32", reason="needs a POSIX pseudo-terminal")
def test_bar_draws_on_a_pseudo_terminal():
    from aidnav.progress import run_on_terminal

    rc, out = run_on_terminal([sys.executable, "-c", SCRIPT], env=_env(TERM="xterm-256color", COLUMNS="120"),
                              timeout=120)
    assert rc == 0
    assert "filter" in out and "━" in out and "ETA" in out
    assert "smoother" in out and "4/4 chunks" in out
    assert "result 42" in out
