"""``overview.png`` of a processing run (``aidnav process`` / ``aidnav tight``): what a navigation
engineer looks at first.

Panels: the track on a local ENU map (metres about the first epoch, WGS-84) with the GNSS fixes, the
fixes the filter rejected (red ×), the withheld fixes and the track during GNSS outages (orange);
height; roll and pitch; heading; the solution's 1σ (position E/N/U [m], attitude [deg]); and the
normalised innovation squared (NIS) per measurement type against its two-sided 95 % χ² band
(dof = number of measured components of each update). Outage windows are shaded on every time panel.
Time axis: seconds since the trajectory's first epoch (stated in the label, on the input's time scale).

Inputs: a :class:`~aidnav.data.Trajectory`, optionally the :class:`~aidnav.data.GnssData` fixes, the
summary dict of :func:`aidnav.apps.process.process_logs` (``outage_windows``, ``rejected_fix_times``, input
names) and a records dict of innovations: ``run_loose``'s ``res.records`` (``pos_status``, ``pos_nis``,
``pos_innov``, ``vel_status``, ``vel_nis``, ``vel_innov``, aligned with the GNSS fixes) or, for the
tightly coupled filter, :func:`tight_records` of ``res.epochs``. Generic rule: every ``<type>_nis``
array is a panel, with ``<type>_dof`` or the finite count of ``<type>_innov`` as the dof,
``<type>_status`` (1 accepted, 0 rejected) for the markers and ``time`` (or the GNSS times) as its time.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import Formatter

from aidnav.analysis.consistency import chi2_band
from aidnav.data import GnssData, Trajectory
from aidnav.io.atomic import replacing
from aidnav.nav.plain import lla_to_enu, wrap_360  # numpy: the figures' child runs without numba

from .maps import fix_groups

__all__ = ["write_overview", "overview_figure", "nis_series", "tight_records", "NIS_NAMES", "Skeleton",
           "panel_names", "draw_panels", "painted_box", "figure_key", "save_png"]

#: Panel names of the usual measurement types.
NIS_NAMES = {"pos": "GNSS position", "vel": "GNSS velocity", "pr": "pseudorange", "rate": "range rate"}
_DEFAULT_DOF = {"pos": 3, "vel": 3}
PROB = 0.95
#: zlib level of overview.png (PIL's default 6): the encoding is ≈ a sixth of the overview's drawing; level 1
#: drew W1's overview in 0.35 instead of 0.41 CPU-s (min of 5, loaded machine) for a file of 351 instead of
#: 300 kB (issue 41, session 9)
PNG_COMPRESS_LEVEL = 1
#: major tick objects made per axis before the run (:meth:`Skeleton.prime`): an empty axis draws 6, a run's
#: time axis 9–10 (W1, its first 60 s), and each one made after the run is ≈ 1 ms of the overview's drawing
PRIMED_TICKS = 10


def tight_records(epochs: dict) -> dict:
    """NIS records of the tightly coupled filter from ``TightResult.epochs``: per GNSS epoch, the sum
    over satellites of ν²/s of the sequential scalar updates (pseudorange ``pr``, range rate ``rate``;
    every tested measurement, gated ones included), with dof = the number of terms. Keys ``time``,
    ``pr_nis``, ``pr_dof``, ``rate_nis``, ``rate_dof``."""
    out = {"time": np.asarray(epochs["time"], float)}
    for k in ("pr", "rate"):
        nu, s = epochs.get(f"{k}_innov"), epochs.get(f"{k}_s")
        if nu is None or s is None:
            continue
        nu, s = np.asarray(nu, float), np.asarray(s, float)
        ok = np.isfinite(nu) & np.isfinite(s) & (s > 0)
        terms = np.where(ok, nu**2 / np.where(ok, s, 1.0), 0.0)
        dof = ok.sum(axis=1)
        out[f"{k}_nis"] = np.where(dof > 0, terms.sum(axis=1), np.nan)
        out[f"{k}_dof"] = dof
    return out


def nis_series(records: dict | None, gnss: GnssData | None = None) -> list[dict]:
    """The NIS panels of ``records``: a list of {key, name, time, nis, dof (per epoch, int), status
    (or None)}. Raises ``ValueError`` when a series has no time (no ``time`` key and no GNSS fixes of
    its length)."""
    if not records:
        return []
    out = []
    for key in sorted(k[:-4] for k in records if k.endswith("_nis")):
        nis = np.asarray(records[f"{key}_nis"], float).ravel()
        t = records.get("time")
        if t is None or len(t) != len(nis):
            if gnss is not None and len(gnss) == len(nis):
                t = gnss.time
            else:
                raise ValueError(f"records[{key + '_nis'!r}]: {len(nis)} values but no 'time' of that length "
                                 f"(GNSS fixes: {None if gnss is None else len(gnss)})")
        if f"{key}_dof" in records:
            dof = np.asarray(records[f"{key}_dof"]).astype(int).ravel()
        elif f"{key}_innov" in records:
            inn = np.asarray(records[f"{key}_innov"], float)
            dof = np.isfinite(inn).reshape(len(nis), -1).sum(axis=1)
        else:
            dof = np.full(len(nis), _DEFAULT_DOF.get(key, 1))
        st = records.get(f"{key}_status")
        out.append({"key": key, "name": NIS_NAMES.get(key, key), "time": np.asarray(t, float), "nis": nis,
                    "dof": dof, "status": None if st is None else np.asarray(st).ravel()})
    return out


def _bands(dof: np.ndarray, prob: float = PROB) -> tuple[np.ndarray, np.ndarray]:
    lo = np.full(len(dof), np.nan)
    hi = np.full(len(dof), np.nan)
    for d in np.unique(dof[dof > 0]):
        a, b = chi2_band(int(d), 1, prob)
        lo[dof == d], hi[dof == d] = a, b
    return lo, hi


def _rejected_mask(gnss: GnssData, summary: dict, records: dict | None) -> np.ndarray:
    st = None if records is None else records.get("pos_status")
    if st is not None and len(st) == len(gnss):
        return np.asarray(st) == 0

    return fix_groups(gnss, summary.get("rejected_fix_times"), None)[0]


def _shade(ax, wins, t0):
    for k, (a, b) in enumerate(wins):
        ax.axvspan(a - t0, b - t0, color="tab:orange", alpha=0.15, lw=0,
                   label="GNSS outage" if k == 0 else None)


def panel_names(traj: Trajectory, gnss: GnssData | None = None, records: dict | None = None) -> list[str]:
    """The panels of the right column: ``rp`` (roll, pitch), ``heading``, ``spos`` / ``satt`` (position /
    attitude 1σ, where the trajectory has them) and ``nis:<type>`` per measurement type with an update (a
    type with none, e.g. GNSS without velocities, gets no panel: an empty panel costs as much to draw as a
    full one; the run page's NIS table says which types had none)."""
    return _panels(traj, _series(records, gnss))


def _series(records, gnss) -> list[dict]:
    return [x for x in nis_series(records, gnss) if np.any(np.isfinite(x["nis"]) & (x["dof"] > 0))]


def _panels(traj: Trajectory, series: list[dict]) -> list[str]:
    has_std_att = traj.std_att is not None and np.any(np.isfinite(traj.std_att))
    has_std_pos = traj.std_pos is not None and np.any(np.isfinite(traj.std_pos))
    return ["rp", "heading"] + (["spos"] if has_std_pos else []) + (["satt"] if has_std_att else []) + \
        [f"nis:{s['key']}" for s in series]


class Skeleton:
    """What the overview draws whatever the run's numbers: the figure, its grid, axes, labels, scales,
    fixed limits and grids for the right column ``right`` (:func:`panel_names`). The figures' child of
    ``aidnav process`` builds it and draws it once (:meth:`prime`: the tick objects, the renderer and the
    text of the fixed labels made) while the parent runs the filter; :func:`overview_figure` then only
    adds the run's artists. The same figure, pixel for pixel, as one built after the run (tested)."""

    def __init__(self, right: list[str]):
        self.right = list(right)
        self.used = False
        self.fig, self.ax_map, self.ax_h, self.axes = _layout(self.right)
        self.ax_map.set_title("map: local ENU about the first epoch")
        self.ax_map.set_aspect("equal", adjustable="datalim")
        self.ax_map.grid(True, alpha=0.3)
        self.ax_h.set_ylabel("height [m]")
        labels = {"rp": "roll, pitch [deg]", "heading": "heading [deg]", "spos": "position 1σ [m]",
                  "satt": "attitude 1σ [deg]"}
        for name, ax in self.axes.items():
            ax.set_ylabel(labels.get(name) or f"NIS {name[4:]}")
            if name in ("spos", "satt"):
                _log_y(ax)
            ax.grid(True, alpha=0.3)
            if name != self.right[-1]:
                ax.tick_params(labelbottom=False)
        if "heading" in self.axes:
            self.axes["heading"].set_ylim(0, 360)
            self.axes["heading"].set_yticks([0, 90, 180, 270, 360])
        self.ax_h.grid(True, alpha=0.3)

    def prime(self) -> None:
        """Draw the empty skeleton once (nothing is saved): its tick objects (:data:`PRIMED_TICKS` per axis:
        those a run's limits need; the unused ones are not drawn), the canvas's renderer and the fixed
        labels' text are made now, not after the run."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # empty log axes
            self.fig.canvas.draw()
        for ax in self.fig.axes:
            ax.xaxis.get_major_ticks(PRIMED_TICKS)
            ax.yaxis.get_major_ticks(PRIMED_TICKS)


def overview_figure(traj: Trajectory, gnss: GnssData | None = None, summary: dict | None = None,
                    records: dict | None = None, title: str | None = None, max_points: int = 20000,
                    skeleton: Skeleton | None = None) -> Figure:
    """The figure of :func:`write_overview` (not saved): the :class:`Skeleton` of its panels (``skeleton``
    when it has those panels and was not used yet, else a new one), then the map, the height, the time
    panels on the right, the shading and the title (in that order: the drawing is the same)."""
    if len(traj.time) == 0:
        raise ValueError("overview: empty trajectory")
    summary = summary or {}
    wins = [tuple(map(float, w)) for w in summary.get("outage_windows", [])]
    series = _series(records, gnss)
    right = _panels(traj, series)
    if skeleton is None or skeleton.used or skeleton.right != right:
        skeleton = Skeleton(right)
    skeleton.used = True
    fig, ax_map, ax_h, axes = skeleton.fig, skeleton.ax_map, skeleton.ax_h, skeleton.axes
    step = max(1, int(np.ceil(len(traj.time) / max_points)))
    sl = slice(None, None, step)
    t0 = float(traj.time[0])
    t = traj.time[sl] - t0
    xl = f"time since {t0:.3f} s [s]"
    _map_panel(ax_map, traj, gnss, summary, records, wins, step)
    if gnss is not None and len(gnss):
        ax_h.plot(gnss.time - t0, gnss.height, ".", ms=2, color="C1", alpha=0.6, label="GNSS")
    ax_h.plot(t, traj.height[sl], color="C0", lw=0.9, label="solution")
    ax_h.set_xlabel(xl)
    ax_h.legend(loc="best", fontsize=8)
    _time_panels(axes, traj, sl, t, t0, series)
    for ax in axes.values():
        _shade(ax, wins, t0)
    axes[right[-1]].set_xlabel(xl)
    _shade(ax_h, wins, t0)
    if title is None:
        inputs = [Path(str(summary[k])).name for k in ("imu", "gnss", "obs") if summary.get(k)]
        title = "aidnav run" + (": " + " + ".join(inputs) if inputs else "")
        if summary.get("smoothed"):
            title += " (smoothed)"
    fig.suptitle(title)
    return fig


def _layout(right: list[str]):
    """The figure and its axes: the map (left, above), the height (left, below) and one panel per name of
    ``right`` (sharing the height's time axis). Returns (fig, ax_map, ax_h, {name: axes})."""
    nr = max(len(right), 3)
    height = max(8.0, 0.9 + 2.0 * nr)
    fig = Figure(figsize=(14.0, height))
    FigureCanvasAgg(fig)
    # fixed margins [in] that fit the labels (a layout engine measures every text: about half the drawing)
    gs = fig.add_gridspec(nr, 2, width_ratios=[1.15, 1.0], left=0.055, right=0.99, wspace=0.2,
                          bottom=0.55 / height, top=1.0 - 0.6 / height, hspace=0.45)
    n_map = max(nr - 1, 2) if nr > 3 else 2
    ax_map = fig.add_subplot(gs[:n_map, 0])
    ax_h = fig.add_subplot(gs[n_map:, 0])
    axes = {}
    for i, name in enumerate(right):
        axes[name] = fig.add_subplot(gs[i, 1], sharex=ax_h)
    return fig, ax_map, ax_h, axes


def _map_panel(ax_map, traj: Trajectory, gnss, summary: dict, records, wins, step: int) -> None:
    """The track on a local ENU map about the first finite epoch [m, or km beyond 5 km], the track during
    outages, the fixes used, withheld and rejected, the start and the end."""
    sl = slice(None, None, step)
    fin = np.isfinite(traj.lat) & np.isfinite(traj.lon)
    i0 = int(np.flatnonzero(fin)[0]) if fin.any() else 0
    ref = (float(traj.lat[i0]), float(traj.lon[i0]), float(traj.height[i0]))
    e, n, _ = lla_to_enu(traj.lat[sl], traj.lon[sl], traj.height[sl], *ref)
    ext = max(np.nanmax(e) - np.nanmin(e), np.nanmax(n) - np.nanmin(n)) if np.isfinite(e).any() else 0.0
    scale, unit = (1000.0, "km") if ext > 5000.0 else (1.0, "m")
    e, n = e / scale, n / scale
    ax_map.plot(e, n, lw=1.1, color="C0", label="trajectory", zorder=3)
    for k, (a, b) in enumerate(wins):
        m = (traj.time >= a) & (traj.time < b)
        if m.any():
            oe, on, _ = lla_to_enu(traj.lat[m][::step], traj.lon[m][::step], traj.height[m][::step], *ref)
            oe, on = oe / scale, on / scale
            ax_map.plot(oe, on, lw=3.0, color="tab:orange", zorder=4,
                        label="during outage" if k == 0 else None)
    if gnss is not None and len(gnss):
        ge, gn, _ = lla_to_enu(gnss.lat, gnss.lon, gnss.height, *ref)
        ge, gn = ge / scale, gn / scale
        rej = _rejected_mask(gnss, summary, records)
        wh = np.zeros(len(gnss), bool)
        for a, b in wins:
            wh |= (gnss.time >= a) & (gnss.time < b)
        used = ~rej & ~wh
        ax_map.plot(ge[used], gn[used], ".", ms=2.5, color="C1", alpha=0.7,
                    label=f"{(summary or {}).get('gnss_label', 'GNSS fixes')} ({used.sum()})", zorder=2)
        if wh.any():
            ax_map.plot(ge[wh], gn[wh], "o", ms=3, mfc="none", mec="0.55", mew=0.6,
                        label=f"withheld ({wh.sum()})", zorder=2)
        if rej.any():
            ax_map.plot(ge[rej], gn[rej], "x", ms=6, color="tab:red", mew=1.2,
                        label=f"rejected ({rej.sum()})", zorder=5)
    ax_map.plot(e[0], n[0], "o", color="C2", ms=7, label="start", zorder=6)
    ax_map.plot(e[-1], n[-1], "s", color="C3", ms=7, label="end", zorder=6)
    ax_map.set_xlabel(f"East [{unit}]")
    ax_map.set_ylabel(f"North [{unit}]")
    ax_map.legend(loc="best", fontsize=8)


def _time_panels(axes: dict, traj: Trajectory, sl: slice, t, t0: float, series: list[dict]) -> None:
    """The panels on the right: roll and pitch, heading, the position and attitude 1σ (log axes of the
    :class:`Skeleton`) where the trajectory has them, and one NIS panel per measurement type of ``series``."""
    ax = axes["rp"]
    ax.plot(t, np.degrees(traj.rph[sl, 0]), lw=0.8, label="roll")
    ax.plot(t, np.degrees(traj.rph[sl, 1]), lw=0.8, label="pitch")
    ax.legend(loc="upper right", fontsize=8)
    axes["heading"].plot(t, wrap_360(np.degrees(traj.rph[sl, 2])), ".", ms=1, color="C2")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # log axes with zero / NaN σ
        if "spos" in axes:
            ax = axes["spos"]
            for i, c in enumerate("ENU"):
                ax.plot(t, traj.std_pos[sl, i], lw=0.8, label=f"σ{c}")
            ax.legend(loc="upper right", fontsize=8, ncol=3)
        if "satt" in axes:
            ax = axes["satt"]
            for i, c in enumerate(("roll", "pitch", "heading")):
                ax.plot(t, np.degrees(traj.std_att[sl, i]), lw=0.8, label=f"σ {c}")
            ax.legend(loc="upper right", fontsize=8, ncol=3)
        for s in series:
            _nis_panel(axes[f"nis:{s['key']}"], s, t0)


class _PlainLog(Formatter):
    """Tick labels of a log axis in plain numbers (0.02, 0.1, 5): matplotlib's default log labels (2×10⁻²)
    go through its mathtext parser, about a tenth of the overview's drawing. Minor ticks are labelled
    as matplotlib labels them: none over more than one decade, 2 and 5 over 0.4–1 decade, all below."""

    def __init__(self, minor: bool = False):
        self.minor = minor

    def __call__(self, x, pos=None):
        if not (x > 0 and np.isfinite(x)):
            return ""
        if self.minor:
            lo, hi = sorted(self.axis.get_view_interval())
            decades = np.log10(hi / lo) if lo > 0 else np.inf
            mantissa = round(x / 10.0 ** np.floor(np.log10(x) + 1e-9))
            if decades > 1.0 or (decades > 0.4 and mantissa not in (2, 5)):
                return ""
        return f"{x:.6g}"


def _log_y(ax) -> None:
    """A log y axis labelled in plain numbers (:class:`_PlainLog`)."""
    ax.set_yscale("log")
    ax.yaxis.set_major_formatter(_PlainLog())
    ax.yaxis.set_minor_formatter(_PlainLog(minor=True))


def _nis_panel(ax, s: dict, t0: float) -> None:
    t = s["time"] - t0
    v, dof = s["nis"], s["dof"]
    fin = np.isfinite(v) & (dof > 0)
    lo, hi = _bands(dof)
    d = np.unique(dof[fin])
    if len(d) <= 1:
        if len(d):
            a, b = chi2_band(int(d[0]), 1, PROB)
            ax.axhspan(a, b, color="tab:green", alpha=0.15, lw=0,
                       label=f"{100 * PROB:g}% χ² band ({a:.3g}, {b:.3g})")
            ax.axhline(d[0], color="k", lw=0.6, ls="--", label=f"expected {int(d[0])}")
    else:
        o = np.argsort(t)
        ax.fill_between(t[o], lo[o], hi[o], where=fin[o], step="mid", color="tab:green", alpha=0.15, lw=0,
                        label=f"{100 * PROB:g}% χ² band (dof {int(d.min())}–{int(d.max())})")
    st = s["status"]
    rej = np.zeros(len(v), bool) if st is None or len(st) != len(v) else (st == 0)
    # robust view: the band and 99.5 % of the values; the values above it are drawn on the top edge (▲)
    top = max(np.nanmax(hi[fin]) * 1.3, np.percentile(v[fin], 99.5) * 1.1) if fin.any() else 1.0
    above = fin & (v > top)
    ok = fin & ~rej & ~above
    ax.plot(t[ok], v[ok], ".", ms=2.5, color="tab:blue", label="NIS")
    if (fin & rej & ~above).any():
        ax.plot(t[fin & rej & ~above], v[fin & rej & ~above], "x", ms=5, color="tab:red",
                label=f"rejected ({(fin & rej).sum()})")
    if above.any():
        ax.plot(t[above], np.full(above.sum(), top), "^", ms=5, color="tab:red", clip_on=False,
                label=f"above the view ({above.sum()}, max {np.nanmax(v[above]):.3g})")
    inside = float(np.mean((v[fin] >= lo[fin]) & (v[fin] <= hi[fin]))) if fin.any() else float("nan")
    ax.set_ylim(0, top)
    if len(d) == 1:
        dtxt = f"dof {int(d[0])}"
    else:
        dtxt = f"dof {int(d.min())}–{int(d.max())}" if len(d) else "no data"
    ax.set_title(f"{s['name']} NIS ({dtxt}): {fin.sum()} updates, "
                 + (f"{100 * inside:.1f}% inside the band" if fin.any() else "none"), fontsize=9)
    ax.legend(loc="upper right", fontsize=7, ncol=2)


def draw_panels(fig: Figure, axes: list, title: bool) -> np.ndarray:
    """Draw only ``axes`` of ``fig`` (the others hidden) and, with ``title``, its title into its canvas;
    returns the canvas's pixels, one ``uint32`` (RGBA) per pixel, rows from the top (a view)."""
    for ax in fig.axes:
        ax.set_visible(any(ax is a for a in axes))
    if not title:
        fig.suptitle("")
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba()).view(np.uint32)[..., 0]


def painted_box(px: np.ndarray) -> tuple[int, int, int, int] | None:
    """(first row, end row, first column, end column) of the pixels of ``px`` (:func:`draw_panels`) that are
    not the white background; None when all are."""
    ink = px != np.uint32(0xFFFFFFFF)
    rows, cols = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
    if not len(rows):
        return None
    return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1


def figure_key(fig: Figure) -> tuple:
    """What two drawing processes compare before their pixels are put together: every axes' limits and the
    figure's title (the same job and skeleton give the same figure; a difference means another one)."""
    return tuple(ax.get_xlim() + ax.get_ylim() for ax in fig.axes) + (fig.get_suptitle(),)


def save_png(fig: Figure, path) -> None:
    """The canvas of ``fig``, already drawn, written as ``fig.savefig(path, format="png")`` at the figure's
    dpi writes it after its own draw (matplotlib's PNG writer, the same metadata and zlib level): the same
    bytes (tested)."""
    from matplotlib.image import imsave  # lazy: matplotlib's PNG writer (loaded with the figure)

    imsave(path, fig.canvas.buffer_rgba(), format="png", origin="upper", dpi=fig.dpi,
           pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL})


