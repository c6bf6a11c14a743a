"""Figure of an IMU characterisation: the six Allan deviation curves with the fitted noise terms.

Matplotlib object API on the Agg canvas (no pyplot state). Units: τ in seconds; gyro ADEV in deg/h,
accelerometer ADEV in µg (docs/conventions.md boundary units). Each panel: the overlapping ADEV with its 95%
chi-square interval (filled markers: fitted; open: shown only), the maximum-likelihood model, and each
term's own ADEV with its slope: quantisation −1, white noise (ARW/VRW) −1/2, the Gauss-Markov bias
instability (its bump; the dotted line at 0.6643·B is the flicker floor with the same height), random
walk +1/2. Terms that the log does not resolve are drawn faint and marked "not resolved" ("not
resolvable" when only the white terms were fitted, a short log). Vibration found by the characterisation
is named in the panel (std, frequency): it is the hump and −1 slope of the shortest τ, not fitted.

Speed: a fixed layout (no constrained layout: it draws the figure twice) and the decade grid drawn as
two line collections instead of minor ticks (hundreds of tick artists on six log axes).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, LogLocator, NullLocator

from aidnav.analysis.noise_fit import model as C
from aidnav.analysis.noise_fit.results import Characterisation
from aidnav.units import DEG_H, DEG_H_SQRT_H, DEG_SQRT_H, M_S_SQRT_H, UG, UG_SQRT_H

__all__ = ["plot_allan", "warm_up", "AllanFigure", "panel_title"]

DPI = 120
_COLORS = {"Q": "tab:purple", "N": "tab:green", "GM": "tab:orange", "K": "tab:red"}


def _term_labels(a, sensor: str, span_s: float | None = None) -> dict:
    if sensor == "gyro":
        u = {"Q": (1.0, "rad", "quantisation"), "N": (DEG_SQRT_H, "deg/√h", "ARW"),
             "GM": (DEG_H, "deg/h", "bias instability B"), "K": (DEG_H_SQRT_H, "deg/h/√h", "RRW")}
    else:
        u = {"Q": (1.0, "m/s", "quantisation"), "N": (M_S_SQRT_H, "m/s/√h", "VRW"),
             "GM": (UG, "µg", "bias instability B"), "K": (UG_SQRT_H, "µg/√h", "acc. RW")}
    keys = {"Q": "quantisation", "N": "white", "GM": "bias_instability", "K": "rrw"}
    slope = {"Q": "−1", "N": "−1/2", "GM": "bump", "K": "+1/2"}
    white_only = getattr(a, "white_only", False)
    out = {}
    for t, k in keys.items():
        f, unit, name = u[t]
        te = a.terms[k]
        if te.fitted:
            txt = f"{name} {te.value / f:.3g} [{te.lo / f:.3g}, {te.hi / f:.3g}] {unit} (slope {slope[t]})"
            if t == "N" and white_only:
                txt += ", white noise only"
            if t == "GM":
                tt = a.terms["gm_tau"]
                txt += (f", T {tt.value:.3g} s" if tt.fitted else ", T not resolved")
        elif white_only and t in ("GM", "K"):
            txt = f"{name} not resolvable in {span_s:.3g} s (slope {slope[t]})" if span_s else \
                f"{name} not resolvable (slope {slope[t]})"
        else:
            ub = "" if te.upper is None else f" < {te.upper / f:.3g} {unit}"
            txt = f"{name} not resolved{ub} (slope {slope[t]})"
        out[t] = (te.fitted, txt)
    return out


_SUPERSCRIPT = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")


def _power_of_ten(x: float, _pos=None) -> str:
    """Tick label of a decade as plain text, 10⁻² (the default log formatter typesets $10^{-2}$ with
    mathtext: its parser costs ~20 ms per distinct label, a third of the figure's time)."""
    if not x > 0:
        return ""
    k = round(math.log10(x))
    if abs(x / 10.0**k - 1.0) > 1e-9:
        return f"{x:g}"
    return "10" + str(k).translate(_SUPERSCRIPT)


#: the major ticks' labels (decades: see :func:`_power_of_ten`)
_DECADE_LABELS = FuncFormatter(_power_of_ten)


def _decade_grid(ax, lo: float, hi: float, axis: str) -> None:
    """Minor grid lines at 2..9 × 10^k between lo and hi (one line collection)."""
    k0, k1 = math.floor(math.log10(lo)), math.ceil(math.log10(hi))
    vals = [m * 10.0**k for k in range(k0, k1 + 1) for m in range(2, 10)]
    vals = [v for v in vals if lo < v < hi]
    if not vals:
        return
    if axis == "x":
        ax.vlines(vals, 0, 1, transform=ax.get_xaxis_transform(), colors="0.5", lw=0.4, alpha=0.25, zorder=0)
    else:
        ax.hlines(vals, 0, 1, transform=ax.get_yaxis_transform(), colors="0.5", lw=0.4, alpha=0.25, zorder=0)


def warm_up() -> None:
    """Draw one panel of a made-up axis (white noise, a Gauss-Markov bump, a random walk) into memory and
    write it as a PNG: the first panel of a process pays for matplotlib's font loading, its text and
    tick machinery and the PNG writer (~0.1 s CPU), which this moves ahead of the data
    (:class:`aidnav.apps.characterise.FigureProcess` runs it while the log is read). The figures drawn
    afterwards are the same, byte for byte (tests)."""
    import io  # lazy: only the warm-up and the saving need it

    # lazy: only the warm-up and the saving need it
    from aidnav.analysis.noise_fit.results import AxisFit, TermEstimate

    tau = 2.0 ** np.arange(20) / 100.0
    coef = np.array([0.0, 2.5e-9, 1e-10, 1e-14])
    t_corr = 100.0
    adev = np.sqrt(C.model_avar(tau, coef, t_corr))
    used = np.arange(20) < 18
    fit = TermEstimate("fitted", 1.0, 0.9, 1.1)
    terms = {"white": TermEstimate("fitted", 5e-5, 4.9e-5, 5.1e-5), "quantisation": TermEstimate(
        "not resolved", upper=1e-7), "gm_sigma": fit, "gm_tau": TermEstimate("fitted", 100.0, 50.0, 200.0),
        "bias_instability": fit, "rrw": TermEstimate("not resolved", upper=1e-6)}
    a = AxisFit("gyro_x", tau, adev, adev * 0.9, adev * 1.1, np.full(20, 10.0), np.zeros(20, int), used,
                terms, coef, t_corr, 10.0, 10, 1.0)
    fig = Figure(figsize=(5.0, 4.0), dpi=DPI)
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    _panel(ax, a, {}, 3600.0)
    fig.suptitle("Allan deviation: warm-up")
    fig.savefig(io.BytesIO(), dpi=DPI, format="png")


def _panel(ax, a, vib: dict, span_s: float | None) -> None:
    """The artists of one axis's panel (``a``: an :class:`aidnav.analysis.noise_fit.AxisFit`)."""
    sensor = a.sensor
    f, unit = (DEG_H, "deg/h") if sensor == "gyro" else (UG, "µg")
    tau = a.taus
    y = a.adev / f
    lo = np.where(np.isfinite(a.adev_lo), a.adev_lo / f, y)
    hi = np.where(np.isfinite(a.adev_hi), a.adev_hi / f, y)
    err = np.vstack((y - lo, hi - y))
    u = a.used
    ax.errorbar(tau[u], y[u], yerr=err[:, u], fmt="o", ms=4, color="tab:blue", ecolor="tab:blue",
                elinewidth=0.8, capsize=2, label="ADEV (95%)")
    if (~u).any():
        ax.errorbar(tau[~u], y[~u], yerr=err[:, ~u], fmt="o", ms=4, mfc="none", color="tab:blue",
                    ecolor="tab:blue", elinewidth=0.5, capsize=2, alpha=0.6, label="not fitted")
    tf = tau[u] if u.any() else tau  # the model is drawn over the fitted τ range
    tt = np.exp(np.linspace(math.log(tf[0]), math.log(tf[-1]), 200))
    ax.plot(tt, a.model_adev(tt) / f, color="k", lw=1.2, label="fitted model")
    labels = _term_labels(a, sensor, span_s)
    for t in ("Q", "N", "GM", "K"):
        comp = a.model_adev(tt, t) / f
        fitted, txt = labels[t]
        if not np.any(comp > 0):
            ax.plot([], [], color=_COLORS[t], ls=":", lw=1.0, alpha=0.5, label=txt)
            continue
        ax.plot(tt, comp, color=_COLORS[t], ls="--" if fitted else ":", lw=1.3 if fitted else 0.9,
                alpha=1.0 if fitted else 0.5, label=txt)
        if t == "GM" and fitted:
            b = a.terms["bias_instability"].value
            ax.axhline(C.FLICKER_ADEV * b / f, color=_COLORS[t], ls=":", lw=0.8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ymin = max(np.nanmin(lo[lo > 0]) if np.any(lo > 0) else y.min(), 1e-300) / 3.0
    ymax = np.nanmax(hi) * 3.0
    xmin, xmax = tau[0] / 1.5, tau[-1] * 1.5
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_locator(LogLocator(base=10.0, numticks=12))
        axis.set_major_formatter(_DECADE_LABELS)
        axis.set_minor_locator(NullLocator())
    _decade_grid(ax, xmin, xmax, "x")
    _decade_grid(ax, ymin, ymax, "y")
    ax.grid(True, which="major", alpha=0.25)
    ax.set_xlabel("τ [s]")
    ax.set_ylabel(f"Allan deviation [{unit}]")
    ax.set_title(panel_title(a, vib), fontsize="medium")
    ax.legend(fontsize="x-small", loc="best")


def panel_title(a, vib: dict | None) -> str:
    """Title of an axis's panel: its name, and the vibration found on it (``vib``: the characterisation's
    vibration report, None: none)."""
    name = a.axis.replace("_", " ")
    d = ((vib or {}).get("axes") or {}).get(a.axis)
    if d and d.get("vibration"):
        k, vu = ("std_deg_s", "deg/s") if a.sensor == "gyro" else ("std_m_s2", "m/s²")
        pk = "" if d.get("peak_hz") is None else f" at {d['peak_hz']:.3g} Hz"
        name += f" — vibration {d[k]:.3g} {vu}{pk} (short-τ hump)"
    return name


class AllanFigure:
    """The 2 × 3 panel figure of :func:`plot_allan`, built and drawn panel by panel.

    ``panel(i, a)`` builds panel i (0-5, the order of ``AXES``) from an axis's fit and draws into the image
    every built panel whose predecessors are drawn (in order: the pixels of one draw of the whole
    figure); ``save(path)`` draws what is left (the title) and writes the PNG. The file is the one
    ``Figure.savefig`` writes of the same figure (tests): a caller that gets the axes one by one (the
    figure's process of ``aidnav characterise``, while the other axes are fitted) draws most of the
    figure before the last axis is in.
    """

    def __init__(self, title: str | None = None, span_s: float | None = None, vib: dict | None = None):
        fig = Figure(figsize=(16.0, 9.5), dpi=DPI)
        FigureCanvasAgg(fig)
        fig.subplots_adjust(left=0.05, right=0.99, bottom=0.06, top=0.92 if title else 0.95, wspace=0.17,
                            hspace=0.25)
        self.axs = fig.subplots(2, 3, squeeze=False)
        if title:
            fig.suptitle(title)
        self.fig, self.span_s, self.vib = fig, span_s, vib or {}
        self.built: set[int] = set()
        self.drawn = 0
        self._renderer = None

    def panel(self, i: int, a) -> None:
        _panel(self.axs[i // 3, i % 3], a, self.vib, self.span_s)
        self.built.add(i)
        self._draw_ready()

    def set_title(self, title: str) -> None:
        """Change the figure's title (a figure made with one: the layout leaves room for it)."""
        if self.fig._suptitle is None:
            raise ValueError("AllanFigure.set_title: a figure made without a title")
        self.fig.suptitle(title)

    def title(self, i: int) -> str:
        return self.axs[i // 3, i % 3].get_title()

    def _draw_ready(self) -> None:
        """Draw the built panels that follow the drawn ones (the image and its background are made by the
        first call: a caller may make them ahead of the panels, ``_draw_ready()`` before any)."""
        fig = self.fig
        if self._renderer is None:
            self._renderer = fig.canvas.get_renderer()
            self._renderer.clear()
            fig.patch.draw(self._renderer)
        while self.drawn < len(fig.axes) and self.drawn in self.built:
            ax = fig.axes[self.drawn]
            ax.apply_aspect()
            ax.draw(self._renderer)
            self.drawn += 1

    def save(self, path) -> Path:
        import matplotlib.image  # lazy: only the warm-up and the saving need it

        fig = self.fig
        if self.drawn < len(fig.axes):
            raise ValueError(f"AllanFigure.save: panels {sorted(set(range(6)) - self.built)} not built")
        # the figure's other artists (the title) are drawn after the axes, as Figure.draw does (by zorder)
        rest = sorted((x for x in fig.get_children() if x is not fig.patch and x not in fig.axes
                       and not x.get_animated()), key=lambda x: x.get_zorder())
        if any(x.get_zorder() < min(ax.get_zorder() for ax in fig.axes) for x in rest):
            raise ValueError("AllanFigure.save: an artist below the axes")
        for x in rest:
            x.draw(self._renderer)
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        # what Figure.savefig(path, dpi=DPI) does for a PNG after its draw (FigureCanvasAgg.print_png)
        matplotlib.image.imsave(path, fig.canvas.buffer_rgba(), format="png", origin="upper", dpi=fig.dpi)
        return path


def plot_allan(ch: Characterisation, path, title: str | None = None) -> Path:
    """Write the 2 × 3 panel Allan deviation figure of a characterisation
    (:class:`aidnav.analysis.noise_fit.Characterisation`) to ``path`` (PNG) and return the path."""
    fig = AllanFigure(title, getattr(ch, "duration_s", None), getattr(ch, "vibration", None))
    for i, a in enumerate(ch.axes):
        fig.panel(i, a)
    return fig.save(path)
