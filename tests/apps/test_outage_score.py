"""The outage score without RTK-fixed fixes (issue 38): scored on all withheld fixes, the RMS per quality
beside it; with quality-1 fixes withheld, on those only (as before)."""

from __future__ import annotations

import numpy as np

from aidnav.apps.outages import score_outages, withheld_coverage
from aidnav.data import GnssData, Trajectory
from aidnav.nav.earth import radii


def _case(quality):
    n = 101
    t = np.arange(n, dtype=float)
    lat = np.full(n, np.radians(30.0))
    tr = Trajectory(t, lat, np.zeros(n), np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3)))
    rm, _ = radii(np.radians(30.0))
    # the fixes 1 m (quality 4) or 2 m (quality 5) north of the solution
    off = np.where(quality == 4, 1.0, 2.0) / rm
    g = GnssData(t, lat + off, np.zeros(n), np.zeros(n), quality=quality)
    withheld = (t >= 20) & (t < 40)
    return tr, g, withheld


def test_score_without_quality_1_uses_all_withheld_fixes_per_quality():
    q = np.where(np.arange(101) % 2 == 0, 4, 5)
    tr, g, wh = _case(q)
    s = score_outages(tr, g, [(20.0, 40.0)], wh)
    assert s["n_scored"] == 20 and s["reference"].startswith("all withheld")
    assert s["per_quality"]["4"]["n"] == 10 and abs(s["per_quality"]["4"]["rms_m"] - 1.0) < 1e-6
    assert abs(s["per_quality"]["5"]["rms_m"] - 2.0) < 1e-6
    assert abs(s["rms_m"] - np.sqrt(2.5)) < 1e-6


def test_score_with_quality_1_uses_those_only():
    q = np.where(np.arange(101) % 2 == 0, 1, 5)
    tr, g, wh = _case(q)
    s = score_outages(tr, g, [(20.0, 40.0)], wh)
    assert s["n_scored"] == 10 and set(s["per_quality"]) == {"1"} and "quality 1" in s["reference"]


def test_withheld_coverage_counts_quality_1_fixes_within_3_sigma():
    """Known answer: quality-1 fixes 2 m north of the solution (``_case``), σ_N 0.8 m on half of them (3σ
    covers 2 m) and 0.5 m on the others (it does not): coverage ½ over the withheld quality-1 fixes; none
    withheld, or no quality column: NaN, not a number that looks like a score."""
    q = np.where(np.arange(101) % 2 == 0, 1, 4)  # the quality-4 ones (1 m off) are not counted
    tr, g, wh = _case(q)
    std = np.zeros((101, 3))
    std[:, 0] = 0.5
    std[:, 1] = np.where(np.arange(101) % 4 == 0, 0.8, 0.5)
    tr.std_pos = std
    assert withheld_coverage(tr, g, wh) == 0.5  # quality 1 withheld at t = 20, 22, …, 38; σ 0.8 at 20, 24, …
    assert np.isnan(withheld_coverage(tr, g, np.zeros(101, bool)))
    g.quality = None
    assert np.isnan(withheld_coverage(tr, g, wh))
