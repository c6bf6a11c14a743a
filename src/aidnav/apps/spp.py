"""The job behind ``aidnav spp``: single point positioning on RINEX files → a GNSS solution file and a page.

RINEX observation + navigation (broadcast ephemerides; with the receiver's UBX log the observation file
names, its RXM-SFRBX ephemerides too: ``--ubx-nav``, :mod:`aidnav.io.nav_sources`) →
:func:`aidnav.estimators.spp.spp_series`
(weighted least squares per epoch, Klobuchar / none / dual-frequency ionosphere, Saastamoinen troposphere,
residual check; Doppler velocity) → ``DIR/solution.<fmt>``: an interchange GNSS file (``time`` GPS seconds
of week, ``gps_week`` in its metadata, ``lat_deg, lon_deg, height_m`` ellipsoidal, ``ve, vn, vu``,
``std_e_m, std_n_m, std_u_m``, ``quality`` = 5, single) that ``aidnav process --gnss`` and ``aidnav
evaluate`` read; ``summary.json``/``summary.txt`` (epochs, fixes, DOP, exclusions, what the ionosphere
correction was) and ``run.html`` with the overview figure and the maps.

σ of a fix: σE = σN = HDOP × σ₀, σU = VDOP × σ₀ with σ₀ the code σ (``--code-sigma``, 3 m by default: a
stated single-frequency range error, not fitted on any data).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aidnav.apps.common import prepare_out_dir, write_summary_files
from aidnav.data import GnssData
from aidnav.errors import InputError
from aidnav.estimators.spp import spp_series
from aidnav.io.formats import gnss_to_trajectory
from aidnav.io.interchange import write_gnss
from aidnav.io.nav_sources import AUTO, format_sources, read_observations_and_navigation

__all__ = ["spp_files", "format_spp_summary"]


def spp_files(obs_path, nav_path, out_dir="spp", fmt: str = "parquet", iono: str = "klobuchar",
              mask_deg: float = 10.0, code_sigma_m: float = 3.0, figures: bool = True, ubx_nav=AUTO) -> dict:
    """Run SPP on the RINEX files and write the solution, the summary and the page into ``out_dir``;
    returns the summary dict. ``ubx_nav``: the UBX log whose broadcast ephemerides are added — a path,
    "auto" (the log the observation file's header names, where it is found) or "none"
    (:mod:`aidnav.io.nav_sources`)."""
    if fmt not in ("parquet", "csv"):
        raise InputError(f"--format {fmt}: expected parquet or csv")
    if iono not in ("klobuchar", "none", "dual"):
        raise InputError(f"--iono {iono}: expected klobuchar, none or dual")
    if not code_sigma_m > 0:
        raise InputError(f"--code-sigma {code_sigma_m}: expected a σ > 0 m")
    out = prepare_out_dir(out_dir)
    # every system with ephemerides
    obs, eph, notes, sources = read_observations_and_navigation(obs_path, nav_path, ubx_nav=ubx_nav)
    sp = spp_series(obs, eph, sigma0=code_sigma_m, iono=iono, mask_deg=mask_deg)
    no_coef = iono == "klobuchar" and getattr(eph, "iono_alpha", None) is None
    default = no_coef and any("default coefficients" in e for e in sp["events"])
    if no_coef:
        notes.append(f"warning: {Path(nav_path).name} has no Klobuchar coefficients (ION ALPHA/BETA): "
                     + ("RTKLIB's default coefficients are used instead (a rough model, σ 50 % of the delay)"
                        if default else "the ionospheric delay (several metres vertically) is not corrected")
                     + "; --iono dual with an L2 code, or a navigation file with the coefficients, is better")
    ok = np.isfinite(sp["lat"])
    if not ok.any():
        raise InputError(f"{obs_path}: no epoch has a position (too few satellites with ephemerides)")
    hd, vd = sp["hdop"][ok], sp["vdop"][ok]
    std = np.column_stack([hd * code_sigma_m, hd * code_sigma_m, vd * code_sigma_m])
    vel = sp["vel_enu"][ok]
    g = GnssData(sp["time"][ok], sp["lat"][ok], sp["lon"][ok], sp["h"][ok], vel=vel, std_pos=std,
                 quality=np.full(int(ok.sum()), 5), week=getattr(obs, "ref_week", None),
                 height_datum="ellipsoid")
    ubx = f" + {Path(sources['ubx_nav']).name}" if sources["ubx_nav"] else ""
    sol = write_gnss(g, out / f"solution.{fmt}",
                     notes=[f"aidnav spp of {Path(obs_path).name} + {Path(nav_path).name}{ubx}; iono {iono}; "
                            f"mask {mask_deg:g} deg; σ = DOP × {code_sigma_m:g} m"])
    summary = {"obs": str(obs_path), "nav": str(nav_path), "output": str(sol), "ephemerides": sources,
               "time_scale": "GPS seconds of week" + (f" (week {g.week})" if g.week is not None else ""),
               "epochs": int(len(sp["time"])), "fixes": int(ok.sum()),
               "ionosphere": {"klobuchar": ("RTKLIB's default Klobuchar coefficients (none in the navigation "
                                            "file)" if default else "none (no coefficients in the navigation "
                                            "file)" if no_coef else "broadcast Klobuchar model"),
                              "none": "not corrected (--iono none)",
                              "dual": "dual-frequency code combination"}[iono],
               "mask_deg": mask_deg, "code_sigma_m": code_sigma_m,
               "pdop_median": float(np.nanmedian(sp["pdop"][ok])),
               "satellites_used_median": float(np.median(sp["n_used"][ok])),
               "systems": sorted({n[0] for n in obs.names}),
               "inter_system_bias_m_median": {c: float(np.nanmedian(v)) for c, v in sp["isb_m"].items()
                                              if np.isfinite(v).any()},
               "warnings": [n[len("warning: "):] for n in notes if n.startswith("warning: ")],
               "events": list(sp["events"]), "notes": [n for n in notes if not n.startswith("warning: ")]}
    write_summary_files(out, summary, format_spp_summary(summary))
    if figures:
        from aidnav.report.run_page import write_run_outputs  # lazy: matplotlib

        page = {**summary, "gnss_label": "SPP fixes (aidnav)", "title": f"aidnav spp: {Path(obs_path).name}"}
        write_run_outputs(out, gnss_to_trajectory(g), g, page, base="solution")
    return summary


def format_spp_summary(s: dict) -> str:
    """Human-readable summary of ``aidnav spp``."""
    lines = [f"aidnav spp: {s['obs']} + {s['nav']}", f"output: {s['output']}",
             f"{s['fixes']} of {s['epochs']} epochs with a position; median PDOP {s['pdop_median']:.2f}, "
             f"median satellites used {s['satellites_used_median']:g}",
             f"ionosphere: {s['ionosphere']}; mask {s['mask_deg']:g} deg; σ = DOP × {s['code_sigma_m']:g} m"]
    if s.get("ephemerides"):
        lines.append(format_sources(s["ephemerides"]))
    lines += [f"warning: {w}" for w in s.get("warnings", [])]
    lines += [f"event: {e}" for e in s.get("events", [])]
    return "\n".join(lines) + "\n"
