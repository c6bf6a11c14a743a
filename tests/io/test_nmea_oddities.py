"""What receivers print never ends in exit 1: each file of the corpus ``tests/io/nmea_oddities`` gives a
result or exit 2 with ``error: FILE[:LINE]: …`` through the command line (``aidnav convert --gnss``), and
the readable ones give the known answers below."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from aidnav.cli import app
from aidnav.io import formats
from aidnav.io.errors import DataError
from aidnav.io.nmea import read_nmea

CORPUS = Path(__file__).parent / "nmea_oddities"
#: file → the line the error names (None: the file as a whole)
REFUSED = {"time_goes_back.nmea": 6, "no_fix_at_all.nmea": None, "only_rmc.nmea": None,
           "gga_without_date.nmea": None, "latitude_out_of_range.nmea": 2, "empty.nmea": None}
FILES = sorted(p.name for p in CORPUS.glob("*.nmea"))


def test_corpus_is_complete():
    assert len(FILES) == 16 and set(REFUSED) <= set(FILES)


@pytest.mark.parametrize("name", FILES)
def test_never_exit_1(tmp_path, name):
    r = CliRunner().invoke(app, ["convert", "--gnss", str(CORPUS / name), "-o", str(tmp_path / "o")])
    out = r.output
    assert r.exit_code != 1 and "internal error" not in out, out
    if name in REFUSED:
        assert r.exit_code == 2, out
        line = REFUSED[name]
        assert f"error: {CORPUS / name}" in " ".join(out.split()) or f"{name}" in out, out
        if line is not None:
            assert f"{name}:{line}:" in out.replace("\n", ""), out
    else:
        assert r.exit_code == 0, out
        assert (tmp_path / "o" / "gnss.parquet").exists()


def test_leap_second_is_on_gps_time_between_its_neighbours():
    g = read_nmea(CORPUS / "leap_second.nmea")
    # 2016-12-31 23:59:58 UTC = 2017-01-01 00:00:15 GPST (17 s) = week 1930, 15 s; then 1 s apart, the leap
    # second 23:59:60 included, and 2017-01-01 00:00:00 UTC = 00:00:18 GPST (18 s)
    assert g.week == 1930
    np.testing.assert_allclose(g.time, [15.0, 16.0, 17.0, 18.0, 19.0], rtol=0, atol=1e-9)


def test_readable_oddities_known_answers():
    g = read_nmea(CORPUS / "empty_before_fix.nmea")
    assert len(g) == 2 and g.quality.tolist() == [5, 5]
    g = read_nmea(CORPUS / "mixed_talkers.nmea")  # GN RMC + GP GGA + GL GST are one epoch
    assert len(g) == 2 and g.std_pos is not None
    np.testing.assert_allclose(g.std_pos, [[0.01, 0.02, 0.03]] * 2)
    assert any("talkers GA, GL, GN, GP" in e for e in g.events)
    g = read_nmea(CORPUS / "truncated_last_line.nmea")
    assert len(g) == 2 and any("lines 5 " in e for e in g.events)
    g = read_nmea(CORPUS / "bad_checksums.nmea")
    assert len(g) == 2 and np.diff(g.time).tolist() == [2.0]  # 120002 refused, lowercase checksum kept
    g = read_nmea(CORPUS / "garbled_fields.nmea")
    assert len(g) == 3 and np.diff(g.time).tolist() == [3.0, 1.0]  # hour 25, 40O5, x, second 61 skipped
    g = read_nmea(CORPUS / "binary_mixed.nmea")
    assert len(g) == 2
    g = read_nmea(CORPUS / "late_gst.nmea")  # the GST after the next GGA joins its own epoch
    assert len(g) == 2 and np.allclose(g.std_pos[:, 2], 0.03)


def test_datum_of_nmea_and_the_configured_offset():
    lat_m = 1601.474
    g = formats.read_gnss(CORPUS / "some_without_separation.nmea", height_offset_m=-21.4)
    assert g.height_datum == "ellipsoid" and g.height_offset_m == 0.0
    np.testing.assert_allclose(g.height, lat_m - 21.4)  # the offset is NOT added a second time
    warn = [e for e in g.events if e.startswith("warning:") and "NOT applied" in e]
    assert warn and "-21.400" in warn[0] and "nmea" in warn[0]
    g = formats.read_gnss(CORPUS / "no_separation.nmea", height_offset_m=-21.4)
    assert g.height_datum == "msl" and g.height_offset_m == -21.4
    np.testing.assert_allclose(g.height, lat_m - 21.4)  # MSL + the configured undulation
    g = formats.read_gnss(CORPUS / "no_separation.nmea")
    assert any(e.startswith("warning:") and "mean sea level" in e for e in g.events)


def test_hdop_sigma_is_stated():
    g = read_nmea(CORPUS / "empty_before_fix.nmea")  # no GST: HDOP 0.6 × UERE 1 m
    np.testing.assert_allclose(g.std_pos, [[0.6, 0.6, 1.2]] * 2)
    assert any("HDOP" in e and "UERE" in e for e in g.events)
    with pytest.raises(DataError, match="does not increase"):
        read_nmea(CORPUS / "time_goes_back.nmea")
