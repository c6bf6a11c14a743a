"""Micro-benchmark of the Kalman core's batch update (issue 40): :func:`aidnav.filters.kalman.update` (the
Joseph form expanded, O(n²m)) against its form before issue 40 (the product (I − KH) P (I − KH)ᵀ + K R Kᵀ,
2n³, kept here as a numba kernel), per call, at the tight filter's sizes (21, 33, 37 states) and the rows
of a velocity record (3 rows; H sparse as the velocity model's: δv, attitude and gyro-bias entries), and
with a dense H (the worst case) of 1, 3 and 6 rows.

Each figure: best of 7 repetitions of 2,000 calls (compiled code warm, the same P restored before each
repetition), CPU time of this process (time.process_time; single-threaded kernels) and wall time; the
machine's load average is printed. No target of its own: it explains ``benchmarks/tight.py``'s change.

Run: ``python benchmarks/kalman_update.py``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

import numpy as np  # noqa: E402

from aidnav.filters.kalman import update  # noqa: E402
from aidnav.jit import njit  # noqa: E402

CALLS, REPS = 2000, 7


@njit(cache=False)
def update_product(x, P, H, R, z, gate, innov_out, s_out):
    """``kalman.update`` before issue 40 (the Joseph product form, then symmetrised)."""
    m = z.shape[0]
    nu = z - H @ x
    PHt = P @ H.T
    S = H @ PHt + R
    for i in range(m):
        innov_out[i] = nu[i]
        s_out[i] = S[i, i]
    Sinv = np.linalg.inv(S)
    nis = nu @ Sinv @ nu
    if gate > 0.0 and nis > gate:
        return False, nis
    K = PHt @ Sinv
    x += K @ nu
    n = x.shape[0]
    IKH = -K @ H
    for i in range(n):
        IKH[i, i] += 1.0
    P[:, :] = IKH @ P @ IKH.T + K @ R @ K.T
    Pt = P.T.copy()
    P += Pt
    P *= 0.5
    return True, nis


@njit(cache=False)
def _calls(fn, x, P, H, R, z, k):
    nu, sd = np.zeros(z.shape[0]), np.zeros(z.shape[0])
    for _ in range(k):
        fn(x, P, H, R, z, 0.0, nu, sd)


def per_call(fn, n, m, rng, sparse):
    a = rng.normal(size=(n, n))
    P0 = a @ a.T / n + np.eye(n)
    H = rng.normal(size=(m, n))
    if sparse:  # a velocity record's row: its δv entry, attitude and gyro bias (lever arm) entries
        H[:, 15:] = 0.0
        H[:, 6:12] = 0.0
        H[:, 3:6] = np.eye(3)[:m] if m <= 3 else 0.0
    R = np.diag(rng.uniform(0.5, 2.0, m))
    x, z = np.zeros(n), rng.normal(size=m) * 1e-3
    _calls(fn, x, P0.copy(), H, R, z, 2)  # compile
    best_cpu, best_wall = np.inf, np.inf
    for _ in range(REPS):
        P = P0.copy()  # (the updates shrink P; the cost does not depend on its values)
        c, w = time.process_time(), time.perf_counter()
        _calls(fn, x, P, H, R, z, CALLS)
        best_cpu = min(best_cpu, time.process_time() - c)
        best_wall = min(best_wall, time.perf_counter() - w)
    return best_cpu / CALLS, best_wall / CALLS


def main():
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; per call, best of {REPS} x "
          f"{CALLS}")
    rng = np.random.default_rng(0)
    for n, m, sparse in ((21, 3, True), (33, 3, True), (37, 3, True), (21, 1, False), (33, 1, False),
                         (33, 3, False), (33, 6, False), (37, 6, False)):
        old = per_call(update_product, n, m, rng, sparse)
        new = per_call(update, n, m, rng, sparse)
        print(f"n {n:2d} m {m} H {'sparse' if sparse else 'dense '}: product form {old[0] * 1e6:6.2f} us CPU "
              f"({old[1] * 1e6:6.2f} wall), expanded {new[0] * 1e6:6.2f} us CPU ({new[1] * 1e6:6.2f} wall): "
              f"{old[0] / new[0]:4.1f}x by CPU")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
