"""A trajectory CSV read in batches (:func:`aidnav.io.stream.trajectory_chunks`, issue 29): Arrow's streaming
reader holds a bounded number of blocks whatever the file's length, small blocks are joined into pieces of
about ``chunk_rows`` rows, and the whole-file reader's numbers, checks and line numbers are kept across
blocks and pieces."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pytest

from aidnav.data import Trajectory
from aidnav.io import stream
from aidnav.io.errors import DataError
from aidnav.io.interchange import read_trajectory, write_trajectory
from aidnav.io.stream import trajectory_chunks

BLOCK = 1 << 16  # the smallest block the reader uses


def _traj(n):
    rng = np.random.default_rng(3)
    t = 100.0 + 0.01 * np.arange(n)
    lat, lon = np.radians(30.0) + rng.normal(0, 1e-6, n), np.radians(114.0) + rng.normal(0, 1e-6, n)
    return Trajectory(t, lat, lon, 40.0 + rng.normal(0, 1.0, n), rng.normal(0, 1.0, (n, 3)),
                      rng.uniform(0, 2 * np.pi, (n, 3)), std_pos=np.abs(rng.normal(0.3, 0.05, (n, 3))),
                      std_vel=np.abs(rng.normal(0.03, 0.01, (n, 3))),
                      std_att=np.abs(rng.normal(5e-4, 1e-4, (n, 3))))


@pytest.fixture
def small_blocks(monkeypatch):
    monkeypatch.setattr(stream, "CSV_BLOCK_BYTES", BLOCK)


def test_csv_reader_memory_is_bounded_by_the_block_not_the_file(tmp_path, small_blocks):
    p = write_trajectory(_traj(30000), tmp_path / "est.csv")
    size = p.stat().st_size
    assert size > 100 * BLOCK  # far more than the blocks Arrow reads ahead (32)
    base = pa.total_allocated_bytes()
    peak, times = 0, []
    for t in trajectory_chunks(p, 4000).times():  # pieces of ≈ 4,000 rows ≈ 1.4 MB of text: 20 blocks
        peak = max(peak, pa.total_allocated_bytes() - base)
        times.append(t)
    # Arrow's pool between pieces: at most the read-ahead queue (32 blocks) and the block being parsed,
    # with its parsed columns; reading a piece's worth of text per block it held the whole file
    assert peak < 48 * BLOCK < size / 2
    assert len(times) > 5 and max(len(t) for t in times) <= 4000 and min(len(t) for t in times[:-1]) > 3000
    np.testing.assert_array_equal(np.concatenate(times), read_trajectory(p).time)


def test_joined_blocks_give_the_whole_readers_numbers(tmp_path, small_blocks):
    p = write_trajectory(_traj(5000), tmp_path / "est.csv")
    parts = list(trajectory_chunks(p, 1000))
    whole = read_trajectory(p)
    assert len(parts) > 4 and max(len(c) for c in parts) <= 1000
    for name in ("time", "lat", "lon", "height", "vel", "rph", "std_pos", "std_vel", "std_att"):
        np.testing.assert_array_equal(np.concatenate([getattr(c, name) for c in parts]), getattr(whole, name))


def _with_line(p, k, new, tmp_path, name):
    lines = p.read_text().splitlines()
    out = tmp_path / name
    out.write_text("\n".join(lines[:k] + new(lines, k) + lines[k + 1:]) + "\n")
    return out


@pytest.mark.parametrize("where", ["inside a piece", "first of a piece"])
def test_duplicate_time_line_numbers_across_blocks_and_pieces(tmp_path, small_blocks, where):
    p = write_trajectory(_traj(5000), tmp_path / "est.csv")
    lines = p.read_text().splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("time"))  # lines before the first record
    sizes = [len(c) for c in trajectory_chunks(p, 1000)]
    r = sum(sizes[:2]) if where == "first of a piece" else sum(sizes[:2]) + 700  # 0-based record
    k = head + 1 + r  # its line, 0-based

    def dup(ls, k):
        f = ls[k].split(",")
        f[0] = ls[k - 1].split(",")[0]
        return [",".join(f)]

    bad = _with_line(p, k, dup, tmp_path, "dup.csv")
    with pytest.raises(DataError, match="duplicate time") as whole:
        read_trajectory(bad)
    with pytest.raises(DataError, match="duplicate time") as ei:
        list(trajectory_chunks(bad, 1000))
    assert ei.value.line == whole.value.line == k + 1
    assert str(ei.value) == str(whole.value)


def test_empty_field_after_joined_blocks_is_the_whole_readers_error(tmp_path, small_blocks):
    p = write_trajectory(_traj(5000), tmp_path / "est.csv")
    lines = p.read_text().splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("time"))
    k = head + 1 + 2600

    def empty(ls, k):
        f = ls[k].split(",")
        f[3] = ""
        return [",".join(f)]

    bad = _with_line(p, k, empty, tmp_path, "empty.csv")
    with pytest.raises(DataError) as whole:
        read_trajectory(bad)
    with pytest.raises(DataError) as ei:
        list(trajectory_chunks(bad, 1000))
    assert str(ei.value) == str(whole.value) and ei.value.line == k + 1


def test_writer_row_groups_of_held_pieces(tmp_path):
    """row_group_rows: pieces held until a row group has that many rows (the last one smaller); the same
    table as one row group per piece."""
    import pyarrow.parquet as pq

    n = 1000
    tr = _traj(n)
    tr.extra = {"x": np.arange(float(n))}
    tabs = {}
    for rg in (None, 250):
        w = stream.TrajectoryWriter(tmp_path / f"t{rg}.parquet", week=2300, row_group_rows=rg)
        for a in range(0, n, 90):
            w.write(stream.take_rows(tr, slice(a, min(a + 90, n))))
        p = w.close()
        with pq.ParquetFile(p) as pf:
            rows = [pf.metadata.row_group(i).num_rows for i in range(pf.num_row_groups)]
        assert rows == ([90] * 11 + [10] if rg is None else [270, 270, 270, 190])
        tabs[rg] = pq.read_table(p)
    assert tabs[None].equals(tabs[250], check_metadata=True)
