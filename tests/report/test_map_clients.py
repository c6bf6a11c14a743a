"""aidnav's maps and solution files opened by the clients people use (issue 38): KML by fastkml (and
GDAL's ``ogrinfo`` where installed) with absolute altitudes and UTC time stamps, GeoJSON validated by the
``geojson`` package with ISO-8601 UTC times, Parquet field metadata read back with pyarrow."""

from __future__ import annotations

import datetime as dt
import json
import shutil
import subprocess
import warnings

import numpy as np
import pytest

from aidnav.data import GnssData, Trajectory
from aidnav.report.maps import write_geojson, write_kml

WEEK = 2381
SOW0 = 408600.0
N_GEOID = -21.4


def _utc_iso(sow: float) -> str:
    """Independent of aidnav: GPS epoch + week + sow − 18 leap seconds (2025)."""
    t = dt.datetime(1980, 1, 6) + dt.timedelta(weeks=WEEK, seconds=sow - 18)
    return t.strftime("%Y-%m-%dT%H:%M:%S.%f") + "Z"


def _flight(n=300):
    """A 7,000-m flight (the issue's example): 0.5 s apart, climbing."""
    t = SOW0 + 0.5 * np.arange(n)
    lat = np.radians(47.0 + 1e-4 * np.arange(n))
    lon = np.radians(8.0 + 2e-4 * np.arange(n))
    h = 7000.0 + 0.5 * np.arange(n)
    std = np.tile([0.5, 0.5, 1.0], (n, 1))
    tr = Trajectory(t, lat, lon, h, np.zeros((n, 3)), np.zeros((n, 3)), std_pos=std, week=WEEK)
    k = np.arange(0, n, 10)
    g = GnssData(t[k], lat[k], lon[k], h[k], std_pos=np.tile([1.0, 1.0, 2.0], (len(k), 1)),
                 quality=np.full(len(k), 5), week=WEEK)
    return tr, g


def _kml(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # lxml absent: no pretty print
        from fastkml import kml

        k = kml.KML.parse(path, strict=True)
    (doc,) = k.features
    return {f.name: list(f.features) for f in doc.features}


def test_kml_absolute_altitudes_and_times_in_fastkml(tmp_path):
    tr, g = _flight()
    wins = [(SOW0 + 50.0, SOW0 + 60.0)]
    p = write_kml(tmp_path / "f.kml", tr, g, outages=wins, geoid_undulation_m=N_GEOID)
    folders = _kml(p)
    assert set(folders) == {"trajectory", "track", "gnss", "rejected", "outage"}
    lines = folders["trajectory"] + folders["outage"]
    for pm in lines + folders["gnss"]:
        assert pm.kml_geometry.altitude_mode.value == "absolute"
    # altitude above MSL = ellipsoidal height − N
    z = np.array([c[2] for pm in folders["trajectory"] for c in pm.geometry.coords])
    assert z[0] == pytest.approx(7000.0 - N_GEOID)
    # fixes carry their UTC time stamp
    pts = folders["gnss"]
    when = sorted(pm.times.timestamp.dt for pm in pts)
    assert when[0].strftime("%Y-%m-%dT%H:%M:%S.%fZ") == _utc_iso(SOW0)
    # the outage line spans its window in UTC
    span = folders["outage"][0].times
    assert span.begin.dt.strftime("%Y-%m-%dT%H:%M:%S.%fZ") == _utc_iso(SOW0 + 50.0)
    assert span.end.dt.strftime("%Y-%m-%dT%H:%M:%S.%fZ") == _utc_iso(SOW0 + 60.0)
    trk = folders["track"][0].kml_geometry
    assert trk.altitude_mode.value == "absolute"
    # a timed gx:Track (Google Earth's time slider): as many `when` as coordinates, UTC, absolute
    text = p.read_text()
    block = text[text.index("<gx:Track>"):text.index("</gx:Track>")]
    assert block.count("<when>") == block.count("<gx:coord>") == len(tr.time)
    assert f"<when>{_utc_iso(SOW0)}</when>" in text
    assert text.count("<Style ") <= 12, "styles are shared per colour, not written per point"


def test_geojson_validates_and_has_utc_times(tmp_path):
    import geojson

    tr, g = _flight()
    p = write_geojson(tmp_path / "f.geojson", tr, g, outages=[(SOW0 + 50.0, SOW0 + 60.0)])
    obj = geojson.loads(p.read_text())
    assert obj.is_valid, obj.errors()
    for f in obj["features"]:
        assert geojson.GeoJSON.to_instance(f).is_valid
    pts = [f["properties"] for f in obj["features"] if f["properties"]["layer"] == "gnss"]
    assert pts[0]["time"] == _utc_iso(SOW0) and pts[0]["gps_week"] == WEEK and pts[0]["time_s"] == SOW0
    line = next(f["properties"] for f in obj["features"] if f["properties"]["layer"] == "trajectory")
    assert line["time_start"] == _utc_iso(SOW0)
    out = next(f["properties"] for f in obj["features"] if f["properties"]["layer"] == "outage")
    assert out["time_start"] == _utc_iso(SOW0 + 50.0) and out["time_end"] == _utc_iso(SOW0 + 60.0)


@pytest.mark.skipif(shutil.which("ogrinfo") is None, reason="GDAL's ogrinfo not installed (apt-get install "
                    "gdal-bin)")
def test_kml_in_ogrinfo(tmp_path):
    tr, g = _flight()
    p = write_kml(tmp_path / "f.kml", tr, g, geoid_undulation_m=N_GEOID)
    r = subprocess.run(["ogrinfo", "-ro", "-al", str(p)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert "POINT Z (" in out and "LINESTRING Z (" in out, out[:2000]
    # the driver reads the time stamp of each fix and the absolute altitude mode
    stamp = _utc_iso(SOW0)[:19].replace("-", "/").replace("T", " ")  # ogrinfo: 2025/08/28 17:29:42+00
    assert f"timestamp (DateTime) = {stamp}" in out, out[:3000]
    assert "altitudeMode (String) = absolute" in out
    assert f"POINT Z (8.00000000000001 47.0 {7000.0 - N_GEOID:g})" in out


def test_fix_description_is_json_with_utc(tmp_path):
    tr, g = _flight()
    folders = _kml(write_kml(tmp_path / "f.kml", tr, g))
    info = json.loads(folders["gnss"][0].description)
    assert info["time"] == _utc_iso(SOW0) and info["gps_week"] == WEEK
