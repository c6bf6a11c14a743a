"""`aidnav simulate` → `aidnav process` → `aidnav evaluate` end to end, and bad input on the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from aidnav.cli import app

SCN = """name: cli
seed: 3
initial: {lat_deg: 40, lon_deg: 116, height_m: 100, speed_m_s: 0, heading_deg: 30}
segments:
  - {type: static, duration_s: 30}
  - {type: accelerate, duration_s: 10, to_speed_m_s: 15}
  - {type: turn, angle_deg: 90, duration_s: 20}
  - {type: straight, duration_s: 30}
  - {type: turn, angle_deg: -90, duration_s: 20}
  - {type: straight, duration_s: 30}
sensors:
  imu: {grade: tactical}
  gnss: {rate_hz: 1, sigma_pos_m: [0.3, 0.3, 0.6], sigma_vel_m_s: [0.03, 0.03, 0.05]}
"""

CFG = """imu: {arw_deg_sqrt_h: 0.1, vrw_m_s_sqrt_h: 0.05, gyro_bias_sigma_deg_h: 3, accel_bias_sigma_ug: 300,
      gyro_bias_tau_s: 0, accel_bias_tau_s: 0}
init: {mode: auto, static_window_s: 20, attitude_sigma_deg: [0.5, 0.5, 180], course_min_speed_m_s: 2.0}
constraints: {zupt: true}
"""

runner = CliRunner()


@pytest.fixture(scope="module")
def simdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    (d / "scn.yaml").write_text(SCN)
    r = runner.invoke(app, ["simulate", str(d / "scn.yaml"), "-o", str(d / "sim"), "--format", "csv"])
    assert r.exit_code == 0, r.output
    (d / "cfg.yaml").write_text(CFG)
    return d


def test_process_then_evaluate(simdir):
    outdir = simdir / "est"
    out = outdir / "trajectory.csv"
    r = runner.invoke(app, ["process", "--imu", str(simdir / "sim/imu.csv"), "--gnss",
                            str(simdir / "sim/gnss.csv"), "--config", str(simdir / "cfg.yaml"), "-o",
                            str(outdir), "--format", "csv", "--outage", "80:10", "--smooth"])
    assert r.exit_code == 0, r.output
    summary = json.loads((outdir / "summary.json").read_text())
    assert summary["gnss_withheld"] == 10
    assert summary["outage_score"]["n_scored"] == 10
    assert any("heading from GNSS course" in e for e in summary["events"])
    r = runner.invoke(app, ["evaluate", "--estimate", str(out), "--truth", str(simdir / "sim/truth.csv"),
                            "-o",
                            str(simdir / "eval")])
    assert r.exit_code == 0, r.output
    stats = json.loads((simdir / "eval/errors.json").read_text())
    text = json.dumps(stats)
    assert "horizontal" in text
    # after the motion starts, the tactical-grade solution is good to well under 1 m
    from aidnav.analysis.errors import error_statistics, trajectory_errors
    from aidnav.io.interchange import read_trajectory

    e = trajectory_errors(read_trajectory(out), read_trajectory(simdir / "sim/truth.csv"))
    st = error_statistics(e, window=(60.0, np.inf))
    assert st.loc["pos horizontal", "RMS"] < 0.5
    assert st.loc["heading", "RMS"] < 0.5


def test_process_without_config_states_assumptions(simdir, tmp_path):
    r = runner.invoke(app, ["process", "--imu", str(simdir / "sim/imu.csv"), "--gnss",
                            str(simdir / "sim/gnss.csv"), "-o", str(tmp_path / "est")])
    assert r.exit_code == 0, r.output
    assert "no --config" in r.output
    assert (tmp_path / "est" / "trajectory.parquet").exists()


@pytest.mark.parametrize("content, needle", [
    ("", "empty"),
    ("time,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_m_s,dv_y_m_s,dv_z_m_s\n0.01,0,0,0,0,0,0.098\n"
     "0.02,0,0,0,0,0.098\n", ":3"),
    ("time,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_m_s,dv_y_m_s,dv_z_m_s\n0.01,0,0,0,0,0,0.098\n"
     "0.02,0,nan,0,0,0,0.098\n", ":3"),
    ("time,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_m_s,dv_y_m_s,dv_z_m_s\n0.01,0,0,0,0,0,0.098\n"
     "0.01,0,0,0,0,0,0.098\n", ":3"),
])
def test_bad_imu_file_names_file_and_line(simdir, tmp_path, content, needle):
    bad = tmp_path / "bad_imu.csv"
    bad.write_text(content)
    r = runner.invoke(app, ["process", "--imu", str(bad), "--gnss", str(simdir / "sim/gnss.csv"), "-o",
                            str(tmp_path / "o")])
    assert r.exit_code == 2
    assert "bad_imu.csv" in r.output and needle in r.output.replace("\n", "")


def test_bad_config_names_the_key(simdir, tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("imu: {arw_deg_per_sqrt_h: 0.1}\n")
    r = runner.invoke(app, ["process", "--imu", str(simdir / "sim/imu.csv"), "--gnss",
                            str(simdir / "sim/gnss.csv"), "--config", str(cfg), "-o",
                            str(tmp_path / "o")])
    assert r.exit_code == 2
    assert "imu.arw_deg_per_sqrt_h" in r.output


def test_gnss_outlier_is_rejected_and_reported(simdir, tmp_path):
    from aidnav.io.interchange import read_gnss, write_gnss

    g = read_gnss(simdir / "sim/gnss.csv")
    g.lat[70] += 1000.0 / 6.37e6  # 1 km north
    write_gnss(g, tmp_path / "g.csv")
    out = tmp_path / "o"
    r = runner.invoke(app, ["process", "--imu", str(simdir / "sim/imu.csv"), "--gnss",
                            str(tmp_path / "g.csv"), "--config", str(simdir / "cfg.yaml"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    s = json.loads((out / "summary.json").read_text())
    assert s["gnss_position_rejected"] >= 1
    assert g.time[70] in s["rejected_fix_times"]


def test_nan_gnss_fix_is_skipped_and_reported(simdir):
    from aidnav.apps.process import load_config
    from aidnav.filters.loose import run_loose
    from aidnav.io.interchange import read_gnss, read_imu

    g = read_gnss(simdir / "sim/gnss.csv")
    g.lat[60] = np.nan
    events: list[str] = []
    r = run_loose(read_imu(simdir / "sim/imu.csv"), g, load_config(simdir / "cfg.yaml"), events=events)
    assert any("NaN/inf" in e for e in events), events
    assert r.records["pos_status"][60] == -1
    assert np.all(np.isfinite(r.state))


def test_tight_cli_on_walk_data(data_dir, tmp_path):
    """`aidnav tight` on the walk set (4 GPS satellites with an ephemeris in the nav file, 6 Galileo ones in
    the UBX log): a solution within the metre-level accuracy such a solution can have (the RTK reference,
    Q = 1 epochs)."""
    d = data_dir / "rtklibexplorer_walk_0827"
    out = tmp_path / "tight"
    r = runner.invoke(app, ["tight", "--imu", str(d / "imu_1730.csv"), "--obs",
                            str(d / "rinex_converted/gnss_1730.obs"), "--nav",
                            str(d / "rinex_converted/gnss_1730.nav"), "--truth",
                            str(d / "gnss_1730_sf.pos"),
                            "--truth-height-offset", "-21.4", "-o", str(out)])
    assert r.exit_code == 0, r.output
    s = json.loads((out / "summary.json").read_text())
    assert s["reference"]["Q=1"]["epochs"] > 300
    assert s["reference"]["Q=1"]["horizontal_rms_m"] < 15.0
    # by default the UBX log the observation file names adds its Galileo ephemerides, said in the summary
    src = s["ephemerides"]
    assert src["ubx_nav"].endswith("gnss_1730.ubx") and "Galileo" in src["satellites"]
    assert "E" in s["inter_system_bias_m"] and "ephemerides: gnss_1730.nav + gnss_1730.ubx" in r.output
    # every reference epoch is scored too, not only the fixed ones
    assert s["reference"]["all"]["epochs"] >= s["reference"]["Q=1"]["epochs"]
    # the page (issue 38): the reference track and the differences against time, the NIS table, and
    # aidnav's own SPP fixes not called "GNSS fixes"
    page = (out / "run.html").read_text()
    assert (out / "reference.png").exists() and "Solution against the reference" in page
    assert "Filter consistency (NIS)" in page


@pytest.mark.slow
def test_tight_cli_smooth_on_walk_data(data_dir, tmp_path):
    """`aidnav tight --smooth` writes the smoothed solution (smoothed < forward RMS on the walk is asserted
    in tests/filters/test_smoothing_all.py): here the CLI path, its summary flag and its reference score."""
    d = data_dir / "rtklibexplorer_walk_0827"
    if not d.is_dir():
        pytest.skip(f"{d} not found")
    out = tmp_path / "smooth"
    r = runner.invoke(app, ["tight", "--imu", str(d / "imu_1730.csv"), "--obs",
                            str(d / "rinex_converted/gnss_1730.obs"), "--nav",
                            str(d / "rinex_converted/gnss_1730.nav"), "--truth", str(d / "gnss_1730_sf.pos"),
                            "--truth-height-offset", "-21.4", "--no-figures", "-o", str(out), "--smooth"])
    assert r.exit_code == 0, r.output
    s = json.loads((out / "summary.json").read_text())
    assert s["smoothed"] is True
    assert s["reference"]["Q=1"]["horizontal_rms_m"] < 15.0
