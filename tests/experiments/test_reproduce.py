"""Reproduction dispatcher and summary.json helper."""

from __future__ import annotations

import json
import sys
import types

import pytest
from typer.testing import CliRunner

from aidnav.cli import app
from aidnav.experiments import reproduce as rp
from aidnav.experiments.reproduce.summary import (
    SummaryError,
    Target,
    evaluate_target,
    summary_row,
    summary_table,
    write_summary,
)

PKG = "aidnav.experiments.reproduce"


@pytest.fixture
def fake_seed(monkeypatch):
    """Install a fake module for a seed: fake_seed("001", run_function)."""
    def install(seed, fn):
        mod = types.ModuleType(f"{PKG}.seed_{seed}")
        if fn is not None:
            mod.run = fn
        monkeypatch.setitem(sys.modules, f"{PKG}.seed_{seed}", mod)
        return mod

    return install


def test_resolve_seeds():
    assert rp.resolve_seeds("all") == ["000", "001", "002", "003", "004"]
    assert rp.resolve_seeds("4") == ["004"] and rp.resolve_seeds("seed_002") == ["002"]
    with pytest.raises(ValueError, match="unknown seed"):
        rp.resolve_seeds("007")


def test_missing_module(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, f"{PKG}.seed_002", None)  # as if it did not exist
    with pytest.raises(rp.SeedUnavailable, match="seed 002"):
        rp.run_seed("002", tmp_path)


def test_not_implemented_removes_summary(fake_seed, tmp_path):
    def run(out_dir, runs=None, console=None):
        write_summary(out_dir, seed="001", title="t", runs=1, base_seed=1, tables=[])
        raise NotImplementedError("Table 2 needs the tight filter")

    fake_seed("001", run)
    with pytest.raises(rp.SeedUnavailable, match="Table 2 needs the tight filter"):
        rp.run_seed("001", tmp_path)
    assert not (tmp_path / "summary.json").exists()
    fake_seed("001", None)
    with pytest.raises(rp.SeedUnavailable, match="no run"):
        rp.run_seed("001", tmp_path)


def test_cli_reproduce_exit_2(fake_seed, tmp_path):
    def run(out_dir, runs=None, console=None):
        raise NotImplementedError

    fake_seed("003", run)
    r = CliRunner().invoke(app, ["reproduce", "003", "-o", str(tmp_path / "o")])
    assert r.exit_code == 2
    assert "seed 003" in r.output and "cannot be reproduced yet" in r.output
    assert not (tmp_path / "o" / "summary.json").exists()
    r = CliRunner().invoke(app, ["reproduce", "9", "-o", str(tmp_path / "o")])
    assert r.exit_code == 2 and "unknown seed" in r.output


def test_reproduce_all_dispatches(fake_seed, tmp_path):
    seen = {}

    def ok(seed):
        def run(out_dir, runs=None, console=None):
            seen[seed] = (out_dir, runs)
            rows = [summary_row("heading std", "deg", ours=0.21, paper=0.2483, target="ours <= 1.2 * paper")]
            write_summary(out_dir, seed=seed, title="x", runs=runs or 1, base_seed=1,
                          tables=[summary_table("Table 4", "c", rows)])
        return run

    for s in rp.SEEDS:
        fake_seed(s, ok(s) if s != "002" else None)
    outs = rp.reproduce("all", tmp_path, runs=5)
    assert [o.ok for o in outs] == [True, True, False, True, True]
    assert seen["004"] == (tmp_path / "seed_004", 5)
    summ = json.loads((tmp_path / "seed_004" / "summary.json").read_text())
    assert summ["tables"][0]["rows"][0]["holds"] is True
    r = CliRunner().invoke(app, ["reproduce", "all", "-o", str(tmp_path / "b")])
    assert r.exit_code == 2 and "seed 002" in r.output and "seed 004: done" in r.output
    one = rp.reproduce("004", tmp_path / "single")
    assert one[0].ok and one[0].summary == tmp_path / "single" / "summary.json"


