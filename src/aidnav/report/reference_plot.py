"""A solution against a reference solution (``aidnav tight --truth``, issue 38): one figure with the
tracks (solution, reference, the GNSS/SPP fixes) on a local ENU map and the E, N, U differences
solution − reference against time at every reference epoch inside the solution's span; and the NIS
table of a run's innovation records (mean NIS per measurement type with its 95 % band) in the form of
the ``nis`` entry of ``aidnav process`` summaries, which ``run.html`` lays out as a table.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from aidnav.analysis.consistency import chi2_band
from aidnav.data import GnssData, Trajectory
from aidnav.nav.earth import lla_difference_enu, lla_to_enu

from .overview import nis_series

__all__ = ["reference_differences", "write_reference_figure", "nis_table"]


def reference_differences(traj: Trajectory, ref: GnssData) -> tuple[np.ndarray, np.ndarray]:
    """(times, (M, 3) E, N, U differences solution − reference [m]) at the reference epochs inside the
    solution's span (the solution interpolated linearly to them)."""
    m = (ref.time >= traj.time[0]) & (ref.time <= traj.time[-1])
    t = ref.time[m]
    lat = np.interp(t, traj.time, traj.lat)
    lon = np.interp(t, traj.time, np.unwrap(traj.lon))
    h = np.interp(t, traj.time, traj.height)
    de, dn, du = lla_difference_enu(lat, lon, h, ref.lat[m], ref.lon[m], ref.height[m])
    return t, np.column_stack([de, dn, du])


def write_reference_figure(path, traj: Trajectory, ref: GnssData, fixes: GnssData | None = None,
                           fixes_label: str = "GNSS fixes", ref_label: str = "reference",
                           time_scale: str = "GPS SOW") -> Path:
    """The tracks and the differences from the reference (module docstring) as a PNG; returns its path."""
    t, d = reference_differences(traj, ref)
    fig = Figure(figsize=(14, 9))
    FigureCanvasAgg(fig)
    gs = fig.add_gridspec(3, 2, width_ratios=[1.0, 1.3])
    ax_map = fig.add_subplot(gs[:, 0])
    o = (ref.lat[0], ref.lon[0], ref.height[0])
    for obj, style, label in ((ref, dict(color="k", lw=1.4), ref_label),
                              (traj, dict(color="C0", lw=1.0), "solution")):
        e, n, _ = lla_to_enu(obj.lat, obj.lon, obj.height, *o)
        ax_map.plot(e, n, label=label, **style)
    if fixes is not None and len(fixes):
        e, n, _ = lla_to_enu(fixes.lat, fixes.lon, fixes.height, *o)
        ax_map.plot(e, n, ".", ms=2.5, color="C1", alpha=0.6, label=fixes_label)
    ax_map.set_xlabel("east [m]")
    ax_map.set_ylabel("north [m]")
    ax_map.set_aspect("equal", adjustable="datalim")
    ax_map.legend(loc="best", fontsize=8)
    ax_map.set_title("tracks")
    t0 = float(t[0]) if len(t) else 0.0
    for k, name in enumerate(("east", "north", "up")):
        ax = fig.add_subplot(gs[k, 1])
        if len(t):
            rms = float(np.sqrt(np.mean(d[:, k] ** 2)))
            ax.plot(t - t0, d[:, k], lw=0.8, color=f"C{k}", label=f"RMS {rms:.3g} m")
            ax.legend(loc="upper right", fontsize=8)
        ax.axhline(0.0, color="0.5", lw=0.5)
        ax.set_ylabel(f"{name} [m]")
        if k == 0:
            ax.set_title(f"solution − {ref_label} at {len(t)} reference epochs")
    ax.set_xlabel(f"time since {t0:.3f} s ({time_scale}) [s]")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    return path


def nis_table(records: dict | None, gnss: GnssData | None = None, prob: float = 0.95) -> dict:
    """{name: {mean, dof, n, band95, in_band}} of the NIS series of ``records`` (:func:`nis_series`):
    the mean over the epochs with an NIS, its mean dof and the two-sided ``prob`` band of the mean of n
    χ²(dof) values (the dof rounded to the nearest integer when it varies)."""
    out = {}
    for s in nis_series(records, gnss):
        ok = np.isfinite(s["nis"]) & (s["dof"] > 0)
        n = int(ok.sum())
        if n == 0:
            continue
        mean = float(np.mean(s["nis"][ok]))
        dof_mean = float(np.mean(s["dof"][ok]))
        # the mean of n values of NIS/dof-weighted sums: band of the sum of all terms, divided by n
        lo, hi = chi2_band(int(np.sum(s["dof"][ok])), 1, prob)
        band = [float(lo) / n, float(hi) / n]
        out[s["key"]] = {"mean": mean, "dof": dof_mean, "n": n, "band95": band,
                         "in_band": bool(band[0] <= mean <= band[1])}
    return out
