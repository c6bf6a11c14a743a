"""Benchmark of the tightly coupled and federated filters (issue 24): IMU samples per second.

* tight: :func:`aidnav.filters.tight.run_tight` on the rtklibexplorer walk (as ``aidnav tight`` runs it,
  :func:`aidnav.apps.tight.process_tight`; SPP and reading outside the timing), forward and, where the
  filter has it, forward + RTS smoother; horizontal RMS against the RTK reference (Q = 1) for both.
* federated: :func:`aidnav.filters.federated.run_federated` on the seed-000 simulation.
Best of 3, compiled code warm. Target (issue 24): no slower than before the engine migration
(tight before: see docs/results.md / the report of the migration).

Run: ``python benchmarks/tight.py`` (needs ../shared/data or $AIDNAV_DATA).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import inspect  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("AIDNAV_DATA", ROOT.parent / "shared" / "data"))
WALK = DATA / "rtklibexplorer_walk_0827"
TARGET_TIGHT = float(os.environ.get("TIGHT_TARGET_SPS", "0"))  # samples/s before the migration


def best_of(fn, n=3):
    best, out = float("inf"), None
    for _ in range(n):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def tight_case():
    import aidnav.apps.tight as app
    from aidnav.apps.process import read_gnss_any, read_imu_any
    from aidnav.apps.tight import compare_with_reference, process_tight
    from aidnav.filters import tight
    from aidnav.io.rinex import read_rinex_nav, read_rinex_obs

    imu = read_imu_any(WALK / "imu_1730.csv")
    obs = read_rinex_obs(WALK / "rinex_converted/gnss_1730.obs")
    eph = read_rinex_nav(WALK / "rinex_converted/gnss_1730.nav", ref_week=getattr(obs, "ref_week", None))
    ref = read_gnss_any(WALK / "gnss_1730_sf.pos", -21.4)
    captured = {}
    orig = tight.run_tight

    def capture(*a, **k):  # the arguments process_tight gives run_tight
        captured["a"], captured["k"] = a, k
        return orig(*a, **k)

    app.run_tight = capture
    try:
        process_tight(imu, obs, eph)
    finally:
        app.run_tight = orig
    a, k = captured["a"], captured["k"]
    n = len(imu)
    modes = [("forward", {})]
    if "smooth" in inspect.signature(orig).parameters:
        modes.append(("forward + RTS", {"smooth": True}))
    for name, extra in modes:
        dt, res = best_of(lambda kw={**k, **extra}: orig(*a, **kw))
        traj = tight.to_trajectory(res)
        c = compare_with_reference(traj.time, traj.lat, traj.lon, traj.height, ref, quality=1)
        sig = np.median(np.hypot(traj.std_pos[:, 0], traj.std_pos[:, 1]))
        print(f"tight {name:14s}: {n / dt:12,.0f} IMU samples/s ({dt:.3f} s for {n} samples); "
              f"horizontal RMS (Q=1) {c['horizontal_rms']:.2f} m; median horizontal sigma {sig:.2f} m")
    return n


def federated_case():
    from aidnav.filters import federated

    fn = getattr(federated, "benchmark_case", None)
    if fn is None:
        print("federated: no benchmark_case in aidnav.filters.federated")
        return
    fn(best_of)


def main():
    if not WALK.is_dir():
        print(f"data folder {WALK} not found: set AIDNAV_DATA")
        return 2
    tight_case()
    federated_case()
    if TARGET_TIGHT:
        print(f"target: tight forward >= {TARGET_TIGHT:,.0f} samples/s (before the migration)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