def test_summary_rows_compute_holds():
    r = summary_row("heading std, none", "deg", ours=0.21, paper=0.2483, target="none / figure8 >= 5",
                    values={"none": 0.21, "figure8": 0.03})
    assert r == {"quantity": "heading std, none", "unit": "deg", "paper": 0.2483, "ours": 0.21,
                 "stderr": None, "target": "none / figure8 >= 5", "holds": True, "verdict": "holds",
                 "spec": False, "reason": None, "margin": None, "values": {"none": 0.21, "figure8": 0.03},
                 "runs": None, "check": "0.21 / 0.03 >= 5"}
    r = summary_row("x", "m", ours=2.0, paper=1.0, target="abs(ours - paper) <= 0.1 * paper")
    assert r["holds"] is False
    assert summary_row("x", "m", ours=2.0)["holds"] is None
    even = Target("ours is even", lambda o, p: o % 2 == 0)
    assert summary_row("x", "m", ours=2.0, target=even)["holds"] is True
    nan = summary_row("x", "m", ours=float("nan"), paper=1.0, target="ours < paper")
    assert (nan["ours"], nan["holds"], nan["verdict"]) == (None, False, "fails") and nan["reason"]
    for bad in ("ours <", "__import__('os')", "ours.real > 1", "ours + 1", "unknown > 1", "paper < 1"):
        with pytest.raises(SummaryError):
            evaluate_target(bad, 1.0, None)


def test_write_summary_schema(tmp_path):
    rows = [summary_row("q", "deg", ours=1.0, paper=None, target="ours < 2")]
    p = write_summary(tmp_path, seed="004", title="T", runs=10, base_seed=1,
                      tables=[summary_table("Table 4", "cap", rows)], figures=["f.png"], notes=["n"],
                      aidnav_version="9.9")
    d = json.loads(p.read_text())
    assert d == {"seed": "004", "title": "T", "aidnav_version": "9.9", "runs": 10, "base_seed": 1,
                 "tables": [{"name": "Table 4", "caption": "cap", "kind": "results", "rows": [
                     {"quantity": "q", "unit": "deg", "paper": None, "ours": 1.0, "stderr": None,
                      "target": "ours < 2", "holds": True, "verdict": "holds", "spec": False, "reason": None,
                      "margin": None, "values": None, "runs": None, "check": "1 < 2"}]}],
                 "figures": ["f.png"], "notes": ["n"],
                 "verdicts": {"spec": {"holds": 0, "fails": 0, "unresolved": 0, "structural-null": 0},
                              "other": {"holds": 1, "fails": 0, "unresolved": 0, "structural-null": 0}}}
    typed = dict(rows[0], target=None, holds=True)
    with pytest.raises(SummaryError, match="holds without a target"):
        write_summary(tmp_path / "x", seed="004", title="T", runs=1, base_seed=1,
                      tables=[summary_table("t", "c", [typed])])
    assert not (tmp_path / "x" / "summary.json").exists()


def _write_one(path, row):
    return write_summary(path, seed="004", title="T", runs=1, base_seed=1,
                         tables=[summary_table("t", "c", [row])])


