"""Issue 40 (report only): the walk's `aidnav tight` (no configuration) with the data of the UBX log merged
into the RINEX navigation file's (:func:`aidnav.io.rinex.read_rinex_pair` with ``ubx_nav`` and
``ubx_sources``): per case the ``gnss.systems`` and the sources (inav: Galileo I/NAV records, lnav / cnav:
GPS LNAV / CNAV records — CNAV adds G08, G18, G24 —, klobuchar ("+iono"): the log's Klobuchar
coefficients; the nav file has none, so without it RTKLIB's default coefficients are used).
``--cut-g08 N``: a diagnostic, G08's first N code epochs removed (its acquisition: the receiver's own
prStdev 82 → 5 m over ~10 s).

Prints per case, forward and smoothed: position RMS against the RTK `.pos` at its Q = 1 epochs (horizontal,
vertical; :func:`aidnav.apps.tight.compare_with_reference`), the 3σ coverage of the position per ENU axis
(|error| ≤ 3σ, σ interpolated at the reference epochs), the horizontal velocity RMS over the Q = 1
intervals (:func:`aidnav.analysis.velocity_reference.interval_velocity_errors`, issue 40's figure; target
≤ 0.05 m/s) and its 3σ coverage per axis (σ = the estimate's velocity σ at the interval's middle: a rough
figure, the interval mean's σ is smaller), the satellites used, CPU and wall time and the load.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from aidnav.analysis.velocity_reference import interval_velocity_errors
from aidnav.apps.process import read_imu_any
from aidnav.apps.tight import compare_with_reference
from aidnav.estimators.tight_solution import process_tight
from aidnav.filters.tight import TightConfig, to_trajectory
from aidnav.io.rinex import read_rinex_pair
from aidnav.io.rtklib import read_pos
from aidnav.nav.gnss_sat import sat_name

_DATA = Path(os.environ.get("AIDNAV_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
WALK = _DATA / "rtklibexplorer_walk_0827"
CASES = {"nav file": ("GECR", None), "nav file +iono": ("GECR", "klobuchar"),
         "+GPS": ("G", "lnav,cnav"), "+GPS +iono": ("G", "lnav,cnav,klobuchar"),
         "+Galileo": ("GECR", "inav"), "+Galileo +iono": ("GECR", "inav,klobuchar"),
         "+all": ("GECR", "inav,lnav,cnav"), "+all +iono (default)": ("GECR", "inav,lnav,cnav,klobuchar")}


def run(systems: str, sources: str | None, smooth: bool, data: Path = WALK, cut_g08: int = 0) -> dict:
    cfg = TightConfig(gnss={"systems": systems})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        obs, eph, ev = read_rinex_pair(data / "rinex_converted" / "gnss_1730.obs",
                                       data / "rinex_converted" / "gnss_1730.nav", systems,
                                       ubx_nav=data / "gnss_1730.ubx" if sources else None,
                                       ubx_sources=sources or "")
    if cut_g08 and 8 in obs.prn:
        j = list(obs.prn).index(8)
        code = obs.code1.copy()
        first = int(np.argmax(np.isfinite(code[:, j])))
        code[:first + cut_g08, j] = np.nan
        obs = replace(obs, code1=code)
    imu = read_imu_any(data / "imu_1730.csv")
    ref = read_pos(data / "gnss_1730_sf.pos", height_offset_m=-21.4)
    res, _ = process_tight(imu, obs, eph, cfg, events=ev, smooth=smooth)
    traj = to_trajectory(res)
    c = compare_with_reference(traj.time, traj.lat, traj.lon, traj.height, ref, quality=1)
    q1 = ref.quality == 1
    tr = ref.time[q1]
    tr = tr[(tr >= traj.time[0]) & (tr <= traj.time[-1])]
    sig = np.column_stack([np.interp(tr, traj.time, traj.std_pos[:, k]) for k in range(3)])
    cov = 100 * np.mean(np.abs(c["diff_enu"]) <= 3 * sig[:len(c["diff_enu"])], axis=0)
    iv = interval_velocity_errors(res.time, res.state[:, 3:6], ref.time, ref.lat, ref.lon, ref.height, use=q1)
    tm = 0.5 * (iv.t_start + iv.t_end)
    sv = np.column_stack([np.interp(tm, traj.time, traj.std_vel[:, k]) for k in range(3)])
    vcov = 100 * np.mean(np.abs(iv.err) <= 3 * sv, axis=0)
    sats = sorted({int(p) for p in obs.prn})
    return {"h": c["horizontal_rms"], "v": c["vertical_rms"], "cov": cov, "vel": iv.rms_horizontal(),
            "n_iv": len(iv), "vcov": vcov, "sats": [sat_name(s) for s in sats]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=WALK)
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated: " + ", ".join(CASES))
    ap.add_argument("--cut-g08", type=int, default=0, help="diagnostic: remove G08's first N code epochs")
    a = ap.parse_args()
    for name in a.cases.split(","):
        systems, sources = CASES[name]
        for smooth in (False, True):
            c0, w0 = time.process_time(), time.perf_counter()
            r = run(systems, sources, smooth, a.data, a.cut_g08)
            pc, vc = "/".join(f"{x:.1f}" for x in r["cov"]), "/".join(f"{x:.1f}" for x in r["vcov"])
            print(f"{name:20s} {'smoothed' if smooth else 'forward '}: H {r['h']:.3f} m, V {r['v']:.3f} m, "
                  f"3σ E/N/U {pc} %; velocity H RMS {r['vel']:.4f} m/s ({r['n_iv']} intervals; target <= "
                  f"0.05), 3σ E/N/U {vc} %; CPU {time.process_time() - c0:.1f} s, wall "
                  f"{time.perf_counter() - w0:.1f} s, load {os.getloadavg()[0]:.2f}")
        print(f"    satellites observed with an ephemeris ({len(r['sats'])}): {' '.join(r['sats'])}")


if __name__ == "__main__":
    main()
