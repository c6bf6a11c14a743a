"""Issue 40 (report only): is the walk's ~8 m horizontal difference from its RTK reference the solutions' or
the reference's? Single point positions (:func:`aidnav.estimators.spp.spp_series`, σ0 3 m, mask 10°) of
independent satellite sets against the reference (`gnss_1730_sf.pos`: the receiver's own RTK NAV-PVT; its
absolute position is the unknown base station's): GPS only (the RINEX nav file's 4 satellites) with the
Klobuchar fallback, without an ionospheric correction and with the L1/L2C dual-frequency delay; Galileo only
(the 6 healthy I/NAV satellites of the UBX log, :mod:`aidnav.io.nav_sources`); both; and both with each
satellite left out in turn. An error of the solutions comes from their satellites (orbits, clocks, group
delays, multipath) and differs between independent sets; an offset of the reference is common to all.
Prints per set the mean and SD of the E/N/U differences [m] over the epochs, the horizontal RMS and the
median PDOP, then the spread of the leave-one-out means.
"""

from __future__ import annotations

import copy
import os
import time
import warnings
from pathlib import Path

import numpy as np

from aidnav.estimators.spp import spp_series
from aidnav.io.nav_sources import read_observations_and_navigation
from aidnav.io.rtklib import read_pos
from aidnav.nav.earth import lla_difference_enu
from aidnav.nav.gnss_sat import sat_name

_DATA = Path(os.environ.get("AIDNAV_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
WALK = _DATA / "rtklibexplorer_walk_0827"


def offsets(sp, ref):
    """E/N/U differences (K, 3) of the SPP fixes from the reference epoch nearest each (within 0.05 s)."""
    ok = np.isfinite(sp["lat"])
    t = sp["time"][ok]
    i = np.clip(np.searchsorted(ref.time, t), 0, len(ref) - 1)
    m = np.abs(ref.time[i] - t) < 0.05
    return np.column_stack(lla_difference_enu(sp["lat"][ok][m], sp["lon"][ok][m], sp["h"][ok][m],
                                              ref.lat[i][m], ref.lon[i][m], ref.height[i][m]))


def subset(obs, keep):
    """The observations with the code of every satellite not in ``keep`` (names) removed."""
    o = copy.deepcopy(obs)
    for j, p in enumerate(o.prn):
        if sat_name(p) not in keep:
            o.code1[:, j] = np.nan
    return o


def main():
    c0, w0 = os.times(), time.time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        rx = WALK / "rinex_converted"
        obs, eph, _, src = read_observations_and_navigation(rx / "gnss_1730.obs", rx / "gnss_1730.nav", "GE",
                                                            "auto")
    ref = read_pos(WALK / "gnss_1730_sf.pos", height_offset_m=-21.4)
    gps, gal = src["satellites"].get("GPS", []), src["satellites"].get("Galileo", [])
    have = {sat_name(p) for j, p in enumerate(obs.prn) if np.isfinite(obs.code1[:, j]).any()}
    gps, gal = [s for s in gps if s in have], [s for s in gal if s in have]
    print(f"GPS {' '.join(gps)}; Galileo {' '.join(gal)} (ephemerides: {src['how']})")
    cases = [("GPS only, Klobuchar (default coefficients)", gps, "klobuchar"),
             ("GPS only, no ionospheric correction", gps, "none"),
             ("GPS only, dual-frequency L1/L2C", gps, "dual"),
             ("Galileo only, Klobuchar", gal, "klobuchar"),
             ("Galileo only, no ionospheric correction", gal, "none"),
             ("GPS + Galileo, Klobuchar", gps + gal, "klobuchar")]
    for label, keep, iono in cases:
        sp = spp_series(subset(obs, keep), eph, sigma0=3.0, iono=iono, mask_deg=10.0)
        d = offsets(sp, ref)
        h = np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2))
        print(f"{label:44s} {len(d):4d} epochs: mean E/N/U {' / '.join(f'{x:6.2f}' for x in d.mean(0))}, SD "
              f"{' / '.join(f'{x:4.2f}' for x in d.std(0))}, H RMS {h:.2f} m, "
              f"PDOP {np.nanmedian(sp['pdop']):.2f}")
    means = []
    for s in gps + gal:
        rest = [x for x in gps + gal if x != s]
        d = offsets(spp_series(subset(obs, rest), eph, sigma0=3.0, iono="klobuchar", mask_deg=10.0), ref)
        means.append(d.mean(0))
        print(f"  GPS + Galileo without {s}: mean E/N/U {' / '.join(f'{x:6.2f}' for x in d.mean(0))} m, "
              f"horizontal {np.hypot(*d.mean(0)[:2]):.2f} m")
    h = np.hypot(*np.array(means)[:, :2].T)
    c1 = os.times()
    print(f"leave-one-out horizontal mean offset {h.min():.2f}-{h.max():.2f} m over {len(h)} sets; wall "
          f"{time.time() - w0:.1f} s, CPU {c1.user - c0.user + c1.system - c0.system:.1f} s, load "
          f"{os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