def test_write_summary_rejects_holds_that_disagree_with_the_target(tmp_path):
    good = summary_row("q", "deg", ours=3.0, paper=1.0, target="ours < 2 * paper", spec=True)
    assert good["holds"] is False and good["verdict"] == "fails" and good["reason"]
    for bad, msg in [(dict(good, holds=True, verdict="holds", reason=None), "disagrees with its target"),
                     (dict(good, verdict="holds"), "verdict"),
                     (dict(good, reason=None), "needs a reason"),
                     (dict(good, target="ours < 2 * k"), "cannot be checked"),
                     (dict(good, target=None, holds=None, verdict=None), "spec row needs a target"),
                     (dict(good, target=None, verdict=None, spec=False), "holds without a target")]:
        with pytest.raises(SummaryError, match=msg):
            _write_one(tmp_path / "x", bad)
        assert not (tmp_path / "x" / "summary.json").exists()
    # a hand-made row with named values is re-evaluated from them
    v = summary_row("q", "-", ours=1.0, target="ours < k", values={"k": 2.0})
    _write_one(tmp_path / "ok", v)
    with pytest.raises(SummaryError, match="disagrees"):
        _write_one(tmp_path / "x", dict(v, values={"k": 0.5}))
    with pytest.raises(SummaryError, match="spec row needs a target"):
        summary_row("q", "-", ours=1.0, spec=True)


def test_unresolved_within_two_standard_errors():
    # an ordering a > b that holds by 0.3 with a standard error of 0.2: not resolved (< 2 se)
    r = summary_row("a - b", "-", ours=0.3, target="ours > 0", stderr=0.2, margin=(0.3, 0.2), spec=True)
    # holds is the verdict's (issue 39): an unresolved row does not hold, even on the holding side
    assert r["holds"] is False and r["verdict"] == "unresolved" and "standard errors" in r["reason"]
    r = summary_row("a - b", "-", ours=0.5, target="ours > 0", stderr=0.2, margin=(0.5, 0.2), spec=True)
    assert r["verdict"] == "holds" and r["reason"] is None
    r = summary_row("a - b", "-", ours=-0.5, target="ours > 0", margin=(-0.5, 0.2), reason="physics")
    assert r["verdict"] == "fails" and r["reason"] == "physics"


def test_report_page_and_index(tmp_path):
    import re

    from aidnav.experiments.reproduce.page import report_folder, write_index

    rows = [summary_row("x [ms] <b>", "m", ours=1.0, paper=2.0, target="ours < paper", spec=True,
                        stderr=0.1),
            summary_row("echo", "m", ours=1.0, paper=1.0)]
    d = tmp_path / "seed_004"
    write_summary(d, seed="004", title="T", runs=3, base_seed=1,
                  tables=[summary_table("Table 4", "cap", rows),
                          summary_table("Sens", "c", rows[1:], kind="sensitivity")])
    (p,) = report_folder(d)
    text = p.read_text()
    assert "x [ms] &lt;b&gt;" in text and "Sensitivity studies" in text and "max-width:1300px" in text
    assert len(re.findall("<table>", text)) == 2
    idx = write_index(tmp_path)
    assert 'href="seed_004/report.html"' in idx.read_text()
    paths = report_folder(tmp_path)
    assert paths[-1] == idx


