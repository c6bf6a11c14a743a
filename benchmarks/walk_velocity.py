"""Issue 40 (report only): the walk's velocity with and without the carrier phase, and its σ.

`aidnav tight` with no configuration on ``rtklibexplorer_walk_0827``, forward and smoothed, for the cases:
the default (``ubx_nav: auto`` with the UBX log's default sources, :data:`aidnav.io.rinex.UBX_SOURCES`: its
ephemerides, Klobuchar coefficients and the receiver's phase σ, RXM-RAWX cpStdev), the same with ``rawx``
(the BeiDou B1C satellites the observation file lacks), without ``cpstdev`` (session 14's inputs), the
navigation file alone (``none``), and the default without the phase (``gnss.use_phase: false``). First, the
reference's own velocity noise by the three-cornered hat
(:func:`aidnav.analysis.velocity_reference.three_cornered_hat`: TDCP least-squares velocities of Galileo
alone and of GPS + BeiDou against the reference's position differences), standing and walking. Printed
per case:

* horizontal / vertical velocity RMS against the RTK positions' differences over the Q = 1 intervals
  (:func:`aidnav.analysis.velocity_reference.interval_velocity_errors`; target ≤ 0.05 m/s horizontal, with the
  phase), and the 3σ coverage of those interval errors per ENU axis with the filter's velocity σ at the
  interval's middle, alone and with the reference's noise of the hat added (standing / walking: speed
  below / above 0.2 m/s);
* while walking, the filter's own error per horizontal axis (√(RMS² − σ_r²), σ_r the hat's) over the RMS of
  its velocity σ there (target ≤ 1.2: issue 40, session 16);
* position H / V RMS and 3σ coverage at every reference epoch (targets H ≤ 8.50 m, V ≤ 3.5 m, ≥ 95 %);
* the TDCP records used and the CPU time per run, with the load average.
"""

from __future__ import annotations

import os
import sys
import warnings

import numpy as np
from galileo_walk_tight import WALK, walk_run  # the walk's tight run, scored as there (benchmarks/)

from aidnav.analysis.velocity_reference import interval_velocity_errors, three_cornered_hat
from aidnav.filters.tight import TightConfig
from aidnav.io.nav_sources import read_observations_and_navigation
from aidnav.io.rinex import UBX_SOURCES, UBX_SOURCES_ALL
from aidnav.io.rtklib import read_pos

CASES = {  # name: (ubx_nav, ubx_sources, use_phase)
    "default": ("auto", UBX_SOURCES, True),
    "+ rawx (BeiDou B1C)": ("auto", UBX_SOURCES_ALL, True),
    "no cpstdev (session 14's inputs)": ("auto", UBX_SOURCES.replace(",cpstdev", ""), True),
    "nav file alone": ("none", UBX_SOURCES, True),
    "default, no phase": ("auto", UBX_SOURCES, False),
}
if "--default-only" in sys.argv[1:]:  # the default only (2 runs instead of 10)
    CASES = {"default": CASES["default"]}


def run(ubx_nav: str, sources: str, use_phase: bool, smooth: bool):
    """(position ENU errors (N, 3), position σ (N, 3), interval velocity errors, velocity σ at the
    intervals' middles (K, 3), the result)."""
    cfg = TightConfig()
    if not use_phase:
        cfg = cfg.model_copy(update={"gnss": cfg.gnss.model_copy(update={"use_phase": False})})
    d, j, iv, tr, res, _ = walk_run(cfg, ubx_nav, smooth, ubx_sources=sources)
    mid = 0.5 * (iv.t_start + iv.t_end)
    sv = np.column_stack([np.interp(mid, tr.time, tr.std_vel[:, i]) for i in range(3)])
    return d, tr.std_pos[j], iv, sv, res


