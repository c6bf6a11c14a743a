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
