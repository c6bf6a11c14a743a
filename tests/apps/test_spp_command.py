"""``aidnav spp --obs OBS --nav NAV -o DIR`` on the walk's RINEX files (issue 38): a solution file that
the GNSS readers take, a summary saying what the ionosphere correction was, and a page."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from aidnav.cli import app
from aidnav.io import formats
from aidnav.nav.earth import lla_difference_enu


def test_spp_command_on_the_walk(tmp_path, walk_dir, walk_nav_file):
    d = walk_dir
    r = CliRunner().invoke(app, ["spp", "--obs", str(d / "rinex_converted" / "gnss_1730.obs"), "--nav",
                                 str(walk_nav_file), "-o", str(tmp_path / "s")])
    assert r.exit_code == 0, r.output
    assert "ionosphere:" in r.output
    # by default the UBX log the observation file's header names (one directory up) gives its Galileo
    # I/NAV ephemerides, and the summary says so (issue 40, aidnav.io.nav_sources)
    assert "ephemerides: gnss_1730.nav + gnss_1730.ubx (RXM-SFRBX; auto" in r.output
    s = json.loads((tmp_path / "s" / "summary.json").read_text())
    src = s["ephemerides"]
    assert Path(src["ubx_nav"]) == d / "gnss_1730.ubx" and src["how"].startswith("auto")
    assert len(src["satellites"]["Galileo"]) == 6 and "E14" in src["unhealthy"]  # E14: health word 130
    assert "E" in s["systems"] and "E" in s["inter_system_bias_m_median"]
    assert s["satellites_used_median"] >= 8
    g = formats.read_gnss(tmp_path / "s" / "solution.parquet")
    ref = formats.read_gnss(d / "gnss_1730_sf.pos")
    # the RINEX tags are the receiver's (1 ms from the solution's epochs): nearest within 10 ms
    j = np.clip(np.searchsorted(ref.time, g.time), 1, len(ref.time) - 1)
    j = np.where(np.abs(ref.time[j - 1] - g.time) < np.abs(ref.time[j] - g.time), j - 1, j)
    i = np.flatnonzero(np.abs(ref.time[j] - g.time) < 0.01)
    j, t = j[i], g.time[i]
    assert len(t) > 400
    de, dn, _ = lla_difference_enu(g.lat[i], g.lon[i], 0.0, ref.lat[j], ref.lon[j], 0.0)
    rms = float(np.sqrt(np.mean(de**2 + dn**2)))
    print(f"SPP horizontal RMS against the RTK .pos: {rms:.2f} m over {len(t)} epochs")
    assert rms < 15.0  # docs/results.md: SPP 8.33 m with the Galileo satellites (8.50 m GPS only)
    assert (g.quality == 5).all() and g.std_pos is not None and np.all(g.std_pos > 0)
    page = (tmp_path / "s" / "run.html").read_text()
    assert "<img" in page and (tmp_path / "s" / "solution.kml").exists()
