"""``aidnav evaluate`` on files read in pieces smaller than the logs (issue 29): the same summary, table and
per-epoch errors as the whole-trajectory functions on the whole files, for Parquet and CSV; the readers'
checks across batch boundaries."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from rich.console import Console

from aidnav.analysis.consistency import consistency_report, nees
from aidnav.analysis.errors import error_statistics, fraction_within_sigma, trajectory_errors
from aidnav.apps.evaluate import evaluate_files
from aidnav.data import Trajectory
from aidnav.io.errors import DataError
from aidnav.io.interchange import read_trajectory, write_trajectory
from aidnav.io.stream import trajectory_chunks


def _pair(n=4000):
    rng = np.random.default_rng(11)
    t = 5000.0 + 0.01 * np.arange(n)
    t = np.delete(t, np.r_[3 * n // 8:3 * n // 8 + n // 20])  # a gap in the estimate
    m = len(t)
    lat = np.radians(30.0) + 2e-7 * np.cos(t / 5.0)
    lon = np.radians(114.0) + 1e-6 * (t - t[0])
    h = 40.0 + 0.2 * np.sin(t)
    vel = np.column_stack([np.sin(t), np.cos(t), np.zeros(m)])
    rph = np.column_stack([0.01 * np.sin(t), 0.01 * np.cos(t), (0.02 * (t - t[0]) + 6.2) % (2 * np.pi)])
    est = Trajectory(t, lat + rng.normal(0, 3e-8, m), lon + rng.normal(0, 3e-8, m), h + rng.normal(0, 0.2, m),
                     vel + rng.normal(0, 0.03, (m, 3)), (rph + rng.normal(0, 5e-4, (m, 3))) % (2 * np.pi),
                     std_pos=np.abs(rng.normal(0.3, 0.05, (m, 3))), std_vel=np.full((m, 3), 0.03),
                     std_att=np.full((m, 3), 5e-4))
    tr = np.unique(np.concatenate([[4990.0], 5000.0 + 0.1 * np.arange(400) + 0.004, [5050.0]]))
    ref = Trajectory(tr, np.interp(tr, t, lat), np.interp(tr, t, lon), np.interp(tr, t, h),
                     np.column_stack([np.interp(tr, t, vel[:, i]) for i in range(3)]),
                     np.column_stack([np.interp(tr, t, rph[:, i]) for i in range(3)]))
    return est, ref


@pytest.mark.parametrize("ext", ["parquet", "csv"])
def test_streamed_evaluate_equals_whole(tmp_path, ext):
    est, ref = _pair()
    pe = write_trajectory(est, tmp_path / f"est.{ext}", week=2300)
    pr = write_trajectory(ref, tmp_path / f"ref.{ext}")
    chunks = list(trajectory_chunks(pe, 256))
    assert len(chunks) > 10 and max(len(c) for c in chunks) <= 256 * (1 if ext == "parquet" else 2)
    stats, written = evaluate_files(pe, pr, out_dir=tmp_path / "out", console=Console(quiet=True),
                                    chunk_rows=256)
    # the whole-trajectory functions on the files read whole
    e = trajectory_errors(read_trajectory(pe), read_trajectory(pr))
    want = error_statistics(e)
    assert e.n_gap > 0 and e.n_outside == 2 and len(e) > 300
    pd.testing.assert_frame_equal(stats, want, check_exact=True)
    js = json.loads((tmp_path / "out" / "errors.json").read_text())
    assert js["epochs"] == e.counts() and js["notes"] == e.notes
    assert (js["t0"], js["t1"]) == (e.time[0], e.time[-1])
    for k, key in ((1.0, "within_1sigma"), (3.0, "within_3sigma")):
        w = fraction_within_sigma(e, k)
        assert [r["fraction"] for r in js[key]] == list(w["fraction"])
    sp = e.std_pos
    cov = np.zeros((len(e), 3, 3))
    cov[:, np.arange(3), np.arange(3)] = sp**2
    rep = consistency_report(nees(e.pos, cov), 3).to_dict()
    got = {k: v for k, v in js["position_nees"].items() if k != "covariance"}
    assert got == json.loads(json.dumps(rep))
    csv = pd.read_csv(tmp_path / "out" / "errors.csv")
    whole = e.to_dataframe()
    assert list(csv.columns) == list(whole.columns)
    np.testing.assert_array_equal(csv.to_numpy(), whole.to_numpy())  # shortest round-trip decimals
    assert {p.name for p in written} >= {"errors.json", "errors.csv", "position_nees.png"}
    assert not list((tmp_path / "out").glob("*.spool"))  # the temporary files are gone


def test_csv_batches_keep_the_readers_checks(tmp_path):
    est, _ = _pair(600)
    p = write_trajectory(est, tmp_path / "est.csv")
    lines = p.read_text().splitlines()
    k = 500  # a data line far past the first batch of 32 rows
    f = lines[k].split(",")
    f[0] = lines[k - 1].split(",")[0]  # duplicate time
    bad = tmp_path / "dup.csv"
    bad.write_text("\n".join(lines[:k] + [",".join(f)] + lines[k + 1:]) + "\n")
    with pytest.raises(DataError, match="duplicate time") as ei:
        list(trajectory_chunks(bad, 32))
    assert ei.value.line == k + 1
    blank = tmp_path / "blank.csv"
    blank.write_text("\n".join(lines[:k] + [""] + lines[k:]) + "\n")
    with pytest.raises(DataError, match="blank line"):
        list(trajectory_chunks(blank, 32))
    parts = list(trajectory_chunks(p, 32))  # the good file: the whole reader's numbers, piece by piece
    whole = read_trajectory(p)
    np.testing.assert_array_equal(np.concatenate([c.time for c in parts]), whole.time)
    np.testing.assert_array_equal(np.concatenate([c.rph for c in parts]), whole.rph)
    np.testing.assert_array_equal(np.concatenate([c.std_pos for c in parts]), whole.std_pos)
