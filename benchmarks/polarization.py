"""Throughput benchmark of the seed-002 polarization attitude fix (dipole triad, §3).

Prints attitude fixes per second on one core: each fix is N = 1000 complex snapshots → sample covariance
→ concentrated ML (started from the principal-eigenvector closed form) → attitude, line-of-sight
resolution and CRB covariance (:func:`aidnav.estimators.polarization.estimate_attitude`, method "ml").
Snapshots are simulated beforehand (not timed); η = 27°, SNR 10 dB, random attitudes. Best of several
runs, with a per-stage breakdown (each stage timed on its own over the same fixes):

* sample covariance R̂ (N = 1000),
* principal eigenvector + closed form,
* ML optimisation (BFGS from the closed form),
* attitude (line-of-sight resolution, C_b^n, Euler angles, CRB),

and the end-to-end figure (``estimate_attitude(sample_covariance(S), ...)``, input checks included).

Then the batch API (:mod:`aidnav.estimators.polarization_batch`, numba, one call for all fixes):
``estimate_attitude_batch(sample_covariance_batch(S), ...)`` end to end, with its two stages, and the
largest difference of its attitudes from the per-fix API's.

Target: >= 20,000 fixes/s.

Run: ``python benchmarks/polarization.py [--fixes K] [--repeat R] [--snapshots N]``.
"""

from __future__ import annotations

import os

# one core: set before numpy / scipy are imported
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from aidnav.estimators.polarization import (  # noqa: E402
    closed_form_covariance,
    crb_attitude,
    estimate_attitude,
    ml_estimate,
    resolve_line_of_sight,
)
from aidnav.estimators.polarization_batch import (  # noqa: E402
    estimate_attitude_batch,
    sample_covariance_batch,
)
from aidnav.nav.rotations import dcm_from_euler, euler_from_dcm  # noqa: E402
from aidnav.sim.dipole_triad import (  # noqa: E402
    sample_covariance,
    simulate_snapshots,
    wave_params_for_attitude,
)

TARGET = 20_000
D = np.pi / 180.0
ETA, SNR_DB, TX_TILT = 27.0 * D, 10.0, 0.0


def make_cases(k: int, n: int, rng: np.random.Generator):
    """k random geometries/attitudes and their snapshot blocks (k, n, 3)."""
    cases, S = [], np.empty((k, n, 3), dtype=complex)
    for i in range(k):
        rph = (rng.uniform(-20, 20) * D, rng.uniform(-10, 10) * D, rng.uniform(0, 360) * D)
        brg, el = rng.uniform(0, 2 * np.pi), rng.uniform(1, 20) * D
        wave = wave_params_for_attitude(dcm_from_euler(*rph), brg, el, TX_TILT)
        S[i] = simulate_snapshots(*wave, ETA, SNR_DB, n, rng)
        cases.append((brg, el, rph))
    return cases, S


