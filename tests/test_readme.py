"""The README's Python section runs as written (doctest)."""

from __future__ import annotations

import doctest
import os
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


@pytest.mark.slow
def test_readme_python_section():
    cwd = os.getcwd()
    os.chdir(README.parent)
    try:
        res = doctest.testfile(str(README), module_relative=False, optionflags=doctest.ELLIPSIS)
    finally:
        os.chdir(cwd)
    assert res.attempted > 5
    assert res.failed == 0


def _walkthrough_commands() -> list[str]:
    """The bash lines of the README walkthrough (continuations joined, comments and the viewer dropped)."""
    text = README.read_text()
    block = text.split("## Walkthrough", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    block = block.replace("\\\n", " ")
    cmds = []
    for line in block.splitlines():
        line = line.split("#", 1)[0].strip()
        if line.startswith("aidnav "):
            cmds.append(line)
    return cmds


@pytest.mark.slow
def test_readme_walkthrough(tmp_path):
    """simulate → process → evaluate as the README writes them, then the page and figures it promises."""
    import shlex
    import subprocess
    import sys

    cmds = _walkthrough_commands()
    assert [c.split()[1] for c in cmds] == ["simulate", "process", "evaluate"]
    for c in cmds:
        args = shlex.split(c)[1:]
        r = subprocess.run([sys.executable, "-m", "aidnav", *args], cwd=tmp_path, capture_output=True,
                           text=True, timeout=900)
        assert r.returncode == 0, (c, r.stdout, r.stderr)
    run = tmp_path / "out" / "run"
    for f in ("trajectory.parquet", "summary.json", "summary.txt", "overview.png", "run.html",
              "trajectory.kml", "trajectory.geojson", "evaluate/errors.json"):
        assert (run / f).is_file(), f
    html = (run / "run.html").read_text()
    assert "data:image/png;base64," in html
