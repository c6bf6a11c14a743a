"""Benchmark of the tightly coupled and federated filters (issue 24): IMU samples per second.

* tight: :func:`aidnav.filters.tight.run_tight` on the rtklibexplorer walk (as ``aidnav tight`` runs
  it, :func:`aidnav.estimators.tight_solution.process_tight`; SPP and reading outside the timing), forward
  and, where the filter has it, forward + RTS smoother; horizontal RMS against the RTK reference (Q = 1)
  for both; with no configuration (the unknown-grade IMU model: 27 INS states) and, forward, with the
  15-state model.
* federated: :func:`aidnav.filters.federated.run_federated` on the seed-000 simulation (600 s, 100 Hz),
  fusion-reset and centralized, forward and forward + RTS.
Best of 3, compiled code warm, CPU time of this process (single-threaded kernels: the figure that
holds on a shared machine; wall time = CPU time on an idle one). Target (issue 24): no slower than
before the engine migration (``BEFORE``, measured with the pre-engine kernels, wall time).

* satcom: :func:`aidnav.estimators.satcom.run_nav8` (seed 003's 8-state filter; no target in issue 24).

Run: ``python benchmarks/tight.py [tight_module [federated_module [satcom_module]]]`` (needs ../shared/data or
$AIDNAV_DATA; the optional module names let the same script time another implementation).
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
# IMU samples/s of the pre-engine kernels (commit c842deb): this script, best of 3, shared 2-core machine
BEFORE = {"tight": 625_559, "reset": 1_151_719, "centralized": 1_511_781}
TARGET_TIGHT = 800_000  # issue 40: tight forward with the range-error states on (IMU samples/s)


def best_of(fn, n=3, wall=None):
    """Best CPU time of ``n`` calls and the last result; the best wall time appended to ``wall`` if given."""
    best, best_wall, out = float("inf"), float("inf"), None
    for _ in range(n):
        t, w = time.process_time(), time.perf_counter()
        out = fn()
        best = min(best, time.process_time() - t)
        best_wall = min(best_wall, time.perf_counter() - w)
    if wall is not None:
        wall.append(best_wall)
    return best, out


def tight_case(module="aidnav.filters.tight"):
    import importlib

    import aidnav.estimators.tight_solution as app  # the module whose run_tight process_tight calls
    from aidnav.apps.process import read_gnss_any, read_imu_any
    from aidnav.apps.tight import compare_with_reference, process_tight
    tight = importlib.import_module(module)
    from aidnav.io.rinex import read_rinex_nav, read_rinex_obs

    imu = read_imu_any(WALK / "imu_1730.csv")
    obs = read_rinex_obs(WALK / "rinex_converted/gnss_1730.obs")
    eph = read_rinex_nav(WALK / "rinex_converted/gnss_1730.nav", ref_week=getattr(obs, "ref_week", None))
    ref = read_gnss_any(WALK / "gnss_1730_sf.pos", -21.4)
    orig = tight.run_tight
    # no configuration (what `aidnav tight` runs: the unknown-grade IMU model, 27 INS states) and the
    # 15-state model of the issue-40 figures before session 9 (imu: noise from the static samples only)
    cases = [("no config", None), ("15 INS states", tight.TightConfig(imu={"noise_from_static": True}))]
    n = len(imu)
    for label, cfg in cases:
        captured = {}

        def capture(*a, cap=captured, **k):  # the arguments process_tight gives run_tight
            cap["a"], cap["k"] = a, k
            return orig(*a, **k)

        app.run_tight = capture
        try:
            process_tight(imu, obs, eph, cfg)
        finally:
            app.run_tight = orig
        a, k = captured["a"], captured["k"]
        modes = [("forward", {})]
        if cfg is None and "smooth" in inspect.signature(orig).parameters:
            modes.append(("forward + RTS", {"smooth": True}))
        for name, extra in modes:
            wall = []
            dt, res = best_of(lambda kw={**k, **extra}, args=a: orig(*args, **kw), wall=wall)
            traj = tight.to_trajectory(res)
            c = compare_with_reference(traj.time, traj.lat, traj.lon, traj.height, ref, quality=1)
            sig = np.median(np.hypot(traj.std_pos[:, 0], traj.std_pos[:, 1]))
            # three decimals and the vertical: the two models' horizontal figures agree to 1 cm (8.378 and
            # 8.384 m; median sigma 6.0062 and 6.0063 m; positions up to 0.26 m apart): on the walk the
            # pseudoranges and range-error states, not the IMU's error model, set the horizontal position
            print(f"tight {name:14s} ({label}, {res.nstate} states): {n / dt:10,.0f} IMU samples/s "
                  f"({dt:.4f} CPU-s, wall {n / wall[0]:,.0f}/s, for {n} samples); RMS (Q=1) horizontal "
                  f"{c['horizontal_rms']:.3f} m, vertical {c['vertical_rms']:.3f} m; median horizontal sigma "
                  f"{sig:.4f} m")
            if name == "forward":
                met = "met" if n / dt >= TARGET_TIGHT else "NOT met"
                print(f"  target (issue 40): >= {TARGET_TIGHT:,} forward with the range-error states on "
                      f"({res.range_error.shape[1]} states): {met}")
    return n


def federated_case(module="aidnav.filters.federated"):
    import importlib

    from aidnav.experiments.reproduce import seed_000 as s0

    federated = importlib.import_module(module)
    sim, sv, cfg = s0.simulate_case(np.random.SeedSequence(11), duration_s=600.0)
    n = len(sim.imu)
    modes = [("forward", {})]
    if "smooth" in inspect.signature(federated.run_federated).parameters:
        modes.append(("forward + RTS", {"smooth": True}))
    for mode in ("reset", "centralized"):
        fed = federated.FederatedConfig(mode=mode)
        for name, extra in modes:
            def run(f=fed, kw=extra):
                return federated.run_federated(sim.imu, sim.gnss, sv, cfg, f, **kw)

            dt, _ = best_of(run)
            print(f"federated {mode:11s} {name:14s}: {n / dt:12,.0f} IMU samples/s "
                  f"({dt:.3f} s for {n} samples)")


def satcom_case(module="aidnav.estimators.satcom"):
    """The seed-003 8-state navigation filter (run_nav8) on a 160 s MEMS car run at 100 Hz."""
    import importlib

    from aidnav.sim.run import simulate
    from aidnav.sim.scenario import Scenario

    satcom = importlib.import_module(module)
    scn = Scenario.model_validate(dict(
        name="bench", seed=1, initial=dict(lat_deg=39.9, lon_deg=116.4, height_m=50.0, heading_deg=60.0),
        imu_rate_hz=100.0, transition_s=2.0,
        segments=[dict(type="static", duration_s=20), dict(type="accelerate", duration_s=10, to_speed_m_s=15),
                  dict(type="straight", duration_s=60), dict(type="turn", angle_deg=90, rate_deg_s=6),
                  dict(type="straight", duration_s=55)],
        sensors=dict(imu=dict(grade="mems"), gnss=dict(rate_hz=1.0))))
    sim = simulate(scn, seed=7)
    tr = sim.truth
    args = (sim.imu, sim.gnss, tr.lat[0], tr.lon[0], tr.height[0], tr.vel[0], tr.rph[0])
    dt, _ = best_of(lambda: satcom.run_nav8(*args))
    n = len(sim.imu)
    print(f"satcom run_nav8 (8-state)       : {n / dt:12,.0f} IMU samples/s ({dt:.3f} s for {n} samples)")


def main():
    if not WALK.is_dir():
        print(f"data folder {WALK} not found: set AIDNAV_DATA")
        return 2
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs (CPU time of this process below)")
    tight_case(*sys.argv[1:2])
    federated_case(*sys.argv[2:3])
    satcom_case(*sys.argv[3:4])
    print("target (issue 24): no slower than before the engine migration; measured before on this machine "
          f"(best of 3, shared CPUs): tight forward {BEFORE['tight']:,} samples/s, federated reset forward "
          f"{BEFORE['reset']:,}, centralized {BEFORE['centralized']:,}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
