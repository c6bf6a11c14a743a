"""Issue 40 (report only): the walk's `aidnav tight` with no configuration, with the RINEX navigation file
alone (``gnss.ubx_nav: none``) and with the default (``auto``: the UBX log the observation file's header
names, :mod:`aidnav.io.nav_sources`, whose RXM-SFRBX ephemerides are added), forward and smoothed:

* position against the RTK reference at every reference epoch (the test's scoring: the output sample at or
  after it): horizontal / vertical RMS, the mean and the standard deviation of the E/N/U differences, the
  filter's median σ and the 3σ coverage per axis (targets: H ≤ 8.50 m, V ≤ 3.5 m, coverage ≥ 95 %);
* horizontal velocity RMS against the RTK positions' differences over the Q = 1 intervals
  (:func:`aidnav.analysis.velocity_reference.interval_velocity_errors`; target ≤ 0.05 m/s);
* per run the wall and CPU time and the load average.

``--no-clock-from-log``: the receiver clock's prior as the grade gives it (``gnss.clock_from_log`` off:
the tree before issue 40 session 15), for the before/after comparison.
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from aidnav.analysis.velocity_reference import interval_velocity_errors
from aidnav.apps.process import read_imu_any
from aidnav.apps.tight import process_tight
from aidnav.filters.tight import TightConfig, to_trajectory
from aidnav.io.nav_sources import format_sources, read_observations_and_navigation
from aidnav.io.rtklib import read_pos
from aidnav.nav.earth import lla_difference_enu

_DATA = Path(os.environ.get("AIDNAV_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
WALK = _DATA / "rtklibexplorer_walk_0827"


def walk_run(cfg, ubx_nav: str, smooth: bool, ubx_sources: str | None = None):
    """``aidnav tight`` on the walk as the command reads it, scored: (ENU errors (N, 3) [m] at the reference
    epochs in the run, the output rows ``j`` of those epochs, the interval velocity errors, the trajectory,
    the result, the ephemeris sources)."""
    kw = {} if ubx_sources is None else {"ubx_sources": ubx_sources}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        obs, eph, ev, src = read_observations_and_navigation(
            WALK / "rinex_converted" / "gnss_1730.obs", WALK / "rinex_converted" / "gnss_1730.nav",
            cfg.gnss.systems, ubx_nav, **kw)
    imu = read_imu_any(WALK / "imu_1730.csv")
    ref = read_pos(WALK / "gnss_1730_sf.pos", height_offset_m=-21.4)
    res, _ = process_tight(imu, obs, eph, cfg, events=ev, smooth=smooth)
    tr = to_trajectory(res)
    sel = (ref.time >= tr.time[0]) & (ref.time <= tr.time[-1])
    j = np.clip(np.searchsorted(tr.time, ref.time[sel]), 0, len(tr.time) - 1)
    d = np.column_stack(lla_difference_enu(tr.lat[j], tr.lon[j], tr.height[j], ref.lat[sel], ref.lon[sel],
                                           ref.height[sel]))
    iv = interval_velocity_errors(res.time, res.state[:, 3:6], ref.time, ref.lat, ref.lon, ref.height,
                                  use=ref.quality == 1)
    return d, j, iv, tr, res, src


def run(ubx_nav: str, smooth: bool, clock_from_log: bool = True):
    cfg = TightConfig() if clock_from_log else TightConfig(gnss={"clock_from_log": False})
    d, j, iv, tr, _, src = walk_run(cfg, ubx_nav, smooth)
    cover = np.mean(np.abs(d) <= 3 * tr.std_pos[j], axis=0)
    sig = np.median(tr.std_pos[j], axis=0)
    return d, (cover, sig), iv.rms_horizontal(), len(iv), src


def main():
    clock_from_log = "--no-clock-from-log" not in sys.argv[1:]
    print(f"walk {WALK}; aidnav tight, no configuration; gnss.clock_from_log {clock_from_log}")
    for ubx_nav in ("none", "auto"):
        for smooth in (False, True):
            c0, w0 = os.times(), time.time()
            d, (cover, sig), vel, n_iv, src = run(ubx_nav, smooth, clock_from_log)
            c1 = os.times()
            h = np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2))
            kind = 'smoothed' if smooth else 'forward'
            print(f"ubx_nav {ubx_nav}, {kind}: H RMS {h:.3f} m (target <= 8.50), "
                  f"V RMS {np.sqrt(np.mean(d[:, 2] ** 2)):.3f} m (<= 3.5); mean E/N/U "
                  f"{' / '.join(f'{x:.2f}' for x in d.mean(0))} m, SD "
                  f"{' / '.join(f'{x:.2f}' for x in d.std(0))} m; median sigma "
                  f"{' / '.join(f'{x:.2f}' for x in sig)} m; 3-sigma coverage "
                  f"{' / '.join(f'{100 * x:.1f}' for x in cover)} % ({len(d)} epochs); velocity H RMS "
                  f"{vel:.4f} m/s ({n_iv} intervals; target <= 0.05); wall {time.time() - w0:.1f} s, CPU "
                  f"{c1.user - c0.user + c1.system - c0.system:.1f} s, load {os.getloadavg()[0]:.2f}")
            if not smooth:
                print("   ", format_sources(src))


if __name__ == "__main__":
    main()
