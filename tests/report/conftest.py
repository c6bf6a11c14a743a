"""Fixtures of the report tests: a headless-Chromium layout probe and a tiny campaign."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml

CHROMIUM = Path("/usr/bin/chromium")

#: Run after every image has loaded (window "load"): the window width, the page's scroll width, the
#: elements reaching past the window (outside / inside a horizontally scrolling box), the scroll boxes
#: whose content is cut, and the state of every image. Written into the DOM as JSON for --dump-dom.
_PROBE = r"""
<script>
window.addEventListener('load', () => {
  const w = window.innerWidth;
  const desc = e => e.tagName.toLowerCase() + (e.className ? '.' + e.className : '') + ': ' +
                    (e.textContent || '').trim().slice(0, 60);
  const over = [], overInScroll = [], cut = [];
  for (const e of document.body.querySelectorAll('*')) {
    const r = e.getBoundingClientRect();
    if (r.width === 0 && r.height === 0) continue;
    if (r.right > w + 0.5 || r.left < -0.5 || r.width > w) {
      (e.closest('.scroll') ? overInScroll : over).push([desc(e), r.left, r.right]);
    }
  }
  for (const e of document.querySelectorAll('.scroll')) {
    if (e.scrollWidth > e.clientWidth + 1) cut.push([desc(e), e.clientWidth, e.scrollWidth]);
  }
  const imgs = [...document.images].map(i => ({alt: i.alt, complete: i.complete, width: i.naturalWidth,
                                              data: i.getAttribute('src').startsWith('data:image/')}));
  const res = {width: w, scrollWidth: document.documentElement.scrollWidth, over: over,
               overInScroll: overInScroll, cut: cut, images: imgs};
  const p = document.createElement('pre');
  p.id = 'layout-probe';
  p.style.display = 'none';
  p.textContent = JSON.stringify(res);
  document.body.appendChild(p);
});
</script>
"""


def _layout(page: Path, tmp: Path, width: int = 1400, height: int = 900) -> dict:
    """Load a copy of ``page`` (probe script added) in headless Chromium at ``width`` x ``height`` px;
    also writes a screenshot ``tmp/<name>.png``. Returns the probe's result."""
    text = page.read_text(encoding="utf-8")
    assert "</body>" in text, f"{page}: no </body>"
    probe = tmp / (page.stem + "_probe.html")
    probe.write_text(text.replace("</body>", _PROBE + "</body>"), encoding="utf-8")
    args = [str(CHROMIUM), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
            f"--window-size={width},{height}", "--virtual-time-budget=10000"]
    r = subprocess.run(args + ["--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=120)
    m = re.search(r'<pre id="layout-probe"[^>]*>(.*?)</pre>', r.stdout, re.S)
    assert m, f"no probe result from Chromium (rc {r.returncode}): {r.stderr[-2000:]}"
    import html

    shot = tmp / (page.stem + "_screenshot.png")
    subprocess.run(args + [f"--screenshot={shot}", probe.as_uri()], capture_output=True, timeout=120)
    res = json.loads(html.unescape(m.group(1)))
    res["screenshot"] = shot
    return res


@pytest.fixture(scope="session")
def chromium_layout(tmp_path_factory):
    """``layout(page_path) -> dict`` (see :func:`_layout`); skips when /usr/bin/chromium is absent."""
    if not CHROMIUM.exists() or shutil.which(str(CHROMIUM)) is None:
        pytest.skip("headless Chromium not installed at /usr/bin/chromium")
    tmp = tmp_path_factory.mktemp("chromium")
    return lambda page, **kw: _layout(Path(page), tmp, **kw)


#: A tiny campaign: 2 sweep points x 2 runs of a 30 s flight (long metadata strings come from the paths).
TINY = {
    "name": "tiny report layout",
    "description": "layout check of the campaign report",
    "scenario": {
        "initial": {"lat_deg": 30.0, "lon_deg": 114.0, "height_m": 500.0, "speed_m_s": 50.0,
                    "heading_deg": 10.0},
        "imu_rate_hz": 100,
        "transition_s": 2,
        "segments": [{"type": "straight", "duration_s": 10, "name": "AB"},
                     {"type": "u_turn", "duration_s": 10, "name": "U"},
                     {"type": "straight", "duration_s": 10, "name": "CD"}],
    },
    "sensors": {"imu": {"grade": "tactical"}, "gnss": {"rate_hz": 2}},
    "estimators": [{"name": "loose", "type": "loose"}],
    "runs": 2,
    "base_seed": 7,
    "sweep": {"imu.grade": ["tactical", "mems"]},
    "statistics": {"quantities": ["pos_h", "vel_h", "heading"],
                   "windows": {"AB": {"segment": "AB"}, "CD": {"segment": "CD"}, "last5": {"last_s": 5}},
                   "convergence": {"h1": {"quantity": "heading", "below": 1.0}}},
}


@pytest.fixture(scope="session")
def tiny_campaign(tmp_path_factory) -> Path:
    """The tiny campaign computed and reported, in a directory with a long path (as users have)."""
    from aidnav.experiments.report import write_report
    from aidnav.experiments.runner import run_experiment

    root = tmp_path_factory.mktemp("campaign")
    deep = root / "a_rather_long_directory_name_for_experiments" / "another_level_of_nesting_2026-12-01"
    deep.mkdir(parents=True)
    exp = deep / "tiny_report_layout_experiment_with_a_long_file_name.yaml"
    exp.write_text(yaml.safe_dump(TINY, sort_keys=False))
    out = deep / "campaign_output_directory"
    run_experiment(exp, out, progress=False)
    write_report(out)
    return out


def summary_example(tmp_path) -> dict:
    """A process_logs-like summary with long strings, outages and calibration estimates."""
    long_dir = tmp_path / ("very_long_directory_name_" * 4) / "logs"
    return {
        "imu": str(long_dir / "imu_1934_with_a_long_file_name.csv"),
        "gnss": str(long_dir / "gnss_1934_sf.pos"),
        "config": None, "output": str(tmp_path / "out" / "trajectory.csv"), "smoothed": True,
        "time_scale": "input (GPS seconds of week for GNSS-timed logs)",
        "imu_samples": 180000, "imu_rate_hz": 100.0, "gnss_fixes": 1800, "gnss_withheld": 300,
        "gnss_position_accepted": 1490, "gnss_position_rejected": 10,
        "gnss_velocity_accepted": 1500, "gnss_velocity_rejected": 0,
        "rejected_fix_times": [345600.0 + k for k in range(10)],
        "counts": {"zupt_updates": 120, "nhc_updates": 0},
        "outage_windows": [[345640.0, 345655.0], [345685.0, 345700.0]],
        "events": ["IMU gap of 0.05 s at t=345612.3 <bad> & ok", "x" * 500],
        "notes": ["no --config: defaults"],
        "timing_s": {"read": 0.2, "filter": 1.5, "write": 0.4},
        "outage_score": {"n_outages": 2, "n_withheld": 300, "n_scored": 290, "end_error_median_m": 1.23,
                         "end_error_p95_m": 2.5, "end_error_max_m": 2.6, "rms_m": 0.9,
                         "outages": [{"start": 345640.0, "end": 345655.0, "n": 145, "end_error_m": 1.2,
                                      "rms_m": 0.8},
                                     {"start": 345685.0, "end": 345700.0, "n": 145, "end_error_m": 2.6,
                                      "rms_m": 1.0}]},
        "calibration": {"gyro_bias_x_deg_h": {"value": 12.5, "std": 0.75},
                        "accel_bias_ug": {"value": [100.0, -50.0, 20.0], "std": [5.0, 5.0, 8.0]},
                        "lever_arm_m": [0.1, 0.2, -0.3], "time_offset": {"value": 0.012, "sigma": 0.001,
                                                                          "unit": "s"}},
        "custom_value": np.float64(3.25),
        "gnss_height_offset_m": -21.4,
        "warnings": ["GNSS fixes stop 12.0 s before the IMU log ends"],
        "nis": {"gnss_position": {"mean": 2.9, "dof": 3.0, "n": 1490, "band95": [2.78, 3.12],
                                  "in_band": True},
                "gnss_velocity": {"mean": 7.5, "dof": 2.0, "n": 1500, "band95": [1.9, 2.1],
                                  "in_band": False}},
    }


@pytest.fixture
def run_summary(tmp_path) -> dict:
    """:func:`summary_example` in the test's temporary directory."""
    return summary_example(tmp_path)
