"""Issue 40 (report only): the phase–Doppler cycle-slip test's false alarms and its detections
(:func:`aidnav.estimators.tdcp.phase_increments`), the constant half-cycle threshold (before issue 40 session
17) against the statistical test at ``gnss.slip_false_alarm`` (default 1e-3; the tight filter's default
noises: zenith Doppler σ ``gnss.rate_sigma_m_s`` 0.1 m/s, the receiver's phase σ where given, else 5 mm):

* the simulated pedestrian (:mod:`aidnav.sim.pedestrian`, no slips: every code-2 flag is a false alarm) over
  ``--seeds`` seeds (default 3), the geometry from the SPP positions as ``aidnav tight`` takes it; and the
  one-cycle slips injected there (one every 20 epochs, satellites in turn) found, by elevation band;
* the walk ``rtklibexplorer_walk_0827`` (its RINEX with the UBX log's ephemerides and cpStdev, as ``aidnav
  tight`` reads it, ``ubx_nav auto``; and with the RINEX nav file alone, ``none``: four GPS satellites with
  an ephemeris, every interval tested satellite by satellite; no known slip: the flags are upper bounds on
  its false alarms), per satellite.

Targets: the false-alarm rate near ``slip_false_alarm`` (its binomial 99.9 % quantile); a one-cycle slip
found where the stated σ put the smallest slip found with 99 % probability under a cycle (module doc).
"""

from __future__ import annotations

import argparse
import os
import warnings
from pathlib import Path

import numpy as np
from scipy.stats import binom

from aidnav.estimators.dgps import spp_series
from aidnav.estimators.tdcp import SLIP_FALSE_ALARM, phase_increments, slip_geometry
from aidnav.filters.tight import TightConfig
from aidnav.io.nav_sources import read_observations_and_navigation
from aidnav.sim.pedestrian import simulate_pedestrian

_DATA = Path(os.environ.get("AIDNAV_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
WALK = _DATA / "rtklibexplorer_walk_0827"


def tests(o, eph, phase=None):
    """(old codes, new codes, candidates (T−1, S) bool, elevations (T, S)) of observations ``o``."""
    g = TightConfig().gnss
    o = o.with_frequencies(eph)
    L = o.phase1 if phase is None else phase
    geo = slip_geometry(o, eph, spp_series(o, eph)["ecef"])
    sig = g.phase_sigma_m if o.phase_sigma1 is None else np.where(np.nan_to_num(o.phase_sigma1) > 0,
                                                                   o.phase_sigma1, g.phase_sigma_m)
    a = (o.time, L, o.lli1, o.range_rate())
    _, old = phase_increments(*a, 0.5, o.wavelengths())
    _, new = phase_increments(*a, None, o.wavelengths(), geo, (g.rate_sigma_m_s, sig), g.slip_false_alarm)
    cand = np.isfinite(L[1:] - L[:-1]) & ((o.lli1[1:] & 1) == 0)
    return old, new, cand, geo[1]


def line(name, old, new, n):
    bound = binom.ppf(0.999, n, SLIP_FALSE_ALARM)
    print(f"{name}: {n} increments; constant 0.5 cycle {int((old == 2).sum())} ({(old == 2).sum() / n:.2%}); "
          f"statistical {int((new == 2).sum())} ({(new == 2).sum() / n:.3%}; 99.9 % bound at "
          f"{SLIP_FALSE_ALARM:g}: {bound:.0f})")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    a = ap.parse_args(argv)
    tot = np.zeros(3, int)
    found = {b: [0, 0, 0, 0] for b in ("<15", "15-30", ">=30")}
    for seed in range(a.seeds):
        run = simulate_pedestrian(seed)
        old, new, cand, el = tests(run.obs, run.eph)
        line(f"pedestrian seed {seed}", old[1:][cand], new[1:][cand], int(cand.sum()))
        tot += [(old[1:][cand] == 2).sum(), (new[1:][cand] == 2).sum(), cand.sum()]
        L = run.obs.phase1.copy()
        inj = []
        for i, k in enumerate(range(20, len(L), 20)):
            js = np.flatnonzero(cand[k - 1])
            j = int(js[i % len(js)])
            L[k:, j] += 1.0
            inj.append((k, j))
        o2, n2, _, _ = tests(run.obs, run.eph, L)
        for k, j in inj:
            e = np.degrees(el[k, j])
            b = "<15" if e < 15 else ("15-30" if e < 30 else ">=30")
            found[b][0] += int(o2[k, j] == 2)
            found[b][1] += int(n2[k, j] == 2)
            found[b][2] += 1
    line(f"pedestrian {a.seeds} seeds", np.repeat(2, tot[0]), np.repeat(2, tot[1]), int(tot[2]))
    for b, (fo, fn, n, _) in found.items():
        print(f"  injected one-cycle slips at elevation {b} deg: found {fo}/{n} (constant), {fn}/{n} "
              "(statistical)")
    for nav in ("auto", "none"):
        walk(nav)


def walk(nav):
    """The walk's flags with ``ubx_nav`` = ``nav`` (none: the RINEX nav file alone, four GPS satellites with
    an ephemeris: the satellite-by-satellite test), all and on the satellites with an ephemeris (used)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        obs, eph, _, _ = read_observations_and_navigation(
            WALK / "rinex_converted" / "gnss_1730.obs", WALK / "rinex_converted" / "gnss_1730.nav",
            TightConfig().gnss.systems, nav)
    eph = eph.to_week(obs.ref_week) if eph.ref_week != obs.ref_week else eph
    old, new, cand, el = tests(obs, eph)
    used = np.isfinite(el).any(axis=0)
    line(f"walk {nav}", old[1:][cand], new[1:][cand], int(cand.sum()))
    cu = cand & used[None]
    line(f"walk {nav}, used satellites", old[1:][cu], new[1:][cu], int(cu.sum()))
    for j, name in enumerate(obs.names):
        if cand[:, j].any():
            e = np.nanmedian(np.degrees(el[:, j])) if np.isfinite(el[:, j]).any() else np.nan
            print(f"  {name}: {int(cand[:, j].sum())} increments, median elevation {e:.0f} deg; flagged "
                  f"{int((old[:, j] == 2).sum())} (constant), {int((new[:, j] == 2).sum())} (statistical)")

if __name__ == "__main__":
    main()
