"""Issue 40 (report only): the walk's `aidnav tight` horizontal velocity RMS against the RTK positions'
differences (Q = 1 intervals, :func:`aidnav.analysis.velocity_reference.interval_velocity_errors`), with the
RINEX nav file alone and with the Galileo I/NAV ephemerides decoded from the UBX log added
(``read_rinex_pair(..., ubx_nav=...)``). Target (issue 40): ≤ 0.05 m/s horizontal; no configuration."""

from __future__ import annotations

import os
import time
import warnings
from pathlib import Path

from aidnav.analysis.velocity_reference import interval_velocity_errors
from aidnav.apps.process import read_imu_any
from aidnav.apps.tight import process_tight
from aidnav.filters.tight import TightConfig
from aidnav.io.rinex import read_rinex_pair
from aidnav.io.rtklib import read_pos

_DATA = Path(os.environ.get("AIDNAV_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
WALK = _DATA / "rtklibexplorer_walk_0827"


def run(ubx: bool):
    cfg = TightConfig()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        obs, eph, ev = read_rinex_pair(WALK / "rinex_converted" / "gnss_1730.obs",
                                       WALK / "rinex_converted" / "gnss_1730.nav", cfg.gnss.systems,
                                       ubx_nav=WALK / "gnss_1730.ubx" if ubx else None)
    imu = read_imu_any(WALK / "imu_1730.csv")
    ref = read_pos(WALK / "gnss_1730_sf.pos", height_offset_m=-21.4)
    res, _ = process_tight(imu, obs, eph, cfg, events=ev)
    iv = interval_velocity_errors(res.time, res.state[:, 3:6], ref.time, ref.lat, ref.lon, ref.height,
                                  use=ref.quality == 1)
    sats = sorted({int(p) for p in obs.prn})
    return iv.rms_horizontal(), len(iv), sats, ev


def main():
    for ubx in (False, True):
        c0, w0 = os.times(), time.time()
        rms, n, sats, ev = run(ubx)
        c1 = os.times()
        print(f"{'with' if ubx else 'without'} the UBX Galileo I/NAV: horizontal velocity RMS {rms:.4f} m/s "
              f"({n} intervals; target <= 0.05); satellites {len(sats)}; wall {time.time() - w0:.1f} s, "
              f"CPU {c1.user - c0.user:.1f} s, load {os.getloadavg()[0]:.2f}")
        for e in ev:
            if "Galileo" in e:
                print("   ", e)


if __name__ == "__main__":
    main()
