"""Reproduction pages in a real browser (issue 39): headless Chromium screenshots each report; every table
and figure is visible, nothing is wider than a 1400-px window, and the seeds' Chinese characters (e.g. 精度)
render as glyphs, not as missing-glyph boxes, in the page and in the figures.

The CJK check draws each CJK character of the page on a canvas in the page's font and compares its pixels
with a character no font has (a missing-glyph box) and with a second CJK character (two boxes draw alike).
It needs a CJK font (Debian/Ubuntu: ``apt-get install fonts-noto-cjk``, which ``.ci/run`` installs). The
tests skip only when Chromium is absent. ``AIDNAV_REPRODUCE_DIR`` (a folder written by
``aidnav reproduce all``) adds every seed's real report to the check.
"""

from __future__ import annotations

import json
import os
import shutil
import warnings
from pathlib import Path

import pytest

from aidnav.experiments.reproduce._study import Study, cjk_font
from aidnav.experiments.reproduce.page import browser_check, write_index
from aidnav.experiments.reproduce.summary import grid_table, summary_row, summary_table

WIDTH = 1400


def _chromium_or_skip():
    if not any(shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")):
        pytest.skip("Chromium is not installed (apt-get install chromium): the page checks need a browser")


def _check_page(page: Path, work: Path, n_figures: int) -> dict:
    got = browser_check(page, work, width=WIDTH)
    assert got is not None
    assert got["tables"] >= 1 and got["tables_visible"] == got["tables"], got
    assert got["imgs"] == n_figures and got["imgs_ok"] == n_figures, got
    assert got["maxright"] <= WIDTH and got["scrollw"] <= WIDTH, got
    assert not got["cjk_boxes"], (f"{page}: {got['cjk_boxes']!r} render as boxes in {got['font']!r}: "
                                  "install a CJK font (apt-get install fonts-noto-cjk)")
    assert got["shot"].stat().st_size > 10_000
    return got


def test_report_with_cjk_text_grid_and_figure_in_chromium(tmp_path):
    _chromium_or_skip()
    st = Study("000", "SAPV 精度 test", tmp_path / "seed_000", runs=3)
    assert st.cjk_font is not None and cjk_font() == st.cjk_font, \
        "no CJK font for matplotlib: apt-get install fonts-noto-cjk"
    fig, axs = st.figure(1, 1, w=30.0, h=4.0)  # 3300 px wide: must scale down to the window
    axs[0, 0].plot([0, 1], [2, 1])
    axs[0, 0].set_title("seed: 精度 < 2′")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # matplotlib warns "Glyph … missing from font(s)" for a box
        st.save(fig, "fig_cjk.png")
    cells = {(q, c): summary_row(f"{q} {c}", "arcmin", ours=1.0 + i, paper=2.0, stderr=0.1)
             for i, (q, c) in enumerate([(q, c) for q in ("heading", "pitch") for c in ("mean", "std")])}
    rows = [summary_row("level accuracy (精度) < 2′ " + "x" * 200, "arcmin", ours=1.2, target="ours < lim",
                        values={"lim": 2.0}, spec=True, stderr=0.1),
            summary_row("S / 8 − 1", "-", ours=0.0, target="ours > 0", margin=(0.0, 0.0))]
    doc = st.finish([grid_table("Table 2", "paper-shaped", cells, ["heading", "pitch"], ["mean", "std"], rows,
                                runs=3),
                     summary_table("Sens", "精度 sensitivity", rows[:1], kind="sensitivity")],
                    notes=["the seed's 精度 (accuracy)"], print_tables=False)
    got = _check_page(tmp_path / "seed_000" / "report.html", tmp_path / "b", len(doc["figures"]))
    assert "精" in got["cjk"] and "度" in got["cjk"] and got["tables"] == 3
    text = (tmp_path / "seed_000" / "report.html").read_text()
    assert "1.2 &lt; 2" in text and "structural-null" in text  # the target with its numbers
    _check_page(write_index(tmp_path), tmp_path / "b", 0)


def test_every_reproduction_report_in_chromium(tmp_path):
    """Every report of an ``aidnav reproduce all`` folder (``AIDNAV_REPRODUCE_DIR``), screenshotted."""
    d = os.environ.get("AIDNAV_REPRODUCE_DIR")
    if not d:
        pytest.skip("set AIDNAV_REPRODUCE_DIR to a folder written by `aidnav reproduce all` to check its "
                    "pages")
    _chromium_or_skip()
    pages = sorted(Path(d).glob("seed_*/report.html"))
    assert pages, f"{d}: no seed_*/report.html"
    for page in pages:
        figs = json.loads((page.parent / "summary.json").read_text())["figures"]
        _check_page(page, tmp_path, len(figs))
    _check_page(Path(d) / "index.html", tmp_path, 0)
