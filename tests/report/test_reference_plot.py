"""The tight page's reference figure and NIS table (issue 38): known differences and known NIS."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.data import GnssData, Trajectory
from aidnav.nav.earth import radii
from aidnav.report.reference_plot import nis_table, reference_differences, write_reference_figure
from aidnav.report.run_page import run_page_html


def _traj(n=100):
    t = 1000.0 + np.arange(n, dtype=float)
    lat = np.radians(30.0) + 1e-6 * np.arange(n)
    lon = np.full(n, np.radians(114.0))
    return Trajectory(t, lat, lon, np.full(n, 50.0), np.zeros((n, 3)), np.zeros((n, 3)))


def test_differences_are_known_and_the_figure_is_written(tmp_path):
    tr = _traj()
    dlat = 2e-7  # the reference 2e-7 rad south: the solution is (R_M + h)·2e-7 m north of it
    k = np.r_[np.arange(0, 100, 5), 99]
    tref = np.r_[tr.time[k[:-1]] + 0.5, 1200.0]  # the last one past the solution's end
    ref = GnssData(tref, np.r_[tr.lat[k[:-1]] + 0.5e-6, 0.0] - dlat, tr.lon[k], tr.height[k] - 1.0)
    t, d = reference_differences(tr, ref)
    rm, _ = radii(np.radians(30.0))
    assert len(t) == 20 and t[-1] == 1095.5  # the epoch at 1200 s lies past the solution's end
    np.testing.assert_allclose(d[:, 1], (rm + 50.0) * dlat, rtol=1e-4)
    np.testing.assert_allclose(d[:, 0], 0.0, atol=1e-6)
    np.testing.assert_allclose(d[:, 2], 1.0, atol=1e-6)
    p = write_reference_figure(tmp_path / "ref.png", tr, ref, ref, "SPP fixes (aidnav)", "reference x.pos",
                               time_scale="GPS SOW")
    assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_nis_table_known_answers_and_its_place_on_the_page():
    n = 400
    rng = np.random.default_rng(3)
    dof = np.full(n, 6)
    rec = {"time": np.arange(n, dtype=float), "pr_nis": rng.chisquare(6, n), "pr_dof": dof,
           "rate_nis": 4.0 * rng.chisquare(5, n), "rate_dof": np.full(n, 5)}
    tab = nis_table(rec)
    assert tab["pr"]["n"] == n and tab["pr"]["dof"] == 6 and tab["pr"]["in_band"]
    lo, hi = tab["pr"]["band95"]
    assert lo < 6 < hi and hi - lo == pytest.approx(2 * 1.96 * np.sqrt(12 / n), rel=0.05)
    assert not tab["rate"]["in_band"]  # four times too large
    html = run_page_html({"obs": "x.obs", "nis": tab, "gnss_label": "SPP fixes (aidnav)"})
    assert "Filter consistency (NIS)" in html and "OUT OF BAND" in html
