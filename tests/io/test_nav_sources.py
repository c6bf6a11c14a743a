"""Which navigation data `aidnav tight` / `aidnav spp` read (issue 40, :mod:`aidnav.io.nav_sources`): the UBX
log that the observation file's header names as its source (RTKLIB convbin's comments), found beside it or
in its parent directory, by default; 'none' and a given path; a named log that holds no ephemeris leaves
the navigation file alone with a warning (automatic) or is an input error (given)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aidnav.cli import app
from aidnav.io.errors import DataError
from aidnav.io.nav_sources import format_sources, resolve_ubx_nav, source_log

_HEADER = """     3.04           OBSERVATION DATA    M: Mixed            RINEX VERSION / TYPE
CONVBIN 2.4.3                           20261122 175308 UTC PGM / RUN BY / DATE
{format:<60s}COMMENT
{log:<60s}COMMENT
G    4 C1C L1C D1C S1C                                      SYS / # / OBS TYPES
                                                            END OF HEADER
> 2025 08 28 17 30 39.7480000  0  1
"""


def _obs(path: Path, fmt="format: u-blox UBX", log="log: rover.ubx") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(_HEADER.format(format=fmt, log=log))
    return path


def test_the_log_the_header_names_beside_the_file_or_in_its_parent(tmp_path):
    obs = _obs(tmp_path / "rinex" / "rover.obs")
    assert source_log(obs)[0] is None  # named, but nowhere
    assert "not found" in source_log(obs)[1]
    (tmp_path / "rover.ubx").write_bytes(b"\xb5\x62")
    assert source_log(obs)[0] == tmp_path / "rover.ubx"  # convbin -o rinex/rover.obs rover.ubx
    (tmp_path / "rinex" / "rover.ubx").write_bytes(b"\xb5\x62")
    assert source_log(obs)[0] == tmp_path / "rinex" / "rover.ubx"  # beside it first
    # a Windows path in the comment: its file name
    windows = _obs(tmp_path / "w" / "x.obs", log=r"log: C:\data\rover.ubx")
    assert source_log(windows)[0] == tmp_path / "rover.ubx"


def test_no_log_without_a_ubx_format_and_log_comment(tmp_path):
    (tmp_path / "rover.ubx").write_bytes(b"\xb5\x62")
    for fmt, log in (("format: RTCM 3", "log: rover.ubx"), ("format: u-blox UBX", "pgm: x"),
                     ("nothing", "nothing")):
        path, why = source_log(_obs(tmp_path / "a.obs", fmt, log))
        assert path is None and "names no u-blox UBX source log" in why
    comment_after_header = _obs(tmp_path / "b.obs", "x", "y")
    comment_after_header.write_text(comment_after_header.read_text() + f"{'log: rover.ubx':<60s}COMMENT\n")
    assert source_log(comment_after_header)[0] is None  # only the header counts


def test_the_setting(tmp_path):
    obs = _obs(tmp_path / "rover.obs")
    (tmp_path / "rover.ubx").write_bytes(b"\xb5\x62")
    for off in (None, "none", " NONE "):
        assert resolve_ubx_nav(off, obs)[0] is None
    assert resolve_ubx_nav("auto", obs) == (tmp_path / "rover.ubx",
                                            "auto: rover.obs's header names rover.ubx as its source log")
    (tmp_path / "cfg" / "logs").mkdir(parents=True)
    (tmp_path / "cfg" / "logs" / "x.ubx").write_bytes(b"\xb5\x62")
    assert resolve_ubx_nav("logs/x.ubx", obs, base_dir=tmp_path / "cfg") == (tmp_path / "cfg" / "logs/x.ubx",
                                                                            "given")
    with pytest.raises(DataError, match="UBX log not found — give"):
        resolve_ubx_nav("logs/x.ubx", obs, base_dir=tmp_path)
    line = format_sources({"nav": "a/n.nav", "ubx_nav": None, "how": "not asked for (ubx_nav: none)",
                           "satellites": {"GPS": ["G01", "G02"]}, "unhealthy": ["E14"]})
    assert line == ("ephemerides: n.nav (not asked for (ubx_nav: none)); satellites with a healthy "
                    "ephemeris: GPS 2; flagged unhealthy: E14")


def _spp(args, out):
    r = CliRunner().invoke(app, ["spp", *map(str, args), "--no-figures", "--json", "-o", str(out)])
    return r, (json.loads((out / "summary.json").read_text()) if r.exit_code == 0 else None)


def test_walk_spp_without_the_ubx_log_when_told(tmp_path, walk_dir):
    """--ubx-nav none: the navigation file's 4 GPS satellites alone (the default, the log the observation
    file names, is tested by tests/apps/test_spp_command.py)."""
    obs, nav = walk_dir / "rinex_converted" / "gnss_1730.obs", walk_dir / "rinex_converted" / "gnss_1730.nav"
    r, s = _spp(["--obs", obs, "--nav", nav, "--ubx-nav", "none"], tmp_path / "none")
    assert r.exit_code == 0, r.output
    assert s["ephemerides"]["ubx_nav"] is None and "Galileo" not in s["ephemerides"]["satellites"]
    assert s["systems"] == ["G"] and s["satellites_used_median"] == 4


def test_a_named_log_without_ephemerides(tmp_path, walk_dir):
    """Automatic: a warning and the navigation file alone; given with --ubx-nav: exit 2 naming the log."""
    rx = tmp_path / "rinex_converted"
    rx.mkdir()
    for f in ("gnss_1730.obs", "gnss_1730.nav"):
        shutil.copy(walk_dir / "rinex_converted" / f, rx / f)
    (tmp_path / "gnss_1730.ubx").write_bytes(b"\xb5\x62\x02\x13" + bytes(40))  # no complete frame
    args = ["--obs", rx / "gnss_1730.obs", "--nav", rx / "gnss_1730.nav"]
    r, s = _spp(args, tmp_path / "auto")
    assert r.exit_code == 0, r.output
    assert s["ephemerides"]["ubx_nav"] is None
    assert any("gnss_1730.ubx" in w and "not used" in w for w in s["warnings"]), s["warnings"]
    r, _ = _spp([*args, "--ubx-nav", tmp_path / "gnss_1730.ubx"], tmp_path / "given")
    assert r.exit_code == 2 and "gnss_1730.ubx" in r.output, r.output
