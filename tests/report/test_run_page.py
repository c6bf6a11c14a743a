"""run.html (aidnav.report.run_page): self-contained, sections from the summary, figures embedded,
clear errors; the shared HTML helpers."""

from __future__ import annotations

import base64
import html
import json
import re
from html.parser import HTMLParser

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from aidnav.report.html import fmt, img_file_tag, kv_table, table
from aidnav.report.run_page import write_run_page

VOID = {"meta", "img", "br", "hr", "input", "link"}


class _Balance(HTMLParser):
    """Checks that every non-void element is closed in order."""

    def __init__(self):
        super().__init__()
        self.stack, self.errors, self.imgs = [], [], []

    def handle_starttag(self, tag, attrs):
        if tag == "img":
            self.imgs.append(dict(attrs))
        if tag not in VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self.stack[-1] if self.stack else 'nothing'}")
        else:
            self.stack.pop()


def parse(text: str) -> _Balance:
    p = _Balance()
    p.feed(text)
    p.close()
    assert not p.errors and not p.stack, (p.errors, p.stack)
    return p


def _png(path, w=4, h=3):
    fig = Figure(figsize=(w, h))
    FigureCanvasAgg(fig)
    fig.add_subplot(1, 1, 1).plot([0, 1], [1, 0])
    fig.savefig(path, dpi=50)
    return path


def test_run_page_sections_and_embedding(tmp_path, run_summary):
    s = run_summary
    f1 = _png(tmp_path / "overview.png")
    f2 = _png(tmp_path / "position_errors.png")
    p = write_run_page(tmp_path / "run.html", s, [f1, (f2, "Position errors")])
    text = p.read_text()
    assert text.startswith("<!DOCTYPE html>") and "<script" not in text and 'src="http' not in text
    parsed = parse(text)
    for h in ("Run", "GNSS outages", "Score: filter output", "Calibration estimates", "Events (2)",
              "Notes (1)", "Rejected GNSS positions", "Other values", "Figures", "Summary (JSON)"):
        assert f"<h2>{h}</h2>" in text or f"<h3>{h}</h3>" in text or f"<h2>{h}" in text, h
    # images: data URIs holding exactly the files' bytes, in order
    srcs = [i["src"] for i in parsed.imgs]
    assert len(srcs) == 2 and all(x.startswith("data:image/png;base64,") for x in srcs)
    assert base64.b64decode(srcs[0].split(",", 1)[1]) == f1.read_bytes()
    assert base64.b64decode(srcs[1].split(",", 1)[1]) == f2.read_bytes()
    assert "<h3>Position errors</h3>" in text
    assert "<h2>Filter consistency (NIS)</h2>" in text and '<td class="bad">OUT OF BAND</td>' in text
    assert "<h2>Warnings (1)</h2>" in text and "<td>GNSS height offset added [m]</td><td>-21.4</td>" in text
    # events are escaped
    assert "&lt;bad&gt; &amp; ok" in text and "<bad>" not in text
    # calibration rows: value, σ and the unit from the name or the dict
    assert re.search(r"<td>gyro_bias_x_deg_h</td><td>12\.5</td><td>0\.75</td><td>deg/h</td>", text)
    assert re.search(r"<td>accel_bias_ug</td><td>100, -50, 20</td><td>5, 5, 8</td><td>µg</td>", text)
    assert re.search(r"<td>time_offset</td><td>0\.012</td><td>0\.001</td><td>s</td>", text)
    assert re.search(r"<td>lever_arm_m</td><td>0\.1, 0\.2, -0\.3</td><td>–</td><td>m</td>", text)
    # the JSON block holds the whole summary
    js = re.search(r"<pre>(.*?)</pre>", text, re.S).group(1)
    back = json.loads(html.unescape(js))
    assert back["outage_score"] == s["outage_score"] and back["custom_value"] == 3.25
    assert back["calibration"]["accel_bias_ug"]["std"] == [5.0, 5.0, 8.0]
    assert "aidnav process: imu_1934_with_a_long_file_name.csv + gnss_1934_sf.pos" in text


def test_run_page_errors(tmp_path, run_summary):
    s = run_summary
    with pytest.raises(FileNotFoundError, match="missing.png"):
        write_run_page(tmp_path / "run.html", s, [tmp_path / "missing.png"])
    assert not (tmp_path / "run.html").exists()
    with pytest.raises(ValueError, match="needs a 'value'"):
        write_run_page(tmp_path / "run.html", {**s, "calibration": {"x": {"std": 1}}})
    with pytest.raises(ValueError, match="mapping"):
        write_run_page(tmp_path / "run.html", {**s, "calibration": [1, 2]})
    with pytest.raises(ValueError, match="summary must be a dict"):
        write_run_page(tmp_path / "run.html", [1])
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(ValueError, match="cannot embed"):
        img_file_tag(tmp_path / "notes.txt")


