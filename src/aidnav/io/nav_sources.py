"""Which navigation data a tight or SPP run reads: the RINEX navigation file and, where there is one, the
receiver's own UBX log, whose RXM-SFRBX frames hold the broadcast ephemerides the RINEX conversion left
out (issue 40: the walk's nav file has 4 GPS satellites; its UBX log has 7 Galileo satellites' I/NAV
ephemerides beside them).

The setting (``gnss.ubx_nav`` of the tight configuration, ``--ubx-nav`` of ``aidnav tight`` and ``aidnav
spp``) is one of

* ``"auto"`` (the default): the UBX log that the observation file itself names as its source — RTKLIB's
  ``convbin`` writes the header comments ``format: u-blox UBX`` and ``log: NAME`` — found in the
  observation file's directory or in its parent (``convbin ... -o rinex/x.obs x.ubx`` run beside the log);
  nothing is guessed from file names, and a log that is named but absent, or holds no complete ephemeris,
  leaves the navigation file alone (an event says so);
* ``"none"`` (or ``None``): the navigation file alone;
* a path: that UBX log (relative paths against ``base_dir``: the configuration file's directory, or the
  current directory for the command-line option); a missing file or a log without ephemerides is an input
  error (exit 2).

:func:`read_observations_and_navigation` reads the pair (:func:`aidnav.io.rinex.read_rinex_pair`) with the
log the setting gives and returns the sources it used (for the summary's ``ephemerides`` line).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aidnav.io.errors import DataError
from aidnav.io.rinex import UBX_SOURCES, read_rinex_pair
from aidnav.nav.gnss_sat import E_HEALTH, E_PRN, SYSTEMS, sat_name

__all__ = ["AUTO", "NONE", "source_log", "resolve_ubx_nav", "read_observations_and_navigation",
           "format_sources"]

AUTO, NONE = "auto", "none"
_SYSTEM_NAMES = {"G": "GPS", "E": "Galileo", "C": "BeiDou", "R": "GLONASS", "S": "SBAS"}


def source_log(obs_path) -> tuple[Path | None, str]:
    """The UBX log named in the RINEX observation file's header (``format: u-blox UBX`` and ``log: NAME``
    comments, RTKLIB ``convbin``) when it exists beside the file or in its parent directory: (path or None,
    what was found, for the events)."""
    obs_path = Path(obs_path)
    fmt, log = None, None
    try:
        with open(obs_path, encoding="ascii", errors="replace") as f:
            for line in f:
                if line[60:].startswith("COMMENT"):
                    text = line[:60].strip()
                    if text.lower().startswith("format:"):
                        fmt = text[len("format:"):].strip()
                    elif text.lower().startswith("log:"):
                        log = text[len("log:"):].strip()
                if "END OF HEADER" in line:
                    break
    except OSError:
        return None, f"{obs_path.name}: not readable"
    if log is None or fmt is None or "ubx" not in fmt.lower():
        return None, f"{obs_path.name}: its header names no u-blox UBX source log"
    name = Path(log.replace("\\", "/")).name
    for d in (obs_path.parent, obs_path.parent.parent):
        if (d / name).is_file():
            return d / name, f"{obs_path.name}'s header names {name} as its source log"
    return None, (f"{obs_path.name}'s header names {name} as its source log, not found beside it or in its "
                  "parent directory")


def resolve_ubx_nav(setting, obs_path, base_dir=None) -> tuple[Path | None, str]:
    """The UBX log of ``setting`` (module doc) for the observation file ``obs_path``: (path or None, how it
    was chosen). A path is taken as given (relative to ``base_dir`` when it is relative and ``base_dir`` is
    given); a given path that is not a file is a DataError."""
    if setting is None or str(setting).strip().lower() == NONE:
        return None, "not asked for (ubx_nav: none)"
    s = str(setting).strip()
    if s.lower() == AUTO:
        path, why = source_log(obs_path)
        return path, f"auto: {why}"
    p = Path(s).expanduser()
    if not p.is_absolute() and base_dir is not None:
        p = Path(base_dir) / p
    if not p.is_file():
        raise DataError(p, None, "UBX log not found — give the receiver's UBX log, 'auto' (the log the "
                        "observation file names) or 'none' (--ubx-nav, gnss.ubx_nav)")
    return p, "given"


def read_observations_and_navigation(obs_path, nav_path, systems: str = "GECR", ubx_nav=AUTO,
                                     base_dir=None, ubx_sources: str = UBX_SOURCES):
    """:func:`aidnav.io.rinex.read_rinex_pair` with the UBX log of the setting ``ubx_nav`` (module doc).
    Returns (observations, ephemerides, events, sources): ``sources`` = {"nav": the navigation file,
    "ubx_nav": the log used or None, "how": how it was chosen, "satellites": {system name: satellites with
    a healthy ephemeris}, "unhealthy": [satellites whose every record is flagged]}. An automatic log that
    cannot be read into any ephemeris is left out with a warning event; a given one is an input error.
    ``ubx_sources``: what is taken from the log (as :func:`aidnav.io.rinex.read_rinex_pair`'s; all by
    default)."""
    ubx, how = resolve_ubx_nav(ubx_nav, obs_path, base_dir)
    events: list[str] = []
    if ubx is not None and how.startswith(AUTO):
        try:
            obs, eph, ev = read_rinex_pair(obs_path, nav_path, systems, ubx_nav=ubx, ubx_sources=ubx_sources)
        except DataError as e:
            events.append(f"warning: {ubx.name} (auto: named by {Path(obs_path).name}) not used: "
                          f"{e.problem}; the navigation file alone")
            ubx, how = None, f"auto: {ubx.name} holds no usable ephemeris"
            obs, eph, ev = read_rinex_pair(obs_path, nav_path, systems)
    else:
        obs, eph, ev = read_rinex_pair(obs_path, nav_path, systems, ubx_nav=ubx, ubx_sources=ubx_sources)
    events += ev
    t = eph.table
    sats: dict[str, list[str]] = {}
    for sid in np.unique(t[t[:, E_HEALTH] == 0, E_PRN].astype(int)):
        sats.setdefault(_SYSTEM_NAMES.get(SYSTEMS[sid // 100], SYSTEMS[sid // 100]), []).append(sat_name(sid))
    healthy = set(t[t[:, E_HEALTH] == 0, E_PRN].astype(int))
    unhealthy = sorted(sat_name(s) for s in set(t[:, E_PRN].astype(int)) - healthy)
    sources = {"nav": str(nav_path), "ubx_nav": None if ubx is None else str(ubx), "how": how,
               "satellites": sats, "unhealthy": unhealthy}
    return obs, eph, events, sources


def format_sources(src: dict) -> str:
    """One line for the summaries: which files gave the ephemerides, how the UBX log was chosen, and the
    satellites with a healthy ephemeris per system."""
    files = Path(src["nav"]).name + (f" + {Path(src['ubx_nav']).name} (RXM-SFRBX; {src['how']})"
                                     if src.get("ubx_nav") else f" ({src['how']})")
    per = ", ".join(f"{k} {len(v)}" for k, v in src["satellites"].items())
    bad = f"; flagged unhealthy: {' '.join(src['unhealthy'])}" if src.get("unhealthy") else ""
    return f"ephemerides: {files}; satellites with a healthy ephemeris: {per or 'none'}{bad}"
