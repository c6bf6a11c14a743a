"""Overview figure of a trajectory: map view, altitude and attitude (matplotlib, Agg, no pyplot state).

Frames and units: the map is in local East/North metres about the first point (ENU, WGS-84), altitude
is ellipsoidal height [m], roll/pitch/heading in degrees (heading clockwise from North, [0, 360)),
time in seconds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from aidnav.data import GnssData, Trajectory
from aidnav.nav.earth import lla_to_enu
from aidnav.nav.rotations import wrap_360

__all__ = ["plot_trajectory"]


def plot_trajectory(traj: Trajectory, path, title: str | None = None, segments: list[dict] | None = None,
                    gnss: GnssData | None = None, max_points: int = 20000) -> Path:
    """Write a PNG overview of ``traj`` to ``path`` and return the path.

    Parameters
    ----------
    traj : trajectory (lat/lon [rad], height [m], rph [rad]); time [s].
    path : output file (.png).
    title : figure title.
    segments : optional rows {name, start_s, end_s} (from :func:`aidnav.sim.trajectory.generate_truth`);
        boundaries are drawn on the time plots and names written at the segment starts on the map.
    gnss : optional GNSS fixes (lat/lon [rad], height [m]) drawn as dots on the map and altitude plots.
    max_points : the curves are decimated to at most this many points.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    step = max(1, int(np.ceil(len(traj.time) / max_points)))
    sl = slice(None, None, step)
    t = traj.time[sl]
    lat0, lon0, h0 = float(traj.lat[0]), float(traj.lon[0]), float(traj.height[0])
    e, n, _ = lla_to_enu(traj.lat[sl], traj.lon[sl], traj.height[sl], lat0, lon0, h0)

    fig = Figure(figsize=(12, 8), layout="constrained")
    FigureCanvasAgg(fig)
    gs = fig.add_gridspec(3, 2, width_ratios=[1.1, 1.0])
    ax_map = fig.add_subplot(gs[:, 0])
    ax_h = fig.add_subplot(gs[0, 1])
    ax_rp = fig.add_subplot(gs[1, 1], sharex=ax_h)
    ax_y = fig.add_subplot(gs[2, 1], sharex=ax_h)

    ax_map.plot(e, n, lw=1.2, color="C0", label="trajectory", zorder=3)
    ax_map.plot(e[0], n[0], "o", color="C2", label="start", zorder=4)
    ax_map.plot(e[-1], n[-1], "s", color="C3", label="end", zorder=4)
    if gnss is not None and len(gnss):
        ge, gn, _ = lla_to_enu(gnss.lat, gnss.lon, gnss.height, lat0, lon0, h0)
        ax_map.plot(ge, gn, ".", ms=2, color="C1", alpha=0.6, label="GNSS", zorder=2)
        ax_h.plot(gnss.time, gnss.height, ".", ms=2, color="C1", alpha=0.6)
    if segments:
        for row in segments:
            k = int(np.clip(np.searchsorted(t, row["start_s"]), 0, len(t) - 1))
            ax_map.annotate(str(row["name"]), (e[k], n[k]), fontsize=8, xytext=(3, 3),
                            textcoords="offset points")
    ax_map.set_xlabel("East [m]")
    ax_map.set_ylabel("North [m]")
    ax_map.set_aspect("equal", adjustable="datalim")
    ax_map.grid(True, alpha=0.3)
    ax_map.legend(loc="best", fontsize=8)
    ax_map.set_title("map (local ENU about the start)")

    ax_h.plot(t, traj.height[sl], color="C0", zorder=3)
    ax_h.set_ylabel("height [m]")
    ax_rp.plot(t, np.degrees(traj.rph[sl, 0]), label="roll")
    ax_rp.plot(t, np.degrees(traj.rph[sl, 1]), label="pitch")
    ax_rp.set_ylabel("[deg]")
    ax_rp.legend(loc="best", fontsize=8)
    ax_y.plot(t, wrap_360(np.degrees(traj.rph[sl, 2])), ".", ms=1, color="C2")
    ax_y.set_ylabel("heading [deg]")
    ax_y.set_ylim(0, 360)
    ax_y.set_yticks([0, 90, 180, 270, 360])
    ax_y.set_xlabel("time [s]")
    for ax in (ax_h, ax_rp, ax_y):
        ax.grid(True, alpha=0.3)
        if segments:
            for row in segments[1:]:
                ax.axvline(row["start_s"], color="0.6", lw=0.6, ls="--")
    if title:
        fig.suptitle(title)
    fig.savefig(path, dpi=110)
    return path
