"""Issue 40: pseudorange residuals of the walk's Galileo satellites with the I/NAV ephemerides decoded from
the UBX log's RXM-SFRBX frames (:mod:`aidnav.io.galileo_inav`), against the RTK reference positions.

Per epoch (every ``--step`` s): residual = pseudorange − geometric range (Sagnac) + c·dt_sat − Klobuchar
(RTKLIB's default coefficients; the nav file has none) − Saastamoinen troposphere; the common receiver
clock is the median of the GPS residuals, and the GPS–Galileo offset (system time + inter-system bias) the
median of all Galileo residuals after it. Prints the per-satellite RMS and the overall RMS [m] (figure;
target: metres level, i.e. like the GPS satellites' own). Reference heights: the .pos file's hMSL − 21.4 m.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

from aidnav.io.galileo_inav import read_ubx_galileo_inav
from aidnav.io.rinex import read_rinex_nav, read_rinex_obs
from aidnav.io.rtklib import read_pos
from aidnav.nav import gnss_sat as gs
from aidnav.nav.earth import lla_to_ecef

_DATA = Path(os.environ.get("AIDNAV_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
WALK = _DATA / "rtklibexplorer_walk_0827"


def epoch_residuals(table, prn, t, pr, llh, klob) -> dict:
    """{satellite id: pseudorange [m] − geometric range from the reference position ``llh`` (lat, lon
    [rad], ellipsoidal height [m]) + satellite clock − Klobuchar delay (``klob`` = (α, β)) − troposphere}
    at GPS time ``t`` [s of week], elevation ≥ 10°; the receiver clock is still in it."""
    lat, lon, h = llh
    rr = np.asarray(lla_to_ecef(lat, lon, h), float).ravel()
    pos, _, clk, _ = gs.satellites_from_pseudoranges(table, prn, t, pr)
    res = {}
    for j, sid in enumerate(prn):
        if not np.isfinite(pr[j]) or not np.isfinite(pos[j, 0]):
            continue
        rng, e = gs.geo_range(pos[j], rr)
        az, el, _ = gs.az_el(e, lat, lon)
        if el < np.radians(10):
            continue
        iono = gs.klobuchar(lat, lon, az, el, t % 604800.0, *klob)
        res[int(sid)] = pr[j] - rng + clk[j] - iono - gs.tropo_delay(lat, h, el, 0.7)
    return res


def residuals(data_dir: Path, step_s: float = 10.0):
    obs = read_rinex_obs(data_dir / "rinex_converted" / "gnss_1730.obs", systems="GE")
    gps = read_rinex_nav(data_dir / "rinex_converted" / "gnss_1730.nav", systems="G").to_week(obs.ref_week)
    gal = read_ubx_galileo_inav(data_dir / "gnss_1730.ubx", ref_week=obs.ref_week)
    table = np.vstack([gps.table, gal.table[gal.table[:, gs.E_HEALTH] == 0]])
    ref = read_pos(data_dir / "gnss_1730_sf.pos", height_offset_m=-21.4)
    alpha, beta, _ = gs.klobuchar_coefficients(None, None)
    out = {}  # sat id → list of residuals
    t_next = -np.inf
    for k, t in enumerate(obs.time):
        if t < t_next:
            continue
        t_next = t + step_s
        i = int(np.argmin(np.abs(ref.time - t)))  # both on the walk's week (seconds of week)
        lat, lon, h = ref.lat[i], ref.lon[i], ref.height[i]
        res = epoch_residuals(table, obs.prn, t, obs.code1[k], (lat, lon, h), (alpha, beta))
        g = [v for s, v in res.items() if s < 100]
        if len(g) < 2:
            continue
        clock = np.median(g)
        for s, v in res.items():
            out.setdefault(s, []).append(v - clock)
    gal_all = np.concatenate([out[s] for s in out if s >= 100]) if any(s >= 100 for s in out) else []
    offset = float(np.median(gal_all)) if len(gal_all) else np.nan
    return out, offset, gal


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=WALK)
    ap.add_argument("--step", type=float, default=10.0)
    a = ap.parse_args()
    c0 = os.times()
    out, offset, gal = residuals(a.data, a.step)
    print(gal.events[0])
    print(f"GPS-Galileo offset (system time + ISB, median): {offset:.2f} m")
    allg = []
    for s in sorted(out):
        v = np.asarray(out[s]) - (offset if s >= 100 else 0.0)
        if s >= 100:
            allg.append(v)
        rms = np.sqrt(np.mean(v * v))
        print(f"  {gs.sat_name(s)}: n {len(v):3d}  mean {np.mean(v):7.2f} m  RMS {rms:6.2f} m")
    allg = np.concatenate(allg)
    c1 = os.times()
    print(f"Galileo residual RMS {np.sqrt(np.mean(allg**2)):.2f} m over {len(allg)} (target: metres level); "
          f"CPU {c1.user - c0.user + c1.system - c0.system:.1f} s, load {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