def best_time(fn, repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fixes", type=int, default=300, help="fixes per timed run")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs (best is kept)")
    ap.add_argument("--snapshots", type=int, default=1000, help="snapshots N per fix")
    a = ap.parse_args(argv)

    rng = np.random.default_rng(16)
    cases, S = make_cases(a.fixes, a.snapshots, rng)
    n, k = a.snapshots, a.fixes
    Rs = [sample_covariance(S[i]) for i in range(k)]
    cfs = [closed_form_covariance(R, ETA) for R in Rs]
    mls = [ml_estimate(R, ETA, start=cf) for R, cf in zip(Rs, cfs, strict=True)]

    def stage_cov():
        for i in range(k):
            sample_covariance(S[i])

    def stage_cf():
        for R in Rs:
            closed_form_covariance(R, ETA)

    def stage_ml():
        for R, cf in zip(Rs, cfs, strict=True):
            ml_estimate(R, ETA, start=cf)

    def stage_att():
        for ml, (brg, el, _) in zip(mls, cases, strict=True):
            g, C, _ = resolve_line_of_sight(ml.phi, ml.theta, ml.gamma, brg, el, TX_TILT)
            crb_attitude(ml.phi, ml.theta, g, ETA, max(ml.snr, 1e-6), n, brg, el, TX_TILT)
            euler_from_dcm(C)

    fixes = []

    def end_to_end():
        fixes.clear()
        for i, (brg, el, _) in enumerate(cases):
            fixes.append(estimate_attitude(sample_covariance(S[i]), n, ETA, brg, el, TX_TILT))

    end_to_end()  # warm-up (imports, caches)
    stages = [(f"sample covariance (N = {n})", stage_cov), ("eigenvector + closed form", stage_cf),
              ("ML optimisation (BFGS)", stage_ml), ("attitude + LOS + CRB", stage_att)]
    times = {name: best_time(fn, a.repeat) / k for name, fn in stages}
    t_e2e = best_time(end_to_end, a.repeat) / k

    err = []
    for fx, (_, _, rph) in zip(fixes, cases, strict=True):
        d = np.asarray(fx.rph) - np.asarray(rph)
        d[2] = (d[2] + np.pi) % (2 * np.pi) - np.pi
        err.append(np.abs(d))
    nit = np.mean([m.nit for m in mls])

    print(f"polarization attitude fix benchmark — {platform.processor() or platform.machine()}, "
          f"python {platform.python_version()}, numpy {np.__version__}, 1 thread")
    print(f"fixes {k} x N = {n} snapshots, eta = 27 deg, SNR = {SNR_DB:g} dB, best of {a.repeat}")
    print(f"{'stage':34s} {'us/fix':>10s} {'fixes/s':>12s}")
    for name, t in times.items():
        print(f"{name:34s} {t * 1e6:10.1f} {1 / t:12,.0f}")
    print(f"{'sum of stages':34s} {sum(times.values()) * 1e6:10.1f} {1 / sum(times.values()):12,.0f}")
    print(f"{'end to end (estimate_attitude)':34s} {t_e2e * 1e6:10.1f} {1 / t_e2e:12,.0f}")
    err = np.degrees(np.max(err, axis=1))
    print(f"mean BFGS iterations {nit:.1f}; attitude error max {np.max(err[err < 90]):.2f} deg, "
          f"line-of-sight flips (no prior) {int(np.sum(err >= 90))}/{k}")
    print(f"per-fix API: {1 / t_e2e:,.0f} fixes/s")

    # batch API
    brg = np.array([c[0] for c in cases])
    el = np.array([c[1] for c in cases])
    batch = {}

    def b_cov():
        batch["R"] = sample_covariance_batch(S)

    def b_fix():
        batch["fix"] = estimate_attitude_batch(batch["R"], n, ETA, brg, el, TX_TILT)

    def b_e2e():
        batch["e2e"] = estimate_attitude_batch(sample_covariance_batch(S), n, ETA, brg, el, TX_TILT)

    b_e2e()  # warm-up (numba cache load / compile)
    tb = {"batch sample covariance": best_time(b_cov, a.repeat) / k,
          "batch ML + attitude + CRB": best_time(b_fix, a.repeat) / k}
    t_b = best_time(b_e2e, a.repeat) / k
    for name, t in tb.items():
        print(f"{name:34s} {t * 1e6:10.1f} {1 / t:12,.0f}")
    print(f"{'batch end to end':34s} {t_b * 1e6:10.1f} {1 / t_b:12,.0f}")
    fb = batch["e2e"]
    d_rph = np.max(np.abs(np.array([fx.rph for fx in fixes]) - fb.rph))
    print(f"batch vs per-fix: max |d(roll, pitch, heading)| {np.degrees(d_rph):.2e} deg; mean Newton steps "
          f"{fb.nit.mean():.1f}; converged {int(fb.converged.sum())}/{k}")
    ok = 1 / t_b >= TARGET
    print(f"target >= {TARGET:,} fixes/s: {'MET' if ok else 'NOT MET'} (batch {1 / t_b:,.0f} fixes/s, "
          f"per-fix API {1 / t_e2e:,.0f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
