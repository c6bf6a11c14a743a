"""run.html lays out the filter-health lists as tables with readable times (issue 38): the windows where
the NIS is far out of its band and the re-initialisations, never one run-on paragraph with 2.433e+05."""

from __future__ import annotations

from aidnav.report.run_page import run_page_html


def test_nis_windows_and_reinitialisations_are_tables_with_readable_times(run_summary):
    s = dict(run_summary)
    s["nis_windows_far_out"] = [{"model": "gnss_velocity", "start": 243300.0, "end": 243330.0, "n": 120,
                                 "mean_nis": 9.5, "dof": 2.0, "band": [1.6, 2.5], "rejected": 3}]
    s["reinitialisations"] = [{"time": 243312.25, "model": "gnss_velocity", "why": "NIS window", "nis": 40.2}]
    s["gnss_height_datum"] = "ellipsoid"
    html = run_page_html(s)
    assert "2.433e+05" not in html and "243300.000" in html and "243330.000" in html
    i = html.index("NIS windows far out of their band (1)")
    assert "<table" in html[i:i + 600] and "gnss velocity" in html[i:i + 2000]
    assert "Re-initialisations (1)" in html and "243312.250" in html
    assert "GNSS heights in the file" in html and "ellipsoid" in html
    other = html.split("Other values")[1].split("Summary (JSON)")[0] if "Other values" in html else ""
    assert "nis_windows_far_out" not in other and "reinitialisations" not in other
