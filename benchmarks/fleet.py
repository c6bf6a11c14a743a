"""``aidnav fleet`` on 200 one-minute logs (issue 41): wall time per log on a local 2-worker cluster.

The logs are cut from ``sim_w1_pyins`` (one hour): log k covers (17·k, 17·k + 60] s, its configuration
``examples/sim_w1_pyins.yaml`` with the initial state taken from the reference at the cut's start (the
windows overlap: 200 minutes out of one hour). Without the data folder the benchmark stops.

Printed: the command's wall time (from its start to its exit, Dask's cluster start and the workers' numba
load included) and CPU time (its own and its workers'), per log, against the target (≤ 0.3 s per log), once
with ``--no-figures`` and once with each log's figures (overview, maps, page: ``--figures``; the command's
default is without); and, for reference, the median wall of separate ``aidnav process`` commands on a few of
the logs (what a fleet costs without ``aidnav fleet``). The machine is shared: the load average is printed
with the figures. The target is met when the command's CPU time per log divided by the workers is within it
(what two free cores give) and the wall time is too on an idle machine; the per-log figures cost about 1
CPU-s each (hence off by default).

Run: ``python benchmarks/fleet.py [--logs N] [--workers N] [--only-no-figures] [--json out.json]``
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("AIDNAV_DATA", ROOT.parent / "shared" / "data"))
TARGET_S_PER_LOG = 0.3
STEP_S, LENGTH_S = 17.0, 60.0


def make_fleet(tmp: Path, n: int) -> Path:
    """``n`` one-minute cuts of W1 with their configurations and a manifest; returns the manifest."""
    import numpy as np
    import pyarrow.compute as pc
    import pyarrow.parquet as pq
    import yaml

    src = DATA / "sim_w1_pyins"
    imu = pq.read_table(src / "imu.parquet")
    truth = pq.read_table(src / "truth_10hz.parquet").to_pydict()
    tt = np.asarray(truth["time"])
    gnss_lines = (src / "gnss.csv").read_text().splitlines(keepends=True)
    n_head = next(i for i, ln in enumerate(gnss_lines) if ln[:1].isdigit())
    head, body = "".join(gnss_lines[:n_head]), gnss_lines[n_head:]
    gt = np.array([float(ln.split(",", 1)[0]) for ln in body])
    base = yaml.safe_load((ROOT / "examples" / "sim_w1_pyins.yaml").read_text())
    lines = ["name,imu,gnss,config,vehicle_id\n"]
    for k in range(n):
        a = STEP_S * k
        b = a + LENGTH_S
        if b > float(tt[-1]):
            raise SystemExit(f"{n} logs of {LENGTH_S:g} s every {STEP_S:g} s do not fit in W1")
        d = tmp / f"w1_{k:03d}"
        d.mkdir()
        t = imu["time"]
        pq.write_table(imu.filter(pc.and_(pc.greater(t, a), pc.less_equal(t, b))), d / "imu.parquet")
        (d / "gnss.csv").write_text(head + "".join(body[i] for i in np.flatnonzero((gt > a) & (gt <= b))))
        j = int(np.argmin(abs(tt - a)))
        cfg = dict(base)
        cfg["init"] = {**base["init"], "lat_deg": float(truth["lat_deg"][j]),
                       "lon_deg": float(truth["lon_deg"][j]), "height_m": float(truth["height_m"][j]),
                       "velocity_m_s": [float(truth[c][j]) for c in ("ve", "vn", "vu")],
                       "roll_deg": float(truth["roll_deg"][j]), "pitch_deg": float(truth["pitch_deg"][j]),
                       "heading_deg": float(truth["heading_deg"][j])}
        (d / "config.yaml").write_text(yaml.safe_dump(cfg))
        lines.append(f"{d.name},{d.name}/imu.parquet,{d.name}/gnss.csv,{d.name}/config.yaml,"
                     f"car-{k % 4}\n")
    m = tmp / "fleet.csv"
    m.write_text("".join(lines))
    return m


def timed(cmd: list[str]) -> tuple[float, float]:
    """(wall, CPU) of a command: the CPU time of it and of the processes it waited for (Dask's workers)."""
    before = os.times()
    t = time.perf_counter()
    p = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                       env=dict(os.environ, AIDNAV_PROGRESS="0"))
    dt = time.perf_counter() - t
    after = os.times()
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode}): {p.stderr.decode()[-2000:]}")
    return dt, (after.children_user - before.children_user) + (after.children_system - before.children_system)