def reference_noise():
    """σ_r (2, 3) per ENU axis [m/s] of the reference's interval velocities, standing (row 0) and walking
    (row 1), by the three-cornered hat of TDCP least-squares velocities (receiver σ, variance factor) of
    the Galileo satellites and of the GPS + BeiDou ones (``rawx``) against the reference; with the TDCP
    sets' own σ_a, σ_b and their stated median σ, printed."""
    from aidnav.estimators.dgps import spp_series  # lazy: only here
    from aidnav.estimators.tdcp import tdcp_series  # lazy: only here

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        obs, eph, _, _ = read_observations_and_navigation(
            WALK / "rinex_converted" / "gnss_1730.obs", WALK / "rinex_converted" / "gnss_1730.nav",
            "GECR", "auto", ubx_sources=UBX_SOURCES_ALL)
    ref = read_pos(WALK / "gnss_1730_sf.pos", height_offset_m=-21.4)
    pos = spp_series(obs, eph)["ecef"]
    iv = interval_velocity_errors(ref.time, ref.vel, ref.time, ref.lat, ref.lon, ref.height,
                                  use=ref.quality == 1)
    k = np.clip(np.searchsorted(obs.time, iv.t_end - 0.005), 1, len(obs.time) - 1)
    same = (np.abs(obs.time[k] - iv.t_end) < 0.005) & (np.abs(obs.time[k - 1] - iv.t_start) < 0.005)
    sets = []
    for letters in ("E", "GC"):
        o = obs.subset_sats(obs.prn[np.array([n[0] in letters for n in obs.names])])
        r = tdcp_series(o, eph, pos)
        sets.append((np.where(same[:, None], r["vel_enu"][k - 1], np.nan),
                     np.sqrt(np.einsum("kii->ki", r["vel_cov_enu"][k - 1]))))
    walking = np.hypot(iv.ref[:, 0], iv.ref[:, 1]) >= 0.2
    out = np.zeros((2, 3))
    for i, m in enumerate((~walking, walking)):
        va, vb, vr = three_cornered_hat(sets[0][0][m], sets[1][0][m], iv.ref[m])
        out[i] = np.sqrt(np.maximum(vr, 0.0))
        f = np.isfinite(sets[0][0][m, 0]) & np.isfinite(sets[1][0][m, 0])
        print(f"reference noise by the three-cornered hat, {'walking' if i else 'standing'} ({f.sum()} "
              f"intervals): sigma_r E/N/U {' / '.join(f'{x:.4f}' for x in out[i])} m/s; Galileo TDCP "
              f"{' / '.join(f'{x:.4f}' for x in np.sqrt(np.maximum(va, 0)))} (stated median "
              f"{' / '.join(f'{x:.4f}' for x in np.median(sets[0][1][m][f], axis=0))}); GPS + BeiDou TDCP "
              f"{' / '.join(f'{x:.4f}' for x in np.sqrt(np.maximum(vb, 0)))} (stated "
              f"{' / '.join(f'{x:.4f}' for x in np.median(sets[1][1][m][f], axis=0))})", flush=True)
    return out


def main():
    print(f"walk {WALK}; aidnav tight, no configuration; load {os.getloadavg()[0]:.2f}")
    sig_r = reference_noise()
    for name, (ubx_nav, sources, use_phase) in CASES.items():
        for smooth in (False, True):
            c0 = os.times()
            d, sp, iv, sv, res = run(ubx_nav, sources, use_phase, smooth)
            c1 = os.times()
            h = np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2))
            cov_p = 100 * np.mean(np.abs(d) <= 3 * sp, axis=0)
            cov_v = 100 * np.mean(np.abs(iv.err) <= 3 * sv, axis=0)
            walking = np.hypot(iv.ref[:, 0], iv.ref[:, 1]) >= 0.2
            s_tot = np.sqrt(sv**2 + sig_r[walking.astype(int)] ** 2)
            cov_r = 100 * np.mean(np.abs(iv.err) <= 3 * s_tot, axis=0)
            # the filter's own error while walking (the reference's noise removed) against its σ there
            own = np.sqrt(np.maximum(np.mean(iv.err[walking] ** 2, axis=0) - sig_r[1] ** 2, 0.0))
            ratio = own / np.sqrt(np.mean(sv[walking] ** 2, axis=0))
            print(f"{name}, {'smoothed' if smooth else 'forward'}: velocity H {iv.rms_horizontal():.4f} m/s "
                  f"(target <= 0.05), V {iv.rms_vertical():.4f} m/s, 3-sigma coverage E/N/U "
                  f"{' / '.join(f'{x:.1f}' for x in cov_v)} %, with the reference's noise "
                  f"{' / '.join(f'{x:.1f}' for x in cov_r)} % ({len(iv)} intervals); walking own error E/N "
                  f"{own[0]:.4f} / {own[1]:.4f} m/s, its ratio to the filter's sigma {ratio[0]:.2f} / "
                  f"{ratio[1]:.2f} (target <= 1.2); position H "
                  f"{h:.3f} m (<= 8.50), V {np.sqrt(np.mean(d[:, 2] ** 2)):.3f} m (<= 3.5), 3-sigma "
                  f"{' / '.join(f'{x:.1f}' for x in cov_p)} %; velocity records used "
                  f"{res.counts['velocity_used']} of {res.counts['velocity_records']}; CPU "
                  f"{c1.user - c0.user + c1.system - c0.system:.1f} s, load {os.getloadavg()[0]:.2f}",
                  flush=True)


if __name__ == "__main__":
    main()
