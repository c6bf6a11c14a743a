"""overview.png of a processing run (aidnav.report.overview): NIS series and their dof, the tightly
coupled records, the panels and markers of the figure."""

from __future__ import annotations

import os
import struct

import numpy as np
import pytest
from scipy.stats import chi2

from aidnav.analysis.consistency import chi2_band
from aidnav.data import GnssData, Trajectory
from aidnav.report.overview import (
    Skeleton,
    nis_series,
    overview_figure,
    panel_names,
    tight_records,
    write_overview,
)


def _run(n=3000, m=300, seed=0):
    """A 300 s straight run at 10 Hz output with 1 Hz fixes, NIS drawn from χ²(3) / χ²(2)."""
    rng = np.random.default_rng(seed)
    t = 345600.0 + 0.1 * np.arange(n)
    lat = np.radians(30.0) + 1e-7 * np.arange(n)
    lon = np.radians(114.0) + 1e-7 * np.arange(n)
    h = 50.0 + 0.01 * np.arange(n)
    vel = np.tile([1.0, 1.0, 0.0], (n, 1))
    rph = np.tile(np.radians([1.0, -2.0, 45.0]), (n, 1))
    tr = Trajectory(t, lat, lon, h, vel, rph, std_pos=np.full((n, 3), 0.5), std_vel=np.full((n, 3), 0.05),
                    std_att=np.full((n, 3), np.radians(0.2)))
    k = np.arange(0, n, n // m)
    g = GnssData(t[k], lat[k], lon[k], h[k], vel=vel[k], std_pos=np.full((len(k), 3), 0.5))
    pos_innov = rng.standard_normal((len(k), 3))
    vel_innov = rng.standard_normal((len(k), 3))
    vel_innov[:, 2] = np.nan  # vertical velocity not measured: dof 2
    rec = {"pos_status": np.ones(len(k), np.int8), "vel_status": np.ones(len(k), np.int8),
           "pos_innov": pos_innov, "pos_nis": (pos_innov**2).sum(1),
           "vel_innov": vel_innov, "vel_nis": np.nansum(vel_innov**2, 1)}
    rec["pos_status"][7] = 0
    rec["pos_nis"][7] = 500.0  # a rejected fix far above the band
    rec["pos_status"][:3] = -1  # before the start: not used
    rec["pos_nis"][:3] = np.nan
    return tr, g, rec


def test_tight_records_sum_of_scalar_nis():
    rng = np.random.default_rng(4)
    m, s_n = 400, 9
    s = rng.uniform(1.0, 25.0, size=(m, s_n))
    nu = rng.standard_normal((m, s_n)) * np.sqrt(s)
    mask = rng.random((m, s_n)) < 0.3
    nu[mask] = np.nan
    s[mask] = np.nan
    nu[5] = np.nan  # an epoch without measurements
    ep = {"time": np.arange(m, dtype=float), "pr_innov": nu, "pr_s": s, "rate_innov": nu[:, :2],
          "rate_s": s[:, :2]}
    r = tight_records(ep)
    ok = np.isfinite(nu)
    np.testing.assert_array_equal(r["pr_dof"], ok.sum(1))
    i = 10
    np.testing.assert_allclose(r["pr_nis"][i], np.sum(nu[i, ok[i]] ** 2 / s[i, ok[i]]), rtol=1e-12)
    assert np.isnan(r["pr_nis"][5]) and r["pr_dof"][5] == 0
    # the total of consistent innovations is χ²(Σ dof): inside its two-sided 99.9% interval
    tot, dof = np.nansum(r["pr_nis"]), r["pr_dof"].sum()
    assert chi2.ppf(0.0005, dof) < tot < chi2.ppf(0.9995, dof)
    assert set(r) == {"time", "pr_nis", "pr_dof", "rate_nis", "rate_dof"}


def test_nis_series_dof_rules():
    tr, g, rec = _run()
    ser = {s["key"]: s for s in nis_series(rec, g)}
    assert set(ser) == {"pos", "vel"}
    assert np.all(ser["pos"]["dof"] == 3) and np.all(ser["vel"]["dof"] == 2)
    np.testing.assert_array_equal(ser["pos"]["time"], g.time)
    s2 = nis_series({"pos_nis": rec["pos_nis"]}, g)[0]
    assert np.all(s2["dof"] == 3) and s2["status"] is None
    s3 = nis_series({"time": np.arange(4.0), "baro_nis": np.ones(4), "baro_dof": np.ones(4)})[0]
    assert s3["name"] == "baro" and np.all(s3["dof"] == 1)
    with pytest.raises(ValueError, match="no 'time'"):
        nis_series({"pos_nis": np.ones(5)}, g)
    assert nis_series(None) == []


def _legend_labels(ax):
    leg = ax.get_legend()
    return [t.get_text() for t in leg.get_texts()] if leg else []


def test_overview_panels_and_markers():
    tr, g, rec = _run()
    wins = [[g.time[100], g.time[130]], [g.time[200], g.time[215]]]
    summary = {"imu": "/x/imu.csv", "gnss": "/x/gnss.pos", "outage_windows": wins,
               "rejected_fix_times": [float(g.time[7])], "smoothed": True}
    fig = overview_figure(tr, g, summary, rec)
    # map, height, roll/pitch, heading, σ pos, σ att, NIS pos, NIS vel
    assert len(fig.axes) == 8
    map_ax = fig.axes[0]
    labels = _legend_labels(map_ax)
    n_wh = int(sum(((g.time >= a) & (g.time < b)).sum() for a, b in wins))
    assert f"withheld ({n_wh})" in labels and "rejected (1)" in labels and "during outage" in labels
    titles = [ax.get_title() for ax in fig.axes]
    (pos_title,) = [x for x in titles if x.startswith("GNSS position NIS")]
    v = rec["pos_nis"]
    fin = np.isfinite(v)
    lo, hi = chi2_band(3, 1, 0.95)
    inside = 100 * np.mean((v[fin] >= lo) & (v[fin] <= hi))
    assert f"{fin.sum()} updates, {inside:.1f}% inside the band" in pos_title and "dof 3" in pos_title
    (vel_title,) = [x for x in titles if x.startswith("GNSS velocity NIS")]
    assert "dof 2" in vel_title
    pos_ax = fig.axes[titles.index(pos_title)]
    assert pos_ax.get_ylim()[1] < 100  # the 500 of the rejected fix does not set the scale ...
    # ... but is shown on the top edge
    assert any(lab.startswith("above the view (1, max 500") for lab in _legend_labels(pos_ax))
    assert fig.get_suptitle() == "aidnav run: imu.csv + gnss.pos (smoothed)"


def test_no_panel_for_a_type_without_updates():
    tr, g, rec = _run()
    rec = {**rec, "vel_nis": np.full(len(rec["vel_nis"]), np.nan)}  # GNSS without velocities
    fig = overview_figure(tr, g, {}, rec)
    titles = [ax.get_title() for ax in fig.axes]
    assert len(fig.axes) == 7 and not any(x.startswith("GNSS velocity NIS") for x in titles)
    assert any(x.startswith("GNSS position NIS") for x in titles)


def test_rejected_from_summary_without_records():
    tr, g, _ = _run()
    fig = overview_figure(tr, g, {"rejected_fix_times": [float(g.time[3]), float(g.time[9])]})
    assert "rejected (2)" in _legend_labels(fig.axes[0])
    assert len(fig.axes) == 6  # no NIS panel without records


def test_write_overview_png_width(tmp_path):
    tr, g, rec = _run()
    p = write_overview(tmp_path / "o" / "overview.png", tr, g, {}, rec)
    data = p.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    w, h = struct.unpack(">II", data[16:24])
    assert w == 1400 and h > 800
    tr.std_pos = tr.std_att = None
    write_overview(tmp_path / "bare.png", tr)  # no σ, no GNSS, no summary: still a figure
    with pytest.raises(ValueError, match="empty"):
        write_overview(tmp_path / "e.png", Trajectory(*(np.zeros((0,)),) * 4, np.zeros((0, 3)),
                                                      np.zeros((0, 3))))


def test_primed_skeleton_draws_the_same_png(tmp_path):
    """The figures' child builds and draws the overview's skeleton before the run's numbers come: the PNG
    is the one drawn in one go, byte for byte (outages, a rejected fix, both NIS panels); a skeleton of
    other panels, or one used already, is not used."""
    tr, g, rec = _run()
    wins = [[g.time[100], g.time[130]]]
    summary = {"imu": "/x/imu.csv", "gnss": "/x/gnss.pos", "outage_windows": wins}
    one_go = write_overview(tmp_path / "a.png", tr, g, summary, rec).read_bytes()
    right = panel_names(tr, g, rec)
    assert right == ["rp", "heading", "spos", "satt", "nis:pos", "nis:vel"]
    sk = Skeleton(right)
    sk.prime()
    assert write_overview(tmp_path / "b.png", tr, g, summary, rec, skeleton=sk).read_bytes() == one_go
    assert sk.used
    fig = overview_figure(tr, g, summary, rec, skeleton=sk)  # used already: a new figure
    assert fig is not sk.fig
    other = Skeleton(right[:-1])
    assert overview_figure(tr, g, summary, rec, skeleton=other) is not other.fig and not other.used


@pytest.mark.skipif(not hasattr(os, "fork"), reason="the helper is a forked process")
def test_overview_drawn_by_two_processes_is_the_one_drawn_whole(tmp_path):
    """``aidnav process``'s figures' child and its helper each draw half of the panels; the helper's box
    of painted pixels put into the child's canvas gives the PNG drawn whole, byte for byte (outages, a
    rejected fix, both NIS panels). Where the halves would meet (the helper given the first and the last
    panel of the column: its box holds the child's panels), the child draws the figure whole."""
    import pickle

    from aidnav.apps.overview_helper import DrawingHelper, split_panels

    tr, g, rec = _run()
    wins = [[g.time[100], g.time[130]]]
    summary = {"imu": "/x/imu.csv", "gnss": "/x/gnss.pos", "outage_windows": wins}
    whole = write_overview(tmp_path / "a.png", tr, g, summary, rec).read_bytes()
    right = panel_names(tr, g, rec)
    assert split_panels(right) == right[1:]
    for names, parts in ((None, 2), (["rp", "nis:vel"], 1)):
        sk = Skeleton(right)
        sk.prime()
        helper = DrawingHelper.start(sk, 1, names=names)
        job = ("job", str(tmp_path), tr, g, summary, rec, False, False)
        helper.send(pickle.dumps(job), job)
        try:
            png = write_overview(tmp_path / "b.png", tr, g, summary, rec, skeleton=sk, draw=helper.draw)
        finally:
            helper.end()
        assert helper.parts == parts
        assert png.read_bytes() == whole
    # a helper gone before its job (killed): the child draws the figure whole and writes both maps itself
    import signal

    from aidnav.report.maps import write_maps

    sk = Skeleton(right)
    sk.prime()
    helper = DrawingHelper.start(sk, 1)
    os.kill(helper.pid, signal.SIGKILL)
    job = ("job", str(tmp_path / "m"), tr, g, summary, rec, False, True)
    (tmp_path / "m").mkdir()
    helper.send(pickle.dumps(job), job)
    try:
        png = write_overview(tmp_path / "c.png", tr, g, summary, rec, skeleton=sk, draw=helper.draw)
        maps = helper.maps()
    finally:
        helper.end()
    assert helper.parts == 1 and png.read_bytes() == whole
    ref = write_maps(tmp_path / "trajectory", tr, g, summary)  # (the maps' names are the base's)
    assert [p.read_bytes() for p in (maps["kml"], maps["geojson"])] == [p.read_bytes() for p in ref]
