"""``fleet.html`` of ``aidnav fleet`` (issue 41): one self-contained page over a fleet of logs.

Sections: the counts (logs, ok, failed); the distributions, per vehicle (``vehicle_id``), of the accuracy
against the reference where the manifest gave one (horizontal / 3-D position RMS), of the σ consistency
(mean NIS over its degrees of freedom: 1 when the filter's σ match its innovations) and of the
calibration estimates (IMU–GNSS time offset, mounting roll/pitch/heading, lever arm x/y/z) where the
filter estimated them; every failed log with its error; and the table of every log.

Input: the fleet table's rows (:func:`aidnav.apps.fleet.fleet_table`, as dicts). The page depends on the
rows only (no time, no random jitter): the same rows give the same bytes.
"""

from __future__ import annotations

import math

import numpy as np

from .html import escape, fmt, img_tag, kv_table, page, png_b64, table

__all__ = ["fleet_page_html", "PANELS"]

#: (title, columns, the column saying whether it was estimated (None: always shown))
PANELS = [
    ("horizontal position RMS vs reference [m]", ["err_h_rms_m"], None),
    ("3-D position RMS vs reference [m]", ["err_3d_rms_m"], None),
    ("GNSS position: mean NIS / dof (1 = consistent σ)", ["nis_gnss_position_ratio"], None),
    ("GNSS velocity: mean NIS / dof", ["nis_gnss_velocity_ratio"], None),
    ("IMU–GNSS time offset [s]", ["time_offset_s"], "time_offset_s_estimated"),
    ("mounting roll / pitch / heading [deg]", ["mounting_roll_deg", "mounting_pitch_deg",
                                               "mounting_heading_deg"], "mounting_rph_deg_estimated"),
    ("lever arm x / y / z [m]", ["lever_arm_x_m", "lever_arm_y_m", "lever_arm_z_m"], "lever_arm_m_estimated"),
]
_TABLE = [("name", "log"), ("vehicle_id", "vehicle"), ("status", "status"), ("duration_s", "duration [s]"),
          ("gnss_position_rejected", "fixes rejected"), ("nis_gnss_position_ratio", "NIS/dof pos"),
          ("err_h_rms_m", "horiz. RMS [m]"), ("time_offset_s", "time offset [s]"),
          ("reinitialisations", "re-inits")]


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _panels(rows: list[dict]) -> list[tuple[str, list[str]]]:
    out = []
    for title, cols, flag in PANELS:
        ok = [r for r in rows if r.get("status") == "ok" and (flag is None or r.get(flag))]
        cols = [c for c in cols if any(_finite(r.get(c)) for r in ok)]
        if cols:
            out.append((title, cols))
    return out


def _figure(rows: list[dict], panels, groups: list[str]):
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # lazy: matplotlib is heavy to import
    from matplotlib.figure import Figure  # lazy: matplotlib is heavy to import

    ncol = min(2, len(panels))
    nrow = (len(panels) + ncol - 1) // ncol
    fig = Figure(figsize=(6 * ncol, 3.0 * nrow), layout="constrained")
    FigureCanvasAgg(fig)
    ok = [r for r in rows if r.get("status") == "ok"]
    for k, (title, cols) in enumerate(panels):
        ax = fig.add_subplot(nrow, ncol, k + 1)
        width = 0.8 / len(cols)
        for j, c in enumerate(cols):
            data, pos = [], []
            for g, name in enumerate(groups):
                v = np.array([r[c] for r in ok if r.get("vehicle_id") == name and _finite(r.get(c))])
                if len(v):
                    data.append(v)
                    pos.append(g + (j - (len(cols) - 1) / 2) * width)
            if not data:
                continue
            bp = ax.boxplot(data, positions=pos, widths=width * 0.8, patch_artist=True, showfliers=False,
                            manage_ticks=False)
            for b in bp["boxes"]:
                b.set(facecolor=f"C{j}", alpha=0.35)
            # every log a point, spread across the box by its rank (deterministic)
            xs = np.concatenate([p + width * 0.3 * (np.arange(len(d)) / max(len(d) - 1, 1) - 0.5)
                                 for p, d in zip(pos, data, strict=True)])
            ax.plot(xs, np.concatenate(data), ".", color=f"C{j}", ms=3,
                    label=c if len(cols) > 1 else None)
        ax.set_xticks(range(len(groups)), groups, rotation=30 if len(groups) > 6 else 0)
        ax.set_xlim(-0.6, len(groups) - 0.4)
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
        if len(cols) > 1:
            ax.legend(fontsize=7)
    return fig


def fleet_page_html(rows: list[dict], title: str = "aidnav fleet") -> str:
    """The HTML text of ``fleet.html`` (module doc)."""
    ok = [r for r in rows if r.get("status") == "ok"]
    failed = [r for r in rows if r.get("status") != "ok"]
    groups = sorted({str(r.get("vehicle_id") or "all") for r in rows})
    parts = [f"<h1>{escape(title)}</h1>",
             kv_table([["logs", len(rows)], ["ok", len(ok)], ["failed", len(failed)],
                       ["vehicles", ", ".join(groups)]])]
    panels = _panels(rows)
    if panels:
        parts.append("<h2>Distributions per vehicle</h2>")
        parts.append('<p class="note">One point per log (successful logs); boxes: quartiles and whiskers '
                     "to 1.5 IQR. Calibration panels only where the filter estimated the quantity.</p>")
        parts.append(img_tag(png_b64(_figure(rows, panels, groups)), "fleet distributions"))
    if failed:
        parts.append(f"<h2>Failed logs ({len(failed)})</h2>")
        parts.append(table(["log", "vehicle", "error"],
                           [[r["name"], r.get("vehicle_id") or "", r.get("error") or ""] for r in failed]))
    parts.append(f"<h2>All logs ({len(rows)})</h2>")
    body = []
    for r in rows:
        cells = []
        for c, _ in _TABLE:
            v = r.get(c)
            if c == "status":
                cells.append((escape(str(v)), "good" if v == "ok" else "bad"))
            else:
                cells.append(fmt(v) if v is not None else "–")
        body.append(cells)
    parts.append(table([h for _, h in _TABLE], body))
    parts.append('<p class="note">Every value of every log: fleet.parquet beside this page; each log\'s '
                 "outputs in its own folder.</p>")
    return page(title, parts)
