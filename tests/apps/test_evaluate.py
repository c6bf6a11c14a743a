"""Tests of aidnav.apps.evaluate and the ``aidnav evaluate`` command.

The readers are replaced by in-memory trajectories (monkeypatch), so these tests depend on
neither the interchange nor the RTKLIB module; the round trip through real interchange files is
skipped when ``aidnav.io.interchange`` is not importable.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from rich.console import Console

import aidnav.apps.evaluate as ev
from aidnav.data import GnssData, Trajectory
from aidnav.nav.earth import radii

T0 = 345600.0


def _truth(n=200, dt=0.1):
    t = T0 + dt * np.arange(n)
    lat = np.radians(30.0) + 1e-7 * np.arange(n)
    lon = np.full(n, np.radians(114.0))
    h = np.full(n, 20.0)
    vel = np.tile([0.0, 1.0, 0.0], (n, 1))
    rph = np.tile(np.radians([0.0, 0.0, 359.95]), (n, 1))
    return Trajectory(t, lat, lon, h, vel, rph)


def _estimate(truth: Trajectory, dn=1.0, dheading_deg=0.1):
    rm, _ = radii(truth.lat)
    rph = truth.rph.copy()
    rph[:, 2] = (rph[:, 2] + np.radians(dheading_deg)) % (2 * np.pi)
    n = len(truth)
    return Trajectory(truth.time.copy(), truth.lat + dn / (rm + truth.height), truth.lon.copy(),
                      truth.height.copy(), truth.vel.copy(), rph, std_pos=np.full((n, 3), 0.8),
                      std_vel=np.full((n, 3), 0.1), std_att=np.full((n, 3), np.radians(0.2)))


@pytest.fixture
def files(monkeypatch, tmp_path):
    truth = _truth()
    est = _estimate(truth)
    data = {"est.csv": est, "truth.csv": truth}
    monkeypatch.setattr(ev, "read_any_trajectory", lambda p, notes=None, height_offset_m=0.0: data[p.name])
    return tmp_path / "est.csv", tmp_path / "truth.csv", data


def test_evaluate_files_writes_outputs(files, tmp_path):
    est_p, truth_p, _ = files
    console = Console(record=True, width=140)
    stats, written = ev.evaluate_files(est_p, truth_p, out_dir=tmp_path / "out", console=console)
    assert stats.loc["pos N", "RMS"] == pytest.approx(1.0, abs=1e-6)
    assert stats.loc["heading", "RMS"] == pytest.approx(0.1, abs=1e-9)
    names = {p.name for p in written}
    assert {"errors.json", "errors.csv", "position_errors.png", "velocity_errors.png",
            "attitude_errors.png", "horizontal_error.png", "position_nees.png"} <= names
    assert all(p.exists() for p in written)
    text = console.export_text()
    assert "pos N" in text and "heading" in text and "RMS" in text and "95%" in text
    js = json.loads((tmp_path / "out" / "errors.json").read_text())
    rows = {r["quantity"]: r for r in js["statistics"]}
    assert rows["pos N"]["RMS"] == pytest.approx(1.0, abs=1e-6) and rows["pos N"]["unit"] == "m"
    assert js["epochs"]["used"] == 200 and js["epochs"]["outside_span"] == 0
    assert js["position_nees"]["dof"] == 3
    csv = (tmp_path / "out" / "errors.csv").read_text().splitlines()
    assert csv[0].startswith("time,de_m,dn_m,du_m") and len(csv) == 201


def test_evaluate_without_out_dir_writes_nothing(files):
    est_p, truth_p, _ = files
    stats, written = ev.evaluate_files(est_p, truth_p, console=Console(quiet=True))
    assert written == [] and "pos horizontal" in stats.index


def test_evaluate_no_overlap_raises(files):
    est_p, truth_p, data = files
    data["truth.csv"].time = data["truth.csv"].time - 604800.0 / 2  # other time scale
    with pytest.raises(ValueError, match="same time scale"):
        ev.evaluate_files(est_p, truth_p, console=Console(quiet=True))


def test_trajectory_from_gnss():
    g = GnssData(time=[1.0, 2.0], lat=[0.5, 0.5], lon=[2.0, 2.0], height=[10.0, 11.0],
                 std_pos=np.ones((2, 3)))
    tr = ev.trajectory_from_gnss(g)
    assert tr.rph.shape == (2, 3) and np.all(np.isnan(tr.rph)) and np.all(np.isnan(tr.vel))
    np.testing.assert_allclose(tr.std_pos, 1.0)
    g.vel = np.zeros((2, 3))
    assert np.all(ev.trajectory_from_gnss(g).vel == 0.0)


def test_rtk_like_reference_has_no_attitude_rows(monkeypatch, tmp_path):
    truth = _truth()
    g = GnssData(truth.time[::10], truth.lat[::10], truth.lon[::10], truth.height[::10])
    data = {"est.csv": _estimate(truth), "ref.pos": ev.trajectory_from_gnss(g)}
    monkeypatch.setattr(ev, "read_any_trajectory", lambda p, notes=None, height_offset_m=0.0: data[p.name])
    stats, _ = ev.evaluate_files(tmp_path / "est.csv", tmp_path / "ref.pos", console=Console(quiet=True))
    assert "heading" not in stats.index and "vel N" not in stats.index
    assert stats.loc["pos N", "n"] == 20


def test_cli_evaluate(files, tmp_path):
    typer_testing = pytest.importorskip("typer.testing")
    from aidnav.cli import app

    est_p, truth_p, _ = files
    res = typer_testing.CliRunner().invoke(app, ["evaluate", "--estimate", str(est_p), "--truth",
                                                 str(truth_p),
                                                 "-o", str(tmp_path / "cli")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "cli" / "errors.json").exists()


def test_interchange_round_trip(tmp_path):
    interchange = pytest.importorskip("aidnav.io.interchange")
    if not hasattr(interchange, "write_trajectory"):
        pytest.skip("aidnav.io.interchange.write_trajectory not available")
    truth = _truth()
    est = _estimate(truth)
    pe = interchange.write_trajectory(est, tmp_path / "est.csv")
    pt = interchange.write_trajectory(truth, tmp_path / "truth.csv")
    stats, _ = ev.evaluate_files(pe, pt, console=Console(quiet=True))
    assert stats.loc["pos N", "RMS"] == pytest.approx(1.0, abs=1e-6)
    assert stats.loc["heading", "RMS"] == pytest.approx(0.1, abs=1e-9)
    assert stats.loc["pos N", "n"] == len(truth)


def test_rtklib_pos_reference(tmp_path):
    rtklib = pytest.importorskip("aidnav.io.rtklib")
    interchange = pytest.importorskip("aidnav.io.interchange")
    if not hasattr(interchange, "write_trajectory"):
        pytest.skip("aidnav.io.interchange.write_trajectory not available")
    truth = _truth()
    pe = interchange.write_trajectory(_estimate(truth), tmp_path / "est.csv")
    lines = ["% GPST latitude(deg) longitude(deg) height(m) Q ns sdn(m) sde(m) sdu(m) sdne(m) sdeu(m) "
             "sdun(m) age(s) ratio"]
    for k in range(0, len(truth), 10):  # 1 Hz fixes, week 2300
        lines.append(f"2300 {truth.time[k]:.3f} {np.degrees(truth.lat[k]):.12f} "
                     f"{np.degrees(truth.lon[k]):.12f} {truth.height[k]:.4f} 1 12 0.01 0.01 0.02 0 0 0 0 9.9")
    pos = tmp_path / "ref.pos"
    pos.write_text("\n".join(lines) + "\n")
    assert len(rtklib.read_pos(pos).time) == 20
    stats, _ = ev.evaluate_files(pe, pos, console=Console(quiet=True))
    assert "heading" not in stats.index
    assert stats.loc["pos N", "n"] == 20
    assert stats.loc["pos N", "RMS"] == pytest.approx(1.0, abs=1e-3)  # 1e-12 deg in the file ≈ 0.1 mm
