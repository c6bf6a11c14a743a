"""Throughput benchmark of the strapdown mechanization and the motion/IMU simulator.

Prints IMU samples per second, on one core, after a warm-up call (numba compilation or cache load
excluded), best of several runs over a 1-hour 100 Hz figure-8 flight (360,000 samples):

* ``strapdown.mechanize`` (vertical channel held to the truth, and free),
* ``motion.generate`` (truth trajectory + exact IMU increments).

Targets: mechanize >= 2,000,000 samples/s, generate >= 1,000,000 samples/s.

Run: ``python benchmarks/strapdown.py [--repeat N] [--samples N]``.
"""

from __future__ import annotations

import os

# one core: set before numba / numpy are imported
for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from aidnav.nav import rotations, strapdown  # noqa: E402
from aidnav.sim import motion  # noqa: E402

TARGET_MECH = 2_000_000
TARGET_GEN = 1_000_000


def figure8_profile(duration: float, speed: float = 100.0, rate_deg_s: float = 3.0):
    """Primitive segments of a figure-8 flight: straight, then alternating ±360° turns with straights."""
    r = np.radians(rate_deg_s)
    tb, vals = [0.0], [[0.0, 0.0, 0.0]]
    t, sign = 60.0, 1.0
    while t < duration:
        tb.append(t)
        vals.append([0.0, sign * r, 0.0])
        t += 2 * np.pi / r
        tb.append(t)
        vals.append([0.0, 0.0, 0.0])
        t += 20.0
        sign = -sign
    tb = np.array(tb)
    return tb, motion.half_widths(tb, 4.0), np.array(vals)


def best_time(fn, repeat: int) -> float:
    """Best wall time [s] of ``repeat`` calls of ``fn`` (after one warm-up call)."""
    fn()
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=360_000, help="IMU samples per run (100 Hz)")
    ap.add_argument("--repeat", type=int, default=7, help="timed runs; the best is reported")
    args = ap.parse_args()

    dt, n = 0.01, args.samples
    tb, half, vals = figure8_profile(n * dt)
    y0 = np.array([np.radians(40.0), np.radians(116.0), 1000.0, 100.0, np.radians(30.0), 0.0])

    def gen():
        return motion.generate(tb, half, vals, y0, 0.0, dt, n)

    truth, dth, dv = gen()
    q = rotations.euler_to_quat_batch(np.ascontiguousarray(truth[:, 7:10]))
    st0 = strapdown.make_state(truth[0, 1], truth[0, 2], truth[0, 3], truth[0, 4:7], q[0])
    time_s = np.ascontiguousarray(truth[1:, 0])
    hold_h = np.ascontiguousarray(truth[1:, 3])
    hold_vu = np.ascontiguousarray(truth[1:, 6])
    empty = np.empty(0)

    rows = [
        (
            "strapdown.mechanize (height held)",
            TARGET_MECH,
            best_time(lambda: strapdown.mechanize(time_s, dth, dv, st0, 0.0, hold_h, hold_vu), args.repeat),
        ),
        (
            "strapdown.mechanize (free vertical)",
            TARGET_MECH,
            best_time(lambda: strapdown.mechanize(time_s, dth, dv, st0, 0.0, empty, empty), args.repeat),
        ),
        ("motion.generate (truth + IMU)", TARGET_GEN, best_time(gen, args.repeat)),
    ]

    print(
        f"aidnav strapdown benchmark: {n:,} IMU samples (100 Hz figure-8), best of {args.repeat}, "
        f"1 thread, {platform.processor() or platform.machine()}, numpy {np.__version__}"
    )
    hdr = f"{'kernel':<38} {'best time [s]':>13} {'samples/s':>14} {'target':>12}  verdict"
    print(hdr)
    print("-" * len(hdr))
    for name, target, t in rows:
        rate = n / t
        verdict = "OK" if rate >= target else "BELOW TARGET"
        print(f"{name:<38} {t:>13.4f} {rate:>14,.0f} {target:>12,}  {verdict}")


if __name__ == "__main__":
    main()