def test_tight_summary_page(tmp_path):
    s = {"imu": "imu.csv", "obs": "rover.obs", "nav": "rover.nav", "output": "out/tight.csv", "states": 17,
         "events": ["start at t=1.000 from SPP"],
         "reference": {"file": "ref.pos", "epochs": 100, "horizontal_rms_m": 1.5,
                       "rms_enu_m": [1.0, 1.1, 2.0]}}
    text = write_run_page(tmp_path / "run.html", s).read_text()
    parse(text)
    assert "aidnav tight: imu.csv + rover.obs" in text and "Comparison with the reference" in text
    assert "1, 1.1, 2" in text


def test_html_helpers():
    assert fmt(None) == fmt(float("nan")) == fmt(np.float64("inf")) == "–"
    assert fmt(True) == "yes" and fmt(np.int64(3)) == "3" and fmt(1.23456789) == "1.235" and fmt("a") == "a"
    t = table(["a", "b"], [[1, ("<b>x</b>", "good")]])
    assert '<div class="scroll">' in t and '<td class="good"><b>x</b></td>' in t
    kv = kv_table([["k", "<v>"]])
    assert 'class="kv"' in kv and "&lt;v&gt;" in kv


def test_write_run_outputs(tmp_path, run_summary):
    import io

    from rich.console import Console

    from aidnav.data import GnssData, Trajectory
    from aidnav.progress import ProgressBar
    from aidnav.report.run_page import write_run_outputs

    n = 500
    t = 345600.0 + 0.2 * np.arange(n)
    lat = np.radians(30.0) + 1e-7 * np.arange(n)
    lon = np.full(n, np.radians(114.0))
    tr = Trajectory(t, lat, lon, np.full(n, 5.0), np.zeros((n, 3)), np.zeros((n, 3)),
                    std_pos=np.full((n, 3), 0.3))
    g = GnssData(t[::5], lat[::5], lon[::5], np.full(n // 5, 5.0))
    run_summary["outage_windows"] = [[t[100], t[150]]]
    buf = io.StringIO()
    with ProgressBar("process", console=Console(file=buf, force_terminal=True, width=120)) as bar:
        paths = write_run_outputs(tmp_path / "OUT", tr, g, run_summary, progress=bar)
    assert {k: p.name for k, p in paths.items()} == {"overview": "overview.png", "kml": "trajectory.kml",
                                                      "geojson": "trajectory.geojson", "run_page": "run.html"}
    assert all(p.exists() and p.parent == tmp_path / "OUT" for p in paths.values())
    text = paths["run_page"].read_text()
    assert "<h3>Overview</h3>" in text and len(parse(text).imgs) == 1
    assert "figures and maps" in buf.getvalue() and "3/3 steps" in buf.getvalue()


def test_calibration_estimates_units():
    import math
    from types import SimpleNamespace

    from aidnav.report.run_page import calibration_estimates, run_page_html

    deg_h = math.pi / 180 / 3600  # rad/s
    ug = 9.80665e-6  # m/s²
    n = 21
    pdiag = np.zeros((2, n))
    pdiag[-1, 9:12] = (np.array([1.0, 2.0, 3.0]) * deg_h) ** 2
    pdiag[-1, 12:15] = (np.array([10.0, 20.0, 30.0]) * ug) ** 2
    pdiag[-1, 15:21] = 1e-12  # σ 1 ppm
    bias = np.zeros((2, 12))
    bias[-1, :3] = np.array([50.0, -5.0, 0.5]) * deg_h
    bias[-1, 3:6] = np.array([100.0, 0.0, -200.0]) * ug
    bias[-1, 6:] = 1e-6 * np.arange(1, 7)
    cal = calibration_estimates(SimpleNamespace(bias=bias, pdiag=pdiag))
    assert list(cal)[:3] == ["gyro_bias_x_deg_h", "gyro_bias_y_deg_h", "gyro_bias_z_deg_h"]
    assert len(cal) == 12
    def col(fmt, key):
        return [cal[fmt.format(a)][key] for a in "xyz"]

    np.testing.assert_allclose(col("gyro_bias_{}_deg_h", "value"), [50, -5, 0.5], rtol=1e-12)
    np.testing.assert_allclose(col("gyro_bias_{}_deg_h", "std"), [1, 2, 3], rtol=1e-12)
    np.testing.assert_allclose(col("accel_bias_{}_ug", "value"), [100, 0, -200], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(col("accel_bias_{}_ug", "std"), [10, 20, 30], rtol=1e-12)
    np.testing.assert_allclose(cal["accel_sf_z_ppm"]["value"], 6.0, rtol=1e-12)
    np.testing.assert_allclose(cal["gyro_sf_x_ppm"]["std"], 1.0, rtol=1e-9)
    assert "gyro_bias_x_deg_h" in run_page_html({"calibration": cal})
    with pytest.raises(ValueError, match="fewer than"):
        calibration_estimates(SimpleNamespace(bias=bias, pdiag=pdiag[:, :15]))
