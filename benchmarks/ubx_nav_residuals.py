"""Issue 40: pseudorange residuals against the RTK reference of every satellite whose ephemeris comes from the
walk's UBX log (GPS LNAV, GPS CNAV, Galileo I/NAV: :func:`aidnav.io.rinex.read_rinex_pair` with ``ubx_nav``),
beside the 4 GPS satellites of the RINEX navigation file.

Per epoch (every ``--step`` s): residual = pseudorange − geometric range (Sagnac) + c·(dt_sat − T_GD) −
Klobuchar (RTKLIB's default coefficients, the nav file has none; ``--broadcast-iono``: the log's) −
Saastamoinen, elevation ≥ 10°, at the
RTK position (nearest `.pos` epoch, hMSL − 21.4 m); the receiver clock is the median of the residuals of the
GPS satellites *of the RINEX file* (so the new ones are judged against them), and one GPS–Galileo offset
the median of the Galileo residuals. Prints per-satellite mean/RMS [m] and the RMS of the GPS satellites
added from the log beside the file's (figure; target: the same metres level — a wrong field gives km).
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from pathlib import Path

import numpy as np
from galileo_inav_residuals import epoch_residuals  # the same per-epoch residuals (benchmarks/)

from aidnav.io.rinex import read_rinex_nav, read_rinex_pair
from aidnav.io.rtklib import read_pos
from aidnav.nav import gnss_sat as gs

_DATA = Path(os.environ.get("AIDNAV_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
WALK = _DATA / "rtklibexplorer_walk_0827"


def residuals(data_dir: Path, step_s: float = 10.0, broadcast_iono: bool = False):
    """(residuals per satellite id {id: [m]}, GPS–Galileo offset [m], ids of the nav file's GPS satellites,
    the merged ephemerides). ``broadcast_iono``: the log's Klobuchar coefficients (CNAV type 30) instead of
    RTKLIB's defaults."""
    rinex = data_dir / "rinex_converted"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        obs, eph, _ = read_rinex_pair(rinex / "gnss_1730.obs", rinex / "gnss_1730.nav", "GE",
                                      ubx_nav=data_dir / "gnss_1730.ubx")
        file_gps = set(read_rinex_nav(rinex / "gnss_1730.nav", systems="G").table[:, gs.E_PRN].astype(int))
    ref = read_pos(data_dir / "gnss_1730_sf.pos", height_offset_m=-21.4)
    klob = (eph.iono_alpha, eph.iono_beta) if broadcast_iono else (None, None)
    alpha, beta, _ = gs.klobuchar_coefficients(*klob)
    out: dict[int, list] = {}
    t_next = -np.inf
    for k, t in enumerate(obs.time):
        if t < t_next:
            continue
        t_next = t + step_s
        i = int(np.argmin(np.abs(ref.time - t)))
        lat, lon, h = ref.lat[i], ref.lon[i], ref.height[i]
        res = epoch_residuals(eph.table, obs.prn, t, obs.code1[k], (lat, lon, h), (alpha, beta))
        base = [v for s, v in res.items() if s in file_gps]
        if len(base) < 2:
            continue
        clock = np.median(base)
        for s, v in res.items():
            out.setdefault(s, []).append(v - clock)
    gal = [v for s in out if s >= 100 for v in out[s]]
    offset = float(np.median(gal)) if gal else 0.0
    return out, offset, file_gps, eph


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=WALK)
    ap.add_argument("--step", type=float, default=10.0)
    ap.add_argument("--broadcast-iono", action="store_true", help="the log's Klobuchar coefficients")
    a = ap.parse_args()
    c0, w0 = time.process_time(), time.perf_counter()
    out, offset, file_gps, eph = residuals(a.data, a.step, a.broadcast_iono)
    print("\n".join(e for e in eph.events if "ubx" in e))
    print(f"GPS-Galileo offset (median): {offset:.2f} m")
    groups: dict[str, list] = {"GPS, RINEX nav file": [], "GPS, from the UBX log": [], "Galileo, UBX log": []}
    for s in sorted(out):
        v = np.asarray(out[s]) - (offset if s >= 100 else 0.0)
        g = "Galileo, UBX log" if s >= 100 else ("GPS, RINEX nav file" if s in file_gps else
                                                 "GPS, from the UBX log")
        groups[g].append(v)
        print(f"  {gs.sat_name(s)} ({g}): n {len(v):3d}  mean {np.mean(v):7.2f} m  RMS "
              f"{np.sqrt(np.mean(v * v)):6.2f} m")
    for g, vs in groups.items():
        if vs:
            v = np.concatenate(vs)
            rms = np.sqrt(np.mean(v * v))
            print(f"{g}: residual RMS {rms:.2f} m over {len(v)} (target: metres, as the file's GPS)")
    print(f"CPU {time.process_time() - c0:.1f} s, wall {time.perf_counter() - w0:.1f} s, "
          f"load {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
