"""KML and GeoJSON exports (aidnav.report.maps): they parse back with fastkml / the geojson package,
carry the layers, and their coordinates round-trip to 1e-9 deg."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from aidnav.data import GnssData, Trajectory
from aidnav.report.maps import SIGMA_CLASSES_M, track_pieces, write_geojson, write_kml, write_maps

TOL_DEG = 1e-9


def _traj(n=600, nan_at=(250,)):
    t = 345600.0 + 0.1 * np.arange(n)
    a = np.linspace(0, 3 * np.pi, n)
    lat = np.radians(30.5 + 1e-3 * np.sin(a)) + 1e-13 * np.arange(n)  # digits beyond 1e-9 deg
    lon = np.radians(114.3 + 2e-3 * a / np.pi)
    h = 20.0 + np.cos(a)
    sig = np.interp(np.arange(n), [0, 100, 300, 400, n - 1], [30.0, 0.5, 0.03, 3.0, 0.1])
    std = np.column_stack([sig, sig, 2 * sig])
    lat[list(nan_at)] = np.nan
    return Trajectory(t, lat, lon, h, np.zeros((n, 3)), np.zeros((n, 3)), std_pos=std)


def _gnss(traj, every=10):
    k = np.arange(0, len(traj.time), every)
    k = k[np.isfinite(traj.lat[k])]
    q = np.where(np.arange(len(k)) % 7 == 3, 2, 1)
    q[5] = 5
    return GnssData(traj.time[k], traj.lat[k], traj.lon[k], traj.height[k] + 0.3,
                    std_pos=np.tile([0.02, 0.02, 0.05], (len(k), 1)), quality=q)


def _expected_track(traj, max_points=20000):
    ok = np.isfinite(traj.lat)
    return np.column_stack([np.degrees(traj.lon[ok]), np.degrees(traj.lat[ok]), traj.height[ok]])


def _dedupe(coords):
    """Concatenated piece coordinates without the boundary points that two pieces share."""
    out = [coords[0]]
    for c in coords[1:]:
        if not np.array_equal(c, out[-1]):
            out.append(c)
    return np.array(out)


def test_track_pieces_follow_sigma_classes():
    tr = _traj(nan_at=())
    pieces, mode, nd = track_pieces(tr, "sigma")
    assert mode == "sigma" and nd == 0
    sig_h = np.hypot(tr.std_pos[:, 0], tr.std_pos[:, 1])
    cls = np.searchsorted(SIGMA_CLASSES_M, sig_h)
    assert len(pieces) == 1 + np.count_nonzero(np.diff(cls))
    for p in pieces:
        # every point except a shared last one is in the piece's class
        assert np.all(cls[p["idx"][:-1]] == p["cls"])
        assert np.all(sig_h[p["idx"][:-1]] <= (SIGMA_CLASSES_M + (np.inf,))[p["cls"]])
    for a, b in zip(pieces[:-1], pieces[1:], strict=True):
        assert a["idx"][-1] == b["idx"][0]  # continuous line


def test_geojson_round_trip_and_layers(tmp_path, monkeypatch):
    import geojson
    import geojson.geometry

    # the geojson package rounds parsed coordinates to DEFAULT_PRECISION = 6 decimals (0.1 m) by default;
    # 15 decimals keep what the file holds
    monkeypatch.setattr(geojson.geometry, "DEFAULT_PRECISION", 15)
    tr = _traj()
    g = _gnss(tr)
    rej_t = [float(g.time[4]), float(g.time[9])]
    wins = [(float(tr.time[300]), float(tr.time[350]))]
    p = write_geojson(tmp_path / "t.geojson", tr, g, outages=wins, rejected_times=rej_t)
    obj = geojson.loads(p.read_text())
    assert obj.is_valid, obj.errors()
    feats = obj["features"]
    layers = {f["properties"]["layer"] for f in feats}
    assert layers == {"trajectory", "gnss", "rejected", "outage"}
    track = [c for f in feats if f["properties"]["layer"] == "trajectory"
             for c in f["geometry"]["coordinates"]]
    got = _dedupe(np.array(track))
    exp = _expected_track(tr)
    # the NaN epoch splits the line: both parts present, nothing else lost
    assert got.shape == exp.shape
    np.testing.assert_allclose(got[:, :2], exp[:, :2], rtol=0, atol=TOL_DEG)
    np.testing.assert_allclose(got[:, 2], exp[:, 2], rtol=0, atol=1e-9)
    assert obj["properties"]["non_finite_epochs_left_out"] == 1
    pts = [f for f in feats if f["geometry"]["type"] == "Point"]
    assert len(pts) == len(g)
    times = np.array([f["properties"]["time_s"] for f in pts])
    order = np.argsort(times)
    xy = np.array([f["geometry"]["coordinates"] for f in pts])[order]
    np.testing.assert_allclose(xy[:, 0], np.degrees(g.lon), rtol=0, atol=TOL_DEG)
    np.testing.assert_allclose(xy[:, 1], np.degrees(g.lat), rtol=0, atol=TOL_DEG)
    rejected = sorted(f["properties"]["time_s"] for f in pts if f["properties"]["layer"] == "rejected")
    assert rejected == rej_t
    q = {f["properties"]["time_s"]: f["properties"]["quality"] for f in pts}
    assert [q[t] for t in g.time] == list(g.quality)
    withheld = [f["properties"]["time_s"] for f in pts if f["properties"]["withheld"]]
    assert withheld == [t for t in g.time if wins[0][0] <= t < wins[0][1]]
    (out,) = [f for f in feats if f["properties"]["layer"] == "outage"]
    oc = np.array(out["geometry"]["coordinates"])
    m = (tr.time >= wins[0][0]) & (tr.time < wins[0][1])
    np.testing.assert_allclose(oc[:, 1], np.degrees(tr.lat[m]), rtol=0, atol=TOL_DEG)
    assert out["properties"]["start_s"] == wins[0][0] and out["properties"]["end_s"] == wins[0][1]
    json.loads(p.read_text())  # strict JSON (no NaN tokens)
    assert "NaN" not in p.read_text()


def _kml_folders(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # lxml absent: no pretty print
        from fastkml import kml

        k = kml.KML.parse(path, strict=True)
    (doc,) = k.features
    return {f.name: list(f.features) for f in doc.features}


def test_kml_round_trip_and_layers(tmp_path):
    tr = _traj()
    g = _gnss(tr)
    rej_t = [float(g.time[2])]
    wins = [(float(tr.time[100]), float(tr.time[120])), (float(tr.time[400]), float(tr.time[450]))]
    p = write_kml(tmp_path / "t.kml", tr, g, outages=wins, rejected_times=rej_t, color_by="sigma")
    folders = _kml_folders(p)
    assert set(folders) == {"trajectory", "gnss", "rejected", "outage"}
    coords = [c for pm in folders["trajectory"] for c in pm.geometry.coords]
    got = _dedupe(np.array(coords))
    exp = _expected_track(tr)
    assert got.shape == exp.shape
    np.testing.assert_allclose(got, exp, rtol=0, atol=TOL_DEG)
    fix = np.array([pm.geometry.coords[0] for pm in folders["gnss"] + folders["rejected"]])
    t_fix = np.array([json.loads(pm.description)["time_s"] for pm in folders["gnss"] + folders["rejected"]])
    o = np.argsort(t_fix)
    np.testing.assert_array_equal(t_fix[o], g.time)
    np.testing.assert_allclose(fix[o, 0], np.degrees(g.lon), rtol=0, atol=TOL_DEG)
    np.testing.assert_allclose(fix[o, 1], np.degrees(g.lat), rtol=0, atol=TOL_DEG)
    np.testing.assert_allclose(fix[o, 2], g.height, rtol=0, atol=1e-9)
    assert [json.loads(pm.description)["time_s"] for pm in folders["rejected"]] == rej_t
    assert len(folders["outage"]) == 2
    assert "sigma" in p.read_text() or "σh" in p.read_text()


def test_colour_by_quality_and_errors(tmp_path):
    tr = _traj(nan_at=())
    tr.extra["quality"] = np.where(np.arange(len(tr.time)) < 300, 1, 2)
    pieces, mode, _ = track_pieces(tr, "auto")
    assert mode == "quality" and [p["cls"] for p in pieces] == [1, 2]
    tr2 = _traj(nan_at=())
    with pytest.raises(ValueError, match="no quality"):
        track_pieces(tr2, "quality")
    with pytest.raises(ValueError, match="color_by"):
        track_pieces(tr2, "speed")
    tr2.std_pos = None
    with pytest.raises(ValueError, match="no position σ"):
        track_pieces(tr2, "sigma")
    assert track_pieces(tr2, "auto")[1] == "none"


def test_decimation_keeps_ends_and_summary_layers(tmp_path):
    tr = _traj(n=5000, nan_at=())
    pieces, _, _ = track_pieces(tr, "sigma", max_points=100)
    idx = np.unique(np.concatenate([p["idx"] for p in pieces]))
    assert idx[0] == 0 and idx[-1] == 4999 and len(idx) <= 101
    summary = {"outage_windows": [[tr.time[10], tr.time[200]]], "rejected_fix_times": []}
    paths = write_maps(tmp_path / "trajectory", tr, _gnss(tr, 50), summary, max_points=100)
    assert [p.name for p in paths] == ["trajectory.kml", "trajectory.geojson"]
    assert "outage" in _kml_folders(paths[0])