def test_cli_report_accepts_a_reproduction_folder(tmp_path):
    rows = [summary_row("q", "m", ours=1.0, paper=2.0, target="ours < paper", spec=True)]
    for seed in ("000", "003"):
        write_summary(tmp_path / f"seed_{seed}", seed=seed, title="T [x]", runs=1, base_seed=1,
                      tables=[summary_table("t", "c", rows)])
    r = CliRunner().invoke(app, ["report", str(tmp_path / "seed_003")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "seed_003" / "report.html").exists()
    r = CliRunner().invoke(app, ["report", str(tmp_path)])
    assert r.exit_code == 0 and (tmp_path / "index.html").exists() and (tmp_path / "seed_000" / "report.html")
    r = CliRunner().invoke(app, ["report", str(tmp_path / "nothing")])
    assert r.exit_code != 0


def test_report_fits_a_1400_px_browser_window(tmp_path):
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from aidnav.experiments.reproduce.page import browser_layout, write_seed_page

    fig = Figure(figsize=(30, 4))  # a 3000-px-wide figure must scale down
    FigureCanvasAgg(fig)
    fig.subplots().plot(np.arange(10))
    fig.savefig(tmp_path / "wide.png", dpi=100)
    long = "x" * 300  # an unbreakable word, a long target, many rows
    rows = [summary_row(f"{long} {i}", "m", ours=float(i), paper=1.0, target=f"ours < paper + {i} * 1e-3 + 0"
                        + " + 0" * 60, spec=True, stderr=0.1) for i in range(30)]
    write_summary(tmp_path, seed="002", title="wide " + long, runs=1, base_seed=1,
                  tables=[summary_table("T", "c " + long, rows)], figures=["wide.png"], notes=[long])
    page = write_seed_page(tmp_path)
    got = browser_layout(page, tmp_path)
    if got is None:
        pytest.skip("Chromium is not installed")
    maxright, scrollw, imgs, shot = got
    assert imgs == 1 and shot.stat().st_size > 10_000
    assert maxright <= 1400 and scrollw <= 1400, (maxright, scrollw)


def test_resolved_row_states_a_spec_trend_at_its_resolution(tmp_path):
    from aidnav.experiments.reproduce.summary import resolved_row

    # within 2 se: not unresolved but 'fails', with the bound the runs give on the effect
    r = resolved_row(summary_row("a / b", "-", ours=1.1, target="ours >= 1", stderr=0.1, margin=(0.1, 0.1),
                                 spec=True), 30, "physics")
    assert (r["verdict"], r["holds"], r["spec"], r["margin"]) == ("fails", False, True, None)
    assert r["target"] == "d >= 2 * se" and r["values"] == {"d": 0.1, "se": 0.1}
    assert "not resolvable at 30 runs" in r["reason"] and "±0.3" in r["reason"]
    assert r["reason"].endswith("physics")
    assert "[ours >= 1, resolved at 2 se over 30 runs]" in r["quantity"]
    # resolved on the holding side: holds; resolved on the failing side: fails, and says so
    ok = resolved_row(summary_row("x", "-", ours=1.5, target="ours >= 1", margin=(0.5, 0.1), spec=True), 30)
    assert ok["verdict"] == "holds" and ok["reason"] is None
    bad = resolved_row(summary_row("x", "-", ours=0.5, target="ours >= 1", margin=(-0.5, 0.1), spec=True), 30)
    assert bad["verdict"] == "fails" and "failing side" in bad["reason"]
    # a row without a margin is left alone; the rows pass write_summary's checks
    plain = summary_row("x", "-", ours=1.0, target="ours < 2", spec=True)
    assert resolved_row(plain, 30) is plain
    _write_one(tmp_path / "w", r)
    d = json.loads((tmp_path / "w" / "summary.json").read_text())
    assert d["verdicts"]["spec"] == {"holds": 0, "fails": 1, "unresolved": 0, "structural-null": 0}


def test_holds_is_the_verdict_and_targets_show_their_numbers(tmp_path):
    """Issue 39: ``holds == (verdict == "holds")`` on every row; an exactly-zero effect is structural-null;
    the target is shown with its numbers; rows carry their run count (the table's by default)."""
    from aidnav.experiments.reproduce.page import write_seed_page
    from aidnav.experiments.reproduce.summary import grid_table, target_shown

    null = summary_row("S / 8 − 1", "-", ours=0.0, target="ours > 0", margin=(0.0, 0.0), spec=True)
    assert (null["verdict"], null["holds"]) == ("structural-null", False)
    assert "by construction" in null["reason"]
    band = summary_row("NEES", "-", ours=1.02, target="lo <= ours <= hi", values={"lo": 0.95, "hi": 1.05})
    assert band["check"] == "0.95 <= 1.02 <= 1.05" and target_shown(band) == band["check"]
    un = summary_row("a", "-", ours=1.1, target="ours >= 1", margin=(0.1, 0.1), stderr=0.1, runs=600)
    assert un["runs"] == 600 and not un["holds"]
    cells = {(q, c): summary_row(f"{q} {c}", "arcmin", ours=1.0 + i, paper=2.0, stderr=0.1)
             for i, (q, c) in enumerate([("heading", "std"), ("pitch", "std")])}
    t = grid_table("Table 2", "cap", cells, ["heading", "pitch"], ["std", "mean"], [null, band, un], runs=30)
    assert t["grid"]["index"] == [[0, None], [1, None]]
    p = write_summary(tmp_path, seed="000", title="T", runs=30, base_seed=1, tables=[t])
    d = json.loads(p.read_text())
    rows = d["tables"][0]["rows"]
    assert all(r["holds"] == (r["verdict"] == "holds") for r in rows if r["target"])
    assert [r["runs"] for r in rows] == [30, 30, 30, 30, 600]
    assert d["verdicts"]["spec"]["structural-null"] == 1 and d["tables"][0]["grid"] == t["grid"]
    # a hand-made row whose holds disagrees with its verdict is refused
    with pytest.raises(SummaryError, match="holds"):
        _write_one(tmp_path / "x", dict(un, holds=True))
    text = write_seed_page(tmp_path).read_text()
    assert "0.95 &lt;= 1.02 &lt;= 1.05" in text and "structural-null" in text
    assert text.count("<table>") == 2  # the grid and the rows outside it


def test_seed_004_table_8_structural_null_is_its_own_verdict():
    """A factor that does not act on a quantity in every run (per-run ratios within NULL_TOL of 1) gives the
    verdict structural-null (not holds, not fails, not unresolved); a real Monte Carlo effect does not."""
    from types import SimpleNamespace

    import numpy as np

    from aidnav.experiments.reproduce.seed_004_tables import QUANTS, Group, structural_null, t8_rows

    rng = np.random.default_rng(3)
    base = rng.uniform(0.5, 1.5, (8, len(QUANTS)))
    cases = {}
    for i, b in enumerate((20, 40, 60)):
        a = base * (1.0 + 1e-7 * i)  # velocity and position: the same in every run (to rounding)
        a[:, QUANTS.index("baseline")] *= (1.0, 4.0, 9.0)[i]
        a[:, QUANTS.index("lat")] = base[:, QUANTS.index("lat")] * rng.uniform(0.8, 1.2, 8)  # a noisy effect
        cases[b] = SimpleNamespace(std=a)
    g = Group(cases)
    assert structural_null(g, "vE", (20, 40, 60)) < 1e-6 and structural_null(g, "lat", (20, 40, 60)) is None
    rows = {r["quantity"].split(" [")[0]: r for r in t8_rows(g)}
    ve = rows["vE: smallest ratio of successive L0 (non-decreasing: >= 1)"]
    assert (ve["verdict"], ve["holds"], ve["spec"]) == ("structural-null", False, True)
    assert "structural null" in ve["reason"] and "drifting master" in ve["reason"]
    lat = next(r for q, r in rows.items() if q.startswith("lat: smallest ratio"))
    assert lat["verdict"] != "structural-null"


def test_seed_004_cases_white_master_and_inflated_q():
    """Seed 004's default case has the white master (SPEC §5.1, 2026-12-06); the third noise configuration
    keeps the density reading in the truth and gives the filter the ARW reading's gyro noise (60× the
    density's ARW: 0.1°/√h against 0.1°/h/√Hz)."""
    import numpy as np

    from aidnav.experiments.reproduce import seed_004 as s4

    base = s4.sim_config(s4.BASE4)
    assert base.master.pos_drift_fraction == 0.0
    q = s4.Case4(grade="sub", filter_grade="sub_arw")
    truth, filt = s4.sim_config(q), s4.filter_config(q)
    arw_truth = float(np.max(truth.sub_imu.gyro_arw))
    assert filt.gyro_arw == pytest.approx(60.0 * arw_truth, rel=1e-12)
    assert s4.filter_config(s4.Case4(grade="sub")).gyro_arw == pytest.approx(arw_truth, rel=1e-12)
