"""Issue 40 (report only): the walk's velocity with and without the carrier phase, and its σ.

`aidnav tight` with no configuration on ``rtklibexplorer_walk_0827``, forward and smoothed, for the cases:
the default (``ubx_nav: auto`` with every source of the UBX log, :data:`aidnav.io.rinex.UBX_SOURCES`: its
ephemerides, Klobuchar coefficients and RXM-RAWX measurements — the BeiDou B1C satellites the observation
file lacks and the receiver's phase σ), the same without ``rawx`` (session 14's default), the navigation file
alone (``none``), and the default without the phase (``gnss.use_phase: false``). Printed per case:

* horizontal / vertical velocity RMS against the RTK positions' differences over the Q = 1 intervals
  (:func:`aidnav.analysis.velocity_reference.interval_velocity_errors`; target ≤ 0.05 m/s horizontal, with the
  phase), and the 3σ coverage of those interval errors per ENU axis with the filter's velocity σ at the
  interval's middle (the reference's own noise, ≈ 0.015 m/s per axis standing still, counts against it);
* position H / V RMS and 3σ coverage at every reference epoch (targets H ≤ 8.50 m, V ≤ 3.5 m, ≥ 95 %);
* the TDCP records used and the CPU time per run, with the load average.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from aidnav.analysis.velocity_reference import interval_velocity_errors
from aidnav.apps.process import read_imu_any
from aidnav.apps.tight import process_tight
from aidnav.filters.tight import TightConfig, to_trajectory
from aidnav.io.nav_sources import read_observations_and_navigation
from aidnav.io.rinex import UBX_SOURCES
from aidnav.io.rtklib import read_pos
from aidnav.nav.earth import lla_difference_enu

_DATA = Path(os.environ.get("AIDNAV_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
WALK = _DATA / "rtklibexplorer_walk_0827"
CASES = {  # name: (ubx_nav, ubx_sources, use_phase)
    "default": ("auto", UBX_SOURCES, True),
    "no rawx (session 14)": ("auto", UBX_SOURCES.replace(",rawx", ""), True),
    "nav file alone": ("none", UBX_SOURCES, True),
    "default, no phase": ("auto", UBX_SOURCES, False),
}


def run(ubx_nav: str, sources: str, use_phase: bool, smooth: bool):
    """(position ENU errors (N, 3), position σ (N, 3), interval velocity errors, velocity σ at the
    intervals' middles (K, 3), the result)."""
    cfg = TightConfig()
    if not use_phase:
        cfg = cfg.model_copy(update={"gnss": cfg.gnss.model_copy(update={"use_phase": False})})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        obs, eph, ev, _ = read_observations_and_navigation(
            WALK / "rinex_converted" / "gnss_1730.obs", WALK / "rinex_converted" / "gnss_1730.nav",
            cfg.gnss.systems, ubx_nav, ubx_sources=sources)
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
    mid = 0.5 * (iv.t_start + iv.t_end)
    sv = np.column_stack([np.interp(mid, tr.time, tr.std_vel[:, i]) for i in range(3)])
    return d, tr.std_pos[j], iv, sv, res


def main():
    print(f"walk {WALK}; aidnav tight, no configuration; load {os.getloadavg()[0]:.2f}")
    for name, (ubx_nav, sources, use_phase) in CASES.items():
        for smooth in (False, True):
            c0 = os.times()
            d, sp, iv, sv, res = run(ubx_nav, sources, use_phase, smooth)
            c1 = os.times()
            h = np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2))
            cov_p = 100 * np.mean(np.abs(d) <= 3 * sp, axis=0)
            cov_v = 100 * np.mean(np.abs(iv.err) <= 3 * sv, axis=0)
            print(f"{name}, {'smoothed' if smooth else 'forward'}: velocity H {iv.rms_horizontal():.4f} m/s "
                  f"(target <= 0.05), V {iv.rms_vertical():.4f} m/s, 3-sigma coverage E/N/U "
                  f"{' / '.join(f'{x:.1f}' for x in cov_v)} % ({len(iv)} intervals); position H "
                  f"{h:.3f} m (<= 8.50), V {np.sqrt(np.mean(d[:, 2] ** 2)):.3f} m (<= 3.5), 3-sigma "
                  f"{' / '.join(f'{x:.1f}' for x in cov_p)} %; velocity records used "
                  f"{res.counts['velocity_used']} of {res.counts['velocity_records']}; CPU "
                  f"{c1.user - c0.user + c1.system - c0.system:.1f} s, load {os.getloadavg()[0]:.2f}",
                  flush=True)


if __name__ == "__main__":
    main()