def write_overview(path, traj: Trajectory, gnss: GnssData | None = None, summary: dict | None = None,
                   records: dict | None = None, title: str | None = None, dpi: int = 100,
                   skeleton: Skeleton | None = None, draw=None) -> Path:
    """Write ``overview.png`` (see the module docstring) to ``path`` and return the path.

    traj : the solution; gnss : the GNSS fixes used (antenna positions); summary : the dict of
    :func:`aidnav.apps.process.process_logs` (outage windows, rejected fix times, input names); records :
    innovation records (``res.records`` of ``run_loose``, or :func:`tight_records`); dpi : 100 gives a
    1400-px-wide image; skeleton : a :class:`Skeleton` built beforehand (used when its panels are this
    run's); draw : called with the figure to draw it into its canvas (the figures' child of ``aidnav
    process`` draws it with a second process: :mod:`aidnav.apps.run_outputs`), a PNG at the figure's dpi
    only; the canvas is then written by :func:`save_png`.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig = overview_figure(traj, gnss, summary, records, title, skeleton=skeleton)
    fmt = path.suffix.lstrip(".") or "png"
    png = {"pil_kwargs": {"compress_level": PNG_COMPRESS_LEVEL}} if fmt == "png" else {}
    with replacing(path) as tmp:  # under a temporary name until complete
        if draw is not None and fmt == "png" and dpi == fig.dpi:
            draw(fig)
            save_png(fig, tmp)
        else:
            fig.savefig(tmp, dpi=dpi, format=fmt, **png)
    return path
