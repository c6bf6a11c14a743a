"""Console summary of a characterisation (a rich table)."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table

from aidnav.analysis.noise_fit.output import UNIT_LABELS
from aidnav.analysis.noise_fit.results import Characterisation


def print_characterisation(ch: Characterisation, console=None) -> None:
    """A rich table of the fitted terms per axis (boundary units) and the notes."""
    console = console or Console()
    tab = Table(title=f"IMU noise ({ch.n_samples} samples at {ch.fs_hz:.6g} Hz, {ch.duration_s:.6g} s; "
                      "95% intervals)")
    cols = (("white", "ARW deg/√h | VRW m/s/√h"), ("bias_instability", "bias instab. deg/h | µg"),
            ("gm_tau", "GM T s"), ("rrw", "RRW deg/h/√h | µg/√h"), ("quantisation", "Q rad | m/s"))
    tab.add_column("axis")
    for _, name in cols:
        tab.add_column(name)
    for a in ch.axes:
        units = UNIT_LABELS[a.sensor]
        row = [a.axis]
        for key, _ in cols:
            t = a.terms[key]
            f = units[key][1]
            if t.fitted:
                row.append(f"{t.value / f:.4g} [{t.lo / f:.3g}, {t.hi / f:.3g}]")
            elif t.upper is not None:
                row.append(f"n.r. (< {t.upper / f:.3g})")
            else:
                row.append("n.r.")
        tab.add_row(*row)
    console.print(tab)
    for n in ch.notes:
        if n not in ch.warnings:
            console.print(f"note: {n}")
    for w in ch.warnings:
        console.print(f"warning: {w}", style="bold yellow", markup=False)  # (the CLI's console: no markup)
