"""run.html and report.html in headless Chromium at a 1400-px window: no element wider than the window
(wide data tables scroll inside their own box, and the tables here fit even there), every image loads.
Skips when /usr/bin/chromium is absent."""

from __future__ import annotations

import numpy as np

from aidnav.data import GnssData, Trajectory
from aidnav.report.overview import write_overview
from aidnav.report.run_page import write_run_page

PNG = b"\x89PNG\r\n\x1a\n"


def _check(res, n_images):
    assert res["width"] == 1400
    assert res["scrollWidth"] <= res["width"], "the page scrolls sideways"
    assert res["over"] == [], f"elements past the window: {res['over'][:5]}"
    assert res["overInScroll"] == [] and res["cut"] == [], (res["overInScroll"][:5], res["cut"])
    assert len(res["images"]) == n_images
    bad = [i for i in res["images"] if not (i["complete"] and i["width"] > 0 and i["data"])]
    assert bad == [], f"images that did not load: {bad}"
    assert res["screenshot"].read_bytes()[:8] == PNG


def test_run_page_in_chromium(tmp_path, chromium_layout, run_summary):
    n = 2000
    t = 345600.0 + 0.1 * np.arange(n)
    lat = np.radians(30.0) + 1e-7 * np.arange(n)
    lon = np.full(n, np.radians(114.0))
    tr = Trajectory(t, lat, lon, np.full(n, 10.0), np.zeros((n, 3)), np.zeros((n, 3)),
                    std_pos=np.full((n, 3), 0.3), std_att=np.full((n, 3), 0.01))
    k = np.arange(0, n, 10)
    g = GnssData(t[k], lat[k], lon[k], np.full(len(k), 10.0))
    ov = write_overview(tmp_path / "overview.png", tr, g, run_summary)
    page = write_run_page(tmp_path / "run.html", run_summary, [ov, (ov, "again, with a caption")])
    _check(chromium_layout(page), 2)


def test_campaign_report_in_chromium(tiny_campaign, chromium_layout):
    # the campaign's metadata (long paths, seed scheme) used to push the values off-screen at 1400 px
    _check(chromium_layout(tiny_campaign / "report.html"), 1 + 2 * 2)
