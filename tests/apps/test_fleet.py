"""``aidnav fleet`` (issue 41): a small fleet of short static logs, one of them corrupted; the local
cluster and an external scheduler give the same bytes; a SIGKILL in the middle and a rerun redo only what
is missing."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from aidnav.apps.fleet import ROW_FILE, read_manifest, run_fleet
from aidnav.errors import InputError

from .test_process_stream import static_log

HEAD = "name,imu,gnss,config,truth,vehicle_id\n"


def fleet(tmp: Path, seconds=(20, 20, 25, 30), corrupt: int | None = 2) -> Path:
    """Static logs at 30° N 114° E 50 m (GNSS noise σ 0.5 m), a reference file of that spot, and a
    manifest; log number ``corrupt`` has an IMU file that is not Parquet."""
    lines = [HEAD]
    for k, s in enumerate(seconds):
        d = tmp / f"log{k}"
        d.mkdir()
        imu, gnss, cfg = static_log(d, s, seed=k)
        if k == corrupt:
            imu.write_bytes(b"PAR1" + bytes(range(256)) * 8)  # a truncated file with a Parquet magic
        lines.append(f"log{k},log{k}/{imu.name},log{k}/{gnss.name},log{k}/{cfg.name},truth.csv,"
                     f"{'car-a' if k % 2 else 'car-b'}\n")
    t = np.arange(0.0, max(seconds) + 2.0, 0.5)
    z = np.zeros_like(t)
    cols = {"time": t, "lat_deg": z + 30.0, "lon_deg": z + 114.0, "height_m": z + 50.0, "ve": z, "vn": z,
            "vu": z, "roll_deg": z, "pitch_deg": z, "heading_deg": z}
    np.savetxt(tmp / "truth.csv", np.column_stack(list(cols.values())), delimiter=",", fmt="%.9f",
               header=",".join(cols), comments="")
    m = tmp / "fleet.csv"
    m.write_text("".join(lines))
    return m


def outputs(d: Path) -> dict[str, bytes]:
    """Every file under ``d`` by relative path (the rows' wall time left out: the one value of time)."""
    out = {}
    for p in sorted(d.rglob("*")):
        if p.is_file():
            data = p.read_bytes()
            if p.name == ROW_FILE:
                row = json.loads(data)
                row.pop("wall_s")
                data = json.dumps(row, sort_keys=True).encode()
            if p.name == "fleet.parquet":
                data = pq.read_table(p).drop(["wall_s"]).to_pylist().__repr__().encode()
            out[str(p.relative_to(d))] = data
    return out


def test_manifest_errors_name_the_line(tmp_path):
    m = tmp_path / "m.csv"
    m.write_text("name,imu\na,b\n")
    with pytest.raises(InputError, match=r"m.csv:1: missing column\(s\) gnss"):
        read_manifest(m)
    m.write_text("name,imu,gnss\na,i.parquet,g.csv\na,i.parquet,g.csv\n")
    with pytest.raises(InputError, match=r"m.csv:3: name 'a' already on line 2"):
        read_manifest(m)
    m.write_text("name,imu,gnss,time_offset\na,i.parquet,g.csv,soon\n")
    with pytest.raises(InputError, match=r"m.csv:2: time_offset 'soon' is not a finite number"):
        read_manifest(m)
    m.write_text("name,imu,gnss\n../up,i.parquet,g.csv\n")
    with pytest.raises(InputError, match=r"m.csv:2: name '../up'"):
        read_manifest(m)
    m.write_text("name,imu,gnss,vehicle,smooth\nx,d/i.parquet,g.csv,car,true\n")
    (log,) = read_manifest(m)
    assert log.imu == str(tmp_path / "d" / "i.parquet") and log.vehicle == "car" and log.smooth


#: the two Dask runs of the test below, in a child interpreter (argv: manifest, output folder, the folder the
#: local cluster's outputs are moved to before the external scheduler writes the same output folder). A Dask
#: scheduler run in the test process (a local cluster's is) leaves distributed's process-wide offload thread
#: (``Dask-Offload``) alive until the process ends, and a later test in the same process that forks (the
#: figures' processes of ``process`` and ``characterise``) needs a process with no other thread (issue 41,
#: session 13: tests/conftest.py's ``_no_thread_left`` named this test)
_DASK_RUNS = """
import json, os, sys
from distributed import LocalCluster
from aidnav.apps.fleet import run_fleet
m, out, first = sys.argv[1:4]
res = run_fleet(m, out, workers=2, figures=True)  # each log's figures too: the same bytes as well
os.rename(out, first)  # (the summaries name the output folder: the second run writes the same one)
with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
    res2 = run_fleet(m, out, scheduler=cl.scheduler_address, figures=True)
    address = cl.scheduler_address
print(json.dumps({"local": [res.backend, res.computed], "external": [res2.backend, address]}))
"""


def test_fleet_local_and_external_scheduler_same_bytes(tmp_path):
    m = fleet(tmp_path)
    out, first_out = tmp_path / "out", tmp_path / "out-local"
    run = subprocess.run([sys.executable, "-c", _DASK_RUNS, str(m), str(out), str(first_out)],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    got = json.loads(run.stdout.strip().splitlines()[-1])
    backend, computed = got["local"]
    assert backend["kind"] == "dask" and computed == 4
    rows = {r["name"]: r for r in pq.read_table(first_out / "fleet.parquet").to_pylist()}
    assert [r["status"] for r in rows.values()] == ["ok", "ok", "failed", "ok"]
    assert "log2" in rows["log2"]["error"] and "imu" in rows["log2"]["error"]
    for name in ("log0", "log1", "log3"):
        r = rows[name]
        # a static receiver seen with σ = 0.5 m white noise per axis: the filtered position is within
        # the fixes' own horizontal RMS (0.71 m), and the innovations match the filter's σ
        assert r["err_h_rms_m"] < 0.71
        assert 0.5 < r["nis_gnss_position_ratio"] < 2.0
        assert r["imu_samples"] == 100 * int(name != "log3" and 20 or 30)
        assert (first_out / name / "trajectory.parquet").is_file()
        assert (first_out / name / "overview.png").is_file()
        assert r["vehicle_id"] == ("car-a" if name in ("log1", "log3") else "car-b")
    html = (first_out / "fleet.html").read_text()
    assert "Failed logs (1)" in html and "log2" in html and "fleet distributions" in html
    first = outputs(first_out)
    assert "timing_s" not in json.loads((first_out / "log0" / "summary.json").read_text())

    backend2, address = got["external"]
    assert backend2["scheduler"] == address
    second = outputs(out)
    assert sorted(first) == sorted(second)
    assert [k for k in first if first[k] != second[k]] == []

    kept = (out / "log0" / "trajectory.parquet").read_bytes()
    again = run_fleet(m, out, workers=2, figures=True)  # nothing to do: every log has its row (no Dask)
    assert again.computed == 0 and again.reused == 4 and again.backend["kind"] == "none"
    assert (out / "log0" / "trajectory.parquet").read_bytes() == kept


def test_sigkill_in_the_middle_then_rerun_redoes_only_what_is_missing(tmp_path):
    m = fleet(tmp_path, seconds=(20, 20, 900, 20, 20), corrupt=None)  # the third log is the long one
    out = tmp_path / "out"
    env = dict(os.environ, AIDNAV_PROGRESS="0")
    p = subprocess.Popen([sys.executable, "-m", "aidnav", "fleet", str(m), "-o", str(out), "--workers", "1",
                          "--no-figures"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    rows = [out / f"log{k}" / ROW_FILE for k in range(5)]
    deadline = time.monotonic() + 300
    while not rows[1].exists() and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    p.send_signal(signal.SIGKILL)
    p.wait()
    done = [r for r in rows if r.exists()]
    assert rows[0] in done and rows[1] in done and rows[4] not in done, p.stderr.read().decode()
    stamp = {r: (r.stat().st_mtime_ns, r.read_bytes()) for r in done}
    assert not (out / "fleet.parquet").exists()

    res = run_fleet(m, out, workers=1, figures=False)
    assert res.reused == len(done) and res.computed == 5 - len(done)
    assert all(r["status"] == "ok" for r in res.rows)
    for r, (mtime, data) in stamp.items():  # what was done is not redone
        assert r.stat().st_mtime_ns == mtime and r.read_bytes() == data
    assert pq.read_table(out / "fleet.parquet").num_rows == 5