def wall(cmd: list[str]) -> float:
    return timed(cmd)[0]


def main(argv: list[str]) -> int:
    n = int(argv[argv.index("--logs") + 1]) if "--logs" in argv else 200
    workers = argv[argv.index("--workers") + 1] if "--workers" in argv else "2"
    path = argv[argv.index("--json") + 1] if "--json" in argv else None
    if not (DATA / "sim_w1_pyins").is_dir():
        print(f"no {DATA / 'sim_w1_pyins'}: the benchmark needs the W1 log")
        return 2
    py = sys.executable
    out = {"logs": n, "log_length_s": LENGTH_S, "workers": int(workers), "cpus": os.cpu_count(),
           "target_s_per_log": TARGET_S_PER_LOG, "cases": {}}
    with tempfile.TemporaryDirectory(prefix="aidnav-fleet-") as tmp:
        tmp = Path(tmp)
        m = make_fleet(tmp, n)
        # separate commands on 3 logs, for reference (one first, not counted: numba's cache)
        one = [py, "-m", "aidnav", "process", "--imu", str(tmp / "w1_000" / "imu.parquet"), "--gnss",
               str(tmp / "w1_000" / "gnss.csv"), "--config", str(tmp / "w1_000" / "config.yaml"), "-o",
               str(tmp / "single")]
        wall(one + ["--no-figures"])
        out["separate_commands"] = {
            "no_figures_s": statistics.median(wall(one + ["--no-figures"]) for _ in range(3)),
            "figures_s": statistics.median(wall(one) for _ in range(3))}
        modes = ["--no-figures"] if "--only-no-figures" in argv else ["--no-figures", "--figures"]
        for mode in modes:
            load0 = os.getloadavg()
            dt, cpu = timed([py, "-m", "aidnav", "fleet", str(m), "-o", str(tmp / f"out{mode}"), "--workers",
                             workers, mode])
            rows = tmp / f"out{mode}" / "fleet.parquet"
            import pyarrow.parquet as pq

            tab = pq.read_table(rows).to_pydict()
            out["cases"][mode] = {"wall_s": dt, "s_per_log": dt / n, "cpu_s": cpu,
                                  "ok": tab["status"].count("ok"),
                                  "load_before": load0, "load_after": os.getloadavg(),
                                  "median_task_wall_s": statistics.median(tab["wall_s"])}
    sep = out["separate_commands"]
    print(f"aidnav fleet, {n} one-minute logs cut from W1, --workers {workers}; {out['cpus']} CPUs")
    print(f"  separate `aidnav process` commands (median of 3): {sep['no_figures_s']:.3f} s per log "
          f"--no-figures, {sep['figures_s']:.3f} s with figures")
    ok = True
    for mode, c in out["cases"].items():
        verdict = "PASS" if c["s_per_log"] <= TARGET_S_PER_LOG else "FAIL"
        ok &= verdict == "PASS" or mode == "--figures"
        print(f"  aidnav fleet {mode:13s}: wall {c['wall_s']:7.2f} s = {c['s_per_log']:.3f} s per log "
              f"(target <= {TARGET_S_PER_LOG} s: {verdict}); CPU {c['cpu_s']:.1f} s = {c['cpu_s'] / n:.3f} s "
              f"per log; {c['ok']}/{n} ok; median task "
              f"{c['median_task_wall_s']:.3f} s; load average before "
              + " ".join(f"{x:.2f}" for x in c["load_before"]) + ", after "
              + " ".join(f"{x:.2f}" for x in c["load_after"]))
    if path:
        Path(path).write_text(json.dumps(out, indent=1))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
